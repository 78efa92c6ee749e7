"""Trajectory files: one `.npz` of arrays plus a JSON sidecar of the same name.

A planned or simulated motion lives in *numerical time* tau (DESIGN.md 4.1): the
time-freezing reformulation adds a clock state t(tau) that stops (dt/dtau = 0) while
an auxiliary impact mode is active. `Trajectory` keeps every sample in numerical time
together with the clock; `physical_time` gives the samples in physical time, frozen
pieces dropped, so that an impact becomes an instantaneous jump of the velocity.

File layout (format version 1), `NAME.npz` + `NAME.json`:

* `NAME.npz` (numpy, no pickles), one row per sample k = 0..N-1 in numerical time:

  ==================  ============  ============================================================
  array               shape         meaning
  ==================  ============  ============================================================
  `tau`               (N,)          numerical time [s], non-decreasing
  `clock`             (N,)          physical time t(tau) [s], non-decreasing
  `s`                 (N,)          speed of time [-] of the control interval holding the sample
  `q`                 (N, nq)       configuration, in the robot's own Pinocchio convention
  `v`                 (N, nv)       generalised velocity [m/s, rad/s]
  `u`                 (N, nu)       control (joint torques/forces [N m, N]); nu may be 0
  `gap`               (N, nc)       contact gaps f_c,k(q) [m]; nc may be 0
  `normal_velocity`   (N, nc)       n_k(q)^T v [m/s]
  `force`             (N, nc, 3)    contact force on the robot, world frame [N] (0 when frozen)
  `impulse`           (N, nc, 3)    impulse [N s] of the frozen piece that ends at sample k
                                    (0 elsewhere)
  `t`                 (M,)          physical time [s] with the frozen pieces dropped
  `t_index`           (M,)          sample indices of `t`: t = clock[t_index], and
                                    q[t_index], v[t_index], ... are the physical samples
  `extra_<name>`      (N, ...)      optional solver-specific arrays (e.g. step variables)
  ==================  ============  ============================================================

* `NAME.json`: `format` = "tfcontact-trajectory", `format_version`, `status`,
  `dimensions` (N, nq, nv, nu, nc), `npz_sha256` (ties the pair together), `arrays`
  (units and meaning), `robot` (`source`: URDF path relative to the repository or an
  example-robot-data name; `base`; `locked_joints`; `contacts`: frame names and radii),
  `scene` (terrain, optional boxes and holes), `solver` (settings, timings, NLP count, iterations,
  complementarity residual, optional `history`: one entry per homotopy step) and
  `verification` (independent checks of the plan).

A script of one's own reads the pair with numpy and json alone::

    import json, numpy as np
    meta = json.load(open("plan.json"))
    arrays = np.load("plan.npz")
    t, q_phys = arrays["t"], arrays["q"][arrays["t_index"]]

`scripts/check_trajectory.py` goes further without importing tfcontact: it rebuilds the
robot from `meta["robot"]` with plain Pinocchio and checks the gaps and the momentum
balance of every impact.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput, TrajectoryFileError

FORMAT = "tfcontact-trajectory"
FORMAT_VERSION = 1

#: Default tolerance on the clock rate dt/dtau below which an interval counts as frozen.
FROZEN_RATE_TOL = 1e-6

ARRAY_DOCS: dict[str, str] = {
    "tau": "numerical time [s], shape (N,)",
    "clock": "physical time t(tau) [s], shape (N,)",
    "s": "speed of time [-] (dt/dtau where the clock runs), shape (N,)",
    "q": "configuration, robot's Pinocchio convention, shape (N, nq)",
    "v": "generalised velocity [m/s, rad/s], shape (N, nv)",
    "u": "control [N m, N], shape (N, nu)",
    "gap": "contact gaps [m], shape (N, nc)",
    "normal_velocity": "contact normal velocities n^T v [m/s], shape (N, nc)",
    "force": "contact forces on the robot, world frame [N], 0 when frozen, shape (N, nc, 3)",
    "impulse": "impulse of the frozen piece ending at this sample, world frame [N s], "
    "shape (N, nc, 3)",
    "t": "physical time with frozen pieces dropped [s], shape (M,)",
    "t_index": "sample index of each entry of t: t = clock[t_index], shape (M,)",
}

_METADATA = ("robot", "scene", "solver", "verification")

#: Keys a saved trajectory's `robot` entry must have: enough to rebuild the robot with
#: plain Pinocchio (`tfcontact.robot.RobotSpec.to_dict()` gives them).
ROBOT_KEYS = ("source", "base", "locked_joints", "contacts")


def _missing_robot_keys(robot: dict) -> list[str]:
    return [key for key in ROBOT_KEYS if key not in robot]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A motion sampled in numerical time tau, with the clock t(tau) and its metadata.

    Main arrays (one row per sample, N >= 2 samples):
        tau: numerical time [s], shape (N,), non-decreasing.
        clock: physical time t(tau) [s], shape (N,), non-decreasing.
        s: speed of time [-], shape (N,).
        q: configurations, shape (N, nq), in the robot's Pinocchio convention.
        v: generalised velocities, shape (N, nv).
        u: controls, shape (N, nu) (nu = 0 for a passive system).

    Contact arrays (nc contacts, in the order of `robot["contacts"]`):
        gap: gaps [m], shape (N, nc).
        normal_velocity: normal velocities [m/s], shape (N, nc).
        force: contact forces, world frame [N], shape (N, nc, 3). Zero when not given.
        impulse: impulses of frozen pieces [N s], shape (N, nc, 3). Zero when not given.

    Metadata (JSON-serialisable dicts, see the module docstring):
        status: the solver's status word, e.g. "success".
        robot, scene, solver, verification: free-form dicts with the documented keys.
        extras: further arrays of shape (N, ...), saved as `extra_<name>`.

    Raises:
        InvalidInput: an array has the wrong shape or non-finite values, or a dict does
            not serialise to JSON.
    """

    tau: np.ndarray
    clock: np.ndarray
    s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    gap: np.ndarray
    normal_velocity: np.ndarray
    force: np.ndarray | None = None
    impulse: np.ndarray | None = None
    status: str = "unknown"
    robot: dict[str, Any] = field(default_factory=dict)
    scene: dict[str, Any] = field(default_factory=dict)
    solver: dict[str, Any] = field(default_factory=dict)
    verification: dict[str, Any] = field(default_factory=dict)
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        arrays = {name: getattr(self, name) for name in _REQUIRED}
        n_contacts = np.asarray(self.gap).shape[1] if np.ndim(self.gap) == 2 else 0
        n = np.shape(self.tau)[0] if np.ndim(self.tau) >= 1 else 0
        for name in ("force", "impulse"):
            arrays[name] = (
                np.zeros((n, n_contacts, 3)) if getattr(self, name) is None else getattr(self, name)
            )
        checked = _check_arrays(arrays, InvalidInput, "")
        for name, value in checked.items():
            object.__setattr__(self, name, value)
        extras = {}
        for name, value in dict(self.extras).items():
            value = np.array(value)
            if not name.isidentifier():
                raise InvalidInput(f"`extras` key `{name}` must be a Python identifier")
            if value.ndim == 0 or value.shape[0] != self.n_samples:
                raise InvalidInput(
                    f"`extras[{name!r}]` must have one row per sample ({self.n_samples}), "
                    f"got shape {value.shape}"
                )
            value.setflags(write=False)
            extras[name] = value
        object.__setattr__(self, "extras", extras)
        if not isinstance(self.status, str):
            raise InvalidInput(f"`status` must be a string, got {self.status!r}")
        for name in _METADATA:
            value = getattr(self, name)
            if not isinstance(value, dict):
                raise InvalidInput(f"`{name}` must be a dict, got {type(value).__name__}")
            try:
                json.dumps(value, allow_nan=False)
            except (TypeError, ValueError) as err:
                raise InvalidInput(
                    f"`{name}` must serialise to JSON (plain dicts, lists, str, finite numbers): "
                    f"{err}"
                ) from err
        contacts = self.robot.get("contacts")
        if isinstance(contacts, list) and len(contacts) != self.n_contacts:
            raise InvalidInput(
                f"`robot['contacts']` lists {len(contacts)} contacts but `gap` has "
                f"{self.n_contacts} columns"
            )

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return self.tau.shape[0]

    @property
    def n_contacts(self) -> int:
        """Number of contacts nc."""
        return self.gap.shape[1]

    def physical(self, *, rate_tol: float = FROZEN_RATE_TOL) -> PhysicalSamples:
        """The samples in physical time; see `physical_time`."""
        return physical_time(self, rate_tol=rate_tol)


