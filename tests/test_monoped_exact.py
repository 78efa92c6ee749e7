"""TF-9's two-stage chain (tfcontact.scenes.monoped_exact): the continuation past an
iteration cap, the tiled guess, the files `tfcontact plan monoped` writes, and the reduced
task end to end (slow: about 6 minutes)."""

from __future__ import annotations

import dataclasses
import json
import types
from pathlib import Path

import numpy as np
import pytest

import tfcontact.scenes.monoped_exact as chain_module
from tfcontact.cli import main
from tfcontact.errors import InvalidInput
from tfcontact.ocp.polish import FLIGHT, STICK, Phase, PolishedPlan
from tfcontact.plan_format import load_trajectory
from tfcontact.scenes.monoped import REDUCED_TASK, monoped_problem
from tfcontact.scenes.monoped_exact import (
    EXACT_TASK,
    HAND_SET_SCHEDULE,
    ExactPlan,
    Schedule,
    tiled_guess,
    verify_saved,
)

SAVED_PLAN = Path(__file__).resolve().parents[1] / "benchmarks" / "monoped_exact_plan.npz"


def _plan(status: str, cost: float, shift: float = 0.0, verification=None) -> PolishedPlan:
    t = np.linspace(0.0, 1.0, 5)
    return PolishedPlan(
        phases=(Phase(STICK, 0.0, 1.0),), t=t, x=np.zeros((5, 8)) + shift, u=np.zeros((10, 2)),
        boundary_states=np.zeros((11, 8)), contact_forces=np.zeros((0, 2)),
        impact_impulses=np.zeros((0, 2)), cost=cost, ipopt_status=status, iterations=7,
        solve_time=1.0, verification=verification or types.SimpleNamespace(passed=True,
                                                                           summary=str))


def test_a_capped_step_hands_its_iterate_on_and_the_last_is_solved_again(monkeypatch):
    """Step 1 stops at the iteration cap: step 2 starts from its iterate. Step 2 stops at
    the cap too: it is solved once more from its own iterate, and that decides."""
    outcomes = iter([("Maximum_Iterations_Exceeded", 1.0), ("Maximum_Iterations_Exceeded", 2.0),
                     ("Solve_Succeeded", 3.0)])
    guesses = []

    def fake_polish(problem, phases, options, *, guess, verbose):
        guesses.append(None if guess is None else float(guess[1][0, 0]))
        status, cost = next(outcomes)
        return _plan(status, cost, shift=cost)

    monkeypatch.setattr(chain_module, "polish_contact", fake_polish)
    mp = monoped_problem(REDUCED_TASK)
    levels = [("first", mp, None), ("second", mp, None)]
    result = chain_module.run_chain(levels, (Phase(STICK, 0, 1),), None, [], 0.0,
                                 verbose=False)
    assert guesses == [None, 1.0, 2.0]  # each solve starts from the last iterate
    assert [s.name for s in result.steps] == ["first", "second",
                                              "second, again from its capped iterate"]
    assert result.plan.cost == 3.0 and result.status == "converged" and not result.message


def test_any_other_failure_stops_the_chain(monkeypatch):
    calls = []

    def fake_polish(problem, phases, options, *, guess, verbose):
        calls.append(1)
        return _plan("Infeasible_Problem_Detected", 1.0)

    monkeypatch.setattr(chain_module, "polish_contact", fake_polish)
    mp = monoped_problem(REDUCED_TASK)
    result = chain_module.run_chain([("first", mp, None), ("second", mp, None)],
                                 (Phase(STICK, 0, 1),), None, [], 0.0, verbose=False)
    assert len(calls) == 1 and result.status == "nlp_failed" and not result.success
    assert "first: IPOPT Infeasible_Problem_Detected" in result.summary()


