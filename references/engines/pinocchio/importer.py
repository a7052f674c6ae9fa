"""Pinocchio's own importer (``buildModelFromUrdf``, ``buildModelFromMJCF``) on a model file,
read back (:mod:`references.engines.importers`): each joint's body (named after the link of
the first BODY frame on it) with its inertia placed by ``oMi``, revolute joints' motion
subspace axes, position limits, damping, friction and armature, at ``pinocchio.neutral``."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, limit, mjcf_copy, to_root

_VISUAL = (
    "Pinocchio's MJCF parser adds up the mass of a body's collision geoms only: a geom with "
    "contype=0 and conaffinity=0 counts as visual and brings no mass (MuJoCo counts every "
    "geom); the faithful configuration loads a copy with contype='1' on every geom"
)
_FIRST = (
    "Pinocchio's MJCF parser builds the first <body> under <worldbody> only: a body tree "
    "after it is dropped"
)
#: the known cause of a difference, by configuration, quantity and format, printed beside it
HINTS = {
    **{("as-loaded", q, "mjcf"): _VISUAL for q in ("mass", "com", "inertia")},
    **{(c, "missing", "mjcf"): _FIRST for c in ("as-loaded", "faithful")},
}


def _collidable(root) -> None:
    """Every geom of an MJCF tree (and every default geom) made collidable (contype 1), so
    that Pinocchio's parser counts its mass (module :data:`HINTS`)."""
    for g in root.iter("geom"):
        g.set("contype", "1")


def pinocchio_file(model, config: str):
    """(the file Pinocchio's parser loads in ``config``, a temporary folder or None): the
    importers' :func:`~references.engines.importers.file_for`, and for a faithful MJCF file a
    copy whose every geom is collidable (:data:`HINTS`)."""
    if config == "faithful" and model.format == "mjcf":
        return mjcf_copy(model.path, _collidable)
    return file_for(model, config)


def readback(model, config: str, floating: bool = False) -> Readback:
    import pinocchio as pin

    rb = Readback("pinocchio", config)
    path, tmp = pinocchio_file(model, config)
    try:
        if model.format == "urdf" and floating:  # the root on a free flyer, as a user does
            pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
        elif model.format == "urdf":
            pm = pin.buildModelFromUrdf(str(path))
        else:
            pm = pin.buildModelFromMJCF(str(path))
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {exc}".strip()
        return rb
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    data = pm.createData()
    q = pin.neutral(pm)
    # the zero configuration of the read-back: MJCF joints at their ref. Pinocchio's MJCF
    # coordinates are MuJoCo's qpos (at q = ref a body sits where the file puts it), so its
    # neutral q = 0 turns a joint with a ref away from that pose
    refs = {j.name: j.ref for j in model.joints if j.ref}
    for i in range(1, pm.njoints):
        jm = pm.joints[i]
        if pm.names[i] in refs and jm.nq == 1:
            q[jm.idx_q] = refs[pm.names[i]]
    pin.forwardKinematics(pm, data, q)
    pin.updateFramePlacements(pm, data)
    # the root link's frame
    fid = pm.getFrameId(model.root) if pm.existFrame(model.root) else None
    if fid is None:
        rb.error = f"no frame named after the root link {model.root!r}"
        return rb
    T = data.oMf[fid].homogeneous
    # each joint's body is named after the link of its BODY frame right after the joint
    body_of = {}
    for f in pm.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint not in body_of:
            body_of[f.parentJoint] = f.name
    for i in range(1, pm.njoints):
        name = body_of.get(i, pm.names[i])
        I = pm.inertias[i]
        oM = data.oMi[i]
        R = oM.rotation
        com = oM.act(I.lever)
        rb.bodies[name] = to_root(T, I.mass, com, R @ I.inertia @ R.T)
        rb.joint_body[pm.names[i]] = name
        jm = pm.joints[i]
        sname = jm.shortname()
        if not sname.startswith("JointModelR"):
            continue
        ax = np.asarray(data.joints[i].S).reshape(6, -1)[3:6, 0]
        idx = jm.idx_q
        unbounded = "Unbounded" in sname or sname.startswith("JointModelRUB")
        rb.joints[pm.names[i]] = {
            "axis": T[:3, :3].T @ (R @ ax),
            "point": T[:3, :3].T @ (oM.translation - T[:3, 3]),
            "lower": None if unbounded else limit(pm.lowerPositionLimit[idx]),
            "upper": None if unbounded else limit(pm.upperPositionLimit[idx]),
            "damping": float(pm.damping[jm.idx_v]),
            "friction": float(pm.friction[jm.idx_v]),
            "armature": float(pm.armature[jm.idx_v]),
        }
    return rb


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("RKMK4",)


