"""Process-wide native resources, touched in one place and always given back.

IPOPT's linear algebra runs MUMPS on CasADi's bundled OpenBLAS, whose thread count is a
process-wide setting; and glibc keeps freed heap pages of large NLPs unless asked to hand
them back. Both are reached through ctypes here, and nowhere else: `blas_threads` sets the
count for a block and restores it after, `return_memory` trims the heap between solves,
and `peak_memory` reads the kernel's high-water mark (`reset_peak_memory` restarts it).
"""

from __future__ import annotations

import ctypes
import gc
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import casadi as ca


def casadi_openblas() -> ctypes.CDLL | None:
    """CasADi's bundled OpenBLAS (MUMPS's BLAS inside IPOPT), or None if there is none."""
    for name in ("libcasadi-tp-openblas.so.0", "libcasadi-tp-openblas.so"):
        path = Path(ca.__file__).parent / name
        if path.exists():
            try:
                lib = ctypes.CDLL(str(path))
            except OSError:
                return None
            return lib if hasattr(lib, "openblas_set_num_threads") else None
    return None


@contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """Run IPOPT's linear algebra (MUMPS on CasADi's OpenBLAS) with n threads, then restore
    the count it had.

    IPOPT's path depends on the rounding, and the rounding on the BLAS thread count: the
    reduced monoped's first exact re-solve takes 458 iterations with 2 threads and 2284
    with 1. Fixing the count makes a run follow the measured path on machines of the same
    kind. None, or no OpenBLAS of CasADi's: leave it as it is."""
    lib = None if n is None else casadi_openblas()
    if lib is None:
        yield
        return
    before = int(lib.openblas_get_num_threads())
    lib.openblas_set_num_threads(int(n))
    try:
        yield
    finally:
        lib.openblas_set_num_threads(before)


def return_memory() -> None:
    """Collect garbage and hand freed heap pages back to the system (glibc's malloc_trim).

    Without it the process kept much of each NLP's freed graph: the reduced monoped's
    chain of re-solves held 3.0 GB after its last step (0.17 GB with it), the full chain
    peaked at 21 GB. Not glibc: nothing to trim."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def reset_peak_memory() -> None:
    """Start `peak_memory` afresh (Linux: the kernel's high-water mark of the resident set,
    reset through /proc/self/clear_refs); elsewhere nothing."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        pass


def peak_memory() -> float | None:
    """The process's peak resident memory [GB] since the last `reset_peak_memory` (Linux's
    VmHWM); None where /proc does not tell."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20  # kB
    except OSError:
        pass
    return None
