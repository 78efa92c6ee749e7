"""tfcontact.robot.loading's model checks: masses, inertias and M(q) are checked at load.

Each faulty URDF is robots/hopper.urdf with one substitution; the error must be
`InvalidRobotModel` (a `RobotLoadError`) naming the URDF link, the value found and the fix.
The project's robots and the example-robot-data robots used in the tests must still load.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tfcontact.errors import InvalidRobotModel, RobotLoadError
from tfcontact.robot import REPO_ROOT, load_robot

HOPPER = (REPO_ROOT / "robots" / "hopper.urdf").read_text()
LEG_MASS = '<mass value="0.1"/>'
LEG_INERTIA = '<inertia ixx="0.025" ixy="0" ixz="0" iyy="0.025" iyz="0" izz="0.025"/>'
ZERO_INERTIA = '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>'
FOOT_LINK = '<link name="foot">'


def hopper_with(tmp_path: Path, *substitutions: tuple[str, str]) -> Path:
    """robots/hopper.urdf with each (old, new) replaced once, written to tmp_path."""
    text = HOPPER
    for old, new in substitutions:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / "hopper_variant.urdf"
    path.write_text(text)
    return path


# (substitutions, joint or None, pattern the message must match); the link is always `leg`.
FAULTS = {
    "mass zero": (
        [(LEG_MASS, '<mass value="0"/>')], "leg_joint",
        r"joint `leg_joint` \(links `leg`, `foot`\) has mass 0 kg but a rotational inertia "
        r".*give link `leg` a positive "
        r"<mass value=\.\.\.>",
    ),
    "massless leg": (
        [(LEG_MASS, '<mass value="0"/>'), (LEG_INERTIA, ZERO_INERTIA)], "leg_joint",
        r"joint `leg_joint` moves links `leg`, `foot`, whose mass is 0 kg in all, so M\(q\) "
        r"is singular .*give link `leg` a positive <mass value=\.\.\.>",
    ),
    "negative mass": (
        [(LEG_MASS, '<mass value="-0.1"/>')], None,
        r"link `leg` has a negative mass -0\.1 kg; give link `leg` a positive "
        r"<mass value=\.\.\.>",
    ),
    "mass nan": (
        [(LEG_MASS, '<mass value="nan"/>')], None,
        r'link `leg` has <mass> value "nan", not a finite number .*give link `leg` a '
        r"positive <mass value=\.\.\.>",
    ),
    "centre of mass nan": (
        [('<origin xyz="0 0 0" rpy="0 0 0"/>\n      ' + LEG_MASS,
          '<origin xyz="0 nan 0" rpy="0 0 0"/>\n      ' + LEG_MASS)], None,
        r'link `leg` has <inertial><origin> xyz "0 nan 0", not a finite number',
    ),
    "negative inertia": (
        [('ixx="0.025"', 'ixx="-0.025"')], None,
        r"link `leg` has an inertia matrix with a negative principal moment -0\.025 kg m\^2",
    ),
    "inertia not positive definite": (  # positive diagonal, eigenvalues (-0.025, 0.025, 0.075)
        [('ixx="0.025" ixy="0"', 'ixx="0.025" ixy="0.05"')], None,
        r"link `leg` has an inertia matrix with a negative principal moment -0\.025 kg m\^2 "
        r"\(principal moments -0\.025, 0\.025, 0\.075\)",
    ),
    "triangle inequality": (  # positive definite, but 0.01 + 0.01 < 0.05: no body has it
        [(LEG_INERTIA, '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.05"/>')],
        "leg_joint",
        r"joint `leg_joint` \(links `leg`, `foot`\) has principal moments of inertia 0\.01, "
        r"0\.01, 0\.05 kg m\^2, which break the triangle inequality I1 \+ I2 >= I3 "
        r"\(0\.02 < 0\.05\).*give link `leg` an <inertia>",
    ),
}


@pytest.mark.parametrize("fault", list(FAULTS))
def test_faulty_hopper_is_refused_naming_the_link(tmp_path, fault):
    substitutions, joint, pattern = FAULTS[fault]
    path = hopper_with(tmp_path, *substitutions)
    with pytest.raises(InvalidRobotModel, match=pattern) as info:
        load_robot(path, base="planar")
    assert isinstance(info.value, RobotLoadError)  # callers catching the old error still do
    assert info.value.link == "leg"
    assert info.value.joint == joint
    assert str(info.value).startswith("`hopper_variant.urdf`: ")


def test_fault_in_a_locked_link_is_still_refused(tmp_path):
    """The raw URDF is checked too: locking merges the link but does not hide its fault."""
    path = hopper_with(tmp_path, (LEG_MASS, '<mass value="-0.1"/>'))
    with pytest.raises(InvalidRobotModel, match="link `leg` has a negative mass"):
        load_robot(path, base="planar", locked_joints=("leg_joint",))


def test_mass_matrix_singular_at_neutral_names_the_joint(tmp_path):
    """Every body is physical, but the leg is a point mass sliding along the hip axis: the
    hip's rotation moves no inertia, so M(q) = diag(0, m_l) is singular in the hip's row."""
    path = hopper_with(tmp_path, (LEG_INERTIA, ZERO_INERTIA),
                       ('<axis xyz="0 0 -1"/>', '<axis xyz="0 1 0"/>'))
    with pytest.raises(InvalidRobotModel, match=re.escape(
            "M(q) at the neutral configuration is singular in the row of joint `hip_joint`, "
            "which moves links `hip_link`: Cholesky pivot 0 ")) as info:
        load_robot(path, base="fixed")
    assert info.value.link == "hip_link"
    assert info.value.joint == "hip_joint"
    assert "give link `hip_link` a mass and an <inertia>" in str(info.value)
    assert "lock the joint with `locked_joints`" in str(info.value)


def test_mass_matrix_is_checked_inside_the_joint_limits(tmp_path):
    """A point-mass leg has no hip inertia at leg length 0, which the limits [0.1, 0.5] m
    exclude: the check uses the neutral configuration moved into the limits."""
    path = hopper_with(tmp_path, (LEG_INERTIA, ZERO_INERTIA))
    assert load_robot(path, base="fixed").nv == 2


def test_massless_and_placeholder_links_fixed_to_a_body_load(tmp_path):
    """URDF habits that are not faults: a massless sensor frame with a zero <inertial> and a
    1e-6 kg placeholder whose inertia (all entries 1e-6) is rank one (anymal, hyq), both
    fixed to the leg, and the hopper's massless `hip_link` between two joints."""
    sensor = ('<link name="imu"><inertial><mass value="0"/>' + ZERO_INERTIA
              + '</inertial></link>\n  <joint name="imu_joint" type="fixed"><parent link="leg"/>'
              '<child link="imu"/></joint>\n  ')
    placeholder = ('<link name="dummy"><inertial><mass value="1e-6"/><inertia ixx="1e-6" '
                   'ixy="1e-6" ixz="1e-6" iyy="1e-6" iyz="1e-6" izz="1e-6"/></inertial></link>'
                   '\n  <joint name="dummy_joint" type="fixed"><parent link="leg"/>'
                   '<child link="dummy"/></joint>\n  ')
    path = hopper_with(tmp_path, (FOOT_LINK, sensor + placeholder + FOOT_LINK))
    robot = load_robot(path, base="planar")
    assert robot.nv == 5
    assert robot.model.existFrame("imu") and robot.model.existFrame("dummy")


ROBOTS = {
    "hopper": dict(base="planar"),
    "ball": dict(base="floating"),
    "monoped": dict(base="planar_xz"),
    "solo12": dict(base="floating"),
    "a1": dict(base="floating"),
    "go1": dict(base="floating"),
    "anymal": dict(base="floating"),
    "hyq": dict(base="floating"),
    "talos": dict(base="floating"),
    "bolt": dict(base="floating"),
    "double_pendulum": dict(base="fixed"),
    "panda": dict(base="fixed"),
}


@pytest.mark.parametrize("name", list(ROBOTS))
def test_existing_robots_pass_the_checks(name):
    robot = load_robot(name, **ROBOTS[name])
    assert robot.nv > 0
