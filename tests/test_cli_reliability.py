"""The command line under interrupts, bad folders and bad flags: through the real
`tfcontact` program in a subprocess where signals or permissions are the point."""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from tfcontact import interrupt
from tfcontact.cli import EXIT_CODES, main
from tfcontact.errors import Interrupted, InvalidInput, TimeLimitReached
from tfcontact.ocp.nodes import ipopt_solver, report_progress, solve_guarded
from tfcontact.scenes.output import OutputFolder

TFCONTACT = [sys.executable, "-m", "tfcontact.cli"]
# `tfcontact` as a terminal's foreground job starts it, with Python's SIGINT handler: when
# the tests run as a background job of a shell script, SIGINT is ignored from the start
# (and stays so, in their subprocesses and in tfcontact).
TFCONTACT_IN_FOREGROUND = [
    sys.executable, "-c", "import runpy, signal; "
    "signal.signal(signal.SIGINT, signal.default_int_handler); "
    "runpy.run_module('tfcontact.cli', run_name='__main__', alter_sys=True)"]


@pytest.fixture
def sigint_handled():
    """Python's own SIGINT handler in this process for the test (see above)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _start_plan(out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [*TFCONTACT_IN_FOREGROUND, "plan", "hopper", "--out", str(out), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_ipopt(process: subprocess.Popen, timeout: float = 120.0) -> list[str]:
    """Read the plan's progress until the first NLP has finished (IPOPT is then running
    the second one); the lines read so far."""
    lines = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        if "Solve_Succeeded" in line or "Solved_To_Acceptable" in line:
            return lines
    process.kill()
    pytest.fail("the plan printed no solved NLP: " + "".join(lines))


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_inside_ipopt_stops_the_plan_and_keeps_the_old_one(tmp_path, signum):
    """Before: one SIGINT 10 s into `plan hopper` ran 70 s more, exited 0 and replaced the
    folder's plan. Now the plan stops within 2 s, exits 130, and with --force given the
    earlier plan in the folder is untouched and no staging folder is left."""
    out = tmp_path / "hop"
    out.mkdir()
    (out / "summary.json").write_text("earlier plan")
    process = _start_plan(out, "--force")
    _wait_for_ipopt(process)
    sent = time.monotonic()
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    stopped = time.monotonic() - sent
    assert process.returncode == 130, err
    assert stopped < 2.0
    assert signal.Signals(signum).name in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hop"]
    assert [p.name for p in out.iterdir()] == ["summary.json"]
    assert (out / "summary.json").read_text() == "earlier plan"


def _slow_nlp() -> ca.Function:
    """An infeasible NLP that IPOPT works on for tens of seconds, with the iteration
    callback that tfcontact's solvers carry."""
    n = 20000
    x = ca.SX.sym("x", n)
    f = ca.sum1((x[1:] - x[:-1] ** 2) ** 2) + ca.sum1((1 - x) ** 2)
    g = ca.vertcat(ca.sum1(x ** 2) + 1, ca.sin(x[:-1]) * ca.cos(x[1:]))
    return ca.nlpsol("slow", "ipopt", {"x": x, "f": f, "g": g},
                     {"ipopt": {"print_level": 0, "sb": "yes", "max_iter": 100000},
                      "print_time": False, "error_on_fail": False,
                      "iteration_callback": _STOP})


_STOP = interrupt.StopOnSignal()  # CasADi keeps a borrowed reference only


def test_guard_turns_ctrl_c_inside_ipopt_into_interrupted(sigint_handled):
    """Without the guard CasADi ends the NLP with NonIpopt_Exception_Thrown and returns as
    if IPOPT had failed; inside it the same SIGINT raises `Interrupted` within an
    iteration, and the process's own SIGINT handler is back afterwards."""
    solver = _slow_nlp()
    before = signal.getsignal(signal.SIGINT)
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(Interrupted) as caught, interrupt.guard():
        solver(x0=0.5, lbg=0, ubg=ca.vertcat(0, 0.1 * ca.DM.ones(19999)))
    timer.join()
    assert time.monotonic() - start < 3.0
    assert caught.value.signal_number == signal.SIGINT
    assert isinstance(caught.value, KeyboardInterrupt)
    assert signal.getsignal(signal.SIGINT) is before