class _Sim:
    """A model built by Pinocchio's importer (a URDF's floating root on a
    ``JointModelFreeFlyer``, as Pinocchio's documentation has a user do), its state set from
    the scenario's start, stepped by the suite's RKMK4 on Pinocchio's configuration group
    around ``aba`` with zero torque (the scheme of :mod:`references.engines.pinocchio.system`):
    ``references.engines.importers.simulate``'s ``sim``. Pinocchio's ``aba`` applies the
    model's armature, not its damping, friction or limits (a user adds those as torques):
    the settings say so."""

    def __init__(self, scenario, config: str, integrator: str, dt: float):
        import pinocchio as pin

        from references.engines.importers import start_of
        from references.errors import Unsupported

        self.pin = pin
        model = scenario.model
        st = start_of(scenario)
        path, tmp = pinocchio_file(model, config)
        try:
            if model.format == "urdf" and st.floating:
                pm = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
            elif model.format == "urdf":
                pm = pin.buildModelFromUrdf(str(path))
            else:
                pm = pin.buildModelFromMJCF(str(path))
        except Exception as exc:
            raise Unsupported(
                f"pinocchio: its importer cannot load {scenario.model_spec['file']} ({config}):"
                f" {type(exc).__name__}: {str(exc).strip()[:300]}"
            ) from None
        finally:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
        pm.gravity.linear = np.asarray(st.gravity, float)
        rec = {"importer": "buildModelFromUrdf" + (" + JointModelFreeFlyer" if model.format ==
               "urdf" and st.floating else "") if model.format == "urdf" else
               "buildModelFromMJCF", "configuration": config, "integrator": integrator,
               "gravity": st.gravity.tolist(),
               "torque": "0 (aba applies no damping, friction or limits of the file)"}  # fmt: skip
        if config == "faithful":
            pm.armature[:] = 0.0
            rec["armature"] = "0"
            if model.format == "mjcf":
                rec["geoms"] = "every geom collidable (contype 1), so that each brings its mass"
        else:
            rec["armature"] = sorted(set(np.round(np.asarray(pm.armature), 12).tolist()))
        if st.held and config == "faithful":  # held as a Pinocchio user holds joints
            lock = [pm.getJointId(n) for n in st.held if pm.existJointName(n)]
            self.m = pm
            q_ref, _ = self._start(st, scenario)
            pm = pin.buildReducedModel(pm, lock, q_ref)
            rec["held joints"] = f"{st.held}: buildReducedModel at their start"
        elif st.held:
            rec["held joints"] = f"{st.held}: free in Pinocchio's model, at rest at t = 0"
        self.m, self.d = pm, pm.createData()
        self.tau = np.zeros(pm.nv)
        self.h = float(dt)
        self.q, self.v = self._start(st, scenario)
        self.settings, self.clock = rec, 0.0
        self._fid: dict = {}

    def _start(self, st, scenario):
        pin, m = self.pin, self.m
        q, v = pin.neutral(m), np.zeros(m.nv)
        for i in range(1, m.njoints):
            jm, name = m.joints[i], m.names[i]
            kind = jm.shortname()
            iq, iv = jm.idx_q, jm.idx_v
            if kind == "JointModelFreeFlyer":
                # the joint frame's world pose from the root link's (its BODY frame's placement)
                root = scenario.model.root
                if not m.existFrame(root):
                    raise ValueError(f"pinocchio: no frame named after the root link {root!r}")
                F = m.frames[m.getFrameId(root)]
                Tj = st.T @ np.linalg.inv(F.placement.homogeneous)
                M = m.jointPlacements[i].inverse() * pin.SE3(Tj[:3, :3], Tj[:3, 3])
                q[iq : iq + 7] = pin.SE3ToXYZQUAT(M)
                vj = st.v + np.cross(st.w, Tj[:3, 3] - st.T[:3, 3])
                v[iv : iv + 3] = Tj[:3, :3].T @ vj
                v[iv + 3 : iv + 6] = Tj[:3, :3].T @ st.w
            elif jm.nq == 1 and jm.nv == 1:
                q[iq] = float(st.q.get(name, 0.0))
                v[iv] = float(st.qd.get(name, 0.0))
            elif jm.nq == 2 and jm.nv == 1:  # unbounded revolute: (cos, sin)
                a = float(st.q.get(name, 0.0))
                q[iq : iq + 2] = [np.cos(a), np.sin(a)]
                v[iv] = float(st.qd.get(name, 0.0))
            elif name in st.given:
                raise ValueError(f"pinocchio: joint {name!r} ({kind}): its start is not set here")
        return q, v

    def _frame(self, name, joint) -> int:
        """Pinocchio's frame id of a link: its BODY frame by name, else the first BODY frame
        on the joint that moves it (an unnamed MJCF body)."""
        pin, m = self.pin, self.m
        if m.existFrame(name, pin.FrameType.BODY):
            return m.getFrameId(name, pin.FrameType.BODY)
        if joint is not None and m.existJointName(joint):
            jid = m.getJointId(joint)
            for k, f in enumerate(m.frames):
                if f.type == pin.FrameType.BODY and f.parentJoint == jid:
                    return k
        raise KeyError(f"pinocchio: link {name!r} (joint {joint!r}) is not in the loaded model")

    def _accel(self, q, v):
        return np.array(self.pin.aba(self.m, self.d, q, v, self.tau))

    def _step(self, q, v, h):
        """One RKMK4 step (the scheme of references.engines.pinocchio.system)."""
        pin, m = self.pin, self.m

        def dexpinv(q0, th, u):
            J = pin.dIntegrate(m, q0, th, pin.ArgumentPosition.ARG1)
            return np.linalg.solve(J, u)

        k1t, k1v = v, self._accel(q, v)
        th = 0.5 * h * k1t
        v2 = v + 0.5 * h * k1v
        k2t, k2v = dexpinv(q, th, v2), self._accel(pin.integrate(m, q, th), v2)
        th = 0.5 * h * k2t
        v3 = v + 0.5 * h * k2v
        k3t, k3v = dexpinv(q, th, v3), self._accel(pin.integrate(m, q, th), v3)
        th = h * k3t
        v4 = v + h * k3v
        k4t, k4v = dexpinv(q, th, v4), self._accel(pin.integrate(m, q, th), v4)
        theta = (h / 6.0) * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
        v_new = v + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        return pin.normalize(m, pin.integrate(m, q, theta)), v_new

    def advance(self, n: int) -> None:
        import time

        from references.engines import timing

        t0 = time.perf_counter()
        q, v = self.q, self.v
        for _ in range(n):
            q, v = self._step(q, v, self.h)
        self.q, self.v = q, v
        self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices

    def links(self, names):
        pin, m, d = self.pin, self.m, self.d
        pin.forwardKinematics(m, d, self.q, self.v)
        n = len(names)
        T = np.tile(np.eye(4), (n, 1, 1))
        v, w = np.zeros((n, 3)), np.zeros((n, 3))
        for i, (name, joint) in enumerate(names):
            if name not in self._fid:
                self._fid[name] = self._frame(name, joint)
            f = self._fid[name]
            T[i] = pin.updateFramePlacement(m, d, f).homogeneous
            tw = pin.getFrameVelocity(m, d, f, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            v[i], w[i] = tw.linear, tw.angular
        return T, v, w


def load(scenario, config: str, integrator: str, dt: float) -> _Sim:
    """The scenario's model file loaded by Pinocchio's importer in ``config``, its state set
    (:func:`references.engines.importers.simulate`)."""
    return _Sim(scenario, config, integrator, dt)
