"""Process-wide native resources, touched in one place and always given back.

IPOPT's linear algebra runs MUMPS on CasADi's bundled OpenBLAS, whose thread count is a
process-wide setting; and glibc keeps freed heap pages of large NLPs unless asked to hand
them back. Both are reached through ctypes here, and nowhere else: `blas_threads` sets the
count for a block and restores it after, `return_memory` trims the heap between solves,
and `peak_memory` reads the kernel's high-water mark (`reset_peak_memory` restarts it).
`compiled` gives a function as machine code when a C compiler is there (`Compiler`,
`element_compiler`): the same values, evaluated without CasADi's virtual machine.
"""

from __future__ import annotations

import ctypes
import gc
import hashlib
import os
import shutil
import tempfile
import warnings
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from tfcontact.errors import InvalidInput, positive_int

COMPILER_VARIABLE = "TFCONTACT_COMPILER"
"""The environment variable that picks `element_compiler`: unset or empty, Debian's `tcc`
if it is on the PATH; "none", no compiler; another value, that command."""


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


@dataclass(frozen=True)
class Compiler:
    """A C compiler that CasADi's shell importer calls to compile a function just in time
    (CasADi's generated C, compiled, linked and loaded; the files in the temporary folder,
    removed after loading).

    Measured on the reduced monoped's exact re-solves (benchmarks/monoped_bench.md): tcc's
    code evaluated the RK4 steps' derivatives 3.5x faster than CasADi's virtual machine,
    along the same IPOPT iterations (the same arithmetic in the same order: no fused
    multiply-adds, the same libm). On functions of millions of instructions (solo12's
    four-foot element) compiled code was no faster: those are bound by memory traffic
    (benchmarks/legged.md), and `max_instructions` leaves them to the virtual machine.

    Attributes:
        command: the compiler, also the linker (`command -shared`); on the PATH.
        flags: its flags when compiling (with -fPIC -c).
        max_instructions: larger functions are not compiled.
    """

    command: str = "tcc"
    flags: tuple[str, ...] = ()
    max_instructions: int = 1_000_000

    def __post_init__(self) -> None:
        if not isinstance(self.command, str) or not self.command:
            raise InvalidInput(f"`command` must name a C compiler, got {self.command!r}")
        if isinstance(self.flags, str) or not all(isinstance(f, str) for f in self.flags):
            raise InvalidInput(f"`flags` must be a sequence of strings, got {self.flags!r}")
        object.__setattr__(self, "flags", tuple(self.flags))
        positive_int(self.max_instructions, "max_instructions")

    def options(self) -> dict:
        """CasADi's Function options that compile with this compiler."""
        shell = {"compiler": self.command, "linker": self.command,
                 "directory": tempfile.gettempdir() + os.sep, "verbose": False}
        if self.flags:  # (an empty list would reach CasADi as a list of booleans)
            shell["compiler_flags"] = list(self.flags)
        return {"jit": True, "compiler": "shell", "jit_options": shell}


def element_compiler() -> Compiler | None:
    """The compiler of `compiled`, from `COMPILER_VARIABLE`: unset or empty, tcc when it is
    on the PATH (else None: CasADi's virtual machine); "none", None; another value, that
    command, which must be on the PATH.

    Raises:
        InvalidInput: the variable names a command that is not on the PATH.
    """
    name = os.environ.get(COMPILER_VARIABLE, "").strip()
    if not name:
        return Compiler() if shutil.which("tcc") else None
    if name == "none":
        return None
    if shutil.which(name) is None:
        raise InvalidInput(f"{COMPILER_VARIABLE}={name!r}: no such command on the PATH; "
                           f"name a C compiler (tcc) or set it to 'none'")
    return Compiler(command=name)


_failed: set[str] = set()

CACHE_SIZE = 32
"""How many compiled functions `compiled` keeps for reuse (least recently used first
out). Each holds its shared object in the temporary folder while it lives, so the cache
is bounded: a long-lived process (a sweep's worker) does not fill the folder."""

_cache: OrderedDict[tuple[str, Compiler], ca.Function] = OrderedDict()


def compiled(name: str, inputs: Sequence[ca.SX], outputs: Sequence[ca.SX],
             compiler: Compiler | None = None) -> ca.Function:
    """ca.Function(name, inputs, outputs), compiled by `compiler` (default
    `element_compiler()`) unless there is none or the function has more than its
    `max_instructions`. A compiler that fails is warned about once and left alone: the
    function then runs on CasADi's virtual machine, with the same values.

    The same expression compiled again (a homotopy's next level, another schedule's NLP
    of the same robot: the reduced monoped builds 22 distinct element functions 44 times)
    is taken from a cache of the last `CACHE_SIZE` instead; its name then stays the first
    one's."""
    function = ca.Function(name, list(inputs), list(outputs))
    compiler = element_compiler() if compiler is None else compiler
    if (compiler is None or compiler.command in _failed
            or function.n_instructions() > compiler.max_instructions):
        return function
    # the serialised graph names the function: key on one with a fixed name
    graph = ca.Function("element", list(inputs), list(outputs)).serialize()
    key = (hashlib.sha256(graph.encode()).hexdigest(), compiler)
    if key in _cache:
        _cache.move_to_end(key)
        return _cache[key]
    try:
        machine = ca.Function(name, list(inputs), list(outputs), compiler.options())
    except RuntimeError as error:
        _failed.add(compiler.command)
        warnings.warn(f"{compiler.command} could not compile {name} (CasADi: "
                      f"{str(error).strip().splitlines()[-1][:200]}); functions run on "
                      f"CasADi's virtual machine ({COMPILER_VARIABLE}=none stops trying)",
                      RuntimeWarning, stacklevel=2)
        return function
    _cache[key] = machine
    while len(_cache) > CACHE_SIZE:
        _cache.popitem(last=False)
    return machine
