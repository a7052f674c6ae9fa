"""What each subcommand of ``director-bench`` does: one library call each (:mod:`reports.suite`,
the report, the gate), and the lines it prints."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

#: the widths `list` lays its text out in: the terminal's, within these bounds
LIST_WIDTH = (60, 100)


#: the column where the text beside a scenario's or an integrator's name begins
LIST_COLUMN = 28


def _columns(left: str, text: str, width: int) -> list[str]:
    """``left`` then ``text`` wrapped at word boundaries from column LIST_COLUMN to ``width``
    (a word is never cut, not even at a hyphen; a NUL in ``text`` is a space that does not
    break); a ``left`` too wide for its column gets a line of its own."""
    import textwrap

    pad = " " * LIST_COLUMN
    lines = textwrap.wrap(
        text, width - LIST_COLUMN, break_long_words=False, break_on_hyphens=False
    ) or [""]
    lines = [line.replace("\0", " ") for line in lines]
    if len(left) < LIST_COLUMN:
        first = [f"{left:<{LIST_COLUMN}}{lines[0]}".rstrip()]
        return first + [pad + line for line in lines[1:]]
    return [left] + [pad + line for line in lines]


def _first_sentence(text: str) -> str:
    import re

    text = " ".join(text.split())
    return re.split(r"(?<=[.!?])\s+(?=[A-Z])", text, maxsplit=1)[0]


def cmd_list(args) -> int:
    import shutil
    import textwrap

    from reports.suite import catalog

    cat = catalog()
    if args.json:
        print(json.dumps(cat, indent=1))
        return 0
    lo, hi = LIST_WIDTH
    width = min(max(shutil.get_terminal_size((80, 24)).columns, lo), hi)
    out = ["Scenarios (* = in the default suite):"]
    for s in cat["scenarios"]:
        mark = "*" if s["default"] else " "
        text = f"{s['t_end']:g} s at dt {s['dt']:g} s. {_first_sentence(s['description'])}"
        out += _columns(f"{mark} {s['name']}", text, width)
    out += [""] + textwrap.wrap(
        "Engines and integrators (* = in the default suite). Give an integrator by the name on "
        "the left (--integrators semi-implicit-euler); case does not matter, and the display "
        'name, quoted, works too ("semi-implicit Euler").',
        width,
        break_on_hyphens=False,
    )
    for e in cat["engines"]:
        state = e["version"] if e["available"] else f"NOT AVAILABLE: {e['why']}"
        out += textwrap.wrap(
            f"{e['name']} {state}", width, subsequent_indent="    ", break_on_hyphens=False
        )
        for i in e["integrators"]:
            mark = "*" if i["default"] else " "
            text = f"order {i['order']}, {i['family']}"
            if i["name"] != i["slug"]:
                shown = i["name"].replace(" ", "\0")  # a display name stays on one line
                text += f'; shown as "{shown}"'
            out += _columns(f"  {mark} {i['slug']}", text, width)
    print("\n".join(out))
    return 0


def _show_lines(sc) -> list[str]:
    """What ``show`` prints of one checked scenario: its bodies and joints, run, reference
    and the scales its metrics are divided by."""
    from references.engines.exact.system import reference_kind as system_reference_kind

    def vec(a) -> str:
        return "[" + ", ".join(f"{float(x):.6g}" for x in a) + "]"

    lines = [f"{sc.name} ({sc.path}): valid"]
    if sc.kind != "body":
        loops = sc.loop_joints
        lines.append(
            f"  a system of {len(sc.bodies)} bodies, {len(sc.joints)} joints"
            + (f"; loop closures: {', '.join(sorted(loops))}" if loops else "; a tree")
            + ("; floating" if sc.floating else "")
        )
        for b in sc.bodies:
            lines.append(
                f"    body {b.name}: mass {b.mass:.6g} kg, moments {vec(b.inertia)} kg m^2, "
                f"x_G {vec(b.position)} m"
            )
        for j in sc.joints:
            lines.append(f"    joint {j.name}: {j.kind} {j.body_a} - {j.body_b or 'ground'}")
        for s in getattr(sc, "springs", ()):
            lines.append(
                f"    spring {s.name}: {s.body_a} - {s.body_b or 'ground'}, stiffness "
                f"{s.stiffness:g} N/m, damping {s.damping:g} N s/m, rest length "
                f"{s.rest_length:g} m"
            )
        for t in getattr(sc, "torques", ()):
            lines.append(f"    torque {t.torque:g} N m on joint {t.joint}")
        if sc.kind == "contact":
            lines += _contact_lines(sc, vec)
        if getattr(sc, "model", None) is not None:
            from scenarios.models.scenario import describe

            lines += describe(sc)
        kind = system_reference_kind(sc)
    else:
        from references.exact import resolve_kind

        where = "pivoted" if sc.pivoted else "free"
        lines.append(
            f"  one {where} body: mass {sc.mass:.6g} kg, moments {vec(sc.inertia)} kg m^2, "
            f"W0 {vec(sc.omega_body)} rad/s"
        )
        kind = resolve_kind(sc)
    lines.append(f"  gravity {vec(sc.gravity)} m/s^2")
    sweep = ", ".join(f"{h:g}" for h in sc.dt_sweep) or "-"
    lines.append(
        f"  run: t_end {sc.t_end:g} s, dt {sc.dt:g} s ({round(sc.t_end / sc.dt)} steps), "
        f"dt_sweep {sweep}, save_every {sc.save_every}"
    )
    asked = "" if sc.reference == kind else f" (asked: {sc.reference})"
    lines.append(f"  reference: {kind}{asked}")
    if sc.kind == "contact":
        from reports.metrics import contact as mc

        lines.append(
            f"  contact scales: L {mc.size(sc):.4g} m (slides beyond L/10), F_c "
            f"{mc.force_scale(sc):.4g} N, V_c {mc.speed_scale(sc):.4g} m/s"
        )
    else:
        scales = ", ".join(f"{k} {v:.4g}" for k, v in sc.energy_scales.items())
        lines.append(f"  scales: energy ({scales}) J, momentum {sc.momentum_scale:.4g} kg m^2/s")
    if sc.tolerances:
        lines.append(f"  tolerances: {sc.tolerances}")
    return lines


def _contact_lines(sc, vec) -> list[str]:
    """The shapes, planes, touching pairs, forces and closed form of a contact scene."""
    out = []
    for b in sc.bodies:
        s = b.shape
        if s is None:
            continue
        size = (
            f"half extents {vec(s.half_extents)}"
            if s.kind == "box"
            else f"radius {s.radius:g}"
            + (f", half length {s.half_length:g}" if s.kind in ("capsule", "cylinder") else "")
        )
        out.append(f"    shape of {b.name}: {s.kind}, {size} m, offset {vec(s.position)} m")
    for p in sc.planes:
        out.append(f"    plane {p.name}: normal {vec(p.normal)}, through {vec(p.point)} m")
    for c in sc.contacts:
        out.append(f"    contact {c.a} - {c.b}: mu {c.mu:g}, e {c.e:g}")
    for f in sc.forces:
        out.append(f"    force on {f.body}: {vec(f.force)} N at {vec(f.point)} m (body axes)")
    if sc.reference not in ("auto", "none"):
        import numpy as np

        from references.exact.contact_scene import contact_motion

        facts = contact_motion(sc, np.array([0.0, sc.t_end])).facts
        shown = {
            k: v
            for k, v in facts.items()
            if isinstance(v, bool | float) and k not in ("friction_ratio",)
        }
        out.append(
            "    closed form: "
            + ", ".join(
                f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}" for k, v in shown.items()
            )
        )
    return out  # fmt: skip


def cmd_show(args) -> int:
    from reports.run.plan import check_families
    from reports.suite import check_engine_settings, resolve_scenarios

    scs = resolve_scenarios(args.scenarios)
    check_engine_settings(scs)
    out = []
    for sc in scs:
        check_families(sc)
        out += _show_lines(sc)
        if args.importers and getattr(sc, "model", None) is not None:
            out += _importer_lines(sc, args.engines)
    print("\n".join(out))
    return 0


def _importer_lines(sc, engines) -> list[str]:
    """The importer-difference table of a robot-model scenario (``show --importers``)."""
    from references.engines.importers import importer_table

    rows = importer_table(sc.model, engines=engines, fixed_base=not sc.floating)
    lines = ["  importers (each engine's own loader, read back at the zero configuration, "
             "root-link frame; differences from our reading):"]  # fmt: skip
    lines += [f"    {r.line()}" for r in rows]
    return lines


def cmd_compile(args) -> int:
    from reports.suite import compile_kernels

    got = compile_kernels(jobs=args.jobs)
    kernels, seconds = got["kernels"], got["seconds"]
    for run, message in got["errors"]:
        print(f"director-bench compile: note: the short run {run} errored ({message}); "
              "what it did not reach compiles at its first run")  # fmt: skip
    if kernels:
        cpu = sum(c for _, c in kernels)
        print(f"compiled {len(kernels)} numba kernel(s) in {seconds:.1f} s ({cpu:.1f} s of CPU "
              f"compiling), through {got['runs']} short runs; numba keeps them beside the "
              "sources (__pycache__) for every later run")  # fmt: skip
    else:
        print(f"nothing to compile: every kernel of the default suite's runs was in numba's "
              f"cache ({got['runs']} short runs checked in {seconds:.1f} s)")  # fmt: skip
    return 0


def cmd_run(args) -> int:
    if args.no_reference_cache:  # before any worker starts: they inherit it
        import os

        from references.cache import SWITCH_ENV

        os.environ[SWITCH_ENV] = "off"
    from reports.suite import run

    summary = run(
        args.scenarios,
        all_scenarios=args.all,
        engines=args.engines,
        integrators=args.integrators,
        dts=args.dt,
        t_end=args.t_end,
        sweep=not args.no_sweep,
        out=args.out,
        redo=args.redo,
        fmt=args.format,
        report=not args.no_report,
        progress=not args.quiet,
        jobs=args.jobs,
        scheduler=args.scheduler,
        save_every=args.save_every,
        segment=args.segment,
        accuracies=args.accuracy,
        full=args.full,
        trajectories=args.trajectories,
    )
    df = summary.results
    print(
        f"{summary.n_run} runs executed, {summary.n_skipped} already done "
        f"(use --redo to run them again). The folder holds {len(df)} runs."
    )
    print("Status:  " + _counts(df["status"]))
    print("Verdict: " + _counts(df["verdict"].replace("", "none")))
    out = summary.out
    print(f"results:      {out / 'results.sqlite'} (exported: results.csv, results.parquet)")
    if args.trajectories == "report":
        print(
            f"trajectories: {out / 'trajectories'}: the series the report draws, at each "
            "scenario's own step (--trajectories full keeps every run's whole trajectory)"
        )
    if summary.report:
        print(f"report:       {summary.report['html']}\n              {summary.report['markdown']}")
    print(f"junit:        {summary.junit}")
    for why in summary.unloadable.values():
        print(f"not run:      {why}")
    for engine, why in summary.left_out.items():
        print(f"not run:      {engine}, left out of the default suite here: {why}; "
              "--engines all adds it")  # fmt: skip
    for path in summary.moved:
        print(
            f"moved aside:  {path} (it was changed by hand after director-bench wrote it; the "
            f"commands read the store, and {path.stem} was written again from it)"
        )
    if summary.removed:
        names = ", ".join(p.name for p in summary.removed)
        print(
            f"removed:      {names} (the verdict of an earlier `check` or `compare` on the "
            "results before this run; run it again)"
        )
    failed = df[(df["verdict"] == "fail") | (df["status"] == "error")]
    if len(failed):
        print(f"{len(failed)} run(s) failed their verdict or errored{_known(out, df)}; see the "
              "report's failures.")  # fmt: skip
    return 1 if (args.strict and len(failed)) else 0


def _known(out, df) -> str:
    """How many of the failures of the results ``df`` the committed baseline expects: ``: all
    190 fail as in the committed baseline (FILE), known failures``, ``: 185 fail as in ...,
    5 do not (`director-bench check` lists them)``, and how many runs it does not hold (``2
    not in it``: another suite's runs have no expectation there)."""
    from reports.gate.check import failures_in_baseline
    from reports.suite import DEFAULT_BASELINE

    if not DEFAULT_BASELINE.is_file():
        return ""
    known, other, absent = failures_in_baseline(out, df, DEFAULT_BASELINE)
    where = f"the committed baseline ({DEFAULT_BASELINE})"
    if not known and not other:
        return f": none of them is in {where}"
    if not other and not absent:
        return f": all {known} fail as in {where}, known failures, not regressions"
    text = f": {known} fail as in {where}"
    if other:
        text += (
            f", {other} do not (`director-bench check {out} --baseline {DEFAULT_BASELINE}` "
            "lists them)"
        )
    return text + (f", {absent} not in it" if absent else "")


def _counts(series) -> str:
    counts = series.value_counts().to_dict()
    return ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "none"


def cmd_ensemble(args) -> int:
    from reports.store.ensemble import summary
    from reports.suite import ensemble

    df, rep = ensemble(
        args.scenario,
        args.n,
        seed=args.seed,
        engines=args.engines,
        integrators=args.integrators,
        dt=args.dt,
        t_end=args.t_end,
        out=args.out,
        jobs=args.jobs,
        scheduler=args.scheduler,
        progress=not args.quiet,
        report=not args.no_report,
    )
    for r in summary(df):
        print(
            f"{r['engine']:>9} {r['integrator']:<22} members {r['members']:>7}  attitude "
            f"error median {r['attitude_error_max median']:.2e} max "
            f"{r['attitude_error_max max']:.2e}"
        )
    print(f"ensemble:     {Path(args.out) / 'ensemble.csv'}")
    if rep:
        print(f"report:       {rep['html']}")
    return 0


def _warn_edited(folder) -> None:
    """Say so when an export of ``folder`` (results.csv, results.parquet) was changed by
    hand (reports.store.exports): the commands read the store, so the change is not read."""
    from reports.store.exports import edited

    for sentence in edited(folder).values():
        print(f"director-bench: warning: {sentence}", file=sys.stderr)
        if os.environ.get("GITHUB_ACTIONS"):
            print(f"::warning title=director-bench: an export was edited::{sentence}")


def cmd_report(args) -> int:
    from reports.report.build import build_report

    folder = Path(args.dir)
    if (folder / "results.sqlite").is_file():
        _warn_edited(folder)
    if (folder / "results.sqlite").is_file() and not os.access(folder, os.W_OK):
        # the store reads fine (compare and check work here); the report is written beside it
        print(
            f"director-bench: error: {folder} is read-only and the report is written into the "
            f"results folder: copy it somewhere writable (`cp -r {folder} COPY`) and run "
            "`director-bench report COPY`",
            file=sys.stderr,
        )
        return 1
    rep = build_report(args.dir, progress=True)
    print(f"report: {rep['html']}\n        {rep['markdown']}")
    return 0


def cmd_baseline(args) -> int:
    from reports.gate.check import write_baseline
    from scenarios.schema import InputError

    if Path(args.write).is_dir():
        raise InputError(f"--write {args.write}: is a folder; give the baseline file's name")
    path = write_baseline(args.dir, args.write)
    print(f"baseline written: {path}")
    return 0


def cmd_check(args) -> int:
    from reports.gate.check import check

    if (Path(args.dir) / "results.sqlite").is_file():
        _warn_edited(args.dir)
    return check(
        args.dir,
        args.baseline,
        factor=args.factor,
        timing_factor=args.timing_factor,
        markdown=args.markdown,
        json_path=args.json,
    )


def cmd_compare(args) -> int:
    from reports.gate.compare import run_compare

    for folder in (args.a, args.b):
        if (Path(folder) / "results.sqlite").is_file():
            _warn_edited(folder)
    return run_compare(
        args.a,
        args.b,
        factor=args.factor,
        cost_factor=args.cost_factor,
        vary=tuple(args.vary or ()),
        show_all=args.all,
        markdown=args.markdown,
        json_path=args.json,
    )
