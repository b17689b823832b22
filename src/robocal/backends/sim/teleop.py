"""Simulated teleoperation sessions with a known truth: a human moves a leader arm, a follower servo arm tracks it.

A session is a few episodes. In each, a simulated operator moves every leader joint through via points on
minimum-jerk paths with pauses (human-like), taking some joints into a range end (pushed against the stop and
held), some near one (2–10° short) and the rest through the middle of their range. The leader's reading is its
angle plus its calibration offset, quantised; that number is the ``action`` and the follower's goal in the
follower's *own* calibration frame, so the follower stands at ``action − offset_follower``. The follower is the
vectorised servo plant of :mod:`.teleop_plant` (LeRobot's gains, gravity, friction, backlash, stops, encoder
quantisation); its reading plus its offset is ``observation.state``.

Faults (:class:`TeleopFaults`), each on one joint: a calibration offset on either arm, an encoder slip mid-episode
(the follower's reading jumps, then the arm moves so that its reading follows the goal again), values clipped at a
calibrated range end short of the stop (LeRobot clamps a value to the calibration's range), a mirrored sign
convention (the action recorded with the opposite sign, huggingface/lerobot PR #4256).

Arms (:data:`TELEOP_ARMS`): SO-101 (STS3215, ``P_Coefficient`` 16, ``D_Coefficient`` 32) and Koch (XL430 /
XL330 at their factory gains, ``elbow_flex`` 1500 / 600, as LeRobot configures them: the follower profiles'
``position_gains``), through each vendor's position-loop model (``backends/<vendor>/gains.py``). Stops are the robot
profiles' ``auto_calibration`` angles. Gravity comes from the caller (the SO-101 URDF's masses) or, for Koch
(whose URDF has no masses), from per-joint amplitudes assumed here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...core.arrays import FloatArray
from ..dynamixel.gains import POSITION_LOOP as DYNAMIXEL_LOOP
from ..feetech.gains import POSITION_LOOP as FEETECH_LOOP
from ..servo_ratings import RATINGS, PositionLoop
from .teleop_limits import SCATTER_DEG, clamp_bounds_deg, goal_limits_deg, hand_scatter_deg
from .teleop_plant import GravityFn, PlantArrays, simulate_tracking

__all__ = [
    "SCATTER_DEG",
    "TELEOP_ARMS",
    "TeleopArm",
    "TeleopFaults",
    "TeleopJointTruth",
    "TeleopSession",
    "clamp_bounds_deg",
    "goal_limits_deg",
    "hand_scatter_deg",
    "simulate_sessions",
]

_INF = math.inf


@dataclass(frozen=True)
class TeleopArm:
    """A leader/follower pair's joints and the follower's servo physics.

    Attributes:
        name: ``so101`` or ``koch``.
        robot_type: ``robot_type`` of the dataset (the follower's LeRobot name).
        joints: Joint names, bus order.
        stop_lo_deg: Lower stop per joint (``-inf``: none, a full-turn joint).
        stop_hi_deg: Upper stop per joint.
        kp_nm_rad: Position gain per joint.
        kd_nms_rad: D gain per joint.
        tau_max_nm: Torque cap (the servo's stall torque) per joint.
        gravity_amp_nm: Gravity amplitude per joint when no gravity callback is given (``τ = −A·sin q``).
        back_emf_nms_rad: The motor's back-EMF damping under voltage (PWM) control, stall torque over no-load
            speed (STS3215 1.91 N·m / 4.7 rad/s; XL430 1.5 / 6.0; XL330-M288 0.52 / 10.8).
        modes: LeRobot normalisation mode per joint (with degrees).
        range_modes: Modes without ``use_degrees`` (LeRobot's default for Koch).
        full_turn: Joints LeRobot records as a whole turn (``0..4095``: no range, no limits).
        goal_limited: The follower's servo clamps its goal to the recorded range (Feetech STS3215 in position
            mode: LeRobot writes ``range_min``/``range_max`` to ``Min/Max_Position_Limit``); a Dynamixel in
            extended position mode (Koch) does not enforce them.
    """

    name: str
    robot_type: str
    joints: tuple[str, ...]
    stop_lo_deg: tuple[float, ...]
    stop_hi_deg: tuple[float, ...]
    kp_nm_rad: tuple[float, ...]
    kd_nms_rad: tuple[float, ...]
    tau_max_nm: tuple[float, ...]
    gravity_amp_nm: tuple[float, ...]
    back_emf_nms_rad: tuple[float, ...]
    modes: tuple[str, ...]
    range_modes: tuple[str, ...]
    full_turn: tuple[str, ...] = ()
    goal_limited: bool = False

    def recorded(self, j: int) -> bool:
        """Joint ``j`` has a recorded range between stops (not a full turn, not stop-free)."""
        return self.joints[j] not in self.full_turn and math.isfinite(self.stop_lo_deg[j])

    def plant(self) -> PlantArrays:
        """The follower's physics as arrays (printed-arm friction, 300 N·m/rad stops, 0.2° backlash)."""
        n = len(self.joints)

        def arr(x: float | tuple[float, ...]) -> FloatArray:
            out: FloatArray = np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)).copy()
            return out

        return PlantArrays(
            kp_nm_rad=arr(self.kp_nm_rad),
            kd_nms_rad=arr(self.kd_nms_rad),
            tau_max_nm=arr(self.tau_max_nm),
            inertia_kgm2=arr(0.004),
            coulomb_nm=arr(0.04) * arr(self.tau_max_nm) / 1.91,
            stiction_nm=arr(0.06) * arr(self.tau_max_nm) / 1.91,
            viscous_nms_rad=arr(0.02) + arr(self.back_emf_nms_rad),
            backlash_rad=arr(math.radians(0.2)),
            stop_lo_rad=np.radians(arr(self.stop_lo_deg)),
            stop_hi_rad=np.radians(arr(self.stop_hi_deg)),
            stop_k_nm_rad=arr(300.0),
            noise_rad=arr(0.4 * math.tau / 4096),
        )


