import numpy as np
import pytest


@pytest.fixture(autouse=True)
def _strict_numerics():
    """Floating point errors raise in tests (DESIGN: strict numerics)."""
    with np.errstate(all="raise"):
        yield


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
