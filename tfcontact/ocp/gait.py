"""Which gait a legged plan shows: its swings grouped into the feet that lift together,
and for four legs the gait's name (pronk, trot, pace, bound, walk).

A report, not a goal: a discovery finds the contact sequence, and this names what it
found (issue 30 asks which gait emerged). Read from a plan's motion in physical time
(gaps) and where each foot sits relative to the base (front or hind, left or right).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.ocp.goals import sample_runs

# Pairs of legs lifting together, by how they sit: (same front/hind, same side).
PAIR_GAITS = {(False, False): "trot", (False, True): "pace", (True, False): "bound"}


@dataclass(frozen=True)
class Swing:
    """Contact `contact` off the ground from `start` to `end` [s], rising above the
    gait's height in between."""

    contact: int
    start: float
    end: float


@dataclass(frozen=True)
class GaitReport:
    """A plan's gait: `groups`, the contacts' names lifting together, in the order of
    their lift-offs, and `name`: "pronk" (all four), "trot" (diagonal pairs), "pace"
    (same-side pairs), "bound" (front pair, hind pair), "walk" (one foot at a time),
    "mixed" (other groups), "standing" (no swing), or "" (not four legs split two
    front, two hind, two left, two right)."""

    name: str
    groups: tuple[tuple[str, ...], ...]

    def line(self) -> str:
        swings = ", ".join("+".join(g) for g in self.groups) or "none"
        return f"gait: {self.name or 'unnamed'} (swings in order: {swings})"

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "groups": [list(g) for g in self.groups]}


def swings_of(t: np.ndarray, gaps: np.ndarray, height: float, touch: float = 1e-3
              ) -> list[Swing]:
    """Every swing of every contact: a run of samples with its gap above `touch` [m] that
    follows a sample at or below it (a lift-off, not a start in the air) and rises to at
    least `height` [m] (a step, not a skim), in the order of their lift-offs."""
    t = np.asarray(t, dtype=float).reshape(-1)
    gaps = np.asarray(gaps, dtype=float).reshape(t.size, -1)
    if not 0 < touch < height:
        raise InvalidInput(f"need 0 < touch < height, got {touch}, {height}")
    found = []
    for i, column in enumerate(gaps.T):
        for a, b in sample_runs(column > touch):
            if a > 0 and column[a:b + 1].max() >= height:
                found.append(Swing(i, float(t[a - 1]), float(t[min(b + 1, t.size - 1)])))
    return sorted(found, key=lambda s: (s.start, s.contact))


def group_swings(swings: Sequence[Swing]) -> list[tuple[int, ...]]:
    """The swings grouped into feet lifting together: a swing joins the group of the first
    swing before it that overlaps it by at least half the shorter of the two (and has no
    swing of its contact yet), else it starts a group. Groups in the order of their first
    lift-off, each its contacts sorted."""
    groups: list[list[Swing]] = []
    for swing in swings:
        for group in groups:
            first = group[0]
            overlap = min(first.end, swing.end) - max(first.start, swing.start)
            shorter = min(first.end - first.start, swing.end - swing.start)
            if (overlap >= 0.5 * shorter and overlap > 0
                    and all(s.contact != swing.contact for s in group)):
                group.append(swing)
                break
        else:
            groups.append([swing])
    return [tuple(sorted(s.contact for s in group)) for group in groups]


def name_gait(t: np.ndarray, gaps: np.ndarray, names: Sequence[str], offsets: np.ndarray,
              height: float = 0.01, touch: float = 1e-3) -> GaitReport:
    """The gait of a plan's motion.

    Args:
        t: physical times [s], (M,); gaps: the contacts' gaps [m] there, (M, n).
        names: the contacts' names, (n,).
        offsets: each contact's position relative to the base in the base's axes at the
            start [m], (n, 3): x > 0 front, y > 0 left.
        height: a swing rises at least this [m] above the ground.
        touch: a gap at most this [m] is on the ground.
    """
    offsets = np.asarray(offsets, dtype=float).reshape(len(names), 3)
    groups = group_swings(swings_of(t, gaps, height, touch))
    named = tuple(tuple(names[i] for i in g) for g in groups)
    front, left = offsets[:, 0] > 0, offsets[:, 1] > 0
    # four legs, one in each quadrant: two front, two hind, two left, two right
    quadrants = {(bool(f), bool(s)) for f, s in zip(front, left, strict=True)}
    if len(names) != 4 or len(quadrants) != 4:
        return GaitReport("", named)
    if not groups:
        return GaitReport("standing", named)
    sizes = {len(g) for g in groups}
    if sizes == {4}:
        return GaitReport("pronk", named)
    if sizes == {1}:
        return GaitReport("walk", named)
    if sizes == {2}:
        kinds = {PAIR_GAITS[bool(front[a] == front[b]), bool(left[a] == left[b])]
                 for a, b in groups}  # two legs differ in front/hind, side or both
        if len(kinds) == 1:
            return GaitReport(kinds.pop(), named)
    return GaitReport("mixed", named)
