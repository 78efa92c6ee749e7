"""The exact re-solve along a sequence of stances (`tfcontact.ocp.stances`) against closed
forms with two contacts: two point masses, each with its own frictional contact with the
ground (independent contacts, so every stance's Delassus matrix is regular)."""

import dataclasses

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tfcontact.errors import InvalidInput
from tfcontact.ocp import ContactProblem
from tfcontact.ocp.stances import (
    Stance,
    StanceDynamics,
    StanceOptions,
    cone_rows,
    interior_weights,
    resolve_stances,
    stall_stop,
    stance_schedule,
    swings,
)
from tfcontact.timefreezing import time_freeze
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact
from tfcontact.verify import EventKind, replay_multicontact

G = 9.81
MASSES = (1.0, 2.0)
MU = 0.7


def two_masses() -> ComplementarityLagrangianSystem:
    """q = (x1, z1, x2, z2); u = (x and z force on each mass); contact i: gap z_i,
    tangent x_i."""
    q, v, u = ca.SX.sym("q", 4), ca.SX.sym("v", 4), ca.SX.sym("u", 4)
    m1, m2 = MASSES
    contacts = tuple(
        Contact(gap=q[2 * i + 1], tangents=ca.jacobian(q[2 * i], q).T, mu=MU, name=f"m{i}")
        for i in range(2))
    forces = ca.vertcat(u[0], u[1] - m1 * G, u[2], u[3] - m2 * G)
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.diag(ca.DM([m1, m1, m2, m2])), forces=forces,
        contacts=contacts)


def problem(q0, v0, *, horizon, n_intervals, u_lower, u_upper, running):
    tf = time_freeze(two_masses())
    return ContactProblem(system=tf, q0=q0, v0=v0, horizon=horizon, n_intervals=n_intervals,
                          u_lower=u_lower, u_upper=u_upper, running_cost=running(tf))


DROP_HEIGHTS, DROP_SPEED = (0.25, 0.6), 0.5  # touchdowns at 0.226 and 0.350 s


def two_drops():
    """Both masses dropped from `DROP_HEIGHTS`, the first moving at `DROP_SPEED`, no
    controls: the problem, its stances and a guess whose touchdowns are 10 ms off the
    free-fall times t_i = sqrt(2 h_i / g), which are returned last."""
    (h1, h2), speed = DROP_HEIGHTS, DROP_SPEED
    p = problem([0.0, h1, 0.0, h2], [speed, 0.0, 0.0, 0.0], horizon=0.5, n_intervals=5,
                u_lower=[0.0] * 4, u_upper=[0.0] * 4, running=lambda tf: ca.DM(0.0))
    t1, t2 = np.sqrt(2 * h1 / G), np.sqrt(2 * h2 / G)
    t = np.linspace(0.0, 0.5, 201)
    x = np.zeros((len(t), 8))
    x[:, 0] = speed * np.minimum(t, t1 + 0.01)
    x[:, 1] = np.maximum(h1 - G * t**2 / 2, 0.0)
    x[:, 3] = np.maximum(h2 - G * t**2 / 2, 0.0)
    stances = (Stance((), 0.0, t1 + 0.01), Stance((0,), t1 + 0.01, t2 - 0.01),
               Stance((0, 1), t2 - 0.01, 0.5))
    return p, stances, (t, x, np.zeros((5, 4))), (t1, t2)


@pytest.mark.parametrize(("integrator", "inverse_dynamics", "element_derivatives",
                          "lifted_forces", "barrier"),
                         [("rk4", False, False, False, "monotone"),
                          ("rk4", False, True, False, "monotone"),
                          ("radau", False, False, False, "monotone"),
                          ("radau", False, True, False, "monotone"),
                          ("radau", True, False, False, "monotone"),
                          ("radau", False, False, True, "monotone"),
                          ("radau", False, True, True, "monotone"),
                          ("radau", False, True, True, "adaptive")])
def test_two_drops_touch_down_at_the_free_fall_times_and_stop(integrator, inverse_dynamics,
                                                              element_derivatives,
                                                              lifted_forces, barrier):
    """Both masses dropped, the first with a horizontal speed: each touchdown at
    sqrt(2 h / g) (RK4 and Radau IIA integrate free fall exactly), the impact leaves it at rest
    (Lambda_t = -m v_x inside the cone), and the multi-contact reference agrees; Radau in
    three forms of the dynamics (explicit, forces lifted, inverse dynamics), the explicit
    and the lifted one also with their elements differentiated once each
    (`element_derivatives`). The guess is 10 ms off: the re-solve moves the switches to
    the closed forms. The controls are fixed at zero, so the NLP is square (no degree of
    freedom): under IPOPT's adaptive barrier (`barrier`) IPOPT ended it in its restoration
    phase (Feasible_Point_Found where measured), and its feasible point is its solution."""
    p, stances, guess, (t1, t2) = two_drops()
    options = StanceOptions(tol=1e-10, integrator=integrator, inverse_dynamics=inverse_dynamics,
                            element_derivatives=element_derivatives, threads=2,
                            lifted_forces=lifted_forces, barrier=barrier)
    plan = resolve_stances(p, stances, options, guess=guess, verbose=False)
    assert plan.solved, plan.ipopt_status
    assert [s.closed for s in plan.stances] == [(), (0,), (0, 1)]
    assert plan.stances[1].start == pytest.approx(t1, abs=1e-7)
    assert plan.stances[2].start == pytest.approx(t2, abs=1e-7)
    end = plan.boundary_states[-1]
    assert end[0] == pytest.approx(DROP_SPEED * t1, abs=1e-6)  # slid no further after landing
    np.testing.assert_allclose(end[[1, 3]], 0.0, atol=1e-7)
    np.testing.assert_allclose(end[4:], 0.0, atol=1e-7)
    assert plan.verification.passed, plan.verification.summary()
    assert plan.verification.end_state_deviation < 1e-6


