"""A simulated Damiao motor: the firmware as the sources describe it, behind the shared joint plant.

One :class:`SimDamiaoMotor` answers the frames of one motor (``handle``); :class:`~.sim_bus.SimDamiaoBus` puts
several on a CAN channel. What is modelled, and what is assumed where no source says (docs/damiao.md,
"Simulator"):

* **Registers**: RAM and flash copies. Power-on loads RAM from flash; 0x55 writes RAM (and is echoed), 0xAA
  copies RAM to flash (counted in :attr:`SimDamiaoMotor.flash_writes`; no reply, assumed). PMAX / VMAX / TMAX
  are the model's (``tables.MODELS``) and scale every MIT and state frame at once; MST_ID / ESC_ID take effect
  at the next power-on (assumed); TIMEOUT 0 (off, assumed factory value); CTRL_MODE 1 (MIT).
* **Position**: two single-turn encoders, the multi-turn count in RAM only (third-party reports; OA's motor
  page). The zero is an angle of the single-turn output encoder kept in flash: ``set zero`` (0xFE) stores the
  current angle there at once and survives a power cycle without 0xAA (assumed: every OpenArm stack treats it
  as persistent); after a power cycle the reading restarts within ±π of the zero, so a joint more than half a
  turn from its zero comes back 2π off (the IsaacTeleop#734 report).
* **States**: disabled (0x0) until 0xFC, enabled (0x1); a fault latches its code (0x8-0xE), makes the motor
  limp and ignores 0xFC until 0xFB (which leaves it disabled). TIMEOUT > 0: an enabled motor that hears no
  frame for TIMEOUT × 50 µs goes to 0xD (communication lost) and limp (DMP clears it with 0xFB). The plant's
  overload latch is reported as 0xE. No source describes over-range commands: the MIT fields clamp on the
  wire, so there is no such fault here.
* **Replies**: MIT command, enable, disable, refresh → state frame on MST_ID; set zero and clear error → a state
  frame too (:attr:`answers_zero_and_clear`, assumed; no source says); register read → 0x33 reply, write →
  0x55 echo, on MST_ID (assumed); save → none. MIT frames are obeyed only in CTRL_MODE 1; the other modes'
  frames (0x100/0x200/0x300 + ESC_ID) are not simulated and get no reply.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from ...errors import DeviceError, UsageError
from ..sim.physics import Drive, JointPlant, SimClock
from .protocol import (
    Frame,
    MitCommand,
    MotorState,
    decode_config_request,
    decode_mit_command,
    decode_special,
    encode_register_reply,
    encode_state,
    unpack_register_value,
)
from .tables import (
    CMD_CLEAR_ERROR,
    CMD_DISABLE,
    CMD_ENABLE,
    CMD_SET_ZERO,
    OP_READ,
    OP_REFRESH,
    OP_SAVE,
    OP_WRITE,
    REGISTERS,
    ControlMode,
    MotorLimits,
    Register,
    State,
    model_limits,
)

__all__ = ["MODEL_HARDWARE", "TIMEOUT_UNIT_S", "ModelHardware", "SimDamiaoMotor", "default_registers"]

TIMEOUT_UNIT_S = 50e-6
"""One unit of the TIMEOUT register (9): 50 µs (DMP: ``reg = ms × 20``)."""


@dataclass(frozen=True)
class ModelHardware:
    """Datasheet values of one model (OA ``website/docs/hardware/openarm-2.0/motor.mdx``).

    Attributes:
        peak_torque_nm: Peak output torque (the simulated motor never pushes harder).
        gear_ratio: Register GR (20).
        pole_pairs: Register NPP (16).
        encoder_counts: Counts per turn of the single-turn output encoder (14 bits).
    """

    peak_torque_nm: float
    gear_ratio: float
    pole_pairs: int
    encoder_counts: int = 16384


MODEL_HARDWARE: dict[str, ModelHardware] = {
    "DM4310": ModelHardware(7.0, 10.0, 14),
    "DM4340": ModelHardware(27.0, 40.0, 14),
    "DM4340_48V": ModelHardware(27.0, 40.0, 14),
    "DM8009": ModelHardware(40.0, 9.0, 21),
}
"""The OpenArm's models; any other model is simulated with its TMAX as peak torque, GR 1 and NPP 14."""


def _hardware(model: str) -> ModelHardware:
    key = model_limits(model).model
    limits = model_limits(key)
    return MODEL_HARDWARE.get(key, ModelHardware(limits.t_max_nm, 1.0, 14))