def _loop(loop: PositionLoop, model: str, gains: tuple[int, int, int] | None = None) -> tuple[float, float, float]:
    """``(kp, kd, τ_stall)`` of a servo's position loop at ``gains`` (P, I, D), else at its factory gains."""
    p, _, d = gains or loop.factory_gains(model)
    kp, kd = loop.gains_nm_rad(model, p, d)
    return kp, kd, RATINGS[model].stall_torque_nm


_ARM_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
_SO = _loop(FEETECH_LOOP, "sts3215", (16, 0, 32))
_XL430 = _loop(DYNAMIXEL_LOOP, "xl430-w250")
_XL330 = _loop(DYNAMIXEL_LOOP, "xl330-m288")
_XL330_ELBOW = _loop(DYNAMIXEL_LOOP, "xl330-m288", (1500, 0, 600))
_KOCH = (_XL430, _XL430, _XL330_ELBOW, _XL330, _XL330, _XL330)

TELEOP_ARMS: dict[str, TeleopArm] = {
    "so101": TeleopArm(
        name="so101",
        robot_type="so101_follower",
        joints=_ARM_JOINTS,
        stop_lo_deg=(-110.0, -100.0, -96.83, -95.0, -170.0, -10.0),
        stop_hi_deg=(110.0, 100.0, 96.83, 95.0, 170.0, 115.0),
        kp_nm_rad=(_SO[0],) * 6,
        kd_nms_rad=(_SO[1],) * 6,
        tau_max_nm=(_SO[2],) * 6,
        gravity_amp_nm=(0.0, 0.6, 0.3, 0.05, 0.0, 0.0),
        back_emf_nms_rad=(1.91 / 4.7,) * 6,
        modes=("degrees",) * 5 + ("range_0_100",),
        range_modes=("range_m100_100",) * 5 + ("range_0_100",),
        full_turn=("wrist_roll",),
        goal_limited=True,
    ),
    "koch": TeleopArm(
        name="koch",
        robot_type="koch_follower",
        joints=_ARM_JOINTS,
        stop_lo_deg=(-_INF, -96.7, -96.7, -97.4, -_INF, -11.46),
        stop_hi_deg=(_INF, 96.7, 96.7, 97.4, _INF, 76.4),
        kp_nm_rad=tuple(g[0] for g in _KOCH),
        kd_nms_rad=tuple(g[1] for g in _KOCH),
        tau_max_nm=tuple(g[2] for g in _KOCH),
        gravity_amp_nm=(0.0, 0.35, 0.12, 0.015, 0.0, 0.0),
        back_emf_nms_rad=(1.5 / 6.0, 1.5 / 6.0) + (0.52 / 10.8,) * 4,
        modes=("degrees",) * 5 + ("range_0_100",),
        range_modes=("range_m100_100",) * 5 + ("range_0_100",),
        full_turn=("shoulder_pan", "wrist_roll"),
    ),
}
"""The simulated pairs. SO-101 stops: ``so101_follower.yaml``; Koch: ``koch_follower.yaml`` (pan and wrist roll
turn fully: no stops). Koch gravity amplitudes are assumptions (its URDF carries no masses). The SO-101's STS3215s
clamp goals to ``Min/Max_Position_Limit`` (LeRobot's recorded range); the Koch's Dynamixels, in extended position
mode, do not (``docs/lerobot.md``)."""