def test_a_level_may_set_its_options_from_the_last_plan(monkeypatch):
    """The Radau levels: the second refines the first's mesh where its local defects
    exceed 0.05 / 20 (intervals 3 and 7 here), doubling their 12 elements."""
    seen = []
    defects = [1e-4] * 20
    defects[3], defects[7] = 0.03, float("nan")

    def fake_polish(problem, phases, options, *, guess, verbose):
        seen.append(options)
        plan = _plan("Solve_Succeeded", 1.0, verification=types.SimpleNamespace(
            passed=True, summary=str, local_defects=tuple(defects)))
        return dataclasses.replace(plan, integrator=options.integrator,
                                   substeps=options.substeps_per_interval(20))

    monkeypatch.setattr(chain_module, "polish_contact", fake_polish)
    mp = monoped_problem(EXACT_TASK)
    result = chain_module.run_chain(chain_module.radau_levels(mp), (Phase(STICK, 0, 2.5),),
                                 None, [], 0.0, verbose=False)
    assert result.status == "converged" and len(seen) == 2
    assert seen[0].integrator == "radau" and seen[0].substeps == 12
    assert seen[0].cone_margins == (0.98,)
    expected = [12] * 20
    expected[3] = expected[7] = 24
    assert seen[1].substeps == tuple(expected) and seen[1].integrator == "radau"


def test_tiled_guess_repeats_the_hop_on_the_schedule():
    """The hop three times: lift-offs at the control jumps 0.5, 1.25, 2.0 s, one metre
    further per hop, time scaled (velocities / scale, torques / scale^2)."""
    hop = _hop()
    (t_guess, x_guess, u_guess), phases = tiled_guess(hop, EXACT_TASK)
    lift_offs = HAND_SET_SCHEDULE.lift_offs
    assert [p.mode for p in phases] == [STICK, FLIGHT] * 3 + [STICK]
    assert [p.start for p in phases if p.mode == FLIGHT] == list(lift_offs)
    dt = EXACT_TASK.horizon / EXACT_TASK.n_intervals
    assert all(abs(s / dt - round(s / dt)) < 1e-12 for s in lift_offs)  # control jumps
    assert np.all(np.diff(t_guess) >= 0) and t_guess[-1] == pytest.approx(2.5)
    assert x_guess[0, 0] == 0.0 and x_guess[-1, 0] == pytest.approx(3.0)
    # the first stance: 0.6 s of the hop onto 0.5 s, so v_x = 1 / (5/6)
    assert x_guess[1, 4] == pytest.approx(1.2)
    assert u_guess.shape == (20, 2) and u_guess[0, 0] == pytest.approx(4.0 * 1.2**2)
    # another schedule: its lift-offs and flights, the first stance 0.6 s onto 0.375 s
    other = Schedule(lift_offs=(0.375, 1.0, 1.625), flight_time=0.3)
    (t_guess, x_guess, _), phases = tiled_guess(hop, EXACT_TASK, other)
    assert [(p.start, p.end) for p in phases if p.mode == FLIGHT] == [
        (a, a + 0.3) for a in other.lift_offs]
    assert x_guess[1, 4] == pytest.approx(0.6 / 0.375)
    assert x_guess[-1, 0] == pytest.approx(3.0) and t_guess[-1] == pytest.approx(2.5)


def _hop() -> PolishedPlan:
    """A stand-in reduced hop: q_x from 0 to 1 at 1 m/s, flight 0.6-0.89 s, 4 N m."""
    t = np.linspace(0.0, 1.0, 101)
    x = np.zeros((101, 8))
    x[:, 0] = t
    x[:, 4] = 1.0
    return PolishedPlan(
        phases=(Phase(STICK, 0, 0.55), Phase("slip-", 0.55, 0.6), Phase(FLIGHT, 0.6, 0.89),
                Phase(STICK, 0.89, 1.0)),
        t=t, x=x, u=np.full((10, 2), 4.0), boundary_states=x[::10],
        contact_forces=np.zeros((0, 2)), impact_impulses=np.zeros((0, 2)), cost=0.0,
        ipopt_status="Solve_Succeeded", iterations=0, solve_time=0.0, verification=None)


