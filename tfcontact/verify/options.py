"""The settings of a plan's verification (`VerifyOptions`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from tfcontact.errors import InvalidInput
from tfcontact.verify.methods import AutoReplay, Replay


@dataclass(frozen=True)
class VerifyOptions:
    """How a plan is checked (see `Verification`).

    Args:
        replay: how the plan's controls are re-simulated for the end-state check:
            `ExactReplay()` (the event-detecting integration of the original system with
            impacts, `simulate_impacts`: one contact, or several frictionless elastic
            ones), `MultiContactReplay()` (the event-driven simulator of several
            frictional inelastic contacts, `simulate_multicontact`),
            `FesdReplay(refinement=4, scheme=RadauIIA(3), relaxation=Scholtes())` (the FESD
            simulator on a finer grid) or `AutoReplay(fallback=FesdReplay())` (the exact
            replay where it applies, else the multi-contact one where that applies and
            succeeds, else the fallback).
        end_state_tolerance: of the end-state deviation [state units].
        gap_tolerance: the penetration allowed [m]; also the gap below which a contact
            counts as closed (its impulses and slip are checked).
        cone_tolerance: of the friction-cone and maximal-dissipation violations, relative
            to the largest normal impulse of the plan [-]: the impulses recovered from the
            plan's collocation polynomials carry its relaxed complementarity and quadrature
            errors, proportional to them.
        clock_tolerance: of the clock's decrease and its end error [s].

    Raises:
        InvalidInput: `replay` is not a `Replay` object, or a tolerance is not a positive
            number.
    """

    replay: Replay = field(default_factory=AutoReplay)
    end_state_tolerance: float = 5e-2
    gap_tolerance: float = 1e-3
    cone_tolerance: float = 1e-2
    clock_tolerance: float = 1e-6

    def __post_init__(self) -> None:
        if not isinstance(self.replay, Replay):
            raise InvalidInput(
                f"`replay` must be a Replay object (ExactReplay(), FesdReplay(...) or "
                f"AutoReplay()), got {self.replay!r}")
        for name in ("end_state_tolerance", "gap_tolerance", "cone_tolerance",
                     "clock_tolerance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not (math.isfinite(value) and value > 0):
                raise InvalidInput(f"`{name}` must be a positive number, got {value!r}")