@dataclass(frozen=True)
class TeleopFaults:
    """What is wrong in a session (all optional; angles in degrees).

    Attributes:
        offset_joint: Joint whose calibration is off.
        offset_deg: Reading minus true angle on that joint, on ``offset_arm``.
        offset_arm: ``follower`` or ``leader``.
        slip_joint: Joint whose follower encoder jumps.
        slip_episode: Episode of the jump.
        slip_frame: Frame of the jump within the episode.
        slip_deg: Size of the jump (added to the follower's reading from then on).
        clip_joint: Joint whose follower values are clipped at a calibrated range end.
        clip_end: ``lo`` or ``hi``.
        clip_short_deg: How far short of the stop the clipped range ends.
        flip_joint: Joint whose action is recorded with the opposite sign.
    """

    offset_joint: str | None = None
    offset_deg: float = 0.0
    offset_arm: str = "follower"
    slip_joint: str | None = None
    slip_episode: int = 0
    slip_frame: int = 0
    slip_deg: float = 0.0
    clip_joint: str | None = None
    clip_end: str = "hi"
    clip_short_deg: float = 8.0
    flip_joint: str | None = None


@dataclass(frozen=True)
class TeleopJointTruth:
    """What really happened on one joint.

    Attributes:
        offset_deg: Follower calibration minus leader calibration (what a health check should report).
        approach_lo_deg: Closest the leader came to the lower stop over the session (0: pushed against it).
        approach_hi_deg: Closest to the upper stop.
        follower_contact: The follower was pressed against a stop by more than 0.5° of goal beyond it.
        pin_depth_deg: How far beyond a stop the follower's goal went at most (0: never beyond).
        held_lo_deg: How hard the lower stop held the follower: the largest stop torque kept for 0.2 s, as the
            goal error of the follower's position gain that makes it (``τ_stop / kp``, degrees; 0: never held).
            Gravity sag and friction make it smaller than ``pin_depth_deg``: a goal 3° past the stop of a joint
            that sags 2.5° there holds it by 0.5° only.
        held_hi_deg: Same, the upper stop.
        friction_span_deg: ``2·τ_stiction / kp``, degrees: how far apart friction lets a correct follower come to
            rest for one goal (either side of it). A stop that holds the follower by less than this leaves a
            residual a correct follower's friction could also leave: the offset is not in the data.
        limited_lo_deg: How far the follower's servo held its goal back at its lower position limit (the
            leader's number past the limit, kept 0.2 s; 0 where the servo enforces none). A follower held by its
            limit stands there while its leader goes on, as one held by its stop does.
        limited_hi_deg: Same, the upper limit.
        scatter_deg: How far short of both stops the follower's recorded range ends (its limits' hand scatter): a
            correct calibration's follower is held by up to this at its limits too.
    """

    offset_deg: float
    approach_lo_deg: float
    approach_hi_deg: float
    follower_contact: bool
    pin_depth_deg: float = 0.0
    held_lo_deg: float = 0.0
    held_hi_deg: float = 0.0
    friction_span_deg: float = 0.0
    limited_lo_deg: float = 0.0
    limited_hi_deg: float = 0.0
    scatter_deg: float = 0.0