def test_a_capped_nlp_solved_again_from_its_iterate_converges():
    """`capped_restarts`: the two drops with IPOPT capped at 4 iterations stop short of
    the closed forms; solved again from their primal-dual iterate they reach them, in the
    iterations the uncapped solve takes (no fresh start from the interior)."""
    p, stances, guess, (t1, t2) = two_drops()
    runs = {restarts: resolve_stances(p, stances, StanceOptions(tol=1e-10, max_iter=4,
                                                                capped_restarts=restarts),
                                      guess=guess, verbose=False)
            for restarts in (0, 5)}
    uncapped = resolve_stances(p, stances, StanceOptions(tol=1e-10), guess=guess,
                               verbose=False)
    assert runs[0].ipopt_status == "Maximum_Iterations_Exceeded"
    # where the time went: the build, IPOPT, and CasADi's evaluations inside IPOPT
    timing = uncapped.timing
    assert 0 < timing.evaluations < timing.ipopt
    assert 0 < timing.build and timing.build + timing.ipopt <= uncapped.solve_time
    assert timing.n_variables > 8 * 5 and timing.n_constraints > 8 * 5
    assert f"{timing.n_variables} variables" in uncapped.summary()
    assert abs(runs[0].stances[2].start - t2) > 1e-4
    assert runs[5].solved and runs[5].iterations <= uncapped.iterations + 2
    assert runs[5].stances[1].start == pytest.approx(t1, abs=1e-7)
    assert runs[5].stances[2].start == pytest.approx(t2, abs=1e-7)
    with pytest.raises(InvalidInput, match="capped_restarts"):
        StanceOptions(capped_restarts=-1)
    with pytest.raises(InvalidInput, match="step_error_restarts"):
        StanceOptions(step_error_restarts=True)
    with pytest.raises(InvalidInput, match="`element_derivatives` must be True or False"):
        StanceOptions(element_derivatives="yes")
    with pytest.raises(InvalidInput, match="threads"):
        StanceOptions(threads=0)
    with pytest.raises(InvalidInput, match="`lifted_forces` needs integrator='radau'"):
        StanceOptions(lifted_forces=True, integrator="rk4")
    with pytest.raises(InvalidInput, match="`lifted_forces` needs"):
        StanceOptions(lifted_forces=True, inverse_dynamics=True)
    with pytest.raises(InvalidInput, match="`barrier` must be one of adaptive, monotone"):
        StanceOptions(barrier="mehrotra")


def test_a_stalled_nlp_stops_at_its_feasible_iterate():
    """`stall_iterations`: with a tolerance no iterate reaches (1e-20), IPOPT without it
    runs on to its own acceptable level (15 iterations there) or its cap; with it, it stops
    after 3 feasible iterations of unchanged objective, as acceptable, at the closed forms
    (the two drops' square NLP: every feasible point is its solution)."""
    p, stances, guess, (t1, t2) = two_drops()
    runs = {stall: resolve_stances(p, stances, StanceOptions(tol=1e-20, max_iter=60,
                                                             stall_iterations=stall),
                                   guess=guess, verbose=False)
            for stall in (0, 3)}
    assert runs[3].ipopt_status == "Solved_To_Acceptable_Level" and runs[3].solved
    assert runs[3].iterations < runs[0].iterations
    assert runs[3].stances[1].start == pytest.approx(t1, abs=1e-7)
    assert runs[3].stances[2].start == pytest.approx(t2, abs=1e-7)
    assert stall_stop(0) == {}
    with pytest.raises(InvalidInput, match="stall_iterations"):
        StanceOptions(stall_iterations=-1)


@pytest.mark.parametrize(("inverse_dynamics", "element_derivatives", "lifted_forces",
                          "barrier"),
                         [(False, False, False, "monotone"), (True, False, False, "monotone"),
                          (False, True, False, "monotone"), (False, False, True, "monotone"),
                          (False, True, True, "monotone"), (False, True, True, "adaptive")])
def test_a_stick_force_ends_at_the_cone_and_a_lift_off_opens(inverse_dynamics,
                                                             element_derivatives,
                                                             lifted_forces, barrier,
                                                             monkeypatch):
    """Mass 1 rests and is pushed sideways as hard as it can while it sticks: the push
    reaches c mu m g (the cone's edge) and it does not move. Mass 2 lifts off at the
    control jump 0.2 s: the new control's vertical force is at least its weight. Both
    forms of the dynamics (the forces as expressions, as variables with the acceleration
    explicit, or both as variables), the first two also with element derivatives, the
    lifted one also under IPOPT's adaptive barrier (`barrier`, which reaches IPOPT)."""
    margin = 0.9
    p = problem([0.0, 0.0, 1.0, 0.0], [0.0] * 4, horizon=0.4, n_intervals=4,
                u_lower=[-20.0, 0.0, 0.0, 0.0], u_upper=[20.0, 0.0, 0.0, 40.0],
                running=lambda tf: (tf.u[0] - 20.0) ** 2 + 1e-2 * tf.u[3] ** 2
                + 1e5 * (tf.y[tf.q_index][3] - 0.05) ** 2 * (tf.y[tf.clock_index] > 0.3))
    t = np.linspace(0.0, 0.4, 41)
    x = np.zeros((len(t), 8))
    x[:, 2] = 1.0
    x[:, 3] = np.where(t > 0.2, 0.5 * (t - 0.2), 0.0)
    stances = (Stance((0, 1), 0.0, 0.2), Stance((0,), 0.2, 0.4))
    options = StanceOptions(cone_margin=margin, tol=1e-10, inverse_dynamics=inverse_dynamics,
                            element_derivatives=element_derivatives,
                            lifted_forces=lifted_forces, barrier=barrier)
    guess = (t, x, np.zeros((4, 4)))
    given = []  # the barrier each IPOPT solver was built with
    solver = ca.Opti.solver

    def recording_solver(opti, name, plugin, ipopt):
        given.append(ipopt["mu_strategy"])
        return solver(opti, name, plugin, ipopt)

    monkeypatch.setattr(ca.Opti, "solver", recording_solver)
    plan = resolve_stances(p, stances, options, guess=guess, verbose=False)
    assert plan.solved, plan.ipopt_status
    assert given == [barrier]
    if lifted_forces:  # the forces are variables: (lambda_n, lambda_t) per closed contact
        # at each of 3 elements x 3 Radau stages per interval, 2 intervals of each stance
        explicit = resolve_stances(p, stances, dataclasses.replace(options,
                                                                   lifted_forces=False),
                                   guess=guess, verbose=False)
        assert plan.timing.n_variables - explicit.timing.n_variables == 18 * 4 + 18 * 2
        assert plan.cost == pytest.approx(explicit.cost, rel=1e-6)  # the same optimum
    np.testing.assert_allclose(plan.u[:, 0], margin * MU * MASSES[0] * G, rtol=1e-6)
    np.testing.assert_allclose(plan.x[:, [0, 1]], [[0.0, 0.0]] * len(plan.x), atol=1e-7)
    assert plan.u[2, 3] >= MASSES[1] * G - 1e-6  # it opens: u_z >= m g at the jump
    assert np.all(plan.x[plan.t < 0.2 - 1e-9, 3] < 1e-7)  # mass 2 stood until then
    assert plan.boundary_states[-1, 3] > 0.01
    assert plan.verification.passed, plan.verification.summary()


