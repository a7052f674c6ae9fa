"""Drake's integrators as the adapter offers them, each named for what it is (Drake's scheme
names, as in ``ResetIntegratorFromFlags`` and the Drake documentation of
``systems::analysis``), and the families of those that fit none of the suite's:

- continuous mode (``MultibodyPlant(time_step=0)``) at a FIXED step dt
  (``set_fixed_step_mode(True)``, maximum step size dt): ``explicit_euler``,
  ``semi_explicit_euler``, ``runge_kutta2``/``3``/``5``, ``bogacki_shampine3``,
  ``implicit_euler``, ``velocity_implicit_euler``, ``radau1``, ``radau3``, ``cenic``;
- continuous mode ERROR-CONTROLLED at a target accuracy (``adaptive``; dt is only the interval
  of the checkpoints; the largest step is the horizon): every scheme with an error estimate;
- discrete mode (``MultibodyPlant(time_step=dt)``, SAP): Drake's discrete update.

Every one integrates the joint's coordinates in their vector space: a quaternion is advanced
additively and never renormalised (:mod:`references.conventions` shows the norm's drift in
the orthonormality of R). The Simulator's silent default (runge_kutta3, error-controlled at
accuracy 1e-4, largest step 0.1 s) is always replaced, and the replacement read back.
"""

from __future__ import annotations

from references.engines.integrators import Family, Integrator, register_family

EXPLICIT_EULER = register_family(
    Family(
        "explicit Euler",
        "first order, forward Euler on the coordinates: positions and velocities both from "
        "the derivatives at the start of the step (not semi-implicit)",
    )
)
SEMI_EXPLICIT_Q = register_family(
    Family(
        "semi-implicit Euler on quaternion coordinates",
        "first order: the velocity update of semi-implicit Euler (gyroscopic term explicit), "
        "then the quaternion advanced additively (q += h N(q) v) and never renormalised; the "
        "rates agree with MuJoCo Euler's to round-off, the attitude does not (measured: 1e-10 "
        "and 3e-2 rad on dzhanibekov over 30 s)",
    )
)
EXPLICIT_RK = register_family(
    Family(
        "explicit Runge-Kutta on coordinates",
        "explicit Runge-Kutta methods applied to (q, v) as a vector ODE: a quaternion is "
        "integrated as four numbers, not on SO(3), and not renormalised",
    )
)
IMPLICIT_RK = register_family(
    Family(
        "implicit Runge-Kutta on coordinates",
        "fully implicit methods (implicit Euler, Radau IIA) on (q, v) as a vector ODE, "
        "solved by Newton iterations with a finite-difference Jacobian",
    )
)
CONVEX = register_family(
    Family(
        "convex implicit (CENIC)",
        "Drake's CENIC: a convex, error-controlled implicit integrator built for contact",
    )
)
DISCRETE = register_family(
    Family(
        "discrete (SAP)",
        "Drake's discrete-time MultibodyPlant update with the SAP solver: velocities from the "
        "start-of-step dynamics (joint damping implicit), then positions from the new "
        "velocities",
    )
)


#: the configurations in the default suite: the first-order one every engine shares, Drake's
#: most accurate explicit scheme at a fixed step and under error control; the others cost 80 s
#: (fixed steps) and 150 s (error-controlled sweeps) on the default scenarios and run on request
_DEFAULT_SUITE = ("semi_explicit_euler", "runge_kutta5", "runge_kutta5 (error-controlled)")


def _fixed(scheme, family, order, description, evals=None):
    return Integrator(
        scheme,
        family,
        order,
        description,
        evals_per_step=evals,
        options={"mode": "fixed step", "scheme": scheme},
        default=scheme in _DEFAULT_SUITE,
    )


def _controlled(scheme, family, order, description):
    name = f"{scheme} (error-controlled)"
    return Integrator(
        name,
        family,
        order,
        description,
        evals_per_step=None,
        options={"mode": "error-controlled", "scheme": scheme},
        adaptive=True,
        default=name in _DEFAULT_SUITE,
    )


#: Drake's convex integrator (CENIC), unlike every other scheme here: it needs a Diagram with a
#: SceneGraph (it refuses a bare plant: "must be given a Diagram"), it counts no derivative
#: evaluations (its runs report none, and an error-controlled run's budget counts its steps),
#: and its position update keeps a quaternion at unit norm
CONVEX_SCHEME = "cenic"

_QUAT = "the quaternion is advanced additively and never renormalised"

