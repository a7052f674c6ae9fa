"""Force elements in director_model.system (a constant joint torque, a linear spring-damper)
against exact motions and an independent ODE, with their orders.

References (none from the integrator):
- a body turning about a fixed hinge through its centre of mass under a constant torque,
  theta = tau t^2 / (2 I) (Newton's second law about a fixed axis);
- a slider on a level rail pulled by a spring-damper to a fixed point: the damped oscillator's
  closed form u(t) = exp(-z w t) (u0 cos(wd t) + z w u0 / wd sin(wd t));
- a rod hinged at one end under gravity and a constant torque about the hinge: the scalar
  pendulum equation I_O theta'' = tau + m g (L/2) cos(theta), written here and integrated by
  scipy's DOP853 at rtol 1e-13 (1e-12 relative at most).
Bounds are 3x the errors measured when the tests were written (in the comments), orders from
the error ratio at dt and dt/2 within 0.15 of the scheme's order (measured: within 0.12).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from director_model.system import (
    Body,
    InvalidJointError,
    Joint,
    Spring,
    Torque,
    simulate_system,
)

STEPS = {"rattle": (1e-3, 5e-4), "rattle4": (1e-2, 5e-3), "rattle6": (2e-2, 1e-2)}
ORDER = {"rattle": 2, "rattle4": 4, "rattle6": 6}


def _every(dt, period=0.1):
    return int(round(period / dt))


def hinge_torque(scheme, dt, tau=0.35, t_end=2.0):
    """Largest rotation-matrix entry error of the torqued hinge against its exact motion, and
    the run."""
    b = [Body("a", 2.0, (0.3, 0.5, 0.7))]
    j = [Joint("revolute", "a", None, (0, 0, 0), (0, 0, 0), (0, 0, 1), (0, 0, 1), name="h")]
    tr = simulate_system(b, j, dt=dt, t_end=t_end, scheme=scheme, save_every=_every(dt),
                         torques=[Torque("h", tau)])  # fmt: skip
    th = tau * tr.t**2 / (2 * 0.7)
    c, s = np.cos(th), np.sin(th)
    Rz = np.zeros((len(th), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    return float(np.abs(tr.rotation[:, 0] - Rz).max()), tr


def slider(scheme, dt, c, m=1.5, k=40.0, l0=2.7, t_end=3.0):
    """Position error (m) of the spring-damper slider against the damped oscillator, and the
    run. The spring runs from the slider's centre (x0 = 1 m) to the world point x = -2 m, so it
    starts 0.3 m beyond its rest length and stays long (its direction never flips)."""
    b = [Body("s", m, (0.1, 0.1, 0.1), position=(1.0, 0, 0))]
    j = [Joint("prismatic", "s", None, (0, 0, 0), (1.0, 0, 0), (1, 0, 0), (1, 0, 0), name="p")]
    sp = [Spring("s", None, (0, 0, 0), (-2.0, 0, 0), k, c, l0)]
    tr = simulate_system(b, j, dt=dt, t_end=t_end, scheme=scheme, springs=sp,
                         save_every=_every(dt))  # fmt: skip
    u0 = 1.0 + 2.0 - l0
    w = math.sqrt(k / m)
    z = c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)
    t = tr.t
    u = np.exp(-z * w * t) * (u0 * np.cos(wd * t) + z * w * u0 / wd * np.sin(wd * t))
    return float(np.abs(tr.position[:, 0, 0] - (u - 2.0 + l0)).max()), tr


def torqued_pendulum(scheme, dt, tau=1.5, m=1.2, L=0.8, t_end=3.0):
    """Position error (m) of a rod hinged at one end (about +y, gravity -z) under a constant
    torque about the hinge, against the scalar pendulum equation; and the run."""
    b = [Body("p", m, (0.002, m * L * L / 12, m * L * L / 12), position=(L / 2, 0, 0))]
    j = [Joint("revolute", "p", None, (-L / 2, 0, 0), (0, 0, 0), (0, 1, 0), (0, 1, 0),
               name="h")]  # fmt: skip
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=dt, t_end=t_end, scheme=scheme,
                         torques=[Torque("h", tau)], save_every=_every(dt))  # fmt: skip
    I_O = m * L * L / 3
    # theta about +y turns the rod's x axis to (cos, 0, -sin): V = -m g (L/2) sin(theta)
    sol = solve_ivp(lambda _, y: (y[1], (tau + m * 9.81 * (L / 2) * math.cos(y[0])) / I_O),
                    (0, t_end), (0.0, 0.0), method="DOP853", rtol=1e-13, atol=1e-14,
                    dense_output=True)  # fmt: skip
    th = sol.sol(tr.t)[0]
    exact = np.stack([L / 2 * np.cos(th), 0 * th, -L / 2 * np.sin(th)], axis=1)
    return float(np.abs(tr.position[:, 0] - exact).max()), tr


# measured errors at the finer step of STEPS (the bound is 3x)
HINGE = {"rattle": 1.75e-8, "rattle4": 5.96e-11, "rattle6": 3.4e-16}
SLIDER = {(0.0, "rattle"): 1.14e-6, (0.0, "rattle4"): 1.21e-7, (0.0, "rattle6"): 3.18e-11,
          (0.6, "rattle"): 6.84e-7, (0.6, "rattle4"): 7.08e-8,
          (0.6, "rattle6"): 1.86e-11}  # fmt: skip
PENDULUM = {"rattle": 9.49e-5, "rattle4": 1.44e-4, "rattle6": 2.57e-7}


@pytest.mark.parametrize("scheme", list(ORDER))
def test_a_constant_torque_turns_a_hinge_by_tau_t2_over_2I(scheme):
    e1, _ = hinge_torque(scheme, STEPS[scheme][0])
    e2, tr = hinge_torque(scheme, STEPS[scheme][1])
    assert e2 < 3 * HINGE[scheme] + 1e-14  # rattle6 is at round-off
    if scheme != "rattle6":
        assert abs(math.log2(e1 / e2) - ORDER[scheme]) < 0.15
    # the energy with the torque's potential -tau theta is conserved to the scheme's error
    assert np.ptp(tr.energy) < 1e-7


@pytest.mark.parametrize("c", [0.0, 0.6])
@pytest.mark.parametrize("scheme", list(ORDER))
def test_a_spring_damper_slider_follows_the_damped_oscillator(scheme, c):
    e1, _ = slider(scheme, STEPS[scheme][0], c)
    e2, tr = slider(scheme, STEPS[scheme][1], c)
    assert e2 < 3 * SLIDER[c, scheme]
    # the damper is implicit and symmetric in the step: the compositions keep their order
    assert abs(math.log2(e1 / e2) - ORDER[scheme]) < 0.15
    dE = np.diff(tr.energy)
    if c == 0:
        assert np.ptp(tr.energy) < 2e-5  # 1/2 k 0.3^2 = 1.8 J in play
    else:  # a damper only takes energy out
        assert dE.max() < 1e-12


@pytest.mark.parametrize("scheme", list(ORDER))
def test_a_torqued_pendulum_follows_its_scalar_equation(scheme):
    e1, _ = torqued_pendulum(scheme, STEPS[scheme][0])
    e2, _ = torqued_pendulum(scheme, STEPS[scheme][1])
    assert e2 < 3 * PENDULUM[scheme]
    assert abs(math.log2(e1 / e2) - ORDER[scheme]) < 0.15


def _one_body():
    b = [Body("a", 1.0, (0.1, 0.1, 0.1), position=(1.0, 0, 0))]
    j = [Joint("prismatic", "a", None, (0, 0, 0), (1.0, 0, 0), (1, 0, 0), (1, 0, 0), name="p")]
    return b, j


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"torques": [Torque("p", 1.0)]}, "prismatic"),
        ({"torques": [Torque("nope", 1.0)]}, "unknown joint"),
        ({"springs": [Spring("a", "b", (0, 0, 0), (0, 0, 0), 1.0, 0.0, 1.0)]}, "unknown body"),
        ({"springs": [Spring("a", None, (0, 0, 0), (0, 0, 0), 1.0, 0.0, 0.0)]}, "rest_length"),
        ({"springs": [Spring("a", None, (0, 0, 0), (1.0, 0, 0), 1.0, 0.0, 1.0)]}, "length 0"),
        ({"springs": [Spring("a", None, (0, 0, 0), (0, 0, 0), -1.0, 0.0, 1.0)]}, ">= 0"),
    ],
)
def test_a_bad_force_element_is_refused_by_name(kw, words):
    b, j = _one_body()
    with pytest.raises(InvalidJointError, match=words):
        simulate_system(b, j, dt=1e-3, t_end=1e-3, **kw)
