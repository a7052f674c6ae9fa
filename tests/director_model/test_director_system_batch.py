"""director_model.system.simulate_system_batch: N systems of one topology in parallel.

The reference of every member is its own simulate_system run (the single-system kernel run
alone): the batch calls the same kernel per member with the member's own state and output,
so the saved states must be equal bit for bit, on 1 and on 2 threads.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

import director_model as dm
from director_model.system import Body, simulate_system, simulate_system_batch
from director_model.system.examples import parallelogram_four_bar, rod_chain

G = (0.0, 0.0, -9.81)


def _assert_member_equals_single(tr, k, bodies, joints, **kw):
    s = simulate_system(bodies, joints, **kw)
    assert tr.solver == s.solver
    np.testing.assert_array_equal(tr.t, s.t)
    for f in ("position", "velocity", "rotation", "omega_body"):
        np.testing.assert_array_equal(getattr(tr, f)[k], getattr(s, f), err_msg=f"{f}[{k}]")
    m = tr.member(k)
    for f in ("energy", "angular_momentum", "constraint_position", "constraint_velocity"):
        np.testing.assert_array_equal(getattr(m, f), getattr(s, f), err_msg=f"{f}[{k}]")
    assert m.newton_iterations == s.newton_iterations


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize(("n", "hang", "scheme"), [(3, True, "rattle4"), (2, False, "rattle")])
def test_members_equal_their_single_runs_bit_for_bit(threads, n, hang, scheme):
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"numba has {numba.config.NUMBA_NUM_THREADS} thread(s)")
    members = [rod_chain(n, hang, seed=s) for s in range(5)]
    joints = members[0][1]
    kw = dict(gravity=G if hang else (0.0, 0.0, 0.0), scheme=scheme, dt=1e-3, t_end=0.04,
              save_every=7)  # fmt: skip
    tr = simulate_system_batch([m[0] for m in members], joints, threads=threads, **kw)
    assert tr.threads == threads and tr.ok.all() and len(tr) == 5
    assert tr.position.shape == (5, len(tr.t), n, 3) and tr.rotation.shape[-2:] == (3, 3)
    # the members differ (different seeds): equality below is not that of one state copied
    assert np.abs(tr.position[0, -1] - tr.position[1, -1]).max() > 1e-3
    for k, (bodies, _) in enumerate(members):
        _assert_member_equals_single(tr, k, bodies, joints, **kw)


def test_closed_loop_batch_minnorm_equals_single_runs():
    # redundant rows (minimum-norm solver) and different initial angles and rates
    cases = [parallelogram_four_bar(0.2 * k, 7.0 - k) for k in range(3)]
    joints = cases[0][1]
    kw = dict(gravity=G, scheme="rattle", dt=2e-3, t_end=0.02, save_every=5)
    tr = simulate_system_batch([c[0] for c in cases], joints, threads=2, **kw)
    assert tr.solver == "minnorm"
    for k, c in enumerate(cases):
        _assert_member_equals_single(tr, k, c[0], joints, **kw)


def test_failed_member_is_reported_and_the_others_go_on():
    # h |W| >= 1 has no solution of the rotation equation (as in test_director_system)
    bodies, joints = rod_chain(2, False, spin=False)
    b1 = bodies[1]
    spin = [bodies[0], Body("b1", 1.0, b1.inertia, b1.position, b1.rotation,
                            omega_body=(0.0, 0.0, 400.0))]  # fmt: skip
    kw = dict(scheme="rattle", dt=0.01, t_end=0.05, save_every=1)
    tr = simulate_system_batch([bodies, spin, bodies], joints, **kw)
    assert list(tr.ok) == [True, False, True]
    assert tr.steps_done[1] == 0 and "step 1 starting at t = 0 s" in tr.messages[1]
    assert tr.messages[0] is None and np.isnan(tr.position[1, 1:]).all()
    with pytest.raises(dm.StepSizeError, match=r"member 1: rattle: step 1"):
        tr.member(1)
    with pytest.raises(dm.StepSizeError, match=r"step 1 starting at t = 0 s"):
        simulate_system(spin, joints, **kw)
    _assert_member_equals_single(tr, 2, bodies, joints, **kw)


def test_bad_batches_are_refused_with_the_member_and_the_rule():
    a, joints = rod_chain(2, True, seed=1, spin=False)
    b, _ = rod_chain(2, True, seed=2, spin=False)
    heavy = [b[0], Body("b1", 2.0, b[1].inertia, b[1].position, b[1].rotation)]
    kw = dict(gravity=G, dt=1e-3, t_end=0.002)
    with pytest.raises(dm.InvalidRunError, match=r"bodies_batch\[1\]: body 'b1': mass or"):
        simulate_system_batch([a, heavy], joints, **kw)
    moved = [b[0], Body("b1", 1.0, b[1].inertia, b[1].position + 0.1, b[1].rotation)]
    with pytest.raises(dm.system.InvalidJointError, match=r"bodies_batch\[1\]: .*joint1"):
        simulate_system_batch([a, moved], joints, **kw)
    with pytest.raises(dm.InvalidRunError, match=r"bodies_batch: empty"):
        simulate_system_batch([], joints, **kw)
    with pytest.raises(dm.InvalidRunError, match=r"threads = 0: must be a whole number"):
        simulate_system_batch([a], joints, threads=0, **kw)
