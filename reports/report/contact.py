"""The report's contact section and figures: contact runs are the rows whose recorded scene
kind is ``contact`` (``scene_kind``, :data:`scenarios.SCENE_KINDS`).

- :func:`creep_table`: engine x configuration x stick scene, the creep speed in um/s (exact 0:
  Coulomb friction holds every stick scene);
- :func:`stick_slide_matrix`: engine x configuration x stick/slide scene, whether the run
  sticks where Coulomb sticks and slides where it slides (a body slides when it moves more
  than a tenth of its size, :data:`reports.metrics.contact.SLIDE_FRACTION`);
- :func:`contact_section`: both tables under the heading "Contact", with how they are made;
- :func:`contact_plot`: a scene's figure, drawn from the series beside each run's trajectory
  (:func:`reports.run.contact.series`): the distance moved and the deepest penetration over
  time, each configuration at the scene's own dt, the closed form's distance in grey. The
  penetration is drawn as its largest value over the :func:`pen_window` before each time
  (a box rocking or a ball hopping on a soft contact touches and leaves the ground from one
  saved state to the next: drawn sample by sample on a log axis, the lines of a dozen
  configurations fill the panel between 1e-12 and 1e-4 m and none can be read).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: the smallest value shown on the log axes (no overlap, no motion are drawn here)
FLOOR = 1e-12
#: the penetration panel draws the deepest penetration over this fraction of the horizon
#: before each saved state (module docstring)
PEN_WINDOW = 0.05
#: ... and over at least this long, s: a short scene's 5 % (25 ms of a 0.5 s push) is shorter
#: than the 20-30 ms a box sliding on MuJoCo's or Drake's soft contact spends off the ground
PEN_WINDOW_MIN_S = 0.1


def pen_window(t_end: float) -> float:
    """The time (s) over which the penetration panel takes the deepest penetration before
    each saved state: :data:`PEN_WINDOW` of the run, at least :data:`PEN_WINDOW_MIN_S`."""
    return max(PEN_WINDOW * t_end, PEN_WINDOW_MIN_S)


def running_max(values, window: int) -> np.ndarray:
    """Each sample's largest value among itself and the ``window - 1`` before it."""
    v = np.asarray(values, float)
    if window <= 1 or len(v) == 0:
        return v.copy()
    padded = np.concatenate([np.full(window - 1, -np.inf), v])
    return np.lib.stride_tricks.sliding_window_view(padded, window).max(axis=1)


def contact_rows(df):
    """The runs of contact scenes in a results table (the scene kind the runner recorded,
    ``scene_kind``; a store of an older format has it filled when read), every status."""
    if "scene_kind" not in df:
        return df.iloc[0:0]
    return df[df["scene_kind"] == "contact"]


def _config(row) -> str:
    return f"{row['engine']} {row['integrator']}"


def _pivot(df, value, scenes):
    """{configuration: {scene: value(row)}} at each scene's own dt (the exact reference's
    step, reports.store.results.default_dt: a run with the dt sweep holds the scene's other
    steps too)."""
    from reports.store.results import default_dt

    out: dict[str, dict] = {}
    for scene in scenes:
        sub = df[df["scenario"] == scene]
        if not len(sub):
            continue
        h = default_dt(sub)
        for _, r in sub[np.isclose(sub["dt"], h, rtol=1e-9)].iterrows():
            out.setdefault(_config(r), {})[scene] = value(r)
    return out


def creep_scenes(df) -> list[str]:
    rows = contact_rows(df)
    return sorted(rows[rows["creep_speed"].notna()]["scenario"].unique())


def matrix_scenes(df) -> list[str]:
    rows = contact_rows(df)
    return sorted(rows[rows["stick_slide_mismatch"].notna()]["scenario"].unique())


