"""The physical checks of a plan: contact impulses, friction cone, maximal dissipation,
clock, Painleve.

The checks use only the plan's samples and the original system's data (M(q), smooth
forces, contact Jacobians), never the time-freezing modes the plan was computed with, so
that an error in those modes shows up here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import linprog

from tfcontact.timefreezing import ComplementarityLagrangianSystem


def contact_impulses(
    t: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    mass_matrix: Callable[[np.ndarray], np.ndarray],
    smooth_force: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    contact_jacobian: Callable[[np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """Contact impulses over each sample interval from the momentum balance.

    On [t_k, t_{k+1}]: M (v_{k+1} - v_k) - int f_v dt = J^T Lambda, with M and J taken at
    the interval's start (q does not jump) and the smooth force integrated by the
    trapezoidal rule in physical time. An impact has t_{k+1} = t_k and so no smooth part.

    Args:
        t: physical times, shape (K,); q, v: shape (K, n_v); u: controls, shape (K, n_u).
        mass_matrix: M(q), (n_v, n_v). smooth_force: f_v(q, v, u), (n_v,).
        contact_jacobian: the columns [n_1, B_1, n_2, B_2, ...] in R^{n_v}, (n_v, m).

    Returns:
        impulses: shape (K - 1, m), least-squares Lambda per interval.
        fit_residual: shape (K - 1,), ||M dv - int f_v - J Lambda|| (what contacts cannot explain).
    """
    n = len(t) - 1
    impulses = []
    residuals = []
    for k in range(n):
        dt = t[k + 1] - t[k]
        momentum = mass_matrix(q[k]) @ (v[k + 1] - v[k])
        force = 0.5 * dt * (smooth_force(q[k], v[k], u[k]) + smooth_force(q[k + 1], v[k + 1], u[k]))
        jac = contact_jacobian(q[k])
        lam, *_ = np.linalg.lstsq(jac, momentum - force, rcond=None)
        impulses.append(lam)
        residuals.append(np.linalg.norm(jac @ lam - (momentum - force)))
    return np.asarray(impulses), np.asarray(residuals)


def collocation_impulses(
    x_start: np.ndarray,
    x_stages: np.ndarray,
    h: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    u: np.ndarray,
    index: tuple[slice, slice, int],
    mass_matrix: Callable[[np.ndarray], np.ndarray],
    smooth_force: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    contact_jacobian: Callable[[np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """Contact impulses per finite element from the plan's collocation polynomials.

    A collocation method makes the stage derivatives exact on its polynomial: with
    X_j = x_0 + h sum_k A_jk X'_k, the numerical-time derivatives at the stages are
    X' = A^{-1} (X - x_0) / h. At every stage the contact force rate follows from the
    momentum balance in numerical time tau, M(q) dv/dtau - f_v(q, v, u) dt/dtau =
    J(q)^T lambda (least squares), and the element's impulse is h sum_j b_j lambda_j: the
    collocation quadrature, exact to the scheme's order, with no time step in the
    denominator, so frozen (impact) and running pieces are treated alike.

    Args:
        x_start: (E, n_y) states at the elements' starts; x_stages: (E, s, n_y).
        h: (E,) element lengths in numerical time; A, b: the collocation tableau.
        u: (E, n_u) physical controls per element.
        index: (q slice, v slice, clock index) into y.
        mass_matrix, smooth_force, contact_jacobian: as in `contact_impulses`.

    Returns:
        impulses: (E, m) contact impulses [N s]; fit_residual: (E,) the quadrature of
        ||M v' - f_v t' - J^T lambda||, what the contacts cannot explain [N s].
    """
    q_index, v_index, clock = index
    inverse = np.linalg.inv(np.asarray(A, dtype=float))
    b = np.asarray(b, dtype=float)
    impulses, residuals = [], []
    for e in range(len(h)):
        rates = inverse @ (x_stages[e] - x_start[e]) / h[e]
        lam_e, res_e = 0.0, 0.0
        for j in range(len(b)):
            qj, vj = x_stages[e, j, q_index], x_stages[e, j, v_index]
            rhs = (mass_matrix(qj) @ rates[j, v_index]
                   - smooth_force(qj, vj, u[e]) * rates[j, clock])
            jac = contact_jacobian(qj)
            lam, *_ = np.linalg.lstsq(jac, rhs, rcond=None)
            lam_e = lam_e + h[e] * b[j] * lam
            res_e += h[e] * b[j] * float(np.linalg.norm(jac @ lam - rhs))
        impulses.append(lam_e)
        residuals.append(res_e)
    return np.asarray(impulses), np.asarray(residuals)


def friction_cone_violation(
    impulses: np.ndarray, mu: Sequence[float], n_tangents: Sequence[int]
) -> float:
    """max over intervals and contacts of max(||Lambda_t|| - mu Lambda_n, -Lambda_n, 0).

    `impulses` columns are ordered per contact as (normal, tangent_1, ..., tangent_d).
    """
    worst = 0.0
    col = 0
    for mu_i, d in zip(mu, n_tangents, strict=True):
        normal = impulses[:, col]
        tangential = np.linalg.norm(impulses[:, col + 1 : col + 1 + d], axis=1)
        worst = max(worst, float(np.max(tangential - mu_i * normal, initial=0.0)),
                    float(np.max(-normal, initial=0.0)))
        col += 1 + d
    return worst


SLIP_THRESHOLD = 1e-3
"""Tangential contact speed [m/s] above which a contact counts as slipping: sticking in a
plan leaves a residual slip of the order of its complementarity tolerance, far below
1 mm/s, so a faster slip is real sliding whose friction must be on the cone's edge."""


