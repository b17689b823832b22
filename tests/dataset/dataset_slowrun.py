"""Run ``robocal dataset recalibrate`` with every data file slowed down, so another process can kill it midway.

``python dataset_slowrun.py SECONDS_PER_FILE ARGS...``: the arguments after the delay are those of
``robocal dataset recalibrate``. Workers are forked, so they run the slowed function too.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from robocal.cli.main import main
from robocal.dataset import _driver

_real_work = _driver._work


def _slow_work(args: Any) -> Any:
    time.sleep(float(sys.argv[1]))
    return _real_work(args)


if __name__ == "__main__":
    _driver._work = _slow_work
    sys.exit(main(["dataset", "recalibrate", *sys.argv[2:]]))
