"""LeRobot 0.6.1's own buses and robot classes against ``robocal sim``, compared with robocal's commands.

Each LeRobot step runs in the interop environment (``make_env.py``) through ``harness/lerobot_harness.py``;
its ``input()`` prompts are answered as a person would: the operator moves the simulated joints through the
simulator's control socket, then ENTER is typed.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.backends.dynamixel import DYNAMIXEL_MODELS
from robocal.backends.sim.control import SimControl
from robocal.lerobot import normalize, read_calibration
from robocal.workflows.lerobot import norm_modes, robot_spec

from ..test_sim_arm_cli import calibrate_with_operator
from .conftest import Interactive, SimProcess, harness_argv, harness_env, result_of, robocal, run_harness

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

DEVICE_DIR = {"so101_follower": "so_follower", "koch_follower": "koch_follower"}
EEPROM = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode")


def lerobot_calibrate(python: Path, cwd: Path, robot: str, port: str, control: str, cal_dir: Path) -> Path:
    """LeRobot's ``robot.calibrate()`` (as ``lerobot-calibrate`` runs it), the operator answering its prompts."""
    run = Interactive(
        harness_argv(python, "calibrate", robot=robot, port=port, id="x", cal_dir=str(cal_dir)),
        cwd,
        harness_env(),
    )
    code, out = run.calibrate_as_operator(
        control, "to the middle of its range of motion and press ENTER", "Recording positions. Press ENTER to stop"
    )
    assert code == 0, out[-3000:]
    return Path(result_of(out)["path"])


def eeprom(control: str) -> dict[str, dict[str, int]]:
    with SimControl(control) as ctl:
        return {n: {k: j[k] for k in EEPROM if k in j} for n, j in ctl.state().items()}


@pytest.fixture(scope="module", params=["so101_follower", "koch_follower"])
def calibrated(request, lerobot_python, tmp_path_factory: pytest.TempPathFactory):
    """Two identically seeded simulators: one calibrated by LeRobot, one by robocal.

    Built once per robot for the tests below (two calibrations take a while); a test that changes a simulator
    puts it back before it ends.
    """
    robot = request.param
    tmp_path = tmp_path_factory.mktemp(f"calibrated-{robot}")
    started: list[SimProcess] = []
    try:
        sim_le = SimProcess([robot, "--seed", "5"], tmp_path)
        started.append(sim_le)
        sim_rc = SimProcess([robot, "--seed", "5"], tmp_path)
        started.append(sim_rc)
        le_file = lerobot_calibrate(
            lerobot_python, tmp_path, robot, sim_le.info["port"], sim_le.info["control"], tmp_path / "le"
        )
        calibrate_with_operator(tmp_path, robot, sim_rc.info["port"], sim_rc.info["control"], "x")
        rc_file = tmp_path / "cal" / "robots" / DEVICE_DIR[robot] / "x.json"
        yield robot, sim_le, sim_rc, le_file, rc_file
    finally:
        for sim in started:
            sim.stop()


@pytest.mark.slow
def test_calibrate_leaves_identical_json_bytes_and_eeprom(calibrated) -> None:
    robot, sim_le, sim_rc, le_file, rc_file = calibrated
    assert le_file.read_bytes() == rc_file.read_bytes()
    data = json.loads(le_file.read_text())
    assert list(data) == list(robot_spec(robot).motor_names)
    assert data["wrist_roll"]["range_min"] == 0 and data["wrist_roll"]["range_max"] == 4095
    le, rc = eeprom(sim_le.info["control"]), eeprom(sim_rc.info["control"])
    assert le == rc
    assert {n: v["Homing_Offset"] for n, v in le.items()} == {n: c["homing_offset"] for n, c in data.items()}


