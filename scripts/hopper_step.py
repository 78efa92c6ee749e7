"""The hopper of robots/hopper.urdf hops onto a 5 cm step, planned on a `Terrain`.

The task is the bench hop (TF-8, `hopper_task("bench")`: from x = 0.1 to x = 1.0 in 1 s,
one flight) with the ground made of primitives instead of one half-space: a flat ground
and a step of height `--step` (5 cm) from x = `--edge` on, its edge rounded with radius
`--rounding`, both with the task's friction. The geometry is the true one: the foot
sphere (radius 2 cm) rests with its centre 2 cm above a surface, so the reference's
heights are raised by the foot radius, and the end state by the step as well. Only the
primitives the foot can reach are modelled (`Terrain.relevant_to`).

The problem is `tfcontact.scenes.hopper.hopper_problem` of the raised task on the
terrain (`hopper_problem(task, ground=terrain)`); the solver
settings are the bench task's (Scholtes from sigma_0 = 0.1 to a residual of 1e-3, loose
intermediate NLPs). Prints the status, whether the independent verification passed,
the task's goals, and where the foot ended against the step.

    python scripts/hopper_step.py                  # the 5 cm step at x = 0.7
    python scripts/hopper_step.py --step 0 # the flat hop on a Terrain, for comparison
    python scripts/hopper_step.py --attempts 4 --edge 0.85

Measured here (2 shared cores): the flat hop on a one-plane Terrain converges and is
verified, goals met (14 s). Onto the 5 cm step at x = 0.7 it does NOT yet succeed: the
first attempt stops short with the foot against the step's face (verification_failed,
end x 0.74); with `--attempts 4` the fourth (perturbed) guess converges, verified with
its goals met (end x 0.97), but the foot never touches the step: it is still in flight
at T, 2.9 cm above the step. With the edge at 0.5 or 0.85 the plans are verified but
end short (x 0.58, 0.89). The task (a flat-ground reference raised at its end, no goal
that the foot rests on the step) is the likely culprit, not the gap; a way point on the
step, or a terminal gap constraint, is the next thing to try.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time

import casadi as ca
import numpy as np


def build(step: float, edge: float, rounding: float, smoothing: float):
    """(robot, terrain, problem) of the hop onto the step (`step` = 0: flat ground only)."""
    from tfcontact.robot import Box, Plane, Region, Terrain
    from tfcontact.scenes.hopper import FOOT_RADIUS, hopper_problem, hopper_task

    bench = hopper_task("bench")
    solids = [Plane(friction=bench.mu)]
    if step > 0:
        solids.append(Box(x=(edge, math.inf), top=step, rounding=rounding,
                          friction=bench.mu))
    terrain = Terrain(tuple(solids), smoothing=smoothing)
    # the foot stays within the task's x range and below the base's upper bound
    x_lo, x_hi = bench.lower[0], bench.upper[0]
    terrain = terrain.relevant_to(Region(lower=(x_lo - 0.5, -math.inf, 0.0),
                                         upper=(x_hi + 0.5, math.inf, bench.upper[1])),
                                  margin=FOOT_RADIUS)
    raise_by = [FOOT_RADIUS] * (len(bench.waypoints) - 1) + [FOOT_RADIUS + step]
    waypoints = tuple((w[0], w[1] + dz, *w[2:]) for w, dz in zip(bench.waypoints, raise_by,
                                                                 strict=True))
    task = dataclasses.replace(bench, name="step", waypoints=waypoints)
    robot, _, problem = hopper_problem(task, ground=terrain)
    return robot, terrain, problem


def options(attempts: int = 1):
    """The bench task's settings (`hopper_options("bench")`, the task layer's `fast`
    preset); `attempts` solves from perturbed guesses while a plan fails."""
    from tfcontact.scenes.hopper import hopper_options

    return dataclasses.replace(hopper_options("bench"), attempts=attempts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step", type=float, default=0.05,
                        help="step height [m]; 0: the flat bench hop, for comparison")
    parser.add_argument("--edge", type=float, default=0.7, help="x of the step's edge [m]")
    parser.add_argument("--rounding", type=float, default=0.01, help="edge radius [m]")
    parser.add_argument("--smoothing", type=float, default=0.005,
                        help="smooth-minimum length joining ground and step [m]")
    parser.add_argument("--attempts", type=int, default=1,
                        help="solves from perturbed guesses while a plan fails")
    args = parser.parse_args(argv)

    from tfcontact.ocp.contact import solve_contact

    robot, terrain, problem = build(args.step, args.edge, args.rounding, args.smoothing)
    print(f"terrain: {terrain.to_dict()}")
    start = time.perf_counter()
    result = solve_contact(problem, options(args.attempts), verbose=False, throw=False)
    elapsed = time.perf_counter() - start
    print(f"status {result.status}; verification passed: {result.verification.passed}; "
          f"task goals met: {result.task.passed}; {elapsed:.0f} s")
    print(result.summary())
    # where the foot ended: its gap to the terrain and the surface under it
    import pinocchio as pin

    cls = problem.system.cls
    gap = ca.Function("gap", [cls.q], [cls.contacts[0].gap])
    q_end = result.physical.y[-1, problem.system.q_index]
    pin.framesForwardKinematics(robot.model, robot.data, q_end)
    p = robot.data.oMf[robot.model.getFrameId("foot")].translation
    print(f"end: base x = {q_end[0]:.3f} m, foot centre at ({p[0]:.3f}, {p[2]:.3f}) m over "
          f"the surface at {terrain.height_at(p[0]):.3f} m, foot gap {float(gap(q_end)):.2e} m")
    # did the foot touch down on the step (gap below 1 mm with the centre past the edge)?
    foot = ca.Function("foot", [cls.q], [robot.twin.frame_position("foot")])
    qs = result.physical.y[:, problem.system.q_index]
    xs = np.array([float(foot(q)[0]) for q in qs])
    gaps = np.array([float(gap(q)) for q in qs])
    on_step = (xs > args.edge) & (gaps < 1e-3)
    landed = bool(np.any(on_step)) if args.step > 0 else None
    if landed is not None:
        first = result.physical.t[np.argmax(on_step)] if landed else None
        print(f"foot touched down on the step: {landed}"
              + (f" (first at t = {first:.3f} s)" if landed else ""))
    ok = result.verification.passed and result.task.passed and landed is not False
    print("reached the step and verified" if ok else "NOT reached and verified")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
