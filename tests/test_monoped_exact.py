"""TF-9's monoped as stages (tfcontact.scenes.monoped_exact): the reduced hop's start, the
tiled guess and the schedule search, the Radau levels, the files `tfcontact plan monoped`
writes, and the reduced task end to end (slow: about 4 minutes). The Radau levels on the
saved RK4 plan (slow: about 12 minutes) are in tests/test_monoped_radau_levels.py, a file
of their own so that the test runner's two workers share the two longest tests. The chain's
own rules (iteration caps, failures, refined meshes) are tested in tests/test_ocp_chain.py."""

from __future__ import annotations

import dataclasses
import json
import types
from pathlib import Path

import numpy as np
import pytest
from stand_in_plans import SAVED_PLAN, saved_plan, stand_in_plan

import tfcontact.ocp.chain as chain
import tfcontact.scenes.monoped_exact as monoped_exact
from tfcontact.cli import main
from tfcontact.errors import InvalidInput
from tfcontact.ocp.chain import ResolveChain, resolve_chain
from tfcontact.ocp.polish import FLIGHT, STICK, Phase, PolishedPlan
from tfcontact.plan_format import load_trajectory
from tfcontact.plan_format.resolved import load_resolved_plan
from tfcontact.scenes.monoped import REDUCED_TASK, monoped_problem
from tfcontact.scenes.monoped_exact import (
    EXACT_TASK,
    HAND_SET_SCHEDULE,
    OneHopWithSlip,
    Schedule,
    TiledHops,
    tiled_guess,
    verify_saved,
)
from tfcontact.scenes.pipeline import NoStart, Plan, PlanOutcome, StageInput


def test_the_radau_levels_refine_the_mesh_where_the_local_defects_are_large(monkeypatch):
    """The Radau levels: 12 elements per interval with the cone 2 % inside, then that mesh
    doubled where its local defects exceed 0.05 / 20 (intervals 3 and 7 here)."""
    seen = []
    defects = [1e-4] * 20
    defects[3], defects[7] = 0.03, float("nan")

    def fake_polish(problem, phases, options, *, guess, verbose):
        seen.append(options)
        plan = stand_in_plan("Solve_Succeeded", 1.0, verification=types.SimpleNamespace(
            passed=True, summary=str, local_defects=tuple(defects)))
        return dataclasses.replace(plan, integrator=options.integrator,
                                   substeps=options.substeps_per_interval(20))

    monkeypatch.setattr(chain, "polish_contact", fake_polish)
    monkeypatch.setattr(chain, "path_violation", lambda problem, plan: 0.0)
    mp = monoped_problem(EXACT_TASK)
    result = resolve_chain(monoped_exact.radau_levels(mp.problem), (Phase(STICK, 0, 2.5),),
                           None, verbose=False)
    assert result.status == "converged" and len(seen) == 2
    assert seen[0].integrator == "radau" and seen[0].substeps == 12
    assert seen[0].cone_margins == (0.98,)
    expected = [12] * 20
    expected[3] = expected[7] = 24
    assert seen[1].substeps == tuple(expected) and seen[1].integrator == "radau"
    assert seen[1].cone_margins == (0.98,)


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
    # the hop's own phases cut it: a hop landing at 0.8 s fills the first flight slot
    # (0.5-0.76 s) with its q_x from 0.6 to 0.8 m
    phases = (*hop.phases[:2], Phase(FLIGHT, 0.6, 0.8), Phase(STICK, 0.8, 1.0))
    (t_guess, x_guess, _), _ = tiled_guess(dataclasses.replace(hop, phases=phases),
                                           EXACT_TASK)
    flight = slice(25, 50)  # each segment is 25 samples: the first stance, the flight
    np.testing.assert_allclose(t_guess[flight][[0, -1]], [0.5, 0.76])
    np.testing.assert_allclose(x_guess[flight, 0][[0, -1]], [0.6, 0.8])


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
    schedules = monoped_exact.uniform_schedules(_hop())
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
        return stand_in_plan(*outcomes[lift_off])

    monkeypatch.setattr(monoped_exact, "polish_contact", fake_polish)
    mp = monoped_problem(EXACT_TASK)
    schedules = tuple(Schedule((a, a + 0.75), 0.26) for a in outcomes)
    best, trials = monoped_exact.search_schedule(_hop(), schedules, mp.problem, None,
                                                 verbose=True)
    assert seen == list(outcomes) and len(trials) == 4
    out = capsys.readouterr().out  # a line as each candidate starts, one as it ends
    assert "monoped: schedule 2 of 4, lift-offs 0.5, 1.25 s" in out
    assert "  IPOPT Infeasible_Problem_Detected, 7 iterations" in out
    assert best.schedule.lift_offs == (0.625, 1.375) and best.plan.cost == 190.0
    outcomes.update({0.375: ("Infeasible_Problem_Detected", 1.0),
                     0.625: ("Restoration_Failed", 1.0)})
    best, trials = monoped_exact.search_schedule(_hop(), schedules, mp.problem, None,
                                                 verbose=False)
    assert best is None and len(trials) == 4


