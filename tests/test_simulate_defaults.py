"""The simulator's defaults on ordinary impacts with friction, its physical horizon and
`state_at`, against closed forms that share nothing with time-freezing or FESD.

A unit point mass dropped from height h with horizontal speed v0 onto ground with Coulomb
friction mu (inelastic): free fall until t1 = sqrt(2 h / g), where the impulse in the cone
stops the normal velocity and takes mu sqrt(2 g h) off the tangential one (clamped at 0);
then it slides, decelerating at mu g, until it sticks.
"""

import math

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import IncompatibleOptions, InvalidInput, SolveFailed
from tfcontact.fesd import (
    NO_ADAPTATION,
    Adaptivity,
    Physical,
    SimulationStatus,
    simulate,
)
from tfcontact.mpcc import Homotopy
from tfcontact.scenes.particles import G, point_mass
from tfcontact.timefreezing import Inelastic, time_freeze, to_physical_time
from tfcontact.verify import simulate_impacts

# Relaxed complementarity lets the particle sink about 1.2e-5 m while frozen, and the
# clock creeps through the frozen piece (2e-6 s): both show in the state after the impact.
TOL_AFTER_IMPACT = 5e-5


def dropped_particle(t: float, h: float, v0: float, mu: float) -> np.ndarray:
    """(x, z, v_x, v_z) of the dropped particle at physical time t (post-impact at t1)."""
    t1 = math.sqrt(2 * h / G)
    if t < t1:
        return np.array([v0 * t, h - G * t**2 / 2, v0, -G * t])
    v_post = max(0.0, v0 - mu * G * t1)  # the tangential impulse is mu times the normal one
    s = min(t - t1, v_post / (mu * G))  # sliding time until it sticks
    return np.array([v0 * t1 + v_post * s - mu * G * s**2 / 2, 0.0, v_post - mu * G * s, 0.0])


@pytest.mark.parametrize(
    ("h", "v0", "mu"),
    [(1.0, 3.0, 0.3),  # still slides at the horizon
     (1.0, 3.0, 0.5),  # slides, sticks at t = 0.61 s
     (0.5, 1.0, 0.5)],  # the impact itself stops the slip (v0 < mu sqrt(2 g h))
)
def test_dropped_particle_with_defaults_matches_the_closed_form(h, v0, mu):
    """Defaults (a_n = 100 in the model, RadauIIA(2), 2 elements per step), physical
    horizon 0.8 s: the clock ends at 0.8 and `state_at` follows the closed form, with the
    jump of the impact between side="pre" and side="post"."""
    tf = time_freeze(point_mass(2, mu=mu))
    result = simulate(tf, tf.initial_state([0.0, h], [v0, 0.0]), horizon=Physical(0.8),
                      n_steps=8)
    assert result.success
    assert result.x[-1, tf.clock_index] == pytest.approx(0.8, abs=1e-9)
    t1 = math.sqrt(2 * h / G)
    impacts = to_physical_time(tf, result.t, result.x).impacts
    assert len(impacts) == 1
    assert impacts[0].time == pytest.approx(t1, abs=1e-8)
    for t in (0.1, 0.3, t1 * 0.999):
        np.testing.assert_allclose(result.state_at(t)[:4], dropped_particle(t, h, v0, mu),
                                   atol=1e-8)
    np.testing.assert_allclose(result.state_at(t1, side="pre")[:4],
                               dropped_particle(t1 * (1 - 1e-15), h, v0, mu), atol=1e-7)
    times = [t1, 0.5, 0.6, 0.65, 0.7, 0.8]
    np.testing.assert_allclose(result.state_at(np.array(times))[:, :4],
                               [dropped_particle(t, h, v0, mu) for t in times],
                               atol=TOL_AFTER_IMPACT)
    assert result.x[:, 1].min() > -1e-4  # penetration of the relaxed solution
    gain = [a for a in result.adaptations if a.kind == "gain"]
    assert len(gain) == 1 and gain[0].before == 100.0 and gain[0].after < 100.0
    assert "hits at |v_n|" in gain[0].reason
    assert result.adaptations[-1].kind == "last_step"