def maximal_dissipation_violation(
    impulses: np.ndarray,
    slip_velocities: np.ndarray,
    mu: Sequence[float],
    n_tangents: Sequence[int],
    slip_threshold: float = SLIP_THRESHOLD,
) -> tuple[float, int]:
    """Coulomb's maximal dissipation on the elements where a contact slips.

    Inside the cone is not enough: while a contact slips with v_t = B^T v != 0, its
    friction dissipates as much as the cone allows, i.e. lies on the cone's edge against
    the slip, Lambda_t = -mu Lambda_n v_t / ||v_t||. An element counts as slipping for a
    contact if ||v_t|| > `slip_threshold` at every sample and the slip keeps its direction
    (the unit directions' pairwise dot products stay positive; planar: the same sign);
    its violation is ||Lambda_t + mu Lambda_n d||, d the normalised mean of the unit
    directions (exact for a planar slip; a 3-D slip turning by an angle within the element
    adds up to about that angle times mu Lambda_n). Elements that stick or reverse their
    slip are not checked: there the friction may lie anywhere in the cone
    (`friction_cone_violation`). An open contact must be given zero slip (it has no
    friction to check).

    Args:
        impulses: (E, m), columns per contact (normal, tangent_1, ..., tangent_d) [N s].
        slip_velocities: (E, P, sum of d) the tangential contact velocities B_i^T v at P
            samples of each element (e.g. its start, stages and end), contacts' tangent
            columns in the order of `impulses` [m/s].
        mu, n_tangents: per contact.
        slip_threshold: the slip speed below which a sample counts as sticking [m/s].

    Returns:
        (the largest violation over slipping elements and contacts [N s], 0.0 if none;
        the number of slipping element-contacts checked).
    """
    worst, checked = 0.0, 0
    col, slip_col = 0, 0
    for mu_i, d in zip(mu, n_tangents, strict=True):
        if d:
            slipping, direction = slip_directions(
                slip_velocities[:, :, slip_col : slip_col + d], slip_threshold)
            if np.any(slipping):
                direction = direction[slipping]
                normal = impulses[slipping, col]
                tangential = impulses[slipping, col + 1 : col + 1 + d]
                residual = tangential + mu_i * normal[:, None] * direction
                worst = max(worst, float(np.max(np.linalg.norm(residual, axis=1))))
                checked += int(np.count_nonzero(slipping))
        col += 1 + d
        slip_col += d
    return worst, checked


