"""The horizon of a trajectory reference (references/exact/multibody/horizon.py) on a double
spherical pendulum of rigid bodies: finite and checked against an independent run when the
motion is chaotic, the whole run when it is a small regular swing."""

from __future__ import annotations

import numpy as np
import pytest

from references.conventions import matrix_to_quat_wxyz
from references.exact._util import rot_axis, rotation_angle
from references.exact.multibody import Body, Joint, Tree, solve
from references.exact.multibody.horizon import trajectory_horizon

TREE = Tree(
    [Body("upper", 1.0, (0.02, 0.021, 0.003)), Body("lower", 0.8, (0.015, 0.016, 0.002))],
    [
        Joint("spherical", "upper", None, (0, 0, 0), (0, 0, 0.25)),
        Joint("spherical", "lower", "upper", (0, 0, -0.25), (0, 0, 0.2)),
    ],
    (0, 0, -9.81),
)


def quats(*rotations):
    return np.concatenate(
        [matrix_to_quat_wxyz(rot_axis(np.asarray(a, float), ang)[0]) for a, ang in rotations]
    )


def test_chaotic_double_spherical_pendulum_has_a_finite_horizon():
    q0 = quats(((1, 0, 0), 2.0), ((0, 1, 0), 1.0))  # upper link raised 115 degrees
    u0 = np.array([0.0, 3.0, 1.0, 2.0, 0.0, 0.5])
    t = np.linspace(0.0, 9.0, 181)
    tol = 1e-6
    hz = trajectory_horizon(TREE, q0, u0, t, tol_attitude=tol, probes=2)
    # measured: horizon 7.6 s with these two copies (6.85 s with three), divergence growing
    # at 2.1/s (a Lyapunov time of 0.5 s)
    assert not hz.within and 2.0 < hz.horizon < 8.5
    assert hz.growth_rate > 0.5
    assert np.max(hz.divergence["attitude"]) > 10 * tol  # chaos: the copies do part
    # an independent run (rtol 1e-12: errors ~10 times the reference's, of the size of the
    # perturbation) agrees with the reference to the tolerance inside the horizon
    other = solve(TREE, q0, u0, t, rtol=1e-12, estimate=False)
    ang = rotation_angle(hz.reference.R.reshape(-1, 3, 3), other.R.reshape(-1, 3, 3))
    ang = ang.reshape(len(t), -1).max(axis=1)
    assert np.max(ang[t <= hz.horizon]) < tol


def test_small_regular_swing_is_meaningful_over_the_whole_run():
    q0 = quats(((1, 0, 0), 0.05), ((0, 1, 0), 0.0))
    u0 = 0.05 * np.array([0.0, 3.0, 1.0, 2.0, 0.0, 0.5])
    t = np.linspace(0.0, 9.0, 91)
    hz = trajectory_horizon(TREE, q0, u0, t, tol_attitude=1e-6, probes=2)
    assert hz.within and hz.horizon == t[-1]
    assert np.max(hz.divergence["attitude"]) < 1e-9  # measured 6e-11: no exponential growth


def test_bad_tolerance_is_refused():
    with pytest.raises(ValueError, match="tolerances must be > 0"):
        trajectory_horizon(
            TREE,
            quats(((1, 0, 0), 0.1), ((1, 0, 0), 0.1)),
            np.zeros(6),
            [0.0, 1.0],
            tol_attitude=0.0,
        )
