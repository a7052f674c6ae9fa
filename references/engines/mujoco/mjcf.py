"""The MJCF document MuJoCo's system builder hands to MuJoCo: a body per body of the plan
(its principal frame at its centre of mass, parented as the spanning tree says), each tree
joint as MuJoCo's joints of its kind (:func:`parts`: a universal joint two hinges, a
cylindrical one a hinge and a slide), each point pair of a loop closure an ``equality
connect`` between two sites and each held distance (a universal closure's) a spatial tendon
between two sites with an ``equality tendon`` on its length (the length itself is set after
compiling: :func:`hold_distances`), all with the builder's solref and solimp, each spring of
the force elements a spatial tendon with its stiffness, damping and rest length
(:mod:`references.engines.mujoco.forces`), and the integrator and step (:func:`model_xml`).
The frames and the kinds are described in :mod:`references.engines.mujoco.system`."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from references import conventions as cv
from references.engines import reduced
from references.engines.mujoco.forces import spring_parts
from references.errors import Unsupported

#: the MuJoCo joint type (or pair of types) of each plan kind
_MJ = {"free": "free", "spherical": "ball", "revolute": "hinge", "prismatic": "slide",
       "universal": "universal", "cylindrical": "cylindrical"}  # fmt: skip

#: the deepest nesting of bodies MuJoCo 4.0's MJCF reader takes (measured: a chain of 480
#: bodies compiles, 500 raises XML_ELEMENT_DEPTH_EXCEEDED; the margin covers the wrapping
#: elements)
MJCF_MAX_DEPTH = 480


def _num(a) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(a))


def mj_type(tj: reduced.TreeJoint) -> str:
    """MuJoCo's name of the tree joint's type (module docstring's table)."""
    return _MJ[tj.kind]


def parts(tj: reduced.TreeJoint) -> list:
    """The MuJoCo joints of the body ``tj`` attaches, in order: (type, axis in the child's
    frame or None); a universal joint is a hinge about the parent-fixed axis then one about
    the child-fixed axis, a cylindrical one a hinge and a slide on the axis."""
    return {
        "free": [("free", None)],
        "spherical": [("ball", None)],
        "revolute": [("hinge", tj.axis_c)],
        "prismatic": [("slide", tj.axis_c)],
        "universal": [("hinge", None if tj.axis_p is None else tj.R_ref.T @ tj.axis_p),
                      ("hinge", tj.axis_c)],
        "cylindrical": [("hinge", tj.axis_c), ("slide", tj.axis_c)],
    }[tj.kind]  # fmt: skip


def model_xml(scenario, pl: reduced.Plan, integrator: str, dt: float, solref, solimp) -> str:
    """The MJCF of a plan (public so that tests can inspect, and plant mistakes in, what is
    built)."""
    children: dict[int, list[int]] = {}
    for c in pl.order:
        children.setdefault(pl.tree[c].parent, []).append(c)
    sites: dict[int, list[str]] = {}
    eqs, tendons = [], []
    for li, lp in enumerate(pl.loops):
        for pi, (pa, pb) in enumerate(lp.pairs):
            sa, sb = f"loop{li}_{pi}_a", f"loop{li}_{pi}_b"
            sites.setdefault(lp.a, []).append(f'<site name="{sa}" pos="{_num(pa)}"/>')
            sites.setdefault(lp.b, []).append(f'<site name="{sb}" pos="{_num(pb)}"/>')
            eqs.append(
                f'<connect name="loop{li}_{pi}" site1="{sa}" site2="{sb}" '
                f'solref="{_num(solref)}" solimp="{_num(solimp)}"/>'
            )
        for di, (pa, pb, _) in enumerate(lp.distances):
            sa, sb, tn = f"loop{li}_d{di}_a", f"loop{li}_d{di}_b", f"loop{li}_d{di}"
            sites.setdefault(lp.a, []).append(f'<site name="{sa}" pos="{_num(pa)}"/>')
            sites.setdefault(lp.b, []).append(f'<site name="{sb}" pos="{_num(pb)}"/>')
            tendons.append(
                f'<spatial name="{tn}" limited="false" stiffness="0" damping="0" '
                f'frictionloss="0" armature="0"><site site="{sa}"/><site site="{sb}"/></spatial>'
            )
            eqs.append(
                f'<tendon name="{tn}" tendon1="{tn}" polycoef="0 0 0 0 0" '
                f'solref="{_num(solref)}" solimp="{_num(solimp)}"/>'
            )

    # the force elements' springs: their tendons after the held distances'
    spring_sites, spring_tendons = spring_parts(scenario, pl)
    for c, elems in spring_sites.items():
        sites.setdefault(c, []).extend(elems)
    tendons += spring_tendons

    # every body's element from its children's, leaves first (a chain of 2000 bodies nests
    # 2000 deep: no recursion)
    depth = {}
    for c in pl.order:
        parent = pl.tree[c].parent
        depth[c] = 2 if parent < 0 else depth[parent] + 1
    deepest = max(depth.values(), default=2) - 1
    if deepest > MJCF_MAX_DEPTH:
        raise Unsupported(
            f"mujoco: the tree nests {deepest} bodies deep; MuJoCo's MJCF reader (tinyxml2) "
            f"refuses elements nested deeper than about {MJCF_MAX_DEPTH} bodies "
            "(XML_ELEMENT_DEPTH_EXCEEDED), and this builder writes MJCF"
        )
    text: dict[int, str] = {}
    for c in reversed(pl.order):
        tj = pl.tree[c]
        b = pl.bodies[c]
        pad = "  " * depth[c]
        if tj.kind == "free":
            pos, quat = np.asarray(b.position, float), cv.matrix_to_quat_wxyz(tj.R_ref)
            joint = f'<freejoint name="j{c}"/>'
        else:
            pos = tj.X - tj.R_ref @ tj.Y
            quat = cv.matrix_to_quat_wxyz(tj.R_ref)
            joint = "\n".join(
                f'<joint name="j{c}_{i}" type="{typ}" pos="{_num(tj.Y)}"'
                + ("" if ax is None else f' axis="{_num(ax)}"')
                + ' limited="false" damping="0" armature="0" frictionloss="0" stiffness="0"/>'
                for i, (typ, ax) in enumerate(parts(tj))
            )
        inner = "\n".join(
            [
                joint,
                f'<inertial pos="0 0 0" quat="1 0 0 0" mass="{float(b.mass)!r}" '
                f'diaginertia="{_num(b.inertia)}"/>',
                *sites.get(c, []),
                *(text.pop(k) for k in children.get(c, [])),
            ]
        )
        text[c] = (
            f'{pad}<body name={quoteattr(str(b.name))} pos="{_num(pos)}" quat="{_num(quat)}" '
            f'gravcomp="0">\n{inner}\n{pad}</body>'
        )

    world = "\n".join([*sites.get(-1, []), *(text.pop(c) for c in children.get(-1, []))])
    equality = f"<equality>\n{chr(10).join(eqs)}\n</equality>" if eqs else ""
    if tendons:
        equality = f"<tendon>\n{chr(10).join(tendons)}\n</tendon>\n  {equality}"
    return f"""<mujoco model={quoteattr(str(scenario.name))}>
  <compiler angle="radian" inertiafromgeom="false" autolimits="false"/>
  <option timestep="{dt!r}" gravity="{_num(pl.gravity)}" integrator="{integrator}"
          density="0" viscosity="0" wind="0 0 0">
    <flag contact="disable" autoreset="disable"/>
  </option>
  <worldbody>
{world}
  </worldbody>
  {equality}
</mujoco>"""


def hold_distances(m, pl: reduced.Plan) -> None:
    """Set each held distance on the compiled model: MuJoCo's tendon equality holds a tendon's
    length at its length in the reference configuration qpos0 plus ``polycoef[0]``
    (``eq_data[e, 0]``), so polycoef[0] = the distance - ``tendon_length0``. The equalities
    are in :func:`model_xml`'s order: per loop its connects, then its tendons."""
    e = t = 0
    for lp in pl.loops:
        e += len(lp.pairs)
        for _, _, dist in lp.distances:
            m.eq_data[e, 0] = float(dist) - float(m.tendon_length0[t])
            e, t = e + 1, t + 1


def loop_points(m, d, pl: reduced.Plan) -> dict:
    """MuJoCo's loop constraints in the world (after ``mj_kinematics``): per closure label,
    (the connects' two sites, the held distances' two sites and held length), the form
    :func:`~references.engines.reduced.check_loops` takes."""
    out, e, t = {}, 0, 0
    for lp in pl.loops:
        pairs = []
        for _ in lp.pairs:
            s1, s2 = m.eq_obj1id[e], m.eq_obj2id[e]
            pairs.append((d.site_xpos[s1].copy(), d.site_xpos[s2].copy()))
            e += 1
        dists = []
        for _ in lp.distances:
            adr = m.tendon_adr[t]
            s1, s2 = m.wrap_objid[adr], m.wrap_objid[adr + 1]
            held = float(m.eq_data[e, 0] + m.tendon_length0[t])
            dists.append((d.site_xpos[s1].copy(), d.site_xpos[s2].copy(), held))
            e, t = e + 1, t + 1
        out[lp.label] = (pairs, dists)
    return out