def test_cone_rows_planar_and_spatial():
    # planar (lambda_n, lambda_t) and 3-D (lambda_n, lambda_t1, lambda_t2)
    rows = cone_rows([2.0, 1.0, 3.0, 1.0, 1.0], [2, 3], [0.5, 0.5], (0, 1), 1.0,
                     keep_normal=True)
    np.testing.assert_allclose([float(r) for r in rows], [2.0, 0.0, 2.0, 3.0, 2.25 - 2.0])
    # planar with c mu > 0: the two cone rows imply lambda_n >= 0, which is left out
    # (at a vanishing impulse the three rows were active and dependent)
    rows = cone_rows([2.0, 1.0, 3.0, 1.0, 1.0], [2, 3], [0.5, 0.5], (0, 1), 1.0)
    np.testing.assert_allclose([float(r) for r in rows], [0.0, 2.0, 3.0, 2.25 - 2.0])
    assert len(cone_rows([0.0, 0.0], [2], [0.0], (0,), 1.0)) == 3  # frictionless: kept


def test_the_schedule_of_samples_keeps_the_order_of_touchdowns_and_lift_offs():
    t = np.linspace(0.0, 1.0, 101)
    gaps = np.zeros((101, 2))
    gaps[(t > 0.06) & (t < 0.505), 1] = 0.05  # foot 1 swings, lands at 0.51 s
    gaps[t > 0.525, 0] = 0.05  # foot 0 lifts off after 0.52 s
    stances = stance_schedule(t, gaps, 1.0, 20)
    # foot 0's lift-off goes to the control jump after foot 1's touchdown (0.55 s), not to
    # the nearest one before it (0.5 s: a flight phase the plan did not have)
    assert [s.closed for s in stances] == [(0, 1), (0,), (0, 1), (1,)]
    assert stances[1].start == pytest.approx(0.05)
    assert stances[2].start == pytest.approx(0.51)
    assert stances[3].start == pytest.approx(0.55)
    # a touchdown sampled at a control jump where a lift-off goes too: after it, in the
    # samples' order (foot 0 last down at 0.09 s, foot 1 first down again at 0.1 s)
    gaps[:] = 0.0
    gaps[(t > 0.03) & (t < 0.095), 1] = 0.05
    gaps[t > 0.095, 0] = 0.05
    stances = stance_schedule(t, gaps, 1.0, 20)
    assert [s.closed for s in stances] == [(0, 1), (0,), (), (1,)]
    assert stances[2].start == pytest.approx(0.1) and stances[3].start > 0.1
    # a lift-off in the first interval goes to the first jump; one in the last is dropped
    gaps[:] = 0.0
    gaps[t > 0.015, 0] = 0.05
    gaps[t > 0.985, 1] = 0.05
    assert [(s.closed, s.start) for s in stance_schedule(t, gaps, 1.0, 20)] == [
        ((0, 1), 0.0), ((1,), 0.05)]


def test_end_standing_drops_the_lift_offs_with_no_touchdown_after_them():
    """A jump's relaxed plan that lands and lifts its feet again before T (solo12: a
    flight from 0.55 s): with `end_standing` every foot stays down from its last
    touchdown (a foot that leaves for good stays down from the start); a foot never down
    stays open, and the swings before a touchdown are kept."""
    t = np.linspace(0.0, 1.0, 101)
    gaps = np.zeros((101, 4))
    gaps[(t > 0.22) & (t < 0.605), :2] = 0.1  # feet 0 and 1 jump, land at 0.61 s
    gaps[t > 0.855, 0] = 0.02  # foot 0 lifts again at the end
    gaps[t > 0.755, 1] = 0.02  # and foot 1
    gaps[t > 0.155, 2] = 0.05  # foot 2 leaves for good
    gaps[:, 3] = 0.05  # foot 3 is never down
    found = stance_schedule(t, gaps, 1.0, 20)
    assert [(s.closed, round(s.start, 3)) for s in found] == [
        ((0, 1, 2), 0.0), ((0, 1), 0.15), ((), 0.2), ((0, 1), 0.61), ((0,), 0.75),
        ((), 0.85)]
    standing = stance_schedule(t, gaps, 1.0, 20, StanceOptions(end_standing=True))
    assert [(s.closed, round(s.start, 3)) for s in standing] == [
        ((0, 1, 2), 0.0), ((2,), 0.2), ((0, 1, 2), 0.61)]
    assert standing[-1].end == 1.0
    with pytest.raises(InvalidInput, match="end_standing"):
        StanceOptions(end_standing=1)


def test_a_flight_no_control_jump_can_hold_is_closed_over():
    """A lift-off goes to a control jump, so a flight with no jump between the contact's
    closing before it and its touchdown cannot be modelled: the contact stays closed
    across it (the rule before moved the chatter's lift-off to the jump at the touchdown
    and gave an extra flight and stance). A flight that spans a jump is kept."""
    t = np.linspace(0.0, 1.0, 1001)
    gaps = np.zeros((1001, 2))
    gaps[(t > 0.06) & (t < 0.3), 1] = 0.05  # foot 1 swings, lands at 0.3 s
    gaps[(t > 0.307) & (t < 0.313), 1] = 0.01  # and chatters up again inside (0.3, 0.35)
    stances = stance_schedule(t, gaps, 1.0, 20)
    assert [s.closed for s in stances] == [(0, 1), (0,), (0, 1)]
    assert stances[2].start == pytest.approx(0.3)
    # from the start: a hop of foot 0 that lands before the first jump (0.05 s)
    gaps[:] = 0.0
    gaps[(t > 0.01) & (t < 0.04), 0] = 0.02
    assert [s.closed for s in stance_schedule(t, gaps, 1.0, 20)] == [(0, 1)]
    # the same hop landing after the first jump is a flight from it
    gaps[(t > 0.01) & (t < 0.07), 0] = 0.02
    stances = stance_schedule(t, gaps, 1.0, 20)
    assert [(s.closed, round(s.start, 3)) for s in stances] == [
        ((0, 1), 0.0), ((1,), 0.05), ((0, 1), 0.07)]


def test_a_tap_at_a_control_jump_touches_down_before_it_lifts_off():
    """A foot that lands on the very sample of a control jump and rises after it (the
    relaxed walk of biped-walk's sweep start 003: down at 0.2 s, 5.9 mm up at 0.227 s):
    its touchdown goes just before its own lift-off at that jump. The rule before put it
    just after, as for another foot's touchdown there, and refused the schedule ("contacts
    [0] change twice within one control interval")."""
    t = np.array([0.0, 0.05, 0.1, 0.133, 0.15, 0.182, 0.2, 0.227, 0.25, 0.3, 0.4, 0.5, 1.0])
    gaps = np.zeros((len(t), 2))
    gaps[:, 0] = [0.0, 0.0, 0.003, 0.0057, 0.0061, 0.0028, 0.0, 0.0059, 0.02, 0.1, 0.05,
                  0.0, 0.0]
    stances = stance_schedule(t, gaps, 1.0, 20)
    assert [s.closed for s in stances] == [(0, 1), (1,), (0, 1), (1,), (0, 1)]
    assert stances[1].start == pytest.approx(0.1)  # its first lift-off
    assert 0.2 - 1e-6 < stances[2].start < 0.2  # down just before the jump
    assert stances[3].start == pytest.approx(0.2)  # up at the jump
    assert stances[4].start == pytest.approx(0.5)
    # another foot's touchdown on that sample still goes after the lift-off
    gaps[:, 1] = np.where((t > 0.05) & (t < 0.2), 0.01, 0.0)
    gaps[:, 0] = np.where(t > 0.19, 0.01, 0.0)
    stances = stance_schedule(t, gaps, 1.0, 20)
    assert [s.closed for s in stances] == [(0, 1), (0,), (), (1,)]
    assert stances[3].start > 0.2


