"""A system's force elements (:mod:`scenarios.force_elements`) in MuJoCo's model: each linear
spring-damper a spatial tendon between two sites, each constant joint torque a generalised
force on its hinge.

- Spring ``k``: sites ``spring<k>_a`` on body a at ``anchor_a`` and ``spring<k>_b`` on body b at
  ``anchor_b`` (the world body for the ground: ``anchor_b`` is then a world point; every body
  frame is the principal frame at the centre of mass, so the anchors are the site positions as
  written), and a spatial tendon ``spring<k>`` through the two sites with ``stiffness`` k,
  ``damping`` c and ``springlength`` l0 (MuJoCo documentation, "XML Reference / tendon /
  spatial": a tendon's passive force -k (L - l0) - c L' acts along it, the scenario's law),
  unlimited, no friction loss or armature. Read back: the sites' bodies and positions, the
  tendon's two site wraps, k, c, l0 and the zeros.
- Torque on a revolute joint that MuJoCo holds as a hinge of the tree: ``qfrc_applied`` on the
  hinge's degree of freedom, Q = (the torque on the hinge's child) . (its axis in the world):
  +tau when the child is the joint's body a, -tau (u . n_c) when it is body b (n_c = -u for
  axes written antiparallel). MuJoCo keeps ``qfrc_applied`` from step to step (mj_step never
  clears it); it is set once, and the value read back before the first step. A torque on a
  joint that closes a loop has no degree of freedom to act on and is unsupported (the
  message says so).

Integrators: how each of MuJoCo's integrators treats the tendon's passive force is MuJoCo's
own (measured on a damped arm: RK4 converges at order 4, Euler at order 1;
tests/references/engines/test_mujoco_forces.py).
"""

from __future__ import annotations

import numpy as np

from references.engines import reduced
from references.errors import EngineError, Unsupported


def _num(a) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(a))


def spring_parts(scenario, pl: reduced.Plan) -> tuple[dict, list]:
    """({body index (-1: the world): [site elements]}, [tendon elements]) of the springs."""
    idx = {n: i for i, n in enumerate(pl.names)}
    sites: dict[int, list[str]] = {}
    tendons = []
    for k, s in enumerate(getattr(scenario, "springs", ())):
        a, b = idx[s.body_a], -1 if s.body_b is None else idx[s.body_b]
        sites.setdefault(a, []).append(f'<site name="spring{k}_a" pos="{_num(s.anchor_a)}"/>')
        sites.setdefault(b, []).append(f'<site name="spring{k}_b" pos="{_num(s.anchor_b)}"/>')
        tendons.append(
            f'<spatial name="spring{k}" limited="false" stiffness="{s.stiffness!r}" '
            f'damping="{s.damping!r}" springlength="{s.rest_length!r}" frictionloss="0" '
            f'armature="0"><site site="spring{k}_a"/><site site="spring{k}_b"/></spatial>'
        )
    return sites, tendons


def site_pair(mujoco, m, t: int):
    """The two sites of tendon ``t`` if it is a straight line between two sites (a spring's
    or a loop closure's), else None."""
    adr = m.tendon_adr[t]
    if m.tendon_num[t] != 2 or any(
        m.wrap_type[adr + i] != mujoco.mjtWrap.mjWRAP_SITE for i in range(2)
    ):
        return None
    return m.wrap_objid[adr], m.wrap_objid[adr + 1]


def read_back_springs(mujoco, m, scenario, pl: reduced.Plan, bid: dict, first: int, want, bad):
    """Compare the springs' tendons (from tendon ``first`` on) with the scenario: ``want(what,
    got, expected, scale)`` and ``bad`` (a list) are the builder's read-back."""
    idx = {n: i for i, n in enumerate(pl.names)}
    L = pl.length
    for k, s in enumerate(getattr(scenario, "springs", ())):
        what = f"spring {s.name!r}"
        t = first + k
        sites = site_pair(mujoco, m, t)
        if sites is None:
            bad.append(f"{what}: its tendon is not a straight line between two sites")
            continue
        s1, s2 = sites
        b1 = bid[idx[s.body_a]]
        b2 = 0 if s.body_b is None else bid[idx[s.body_b]]
        if m.site_bodyid[s1] != b1 or m.site_bodyid[s2] != b2:
            bad.append(f"{what}: its sites are on bodies {m.site_bodyid[[s1, s2]].tolist()}, "
                       f"needs {[b1, b2]}")  # fmt: skip
        want(f"{what}: site on a (anchor_a)", m.site_pos[s1], s.anchor_a, L)
        want(f"{what}: site on b (anchor_b)", m.site_pos[s2], s.anchor_b, L)
        want(f"{what}: tendon_stiffness", m.tendon_stiffness[t], s.stiffness)
        want(f"{what}: tendon_damping", m.tendon_damping[t], s.damping)
        # MuJoCo 3+ holds a dead band [low, high]; one springlength is both
        want(f"{what}: tendon_lengthspring", m.tendon_lengthspring[t], [s.rest_length] * 2, L)
        for f in ("tendon_frictionloss", "tendon_armature", "tendon_limited"):
            if np.any(np.asarray(getattr(m, f)[t]) != 0):
                bad.append(f"{what}: {f} {getattr(m, f)[t]}: must be 0")


def torque_forces(m, scenario, pl: reduced.Plan, bid: dict) -> list[tuple[int, float, str]]:
    """[(degree of freedom, generalised force, label)] of the joint torques (module
    docstring); :class:`Unsupported` for a torque on a loop closure."""
    out = []
    tree = {tj.name: (c, tj) for c, tj in pl.tree.items()}
    by = {j.name: j for j in pl.joints}
    for tq in getattr(scenario, "torques", ()):
        j = by[tq.joint]
        if tq.joint not in tree:
            raise Unsupported(
                f"mujoco: the torque on joint {tq.joint!r}: that joint closes a loop (an "
                "equality connect), which has no degree of freedom for MuJoCo's applied "
                "generalised force (qfrc_applied) to act on"
            )
        c, tj = tree[tq.joint]
        _, Rc, _, _ = reduced.world(pl, c)
        ia = pl.names.index(j.body_a)
        _, Ra, _, _ = reduced.world(pl, ia)
        u = Ra @ reduced.unit(j.axis_a, f"joint {j.name!r}: axis_a")
        on_child = tq.torque * u if ia == c else -tq.torque * u
        Q = float(on_child @ (Rc @ tj.axis_c))
        dof = int(m.jnt_dofadr[m.body_jntadr[bid[c]]])
        out.append((dof, Q, f"torque on {tq.joint!r}: qfrc_applied[{dof}] = {Q:.12g} N m"))
    return out


def apply_torques(d, forces) -> None:
    """Set ``qfrc_applied`` (every other entry 0) and read it back."""
    d.qfrc_applied[:] = 0.0
    for dof, Q, _ in forces:
        d.qfrc_applied[dof] += Q
    want = np.zeros_like(d.qfrc_applied)
    for dof, Q, _ in forces:
        want[dof] += Q
    if not np.array_equal(np.asarray(d.qfrc_applied), want):
        raise EngineError(f"mujoco: qfrc_applied holds {d.qfrc_applied.tolist()}, set {want}")
