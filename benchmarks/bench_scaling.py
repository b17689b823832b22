"""Scaling in the joint count: every file operation must take time linear in N (slope of log t / log N ≈ 1).

For each operation the joint count grows 10³, 3·10³, 10⁴ … 10⁶; the slope is the least-squares fit of
log(time) against log(N) over the sizes that took at least 20 ms (below that, fixed costs such as imports and
file opens dominate). A quadratic operation shows a slope near 2. An operation stops growing when its next
size is predicted to take longer than the per-size budget; the line then says where it stopped. The YAML
formats robocal writes are read and written by the fast path of ``formats/_yaml_fast.py`` (ruamel.yaml's
round-trip parser took about 0.5-1 ms per joint); on a loaded 2-core machine the URDF operations need about
70 s at 10⁶ joints, so ``ROBOCAL_BENCH_BUDGET_S=300`` lets every operation reach 10⁶.

Time is this process's CPU time (``time.process_time``: user + system), not wall-clock time, so other work on a
shared machine does not distort the slope (wall time on a loaded 2-core box varied by 5× between runs).

Environment: ``ROBOCAL_BENCH_MAX_JOINTS`` (default 1000000), ``ROBOCAL_BENCH_BUDGET_S`` (default 20, seconds
per size and operation).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from robocal.core import RobotCalibration
from robocal.errors import CalibError
from robocal.formats import detect_format, read_calibration, write_calibration
from robocal.formats.urdf import read_urdf
from robocal.workflows.files.job import check_calibration, convert_file

SIZES = (1_000, 3_000, 10_000, 30_000, 100_000, 300_000, 1_000_000)
MIN_FIT_S = 0.02


def _urdf_text(n: int, transmissions: bool = False) -> str:
    parts = ['<?xml version="1.0"?>\n<robot name="scaling">\n  <link name="l0"/>\n']
    for i in range(n):
        parts.append(
            f'<link name="l{i + 1}"/><joint name="j{i}" type="revolute"><parent link="l{i}"/>'
            f'<child link="l{i + 1}"/><limit lower="-3" upper="3"/></joint>\n'
        )
    parts.append('  <ros2_control name="system" type="system">\n')
    for i in range(n):
        parts.append(
            f'<joint name="j{i}"><param name="can_id">{i + 1}</param>'
            f'<param name="direction">{-1 if i % 3 == 0 else 1}</param></joint>\n'
        )
    if transmissions:
        for i in range(n):
            parts.append(
                f'    <transmission name="j{i}_transmission">\n'
                "      <plugin>transmission_interface/SimpleTransmission</plugin>\n"
                f'      <actuator name="j{i}_actuator" role="actuator1"/>\n'
                f'      <joint name="j{i}" role="joint1">\n'
                "        <mechanical_reduction>1.0</mechanical_reduction>\n"
                "        <offset>0.0</offset>\n      </joint>\n    </transmission>\n"
            )
    parts.append("  </ros2_control>\n</robot>\n")
    return "".join(parts)


def _calibration(n: int) -> RobotCalibration:
    names = [f"j{i}" for i in range(n)]
    direction = np.where(np.arange(n) % 3 == 0, -1.0, 1.0)
    return RobotCalibration(names, direction, np.linspace(-1.0, 1.0, n))


class _Case:
    """Files of one size in a temporary folder, made once and shared by the operations."""

    def __init__(self, root: Path, n: int) -> None:
        self.n = n
        self.dir = root / f"n{n}"
        self.dir.mkdir()
        self.cal = _calibration(n)
        ids = {f"j{i}": i + 1 for i in range(n)}
        self.urdf = self.dir / "robot.urdf"
        self.urdf.write_text(_urdf_text(n))
        self.urdf_tr = self.dir / "robot_tr.urdf"
        self.urdf_tr.write_text(_urdf_text(n, transmissions=True))
        self.json = self.dir / "calibration.json"
        self.json.write_text(
            json.dumps(
                {
                    name: {"id": ids[name], "direction": int(d), "homing_offset": float(h)}
                    for name, d, h in zip(
                        self.cal.joint_names, self.cal.direction, self.cal.homing_offset, strict=True
                    )
                }
            )
        )
        self._model: object = None

    def model(self):  # type: ignore[no-untyped-def]
        if self._model is None:
            self._model = read_urdf(self.urdf)
        return self._model

    def out(self, name: str) -> Path:
        p = self.dir / name
        for q in (p, p.with_name(p.name + ".bak")):
            q.unlink(missing_ok=True)
        return p


def _ops() -> dict[str, Callable[[_Case], Callable[[], object]]]:
    """Operation name → (case → the timed call); the set-up outside the timed call is not measured."""

    def make_yaml(fmt: str) -> Callable[[_Case], Callable[[], object]]:
        def prep(c: _Case) -> Callable[[], object]:
            path = c.dir / f"{fmt}.yaml"
            if not path.exists():
                write_calibration(path, c.cal, fmt, ids={n: i + 1 for i, n in enumerate(c.cal.joint_names)})
            return lambda: read_calibration(path)

        return prep

    def check_cli(c: _Case) -> Callable[[], object]:
        from robocal.cli._common import print_plain_table

        model = c.model()
        cf = read_calibration(c.json)

        def run() -> object:
            report = check_calibration(cf, model)
            rows = [
                (j.name, str(j.motor_id), f"{j.direction:+d}", f"{j.homing_offset:.6f}", "ok")
                for j in report.joints
            ]
            with contextlib.redirect_stdout(io.StringIO()):
                print_plain_table(("joint", "id", "direction", "homing_offset", "status"), rows)
            return report

        return run

    def transmission_into(c: _Case) -> Callable[[], object]:
        model = c.model()
        cal = c.cal

        def run() -> object:
            dst = c.out("into.urdf")
            dst.write_bytes(c.urdf.read_bytes())
            return write_calibration(dst, cal, "ros2-transmission", urdf=model)

        return run

    def read_berkeley(c: _Case) -> Callable[[], object]:
        path = c.out("rb.yaml")
        write_calibration(path, c.cal, "berkeley-offsets", joint_order=c.cal.joint_names)
        model = c.model()
        return lambda: read_calibration(path, "berkeley-offsets", urdf=model)

    def transmission_update(c: _Case) -> Callable[[], object]:
        def run() -> object:
            dst = c.out("update.urdf")
            dst.write_bytes(c.urdf_tr.read_bytes())
            return write_calibration(dst, c.cal, "ros2-transmission")

        return run

    def set_origins(c: _Case) -> Callable[[], object]:
        from robocal.formats.urdf import UrdfDocument

        doc = UrdfDocument.load(c.urdf)
        names = c.cal.joint_names

        def run() -> object:
            for i, name in enumerate(names):
                doc.set_origin(name, (0.001 * i, 0.0, 0.1), (0.0, 0.0, 0.5))
            return doc

        return run

    return {
        "URDF set_origin on every joint": set_origins,
        "RobotCalibration + select": lambda c: (
            lambda: RobotCalibration(c.cal.joint_names, c.cal.direction, c.cal.homing_offset).select(
                c.cal.joint_names[::-1]
            )
        ),
        "detect lite-json": lambda c: lambda: detect_format(c.json),
        "read lite-json": lambda c: lambda: read_calibration(c.json),
        "write lite-json": lambda c: (
            lambda model: lambda: write_calibration(c.out("w.json"), c.cal, "lite-json", urdf=model)
        )(c.model()),
        "convert json->json (CLI path)": lambda c: lambda: convert_file(c.json, c.out("conv.json")),
        "write berkeley-offsets": lambda c: (
            lambda: write_calibration(
                c.out("b.yaml"), c.cal, "berkeley-offsets", joint_order=c.cal.joint_names
            )
        ),
        "read berkeley-offsets": read_berkeley,
        "read URDF": lambda c: lambda: read_urdf(c.urdf),
        "check (report + table)": check_cli,
        "ros2-transmission into URDF": transmission_into,
        "ros2-transmission update": transmission_update,
        "read ros2-transmission": lambda c: lambda: read_calibration(c.urdf_tr),
        "write robocal yaml": lambda c: lambda: write_calibration(c.out("w.rc.yaml"), c.cal, "robocal"),
        "read robocal yaml": make_yaml("robocal"),
        "write lite-yaml": lambda c: (
            lambda model: lambda: write_calibration(c.out("w.lite.yaml"), c.cal, "lite-yaml", urdf=model)
        )(c.model()),
        "read lite-yaml": make_yaml("lite-yaml"),
    }


def _slope(points: list[tuple[int, float]]) -> float | None:
    fit = [(n, t) for n, t in points if t >= MIN_FIT_S]
    if len(fit) < 2:
        fit = points[-2:] if len(points) >= 2 else []
    if len(fit) < 2:
        return None
    x = np.log([n for n, _ in fit])
    y = np.log([t for _, t in fit])
    return float(np.polyfit(x, y, 1)[0])


def main() -> None:
    max_n = int(os.environ.get("ROBOCAL_BENCH_MAX_JOINTS", "1000000"))
    budget = float(os.environ.get("ROBOCAL_BENCH_BUDGET_S", "20"))
    sizes = [n for n in SIZES if n <= max_n]
    ops = _ops()
    results: dict[str, list[tuple[int, float]]] = {name: [] for name in ops}
    stopped: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="robocal-scaling-") as tmp:
        for n in sizes:
            active = [name for name in ops if name not in stopped]
            if not active:
                break
            case = _Case(Path(tmp), n)
            for name in active:
                pts = results[name]
                if pts:  # predict this size from the last one assuming linear time; skip if over budget
                    last_n, last_t = pts[-1]
                    predicted = last_t * n / last_n
                    if predicted > budget:
                        stopped[name] = f"stopped before N={n:,} (predicted {predicted:.0f} s > {budget:g} s)"
                        continue
                repeat = 3 if (pts and pts[-1][1] < 0.2) or not pts else 1
                best = math.inf
                try:
                    call = ops[name](case)
                    for _ in range(repeat):
                        t0 = time.process_time()
                        call()
                        best = min(best, time.process_time() - t0)
                except CalibError as exc:  # e.g. robocal's 8 MiB calibration-file and 16 MiB URDF limits
                    stopped[name] = f"stopped at N={n:,}: {exc}"
                    continue
                pts.append((n, best))
            shutil.rmtree(case.dir)
    print(
        f"CPU time of this process per size (s); slope of log(time)/log(N), linear = 1, quadratic = 2; "
        f"budget {budget:g} s/size"
    )
    header = f"  {'operation':<32}" + "".join(f"{n:>10,}" for n in sizes) + "   slope"
    print(header)
    for name, pts in results.items():
        by_n = dict(pts)
        cells = "".join(f"{by_n[n]:>10.3f}" if n in by_n else f"{'-':>10}" for n in sizes)
        slope = _slope(pts)
        s = f"{slope:7.2f}" if slope is not None else "      -"
        per = f"   {pts[-1][1] / pts[-1][0] * 1e6:.1f} us/joint" if pts else ""
        print(f"  {name:<32}{cells}{s}{per}")
        if name in stopped:
            print(f"  {'':<32}{stopped[name]}")


if __name__ == "__main__":
    main()
