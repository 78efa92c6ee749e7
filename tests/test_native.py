"""Process-wide native resources (tfcontact.native): the BLAS thread count is set for a
block and restored, freed memory is collected and trimmed, the peak memory is read and
restarted."""

from __future__ import annotations

import weakref

import pytest

from tfcontact.native import (
    blas_threads,
    casadi_openblas,
    peak_memory,
    reset_peak_memory,
    return_memory,
)


def test_blas_threads_are_set_for_the_block_and_restored():
    """The re-solves' paths depend on the BLAS thread count (measured: 458 against 2284
    iterations): `blas_threads` sets CasADi's OpenBLAS for the block and restores it, also
    when the block raises."""
    lib = casadi_openblas()
    if lib is None:
        pytest.skip("this CasADi build has no bundled OpenBLAS")
    before = lib.openblas_get_num_threads()
    with blas_threads(1):
        assert lib.openblas_get_num_threads() == 1
    with blas_threads(3):
        assert lib.openblas_get_num_threads() == 3
    assert lib.openblas_get_num_threads() == before
    with blas_threads(None):
        assert lib.openblas_get_num_threads() == before
    with pytest.raises(RuntimeError), blas_threads(1):
        raise RuntimeError("a failed solve")
    assert lib.openblas_get_num_threads() == before


def test_return_memory_collects_unreachable_cycles():
    class Node:
        pass

    node = Node()
    node.self = node  # a cycle: only the garbage collector frees it
    alive = weakref.ref(node)
    del node
    return_memory()
    assert alive() is None


def test_peak_memory_sees_a_block_that_is_gone_until_it_is_reset():
    """The high-water mark keeps 300 MB that were touched and freed; a reset forgets them."""
    import numpy as np

    reset_peak_memory()
    before = peak_memory()
    if before is None:
        pytest.skip("no /proc high-water mark here")
    block = np.ones(300 * 2**20 // 8)
    del block
    return_memory()
    assert peak_memory() >= before + 0.25
    reset_peak_memory()
    assert peak_memory() < before + 0.25
