"""The gait report (`tfcontact.ocp.gait`): swings read from gaps, grouped by overlap, and
named from where the feet sit, on gait diagrams written by hand."""

import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.ocp.gait import group_swings, name_gait, swings_of

NAMES = ("FL", "FR", "HL", "HR")
# solo12-like: front x > 0, left y > 0
OFFSETS = np.array([[0.19, 0.15, -0.24], [0.19, -0.15, -0.24],
                    [-0.19, 0.15, -0.24], [-0.19, -0.15, -0.24]])
T = np.linspace(0.0, 1.0, 201)


def diagram(swings: dict[str, list[tuple[float, float]]], lift: float = 0.04) -> np.ndarray:
    """Gaps of four feet on the ground but for `swings` {foot: [(start, end), ...]}, each a
    sine arc up to `lift`."""
    gaps = np.zeros((T.size, 4))
    for foot, spans in swings.items():
        for a, b in spans:
            inside = (T > a) & (T < b)
            gaps[inside, NAMES.index(foot)] = lift * np.sin(np.pi * (T[inside] - a) / (b - a))
    return gaps


def test_swings_are_lift_offs_that_rise_above_the_height():
    gaps = diagram({"FL": [(0.1, 0.3)], "FR": [(0.5, 0.7)]})
    gaps[(T > 0.8) & (T < 0.9), 2] = 0.004  # a skim below the height: not a swing
    gaps[:20, 3] = 0.05  # in the air from the start: no lift-off seen
    found = swings_of(T, gaps, height=0.01)
    assert [(s.contact, round(s.start, 3), round(s.end, 3)) for s in found] == [
        (0, 0.1, 0.3), (1, 0.5, 0.7)]
    with pytest.raises(InvalidInput, match="touch < height"):
        swings_of(T, gaps, height=1e-3, touch=1e-3)


@pytest.mark.parametrize(("swings", "name", "groups"), [
    ({f: [(0.2, 0.5), (0.65, 0.9)] for f in NAMES}, "pronk",
     (NAMES, NAMES)),
    ({"FL": [(0.1, 0.3), (0.5, 0.7)], "HR": [(0.1, 0.3), (0.5, 0.7)],
      "FR": [(0.3, 0.5), (0.7, 0.9)], "HL": [(0.3, 0.5), (0.7, 0.9)]}, "trot",
     (("FL", "HR"), ("FR", "HL"), ("FL", "HR"), ("FR", "HL"))),
    ({"FL": [(0.1, 0.3)], "HL": [(0.11, 0.31)], "FR": [(0.3, 0.5)], "HR": [(0.32, 0.5)]},
     "pace", (("FL", "HL"), ("FR", "HR"))),
    ({"FL": [(0.1, 0.3)], "FR": [(0.12, 0.3)], "HL": [(0.35, 0.55)], "HR": [(0.35, 0.5)]},
     "bound", (("FL", "FR"), ("HL", "HR"))),
    ({"FL": [(0.1, 0.25)], "HR": [(0.25, 0.4)], "FR": [(0.4, 0.55)], "HL": [(0.55, 0.7)]},
     "walk", (("FL",), ("HR",), ("FR",), ("HL",))),
    ({"FL": [(0.1, 0.3)], "HR": [(0.1, 0.3)], "FR": [(0.1, 0.3)], "HL": [(0.5, 0.7)]},
     "mixed", (("FL", "FR", "HR"), ("HL",))),
    ({}, "standing", ()),
])
def test_gaits_are_named_from_the_feet_that_lift_together(swings, name, groups):
    report = name_gait(T, diagram(swings), NAMES, OFFSETS)
    assert report.name == name
    assert report.groups == groups
    assert report.line().startswith(f"gait: {name} (swings in order: ")
    assert report.to_dict() == {"name": name, "groups": [list(g) for g in groups]}


def test_a_mix_of_pairs_and_a_short_overlap_are_not_one_gait():
    swings = {"FL": [(0.1, 0.3), (0.7, 0.9)], "HR": [(0.1, 0.3), (0.7, 0.9)],
              "FR": [(0.4, 0.6)], "HL": [(0.4, 0.6)]}
    assert name_gait(T, diagram(swings), NAMES, OFFSETS).name == "trot"
    # a diagonal pair, one foot, then a same-side pair: no one name
    swings = {"FL": [(0.1, 0.3)], "HR": [(0.1, 0.3), (0.7, 0.9)], "FR": [(0.4, 0.6)],
              "HL": [(0.7, 0.9)]}
    report = name_gait(T, diagram(swings), NAMES, OFFSETS)
    assert report.name == "mixed"
    assert report.groups == (("FL", "HR"), ("FR",), ("HL", "HR"))
    # a touching overlap (one swing lands as the next lifts) keeps them apart
    assert group_swings(swings_of(T, diagram({"FL": [(0.1, 0.3)], "FR": [(0.29, 0.5)]}),
                                  0.01)) == [(0,), (1,)]


def test_a_robot_without_four_legs_split_front_hind_and_left_right_gets_no_name():
    swings = {"FL": [(0.1, 0.3)], "FR": [(0.4, 0.6)]}
    planar = OFFSETS * [1.0, 0.0, 1.0]  # a sagittal model: left and right coincide
    report = name_gait(T, diagram(swings), NAMES, planar)
    assert report.name == "" and report.groups == (("FL",), ("FR",))
    assert report.line() == "gait: unnamed (swings in order: FL, FR)"
    two = name_gait(T, diagram(swings)[:, :2], NAMES[:2], OFFSETS[:2])
    assert two.name == "" and two.groups == (("FL",), ("FR",))
