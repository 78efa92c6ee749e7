"""The exact re-solve along a contact sequence (tfcontact.ocp.polish): its hybrid dynamics
and touchdown rows against closed forms and the reference's impulse flow, and the saved
TF-9 plan against the exact replay. Its solves run in tests/test_monoped_exact.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.ocp import polish
from tfcontact.plan_format.resolved import load_resolved_plan
from tfcontact.scenes.monoped_exact import verify_saved
from tfcontact.scenes.particles import G, painleve_rod, point_mass
from tfcontact.verify import planar_impulse_flow

SAVED_PLAN = Path(__file__).resolve().parents[1] / "benchmarks" / "monoped_exact_plan.npz"
RK4_PLAN = SAVED_PLAN.with_name("monoped_exact_rk4_plan.npz")  # the Radau levels' start
SEARCH_PLAN = SAVED_PLAN.with_name("monoped_search_plan.npz")  # `tfcontact plan monoped`


def test_stick_holds_a_pushed_particle_with_the_opposing_friction():
    """A unit particle on the ground pushed sideways by F < mu m g: no acceleration,
    lambda_n = m g, lambda_t = -F; in flight it falls with g and is pushed with F."""
    dyn = polish.HybridDynamics(point_mass(2, mu=0.5, controlled=True))
    x = np.array([0.3, 0.0, 0.0, 0.0])
    u = np.array([2.0, 0.0])
    np.testing.assert_allclose(np.asarray(dyn.rhs["stick"](x, u)).ravel(), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dyn.force(x, u)).ravel(), [G, -2.0], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(dyn.rhs[polish.FLIGHT](x, u)).ravel()[2:], [2.0, -G],
                               rtol=1e-12)


@pytest.mark.parametrize(("mode", "sign"), [("slip+", 1.0), ("slip-", -1.0)])
def test_slip_decelerates_a_sliding_particle_by_mu_g(mode, sign):
    """A particle of mass 3 sliding on the ground at v_x = s: lambda_n = m g, a_x = -s mu g,
    no normal acceleration; the rate W_nn - s mu W_nt is 1/m (W_nt = 0)."""
    dyn = polish.HybridDynamics(point_mass(2, mu=0.4, mass=3.0))
    x = np.array([0.0, 0.0, sign, 0.0])
    a = np.asarray(dyn.rhs[mode](x, np.zeros(0))).ravel()
    np.testing.assert_allclose(a, [sign, 0.0, -sign * 0.4 * G, 0.0], atol=1e-12)
    lam_n, rate = (float(v) for v in dyn.slip_force[mode](x, np.zeros(0)))
    assert lam_n == pytest.approx(3.0 * G, rel=1e-12)
    assert rate == pytest.approx(1 / 3.0, rel=1e-12)


def test_baumgarte_pulls_a_drifted_contact_back():
    """Off the contact (gap h, closing at v_n), the stick rows give the normal acceleration
    -(2 alpha v_n + alpha^2 h): the drift decays instead of staying."""
    dyn = polish.HybridDynamics(point_mass(2, mu=0.5), alpha=20.0)
    x = np.array([0.0, 1e-4, 0.0, -2e-3])
    a_z = float(np.asarray(dyn.rhs[polish.STICK](x, np.zeros(0))).ravel()[3])
    assert a_z == pytest.approx(-(2 * 20.0 * -2e-3 + 20.0**2 * 1e-4), rel=1e-12)


def test_stick_pins_the_rods_end_like_a_pendulum_pivot():
    """Painleve's rod with its lower end stuck is a pendulum about that end:
    theta'' = -(3 g / 2 L) cos(theta) whatever omega; the centre's acceleration follows
    from the pinned end."""
    length = 1.0
    dyn = polish.HybridDynamics(painleve_rod(mu=0.5, length=length))
    theta, omega = 0.7, 1.3
    q = np.array([0.2 + length / 2 * np.cos(theta), length / 2 * np.sin(theta), theta])
    v = np.array([-length / 2 * np.sin(theta) * omega, length / 2 * np.cos(theta) * omega,
                  omega])
    a = np.asarray(dyn.rhs[polish.STICK](np.concatenate([q, v]), np.zeros(0))).ravel()[3:]
    alpha = -3 * G / (2 * length) * np.cos(theta)
    np.testing.assert_allclose(a[2], alpha, rtol=1e-12)
    np.testing.assert_allclose(
        a[:2], length / 2 * np.array([-np.sin(theta) * alpha - np.cos(theta) * omega**2,
                                      np.cos(theta) * alpha - np.sin(theta) * omega**2]),
        rtol=1e-12)


def _collocate(rhs, tableau, x0, u, span, n_elements):
    """Integrate by solving one element's collocation equations after the other."""
    import casadi as ca

    n, s = x0.size, tableau.stages
    unknown, x_sym = ca.SX.sym("z", n * s), ca.SX.sym("x", n)
    stages = [unknown[j * n:(j + 1) * n] for j in range(s)]
    h = span / n_elements
    residual = ca.vertcat(*polish.collocation_residuals(rhs, tableau, x_sym, stages, u, h))
    solve = ca.rootfinder("element", "newton", ca.Function("r", [unknown, x_sym], [residual]),
                          {"abstol": 1e-13})
    x = np.asarray(x0, dtype=float)
    for _ in range(n_elements):
        z = np.asarray(solve(np.tile(x, s), x)).ravel()
        x = z[-n:]  # Radau IIA: the last stage is the element's end
    return x


