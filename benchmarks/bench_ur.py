"""UR benchmark: batched DH forward kinematics of 10⁶ joint vectors vs a per-vector Python loop (same run).

Also times the correction + YAML text of one calibration, and the URDF-origin FK used by ``robocal ur verify``.
"""

from __future__ import annotations

import math

import numpy as np
from _timing import best_time

from robocal.core.dh import DHParameters, fk_dh, fk_dh_loop
from robocal.core.ur import TEST_SET_3_DELTAS, correct_kinematics, fk_origins, nominal_dh
from robocal.formats.ur_kinematics import kinematics_to_text

N_BATCH = 1_000_000
N_LOOP = 20_000  # the pure-Python baseline is timed on a subset and reported per vector


def main() -> None:
    dh: DHParameters = nominal_dh("ur10e") + TEST_SET_3_DELTAS
    q = np.random.default_rng(0).uniform(-2 * math.pi, 2 * math.pi, (N_BATCH, 6))

    t_batch = best_time(lambda: fk_dh(dh, q), repeat=2)
    q_list = q[:N_LOOP].tolist()
    t_loop = best_time(lambda: [fk_dh_loop(dh, qi) for qi in q_list], repeat=1)
    t_np_each = best_time(lambda: [fk_dh(dh, q[i]) for i in range(2000)], repeat=1)
    per_batch = t_batch / N_BATCH
    per_loop = t_loop / N_LOOP
    per_np_each = t_np_each / 2000
    print(f"batched fk_dh, {N_BATCH} vectors: {t_batch:.3f} s ({per_batch * 1e9:.0f} ns/vector)")
    print(f"baseline pure-Python loop ({N_LOOP} vectors): {per_loop * 1e6:.1f} µs/vector "
          f"→ {per_loop * N_BATCH:.1f} s for {N_BATCH}; speed-up ×{per_loop / per_batch:.0f}")
    print(f"baseline fk_dh called per vector (2000 vectors): {per_np_each * 1e6:.1f} µs/vector; "
          f"speed-up ×{per_np_each / per_batch:.0f}")

    # the same chain through the corrected URDF origins (what verify evaluates)
    kin = correct_kinematics(dh)
    q_v = q[:100_000]
    t_origins = best_time(lambda: fk_origins(kin.xyz_array(), kin.rpy_array(), q_v), repeat=2)
    t_dh_v = best_time(lambda: fk_dh(dh, q_v), repeat=2)
    print(f"fk_origins (URDF path), 100000 vectors: {t_origins:.3f} s vs fk_dh {t_dh_v:.3f} s "
          f"(ratio {t_origins / t_dh_v:.2f})")

    t_corr = best_time(lambda: kinematics_to_text(correct_kinematics(dh)), repeat=20)
    print(f"correction + YAML text of one calibration: {t_corr * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