def test_bad_schedules_are_refused():
    p = problem([0.0, 0.0, 1.0, 0.0], [0.0] * 4, horizon=0.4, n_intervals=4,
                u_lower=[0.0] * 4, u_upper=[0.0] * 4, running=lambda tf: ca.DM(0.0))
    guess = (np.array([0.0, 0.4]), np.zeros((2, 8)), np.zeros((4, 4)))
    with pytest.raises(InvalidInput, match="control jump"):
        resolve_stances(p, (Stance((0, 1), 0.0, 0.15), Stance((0,), 0.15, 0.4)),
                        guess=guess, verbose=False)
    with pytest.raises(InvalidInput, match="either close contacts .a touchdown. or open them"):
        resolve_stances(p, (Stance((0,), 0.0, 0.15), Stance((1,), 0.15, 0.4)),
                        guess=guess, verbose=False)
    with pytest.raises(InvalidInput, match="statically indeterminate"):
        twin = two_masses()  # both contacts on mass 1: the same rows twice
        q, v, u = twin.q, twin.v, twin.u
        same = ComplementarityLagrangianSystem(
            q=q, v=v, u=u, mass_matrix=twin.mass_matrix, forces=twin.forces,
            contacts=tuple(Contact(gap=q[1], tangents=ca.jacobian(q[0], q).T, mu=MU,
                                   name=f"c{i}") for i in range(2)))
        tf = time_freeze(same)
        resolve_stances(ContactProblem(system=tf, q0=[0.0] * 4, v0=[0.0] * 4, horizon=0.4,
                                       n_intervals=4, u_lower=[0.0] * 4, u_upper=[0.0] * 4,
                                       running_cost=ca.DM(0.0)),
                        (Stance((0, 1), 0.0, 0.4),), guess=guess, verbose=False)
    with pytest.raises(InvalidInput, match="cone_margin"):
        StanceOptions(cone_margin=1.5)
    with pytest.raises(InvalidInput, match="inverse_dynamics.*radau"):
        StanceOptions(integrator="rk4", inverse_dynamics=True)
    with pytest.raises(InvalidInput, match="inverse_dynamics"):
        StanceOptions(inverse_dynamics=None)


def spatial_mass() -> ComplementarityLagrangianSystem:
    """A point mass on the ground with 3-D friction: q = (x, y, z), u = force on it."""
    q, v, u = ca.SX.sym("q", 3), ca.SX.sym("v", 3), ca.SX.sym("u", 3)
    m = MASSES[0]
    contact = Contact(gap=q[2], tangents=ca.jacobian(q[:2], q).T, mu=MU, name="foot")
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=m * ca.DM.eye(3), forces=u - ca.DM([0.0, 0.0, m * G]),
        contacts=(contact,))


def pushed_spatial_mass(options: StanceOptions, u_lower, u_upper, target):
    """The mass standing throughout, its force driven towards `target` (the cost
    ||u - target||^2): the stance's rows decide how far it gets."""
    tf = time_freeze(spatial_mass())
    p = ContactProblem(system=tf, q0=[0.0] * 3, v0=[0.0] * 3, horizon=0.2, n_intervals=2,
                       u_lower=u_lower, u_upper=u_upper,
                       running_cost=ca.sumsqr(tf.u - ca.DM(target)))
    guess = (np.array([0.0, 0.2]), np.zeros((2, 6)), np.zeros((2, 3)))
    plan = resolve_stances(p, (Stance((0,), 0.0, 0.2),), options, guess=guess, verbose=False)
    assert plan.solved, plan.ipopt_status
    np.testing.assert_allclose(plan.x[:, :3], 0.0, atol=1e-7)  # it stuck
    return plan


@pytest.mark.parametrize("facets", [None, 4, 8])
def test_a_3d_stick_force_ends_at_the_circle_or_the_inscribed_pyramid(facets):
    """Pushed along x as hard as it can while it sticks: the push reaches c mu m g on the
    circular cone, and c mu cos(pi / n) m g on the inscribed pyramid of n facets (a
    facet's normal along x); pushed diagonally, a 4-facet pyramid's vertex direction,
    c mu m g (|u| along the diagonal) again."""
    margin, weight = 0.95, MASSES[0] * G
    inner = 1.0 if facets is None else np.cos(np.pi / facets)
    options = StanceOptions(cone_margin=margin, cone_facets=facets, tol=1e-10)
    plan = pushed_spatial_mass(options, [-20.0, 0.0, 0.0], [20.0, 0.0, 0.0],
                               [20.0, 0.0, 0.0])
    np.testing.assert_allclose(plan.u[:, 0], margin * MU * inner * weight, rtol=1e-6)
    assert plan.verification.passed, plan.verification.summary()
    if facets == 4:
        plan = pushed_spatial_mass(options, [-20.0, -20.0, 0.0], [20.0, 20.0, 0.0],
                                   [20.0, 20.0, 0.0])
        np.testing.assert_allclose(np.hypot(plan.u[:, 0], plan.u[:, 1]),
                                   margin * MU * weight, rtol=1e-6)


def test_a_stance_keeps_its_minimal_normal_force():
    """Pulled up as hard as it can while it stands: lambda_n = m g - u_z reaches
    `min_normal_force`. Without it, 0: the foot on the floor of its cone (here IPOPT's
    round-off, lambda_n about -1e-8 N, failed the verification's cone check)."""
    weight = MASSES[0] * G
    for floor in (0.0, 2.0):
        plan = pushed_spatial_mass(StanceOptions(min_normal_force=floor, tol=1e-10),
                                   [0.0, 0.0, 0.0], [0.0, 0.0, 40.0], [0.0, 0.0, 40.0])
        np.testing.assert_allclose(plan.u[:, 2], weight - floor, rtol=1e-6, atol=1e-6)
        if floor > 0:
            assert plan.verification.passed, plan.verification.summary()