@pytest.mark.slow
def test_draccus_loads_robocal_files_and_connect_finds_them_calibrated(
    calibrated, lerobot_python, tmp_path: Path
) -> None:
    robot, _sim_le, sim_rc, _le_file, rc_file = calibrated
    cal_dir = rc_file.parent
    loaded = run_harness(
        lerobot_python, "load", tmp_path, robot=robot, port=sim_rc.info["port"], id="x", cal_dir=str(cal_dir)
    )
    assert loaded["calibration"] == json.loads(rc_file.read_text())
    connected = run_harness(
        lerobot_python,
        "connect",
        tmp_path,
        robot=robot,
        port=sim_rc.info["port"],
        id="x",
        cal_dir=str(cal_dir),
    )
    assert connected["is_calibrated"] is True


@pytest.mark.slow
def test_robocal_check_on_lerobot_calibrated_servos_then_names_the_changed_limit(
    calibrated, lerobot_python, tmp_path: Path
) -> None:
    robot, sim_le, _sim_rc, le_file, _rc_file = calibrated
    port = sim_le.info["port"]
    ok = robocal("lerobot", "check", "--robot", robot, "--port", port, "--file", str(le_file), cwd=tmp_path)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert f"EEPROM matches {le_file}" in ok.stdout
    limit = json.loads(le_file.read_text())["elbow_flex"]["range_min"]

    def write_limit(value: int) -> None:
        run_harness(
            lerobot_python,
            "write_limit",
            tmp_path,
            robot=robot,
            port=port,
            id="x",
            cal_dir=str(le_file.parent),
            motor="elbow_flex",
            register="Min_Position_Limit",
            value=value,
        )

    write_limit(limit + 7)
    try:
        bad = robocal(
            "lerobot", "check", "--robot", robot, "--port", port, "--file", str(le_file), cwd=tmp_path
        )
    finally:
        write_limit(limit)  # the simulator is shared with the other tests (see ``calibrated``)
    assert bad.returncode == 1
    assert bad.stdout.strip().splitlines() == [
        f"differs: motor 'elbow_flex' (id 3): range_min is {limit + 7} on the motor, {limit} in the file"
    ]


@pytest.mark.slow
def test_normalised_reads_agree_bit_for_bit(calibrated, lerobot_python, tmp_path: Path) -> None:
    robot, _sim_le, sim_rc, _le_file, rc_file = calibrated
    spec = robot_spec(robot)
    grid = list(range(-200, 4296))  # every tick of a turn, and beyond both ends
    got = run_harness(
        lerobot_python,
        "normalize",
        tmp_path,
        robot=robot,
        port=sim_rc.info["port"],
        id="x",
        cal_dir=str(rc_file.parent),
        grid=grid,
    )
    cals = read_calibration(rc_file)
    modes = norm_modes(spec)
    feetech = spec.vendor == "feetech"
    for k, name in enumerate(spec.motor_names):
        mine = normalize([float(v) for v in grid], cals[name], modes[k], apply_drive_mode=feetech)
        assert [float(x).hex() for x in mine] == got["grid"][name], name
    raw = [got["raw"][n] for n in spec.motor_names]
    live = normalize(raw, [cals[n] for n in spec.motor_names], list(modes), apply_drive_mode=feetech)
    assert [float(x).hex() for x in live] == [got["norm"][n] for n in spec.motor_names]


@pytest.mark.slow
def test_broadcast_ping_and_scan_port(lerobot_python, sim_process, tmp_path: Path) -> None:
    so = sim_process(["so101_follower"])
    got = run_harness(
        lerobot_python, "broadcast_ping", tmp_path, vendor="feetech", port=so.info["port"], scan=True
    )
    assert got["found"] == {str(i): 777 for i in range(1, 7)}
    assert got["scan"] == {"1000000": [1, 2, 3, 4, 5, 6]}  # the servos answer at their own speed only
    koch = sim_process(["koch_follower"])
    got = run_harness(lerobot_python, "broadcast_ping", tmp_path, vendor="dynamixel", port=koch.info["port"])
    # Koch follower: xl430-w250 (model number 1060) at ids 1-2, xl330-m288 (1200) at ids 3-6
    assert got["found"] == {"1": 1060, "2": 1060, "3": 1200, "4": 1200, "5": 1200, "6": 1200}
    assert [DYNAMIXEL_MODELS[m.model][0] for m in robot_spec("koch_follower").motors] == [1060, 1060] + [1200] * 4


