"""PyBullet's loop closures as :mod:`references.engines.pybullet.system` builds them (its
docstring): the constraints' record, where PyBullet holds them at t = 0 (the form of
:func:`~references.engines.reduced.check_loops`), and their read-back."""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from references.engines import reduced
from references.errors import EngineError


def constraint_record(bm) -> list:
    p, cid = bm.p, bm.cid
    out = []
    for lp, cons, *_ in bm.constraints:
        info = p.getConstraintInfo(cons, physicsClientId=cid)
        kind = "JOINT_PRISMATIC" if lp.kind == "prismatic" else "JOINT_POINT2POINT"
        out.append({"closure": lp.label, "type": kind,
                    "maxAppliedForce (N)": float(info[10]), "erp": float(info[14])})  # fmt: skip
    return out


def loop_world(bm, x, R) -> dict:
    """The constraints as PyBullet holds them (getConstraintInfo's pivots, in each link's COM
    frame, the world for the ground), placed by PyBullet's link states (x, R) at t = 0: the
    form of :func:`~references.engines.reduced.check_loops`. A prismatic constraint gives three
    pairs: its pivots, the points one length scale along the axis (a's axis, taken to b by the
    rotation b's frame holds relative to a's), and the same across the axis."""
    p, cid, pl = bm.p, bm.cid, bm.pl
    out: dict = {lp.label: ([], []) for lp in pl.loops}
    for lp, cons, *_ in bm.constraints:
        info = p.getConstraintInfo(cons, physicsClientId=cid)
        Rb = np.eye(3) if lp.b < 0 else R[lp.b]
        pa = x[lp.a] + R[lp.a] @ np.asarray(info[6], float)
        pb = np.asarray(info[7], float) if lp.b < 0 else x[lp.b] + Rb @ np.asarray(info[7])
        out[lp.label][0].append((pa, pb))
        if lp.kind == "prismatic":
            Fa = R[lp.a] @ cv.quat_xyzw_to_matrix(info[8])
            Fb = Rb @ cv.quat_xyzw_to_matrix(info[9])
            u = R[lp.a] @ np.asarray(info[5], float)
            for d in (u, reduced.across(u)):
                out[lp.label][0].append((pa + pl.length * d, pb + pl.length * Fb @ Fa.T @ d))
    return out


def check_constraints(bm, erp: float, max_force: float) -> None:
    p, cid = bm.p, bm.cid
    bad = []
    for lp, cons, Xa, Xb, *slider in bm.constraints:
        info = p.getConstraintInfo(cons, physicsClientId=cid)
        kind = p.JOINT_PRISMATIC if slider else p.JOINT_POINT2POINT
        if info[4] != kind:
            bad.append(f"{lp.label}: constraint type {info[4]}, needs {kind}")
        checks = [("pivot on body a", info[6], Xa), ("pivot on body b", info[7], Xb),
                  ("erp", info[14], erp), ("max force", info[10], max_force)]  # fmt: skip
        if slider:
            axis, Fb = slider
            checks += [("axis (a's link frame)", info[5], axis),
                       ("frame on a", cv.quat_xyzw_to_matrix(info[8]), np.eye(3)),
                       ("frame on b", cv.quat_xyzw_to_matrix(info[9]), Fb)]  # fmt: skip
        for what, got, exp in checks:
            if not np.allclose(got, exp, rtol=reduced.CHECK_TOL, atol=reduced.CHECK_TOL):
                bad.append(f"{lp.label}: {what} {np.round(got, 12).tolist()}, expected "
                           f"{np.round(exp, 12).tolist()}")  # fmt: skip
    if bad:
        raise EngineError("pybullet: loop closures differ from the scenario: " + "; ".join(bad))