def test_uniform_schedules_hop_once_per_hole_and_land_before_the_horizon():
    """Lift-offs k_1, k_1 + s, k_1 + 2 s intervals (0.125 s), flights as long as the hop's
    (0.29 s); (5, 6) would land at 2.415 s, after T - T / N = 2.375 s: left out."""
    schedules = chain_module.uniform_schedules(_hop())
    assert [s.lift_offs for s in schedules] == [
        (0.375, 1.0, 1.625), (0.375, 1.125, 1.875), (0.5, 1.125, 1.75), (0.5, 1.25, 2.0),
        (0.625, 1.25, 1.875)]
    assert all(s.flight_time == pytest.approx(0.29) for s in schedules)


def test_the_search_keeps_the_solved_schedule_with_the_lowest_objective(monkeypatch, capsys):
    """Each candidate's first re-solve starts from the hop tiled on it; infeasible ones
    are reported but not chosen, even with a lower objective."""
    outcomes = {0.375: ("Solve_Succeeded", 226.0), 0.5: ("Infeasible_Problem_Detected", 100.0),
                0.625: ("Solve_Succeeded", 190.0), 0.75: ("Maximum_Iterations_Exceeded", 50.0)}
    seen = []

    def fake_polish(problem, phases, options, *, guess, verbose):
        lift_off = next(p.start for p in phases if p.mode == FLIGHT)
        seen.append(lift_off)
        return _plan(*outcomes[lift_off])

    monkeypatch.setattr(chain_module, "polish_contact", fake_polish)
    mp = monoped_problem(EXACT_TASK)
    schedules = tuple(Schedule((a, a + 0.75), 0.26) for a in outcomes)
    best, trials = chain_module.search_schedule(_hop(), schedules, mp, None, verbose=True)
    assert seen == list(outcomes) and len(trials) == 4
    out = capsys.readouterr().out  # a line as each candidate starts, one as it ends
    assert "monoped: schedule 2 of 4, lift-offs 0.5, 1.25 s" in out
    assert "  IPOPT Infeasible_Problem_Detected, 7 iterations" in out
    assert best.schedule.lift_offs == (0.625, 1.375) and best.plan.cost == 190.0
    outcomes.update({0.375: ("Infeasible_Problem_Detected", 1.0),
                     0.625: ("Restoration_Failed", 1.0)})
    best, trials = chain_module.search_schedule(_hop(), schedules, mp, None, verbose=False)
    assert best is None and len(trials) == 4


def test_the_searched_schedule_s_re_solve_starts_the_rest_of_the_chain(monkeypatch):
    """With schedule="search": every candidate is a step of the chain, the cheapest solved
    one's plan is the next re-solve's guess, and the chain skips its own first step."""
    quiet = types.SimpleNamespace(passed=True, summary=str, local_defects=(1e-4,) * 20)
    reduced = ExactPlan(dataclasses.replace(_hop(), verification=quiet),
                        monoped_problem(REDUCED_TASK), (), 0.0, 1.0)
    monkeypatch.setattr(chain_module, "reduced_exact_plan", lambda verbose: reduced)
    costs = iter([203.0, 190.0, 223.0, 446.0, 205.0, 191.0, 191.5, 192.6, 192.6])
    guesses = []

    def fake_polish(problem, phases, options, *, guess, verbose):
        guesses.append(guess)
        cost = next(costs)
        return _plan("Solve_Succeeded", cost, shift=cost, verification=quiet)

    monkeypatch.setattr(chain_module, "polish_contact", fake_polish)
    result = chain_module.full_exact_plan(verbose=False)
    names = [step.name for step in result.steps]
    assert len(names) == 5 + 4 and all("lift-offs" in n for n in names[:5])
    assert "lift-offs 0.375, 1.125, 1.875 s" in names[1] and result.steps[1].objective == 190.0
    assert names[5] == "full task, bump holes, 16 nodes x 2 RK4 steps"
    assert guesses[5][1][0, 0] == 190.0  # the chosen candidate's states
    assert result.status == "converged" and result.plan.cost == 192.6


