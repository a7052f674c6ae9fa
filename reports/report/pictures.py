"""The pictures of a scenario: the body (the uniform box with its principal moments) and its
motion, a strip of poses and the trace of one body axis, from the reference's run of a results
folder (:func:`scenario_plot_from_results`) or from the library scenario itself
(:func:`scenario_picture`). ``python -m reports.report.pictures --scenario-figures docs/figures``
draws them for the documentation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reports.report.canvas import SeriesCache, _plt, _write_png
from reports.store.format import fmt
from reports.store.results import reference_rows
from reports.store.runs import slug

#: the poses of the strip in a scenario picture (equally spaced over the horizon, both ends)
POSES = 5


#: face colours of the body's box, by the body axis a face is normal to (d1, d2, d3)
AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")


def body_box(sc) -> np.ndarray:
    """Half the side lengths (m) of the uniform box with the scenario's mass and principal
    moments about the centre of mass: a box of sides (a1, a2, a3) has I1 = m (a2^2 + a3^2)/12,
    so a1^2 = 6 (I2 + I3 - I1)/m. A side that comes out 0 or negative (moments on the edge
    of the triangle inequality) is drawn as a thin plate: 2 % of the largest."""
    I, m = np.asarray(sc.inertia, dtype=float), float(sc.mass)
    sq = np.array([6.0 * (I[(k + 1) % 3] + I[(k + 2) % 3] - I[k]) / m for k in range(3)])
    half = 0.5 * np.sqrt(np.clip(sq, 0.0, None))
    return np.maximum(half, 0.02 * half.max())


def tracked_axis(sc) -> tuple[int, np.ndarray]:
    """The body axis a scenario picture traces, as (index, unit vector in body axes): a
    pivoted body's axis from the pivot through the centre of mass; a free body's axis
    carrying the largest share of the initial angular momentum, pointing along it."""
    if sc.pivot is not None and np.linalg.norm(sc.pivot) > 0:
        u = -np.asarray(sc.pivot, dtype=float)
        return int(np.argmax(np.abs(u))), u / np.linalg.norm(u)
    L = np.asarray(sc.inertia) * np.asarray(sc.omega_body)
    k = int(np.argmax(np.abs(L)))
    u = np.zeros(3)
    u[k] = 1.0 if L[k] >= 0 else -1.0
    return k, u


def _box_faces(half, R, c):
    """The six faces of a box (half sides ``half``) turned by R about its centre c, with the
    index of the body axis each is normal to."""
    faces, normals = [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for sgn in (-1.0, 1.0):
            corners = []
            for si, sj in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                v = np.zeros(3)
                v[k], v[i], v[j] = sgn * half[k], si * half[i], sj * half[j]
                corners.append(c + R @ v)
            faces.append(corners)
            normals.append(k)
    return faces, normals


def _tip_length(half, u) -> float:
    """How far from the centre of mass the traced axis is drawn: out of the box by half its
    largest side."""
    k = int(np.argmax(np.abs(u)))
    return float(half[k] + 0.6 * np.max(half))


def _draw_pose(ax, sc, R, x, half, u, lim, trace=None) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    faces, normals = _box_faces(half, R, x)
    ax.add_collection3d(
        Poly3DCollection(
            faces,
            facecolors=[AXIS_COLOURS[k] for k in normals],
            edgecolors="0.25",
            linewidths=0.4,
            alpha=0.35,
        )
    )
    tip = x + R @ (u * _tip_length(half, u))
    ax.plot(*np.column_stack([x, tip]), color="k", lw=1.8)
    if sc.pivot is not None:
        ax.plot([0, x[0]], [0, x[1]], [0, x[2]], color="0.2", lw=1.0, ls=(0, (2, 1)))
        ax.scatter([0], [0], [0], color="k", s=14, depthshade=False)
    if trace is not None:
        ax.plot(*trace.T, color="#6a3d9a", lw=1.1)
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-lim, lim)
    ax.set_box_aspect((1, 1, 1), zoom=1.45)
    ax.view_init(elev=18, azim=-58)
    ax.set_axis_off()


def scenario_picture(sc, t, R, x, out_path: Path, note: str = "") -> Path:
    """A picture of a scenario: its body (the uniform box with its mass and principal
    moments, faces coloured by body axis d1 red, d2 green, d3 blue) at t = 0 with the trace of
    one body axis (:func:`tracked_axis`) over the horizon, then a strip of :data:`POSES` poses
    equally spaced in time; a pivot is a black dot with a dashed line to the centre of mass.

    ``t`` (n,), ``R`` (n, 3, 3) body-to-world rotations and ``x`` (n, 3) centre-of-mass
    positions of the motion (the exact reference); a free body's centre of mass is drawn at
    the origin (its flight is not what the picture shows). Writes a small PNG."""
    plt = _plt()
    t, R, x = np.asarray(t, float), np.asarray(R, float), np.asarray(x, float)
    half = body_box(sc)
    k, u = tracked_axis(sc)
    pivoted = sc.pivot is not None
    if not pivoted:
        x = np.zeros_like(x)
    tips = x + np.einsum("nij,j->ni", R, u * _tip_length(half, u))
    reach = np.max(np.linalg.norm(half)) + (np.linalg.norm(sc.pivot) if pivoted else 0.0)
    lim = 1.05 * max(reach, float(np.max(np.abs(tips))))
    fig = plt.figure(figsize=(9.6, 2.4), dpi=80)
    main = fig.add_axes([0.0, 0.07, 0.27, 0.84], projection="3d")
    _draw_pose(main, sc, R[0], x[0], half, u, lim, trace=tips)
    main.set_title(f"{sc.name}: body and the trace of d{k + 1}", fontsize=8.5, pad=0, loc="left")
    idx = np.unique(np.round(np.linspace(0, len(t) - 1, POSES)).astype(int))
    w = 0.71 / len(idx)
    for n, i in enumerate(idx):
        ax = fig.add_axes([0.28 + n * w, 0.07, w, 0.78], projection="3d")
        _draw_pose(ax, sc, R[i], x[i], half, u, lim)
        ax.set_title(f"t = {fmt(float(t[i]))} s", fontsize=8, pad=0)
    side = " x ".join(fmt(2 * h) for h in half)
    text = (
        f"box {side} m (mass {fmt(sc.mass)} kg, the same principal moments), faces normal to "
        f"d1 red, d2 green, d3 blue; black: d{k + 1}; purple: its tip over "
        f"{fmt(float(t[-1]))} s; "
        f"{'pivot: black dot' if pivoted else 'centre of mass held still'}; world z up"
        + (f"; {note}" if note else "")
    )
    fig.text(0.01, 0.01, text, fontsize=7, color="0.3", ha="left", va="bottom")
    _write_png(fig, out_path)
    plt.close(fig)
    return out_path


def library_scenario(row):
    """The library's scenario a run used, or None: the file of the run's scenario name when
    its content hash is the run's, or when its body and initial state give the run's energy
    and momentum scales to 1e-12 (the same body run with another horizon or step). A
    scenario file of one's own gives None: the results folder does not hold its body."""
    import scenarios

    try:
        sc = scenarios.load(str(row["scenario"]))
    except (ValueError, OSError):
        return None
    if sc.scenario_hash == str(row.get("scenario_hash") or ""):
        return sc
    same = [
        abs(float(getattr(sc, col)) - float(row.get(col))) <= 1e-12 * abs(float(row.get(col)))
        for col in ("energy_scale", "momentum_scale")
    ]
    return sc if all(same) else None


