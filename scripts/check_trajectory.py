# /// script
# requires-python = ">=3.11,<3.12"
# dependencies = ["pin>=4.1,<4.2", "numpy>=2", "example-robot-data-loaders>=5.0,<5.1"]
# ///
"""Check a tfcontact trajectory with plain Pinocchio: no tfcontact import.

Usage: python scripts/check_trajectory.py PLAN.json [--tol 1e-6] [--penetration 1e-3]

Exit code: 0 the file is intact and every check passes; 1 a physics check fails; 2 the
file is missing, damaged or foreign (one line on stderr names the problem).

It shows how one's own script reads a trajectory (`PLAN.npz` + `PLAN.json`), verifies it
and rebuilds the robot from the sidecar's `robot` entry:

* `source`: a URDF path (relative to the current folder or to the repository), the
  name of a URDF in the repository's `robots/`, or an example-robot-data name;
* `base`: the root joint put under the URDF's root link: "fixed" (none), "planar"
  (prismatic x, prismatic z, revolute y), "planar_xz" (prismatic x, z), "floating"
  (translation, then ZYX Euler angles), each one Pinocchio composite joint;
* `locked_joints` (+ optional `locked_positions`, default neutral): removed with
  `pinocchio.buildReducedModel`;
* `contacts`: spheres of `radius` [m] centred on frame origins.

Integrity (exit 2 when one fails): the sidecar is JSON of format "tfcontact-trajectory",
version 1 or 2; the npz's SHA-256 is the sidecar's `npz_sha256`; for version 2 the
sidecar's `sidecar_sha256` (SHA-256 of its JSON without that key, sorted keys, separators
"," and ":", ASCII) and each array's shape, dtype and SHA-256 (of its bytes in C order)
match; the arrays agree with the sidecar's dimensions.

Checks (each printed; the exit code is 1 if one fails):

1. `status`: the status is "converged" or "success" and the recorded verification (if
   any) passed;
2. `clock`: the clock never runs backwards and `t == clock[t_index]`;
3. `gaps`: every gap on the physical samples (`t_index`) is >= -penetration [m];
4. `robot`: the rebuilt model's nq matches q and, for version 2, the URDF's SHA-256 is
   the sidecar's `model.urdf.sha256`;
5. `fk`: on flat terrain the stored gaps equal the gaps recomputed by forward kinematics
   (normal . sphere centre - terrain height - radius);
6. `impacts`: impacts found in the recorded data: frozen pieces (the clock rate
   dt/dtau <= the sidecar's `frozen_rate_tol` while tau advances), nonzero recorded
   impulses outside them, and touchdowns inside a sampling interval (a contact closed,
   gap <= 1e-4 m, approaching faster than 1e-2 m/s with the next interval running, that
   by the next sample has reached the ground or slowed its approach by 1e-2 m/s).
   Every frozen piece or recorded impulse satisfies the momentum balance
   M(q) (v+ - v-) = sum_k J_k(q)^T Lambda_k with the recorded impulses Lambda_k (J_k: the
   linear part of contact k's frame Jacobian in the world-aligned frame) to --tol relative
   to max(1, |M dv|); after a touchdown inside an interval the contact no longer approaches.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import lzma
import struct
import sys
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pinocchio as pin

REPO = Path(__file__).resolve().parents[1]
FORMAT = "tfcontact-trajectory"
VERSIONS = (1, 2)
ARRAYS = ("tau", "clock", "s", "q", "v", "u", "gap", "normal_velocity", "force", "impulse",
          "t", "t_index")
SUCCESS = ("converged", "success")
CLOSED_GAP, APPROACH_SPEED = 1e-4, 1e-2  # [m], [m/s]: impact detection
#: What numpy's npz reader raises on damaged bytes (zip, zlib, a flag asking for a password).
NPZ_ERRORS = (zipfile.BadZipFile, zlib.error, lzma.LZMAError, EOFError, OSError, RuntimeError,
              NotImplementedError, ValueError, KeyError, IndexError, OverflowError,
              struct.error, TypeError, MemoryError)


class Damaged(Exception):
    """The pair is missing, damaged or foreign."""


def pair(path: Path) -> tuple[Path, Path]:
    """(PLAN.npz, PLAN.json) of either member of the pair."""
    base = path.with_suffix("") if path.suffix in (".npz", ".json") else path
    return base.with_name(base.name + ".npz"), base.with_name(base.name + ".json")


def sha256_of_sidecar(meta: dict) -> str:
    body = {k: v for k, v in meta.items() if k != "sidecar_sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a finite number")


def load(path: Path) -> tuple[dict, dict]:
    """The sidecar and the arrays, verified (see the module docstring); raises Damaged."""
    npz, sidecar = pair(path)
    for p in (npz, sidecar):
        if not p.is_file():
            raise Damaged(f"{p} does not exist")
    try:
        meta = json.loads(sidecar.read_bytes().decode("utf-8"), parse_constant=reject_constant)
    except (UnicodeDecodeError, ValueError) as err:
        raise Damaged(f"{sidecar} is not valid JSON: {err}") from err
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise Damaged(f"{sidecar} is not a tfcontact trajectory sidecar")
    version = meta.get("format_version")
    if isinstance(version, bool) or version not in VERSIONS:
        raise Damaged(f"{sidecar} has format_version {version!r}; this script reads {VERSIONS}")
    data = npz.read_bytes()
    if hashlib.sha256(data).hexdigest() != meta.get("npz_sha256"):
        raise Damaged(f"{npz} does not match the npz_sha256 of {sidecar.name}")
    digests = version >= 2 or "sidecar_sha256" in meta  # kept if the version was edited
    if digests and sha256_of_sidecar(meta) != meta.get("sidecar_sha256"):
        raise Damaged(f"{sidecar} does not match its sidecar_sha256 (edited or damaged)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as f:
            arrays = {name: f[name] for name in f.files}
    except NPZ_ERRORS as err:
        raise Damaged(f"{npz} is not a readable npz file: {type(err).__name__}: {err}") from err
    missing = [name for name in ARRAYS if name not in arrays]
    if missing:
        raise Damaged(f"{npz} lacks the arrays {', '.join(missing)}")
    if digests:
        listed = meta.get("arrays")
        if not isinstance(listed, dict) or set(listed) != set(arrays):
            raise Damaged(f"{npz} does not hold the arrays its sidecar lists")
        for name, value in arrays.items():
            entry = listed[name]
            digest = hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
            if (not isinstance(entry, dict) or entry.get("shape") != list(value.shape)
                    or entry.get("dtype") != value.dtype.str or entry.get("sha256") != digest):
                raise Damaged(f"{npz}: `{name}` is not the array its sidecar records")
    dims = meta.get("dimensions")
    q, v, u, gap = arrays["q"], arrays["v"], arrays["u"], arrays["gap"]
    shapes = [a.ndim == k for a, k in ((q, 2), (v, 2), (u, 2), (gap, 2), (arrays["tau"], 1))]
    if not all(shapes) or dims != {"N": len(arrays["tau"]), "nq": q.shape[1], "nv": v.shape[1],
                                   "nu": u.shape[1], "nc": gap.shape[1]}:
        raise Damaged(f"{npz}: the array shapes differ from the sidecar's dimensions {dims}")
    robot = meta.get("robot")
    if not isinstance(robot, dict) or any(k not in robot for k in ("source", "base", "contacts")):
        raise Damaged(f"{sidecar}: `robot` lacks source, base or contacts")
    return meta, arrays


def find_urdf(source: str) -> Path:
    """The URDF file of a sidecar's `robot.source`."""
    if source.endswith(".urdf") or "/" in source:
        for candidate in (Path.cwd() / source, REPO / source):
            if candidate.is_file():
                return candidate
        raise FileNotFoundError(f"URDF {source} not found")
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