@dataclass(frozen=True)
class TeleopSession:
    """A simulated session: what the dataset holds and the truth.

    Attributes:
        arm: The pair.
        fps: Frames per second.
        action_deg: ``(E, T, J)`` leader readings (degrees, offsets included; before value mapping).
        state_deg: ``(E, T, J)`` follower readings.
        faults: The injected faults.
        truth: Joint → truth.
        seed: Seed.
        scatter_deg: ``(leader, follower)`` hand scatter of the recorded ranges per joint (:func:`hand_scatter_deg`;
            None: the session's seed gives it).
    """

    arm: TeleopArm
    fps: float
    action_deg: FloatArray
    state_deg: FloatArray
    faults: TeleopFaults
    truth: dict[str, TeleopJointTruth] = field(default_factory=dict)
    seed: int = 0
    scatter_deg: tuple[FloatArray, FloatArray] | None = None

    def scatter(self) -> tuple[FloatArray, FloatArray]:
        """The hand scatter of both arms' recorded ranges, ``(J,)`` each."""
        return self.scatter_deg if self.scatter_deg is not None else hand_scatter_deg(self.arm, self.seed)


def _min_jerk(
    rng: np.random.Generator, frames: int, fps: float, targets: list[float], start: float
) -> FloatArray:
    """A path through ``targets`` (minimum-jerk moves of 0.8–2.5 s, pauses of 0–1 s), ``frames`` long."""
    out = np.empty(frames)
    t = 0
    pos = start
    k = 0
    while t < frames:
        goal = targets[k % len(targets)]
        k += 1
        n_move = max(2, int(rng.uniform(0.8, 2.5) * fps))
        s = np.linspace(0.0, 1.0, n_move)
        path = pos + (goal - pos) * (10 * s**3 - 15 * s**4 + 6 * s**5)
        n_hold = int(rng.uniform(0.0, 1.0) * fps)
        seg = np.concatenate([path, np.full(n_hold, goal)])
        m = min(len(seg), frames - t)
        out[t : t + m] = seg[:m]
        t += m
        pos = goal
    return out


def _leader_paths(
    rng: np.random.Generator, arm: TeleopArm, episodes: int, frames: int, fps: float, p_end: float
) -> FloatArray:
    """``(E, T, J)`` leader true angles, degrees: a human's via points, some at or near a range end."""
    lo, hi = np.asarray(arm.stop_lo_deg), np.asarray(arm.stop_hi_deg)
    out = np.empty((episodes, frames, len(arm.joints)))
    for e in range(episodes):
        for j in range(len(arm.joints)):
            a, b = (lo[j], hi[j]) if math.isfinite(lo[j]) else (-150.0, 150.0)
            mid, half = 0.5 * (a + b), 0.5 * (b - a)
            targets = [float(mid + half * rng.uniform(-0.7, 0.7)) for _ in range(6)]
            if math.isfinite(lo[j]) and rng.uniform() < p_end:
                end = rng.choice([-1.0, 1.0])
                stop = b if end > 0 else a
                # pushed into the stop (held there by the stop) or stopped 2-10° short of it
                gap = -rng.uniform(1.0, 5.0) if rng.uniform() < 0.6 else rng.uniform(2.0, 10.0)
                targets[int(rng.integers(1, 5))] = float(stop - end * gap)
            start = targets[-1]
            path = _min_jerk(rng, frames, fps, targets, start)
            out[e, :, j] = np.clip(path + rng.normal(0.0, 0.05, frames), a, b)
    return out


def _quantise_deg(x: FloatArray) -> FloatArray:
    step = 360.0 / 4096
    out: FloatArray = np.round(x / step) * step
    return out


def _kept(x: FloatArray, frames: int) -> tuple[FloatArray, FloatArray]:
    """``(L, T, J)`` signed amounts → ``(L, J)`` per sign: the largest kept for ``frames`` frames running."""
    out = []
    for y in (np.maximum(x, 0.0), np.maximum(-x, 0.0)):
        k = max(1, min(frames, y.shape[1]))
        win = np.lib.stride_tricks.sliding_window_view(y, k, axis=1)
        out.append(win.min(axis=-1).max(axis=1))
    return out[0], out[1]