def test_a_touchdown_approaches_at_least_at_its_touchdown_speed():
    """Mass 1 lowered from 0.1 m with its vertical force, the cost the integral of v_z^2:
    it creeps down and lands slower than 1 m/s. With `touchdown_speed` 1 m/s its approach
    at the touchdown node is exactly that (the row binds), and the reference agrees."""
    h = 0.1
    p = problem([0.0, h, 1.0, 0.0], [0.0] * 4, horizon=0.4, n_intervals=4,
                u_lower=[0.0] * 4, u_upper=[0.0, 40.0, 0.0, 0.0],
                running=lambda tf: tf.y[tf.v_index][1] ** 2)
    t = np.linspace(0.0, 0.4, 41)
    x = np.zeros((len(t), 8))
    x[:, 1] = np.maximum(h * (1 - t / 0.25), 0.0)
    x[:, 2] = 1.0
    x[:, 5] = np.where(t < 0.25, -h / 0.25, 0.0)
    stances = (Stance((1,), 0.0, 0.25), Stance((0, 1), 0.25, 0.4))
    speeds = {}
    for speed in (None, 1.0):
        plan = resolve_stances(p, stances, StanceOptions(touchdown_speed=speed, tol=1e-10),
                               guess=(t, x, np.zeros((4, 4))), verbose=False)
        assert plan.solved, plan.ipopt_status
        touchdown = int(np.flatnonzero(np.diff(plan.t) == 0)[0])  # pre-impact node
        speeds[speed] = -plan.x[touchdown, 5]
        assert plan.verification.passed, plan.verification.summary()
    assert 0 < speeds[None] < 0.9
    assert speeds[1.0] == pytest.approx(1.0, rel=1e-6)
    with pytest.raises(InvalidInput, match="touchdown_speed"):
        StanceOptions(touchdown_speed=-0.1)


def test_interior_weights_interpolate_the_collocation_polynomial():
    """A polynomial of degree s through (0, c_1, ..., c_s) is reproduced exactly at the
    interior points, `count` equally spaced between consecutive ones."""
    c = np.array([0.155051025721682, 0.644948974278318, 1.0])  # Radau IIA, s = 3
    weights = interior_weights(c, 2)
    nodes = np.concatenate([[0.0], c])
    points = np.concatenate([np.linspace(a, b, 4)[1:3] for a, b in zip(nodes[:-1], nodes[1:],
                                                                strict=True)])
    assert weights.shape == (6, 4)
    for coefficients in ([1.0, 0, 0, 0], [0.3, -2.0, 0.5, 4.0]):
        values = np.polyval(coefficients, nodes)
        np.testing.assert_allclose(weights @ values, np.polyval(coefficients, points),
                                   atol=1e-12)


def block_with_pendulum(mass=1.0, bob=1.0, length=0.1, mu=0.5):
    """A block on the ground (q = x, z) with a pendulum (angle q_3 from hanging down, a
    point bob on a massless rod) swinging from its centre; u pushes the block along x. The
    pendulum's swing loads the block's contact: its forces vary within an element."""
    q, v, u = ca.SX.sym("q", 3), ca.SX.sym("v", 3), ca.SX.sym("u", 1)
    angle, rate = q[2], v[2]
    coupling = bob * length * ca.vertcat(ca.cos(angle), ca.sin(angle))
    mass_matrix = ca.vertcat(
        ca.horzcat(mass + bob, 0, coupling[0]), ca.horzcat(0, mass + bob, coupling[1]),
        ca.horzcat(coupling[0], coupling[1], bob * length**2))
    forces = ca.vertcat(u[0] + coupling[1] * rate**2,
                        -(mass + bob) * G - coupling[0] * rate**2,
                        -bob * G * length * ca.sin(angle))
    contact = Contact(gap=q[1], tangents=ca.jacobian(q[0], q).T, mu=mu, name="block")
    return ComplementarityLagrangianSystem(q=q, v=v, u=u, mass_matrix=mass_matrix,
                                           forces=forces, contacts=(contact,))


def test_interior_rows_keep_the_stick_force_in_its_cone_between_collocation_points():
    """The block pushed as hard as it can while it sticks, the pendulum swinging from
    1 rad, two control intervals of two Radau elements: the rows at the collocation
    points alone let the true stance's friction force (integrated finely from each
    interval's start) leave the cone c mu lambda_n between them by more than 5 %, and the
    reference slips the block; with 3 interior points per gap it stays within 0.5 %,
    and the reference's block sticks."""
    cls = block_with_pendulum()
    tf = time_freeze(cls)
    horizon, margin, mu = 0.4, StanceOptions.cone_margin, cls.contacts[0].mu
    p = ContactProblem(system=tf, q0=[0.0, 0.0, 1.0], v0=[0.0] * 3, horizon=horizon,
                       n_intervals=2, u_lower=[-20.0], u_upper=[20.0],
                       running_cost=(tf.u[0] - 20.0) ** 2)
    t = np.linspace(0.0, horizon, 41)
    x = np.zeros((len(t), 6))
    x[:, 2] = np.cos(10 * t)
    dyn = StanceDynamics(cls)
    excess, slipped = {}, {}
    for count in (0, 3):
        plan = resolve_stances(p, (Stance((0,), 0.0, horizon),),
                               StanceOptions(nodes=2, tol=1e-10, interior_rows=count),
                               guess=(t, x, np.zeros((2, 1))), verbose=False)
        assert plan.solved, plan.ipopt_status
        worst = -np.inf
        for k in range(2):
            def rhs(_, state, u_k=plan.u[k]):
                return np.asarray(dyn.rhs((0,))(state, u_k)).ravel()
            with np.errstate(under="ignore"):
                sol = solve_ivp(rhs, (0.0, horizon / 2), plan.boundary_states[k],
                                rtol=1e-11, atol=1e-12, dense_output=True)
            for s in np.linspace(0.0, horizon / 2, 201):
                lam = np.asarray(dyn.force((0,))(sol.sol(s), plan.u[k])).ravel()
                worst = max(worst, abs(lam[1]) / (margin * mu * lam[0]) - 1.0)
        excess[count] = worst
        reference = replay_multicontact(cls, plan.boundary_states[0], np.array([0.0, 0.2,
                                                                                 0.4]),
                                        plan.u, horizon)
        assert reference.success, reference.message
        slipped[count] = any(e.kind == EventKind.SLIP for e in reference.events)
    assert excess[0] > 0.05 and slipped[0]
    assert excess[3] < 0.005 and not slipped[3]
    with pytest.raises(InvalidInput, match="interior_rows"):
        StanceOptions(interior_rows=1, integrator="rk4")


