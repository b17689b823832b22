"""Re-calibrate recorded LeRobot v3 datasets (pyarrow + numpy).

Public API:

* :func:`recalibrate_table` — one Arrow table, ``value_old → actual encoder position → value_new``.
* :func:`recalibrate_dataset` — a whole dataset root into a new root (process pool, stats recomputed,
  atomic: built in a temporary sibling and renamed at the end).
* :func:`inspect_dataset` — per-joint min/max/mean with full-turn jumps and out-of-range values flagged.
* :func:`generate_dataset` — small synthetic LeRobot v3 datasets for tests and benchmarks.
* Conventions: :class:`JointMapConvention` (canonical joint map) and the LeRobot ones in
  :mod:`robocal.dataset.lerobot`.

Needs the ``dataset`` extra (``pip install 'robocal[dataset]'``, pyarrow).
"""

from __future__ import annotations

from ..backends import require

require("pyarrow", "dataset re-calibration")

from ._convention import JointMapConvention as JointMapConvention  # noqa: E402
from ._convention import ValueConvention as ValueConvention  # noqa: E402
from ._driver import DatasetReport as DatasetReport  # noqa: E402
from ._driver import recalibrate_dataset as recalibrate_dataset  # noqa: E402
from ._engine import FeaturePlan as FeaturePlan  # noqa: E402
from ._engine import recalibrate_table as recalibrate_table  # noqa: E402
from ._engine import recalibrate_values as recalibrate_values  # noqa: E402
from ._file import recalibrate_file as recalibrate_file  # noqa: E402
from ._generate import SO_ARM_JOINTS as SO_ARM_JOINTS  # noqa: E402
from ._generate import GeneratedDataset as GeneratedDataset  # noqa: E402
from ._generate import generate_dataset as generate_dataset  # noqa: E402
from ._inspect import InspectReport as InspectReport  # noqa: E402
from ._inspect import JointSummary as JointSummary  # noqa: E402
from ._inspect import inspect_dataset as inspect_dataset  # noqa: E402
from ._layout import DatasetLayout as DatasetLayout  # noqa: E402
from ._layout import VectorFeature as VectorFeature  # noqa: E402
from ._layout import read_layout as read_layout  # noqa: E402
from ._stats import StatAccumulator as StatAccumulator  # noqa: E402