def _held_deg(stop_nm: FloatArray, kp_nm_rad: FloatArray, frames: int) -> tuple[FloatArray, FloatArray]:
    """``(L, J)`` per end: the largest stop torque kept for ``frames`` frames running, as degrees of goal error."""
    return _kept(np.degrees(stop_nm / kp_nm_rad), frames)  # lower stop pushes up (+), upper down (−)


def simulate_sessions(
    arm: TeleopArm,
    seeds: list[int],
    faults: list[TeleopFaults],
    *,
    gravity: GravityFn | None = None,
    episodes: int = 6,
    episode_s: float = 15.0,
    fps: float = 30.0,
    p_end: float = 0.35,
    modes: tuple[str, ...] | None = None,
    goal_limits: bool = True,
) -> list[TeleopSession]:
    """Simulate one session per seed (all sessions integrated together, one lane per episode).

    LeRobot clamps a value in a range mode (``range_m100_100``, ``range_0_100``) to the calibrated range, both when
    it reads an arm and when it turns the action into the follower's goal. The calibrated range is the profile's
    stops in each arm's own reading frame (a full-turn joint: ±180° about its middle), so in those modes the
    leader's number, the follower's goal and the follower's reading never pass them: a leader-side offset then
    never drives the follower into its stop. Degrees are not clamped by LeRobot, but a follower whose servo enforces
    its position limits (``arm.goal_limited``: the SO-101's STS3215s) clamps the goal to the range LeRobot wrote
    there (:func:`goal_limits_deg`: the hand scatter of :func:`hand_scatter_deg` and the follower's offset), so a
    goal past its stop never reaches the motor: the follower stands at its limit while the leader goes on
    (``goal_limits``, on by default; off: every follower pressed into its stop, the simulator before 2026-11-29).

    Args:
        arm: The pair.
        seeds: One seed per session.
        faults: One fault set per session.
        gravity: Link angles ``(L, J)`` rad (joint order of ``arm``) → gravity torque; default
            ``−A·sin q`` per joint with the arm's amplitudes.
        episodes: Episodes per session.
        episode_s: Length of an episode.
        fps: Frames per second.
        p_end: Chance that an episode takes a joint to or near a range end.
        modes: LeRobot's normalisation mode per joint of the dataset to be written (default ``arm.modes``, the
            modes with ``use_degrees``).
        goal_limits: The follower's servo enforces its position limits where the real one does
            (``arm.goal_limited``).

    Returns:
        The sessions, in the order of ``seeds``.
    """
    names = arm.joints
    frames = round(episode_s * fps)
    n_j = len(names)
    amp = np.asarray(arm.gravity_amp_nm)

    def default_gravity(q: FloatArray) -> FloatArray:
        out: FloatArray = -amp * np.sin(q)
        return out

    leader_true: list[FloatArray] = []
    e_lead, e_foll, slips, limits, scatters = [], [], [], [], []
    modes = arm.modes if modes is None else modes
    for seed, f in zip(seeds, faults, strict=True):
        rng = np.random.default_rng(seed)
        leader_true.append(_leader_paths(rng, arm, episodes, frames, fps, p_end))
        el, ef = np.zeros(n_j), np.zeros(n_j)
        if f.offset_joint is not None:
            (el if f.offset_arm == "leader" else ef)[names.index(f.offset_joint)] = f.offset_deg
        slip = np.zeros((episodes, frames, n_j))
        if f.slip_joint is not None:
            slip[f.slip_episode, f.slip_frame :, names.index(f.slip_joint)] = f.slip_deg
        e_lead.append(el)
        e_foll.append(ef)
        slips.append(slip)
        scatters.append(hand_scatter_deg(arm, seed))
        limits.append(goal_limits_deg(arm, ef, scatters[-1][1], modes, enforced=goal_limits))
    lead = np.concatenate(leader_true)  # (S·E, T, J)
    el_all = np.repeat(np.stack(e_lead), episodes, axis=0)[:, None, :]
    ef_all = np.repeat(np.stack(e_foll), episodes, axis=0)[:, None, :] + np.concatenate(slips)
    rng_all = np.random.default_rng(seeds[0] if seeds else 0)
    action = _quantise_deg(lead + el_all + rng_all.normal(0.0, 0.02, lead.shape))
    clamp_lo, clamp_hi = clamp_bounds_deg(arm, modes)
    action = np.clip(action, clamp_lo, clamp_hi)  # the leader's number, and so the follower's goal
    # the follower's servo clamps the goal to its position limits (its own reading frame)
    lim_lo = np.repeat(np.stack([lim[0] for lim in limits]), episodes, axis=0)[:, None, :]
    lim_hi = np.repeat(np.stack([lim[1] for lim in limits]), episodes, axis=0)[:, None, :]
    goal_reading = np.clip(action, lim_lo, lim_hi)
    limited_lo, limited_hi = _kept(goal_reading - action, round(0.2 * fps))  # lower limit holds it up (+)
    # the follower's goal in its true frame: the servo's goal minus the follower's own offset
    goal_rad = np.radians(goal_reading - ef_all)
    # each episode starts with the follower settled on its first goal (a second of holding, then cut)
    settle = int(fps)
    padded = np.concatenate([np.repeat(goal_rad[:, :1, :], settle, axis=1), goal_rad], axis=1)
    stop_nm = np.zeros(padded.shape)
    plant = arm.plant()
    q_f = simulate_tracking(
        padded,
        plant,
        gravity or default_gravity,
        fps=fps,
        rng=rng_all,
        q0_rad=goal_rad[:, 0, :],
        stop_torque_out=stop_nm,
    )[:, settle:, :]
    state = np.clip(np.degrees(q_f) + ef_all, clamp_lo, clamp_hi)
    span = np.degrees(2.0 * plant.stiction_nm / plant.kp_nm_rad)
    held_lo, held_hi = _held_deg(stop_nm[:, settle:, :], np.asarray(arm.kp_nm_rad), round(0.2 * fps))
    sessions = []
    lo, hi = np.asarray(arm.stop_lo_deg), np.asarray(arm.stop_hi_deg)
    for s, (seed, f) in enumerate(zip(seeds, faults, strict=True)):
        sl = slice(s * episodes, (s + 1) * episodes)
        a, st, lt = action[sl].copy(), state[sl].copy(), lead[sl]
        if f.clip_joint is not None:
            j = names.index(f.clip_joint)
            if f.clip_end == "hi":
                st[..., j] = np.minimum(st[..., j], hi[j] - f.clip_short_deg + ef_all[sl.start, 0, j])
            else:
                st[..., j] = np.maximum(st[..., j], lo[j] + f.clip_short_deg + ef_all[sl.start, 0, j])
        if f.flip_joint is not None:
            a[..., names.index(f.flip_joint)] *= -1.0
        goal_true = np.degrees(goal_rad[sl])
        truth = {}
        for j, name in enumerate(names):
            past = np.maximum(goal_true[..., j] - hi[j], lo[j] - goal_true[..., j])
            truth[name] = TeleopJointTruth(
                offset_deg=float(e_foll[s][j] - e_lead[s][j]),
                approach_lo_deg=float(np.min(lt[..., j] - lo[j])) if math.isfinite(lo[j]) else _INF,
                approach_hi_deg=float(np.min(hi[j] - lt[..., j])) if math.isfinite(hi[j]) else _INF,
                follower_contact=bool(np.any(past > 0.5)),
                pin_depth_deg=max(0.0, float(np.max(past))),
                held_lo_deg=float(np.max(held_lo[sl, j])),
                held_hi_deg=float(np.max(held_hi[sl, j])),
                friction_span_deg=float(span[j]),
                limited_lo_deg=float(np.max(limited_lo[sl, j])),
                limited_hi_deg=float(np.max(limited_hi[sl, j])),
                scatter_deg=float(scatters[s][1][j]) if goal_limits and arm.goal_limited else 0.0,
            )
        sessions.append(TeleopSession(arm, fps, a, st, f, truth, seed, scatters[s]))
    return sessions