_REQUIRED = ("tau", "clock", "s", "q", "v", "u", "gap", "normal_velocity")
_ALL_ARRAYS = (*_REQUIRED, "force", "impulse")


def _check_arrays(arrays: dict[str, Any], error: type[Exception], where: str) -> dict:
    """Convert to float arrays and check shapes, finiteness and monotone times."""
    out: dict[str, np.ndarray] = {}
    for name in _ALL_ARRAYS:
        try:
            value = np.array(arrays[name], dtype=float)
        except (TypeError, ValueError) as err:
            raise error(f"{where}`{name}` is not a numeric array: {err}") from err
        out[name] = value
    n_dims = {"tau": 1, "clock": 1, "s": 1, "q": 2, "v": 2, "u": 2, "gap": 2,
              "normal_velocity": 2, "force": 3, "impulse": 3}
    for name, ndim in n_dims.items():
        if out[name].ndim != ndim:
            raise error(
                f"{where}`{name}` must be {ndim}-D (one row per sample), "
                f"got shape {out[name].shape}"
            )
    n = out["tau"].shape[0]
    if n < 2:
        raise error(f"{where}`tau` must hold at least 2 samples, got {n}")
    for name in _ALL_ARRAYS:
        if out[name].shape[0] != n:
            raise error(
                f"{where}`{name}` has {out[name].shape[0]} rows but `tau` has {n} samples: "
                "every array needs one row per sample"
            )
        if not np.all(np.isfinite(out[name])):
            raise error(f"{where}`{name}` holds non-finite values (nan or inf)")
    nc = out["gap"].shape[1]
    for name, shape in (("normal_velocity", (n, nc)), ("force", (n, nc, 3)),
                        ("impulse", (n, nc, 3))):
        if out[name].shape != shape:
            raise error(
                f"{where}`{name}` must have shape {shape} (nc = {nc} from `gap`), "
                f"got {out[name].shape}"
            )
    for name in ("tau", "clock"):
        if np.any(np.diff(out[name]) < 0):
            k = int(np.argmax(np.diff(out[name]) < 0))
            raise error(
                f"{where}`{name}` must be non-decreasing, but it drops from "
                f"{out[name][k]!r} to {out[name][k + 1]!r} at sample {k + 1}"
            )
    for value in out.values():
        value.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class PhysicalSamples:
    """Samples of a trajectory in physical time, frozen pieces dropped.

    Inside a frozen piece (samples k0..k1 whose intervals all have dt/dtau below the
    tolerance) only the entry sample k0 and the exit sample k1 are kept: they share
    (up to the tolerance) the same physical time, so an impact appears as an
    instantaneous jump of `v` between two consecutive entries of `t`.

    Attributes:
        t: physical time [s], shape (M,), non-decreasing.
        index: the sample index of each entry, shape (M,): `t == traj.clock[index]`.
        q, v, u, gap, normal_velocity, force: the trajectory's arrays at `index`.
        frozen: the frozen pieces as (tau_start, tau_end) pairs [s] in numerical time.
        impacts: the physical times [s] of the frozen pieces.
    """

    t: np.ndarray
    index: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    gap: np.ndarray
    normal_velocity: np.ndarray
    force: np.ndarray
    frozen: tuple[tuple[float, float], ...]
    impacts: tuple[float, ...]


