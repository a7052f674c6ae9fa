"""MuJoCo's own importer (``MjModel.from_xml_path``, URDF and MJCF) on a model file, read back
(:mod:`references.engines.importers`): body masses, centres of mass and inertias
(``body_mass``, ``xipos``, ``ximat``, ``body_inertia``), hinge axes and anchors (``xaxis``,
``xanchor``), limits, damping, friction loss and armature, at the zero configuration
(``qpos0``: MJCF joints at their ``ref``). The faithful URDF adds
``<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>``."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, rot_inertia, to_root


def mujoco_model(model, config: str, floating: bool = False):
    """MuJoCo's model of ``model``'s file in ``config``; a floating URDF root gets a free
    joint (MuJoCo's URDF import attaches the root to the world; a user adds one through
    ``MjSpec``)."""
    import mujoco

    extra = '<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>'
    path, tmp = file_for(model, config, extra)
    try:
        if floating and model.format == "urdf":
            spec = mujoco.MjSpec.from_file(str(path))
            (spec.body(model.root) or spec.worldbody.first_body()).add_freejoint()
            return spec.compile()
        return mujoco.MjModel.from_xml_path(str(path))
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)


def _mujoco_names(m, model):
    import mujoco

    names = []
    for b in range(m.nbody):
        n = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if not n and model.format == "mjcf":
            n = f"body{b}"  # our MJCF reader names unnamed bodies by MuJoCo's body id
        names.append(n)
    return names


def mujoco_readback(m, model, engine, config, fields=None) -> Readback:
    import mujoco

    rb = Readback(engine, config)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    f = fields or m
    names = _mujoco_names(m, model)
    root = model.root
    T = np.eye(4)
    if root in names:
        ir = names.index(root)
        T[:3, :3] = d.xmat[ir].reshape(3, 3)
        T[:3, 3] = d.xpos[ir]
    elif model.format == "urdf":
        rb.notes.append(f"root link {root!r} fused into the world body (fusestatic)")
    else:
        rb.error = f"no body named after the root link {root!r}"
        return rb
    mass = np.asarray(f.body_mass)
    inertia = np.asarray(f.body_inertia)
    for b in range(1, m.nbody):
        R = d.ximat[b].reshape(3, 3)
        rb.bodies[names[b]] = to_root(T, mass[b], d.xipos[b], rot_inertia(R, inertia[b]))
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        dof = m.jnt_dofadr[j]
        lim = bool(m.jnt_limited[j])
        rb.joints[name] = {
            "axis": T[:3, :3].T @ d.xaxis[j],
            "point": T[:3, :3].T @ (d.xanchor[j] - T[:3, 3]),
            "lower": float(m.jnt_range[j, 0]) if lim else None,
            "upper": float(m.jnt_range[j, 1]) if lim else None,
            "damping": float(np.asarray(f.dof_damping)[dof]),
            "friction": float(np.asarray(f.dof_frictionloss)[dof]),
            "armature": float(np.asarray(f.dof_armature)[dof]),
        }
    return rb


def readback(model, config: str, floating: bool = False) -> Readback:
    try:
        m = mujoco_model(model, config, floating)
    except Exception as exc:  # the importer's refusal is the finding
        return Readback("mujoco", config, error=f"{type(exc).__name__}: {exc}".strip())
    return mujoco_readback(m, model, "mujoco", config)


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("RK4",)

#: the integrator names of MuJoCo's ``mjtIntegrator``
_MJINT = {"Euler": "mjINT_EULER", "implicit": "mjINT_IMPLICIT",
          "implicitfast": "mjINT_IMPLICITFAST", "RK4": "mjINT_RK4"}  # fmt: skip

#: what the faithful configuration switches off through MuJoCo's disable flags
_FAITHFUL_OFF = ("mjDSBL_CONTACT", "mjDSBL_LIMIT", "mjDSBL_PASSIVE", "mjDSBL_FRICTIONLOSS",
                 "mjDSBL_ACTUATION", "mjDSBL_SPRING", "mjDSBL_DAMPER")  # fmt: skip


def _compile(scenario, config: str, st):
    """MuJoCo's model of the scenario's file in ``config``: as loaded, the file itself; a
    floating URDF root gets a free joint through ``MjSpec`` (MuJoCo's URDF import attaches
    the root to the world), which is what a user does; a fixed URDF root is placed at the
    scenario's base pose ``st.T`` (an MJCF root keeps the file's). Faithful:
    :func:`mujoco_model`'s file (a URDF without geometry, static bodies kept)."""
    import mujoco

    from references import conventions as cv

    model = scenario.model
    extra = '<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>'
    path, tmp = file_for(model, config, extra)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        root = spec.body(model.root) or spec.worldbody.first_body()
        if config == "faithful":  # held joints welded where the scenario holds them
            held = set(st.held)
            for eq in list(spec.equalities):  # a coupling of a held joint (URDF <mimic>)
                if {eq.name1, eq.name2} & held:
                    spec.delete(eq)
            for name in st.held:
                j = spec.joint(name)
                if j is None:
                    continue
                _weld_at(j, float(st.q.get(name, j.ref)) - float(j.ref), mujoco)
                spec.delete(j)
        if model.format == "urdf" and st.floating:
            root.add_freejoint()
        elif model.format == "urdf":  # a fixed URDF root, placed where the scenario puts it
            root.pos = st.T[:3, 3]
            root.quat = cv.matrix_to_quat_wxyz(st.T[:3, :3])
        return spec.compile()
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)


