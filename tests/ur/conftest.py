"""Pinned UR test vectors (ur_calibration's calibration_test.cpp delta sets) shared by the UR tests."""

from __future__ import annotations

import pytest

from robocal.core.dh import DHParameters
from robocal.core.ur import nominal_dh

# (base model, d, a, theta, alpha) deltas added to the nominal model (URSim α = ±1.570796327)
DELTA_SETS: dict[int, tuple[str, list[float], list[float], list[float], list[float]]] = {
    1: (
        "ur10",
        [
            0.00065609212979853,
            1.4442162376284788,
            0.854147723854608,
            -2.2989425877563705,
            -1.573498686836816e-05,
            1.9072435590711256e-05,
        ],
        [
            4.6311376834935676e-05,
            -0.00012568315331862312,
            0.00186216581161458,
            9.918593870679266e-05,
            4.215462720453189e-06,
            0,
        ],
        [
            -7.290070070824746e-05,
            -0.01713897289704999,
            -0.03707159413492756,
            0.054279462160583214,
            1.488984257025741e-07,
            1.551499479707493e-05,
        ],
        [
            0.000211987863869334,
            -0.0072553625957652995,
            -0.013483226769541364,
            0.0013495820227329425,
            -0.001263136163679901,
            0,
        ],
    ),
    2: (
        "ur10e",
        [
            -0.000144894975118076141,
            303.469135666158195,
            -309.88394307789747,
            6.41459904397394975,
            -4.48232900190081995e-05,
            -0.00087071402790364627,
        ],
        [
            0.000108651068627930392,
            0.240324175250532346,
            0.00180628180213493472,
            2.63076149165684402e-05,
            3.96638632500012715e-06,
            0,
        ],
        [
            1.59613525316931737e-07,
            -0.917209621528830232,
            7.12936131346499469,
            0.0710299029424392298,
            -1.64258976526054923e-06,
            9.17286101034808787e-08,
        ],
        [
            -0.000444781952841921679,
            -0.00160215112531214153,
            0.00631917793331091861,
            -0.00165055247340828437,
            0.000763682515545038854,
            0,
        ],
    ),
    3: (
        "ur10e",
        [
            -0.000160188285741325043,
            439.140974079900957,
            -446.027059806332147,
            6.88618689642360149,
            -3.86588496858186748e-05,
            -0.00087908274257374186,
        ],
        [
            2.12234865571205891e-05,
            0.632017132627700651,
            0.00229833638891230319,
            -4.61409023720933908e-05,
            -6.39280053471801522e-05,
            0,
        ],
        [
            -2.41478068943590252e-07,
            1.60233952386694556,
            -1.68607190752171299,
            0.0837331147700118711,
            -1.01260355871157781e-07,
            3.91986209186123702e-08,
        ],
        [
            -0.000650246557584166496,
            0.00139416666825590402,
            0.00693818880325995126,
            -0.000811641562390219562,
            0.000411120504570705592,
            0,
        ],
    ),
}


def calibrated_dh(set_id: int) -> DHParameters:
    """Nominal model + the controller deltas of test set ``set_id``."""
    model, d, a, th, al = DELTA_SETS[set_id]
    return nominal_dh(model) + DHParameters(theta_rad=th, a_m=a, d_m=d, alpha_rad=al)


@pytest.fixture(scope="session", params=[1, 2, 3], ids=["set1", "set2", "set3"])
def test_set(request: pytest.FixtureRequest) -> tuple[int, DHParameters]:
    """(set id, calibrated DH) for each of the three upstream delta sets."""
    return request.param, calibrated_dh(request.param)


@pytest.fixture(scope="session")
def dh_sets() -> dict[int, DHParameters]:
    """All three calibrated DH sets."""
    return {k: calibrated_dh(k) for k in DELTA_SETS}
