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


def _expression():
    """A function of the operations robot dynamics use, and its Hessian."""
    import casadi as ca

    x = ca.SX.sym("x", 6)
    e = ca.vertcat(ca.sin(x[0]) * ca.sqrt(x[1] ** 2 + 1) / (x[2] + 3),
                   ca.atan2(x[3], x[4] + 2), ca.exp(x[5]) * ca.fmax(x[0], x[1]),
                   ca.power(x[1] ** 2 + 0.5, 1.3), ca.if_else(x[0] > 0, x[1], x[2]),
                   ca.tanh(x[3]) + ca.log(x[4] ** 2 + 1) * ca.cos(x[2]))
    return x, [e, ca.hessian(ca.sumsqr(e), x)[0]]


def _recording_compiler(tmp_path, real: str):
    """A compiler command that logs each call, then runs `real`."""
    log = tmp_path / "calls.log"
    script = tmp_path / "cc"
    script.write_text(f'#!/bin/sh\necho "$@" >> {log}\nexec {real} "$@"\n')
    script.chmod(0o755)
    return str(script), log


def test_compiled_functions_give_the_virtual_machines_values_bit_for_bit(tmp_path):
    """tcc compiles the function (the compiler is called) and its machine code gives
    CasADi's virtual machine's values exactly, so IPOPT follows the same iterates; a
    function above `max_instructions` is left to the virtual machine."""
    import shutil

    import casadi as ca
    import numpy as np

    from tfcontact.native import Compiler, compiled

    if shutil.which("tcc") is None:
        pytest.skip("no tcc on the PATH (Debian's package tcc; .ci/run installs it)")
    command, log = _recording_compiler(tmp_path, shutil.which("tcc"))
    x, outputs = _expression()
    machine = compiled("element", [x], outputs, Compiler(command=command))
    assert log.exists() and "-shared" in log.read_text()  # compiled and linked
    plain = ca.Function("element", [x], outputs)
    for value in np.random.default_rng(0).normal(size=(20, 6)):
        for a, b in zip(machine(value), plain(value), strict=True):
            assert np.array_equal(np.asarray(a), np.asarray(b))
    log.unlink()
    compiled("element", [x], outputs, Compiler(command=command, max_instructions=10))
    assert not log.exists()


def test_a_compiler_that_fails_leaves_the_function_on_the_virtual_machine():
    """`false` as the compiler: a warning naming the way out, and a working function."""
    import numpy as np

    from tfcontact.native import COMPILER_VARIABLE, Compiler, compiled

    x, outputs = _expression()
    with pytest.warns(RuntimeWarning, match=f"could not compile.*{COMPILER_VARIABLE}=none"):
        function = compiled("element", [x], outputs, Compiler(command="false"))
    assert np.isfinite(np.asarray(function(np.ones(6))[0])).all()


def test_the_element_compiler_is_chosen_by_the_environment(monkeypatch):
    """Unset: tcc if on the PATH; "none": no compiler; a command not on the PATH: a clear
    error naming the variable; bad Compiler fields are refused."""
    import shutil

    from tfcontact.errors import InvalidInput
    from tfcontact.native import COMPILER_VARIABLE, Compiler, element_compiler

    monkeypatch.delenv(COMPILER_VARIABLE, raising=False)
    assert (element_compiler() is None) == (shutil.which("tcc") is None)
    monkeypatch.setenv(COMPILER_VARIABLE, "none")
    assert element_compiler() is None
    monkeypatch.setenv(COMPILER_VARIABLE, "sh")
    assert element_compiler() == Compiler(command="sh")
    monkeypatch.setenv(COMPILER_VARIABLE, "no-such-compiler")
    with pytest.raises(InvalidInput, match=f"{COMPILER_VARIABLE}='no-such-compiler'"):
        element_compiler()
    with pytest.raises(InvalidInput, match="max_instructions"):
        Compiler(max_instructions=0)
    with pytest.raises(InvalidInput, match="command"):
        Compiler(command="")
    with pytest.raises(InvalidInput, match="`flags` must be a sequence of strings"):
        Compiler(flags="-O1")
    assert Compiler(flags=["-O1"]).flags == ("-O1",)


def test_the_same_expression_is_compiled_once_and_the_cache_is_bounded(tmp_path, monkeypatch):
    """A homotopy's next level builds the same element functions again: `compiled` takes
    them from its cache (the compiler is not called, the values are the same), and the
    cache keeps at most `CACHE_SIZE` functions (each holds a shared object in /tmp)."""
    import shutil

    import casadi as ca
    import numpy as np

    import tfcontact.native as native
    from tfcontact.native import Compiler, compiled

    if shutil.which("tcc") is None:
        pytest.skip("no tcc on the PATH (Debian's package tcc; .ci/run installs it)")
    command, log = _recording_compiler(tmp_path, shutil.which("tcc"))
    compiler = Compiler(command=command)

    def calls() -> int:
        return sum("-shared" in line for line in log.read_text().splitlines())

    x, outputs = _expression()
    first = compiled("level_1_hessian", [x], outputs, compiler)
    assert calls() == 1
    y = ca.SX.sym("x", 6)  # new symbols, the same expression
    again = compiled("level_2_hessian", [y], ca.substitute(outputs, [x], [y]), compiler)
    assert calls() == 1 and again is first
    value = np.linspace(-1, 1, 6)
    assert np.array_equal(np.asarray(again(value)[1]), np.asarray(first(value)[1]))
    compiled("other", [x], [outputs[0] + 1], compiler)  # another expression: compiled
    assert calls() == 2
    monkeypatch.setattr(native, "CACHE_SIZE", 1)
    compiled("third", [x], [outputs[0] * 2], compiler)  # evicts the first two
    assert calls() == 3
    compiled("level_3_hessian", [x], outputs, compiler)
    assert calls() == 4