def _after_reduced(chain_status: str = "Solve_Succeeded", task: str = "full") -> StageInput:
    """What the full task's stage gets: the reduced hop's exact re-solve before it."""
    quiet = types.SimpleNamespace(passed=True, summary=str, local_defects=(1e-4,) * 20)
    hop = dataclasses.replace(_hop(), verification=quiet, ipopt_status=chain_status)
    reduced = ResolveChain(hop, monoped_problem(REDUCED_TASK).problem,
                           (chain.ChainStep.of("exact re-solve, 8 nodes", hop, 1.0),), 0.0, 1.0)
    before = PlanOutcome(None, None, reduced.status, reduced.success, "reduced", chain=reduced)
    return StageInput("monoped", task, Path("."), False, None, before)


def test_the_searched_schedule_s_re_solve_starts_the_rest_of_the_chain(monkeypatch):
    """With "search": every candidate is a step of the chain, the cheapest solved one's
    plan is the next re-solve's guess, and the chain skips its own first level."""
    quiet = types.SimpleNamespace(passed=True, summary=str, local_defects=(1e-4,) * 20)
    costs = iter([203.0, 190.0, 223.0, 446.0, 205.0, 191.0, 191.5, 192.6, 192.6])
    guesses = []

    def fake_polish(problem, phases, options, *, guess, verbose):
        guesses.append(guess)
        cost = next(costs)
        return stand_in_plan("Solve_Succeeded", cost, shift=cost, verification=quiet)

    monkeypatch.setattr(monoped_exact, "polish_contact", fake_polish)
    monkeypatch.setattr(chain, "polish_contact", fake_polish)
    monkeypatch.setattr(chain, "path_violation", lambda problem, plan: 0.0)
    stage = monoped_exact.STAGES[2]
    levels = monoped_exact.full_levels(monoped_exact.full_setup())
    start = stage.start.begin(_after_reduced(), levels)
    assert start.skip_levels == 1
    result = resolve_chain(levels[start.skip_levels:], start.phases, start.guess,
                           steps=start.steps, verbose=False)
    names = [step.name for step in result.steps]
    assert names[0] == "exact re-solve, 8 nodes"  # the reduced hop's steps come first
    # 5 candidates, then 3 levels: the refined mesh is the 12-element one (every local
    # defect within its share), the same NLP, so not solved again
    assert len(names) == 1 + 5 + 3 and all("lift-offs" in n for n in names[1:6])
    assert names[-1].startswith("full task, TF-9's ellipses, Radau IIA order 5, 12 elements")
    assert "lift-offs 0.375, 1.125, 1.875 s" in names[2] and result.steps[2].objective == 190.0
    assert names[6] == "full task, bump holes, 16 nodes x 2 RK4 steps"
    assert guesses[5][1][0, 0] == 190.0  # the chosen candidate's states
    assert result.status == "converged" and result.plan.cost == 192.6


def test_the_hand_set_schedule_is_followed_from_the_chain_s_first_level():
    levels = monoped_exact.full_levels(monoped_exact.full_setup())
    start = monoped_exact.STAGES[2].start.begin(_after_reduced(task="hand-set"), levels)
    assert start.skip_levels == 0
    assert [p.start for p in start.phases if p.mode == FLIGHT] == list(HAND_SET_SCHEDULE.lift_offs)


def test_the_hops_are_tiled_only_from_a_verified_reduced_hop(monkeypatch):
    with pytest.raises(NoStart, match="the reduced hop is not verified \\(nlp_failed"):
        TiledHops({"full": "search"}).begin(_after_reduced("Infeasible_Problem_Detected"), ())
    monkeypatch.setattr(monoped_exact, "polish_contact",
                        lambda *a, **k: stand_in_plan("Infeasible_Problem_Detected", 1.0))
    levels = monoped_exact.full_levels(monoped_exact.full_setup())
    with pytest.raises(NoStart, match="no schedule of 5 gave a solved re-solve"):
        TiledHops({"full": "search"}).begin(_after_reduced(), levels)