@pytest.mark.parametrize("form", ["heaviside", "stewart"])
def test_adapted_gain_sets_the_frozen_duration_and_the_contact_clock_rate(form):
    """The adapted a_n makes the frozen piece last |v_n| / a_n = frozen_steps steps of
    numerical time, and persistent contact runs the clock at gamma = a_n / (a_n + g)
    ([AUTO23] eq. (17)) -- the gain really is scaled, not just reported."""
    h, step = 1.0, 0.1
    tf = time_freeze(point_mass(2, mu=0.3), method=Inelastic(form=form))
    result = simulate(tf, tf.initial_state([0.0, h], [3.0, 0.0]), horizon=1.2, n_steps=12)
    a_n = result.a_n[0]
    v_impact = math.sqrt(2 * G * h)
    assert a_n == pytest.approx(v_impact / (2.0 * step), rel=1e-12)  # frozen_steps = 2
    impact = to_physical_time(tf, result.t, result.x).impacts[0]
    assert impact.tau[1] - impact.tau[0] == pytest.approx(v_impact / a_n, rel=1e-4)
    after = result.t > impact.tau[1] + 1e-9
    rate = np.diff(result.x[after, tf.clock_index]) / np.diff(result.t[after])
    np.testing.assert_allclose(rate, a_n / (a_n + G), rtol=1e-6)


def test_default_run_that_failed_on_main_now_succeeds():
    """The particle dropped 1 m at v0 = 3 m/s with mu = 0.3, a_n = 100, horizon 1.5 s in
    15 steps, the simulator's other defaults. On main (b9ef65e) `simulate(tf.pss, ...)`
    failed: step 6 of 15, IPOPT Infeasible_Problem_Detected at sigma = 1e-9 after 1010
    iterations (1.0 s); so did 5 of 6 drops with mu in {0.2, 0.3, 0.5}, v0 in {1, 3}.
    `NO_ADAPTATION` is that simulator; its message now names a_n and the step with values
    to try. With the defaults (a_n lowered to 22.1, failed steps cut) it succeeds."""
    tf = time_freeze(point_mass(2, mu=0.3))
    y0 = tf.initial_state([0.0, 1.0], [3.0, 0.0])
    old = simulate(tf, y0, horizon=1.5, n_steps=15, adapt=NO_ADAPTATION, throw=False)
    assert old.status is SimulationStatus.STEP_FAILED
    assert old.n_steps == 6 and old.adaptations == ()
    assert "step 6 of 15 failed" in old.message
    assert "the contacts had a_n = 100, try a_n = 25" in old.message
    assert "n_steps = 30 (step 0.05 s instead of 0.1 s)" in old.message
    new = simulate(tf, y0, horizon=1.5, n_steps=15)
    assert new.success and new.n_steps == 15
    assert new.t[-1] == pytest.approx(1.5, abs=1e-12)
    assert [a.kind for a in new.adaptations] == ["gain"]
    t_end = new.x[-1, tf.clock_index]
    np.testing.assert_allclose(new.x[-1, :4], dropped_particle(t_end, 1.0, 3.0, 0.3),
                               atol=TOL_AFTER_IMPACT)


def test_block_sliding_to_rest_keeps_its_gain():
    """A block on the ground at v0 = 2 m/s, mu = 0.3: no impact, so a_n stays; it stops at
    v0 / (mu g) = 0.680 s and stays there."""
    v0, mu = 2.0, 0.3
    tf = time_freeze(point_mass(2, mu=mu))
    result = simulate(tf, tf.initial_state([0.0, 0.0], [v0, 0.0]), horizon=Physical(1.0),
                      n_steps=10)
    assert result.success
    assert result.a_n == (100.0,)
    assert [a.kind for a in result.adaptations] == ["last_step"]
    stop = v0 / (mu * G)
    for t in (0.2, 0.5, stop, 0.9, 1.0):
        s = min(t, stop)
        expected = [v0 * s - mu * G * s**2 / 2, 0.0, v0 - mu * G * s, 0.0, t]
        np.testing.assert_allclose(result.state_at(t), expected, atol=1e-7)


