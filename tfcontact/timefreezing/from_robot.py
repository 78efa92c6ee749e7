"""A CLS from a loaded robot (`tfcontact.robot`): a thin adapter.

q, v and M(q), h(q, v) come from the robot's CasADi twin; each contact candidate's gap,
normal n(q) = J^T n_w and tangents B(q) = J^T T come from `Robot.contact_terms(ground)`,
against a `Ground` half-space or a `Terrain` of primitives (then n_w and T follow the
terrain's local normal).
The controls are the generalised forces of the actuated joints:
f_v = S^T u - h(q, v), with S selecting the velocity entries of the actuated joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact

BASE_JOINT = "root_joint"
"""The name `tfcontact.robot.load_robot` gives the base joint (never actuated)."""


def from_robot(
    robot: Any,
    ground: Any = None,
    *,
    mu: float | Sequence[float] | None = None,
    restitution: float = 0.0,
    a_n: float = 100.0,
    eps_t: float = 1e-7,
    actuated: Sequence[str] | None = None,
) -> ComplementarityLagrangianSystem:
    """The CLS of a `tfcontact.robot.Robot` against a ground half-space or a terrain.

    Main arguments:
        robot: a loaded robot (`tfcontact.robot.load_robot(..., contacts=...)`).
        ground: a `tfcontact.robot.Ground` or `tfcontact.robot.Terrain`; default flat
            ground at height 0.
        mu: Coulomb coefficient [-] of every contact (a number) or of each contact in
            order (a sequence); None: the terrain's `Terrain.friction` (its surfaces must
            agree), or 0 for a Ground (which carries none). 0: frictionless, no tangents.

    Other arguments:
        restitution, a_n, eps_t: as in `Contact`, for every contact.
        actuated: names of the actuated joints (default: every joint but the base
            `root_joint`); the controls u are their generalised forces [N, N m], in order.

    Returns:
        A `ComplementarityLagrangianSystem` in the twin's symbols q, v and new controls u.

    Raises:
        InvalidInput: the robot has no contact candidates, an unknown actuated joint, or
            a sequence `mu` of the wrong length.
        IncompatibleOptions: `mu` = None with a terrain whose surfaces differ in friction.
    """
    from tfcontact.robot import Ground, Terrain

    ground = Ground() if ground is None else ground
    terms = robot.contact_terms(ground)
    if not terms:
        raise InvalidInput(
            "the robot has no contact candidates: load it with "
            "`contacts=(ContactSpec(frame, radius), ...)`"
        )
    if mu is None:
        mu = ground.friction if isinstance(ground, Terrain) else 0.0
    mus = _coefficients(mu, [t.frame for t in terms])
    model = robot.model
    names = list(model.names[1:])
    chosen = [n for n in names if n != BASE_JOINT] if actuated is None else list(actuated)
    unknown = [n for n in chosen if n not in names]
    if unknown:
        raise InvalidInput(f"`actuated` names unknown joints {unknown}; joints: {names}")
    columns = []
    for name in chosen:
        joint = model.joints[model.getJointId(name)]
        columns += list(range(joint.idx_v, joint.idx_v + joint.nv))
    selection = np.zeros((robot.nv, len(columns)))
    selection[columns, np.arange(len(columns))] = 1.0
    twin = robot.twin
    u = ca.SX.sym("u", len(columns))
    forces = ca.mtimes(ca.DM(selection), u) - twin.h
    contacts = tuple(
        Contact(gap=t.gap, normal=t.normal, tangents=t.tangents if m > 0 else None, mu=m,
                restitution=restitution, a_n=a_n, eps_t=eps_t, name=t.frame)
        for t, m in zip(terms, mus, strict=True)
    )
    v_names = []
    for name in names:
        joint = model.joints[model.getJointId(name)]
        v_names += [name] if joint.nv == 1 else [f"{name}_{k}" for k in range(joint.nv)]
    return ComplementarityLagrangianSystem(
        q=twin.q, v=twin.v, u=u, mass_matrix=twin.M, forces=forces, contacts=contacts,
        q_names=tuple(f"q_{n}" for n in v_names), v_names=tuple(f"v_{n}" for n in v_names),
        control_names=tuple(f"u_{names_of(model, c)}" for c in columns),
    )


def _coefficients(mu: Any, frames: list[str]) -> list[float]:
    """One Coulomb coefficient per contact (their range is checked by `Contact`)."""
    if isinstance(mu, Sequence | np.ndarray) and not isinstance(mu, str):
        values = list(np.ravel(mu)) if isinstance(mu, np.ndarray) else list(mu)
        if len(values) != len(frames):
            raise InvalidInput(
                f"`mu` has {len(values)} coefficients but the robot has {len(frames)} "
                f"contacts {frames}; give one per contact, in order, or a single number"
            )
    else:
        values = [mu] * len(frames)
    for value in values:
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise InvalidInput(f"`mu` must be a number or one number per contact, got {mu!r}")
    return [float(v) for v in values]


def names_of(model: Any, v_index: int) -> str:
    """The joint name (with an axis suffix for multi-DoF joints) of velocity entry v_index."""
    for i in range(1, model.njoints):
        joint = model.joints[i]
        if joint.idx_v <= v_index < joint.idx_v + joint.nv:
            name = model.names[i]
            return name if joint.nv == 1 else f"{name}_{v_index - joint.idx_v}"
    raise InvalidInput(f"no joint has velocity index {v_index}")