def _slow_opti(n: int = 20000, max_iter: int = 100000
               ) -> tuple[ca.Opti, interrupt.StopOnSignal]:
    """`_slow_nlp` as an Opti problem, set up the way the exact re-solves set theirs
    (`ipopt_solver`), with their progress lines armed."""
    opti = ca.Opti()
    x = opti.variable(n)
    opti.minimize(ca.sum1((x[1:] - x[:-1] ** 2) ** 2) + ca.sum1((1 - x) ** 2))
    opti.subject_to(ca.sum1(x ** 2) + 1 == 0)
    opti.subject_to(opti.bounded(0, ca.sin(x[:-1]) * ca.cos(x[1:]), 0.1))
    opti.set_initial(x, 0.5)
    stop = ipopt_solver(opti, {"print_time": False},
                        {"print_level": 0, "sb": "yes", "max_iter": max_iter})
    report_progress(stop)
    return opti, stop


def test_a_signal_stops_an_opti_solve_within_an_iteration(sigint_handled):
    """The exact re-solves solve through CasADi's Opti, whose own progress callback
    replaced the iteration callback that stops IPOPT: a SIGINT was recorded and IPOPT ran
    on (measured: a 5000-iteration solve to its end, 131 s; a stance re-solve of solo12
    for 30 minutes after SIGTERM). Now it stops within an iteration."""
    opti, stop = _slow_opti()  # `stop` kept alive: CasADi borrows it
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(Interrupted) as caught:
        solve_guarded(opti, None)
    timer.join()
    assert time.monotonic() - start < 3.0
    assert caught.value.signal_number == signal.SIGINT
    assert opti.debug.stats()["return_status"] == "User_Requested_Stop"


def test_a_time_limit_stops_an_nlp_within_an_iteration():
    """Inside `time_limit` an NLP that IPOPT works on for tens of seconds stops at the
    first iteration past the deadline and its guard raises `TimeLimitReached` with the
    limit; after the block no deadline is left."""
    solver = _slow_nlp()
    start = time.monotonic()
    with pytest.raises(TimeLimitReached) as caught, interrupt.time_limit(1.0), \
            interrupt.guard():
        solver(x0=0.5, lbg=0, ubg=ca.vertcat(0, 0.1 * ca.DM.ones(19999)))
    assert time.monotonic() - start < 3.0
    assert solver.stats()["return_status"] == "User_Requested_Stop"
    assert caught.value.limit == 1.0 and 1.0 <= caught.value.elapsed < 3.0
    assert "time limit of 1 s" in str(caught.value)
    assert not isinstance(caught.value, Exception)  # no `except Exception` swallows it
    assert not interrupt.past_deadline()
    with interrupt.guard():
        pass


def test_a_time_limit_stops_an_opti_solve_on_a_worker_thread():
    """A sweep's case runs on a Dask worker's thread, where no signal handler can be set:
    the limit still stops the exact re-solves' Opti solve (whose failed solve CasADi turns
    into a RuntimeError, `solve_guarded` into its last iterate) with `TimeLimitReached`."""
    outcome = []

    def solve() -> None:
        opti, stop = _slow_opti()  # `stop` kept alive: CasADi borrows it
        try:
            with interrupt.time_limit(1.0):
                solve_guarded(opti, None)
        except TimeLimitReached as error:
            outcome.append((error, opti.debug.stats()["return_status"]))

    worker = threading.Thread(target=solve)
    start = time.monotonic()
    worker.start()
    worker.join(timeout=60)
    assert time.monotonic() - start < 10.0  # the Opti set-up included
    ((error, status),) = outcome
    assert status == "User_Requested_Stop" and error.limit == 1.0


def test_no_nlp_starts_after_the_time_limit_and_nested_limits_keep_the_earlier():
    ran = []
    with interrupt.time_limit(60.0), interrupt.time_limit(0.01):
        time.sleep(0.02)
        with pytest.raises(TimeLimitReached), interrupt.guard():
            ran.append("NLP")
    assert not ran
    with interrupt.time_limit(0.01), interrupt.time_limit(60.0):
        time.sleep(0.02)
        assert interrupt.past_deadline()
    with interrupt.time_limit(None):
        assert not interrupt.past_deadline()
    for bad in (0, -1.0, float("inf"), "10"):
        with pytest.raises(InvalidInput, match="time limit"), interrupt.time_limit(bad):
            pass


