"""The suite's top-level operations, one function per CLI subcommand (the CLI is a thin layer)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from scenarios.schema import InputError, did_you_mean

DEFAULT_BASELINE = Path(__file__).resolve().parent / "baselines" / "default.json"
#: the default output folder of ``run`` and, apart from it, of ``ensemble``
RUN_OUT = "results"
ENSEMBLE_OUT = "results-ensemble"


@dataclass
class RunSummary:
    out: Path
    n_run: int
    n_skipped: int
    results: object  # pandas DataFrame: the folder's current results
    report: dict
    junit: Path | None
    #: engines whose adapter does not load here (no integrator to run), with the reason
    unloadable: dict = field(default_factory=dict)
    #: engines left out of the default suite on this machine, with the reason
    left_out: dict = field(default_factory=dict)
    #: exports edited by hand, moved aside before they were written again
    #: (reports.store.exports.keep_edited)
    moved: list = field(default_factory=list)
    #: the verdicts of an earlier check or compare of the folder, removed (:data:`VERDICTS`)
    removed: list = field(default_factory=list)


#: what ``check`` and ``compare`` write into a results folder by default: a verdict on the
#: results as they were, stale once a run changes them, so ``run`` removes them
VERDICT_FILES = ("check.md", "check.json", "compare.md", "compare.json")


def resolve_scenarios(names, all_: bool = False) -> list:
    """Scenario objects for names or paths; none given: the default suite. Two different
    scenarios with the same name are an error naming both files (results are filed by name),
    and so is a closed-form reference that does not apply (:func:`check_references`)."""
    import scenarios

    if all_:
        names = scenarios.list_scenarios() + scenarios.list_systems() + scenarios.list_contact()
        names += scenarios.default_robots()
    elif not names:
        names = scenarios.default_suite() + scenarios.default_systems()
        names += scenarios.default_contact() + scenarios.default_robots()
    out, seen = [], {}
    for n in names:
        sc = scenarios.load(n)
        prev = seen.get(sc.name)
        if prev is not None and prev.scenario_hash != sc.scenario_hash:
            raise InputError(
                f"two different scenarios are named {sc.name!r}: {prev.path} and {sc.path}; "
                "results are filed by name, so give one of them another name"
            )
        if prev is None:
            seen[sc.name] = sc
            out.append(sc)
    check_references(out)
    check_singular(out)
    return out


def check_singular(scs) -> None:
    """Refuse a system whose loops are at a singular configuration at t = 0 (two branches
    of the loop meet there, so no motion follows from the state: the director model's
    Newton iteration found no step and every other engine picks a branch by its own
    round-off), naming the loop closures
    (:func:`references.exact.multibody.loops.singular_at`)."""
    from scenarios.schema import file_error

    for sc in scs:
        if not sc.loop_joints:
            continue
        from references.exact.multibody import loops

        try:
            system, q0, _ = loops.system_from_world(sc.bodies, sc.joints, sc.gravity)
        except ValueError:
            continue  # the reference says why when it runs
        rel = loops.singular_at(system, q0)
        if rel > 0:
            idx = [i for i, j in enumerate(sc.joints) if j.name in system.closure_joints]
            field = f"joints[{idx[0]}]" if idx else "joints"
            rule = (f"the loops are at a singular configuration at t = 0: their rows lose rank "
                    f"there (directions their rates allow break their second-order condition "
                    f"by {rel:.3g} relative), two branches of the loop meet and no motion "
                    f"follows from this state; start off it (loop closures "
                    f"{', '.join(system.closure_joints)})")  # fmt: skip
            raise file_error(sc.path, [(field, sc.joints[idx[0]].name if idx else "", rule)])


#: a system's reference estimated to take longer than this (s) is announced before the runs
COST_WARNING_S = 60.0


def warn_costs(scs, t_end=None, say=None) -> list[str]:
    """Print (stderr, or through ``say``) and return a line for each system whose numerical
    reference is estimated to take more than :data:`COST_WARNING_S` (a pilot run,
    :func:`references.engines.exact.system.estimate`), and say when that exceeds the
    reference's bound (it is then refused at once and the rows have no reference)."""
    import sys

    if say is None:

        def say(text: str) -> None:
            print(text, file=sys.stderr)

    from references.engines.exact import system as exact_system
    from references.exact.multibody.integrate import MAX_WALL

    lines = []
    for sc in scs:
        if sc.kind == "body":
            continue
        sc2 = sc if t_end is None else sc.replace(t_end=float(t_end))
        try:
            got = exact_system.estimate(sc2)
        except ValueError:
            continue  # the reference says why when it runs
        if got is None or got[0] <= COST_WARNING_S:
            continue
        est, how = got
        over = (
            f"; beyond its bound of {MAX_WALL:g} s it is refused at once and the rows judge "
            "invariants and joints only"
            if est > MAX_WALL
            else ""
        )
        lines.append(f"scenario {sc.name!r}: its reference will take about {est:.3g} s "
                     f"({how}){over}")  # fmt: skip
        say(f"director-bench: note: {lines[-1]}")
    return lines


