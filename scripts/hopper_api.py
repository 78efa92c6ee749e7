"""From a URDF to a verified plan and its replay with tfcontact's top-level API (README).

The hopper of robots/hopper.urdf (TF-8's one-hop task of nosnoc_py's example, built from
the URDF by `hopper_problem`): the solver finds when the foot touches and leaves the
ground, verifies the plan against an exact-impact simulation, checks its goals, and
writes a standalone replay page.

    python scripts/hopper_api.py        # writes hopper.html in the current folder
"""

import tfcontact
from tfcontact.scenes.hopper import hopper_options, hopper_problem

robot, ground, problem = hopper_problem("bench")     # load_robot("hopper", ...) inside
result = tfcontact.plan(problem, hopper_options("bench"), verbose=False)
print(result.status, result.verification.passed, result.task.passed)   # converged True True
print(result.task.summary())                         # end x, lift-offs, motion: measured
page = tfcontact.replay(tfcontact.trajectory(result, robot.spec), html="hopper.html")
print(f"replay: {page.html} ({page.n_frames} frames)")
