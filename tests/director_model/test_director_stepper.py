"""director_model.Stepper: chunks of steps give bit for bit the run of ``simulate``.

The reference of every comparison is an independent computation: one ``simulate`` run of
the whole horizon (its own compiled call, its own state), not values copied from the code
under test. Equality is exact (``np.array_equal``): chunking must not change a single bit.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import director_model as dm

FIELDS = ("t", "position", "velocity", "rotation", "director_velocity", "omega_body", "energy",
          "angular_momentum", "linear_momentum", "constraint_position",
          "constraint_velocity")  # fmt: skip

R0 = Rotation.from_rotvec([0.3, -0.5, 0.7]).as_matrix()
CASES = {
    # free body with gravity and a moving centre of mass
    "free": dict(mass=1.5, inertia=(1.0, 2.0, 2.5), rotation=R0, omega_body=(1.0, -0.7, 0.5),
                 position=(1.0, 2.0, 3.0), velocity=(0.1, -0.2, 0.3), gravity=(0.3, 0.0, -9.81)),
    # pivoted body under gravity, pivot off the principal axes (non-diagonal Ibar)
    "pivoted": dict(mass=1.5, inertia=(1.0, 2.0, 2.5), rotation=R0, omega_body=(1.0, -0.7, 0.5),
                    gravity=(0.3, 0.0, -9.81), pivot=(0.1, -0.3, 0.2)),
    # heavy top pivoted on its axis (diagonal Ibar: the straight-line solver)
    "top": dict(mass=1.0, inertia=(4.75, 4.75, 1.0),
                rotation=Rotation.from_rotvec([0.05, 0.0, 0.0]).as_matrix(),
                omega_body=(0.0, 0.0, 50.0), gravity=(0.0, 0.0, -40.0), pivot=(0.0, 0.0, -0.5)),
}  # fmt: skip
DT = 2e-3
EVERY = 5


def _assert_same(a, b, where=""):
    for f in FIELDS:
        assert np.array_equal(getattr(a, f), getattr(b, f)), (where, f)


@pytest.mark.parametrize("scheme", list(dm.SCHEMES))
@pytest.mark.parametrize("case", list(CASES))
def test_chunks_equal_one_run_bit_for_bit(scheme, case):
    n1, n2, n3 = 3 * EVERY, 2 * EVERY + 3, 7  # the first chunk ends on a saved step
    whole = dm.simulate(**CASES[case], scheme=scheme, dt=DT, t_end=(n1 + n2 + n3) * DT,
                        save_every=EVERY)  # fmt: skip
    st = dm.Stepper(**CASES[case], scheme=scheme, dt=DT)
    a = st.advance(n1, save_every=EVERY, include_start=True)
    b = st.advance(n2, save_every=EVERY)
    c = st.advance(n3, save_every=EVERY)
    assert st.nstep_done == n1 + n2 + n3 and st.time == (n1 + n2 + n3) * DT
    assert (a.nstep, b.nstep, c.nstep) == (n1, n2, n3)
    # saved steps (absolute): chunks 0, 5, 10, 15 | 20, 25, 28 | 33, 35; the single run
    # 0, 5, ..., 35. Common: a[0:4] = whole[0:4], b[0:2] = whole[4:6], c[-1] = whole[-1]
    assert np.array_equal(whole.t, np.arange(0, 36, 5) * DT)
    for f in FIELDS:
        w = getattr(whole, f)
        assert np.array_equal(getattr(a, f), w[0:4]), ("a", f)
        assert np.array_equal(getattr(b, f)[0:2], w[4:6]), ("b", f)
        assert np.array_equal(getattr(c, f)[-1], w[-1]), ("c", f)
    assert np.array_equal(b.t, np.array([20, 25, 28]) * DT)
    assert np.array_equal(c.t, np.array([33, 35]) * DT)
    # the reported state is the last saved one, bit for bit
    x, v, R, W = st.state()
    assert np.array_equal(x, whole.position[-1]) and np.array_equal(v, whole.velocity[-1])
    assert np.array_equal(R, whole.rotation[-1]) and np.array_equal(W, whole.omega_body[-1])


@pytest.mark.parametrize("scheme", ["rattle", "rattle6"])
def test_many_small_chunks_equal_one_run(scheme):
    n = 40
    whole = dm.simulate(**CASES["free"], scheme=scheme, dt=DT, t_end=n * DT, save_every=1)
    st = dm.Stepper(**CASES["free"], scheme=scheme, dt=DT)
    parts = [st.advance(1, include_start=True)] + [st.advance(1) for _ in range(n - 1)]
    for f in FIELDS:
        got = np.concatenate([getattr(p, f) for p in parts])
        assert np.array_equal(got, getattr(whole, f)), f


def test_simulate_is_one_chunk_with_its_start():
    st = dm.Stepper(**CASES["pivoted"], scheme="rattle4", dt=DT)
    _assert_same(st.advance(23, save_every=4, include_start=True),
                 dm.simulate(**CASES["pivoted"], scheme="rattle4", dt=DT, t_end=23 * DT,
                             save_every=4))  # fmt: skip


def test_state_before_any_step_is_the_input():
    c = CASES["free"]
    st = dm.Stepper(**c, dt=DT)
    x, v, R, W = st.state()
    assert st.nstep_done == 0 and st.time == 0.0
    assert np.array_equal(x, c["position"]) and np.array_equal(v, c["velocity"])
    assert np.array_equal(R, c["rotation"])
    # W comes back through D' = D hat(Ibar^{-1} Ibar W) and vee(skew(D^T D')): a few
    # roundings of O(|W|) products (R0 orthonormal to ~1e-16)
    assert np.max(np.abs(W - c["omega_body"])) < 8 * np.finfo(float).eps * np.linalg.norm(W)
    assert isinstance(st.state(), dm.StepperState) and st.state().rotation.shape == (3, 3)


def test_free_centre_of_mass_is_exact_free_flight():
    # every scheme integrates free flight exactly; the stepper gives it in closed form at the
    # absolute time, so chunking does not matter and nothing accumulates: x0 + v0 t + g t^2/2
    c = CASES["free"]
    st = dm.Stepper(**c, scheme="rattle", dt=DT)
    for _ in range(3):
        tr = st.advance(1000, save_every=250)
    t = tr.t[:, None]
    x = np.asarray(c["position"]) + np.asarray(c["velocity"]) * t + 0.5 * np.asarray(
        c["gravity"]) * t * t  # fmt: skip
    # numpy evaluates the same formula with another association: a few ulps of |x|
    assert np.max(np.abs(tr.position - x)) < 8 * np.finfo(float).eps * np.abs(x).max()


def test_failure_mid_chunk_reports_absolute_time_and_keeps_last_state():
    # a pendulum released horizontally: dt = 0.3 is fine at first and fails as |W| grows
    kw = dict(mass=1.0, inertia=(0.1, 0.1, 0.1),
              rotation=Rotation.from_rotvec([0, np.pi / 2, 0]).as_matrix(),
              omega_body=(0, 0, 0), gravity=(0, 0, -9.81), pivot=(0, 0, 1.0), dt=0.3)  # fmt: skip
    with pytest.raises(dm.StepSizeError) as whole:
        dm.simulate(**kw, t_end=30.0)
    st = dm.Stepper(**kw)
    st.advance(1)
    with pytest.raises(dm.StepSizeError) as chunked:
        st.advance(99)
    assert chunked.value.time == whole.value.time and chunked.value.step == whole.value.step
    assert str(chunked.value) == str(whole.value)
    done = whole.value.step - 1
    assert st.nstep_done == done and st.time == done * 0.3
    ref = dm.simulate(**kw, t_end=done * 0.3, save_every=done)
    x, v, R, W = st.state()
    assert np.array_equal(R, ref.rotation[-1]) and np.array_equal(W, ref.omega_body[-1])


def test_failure_inside_a_composition_step_keeps_the_step_start():
    # rattle4's middle substep is 1.70 h backwards: with h |W| = 0.7 the first substep
    # (1.35 h) succeeds and the second fails; the stepper stays at the step's start
    kw = dict(mass=1.0, inertia=(2.0, 3.0, 4.0), rotation=np.eye(3), omega_body=(0, 0, 7.0),
              scheme="rattle4", dt=0.1)  # fmt: skip
    st = dm.Stepper(**kw)
    before = st.state()
    with pytest.raises(dm.StepSizeError, match=r"step 1 starting at t = 0 s"):
        st.advance(3)
    after = st.state()
    assert st.nstep_done == 0
    for a, b in zip(before, after, strict=True):
        assert np.array_equal(a, b)


def test_advance_validates_counts():
    st = dm.Stepper(**CASES["free"], dt=DT)
    for bad in (0, -1, 1.5, True, "3"):
        with pytest.raises(dm.InvalidRunError, match="nstep"):
            st.advance(bad)
        with pytest.raises(dm.InvalidRunError, match="save_every"):
            st.advance(3, save_every=bad)
    with pytest.raises(dm.InvalidRunError, match="dt"):
        dm.Stepper(**CASES["free"], dt=0.0)
    with pytest.raises(dm.InvalidRunError, match="compensated"):
        dm.Stepper(**CASES["free"], dt=DT, compensated="yes")
    assert st.nstep_done == 0  # nothing was stepped
