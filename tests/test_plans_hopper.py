"""The README's main job end to end: `tfcontact plan hopper --out DIR` (slow, CI runs it)."""

import json
import re

import numpy as np
import pytest

from tfcontact.cli import main
from tfcontact.plan_format import load_trajectory
from tfcontact.scenes.hopper import hopper_task

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def hopper_plan(tmp_path_factory):
    out = tmp_path_factory.mktemp("hopper")
    code = main(["plan", "hopper", "--out", str(out)])
    return code, out


def sidecar_end_x(out):
    return float(load_trajectory(out / "trajectory.npz").q[-1, 0])


def test_plan_command_writes_every_file_and_an_honest_status(hopper_plan):
    code, out = hopper_plan
    for name in ("trajectory.npz", "trajectory.json", "replay.html", "summary.json",
                 "states.png", "clock.png", "contacts.png", "homotopy.png", "collisions.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    sidecar = json.loads((out / "trajectory.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    assert sidecar["robot"]["source"] == "hopper"
    assert sidecar["solver"]["complementarity_residual"] <= 1e-4
    # The exit code, the sidecar and the summary agree: success only with a passed check.
    assert summary["success"] == (code == 0)
    assert summary["success"] == (sidecar["verification"]["passed"]
                                  and sidecar["status"] == "converged")
    # Physical is not enough: the task's goals are measured and reported beside it.
    checks = {c["name"]: c for c in summary["task_checks"]["checks"]}
    assert set(checks) == {"end x", "lift-offs contact 0", "motion"}
    assert summary["success"] == (sidecar["verification"]["passed"]
                                  and summary["task_checks"]["passed"])
    assert checks["end x"]["value"] == pytest.approx(
        abs(sidecar_end_x(out) - hopper_task("short").x_end[0]), abs=1e-9)
    # Every solve is on record (up to 3: a failed plan is solved again from a perturbed
    # guess); only the last may have succeeded, and the plan is the one marked chosen.
    attempts = sidecar["solver"]["attempts"]
    assert 1 <= len(attempts) <= 3
    assert [a["status"] for a in attempts if a["chosen"]] == [sidecar["status"]]
    assert all(a["status"] != "converged" for a in attempts[:-1])
    # Each solve keeps its homotopy's NLPs, the chosen one's the same as the history's.
    for attempt in attempts:
        assert sum(nlp["iterations"] for nlp in attempt["nlps"]) == attempt["iterations"]
    chosen = [a for a in attempts if a["chosen"]][0]
    assert [n["sigma"] for n in chosen["nlps"]] == [h["sigma"] for h in
                                                   sidecar["solver"]["history"]]
    # The URDF's full collision model (base box, foot sphere) along the plan against the
    # ground: clear, the foot (the declared contact) touching it, the base well above.
    collisions = summary["collisions"]
    assert collisions["passed"] and collisions["status"] == "clear", collisions["worst"]
    bodies = {b["body"]: b for b in collisions["bodies"]}
    assert {name: b["contact"] for name, b in bodies.items()} == {"base_0": False,
                                                                  "foot_0": True}
    physical = load_trajectory(out / "trajectory.npz").physical()
    assert bodies["foot_0"]["min_distance"] == pytest.approx(physical.gap[:, 0].min(), abs=1e-9)


def test_hopper_discovers_flight_phases_and_reaches_the_goal(hopper_plan):
    _, out = hopper_plan
    traj = load_trajectory(out / "trajectory.npz")
    task = hopper_task("short")
    gaps = traj.gap[:, 0]
    # It flies (from a start-everywhere guess): the foot is clearly off the ground at
    # some time and back on it later. Landing by T is not asked: the goal is a
    # least-squares terminal cost, and some plans end in a small second hop (measured:
    # 2.7 mm up at T from one of four starts moved by 1e-9; 3.3 mm on an AVX-512 machine).
    assert gaps.max() > 0.05
    assert gaps.min() > -1e-3
    assert np.any(np.abs(gaps[np.argmax(gaps):]) < 1e-3)
    # The terminal cost pulls the base to x_goal; tolerance 5 cm (a least-squares goal).
    assert abs(traj.q[-1, 0] - task.x_end[0]) < 0.05
    assert abs(traj.clock[-1] - task.horizon) < 1e-6
    assert np.all(np.diff(traj.clock) >= -1e-9)


def test_hopper_plan_passes_the_independent_verification(hopper_plan):
    code, out = hopper_plan
    sidecar = json.loads((out / "trajectory.json").read_text())
    verification = sidecar["verification"]
    assert verification["passed"] is True
    assert code == 0
    # Checked against the event-detecting simulation of the original system, which lands
    # the hopper with real impacts (touch-downs after the flight phases).
    assert verification["method"].startswith("event-detecting reference")
    assert int(re.search(r"(\d+) impacts", verification["method"]).group(1)) >= 1
    assert verification["end_state_deviation"] <= verification["tolerances"]["end_state"]


LONG_ROUND_OFF = pytest.mark.xfail(strict=False, reason=(
    "round-off decides the long plan: on a Zen 3 EPYC without AVX-512 (2026-11-29, fresh "
    "venv, the landed code) its one attempt ended verification_failed with a local defect "
    "of 0.36 in interval 4 of 30 (the others at most 3e-3); it passed on the two machines "
    "first measured"))
"""The long task's verdict depends on the machine's round-off (benchmarks/hopper_bench.md)."""


@pytest.fixture(scope="module")
def long_plan(tmp_path_factory):
    """TF-8's long task (`--task long`, about 2 minutes)."""
    out = tmp_path_factory.mktemp("hopper_long")
    code = main(["plan", "hopper", "--task", "long", "--out", str(out), "--quiet"])
    return code, json.loads((out / "trajectory.json").read_text()), out


def test_long_task_reports_what_it_measured(long_plan):
    """Whatever round-off does to the homotopy and the replay, the exit code, the status
    and the verification agree, and the sidecar keeps the solve's record."""
    code, sidecar, _ = long_plan
    verification = sidecar["verification"]
    assert (code == 0) == (sidecar["status"] == "converged")
    if sidecar["status"] in ("converged", "verification_failed"):  # the homotopy converged
        assert verification["passed"] == (sidecar["status"] == "converged")
    attempts = sidecar["solver"]["attempts"]
    assert len(attempts) == 1 and attempts[0]["status"] == sidecar["status"]
    assert len(verification["local_defects"]) == 30
    # Every NLP is on record, refined steps marked, at most `max_refinements` of them
    # (on an AVX-512 EPYC one: sigma = 3.2e-4 after NLP 5 failed).
    solver = sidecar["solver"]
    refinements = solver["settings"]["homotopy"]["max_refinements"]
    assert refinements == 3
    history = solver["history"]
    assert len(history) == solver["nlp_count"] == len(solver["iterations_per_nlp"])
    assert sum(step["refined"] for step in history) <= refinements
    solved = [s["ipopt_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
              for s in history]
    for i, step in enumerate(history):
        if step["refined"]:  # right after a failed NLP, between its sigma and the last solved
            assert i >= 2 and not solved[i - 1]
            last_solved = max(j for j in range(i - 1) if solved[j])
            assert history[i - 1]["sigma"] < step["sigma"] < history[last_solved]["sigma"]


@LONG_ROUND_OFF
def test_long_task_hops_twice_reaches_the_goal_and_keeps_to_the_dynamics(long_plan):
    """What held for the long plans measured (benchmarks/hopper_bench.md): the homotopy
    converges to two or more hops that reach the goal (on an AVX-512 EPYC only with the
    homotopy's step refinement: without it NLP 5 fails, nlp_failed); restarted at each
    control interval from the plan's own state, the exact-impact reference ends within 0.1
    of the plan's next state
    (measured in the sixth session: at most 6.2e-3 in four plans, 5.2e-2 in the fifth,
    where its replay lands 4 ms after the plan; plans of other settings reached 0.19 and
    1.4); gaps, friction cone, maximal dissipation and clock pass."""
    code, sidecar, out = long_plan
    assert sidecar["status"] in ("converged", "verification_failed"), sidecar["status"]
    verification = sidecar["verification"]
    # Whatever round-off does to the replay, the status and exit code say what it measured.
    assert (code == 0) == (sidecar["status"] == "converged") == verification["passed"]
    deviation, tol = verification["end_state_deviation"], verification["tolerances"]["end_state"]
    if deviation > tol:
        # only as an open-loop unstable plan whose local defects add up to the tolerance
        assert verification["passed"] == verification["open_loop_unstable"]
        if verification["open_loop_unstable"]:
            assert verification["defect_sum"] <= tol
            assert verification["open_loop_amplification"] * verification["defect_sum"] \
                >= deviation
    assert verification["method"].startswith("event-detecting reference")
    defects = np.asarray(verification["local_defects"], dtype=float)
    assert defects.size == 30 and np.count_nonzero(np.isfinite(defects)) >= 20
    assert np.nanmax(defects) < 0.1
    assert verification["min_gap"] >= -verification["tolerances"]["gap"]
    assert verification["friction_cone_violation"] < 1e-3
    assert verification["dissipation_violation"] < 1e-3
    assert verification["clock_monotone"] and verification["clock_end_error"] < 1e-6
    traj = load_trajectory(out / "trajectory.npz")
    task = hopper_task("long")
    airborne = traj.gap[:, 0] > 0.02
    take_offs = np.count_nonzero(airborne[1:] & ~airborne[:-1])
    assert take_offs >= 2
    assert abs(traj.q[-1, 0] - task.x_end[0]) < 0.05


@LONG_ROUND_OFF
def test_long_task_passes_the_verification(long_plan):
    """From this start the plan passes on both machines measured (1.1e-2 from its replay on
    an x86_64 without AVX-512 and, with the step refinement, on an AVX-512 EPYC). Which plan
    the homotopy reaches depends on round-off: from starts moved by +-1e-9 and +-2e-9 m
    four of five passed on each machine, one failed its replay (benchmarks/hopper_bench.md,
    sixth and ninth sessions, 2026-11-25)."""
    code, sidecar, _ = long_plan
    assert sidecar["verification"]["passed"] is True and code == 0


def test_short_plan_passes_the_verification_when_round_off_moves_the_iterates():
    """IPOPT's tolerance 1e-9 instead of 1e-8 moves every iterate by round-off (a stand-in
    for another machine's BLAS): the plan, with the task's restarts, must still pass.
    With the unscaled gap (gap_scale = 1) both ended 17 away from their replay on one
    machine (benchmarks/hopper_bench.md, robustness)."""
    from dataclasses import replace

    from tfcontact.ocp.contact import solve_contact
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    _, _, problem = hopper_problem("short")
    options = hopper_options("short")
    options = replace(options, nlp=replace(options.nlp, tol=1e-9))
    result = solve_contact(problem, options, verbose=False)
    assert result.success, result.summary()
    assert result.physical.gaps[:, 0].max() > 0.05  # it flies


def test_bench_task_with_loose_stepping_stones_passes_the_verification():
    """The configuration of the speed comparison (scripts/bench_hopper.py): the homotopy's
    stepping-stone NLPs solved only to IPOPT tolerance 0.1, the last to 1e-8. Its plan must
    pass the same checks as every plan (benchmarks/hopper_bench.md, seventh session)."""
    from tfcontact.ocp.contact import solve_contact
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    _, _, problem = hopper_problem("bench")
    options = hopper_options("bench")
    assert options.nlp.intermediate_tol == pytest.approx(0.1)
    result = solve_contact(problem, options, verbose=False)
    assert result.success, result.summary()
    steps = result.ocp.mpcc_result.history
    assert [s.intermediate for s in steps] == [True] * (len(steps) - 1) + [False]
    assert result.physical.gaps[:, 0].max() > 0.05  # it flies
    assert result.verification.end_state_deviation <= options.verify.end_state_tolerance