@pytest.mark.slow
def test_setup_motors_on_factory_servos_then_robocal_calibrates(
    lerobot_python, sim_process, tmp_path: Path
) -> None:
    sim = sim_process(["so101_follower", "--factory"])
    run = Interactive(
        harness_argv(
            lerobot_python,
            "setup_motors",
            robot="so101_follower",
            port=sim.info["port"],
            id="x",
            cal_dir=str(tmp_path / "le"),
        ),
        tmp_path,
        harness_env(),
    )
    order = []
    with SimControl(sim.info["control"]) as ctl:
        at = 0
        for motor in reversed(robot_spec("so101_follower").motor_names):
            at = run.expect(
                f"Connect the controller board to the '{motor}' motor only and press enter.", after=at
            )
            assert ctl.attach([motor]) == [motor]
            order.append(motor)
            run.send()
        code, out = run.finish()
        assert code == 0, out[-3000:]
        assert result_of(out)["ids"] == {n: i for i, n in enumerate(robot_spec("so101_follower").motor_names, 1)}
        ctl.attach("all")
        state = ctl.state()
    assert order[0] == "gripper"
    assert {n: (j["id"], j["baudrate"]) for n, j in state.items()} == {
        n: (i, 1_000_000) for i, n in enumerate(robot_spec("so101_follower").motor_names, 1)
    }
    got = run_harness(lerobot_python, "broadcast_ping", tmp_path, vendor="feetech", port=sim.info["port"])
    assert got["found"] == {str(i): 777 for i in range(1, 7)}
    calibrate_with_operator(tmp_path, "so101_follower", sim.info["port"], sim.info["control"], "after-setup")
    after = json.loads((tmp_path / "cal/robots/so_follower/after-setup.json").read_text())
    assert [c["id"] for c in after.values()] == [1, 2, 3, 4, 5, 6]


HAND_EDITS = {
    "string": ("homing_offset", "12", 12, "field homing_offset is '12'; expected an integer"),
    "drive_mode_2": ("drive_mode", 2, 2, "field drive_mode is 2; expected 0 or 1"),
    "min_not_below_max": ("range_min", 3000, 3000, "field range_min 3000 must be less than range_max 3000"),
    "duplicate_id": ("id", 2, 2, "field id 2 is also used by 'shoulder_lift'"),
}


# The fast tier (`-m "not slow"`) runs one hand edit: LeRobot's environment starts in each.
@pytest.mark.parametrize(
    "case", [pytest.param(c, marks=() if c == "duplicate_id" else pytest.mark.slow) for c in HAND_EDITS]
)
def test_hand_edited_files_lerobot_loads_and_robocal_refuses(
    case: str, lerobot_python, tmp_path: Path
) -> None:
    """The differences docs/try_without_a_robot.md lists: LeRobot's draccus loader takes these files."""
    field, written, lerobot_value, message = HAND_EDITS[case]
    names = robot_spec("so101_follower").motor_names
    data = {
        n: {"id": i, "drive_mode": 0, "homing_offset": 10, "range_min": 1000, "range_max": 3000}
        for i, n in enumerate(names, 1)
    }
    data["elbow_flex"][field] = written
    (tmp_path / "le").mkdir()
    path = tmp_path / "le" / "x.json"
    path.write_text(json.dumps(data, indent=4))
    loaded = run_harness(
        lerobot_python,
        "load",
        tmp_path,
        robot="so101_follower",
        port="/dev/null",
        id="x",
        cal_dir=str(tmp_path / "le"),
    )
    assert loaded["calibration"]["elbow_flex"][field] == lerobot_value
    r = robocal(
        "lerobot", "show", "--robot", "so101_follower", "--port", "sim", "--file", str(path), cwd=tmp_path
    )
    assert r.returncode == 2
    assert r.stderr.strip() == f"error: {path}: motor 'elbow_flex': {message}"
