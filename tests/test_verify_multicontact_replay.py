"""The multi-contact replay (`MultiContactReplay`, and `AutoReplay`'s choice of it) on a
real two-contact frictional time-freezing plan solved by the library: a box on two contact
spheres pushed along the ground."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from two_contact_box import pushed_box_problem, solved_plan

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.verify import (
    AutoReplay,
    EvaluationBudget,
    ExactReplay,
    FesdReplay,
    MultiContactOptions,
    MultiContactReplay,
    TimeFreezingPlan,
    VerifyOptions,
    check_time_freezing_plan,
)

# A 2 kg box on two 0.1 m contact spheres 0.4 m apart whose centres are at the body's
# height: the friction acts at the centres, so a horizontal push gives no pitch moment and
# the normal forces split evenly (the impulses the checks recover are then unique).
MU = 0.4
N_INTERVALS = 4


@pytest.fixture(scope="module")
def pushed_box(tmp_path_factory) -> TimeFreezingPlan:
    """The box pushed from rest towards x = 0.15 m in 0.6 s: it slides and comes to a
    stop on both contacts (measured: solved in 3 s, 525 IPOPT iterations)."""
    return solved_plan(pushed_box_problem(tmp_path_factory.mktemp("box"), MU, 0.2, 0.0))


def test_the_replays_that_take_two_frictional_inelastic_contacts(pushed_box):
    cls = pushed_box.system.cls
    assert cls.n_contacts == 2 and all(c.mu == MU and c.restitution == 0
                                       for c in cls.contacts)
    assert not ExactReplay.applies_to(cls) and MultiContactReplay.applies_to(cls)
    with pytest.raises(IncompatibleOptions, match="several contacts needs them frictionless"):
        check_time_freezing_plan(pushed_box, VerifyOptions(replay=ExactReplay()))


def test_auto_replay_checks_a_two_contact_plan_with_the_multicontact_reference(pushed_box):
    """`AutoReplay` (the default) replays the plan with the event-driven multi-contact
    simulator: the end state and every local defect agree to the plan's tolerances
    (measured: end-state deviation 9.1e-8, defects <= 3.7e-7, 0.07 s; interval 3's
    restart, inside the ground and separating, took the event cap (defect inf) with the
    velocity tolerance 1e-7 before the simulator landed such starts back at their depth:
    2.5e-8 now)."""
    auto = check_time_freezing_plan(pushed_box)
    assert auto.passed, auto.summary()
    assert auto.method.startswith("event-driven multi-contact reference (DOP853, contact "
                                  "LCPs, inelastic frictional impacts), 0 impacts")
    assert auto.end_state_deviation < 1e-6
    assert len(auto.local_defects) == N_INTERVALS and max(auto.local_defects) < 1e-5
    assert not any("FESD" in note for note in auto.notes)
    direct = check_time_freezing_plan(pushed_box, VerifyOptions(replay=MultiContactReplay()))
    assert direct.summary() == auto.summary()


def test_a_plan_with_scaled_controls_fails_the_multicontact_replay(pushed_box):
    """The same states with the push scaled by 1.5: the replay slides further than the
    plan, so the end-state check fails and the local defects show where (measured:
    end-state deviation 0.18, first interval's defect 0.64)."""
    u = pushed_box.u.copy()
    n_u = pushed_box.system.cls.n_u
    u[:, :n_u] *= 1.5
    tampered = replace(pushed_box, u=u)
    verification = check_time_freezing_plan(tampered)
    assert verification.method.startswith("event-driven multi-contact reference")
    assert not verification.passed
    assert verification.end_state_deviation > VerifyOptions().end_state_tolerance
    assert max(verification.local_defects) > VerifyOptions().end_state_tolerance


def test_auto_replay_falls_back_to_fesd_when_the_multicontact_simulation_stops(pushed_box):
    """A multi-contact simulation that stops with a status (here its evaluation budget)
    fails `MultiContactReplay`'s verification, the status and where it stopped in the
    notes; `AutoReplay` says which status and why and replays with its FESD fallback,
    keeping the multi-contact local defects (inf: stopped too)."""
    starved = MultiContactReplay(simulation=MultiContactOptions(max_rhs_evaluations=20))
    stopped = check_time_freezing_plan(pushed_box, VerifyOptions(replay=starved))
    assert not stopped.passed and stopped.end_state_deviation == np.inf
    assert stopped.method == "event-driven multi-contact reference (stopped)"
    assert stopped.notes[0].startswith("multi-contact reference stopped at t = ")
    assert "with status max_rhs_evaluations: stopped after 20" in stopped.notes[0]
    auto = check_time_freezing_plan(pushed_box, VerifyOptions(replay=AutoReplay(
        fallback=FesdReplay(refinement=2), multicontact=starved)))
    assert auto.method.startswith("FESD re-simulation, 8 steps")
    assert auto.notes[0].startswith("multi-contact reference stopped at t = ")
    assert "with status max_rhs_evaluations: stopped after 20 model evaluations" \
        in auto.notes[0]
    assert auto.notes[0].endswith("; FESD used")
    assert np.all(np.isinf(auto.local_defects))


def test_the_check_stops_when_its_evaluation_budget_is_used_up(pushed_box):
    """One budget for the open-loop replay and every local-defect restart. The open-loop
    replay decides (the local defects are diagnostics here): with 300 evaluations it runs,
    the plan passes, and the restarts after the budget is used up are not run (inf), the
    notes saying how many; with 50 the open-loop replay itself stops and the plan fails."""
    full = check_time_freezing_plan(pushed_box, VerifyOptions(replay=MultiContactReplay()))
    assert full.passed and np.all(np.isfinite(full.local_defects))
    assert not any("budget" in n for n in full.notes)
    short = check_time_freezing_plan(pushed_box, VerifyOptions(
        replay=MultiContactReplay(budget=300)))
    assert short.passed
    assert short.end_state_deviation == full.end_state_deviation
    note = next(n for n in short.notes if "budget" in n)
    assert note.startswith("the multi-contact reference used up its budget of 300 model "
                           "evaluations")
    skipped = int(note.split(": ")[1].split()[0])
    assert 1 <= skipped < N_INTERVALS
    assert np.isfinite(short.local_defects[0])  # the first restart ran
    assert np.isinf(short.local_defects[-skipped:]).all()
    starved = check_time_freezing_plan(pushed_box, VerifyOptions(
        replay=MultiContactReplay(budget=50)))
    assert not starved.passed and starved.end_state_deviation == np.inf
    assert "with status max_rhs_evaluations: stopped after 50" in starved.notes[0]
    assert np.isinf(starved.local_defects).all()
    with pytest.raises(InvalidInput, match="`budget` must be a positive integer"):
        MultiContactReplay(budget=0)


def test_a_budget_caps_each_simulation_at_what_is_left():
    budget = EvaluationBudget(100)
    options = MultiContactOptions(max_rhs_evaluations=1000)
    assert budget.options(options).max_rhs_evaluations == 100
    budget.spend(70)
    assert budget.options(options).max_rhs_evaluations == 30 and not budget.exhausted
    budget.spend(40)
    assert budget.exhausted and budget.options(options).max_rhs_evaluations == 1
    assert budget.options(MultiContactOptions(max_rhs_evaluations=10)).max_rhs_evaluations == 1


def test_replay_options_are_checked():
    with pytest.raises(InvalidInput, match="`simulation` must be a MultiContactOptions, "
                                           "got 3"):
        MultiContactReplay(simulation=3)
    with pytest.raises(InvalidInput, match=r"`multicontact` must be a MultiContactReplay, "
                                           r"got FesdReplay\("):
        AutoReplay(multicontact=FesdReplay())
    assert AutoReplay() == AutoReplay(FesdReplay(), MultiContactReplay())
    # The simulator's own velocity tolerance (1e-7 m/s): restarts inside the ground that
    # separate slightly land back at their depth (no event cap, test_verify_multicontact).
    assert MultiContactReplay().simulation == MultiContactOptions()


def test_a_replay_that_ran_to_t_is_handed_over_at_its_boundaries(pushed_box):
    """A replay that ran to T comes with itself at the boundaries before T (`parted`:
    where `end_state_check` judges the plan should the kicked replays to T stop): its
    deviation from the plan at each (the plan followed: below 1e-5), and its `replay_to`
    from the start runs to a boundary's state."""
    outcome = MultiContactReplay().run(pushed_box, VerifyOptions().gap_tolerance, [])
    parted = outcome.parted
    assert outcome.stopped is None and parted is not None
    assert len(parted.deviations) == N_INTERVALS and max(parted.deviations) < 1e-5
    k = N_INTERVALS - 1
    np.testing.assert_allclose(parted.replay_to(pushed_box.replayed().x0, k),
                               parted.states[k], atol=1e-7)
