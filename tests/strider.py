"""A robot of the tests' own with two legs (`STRIDER_URDF`) and a task that shifts its body
2 cm with both feet down (`STRIDER_TASK`, with `exact_resolve`: a discovery and a stance
re-solve in about half a minute), written by `write_strider`."""

from __future__ import annotations

from pathlib import Path

# A robot of the test's own with two legs: a 1 kg body on an x-z base, each leg a hip
# (revolute about y) and a prismatic shin (0.05 kg each link), a toe at its end.
STRIDER_URDF = """<?xml version="1.0"?>
<robot name="strider">
  <link name="body">
    <inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0"
      iyz="0"/></inertial>
    <collision><geometry><box size="0.3 0.1 0.05"/></geometry></collision>
  </link>
""" + "".join(f"""  <link name="hip_link{i}">
    <inertial><mass value="0.05"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0"
      iyz="0"/></inertial>
  </link>
  <joint name="hip{i}" type="revolute">
    <parent link="body"/><child link="hip_link{i}"/><origin xyz="{x} 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1.0" upper="1.0" effort="5" velocity="20"/>
  </joint>
  <link name="shin{i}">
    <inertial><mass value="0.05"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0"
      iyz="0"/></inertial>
  </link>
  <joint name="leg{i}" type="prismatic">
    <parent link="hip_link{i}"/><child link="shin{i}"/><axis xyz="0 0 -1"/>
    <limit lower="0.1" upper="0.4" effort="30" velocity="20"/>
  </joint>
  <link name="toe{i}"/>
  <joint name="toe{i}_joint" type="fixed"><parent link="shin{i}"/><child link="toe{i}"/></joint>
""" for i, x in ((0, 0.1), (1, -0.1))) + "</robot>\n"

STRIDER_TASK = """
name = "strider-shift"
horizon = 0.3
n_intervals = 6
exact_resolve = true
[robot]
source = "strider.urdf"
base = "planar_xz"
[[contacts]]
frame = "toe0"
radius = 0.02
friction = 0.8
no_slip = true
[[contacts]]
frame = "toe1"
radius = 0.02
friction = 0.8
no_slip = true
[start]
z = 0.27
leg0 = 0.25
leg1 = 0.25
[[waypoints]]
t = 0.3
x = 0.02
z = 0.28
[goals]
end = { x = 0.02 }
[costs]
tracking = { x = 50, z = 500 }
terminal = { x = 300, z = 300 }
control = 0.001
"""


def write_strider(folder: Path) -> Path:
    """The URDF and the task file in `folder`; returns the task file's path."""
    (folder / "strider.urdf").write_text(STRIDER_URDF)
    path = folder / "strider.toml"
    path.write_text(STRIDER_TASK)
    return path


# The strider along a contact sequence given as data: toe0 lifts at 0.1 s and lands
# inside 0.15-0.2 s (no discovery).
STRIDER_STEP = (STRIDER_TASK.replace("exact_resolve = true\n", "")
                .replace("[goals]\n", "[goals]\nlift_offs = { toe0 = 1 }\nlift_height = 0.01\n")
                + """
[[stances]]
closed = ["toe0", "toe1"]
start = 0.0
[[stances]]
closed = ["toe1"]
start = 0.1
[[stances]]
closed = ["toe0", "toe1"]
start = 0.175
""")
