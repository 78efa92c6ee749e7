"""Serialisable descriptions of a robot: what to load, which base, what to lock, which contacts.

A `RobotSpec` holds only plain data (strings, floats, tuples) so that a trajectory
file can store it as JSON and a viewer can rebuild the same robot later with
`load_robot(RobotSpec.from_dict(json.loads(text)))`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from tfcontact.errors import InvalidInput

#: Base joints `load_robot` can put between the world and the URDF's root link.
#:
#: * ``"fixed"``: the root link is welded to the world (the URDF as written).
#: * ``"planar"``: x, z, pitch: prismatic X, prismatic Z, revolute Y (nq = nv = 3).
#: * ``"planar_xz"``: x, z: prismatic X, prismatic Z, no rotation (nq = nv = 2).
#: * ``"vertical"``: z: one prismatic Z joint (nq = nv = 1), a vertical rail (a leg test
#:   bench); the robot's own joints move in the x-z plane.
#: * ``"floating"``: translation then ZYX Euler angles (nq = nv = 6),
#:   q_base = (x, y, z, yaw, pitch, roll), R = Rz(yaw) Ry(pitch) Rx(roll).
BASES: tuple[str, ...] = ("fixed", "planar", "planar_xz", "vertical", "floating")

#: Bases whose motion stays in the world x-z plane (one tangent direction per contact).
PLANAR_BASES: tuple[str, ...] = ("planar", "planar_xz", "vertical")

#: The base joint's coordinates of each base, in order, with their units.
BASE_COORDINATES: dict[str, tuple[tuple[str, str], ...]] = {
    "fixed": (),
    "planar": (("x", "m"), ("z", "m"), ("pitch", "rad")),
    "planar_xz": (("x", "m"), ("z", "m")),
    "vertical": (("z", "m"),),
    "floating": (("x", "m"), ("y", "m"), ("z", "m"), ("yaw", "rad"), ("pitch", "rad"),
                 ("roll", "rad")),
}


def dof_units(model: Any, base: str) -> list[tuple[str, str]]:
    """(joint, unit of the coordinate) per velocity entry of a Pinocchio model."""
    out: list[tuple[str, str]] = []
    for j in range(1, model.njoints):
        joint, name = model.joints[j], model.names[j]
        kind = joint.shortname()
        if name == "root_joint" and base in BASE_COORDINATES:
            units = [unit for _, unit in BASE_COORDINATES[base]]
        elif "Prismatic" in kind or kind[:11] == "JointModelP" or "Translation" in kind:
            units = ["m"] * joint.nv
        elif ("Revolute" in kind or kind[:11] == "JointModelR" or "SphericalZYX" in kind):
            units = ["rad"] * joint.nv
        else:
            units = ["-"] * joint.nv
        out += [(name, unit) for unit in units]
    return out


@dataclass(frozen=True)
class ContactSpec:
    """A contact candidate: a sphere of radius `radius` [m] centred on the origin of `frame`.

    Args:
        frame: name of a frame of the Pinocchio model (a link, a joint or a fixed frame).
        radius: sphere radius [m], > 0. A point foot is a small sphere.

    Raises:
        InvalidInput: empty frame name or a radius that is not a positive finite number.
    """

    frame: str
    radius: float

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str) or not self.frame:
            raise InvalidInput(
                f"`frame` must be a non-empty frame name, got {self.frame!r}; "
                "pass the name of a frame of the robot model"
            )
        if isinstance(self.radius, bool) or not isinstance(self.radius, int | float):
            raise InvalidInput(
                f"`radius` must be a number [m], got {type(self.radius).__name__} "
                f"{self.radius!r}"
            )
        if not math.isfinite(self.radius) or self.radius <= 0.0:
            raise InvalidInput(
                f"`radius` must be > 0 [m], got {self.radius!r} for frame `{self.frame}`; "
                "model a point foot as a small sphere, e.g. radius=0.01"
            )
        object.__setattr__(self, "radius", float(self.radius))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types: ``{"frame": str, "radius": float}``."""
        return {"frame": self.frame, "radius": self.radius}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ContactSpec:
        """Inverse of `to_dict`; missing or unknown keys raise InvalidInput."""
        _check_keys(data, {"frame", "radius"}, "ContactSpec")
        return cls(frame=data["frame"], radius=data["radius"])