def creep_table(df) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of the creep table: um/s, the status where a run did not finish."""
    rows = contact_rows(df)
    scenes = creep_scenes(df)

    def cell(r):
        if r["status"] != "ok":
            return r["status"]
        v = float(r["creep_speed"])
        return "-" if math.isnan(v) else f"{v * 1e6:.3g}"

    table = _pivot(rows, cell, scenes)
    body = [[c, *[table[c].get(s, "") for s in scenes]] for c in sorted(table)]
    return ["configuration", *[f"{s} [um/s]" for s in scenes]], body


def stick_slide_matrix(df) -> tuple[list[str], list[list[str]]]:
    """(header, rows): per stick/slide scene the closed form's answer in the header and each
    run's (its own, and 'wrong' where it differs)."""
    rows = contact_rows(df)
    scenes = matrix_scenes(df)
    expect = {}
    for s in scenes:
        sub = rows[rows["scenario"] == s]
        expect[s] = "sticks" if sub["creep_speed"].notna().any() else "slides"

    def cell(r):
        if r["status"] not in ("ok", "diverged"):
            return r["status"]
        wrong = float(r["stick_slide_mismatch"]) > 0.5
        scene_sticks = expect[r["scenario"]] == "sticks"
        did = "sticks" if scene_sticks != wrong else "slides"
        return f"{did} (wrong)" if wrong else did

    table = _pivot(rows, cell, scenes)
    head = ["configuration", *[f"{s} (Coulomb: {expect[s]})" for s in scenes]]
    return head, [[c, *[table[c].get(s, "") for s in scenes]] for c in sorted(table)]


def contact_section(doc, df) -> None:
    """The report's contact section (module docstring), when the results hold contact runs."""
    rows = contact_rows(df)
    if not len(rows):
        return
    doc.heading(2, "Contact")
    doc.para(
        "Creep: the mean speed of a body over the second half of a run where Coulomb friction "
        "holds it (exact 0; the default bound is 100 um/s). Stick/slide: a run slides when a "
        "body moves more than a tenth of its size over the run; the closed form's answer "
        "heads each column. Each run's errors against the closed form are in the scene's "
        "table below."
    )
    head, body = creep_table(df)
    if body:
        doc.table("Creep speed in stick scenes, um/s", head, body)
    head, body = stick_slide_matrix(df)
    if body:
        doc.table("Stick or slide, against Coulomb's law", head, body)


def contact_plot(rows, h, cache, out: Path, scenario: str, plt, save, styles=None,
                 new_figure=None, legend=None):  # fmt: skip
    """The figure of a contact scene (module docstring) as ``<slug>__system.png``, or None."""
    from reports.report.groups import group_rows
    from reports.report.labels import config_label
    from reports.store.results import is_reference_record
    from reports.store.runs import slug

    runs = []
    for g in group_rows(rows):
        s = cache.get(g.first)
        if s is not None and "moved" in s:
            runs.append((g.first, ", ".join(config_label(r) for r in g.rows), s))
    if not runs:
        return None
    if new_figure is not None:
        fig, axes = new_figure(2)
    else:
        fig, axes = plt.subplots(2, 1, figsize=(7.5, 4.6), sharex=True)
    # a stick scene (the closed form does not move): the distance on a log axis, where creep
    # of 1e-11 m and of 1e-3 m both show
    still = all(np.nanmax(np.abs(np.asarray(s.get("moved_exact", [np.nan]), float)),
                          initial=0.0) == 0.0 for _, _, s in runs)  # fmt: skip
    exact_drawn = False
    for k, (row, name, s) in enumerate(runs):
        if is_reference_record(row):
            continue
        st = styles.of(row, always_marker=True) if styles is not None else {}
        st.pop("lw", None)
        every = max(1, len(s["t"]) // 6)
        st.setdefault("markevery", (k % every, every))
        moved = np.asarray(s["moved"], float)
        axes[0].plot(s["t"], np.maximum(moved, FLOOR) if still else moved, lw=1.3, label=name,
                     **st)  # fmt: skip
        tt = np.asarray(s["t"], float)
        step = (tt[-1] - tt[0]) / max(len(tt) - 1, 1)
        window = max(1, int(round(pen_window(tt[-1] - tt[0]) / step))) if step > 0 else 1
        pen = np.maximum(running_max(s["penetration"], window), FLOOR)
        axes[1].plot(s["t"], pen, lw=1.3, label=name, **st)
        ex = np.asarray(s.get("moved_exact", []), float)
        if not exact_drawn and len(ex) and np.isfinite(ex).all():
            axes[0].plot(s["t"], ex, color="0.55", lw=2.4, alpha=0.6, label="closed form",
                         zorder=0)  # fmt: skip
            exact_drawn = True
    axes[0].set_ylabel("distance moved [m]")
    if still:
        axes[0].set_yscale("log")
        axes[0].set_ylabel("distance moved [m]\n(closed form: 0)")
    span = pen_window(float(np.nanmax([np.asarray(s["t"], float)[-1] for _, _, s in runs])))
    axes[1].set_ylabel(f"penetration [m]: deepest\nin the {span:.2g} s before")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[1].set_xlabel("t [s]")
    dt = "" if math.isnan(h) else f" at dt = {h:g} s"
    axes[0].set_title(f"{scenario}: distance moved and penetration over time{dt}", fontsize=10)
    if legend is not None:
        legend(axes[0])
    else:
        axes[0].legend(fontsize=7)
    Path(out).mkdir(parents=True, exist_ok=True)
    alt = (f"{scenario}: per configuration{dt}, the distance its bodies moved (the closed form "
           f"in grey) and the deepest penetration in the {span:.2g} s before each "
           "time (log axis)")  # fmt: skip
    return save(fig, Path(out) / f"{slug(scenario)}__system.png", alt=alt)


def _markdown(head, body) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in body]
    return "\n".join(lines)