def test_an_unknown_schedule_is_refused():
    with pytest.raises(InvalidInput, match="a schedule must be a Schedule or 'search'"):
        TiledHops({"full": "hand"})


def test_the_reduced_hop_is_followed_with_a_slip_before_its_lift_off(monkeypatch):
    """The discovered stick, flight, stick becomes stick, slip, flight, stick with the slip
    from 0.55 s; another sequence gives no start, with the sequence named."""
    found = (Phase(STICK, 0.0, 0.6), Phase(FLIGHT, 0.6, 0.88), Phase(STICK, 0.88, 1.0))
    monkeypatch.setattr(monoped_exact, "contact_phases", lambda result: found)
    monkeypatch.setattr(monoped_exact, "discovery_step", lambda result: None)
    given = StageInput("monoped", "reduced", Path("."), False, None,
                       PlanOutcome(None, None, "converged", True, "", result=object()))
    start = OneHopWithSlip().begin(given, ())
    assert [(p.mode, p.start, p.end) for p in start.phases] == [
        (STICK, 0.0, 0.55), ("slip-", 0.55, 0.6), (FLIGHT, 0.6, 0.88), (STICK, 0.88, 1.0)]
    monkeypatch.setattr(monoped_exact, "contact_phases", lambda result: found[:1])
    with pytest.raises(NoStart, match="not one hop lifting off after 0.55 s"):
        OneHopWithSlip().begin(given, ())


@pytest.mark.parametrize("lift_offs, flight, match", [
    ((), 0.26, "needs lift-offs"), ((0.5, 1.0), 0.0, "positive flight"),
    ((0.5, 0.7), 0.26, "after the last one landed"), ((0.0, 1.0), 0.26, "after t = 0")])
def test_a_schedule_whose_hops_overlap_is_refused(lift_offs, flight, match):
    with pytest.raises(InvalidInput, match=match):
        Schedule(lift_offs=lift_offs, flight_time=flight)


def test_a_schedule_landing_after_the_horizon_is_refused():
    with pytest.raises(InvalidInput, match="lands after the horizon"):
        tiled_guess(None, EXACT_TASK, Schedule(lift_offs=(0.5, 2.375), flight_time=0.26))


def test_plan_monoped_searches_its_schedule_unless_asked_for_the_hand_set_one():
    """The full task (the default) searches the schedule, `--task hand-set` follows
    `HAND_SET_SCHEDULE`, `--task reduced` stops after the reduced hop."""
    plan = monoped_exact.STAGES
    assert plan[2].start.schedules == {"full": "search", "hand-set": HAND_SET_SCHEDULE}
    assert plan[2].tasks == ("full", "hand-set") and plan[1].tasks is None
    # --task terrain: the same search, then the terrain holes' Radau levels
    assert plan[3].start.schedules == {"terrain": "search"} and plan[3].tasks == ("terrain",)
    setup = monoped_exact.terrain_setup()
    levels = monoped_exact.terrain_levels(setup)
    full = monoped_exact.full_levels(monoped_exact.full_setup())
    assert [level.name for level in levels[:len(full)]] == [level.name for level in full]
    assert [level.problem for level in levels[len(full):]] == [setup.problem] * 2
    assert levels[len(full)].options.touchdown_rate == monoped_exact.TERRAIN_TOUCHDOWN_RATE
    assert setup.scene["terrain"]["primitives"][1]["kind"] == "hole"