def _weld_at(j, d: float, mujoco) -> None:
    """Move the body of the joint ``j`` (an ``MjsJoint``) as the joint would at ``d`` from
    its ref, so that deleting the joint welds the body there: a slide translates it along
    the axis, a hinge turns it about the axis through the joint's point (body frame)."""
    from references import conventions as cv
    from scenarios.models.model import axis_rotation

    if d == 0.0:
        return
    b = j.parent
    a = np.asarray(j.axis, float) / np.linalg.norm(j.axis)
    M = np.eye(4)
    if int(j.type) == int(mujoco.mjtJoint.mjJNT_SLIDE):
        M[:3, 3] = a * d
    elif int(j.type) == int(mujoco.mjtJoint.mjJNT_HINGE):
        c = np.asarray(j.pos, float)
        M[:3, :3] = axis_rotation(a, d)
        M[:3, 3] = c - M[:3, :3] @ c
    else:
        raise ValueError(f"held joint {j.name!r}: a {j.type} joint is not welded here")
    q = np.asarray(b.quat, float)
    T = np.eye(4)
    T[:3, :3] = cv.quat_wxyz_to_matrix(q / np.linalg.norm(q))
    T[:3, 3] = b.pos
    T = T @ M
    b.pos = T[:3, 3]
    b.quat = cv.matrix_to_quat_wxyz(T[:3, :3])