def test_cone_rows_of_a_pyramid_and_a_floor():
    # (lambda_n, lambda_t1, lambda_t2) = (2, 1, 0), mu 0.5: on the circle's edge, outside
    # the 4-facet pyramid (inner radius mu cos(pi/4) lambda_n = 0.707)
    rows = [float(r) for r in cone_rows([2.0, 1.0, 0.0], [3], [0.5], (0,), 1.0, facets=4)]
    inner = np.cos(np.pi / 4)
    np.testing.assert_allclose(rows, [inner - 1.0, inner, inner + 1.0, inner])
    # the pyramid implies lambda_n >= 0: no row for it unless a floor asks for one
    rows = cone_rows([2.0, 0.0, 0.0], [3], [0.5], (0,), 1.0, facets=4, floor=0.5)
    assert [float(r) for r in rows][0] == 1.5 and len(rows) == 5
    assert len(cone_rows([2.0, 1.0], [2], [0.5], (0,), 1.0, floor=0.5)) == 3
    for bad in ({"cone_facets": 3}, {"cone_facets": 6.0}, {"min_normal_force": -1.0},
                {"min_normal_force": True}, {"contact_tolerance": 0.0}):
        with pytest.raises(InvalidInput, match=next(iter(bad))):
            StanceOptions(**bad)


@pytest.mark.parametrize("gain", [100.0, 1.0])
def test_an_open_contact_with_a_slip_gain_flies_within_it_and_lands_at_its_speed(gain):
    """`open_slip_gains`: where mass 1 is open, v_x^2 <= K z at every node but its
    touchdown's own (there z = 0 would force v_x = 0 through a row whose gradient in v_x
    vanishes); the inelastic impact then stops it in the cone. Dropped from 0.25 m at
    0.5 m/s: with K = 100 the rows never bind and the closed form is free flight, no force
    and the landing at 0.5 m/s; with K = 1 they bind from the start (0.5^2 = K z) and the
    control brakes it, not to rest."""
    h, speed = 0.25, 0.5
    p = problem([0.0, h, 1.0, 0.0], [speed, 0.0, 0.0, 0.0], horizon=0.4, n_intervals=4,
                u_lower=[-20.0, 0.0, 0.0, 0.0], u_upper=[20.0, 0.0, 0.0, 0.0],
                running=lambda tf: 1e-3 * tf.u[0] ** 2)
    t1 = np.sqrt(2 * h / G)  # 0.226 s: the vertical motion has no control
    t = np.linspace(0.0, 0.4, 81)
    x = np.zeros((len(t), 8))
    x[:, 0] = speed * np.minimum(t, t1)
    x[:, 1] = np.maximum(h - G * t**2 / 2, 0.0)
    x[:, 2] = 1.0
    stances = (Stance((1,), 0.0, t1), Stance((0, 1), t1, 0.4))
    plan = resolve_stances(p, stances, StanceOptions(open_slip_gains=(gain, None), tol=1e-10),
                           guess=(t, x, np.zeros((4, 4))), verbose=False)
    assert plan.solved, plan.ipopt_status
    assert plan.stances[1].start == pytest.approx(t1, abs=1e-7)
    before = np.flatnonzero(plan.t <= plan.stances[1].start)[-2]  # the pre-impact node
    assert plan.t[before] == pytest.approx(t1, abs=1e-7)
    flying = plan.t < t1 - 1e-9
    # to IPOPT's constraint accuracy (a binding row ends about 1e-8 outside)
    assert np.all(plan.x[flying, 4] ** 2 <= gain * plan.x[flying, 1] + 1e-7)
    landing_speed = plan.x[before, 4]
    if gain == 100.0:
        assert np.abs(plan.u[:, 0]).max() < 1e-6
        assert landing_speed == pytest.approx(speed, abs=1e-7)
        assert plan.x[before, 0] == pytest.approx(speed * t1, abs=1e-7)
    else:
        assert 0.05 < landing_speed < np.sqrt(gain * plan.x[before - 1, 1])
    assert np.abs(plan.x[before + 1:, 4:]).max() < 1e-6  # at rest after the impact
    assert plan.verification.passed, plan.verification.summary()


def lifting_mass(force: float):
    """Mass 2 rests, lifts off at the control jump 0.2 s and is open to T = 0.4 s, lifted
    by at most `force` [N] at the least squared force; the guess rises 0.5 m/s from 0.2 s
    (0.1 m at T): the problem, its stances and the guess."""
    p = problem([0.0, 0.0, 1.0, 0.0], [0.0] * 4, horizon=0.4, n_intervals=4,
                u_lower=[0.0, 0.0, 0.0, 0.0], u_upper=[0.0, 0.0, 0.0, force],
                running=lambda tf: 1e-2 * tf.u[3] ** 2)
    t = np.linspace(0.0, 0.4, 41)
    x = np.zeros((len(t), 8))
    x[:, 2] = 1.0
    x[:, 3] = np.where(t > 0.2, 0.5 * (t - 0.2), 0.0)
    return p, (Stance((0, 1), 0.0, 0.2), Stance((0,), 0.2, 0.4)), (t, x, np.zeros((4, 4)))


@pytest.mark.parametrize("height", [None, 0.05, 0.5])
def test_a_swing_keeps_the_height_its_guess_reached(height):
    """`swing_heights`: mass 2 rests, lifts off at the control jump 0.2 s and is open to T;
    the cost asks for the least vertical force, so without a row it barely leaves the
    ground (measured: 1.3 cm, back to the ground at T). The guess rises to 0.1 m: with
    h = 0.05 the node where the guess is highest keeps gap >= h; h = 0.5 lies above the
    guess's swing, so no row is added and the plan is the one without rows."""
    p, stances, guess = lifting_mass(40.0)
    t, x, _ = guess
    plan = resolve_stances(p, stances, StanceOptions(tol=1e-10, swing_heights=(None, height)),
                           guess=guess, verbose=False)
    assert plan.solved, plan.ipopt_status
    swing = (plan.t > 0.2) & (plan.t < 0.4)
    guess_highest = np.argmax(np.interp(plan.t[swing], t, x[:, 3]))
    if height == 0.05:
        assert plan.x[swing, 3][guess_highest] >= height - 1e-7
        assert plan.verification.passed, plan.verification.summary()
    else:
        # (this plan falls back to the ground at T, where the reference's impact stops it:
        # its replay then ends 0.39 away, so its verification is not asserted)
        assert plan.x[:, 3].max() < 0.02


@pytest.mark.parametrize("middle", [True, False])
def test_a_swing_the_guess_does_not_lift_gets_its_row_at_its_middle(middle):
    """`swing_middle`: the swing of the test above from a guess resting on the ground
    throughout (a given sequence's guess lifts no foot). With it, the node nearest the
    swing's middle (0.3 s, an element boundary) keeps gap >= 0.05; without it no row is
    added and the mass barely leaves the ground."""
    p, stances, (t, x, u) = lifting_mass(40.0)
    x = x.copy()
    x[:, 3] = 0.0
    options = StanceOptions(tol=1e-10, swing_heights=(None, 0.05), swing_middle=middle)
    plan = resolve_stances(p, stances, options, guess=(t, x, u), verbose=False)
    assert plan.solved, plan.ipopt_status
    at_middle = np.argmin(np.abs(plan.t - 0.3))
    assert plan.t[at_middle] == pytest.approx(0.3, abs=1e-12)
    if middle:
        assert plan.x[at_middle, 3] >= 0.05 - 1e-7
    else:
        assert plan.x[:, 3].max() < 0.02