@dataclass(frozen=True)
class RobotSpec:
    """Everything `load_robot` needs to rebuild a robot, as plain data.

    Args:
        source: a URDF path (absolute, or relative to the current directory or the
            repository root) or an example-robot-data name such as ``"solo12"``.
        base: one of `BASES`.
        locked_joints: names of joints fixed and removed from the model
            (`pinocchio.buildReducedModel`).
        contacts: contact candidates.
        locked_positions: the positions [rad or m] of the locked (1-DoF) joints, in the
            order of `locked_joints`; the empty default locks them at the neutral
            configuration (0).

    Raises:
        InvalidInput: wrong types, an unknown base, repeated names.
    """

    source: str
    base: str = "fixed"
    locked_joints: tuple[str, ...] = ()
    contacts: tuple[ContactSpec, ...] = ()
    locked_positions: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.source, str) or not self.source:
            raise InvalidInput(
                f"`source` must be a URDF path or an example-robot-data name, got "
                f"{self.source!r}"
            )
        if self.base not in BASES:
            raise InvalidInput(
                f"`base` must be one of {', '.join(BASES)}, got {self.base!r}"
            )
        if isinstance(self.locked_joints, str):
            raise InvalidInput(
                f"`locked_joints` must be a sequence of joint names, got the string "
                f"{self.locked_joints!r}; write ({self.locked_joints!r},)"
            )
        locked = tuple(self.locked_joints)
        for name in locked:
            if not isinstance(name, str) or not name:
                raise InvalidInput(f"`locked_joints` must hold joint names, got {name!r}")
        if len(set(locked)) != len(locked):
            raise InvalidInput(f"`locked_joints` names a joint twice: {locked}")
        contacts = tuple(self.contacts)
        for c in contacts:
            if not isinstance(c, ContactSpec):
                raise InvalidInput(
                    f"`contacts` must hold ContactSpec objects, got {type(c).__name__}; "
                    "write ContactSpec(frame, radius)"
                )
        frames = [c.frame for c in contacts]
        if len(set(frames)) != len(frames):
            raise InvalidInput(f"`contacts` names a frame twice: {frames}")
        positions = tuple(self.locked_positions)
        if positions and len(positions) != len(locked):
            raise InvalidInput(
                f"`locked_positions` has {len(positions)} values for {len(locked)} "
                f"`locked_joints` {locked}; give one per locked joint or none (neutral)"
            )
        for x in positions:
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise InvalidInput(f"`locked_positions` must hold finite numbers, got {x!r}")
        object.__setattr__(self, "locked_positions", tuple(float(x) for x in positions))
        object.__setattr__(self, "locked_joints", locked)
        object.__setattr__(self, "contacts", contacts)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (str, list, dict, float)."""
        return {
            "source": self.source,
            "base": self.base,
            "locked_joints": list(self.locked_joints),
            "contacts": [c.to_dict() for c in self.contacts],
            "locked_positions": list(self.locked_positions),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RobotSpec:
        """Inverse of `to_dict`; unknown keys raise InvalidInput."""
        _check_keys(data, {"source", "base", "locked_joints", "contacts", "locked_positions"},
                    "RobotSpec", required={"source"})
        return cls(
            source=data["source"],
            base=data.get("base", "fixed"),
            locked_joints=tuple(data.get("locked_joints", ())),
            contacts=tuple(ContactSpec.from_dict(c) for c in data.get("contacts", ())),
            locked_positions=tuple(data.get("locked_positions", ())),
        )


def _check_keys(data: Any, allowed: set[str], what: str, required: set[str] | None = None) -> None:
    if not isinstance(data, dict):
        raise InvalidInput(f"{what}.from_dict needs a dict, got {type(data).__name__}")
    unknown = set(data) - allowed
    if unknown:
        raise InvalidInput(
            f"{what}.from_dict got unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}"
        )
    missing = (allowed if required is None else required) - set(data)
    if missing:
        raise InvalidInput(f"{what}.from_dict is missing keys {sorted(missing)}")