#: the per-scene table's columns (:func:`scene_tables`): the contact metrics and their headings
SCENE_COLUMNS = {
    "position_error_max": "x err [m]", "attitude_error_max": "att err [rad]",
    "creep_speed": "creep [um/s]", "slide_distance": "moved [m]", "penetration_max": "pen [m]",
    "energy_gain_max": "E gain", "roll_onset_error": "onset err", "roll_speed_error": "v* err",
    "rebound_ratio_error": "rebound err", "signorini_residual": "Sig",
    "coulomb_residual": "Coul", "dissipation_residual": "MDP", "force_sum_error": "support err",
}  # fmt: skip


def scene_tables(df) -> list[tuple[str, float, list[str], list[list[str]]]]:
    """Per contact scene at its own dt: (scene, dt, header, rows), one row per configuration
    that ran there (unsupported ones with their reason): its verdict, each contact metric that
    applies to the scene (creep in um/s) and what failed."""
    from reports.store.results import default_dt

    out = []
    scenes = sorted(contact_rows(df)["scenario"].unique())
    for scene in scenes:
        sub = df[df["scenario"] == scene]
        h = default_dt(contact_rows(sub))
        sub = sub[np.isclose(sub["dt"], h, rtol=1e-9)]
        cols = [c for c in SCENE_COLUMNS if c in sub and sub[c].notna().any()]
        head = ["configuration", "verdict", *(SCENE_COLUMNS[c] for c in cols), "failing / why"]
        body = []
        for _, r in sub.sort_values(["engine", "integrator"]).iterrows():
            cells = []
            for c in cols:
                v = float(r[c])
                cells.append("-" if math.isnan(v) else f"{v * 1e6:.3g}" if c == "creep_speed"
                             else f"{v:.2g}")  # fmt: skip
            ok = r["status"] == "ok"
            why = (r.get("verdict_detail") if ok else r.get("message")) or ""
            why = str(why).replace("|", "/")
            why = why if len(why) <= 140 else why[:137] + "..."
            body.append([_config(r), r["verdict"] if ok else r["status"], *cells, why])
        out.append((scene, h, head, body))
    return out


def main(argv=None) -> int:
    """``python -m reports.report.contact RESULTS_DIR...``: the creep table and the stick/slide
    matrix of results folders as Markdown (the report's contact section, on its own); with
    ``--scenes``, each contact scene's table of every configuration's errors and verdict."""
    import argparse

    import pandas as pd

    from reports.store.results import read_results

    p = argparse.ArgumentParser(prog="python -m reports.report.contact", description=main.__doc__)
    p.add_argument("results", nargs="+", help="results folders (director-bench run --out DIR)")
    p.add_argument("--scenes", action="store_true", help="each scene's table as well")
    args = p.parse_args(argv)
    df = pd.concat([read_results(d) for d in args.results], ignore_index=True)
    print("Creep speed in stick scenes, um/s\n")
    print(_markdown(*creep_table(df)))
    print("\nStick or slide, against Coulomb's law\n")
    print(_markdown(*stick_slide_matrix(df)))
    if args.scenes:
        for scene, h, head, body in scene_tables(df):
            print(f"\n### {scene} (dt {h:g} s)\n")
            print(_markdown(head, body))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