def warn_compiles(specs, say=None) -> list[str]:
    """Print (stderr, or through ``say``) and return a line for each engine whose runs would
    compile for more than :data:`COST_WARNING_S` of CPU in all before they step, where no
    cache holds the compilations: the engine's ``first_run_cost`` (what, CPU seconds, where
    compilations are kept) of each configuration (scenario and integrator; the step sizes
    of a sweep share one), summed."""
    import sys

    from references.engines import EngineError, get_engine

    if say is None:

        def say(text: str) -> None:
            print(text, file=sys.stderr)

    costs: dict = {}
    for s in specs:
        try:
            cost = getattr(get_engine(s.engine), "first_run_cost", None)
        except EngineError:
            continue
        got = cost(s.scenario, s.integrator) if cost is not None else None
        if got is not None:
            costs.setdefault(s.engine, {})[(s.scenario.name, s.integrator)] = got
    lines = []
    for engine, each in costs.items():
        total = sum(c for _, c, _ in each.values())
        if total <= COST_WARNING_S:
            continue
        (sc, integ), (what, top, kept) = max(each.items(), key=lambda kv: kv[1][1])
        lines.append(f"{engine}: {len(each)} configurations compile before they step, about "
                     f"{total:.3g} s of CPU in all where no cache holds them (the largest: "
                     f"{what} for {sc} {integ}, about {top:.3g} s); compilations are kept in "
                     f"{kept}, and a kept one loads in about a second")  # fmt: skip
        say(f"director-bench: note: {lines[-1]}")
    return lines


def check_references(scs) -> None:
    """A user's file that asks for a closed-form reference by name (``reference.kind``
    ``free_body``, ``lagrange_top``, ``steady_precession``; a system's ``spinning_chain``,
    ``conical_pendulum``, ``four_bar``) describes that motion: the closed form sets up from
    the file and, for a system, its state at t = 0 is the file's; else
    :class:`scenarios.ScenarioError` naming the file, ``reference.kind``, the value and why,
    before any run. Unchecked, each run would find it: a single body's rows become errors of
    the suite, and a system's rows run without a reference, their trajectory errors not
    measured, and pass. The library's files are skipped: tests hold each of them to this
    check, and setting up the spinning chain's closed form loads the multibody reference's
    compiled code (about 1.5 s in this process)."""
    import scenarios
    from references.exact import CLOSED_FORMS
    from scenarios.schema import file_error
    from scenarios.system import CONTACT_CLOSED_FORMS, SYSTEM_CLOSED_FORMS

    closed_forms = {
        "body": CLOSED_FORMS,
        "system": SYSTEM_CLOSED_FORMS,
        "contact": CONTACT_CLOSED_FORMS,
    }
    for sc in scs:
        if sc.reference not in closed_forms[sc.kind] or scenarios.is_library_file(sc):
            continue
        why = reference_problem(sc)
        if why is not None:
            other = "auto, numerical"
            rule = f"the closed form asked for does not apply: {why} (or ask for {other})"
            raise file_error(sc.path, [("reference.kind", sc.reference, rule)])


