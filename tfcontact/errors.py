"""The exceptions of tfcontact: one base class, specific subclasses that carry evidence.

Every message names the problem and, where there is one, the fix.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np


class TfcontactError(Exception):
    """Base class of every error tfcontact raises on purpose."""


class InvalidInput(TfcontactError, ValueError):
    """An argument has the wrong value, shape or type."""


def positive_int(value: object, name: str) -> int:
    """`value` as an int if it is a positive integer (not a bool), else `InvalidInput`
    naming the argument `name`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidInput(f"`{name}` must be a positive integer, got {value!r}")
    return int(value)


def nonnegative_number(value: object, name: str) -> float:
    """`value` as a float if it is a finite number >= 0 (not a bool), else `InvalidInput`
    naming the argument `name`."""
    if (isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating)
            or not 0 <= value < np.inf):
        raise InvalidInput(f"`{name}` must be a finite number >= 0, got {value!r}")
    return float(value)


def optional_positive(value: object, name: str) -> None:
    """Nothing if `value` is None or a finite number > 0 (not a bool), else
    `InvalidInput` naming the argument `name`."""
    if value is not None and (
            isinstance(value, bool)
            or not isinstance(value, int | float | np.integer | np.floating)
            or not 0 < value < np.inf):
        raise InvalidInput(f"`{name}` must be None or a number > 0, got {value!r}")


def one_of(value: object, choices: Iterable[str], name: str) -> str:
    """`value` if it is one of `choices` (names of settings), else `InvalidInput` naming
    the argument `name` and the choices."""
    choices = tuple(choices)
    if not isinstance(value, str) or value not in choices:
        raise InvalidInput(f"`{name}` must be one of {', '.join(choices)}, got {value!r}")
    return value


class IncompatibleOptions(TfcontactError, ValueError):
    """Two options were given that cannot be used together."""


class RobotLoadError(TfcontactError):
    """A robot description could not be found or parsed."""


class InvalidRobotModel(RobotLoadError):
    """A robot description parses but is not a physical rigid-body model.

    Attributes:
        link: the URDF link at fault.
        value: the value found (a mass [kg], principal moments [kg m^2], a pivot of M(q)).
        joint: the model joint that moves `link`, or None when the fault is in the raw URDF.
    """

    def __init__(self, message: str, *, link: str, value: Any, joint: str | None = None):
        super().__init__(message)
        self.link = link
        self.value = value
        self.joint = joint


class FrameNotFound(TfcontactError, KeyError):
    """A frame name is not in the robot model."""

    def __init__(self, name: str, frames: list[str] | tuple[str, ...]):
        self.name = name
        self.frames = tuple(frames)
        shown = ", ".join(self.frames[:40]) + (" ..." if len(self.frames) > 40 else "")
        super().__init__(
            f"frame `{name}` is not in the model; pick one of: {shown}"
        )

    def __str__(self) -> str:  # KeyError would quote the message otherwise
        return self.args[0]


class SolveFailed(TfcontactError):
    """A solve did not converge; `result` holds the last iterate and the diagnostics."""

    def __init__(self, message: str, result: Any = None):
        super().__init__(message)
        self.result = result


class TrajectoryFileError(TfcontactError):
    """A trajectory file is damaged, foreign or of an unsupported version."""


class Interrupted(KeyboardInterrupt):
    """A solve was stopped by SIGINT (Ctrl-C) or SIGTERM.

    A `KeyboardInterrupt`, so that no `except Exception` on the way up swallows it; the
    command line turns it into exit code 130. `signal_number` is the signal that arrived.
    """

    def __init__(self, signal_number: int):
        import signal

        self.signal_number = int(signal_number)
        super().__init__(f"interrupted by {signal.Signals(self.signal_number).name}")


class TimeLimitReached(BaseException):
    """A solve ran past the time limit set around it (`tfcontact.interrupt.time_limit`).

    A `BaseException`, as `Interrupted` is a `KeyboardInterrupt`: no `except Exception` on
    the way up turns it into a failed stage that the plan then goes on from. `limit` and
    `elapsed` are wall-clock seconds.
    """

    def __init__(self, limit: float, elapsed: float):
        self.limit = float(limit)
        self.elapsed = float(elapsed)
        super().__init__(f"stopped at the time limit of {self.limit:g} s ({self.elapsed:.0f} s "
                         "elapsed); allow more time or give the plan a better start")