def frozen_intervals(traj: Trajectory, *, rate_tol: float = FROZEN_RATE_TOL) -> np.ndarray:
    """Which sampling intervals [tau_k, tau_k+1] are frozen: dt/dtau <= `rate_tol`.

    Args:
        traj: the trajectory.
        rate_tol: clock rate [-] at or below which the clock counts as stopped.

    Returns:
        Boolean array of shape (N - 1,). A zero-length interval (tau_k+1 = tau_k, e.g. a
        repeated element boundary) counts as frozen exactly when the clock does not move.
    """
    if not (math.isfinite(rate_tol) and rate_tol >= 0):
        raise InvalidInput(f"`rate_tol` must be finite and >= 0, got {rate_tol!r}")
    dt = np.diff(traj.clock)
    dtau = np.diff(traj.tau)
    return dt <= rate_tol * dtau


def physical_time(traj: Trajectory, *, rate_tol: float = FROZEN_RATE_TOL) -> PhysicalSamples:
    """The physical trajectory x(tau) against t(tau), frozen pieces dropped (DESIGN.md 4.1).

    Args:
        traj: the trajectory in numerical time.
        rate_tol: clock rate dt/dtau [-] at or below which an interval counts as frozen.

    Returns:
        The kept samples (see `PhysicalSamples`).
    """
    frozen = frozen_intervals(traj, rate_tol=rate_tol)
    running = ~frozen
    n = traj.n_samples
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    keep[1:] |= running  # the interval into sample k advances the clock
    keep[:-1] |= running  # the interval out of sample k advances the clock
    index = np.flatnonzero(keep)
    pieces = []
    k = 0
    while k < n - 1:
        if frozen[k] and traj.tau[k + 1] > traj.tau[k]:
            start = k
            while k < n - 1 and frozen[k]:
                k += 1
            pieces.append((float(traj.tau[start]), float(traj.tau[k])))
        else:
            k += 1
    impacts = tuple(float(np.interp(a, traj.tau, traj.clock)) for a, _ in pieces)
    return PhysicalSamples(
        t=traj.clock[index],
        index=index,
        q=traj.q[index],
        v=traj.v[index],
        u=traj.u[index],
        gap=traj.gap[index],
        normal_velocity=traj.normal_velocity[index],
        force=traj.force[index],
        frozen=tuple(pieces),
        impacts=impacts,
    )