def reference_problem(sc) -> str | None:
    """Why the closed-form reference ``sc`` asks for does not apply to it, or None (see
    :func:`check_references`): the reference's own refusal, set up at t = 0."""
    if sc.kind == "contact":
        from references.exact._util import ReferenceNotApplicable
        from references.exact.contact_scene import contact_motion

        try:
            contact_motion(sc, [0.0, sc.t_end])
        except ReferenceNotApplicable as exc:
            return str(exc)
        return None
    if sc.kind == "system":
        import numpy as np

        from references.engines.exact import system as exact_system
        from references.errors import Unsupported

        try:
            exact_system.reference(sc, np.zeros(1))
        except Unsupported as exc:
            return str(exc)
        return None
    from references.exact import ReferenceNotApplicable, resolve_kind

    try:
        resolve_kind(sc)
    except ReferenceNotApplicable as exc:
        return str(exc)
    return None


def default_engines(every: bool = False) -> tuple[list[str], dict[str, str]]:
    """(the engines of the default suite on this machine, {engine left out: why}): every
    registered engine but those whose adapter says they do not belong here
    (``default_suite_exclusion``: MJX where JAX sees no accelerator); ``every``: all of them
    (``--engines all``, ``--full``)."""
    from references.engines import engine_names, get_engine

    names = engine_names()
    if every:
        return names, {}
    left_out = {}
    for name in names:
        why = get_engine(name).default_suite_exclusion()
        if why:
            left_out[name] = why
    return [n for n in names if n not in left_out], left_out


#: the --engines word that asks for every registered engine
ALL_ENGINES = "all"


def check_engines(engines) -> list[str]:
    """The engine names asked for (None: every registered engine; ``all`` among them: every
    one too), each checked; a name matches in any case ("MuJoCo" is ``mujoco``)."""
    from references.engines import engine_names

    known = engine_names()
    if engines is None or any(str(e).lower() == ALL_ENGINES for e in engines or ()):
        return known
    if not engines:
        raise InputError(f"--engines: an empty list; give one or more of {', '.join(known)}")
    by_lower = {k.lower(): k for k in known}
    bad = [e for e in engines if e.lower() not in by_lower]
    if bad:
        hint = did_you_mean(bad[0], known)
        raise InputError(
            f"--engines: unknown {', '.join(map(repr, bad))}{hint}; known: {', '.join(known)}"
        )
    return list(dict.fromkeys(by_lower[e.lower()] for e in engines))


def check_engine_settings(scs) -> None:
    """A system file's ``[engine_settings]``: each table names a registered engine and each
    setting one its system builder takes (where the builder declares them; a contact scene:
    its contact builder, :mod:`references.engines.contact`), or InputError
    naming the file, the field, the value and the rule, before any run: a misspelt engine
    would otherwise be ignored, a misspelt setting fail every run of that engine."""
    from references.engines import engine_names
    from references.engines.system import builder_settings

    known_engines = engine_names()
    for sc in scs:
        for engine, values in (getattr(sc, "engine_settings", None) or {}).items():
            if engine not in known_engines:
                raise InputError(
                    f"invalid scenario file {sc.path}: engine_settings.{engine} = {values!r}: "
                    f"not a registered engine{did_you_mean(engine, known_engines)}; known: "
                    f"{', '.join(known_engines)}"
                )
            if sc.kind == "contact":
                from references.engines.contact import builder_settings as contact_settings

                known, what = contact_settings(engine), "contact builder"
                if known is None:
                    known = ()
            else:
                known, what = builder_settings(engine), "system builder"
            for name, value in values.items():
                if known is not None and name not in known:
                    hint = _configured(engine, name) if sc.kind == "contact" else ""
                    raise InputError(
                        f"invalid scenario file {sc.path}: engine_settings.{engine}.{name} = "
                        f"{value!r}: not a setting of {engine}'s {what}"
                        f"{hint or did_you_mean(name, known)}; known: "
                        f"{', '.join(known) or 'none'}"
                    )


