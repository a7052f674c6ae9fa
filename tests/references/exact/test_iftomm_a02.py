"""IFToMM A02, the N-four-bar: the closed form (references.exact.multibody.exact.NFourBar)
against values it does not compute itself.

- Exudyn's example of the same benchmark with N = 2 (jgerstmayr/EXUDYN,
  main/pythonDev/Examples/fourBarMechanismIftomm.py, in its comments) prints the point B0 and
  its velocity at t = 10 s from generalised-alpha runs at h = 2.5e-4 and 1.25e-4 s (second
  order, their differences shrink by 4): Richardson's extrapolation of that pair,
  x_h/2 + (x_h/2 - x_h)/3, leaves ~1e-8 of their error; the closed form must agree to 1e-7.
- Before its first singular configuration the mechanism is a regular closed loop: the loop
  reference (reduced coordinates with the loops as constraint rows, DOP853) agrees with it.
- The library files hold their joints and their energy along the closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from references.engines.exact.system import reference
from references.exact._util import rotation_angle
from references.exact.multibody.exact import NFourBar
from references.trajectory import system_energy
from reports.metrics.system import joint_gaps

#: B0 (m) and its velocity (m/s) at t = 10 s from Exudyn's comments, h = 2.5e-4 and 1.25e-4 s
EXUDYN_H = (np.array([0.3284552113, 0.9445195467, 1.423045728, -0.4948619021]),
            np.array([0.3284573768, 0.9445187937, 1.423050003, -0.4948670827]))  # fmt: skip


def a02(N: int) -> NFourBar:
    return NFourBar(N, 1.0, 1.0, 1.0 / 12.0, 9.81, 0.0, 1.0)


def test_b0_at_ten_seconds_matches_exudyns_extrapolated_runs():
    coarse, fine = EXUDYN_H
    extrapolated = fine + (fine - coarse) / 3.0
    p, v = a02(2).tip(10.0)
    ours = np.array([p[0, 0], p[0, 1], v[0, 0], v[0, 1]])
    assert np.max(np.abs(ours - extrapolated)) < 1e-7, ours - extrapolated
    # and the unextrapolated fine run is off by its own O(h^2) error, ~1e-6: not a tautology
    assert np.max(np.abs(ours - fine)) > 3e-7


def test_the_mechanism_rotates_through_its_singular_configuration():
    nf = a02(40)
    assert nf.case == "rotating"
    th, _ = nf.theta(np.linspace(0.0, 20.0, 2001))
    assert th[-1] > 2 * math.pi  # more than one turn: 4 passages through theta = pi/2 mod pi


@pytest.mark.parametrize("name", ["iftomm_a02_n2", "iftomm_a02"])
def test_library_files_hold_their_joints_and_energy_along_the_closed_form(name):
    sc = scenarios.load(name)
    t = np.linspace(0.0, sc.t_end, 401)
    ref = reference(sc, t)
    assert ref.kind == "n_four_bar" and ref.accuracy < 1e-11
    gaps = joint_gaps(sc, ref.trajectory)
    assert max(float(np.max(g["gap"])) for g in gaps.values()) < 1e-13
    assert max(float(np.max(g["angle"])) for g in gaps.values()) < 1e-13
    E = system_energy(sc, ref.trajectory)
    assert float(np.max(np.abs(E - E[0]))) < 1e-12 * sc.energy_scale


def test_loop_reference_agrees_before_the_first_singular_configuration():
    """The N = 2 mechanism reaches theta = pi/2 at t_s; on [0, 0.8 t_s] the loop reference
    agrees with the closed form to 1e-10."""
    nf = a02(2)
    t = np.linspace(0.0, 3.0, 30001)
    th, _ = nf.theta(t)
    ts = float(t[np.argmax(th > 0.5 * math.pi)])
    sc = scenarios.load("iftomm_a02_n2")
    tt = np.linspace(0.0, 0.8 * ts, 41)
    exact = reference(sc, tt)
    num = reference(sc.replace(reference="numerical", t_end=float(tt[-1])), tt)
    ang = rotation_angle(num.trajectory.rotation.reshape(-1, 3, 3),
                         exact.trajectory.rotation.reshape(-1, 3, 3))  # fmt: skip
    assert float(np.max(ang)) < 1e-10
    assert float(np.max(np.abs(num.trajectory.position - exact.trajectory.position))) < 1e-10
