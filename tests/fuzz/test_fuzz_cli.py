"""Fuzz the ``robocal`` command through a subprocess per run: mutated input files must give exit code 0-3,
no traceback, exactly one ``error:`` line on failure, and no file created or changed unless the command
succeeded (then only its declared outputs).

Each example runs two mutated inputs side by side (one subprocess each, two cores), so the default profile
stays within CI's budget; ``HYPOTHESIS_PROFILE=thorough`` runs 100× as many.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import seeds
from fuzzlib import (
    PENDING,
    byte_mutation,
    fuzz_settings,
    json_mutation,
    snapshot,
    text_mutation,
    yaml_mutation,
)
from hypothesis import given
from hypothesis import strategies as st

SEEDS = seeds.calibration_seeds()


def _yaml_tree(text: str) -> object:
    from robocal.formats._yaml import load_yaml

    return json.loads(json.dumps(load_yaml(text, "seed")))


def _json(data: st.DataObject, seed: bytes) -> bytes:
    return json_mutation(data, seed.decode())


def _yaml(data: st.DataObject, seed: bytes) -> bytes:
    return yaml_mutation(data, seed.decode(), _yaml_tree(seed.decode()))


def _text(data: st.DataObject, seed: bytes) -> bytes:
    return text_mutation(data, seed)


@dataclass
class Command:
    """One CLI command: its input files (name → seed, mutator), its arguments and the files it may write."""

    args: list[str]
    inputs: dict[str, tuple[bytes, Callable[[st.DataObject, bytes], bytes]]]
    outputs: tuple[str, ...] = ()
    trees: dict[str, dict[str, bytes]] = field(default_factory=dict)


def _commands() -> dict[str, Command]:
    urdf = seeds.lite_urdf_text().encode()
    current = seeds.current_seed().encode()
    return {
        "convert": Command(
            ["convert", "cal.json", "out.yaml"],
            {"cal.json": (SEEDS["lite-json"], _json)},
            ("out.yaml", "out.yaml.bak"),
        ),
        "convert-urdf": Command(
            ["convert", "cal.yaml", "robot.urdf", "--to", "ros2-transmission", "--urdf", "lite.urdf"],
            {
                "cal.yaml": (SEEDS["lite-yaml-commented"], _yaml),
                "lite.urdf": (urdf, _text),
                "robot.urdf": (SEEDS["ros2-transmission"], _text),
            },
            ("robot.urdf", "robot.urdf.bak"),
        ),
        "check": Command(
            ["check", "--calibration", "cal.yaml", "--urdf", "lite.urdf"],
            {"cal.yaml": (SEEDS["robocal"], _yaml), "lite.urdf": (urdf, _text)},
        ),
        "lerobot-show": Command(
            ["lerobot", "show", "--robot", "so101_follower", "--port", "sim", "--file", "cal.json"],
            {"cal.json": (current, _json)},
        ),
        "lerobot-migrate": Command(
            ["lerobot", "migrate", "legacy.json", "--vendor", "feetech", "--out", "current.json"],
            {"legacy.json": (seeds.legacy_seed().encode(), _json)},
            ("current.json", "current.json.bak"),
        ),
        "lerobot-export-urdf": Command(
            [
                "lerobot",
                "export-urdf",
                "--robot",
                "so101_follower",
                "--file",
                "cal.json",
                "--out",
                "map.yaml",
            ],
            {"cal.json": (current, _json)},
            ("map.yaml", "map.yaml.bak"),
        ),
        "ur-correct-dh": Command(
            ["ur", "correct", "--dh", "dh.yaml", "--out", "k.yaml"],
            {"dh.yaml": (seeds.DH_YAML.encode(), _yaml)},
            ("k.yaml", "k.yaml.bak"),
        ),
        "ur-correct-deltas": Command(
            ["ur", "correct", "--model", "ur10e", "--deltas", "calibration.conf", "--out", "k.yaml"],
            {"calibration.conf": (seeds.CALIBRATION_CONF.encode(), _text)},
            ("k.yaml", "k.yaml.bak"),
        ),
        "sweep-replay": Command(
            ["sweep", "--urdf", "lite.urdf", "--source", "replay:sweep.csv", "--out", "offsets.yaml"],
            {"sweep.csv": (seeds.csv_seed(200).encode(), _text), "lite.urdf": (urdf, _text)},
            ("offsets.yaml", "offsets.yaml.bak"),
        ),
        "dataset-inspect": Command(
            ["dataset", "inspect", "ds", "--calibration", "cal.json", "--robot", "so101_follower"],
            {
                "cal.json": (current, _json),
                "ds/meta/info.json": (seeds.dataset_seed()["meta/info.json"], _json),
                "ds/meta/stats.json": (seeds.dataset_seed()["meta/stats.json"], _json),
                "ds/meta/episodes/chunk-000/file-000.parquet": (
                    seeds.dataset_seed()["meta/episodes/chunk-000/file-000.parquet"],
                    byte_mutation,
                ),
            },
            trees={"ds": seeds.dataset_seed()},
        ),
        "dataset-recalibrate": Command(
            list(seeds.DATASET_RECALIBRATE),
            {
                "new.json": (current, _json),
                "ds/meta/info.json": (seeds.dataset_seed()["meta/info.json"], _json),
                "ds/data/chunk-000/file-000.parquet": (
                    seeds.dataset_seed()["data/chunk-000/file-000.parquet"],
                    byte_mutation,
                ),
            },
            trees={"ds": seeds.dataset_seed(), ".": {"cal.json": current}},
        ),
    }


COMMANDS = _commands()
ENV_KEYS = (
    "HOME",
    "HF_HOME",
    "HF_LEROBOT_HOME",
    "HF_LEROBOT_CALIBRATION",
    "XDG_CACHE_HOME",
    "XDG_STATE_HOME",
)


def _run(root: Path, home: Path, args: list[str]) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "120", "PYTHONHASHSEED": "0"}
    env.update(dict.fromkeys(ENV_KEYS, str(home)))
    env.pop("HYPOTHESIS_PROFILE", None)
    return subprocess.run(
        [sys.executable, "-m", "robocal", *args],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        errors="replace",
        timeout=90,
        stdin=subprocess.DEVNULL,
        check=False,
    )


def _pending(stderr: str) -> str | None:
    """A traceback of a crash another branch fixes (see fuzzlib.PENDING)."""
    for kind, text, item in PENDING:
        if f"{kind.__name__}:" in stderr and text in stderr:
            return item
    return None


def _check(
    name: str,
    cmd: Command,
    root: Path,
    before: dict[str, tuple[int, int, str]],
    proc: subprocess.CompletedProcess[str],
) -> None:
    err = proc.stderr
    crash = re.search(r"the traceback is in (\S+\.log)", err)  # the CLI's internal-error handler (exit 70)
    log = Path(crash.group(1)).read_text(errors="replace") if crash and Path(crash.group(1)).is_file() else ""
    where = f"robocal {' '.join(cmd.args)} (exit {proc.returncode})\nstderr:\n{err[-3000:]}\n{log[-4000:]}"
    if ("Traceback (most recent call last)" in err or log) and _pending(err + log):
        return
    assert "Traceback" not in err, where
    assert proc.returncode in (0, 1, 2, 3), where
    error_lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    after = snapshot(root)
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    if proc.returncode in (2, 3):
        assert len(error_lines) == 1, where
        assert changed == [], f"{where}\nfiles changed on failure: {changed}"
    else:
        assert error_lines == [], where
        allowed = [c for c in changed if c in cmd.outputs or c.split("/")[0] == "out"]
        assert changed == allowed, f"{where}\nfiles other than the outputs changed: {changed}"


# One command in the fast tier (`-m "not slow"`); every command in the full suite.
@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=() if n == "lerobot-show" else pytest.mark.slow) for n in COMMANDS]
)
@fuzz_settings(1)
@given(data=st.data())
def test_cli_on_mutated_inputs_exits_cleanly(name: str, data: st.DataObject) -> None:
    cmd = COMMANDS[name]
    with tempfile.TemporaryDirectory(prefix="robocal-fuzz-cli-") as tmp:
        base = Path(tmp)
        home = base / "home"
        home.mkdir()
        runs = []
        for k in range(2):  # two mutated inputs per example, run side by side
            root = base / f"run{k}"
            for sub, files in cmd.trees.items():
                seeds.write_tree(root / sub, files)
            root.mkdir(exist_ok=True)
            target = data.draw(st.sampled_from(sorted(cmd.inputs)), label=f"run {k}: file")
            for rel, (seed, mutate) in cmd.inputs.items():
                p = root / rel
                p.parent.mkdir(parents=True, exist_ok=True)
                p.write_bytes(mutate(data, seed) if rel == target else seed)
            runs.append(root)
        befores = [snapshot(r) for r in runs]
        home_before = snapshot(home)
        with ThreadPoolExecutor(max_workers=2) as pool:
            procs = list(pool.map(lambda r: _run(r, home, cmd.args), runs))
        for root, before, proc in zip(runs, befores, procs, strict=True):
            _check(name, cmd, root, before, proc)
        assert snapshot(home) == home_before, "the command wrote into the (redirected) home folder"


@pytest.mark.slow
@pytest.mark.timeout(600)  # 12 commands, two processes at a time: 130 s at load 14 (over the default 120 s)
def test_cli_seed_inputs_succeed() -> None:
    """The unmutated inputs are valid: every command finishes (0, or 1 with warnings) and writes its output."""
    with tempfile.TemporaryDirectory(prefix="robocal-fuzz-cli-") as tmp:
        home = Path(tmp) / "home"
        home.mkdir()
        roots = {}
        for name, cmd in COMMANDS.items():
            root = roots[name] = Path(tmp) / name
            for sub, files in cmd.trees.items():
                seeds.write_tree(root / sub, files)
            root.mkdir(exist_ok=True)
            for rel, (seed, _m) in cmd.inputs.items():
                (root / rel).parent.mkdir(parents=True, exist_ok=True)
                (root / rel).write_bytes(seed)
        with ThreadPoolExecutor(max_workers=2) as pool:
            procs = dict(
                zip(
                    COMMANDS,
                    pool.map(lambda n: _run(roots[n], home, COMMANDS[n].args), COMMANDS),
                    strict=True,
                )
            )
        for name, proc in procs.items():
            assert proc.returncode in (0, 1), f"{name}: {proc.stderr}"
            assert not [ln for ln in proc.stderr.splitlines() if ln.startswith("error:")], name
            for out in COMMANDS[name].outputs:
                if not out.endswith(".bak") and out != "robot.urdf":
                    assert (roots[name] / out).is_file(), f"{name}: {out}"
        assert (roots["dataset-recalibrate"] / "out" / "meta" / "info.json").is_file()
