"""Metrics of bodies in contact, computed by the suite from the states and the engine's own
contact forces of a run (:class:`references.engines.contact.ContactRunOutput`) against the
closed form of the scene (:class:`references.exact.contact.ContactMotion`), the same way for
every engine. Each metric is declared once in :mod:`scenarios.metric_catalog` (``contact``);
the scales:

- L, the size of the scene: the smallest half-size of a body's shape (sphere radius, box
  half extent); a body *slides* when its centre of mass moves more than L/10 over the run;
- F_c, the force in play: the bodies' weight plus the magnitudes of the external forces;
- V_c = sqrt(|g| L), the speed gravity gives over a size (at least the fastest initial speed);
- E_c, the energy in play: the closed form's largest kinetic energy plus m_tot |g| L.

The law residuals follow Le Lidec et al., "Contact models in robotics: a comparative
analysis" (2024; the ContactBench criteria), made dimensionless here: each contact row's force
f on body a at point p with normal n (from b into a), lambda_n = f . n, lambda_t = f -
lambda_n n, the contact's relative velocity u = v_a(p) - v_b(p) from the saved states
(v + w x (p' - x) of each body, p' = p + h v_G,a: the engines find a step's contacts where
the bodies were when it began and save the state where it ended; planes are still),
v_n = u . n, u_t = u - v_n n:

- Signorini: max((-lambda_n)+ / F_c, (lambda_n)+ (v_n)+ / (F_c V_c)), the product only for
  pairs with e = 0 (an impact with restitution pushes while the bodies part);
- Coulomb: (|lambda_t| - mu lambda_n)+ / (mu F_c) (|lambda_t| / F_c when mu = 0);
- maximum dissipation, where |u_t| > 1e-3 V_c: |lambda_t + mu lambda_n u_t/|u_t|| / (mu F_c).
"""

from __future__ import annotations

import math

import numpy as np

from references.trajectory import system_energy
from reports.metrics.catalog import check_attached, measure, measures

#: a body slides when its centre of mass moves more than this fraction of L over the run
SLIDE_FRACTION = 0.1
#: a contact slips (maximum dissipation applies) above this fraction of V_c
SLIP_FRACTION = 1e-3
#: the slip has ended (rolling) when it falls below this fraction of the initial slip
ROLL_FRACTION = 1e-2
#: the last fraction of a run over which the penetration at rest is averaged
REST_FRACTION = 0.1


# -- scales --------------------------------------------------------------------------------------


def size(scenario) -> float:
    """L (m): the smallest half-size of a body's shape."""
    return min(b.shape.size for b in scenario.bodies if b.shape is not None)


def force_scale(scenario) -> float:
    """F_c (N): the bodies' weight plus the magnitudes of the external forces."""
    g = float(np.linalg.norm(scenario.gravity))
    w = g * scenario.total_mass + sum(float(np.linalg.norm(f.force)) for f in scenario.forces)
    return w if w > 0 else 1.0


def speed_scale(scenario) -> float:
    """V_c (m/s): sqrt(|g| L), or the fastest initial speed if larger; 1 if both vanish."""
    v = math.sqrt(float(np.linalg.norm(scenario.gravity)) * size(scenario))
    for b in scenario.bodies:
        r = b.shape.extent if b.shape is not None else 0.0
        v = max(v, float(np.linalg.norm(b.velocity)) + float(np.linalg.norm(b.omega_body)) * r)
    return v if v > 0 else 1.0


def energy_scale(scenario, ref) -> float:
    """E_c (J): the closed form's largest kinetic energy plus m_tot |g| L."""
    m = np.array([b.mass for b in scenario.bodies])
    inertia = np.array([b.inertia for b in scenario.bodies])
    kin = 0.5 * np.einsum("b,nbi,nbi->n", m, ref.v, ref.v)
    kin = kin + 0.5 * np.einsum("nbi,bi,nbi->n", ref.W, inertia, ref.W)
    e = float(np.max(kin)) + scenario.total_mass * float(np.linalg.norm(scenario.gravity)) * size(
        scenario
    )
    return e if e > 0 else 1.0


# -- shared pieces -------------------------------------------------------------------------------


def _states(run):
    return run.trajectory


