"""Dynamixel X control table, models and signed registers as data (a vendor's registers and quirks, no code)."""

from __future__ import annotations

from .._servo_common import ServoModel

__all__ = ["BUS_WATCHDOG_UNIT_S", "DYNAMIXEL_MODELS", "SIGNED_BYTES", "X_TABLE"]

BUS_WATCHDOG_UNIT_S = 0.02
"""One unit of ``Bus_Watchdog`` (98): 20 ms; 1..127 arm it, 0 disarms and clears its error, −1 is the error."""

X_TABLE: dict[str, tuple[int, int]] = {
    "Model_Number": (0, 2),
    "Model_Information": (2, 4),
    "Firmware_Version": (6, 1),
    "ID": (7, 1),
    "Baud_Rate": (8, 1),
    "Return_Delay_Time": (9, 1),
    "Drive_Mode": (10, 1),
    "Operating_Mode": (11, 1),
    "Secondary_ID": (12, 1),
    "Protocol_Type": (13, 1),
    "Homing_Offset": (20, 4),
    "Moving_Threshold": (24, 4),
    "Temperature_Limit": (31, 1),
    "Max_Voltage_Limit": (32, 2),
    "Min_Voltage_Limit": (34, 2),
    "PWM_Limit": (36, 2),
    "Current_Limit": (38, 2),
    "Acceleration_Limit": (40, 4),
    "Velocity_Limit": (44, 4),
    "Max_Position_Limit": (48, 4),
    "Min_Position_Limit": (52, 4),
    "Shutdown": (63, 1),
    "Torque_Enable": (64, 1),
    "LED": (65, 1),
    "Status_Return_Level": (68, 1),
    "Hardware_Error_Status": (70, 1),
    "Velocity_I_Gain": (76, 2),
    "Velocity_P_Gain": (78, 2),
    "Position_D_Gain": (80, 2),
    "Position_I_Gain": (82, 2),
    "Position_P_Gain": (84, 2),
    "Bus_Watchdog": (98, 1),
    "Goal_PWM": (100, 2),
    "Goal_Current": (102, 2),
    "Goal_Velocity": (104, 4),
    "Profile_Acceleration": (108, 4),
    "Profile_Velocity": (112, 4),
    "Goal_Position": (116, 4),
    "Moving": (122, 1),
    "Present_PWM": (124, 2),
    "Present_Current": (126, 2),
    "Present_Velocity": (128, 4),
    "Present_Position": (132, 4),
    "Present_Input_Voltage": (144, 2),
    "Present_Temperature": (146, 1),
}
"""Dynamixel X series control table: name → (address, bytes)."""

DYNAMIXEL_MODELS: dict[str, ServoModel] = {
    "xl330-m077": ServoModel(1190, 4096, 2, X_TABLE),
    "xl330-m288": ServoModel(1200, 4096, 2, X_TABLE),
    "xl430-w250": ServoModel(1060, 4096, 2, X_TABLE),
    "xm430-w350": ServoModel(1020, 4096, 2, X_TABLE),
    "xm540-w270": ServoModel(1120, 4096, 2, X_TABLE),
    "xc430-w150": ServoModel(1070, 4096, 2, X_TABLE),
}
"""Model → its number, resolution, protocol (2.0) and control table (all X series)."""

SIGNED_BYTES: dict[str, int] = {
    "Homing_Offset": 4,
    "Bus_Watchdog": 1,
    "Goal_PWM": 2,
    "Goal_Current": 2,
    "Goal_Velocity": 4,
    "Goal_Position": 4,
    "Present_Position": 4,
    "Present_PWM": 2,
    "Present_Current": 2,
    "Present_Velocity": 4,
}
"""Two's-complement registers and their width."""
