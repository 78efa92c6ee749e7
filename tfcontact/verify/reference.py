"""A reference simulator of the ORIGINAL system with impacts (for verification).

`simulate_impacts` integrates a CLS with one point contact event by event with
`scipy.integrate.solve_ivp` (DOP853, tight tolerances) and treats the nonsmooth events
exactly, without any time-freezing:

* free flight: q' = v, v' = M^{-1} f_v; event gap(q) = 0 from above (impact).
* impact (Newton restitution with Coulomb friction): Lambda_n = -(1 + e) v_n- / D,
  then the tangential impulse Lambda_t = -v_t- / w (stick) if that lies in the cone
  ||Lambda_t|| <= mu Lambda_n, else Lambda_t = -mu Lambda_n v_t- / ||v_t-|| (slip);
  v+ = v- + M^{-1} (n Lambda_n + B Lambda_t). For e = 0 this is exactly the impulse of the
  inelastic time-freezing auxiliary dynamics ([AUTO23] section 4.3, a_t = mu a_n).
  A bounce slower than `rest_velocity` ends in persistent contact (no Zeno cascade).
* inelastic impact of a planar contact whose directions are not kinetically orthogonal
  (a leg: B^T M^{-1} n != 0): the impulse flow dv/dP = W (1, lambda_t) in the normal
  impulse P, W = [n B]^T M^{-1} [n B], lambda_t = -mu sign(v_t) while slipping and
  -W_tn / W_tt (if within +-mu) while v_t = 0, until v_n = 0. The flow is piecewise
  linear, so its pieces are exact; it is the velocity the time-freezing auxiliary
  dynamics M^{-1} (n -+ mu B) a_n reach, with P = a_n tau. In the Painleve region
  (W_nn - mu sign(v_t) W_nt <= 0) the slip piece deepens the approach, but the slip
  always stops (W is positive definite) and the stick piece ends the impact.
* persistent contact, as the index-reduced DAE ([AUTO23] eqs. (13), (22), (23)):
  slip: lambda_t = -mu lambda_n v_t/||v_t||, lambda_n from n^T v' + (dn/dt)^T v = 0;
  stick: (lambda_n, lambda_t) from the acceleration-level equations of n^T v = 0 and
  B^T v = 0. Events: lambda_n = 0 (lift-off), a sign change of v_t along the direction
  it had when the slip phase began (slip -> stick check), ||lambda_t|| = mu lambda_n
  (stick -> slip, slipping along -lambda_t).
* a planar slip that starts pressed (n^T a_free + (dn/dt)^T v < 0) inside the Painleve
  region (W_nn - mu sign(v_t) W_nt <= 0, no consistent normal force): an impact without
  collision, the impulse flow from v_n = 0, which ends in stick (reported among the
  impacts). A stick force that leaves the cone where its slip would be in the region
  raises IncompatibleOptions (a dynamic jam). A slip that runs into the region is not
  resolved: its normal force grows without bound at the region's edge, where the lift-off
  event fires (a free flight of ~1e-7 s and a touchdown follow), the events cascade
  (status "max_events") or the integration stops with InvalidInput (Painleve's rod,
  mu = 2, 24 slips started towards the region: 8, 2 and 14 of them).

Several contacts (a ball in a box) are simulated when every contact is frictionless
and elastic (e > 0): free flight with one touchdown event per gap, and a Newton impulse
on each contact that closes and approaches; contacts that close together (a corner) must
be kinetically orthogonal (n_i^T M^{-1} n_j = 0), where the sequential impulses are the
simultaneous ones. Persistent contact is not simulated there (a bounce slower than
`rest_velocity` stops with IncompatibleOptions).

Limits (checked where possible, raised as IncompatibleOptions):
* one contact, or several frictionless elastic ones (above);
* at an elastic or 3-D frictional impact, B^T M^{-1} n = 0 and B^T M^{-1} B = w I
  (kinetic orthogonality and an isotropic tangent metric), true for particles, balls and
  blocks whose contact point is the centre of mass' projection;
* the gap is kept by the index-reduced dynamics without stabilisation: the position
  drift is of the integrator's tolerance order for curved gaps and zero for affine ones;
* the slip-stop event in 3-D uses v_t . v_t(start of slip), exact while the slip direction
  is constant (e.g. a ball sliding with no tangential force but friction); a rotating slip
  direction could delay it.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem

FREE, SLIP, STICK = "free", "slip", "stick"


@dataclass(frozen=True, eq=False)
class ReferenceImpact:
    """An impact of the reference simulation.

    Attributes:
        time: impact time [s]; pre, post: x = (q, v) before and after;
        normal_impulse: Lambda_n [N s]; tangential_impulse: Lambda_t [N s], shape (n_t,);
        contact: the index of the contact in the CLS.
    """

    time: float
    pre: np.ndarray
    post: np.ndarray
    normal_impulse: float
    tangential_impulse: np.ndarray
    contact: int = 0


@dataclass(frozen=True, eq=False)
class ReferenceSimulation:
    """The result of `simulate_impacts`.

    Attributes:
        t: times [s], shape (K,), non-decreasing; an impact repeats its time (pre, post).
        x: states (q, v), shape (K, 2 n_q).
        impacts: the impacts in order.
        modes: (start time [s], mode) for every phase: "free", "slip" or "stick".
        status: "success", "max_events" or "max_rhs_evaluations" (stopped early, see
            `message`).
        message: what happened.
        n_rhs: right-hand-side evaluations.
        end_impacts: the impact(s) that a contact closing at T (gap within
            `END_GAP_TOLERANCE`, approaching) takes at T, not applied to `x`: the state at T
            is then ambiguous (before or after the impact), and a plan may end on either
            side (FESD puts impacts on control-interval boundaries, and T is one).
    """

    t: np.ndarray
    x: np.ndarray
    impacts: tuple[ReferenceImpact, ...]
    modes: tuple[tuple[float, str], ...]
    status: str
    message: str
    n_rhs: int
    end_impacts: tuple[ReferenceImpact, ...] = ()

    @property
    def impact_times(self) -> np.ndarray:
        return np.array([imp.time for imp in self.impacts])

    def final_state(self) -> np.ndarray:
        return self.x[-1].copy()

    def deviation_at(self, t_end: float, state: np.ndarray,
                     window: float = 0.0) -> tuple[float, str]:
        """(max |x(t_end) - state|, "" or "before"/"after": the side of an impact `state`
        matches best).

        An impact within `window` of t_end (or at T, `end_impacts`) makes the comparison
        ambiguous: a plan may put it on the other side of t_end (FESD puts impacts on
        control-interval boundaries), so the state on either side of it counts.
        """
        at_end = np.flatnonzero(self.t <= t_end)[-1]
        candidates = [(self.x[at_end], "")]
        candidates += [(imp.pre, "before") if imp.time <= t_end else (imp.post, "after")
                       for imp in self.impacts if abs(imp.time - t_end) <= window]
        candidates += [(imp.post, "after") for imp in self.end_impacts
                       if abs(imp.time - t_end) <= window]
        deviation, side = min((float(np.max(np.abs(x - state))), side)
                              for x, side in candidates)
        return deviation, side


END_GAP_TOLERANCE = 1e-6
"""A contact whose gap at T is below this [m] and closing takes its impact at T
(`ReferenceSimulation.end_impacts`)."""


_END_TIME_TOLERANCE = 1e-12  # relative: an event this close to T is an impact at T


class _BudgetExceeded(Exception):
    """The simulation used up its evaluation budget (caught in `simulate_impacts`)."""


class StackedFunction:
    """A CasADi function of dense vectors, its outputs stacked in one dense vector and
    evaluated through CasADi's call buffer: 3-8 us a call against 50-100 us for
    `Function.__call__` and its DM conversions, and a simulation makes thousands."""

    def __init__(self, name: str, inputs: list[ca.SX], outputs: list[ca.SX]):
        self.shapes = [output.shape for output in outputs]
        stacked = ca.vertcat(*[ca.vec(ca.densify(output)) for output in outputs])
        self.function = ca.Function(name, inputs, [stacked])
        self._buffer, self._evaluate = self.function.buffer()
        self._inputs = [np.zeros(int(x.numel())) for x in inputs]
        self._output = np.zeros(int(stacked.numel()))
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))
        self._buffer.set_res(0, memoryview(self._output))

    def __call__(self, *values: np.ndarray) -> list[np.ndarray]:
        """The outputs, dense in their shapes (a copy: the buffer is reused)."""
        for array, value in zip(self._inputs, values, strict=True):
            array[:] = value
        self._evaluate()
        stacked = self._output.copy()
        pieces, start = [], 0
        for rows, cols in self.shapes:
            pieces.append(stacked[start:start + rows * cols].reshape((rows, cols), order="F"))
            start += rows * cols
        return pieces


class _Model:
    """Numeric terms of a one-contact CLS, from CasADi functions."""

    def __init__(self, cls: ComplementarityLagrangianSystem):
        contact = cls.contacts[0]
        self.n = cls.n_q
        self.n_u = cls.n_u
        self.n_t = contact.n_tangents if contact.mu > 0 else 0
        self.mu = contact.mu
        self.e = contact.restitution
        q, v, u = cls.q, cls.v, cls.u
        normal = contact.normal
        tangents = contact.tangents if self.n_t else ca.SX(self.n, 0)
        vn = ca.mtimes(normal.T, v)
        vt = ca.mtimes(tangents.T, v)
        drift_n = ca.mtimes(ca.jacobian(vn, q), v)
        drift_t = ca.mtimes(ca.jacobian(vt, q), v) if self.n_t else ca.SX(0, 1)
        jac = ca.horzcat(normal, tangents)
        minv_jac = cls.solve_mass(jac)
        self._terms = StackedFunction(
            "reference_terms", [ca.vertcat(q, v), u],
            [cls.acceleration, minv_jac, jac, ca.vertcat(drift_n, drift_t), contact.gap])
        self.calls = 0
        self.max_calls = math.inf

    def _count(self) -> None:
        self.calls += 1
        if self.calls > self.max_calls:
            raise _BudgetExceeded

    def terms(self, x: np.ndarray, u: np.ndarray):
        """(a_free, M^-1 J, J, drift, gap) at x = (q, v) under u; J = [n B]."""
        self._count()
        a_free, minv_jac, jac, drift, gap = self._terms(x, u)
        return a_free.ravel(), minv_jac, jac, drift.ravel(), float(gap[0, 0])


def simulate_impacts(
    cls: ComplementarityLagrangianSystem,
    x0: np.ndarray,
    u_of_t: Callable[[float], np.ndarray] | None,
    T: float,
    *,
    rtol: float = 1e-11,
    atol: float = 1e-12,
    max_events: int = 200,
    max_rhs_evaluations: int = 2_000_000,
    rest_velocity: float = 1e-7,
    max_step: float = np.inf,
    breakpoints: Sequence[float] = (),
    start_gap_tolerance: float = 1e-12,
) -> ReferenceSimulation:
    """Event-detecting simulation of the CLS with impacts (module docstring).

    Main arguments:
        cls: a CLS with one contact, or with several frictionless elastic contacts.
        x0: initial state (q0, v0), shape (2 n_q,), with gap(q0) >= 0.
        u_of_t: control as a function of physical time, returning shape (n_u,); None when
            the system has no controls.
        T: final physical time [s].

    Other arguments:
        rtol, atol: solve_ivp tolerances (DOP853).
        max_events: stop (status "max_events") after this many mode changes.
        max_rhs_evaluations: stop (status "max_rhs_evaluations") after this many
            evaluations of the model, so that a step size collapsing near a singular
            configuration ends the simulation instead of hanging it.
        rest_velocity: an impact with |v_n-| below it [m/s] ends in persistent contact.
        max_step: solve_ivp's max_step [s] (limit it when u_of_t has kinks).
        breakpoints: times [s] where u_of_t jumps (a piecewise constant control): each
            integration stops there and the contact mode is decided anew with the new
            control (a push can lift the foot off or break sticking).
        start_gap_tolerance: x0 may lie this far inside the obstacle [m] (a plan's state
            in the middle of an impact); a contact at or inside the surface at x0 that
            closes faster than `rest_velocity` takes its impact at t = 0; one that opens
            faster starts in free flight and lands back at its start's depth. A positive
            gap, however small, starts in free flight.

    Returns:
        A `ReferenceSimulation`.

    Raises:
        InvalidInput: wrong shapes, T <= 0, or x0 inside the obstacle.
        IncompatibleOptions: several contacts of which one has friction or is inelastic,
            non-orthogonal contact directions, or persistent contact with several contacts.
    """
    if not isinstance(cls, ComplementarityLagrangianSystem):
        raise InvalidInput(f"`cls` must be a ComplementarityLagrangianSystem, got {type(cls)}")
    if not (math.isfinite(T) and T > 0):
        raise InvalidInput(f"`T` must be finite and > 0, got {T!r}")
    if max_rhs_evaluations < 1:
        raise InvalidInput(f"`max_rhs_evaluations` must be at least 1, got {max_rhs_evaluations}")
    if not start_gap_tolerance >= 0:
        raise InvalidInput(f"`start_gap_tolerance` must be >= 0 [m], got {start_gap_tolerance!r}")
    inside = max(start_gap_tolerance, 1e-12)  # how far x0 may start inside an obstacle
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.shape != (2 * cls.n_q,):
        raise InvalidInput(f"`x0` must have shape ({2 * cls.n_q},), got {x0.shape}")
    control = checked_control(u_of_t, cls.n_u)
    if cls.n_contacts > 1:
        return _simulate_elastic_contacts(
            cls, x0, control, T, rtol=rtol, atol=atol, max_events=max_events,
            max_rhs_evaluations=max_rhs_evaluations, rest_velocity=rest_velocity,
            max_step=max_step, breakpoints=breakpoints, start_gap_tolerance=inside)
    model = _Model(cls)
    model.max_calls = max_rhs_evaluations

    gap0 = model.terms(x0, control(0.0))[4]
    if gap0 < -inside:
        raise InvalidInput(f"`x0` is inside the obstacle: gap(q0) = {gap0:.3e} < 0")

    ts, xs = [np.array([0.0])], [x0[None, :]]
    impacts: list[ReferenceImpact] = []
    modes: list[tuple[float, str]] = []
    t_cur, x_cur = 0.0, x0.copy()
    n = model.n
    _, _, jac0, _, _ = model.terms(x_cur, control(0.0))
    on_surface = gap0 <= 1e-12  # on it or (within the tolerance) inside it
    if on_surface and jac0[:, 0] @ x_cur[n:] < -rest_velocity:  # closing: the impact first
        pre = x_cur.copy()
        x_cur, lam_n, lam_t, _ = _impact(model, x_cur, control(0.0), rest_velocity)
        impacts.append(ReferenceImpact(0.0, pre, x_cur.copy(), lam_n, lam_t))
        ts.append(np.array([0.0]))
        xs.append(x_cur[None, :])
    contact_now = on_surface and jac0[:, 0] @ x_cur[n:] <= rest_velocity
    mode, direction = (_contact_mode(model, x_cur, control(0.0)) if contact_now
                       else (FREE, None))
    status, message = "success", f"reached T = {T}"
    events_used = 0
    stops = _stops(breakpoints, T)
    # A start inside the surface (within the tolerance) that opens: its flight lands back at
    # the start's depth, else the touchdown event (gap = 0 from above) could never fire and
    # the foot would fall through the ground.
    surface = min(gap0, 0.0) if mode == FREE and on_surface else 0.0
    while t_cur < T:
        if mode == SLIP and _slip_in_painleve_region(model, x_cur, control(t_cur), direction):
            # A pressed slip inside the Painleve region has no consistent normal force: an
            # impact without collision stops it (`_impact_without_collision`).
            u_now = control(t_cur)
            if abs(model.terms(x_cur, u_now)[2][:, 1] @ x_cur[n:]) <= 1e-12:
                raise IncompatibleOptions(
                    f"dynamic jam at t = {t_cur:.6g} s: the stick force leaves the friction "
                    "cone and the slip it starts lies in the Painleve region")
            pre = x_cur.copy()
            x_cur, lam_n, lam_t = _impact_without_collision(model, x_cur, u_now)
            impacts.append(ReferenceImpact(t_cur, pre, x_cur.copy(), lam_n, lam_t))
            ts.append(np.array([t_cur]))
            xs.append(x_cur[None, :])
            mode, direction = _contact_mode(model, x_cur, u_now, stick_first=True)
            continue
        if not modes or modes[-1][1] != mode:
            modes.append((t_cur, mode))
        t_stop, segment_control = _segment(control, stops, t_cur)
        rhs, events = _phase(model, mode, direction, segment_control, surface)
        try:
            with np.errstate(under="ignore"):  # scipy's step-size floor at t = 0 underflows
                sol = solve_ivp(rhs, (t_cur, t_stop), x_cur, method="DOP853", rtol=rtol,
                                atol=atol, events=events, max_step=max_step)
        except _BudgetExceeded:
            status = "max_rhs_evaluations"
            message = (f"stopped after {max_rhs_evaluations} model evaluations in mode "
                       f"{mode}, in ({t_cur:.6g}, {t_stop:.6g}) s")
            break
        if sol.status == -1:
            raise InvalidInput(f"reference integration failed in mode {mode}: {sol.message}")
        ts.append(sol.t[1:])
        xs.append(sol.y.T[1:])
        t_cur, x_cur = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status == 0:
            if t_stop >= T:
                break
            if mode != FREE:  # the control jumps: decide the contact mode anew
                mode, direction = _contact_mode(model, x_cur, control(t_cur),
                                                stick_first=mode == STICK)
            continue
        events_used += 1
        if events_used > max_events:
            status, message = "max_events", f"stopped after {max_events} events at t = {t_cur}"
            break
        fired = [i for i, te in enumerate(sol.t_events) if te.size]
        u_now = control(t_cur)
        if mode == FREE and t_cur >= T - _END_TIME_TOLERANCE * max(T, 1.0):
            break  # an impact at T: reported in end_impacts, not applied (see there)
        if mode == FREE:
            surface = 0.0
            pre = x_cur.copy()
            x_cur, lam_n, lam_t, rest = _impact(model, x_cur, u_now, rest_velocity)
            impacts.append(ReferenceImpact(t_cur, pre, x_cur.copy(), lam_n, lam_t))
            ts.append(np.array([t_cur]))
            xs.append(x_cur[None, :])
            mode, direction = (_contact_mode(model, x_cur, u_now) if rest else (FREE, None))
        elif 0 in fired:  # lift-off
            mode, direction = FREE, None
        elif mode == SLIP:  # the tangential velocity reached zero
            x_cur = _zero_tangential(model, x_cur, u_now)
            mode, direction = _contact_mode(model, x_cur, u_now, stick_first=True)
        else:  # stick -> slip (or lift-off, handled above)
            mode, direction = _contact_mode(model, x_cur, u_now, force_slip=True)
    end_impacts: tuple[ReferenceImpact, ...] = ()
    if status == "success" and mode == FREE:
        u_end = control(T)
        _, _, jac, _, gap = model.terms(x_cur, u_end)
        if gap <= END_GAP_TOLERANCE and jac[:, 0] @ x_cur[n:] < 0.0:
            post, lam_n, lam_t, _ = _impact(model, x_cur, u_end, rest_velocity)
            end_impacts = (ReferenceImpact(T, x_cur.copy(), post, lam_n, lam_t),)
    return ReferenceSimulation(
        t=np.concatenate(ts), x=np.concatenate(xs), impacts=tuple(impacts),
        modes=tuple(modes), status=status, message=message, n_rhs=model.calls,
        end_impacts=end_impacts,
    )


def replay_controls(
    cls: ComplementarityLagrangianSystem,
    x0: np.ndarray,
    clocks: np.ndarray,
    controls: np.ndarray,
    T: float,
    **options: Any,
) -> ReferenceSimulation:
    """`simulate_impacts` with a plan's piecewise constant controls.

    Args:
        cls, x0, T: as for `simulate_impacts`.
        clocks: physical times of the control-interval boundaries, shape (N + 1,)
            (a time-freezing plan's clock there); each one is a breakpoint, so the
            simulation has a sample at each.
        controls: shape (N, n_u); controls[k] acts from clocks[k] on (the last one also
            after clocks[N]).
        options: further keyword arguments of `simulate_impacts`.
    """
    clocks = np.asarray(clocks, dtype=float).ravel()
    controls = np.atleast_2d(np.asarray(controls, dtype=float))
    if controls.shape[0] != len(clocks) - 1:
        raise InvalidInput(f"`controls` has {controls.shape[0]} rows for {len(clocks)} "
                           "clock values: expected one control per interval")

    boundaries = clocks.tolist()  # bisect on a list: numpy's per-call cost shows here
    last = len(controls) - 1

    def u_of_t(t: float) -> np.ndarray:
        return controls[min(max(bisect.bisect_right(boundaries, t) - 1, 0), last)]

    return simulate_impacts(cls, x0, u_of_t if controls.shape[1] else None, T,
                            breakpoints=clocks[1:], **options)


def _stops(breakpoints: Sequence[float], T: float) -> list[float]:
    """The ends of the integration segments: the breakpoints inside (0, T), and T."""
    return sorted({float(b) for b in breakpoints if 0.0 < b < T} | {float(T)})


def _segment(control: Callable[[float], np.ndarray], stops: list[float],
             t_cur: float) -> tuple[float, Callable[[float], np.ndarray]]:
    """(end of the segment from t_cur, its control). Within a segment the control is its
    left limit at the segment's end, so that a jump at the breakpoint is not seen (as an
    event) before it."""
    t_stop = next(b for b in stops if b > t_cur)
    t_left = float(np.nextafter(t_stop, -np.inf))

    def segment_control(t: float) -> np.ndarray:
        return control(min(t, t_left))
    return t_stop, segment_control


def checked_control(u_of_t: Callable[[float], np.ndarray] | None,
                    n_u: int) -> Callable[[float], np.ndarray]:
    """`u_of_t` checked to return shape (n_u,) [N, N m] at every call; zeros(0) for a
    system without controls when it is None."""
    if u_of_t is None:
        if n_u:
            raise InvalidInput(f"`u_of_t` is None but the system has {n_u} controls: give "
                               f"a function of time returning shape ({n_u},)")

        def control(t: float) -> np.ndarray:
            return np.zeros(0)
        return control

    def checked(t: float) -> np.ndarray:
        value = np.atleast_1d(np.asarray(u_of_t(t), dtype=float))
        if value.shape != (n_u,):
            raise InvalidInput(f"`u_of_t` must return shape ({n_u},), got {value.shape}")
        return value
    return checked


def _simulate_elastic_contacts(
    cls: ComplementarityLagrangianSystem,
    x0: np.ndarray,
    control: Callable[[float], np.ndarray],
    T: float,
    *,
    rtol: float,
    atol: float,
    max_events: int,
    max_rhs_evaluations: int,
    rest_velocity: float,
    max_step: float,
    breakpoints: Sequence[float],
    start_gap_tolerance: float,
) -> ReferenceSimulation:
    """Several frictionless elastic contacts: free flight between Newton impacts."""
    for contact in cls.contacts:
        if contact.mu > 0 or contact.restitution == 0:
            raise IncompatibleOptions(
                f"`simulate_impacts` with several contacts needs them frictionless and "
                f"elastic; contact {contact.name!r} has mu = {contact.mu}, "
                f"e = {contact.restitution}")
    n, n_c = cls.n_q, cls.n_contacts
    q, v, u = cls.q, cls.v, cls.u
    normals = ca.horzcat(*[c.normal for c in cls.contacts])
    gaps = ca.vertcat(*[c.gap for c in cls.contacts])
    terms = StackedFunction("reference_terms", [ca.vertcat(q, v), u],
                             [cls.acceleration, cls.solve_mass(normals), normals, gaps])
    restitution = np.array([c.restitution for c in cls.contacts])
    calls = 0

    def evaluate(x: np.ndarray, u_now: np.ndarray):
        nonlocal calls
        calls += 1
        if calls > max_rhs_evaluations:
            raise _BudgetExceeded
        return terms(x, u_now)

    gap0 = evaluate(x0, control(0.0))[3].ravel()
    if np.any(gap0 < -start_gap_tolerance):
        raise InvalidInput(f"`x0` is inside an obstacle: gaps(q0) = {gap0.tolist()}")

    def bounce(t: float, x: np.ndarray,
               gap_tolerance: float = 1e-9) -> tuple[np.ndarray, list[ReferenceImpact]]:
        """Newton impulses on every closed, approaching contact (a corner: two)."""
        done: list[ReferenceImpact] = []
        for _ in range(2 * n_c):
            _, minv_n, nrm, gap = evaluate(x, control(t))
            vn = nrm.T @ x[n:]
            closing = np.flatnonzero((gap.ravel() <= gap_tolerance) & (vn < 0.0))
            if closing.size == 0:
                return x, done
            if closing.size > 1:
                coupling = nrm[:, closing].T @ minv_n[:, closing]
                off = coupling - np.diag(np.diag(coupling))
                if np.abs(off).max() > 1e-9 * np.abs(coupling).max():
                    raise IncompatibleOptions(
                        "contacts closing together are not kinetically orthogonal "
                        f"(n_i^T M^-1 n_j = {coupling.tolist()}): the impulse is not unique")
            i = int(closing[np.argmin(vn[closing])])
            if restitution[i] * -vn[i] < rest_velocity:
                raise IncompatibleOptions(
                    f"contact {cls.contacts[i].name!r} comes to rest at t = {t:.6g} s: "
                    "persistent contact with several contacts is not simulated")
            lam_n = -(1 + restitution[i]) * vn[i] / (nrm[:, i] @ minv_n[:, i])
            post = x.copy()
            post[n:] += minv_n[:, i] * lam_n
            done.append(ReferenceImpact(t, x, post, float(lam_n), np.zeros(0), contact=i))
            x = post
        raise IncompatibleOptions(f"the impacts at t = {t:.6g} s do not end")

    def touchdown(i: int, u_now: Callable[[float], np.ndarray]):
        def event(t: float, x: np.ndarray) -> float:
            return float(evaluate(x, u_now(t))[3].ravel()[i])
        event.terminal, event.direction = True, -1
        return event

    def first_step(t: float, x: np.ndarray) -> float | None:
        """A first step short enough that a contact leaving its wall has an open gap at
        its end: else the touchdown event's root finder lands on the start itself."""
        a_free, _, nrm, gap = evaluate(x, control(t))
        vn, an = nrm.T @ x[n:], nrm.T @ a_free.ravel()
        leaving = np.flatnonzero(gap.ravel() <= 1e-9)
        if leaving.size == 0:
            return None
        flight = float(np.min(vn[leaving] / np.maximum(np.abs(an[leaving]), 1e-300)))
        return 0.5 * flight if flight > 0 else None

    ts, xs = [np.array([0.0])], [x0[None, :]]
    impacts: list[ReferenceImpact] = []
    t_cur, x_cur = 0.0, x0.copy()
    status, message = "success", f"reached T = {T}"
    stops = _stops(breakpoints, T)
    end_impacts: tuple[ReferenceImpact, ...] = ()
    try:
        x_cur, first = bounce(t_cur, x_cur)
        if first:
            impacts += first
            ts.append(np.array([t_cur]))
            xs.append(x_cur[None, :])
        while t_cur < T:
            t_stop, segment_control = _segment(control, stops, t_cur)

            def rhs(t: float, x: np.ndarray, u_now=segment_control) -> np.ndarray:
                return np.concatenate([x[n:], evaluate(x, u_now(t))[0].ravel()])

            step = first_step(t_cur, x_cur)
            if step is not None:
                step = min(step, t_stop - t_cur, max_step)
            with np.errstate(under="ignore"):
                sol = solve_ivp(rhs, (t_cur, t_stop), x_cur, method="DOP853", rtol=rtol,
                                atol=atol, max_step=max_step, first_step=step,
                                events=[touchdown(i, segment_control) for i in range(n_c)])
            if sol.status == -1:
                raise InvalidInput(f"reference integration failed: {sol.message}")
            ts.append(sol.t[1:])
            xs.append(sol.y.T[1:])
            t_cur, x_cur = float(sol.t[-1]), sol.y[:, -1].copy()
            if sol.status == 1 and t_cur >= T - _END_TIME_TOLERANCE * max(T, 1.0):
                break  # an impact at T: reported in end_impacts, not applied
            if sol.status == 1:
                x_cur, new = bounce(t_cur, x_cur)
                if not new:  # a grazing touch: nothing to do
                    continue
                impacts += new
                ts.append(np.array([t_cur]))
                xs.append(x_cur[None, :])
                if len(impacts) > max_events:
                    status = "max_events"
                    message = f"stopped after {max_events} events at t = {t_cur}"
                    break
        if status == "success":
            try:
                end_impacts = tuple(bounce(T, x_cur, END_GAP_TOLERANCE)[1])
            except IncompatibleOptions:  # a contact coming to rest at T: no impact to add
                pass
    except _BudgetExceeded:
        status = "max_rhs_evaluations"
        message = f"stopped after {max_rhs_evaluations} model evaluations near t = {t_cur:.6g} s"
    return ReferenceSimulation(
        t=np.concatenate(ts), x=np.concatenate(xs), impacts=tuple(impacts),
        modes=((0.0, FREE),), status=status, message=message, n_rhs=calls,
        end_impacts=end_impacts,
    )