def _rows(scenario, run):
    """Per contact row, flattened over (sample, row): sample index, pair index, point, normal,
    force, relative velocity u (n_rows, ...) -- rows without a contact dropped."""
    C = run.contacts
    tr = _states(run)
    pair = np.asarray(C["pair"])
    k, j = np.nonzero(pair >= 0)
    if len(k) == 0:
        return None
    idx = {b.name: i for i, b in enumerate(scenario.bodies)}
    pi = pair[k, j]
    p = np.asarray(C["point"])[k, j]
    n = np.asarray(C["normal"])[k, j]
    f = np.asarray(C["force"])[k, j]
    ia = np.array([idx[scenario.contacts[i].a] for i in pi])
    ib = np.array([-1 if scenario.contacts[i].b_is_plane else idx[scenario.contacts[i].b]
                   for i in pi])  # fmt: skip

    h = float(run.settings.get("timestep", 0.0))

    def point_velocity(bi, shift):
        out = np.zeros_like(p)
        ok = bi >= 0
        if ok.any():
            kk, bb = k[ok], bi[ok]
            w = np.einsum("nij,nj->ni", tr.rotation[kk, bb], tr.omega_body[kk, bb])
            q = p[ok] + shift[ok]
            out[ok] = tr.velocity[kk, bb] + np.cross(w, q - tr.position[kk, bb])
        return out

    # the engines find a step's contacts where the bodies were when it began and save the
    # state where it ended: the contact point, fixed relative to body a's centre of mass
    # over the step (exactly so for a sphere's lowest point), has moved by h v_G since
    shift = h * tr.velocity[k, ia]
    u = point_velocity(ia, shift) - point_velocity(ib, shift)
    mu = np.array([scenario.contacts[i].mu for i in pi])
    e = np.array([scenario.contacts[i].e for i in pi])
    return {"k": k, "pair": pi, "point": p, "normal": n, "force": f, "u": u, "mu": mu, "e": e}


def _laws(rows):
    ln = np.einsum("ni,ni->n", rows["force"], rows["normal"])
    lt = rows["force"] - ln[:, None] * rows["normal"]
    vn = np.einsum("ni,ni->n", rows["u"], rows["normal"])
    ut = rows["u"] - vn[:, None] * rows["normal"]
    return ln, lt, vn, ut


def _per_sample(n, k, values) -> np.ndarray:
    """The largest of ``values`` at each sample (0 where a sample has no row), (n,)."""
    out = np.zeros(n)
    np.maximum.at(out, k, values)
    return out


def _facts(ref) -> dict:
    return getattr(ref, "facts", {}) or {}


def _moved(run) -> np.ndarray:
    """Each body's distance from its start at each sample, (n, nb)."""
    x = _states(run).position
    return np.linalg.norm(x - x[:1], axis=2)


# -- the metrics ---------------------------------------------------------------------------------


@measures("attitude_error_max", on="contact")
def attitude_error(traj, ref):
    from reports.metrics.body import nearest_rotation

    Rs = _states(traj).rotation
    Q = nearest_rotation(Rs.reshape(-1, 3, 3)).reshape(Rs.shape)
    Q_ref = nearest_rotation(ref.R.reshape(-1, 3, 3)).reshape(Rs.shape)
    # ||Q - Q_ref||_F = 2 sqrt(2) sin(theta/2): accurate for small angles (the metric of one body)
    d = np.linalg.norm(Q - Q_ref, axis=(2, 3)) / (2.0 * math.sqrt(2.0))
    return np.max(2.0 * np.arcsin(np.clip(d, 0.0, 1.0)), axis=1)


@measures("omega_error_max", on="contact")
def omega_error(traj, ref):
    return np.max(np.linalg.norm(_states(traj).omega_body - ref.W, axis=2), axis=1)


@measures("position_error_max", on="contact")
def position_error(traj, ref):
    return np.max(np.linalg.norm(_states(traj).position - ref.x, axis=2), axis=1)


@measures("orthonormality_max", on="contact")
def orthonormality(traj):
    R = _states(traj).rotation
    eye = np.eye(3)
    return np.max(np.linalg.norm(np.einsum("nbji,nbjk->nbik", R, R) - eye, axis=(2, 3)), axis=1)


@measures("creep_speed", on="contact")
def creep_speed(traj, ref):
    """Stick cases: each body's mean speed over the second half of the run, m/s."""
    if not _facts(ref).get("sticks"):
        return None
    tr = _states(traj)
    if len(tr) < 3:
        return None
    h = len(tr) // 2
    span = tr.t[-1] - tr.t[h]
    d = np.linalg.norm(tr.position[-1] - tr.position[h], axis=1)
    return np.array([float(np.max(d)) / span])


@measures("slide_distance", on="contact")
def slide_distance(traj):
    return np.array([float(np.max(_moved(traj)[-1]))])


