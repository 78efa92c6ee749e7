"""Ctrl-C inside IPOPT: turn the signal into an exception instead of a failed NLP.

CasADi's IPOPT wrapper polls Python's signal handlers between iterations; when a handler
raises, it ends the solve with the status `NonIpopt_Exception_Thrown` and returns
normally, so the homotopy would treat Ctrl-C as a failed NLP and go on (measured: one
SIGINT 10 s into `tfcontact plan hopper` ran 70 s more and exited 0). `guard()` wraps each
long native call: its handler records the signal and raises (so IPOPT stops within an
iteration), and on leaving the block `Interrupted` is raised for the recorded signal.


CasADi may also meet the handler's exception inside a function evaluation, where it is
swallowed and IPOPT goes on (measured: the hopper's NLP then ran its remaining 4 s);
`StopOnSignal` is an IPOPT iteration callback that ends the NLP at the next iteration once
a signal was recorded, whatever happened to the exception.

Outside `guard()` blocks Python's own KeyboardInterrupt can be lost the same way: CasADi's
argument conversion (`DM_from_array` in casadi.py) catches every exception with a bare
`except:` (measured: of 300 SIGINTs sent during calls with numpy arguments, 10 were lost).
`stop_on_signals()`, for command-line entry points, remembers each signal for the whole
program, so that the next `guard()` or `raise_if_signalled()` (before a plan's output is
published) stops it even when the exception itself was swallowed.

A time limit stops a solve the same way: inside a `time_limit(seconds)` block,
`StopOnSignal` ends the running NLP at the first iteration past the deadline and `guard()`
raises `TimeLimitReached` on leaving it (and on entering one after the deadline, so that no
further NLP starts). A homotopy, a stance re-solve or a sweep case thus stops within one
IPOPT iteration of its budget instead of running on to the iteration cap; what is not an
IPOPT solve (a reference simulation) runs to its own budget.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

import casadi as ca

from tfcontact.errors import Interrupted, TimeLimitReached, optional_positive

_CASADI_MODULE = os.path.join("casadi", "casadi.py")
# The signal recorded by the innermost active `guard()` (None: none), read by StopOnSignal.
_pending: list[int] = []
# Signals recorded by `stop_on_signals()`'s handler, kept until its block ends.
_received: list[int] = []
# The innermost `time_limit()` of each thread: .deadline = (monotonic deadline, limit [s],
# monotonic start), or no attribute. Per thread: a sweep's cases run on worker threads.
_limits = threading.local()


class _Caught:
    """The signal recorded inside a `guard()` block (None: none arrived)."""

    def __init__(self) -> None:
        self.signal_number: int | None = None


def _not_ignored(signals: tuple[signal.Signals, ...]) -> list[signal.Signals]:
    # A signal the program started with ignored stays ignored, as Python leaves it: a
    # background job of a shell script starts with SIGINT ignored so that Ctrl-C on the
    # script's terminal does not reach it (before, the guard took SIGINT during NLPs
    # only, so such a plan stopped or went on depending on when the signal came).
    return [s for s in signals if signal.getsignal(s) is not signal.SIG_IGN]


def _guarded_signals() -> list[signal.Signals]:
    # SIGTERM only where the program chose to handle it (the command line does): a
    # library call must not change what SIGTERM does to a user's process.
    chosen = _not_ignored((signal.SIGINT,))
    if callable(signal.getsignal(signal.SIGTERM)):
        chosen.append(signal.SIGTERM)
    return chosen


@contextmanager
def guard() -> Iterator[_Caught]:
    """Run a native call so that SIGINT (unless ignored) and SIGTERM (where handled)
    stop it.

    Raises:
        Interrupted: a signal arrived inside the block (also when the native call caught
            the handler's exception and returned), or before it inside `stop_on_signals()`.
        TimeLimitReached: the innermost `time_limit()` around it has passed, on entering
            or on leaving the block (an NLP stopped by `StopOnSignal` at the deadline).
    """
    caught = _Caught()
    raise_if_past_deadline()
    if threading.current_thread() is not threading.main_thread():
        # Signals reach only the main thread; handlers cannot be set from another one.
        try:
            yield caught
        except Exception as error:  # Opti's RuntimeError for an NLP stopped at the deadline
            raise_if_past_deadline(cause=error)
            raise
        raise_if_past_deadline()
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        caught.signal_number = signum
        _pending.append(signum)
        if _in_casadi_glue(frame):
            # StopOnSignal and the check on leaving the block stop the solve instead.
            return
        raise Interrupted(signum)

    raise_if_signalled()
    _pending.clear()
    previous = {s: signal.signal(s, handler) for s in _guarded_signals()}
    try:
        yield caught
    except Interrupted:
        raise
    except BaseException as error:
        # A native call may turn the handler's exception into its own error (CasADi's
        # Opti raises RuntimeError for the failed solve): the signal still wins.
        if caught.signal_number is None and not isinstance(error, KeyboardInterrupt):
            if isinstance(error, Exception):  # ... and an NLP stopped at the deadline
                raise_if_past_deadline(cause=error)
            raise
        raise Interrupted(caught.signal_number or signal.SIGINT) from error
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        _pending.clear()
    if caught.signal_number is not None:
        raise Interrupted(caught.signal_number)
    raise_if_past_deadline()


def _in_casadi_glue(frame: FrameType | None) -> bool:
    # Inside CasADi's own Python glue (argument conversion) an exception is swallowed by a
    # bare `except:` or "ignored" with a printed traceback (Python 3.13).
    return frame is not None and frame.f_code.co_filename.endswith(_CASADI_MODULE)


_OBJECTIVE = ca.nlpsol_out().index("f")


class StopOnSignal(ca.Callback):
    """IPOPT's `iteration_callback`: stop the NLP once a `guard()` recorded a signal or the
    time limit (`time_limit`) has passed.

    Keep a reference to the object for as long as the solver that uses it lives (CasADi
    holds only a borrowed one).
    """

    def __init__(self) -> None:
        ca.Callback.__init__(self)
        self.construct("stop_on_signal", {})
        self.on_iteration: Callable[[], None] | None = None
        """Called at each iteration (e.g. a progress line of a verbose solve)."""
        self.objective = float("nan")
        """The objective at the iteration being reported (read by `on_iteration`)."""

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        # Any shape: the callback reads nothing of the iterate but its objective.
        return ca.Sparsity.dense(1, 1) if i == _OBJECTIVE else ca.Sparsity.dense(0, 0)

    def eval(self, arg: list) -> list:
        self.objective = float(arg[_OBJECTIVE])
        if self.on_iteration is not None:
            self.on_iteration()
        return [1 if _pending or past_deadline() else 0]


@contextmanager
def stop_on_signals() -> Iterator[None]:
    """For command-line entry points: inside the block SIGINT and SIGTERM (unless the
    program started with them ignored) raise `Interrupted` (a terminated plan cleans up
    like an interrupted one), and each signal is remembered until the block ends, so that
    one whose exception a native call swallowed still stops the program at the next
    `guard()` or `raise_if_signalled()`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        _received.append(signum)
        if not _in_casadi_glue(frame):  # there the exception would be swallowed
            raise Interrupted(signum)

    _received.clear()
    try:
        with _handled_by(handler, _not_ignored((signal.SIGINT, signal.SIGTERM))):
            yield
    finally:
        _received.clear()


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back inside the block (a few file renames that must happen
    together): one that arrives is raised again when the block ends, to the handlers
    before it. (Python-level, not the thread's signal mask: the kernel may hand a signal
    to any of IPOPT's or BLAS's threads.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        held.append(signum)

    try:
        with _handled_by(hold, _not_ignored((signal.SIGINT, signal.SIGTERM))):
            yield
    finally:  # also after an error inside: the user's Ctrl-C still counts
        for signum in dict.fromkeys(held):
            signal.raise_signal(signum)


@contextmanager
def _handled_by(handler: Callable[[int, FrameType | None], None],
                signals: list[signal.Signals]) -> Iterator[None]:
    """`handler` for `signals` inside the block, the handlers before it afterwards."""
    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def raise_if_signalled() -> None:
    """Raise `Interrupted` if `stop_on_signals()` recorded a signal (whose exception may
    have been swallowed on its way up); nothing outside such a block.

    Raises:
        Interrupted: for the last signal recorded.
    """
    if _received:
        raise Interrupted(_received[-1])


@contextmanager
def time_limit(seconds: float | None) -> Iterator[None]:
    """Inside the block, IPOPT solves stop once `seconds` of wall-clock time have passed
    since it began: the NLP running then ends at its next iteration and its `guard()`
    raises `TimeLimitReached` (module docstring). None: no limit of its own (an enclosing
    one still holds); nested limits keep the earlier deadline. Per thread.

    Raises:
        InvalidInput: `seconds` is not None or a number > 0.
    """
    optional_positive(seconds, "time limit")
    outer = getattr(_limits, "deadline", None)
    if seconds is not None:
        began = time.monotonic()
        mine = (began + float(seconds), float(seconds), began)
        if outer is None or mine[0] < outer[0]:
            _limits.deadline = mine
    try:
        yield
    finally:
        if outer is None:
            _limits.__dict__.pop("deadline", None)
        else:
            _limits.deadline = outer


def past_deadline() -> bool:
    """Whether this thread's innermost `time_limit()` has passed (False: none set)."""
    deadline = getattr(_limits, "deadline", None)
    return deadline is not None and time.monotonic() >= deadline[0]


def raise_if_past_deadline(cause: BaseException | None = None) -> None:
    """Raise `TimeLimitReached` (from `cause`, the error a stopped solve raised) if this
    thread's `time_limit()` has passed.

    Raises:
        TimeLimitReached: with the limit and the seconds elapsed since it was set.
    """
    deadline = getattr(_limits, "deadline", None)
    if deadline is not None:
        now = time.monotonic()
        if now >= deadline[0]:
            raise TimeLimitReached(deadline[1], now - deadline[2]) from cause