@pytest.mark.parametrize("fallback", [True, False])
def test_an_unreachable_swing_height_is_dropped_when_it_makes_the_nlp_infeasible(fallback):
    """The swing of the test above with the lifting force capped at 22 N (mass 2 kg: at
    most 1.19 m/s^2 up, 2.4 cm in the 0.2 s of the swing): the guess rises to 0.1 m, but
    the mass cannot reach 5 cm, so the row makes the NLP infeasible (IPOPT says so). With
    `swing_fallback` the NLP is solved again without the row: solved, the row's dropping
    recorded, the iterations of both solves counted, the mass below 5 cm."""
    p, stances, guess = lifting_mass(22.0)
    options = StanceOptions(tol=1e-10, swing_heights=(None, 0.05), swing_fallback=fallback)
    plan = resolve_stances(p, stances, options, guess=guess, verbose=False)
    if not fallback:
        assert plan.ipopt_status == "Infeasible_Problem_Detected"
        assert not plan.swing_rows_dropped
        return
    assert plan.solved and plan.swing_rows_dropped, plan.ipopt_status
    assert "swing-height rows made the NLP infeasible" in plan.summary()
    without = resolve_stances(p, stances, StanceOptions(tol=1e-10), guess=guess,
                              verbose=False)
    assert plan.iterations > without.iterations
    np.testing.assert_allclose(plan.x, without.x, atol=1e-9)
    assert plan.x[:, 3].max() < 0.05


def test_swings_run_from_a_lift_off_or_the_start_to_the_next_touchdown_or_the_end():
    walk = (Stance((0, 1), 0.0, 0.1), Stance((1,), 0.1, 0.2), Stance((0, 1), 0.2, 0.3),
            Stance((1,), 0.3, 0.4))
    assert swings(walk, 0, 0.4) == [(0.1, 0.2), (0.3, 0.4)]
    assert swings(walk, 1, 0.4) == []
    assert swings((Stance((1,), 0.0, 0.1), Stance((0, 1), 0.1, 0.4)), 0, 0.4) == [(0.0, 0.1)]


@pytest.mark.parametrize("heights", [(0.0, None), (-1.0,), (float("inf"),), (True,), [0.1]])
def test_swing_heights_must_be_positive_and_finite(heights):
    with pytest.raises(InvalidInput, match="swing_heights"):
        StanceOptions(swing_heights=heights)
    with pytest.raises(InvalidInput, match="`swing_fallback` must be True or False"):
        StanceOptions(swing_fallback=1)


def test_slip_gains_must_be_positive():
    with pytest.raises(InvalidInput, match="open_slip_gains"):
        StanceOptions(open_slip_gains=(0.0, None))


def test_a_standing_foots_velocity_error_does_not_fail_the_restart():
    """A restart of bolt's verified stance walk (benchmarks/legged.md) at 0.35 s: its left
    foot stands 1.4e-8 m deep with a normal velocity of 1.4e-7 m/s, the plan's accuracy.
    With the simulator's default velocity tolerance (1e-7) it flies and lands back until
    the event cap; with `RESTART_VELOCITY_TOLERANCE` it stands and ends 50 ms later where
    the plan does."""
    from tfcontact.ocp.stances import RESTART_VELOCITY_TOLERANCE
    from tfcontact.task import build_task, load_task, shipped_tasks
    from tfcontact.verify import MultiContactOptions, SimulationStatus, replay_multicontact

    cls = build_task(load_task(shipped_tasks()["biped-walk"])).problem.system.cls
    start = np.array([
        0.040232284935378955, 0.34076739975426895, -0.012798234077715916, 1.0524788741531754,
        -1.431129565631981, 1.275035693272087, -2.2284529258922, 0.34218457439851896,
        -0.2524425650221332, 0.060465069366371915, 1.7725718825263246, -0.9991285567734645,
        12.56058724049405, 13.019686901096765])
    control = np.array([[1.0926085044145883, 2.2543720114314953, -1.1236429591718322,
                         -0.35540917575085657]])
    plan_end = np.array([
        0.059922561757496086, 0.33529031769956424, -0.007563647978981324, 1.1074435010788344,
        -1.4182271451073354, 1.3824112519641343, -2.067794110661475, 0.4646265923355478,
        0.03233763632477731, 0.11904203599979526, 0.4541632891913378, 1.5748182185320159,
        -7.446164325022457, -7.094219741225259])
    clocks = np.array([0.0, 0.05])
    default = replay_multicontact(cls, start, clocks, control, 0.05,
                                  options=MultiContactOptions(start_gap_tolerance=1e-3))
    assert default.status == SimulationStatus.MAX_EVENTS
    restart = replay_multicontact(cls, start, clocks, control, 0.05, options=MultiContactOptions(
        start_gap_tolerance=1e-3, velocity_tolerance=RESTART_VELOCITY_TOLERANCE))
    assert restart.success, restart.message
    assert np.max(np.abs(restart.final_state() - plan_end)) < 1e-5


def test_the_lifted_rows_vanish_at_the_explicit_acceleration_and_forces():
    """`StanceDynamics.inverse` (M a = f + J lambda, J^T a + drift = -stab) is zero at the
    explicit form's a(x, u) and lambda(x, u) for every stance, on a system with a coupled,
    configuration-dependent mass matrix and curved gaps (drift terms), and not zero for
    another acceleration. `StanceDynamics.lifted` (a = M^-1 (f + J lambda)) gives the
    explicit form's slope and zero rows at its forces (the explicit form solves with the
    Delassus matrix instead), and nonzero rows at other forces."""
    from tfcontact.ocp.stances import StanceDynamics

    rng = np.random.default_rng(3)
    q, v, u = ca.SX.sym("q", 4), ca.SX.sym("v", 4), ca.SX.sym("u", 4)
    root = rng.standard_normal((4, 4))
    mass = ca.DM(root @ root.T + 4 * np.eye(4)) * (1 + 0.1 * ca.sin(q[0]))
    contacts = tuple(
        Contact(gap=q[2 * i + 1] + 0.1 * ca.sin(q[2 * i]) ** 2,
                tangents=ca.jacobian(q[2 * i], q).T, mu=MU, name=f"m{i}")
        for i in range(2))
    cls = ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=mass, forces=u - ca.vertcat(0, G, 0, G) + 0.3 * v,
        contacts=contacts)
    dyn = StanceDynamics(cls)
    for closed in [(), (0,), (1,), (0, 1)]:
        for _ in range(3):
            x, control = rng.standard_normal(8), rng.standard_normal(4)
            a = np.asarray(dyn.acceleration(closed)(x, control)).ravel()
            lam = (np.asarray(dyn.force(closed)(x, control)).ravel() if closed
                   else np.zeros(0))
            rows = np.asarray(dyn.inverse(closed)(x, control, a, lam)).ravel()
            assert rows.shape == (4 + 2 * len(closed),)
            np.testing.assert_allclose(rows, 0.0, atol=1e-10)
            other = np.asarray(dyn.inverse(closed)(x, control, a + 0.01, lam)).ravel()
            assert np.max(np.abs(other)) > 1e-3
            if closed:
                slope, held = (np.asarray(out).ravel()
                               for out in dyn.lifted(closed)(x, control, lam))
                np.testing.assert_allclose(slope, np.concatenate([x[4:], a]), atol=1e-10)
                np.testing.assert_allclose(held, 0.0, atol=1e-10)
                held = np.asarray(dyn.lifted(closed)(x, control, lam + 0.01)[1]).ravel()
                assert np.max(np.abs(held)) > 1e-3


