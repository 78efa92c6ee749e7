"""tfcontact.robot: Pinocchio models, their CasADi symbolic twin, contact candidates.

Entry point: `load_robot(source, *, base, locked_joints, contacts) -> Robot`; the ground
is a `Ground` half-space or a `Terrain` of primitives (`Plane`, `Box`, `Hole`).
"""

from tfcontact.robot.contact import ContactTerms, Ground, contact_terms
from tfcontact.robot.loading import REPO_ROOT, Robot, load_robot, project_robots
from tfcontact.robot.spec import (
    BASE_COORDINATES,
    BASES,
    PLANAR_BASES,
    ContactSpec,
    RobotSpec,
    dof_units,
)
from tfcontact.robot.terrain import Box, Hole, Plane, Region, Terrain
from tfcontact.robot.twin import RobotTwin

__all__ = [
    "BASE_COORDINATES",
    "BASES",
    "Box",
    "PLANAR_BASES",
    "REPO_ROOT",
    "Region",
    "ContactSpec",
    "ContactTerms",
    "Ground",
    "Hole",
    "Plane",
    "Robot",
    "RobotSpec",
    "RobotTwin",
    "dof_units",
    "Terrain",
    "contact_terms",
    "load_robot",
    "project_robots",
]