def rebuild(robot: dict, urdf: Path) -> pin.Model:
    """The Pinocchio model described by the sidecar's `robot` entry."""
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


def frozen_pieces(tau: np.ndarray, clock: np.ndarray, rate_tol: float) -> list[tuple[int, int]]:
    """(entry, exit) samples of the runs of intervals where the clock stands still while
    tau advances (dt <= rate_tol dtau), as tfcontact's `physical_time` finds them."""
    frozen = np.diff(clock) <= rate_tol * np.diff(tau)
    pieces, k = [], 0
    while k < len(frozen):
        if frozen[k] and tau[k + 1] > tau[k]:
            start = k
            while k < len(frozen) and frozen[k]:
                k += 1
            pieces.append((start, k))
        else:
            k += 1
    return pieces


def touching(gap: np.ndarray, vn: np.ndarray) -> np.ndarray:
    """(samples - 1, contacts): the contact is closed and approaching at sample k and by
    sample k + 1 has reached the ground or slowed its approach (a touchdown inside the
    interval); one that flies on towards the ground is still in the air."""
    approaching = ((gap <= CLOSED_GAP) & (vn < -APPROACH_SPEED))[:-1]
    return approaching & ((gap[1:] <= 0.0) | (np.diff(vn, axis=0) > APPROACH_SPEED))


