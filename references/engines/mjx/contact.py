"""MJX's contact: the model of :mod:`references.engines.mujoco.contact` (the same MJCF, with
its model name fixed so that one compilation serves every scene of one shape; its bodies on
free joints or on a hinge or slide to the ground, set and read by that module's
``set_initial_state`` and ``read_bodies``), put on the JAX
device with ``mjx.put_model(impl="jax")`` in float64 (``jax.enable_x64``), stepped by
``mjx.step`` in a jitted ``lax.fori_loop`` between saved steps.

Configurations: the pyramidal and the elliptic cone at impratio 1 and 10 (MJX's contact
solver is its Newton solver). MJX does not run MuJoCo's noslip pass: a model with
``noslip_iterations`` 10 stepped the same trajectory as with 0 in a check made when this module
was written, so no noslip configuration is offered.

Contacts at the saved steps: the MJX state brought back to an ``MjData`` (``mjx.get_data``:
its contacts are MJX's with dist <= 0, in MJX's order), each contact's force in its frame
decoded from its constraint rows in MJX's own arrays (:func:`contact_frame_force` on the
device's ``efc_force`` at the contact's MJX row address: ``get_data`` drops the rows whose
Jacobian is zero, an elliptic cone's friction rows when mu = 0, and the addresses it gives
then miss rows). Not C MuJoCo's ``mj_contactForce`` on that ``MjData``: it returned values of
1e160-1e260 on some contacts of some saved steps (box_resting, pyramidal, 4 of 30 samples,
run to run different) where the rows decode to the weight they carry. External forces:
``xfrc_applied`` fixed for the run (forces at the centres of mass only: a force off the
centre of mass, whose torque turns with the body, is unsupported here).
"""

from __future__ import annotations

import time

import numpy as np

from references.engines import timing
from references.engines.contact import ContactLog, SavedStates, external_wrench, pair_index
from references.engines.integrators import Integrator
from references.engines.mujoco import contact as mjc
from references.errors import Unsupported

FAMILY = "soft convex contact"
#: the model name of every scene (MJX keeps names in its compilation key)
MODEL_NAME = "contact_scene"

CONFIGURATIONS = tuple(
    Integrator(c.name, FAMILY, 1, c.description + " (MJX)", options=dict(c.options), default=False)
    for c in mjc.CONFIGURATIONS
    if c.options["noslip_iterations"] == 0
)

SETTINGS = ("solver", "iterations", "tolerance", "solref", "solimp")


def contact_frame_force(cone: int, con, efc_force, address=None) -> np.ndarray:
    """The force (normal, tangent 1, tangent 2) of one contact of dimension 3 in its frame,
    from its constraint rows in ``efc_force`` (at ``address``, default
    ``con.efc_address``), as MuJoCo defines the rows (documentation, "Computation /
    Constraint model"): an elliptic cone's rows are those three forces; a pyramidal cone's
    are the forces along its 2 (dim - 1) edges, the normal force their sum and tangent j's
    mu_j (f_2j - f_2j+1)."""
    a = int(con.efc_address if address is None else address)
    dim = int(con.dim)
    rows = np.asarray(efc_force[a : a + (dim if cone == 1 else 2 * (dim - 1))], dtype=float)
    out = np.zeros(3)
    if cone == 1:
        out[:dim] = rows
        return out
    out[0] = rows.sum()
    for j in range(dim - 1):
        out[1 + j] = float(con.friction[j]) * (rows[2 * j] - rows[2 * j + 1])
    return out


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    from references.engines.contact import configuration as find
    from references.engines.mjx.compile import _import, x64_mode

    mujoco, jax, mjx = _import()
    conf = find("mjx", configuration)
    if any(np.any(f.point != 0) for f in scenario.forces):
        raise Unsupported(
            "mjx contact builder: a force off a centre of mass (its torque turns "
            "with the body) is not applied in the jitted loop"
        )
    xml = mjc.mjcf(scenario, conf, dt, settings).replace(
        "<mujoco>", f'<mujoco model="{MODEL_NAME}">', 1
    )
    m = mujoco.MjModel.from_xml_string(xml)
    if _plant is not None:
        mjc.PLANTABLE[_plant](mujoco, m)
    d = mujoco.MjData(m)
    nb = len(scenario.bodies)
    bid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b.name) for b in scenario.bodies]
    mjc.set_initial_state(mujoco, m, d, scenario, bid)
    for i, b in enumerate(scenario.bodies):
        F, tau = external_wrench(scenario, i, b.rotation)
        d.xfrc_applied[bid[i], :3] = F
        d.xfrc_applied[bid[i], 3:] = tau
    mujoco.mj_forward(m, d)
    pidx = pair_index(scenario)
    geom_name = {
        g: mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g).split(":", 1)[1]
        for g in range(m.ngeom)
    }
    saved = SavedStates(nstep, save_every, nb)
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()

    def save(k, step, dd, dx=None):
        mjc.read_bodies(mujoco, m, dd, scenario, bid, X[k], R[k], V[k], W[k])
        t[k] = step * dt
        if step > 0:
            impl = jax.device_get(dx._impl)  # MJX's rows, before get_data compacts them
            efc = np.asarray(impl.efc_force)
            rows = np.asarray(impl.contact.efc_address)[np.nonzero(impl.contact.dist <= 0)[0]]
            for c in range(dd.ncon):
                con = dd.contact[c]
                if con.efc_address < 0:
                    continue
                pi = pidx.get(frozenset((geom_name[int(con.geom1)], geom_name[int(con.geom2)])))
                if pi is None:
                    continue
                f3 = contact_frame_force(int(m.opt.cone), con, efc, rows[c])
                fr = np.asarray(con.frame).reshape(3, 3)
                f, n = fr.T @ f3, fr[0]
                if geom_name[int(con.geom2)] != scenario.contacts[pi].a:
                    f, n = -f, -n
                log.add(pi, con.pos.copy(), n, f, -float(con.dist))
        log.save()

    save(0, 0, d)
    engine = 0.0
    with x64_mode(True):
        mx = mjx.put_model(m, impl="jax")
        dx = mjx.put_data(m, d, impl="jax")
        # put_data's integer fields are int32, step's int64 under x64: the loop's carry must
        # keep one type, so the state takes the types step gives (values unchanged)
        shapes = jax.eval_shape(mjx.step, mx, dx)
        dx = jax.tree_util.tree_map(lambda a, s: a.astype(s.dtype), dx, shapes)

        @jax.jit
        def advance(mx, dx, n):
            return jax.lax.fori_loop(0, n, lambda _, s: mjx.step(mx, s), dx)

        t0 = time.perf_counter()
        warm = advance(mx, dx, 0)
        jax.block_until_ready(warm)
        compile_s = time.perf_counter() - t0
        timing.stepping()  # compiled: the compilation is not the run's cost
        k, step = 1, 0
        while step < nstep:
            n = min(save_every, nstep - step)
            t0 = time.perf_counter()
            dx = advance(mx, dx, n)
            jax.block_until_ready(dx)
            engine += timing.lap(t0)
            step += n
            dd = mjx.get_data(m, dx)
            save(k, step, dd, dx)
            k += 1
            if not np.all(np.isfinite(dd.qpos)):
                break
    record = mjc.settings_record(m, conf, settings)
    record["noslip"] = "not run by MJX"
    record["precision"] = "float64 (jax.enable_x64)"
    record["jit compile (s)"] = round(compile_s, 3)
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": record,
        "readback": mjc.readback(mujoco, m, scenario),
    }


PLANTABLE = mjc.PLANTABLE