def _configured(engine: str, name: str) -> str:
    """Where a contact setting the builder does not take is what its configurations choose
    (MuJoCo's ``cone``, ``impratio``, ``noslip_iterations``): ", chosen by the
    configuration" and those that set it, for the error text; else ''."""
    from references.engines.contact import configurations

    confs = configurations(engine)
    keys = {k for c in confs for k in (c.options or {})}
    hit = next((k for k in sorted(keys) if name == k or k.startswith(name)), None)
    if hit is None:
        return ""
    names = ", ".join(repr(c.name) for c in confs)
    return (
        f" ({hit} is chosen by the contact configuration: pick one with --integrators; "
        f"{engine} offers {names})"
    )


def check_integrators(integrators, engines: list[str], named: bool = False) -> list[str] | None:
    """The display names of the integrators asked for, each offered by at least one of
    ``engines``. A name is given as displayed ("semi-implicit Euler", quoted in a shell) or
    as its slug (``semi-implicit-euler``, :func:`references.engines.slug`), in any case;
    it selects every integrator of these engines with that slug, an importer configuration
    of one ("rk4-as-loaded") included. ``named``: the engines were
    named by the user (``--engines``), so each must offer at least one of the integrators,
    else it would run nothing, silently (InputError naming it, what it offers and the
    closest name); without ``--engines`` an integrator selects the engines that offer it."""
    from references.engines import get_engine, importers, slug

    if integrators is None:
        return None
    offered: dict[str, list[str]] = {}  # slug -> display names
    for e in engines:
        own = [i.name for i in get_engine(e).integrators]
        for name in own + importers.variants(e, own):  # and its importer configurations
            names = offered.setdefault(slug(name), [])
            if name not in names:
                names.append(name)
    if not integrators:
        raise InputError(f"--integrators: an empty list; give one or more of {', '.join(offered)}")
    bad = [i for i in integrators if slug(i) not in offered]
    if bad:
        hint = did_you_mean(slug(bad[0]), offered)
        raise InputError(
            f"--integrators: {', '.join(map(repr, bad))} offered by none of the engines "
            f"{', '.join(engines)}{hint}; they offer: {', '.join(offered)}"
        )
    asked = {slug(i) for i in integrators}
    for e in engines if named else ():
        names = [i.name for i in get_engine(e).integrators]
        own = list(dict.fromkeys(slug(n) for n in names + importers.variants(e, names)))
        if not asked & set(own):
            hint = did_you_mean(slug(integrators[0]), own)
            raise InputError(
                f"--engines {e}: offers none of the integrators asked for (--integrators "
                f"{','.join(integrators)}), so it would run nothing; {e} offers "
                f"{', '.join(own)}{hint}. Add one of them to --integrators or leave {e} out "
                "of --engines"
            )
    return list(dict.fromkeys(n for i in integrators for n in offered[slug(i)]))


def check_count(name: str, value) -> None:
    if value is not None and not (isinstance(value, int) and value >= 1):
        raise InputError(f"{name} = {value!r}: must be a whole number >= 1")


def check_jobs(jobs) -> None:
    """At most 4 local workers per core: more only share the cores, and each worker's share
    of memory (the limit on the states a run keeps) shrinks with their number."""
    import os

    most = 4 * (os.cpu_count() or 1)
    if jobs is not None and jobs > most:
        raise InputError(f"--jobs {jobs}: at most {most} (4 per core on this machine)")


def check_out(out) -> Path:
    """The output folder, made absolute and created; refused if it is a file or cannot be
    written."""
    import os
    import tempfile

    out = Path(out).expanduser().resolve()
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-probe-", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None
    return out


def worker_preload(engines) -> tuple[str, ...]:
    """What local workers import before they start, beyond the suite's own modules
    (reports.run.parallel.PRELOAD): what the adapters of ``engines`` (None: every engine; names
    in any case) declare safe to import before a fork (``preload``: JAX for MJX, whose import
    starts no thread and initialises no device)."""
    from references.engines import engine_names, get_engine

    known = {n.lower(): n for n in engine_names()}
    asked = engine_names() if engines is None else engines
    out: list[str] = []
    for e in asked:
        name = known.get(str(e).lower())
        if name is not None:
            out += [m for m in get_engine(name).preload if m not in out]
    return tuple(out)