def test_full_exact_plan_refuses_an_unknown_schedule():
    with pytest.raises(InvalidInput, match="Schedule or 'search'"):
        chain_module.full_exact_plan(verbose=False, schedule="hand")


@pytest.mark.parametrize("lift_offs, flight, match", [
    ((), 0.26, "needs lift-offs"), ((0.5, 1.0), 0.0, "positive flight"),
    ((0.5, 0.7), 0.26, "after the last one landed"), ((0.0, 1.0), 0.26, "after t = 0")])
def test_a_schedule_whose_hops_overlap_is_refused(lift_offs, flight, match):
    with pytest.raises(InvalidInput, match=match):
        Schedule(lift_offs=lift_offs, flight_time=flight)


def test_a_schedule_landing_after_the_horizon_is_refused():
    with pytest.raises(InvalidInput, match="lands after the horizon"):
        tiled_guess(None, EXACT_TASK, Schedule(lift_offs=(0.5, 2.375), flight_time=0.26))


@pytest.mark.parametrize("task, schedule", [(None, "search"), ("full", "search"),
                                            ("hand-set", chain_module.HAND_SET_SCHEDULE)])
def test_plan_monoped_searches_its_schedule_unless_asked_for_the_hand_set_one(
        monkeypatch, tmp_path, capsys, task, schedule):
    """The full task (the default) runs the chain with schedule="search", `--task
    hand-set` with `HAND_SET_SCHEDULE`; a chain that found no schedule exits 1 with its
    reason and writes no plan."""
    calls = []

    def fake(verbose, schedule):
        calls.append(schedule)
        return ExactPlan(None, monoped_problem(EXACT_TASK), (), float("nan"), 1.0,
                         message="no schedule of 5 gave a solved re-solve")

    monkeypatch.setattr(chain_module, "full_exact_plan", fake)
    assert main(["plan", "monoped", "--out", str(tmp_path)]
                + (["--task", task] if task else [])) == 1
    assert calls == [schedule]
    assert "no schedule of 5 gave a solved re-solve" in capsys.readouterr().out
    assert not (tmp_path / "plan.npz").exists()


def test_plan_monoped_writes_plan_trajectory_and_replay(monkeypatch, tmp_path, capsys):
    """`tfcontact plan monoped` writes the chain's plan (verified again from the file),
    its trajectory with the three touchdowns as frozen pieces carrying the impulses,
    the figures and the replay; the chain itself is replaced by the saved plan."""
    saved = np.load(SAVED_PLAN)
    phases = chain_module.saved_phases(saved)
    verification, holes = verify_saved(SAVED_PLAN)
    plan = PolishedPlan(
        phases=phases, t=saved["t"], x=saved["x"], u=saved["u"],
        boundary_states=saved["boundary"], contact_forces=np.zeros((0, 2)),
        impact_impulses=np.zeros((0, 2)), cost=236.9, ipopt_status="Solve_Succeeded",
        iterations=1, solve_time=1.0, verification=verification, integrator="radau",
        substeps=tuple(int(n) for n in saved["substeps"]))
    mp = monoped_problem(EXACT_TASK)
    fake = ExactPlan(plan, mp, (), holes, 1.0)
    monkeypatch.setattr(chain_module, "full_exact_plan", lambda verbose, schedule: fake)
    assert main(["plan", "monoped", "--out", str(tmp_path)]) == 0
    assert "plan monoped (full): converged" in capsys.readouterr().out
    for name in ("plan.npz", "path.png", "trajectory.npz", "trajectory.json", "replay.html",
                 "contacts.png", "summary.json"):
        assert (tmp_path / name).is_file(), name
    again, _ = verify_saved(tmp_path / "plan.npz")
    assert again.passed and again.defect_sum == pytest.approx(verification.defect_sum)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["success"] and summary["status"] == "converged"
    traj = load_trajectory(tmp_path / "trajectory.npz")
    assert traj.status == "converged" and traj.verification["passed"]
    landing = np.flatnonzero(np.abs(traj.impulse).sum(axis=(1, 2)) > 0)
    assert landing.size == 3
    assert np.all(traj.clock[landing] == traj.clock[landing - 1])  # frozen: an impact
    assert np.all(traj.tau[landing] > traj.tau[landing - 1])
    assert np.all(traj.impulse[landing, 0, 2] > 0)  # pushing up
    assert traj.solver["method"].startswith("exact re-solve")
    assert traj.solver["method"].endswith("Radau IIA collocation on the fixed control grid")
    assert traj.solver["steps_per_interval"] == list(saved["substeps"])
    # every node is a sample
    assert traj.q.shape[0] == saved["t"].size


