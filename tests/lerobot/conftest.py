"""Shared values of the LeRobot tests."""

from __future__ import annotations

from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH

# A previous calibration in the simulated arms' EEPROM, different from what a sweep finds: rollbacks must restore it.
PREVIOUS = {
    "so101_follower": {
        n: {"Homing_Offset": -100 - i, "Min_Position_Limit": 500 + i, "Max_Position_Limit": 3500 - i}
        for i, n in enumerate(DEFAULT_TRUTH["so101_follower"])
    },
    "koch_leader": {
        n: {
            "Homing_Offset": -3000 + i,
            "Min_Position_Limit": 100 + i,
            "Max_Position_Limit": 3900 - i,
            "Drive_Mode": 0,
        }
        for i, n in enumerate(DEFAULT_TRUTH["koch_leader"])
    },
}
