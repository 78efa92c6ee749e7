"""From numerical time back to physical time (DESIGN.md 4.1, [AUTO23] Theorem 5).

A time-freezing solution y(tau) = (q, v, t)(tau) is continuous in numerical time tau.
The physical trajectory is x(tau) against t(tau) with the frozen pieces (dt/dtau = 0)
dropped: each frozen piece becomes a jump of v at one physical time, an impact, whose
generalised impulse is M(q) (v+ - v-) = sum_i (n_i Lambda_n,i + B_i Lambda_t,i)
([AUTO23] eq. (19): the impulse equals the integral of the auxiliary dynamics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tfcontact.errors import InvalidInput

# Defined next to the simulator (a lower layer), which reads frozen pieces with it too.
from tfcontact.fesd.simulate import FROZEN_RATE_TOL
from tfcontact.timefreezing.system import TimeFreezingSystem


@dataclass(frozen=True, eq=False)
class Impact:
    """One frozen piece of a time-freezing solution, seen in physical time.

    Attributes:
        time: physical time of the jump [s].
        tau: (start, end) of the frozen piece in numerical time [s].
        index: (entry, exit) sample indices in the numerical-time arrays.
        pre, post: the state y just before and just after the jump.
        contacts: indices of the contacts taking part (gap <= gap_tol at entry); empty
            for a hysteresis switch.
        normal_impulse: Lambda_n per contact [N s], shape (n_c,) (0 for the others).
        tangential_impulse: Lambda_t per contact [N s], shape (n_c, 2) (unused columns 0).
        impulse_residual: ||M dv - J Lambda|| [N s]: what the contact directions cannot
            explain (0 up to round-off for an exact solution).
        complete: False when the frozen piece runs into the last sample (the jump was cut
            by the end of the data, `post` is not a post-jump state).
    """

    time: float
    tau: tuple[float, float]
    index: tuple[int, int]
    pre: np.ndarray
    post: np.ndarray
    contacts: tuple[int, ...]
    normal_impulse: np.ndarray
    tangential_impulse: np.ndarray
    impulse_residual: float
    complete: bool = True


@dataclass(frozen=True, eq=False)
class PhysicalTrajectory:
    """A time-freezing solution in physical time.

    Attributes:
        t: physical time [s], shape (M,), non-decreasing; an impact appears as two
            consecutive entries with the same time (pre- and post-impact state).
        y: the states at those times, shape (M, n_y).
        index: the sample index in the numerical-time arrays of each entry, shape (M,).
        impacts: the frozen pieces, in order.
        system: the time-freezing system.
    """

    t: np.ndarray
    y: np.ndarray
    index: np.ndarray
    impacts: tuple[Impact, ...]
    system: TimeFreezingSystem

    @property
    def q(self) -> np.ndarray:
        return self.y[:, self.system.q_index]

    @property
    def v(self) -> np.ndarray:
        return self.y[:, self.system.v_index]

    @property
    def gaps(self) -> np.ndarray:
        """Contact gaps f_c(q) [m] at every sample, shape (M, n_contacts); (M, 0) for a
        system without contacts."""
        cls = self.system.cls
        if cls is None:
            return np.zeros((len(self.t), 0))
        gaps = np.asarray(cls.function("gaps")(self.q.T))
        return gaps.T.reshape(len(self.t), cls.n_contacts)

    @property
    def impact_times(self) -> np.ndarray:
        return np.array([imp.time for imp in self.impacts])

    def segments(self) -> list[slice]:
        """Slices of the continuous pieces between jumps (for plotting without the
        vertical lines of the jumps)."""
        cuts = {0, len(self.t)}
        cuts |= {int(np.searchsorted(self.index, imp.index[1])) for imp in self.impacts}
        cuts = sorted(cuts)
        return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def to_physical_time(
    system: TimeFreezingSystem,
    tau: np.ndarray,
    y: np.ndarray,
    *,
    rate_tol: float = FROZEN_RATE_TOL,
    gap_tol: float = 1e-4,
) -> PhysicalTrajectory:
    """Map a solution in numerical time to physical time, frozen pieces dropped.

    Main arguments:
        system: the time-freezing system the solution belongs to.
        tau: numerical times [s], shape (K,), non-decreasing.
        y: states, shape (K, n_y).

    Other arguments:
        rate_tol: an interval [tau_k, tau_k+1] is frozen when
            t_k+1 - t_k <= rate_tol (tau_k+1 - tau_k). A persistent-contact sliding mode
            runs at the rate gamma in (0, 1] and is kept.
        gap_tol: a contact takes part in an impact when its gap at entry is <= gap_tol [m].

    Returns:
        The `PhysicalTrajectory` with one `Impact` per frozen piece.

    Raises:
        InvalidInput: shapes disagree, tau decreases, or a tolerance is negative.
    """
    tau = np.asarray(tau, dtype=float)
    y = np.asarray(y, dtype=float)
    if tau.ndim != 1 or y.ndim != 2 or y.shape != (tau.size, system.n_y):
        raise InvalidInput(
            f"`tau` must have shape (K,) and `y` shape (K, {system.n_y}), "
            f"got {tau.shape} and {y.shape}"
        )
    if tau.size < 2:
        raise InvalidInput(f"need at least 2 samples, got {tau.size}")
    if np.any(np.diff(tau) < 0):
        raise InvalidInput("`tau` must be non-decreasing")
    for name, value in (("rate_tol", rate_tol), ("gap_tol", gap_tol)):
        if not (math.isfinite(value) and value >= 0):
            raise InvalidInput(f"`{name}` must be finite and >= 0, got {value!r}")
    clock = y[:, system.clock_index]
    dt = np.diff(clock)
    dtau = np.diff(tau)
    frozen = (dt <= rate_tol * dtau) & (dtau > 0)
    n = tau.size
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    keep[1:] |= ~frozen
    keep[:-1] |= ~frozen
    impacts = []
    k = 0
    while k < n - 1:
        if not frozen[k]:
            k += 1
            continue
        start = k
        while k < n - 1 and (frozen[k] or dtau[k] == 0):
            k += 1
        keep[start] = keep[k] = True
        impacts.append(_impact(system, tau, y, start, k, gap_tol))
    index = np.flatnonzero(keep)
    return PhysicalTrajectory(
        t=clock[index], y=y[index], index=index, impacts=tuple(impacts), system=system
    )


def _impact(
    system: TimeFreezingSystem, tau: np.ndarray, y: np.ndarray, start: int, end: int,
    gap_tol: float,
) -> Impact:
    pre, post = y[start].copy(), y[end].copy()
    cls = system.cls
    n_c = 0 if cls is None else cls.n_contacts
    normal_impulse = np.zeros(n_c)
    tangential_impulse = np.zeros((n_c, 2))
    residual = 0.0
    active: tuple[int, ...] = ()
    if cls is not None:
        q = pre[system.q_index]
        gaps = np.asarray(cls.function("gaps")(q)).ravel()
        active = tuple(int(i) for i in np.flatnonzero(gaps <= gap_tol))
        if not active:
            active = (int(np.argmin(gaps)),)
        mass = np.asarray(cls.function("mass")(q))
        momentum = mass @ (post[system.v_index] - pre[system.v_index])
        normals = np.asarray(cls.function("normals")(q))
        columns, owners = [], []
        for i in active:
            columns.append(normals[:, i])
            owners.append((i, -1))
            if cls.contacts[i].n_tangents:
                tangents = np.asarray(cls.function(f"tangents_{i}")(q))
                for j in range(tangents.shape[1]):
                    columns.append(tangents[:, j])
                    owners.append((i, j))
        jac = np.column_stack(columns)
        lam, *_ = np.linalg.lstsq(jac, momentum, rcond=None)
        residual = float(np.linalg.norm(jac @ lam - momentum))
        for (i, j), value in zip(owners, lam, strict=True):
            if j < 0:
                normal_impulse[i] = value
            else:
                tangential_impulse[i, j] = value
    return Impact(
        time=float(y[start, system.clock_index]), tau=(float(tau[start]), float(tau[end])),
        index=(start, end), pre=pre, post=post, contacts=active,
        normal_impulse=normal_impulse, tangential_impulse=tangential_impulse,
        impulse_residual=residual, complete=end < len(tau) - 1,
    )
