import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parent.parent / "scripts"


@pytest.fixture(autouse=True)
def _strict_numerics():
    """Floating point errors raise in tests (DESIGN: strict numerics)."""
    with np.errstate(all="raise"):
        yield


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.fixture
def load_script():
    """Import `<folder>/<name>.py` (default folder: `scripts/`) as a module (registered, so
    that its dataclasses work)."""
    def load(name: str, folder: Path = SCRIPTS):
        spec = importlib.util.spec_from_file_location(f"{folder.name}_{name}",
                                                      folder / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
        return module
    return load


# The suite's longest files, longest first (measured in the suite on 2 cores of a Zen 3
# EPYC, 2026-11-29, 37.5 minutes in all: the legged task plans 27 minutes (solo12's jump
# 15, its trot 7.7, bolt's short walk 3.9), the monoped's Radau levels 7, its exact plans
# 6.5, the hopper's plans 5, the task layer's own tests 5, the pipeline and the sweeps 4
# each; this order was not compared with another in one run). pytest-xdist hands out whole
# files in collection order (`--dist loadfile`), so these go first: each starts on a
# worker of its own and the short files fill in beside them, instead of two long files
# queuing on one worker at the end.
LONGEST_FIRST = ("test_task_legged_plans.py", "test_monoped_exact.py",
                 "test_monoped_radau_levels.py", "test_plans_hopper.py", "test_task.py",
                 "test_pipeline.py", "test_sweep.py")


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.path.name
        return LONGEST_FIRST.index(name) if name in LONGEST_FIRST else len(LONGEST_FIRST)

    items.sort(key=rank)  # stable: the order within a file and among the rest is kept