@pytest.mark.parametrize("pitch", [0.0, 0.2])
def test_robot_falling_on_its_foot_with_defaults(pitch):
    """The hopper of tfcontact.robot with its hip and leg locked (a rigid leg, q = (x, z,
    pitch)) dropped 0.3 m onto its foot, mu = 0.45, a_n = 100. On main (b9ef65e) the
    defaults failed at step 3 of 10 (horizon 1.0) for both pitches. The impact comes at
    sqrt(2 h / g) (free fall of a rigid body), the foot's normal velocity is 0 after it, and
    the states agree with the event-detecting reference (impact LCP, not time-freezing)."""
    from tfcontact.robot import ContactSpec, load_robot
    from tfcontact.timefreezing import from_robot

    robot = load_robot("hopper", base="planar", locked_joints=("hip_joint", "leg_joint"),
                       locked_positions=(0.0, 0.4), contacts=(ContactSpec("foot", 0.02),))
    cls = from_robot(robot, mu=0.45)
    tf = time_freeze(cls)
    gap = ca.Function("gap", [cls.q], [cls.contacts[0].gap])
    q0 = np.array([0.0, 0.0, pitch])
    q0[1] = 0.3 - float(gap(q0))
    v0 = np.array([0.8, 0.0, 0.0])
    result = simulate(tf, tf.initial_state(q0, v0), horizon=Physical(0.5), n_steps=5)
    assert result.success
    reference = simulate_impacts(cls, np.concatenate([q0, v0]), None, 0.5)
    impact = reference.impacts[0]
    assert impact.time == pytest.approx(math.sqrt(2 * 0.3 / G), abs=1e-9)
    (tf_impact,) = to_physical_time(tf, result.t, result.x).impacts
    assert tf_impact.time == pytest.approx(impact.time, abs=1e-8)
    np.testing.assert_allclose(result.state_at(impact.time, side="pre")[:6], impact.pre,
                               atol=1e-7)
    post = result.state_at(impact.time)
    np.testing.assert_allclose(post[:6], impact.post, atol=TOL_AFTER_IMPACT)
    normal = np.asarray(cls.function("normals")(post[:3])).ravel()
    assert abs(normal @ post[3:6]) < 1e-8
    np.testing.assert_allclose(result.x[-1, :6], reference.x[-1], atol=TOL_AFTER_IMPACT)
    assert result.a_n[0] < 100.0


def test_verbose_prints_each_adaptation(capsys):
    tf = time_freeze(point_mass(2, mu=0.3))
    simulate(tf, tf.initial_state([0.0, 1.0], [1.0, 0.0]), horizon=Physical(0.6),
             n_steps=6, verbose=True)
    out = capsys.readouterr().out
    assert "adaptation (gain) at step 1 (tau = 0 s, t = 0 s): a_n 100 -> " in out
    assert "adaptation (last_step)" in out


def test_a_step_that_still_fails_names_a_n_and_the_step():
    """One NLP per homotopy cannot reach the tolerance: cutting does not help either, and
    the message gives the values to try."""
    tf = time_freeze(point_mass(2, mu=0.3))
    with pytest.raises(SolveFailed, match=r"step 1 of 8 failed at tau = 0 s \(t = 0 s\), "
                       r"also cut down to steps of 0\.05 s") as caught:
        simulate(tf, tf.initial_state([0.0, 1.0], [3.0, 0.0]), horizon=0.8, n_steps=8,
                 homotopy=Homotopy(max_nlps=1), retry=False, adapt=Adaptivity(max_cuts=1))
    message = str(caught.value)
    assert "the contacts had a_n = 22.15, try a_n = 5.537" in message
    assert "n_steps = 16 (step 0.05 s instead of 0.1 s)" in message
    assert "n_finite_elements = 3" in message
    result = caught.value.result
    assert result.status is SimulationStatus.STEP_FAILED
    assert [a.kind for a in result.adaptations] == ["gain", "cut"]


