"""tfcontact.robot: Pinocchio models, their CasADi symbolic twin, contact candidates.

Entry point: `load_robot(source, *, base, locked_joints, contacts) -> Robot`.
"""

from tfcontact.robot.contact import ContactTerms, Ground, contact_terms
from tfcontact.robot.loading import REPO_ROOT, Robot, load_robot, project_robots
from tfcontact.robot.spec import BASE_COORDINATES, BASES, PLANAR_BASES, ContactSpec, RobotSpec
from tfcontact.robot.twin import RobotTwin

__all__ = [
    "BASE_COORDINATES",
    "BASES",
    "PLANAR_BASES",
    "REPO_ROOT",
    "ContactSpec",
    "ContactTerms",
    "Ground",
    "Robot",
    "RobotSpec",
    "RobotTwin",
    "contact_terms",
    "load_robot",
    "project_robots",
]