def default_registers(model: str, esc_id: int, mst_id: int) -> dict[Register, float]:
    """The register file a simulated ``model`` starts with (flash; values not listed by a source read 0)."""
    limits = model_limits(model)
    hw = _hardware(model)
    regs = dict.fromkeys(Register, 0.0)
    regs.update(
        {
            Register.MST_ID: float(mst_id),
            Register.ESC_ID: float(esc_id),
            Register.TIMEOUT: 0.0,
            Register.CTRL_MODE: float(ControlMode.MIT),
            Register.PMAX: limits.p_max_rad,
            Register.VMAX: limits.v_max_rad_s,
            Register.TMAX: limits.t_max_nm,
            Register.GR: hw.gear_ratio,
            Register.NPP: float(hw.pole_pairs),
            Register.CAN_BR: 4.0,
            Register.UV_VALUE: 10.0,
            Register.OV_VALUE: 32.0,
            Register.OT_VALUE: 120.0,
        }
    )
    return regs


def _wrap_pi(x: float) -> float:
    """``x`` into [−π, π)."""
    return (x + math.pi) % math.tau - math.pi


@dataclass
class SimDamiaoMotor:
    """State of one simulated Damiao motor (mutable: it is the simulated hardware).

    Args:
        esc_id: The id it listens on (register ESC_ID, flash).
        mst_id: The id its replies carry (register MST_ID, flash).
        model: Model name (``"DM4310"``).
        direction: Motor frame = ``direction`` × joint frame (the plant's).
        mount_rad: Hidden: the output encoder's angle (motor frame, rad) with the joint at 0.
        zero_abs_rad: The zero kept in flash, an output-encoder angle in [0, 2π).
        q_rad: Joint position, rad (joint frame) when there is no plant.
        plant: Physics of the joint (joint frame); None: the position is set from outside.
        clock: Simulated time (required with a plant).
        latency_s: Simulated time each frame takes (with a plant).
        answers_zero_and_clear: 0xFE and 0xFB are answered with a state frame (assumed).
        registers: Overrides of :func:`default_registers` (flash), e.g. ``{Register.VMAX: 8.0}``.
    """

    esc_id: int
    mst_id: int
    model: str = "DM4310"
    direction: int = 1
    mount_rad: float = 0.0
    zero_abs_rad: float = 0.0
    q_rad: float = 0.0
    v_rad_s: float = 0.0
    plant: JointPlant | None = None
    clock: SimClock | None = None
    latency_s: float = 0.0002
    answers_zero_and_clear: bool = True
    registers: dict[Register, float] = field(default_factory=dict)
    mos_temp_c: int = 30
    rotor_temp_c: int = 28
    flash_writes: int = 0
    """0xAA saves and 0xFE zeros so far (the flash is specified for ~10 000)."""
    requests: dict[str, int] = field(default_factory=dict)
    """Frames handled, by kind (``"mit"``, ``"enable"``, ``"set zero"``, ``"refresh"``, ``"read"``, ...)."""
    state: int = State.DISABLED
    last_command: MitCommand | None = None
    last_rx_s: float | None = None
    lost_comm_at_s: list[float] = field(default_factory=list)
    """Simulated (or monotonic) times at which TIMEOUT expired."""
    torque_off_at: list[tuple[float, float]] = field(default_factory=list)
    """Each time the motor stopped being able to push: ``(motor time, time.monotonic())`` of the frame that did it
    (disable 0xFD, the zero-torque MIT frame, clear error) or of its TIMEOUT expiring (the motor's time is the
    simulated clock with a plant, else the monotonic clock; the second is the host machine's, comparable across
    processes, to time a limp against the signal that asked for it)."""

    def __post_init__(self) -> None:
        if self.direction not in (1, -1):
            raise UsageError(f"simulated Damiao motor {self.esc_id:#x}: direction is +1 or -1")
        if self.plant is not None and self.clock is None:
            raise DeviceError(f"simulated Damiao motor {self.esc_id:#x}: a plant needs a simulated clock")
        self.hardware = _hardware(self.model)
        self.flash: dict[Register, float] = default_registers(self.model, self.esc_id, self.mst_id)
        self.flash.update(self.registers)
        self.zero_abs_rad %= math.tau
        if self.plant is not None:
            self.q_rad, self.v_rad_s = self.plant.q_rad, self.plant.v_rad_s
        self.power_on()

    # ------------------------------------------------------------------------------------------ registers
    def reg(self, rid: Register) -> float:
        """A register's value in RAM."""
        return self.ram[rid]

    @property
    def limits(self) -> MotorLimits:
        """The ranges its MIT and state frames use now (RAM PMAX / VMAX / TMAX)."""
        r = self.ram
        return MotorLimits(
            self.model, r[Register.PMAX], r[Register.VMAX], r[Register.TMAX], "simulated registers"
        )

    def power_on(self) -> None:
        """A power cycle: RAM from flash, disabled, no error, the multi-turn count lost (reading within ±π)."""
        self.ram: dict[Register, float] = dict(self.flash)
        self.esc_id = int(self.flash[Register.ESC_ID])
        self.mst_id = int(self.flash[Register.MST_ID])
        self.state = State.DISABLED
        self.last_command = None
        self.last_rx_s = None
        if self.plant is not None:
            self.plant.clear_overload()
        shaft = self.shaft_rad()
        self._zero_cont_rad = shaft - _wrap_pi(shaft - self.zero_abs_rad)

    # ------------------------------------------------------------------------------------------- position
    def joint_rad(self) -> float:
        """True joint position, rad (joint frame; the link, where the output encoder sits)."""
        return self.plant.link_rad if self.plant is not None else self.q_rad

    def shaft_rad(self, joint_rad: float | None = None) -> float:
        """The output shaft's continuous angle, motor frame (what the encoders see before any zero)."""
        q = self.joint_rad() if joint_rad is None else joint_rad
        return self.direction * q + self.mount_rad

    def reading_rad(self, joint_rad: float | None = None) -> float:
        """The position the motor reports for ``joint_rad`` (default now): relative to its zero, multi-turn."""
        if joint_rad is None and self.plant is not None:
            joint_rad = self.plant.read().q_rad  # the encoder: quantised, the plant's noise
        return self.shaft_rad(joint_rad) - self._zero_cont_rad

    def set_position(self, q_rad: float, v_rad_s: float = 0.0) -> None:
        """Move the joint by hand (joint frame)."""
        self.q_rad, self.v_rad_s = float(q_rad), float(v_rad_s)
        if self.plant is not None:
            self.plant.set_state(q_rad, v_rad_s)

    # --------------------------------------------------------------------------------------------- physics
    @property
    def enabled(self) -> bool:
        """Torque on (state 0x1)."""
        return self.state == State.ENABLED

    def drive(self) -> Drive:
        """The MIT law now, joint frame: limp unless enabled with a command, capped at TMAX and peak torque."""
        cmd = self.last_command
        if not self.enabled or cmd is None:
            return Drive()
        d = self.direction
        q_ref = d * (cmd.position_rad + self._zero_cont_rad - self.mount_rad)
        cap = min(self.ram[Register.TMAX], self.hardware.peak_torque_nm)
        return Drive(cmd.kp, cmd.kd, q_ref, d * cmd.velocity_rad_s, d * cmd.torque_nm, cap)

    def now_s(self) -> float:
        """The motor's time: the simulated clock with a plant, else the monotonic clock."""
        return self.clock.now() if self.clock is not None else time.monotonic()

    def check_timeout(self, now_s: float | None = None) -> bool:
        """TIMEOUT: enabled and no frame for TIMEOUT × 50 µs → 0xD and limp; True when it expired now."""
        units = self.ram[Register.TIMEOUT]
        if units <= 0 or not self.enabled or self.last_rx_s is None:
            return False
        due = self.last_rx_s + units * TIMEOUT_UNIT_S
        if (self.now_s() if now_s is None else now_s) < due:
            return False
        if self.plant is not None:
            self.plant.run_until(due, self.drive())
        was = self.pushing()
        self.state = State.LOST_COMM
        self.lost_comm_at_s.append(due)
        if was:
            self.torque_off_at.append((due, time.monotonic()))
        return True

    def sync(self) -> None:
        """Integrate the plant up to the clock under the current command; latch an overload as 0xE."""
        if self.plant is None or self.clock is None:
            return
        self.check_timeout()
        self.plant.run_until(self.clock.now(), self.drive())
        self.q_rad, self.v_rad_s = self.plant.q_rad, self.plant.v_rad_s
        if self.plant.latched and self.enabled:
            if self.pushing():
                self.torque_off_at.append((self.clock.now(), time.monotonic()))
            self.state = State.OVERLOAD

    def pushing(self) -> bool:
        """Enabled with a command that can make torque (any of ``kp``, ``kd``, ``τ_ff`` non-zero)."""
        cmd = self.last_command
        return self.enabled and cmd is not None and any(x != 0.0 for x in (cmd.kp, cmd.kd, cmd.torque_nm))

    def inject_fault(self, code: State) -> None:
        """Latch an error state (0x8-0xE): the motor goes limp until 0xFB."""
        if code in (State.DISABLED, State.ENABLED):
            raise UsageError(f"{code.name} is not a fault")
        self.state = code

    def torque_nm(self) -> float:
        """Output torque now, motor frame."""
        if not self.enabled or self.last_command is None:
            return 0.0
        if self.plant is not None:
            return self.direction * self.plant.tau_motor_nm
        cmd = self.last_command
        raw = cmd.kp * (cmd.position_rad - self.reading_rad()) + cmd.torque_nm
        raw += cmd.kd * (cmd.velocity_rad_s - self.direction * self.v_rad_s)
        cap = min(self.ram[Register.TMAX], self.hardware.peak_torque_nm)
        return max(-cap, min(cap, raw))

    def state_frame(self) -> Frame:
        """The state frame it sends now (on MST_ID)."""
        st = MotorState(
            motor_id=self.esc_id & 0x0F,
            state=int(self.state),
            position_rad=self.reading_rad(),
            velocity_rad_s=self.direction * self.v_rad_s,
            torque_nm=self.torque_nm(),
            mos_temp_c=self.mos_temp_c,
            rotor_temp_c=self.rotor_temp_c,
        )
        return self.mst_id, encode_state(st, self.limits)

    # -------------------------------------------------------------------------------------------- frames
    def handle(self, arbitration_id: int, data: bytes) -> list[Frame]:
        """Answer one frame (to ESC_ID, or to 0x7FF naming ESC_ID); returns the reply frames."""
        if self.plant is not None and self.clock is not None:
            self.clock.advance(self.latency_s)
            self.sync()
        else:
            self.check_timeout()
        self.last_rx_s = self.now_s()
        was = self.pushing()
        out = self._command(bytes(data)) if arbitration_id == self.esc_id else self._config(bytes(data))
        if was and not self.pushing():
            self.torque_off_at.append((self.last_rx_s, time.monotonic()))
        return out

    def _count(self, kind: str) -> None:
        self.requests[kind] = self.requests.get(kind, 0) + 1

    def _command(self, data: bytes) -> list[Frame]:
        special = decode_special(data)
        if special is None:
            if len(data) != 8 or int(self.ram[Register.CTRL_MODE]) != ControlMode.MIT:
                return []
            self._count("mit")
            self.last_command = decode_mit_command(data, self.limits)
            return [self.state_frame()]
        if special == CMD_ENABLE:
            self._count("enable")
            if self.state in (State.DISABLED, State.ENABLED):
                self.state = State.ENABLED
        elif special == CMD_DISABLE:
            self._count("disable")
            if self.enabled:
                self.state = State.DISABLED
            self.last_command = None
        elif special == CMD_SET_ZERO:
            self._count("set zero")
            shaft = self.shaft_rad()
            self._zero_cont_rad = shaft
            self.zero_abs_rad = shaft % math.tau
            self.flash_writes += 1
            if not self.answers_zero_and_clear:
                return []
        elif special == CMD_CLEAR_ERROR:
            self._count("clear error")
            if self.state not in (State.DISABLED, State.ENABLED):
                self.state = State.DISABLED
                self.last_command = None
                if self.plant is not None:
                    self.plant.clear_overload()
            if not self.answers_zero_and_clear:
                return []
        return [self.state_frame()]

    def _config(self, data: bytes) -> list[Frame]:
        req = decode_config_request(data)
        if req.op == OP_REFRESH:
            self._count("refresh")
            return [self.state_frame()]
        if req.op == OP_SAVE:
            self._count("save")
            self.flash = dict(self.ram)
            self.flash_writes += 1
            return []
        if req.register not in Register._value2member_map_:
            return []
        rid = Register(req.register)
        if req.op == OP_WRITE:
            self._count("write")
            if not REGISTERS[rid].writable:
                return []
            value = unpack_register_value(rid, req.value)
            if rid in (Register.PMAX, Register.VMAX, Register.TMAX) and not value > 0:
                return []  # a range of 0 would make every frame meaningless (assumed refused)
            self.ram[rid] = value
            return [(self.mst_id, encode_register_reply(self.esc_id, OP_WRITE, rid, value))]
        self._count("read")
        value = self._live(rid)
        return [(self.mst_id, encode_register_reply(self.esc_id, OP_READ, rid, value))]

    def _live(self, rid: Register) -> float:
        if rid == Register.XOUT:
            return self.reading_rad()
        if rid == Register.P_M:
            return self.reading_rad() * self.ram[Register.GR]
        return self.ram[rid]