def _split(minv_jac: np.ndarray, jac: np.ndarray):
    return minv_jac[:, :1], minv_jac[:, 1:], jac[:, :1], jac[:, 1:]


def _stick_forces(model: _Model, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    a_free, minv_jac, jac, drift, _ = model.terms(x, u)
    k = 1 + model.n_t
    delassus = jac[:, :k].T @ minv_jac[:, :k]
    rhs = jac[:, :k].T @ a_free + drift[:k]
    return np.linalg.solve(delassus, -rhs)


def _slip_rate(model: _Model, minv_jac: np.ndarray, jac: np.ndarray, that) -> float:
    """n^T M^-1 (n - mu B that), W_nn - mu W_nt that in the plane: the normal acceleration
    per unit normal force of a slip along `that`; <= 0 inside the Painleve region."""
    minv_n, minv_b, normal, _ = _split(minv_jac, jac)
    rate = normal[:, 0] @ minv_n[:, 0]
    if model.n_t:
        rate -= model.mu * normal[:, 0] @ (minv_b @ that)
    return float(rate)


def _slip_in_painleve_region(model: _Model, x: np.ndarray, u: np.ndarray, that) -> bool:
    if model.n_t != 1:
        return False
    _, minv_jac, jac, _, _ = model.terms(x, u)
    return _slip_rate(model, minv_jac, jac, that) <= 0


def _slip_normal_force(model: _Model, x: np.ndarray, u: np.ndarray, that: np.ndarray) -> float:
    a_free, minv_jac, jac, drift, _ = model.terms(x, u)
    return -(jac[:, 0] @ a_free + drift[0]) / _slip_rate(model, minv_jac, jac, that)


def _impact_without_collision(model: _Model, x: np.ndarray, u: np.ndarray):
    """The impulse that stops a pressed planar slip inside the Painleve region.

    There the slip has no consistent normal force (lambda_n = -phi / rate < 0). The
    impulse flow from v_n = 0 slips, which deepens the approach, until v_t stops (it always
    does, see `planar_impulse_flow`), then sticks until v_n = 0: both contact velocities
    end at zero, so Lambda = -W^-1 (v_n, v_t), which lies in the cone (|Lambda_t| /
    Lambda_n = W_nn / |W_nt| <= mu there).
    """
    n = model.n
    _, minv_jac, jac, _, _ = model.terms(x, u)
    lam = -np.linalg.solve(jac.T @ minv_jac, jac.T @ x[n:])
    post = x.copy()
    post[n:] += minv_jac @ lam
    return post, float(lam[0]), lam[1:]


def _contact_mode(
    model: _Model, x: np.ndarray, u: np.ndarray, stick_first: bool = False,
    force_slip: bool = False,
):
    """The contact mode at a state on the contact surface: free, slip (with a direction)
    or stick."""
    n = model.n
    a_free, minv_jac, jac, drift, _ = model.terms(x, u)
    phi = jac[:, 0] @ a_free + drift[0]
    if phi > 0:
        return FREE, None
    if model.n_t == 0:
        return SLIP, None
    vt = jac[:, 1:].T @ x[n:]
    speed = np.linalg.norm(vt)
    if speed > 1e-12 and not stick_first:
        return SLIP, vt / speed
    lam = _stick_forces(model, x, u)
    if lam[0] < 0:
        return FREE, None
    lam_t = lam[1:]
    if not force_slip and np.linalg.norm(lam_t) <= model.mu * lam[0] * (1 + 1e-12):
        return STICK, None
    return SLIP, -lam_t / np.linalg.norm(lam_t)


def _zero_tangential(model: _Model, x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Remove the O(tolerance) tangential velocity left at a slip-stop event."""
    n = model.n
    _, minv_jac, jac, _, _ = model.terms(x, u)
    minv_b, b = minv_jac[:, 1:], jac[:, 1:]
    vt = b.T @ x[n:]
    w = b.T @ minv_b
    x = x.copy()
    x[n:] -= minv_b @ np.linalg.solve(w, vt)
    return x


def _phase(model: _Model, mode: str, direction, control, surface: float = 0.0):
    n = model.n
    mu = model.mu

    def tangent_direction(vt: np.ndarray) -> np.ndarray:
        speed = np.linalg.norm(vt)
        return vt / speed if speed > 1e-12 else direction

    if mode == FREE:
        def rhs(t, x):
            return np.concatenate([x[n:], model.terms(x, control(t))[0]])

        def touchdown(t, x):
            return model.terms(x, control(t))[4] - surface

        touchdown.terminal, touchdown.direction = True, -1
        return rhs, [touchdown]

    if mode == SLIP:
        def forces(t, x):
            u = control(t)
            a_free, minv_jac, jac, drift, _ = model.terms(x, u)
            if model.n_t == 0:
                lam_n = -(jac[:, 0] @ a_free + drift[0]) / (jac[:, 0] @ minv_jac[:, 0])
                return a_free + minv_jac[:, 0] * lam_n, lam_n
            # Planar slip keeps the phase's direction until the stop event: the sign of
            # v_t would flip the rhs inside a step that overshoots v_t = 0, and the step
            # size then collapses there instead of the event firing (measured: a hopper
            # replay stalled at |v_t| = 2e-6 m/s).
            that = direction if model.n_t == 1 else tangent_direction(jac[:, 1:].T @ x[n:])
            lam_n = _slip_normal_force(model, x, u, that)
            lam_t = -mu * lam_n * that
            return a_free + minv_jac[:, 0] * lam_n + minv_jac[:, 1:] @ lam_t, lam_n

        def rhs(t, x):
            return np.concatenate([x[n:], forces(t, x)[0]])

        def lift_off(t, x):
            return forces(t, x)[1]

        lift_off.terminal, lift_off.direction = True, -1
        events = [lift_off]
        if model.n_t:
            reference = direction.copy()

            def stop(t, x):
                jac = model.terms(x, control(t))[2]
                return float((jac[:, 1:].T @ x[n:]) @ reference)

            stop.terminal, stop.direction = True, -1
            events.append(stop)
        return rhs, events

    # STICK
    def stick(t, x):
        u = control(t)
        a_free, minv_jac, jac, drift, _ = model.terms(x, u)
        k = 1 + model.n_t
        lam = np.linalg.solve(jac[:, :k].T @ minv_jac[:, :k], -(jac[:, :k].T @ a_free + drift[:k]))
        return a_free + minv_jac[:, :k] @ lam, lam

    def rhs(t, x):
        return np.concatenate([x[n:], stick(t, x)[0]])

    def lift_off(t, x):
        return stick(t, x)[1][0]

    def cone(t, x):
        lam = stick(t, x)[1]
        return mu * lam[0] - np.linalg.norm(lam[1:])

    lift_off.terminal, lift_off.direction = True, -1
    cone.terminal, cone.direction = True, -1
    return rhs, [lift_off, cone]


def planar_impulse_flow(w: np.ndarray, vn: float, vt: float, mu: float):
    """Normal and tangential impulse of an inelastic planar impact by the impulse flow.

    w: the 2x2 Delassus matrix [n b]^T M^{-1} [n b]; (vn, vt): contact velocities before
    the impact. Returns (Lambda_n, Lambda_t) that bring v_n to zero (module docstring).
    """
    lam_n = lam_t = 0.0
    scale = max(abs(vn), abs(vt), 1e-300)
    for _ in range(4):  # slip -> stick -> end, or slip -> reversed slip -> end
        if vn >= 0.0:
            break
        if abs(vt) <= 1e-14 * scale:
            vt = 0.0
            ratio = -w[1, 0] / w[1, 1]
            if abs(ratio) <= mu:
                rate_n = w[0, 0] + w[0, 1] * ratio
                if rate_n <= 0:
                    raise IncompatibleOptions("the impact jams: W_nn - W_nt W_tn / W_tt <= 0")
                step = -vn / rate_n
                lam_n, lam_t, vn = lam_n + step, lam_t + ratio * step, 0.0
                break
            ratio = -mu * math.copysign(1.0, w[1, 0])  # slips the way W_tn pushes
        else:
            ratio = -mu * math.copysign(1.0, vt)
        rate_n = w[0, 0] + w[0, 1] * ratio
        rate_t = w[1, 0] + w[1, 1] * ratio
        # Inside the Painleve region (rate_n <= 0) the slip drives v_n further down, but
        # there the slip always stops first: W_nt^2 < W_nn W_tt <= mu |W_nt| W_tt gives
        # |W_nt| < mu W_tt, so rate_t opposes v_t, and the stick piece (rate_n of the
        # stick ratio: W's Schur complement, > 0) ends the impact.
        closes = -vn / rate_n if rate_n > 0 else math.inf
        stop_at = -vt / rate_t if vt != 0.0 and rate_t * vt < 0 else math.inf
        if not min(closes, stop_at) < math.inf:
            raise IncompatibleOptions(
                "the impact jams (Painleve): W_nn + W_nt lambda_t <= 0 while slipping")
        stops = stop_at < closes
        step = stop_at if stops else closes
        lam_n, lam_t = lam_n + step, lam_t + ratio * step
        vn = vn + rate_n * step
        vt = 0.0 if stops else vt + rate_t * step
        if not stops:
            vn = 0.0
            break
    return lam_n, lam_t


def _impact(model: _Model, x: np.ndarray, u: np.ndarray, rest_velocity: float):
    n = model.n
    _, minv_jac, jac, _, _ = model.terms(x, u)
    minv_n, minv_b, normal, tangents = _split(minv_jac, jac)
    v = x[n:]
    vn = float(normal[:, 0] @ v)
    delassus = float(normal[:, 0] @ minv_n[:, 0])
    scale = max(1.0, float(np.abs(minv_jac).max()))
    rest = model.e == 0 or abs(vn) * model.e < rest_velocity
    e = 0.0 if rest else model.e
    orthogonal = True
    if model.n_t:
        cross = tangents.T @ minv_n[:, 0]
        w_t = tangents.T @ minv_b
        w = float(np.mean(np.diag(w_t)))
        orthogonal = (np.abs(cross).max() <= 1e-9 * scale
                      and np.abs(w_t - w * np.eye(model.n_t)).max() <= 1e-9 * scale)
        if not orthogonal and not (model.n_t == 1 and e == 0.0):
            raise IncompatibleOptions(
                "`simulate_impacts` needs B^T M^{-1} n = 0 and B^T M^{-1} B = w I at an "
                "elastic or 3-D frictional impact; "
                f"got B^T M^-1 n = {cross}, B^T M^-1 B = {w_t.tolist()}"
            )
    if not orthogonal:  # an inelastic planar contact coupled through M(q): a leg
        lam_n, lam_t_1 = planar_impulse_flow(jac.T @ minv_jac, vn,
                                              float(tangents[:, 0] @ v), model.mu)
        lam_t = np.array([lam_t_1])
    else:
        lam_n = -(1 + e) * min(vn, 0.0) / delassus
        lam_t = np.zeros(model.n_t)
        if model.n_t:
            vt = tangents.T @ v
            stick = -vt / w
            if np.linalg.norm(stick) <= model.mu * lam_n:
                lam_t = stick
            else:
                lam_t = -model.mu * lam_n * vt / np.linalg.norm(vt)
    x = x.copy()
    x[n:] = v + minv_n[:, 0] * lam_n + (minv_b @ lam_t if model.n_t else 0.0)
    if rest:  # exactly on the contact surface's velocity constraint
        x[n:] -= minv_n[:, 0] * (normal[:, 0] @ x[n:]) / delassus
    return x, float(lam_n), lam_t, rest