def slip_directions(slip: np.ndarray, slip_threshold: float = SLIP_THRESHOLD
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(E,) whether one contact slips on each element (||v_t|| > `slip_threshold` at every
    sample, unit directions pairwise at less than 90 degrees) and (E, d) its mean unit
    direction (`maximal_dissipation_violation`); `slip` is (E, P, d) [m/s]."""
    speed = np.linalg.norm(slip, axis=2)
    moving = np.all(speed > slip_threshold, axis=1)
    unit = slip / np.where(speed > 0.0, speed, 1.0)[:, :, None]
    aligned = np.all(np.einsum("epk,eqk->epq", unit, unit) > 0.0, axis=(1, 2))
    direction = unit.mean(axis=1)
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    return moving & aligned, direction / np.where(length > 0.0, length, 1.0)


def impulse_freedom(
    x_stages: np.ndarray,
    h: np.ndarray,
    b: np.ndarray,
    q_index: slice,
    contact_jacobian: Callable[[np.ndarray], np.ndarray],
) -> list[np.ndarray]:
    """Per finite element, the changes of its contact impulse that the momentum balance
    cannot see (statically indeterminate contacts: two feet side by side, a box on two
    corners).

    `collocation_impulses` takes the minimum-norm lambda_j at each stage; any lambda_j +
    P_j N c with N spanning the null space of the element's mean contact Jacobian (the
    (n_v, m) matrix J with M v' - f_v t' = J lambda, over its columns nonzero at every
    stage, i.e. contacts closed throughout) and P_j the projector onto the null space of
    J(q_j) reproduces every stage's momentum balance exactly. The
    element impulse then moves by K c, K = h sum_j b_j P_j N. One c per element: the
    stages' null spaces differ by O(|q_j - q_0|), so stage-wise shifts add nothing to first
    order, and cannot cancel into directions the contacts do not have.

    Args:
        x_stages: (E, s, n_y); h: (E,); b: the tableau's weights; q_index: q in y.
        contact_jacobian: as in `contact_impulses` (zero columns for open contacts).

    Returns:
        (E,) arrays K of shape (m, r), r = 0 where the impulse is unique.
    """
    b = np.asarray(b, dtype=float)
    freedom = []
    for e in range(len(h)):
        jacs = [np.asarray(contact_jacobian(x_stages[e, j, q_index]), dtype=float)
                for j in range(len(b))]
        m = jacs[0].shape[1]
        active = np.flatnonzero(np.all([np.abs(jac).max(axis=0) > 0.0 for jac in jacs],
                                       axis=0))
        mean = sum(bj * jac for bj, jac in zip(b, jacs, strict=True))[:, active]
        null = _null_space(mean)
        k = np.zeros((m, null.shape[1]))
        if null.shape[1]:
            for bj, jac in zip(b, jacs, strict=True):
                ja = jac[:, active]
                projected = null - np.linalg.pinv(ja, rcond=1e-10) @ (ja @ null)
                k[active] += h[e] * bj * projected
        freedom.append(k)
    return freedom


def _null_space(a: np.ndarray) -> np.ndarray:
    """An orthonormal basis (columns) of {z : a z = 0}, relative tolerance 1e-10."""
    if a.size == 0:
        return np.zeros((a.shape[1], 0))
    _, sv, vt = np.linalg.svd(a)
    rank = int(np.sum(sv > 1e-10 * max(float(sv.max(initial=0.0)), 1e-300)))
    return vt[rank:].T


CONE_FACES = 64
"""Faces of the polygon circumscribing a 3-D friction cone (and the dissipation residual's
disc) in `coulomb_split`'s linear program: the program's optimum is within
1 / cos(pi / 64) - 1 = 0.12 % of the exact one; the split it returns is judged exactly."""


def coulomb_split(
    impulses: np.ndarray,
    freedom: Sequence[np.ndarray],
    mu: Sequence[float],
    n_tangents: Sequence[int],
    slip_velocities: np.ndarray,
    slip_threshold: float = SLIP_THRESHOLD,
) -> np.ndarray:
    """The split of each element's contact impulse, among those its momentum balance
    admits (`impulse_freedom`: Lambda + K c), that is closest to Coulomb's law: it
    minimises the largest violation of the friction cone (`friction_cone_violation`) and,
    where a contact slips, of maximal dissipation (`maximal_dissipation_violation`).

    Where forces are not unique (several closed contacts), physics asks only that SOME
    admissible split obey the law: the minimum-norm split shares friction evenly between
    contacts whose normal forces differ (a pushed box whose contacts lie below its centre
    of mass) and pushes the one carrying less weight out of its cone. A linear program per
    element (HiGHS; 3-D cones and dissipation discs as circumscribed polygons of
    `CONE_FACES` faces) finds c; the element keeps the minimum-norm split unless the exact
    violation at the program's split is smaller. Elements without freedom are unchanged.

    Args:
        impulses: (E, m) minimum-norm impulses (`collocation_impulses`) [N s].
        freedom: (E,) arrays K (m, r) from `impulse_freedom`.
        mu, n_tangents: per contact.
        slip_velocities, slip_threshold: as in `maximal_dissipation_violation`.

    Returns:
        (E, m) the chosen impulses [N s].
    """
    split = np.array(impulses, dtype=float, copy=True)
    starts = np.cumsum([0] + [1 + d for d in n_tangents])[:-1]
    slip_starts = np.cumsum([0] + list(n_tangents))[:-1]
    slipping = [slip_directions(slip_velocities[:, :, a : a + d], slip_threshold)
                if d else None for a, d in zip(slip_starts, n_tangents, strict=True)]
    angles = 2 * np.pi * (np.arange(CONE_FACES) + 0.5) / CONE_FACES
    faces = {1: np.array([[1.0], [-1.0]]),
             2: np.column_stack([np.cos(angles), np.sin(angles)])}

    def violation(lam: np.ndarray, e: int) -> float:
        row = lam[None]
        cone = friction_cone_violation(row, mu, n_tangents)
        dissipation, _ = maximal_dissipation_violation(
            row, slip_velocities[e : e + 1], mu, n_tangents, slip_threshold)
        return max(cone, dissipation)

    for e, k in enumerate(freedom):
        if k.shape[1] == 0 or violation(split[e], e) == 0.0:
            continue
        # Rows w: each a violation measure w . Lambda <= s, with Lambda = impulses[e] + K c;
        # minimise s >= 0 over (c, s).
        rows = []
        for i, (col, d) in enumerate(zip(starts, n_tangents, strict=True)):
            if not np.any(k[col : col + 1 + d]):
                continue  # this contact's impulse is unique: nothing to choose
            row = np.zeros(len(split[e]))
            row[col] = -1.0
            rows.append(row)  # -Lambda_n <= s
            if not d:
                continue
            moving, direction = slipping[i]
            for face in faces[d]:
                row = np.zeros(len(split[e]))  # face . Lambda_t - mu Lambda_n <= s
                row[col + 1 : col + 1 + d], row[col] = face, -mu[i]
                rows.append(row)
                if moving[e]:  # face . (Lambda_t + mu Lambda_n dir) <= s
                    row = row.copy()
                    row[col] = mu[i] * face @ direction[e]
                    rows.append(row)
        if not rows:
            continue
        weights = np.array(rows)
        cost = np.zeros(k.shape[1] + 1)
        cost[-1] = 1.0
        result = linprog(cost, A_ub=np.column_stack([weights @ k, -np.ones(len(rows))]),
                         b_ub=-(weights @ impulses[e]),
                         bounds=[(None, None)] * k.shape[1] + [(0.0, None)], method="highs")
        if result.status != 0:
            continue
        candidate = impulses[e] + k @ result.x[:-1]
        if violation(candidate, e) < violation(split[e], e):
            split[e] = candidate
    return split


def clock_checks(clock: np.ndarray, horizon: float, tolerance: float) -> tuple[bool, float]:
    """(the clock never decreases by more than `tolerance`, |clock[-1] - horizon|)."""
    monotone = bool(np.all(np.diff(clock) >= -tolerance))
    return monotone, float(abs(clock[-1] - horizon))


def painleve_note(cls: ComplementarityLagrangianSystem, q_samples: np.ndarray,
                  closed: np.ndarray) -> str | None:
    """A note on the closed-contact samples (`q_samples` (S, n_q), `closed` (S, n_c)) where
    a frictional contact is ill-posed (`cls.function("painleve_margins")` < 0), or None.
    There a slip has no unique contact force: the plan's forces are not Coulomb's, and the
    exact replay may jam."""
    frictional = [i for i, c in enumerate(cls.contacts) if c.has_friction and closed[:, i].any()]
    if not frictional:
        return None
    margins = np.asarray(cls.function("painleve_margins")(q_samples.T)).T
    parts = []
    for i in frictional:
        inside = closed[:, i] & (margins[:, i] < 0)
        if inside.any():
            parts.append(f"contact {cls.contacts[i].name!r} at {int(inside.sum())} of "
                         f"{int(closed[:, i].sum())} closed samples (down to "
                         f"{margins[inside, i].min():.3g})")
    if not parts:
        return None
    return ("Painleve: the frictional contact is ill-posed (n^T M^-1 n - mu ||B^T M^-1 n|| "
            "< 0) for " + "; ".join(parts) + ": a slip there has no unique contact force")
