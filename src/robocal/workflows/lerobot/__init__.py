"""LeRobot arm jobs, one module per job; everything is re-exported here.

* :mod:`.arms` — the arms (robot profiles), opening their bus (``sim`` starts a simulated arm), norm modes;
* :mod:`.files` — where an arm's calibration file is;
* :mod:`.calibrate` — LeRobot's current calibration and the legacy (2024) one, with robocal's fixes;
* :mod:`.auto` — ``calibrate --auto``: the joints find their own stops (:mod:`.auto_sim`: the arm it drives, real
  or simulated with physics); not re-exported here;
* :mod:`.eeprom` — EEPROM snapshot, all-or-nothing restore with rollback, check against a file;
* :mod:`.configure` — LeRobot's ``configure()`` presets;
* :mod:`.show` — live normalised positions;
* :mod:`.migrate` — legacy calibration → current scheme;
* :mod:`.joint_map` — the exact URDF joint map of the DEGREES joints.
"""

from __future__ import annotations

from .arms import norm_modes, open_arm, open_bus, open_sim_bus, robot_names, robot_spec, sim_operator
from .calibrate import (
    CalibrateRequest,
    CalibrationNotSavedError,
    CalibrationResult,
    Operator,
    RangeView,
    calibrate,
    calibrate_legacy,
)
from .configure import clear_phase_bit4, configure
from .eeprom import EEPROM_FIELDS, Difference, RollbackReport, check, read_eeprom, restore
from .files import (
    calibration_file,
    calibration_json,
    check_calibration_writable,
    range_warnings,
    read_calibration_file,
)
from .guard import LeftOver, find_left_over, restore_left_over
from .joint_map import check_joint_map_out, export_joint_map, write_joint_map
from .migrate import legacy_to_current, migrate_file
from .show import read_positions, require_motors

__all__ = [
    "EEPROM_FIELDS",
    "CalibrateRequest",
    "CalibrationNotSavedError",
    "CalibrationResult",
    "Difference",
    "LeftOver",
    "Operator",
    "RangeView",
    "RollbackReport",
    "calibrate",
    "calibrate_legacy",
    "calibration_file",
    "calibration_json",
    "check",
    "check_calibration_writable",
    "check_joint_map_out",
    "clear_phase_bit4",
    "configure",
    "export_joint_map",
    "find_left_over",
    "legacy_to_current",
    "migrate_file",
    "norm_modes",
    "open_arm",
    "open_bus",
    "open_sim_bus",
    "range_warnings",
    "read_calibration_file",
    "read_eeprom",
    "read_positions",
    "require_motors",
    "restore",
    "restore_left_over",
    "robot_names",
    "robot_spec",
    "sim_operator",
    "write_joint_map",
]
