"""The hopper benchmark scripts' own logic, without their long solves.

`scripts/bench_hopper.py` replays nosnoc_py's plan with exact impacts (its controls
piecewise constant between the plan's clock values); `scripts/bench_hopper_settings.py`
changes one setting of `hopper_options()` per variant.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from tfcontact.scenes.hopper import hopper_options
from tfcontact.scenes.particles import G, point_mass

SCRIPTS = Path(__file__).resolve().parent.parent / "scripts"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("push, end_x, end_vx", [
    # 1 N < mu m g: the particle stays where the impact stuck it
    (1.0, None, 0.0),
    # 10 N > mu m g: it slides from t = 0.5 s on with (10 - mu m g) / m
    (10.0, 0.5 * (10.0 - 0.5 * G) * 0.5**2, (10.0 - 0.5 * G) * 0.5),
])
def test_replay_of_a_plan_with_a_sticking_landing(push, end_x, end_vx):
    """A particle thrown sideways at 2 m/s from 1 m lands at t_c = sqrt(2 / g) with mu = 0.5:
    the impact stops the slip (mu |v_n-| = 2.2 > 2 m/s); a push in the second of two
    control intervals (clock 0.5 s) acts from its clock value on."""
    bench = _load("bench_hopper")
    cls = point_mass(2, mu=0.5, controlled=True)
    t_c = math.sqrt(2.0 / G)
    x_land = 2.0 * t_c
    exact = np.array([x_land + (end_x or 0.0), 0.0, end_vx, 0.0])
    clocks = np.array([0.0, 0.5, 1.0])
    controls = np.array([[0.0, 0.0], [push, 0.0]])
    x0 = np.array([0.0, 1.0, 2.0, 0.0])
    deviation = bench._replay_deviation(cls, x0, clocks, controls, 1.0, exact)
    assert deviation < 1e-6
    wrong = exact + np.array([0.0, 0.0, 0.1, 0.0])
    assert bench._replay_deviation(cls, x0, clocks, controls, 1.0, wrong) == pytest.approx(
        0.1, abs=1e-6)


def test_settings_variants_change_one_setting_each():
    settings = _load("bench_hopper_settings")
    default = hopper_options("short")
    names = [f.name for f in fields(default)]
    for name, variant in settings.VARIANTS.items():
        options = variant(default)
        changed = [n for n in names if getattr(options, n) != getattr(default, n)]
        if name.startswith("default"):
            assert changed == [], name
        else:
            assert len(changed) == 1, (name, changed)
