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
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["FACTORY_DEFAULTS", "STS3215_DEFAULTS"]

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

FACTORY_DEFAULTS: Mapping[str, Mapping[int, tuple[int, int]]] = {
    "sts3215": STS3215_DEFAULTS,
    "sts3250": STS3215_DEFAULTS,
    "sm8512bl": STS3215_DEFAULTS,
}
"""Model → its factory control table (models not listed start all 0 but for what the simulator sets)."""