@pytest.mark.slow
def test_bolt_steps_once_per_foot_along_the_stances_of_a_saved_discovery():
    """The stance re-solve on a robot of example-robot-data: bolt's walk (the shipped
    `biped-walk` problem; the re-solve keeps neither its path rows nor its period) along
    the stances of a saved time-freezing discovery of one step per foot (its relaxed plan,
    residual 1e-4, at the 61 samples). The exact plan converges and passes the
    multi-contact reference; each foot lifts off once and lands."""
    import dataclasses
    from pathlib import Path

    from tfcontact.task import build_task, load_task, shipped_tasks

    task = load_task(shipped_tasks()["biped-walk"])
    problem = dataclasses.replace(build_task(task).problem, path=None)
    cls = problem.system.cls
    saved = np.load(Path(__file__).parent / "data" / "bolt_one_step_discovery.npz")
    t, x, u = saved["t"], saved["x"], saved["u"]
    gaps = np.asarray(cls.function("gaps")(x[:, :cls.n_q].T)).T
    stances = stance_schedule(t, gaps, problem.horizon, problem.n_intervals)
    # both down, the left foot lifts, both in flight, the right lands, both, the left
    # lifts again: the discovery's sampled order
    assert [s.closed for s in stances] == [(0, 1), (1,), (), (0,), (0, 1), (1,)]
    gains = tuple(c.no_slip_gain for c in task.contacts)
    plan = resolve_stances(problem, stances, StanceOptions(open_slip_gains=gains),
                           guess=(t, x, u), verbose=False)
    assert plan.solved, plan.ipopt_status
    # 113 iterations measured; 562 while an open foot's rows stayed at its own touchdown
    # node, where they force v_t = 0 with a vanishing gradient (benchmarks/legged.md)
    assert plan.iterations < 300
    assert plan.verification.passed, plan.verification.summary()
    assert plan.x[-1, 0] == pytest.approx(0.5, abs=0.05)  # the base's x at T


def test_a_first_stance_whose_contacts_start_off_the_ground_is_refused():
    """The first stance's contacts stick from t = 0: a start with one of them in the air
    (here 0.1 m up) is refused, naming the contact, its gap and the fix."""
    p, stances, guess = lifting_mass(40.0)
    lifted = dataclasses.replace(p, q0=np.array([0.0, 0.0, 1.0, 0.1]))
    with pytest.raises(InvalidInput, match=r"closes contacts \[1\], but the start has them "
                                           r"0.1 m from the ground"):
        resolve_stances(lifted, stances, guess=guess, verbose=False)


def test_an_nlp_stopped_by_a_step_error_is_solved_again_from_its_iterate(monkeypatch,
                                                                         capsys):
    """`step_error_restarts`: IPOPT's Error_In_Step_Computation (stood in for here: the
    first solve, capped at 4 iterations, is reported so) is followed by solves from that
    iterate (then capped restarts), which reach the closed forms; without a restart the
    plan fails honestly."""
    import tfcontact.ocp.stances as stances_module

    class Stopped:  # a solution whose status is IPOPT's step error
        def __init__(self, sol):
            self.sol = sol

        def stats(self):
            return {**self.sol.stats(), "return_status": "Error_In_Step_Computation"}

        def __getattr__(self, name):
            return getattr(self.sol, name)

    real = stances_module.solve_timed
    calls = []

    def first_stopped(opti, threads):
        sol, *times = real(opti, threads)
        calls.append(sol.stats()["iter_count"])
        return (Stopped(sol) if len(calls) == 1 else sol, *times)

    monkeypatch.setattr(stances_module, "solve_timed", first_stopped)
    p, stances, guess, (t1, t2) = two_drops()
    options = StanceOptions(tol=1e-10, max_iter=4, capped_restarts=5)
    plan = resolve_stances(p, stances, options, guess=guess, verbose=True)
    assert len(calls) >= 2 and plan.solved, plan.ipopt_status
    out = capsys.readouterr().out
    assert "stances: IPOPT stopped (Error_In_Step_Computation); solving again from its " \
        "iterate (0 more such restarts allowed)" in out
    assert out.count("    IPOPT started (") == len(calls)  # each solve says so
    assert plan.stances[2].start == pytest.approx(t2, abs=1e-7)
    calls.clear()
    failed = resolve_stances(p, stances, dataclasses.replace(options, step_error_restarts=0),
                             guess=guess, verbose=False)
    assert len(calls) == 1 and failed.ipopt_status == "Error_In_Step_Computation"
    assert not failed.success and failed.status == "nlp_failed"


@pytest.mark.parametrize("rows", [True, False])
def test_an_end_height_goal_is_kept_as_a_terminal_row(rows):
    """`end_height_rows`: the lifting mass (above) asked to end at 5 cm (tolerance 2 cm)
    by an `EndHeight` goal. With the row, the least-force plan ends on the row's lower
    bound, 4 cm (half the tolerance below: the active row, the cost pulling it down);
    without it the mass barely leaves the ground (the goal then missed)."""
    from tfcontact.ocp.goals import EndHeight

    p, stances, guess = lifting_mass(40.0)
    q = ca.SX.sym("q", 4)
    goal = EndHeight(1, 0.05, 0.02, ca.Function("z_low", [q], [q[3]]))
    p = dataclasses.replace(p, goals=(goal,))
    plan = resolve_stances(p, stances, StanceOptions(tol=1e-10, end_height_rows=rows),
                           guess=guess, verbose=False)
    assert plan.solved, plan.ipopt_status
    if rows:
        assert plan.x[-1, 3] == pytest.approx(0.04, abs=1e-6)
        assert plan.verification.passed, plan.verification.summary()
    else:
        assert plan.x[:, 3].max() < 0.02
    with pytest.raises(InvalidInput, match="end_height_rows"):
        StanceOptions(end_height_rows=1)
