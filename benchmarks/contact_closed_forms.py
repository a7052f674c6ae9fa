"""director_model.contact against the classical closed forms of rigid contact, and its order in dt.

Prints two Markdown tables:

1. case, quantity, exact, director, error: each closed form at dt = 1e-3 s (``--dt``);
2. convergence in dt: the error of one quantity of a smooth phase (a tall box tipping about its
   edge: second order expected) and of quantities measured through an event (the first rebound
   of a dropped ball, the rolling onset of a sliding ball: first order expected) at dt, dt/2,
   dt/4, dt/8, with the observed orders log2(e(dt)/e(dt/2)).

The closed forms (Coulomb friction mu, Newton restitution e, g = 9.81 m/s^2, no rolling
resistance; e.g. Pfeiffer and Glocker, *Multibody Dynamics with Unilateral Contacts*, 1996):
a block on an incline of angle th sticks iff tan th <= mu, else slides with a = g (sin th -
mu cos th); a box pushed by F along any horizontal direction sticks iff F <= mu m g, else
a = F/m - mu g along F (isotropic friction); a solid sphere (I = 2/5 m r^2) sliding with
v0, spin w0 rolls from t* = 2 (v0 - r w0) / (7 mu g) at v* = (5 v0 + 2 r w0)/7; a body with
I = k m r^2 rolls down an incline iff mu >= k tan th / (1 + k), at a = g sin th / (1 + k),
else slides at a = g (sin th - mu cos th); resting bodies do not move and each support
carries the weight above it; a drop with restitution e rebounds to e^(2n) h0; a box of base
half-width w (along the slope) and half-height h tips about its downhill edge when
tan th > w/h (and tan th < mu), by the pendulum equation of that edge (integrated here by
scipy's DOP853 at rtol 1e-12).

Usage: python benchmarks/contact_closed_forms.py [--dt 1e-3] [--levels 4]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from director_model.contact import examples as ex
from director_model.contact import incline_frame, simulate_contact

G = ex.G


def _run(scene, dt, t_end, save_every=1):
    return simulate_contact(scene, dt=dt, t_end=t_end, save_every=save_every)


def incline(dt):
    rows = []
    mu = 0.4
    for deg in (15.0, 30.0):
        th = math.radians(deg)
        s, n = incline_frame(th)
        tr = _run(ex.block_on_incline(th, mu), dt, 1.0, 100)
        x = tr.position[:, 0] - tr.position[0, 0]
        if math.tan(th) <= mu:
            rows.append((f"block on incline {deg:g} deg, mu {mu}", "displacement in 1 s (m)",
                         0.0, float(np.abs(x).max()), float(np.abs(x).max())))  # fmt: skip
            fn = float(tr.pair_force[-1, 0] @ n)
            ex_ = G * math.cos(th)
            rows.append(("", "normal force (N)", ex_, fn, abs(fn - ex_)))
        else:
            a = G * (math.sin(th) - mu * math.cos(th))
            d = float(x[-1] @ s)
            rows.append((f"block on incline {deg:g} deg, mu {mu}", "distance in 1 s (m)",
                         0.5 * a, d, abs(d - 0.5 * a)))  # fmt: skip
    return rows


def push(dt):
    rows = []
    mu, m = 0.5, 1.0
    for name, ang in (("axis", 0.0), ("diagonal", math.pi / 4)):
        for frac in (0.9, 1.1):
            F = frac * mu * m * G
            tr = _run(ex.pushed_box(F, ang, mu), dt, 1.0, 100)
            x = tr.position[:, 0] - tr.position[0, 0]
            if frac < 1:
                v = float(np.abs(x).max())
                rows.append((f"push along {name}, F = {frac} mu m g", "displacement (m)", 0.0, v,
                             v))  # fmt: skip
            else:
                a = F / m - mu * G
                d = float(x[-1] @ np.array([math.cos(ang), math.sin(ang), 0.0]))
                rows.append((f"push along {name}, F = {frac} mu m g", "distance in 1 s (m)",
                             0.5 * a, d, abs(d - 0.5 * a)))  # fmt: skip
    return rows


def sphere_roll_onset(v0, w0, mu, dt, r=0.1, m=1.0):
    """(t* measured, v* measured, energy lost measured) of a sliding sphere."""
    tstar = 2.0 * (v0 - r * w0) / (7.0 * mu * G)
    T = 1.5 * abs(tstar) + 0.1
    T = dt * math.ceil(T / dt)
    tr = _run(ex.sphere_on_ground(v0, w0, mu, radius=r, mass=m), dt, T)
    slip = tr.velocity[:, 0, 0] - r * tr.omega_body[:, 0, 1]
    k = int(np.argmax(np.abs(slip) <= 1e-9 * (abs(v0) + abs(r * w0))))
    # the rolling onset lies in the step that ends at t[k]: its linear interpolation
    s0, s1 = slip[k - 1], slip[k]
    t_on = float(tr.t[k - 1] + dt * s0 / (s0 - s1))
    return t_on, float(tr.velocity[-1, 0, 0]), float(tr.energy[0] - tr.energy[-1]), tstar


def sphere(dt):
    rows = []
    mu, r, m = 0.2, 0.1, 1.0
    for name, v0, w0 in (("topspin", 2.0, 5.0), ("backspin", 1.0, -40.0)):
        t_on, v, lost, tstar = sphere_roll_onset(v0, w0, mu, dt, r, m)
        vstar = (5 * v0 + 2 * r * w0) / 7
        e_lost = 0.5 * m * v0**2 + 0.5 * 0.4 * m * r * r * w0**2 - 0.5 * 1.4 * m * vstar**2
        case = f"sphere {name} v0 {v0}, r w0 {r * w0:g}"
        rows.append((case, "t* (s)", tstar, t_on, abs(t_on - tstar)))
        rows.append(("", "v* (m/s)", vstar, v, abs(v - vstar)))
        rows.append(("", "energy lost (J)", e_lost, lost, abs(lost - e_lost)))
    return rows


def rollers(dt):
    rows = []
    th = math.radians(30.0)
    s, _ = incline_frame(th)
    for kind, k in (("sphere", 0.4), ("cylinder", 0.5)):
        thr = k * math.tan(th) / (1 + k)
        for mu in (1.2 * thr, 0.8 * thr):
            tr = _run(ex.roller_on_incline(kind, th, mu), dt, 1.0, 100)
            d = float((tr.position[-1, 0] - tr.position[0, 0]) @ s)
            if mu >= thr:
                a = G * math.sin(th) / (1 + k)
                what = "rolls"
            else:
                a = G * (math.sin(th) - mu * math.cos(th))
                what = "slides"
            rows.append((f"{kind} on 30 deg, mu = {mu / thr:.1f} x threshold ({what})",
                         "distance in 1 s (m)", 0.5 * a, d, abs(d - 0.5 * a)))  # fmt: skip
    return rows


def stack(dt):
    rows = []
    for nbx in (1, 3):
        tr = _run(ex.box_stack(nbx), dt, 1.0, 100)
        dx = float(np.abs(tr.position - tr.position[0]).max())
        case = "resting box" if nbx == 1 else f"stack of {nbx} boxes"
        rows.append((case, "largest displacement in 1 s (m)", 0.0, dx, dx))
        for p, name in enumerate(tr.pair_names):
            fz = float(tr.pair_force[-1, p, 2])
            exact = (nbx - max(p, 0)) * G  # support p carries the boxes p .. nbx-1
            rows.append(("", f"support force {name} (N)", exact, fz, abs(fz - exact)))
        rows.append(("", "largest penetration (m)", 0.0, float(tr.penetration.max()),
                     float(tr.penetration.max())))  # fmt: skip
    return rows


def bounce_heights(e, dt, h0=1.0, nb=3):
    """Apex heights (lowest point above the ground) after each of the first nb impacts."""
    T = 0.0
    t1 = math.sqrt(2 * h0 / G)
    T = t1 * (1 + 2 * sum(e**j for j in range(1, nb + 1))) + 0.05
    T = dt * math.ceil(T / dt)
    tr = _run(ex.dropped_sphere(h0, e), dt, T)
    z = tr.position[:, 0, 2] - 0.1
    vz = tr.velocity[:, 0, 2]
    apex = []
    for k in range(1, len(z) - 1):
        if vz[k - 1] > 0.0 and vz[k] <= 0.0 and z[k] > 1e-9:
            # the parabola through the step's end: apex = z + vz^2 / (2 g) on the rising side
            zk = z[k - 1] + vz[k - 1] ** 2 / (2 * G)
            apex.append(float(zk))
    return apex, float(z.max() if e == 0 else 0.0), tr


def drop(dt):
    rows = []
    h0 = 1.0
    for e in (0.0, 0.5):
        apex, _, tr = bounce_heights(e, dt, h0)
        case = f"drop from {h0} m, e = {e}"
        if e == 0.0:
            k = int(np.argmax(tr.position[:, 0, 2] - 0.1 <= 1e-12))
            after = float(np.abs(tr.position[k:, 0, 2] - 0.1).max())
            rows.append((case, "height after impact (m)", 0.0, after, after))
        else:
            for j, a in enumerate(apex[:3], start=1):
                ex_ = e ** (2 * j) * h0
                rows.append((case if j == 1 else "", f"rebound height {j} (m)", ex_, a,
                             abs(a - ex_)))  # fmt: skip
        rows.append(("", "largest penetration (m)", 0.0, float(tr.penetration.max()),
                     float(tr.penetration.max())))  # fmt: skip
    return rows


TIP = {"angle_deg": 30.0, "mu": 1.0, "half": (0.05, 0.05, 0.15), "t_end": 0.3}


def tip_reference(t):
    """Angle turned about the downhill edge at times t (DOP853, rtol 1e-12): the edge's
    pendulum I_P psi'' = m g L sin(psi - th), I_P = 4/3 m L^2 for a box, psi the angle of the
    centre of mass seen from the edge, measured from the normal towards uphill."""
    th = math.radians(TIP["angle_deg"])
    w, _, h = TIP["half"]
    L = math.hypot(w, h)
    psi0 = math.atan2(w, h)
    sol = solve_ivp(lambda _, y: (y[1], 3 * G / (4 * L) * math.sin(y[0] - th)),
                    (0.0, float(t[-1])), (psi0, 0.0), method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=t)  # fmt: skip
    return psi0 - sol.y[0]


def tip_angle(tr):
    """Angle turned by the box about the world y axis (from its rotation matrices)."""
    R = tr.rotation[:, 0]
    R0 = R[0]
    rel = np.einsum("kji,jl->kil", R, R0)  # R_k^T R_0 ... the relative rotation's y angle
    return -np.arctan2(rel[:, 0, 2] - rel[:, 2, 0], rel[:, 0, 0] + rel[:, 2, 2])


def tipping(dt):
    th = math.radians(TIP["angle_deg"])
    tr = _run(ex.block_on_incline(th, TIP["mu"], TIP["half"]), dt, TIP["t_end"])
    ang = tip_angle(tr)
    ref = tip_reference(tr.t)
    s, _ = incline_frame(th)
    # the downhill bottom edge's centre does not slide
    return [
        ("tall box on 30 deg (w/h = 1/3, mu 1)", "angle turned at 0.3 s (rad)", float(ref[-1]),
         float(ang[-1]), abs(float(ang[-1] - ref[-1]))),
    ]  # fmt: skip


def table(dt):
    rows = []
    for f in (incline, push, sphere, rollers, stack, drop, tipping):
        rows += f(dt)
    return rows


def convergence(dt, levels):
    out = []
    dts = [dt / 2**k for k in range(levels)]
    for name, fn in (
        ("tip angle at 0.3 s (smooth)", lambda d: tipping(d)[0][4]),
        ("first rebound height, e = 0.5 (event)",
         lambda d: abs(bounce_heights(0.5, d)[0][0] - 0.25)),
        ("rolling onset t*, topspin (event)",
         lambda d: abs(sphere_roll_onset(2.0, 5.0, 0.2, d)[0]
                       - 2.0 * (2.0 - 0.5) / (7 * 0.2 * G))),
    ):  # fmt: skip
        errs = [fn(d) for d in dts]
        out.append((name, dts, errs))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--levels", type=int, default=4)
    args = ap.parse_args(argv)
    c0 = time.process_time()
    print(f"## closed forms at dt = {args.dt:g} s\n")
    print("| case | quantity | exact | director | error |")
    print("|---|---|---|---|---|")
    for case, q, e, d, err in table(args.dt):
        print(f"| {case} | {q} | {e:.10g} | {d:.10g} | {err:.2e} |")
    print(f"\n## convergence in dt (from {args.dt:g} s, halving)\n")
    for name, dts, errs in convergence(args.dt, args.levels):
        orders = ["-"] + [f"{math.log2(a / b):.2f}" if a > 0 and b > 0 else "-"
                          for a, b in zip(errs, errs[1:], strict=False)]  # fmt: skip
        print(f"{name}")
        print("| dt (s) | error | order |\n|---|---|---|")
        for d, e, o in zip(dts, errs, orders, strict=True):
            print(f"| {d:.3g} | {e:.3e} | {o} |")
        print()
    print(f"(process CPU {time.process_time() - c0:.1f} s)")


if __name__ == "__main__":
    main()
