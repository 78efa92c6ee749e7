"""An elastic ball in a box: a time-freezing system with four walls (PROBLEMS.md TF-2).

A unit point mass q = (x, y) [m] in the plane, v [m/s], force u in R^2 [N], optional
gravity along -y, inside the box

    y >= -bottom,   x <= right,   y <= top,   x >= -left

(TF-2: R = 1, bottom = R + 0.05, right = R + 0.10, top = R + 0.15, left = R + 0.20).
`Elastic` handles one contact only, so the box is built here in Stewart form with nine
regions ([CSL21], nosnoc's `time_freezing_elastic_ball_in_box` example): the interior
(free flight, clock running), the four walls and the four corners. Wall i carries the
elastic auxiliary spring-damper along its normal (`timefreezing.elastic.normal_spring`,
stiffness k, damping from the restitution e, clock frozen); a corner carries the sum of
its two walls' fields. The switching functions are the four gaps c_i(q) (positive inside),
region j is the sign pattern S_j of c, indicators g = -S c.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.fesd.system import StewartSystem
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact
from tfcontact.timefreezing.elastic import elastic_damping, frozen_duration, normal_spring
from tfcontact.timefreezing.system import TimeFreezingSystem

WALLS = ("bottom", "right", "top", "left")
"""The walls in the order of the contacts and switching functions."""

#: TF-2's wall distances from the origin [m] for R = 1: bottom, right, top, left.
TF2_WALLS = (1.05, 1.10, 1.15, 1.20)

# Corners as pairs of walls (indices into WALLS).
_CORNERS = ((0, 1), (1, 2), (2, 3), (3, 0))


def box_cls(
    walls: tuple[float, float, float, float] = TF2_WALLS,
    *,
    restitution: float = 1.0,
    gravity: float = 0.0,
    mass: float = 1.0,
) -> ComplementarityLagrangianSystem:
    """The CLS of a controlled point mass in the box: four frictionless contacts.

    Args:
        walls: distances [m] of the bottom, right, top and left walls from the origin
            (the box is [-left, right] x [-bottom, top]), all > 0.
        restitution: e in (0, 1] of every wall.
        gravity: g [m/s^2] along -y (TF-2: 0).
        mass: m [kg].

    Returns:
        The CLS with contacts named after `WALLS`; gaps bottom = y + b, right = r - x,
        top = t - y, left = x + l.

    Raises:
        InvalidInput: a wall distance that is not positive, or e outside (0, 1].
    """
    walls = tuple(float(w) for w in walls)
    if len(walls) != 4 or not all(math.isfinite(w) and w > 0 for w in walls):
        raise InvalidInput(
            f"`walls` must be four positive distances (bottom, right, top, left) [m], "
            f"got {walls}")
    if not 0 < restitution <= 1:
        raise InvalidInput(
            f"`restitution` must be in (0, 1] for elastic walls, got {restitution!r}")
    q = ca.SX.sym("q", 2)
    v = ca.SX.sym("v", 2)
    u = ca.SX.sym("u", 2)
    bottom, right, top, left = walls
    gaps = (q[1] + bottom, right - q[0], top - q[1], q[0] + left)
    contacts = tuple(Contact(gap=gap, restitution=restitution, name=name)
                     for gap, name in zip(gaps, WALLS, strict=True))
    forces = u - ca.vertcat(0, mass * gravity)
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.SX(mass * ca.DM.eye(2)), forces=forces,
        contacts=contacts, q_names=("q_x", "q_y"), v_names=("v_x", "v_y"),
        control_names=("u_x", "u_y"),
    )


def ball_in_box(
    walls: tuple[float, float, float, float] = TF2_WALLS,
    *,
    stiffness: float = 100.0,
    restitution: float = 1.0,
    gravity: float = 0.0,
    mass: float = 1.0,
) -> TimeFreezingSystem:
    """The elastic time-freezing system of a ball in a box (module docstring).

    Args:
        walls: distances [m] of the bottom, right, top and left walls from the origin.
        stiffness: k of the auxiliary springs [1/s^2 in numerical time] (TF-2: 100).
        restitution: e in (0, 1] (TF-2: 1, no damping).
        gravity: g [m/s^2] along -y (TF-2: 0).
        mass: m [kg].

    Returns:
        A `TimeFreezingSystem` (kind "elastic", Stewart form, 9 regions) in y = (q, v, t)
        with the CLS of `box_cls` attached (its four gaps serve the verification).
    """
    if not (isinstance(stiffness, int | float) and math.isfinite(stiffness) and stiffness > 0):
        raise InvalidInput(f"`stiffness` must be a finite number > 0, got {stiffness!r}")
    cls = box_cls(walls, restitution=restitution, gravity=gravity, mass=mass)
    damping = elastic_damping(restitution, stiffness)  # 0 for e = 1
    t = ca.SX.sym("t")
    y = ca.vertcat(cls.q, cls.v, t)
    springs = [ca.vertcat(*normal_spring(cls, i, stiffness=stiffness, damping=damping), 0)
               for i in range(4)]
    modes = [ca.vertcat(cls.v, cls.acceleration, 1), *springs]
    signs = [np.ones(4)]
    names = ["interior"]
    for i, wall in enumerate(WALLS):
        row = np.ones(4)
        row[i] = -1
        signs.append(row)
        names.append(wall)
    for i, j in _CORNERS:
        modes.append(springs[i] + springs[j])
        row = np.ones(4)
        row[[i, j]] = -1
        signs.append(row)
        names.append(f"{WALLS[i]}_{WALLS[j]}")
    modes_sx = ca.horzcat(*modes)
    switching = ca.vertcat(*[c.gap for c in cls.contacts])
    pss = StewartSystem.from_sign_matrix(
        y, cls.u, modes_sx, switching, np.array(signs),
        state_names=(*cls.q_names, *cls.v_names, "t"), control_names=cls.control_names,
    )
    return TimeFreezingSystem(
        pss=pss, kind="elastic", clock_index=4, q_index=slice(0, 2), v_index=slice(2, 4),
        modes=modes_sx, region_names=tuple(names), cls=cls,
        info=(("stiffness", float(stiffness)), ("damping", damping),
              ("restitution", float(restitution)), ("walls", walls),
              ("frozen_duration", frozen_duration(restitution, stiffness))),
    )


def circle_reference(t, *, radius: float, omega: float, phase: float = 0.0):
    """The circle to track: q_ref = R (cos(w t + a), sin(w t + a)) [m] and
    v_ref = R w (-sin(w t + a), cos(w t + a)) [m/s] (the seed's issue; TF-2 writes the same
    circle as R (sin, cos) starting at a = pi/4). Works on SX and on numpy arrays.

    Returns:
        (q_ref, v_ref), each a pair (x, y).
    """
    lib = ca if isinstance(t, ca.SX | ca.MX) else np
    angle = omega * t + phase
    q_ref = (radius * lib.cos(angle), radius * lib.sin(angle))
    v_ref = (-radius * omega * lib.sin(angle), radius * omega * lib.cos(angle))
    return q_ref, v_ref
