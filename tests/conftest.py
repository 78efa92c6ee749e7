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
