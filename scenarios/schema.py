"""Reading and validating scenario files (TOML) into :class:`scenarios.model.Scenario` objects.

The schema is documented in ``docs/scenarios.md``. Validation is strict and complete: every
problem found in a file is collected and reported in one :class:`ScenarioError` whose message
names the file, the field (dotted, e.g. ``body.inertia``), the value found and the rule broken.
Nothing is ever repaired silently (a rotation that is not orthonormal is an error, not
re-orthonormalised).

Physical checks of the body (:func:`body_problems`) follow docs/numerics.md section 1: all principal
moments positive, the triangle inequality ``I_i <= I_j + I_k`` (equivalently all convected
moments ``J_i = (I_j + I_k - I_i)/2 >= 0``), and not a thin rod (two ``J_i`` equal to zero).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from scenarios.model import REFERENCE_KINDS, TOLERANCE_METRICS, Scenario

#: Tolerance on the orthonormality of a given rotation matrix, max |R^T R - 1|, and on the
#: norm of a given quaternion. Decimal input with 16-17 significant digits meets it easily; a
#: matrix typed with 12 digits is at the edge (docs/numerics.md's R(10) gives 7.8e-13) and one with
#: fewer digits fails (use ``rotation_vector`` or ``quaternion_wxyz`` then).
ROTATION_TOL = 1e-12

#: Relative tolerance of the triangle inequality and of the thin-rod test, in units of the
#: largest moment: J_i = (I_j + I_k - I_i)/2 is a difference of O(I) numbers, so its rounding
#: is a few ulps of max(I). 16 eps, the same as ``director_model.body.FLAT_TOL``, so that a file
#: accepted here is accepted by the director model (a test checks they agree).
INERTIA_RTOL = 16 * float(np.finfo(float).eps)

#: Largest scenario file read (bytes): a guard against pointing the loader at a device or a
#: huge file by mistake; the library's files are 1-2 KiB.
MAX_FILE_BYTES = 1 << 20

#: Deepest nesting of arrays and tables a scenario file may have: the schema's deepest value
#: is a family's tolerance, ``tolerances."<family>".metric`` (3 levels below the top), and a
#: rotation matrix is a list of lists. A deeper file is not a scenario file, and one nested
#: thousands of levels deep would exhaust the parser's recursion.
MAX_DEPTH = 8

#: Longest scenario name, in bytes (names are ASCII). The name starts the file names a run
#: writes: the folder ``trajectories/<name>/``, the figures ``<name>__<plot>.png`` (the
#: longest, ``<name>__ensemble_attitude_error_max.png``, adds 34 bytes) and the temporary
#: file each is first written to, ``.<file>.<pid>.tmp`` (13 more bytes with a 7-digit
#: process id); an ensemble member is ``<name>#<k>``. 128 leaves half of the 255 bytes a
#: file name may have on Linux, macOS and Windows file systems (NAME_MAX) for these
#: suffixes; tests/scenarios/test_scenarios.py writes every file of a run with a name this long.
MAX_NAME_BYTES = 128

#: Largest angle of a rotation vector (rad): rounding shifts an angle x by about eps x, so
#: beyond ROTATION_TOL/eps (4.5e3 rad) the angle modulo 2 pi is not known to ROTATION_TOL.
MAX_ROTATION_ANGLE = ROTATION_TOL / float(np.finfo(float).eps)

#: Largest number of steps in a run, t_end/dt: 2^53, beyond which the step index k of the
#: time t = k dt is no longer exact in double precision (and dt = 5e-324 would give an
#: infinite count).
MAX_STEPS = 2**53

#: Largest magnitude (SI units) of a mass, moment of inertia, energy, momentum, position or
#: velocity reached over the horizon, and the reciprocal is the smallest mass and moment:
#: the suite squares such quantities when it takes norms and energies, and double precision
#: ends at 1.8e308 (a mass of 1e308 would make every energy infinite).
MAX_MAGNITUDE = 1e150


class InputError(ValueError):
    """Input the user must fix (a file, a name, an option, a folder): the command line exits 2
    with the message, which names the input, its value and the rule. Every other exception is
    a failure of the work (exit 1)."""


class ScenarioError(InputError):
    """A scenario file (or name) is invalid. ``problems`` lists ``(field, value, rule)``
    triples; ``path`` is the file concerned (or None)."""

    def __init__(self, message: str, path: str | None = None, problems=()):
        super().__init__(message)
        self.path = path
        self.problems = list(problems)


# -- rotations ------------------------------------------------------------------------------


def did_you_mean(word: str, names) -> str:
    """`` (did you mean 'x'?)`` naming the ``names`` closest to ``word`` in spelling (difflib's
    ratio of at least 0.6, case ignored), or "" when none is close: the one hint every misspelt
    name gets (a scenario, an engine, a setting, a reference kind, a body of a contact pair)."""
    import difflib

    by_lower = {str(n).lower(): str(n) for n in names}
    close = difflib.get_close_matches(str(word).lower(), list(by_lower), n=3, cutoff=0.6)
    return f" (did you mean {' or '.join(repr(by_lower[c]) for c in close)}?)" if close else ""


def rotation_from_vector(r) -> np.ndarray:
    """R = exp(hat(r)) by Rodrigues' formula, r = angle * unit axis (3,), rad: (3, 3). Exact to
    round-off for any angle, including 0 (Taylor series below 1e-4 rad). The suite's one
    definition: scenario files' rotation vectors here, and, as
    ``references.conventions.rotvec_to_matrix``, the integrators' stages and the engines'
    exponential coordinates.

    Written as R = 1 + s K + c (r r^T - a^2 1) with K = hat(r), a = |r|, s = sin(a)/a,
    c = (1 - cos a)/a^2, in scalar arithmetic (it runs in integrator stages).
    """
    x, y, z = (float(t) for t in np.ravel(r))
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        # Series to the last term that matters in double precision at a < 1e-4.
        s = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
        c = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
    else:
        a = math.sqrt(a2)
        s = math.sin(a) / a
        c = 2.0 * math.sin(0.5 * a) ** 2 / a2  # (1 - cos a)/a^2 without cancellation
    return np.array(
        [
            [1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y],
            [c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x],
            [c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y)],
        ]
    )


def rotation_from_quaternion(q) -> np.ndarray:
    """Rotation matrix of the quaternion (w, x, y, z). The homogeneous form used here is an
    exact rotation for any non-zero q (it divides by |q|^2); callers check |q| = 1 first."""
    w, x, y, z = (float(c) for c in q)
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return np.array(
        [
            [1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
            [s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)],
            [s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)],
        ]
    )


# -- physical checks of a body ----------------------------------------------------------------


def body_problems(mass, inertia, field_prefix: str = "body") -> list[tuple]:
    """Physical-validity problems of a rigid body as ``(field, value, rule)`` triples (empty if
    valid). ``inertia`` are the principal moments about the centre of mass; either argument may
    be None (not checked). Self-contained so that scenario files validate without the director
    model."""
    probs = []
    if mass is not None and not float(mass) > 0:
        probs.append((f"{field_prefix}.mass", mass, "the mass must be > 0 kg"))
    if inertia is None:
        return probs
    I = np.asarray(inertia, dtype=float)
    if np.any(I <= 0):
        pos = I[I > 0]
        if np.count_nonzero(I == 0) == 1 and len(pos) == 2 and pos[0] == pos[1]:
            rule = (
                "a thin rod (zero moment about its axis; two convected moments "
                "J_i = (I_j + I_k - I_i)/2 are zero): the spin about the rod carries no inertia "
                "and the motion is not defined"
            )
        else:
            rule = "every principal moment must be > 0 kg m^2"
        probs.append((f"{field_prefix}.inertia", list(inertia), rule))
        return probs
    tol = INERTIA_RTOL * float(I.max())
    J = 0.5 * (I.sum() - 2.0 * I)  # convected moments J_i = (I_j + I_k - I_i)/2
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        if J[i] < -tol:
            probs.append(
                (
                    f"{field_prefix}.inertia",
                    list(inertia),
                    f"triangle inequality I_{i + 1} <= I_{j + 1} + I_{k + 1} violated "
                    f"({float(I[i])!r} > {float(I[j] + I[k])!r}): no mass distribution has "
                    "these moments",
                )
            )
    if not probs and np.sum(J <= tol) >= 2:
        probs.append(
            (
                f"{field_prefix}.inertia",
                list(inertia),
                "a thin rod (two convected moments J_i = (I_j + I_k - I_i)/2 are zero to "
                f"{INERTIA_RTOL:.2g} relative): the spin about the rod carries no inertia and the "
                "motion is not defined",
            )
        )
    return probs


# -- the schema -------------------------------------------------------------------------------

# table -> field -> (kind, required)
_SPEC: dict[str, dict[str, tuple[str, bool]]] = {
    "": {
        "name": ("name", True),
        "description": ("str", True),
        "source": ("str", False),
        "tags": ("str_list", False),
        "body": ("table", True),
        "initial": ("table", True),
        "environment": ("table", False),
        "run": ("table", True),
        "reference": ("table", False),
        "tolerances": ("table", False),
    },
    "body": {"mass": ("number", True), "inertia": ("vec3", True)},
    "initial": {
        "rotation": ("mat3", False),
        "quaternion_wxyz": ("vec4", False),
        "rotation_vector": ("vec3", False),
        "omega_body": ("vec3", True),
        "position": ("vec3", False),
        "velocity": ("vec3", False),
    },
    "environment": {"gravity": ("vec3", False), "pivot": ("vec3", False)},
    "run": {
        "t_end": ("number", True),
        "dt": ("number", True),
        "dt_sweep": ("number_list", False),
        "save_every": ("int", False),
        "accuracies": ("number_list", False),
    },
    "reference": {"kind": ("str", False)},
}

_KIND_TEXT = {
    "name": (
        f"a non-empty string of at most {MAX_NAME_BYTES} ASCII letters, digits, '_' or '-' "
        "(it starts the names of the files a run writes, and a file name holds 255 bytes)"
    ),
    "str": "a string",
    "str_list": "a list of strings",
    "table": "a table",
    "number": "a finite number",
    "int": "an integer of at most 18 digits",
    "vec3": "a list of 3 finite numbers",
    "vec4": "a list of 4 finite numbers",
    "mat3": "a 3x3 nested list of finite numbers (row-major)",
    "number_list": "a non-empty list of finite numbers",
}


def _is_number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _finite(x) -> bool:
    """A number that is finite as a double (an integer of 400 digits is not)."""
    if not _is_number(x):
        return False
    try:
        return math.isfinite(float(x))
    except OverflowError:
        return False


def _finite_numbers(xs) -> bool:
    return all(_finite(x) for x in xs)


def _type_ok(kind: str, v) -> bool:
    if kind == "name":
        return (
            isinstance(v, str)
            and 0 < len(v) <= MAX_NAME_BYTES
            and all(c.isascii() and (c.isalnum() or c in "_-") for c in v)
        )
    if kind == "str":
        return isinstance(v, str)
    if kind == "str_list":
        return isinstance(v, list) and all(isinstance(s, str) and s for s in v)
    if kind == "table":
        return isinstance(v, dict)
    if kind == "number":
        return _finite(v)
    if kind == "int":
        return isinstance(v, int) and not isinstance(v, bool) and abs(v) < 10**18
    if kind in ("vec3", "vec4"):
        n = 3 if kind == "vec3" else 4
        return isinstance(v, list) and len(v) == n and _finite_numbers(v)
    if kind == "mat3":
        return (
            isinstance(v, list)
            and len(v) == 3
            and all(isinstance(r, list) and len(r) == 3 and _finite_numbers(r) for r in v)
        )
    if kind == "number_list":
        return isinstance(v, list) and len(v) > 0 and _finite_numbers(v)
    raise AssertionError(kind)


def step_plan(dt: float, t_end: float, save_every: int) -> tuple[int, np.ndarray]:
    """Number of steps and the step indices to save (0, s, 2s, ... and always the last).

    ``t_end`` must be a whole number of steps to within 1e-9 relative; anything else is a
    ``ValueError`` (``director_model.InvalidRunError``) rather than a silently shortened or
    lengthened horizon. The suite's one definition: the director model's
    (:func:`director_model.step_plan`), which the validation of a file, every engine and the
    reference all call through here, so that a file that validates runs.
    """
    from director_model import step_plan as plan

    return plan(dt, t_end, save_every)


def _whole_steps_problem(t_end: float, dt: float) -> str | None:
    """Why ``t_end`` is not a whole number of steps of ``dt`` (:func:`step_plan`'s rule), or
    None."""
    try:
        step_plan(dt, t_end, MAX_STEPS)  # the coarsest decimation: the plan is two saves
    except ValueError as exc:
        return str(exc)
    return None


def step_count_problem(t_end: float, dt: float) -> str | None:
    """Why ``t_end/dt`` steps cannot be run (more than :data:`MAX_STEPS`, or not finite: dt
    underflows against t_end), or None. The one rule for files and the command line."""
    ratio = t_end / dt
    if math.isfinite(ratio) and ratio <= MAX_STEPS:
        return None
    return (
        f"t_end/dt = {ratio:.3g} steps (t_end = {t_end!r} s, dt = {dt!r} s): at most 2^53 = "
        f"{MAX_STEPS:.3g} steps, beyond which the step times k dt are not exact in double "
        "precision; choose a larger dt or a shorter horizon"
    )


def _fmt(v) -> str:
    s = repr(v)
    return s if len(s) <= 120 else s[:117] + "..."


def validate(data: dict, path: str | None = None) -> Scenario:
    """Validate parsed TOML ``data`` into a :class:`Scenario`; raise :class:`ScenarioError`
    listing every problem. ``path`` is used in messages and stored on the scenario. A file
    with ``[[bodies]]`` describes a system of bodies, read by :func:`scenarios.load` and
    :func:`scenarios.system_file.validate_system`."""
    probs: list[tuple] = []
    where = path if path is not None else "<scenario data>"

    def bad(field, value, rule):
        probs.append((field, value, rule))

    tables, g = _check_structure(data, bad)
    body, init = g.get("body", {}), g.get("initial", {})
    env, run, ref = g.get("environment", {}), g.get("run", {}), g.get("reference", {})
    probs.extend(body_problems(body.get("mass"), body.get("inertia")))
    R = _check_attitude(init, tables.get("initial", {}), bad)
    pivot = env.get("pivot")
    if pivot is not None:
        for key in ("position", "velocity"):
            if key in tables.get("initial", {}):
                bad(
                    f"initial.{key}",
                    tables["initial"][key],
                    "must be omitted for a pivoted body (environment.pivot is set): the centre "
                    "of mass follows from the rotation, x_G = -R pivot",
                )
    sweep, save_every = _check_run(run, bad)
    kind = ref.get("kind", "auto")
    if kind not in REFERENCE_KINDS:
        bad(
            "reference.kind",
            kind,
            f"must be one of {', '.join(REFERENCE_KINDS)}{did_you_mean(kind, REFERENCE_KINDS)}",
        )
    tolerances = _check_tolerances(data.get("tolerances"), bad)
    if probs:
        raise ScenarioError(_message(where, probs), path=path, problems=probs)

    sc = Scenario(
        name=data["name"],
        description=data["description"],
        mass=float(body["mass"]),
        inertia=np.array(body["inertia"], dtype=float),
        rotation=R,
        omega_body=np.array(init["omega_body"], dtype=float),
        position=np.array(init.get("position", [0.0, 0.0, 0.0]), dtype=float),
        velocity=np.array(init.get("velocity", [0.0, 0.0, 0.0]), dtype=float),
        gravity=np.array(env.get("gravity", [0.0, 0.0, 0.0]), dtype=float),
        pivot=None if pivot is None else np.array(pivot, dtype=float),
        t_end=float(run["t_end"]),
        dt=float(run["dt"]),
        dt_sweep=tuple(float(h) for h in sweep),
        save_every=int(save_every),
        accuracies=tuple(float(a) for a in run.get("accuracies", ())),
        reference=kind,
        tolerances=tolerances,
        source=data.get("source", ""),
        tags=tuple(data.get("tags", ())),
        path=path,
    )
    probs = magnitude_problems(sc)
    if probs:
        raise ScenarioError(_message(where, probs), path=path, problems=probs)
    return sc


def magnitude_problems(sc: Scenario, t_end: float | None = None) -> list[tuple]:
    """Quantities of ``sc`` over the horizon ``t_end`` (default: its own) outside
    [1/:data:`MAX_MAGNITUDE`, :data:`MAX_MAGNITUDE`] (masses and moments) or above
    :data:`MAX_MAGNITUDE` (energies, momenta, positions, velocities), as ``(field, value,
    rule)`` triples. Each is an upper bound (by components, so within a factor 3 of the
    norm) computed before any work from the initial state: a free body's rotational energy and
    angular momentum are conserved and its centre of mass follows the parabola
    x0 + v0 t + g t^2/2; a pivoted body's kinetic energy stays below its initial one plus the
    largest potential drop, 2 m |g| |c|. A system of bodies checks its own
    (:meth:`scenarios.system.SystemScenario.magnitude_problems`)."""
    if sc.kind != "body":
        return sc.magnitude_problems(t_end)
    t = sc.t_end if t_end is None else float(t_end)
    lim = MAX_MAGNITUDE
    probs = []
    with np.errstate(over="ignore", invalid="ignore"):
        for field, value in (("body.mass", sc.mass), ("body.inertia", float(np.min(sc.inertia)))):
            if not 1.0 / lim <= value:
                probs.append((field, value, f"must be at least {1 / lim:g} (SI units)"))
        g, c = float(np.max(np.abs(sc.gravity))), 0.0
        if sc.pivot is not None:
            c = float(np.max(np.abs(sc.pivot)))
        W, Ip = np.abs(sc.omega_body), np.abs(sc.pivot_inertia)
        L = 3.0 * float(np.max(Ip @ W))  # bounds |I W| (components, max norm)
        T = 3.0 * float(np.max(W)) * L
        if sc.pivot is None:
            v = float(np.max(np.abs(sc.velocity))) + g * t
            x = float(np.max(np.abs(sc.position))) + v * t
        else:  # the kinetic energy grows by at most the potential drop; |x| = |c|
            T += 12.0 * g * c * sc.mass
            inertia = np.linalg.eigvalsh(sc.pivot_inertia)
            L = max(L, math.sqrt(2.0 * T * float(inertia[-1])))
            v, x = 3.0 * c * math.sqrt(2.0 * T / float(inertia[0])), 3.0 * c
        figures = {
            "body.mass": sc.mass,
            "body.inertia": float(np.max(sc.inertia)),
            "angular momentum |I W|": L,
            "kinetic energy of rotation": T,
            "potential energy m |g| (|x| + |c|)": 3.0 * g * (x + 4.0 * c) * sc.mass,
            "speed of the centre of mass": v,
            "momentum m |v|": 3.0 * v * sc.mass,
            "kinetic energy of translation m |v|^2": 9.0 * v * v * sc.mass,
            "distance travelled by the centre of mass": x,
        }
    for what, value in figures.items():
        if not value <= lim:
            probs.append(
                (
                    what,
                    value,
                    f"reaches up to {value:.3g} (SI units) over the horizon t_end = {t:g} s, "
                    f"above {lim:g}: the suite squares such quantities in norms and energies "
                    "and double precision ends at 1.8e308; state the body in units that keep "
                    "it moderate",
                )
            )
    return probs


def _check_structure(data: dict, bad) -> tuple[dict, dict]:
    """Unknown keys, missing keys and types of every table but ``tolerances`` (checked by
    :func:`_check_tolerances`). Returns (the tables present, {table: {key: well-typed value}})."""
    good: dict[str, dict] = {}
    tables = {"": data}
    for table in _SPEC:
        if table and isinstance(data.get(table), dict):
            tables[table] = data[table]
    for table, content in tables.items():
        spec = _SPEC[table]
        good[table] = {}
        for key in content:
            if key not in spec:
                dotted = f"{table}.{key}" if table else key
                bad(dotted, content[key], f"unknown key; allowed here: {', '.join(spec)}")
        for key, (kind, required) in spec.items():
            dotted = f"{table}.{key}" if table else key
            if key not in content:
                if required:
                    bad(dotted, "<missing>", f"required: {_KIND_TEXT[kind]}")
                continue
            v = content[key]
            if not _type_ok(kind, v):
                bad(dotted, v, f"must be {_KIND_TEXT[kind]}")
            elif kind != "table":
                good[table][key] = v
    return tables, good


def _check_attitude(init: dict, raw_init: dict, bad) -> np.ndarray:
    """The initial rotation: exactly one of three forms (none: identity), never repaired."""
    forms = ("rotation", "quaternion_wxyz", "rotation_vector")
    given = [k for k in forms if k in init]
    named = [k for k in forms if k in raw_init]
    if len(named) > 1:
        bad("initial", named, "give the initial attitude exactly once: one of " + ", ".join(forms))
        return np.eye(3)
    if given == ["rotation"]:
        R = np.array(init["rotation"], dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):  # entries of 1e200: dev = inf
            dev = float(np.max(np.abs(R.T @ R - np.eye(3))))
        if dev > ROTATION_TOL:
            bad(
                "initial.rotation",
                init["rotation"],
                f"not orthonormal: max |R^T R - 1| = {dev:.3g} > {ROTATION_TOL:g} "
                "(give more digits, or use rotation_vector / quaternion_wxyz)",
            )
        elif float(np.linalg.det(R)) < 0:
            bad("initial.rotation", init["rotation"], "det R = -1: a reflection, not a rotation")
        return R
    if given == ["quaternion_wxyz"]:
        q = np.array(init["quaternion_wxyz"], dtype=float)
        nq = float(np.linalg.norm(q))
        if abs(nq - 1.0) > ROTATION_TOL:
            bad(
                "initial.quaternion_wxyz",
                init["quaternion_wxyz"],
                f"not a unit quaternion: |q| = {nq!r}, must be 1 to within {ROTATION_TOL:g}",
            )
            return np.eye(3)
        return rotation_from_quaternion(q)
    if given == ["rotation_vector"]:
        r = init["rotation_vector"]
        angle = math.hypot(*(float(x) for x in r))
        if not angle <= MAX_ROTATION_ANGLE:
            bad(
                "initial.rotation_vector",
                r,
                f"its angle |r| = {angle:.3g} rad exceeds {MAX_ROTATION_ANGLE:.3g} rad, beyond "
                f"which the angle modulo 2 pi is lost to rounding by more than {ROTATION_TOL:g} "
                "rad: give the angle reduced to [0, 2 pi)",
            )
            return np.eye(3)
        return rotation_from_vector(r)
    return np.eye(3)


def _check_run(run: dict, bad) -> tuple[list, int]:
    """Horizon, step, sweep and decimation; returns (dt_sweep, save_every)."""
    t_end, dt = run.get("t_end"), run.get("dt")
    if t_end is not None and not t_end > 0:
        bad("run.t_end", t_end, "the horizon must be > 0 s")
        t_end = None
    if dt is not None and not dt > 0:
        bad("run.dt", dt, "the time step must be > 0 s")
        dt = None
    steps = [("run.dt", dt)] + [
        (f"run.dt_sweep[{i}]", h) for i, h in enumerate(run.get("dt_sweep", []))
    ]
    for field, h in steps[1:]:
        if not h > 0:
            bad(field, h, "every step must be > 0 s")
    for field, h in steps:
        count = step_count_problem(t_end, h) if t_end is not None and h and h > 0 else None
        if count is not None:
            bad(field, h, count)
        elif t_end is not None and h is not None and h > 0:
            whole = _whole_steps_problem(t_end, h)
            if whole is not None:
                bad(field, h, whole)
    sweep = run.get("dt_sweep", [])
    if len(set(sweep)) != len(sweep):
        bad("run.dt_sweep", sweep, "the steps must be distinct")
    save_every = run.get("save_every", 1)
    if not save_every >= 1:
        bad("run.save_every", save_every, "must be an integer >= 1")
    for i, a in enumerate(run.get("accuracies", [])):
        if not 0 < a < 1:
            bad(f"run.accuracies[{i}]", a, "a target accuracy must be in (0, 1)")
    return sweep, save_every


def _check_tolerances(table, bad) -> dict:
    """The ``[tolerances]`` table: ``metric = bound`` for every integrator family, and
    sub-tables ``[tolerances."<family>"]`` for one family. Returns {family or "*": {metric:
    bound}}. Family names are checked against the engines' registry when runs are planned
    (the scenario layer does not know the engines)."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        bad("tolerances", table, "must be a table of metric = bound and family sub-tables")
        return {}
    out: dict[str, dict] = {}

    def bounds(prefix: str, content: dict, family: str):
        for metric, value in content.items():
            field = f"{prefix}.{metric}"
            if isinstance(value, dict):
                if family != "*":
                    bad(field, value, "a family's sub-table holds only metric = bound")
                else:
                    bounds(f'tolerances."{metric}"', value, metric)
                continue
            if metric not in TOLERANCE_METRICS:
                bad(
                    field,
                    value,
                    f"not a metric with a tolerance; known: {', '.join(TOLERANCE_METRICS)}",
                )
            elif not (_finite(value) and value > 0):
                bad(field, value, "a tolerance must be a finite number > 0")
            else:
                out.setdefault(family, {})[metric] = float(value)

    bounds("tolerances", table, "*")
    return out


def file_error(path: str | None, problems: list[tuple]) -> ScenarioError:
    """The :class:`ScenarioError` of the file ``path`` with ``problems`` ((field, value, rule)
    triples), its message in :func:`validate`'s format: for rules checked outside this module
    (e.g. that a requested reference applies, which needs the references' code)."""
    where = path if path is not None else "<scenario data>"
    return ScenarioError(_message(where, problems), path=path, problems=problems)


def _message(where: str, probs: list[tuple]) -> str:
    n = len(probs)
    head = f"invalid scenario file {where}: {n} problem{'s' if n > 1 else ''}"
    lines = [f"  {field} = {_fmt(value)}: {rule}" for field, value, rule in probs]
    return "\n".join([head, *lines])


def load_file(path: str | Path) -> Scenario:
    """Read and validate one scenario file (a regular file of at most ``MAX_FILE_BYTES``)."""
    return validate(read_file(path), path=str(path))


def read_file(path: str | Path) -> dict:
    """The parsed TOML of one scenario file (a regular file of at most ``MAX_FILE_BYTES``,
    nested at most ``MAX_DEPTH`` deep), or :class:`ScenarioError` saying why not."""
    path = Path(path)
    try:
        if not path.exists():
            raise ScenarioError(f"scenario file {path} does not exist", path=str(path))
        if not path.is_file():
            raise ScenarioError(
                f"scenario file {path} is not a regular file (a folder, a device or a pipe)",
                path=str(path),
            )
        with path.open("rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(f"scenario file {path} cannot be read: {exc}", path=str(path)) from None
    if len(raw) > MAX_FILE_BYTES:
        raise ScenarioError(
            f"scenario file {path} is larger than {MAX_FILE_BYTES // 1024} KiB: not a scenario "
            "file (scenario files are a few KiB of TOML)",
            path=str(path),
        )
    try:
        # "utf-8-sig": a leading byte-order mark (Windows editors write one) is not TOML, but
        # it is no part of the text either; one anywhere else stays an error
        data = tomllib.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            f"invalid scenario file {path}: not UTF-8 text ({exc})", path=str(path)
        ) from None
    except (tomllib.TOMLDecodeError, ValueError) as exc:  # ValueError: an int of 5000 digits
        raise ScenarioError(
            f"invalid scenario file {path}: not valid TOML: {exc}", path=str(path)
        ) from None
    except RecursionError:
        data = None
    if data is None or nesting_depth(data) > MAX_DEPTH:
        raise ScenarioError(
            f"invalid scenario file {path}: arrays or tables nested more than {MAX_DEPTH} "
            "levels deep (a scenario file nests at most 3)",
            path=str(path),
        )
    return data


def nesting_depth(value) -> int:
    """How deeply lists and dicts nest in ``value`` (0 for a scalar), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict):
            v = list(v.values())
        if isinstance(v, list):
            deepest = max(deepest, d + 1)
            stack.extend((x, d + 1) for x in v)
    return deepest