def impacts(meta: dict, arrays: dict) -> list[tuple[int, int, str]]:
    """(pre, post, kind) of every impact found in the recorded data."""
    tau, clock, t_index = arrays["tau"], arrays["clock"], arrays["t_index"]
    gap, vn, impulse = arrays["gap"], arrays["normal_velocity"], arrays["impulse"]
    pieces = frozen_pieces(tau, clock, float(meta.get("frozen_rate_tol", 1e-6)))
    found = [(a, b, "frozen piece") for a, b in pieces]
    frozen = np.zeros(len(tau) - 1, dtype=bool)
    explained = np.zeros(len(tau), dtype=bool)
    for a, b in pieces:
        frozen[a:b] = True
        explained[a + 1:b + 1] = True
    for k in np.flatnonzero(np.any(impulse != 0, axis=(1, 2)) & ~explained):
        earlier = t_index[t_index < k]
        found.append((int(earlier[-1]) if earlier.size else 0, int(k), "impulse"))
    next_frozen = np.append(frozen[1:], False)  # the frozen piece that follows resolves it
    for k in np.flatnonzero(np.any(touching(gap, vn), axis=1) & ~frozen & ~next_frozen):
        if not any(a <= k < b for a, b, _ in found):
            found.append((int(k), int(k) + 1, "inside interval"))
    return sorted(found)


