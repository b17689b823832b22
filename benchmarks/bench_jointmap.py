"""Joint map throughput: per-tick mapping of 14 joints and (T, N) batch mapping of 10⁷ samples.

Baselines measured in the same run: a per-joint Python loop of the same formula (per tick) and
``numpy.copyto`` of the same array (batch; the memory-bandwidth floor).
"""

from __future__ import annotations

import numpy as np
from _timing import best_time

from robocal.core import RobotCalibration

N_JOINTS = 14


def main() -> None:
    rng = np.random.default_rng(0)
    names = [f"j{i}" for i in range(N_JOINTS)]
    direction = rng.choice([-1.0, 1.0], N_JOINTS)
    offset = rng.uniform(-3, 3, N_JOINTS)
    cal = RobotCalibration(names, direction, offset)
    pos, vel, eff = (rng.uniform(-3, 3, N_JOINTS) for _ in range(3))

    def tick_separate() -> None:
        cal.to_joint(pos)
        cal.velocity_to_joint(vel)
        cal.effort_to_joint(eff)

    state = np.array((pos, vel, eff))  # (3, N): what a driver fills per tick (CalibratedRobot does)
    state_out = np.empty_like(state)

    def tick_fused() -> None:
        cal.state_to_joint(state)

    def tick_fused_out() -> None:
        cal.state_to_joint(state, out=state_out)

    def tick_fused_stack() -> None:
        cal.state_to_joint(np.array((pos, vel, eff)))

    d_list, h_list = direction.tolist(), offset.tolist()
    p_list, v_list, e_list = pos.tolist(), vel.tolist(), eff.tolist()

    def tick_loop() -> None:
        q = [0.0] * N_JOINTS
        v = [0.0] * N_JOINTS
        e = [0.0] * N_JOINTS
        for i in range(N_JOINTS):
            d = d_list[i]
            q[i] = d * (p_list[i] - h_list[i])
            v[i] = d * v_list[i]
            e[i] = d * e_list[i]

    t_loop = best_time(tick_loop, 5, 20000)
    t_np = best_time(tick_fused, 5, 20000)
    t_out = best_time(tick_fused_out, 5, 20000)
    t_stack = best_time(tick_fused_stack, 5, 20000)
    t_sep = best_time(tick_separate, 5, 20000)
    print(f"per tick, {N_JOINTS} joints, position+velocity+effort:")
    print(f"  baseline per-joint loop      {t_loop * 1e6:8.2f} us/tick")
    for label, t in (
        ("robocal state_to_joint (3,N)", t_np),
        ("  ... out= preallocated", t_out),
        ("  ... stacking 3 arrays first", t_stack),
        ("  3 separate calls", t_sep),
    ):
        print(f"  {label:<28} {t * 1e6:8.2f} us/tick   ratio robocal/baseline = {t / t_loop:.2f}")
    print("  (target: state_to_joint ratio < 1)")

    total = 10_000_000
    t_rows = total // N_JOINTS
    raw = rng.uniform(-3, 3, (t_rows, N_JOINTS))
    out = np.empty_like(raw)
    samples = raw.size

    def batch() -> None:
        cal.to_joint(raw, out=out)

    def batch_api() -> None:
        cal.to_joint(raw)

    def copy() -> None:
        np.copyto(out, raw)

    t_batch = best_time(batch, 5, 3)
    t_api = best_time(batch_api, 3, 2)
    t_copy = best_time(copy, 5, 3)
    print(f"batch ({t_rows}, {N_JOINTS}) = {samples:.1e} joint-samples:")
    print(
        f"  robocal to_joint(out=...)   {samples / t_batch / 1e6:8.1f} M samples/s   "
        f"ratio to copy = {t_copy / t_batch:.2f}   (target >= 0.5)"
    )
    print(
        f"  robocal to_joint (new array) {samples / t_api / 1e6:8.1f} M samples/s   ratio to copy = {t_copy / t_api:.2f}"
    )
    print(f"  baseline numpy.copyto        {samples / t_copy / 1e6:8.1f} M samples/s")


if __name__ == "__main__":
    main()
