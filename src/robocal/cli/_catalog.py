"""Names and defaults the help pages show, without importing the jobs behind them.

``robocal --help`` and every ``robocal … --help`` build the whole command tree, so whatever a command module
imports at its top is paid by every start of the program (tests start it hundreds of times). The command modules
therefore import their jobs inside the command functions, and take the few values their options show from here:
plain copies of constants whose home is a heavier module (numpy, the file formats, the device sources), each
pinned to its home by ``tests/foundation/test_cli_lazy.py``, and the built-in robot names read from the data
folder as :func:`robocal.formats.profiles.builtin_profile_names` does.
"""

from __future__ import annotations

from importlib import resources

__all__ = [
    "DEFAULT_DIRECTION_STEP_S",
    "DEFAULT_TOPIC",
    "FORMAT_NAMES",
    "UR_MODEL_NAMES",
    "robot_profile_names",
]

DEFAULT_TOPIC = "/lite/joint_states"
"""JointState topic of a rosbag2 replay (home: :data:`robocal.backends.replay.DEFAULT_TOPIC`)."""
DEFAULT_DIRECTION_STEP_S = 5.0
"""``sweep --direction-time`` (home: :data:`robocal.workflows.sweep.session.DEFAULT_DIRECTION_STEP_S`)."""
FORMAT_NAMES: tuple[str, ...] = (
    "lite-json",
    "lite-yaml",
    "berkeley-offsets",
    "ros2-transmission",
    "lerobot-legacy",
    "robocal",
    "openarm-lerobot",
    "openarm-ros2",
)
"""The calibration formats, in the registry's order (home: :data:`robocal.formats.calibration.FORMATS`)."""
UR_MODEL_NAMES: tuple[str, ...] = (
    "ur3",
    "ur5",
    "ur10",
    "ur3e",
    "ur5e",
    "ur10e",
    "ur16e",
    "ur20",
    "ur30",
)
"""The UR models with nominal DH parameters, in order (home: :data:`robocal.core.ur.UR_MODELS`)."""


def robot_profile_names() -> tuple[str, ...]:
    """Names of the robot profiles shipped with robocal, sorted (the ``.yaml`` files of ``robocal/data/profiles``)."""
    folder = resources.files("robocal").joinpath("data").joinpath("profiles")
    return tuple(sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml")))
