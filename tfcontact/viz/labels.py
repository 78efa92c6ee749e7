"""Names with units of a trajectory's coordinates, velocities, controls and contacts.

Figures label their curves "x [m]", "v_x [m/s]", "u_knee [N m]" rather than q[0]. The
names come, in order of preference, from the sidecar's `model` (`describe_robot`: the
plan's own names, e.g. a task file's x, z, pitch, joint names, v_..., u_...), from the
Pinocchio model of the trajectory's robot (base coordinates of
`tfcontact.robot.BASE_COORDINATES`, then joint names), or are the indices q[j], v[j],
u[j] without a unit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tfcontact.plan_format.trajectory import Trajectory
from tfcontact.robot import BASE_COORDINATES, dof_units

_RATE_UNITS = {"m": "m/s", "rad": "rad/s", "-": "-"}


def label(name: str, unit: str | None) -> str:
    """"name [unit]", or the name alone for an unknown unit."""
    return f"{name} [{unit}]" if unit and unit != "-" else name


@dataclass(frozen=True)
class Labels:
    """Legend entries of a trajectory (module docstring).

    Attributes:
        q, v, u: one "name [unit]" per column of q, v and u.
        q_units, v_units, u_units: the distinct units of each group, in order of first use.
        contacts: one name per contact (its frame; "contact k" when unnamed).
        source: where the names came from: "model" (the sidecar), "robot" (the Pinocchio
            model) or "index".
    """

    q: tuple[str, ...]
    v: tuple[str, ...]
    u: tuple[str, ...]
    q_units: tuple[str, ...]
    v_units: tuple[str, ...]
    u_units: tuple[str, ...]
    contacts: tuple[str, ...]
    source: str


def _distinct(units: list[str | None]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(u for u in units if u and u != "-"))


def trajectory_labels(traj: Trajectory, model: Any = None) -> Labels:
    """The legend entries of `traj`; `model` (a Pinocchio model of its robot, optional)
    names the coordinates when the sidecar has no `model` entry."""
    nq, nv, nu = traj.q.shape[1], traj.v.shape[1], traj.u.shape[1]
    contacts = []
    for k, spec in enumerate(traj.robot.get("contacts", []) or []):
        frame = spec.get("frame") if isinstance(spec, dict) else None
        contacts.append(str(frame) if frame else f"contact {k}")
    if len(contacts) != traj.n_contacts:
        contacts = [f"contact {k}" for k in range(traj.n_contacts)]
    names: dict[str, list[tuple[str, str | None]]]
    if traj.model:
        names = {key: [(e["name"], e["unit"]) for e in traj.model[key]]
                 for key in ("coordinates", "velocities", "controls")}
        source = "model"
    elif model is not None and model.nq == nq and model.nv == nv == nq:
        base = str(traj.robot.get("base", "fixed"))
        dofs = dof_units(model, base)
        base_names = [name for name, _ in BASE_COORDINATES.get(base, ())]
        coords = []
        for k, (joint, unit) in enumerate(dofs):
            if joint == "root_joint" and k < len(base_names):
                coords.append((base_names[k], unit))
            else:
                coords.append((joint, unit))
        names = {"coordinates": coords,
                 "velocities": [("v_" + n, _RATE_UNITS[u]) for n, u in coords],
                 "controls": [(f"u[{j}]", None) for j in range(nu)]}
        source = "robot"
    else:
        names = {"coordinates": [(f"q[{j}]", None) for j in range(nq)],
                 "velocities": [(f"v[{j}]", None) for j in range(nv)],
                 "controls": [(f"u[{j}]", None) for j in range(nu)]}
        source = "index"
    q, v, u = (names[k] for k in ("coordinates", "velocities", "controls"))
    return Labels(
        q=tuple(label(n, un) for n, un in q), v=tuple(label(n, un) for n, un in v),
        u=tuple(label(n, un) for n, un in u),
        q_units=_distinct([un for _, un in q]), v_units=_distinct([un for _, un in v]),
        u_units=_distinct([un for _, un in u]), contacts=tuple(contacts), source=source,
    )