def run(
    names=(),
    *,
    all_scenarios: bool = False,
    engines=None,
    integrators=None,
    dts=None,
    t_end=None,
    sweep: bool = True,
    out=RUN_OUT,
    redo: bool = False,
    fmt: str = "parquet",
    report: bool = True,
    progress: bool = True,
    jobs: int | None = None,
    scheduler: str | None = None,
    save_every: int | None = None,
    segment: int | None = None,
    accuracies=None,
    full: bool = False,
    trajectories: str = "report",
) -> RunSummary:
    """Run scenarios x engines x integrators x dt into ``out`` and write the report and
    ``junit.xml`` (the verdicts). Every input is checked before any run (ValueError naming the
    argument, value and rule). ``jobs``: local worker processes (default: one per core);
    ``scheduler``: a Dask scheduler address; ``trajectories``: what each run keeps on disk,
    ``report`` (the series the report draws) or ``full`` (reports.run.files)."""
    import os

    from references.engines import get_engine
    from reports.report import junit
    from reports.report.build import build_report
    from reports.run.files import MODES, assign
    from reports.run.importers import tables_unit
    from reports.run.parallel import make_mapper
    from reports.run.plan import max_states, plan
    from reports.run.progress import Clock
    from reports.run.runner import run_suite
    from reports.store.exports import keep_edited
    from reports.store.provenance import write_provenance
    from reports.store.results import STORE_NAME

    for name, value in (("--jobs", jobs), ("--segment", segment), ("--save-every", save_every)):
        check_count(name, value)
    check_jobs(jobs)
    if trajectories not in MODES:
        raise InputError(f"--trajectories {trajectories!r}: one of {', '.join(MODES)}")
    if fmt != "parquet" and trajectories != "full":
        raise InputError(
            f"--format {fmt}: the format of full trajectories; by default a run keeps the "
            "series the report draws, in Parquet: add --trajectories full"
        )
    out = Path(out).expanduser().resolve()
    try:
        if out.exists() and not out.is_dir():
            raise InputError(f"--out {out}: is a file, not a folder")
    except OSError as exc:  # a name the file system cannot hold (over 255 bytes)
        raise InputError(f"--out {out}: {exc.strerror or exc}") from None
    # a local pool's workers start importing now (reports.run.parallel), while this process
    # loads the scenarios and plans the runs (nothing runs before every input is checked)
    named = engines is not None
    left_out = {}
    if engines is None:  # the default suite's engines on this machine
        engines, left_out = default_engines(every=full)
    local = None if scheduler else make_mapper(jobs, None, out, worker_preload(engines))
    # the systems' reference pilots compile the multibody reference from a fresh clone: a
    # terminal shows a running clock meanwhile (reports.run.progress.Clock)
    with Clock("director-bench: planning the runs", disable=not progress) as clock:
        scs = resolve_scenarios(names, all_scenarios)
        check_engine_settings(scs)
        warn_costs(scs, t_end, say=clock.note)
        engines = check_engines(engines)
        integrators = check_integrators(integrators, engines, named)
        unloadable = {e: why for e in engines if (why := get_engine(e).broken)}
        limit = max_states(jobs or os.cpu_count() or 1)  # reports.run.plan
        specs = plan(
            scs, engines, integrators, dts, t_end, sweep, save_every, segment, accuracies,
            limit, full,
        )  # fmt: skip
        warn_compiles(specs, say=clock.note)
    if not specs:
        why = "".join(f"; {w}" for w in unloadable.values())
        raise InputError(f"nothing to run: no engine offers the integrators asked for{why}")
    specs = assign(specs, trajectories)
    mapper = local or make_mapper(jobs, scheduler, out)
    # every input is checked: only now is anything written
    out = check_out(out)
    write_provenance(out, engines, left_out)
    moved = keep_edited(out) if (out / STORE_NAME).is_file() else []
    removed = [out / n for n in VERDICT_FILES if (out / n).is_file()]
    for p in removed:
        p.unlink()
    # robot models: each importer's table, written by a worker beside the last runs
    tables = tables_unit(scs, engines, out)
    df, n_run = run_suite(
        specs, out, redo=redo, fmt=fmt, progress=progress, mapper=mapper,
        extra=[tables] if tables else [],
    )  # fmt: skip
    path = junit.write(df, out / "junit.xml")  # first: the verdicts never wait on the report
    rep = build_report(out, progress=progress, results=df) if report else {}
    return RunSummary(
        out, n_run, len(specs) - n_run, df, rep, path, unloadable, left_out, moved, removed
    )