def test_radau_elements_of_the_stuck_rod_converge_with_order_five():
    """Radau IIA with 3 stages (TF-9's scheme, `integrator="radau"`) on the rod pinned at
    its end (a pendulum): halving the elements divides the end error by about 2^5."""
    from tfcontact.fesd.tableau import RadauIIA

    length, theta, span = 1.0, 0.7, 0.4
    dyn = polish.HybridDynamics(painleve_rod(mu=0.5, length=length))
    x0 = np.array([0.2 + length / 2 * np.cos(theta), length / 2 * np.sin(theta), theta,
                   0.0, 0.0, 0.0])
    rhs = dyn.rhs[polish.STICK]
    exact = x0  # 2000 RK4 steps: error about 1e-14
    for _ in range(2000):
        exact = np.asarray(dyn.step(polish.STICK, exact, np.zeros(0), span / 2000)).ravel()
    tableau = RadauIIA(3).tableau()
    errors = [np.abs(_collocate(rhs, tableau, x0, np.zeros(0), span, n) - exact).max()
              for n in (4, 8, 16)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 1e-5  # measured 1.6e-6 with 16 elements
    assert np.all(orders > 4.5), (errors, orders)


def test_sticking_impact_stops_the_contact_point():
    """A particle of mass 3 landing with v = (1, -2) m/s: the sticking impact stops it,
    impulse (6, -3) N s."""
    dyn = polish.HybridDynamics(point_mass(2, mu=0.8, mass=3.0))
    post, impulse = dyn.impact(np.array([0.5, 0.0, 1.0, -2.0]))
    np.testing.assert_allclose(np.asarray(post).ravel(), [0.5, 0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.asarray(impulse).ravel(), [6.0, -3.0], rtol=1e-12)


def test_touchdown_rows_hold_exactly_when_the_impulse_flow_ends_in_stick():
    """Random Delassus matrices and landing velocities: outside the Painleve region the
    rows are all >= 0 if and only if the reference's impulse flow ends with v_t = 0.
    Inside it (r_n <= 0) the flow always ends in stick, and the rows (r_n >= 1e-3) leave
    that landing out: a restriction, never a landing the flow does not make."""
    rng = np.random.default_rng(3)
    outcomes, painleve = [], 0
    for _ in range(400):
        root = rng.normal(size=(2, 2))
        w = root @ root.T + 0.05 * np.eye(2)
        v_n, v_t = -rng.uniform(0.1, 2.0), rng.normal()
        mu = rng.uniform(0.2, 1.0)
        sign = 1.0 if v_t >= 0 else -1.0
        lam = np.array(planar_impulse_flow(w, v_n, v_t, mu))
        sticks = abs(v_t + (w @ lam)[1]) < 1e-9
        rows = [big - small for big, small in polish.touchdown_rows(w, v_n, v_t, sign, mu)]
        if w[0, 0] - sign * mu * w[0, 1] <= 0:
            assert sticks and rows[1] < 0, (w, v_n, v_t, mu)
            painleve += 1
            continue
        if min(rows[1:3]) < 0 and min(rows[1:3]) > -1e-3:
            continue  # within the rows' 1e-3 safety margin on the rates
        assert (min(rows) >= 0) == sticks, (w, v_n, v_t, mu)
        outcomes.append(sticks)
    assert 50 < sum(outcomes) < len(outcomes) - 50  # both outcomes sampled
    assert painleve > 5


def test_phase_changes_the_re_solve_does_not_model_are_named():
    with pytest.raises(InvalidInput, match="no 'slip-' -> 'stick' change .* lifts off "
                                           "through slip"):
        polish.polish_contact(None, (polish.Phase("stick", 0, 0.5),
                                     polish.Phase("slip-", 0.5, 0.6),
                                     polish.Phase("stick", 0.6, 1)), guess=None)
    with pytest.raises(InvalidInput, match="must start in stick"):
        polish.polish_contact(None, (polish.Phase(polish.FLIGHT, 0, 1),), guess=None)
    with pytest.raises(InvalidInput, match="cone_margins"):
        polish.PolishOptions(cone_margins=(1.0, 1.2))
    with pytest.raises(InvalidInput, match="'rk4' or 'radau'"):
        polish.PolishOptions(integrator="euler")
    with pytest.raises(InvalidInput, match="elements per interval are `substeps`"):
        polish.PolishOptions(integrator="radau", steps_per_node=2)


def test_a_lift_off_straight_from_stick_must_be_at_a_control_jump():
    """Inside an interval it would need lambda_n = lambda_t = 0 at one switch time."""
    from tfcontact.scenes.monoped import monoped_problem

    problem = monoped_problem("reduced").problem  # T / N = 0.1 s
    with pytest.raises(InvalidInput, match=r"at 0\.55 s\) must be at a control jump"):
        polish.polish_contact(problem, (polish.Phase("stick", 0, 0.55),
                                        polish.Phase("flight", 0.55, 1)), guess=None)
    with pytest.raises(InvalidInput, match=r"`guess` must be a ContactResult or a tuple "
                                           r"\(t, x, u\).*got list"):
        polish.polish_contact(problem, (polish.Phase("stick", 0, 1),), guess=[0, 1, 2])


def test_free_normal_acceleration_is_gravity_plus_push_for_a_particle():
    """The lift-off row at a control jump: n^T M^-1 (f + u) for a point mass of mass 2."""
    dyn = polish.HybridDynamics(point_mass(2, mu=0.5, mass=2.0, controlled=True))
    x = np.array([0.0, 0.0, 1.0, 0.0])
    for push in (5.0, 30.0):
        got = float(dyn.free_normal(x, np.array([0.0, push])))
        assert got == pytest.approx(push / 2.0 - G, rel=1e-12)


@pytest.fixture(scope="module")
def saved_full_plan():
    return np.load(SAVED_PLAN)


@pytest.mark.parametrize("path", [SAVED_PLAN, SEARCH_PLAN], ids=["hand-set", "searched"])
def test_the_saved_full_plan_meets_tf9_and_passes_the_exact_replay(path):
    """benchmarks/monoped_exact_plan.npz (the chain's verified TF-9 plan on the hand-set
    schedule) and monoped_search_plan.npz (on the searched one): from q0 at rest to the
    goal within |u| <= 60, TF-9's ellipses kept at its nodes, and each control
    interval's exact replay from the plan's own state within the tolerance in sum."""
    plan = np.load(path)
    boundary, u = plan["boundary"], plan["u"]
    np.testing.assert_allclose(boundary[0], [0, 0.4, 0, 0, 0, 0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(boundary[-1][:4], [3.0, 0.4, 0.0, 0.0], atol=1e-6)
    assert u.shape == (20, 2) and np.abs(u).max() <= 60 + 1e-9
    verification, holes = verify_saved(path)
    assert verification.passed and verification.open_loop_unstable
    assert verification.clock_monotone and verification.clock_end_error < 1e-12
    assert verification.defect_sum < 5e-2
    assert holes >= -1e-6 and verification.min_gap >= -1e-3
    # The cone on the forces and impulses recomputed from the states and controls: three
    # landings, stick forces pressing and inside the cone (mu = 0.8) up to round-off.
    from tfcontact.scenes.monoped import monoped_problem
    # the reduced task's robot, ground and friction are the full task's
    dyn = polish.HybridDynamics(monoped_problem("reduced").system.cls)
    forces, impulses = polish.contact_values(plan["t"], plan["x"], plan["u"],
                                              load_resolved_plan(path).phases, dyn, 2.5)
    assert len(impulses) == 3 and len(forces) > 300
    both = np.vstack([forces, impulses])
    assert both[:, 0].min() > 0
    assert np.all(np.abs(both[:, 1]) <= 0.8 * both[:, 0] + 1e-6)


def test_the_saved_full_plan_fails_with_one_control_moved(saved_full_plan, tmp_path):
    """The replay check can fail: 0.5 N m more hip torque in one stance interval."""
    moved = dict(saved_full_plan)
    moved["u"] = moved["u"].copy()
    moved["u"][4, 0] += 0.5
    np.savez(tmp_path / "moved.npz", **moved)
    verification, _ = verify_saved(tmp_path / "moved.npz")
    assert not verification.passed
    assert verification.local_defects[4] > 5e-2


@pytest.mark.parametrize("change, monotone", [("end", True), ("order", False)])
def test_the_saved_full_plan_fails_with_node_times_off_the_horizon(saved_full_plan, tmp_path,
                                                                   change, monotone):
    """The plan's node times are its clock: they must not decrease and must end at T.
    The saved plan with its last node 1 ms short, and with two nodes swapped in time,
    fails (its replay, gaps and cone still pass: measured defect sum 8.6e-3)."""
    moved = dict(saved_full_plan)
    t = moved["t"].copy()
    if change == "end":
        t[-1] -= 1e-3
    else:
        t[10], t[11] = t[11], t[10]
    moved["t"] = t
    np.savez(tmp_path / "moved.npz", **moved)
    verification, _ = verify_saved(tmp_path / "moved.npz")
    assert verification.clock_monotone is monotone and not verification.passed
    if change == "end":
        assert verification.clock_end_error == pytest.approx(1e-3)


def test_the_saved_full_plan_fails_with_its_end_off_the_goal(saved_full_plan, tmp_path):
    """The re-solve may leave terminal rows to the final stance's dynamics
    (`polish.terminal_rows_not_held`), so the verification checks q(T) = q_goal itself:
    the saved plan with its base ending 2 mm short (node and boundary) fails on that alone
    (gap and local defects within their tolerances)."""
    from tfcontact.scenes.monoped import monoped_problem
    from tfcontact.scenes.monoped_exact import EXACT_TASK

    problem = monoped_problem(EXACT_TASK).problem
    end = saved_full_plan["boundary"][-1]
    assert polish.terminal_violation(problem, end) <= 1e-6
    moved = dict(saved_full_plan)
    for name in ("boundary", "x"):
        moved[name] = moved[name].copy()
        moved[name][-1, 0] -= 2e-3
    assert polish.terminal_violation(problem, moved["boundary"][-1]) == pytest.approx(
        2e-3, rel=1e-6)
    np.savez(tmp_path / "moved.npz", **moved)
    verification, _ = verify_saved(tmp_path / "moved.npz")
    assert not verification.passed
    assert any("terminal constraint is violated by 0.002" in note
               for note in verification.notes)
    # the open-loop unstable plan passes its replay on the local defects' sum (as unmoved)
    assert verification.open_loop_unstable
    assert verification.defect_sum < verification.tolerances["end_state"]
    assert verification.min_gap >= -verification.tolerances["gap"]
    with pytest.raises(InvalidInput, match="terminal_tolerance"):
        polish.PolishOptions(terminal_tolerance=0.0)


def test_the_mesh_is_refined_where_the_local_defects_exceed_their_share():
    """Tolerance 0.05 over 4 intervals: a share of 0.0125 each; the second interval and the
    one the reference could not replay (nan) get twice the elements."""
    got = polish.refined_substeps((12, 12, 6, 12), [1e-3, 0.03, float("nan"), 0.0125], 0.05)
    assert got == (12, 24, 12, 12)
    assert polish.PolishOptions(substeps=(3, 4)).substeps_per_interval(2) == (3, 4)
    assert polish.PolishOptions(substeps=5).substeps_per_interval(3) == (5, 5, 5)
    with pytest.raises(InvalidInput, match="2 counts for 3 control intervals"):
        polish.PolishOptions(substeps=(3, 4)).substeps_per_interval(3)
    with pytest.raises(InvalidInput, match="3 local defects for 2 intervals"):
        polish.refined_substeps((3, 4), [0.1, 0.2, 0.3], 0.05)
    with pytest.raises(InvalidInput, match="substeps"):
        polish.PolishOptions(substeps=(3, 0))


def test_tf9s_grid_re_solves_the_rk4_plan_but_fails_the_exact_replay():
    """TF-9's own discretisation, Radau IIA order 5 with N_FE = 3 elements per control
    interval, warm started from the verified RK4 plan: IPOPT converges, but the leg's fast
    swings (joint velocities near 100 rad/s before each touchdown) are too fast for
    elements of 42 ms, and the exact replay from the plan's own states parts from it by
    more than 1 within one interval. Measured: 32 iterations, largest defect 14."""
    from tfcontact.scenes.monoped import monoped_problem
    from tfcontact.scenes.monoped_exact import EXACT_TASK

    plan = np.load(RK4_PLAN)
    problem = monoped_problem(EXACT_TASK).problem
    polished = polish.polish_contact(
        problem, load_resolved_plan(RK4_PLAN).phases,
        polish.PolishOptions(substeps=3, integrator="radau", painleve_margin=0.0),
        guess=(plan["t"], plan["x"], plan["u"]), verbose=False)
    assert polished.solved
    assert polished.status == "verification_failed"
    assert max(polished.verification.local_defects) > 1.0
    # its nodes are the stage points: 3 per element, two at each of the 3 touchdowns
    assert len(polished.t) >= 1 + 20 * 3 * 3 + 3
    # The plan's arrays checked again (as a plan read from disk is), the forces and
    # impulses recomputed from the nodes: the same verdict and the same figures.
    again = polish.verify_polished(problem, polished.phases, polished.t, polished.x,
                                   polished.u, polished.boundary_states)
    first = polished.verification
    assert again.passed == first.passed
    np.testing.assert_array_equal(again.local_defects, first.local_defects)
    assert again.min_gap == first.min_gap
    assert again.friction_cone_violation == pytest.approx(first.friction_cone_violation,
                                                          rel=1e-9, abs=1e-12)
    with pytest.raises(InvalidInput, match=r"`u` has shape \(19, 2\); the problem needs"):
        polish.verify_polished(problem, polished.phases, polished.t, polished.x,
                               polished.u[:19], polished.boundary_states)


def test_a_capped_re_solve_reports_progress_and_fails_honestly(monkeypatch, capsys):
    """A long re-solve prints a line every `PROGRESS_EVERY` iterations; stopped at the
    iteration cap, its plan is nlp_failed (not a plan marked successful)."""
    from tfcontact.mpcc import solver as mpcc_solver
    from tfcontact.scenes.monoped import monoped_problem

    monkeypatch.setattr(mpcc_solver, "PROGRESS_EVERY", 5)
    problem = monoped_problem("reduced").problem  # to x = 1: no plan by standing still
    x0 = np.array([0, 0.4, 0, 0, 0, 0, 0, 0.0])
    plan = polish.polish_contact(problem, (polish.Phase("stick", 0, 1),),
                                 polish.PolishOptions(substeps=2, max_iter=12),
                                 guess=(np.array([0.0, 1.0]), np.array([x0, x0]),
                                        np.zeros((10, 2))))
    out = capsys.readouterr().out
    assert "    iteration 5: objective" in out and "    iteration 10: objective" in out
    assert "    iteration 4: objective" not in out
    assert "    IPOPT started (" in out
    # a slow solve also says where it is after `PROGRESS_SECONDS`
    monkeypatch.setattr(mpcc_solver, "PROGRESS_SECONDS", 0.0)
    polish.polish_contact(problem, (polish.Phase("stick", 0, 1),),
                          polish.PolishOptions(substeps=2, max_iter=3),
                          guess=(np.array([0.0, 1.0]), np.array([x0, x0]), np.zeros((10, 2))))
    out = capsys.readouterr().out
    assert all(f"    iteration {i}: objective" in out for i in (1, 2, 3))
    assert plan.ipopt_status == "Maximum_Iterations_Exceeded" and plan.iterations == 12
    assert plan.status == "nlp_failed" and not plan.success
    # where its time went: the build, IPOPT, and CasADi's evaluations inside IPOPT
    timing = plan.timing
    assert 0 < timing.evaluations < timing.ipopt
    assert 0 < timing.build and timing.build + timing.ipopt <= plan.solve_time
    assert timing.n_variables > 10 * 8 * 2 and timing.n_constraints > 10 * 2 * 8
    assert f"{timing.n_variables} variables, {timing.n_constraints} constraints" \
        in plan.summary()


def test_blas_threads_is_validated():
    with pytest.raises(InvalidInput, match="blas_threads"):
        polish.PolishOptions(blas_threads=0)


def test_ldl_solves_give_qrs_dynamics():
    """`HybridDynamics(ldl=True)` (M(q) and the Delassus matrix by LDL^T) gives the QR
    form's right-hand sides, forces and impacts on the monoped, at random states."""
    from tfcontact.scenes.monoped import monoped_problem

    cls = monoped_problem("reduced").problem.system.cls
    qr, ldl = polish.HybridDynamics(cls), polish.HybridDynamics(cls, ldl=True)
    rng = np.random.default_rng(7)
    for _ in range(5):
        x = np.concatenate([[rng.uniform(-1, 1), rng.uniform(0.3, 0.5)],
                            rng.uniform(-1, 1, 2), rng.normal(size=4)])
        u = rng.normal(size=2)
        for mode in (polish.STICK, "slip+", "slip-", polish.FLIGHT):
            np.testing.assert_allclose(np.asarray(ldl.rhs[mode](x, u)),
                                       np.asarray(qr.rhs[mode](x, u)), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(np.asarray(ldl.force(x, u)), np.asarray(qr.force(x, u)),
                                   rtol=1e-9, atol=1e-9)
        for a, b in zip(ldl.impact(x), qr.impact(x), strict=True):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-9)
    count = {name: dyn.shooting(polish.STICK, 2).n_instructions()
             for name, dyn in (("qr", qr), ("ldl", ldl))}
    assert count["ldl"] < count["qr"]


@pytest.mark.parametrize("integrator, substeps, steps", [("rk4", 2, 2), ("radau", 1, 1)])
def test_element_derivatives_are_casadis_own_on_the_re_solves_nlp(monkeypatch, integrator,
                                                                   substeps, steps):
    """The exact re-solve of the full monoped task (three touchdowns inside intervals:
    pieces whose step length is a switch time's) with `element_derivatives`: the
    scattered Jacobian and Hessian of its NLP (shooting steps or collocation elements,
    contact and path rows, one function each) equal CasADi's own derivatives of the
    same NLP at random points."""
    import casadi as ca

    from tfcontact.ocp import nodes
    from tfcontact.scenes.monoped import monoped_problem
    from tfcontact.scenes.monoped_exact import EXACT_TASK

    captured = {}
    recorded = nodes.RepeatedRows.derivative_options

    def capture(rows, threads=1):
        captured["opti"], captured["ours"] = rows.opti, recorded(rows, threads)
        raise StopIteration  # built: no solve

    monkeypatch.setattr(nodes.RepeatedRows, "derivative_options", capture)
    plan = np.load(RK4_PLAN)
    with pytest.raises(StopIteration):
        polish.polish_contact(
            monoped_problem(EXACT_TASK).problem, load_resolved_plan(RK4_PLAN).phases,
            polish.PolishOptions(substeps=substeps, steps_per_node=steps,
                                 integrator=integrator, painleve_margin=0.0,
                                 element_derivatives=True, threads=2),
            guess=(plan["t"], plan["x"], plan["u"]), verbose=False)
    opti, ours = captured["opti"], captured["ours"]
    x, p = ca.SX.sym("x", opti.nx), ca.SX.sym("p", opti.np)
    f, g = ca.Function("nlp", [opti.x, opti.p], [opti.f, opti.g]).expand()(x, p)
    solver = ca.nlpsol("own", "ipopt", {"x": x, "p": p, "f": f, "g": g}, {"print_time": False})
    jac_g, hess_lag = solver.get_function("nlp_jac_g"), solver.get_function("nlp_hess_l")
    rng = np.random.default_rng(11)
    guess = np.asarray(opti.debug.value(opti.x, opti.initial())).ravel()
    for _ in range(2):
        # near the guess (far from it the steps and the leg's dynamics blow up)
        w = guess + 1e-3 * rng.normal(size=opti.nx)
        lam_f, lam_g = rng.normal(), rng.normal(size=opti.ng)
        J_ref, J_ours = jac_g(w, 1.0)[1], ours["jac_g"](w, 1.0)[1]
        H_ref, H_ours = hess_lag(w, 1.0, lam_f, lam_g), ours["hess_lag"](w, 1.0, lam_f, lam_g)
        for ref, value in ((J_ref, J_ours), (H_ref, H_ours)):
            ref, value = ref.full(), value.full()
            assert np.all(np.isfinite(ref)) and np.max(np.abs(ref)) > 0.1
            np.testing.assert_allclose(value, ref, rtol=0, atol=1e-9 * np.max(np.abs(ref)))


def test_element_derivative_options_are_validated():
    with pytest.raises(InvalidInput, match="`element_derivatives` must be True or False"):
        polish.PolishOptions(element_derivatives=1)
    with pytest.raises(InvalidInput, match="`ldl` must be True or False"):
        polish.PolishOptions(ldl="yes")
    with pytest.raises(InvalidInput, match="threads"):
        polish.PolishOptions(threads=0)


def test_interpolation_takes_either_side_of_an_impact():
    """At an impact's repeated time the later sample (post-impact), or with `left_limit`
    the earlier one; elsewhere the two agree."""
    from tfcontact.ocp.nodes import interpolate

    t = np.array([0.0, 1.0, 1.0, 2.0])
    x = np.array([[0.0, 2.0], [1.0, 2.0], [1.0, -1.0], [2.0, -1.0]])  # v jumps at t = 1
    np.testing.assert_array_equal(interpolate(t, x, 1.0), [1.0, -1.0])
    np.testing.assert_array_equal(interpolate(t, x, 1.0, left_limit=True), [1.0, 2.0])
    for at in (0.0, 0.5, 1.5, 2.0, 3.0):
        np.testing.assert_array_equal(interpolate(t, x, at),
                                      interpolate(t, x, at, left_limit=True))
    np.testing.assert_array_equal(interpolate(t, x, 0.5), [0.5, 2.0])


def test_a_plan_re_solved_on_its_own_mesh_starts_on_its_dynamics(monkeypatch):
    """A converged Radau plan (12 elements per interval, three touchdowns) as the guess of
    the same NLP: every equality row holds at IPOPT's starting point. The node ending a
    piece at a touchdown starts from the pre-impact state (the post-impact one put the
    velocity jump into its collocation rows: 124 instead of 1e-11, measured, and the
    refined level from such a start took 783 instead of 203 iterations)."""
    import casadi as ca

    from tfcontact.scenes.monoped import monoped_problem
    from tfcontact.scenes.monoped_exact import EXACT_TASK, radau_options

    plan = load_resolved_plan(Path(__file__).parent / "data" / "monoped_radau12_plan.npz")
    captured = {}

    def capture(opti, threads):
        captured["opti"] = opti
        raise StopIteration  # built: no solve

    monkeypatch.setattr(polish, "solve_timed", capture)
    with pytest.raises(StopIteration):
        polish.polish_contact(monoped_problem(EXACT_TASK).problem, plan.phases,
                              radau_options(plan.substeps), guess=(plan.t, plan.x, plan.u),
                              verbose=False)
    opti = captured["opti"]
    start = opti.debug.value(opti.x, opti.initial())
    g, lower, upper = (np.asarray(ca.Function("rows", [opti.x, opti.p], [rows])(
        start, [])).ravel() for rows in (opti.g, opti.lbg, opti.ubg))
    equal = lower == upper
    assert equal.sum() > 5000 and sum(p.mode == polish.FLIGHT for p in plan.phases) == 3
    assert np.max(np.abs(g - lower)[equal]) < 1e-8


def test_terminal_rows_the_final_stance_holds_are_left_to_it():
    """A particle (x, z) ending in stick on the ground z = 0 keeps z, v_z and v_x from its
    touchdown: of the terminal rows x(T) = (q, v)_goal only the combination along x stays;
    of q(T) = q_goal the same; in flight all stay, and in slip v_x is free to change."""
    import casadi as ca

    dyn = polish.HybridDynamics(point_mass(2, mu=0.5))
    x = ca.SX.sym("x", 4)
    state = ca.Function("state", [x], [x])
    position = ca.Function("position", [x], [x[:2]])
    end = np.array([0.7, 0.0, 0.0, 0.0])
    for terminal, n_rows in ((state, 4), (position, 2)):
        kept = polish.terminal_rows_not_held(terminal, dyn.held[polish.STICK], end)
        np.testing.assert_allclose(np.abs(kept), np.eye(n_rows)[:1], atol=1e-12)
        np.testing.assert_array_equal(
            polish.terminal_rows_not_held(terminal, dyn.held[polish.FLIGHT], end),
            np.eye(n_rows))
    height = ca.Function("height", [x], [x[1]])  # all of it held: no row left
    assert polish.terminal_rows_not_held(height, dyn.held[polish.STICK], end).shape == (0, 1)
    kept = polish.terminal_rows_not_held(state, dyn.held["slip+"], np.array([0.7, 0, 1.0, 0]))
    np.testing.assert_allclose(kept.T @ kept, np.diag([1.0, 0, 1, 0]), atol=1e-12)


def test_the_touchdown_rate_floor_leaves_grazing_landings_out():
    """`touchdown_rate` bounds the impulse flow's normal rate r_n below by a fraction of
    W_nn: a landing with r_n = 0.03 [1/kg] and W_nn = 0.43 (a ratio of 0.07) passes 0.05
    and not 0.1; without it (0, the default) no row is added."""
    mu, sign = 0.8, 1.0
    w = np.array([[0.03 + mu * 0.5, 0.5], [0.5, 2.0]])  # r_n = W_nn - mu W_nt = 0.03
    plain = polish.touchdown_rows(w, -1.0, 0.1, sign, mu)
    assert len(plain) == 6 and plain[1][0] == pytest.approx(0.03)
    passes = polish.touchdown_rows(w, -1.0, 0.1, sign, mu, rate=0.05)
    assert len(passes) == 7 and passes[-1][0] >= passes[-1][1]
    fails = polish.touchdown_rows(w, -1.0, 0.1, sign, mu, rate=0.1)
    assert fails[-1][0] < fails[-1][1]
    for bad in (-0.1, 1.0):
        with pytest.raises(InvalidInput, match="touchdown_rate"):
            polish.PolishOptions(touchdown_rate=bad)