def test_a_plan_stopped_at_its_time_limit_exits_1_and_keeps_the_old_one(tmp_path):
    """`tfcontact plan --time-limit`: the hopper (about 10 s) stopped after 1 s exits 1,
    names the limit, and the folder's earlier plan stays as it was."""
    out = tmp_path / "hop"
    out.mkdir()
    (out / "summary.json").write_text("earlier plan")
    done = subprocess.run([*TFCONTACT, "plan", "hopper", "--out", str(out), "--force",
                           "--time-limit", "1"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert "stopped at the time limit of 1 s" in done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hop"]
    assert (out / "summary.json").read_text() == "earlier plan"


def test_the_opti_progress_reads_the_iterates_objective(capsys):
    """The progress line's objective is the iterate's: after a solve, the callback's last
    objective is the solution's."""
    opti, stop = _slow_opti(n=50, max_iter=30)
    solve_guarded(opti, None)
    assert "IPOPT started" in capsys.readouterr().out
    assert stop.objective == pytest.approx(float(opti.debug.value(opti.f)), rel=1e-12)


class _SignalledInConversion(np.ndarray):
    """An array that receives SIGINT while CasADi's Python glue converts it, inside the
    `try` of casadi.py's DM_from_array (whose bare `except:` takes any exception)."""

    def astype(self, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(100):  # Python runs the signal's handler between these bytecodes
            pass
        return np.asarray(self).astype(*args, **kwargs)


def test_a_signal_casadi_swallows_still_stops_the_next_nlp_and_keeps_the_old_folder(
        tmp_path, sigint_handled):
    """With Python's own handler a SIGINT inside CasADi's argument conversion is lost: the
    call returns as if nothing happened (measured: 10 of 300 SIGINTs sent during calls
    with numpy arguments lost). Under `stop_on_signals()` (the command line's) the signal
    is remembered: the next guarded native call does not start, a plan's output folder
    being written keeps its old content, and the handlers and the record are gone after
    the block."""
    x = ca.SX.sym("x", 3)
    double = ca.Function("double", [x], [2 * x])
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    np.testing.assert_array_equal(np.asarray(double(np.ones(3).view(_SignalledInConversion))),
                                  2.0 * np.ones((3, 1)))  # the KeyboardInterrupt was lost
    out = tmp_path / "hop"
    out.mkdir()
    (out / "summary.json").write_text("earlier plan")
    with interrupt.stop_on_signals():
        double(np.ones(3).view(_SignalledInConversion))  # swallowed again, but recorded
        with pytest.raises(Interrupted) as caught, interrupt.guard():
            pytest.fail("the guarded call started after the signal")
        assert caught.value.signal_number == signal.SIGINT
        with pytest.raises(Interrupted), OutputFolder(out, force=True).staging() as stage:
            (stage / "summary.json").write_text("new plan")
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
    assert (out / "summary.json").read_text() == "earlier plan"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hop"]
    interrupt.raise_if_signalled()  # nothing recorded outside the block
    with interrupt.guard():
        pass


def test_a_signal_between_the_renames_waits_until_the_new_plan_is_in_place(
        tmp_path, monkeypatch, sigint_handled):
    """Replacing a plan is two renames (the old folder aside, the new one in place); a
    SIGINT after the first would leave no folder where the plan belongs. It is held back
    until both are done, then raised."""
    out = tmp_path / "hop"
    out.mkdir()
    (out / "summary.json").write_text("earlier plan")
    rename = os.rename
    renames = []

    def rename_then_signal(source, destination):
        rename(source, destination)
        renames.append(destination)
        if len(renames) == 1:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(100):  # Python would run the handler between these bytecodes
                pass

    monkeypatch.setattr(os, "rename", rename_then_signal)
    with pytest.raises(KeyboardInterrupt), OutputFolder(out, force=True).staging() as stage:
        (stage / "summary.json").write_text("new plan")
    assert len(renames) == 2
    assert (out / "summary.json").read_text() == "new plan"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hop"]


def test_a_program_started_with_sigint_ignored_keeps_ignoring_it():
    """A background job of a shell script starts with SIGINT ignored, so that Ctrl-C on the
    script's terminal does not stop it; Python leaves it so, and so do the command line's
    handlers, the guard around IPOPT and the deferral (before, the guard took SIGINT
    during each NLP only: such a plan stopped or went on depending on when the signal
    came, which made the test above fail when the suite ran in the background). SIGTERM
    is still handled."""
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with interrupt.stop_on_signals():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            assert callable(signal.getsignal(signal.SIGTERM))
            with interrupt.guard():
                assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100):
                    pass
            with interrupt.signals_deferred():
                assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            interrupt.raise_if_signalled()
    finally:
        signal.signal(signal.SIGINT, before)


def test_the_command_line_gives_the_signal_handlers_back(tmp_path):
    """`main` handles SIGINT and SIGTERM only while it runs (a caller's, e.g. a notebook's,
    are back afterwards)."""
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    assert main(["check", str(tmp_path / "missing.npz")]) == 2
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_guard_leaves_other_errors_alone():
    with pytest.raises(ValueError, match="not a signal"), interrupt.guard():
        raise ValueError("not a signal")


def _run(*args: str, without_root_override: bool = False) -> subprocess.CompletedProcess:
    """Run `tfcontact ARGS`; `without_root_override`: as root, drop the capabilities that
    let root write into folders without write permission (setpriv, util-linux)."""
    prefix = []
    if without_root_override and os.geteuid() == 0:
        prefix = ["setpriv", "--bounding-set", "-dac_override,-dac_read_search", "--"]
    return subprocess.run([*prefix, *TFCONTACT, *args], capture_output=True, text=True,
                          timeout=120)


def _one_line_error(result: subprocess.CompletedProcess, *phrases: str) -> None:
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    for phrase in phrases:
        assert phrase in lines[0]


def test_read_only_output_folder_is_refused_before_solving(tmp_path):
    """Before: the whole solve ran, then a PermissionError traceback lost the plan. The
    check runs without root's power to write anywhere."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    start = time.monotonic()
    for out in (locked, locked / "hop"):
        result = _run("plan", "hopper", "--out", str(out), without_root_override=True)
        _one_line_error(result, str(out), "not writable", "--out")
    assert time.monotonic() - start < 60  # nothing was solved
    assert list(locked.iterdir()) == []


def test_output_path_that_is_a_file_is_named(tmp_path):
    afile = tmp_path / "notes.txt"
    afile.write_text("x")
    _one_line_error(_run("plan", "hopper", "--out", str(afile)), "is a file", "--out")
    _one_line_error(_run("plan", "hopper", "--out", str(afile / "hop")),
                    "lies below the file", str(afile))


def test_existing_plan_is_not_replaced_without_force(tmp_path, capsys):
    (tmp_path / "trajectory.npz").write_text("earlier plan")
    assert main(["plan", "hopper", "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "already holds files" in err and "--force" in err
    assert (tmp_path / "trajectory.npz").read_text() == "earlier plan"


def test_flag_values_are_usage_errors(tmp_path, capsys):
    out = tmp_path / "new"
    for argv in (["plan", "hopper", "--attempts", "0", "--out", str(out)],
                 ["replay", "x.npz", "--speed", "0"], ["replay", "x.npz", "--fps", "-1"],
                 ["replay", "x.npz", "--fps", "nan"]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 2
        assert "must be a positive" in capsys.readouterr().err
    assert not out.exists()


def test_exit_codes_are_documented(capsys):
    with pytest.raises(SystemExit):
        main(["plan", "--help"])
    text = capsys.readouterr().out
    for code in EXIT_CODES:
        assert f"  {code} " in text.replace("\n", " \n")
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    assert "130" in readme and "--force" in readme


def test_debug_shows_the_traceback(tmp_path):
    afile = tmp_path / "notes.txt"
    afile.write_text("x")
    result = _run("--debug", "plan", "hopper", "--out", str(afile))
    assert result.returncode != 0 and "Traceback" in result.stderr


def test_output_folder_replaces_only_when_forced(tmp_path):
    target = tmp_path / "plan"
    target.mkdir()
    (target / "old.txt").write_text("old")
    with pytest.raises(InvalidInput, match="already holds files"):
        OutputFolder(target).check()
    with OutputFolder(target, force=True).staging() as stage:
        (stage / "new.txt").write_text("new")
        assert (target / "old.txt").exists()  # nothing moves before the plan is written
    assert [p.name for p in target.iterdir()] == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan"]


def test_output_folder_is_untouched_when_writing_fails(tmp_path):
    target = tmp_path / "plan"
    target.mkdir()
    (target / "old.txt").write_text("old")
    with pytest.raises(KeyboardInterrupt), OutputFolder(target, force=True).staging() as st:
        (st / "half.txt").write_text("half")
        raise KeyboardInterrupt
    assert [p.name for p in target.iterdir()] == ["old.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan"]


def test_check_command_exit_codes(tmp_path, capsys):
    """`tfcontact check`: 0 on an intact physical plan, 2 with one line on a damaged or
    missing file (never a traceback)."""
    saved = Path(__file__).resolve().parent.parent / "benchmarks" / "plans_particles"
    intact = saved / "throwing_ball" / "trajectory.npz"
    assert main(["check", str(intact)]) == 0
    capsys.readouterr()
    for name in ("trajectory.npz", "trajectory.json"):
        (tmp_path / name).write_bytes((intact.parent / name).read_bytes())
    data = bytearray((tmp_path / "trajectory.npz").read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "trajectory.npz").write_bytes(bytes(data))
    for path in (tmp_path / "trajectory.npz", tmp_path / "missing.npz"):
        assert main(["check", str(path)]) == 2
        err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        assert len(err) == 1 and "Traceback" not in err[0]