def check(meta: dict, arrays: dict, tol: float, penetration: float) -> bool:
    q, v, clock = arrays["q"], arrays["v"], arrays["clock"]
    t, t_index, gap, impulse = arrays["t"], arrays["t_index"], arrays["gap"], arrays["impulse"]
    robot, results = meta["robot"], []

    verification = meta.get("verification", {}).get("passed")
    results.append(("status", meta.get("status") in SUCCESS and verification is not False,
                    f"status {meta.get('status')!r}, verification passed: {verification}"))
    monotone = bool(np.all(np.diff(clock) >= 0)) and np.array_equal(t, clock[t_index])
    results.append(("clock", monotone, "non-decreasing, t == clock[t_index]"))
    lowest = float(gap[t_index].min()) if gap.size else 0.0
    results.append(("gaps", lowest >= -penetration,
                    f"min gap {lowest:+.2e} m on the physical samples"))

    try:
        urdf = find_urdf(robot["source"])
        model = rebuild(robot, urdf)
    except (OSError, KeyError, ValueError) as err:
        results.append(("robot", False, f"cannot rebuild the robot: {err}"))
        return report(results)
    recorded = meta.get("model", {}).get("urdf", {}).get("sha256")
    same = recorded is None or recorded == hashlib.sha256(urdf.read_bytes()).hexdigest()
    results.append(("robot", q.shape[1] == model.nq and same,
                    f"{urdf.name}: q has {q.shape[1]} columns, model nq = {model.nq}"
                    + ("" if same else "; the URDF differs from the plan's (SHA-256)")))
    if q.shape[1] != model.nq:
        return report(results)
    data = model.createData()
    frames = [model.getFrameId(c["frame"]) for c in robot["contacts"]]
    radii = np.array([c["radius"] for c in robot["contacts"]])

    terrain = meta.get("scene", {}).get("terrain", {})
    if terrain.get("type", "flat") == "flat" and not meta.get("scene", {}).get("boxes") \
            and "extra_cls_gaps" not in arrays:
        normal = np.asarray(terrain.get("normal", (0.0, 0.0, 1.0)), dtype=float)
        normal /= np.linalg.norm(normal)
        recomputed = np.empty_like(gap)
        for k, qk in enumerate(q):
            pin.framesForwardKinematics(model, data, qk)
            recomputed[k] = [normal @ data.oMf[f].translation for f in frames]
        recomputed -= radii + float(terrain.get("height", 0.0))
        error = float(np.max(np.abs(recomputed - gap))) if gap.size else 0.0
        results.append(("fk", error <= tol, f"max |gap - FK gap| = {error:.2e} m"))
    else:
        results.append(("fk", True, "skipped: the gaps are not against one flat ground"))

    worst, still, found = 0.0, [], impacts(meta, arrays)
    landing = touching(gap, arrays["normal_velocity"])
    for pre, post, kind in found:
        if kind == "inside interval":
            if np.any(arrays["normal_velocity"][post, landing[pre]] < -APPROACH_SPEED):
                still.append(clock[pre])
            continue
        qk = q[pre]
        pin.computeJointJacobians(model, data, qk)
        pin.framesForwardKinematics(model, data, qk)
        M = pin.crba(model, data, qk)
        M = np.triu(M) + np.triu(M, 1).T
        momentum = M @ (v[post] - v[pre])
        lam = impulse[pre + 1:post + 1].sum(axis=0)
        generalised = sum(
            (pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3].T @ lam[i]
             for i, f in enumerate(frames)), np.zeros(model.nv))
        scale = max(1.0, float(np.max(np.abs(momentum))))
        worst = max(worst, float(np.max(np.abs(momentum - generalised))) / scale)
    kinds = [sum(f[2] == name for f in found)
             for name in ("frozen piece", "impulse", "inside interval")]
    detail = (f"{len(found)} impact(s) ({kinds[0]} frozen, {kinds[1]} impulse only, "
              f"{kinds[2]} inside an interval), max |M dv - J^T Lambda| / max(1, |M dv|) "
              f"= {worst:.2e}" + (f"; still approaching after t = {still[0]:.4g} s"
                                  if still else ""))
    results.append(("impacts", worst <= tol and not still, detail))
    return report(results)


def report(results) -> bool:
    for name, ok, detail in results:
        print(f"{'ok  ' if ok else 'FAIL'} {name:8s} {detail}")
    return all(ok for _, ok, _ in results)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trajectory", type=Path, help="PLAN.json or PLAN.npz")
    parser.add_argument("--tol", type=float, default=1e-6,
                        help="tolerance of the fk [m] and impacts [-] checks")
    parser.add_argument("--penetration", type=float, default=1e-3,
                        help="largest allowed penetration [m]")
    args = parser.parse_args()
    try:
        meta, arrays = load(args.trajectory)
    except Damaged as err:
        print(f"damaged: {err}", file=sys.stderr)
        return 2
    return 0 if check(meta, arrays, args.tol, args.penetration) else 1


if __name__ == "__main__":
    sys.exit(main())
