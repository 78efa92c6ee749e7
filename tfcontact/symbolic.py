"""Input checks shared by the layers that take CasADi expressions from users."""

from __future__ import annotations

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput


def as_sx(expr: object, name: str) -> ca.SX:
    """`expr` as casadi.SX; constants (numbers, numpy arrays, DM) are accepted."""
    if isinstance(expr, ca.SX):
        return expr
    if isinstance(expr, ca.DM | np.ndarray | float | int | list):
        return ca.SX(ca.DM(expr))
    raise InvalidInput(f"`{name}` must be a casadi.SX expression, got {type(expr).__name__}")


def labels(names: tuple[str, ...] | None, n: int, prefix: str, arg: str) -> tuple[str, ...]:
    """`names` checked to have n entries, or prefix0, prefix1, ... by default."""
    if names is None:
        return tuple(f"{prefix}{i}" for i in range(n))
    names = tuple(names)
    if len(names) != n:
        raise InvalidInput(f"`{arg}` has {len(names)} names, expected {n}")
    return names


def check_depends(expr: ca.SX, allowed: list[ca.SX], name: str, what: str) -> None:
    """Raise unless `expr` depends only on the symbols in `allowed` (described as `what`)."""
    allowed_names = {s.name() for a in allowed for s in ca.symvar(a)}
    extra = sorted({s.name() for s in ca.symvar(expr)} - allowed_names)
    if extra:
        raise InvalidInput(f"`{name}` depends on symbols {extra}; it may use only {what}")