@pytest.mark.slow
def test_reduced_monoped_exact_plan_hops_over_the_hole(tmp_path):
    """`tfcontact plan monoped --task reduced`: the time-freezing homotopy from the
    start-everywhere guess finds the hop, the exact re-solve makes it a verified plan
    (measured: 778 homotopy iterations, then 458, 122 and 810; objective 176.43, local
    defects summing to 4.2e-3)."""
    assert main(["plan", "monoped", "--task", "reduced", "--out", str(tmp_path),
                 "--quiet"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["success"]
    traj = load_trajectory(tmp_path / "trajectory.npz")
    v = traj.verification
    assert v["passed"] and v["defect_sum"] < v["tolerances"]["end_state"]
    assert v["min_gap"] >= -1e-3 and v["friction_cone_violation"] <= 1e-6
    assert traj.gap.max() > 1e-2  # it leaves the ground
    np.testing.assert_allclose(traj.q[-1], REDUCED_TASK.q_goal, atol=1e-6)
    assert np.abs(traj.u).max() <= REDUCED_TASK.control_bound + 1e-9
    foot = np.asarray(monoped_problem(REDUCED_TASK).foot(traj.q.T)).T
    x_c, a, b = 0.5, REDUCED_TASK.hole_half_width, REDUCED_TASK.hole_depth
    assert np.all(foot[:, 1] >= b * (1 - ((foot[:, 0] - x_c) / a) ** 2) - 1e-6)  # the bump


@pytest.mark.slow
def test_radau_levels_turn_the_rk4_plan_into_a_verified_radau_plan():
    """The chain's last two levels from the saved RK4 plan (what its RK4 levels end
    with): 12 Radau IIA elements per interval fail the exact replay, the mesh refined where
    the local defects are large passes it, 4x closer than the RK4 plan (measured: 262 and
    783 iterations, 8 minutes; defects summing to 8.6e-3 against the RK4 plan's 3.7e-2)."""
    rk4 = np.load(SAVED_PLAN.with_name("monoped_exact_rk4_plan.npz"))
    mp = monoped_problem(EXACT_TASK)
    result = chain_module.run_chain(chain_module.radau_levels(mp),
                                 chain_module.saved_phases(rk4), (rk4["t"], rk4["x"], rk4["u"]),
                                 [], 0.0, verbose=False)
    first, refined = result.steps
    assert first.status == "verification_failed" and refined.status == "converged"
    assert result.success and result.plan.integrator == "radau"
    assert max(result.plan.substeps) == 24 and min(result.plan.substeps) == 12
    v = result.plan.verification
    assert v.defect_sum < 2e-2 and v.min_gap >= -1e-3
    assert result.smallest_hole_value >= -1e-6
    np.testing.assert_allclose(result.plan.boundary_states[-1][:4], EXACT_TASK.q_goal,
                               atol=1e-6)


def test_a_verified_plan_in_a_hole_is_not_a_success():
    """The replay passes but the foot's nodes lie 1e-3 inside a hole: verification_failed."""
    plan = _plan("Solve_Succeeded", 1.0)
    mp = monoped_problem(REDUCED_TASK)
    assert ExactPlan(plan, mp, (), 0.0, 1.0).success
    inside = ExactPlan(plan, mp, (), -1e-3, 1.0)
    assert inside.status == "verification_failed" and not inside.success
    assert ExactPlan(None, mp, (), float("nan"), 1.0, message="no hop").status == "chain_failed"