def compile_kernels(jobs: int | None = None) -> dict:
    """Compile the numba kernels of the default suite's runs into numba's on-disk cache
    (``director-bench compile``, reports.run.compile): plans the default suite as :func:`run`
    does, then executes one short run of each configuration that compiles something."""
    import os

    from reports.run.compile import compile_specs, listen
    from reports.run.plan import max_states, plan

    check_count("--jobs", jobs)
    check_jobs(jobs)
    listen()  # the loops' singularity check (check_singular) compiles multibody kernels here
    engines, _ = default_engines()
    scs = resolve_scenarios(())
    engines = check_engines(engines)
    integrators = check_integrators(None, engines, False)
    limit = max_states(jobs or os.cpu_count() or 1)
    specs = plan(scs, engines, integrators, None, None, False, None, None, None, limit, False)
    return compile_specs(specs, jobs, worker_preload(engines))


def ensemble(
    name,
    n: int,
    *,
    seed: int = 0,
    engines=None,
    integrators=None,
    dt=None,
    t_end=None,
    out=ENSEMBLE_OUT,
    jobs=None,
    scheduler=None,
    progress=True,
    report: bool = True,
):
    """Run ``n`` members of one scenario on every engine/integrator into ``out/ensemble.csv``
    (see :mod:`reports.run.ensemble`), and refresh the report of ``out``. The default folder is
    :data:`ENSEMBLE_OUT`, apart from the suite's ``results``, so that an ensemble never
    joins the main report unless asked to."""
    from reports.report.build import build_report
    from reports.run.ensemble import check_ensemble, run_ensemble
    from reports.run.parallel import make_mapper
    from reports.store.provenance import write_provenance

    (sc,) = resolve_scenarios([name])
    if sc.kind != "body":
        raise InputError(f"ensemble: {name!r} is a system of bodies; ensembles perturb one body")
    named = engines is not None
    engines = check_engines(engines)
    integrators = check_integrators(integrators, engines, named)
    check_count("--jobs", jobs)
    check_jobs(jobs)
    check_ensemble(sc, n, sc.dt if dt is None else dt, sc.t_end if t_end is None else t_end, jobs)
    out = check_out(out)
    if not (out / "provenance.json").exists():
        write_provenance(out)
    df = run_ensemble(
        sc,
        n,
        out,
        seed=seed,
        engines=engines,
        integrators=integrators,
        dt=dt,
        t_end=t_end,
        mapper=make_mapper(jobs, scheduler, out),
        progress=progress,
    )
    rep = build_report(out) if report else {}
    return df, rep


def catalog() -> dict:
    """Scenarios, engines (with version or why unavailable) and their integrators: each
    with its display ``name``, its ``slug`` (the name as typed on a command line) and
    ``default`` (part of the default suite)."""
    import scenarios
    from references.engines import engine_names, get_engine

    scs = []
    default = set(scenarios.default_suite()) | set(scenarios.default_systems())
    default |= set(scenarios.default_contact()) | set(scenarios.default_robots())
    every = scenarios.list_scenarios() + scenarios.list_systems() + scenarios.list_contact()
    # the robot models shipped with the suite (the others need the optional extra `robots`)
    for name in every + scenarios.default_robots():
        sc = scenarios.load(name)
        scs.append(
            {
                "name": name,
                "description": sc.description,
                "default": name in default,
                "pivoted": sc.pivoted,
                "t_end": sc.t_end,
                "dt": sc.dt,
            }
        )
    engs = []
    for name in engine_names():
        cls = get_engine(name)
        why = cls.availability()
        engs.append(
            {
                "name": name,
                "available": why is None,
                "version": cls.version() if why is None else None,
                "why": why,
                "integrators": [
                    {
                        "name": i.name,
                        "slug": i.slug,
                        "default": i.default,
                        "family": i.family,
                        "order": i.order,
                        "description": i.description,
                    }
                    for i in cls.integrators
                ],
            }
        )
    return {"scenarios": scs, "engines": engs}
