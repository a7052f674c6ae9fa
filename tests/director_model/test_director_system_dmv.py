"""The system kernel's rotation solve (the discrete Moser-Veselov equation of one body,
F(w) = 2 (I w + w x I w) - h (1 + |w|^2) pi = 0 for the Gibbs vector w): from its own start
(``_bodies._dmv``) and from the solution for a nearby momentum with that solve's inverse
Jacobian (``_bodies._dmv_iterate``, the Newton iterations of the joint multipliers after the
first). Both must solve the equation to rounding (the residual at most a few eps of its
terms) and agree with each other to a few units in the last place of w; random bodies,
momenta and steps."""

from __future__ import annotations

import numpy as np
import pytest

from director_model.system import _bodies as BD

EPS = np.finfo(float).eps


def _residual(I, w, pi, h):
    """|F(w)| against the size of its terms."""
    Iw = I * w
    F = 2.0 * (Iw + np.cross(w, Iw)) - h * (1.0 + w @ w) * pi
    scale = 2.0 * np.abs(Iw).max() + h * (1.0 + w @ w) * np.abs(pi).max()
    return np.abs(F).max() / scale


@pytest.mark.parametrize("seed", range(6))
def test_dmv_from_a_nearby_solution_finds_the_same_rotation(seed):
    rng = np.random.default_rng(seed)
    I = rng.uniform(0.05, 2.0, 3)
    pi = rng.standard_normal(3) * rng.uniform(0.1, 20.0)
    h = float(rng.choice([1e-4, 1e-3, 1e-2]))
    ok, w0, w1, w2, Ai = BD._dmv(*I, *(1.0 / I), *pi, h)
    assert ok
    w = np.array([w0, w1, w2])
    assert _residual(I, w, pi, h) < 8 * EPS
    # the momentum moved by a multiplier correction (1e-9 relative), then both solves
    pi2 = pi * (1.0 + 1e-9 * rng.standard_normal(3))
    ok, c0, c1, c2, _ = BD._dmv(*I, *(1.0 / I), *pi2, h)
    cold = np.array([c0, c1, c2])
    ok2, v0, v1, v2 = BD._dmv_iterate(*I, *pi2, h, w0, w1, w2, Ai)
    warm = np.array([v0, v1, v2])
    assert ok and ok2
    assert _residual(I, warm, pi2, h) < 8 * EPS
    assert np.abs(warm - cold).max() <= 8 * EPS * np.abs(cold).max()
    assert np.abs(warm - w).max() > 0  # it did move to the new momentum's solution


def test_dmv_iterate_refuses_a_rotation_of_90_degrees_or_more():
    """A symmetric body (I = 1) with h pi = (0.9, 0, 0): 0.9 w^2 - 2 w + 0.9 = 0 along x has
    the roots 0.627 (a 64-degree turn) and 1.596 (116 degrees); started at 1.6 with the
    Jacobian there the iteration finds the second, which is refused (|w| >= 1)."""
    root = (2.0 + np.sqrt(4.0 - 4 * 0.81)) / 1.8
    Ai = (1.0 / (2.0 - 2 * 0.9 * 1.6), 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5)
    ok, w0, w1, w2 = BD._dmv_iterate(1.0, 1.0, 1.0, 90.0, 0.0, 0.0, 0.01, 1.6, 0.0, 0.0, Ai)
    assert not ok and abs(w0 - root) < 1e-12 and w1 == w2 == 0.0
    Ai = (1.0 / (2.0 - 2 * 0.9 * 0.6), 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5)
    ok, w0, *_ = BD._dmv_iterate(1.0, 1.0, 1.0, 90.0, 0.0, 0.0, 0.01, 0.6, 0.0, 0.0, Ai)
    assert ok and abs(w0 - (2.0 - np.sqrt(4.0 - 4 * 0.81)) / 1.8) < 1e-12