def scenario_plot_from_results(df, cache: SeriesCache, out: Path, scenario: str):
    """The scenario picture of a results folder: the body stored beside the exact
    reference's run (:meth:`SeriesCache.body`; in a folder written before it was stored, the
    library's scenario file when the runs used that very file) and that run's motion."""
    rows = df[(df["scenario"] == scenario) & reference_rows(df)]
    rows = rows[rows["status"].isin(("ok", "reference-inaccurate"))]
    if rows.empty:
        return None
    row = rows.sort_values("dt").iloc[0]
    s = cache.get(row)
    sc = cache.body(row) or library_scenario(row)
    if sc is None or s is None or "R00" not in s:
        return None
    R = np.stack([s[f"R{i}{j}"] for i in range(3) for j in range(3)], axis=1).reshape(-1, 3, 3)
    x = np.column_stack([s["x"], s["y"], s["z"]])
    path = scenario_picture(sc, s["t"], R, x, out / f"{slug(scenario)}__scenario.png")
    k, _ = tracked_axis(sc)
    pose = "pivoted on a fixed point" if sc.pivot is not None else "free"
    alt = (
        f"{scenario}: the body as a uniform box ({pose}) with the same principal moments, the "
        f"trace of its body axis d{k + 1} over {fmt(float(s['t'][-1]))} s, and {POSES} poses "
        "equally spaced in time."
    )
    import json

    path.with_suffix(".json").write_text(json.dumps({"alt": alt, "lines": []}))
    return path


def scenario_figures(names, out: Path, samples: int = 401) -> list[Path]:
    """The pictures of library scenarios for the documentation, each from its exact reference
    at ``samples`` times: ``scenario_<name>.png`` in ``out``."""
    import scenarios
    from references.exact import reference_trajectory
    from references.trajectory import one_body

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        sc = scenarios.load(name)
        t = np.linspace(0.0, sc.t_end, samples)
        ref = one_body(reference_trajectory(sc, t))
        path = out / f"scenario_{name}.png"
        paths.append(scenario_picture(sc, t, ref.rotation, ref.position, path))
    return paths


def main(argv=None) -> int:
    """``python -m reports.report.pictures --scenario-figures DIR [NAME ...]``: the pictures of the
    default suite's scenarios (or those named) for the documentation."""
    import argparse

    import scenarios

    p = argparse.ArgumentParser(
        prog="python -m reports.report.pictures",
        description="Draw the pictures of library scenarios (body and motion) into a folder.",
    )
    p.add_argument(
        "--scenario-figures",
        metavar="DIR",
        required=True,
        help="folder to write scenario_<name>.png into (e.g. docs/figures)",
    )
    p.add_argument("names", nargs="*", help="library scenarios (default: the default suite)")
    args = p.parse_args(argv)
    names = args.names or scenarios.default_suite()
    try:
        for path in scenario_figures(names, Path(args.scenario_figures)):
            print(path)
    except (ValueError, OSError) as exc:
        print(f"python -m reports.report.pictures: error: {exc}", file=__import__("sys").stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