def test_plan_monoped_writes_plan_trajectory_and_replay(monkeypatch, tmp_path, capsys):
    """`tfcontact plan monoped` writes the exact plan's node file (verified again from the
    file), its trajectory with the three touchdowns as frozen pieces carrying the
    impulses, the figures and the replay; the stages are replaced by the saved plan."""
    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import Stage, resolved_outcome

    saved = load_resolved_plan(SAVED_PLAN)
    verification, holes = verify_saved(SAVED_PLAN)
    plan = saved_plan(verification, cost=236.9)
    setup = monoped_exact.full_setup()
    resolved = ResolveChain(plan, setup.problem, (), chain.path_violation(setup.problem, plan),
                            1.0)

    class Saved(Stage):
        name = "saved"

        def run(self, given):
            return resolved_outcome(resolved, setup, None)

    monkeypatch.setitem(plans.PLANS, "monoped", Plan("monoped", "saved", ("full",), (Saved(),)))
    assert main(["plan", "monoped", "--out", str(tmp_path)]) == 0
    assert "plan monoped (full): converged" in capsys.readouterr().out
    for name in ("plan.npz", "trajectory.npz", "trajectory.json", "replay.html", "path.png",
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
    assert traj.solver["steps_per_interval"] == list(saved.substeps)
    assert traj.solver["path_violation"] <= chain.PATH_TOLERANCE
    assert [h["x_c"] for h in traj.scene["holes"]] == [0.5, 1.5, 2.5]
    # every node is a sample
    assert traj.q.shape[0] == saved.t.size


def test_a_failed_re_solve_whose_node_times_run_back_is_written_as_failed(
        monkeypatch, tmp_path, capsys):
    """An NLP stopped infeasible can leave a switch past its neighbouring nodes (measured:
    the reduced hop's 8-node level, node times dropping from 0.5 to 0.4957 s). Its
    iterate has no trajectory, but the plan ends with its failed status, its summary and
    its nodes written, not with an error that loses them."""
    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import Stage, resolved_outcome

    checked = types.SimpleNamespace(passed=False, summary=lambda: "FAILED",
                                    local_defects=(np.inf,) * 10)
    iterate = stand_in_plan("Infeasible_Problem_Detected", 737.0, verification=checked)
    iterate = dataclasses.replace(iterate, t=np.array([0.0, 0.25, 0.5, 0.4957, 1.0]))
    setup = monoped_exact.full_setup()
    failed = ResolveChain(iterate, setup.problem, (), 0.0, 1.0, message="infeasible")

    class Failed(Stage):
        name = "failed"

        def run(self, given):
            return resolved_outcome(failed, setup, None)

    monkeypatch.setitem(plans.PLANS, "monoped", Plan("monoped", "failed", ("full",),
                                                     (Failed(),)))
    assert main(["plan", "monoped", "--out", str(tmp_path)]) == 1
    assert "plan monoped (full): nlp_failed" in capsys.readouterr().out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "nlp_failed" and not summary["success"]
    assert "node times decrease" in summary["summary"]
    assert (tmp_path / "plan.npz").is_file() and not (tmp_path / "trajectory.npz").exists()


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason=(
    "round-off decides the reduced hop's discovery: on a Zen 3 EPYC without AVX-512 "
    "(2026-11-29, fresh venv, the landed code) its relaxed plan never lifted the foot "
    "(contact sequence stick only, lift-offs 0 of 1, the foot 5 mm through the ground "
    "at 0.59 s), so the exact re-solve did not start: status collision, exit code 1; "
    "in a later run there its homotopy capped (nlp_failed, 7150 IPOPT iterations) and "
    "restarts from seeds 1 and 2 found no single hop (a failed discovery is now reported "
    "with its own status, nlp_failed, not collision). It hopped and was verified on the "
    "machines first measured"))
def test_reduced_monoped_exact_plan_hops_over_the_hole(tmp_path):
    """`tfcontact plan monoped --task reduced`: the time-freezing homotopy from the
    start-everywhere guess finds the hop, the exact re-solve makes it a verified plan
    (measured with element derivatives and the terminal rows the last stance holds left
    to it: 778 homotopy iterations, then 737, 57 and 35; objective 79.86, local defects
    summing to 1.5e-3; 68 s, 0.6 GB)."""
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


def test_the_scene_draws_the_holes_the_problem_keeps_out():
    from tfcontact.scenes.monoped import hole_profile

    scene = monoped_problem(REDUCED_TASK).scene()
    np.testing.assert_array_equal(scene["holes"][0]["profile"],
                                  hole_profile(REDUCED_TASK, 0.5))


def test_a_saved_plan_is_checked_again_from_the_command_line(tmp_path):
    """`python -m tfcontact.scenes.monoped_exact PLAN.npz` (the README's command): exit 0 on
    the saved plan, 1 on the plan with one torque moved, and no warning on the way (the
    scene module loads without `tfcontact.scenes` importing it first)."""
    import subprocess
    import sys

    def check(path):
        return subprocess.run([sys.executable, "-W", "error", "-m",
                               "tfcontact.scenes.monoped_exact", str(path)],
                              capture_output=True, text=True, timeout=300)

    passed = check(SAVED_PLAN)
    assert passed.returncode == 0, passed.stderr
    assert "verification PASSED" in passed.stdout and not passed.stderr
    saved = dict(np.load(SAVED_PLAN))
    saved["u"] = saved["u"].copy()
    saved["u"][4, 0] += 0.5
    moved = tmp_path / "moved.npz"
    np.savez(moved, **saved)
    failed = check(moved)
    assert failed.returncode == 1 and "verification FAILED" in failed.stdout
