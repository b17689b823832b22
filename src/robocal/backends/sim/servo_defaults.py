"""What a simulated servo's control table holds when it leaves the factory (before robocal's power-on values).

Data only: model → ``{address: (bytes, value)}``, little-endian, every value non-negative. Applied by
:class:`~robocal.backends.sim.servo_model.SimServo` before the vendor's power-on values
(:data:`~robocal.backends.sim.servo_model.SIM_SERVO_KINDS`), so a register the simulator does not compute reads
what a new servo reads instead of 0. Sources and assumptions per value are in docs/sim.md ("Control tables as
shipped").

Feetech STS3215: Feetech's ST3215 memory-table spreadsheet (the English export published with the ``st3215``
crate, corroborated by a second transcription); addresses as in LeRobot's and rustypot's tables.
``Present_Voltage`` and ``Present_Temperature`` have no factory value: a 7.4 V supply and 25 °C are assumed.
The other STS-table models (sts3250, sm8512bl) are given the STS3215's values (assumed; their own sheets were not
read).

Dynamixel X: ROBOTIS e-Manual pages of the XL330-M288, XL330-M077, XL430-W250 and XM430-W350 (EEPROM factory
values, Status_Return_Level 2 and the model's gains). XM540-W270 and XC430-W150 are not listed (their pages were
not read): they keep the simulator's own values.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["FACTORY_DEFAULTS", "STS3215_DEFAULTS", "x_series_defaults"]

STS3215_DEFAULTS: dict[int, tuple[int, int]] = {
    0: (1, 3),  # Firmware_Major_Version
    7: (1, 0),  # Return_Delay_Time (2 µs)
    8: (1, 1),  # Response_Status_Level: every instruction answered
    9: (2, 0),  # Min_Position_Limit
    11: (2, 4095),  # Max_Position_Limit
    13: (1, 70),  # Max_Temperature_Limit, °C
    14: (1, 80),  # Max_Voltage_Limit, 0.1 V
    15: (1, 40),  # Min_Voltage_Limit, 0.1 V
    16: (2, 1000),  # Max_Torque_Limit, 0.1 % of stall (copied into Torque_Limit at power-on)
    18: (1, 12),  # Phase (bit 4 clear: single-turn feedback)
    19: (1, 44),  # Unloading_Condition: temperature, current, overload
    20: (1, 47),  # LED_Alarm_Condition: voltage, sensor, temperature, current, overload
    21: (1, 32),  # P_Coefficient
    22: (1, 32),  # D_Coefficient
    23: (1, 0),  # I_Coefficient
    24: (2, 16),  # Minimum_Startup_Force, 0.1 %
    26: (1, 1),  # CW_Dead_Zone, step
    27: (1, 1),  # CCW_Dead_Zone, step
    28: (2, 500),  # Protection_Current, 6.5 mA
    30: (1, 1),  # Angular_Resolution
    31: (2, 0),  # Homing_Offset
    33: (1, 0),  # Operating_Mode: position servo
    34: (1, 20),  # Protective_Torque, %
    35: (1, 200),  # Protection_Time, 10 ms
    36: (1, 80),  # Overload_Torque, %
    37: (1, 10),  # Velocity_closed_loop_P (not in robocal's table)
    38: (1, 200),  # Over_Current_Protection_Time, 10 ms (not in robocal's table)
    39: (1, 10),  # Velocity_closed_loop_I (not in robocal's table)
    48: (2, 1000),  # Torque_Limit = Max_Torque_Limit at power-on
    55: (1, 0),  # Lock (the simulator's power-on value 1 overrides it; see docs/sim.md)
    62: (1, 74),  # Present_Voltage, 0.1 V [assumed supply: 7.4 V]
    63: (1, 25),  # Present_Temperature, °C [assumed: room temperature]
}
"""STS3215 factory control table (address → (bytes, value)); unlisted addresses read 0."""



def x_series_defaults(
    temperature_c: int, voltage_0v1: tuple[int, int], current_limit: int | None, velocity_limit: int,
    shutdown: int, gains: tuple[int, int, int, int, int], *, xl330: bool = False, startup: bool = True,
    supply_0v1: int = 120,
) -> dict[int, tuple[int, int]]:
    """A Dynamixel X model's factory table (what its e-Manual page lists).

    Args:
        temperature_c: Temperature_Limit (31).
        voltage_0v1: (Max_Voltage_Limit (32), Min_Voltage_Limit (34)), 0.1 V.
        current_limit: Current_Limit (38) in the model's unit (None: the model has none).
        velocity_limit: Velocity_Limit (44), 0.229 rev/min.
        shutdown: Shutdown (63) bits.
        gains: Velocity I, Velocity P, Position D, Position I, Position P (76, 78, 80, 82, 84).
        xl330: The XL330 items (PWM_Slope (62) 140).
        startup: The model has Startup_Configuration (60).
        supply_0v1: Present_Input_Voltage (144) of an idle servo, 0.1 V (assumed: the model's recommended
            supply). Present_Temperature (146) reads 25 °C (assumed: room temperature).
    """
    table: dict[int, tuple[int, int]] = {
        9: (1, 250),  # Return_Delay_Time, 2 µs
        10: (1, 0),  # Drive_Mode
        11: (1, 3),  # Operating_Mode: position
        12: (1, 255),  # Secondary_ID: none
        13: (1, 2),  # Protocol_Type: 2.0
        20: (4, 0),  # Homing_Offset
        24: (4, 10),  # Moving_Threshold, 0.229 rev/min
        31: (1, temperature_c),
        32: (2, voltage_0v1[0]),
        34: (2, voltage_0v1[1]),
        36: (2, 885),  # PWM_Limit, 0.113 %
        44: (4, velocity_limit),
        48: (4, 4095),  # Max_Position_Limit
        52: (4, 0),  # Min_Position_Limit
        63: (1, shutdown),
        68: (1, 2),  # Status_Return_Level: every instruction answered
        144: (2, supply_0v1),  # Present_Input_Voltage [assumed supply]
        146: (1, 25),  # Present_Temperature, °C [assumed: room temperature]
    }
    if current_limit is not None:
        table[38] = (2, current_limit)
    if startup:
        table[60] = (1, 0)  # Startup_Configuration
    if xl330:
        table[62] = (1, 140)  # PWM_Slope, 1.977 mV/ms
    for addr, gain in zip((76, 78, 80, 82, 84), gains, strict=True):
        table[addr] = (2, gain)
    return table


FACTORY_DEFAULTS: Mapping[str, Mapping[int, tuple[int, int]]] = {
    "sts3215": STS3215_DEFAULTS,
    "sts3250": STS3215_DEFAULTS,
    "sm8512bl": STS3215_DEFAULTS,
    "xl330-m288": x_series_defaults(70, (70, 35), 1750, 445, 53, (1600, 180, 0, 0, 400), xl330=True, supply_0v1=50),
    "xl330-m077": x_series_defaults(70, (70, 35), 1750, 1620, 53, (400, 40, 0, 400, 400), xl330=True, supply_0v1=50),
    "xl430-w250": x_series_defaults(72, (140, 60), None, 265, 52, (1000, 100, 4000, 0, 640), supply_0v1=111),
    "xm430-w350": x_series_defaults(80, (160, 95), 1193, 200, 52, (1920, 100, 0, 0, 800), startup=False),
}
"""Model → its factory control table (models not listed start all 0 but for what the simulator sets)."""