@measures("stick_slide_mismatch", on="contact")
def stick_slide_mismatch(scenario, traj, ref):
    """1 when the run slides where Coulomb sticks or sticks where it slides (stick/slide
    cases: the block scenes), else 0."""
    facts = _facts(ref)
    if "sticks" not in facts or "support_forces" in facts:
        return None
    slides = float(np.max(_moved(traj)[-1])) > SLIDE_FRACTION * size(scenario)
    return np.array([float(slides == bool(facts["sticks"]))])


def _gaps(scenario, traj) -> np.ndarray:
    from scenarios.contact import pair_distance

    tr = _states(traj)
    return np.array([pair_distance(scenario, c, tr.position, tr.rotation)
                     for c in scenario.contacts])  # fmt: skip


@measures("penetration_max", on="contact")
def penetration(scenario, traj):
    return np.max(np.maximum(-_gaps(scenario, traj), 0.0), axis=0)


@measures("penetration_rest", on="contact")
def penetration_rest(scenario, traj, ref):
    facts = _facts(ref)
    if not facts.get("sticks"):
        rest = facts.get("rest_time")
        if rest is None or rest > _states(traj).t[-1] * (1 - REST_FRACTION):
            return None
    pen = np.max(np.maximum(-_gaps(scenario, traj), 0.0), axis=0)
    tail = max(1, int(round(REST_FRACTION * len(pen))))
    return np.array([float(np.mean(pen[-tail:]))])


@measures("energy_gain_max", on="contact")
def energy_gain(scenario, traj, ref):
    """(E(t) - W_ext(t) - E(0))+ / E_c, E the bodies' mechanical energy, W_ext the external
    forces' work (constant forces at body points: F . (x_P(t) - x_P(0)))."""
    tr = _states(traj)
    E = system_energy(scenario, tr)
    idx = {b.name: i for i, b in enumerate(scenario.bodies)}
    work = np.zeros(len(tr))
    for f in scenario.forces:
        i = idx[f.body]
        xp = tr.position[:, i] + tr.rotation[:, i] @ f.point
        work += (xp - xp[0]) @ f.force
    return np.maximum(E - work - E[0], 0.0) / energy_scale(scenario, ref)


def _slip(scenario, traj):
    """The rolling body's slip speed (n,): the contact point's velocity along the plane."""
    b = scenario.bodies[0]
    pair = scenario.contacts[0]
    plane = next(p for p in scenario.planes if p.name == pair.b)
    tr = _states(traj)
    n = plane.normal
    r = -b.shape.radius * n
    w = np.einsum("nij,nj->ni", tr.rotation[:, 0], tr.omega_body[:, 0])
    u = tr.velocity[:, 0] + np.cross(w, r)
    return np.linalg.norm(u - (u @ n)[:, None] * n, axis=1)


@measures("roll_onset_error", on="contact")
def roll_onset_error(scenario, traj, ref):
    """|t_roll - t*| / t*: t_roll where the slip, decreasing linearly while the body slides,
    reaches 0: the line through the last two samples before it first falls below 1 % of its
    initial value, extrapolated to 0 (exact for Coulomb sliding between samples); 1 when it
    never falls that low."""
    t_star = _facts(ref).get("t_roll")
    if t_star is None or not math.isfinite(t_star) or t_star <= 0:
        return None
    tr = _states(traj)
    s = _slip(scenario, traj)
    thr = ROLL_FRACTION * s[0]
    below = np.nonzero(s < thr)[0]
    if len(below) == 0 or below[0] == 0:
        return np.array([1.0])
    k = below[0]
    if k >= 2 and s[k - 2] > s[k - 1]:
        rate = (s[k - 2] - s[k - 1]) / (tr.t[k - 1] - tr.t[k - 2])
        t_roll = tr.t[k - 1] + s[k - 1] / rate
    else:
        t0, t1, s0, s1 = tr.t[k - 1], tr.t[k], s[k - 1], s[k]
        t_roll = t0 + s0 / (s0 - s1) * (t1 - t0)
    return np.array([abs(t_roll - t_star) / t_star])


@measures("roll_speed_error", on="contact")
def roll_speed_error(traj, ref):
    """|v(t_end) - v_ref(t_end)| / v*, once the closed form rolls at v* (flat ground)."""
    facts = _facts(ref)
    v_star = facts.get("v_roll")
    if v_star is None or not math.isfinite(v_star) or abs(v_star) == 0:
        return None
    v = _states(traj).velocity[-1, 0]
    return np.array([float(np.linalg.norm(v - ref.v[-1, 0])) / abs(v_star)])