# ----------------------------------------------------------------------------- files


def sidecar_path(path: str | os.PathLike) -> tuple[Path, Path]:
    """The (npz, json) pair of paths for `path` (either member of the pair, or no suffix)."""
    path = Path(path)
    if path.suffix in (".npz", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".npz"), path.with_name(path.name + ".json")


def _atomic_write(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file in the same folder and a rename."""
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)  # mkstemp makes 0600 files; use the usual permissions
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def save_trajectory(path: str | os.PathLike, traj: Trajectory, *,
                    rate_tol: float = FROZEN_RATE_TOL) -> tuple[Path, Path]:
    """Write `traj` as `NAME.npz` + `NAME.json` (see the module docstring for the format).

    Both files are written to temporary files first and renamed into place, the npz
    before the sidecar, so an interrupted save never leaves a truncated file under the
    final name.

    Args:
        path: `NAME`, `NAME.npz` or `NAME.json`; the folder must exist.
        traj: the trajectory.
        rate_tol: clock-rate tolerance used for the stored `t` / `t_index`.

    Returns:
        The paths (npz, json) written.
    """
    if not isinstance(traj, Trajectory):
        raise InvalidInput(f"`traj` must be a Trajectory, got {type(traj).__name__}")
    missing = _missing_robot_keys(traj.robot)
    if missing:
        raise InvalidInput(
            f"`traj.robot` lacks {', '.join(missing)}: a saved trajectory must say how to "
            f"rebuild its robot ({', '.join(ROBOT_KEYS)}; `RobotSpec.to_dict()` gives them)"
        )
    npz_path, json_path = sidecar_path(path)
    if not npz_path.parent.is_dir():
        raise InvalidInput(f"`path`: folder {str(npz_path.parent)!r} does not exist")
    phys = physical_time(traj, rate_tol=rate_tol)
    arrays = {name: getattr(traj, name) for name in _ALL_ARRAYS}
    arrays["t"] = phys.t
    arrays["t_index"] = phys.index.astype(np.int64)
    for name, value in traj.extras.items():
        arrays["extra_" + name] = value
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    data = buffer.getvalue()
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "status": traj.status,
        "dimensions": {
            "N": traj.n_samples, "nq": traj.q.shape[1], "nv": traj.v.shape[1],
            "nu": traj.u.shape[1], "nc": traj.n_contacts,
        },
        "npz_file": npz_path.name,
        "npz_sha256": hashlib.sha256(data).hexdigest(),
        "frozen_rate_tol": rate_tol,
        "arrays": {**ARRAY_DOCS, **{"extra_" + k: "solver-specific" for k in traj.extras}},
        "robot": traj.robot,
        "scene": traj.scene,
        "solver": traj.solver,
        "verification": traj.verification,
    }
    text = json.dumps(meta, indent=2, allow_nan=False) + "\n"
    _atomic_write(npz_path, data)
    _atomic_write(json_path, text.encode("utf-8"))
    return npz_path, json_path


def load_trajectory(path: str | os.PathLike) -> Trajectory:
    """Read a trajectory written by `save_trajectory`, checking it thoroughly.

    Args:
        path: `NAME`, `NAME.npz` or `NAME.json`.

    Returns:
        The trajectory.

    Raises:
        TrajectoryFileError: a file is missing, damaged (truncated, not npz/JSON), foreign
            (not a tfcontact trajectory), of another format version, or its arrays have
            missing entries or inconsistent shapes. The message names the file and the
            problem.
    """
    npz_path, json_path = sidecar_path(path)
    for p in (npz_path, json_path):
        if not p.is_file():
            raise TrajectoryFileError(
                f"{str(p)!r} does not exist: a trajectory is the pair {npz_path.name} + "
                f"{json_path.name}, written by tfcontact.viz.save_trajectory"
            )
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise TrajectoryFileError(f"{str(json_path)!r} is not valid JSON: {err}") from err
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise TrajectoryFileError(
            f"{str(json_path)!r} is not a tfcontact trajectory sidecar "
            f"(expected \"format\": \"{FORMAT}\")"
        )
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        raise TrajectoryFileError(
            f"{str(json_path)!r} has format_version {version!r}; this tfcontact reads "
            f"version {FORMAT_VERSION} only"
        )
    for key in ("status", "dimensions", "npz_sha256", *_METADATA):
        if key not in meta:
            raise TrajectoryFileError(f"{str(json_path)!r} lacks the key `{key}`")
    if not isinstance(meta["robot"], dict) or _missing_robot_keys(meta["robot"]):
        raise TrajectoryFileError(
            f"{str(json_path)!r}: `robot` must be an object with the keys "
            f"{', '.join(ROBOT_KEYS)}"
        )
    data = npz_path.read_bytes()
    if hashlib.sha256(data).hexdigest() != meta["npz_sha256"]:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} does not match its sidecar {json_path.name} (checksum "
            "differs): the npz was modified, truncated or belongs to another save"
        )
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as err:
        raise TrajectoryFileError(f"{str(npz_path)!r} is not a readable npz file: {err}") from err
    missing = [name for name in (*_ALL_ARRAYS, "t", "t_index") if name not in arrays]
    if missing:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} lacks the arrays {', '.join(missing)}"
        )
    where = f"{npz_path.name}: "
    checked = _check_arrays(arrays, TrajectoryFileError, where)
    dims = meta["dimensions"]
    found = {"N": checked["tau"].shape[0], "nq": checked["q"].shape[1],
             "nv": checked["v"].shape[1], "nu": checked["u"].shape[1],
             "nc": checked["gap"].shape[1]}
    if dims != found:
        raise TrajectoryFileError(
            f"{where}array shapes {found} differ from the sidecar's dimensions {dims}"
        )
    t, t_index = arrays["t"], arrays["t_index"]
    if (t.ndim != 1 or t_index.shape != t.shape or not np.issubdtype(t_index.dtype, np.integer)
            or np.any(t_index < 0) or np.any(t_index >= found["N"])
            or not np.array_equal(t, checked["clock"][t_index])):
        raise TrajectoryFileError(f"{where}`t` / `t_index` do not match `clock`")
    extras = {name[len("extra_"):]: value for name, value in arrays.items()
              if name.startswith("extra_")}
    try:
        return Trajectory(
            **checked, status=meta["status"],
            **{key: meta[key] for key in _METADATA}, extras=extras,
        )
    except InvalidInput as err:
        raise TrajectoryFileError(f"{str(json_path)!r}: {err}") from err

