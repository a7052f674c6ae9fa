"""The declarations of the metric catalog: every metric the suite measures, once, as plain data.

One :class:`Metric` per metric says what it is (name, unit, what it is measured against, its
round-off floor), how it is shown (title, short name, figure panel), how it is judged (default
tolerance, which direction is better) and where it applies (single bodies, systems, which
computation). Every table the suite needs is derived from :data:`METRICS`: the result store's
columns, the gate's floors and slack, the report's titles and short names, the verdicts'
default tolerances, the errors figure's panels, the streamed metrics and the names a
scenario's ``[tolerances]`` table accepts (:data:`scenarios.model.TOLERANCE_METRICS`).

Why here, in the scenario layer, as data without functions: a scenario file bounds metrics by
name, so scenario validation must know the names, and the layer rule (``tests/test_layers.py``)
forbids ``scenarios`` importing ``reports``. The declarations therefore sit in the lowest
layer of the suite and import nothing; how each metric is computed is attached to its name in
``reports.metrics`` (the ``measures`` decorator of :mod:`reports.metrics.catalog`, on the
function in :mod:`reports.metrics.body` or :mod:`reports.metrics.system`), which checks on
import that every metric declared here has its function and that no function names a metric
not declared here. Adding a metric is one entry below, its function (with its ``measures``
line) and its test.

The order of :data:`METRICS` is the order of the store's metric columns. The report shows the
metrics compared with an exact solution first (a reference trajectory, or an exact
observable), then the others, each group in this order (:func:`shown_order`).
"""

from __future__ import annotations

from dataclasses import dataclass

#: computed at every saved sample and reduced to its largest value over the run; streamed
#: over long runs as a running maximum over every step (``reports.metrics.streaming``)
POINTWISE = "pointwise"
#: one number per run from the run and an exact value of an observable (e.g. a flip interval)
OBSERVABLE = "observable"
#: one number per configuration from the runs of a dt sweep (``add_convergence_orders``)
SWEEP = "sweep"


@dataclass(frozen=True)
class Metric:
    """One metric of a run (a column of the results store and of ``results.csv``).

    - ``name``: the column and the key of a ``[tolerances]`` table;
    - ``unit``: of the value ("1" for a ratio to ``scale``, "rad", "rad/s", "m");
    - ``per``: for a ratio, the symbol of the scale it is measured in ("E_c"), shown as its
      unit on axes and in tables; "" for a metric with a unit of its own;
    - ``scale``: what the value is measured against, the size of what it measures in the
      scenario, never a quantity that may vanish (text for the docs);
    - ``floor``: round-off floor, in the metric's unit: values below it are round-off and
      compare as equal (gate, compare, report); None: none declared (compared as they are);
    - ``title``: the column title of the report's scenario tables, with the unit; None: not
      a column there;
    - ``short``: the name in verdict texts ("fail (attitude, energy)"); None: the name;
    - ``tolerance``: the default verdict bound for every family (largest value that passes);
      None: reported, not judged unless a family, an integrator or a scenario bounds it;
    - ``higher_is_better``: a larger value is better (an order); otherwise it is an error;
    - ``slack``: for a higher-is-better metric, by how much it may fall before it is worse;
    - ``body``, ``system``, ``contact``: whether it applies to a single body, to a system of
      bodies, to a scene of bodies in contact (computed by ``reports.metrics.contact``);
    - ``headline``: the scene kinds (``scenarios.SCENE_KINDS``) whose runs are summed up by
      this error wherever a run is one number (the scorecard, the short verdict tables,
      summary.json, the work-precision answers); each kind has exactly one such metric;
    - ``headline_energy``: likewise the scene kinds whose runs show this energy error beside
      it (the energy drift of a conservative motion, the energy gained in contact);
    - ``kind``: :data:`POINTWISE`, :data:`OBSERVABLE` or :data:`SWEEP`;
    - ``reference``: needs the reference trajectory (NaN without one);
    - ``series``: the name of its per-sample series, written beside a single body's
      trajectory (the figures read it); None: not written;
    - ``panel``: the y label of its panel in the errors-over-time figure; None: no panel;
    - ``panel_top``: the top of that panel's log axis, beyond which a run has blown up (a
      curve is cut there and marked);
    - ``scale_column``, ``scale_unit``: the store column holding the run's scale and its
      unit, shown under the panel's label.
    """

    name: str
    unit: str
    scale: str
    per: str = ""
    floor: float | None = None
    title: str | None = None
    short: str | None = None
    tolerance: float | None = None
    higher_is_better: bool = False
    slack: float | None = None
    body: bool = True
    system: bool = False
    contact: bool = False
    headline: tuple[str, ...] = ()
    headline_energy: tuple[str, ...] = ()
    kind: str = POINTWISE
    reference: bool = False
    series: str | None = None
    panel: str | None = None
    panel_top: float | None = None
    scale_column: str | None = None
    scale_unit: str = ""