INTEGRATORS = (
    _fixed(
        "semi_explicit_euler",
        SEMI_EXPLICIT_Q.name,
        1,
        "Drake's SemiExplicitEulerIntegrator: v += h a(q, v) with the gyroscopic term "
        f"explicit, then q += h N(q) v with the new v; {_QUAT} (unlike MuJoCo Euler's "
        "exponential map).",
        evals=1.0,
    ),
    _fixed(
        "explicit_euler",
        EXPLICIT_EULER.name,
        1,
        f"Drake's ExplicitEulerIntegrator: x += h f(x) for x = (q, v); {_QUAT}.",
        evals=1.0,
    ),
    _fixed(
        "runge_kutta2",
        EXPLICIT_RK.name,
        2,
        f"Drake's RungeKutta2Integrator (explicit trapezoid, 2 stages); {_QUAT}.",
        evals=2.0,
    ),
    _fixed(
        "runge_kutta3",
        EXPLICIT_RK.name,
        3,
        "Drake's RungeKutta3Integrator (3 stages, the embedded 2nd-order error estimate is "
        f"computed but unused at a fixed step); {_QUAT}.",
        evals=3.0,
    ),
    _fixed(
        "bogacki_shampine3",
        EXPLICIT_RK.name,
        3,
        "Drake's BogackiShampine3Integrator (3rd order, 4 evaluations per step with the "
        f"embedded estimate); {_QUAT}.",
        evals=4.0,
    ),
    _fixed(
        "runge_kutta5",
        EXPLICIT_RK.name,
        5,
        "Drake's RungeKutta5Integrator (Dormand-Prince 5(4), 7 evaluations per step as "
        f"Drake counts them); {_QUAT}.",
        evals=7.0,
    ),
    _fixed(
        "implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's ImplicitEulerIntegrator with its default step doubling: every step of h is "
        "a full implicit Euler step plus two half steps, and the two half steps are kept "
        f"(Newton iterations, finite-difference Jacobian); {_QUAT}.",
    ),
    _fixed(
        "velocity_implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's VelocityImplicitEulerIntegrator: implicit in v, q from the new v, with step "
        f"doubling (two half steps kept); {_QUAT}.",
    ),
    _fixed(
        "radau1",
        IMPLICIT_RK.name,
        1,
        "Drake's RadauIntegrator with 1 stage (Radau IIA = implicit Euler, one step of h; "
        f"Newton iterations, finite-difference Jacobian); {_QUAT}.",
    ),
    _fixed(
        "radau3",
        IMPLICIT_RK.name,
        3,
        f"Drake's RadauIntegrator with 2 stages (Radau IIA, order 3); {_QUAT}.",
    ),
    _fixed(
        CONVEX_SCHEME,
        CONVEX.name,
        1,
        "Drake's CenicIntegrator (convex implicit step) at a fixed step; it needs a Diagram "
        "with a SceneGraph, which the adapter builds (with no geometry).",
    ),
    Integrator(
        "discrete SAP",
        DISCRETE.name,
        1,
        "MultibodyPlant(time_step=dt) with DiscreteContactApproximation.kSap, stepped by the "
        "Simulator's periodic discrete update: v from the start-of-step dynamics, then "
        f"q += h N(q) v with the new v; {_QUAT}.",
        evals_per_step=1.0,
        options={"mode": "discrete", "scheme": "discrete SAP"},
        default=False,
    ),
    _controlled(
        "runge_kutta3",
        EXPLICIT_RK.name,
        3,
        "Drake's RungeKutta3Integrator with error control (embedded 2nd-order estimate) at "
        f"the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "bogacki_shampine3",
        EXPLICIT_RK.name,
        3,
        "Drake's BogackiShampine3Integrator with error control (embedded 2nd-order "
        f"estimate) at the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "runge_kutta5",
        EXPLICIT_RK.name,
        5,
        "Drake's RungeKutta5Integrator (Dormand-Prince 5(4)) with error control at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        "implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's ImplicitEulerIntegrator with error control by step doubling at the target "
        f"accuracy; {_QUAT}.",
    ),
    _controlled(
        "velocity_implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's VelocityImplicitEulerIntegrator with error control by step doubling at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        "radau1",
        IMPLICIT_RK.name,
        1,
        "Drake's 1-stage RadauIntegrator (implicit Euler) with error control (implicit "
        f"trapezoid estimate) at the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "radau3",
        IMPLICIT_RK.name,
        3,
        "Drake's 2-stage RadauIntegrator (Radau IIA, order 3) with error control at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        CONVEX_SCHEME,
        CONVEX.name,
        1,
        "Drake's CenicIntegrator with error control at the target accuracy (Diagram with an "
        "empty SceneGraph).",
    ),
)
