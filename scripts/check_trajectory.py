# /// script
# requires-python = ">=3.11,<3.12"
# dependencies = ["pin>=4.1,<4.2", "numpy>=2", "example-robot-data-loaders>=5.0,<5.1"]
# ///
"""Check a tfcontact trajectory with plain Pinocchio: no tfcontact import.

Usage: python scripts/check_trajectory.py PLAN.json [--tol 1e-6]

It shows how one's own script reads a trajectory (`PLAN.npz` + `PLAN.json`) and
rebuilds the robot from the sidecar's `robot` entry:

* `source`: a URDF path (relative to the current folder or to the repository), the
  name of a URDF in the repository's `robots/`, or an example-robot-data name;
* `base`: the root joint put under the URDF's root link: "fixed" (none), "planar"
  (prismatic x, prismatic z, revolute y), "planar_xz" (prismatic x, z), "floating"
  (translation, then ZYX Euler angles), each one Pinocchio composite joint;
* `locked_joints` (+ optional `locked_positions`, default neutral): removed with
  `pinocchio.buildReducedModel`;
* `contacts`: spheres of `radius` [m] centred on frame origins.

Checks (each printed; the exit code is 1 if one fails):

1. the configuration size nq matches the rebuilt model;
2. the clock never runs backwards and `t == clock[t_index]`;
3. the stored gaps equal the gaps recomputed by forward kinematics (sphere centre
   height minus radius minus the terrain height);
4. every impact (a frozen piece: pre- and post-impact samples share one physical time)
   satisfies the momentum balance M(q) (v+ - v-) = sum_k J_k(q)^T Lambda_k with the
   stored impulses Lambda_k (J_k: the linear part of contact k's frame Jacobian in the
   world-aligned frame).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

REPO = Path(__file__).resolve().parents[1]


def find_urdf(source: str) -> Path:
    """The URDF file of a sidecar's `robot.source`."""
    if source.endswith(".urdf") or "/" in source:
        for candidate in (Path.cwd() / source, REPO / source):
            if candidate.is_file():
                return candidate
        raise SystemExit(f"URDF {source} not found")
    own = REPO / "robots" / f"{source}.urdf"
    if own.is_file():
        return own
    from example_robot_data.robots_loader import ROBOTS
    from example_robot_data.utils import getModelPath

    loader = ROBOTS[source]
    sub = Path(loader.path) / loader.urdf_subpath / loader.urdf_filename
    root = Path(loader.model_path or getModelPath(str(sub)))
    return root / sub


def base_joint(base: str):
    """The root joint of each base of the sidecar."""
    parts = {"planar": [pin.JointModelPX(), pin.JointModelPZ(), pin.JointModelRY()],
             "planar_xz": [pin.JointModelPX(), pin.JointModelPZ()],
             "floating": [pin.JointModelTranslation(), pin.JointModelSphericalZYX()]}
    if base == "fixed":
        return None
    joint = pin.JointModelComposite(parts[base][0])
    for part in parts[base][1:]:
        joint.addJoint(part)
    return joint


def rebuild(robot: dict) -> pin.Model:
    """The Pinocchio model described by the sidecar's `robot` entry."""
    urdf = find_urdf(robot["source"])
    root = base_joint(robot["base"])
    if root is None:
        model = pin.buildModelFromUrdf(str(urdf))
    else:
        model = pin.buildModelFromUrdf(str(urdf), root)
    locked = robot.get("locked_joints", [])
    if locked:
        q_ref = pin.neutral(model)
        for name, value in zip(locked, robot.get("locked_positions", []), strict=False):
            q_ref[model.joints[model.getJointId(name)].idx_q] = value
        model = pin.buildReducedModel(model, [model.getJointId(n) for n in locked], q_ref)
    return model


def check(path: Path, tol: float) -> bool:
    sidecar = path.with_suffix(".json")
    meta = json.loads(sidecar.read_text())
    arrays = dict(np.load(path.with_suffix(".npz")))
    model = rebuild(meta["robot"])
    data = model.createData()
    frames = [model.getFrameId(c["frame"]) for c in meta["robot"]["contacts"]]
    radii = np.array([c["radius"] for c in meta["robot"]["contacts"]])
    height = float(meta.get("scene", {}).get("terrain", {}).get("height", 0.0))
    q, v, clock = arrays["q"], arrays["v"], arrays["clock"]
    t, t_index, gap, impulse = arrays["t"], arrays["t_index"], arrays["gap"], arrays["impulse"]
    results = []

    results.append(("nq", q.shape[1] == model.nq, f"q has {q.shape[1]} columns, model nq = "
                    f"{model.nq}"))
    if q.shape[1] != model.nq:
        return report(results)
    monotone = bool(np.all(np.diff(clock) >= 0)) and np.array_equal(t, clock[t_index])
    results.append(("clock", monotone, "non-decreasing, t == clock[t_index]"))

    recomputed = np.empty_like(gap)
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(model, data, qk)
        recomputed[k] = [data.oMf[f].translation[2] for f in frames] - radii - height
    error = float(np.max(np.abs(recomputed - gap))) if gap.size else 0.0
    results.append(("gaps", error <= tol, f"max |gap - FK gap| = {error:.2e} m"))

    worst = 0.0
    jumps = np.flatnonzero(np.diff(t) == 0)
    for j in jumps:
        pre, post = t_index[j], t_index[j + 1]
        qk = q[pre]
        pin.computeJointJacobians(model, data, qk)
        pin.framesForwardKinematics(model, data, qk)
        M = pin.crba(model, data, qk)
        M = np.triu(M) + np.triu(M, 1).T
        generalised = sum(
            pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3].T @ impulse[post, i]
            for i, f in enumerate(frames)
        )
        worst = max(worst, float(np.max(np.abs(M @ (v[post] - v[pre]) - generalised))))
    results.append(("impacts", worst <= tol,
                    f"{jumps.size} impact(s), max |M dv - J^T Lambda| = {worst:.2e} N s"))
    return report(results)


def report(results) -> bool:
    for name, ok, detail in results:
        print(f"{'ok  ' if ok else 'FAIL'} {name:8s} {detail}")
    return all(ok for _, ok, _ in results)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trajectory", type=Path, help="PLAN.json or PLAN.npz")
    parser.add_argument("--tol", type=float, default=1e-6, help="tolerance of checks 3 and 4")
    args = parser.parse_args()
    return 0 if check(args.trajectory, args.tol) else 1


if __name__ == "__main__":
    sys.exit(main())