class _Sim:
    """A model loaded by MuJoCo's importer, its state set from the scenario's start, stepped
    by ``mj_step`` (``references.engines.importers.simulate``'s ``sim``)."""

    def __init__(self, scenario, config: str, integrator: str, dt: float):
        import mujoco

        from references.engines.importers import start_of
        from references.errors import Unsupported

        self.mj = mujoco
        st = start_of(scenario)
        try:
            m = _compile(scenario, config, st)
        except Exception as exc:  # the importer's refusal is the row's finding
            raise Unsupported(
                f"mujoco: its importer cannot load {scenario.model_spec['file']} "
                f"({config}): {type(exc).__name__}: {str(exc).strip()[:300]}"
            ) from None
        self.names = _mujoco_names(m, scenario.model)
        m.opt.timestep = float(dt)
        m.opt.integrator = int(getattr(mujoco.mjtIntegrator, _MJINT[integrator]))
        m.opt.gravity[:] = st.gravity
        rec = {"importer": "MjSpec.from_file + compile", "configuration": config,
               "integrator": integrator, "gravity": st.gravity.tolist()}  # fmt: skip
        if config == "faithful":
            for f in _FAITHFUL_OFF:
                bit = getattr(mujoco.mjtDisableBit, f, None)
                if bit is not None:
                    m.opt.disableflags |= int(bit)
            # and the fields themselves: MJX does not honour every flag (measured: arm3's
            # friction loss or damping stayed in MJX's Euler with the flags alone)
            for f in ("dof_armature", "dof_damping", "dof_frictionloss", "jnt_stiffness",
                      "body_gravcomp"):  # fmt: skip
                getattr(m, f)[:] = 0.0
            m.jnt_limited[:] = 0
            m.geom_contype[:] = 0
            m.geom_conaffinity[:] = 0
            rec["switched off"] = "contact, limits, springs, damping, friction loss, "
            rec["switched off"] += "actuation (disable flags and the fields); armature 0"
        else:
            off_contact = m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
            rec["as the file has it"] = (
                f"damping {sorted(set(np.round(m.dof_damping, 12).tolist()))}, armature "
                f"{sorted(set(np.round(m.dof_armature, 12).tolist()))}, "
                f"{int(np.sum(m.jnt_limited))} limited joints, {m.nu} actuators (ctrl 0), "
                f"{m.ngeom} geoms (contact {'off' if off_contact else 'on'})"
            )
        d = mujoco.MjData(m)
        self._set_state(m, d, st, scenario)
        if st.held:
            rec["held joints"] = f"{st.held}: " + (
                "removed from the spec (welded at their ref)"
                if config == "faithful"
                else "free in MuJoCo's model, at rest at t = 0"
            )
        self.m, self.d, self.settings, self.clock = m, d, rec, 0.0
        self._ids: dict = {}

    def _set_state(self, m, d, st, scenario):
        mj = self.mj
        from references import conventions as cv

        for j in range(m.njnt):
            name = mj.mj_id2name(m, mj.mjtObj.mjOBJ_JOINT, j) or ""
            qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
            typ = int(m.jnt_type[j])
            if typ == int(mj.mjtJoint.mjJNT_FREE):
                b = m.jnt_bodyid[j]
                if self.names[b] != scenario.model.root:
                    raise ValueError(f"a free joint on body {self.names[b]!r}, not the root")
                R = st.T[:3, :3]
                d.qpos[qa : qa + 3] = st.T[:3, 3]
                d.qpos[qa + 3 : qa + 7] = cv.matrix_to_quat_wxyz(R)
                d.qvel[va : va + 3] = st.v
                d.qvel[va + 3 : va + 6] = R.T @ st.w
            elif typ in (int(mj.mjtJoint.mjJNT_HINGE), int(mj.mjtJoint.mjJNT_SLIDE)):
                if name in st.q:
                    d.qpos[qa] = float(st.q[name])
                if name in st.qd:
                    d.qvel[va] = float(st.qd[name])
            elif name in st.given:
                raise ValueError(f"joint {name!r}: a ball joint's start is not set here")
        mj.mj_forward(m, d)

    def _body(self, name, joint) -> int:
        """MuJoCo's body id of a link: by its name, else as the body its joint moves."""
        mj, m = self.mj, self.m
        if name in self.names:
            return self.names.index(name)
        j = -1 if joint is None else mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, joint)
        if j < 0:
            raise KeyError(f"mujoco: link {name!r} (joint {joint!r}) is not in the loaded model")
        return int(m.jnt_bodyid[j])

    def advance(self, n: int) -> None:
        import time

        from references.engines import timing

        t0 = time.perf_counter()
        self.mj.mj_step(self.m, self.d, n)
        self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices

    def links(self, names):
        mj, m, d = self.mj, self.m, self.d
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_comVel(m, d)
        n = len(names)
        T = np.tile(np.eye(4), (n, 1, 1))
        v, w = np.zeros((n, 3)), np.zeros((n, 3))
        res = np.zeros(6)
        for i, (name, joint) in enumerate(names):
            if name not in self._ids:
                self._ids[name] = self._body(name, joint)
            b = self._ids[name]
            T[i, :3, :3] = d.xmat[b].reshape(3, 3)
            T[i, :3, 3] = d.xpos[b]
            mj.mj_objectVelocity(m, d, mj.mjtObj.mjOBJ_XBODY, b, res, 0)
            w[i], v[i] = res[:3], res[3:]
        return T, v, w


def load(scenario, config: str, integrator: str, dt: float) -> _Sim:
    """The scenario's model file loaded by MuJoCo's importer in ``config``, its state set
    (:func:`references.engines.importers.simulate`)."""
    return _Sim(scenario, config, integrator, dt)
