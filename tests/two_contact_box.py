"""A 2 kg planar box on two contact spheres, for the multi-contact verification tests: its
URDF, and the plan that pushes it from rest along the ground (solved by the library)."""

from __future__ import annotations

from pathlib import Path

import casadi as ca


def box_urdf(half_span: float, depth: float) -> str:
    """A 2 kg box (inertia 0.05 kg m^2) with frames `front` and `back` at
    (+-half_span, 0, -depth) from its centre of mass [m]."""
    return f"""<?xml version="1.0"?>
<robot name="box">
  <link name="body">
    <inertial><mass value="2.0"/><inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0"
      iyz="0"/></inertial>
  </link>
  <link name="front"/><link name="back"/>
  <joint name="front_joint" type="fixed"><parent link="body"/><child link="front"/>
    <origin xyz="{half_span} 0 {-depth}"/></joint>
  <joint name="back_joint" type="fixed"><parent link="body"/><child link="back"/>
    <origin xyz="{-half_span} 0 {-depth}"/></joint>
</robot>
"""


def load_box(folder: Path, half_span: float, depth: float, radius: float):
    """The box on a planar base with contact spheres of `radius` on `front` and `back`."""
    from tfcontact.robot import ContactSpec, load_robot

    path = folder / "box.urdf"
    path.write_text(box_urdf(half_span, depth))
    return load_robot(str(path), base="planar", contacts=(ContactSpec("front", radius),
                                                          ContactSpec("back", radius)))


def pushed_box_problem(folder: Path, mu: float, half_span: float, depth: float):
    """The box on 0.1 m spheres, resting on them, pushed from rest towards x = 0.15 m in
    0.6 s (4 control intervals, |u_x| <= 20 N on the base's x, none on z and pitch)."""
    from tfcontact.ocp import ContactProblem
    from tfcontact.timefreezing import from_robot, time_freeze

    robot = load_box(folder, half_span, depth, 0.1)
    tf = time_freeze(from_robot(robot, mu=mu, a_n=50.0, actuated=["root_joint"]))
    x = tf.y[tf.q_index][0]
    return ContactProblem(system=tf, q0=[0.0, depth + 0.1, 0.0], v0=[0.0, 0.0, 0.0],
                          horizon=0.6, n_intervals=4, u_lower=[-20.0, 0.0, 0.0],
                          u_upper=[20.0, 0.0, 0.0],
                          running_cost=10 * (x - 0.15) ** 2 + 1e-3 * ca.sumsqr(tf.u))


def solved_plan(problem):
    """`problem` solved with the default options, as the `TimeFreezingPlan` the checks
    take."""
    from tfcontact.ocp import ContactSolverOptions, solve_contact
    from tfcontact.ocp.contact import time_freezing_plan

    options = ContactSolverOptions()
    result = solve_contact(problem, options, verbose=False)
    assert result.ocp.success, result.message
    return time_freezing_plan(problem, result.system, result.ocp, result.physical, options)
