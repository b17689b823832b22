"""The RTDE inputs of the simulated UR controller, shared by every RTDE connection.

Input recipes, the input data packages a client sends, and what they change (registers, digital outputs, the
speed slider). Names and types are the RTDE guide's (https://docs.universal-robots.com/tutorials/communication-protocol-tutorials/
rtde-guide.html) and ur_rtde 1.6's ``RTDEIOInterface`` recipes. Masks select what a package changes: bit *n* of
``standard_digital_output_mask`` lets bit *n* of ``standard_digital_output`` set digital output *n*; bit 0 of
``speed_slider_mask`` lets ``speed_slider_fraction`` set the speed slider. The input registers read back as the
outputs of the same name (``input_int_register_18`` …); ``actual_digital_output_bits`` carries the digital outputs
(standard 0–7, configurable 8–15, tool 16–17); ``target_speed_fraction`` the speed slider.
"""

from __future__ import annotations

import struct
import threading
from typing import Any

__all__ = ["RTDE_INPUT_TYPES", "RtdeInputs"]

_CODES = {"BOOL": "?", "UINT8": "B", "UINT32": "I", "INT32": "i", "DOUBLE": "d"}

RTDE_INPUT_TYPES: dict[str, str] = {
    **{f"input_int_register_{i}": "INT32" for i in range(48)},
    **{f"input_double_register_{i}": "DOUBLE" for i in range(48)},
    **{f"input_bit_register_{i}": "BOOL" for i in range(64, 128)},
    "standard_digital_output_mask": "UINT8",
    "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8",
    "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8",
    "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8",
    "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE",
    "standard_analog_output_1": "DOUBLE",
    "speed_slider_mask": "UINT32",
    "speed_slider_fraction": "DOUBLE",
}
"""Every input the simulator takes, with its RTDE type."""

_REGISTER_OUTPUTS: dict[str, str] = {
    n: t for n, t in RTDE_INPUT_TYPES.items() if n.startswith(("input_int_", "input_double_", "input_bit_"))
}
"""The input registers, readable as outputs of the same name and type."""

_DIGITAL_SHIFT = {"standard": 0, "configurable": 8, "tool": 16}


class RtdeInputs:
    """The controller's RTDE input state (thread-safe; one per controller, shared by its connections)."""

    OUTPUT_TYPES = _REGISTER_OUTPUTS
    """The outputs this state adds to the controller's (the registers)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._registers: dict[str, object] = {}
        self._digital_out = 0
        self._speed_slider = 1.0
        self._analog = [0.0, 0.0]

    @staticmethod
    def types(names: list[str]) -> list[str]:
        """The reply types of a SETUP_INPUTS request (``NOT_FOUND`` for a name not modelled)."""
        return [RTDE_INPUT_TYPES.get(n, "NOT_FOUND") for n in names]

    def apply(self, names: tuple[str, ...], payload: bytes) -> bool:
        """Apply one input data package (the values after the recipe id); False when its size does not fit."""
        fmt = ">" + "".join(_CODES[RTDE_INPUT_TYPES[n]] for n in names)
        if struct.calcsize(fmt) != len(payload):
            return False
        values: dict[str, Any] = dict(zip(names, struct.unpack(fmt, payload), strict=True))
        with self._lock:
            for name, value in values.items():
                if name in _REGISTER_OUTPUTS:
                    self._registers[name] = value
            for group, shift in _DIGITAL_SHIFT.items():
                mask = int(values.get(f"{group}_digital_output_mask", 0))
                if mask:
                    bits = int(values.get(f"{group}_digital_output", 0)) & mask
                    self._digital_out = (self._digital_out & ~(mask << shift)) | (bits << shift)
            if int(values.get("speed_slider_mask", 0)) & 1:
                self._speed_slider = min(max(float(values["speed_slider_fraction"]), 0.0), 1.0)
            analog_mask = int(values.get("standard_analog_output_mask", 0))
            for k in (0, 1):
                if analog_mask >> k & 1 and f"standard_analog_output_{k}" in values:
                    self._analog[k] = float(values[f"standard_analog_output_{k}"])
        return True

    def outputs(self) -> dict[str, object]:
        """Output values that follow from the inputs (registers, digital outputs, speed slider, analog outputs)."""
        with self._lock:
            return {
                **self._registers,
                "actual_digital_output_bits": self._digital_out,
                "target_speed_fraction": self._speed_slider,
                "standard_analog_output0": self._analog[0],
                "standard_analog_output1": self._analog[1],
            }