# Default tolerances are this suite's choice of "right": the attitude to 0.1 rad (a flip at the
# right time, a top on the right side), energy and momentum to 1 % of the scenario's scales,
# phase observables to 1 %, and R orthonormal to 1e-9 (every engine that renormalises keeps
# ~1e-15). Below its round-off floor a value is round-off: 3e-16 against 9e-15 is no change.
METRICS: tuple[Metric, ...] = (
    Metric(
        "energy_drift_max", "1",
        "E_c, the energy in play over the horizon: the largest kinetic energy the motion can "
        "reach, never E0 nor energy that cannot change hands (a body on a level slider) "
        "(Scenario.energy_scale; SystemScenario.energy_scale: T0 + V0 - V_low over the "
        "configurations the joints allow, scenarios/energy.py)",
        per="E_c", floor=1e-11, title="energy drift [E_c]", short="energy", tolerance=1e-2,
        system=True, headline_energy=("body", "system"), series="energy_drift",
        panel="|E − E₀| / E_c [1]", panel_top=10.0, scale_column="energy_scale",
        scale_unit="J",
    ),
    Metric(
        "energy_drift_rot_max", "1",
        "a free body's rotational energy 1/2 W.IW (Scenario.rotational_energy_scale)",
        per="E_rot,c", floor=1e-11, short="rotational energy", tolerance=1e-2,
    ),
    Metric(
        "energy_drift_trans_max", "1",
        "a free body's largest translational kinetic energy over the horizon "
        "(Scenario.translational_energy_scale)",
        per="E_tr,c", floor=1e-11, short="translational energy", tolerance=1e-2,
    ),
    Metric(
        "momentum_drift_max", "1",
        "L_c = sqrt(2 E_rot I_max) (Scenario.momentum_scale); a floating system's linear "
        "momentum also over p_c",
        per="L_c", floor=1e-11, title="momentum drift [L_c]", short="momentum",
        tolerance=1e-2, system=True, series="momentum_drift", panel="|ΔL| / L_c [1]",
        panel_top=10.0, scale_column="momentum_scale", scale_unit="kg m²/s",
    ),
    Metric(
        "linear_momentum_drift_max", "1",
        "p_c = sqrt(2 m E_tr,c), the momentum of a free body's largest translational kinetic "
        "energy over the horizon (Scenario.translational_energy_scale)",
        per="p_c", floor=1e-11, title="linear momentum drift [p_c]", short="linear momentum",
        tolerance=1e-2,
    ),
    Metric(
        "orthonormality_max", "1", "none: ||R^T R - 1||_F is relative to the identity",
        floor=1e-11, title="‖RᵀR − 1‖", short="orthonormality", tolerance=1e-9, system=True,
        contact=True, series="orthonormality",
    ),
    Metric(
        "constraint_velocity_max", "1", "w_c, the rate scale (Scenario.rate_scale)",
        per="w_c", floor=1e-11, title="velocity constraint [w_c]", short="velocity constraint",
    ),
    Metric(
        "attitude_error_max", "rad", "none: an angle", floor=1e-10,
        title="attitude error [rad]", short="attitude", tolerance=0.1, system=True,
        contact=True, headline=("body", "system"), reference=True, series="attitude_error",
        panel="attitude error [rad]", panel_top=4.0,
    ),
    Metric(
        "omega_error_max", "rad/s", "none: |W - W_ref| in rad/s", floor=1e-10,
        title="W error [rad/s]", short="W", system=True, contact=True, reference=True,
        series="omega_error",
    ),
    Metric(
        "position_error_max", "m", "none: |x_G - x_G,ref| in m", floor=1e-10,
        title="x_G error [m]", short="position", system=True, contact=True,
        reference=True,
        # a contact scene's: a block's attitude hardly changes whether it holds, creeps or
        # slides; its position against the closed form tells them apart
        headline=("contact",),
    ),
    Metric(
        "flip_interval_error", "1", "the exact flip interval", floor=1e-9,
        title="flip interval error [rel.]", short="flip interval", tolerance=1e-2,
        kind=OBSERVABLE,
    ),
    Metric(
        "nutation_period_error", "1", "the exact nutation period", floor=1e-9,
        title="nutation period error [rel.]", short="nutation period", tolerance=1e-2,
        kind=OBSERVABLE,
    ),
    # systems of bodies: a joint open by 1 mm or its axes 1 mrad apart on the library's links
    # of 0.5 to 1.4 m is the finer precision class (1e-3) of the IFToMM benchmarks (Gonzalez
    # et al. 2006) on a link's size, and 1e11 times the round-off the director schemes keep;
    # the branch check as the attitude (0.1 rad)
    Metric(
        "joint_gap_max", "m", "none: a distance in m", title="joint gap [m]", tolerance=1e-3,
        body=False, system=True,
    ),
    Metric(
        "joint_angle_gap_max", "rad", "none: an angle", title="joint axes gap [rad]",
        tolerance=1e-3, body=False, system=True,
    ),
    Metric(
        "branch_error", "rad", "none: an angle", title="branch error [rad]", tolerance=0.1,
        body=False, system=True,
    ),
    # bodies in contact (reports.metrics.contact): measured on the engine's states and its own
    # contact forces against the closed form of the scene (references.exact.contact); L is
    # the smallest half-size of a body's shape, F_c the scene's weight plus its external
    # forces, V_c = sqrt(|g| L), E_c the energy in play. The bounds: creep 1e-4 m/s, 0.1 % of
    # the library's 0.1 m half-sizes per second (a grasped part would drift 6 mm a minute);
    # penetration 1e-3 m, 1 % of those half-sizes; energy gained 1 % of E_c (as the drifts);
    # rolling onset 5 % of t* (the library's dt is 0.5 % of its t*, its saves 5 %, crossings
    # interpolated); final rolling speed 1 % of v*; rebound ratio h1/h0 within 0.05 of e^2;
    # law residuals and support forces 1 % of F_c (of the weight carried).
    Metric(
        "creep_speed", "m/s",
        "none: the mean speed of a body over the second half of a run where Coulomb sticks "
        "(exact 0), shown in um/s", floor=1e-12, title="creep [m/s]", short="creep",
        tolerance=1e-4, body=False, contact=True, reference=True,
    ),
    Metric(
        "slide_distance", "m",
        "none: the distance a body's centre of mass moved over the run (the stick/slide "
        "matrix: it slides when this exceeds L/10)", title="slide distance [m]",
        body=False, contact=True,
    ),
    Metric(
        "stick_slide_mismatch", "1",
        "none: 1 when the run slides (moves more than L/10) where Coulomb sticks or sticks "
        "where it slides, else 0", title="stick/slide wrong", short="stick/slide",
        tolerance=0.5, body=False, contact=True, reference=True,
    ),
    Metric(
        "penetration_max", "m", "none: the deepest overlap of a listed pair over the run, "
        "from the suite's geometry on the engine's states (scale L)", floor=1e-12,
        title="penetration [m]", short="penetration", tolerance=1e-3, body=False,
        contact=True,
    ),
    Metric(
        "penetration_rest", "m", "none: the mean overlap over the last tenth of a run that "
        "ends at rest (stick and rest cases)", floor=1e-12, title="penetration at rest [m]",
        short="penetration at rest", tolerance=1e-3, body=False, contact=True,
        reference=True,
    ),
    Metric(
        "energy_gain_max", "1", "E_c, the largest kinetic energy of the closed form plus "
        "m |g| L: the mechanical energy less the external forces' work may only fall",
        floor=1e-11, title="energy gained [E_c]", short="energy gained", tolerance=1e-2,
        body=False, contact=True, headline_energy=("contact",),
    ),
    Metric(
        "roll_onset_error", "1", "t*, the closed form's end of slip", floor=1e-9,
        title="rolling onset error [t*]", short="rolling onset", tolerance=5e-2, body=False,
        contact=True, reference=True,
    ),
    Metric(
        "roll_speed_error", "1", "v*, the closed form's rolling speed", floor=1e-9,
        title="rolling speed error [v*]", short="rolling speed", tolerance=1e-2, body=False,
        contact=True, reference=True,
    ),
    Metric(
        "rebound_ratio_error", "1", "none: |h1/h0 - e^2|, the first rebound height over the "
        "drop height against Newton's law", floor=1e-9, title="rebound ratio error",
        short="rebound", tolerance=5e-2, body=False, contact=True, reference=True,
    ),
    Metric(
        "signorini_residual", "1", "F_c and F_c V_c: a negative normal force, or a normal "
        "force while the contact separates (lambda_n v_n+)", floor=1e-12,
        title="Signorini residual", short="Signorini", tolerance=1e-2, body=False,
        contact=True,
    ),
    Metric(
        "coulomb_residual", "1", "mu F_c: friction beyond the cone, (|lambda_t| - mu "
        "lambda_n)+", floor=1e-12, title="Coulomb residual", short="Coulomb",
        tolerance=1e-2, body=False, contact=True,
    ),
    Metric(
        "dissipation_residual", "1", "mu F_c: a slipping contact's friction away from "
        "-mu lambda_n u_t/|u_t| (slip above 1e-3 V_c)", floor=1e-12,
        title="max-dissipation residual", short="max dissipation", tolerance=1e-2,
        body=False, contact=True,
    ),
    # floor: the engines' contact solvers stop at a relative tolerance (MuJoCo's default
    # tolerance 1e-8, the loosest here): a support force is determined to that, and below it
    # a change is where the solver stopped (MuJoCo 3.3.7 -> 4.0.0 moved box_resting's from
    # 6e-12 to 2e-10, flagged as x33 worse by `versions` with a floor of 1e-12)
    Metric(
        "force_sum_error", "1", "the weight each support carries (resting cases): the "
        "normal forces through it summed, mean over the second half", floor=1e-8,
        title="support force error [rel.]", short="support force", tolerance=1e-2,
        body=False, contact=True, reference=True,
    ),
    # a joint's coordinate (the relative rotation of its two bodies) judged like an attitude:
    # a crank 0.1 rad off its reference is a wrong motion even when every body's attitude
    # error is shared with its neighbours
    Metric(
        "joint_coordinate_error_max", "rad", "none: an angle", floor=1e-10,
        title="joint coordinate error [rad]", short="joint coordinate", tolerance=0.1,
        body=False, system=True, reference=True,
    ),
    Metric(
        "convergence_order", "1", "none: a slope of log(error) against log(dt)",
        higher_is_better=True, slack=0.3, system=True, kind=SWEEP,
    ),
)  # fmt: skip


def shown_order(metrics: tuple[Metric, ...] = METRICS) -> list[Metric]:
    """The metrics in the order the report shows them: those compared with an exact solution
    (a reference trajectory or an exact observable) first, then the others; each group in
    catalog order."""
    exact = [m for m in metrics if m.reference or m.kind == OBSERVABLE]
    return exact + [m for m in metrics if m not in exact]


#: the names a scenario's ``[tolerances]`` table may bound: every error (lower is better)
BOUNDED = tuple(m.name for m in METRICS if not m.higher_is_better)