def test_the_physical_horizon_stops_on_its_step_budget():
    tf = time_freeze(point_mass(2, mu=0.3))
    result = simulate(tf, tf.initial_state([0.0, 1.0], [3.0, 0.0]),
                      horizon=Physical(1.0, budget=1.0), n_steps=5, throw=False)
    assert result.status is SimulationStatus.BUDGET_EXCEEDED
    assert result.n_steps == 5
    assert "in 5 steps (budget 5)" in result.message
    assert result.x[-1, tf.clock_index] < 1.0


def test_bare_piecewise_smooth_system_keeps_numerical_time():
    """Given `tf.pss`, simulate knows no clock: no gain adaptation, `state_at` reads the
    simulation's own time, and a physical horizon is refused."""
    tf = time_freeze(point_mass(2, mu=0.3))
    y0 = tf.initial_state([0.0, 1.0], [0.0, 0.0])
    result = simulate(tf.pss, y0, horizon=0.3, n_steps=3)
    assert result.clock_index is None and result.a_n == ()
    np.testing.assert_allclose(result.state_at(0.25)[:4], dropped_particle(0.25, 1.0, 0, 0.3),
                               atol=1e-12)
    with pytest.raises(IncompatibleOptions, match=r"needs the clock of a time-freezing system"):
        simulate(tf.pss, y0, horizon=Physical(0.3), n_steps=3)


def test_bad_horizons_options_and_times_are_refused():
    tf = time_freeze(point_mass(2, mu=0.3, controlled=True))
    y0 = tf.initial_state([0.0, 1.0], [0.0, 0.0])
    for kwargs, match in (({"time": 0.0}, r"`Physical.time` must be > 0 \[s\], got 0.0"),
                          ({"time": math.nan}, r"`Physical.time` must be a finite number"),
                          ({"time": 1.0, "tol": 0.0}, r"`Physical.tol` must be > 0"),
                          ({"time": 1.0, "budget": 0.5}, r"`Physical.budget` must be >= 1")):
        with pytest.raises(InvalidInput, match=match):
            Physical(**kwargs)
    for kwargs, match in (({"max_cuts": -1}, r"`max_cuts` must be a non-negative integer"),
                          ({"frozen_steps": 0.0}, r"`frozen_steps` must be a number > 0"),
                          ({"min_clock_rate": 1.0}, r"`min_clock_rate` must lie in \(0, 1\)"),
                          ({"min_gain_factor": 0.0}, r"`min_gain_factor` must lie in"),
                          ({"gain": 1}, r"`gain` must be True or False")):
        with pytest.raises(InvalidInput, match=match):
            Adaptivity(**kwargs)
    with pytest.raises(InvalidInput, match=r"`horizon` must be a positive number \[s\] or "
                                           r"Physical\(T\), got '1'"):
        simulate(tf, y0, horizon="1", n_steps=2, u=[0.0, 0.0])
    with pytest.raises(IncompatibleOptions, match=r"give constant controls of shape \(2,\)"):
        simulate(tf, y0, horizon=Physical(0.2), n_steps=2, u=np.zeros((2, 2)))
    result = simulate(tf, y0, horizon=Physical(0.2), n_steps=2, u=[0.0, 0.0])
    with pytest.raises(InvalidInput, match=r"`t` must lie in the simulated physical times "
                                           r"\[0, 0.2\] s, got 0.3"):
        result.state_at(0.3)
    with pytest.raises(InvalidInput, match=r"`side` must be 'post' or 'pre', got 'mid'"):
        result.state_at(0.1, side="mid")