@measures("rebound_ratio_error", on="contact")
def rebound_ratio_error(scenario, traj, ref):
    """|h1/h0 - e^2|: h1 the highest the body's lowest point gets between the closed form's
    first and second impacts (after the first for e = 0), h0 the drop height."""
    facts = _facts(ref)
    if "rebound_heights" not in facts:
        return None
    times = facts["impact_times"]
    tr = _states(traj)
    gap = _gaps(scenario, traj)[0]
    t1 = times[0]
    t2 = times[1] if len(times) > 1 else tr.t[-1]
    sel = (tr.t > t1) & (tr.t <= min(t2, tr.t[-1]))
    if not sel.any():
        return None
    h1 = max(float(np.max(gap[sel])), 0.0)
    e2 = facts["rebound_heights"][0] / facts["drop_height"]
    return np.array([abs(h1 / facts["drop_height"] - e2)])


@measures("signorini_residual", on="contact")
def signorini(scenario, traj):
    rows = _rows(scenario, traj)
    n = len(_states(traj))
    if rows is None:
        return np.zeros(n)
    ln, _, vn, _ = _laws(rows)
    F, V = force_scale(scenario), speed_scale(scenario)
    # with restitution an impact's force and its rebound coexist: only the sign is checked
    # there (the rebound has its own metric)
    product = np.where(rows["e"] > 0, 0.0, np.maximum(ln, 0.0) * np.maximum(vn, 0.0))
    r = np.maximum(np.maximum(-ln, 0.0) / F, product / (F * V))
    return _per_sample(n, rows["k"], np.nan_to_num(r, nan=np.inf))


@measures("coulomb_residual", on="contact")
def coulomb(scenario, traj):
    rows = _rows(scenario, traj)
    n = len(_states(traj))
    if rows is None:
        return np.zeros(n)
    ln, lt, _, _ = _laws(rows)
    F, mu = force_scale(scenario), rows["mu"]
    excess = np.maximum(np.linalg.norm(lt, axis=1) - mu * ln, 0.0)
    r = excess / (np.where(mu > 0, mu, 1.0) * F)
    return _per_sample(n, rows["k"], np.nan_to_num(r, nan=np.inf))


@measures("dissipation_residual", on="contact")
def dissipation(scenario, traj):
    rows = _rows(scenario, traj)
    n = len(_states(traj))
    if rows is None:
        return np.zeros(n)
    ln, lt, _, ut = _laws(rows)
    F, V, mu = force_scale(scenario), speed_scale(scenario), rows["mu"]
    speed = np.linalg.norm(ut, axis=1)
    slip = speed > SLIP_FRACTION * V
    want = -mu[:, None] * np.maximum(ln, 0.0)[:, None] * ut / np.maximum(speed, 1e-300)[:, None]
    r = np.where(slip, np.linalg.norm(lt - want, axis=1) / (np.where(mu > 0, mu, 1.0) * F), 0.0)
    return _per_sample(n, rows["k"], np.nan_to_num(r, nan=np.inf))


@measures("force_sum_error", on="contact")
def force_sum_error(scenario, traj, ref):
    """Resting cases: max over supports of |mean over the second half of the normal forces
    through it summed - the weight it carries| / that weight."""
    want = _facts(ref).get("support_forces")
    if want is None:
        return None
    rows = _rows(scenario, traj)
    n = len(_states(traj))
    if rows is None:  # the engine reports no force (the exact engine)
        return None
    ln = np.einsum("ni,ni->n", rows["force"], rows["normal"])
    half = rows["k"] >= n // 2
    samples = max(n - n // 2, 1)
    idx = {b.name: i for i, b in enumerate(scenario.bodies)}
    worst = 0.0
    for i, c in enumerate(scenario.contacts):
        body = idx[c.a]
        w = float(want[body])
        got = float(np.sum(ln[half & (rows["pair"] == i)])) / samples
        worst = max(worst, abs(got - w) / w)
    return np.array([worst])


check_attached("contact")


def compute_contact_metrics(scenario, run, ref) -> dict[str, float]:
    """Every contact metric of one run (:mod:`scenarios.metric_catalog`, ``contact``): the
    largest value over the samples, NaN where it does not apply. ``run``: the
    :class:`~references.engines.contact.ContactRunOutput`; ``ref``: the scene's
    :class:`~references.exact.contact.ContactMotion` at the run's saved times, or None."""
    return measure(scenario, run, ref, reduce=_largest)[0]


def _largest(v) -> float:
    """The largest value of a contact series (NaN for an empty one; a NaN sample stays NaN:
    the law residuals turn theirs into inf themselves)."""
    return math.nan if len(v) == 0 else float(np.max(v))
