"""Trajectory files: one `.npz` of arrays plus a JSON sidecar of the same name.

A planned or simulated motion lives in *numerical time* tau (DESIGN.md 4.1): the
time-freezing reformulation adds a clock state t(tau) that stops (dt/dtau = 0) while
an auxiliary impact mode is active. `Trajectory` keeps every sample in numerical time
together with the clock; `physical_time` gives the samples in physical time, frozen
pieces dropped, so that an impact becomes an instantaneous jump of the velocity.

File layout (format version 2), `NAME.npz` + `NAME.json`:

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

  Every array is float64 except `t_index` (int64) and the extras (any numeric dtype);
  all but the extras are finite.

* `NAME.json`, the sidecar:

  - `format` = "tfcontact-trajectory", `format_version` (2), `status` (the solver's word),
    `dimensions` (N, nq, nv, nu, nc), `frozen_rate_tol` (the clock rate dt/dtau [-] at
    or below which `t` / `t_index` count an interval as frozen);
  - integrity: `npz_sha256` (SHA-256 of the npz file: ties the pair together), `arrays`
    (per array: `meaning` with units, `shape`, `dtype` and `sha256` = SHA-256 of the
    array's bytes in C order) and `sidecar_sha256` (SHA-256 of the sidecar itself: the
    JSON of every other key with sorted keys, separators "," and ":", ASCII only);
  - `robot`: how tfcontact rebuilds the robot (`source`: URDF path, a name of the
    repository's `robots/` or an example-robot-data name; `base`; `locked_joints`;
    `contacts`: frame names and radii; `locked_positions`), i.e. `RobotSpec.to_dict()`;
  - `model`: the robot without the repository (optional, filled by
    `tfcontact.plan_format.adapters`): `urdf` (`locate`: "project" = `robots/NAME.urdf`,
    "example-robot-data" = that package's robot NAME, or "path"; `name`; `sha256` of the
    URDF's bytes), `base` and `base_meaning`, `gravity` [m/s^2], and the lists
    `coordinates` (nq), `velocities` (nv) and `controls` (nu) of `{"name", "unit"}`
    entries (units m, rad, m/s, rad/s, N, N m) naming their joint; each control also
    lists the velocity entries it `drives` with its gain;
  - `scene` (terrain, optional boxes and holes), `task` (free: what the plan was asked),
    `solver` (settings, timings, NLP count, iterations, complementarity residual,
    optional `history`: one entry per homotopy step) and `verification` (independent
    checks of the plan).

  Format version 1 (no `arrays` digests, `model`, `task` or `sidecar_sha256`) still loads.

A script of one's own reads the pair with numpy and json alone::

    import json, numpy as np
    meta = json.load(open("plan.json"))
    arrays = np.load("plan.npz")
    t, q_phys = arrays["t"], arrays["q"][arrays["t_index"]]

`scripts/check_trajectory.py` goes further without importing tfcontact: it verifies the
checksums, rebuilds the robot from `meta["robot"]` with plain Pinocchio and checks the
gaps and the momentum balance of every impact.

`load_trajectory` refuses every damaged pair with a `TrajectoryFileError` naming the file,
the problem and the fix: the checksums catch changed bytes, and the content is checked
on its own (shapes, dtypes, finiteness, monotone tau and clock, `t` / `t_index` against
the clock, the sidecar's dimensions and descriptions against the arrays) so that a
damaged file whose checksum was recomputed is refused as well.
"""

from __future__ import annotations

import hashlib
import io
import json
import lzma
import math
import os
import re
import struct
import tempfile
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput, TrajectoryFileError
from tfcontact.timefreezing import FROZEN_RATE_TOL

FORMAT = "tfcontact-trajectory"
FORMAT_VERSION = 2

#: Format versions `load_trajectory` reads (version 1: no digests, `model` or `task`).
READABLE_VERSIONS = (1, 2)

#: The clock-rate tolerance of version-1 files, which did not store theirs: their stored
#: physical samples `t` / `t_index` were computed with it. Newer files store theirs
#: (`frozen_rate_tol`); a new `Trajectory` takes the time-freezing layer's
#: `FROZEN_RATE_TOL`, the one tolerance of the project.
VERSION_1_RATE_TOL = 1e-6

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
#: Metadata dicts of format version 2 on top of version 1's.
_METADATA_V2 = ("model", "task")

#: Keys a saved trajectory's `robot` entry must have: enough to rebuild the robot with
#: plain Pinocchio (`tfcontact.robot.RobotSpec.to_dict()` gives them).
ROBOT_KEYS = ("source", "base", "locked_joints", "contacts")

#: Units of the `model` entries: coordinates, velocities and controls (`-`: unknown joint).
MODEL_UNITS = {
    "coordinates": ("m", "rad", "-"),
    "velocities": ("m/s", "rad/s", "-"),
    "controls": ("N", "N m", "-"),
}
#: How the `model["urdf"]` entry says where its URDF is.
URDF_LOCATIONS = ("project", "example-robot-data", "path")

_SHA256 = re.compile(r"[0-9a-f]{64}")


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
        model: the robot described without the repository (URDF digest, base, gravity,
            coordinate, velocity and control names with units); empty or as documented.
        task: what the plan was asked (free form; empty by default).
        frozen_rate_tol: clock rate dt/dtau [-] at or below which an interval counts as
            frozen (`physical_time`'s default for this trajectory).

    Raises:
        InvalidInput: an array has the wrong shape or non-finite values, a dict does
            not serialise to JSON, or `model` disagrees with the arrays.
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
    model: dict[str, Any] = field(default_factory=dict)
    task: dict[str, Any] = field(default_factory=dict)
    frozen_rate_tol: float = FROZEN_RATE_TOL

    def __post_init__(self):
        arrays = {name: getattr(self, name) for name in _REQUIRED}
        n_contacts = np.asarray(self.gap).shape[1] if np.ndim(self.gap) == 2 else 0
        n = np.shape(self.tau)[0] if np.ndim(self.tau) >= 1 else 0
        for name in ("force", "impulse"):
            arrays[name] = (
                np.zeros((n, n_contacts, 3)) if getattr(self, name) is None else getattr(self, name)
            )
        checked = _check_arrays(arrays)
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
            if value.dtype.hasobject:
                raise InvalidInput(f"`extras[{name!r}]` must be numeric, got dtype object")
            value.setflags(write=False)
            extras[name] = value
        object.__setattr__(self, "extras", extras)
        if not isinstance(self.status, str):
            raise InvalidInput(f"`status` must be a string, got {self.status!r}")
        for name in (*_METADATA, *_METADATA_V2):
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
        _check_model(self.model, {"coordinates": ("q", self.q.shape[1]),
                                  "velocities": ("v", self.v.shape[1]),
                                  "controls": ("u", self.u.shape[1])})
        object.__setattr__(self, "frozen_rate_tol", _rate_tol(self.frozen_rate_tol))

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return self.tau.shape[0]

    @property
    def n_contacts(self) -> int:
        """Number of contacts nc."""
        return self.gap.shape[1]

    def physical(self, *, rate_tol: float | None = None) -> PhysicalSamples:
        """The samples in physical time; see `physical_time`."""
        return physical_time(self, rate_tol=rate_tol)


_REQUIRED = ("tau", "clock", "s", "q", "v", "u", "gap", "normal_velocity")
_ALL_ARRAYS = (*_REQUIRED, "force", "impulse")
_N_DIMS = {"tau": 1, "clock": 1, "s": 1, "q": 2, "v": 2, "u": 2, "gap": 2,
           "normal_velocity": 2, "force": 3, "impulse": 3}


def _rate_tol(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating) \
            or not (math.isfinite(value) and value >= 0):
        raise InvalidInput(f"`rate_tol` must be finite and >= 0, got {value!r}")
    return float(value)


def _check_arrays(arrays: dict[str, Any]) -> dict[str, np.ndarray]:
    """Convert to float arrays and check shapes, finiteness and monotone times."""
    out: dict[str, np.ndarray] = {}
    for name in _ALL_ARRAYS:
        try:
            value = np.array(arrays[name], dtype=float)
        except (TypeError, ValueError) as err:
            raise InvalidInput(f"`{name}` is not a numeric array: {err}") from err
        out[name] = value
    for name, ndim in _N_DIMS.items():
        if out[name].ndim != ndim:
            raise InvalidInput(
                f"`{name}` must be {ndim}-D (one row per sample), got shape {out[name].shape}"
            )
    n = out["tau"].shape[0]
    if n < 2:
        raise InvalidInput(f"`tau` must hold at least 2 samples, got {n}")
    for name in _ALL_ARRAYS:
        if out[name].shape[0] != n:
            raise InvalidInput(
                f"`{name}` has {out[name].shape[0]} rows but `tau` has {n} samples: "
                "every array needs one row per sample"
            )
        if not np.all(np.isfinite(out[name])):
            raise InvalidInput(f"`{name}` holds non-finite values (nan or inf)")
    nc = out["gap"].shape[1]
    for name, shape in (("normal_velocity", (n, nc)), ("force", (n, nc, 3)),
                        ("impulse", (n, nc, 3))):
        if out[name].shape != shape:
            raise InvalidInput(
                f"`{name}` must have shape {shape} (nc = {nc} from `gap`), got {out[name].shape}"
            )
    for name in ("tau", "clock"):
        if np.any(np.diff(out[name]) < 0):
            k = int(np.argmax(np.diff(out[name]) < 0))
            raise InvalidInput(
                f"`{name}` must be non-decreasing, but it drops from "
                f"{out[name][k]!r} to {out[name][k + 1]!r} at sample {k + 1}"
            )
    for value in out.values():
        value.setflags(write=False)
    return out


def _check_model(model: dict[str, Any], sizes: dict[str, tuple[str, int]]) -> None:
    """`model` is empty or describes the arrays (see the module docstring)."""
    if not model:
        return
    missing = [k for k in ("urdf", "base", "base_meaning", "gravity", *MODEL_UNITS)
               if k not in model]
    if missing:
        raise InvalidInput(f"`model` lacks {', '.join(missing)}")
    urdf = model["urdf"]
    if (not isinstance(urdf, dict) or urdf.get("locate") not in URDF_LOCATIONS
            or not isinstance(urdf.get("name"), str)
            or not _SHA256.fullmatch(str(urdf.get("sha256")))):
        raise InvalidInput(
            "`model['urdf']` must be {\"locate\": one of " + ", ".join(URDF_LOCATIONS)
            + ", \"name\": str, \"sha256\": 64 hex digits}" + f", got {urdf!r}"
        )
    if not isinstance(model["base"], str) or not isinstance(model["base_meaning"], str):
        raise InvalidInput("`model['base']` and `model['base_meaning']` must be strings")
    gravity = model["gravity"]
    if (not isinstance(gravity, list) or len(gravity) != 3
            or not all(isinstance(g, int | float) and not isinstance(g, bool)
                       and math.isfinite(g) for g in gravity)):
        raise InvalidInput(f"`model['gravity']` must be 3 finite numbers [m/s^2], got {gravity!r}")
    for key, units in MODEL_UNITS.items():
        entries, (array, size) = model[key], sizes[key]
        if not isinstance(entries, list) or len(entries) != size:
            count = len(entries) if isinstance(entries, list) else type(entries).__name__
            raise InvalidInput(
                f"`model['{key}']` must list one entry per column of `{array}` ({size}), "
                f"got {count}"
            )
        for entry in entries:
            if (not isinstance(entry, dict) or not isinstance(entry.get("name"), str)
                    or not isinstance(entry.get("joint"), str) or entry.get("unit") not in units):
                raise InvalidInput(
                    f"`model['{key}']` entries must be {{\"name\": str, \"joint\": str, "
                    f"\"unit\": one of {', '.join(units)}}}, got {entry!r}"
                )
            if key == "controls" and not isinstance(entry.get("drives"), list):
                raise InvalidInput(f"`model['controls']` entries need `drives` (a list), "
                                   f"got {entry!r}")


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
        frozen_index: the frozen pieces as (entry, exit) sample indices.
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
    frozen_index: tuple[tuple[int, int], ...] = ()


def frozen_intervals(traj: Trajectory, *, rate_tol: float | None = None) -> np.ndarray:
    """Which sampling intervals [tau_k, tau_k+1] are frozen: dt/dtau <= `rate_tol`.

    Args:
        traj: the trajectory.
        rate_tol: clock rate [-] at or below which the clock counts as stopped; default
            `traj.frozen_rate_tol`.

    Returns:
        Boolean array of shape (N - 1,). A zero-length interval (tau_k+1 = tau_k, e.g. a
        repeated element boundary) counts as frozen exactly when the clock does not move.
    """
    tol = traj.frozen_rate_tol if rate_tol is None else _rate_tol(rate_tol)
    return _frozen(traj.tau, traj.clock, tol)


def _frozen(tau: np.ndarray, clock: np.ndarray, rate_tol: float) -> np.ndarray:
    return np.diff(clock) <= rate_tol * np.diff(tau)


def _kept_samples(frozen: np.ndarray) -> np.ndarray:
    """Indices of the samples in physical time: those next to a running interval, and
    the first and last."""
    keep = np.zeros(frozen.size + 1, dtype=bool)
    keep[0] = keep[-1] = True
    running = ~frozen
    keep[1:] |= running  # the interval into sample k advances the clock
    keep[:-1] |= running  # the interval out of sample k advances the clock
    return np.flatnonzero(keep)


def physical_time(traj: Trajectory, *, rate_tol: float | None = None) -> PhysicalSamples:
    """The physical trajectory x(tau) against t(tau), frozen pieces dropped (DESIGN.md 4.1).

    Args:
        traj: the trajectory in numerical time.
        rate_tol: clock rate dt/dtau [-] at or below which an interval counts as frozen;
            default `traj.frozen_rate_tol`.

    Returns:
        The kept samples (see `PhysicalSamples`).
    """
    frozen = frozen_intervals(traj, rate_tol=rate_tol)
    index = _kept_samples(frozen)
    n = traj.n_samples
    pieces = []
    k = 0
    while k < n - 1:
        if frozen[k] and traj.tau[k + 1] > traj.tau[k]:
            start = k
            while k < n - 1 and frozen[k]:
                k += 1
            pieces.append((start, k))
        else:
            k += 1
    impacts = tuple(float(np.interp(traj.tau[a], traj.tau, traj.clock)) for a, _ in pieces)
    return PhysicalSamples(
        t=traj.clock[index],
        index=index,
        q=traj.q[index],
        v=traj.v[index],
        u=traj.u[index],
        gap=traj.gap[index],
        normal_velocity=traj.normal_velocity[index],
        force=traj.force[index],
        frozen=tuple((float(traj.tau[a]), float(traj.tau[b])) for a, b in pieces),
        impacts=impacts,
        frozen_index=tuple(pieces),
    )


# ----------------------------------------------------------------------------- files

#: The fix named by every message about a damaged pair.
RESTORE = ("restore the pair NAME.npz + NAME.json from a backup, or re-run the plan that "
           "wrote it")

#: Exceptions the zip and npy readers raise on damaged bytes: a flipped flag bit asks for
#: a password (RuntimeError) or another compression method (NotImplementedError, or the
#: lzma / bz2 errors), a damaged stream fails in zlib, a damaged npy header in its parser.
_DAMAGED_NPZ = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, lzma.LZMAError,
                EOFError, OSError, RuntimeError, NotImplementedError, ValueError, KeyError,
                IndexError, OverflowError, struct.error, TypeError, MemoryError)

_ARRAY_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def sidecar_path(path: str | os.PathLike) -> tuple[Path, Path]:
    """The (npz, json) pair of paths for `path` (either member of the pair, or no suffix)."""
    path = Path(path)
    if path.suffix in (".npz", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".npz"), path.with_name(path.name + ".json")


def array_sha256(value: np.ndarray) -> str:
    """SHA-256 of an array's bytes in C order (the sidecar's `arrays[name]["sha256"]`);
    its shape and dtype are recorded next to it."""
    return hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()


def sidecar_sha256(meta: dict[str, Any]) -> str:
    """SHA-256 of a sidecar's content (its `sidecar_sha256`): the JSON of every other key
    with sorted keys, separators "," and ":", ASCII only, so whitespace does not count."""
    body = {key: value for key, value in meta.items() if key != "sidecar_sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def atomic_write(path: Path, data: bytes) -> None:
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
                    rate_tol: float | None = None) -> tuple[Path, Path]:
    """Write `traj` as `NAME.npz` + `NAME.json` (see the module docstring for the format).

    Both files are written to temporary files first and renamed into place, the npz
    before the sidecar, so an interrupted save never leaves a truncated file under the
    final name.

    Args:
        path: `NAME`, `NAME.npz` or `NAME.json`; the folder must exist.
        traj: the trajectory.
        rate_tol: clock-rate tolerance used for the stored `t` / `t_index`; default
            `traj.frozen_rate_tol`. It is stored as the sidecar's `frozen_rate_tol`.

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
    rate_tol = traj.frozen_rate_tol if rate_tol is None else _rate_tol(rate_tol)
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
    docs = {**ARRAY_DOCS, **{"extra_" + k: "solver-specific" for k in traj.extras}}
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
        "arrays": {name: {"meaning": docs[name], "shape": list(value.shape),
                          "dtype": np.asarray(value).dtype.str, "sha256": array_sha256(value)}
                   for name, value in arrays.items()},
        "robot": traj.robot,
        "model": traj.model,
        "scene": traj.scene,
        "task": traj.task,
        "solver": traj.solver,
        "verification": traj.verification,
    }
    meta["sidecar_sha256"] = sidecar_sha256(meta)
    text = json.dumps(meta, indent=2, allow_nan=False) + "\n"
    atomic_write(npz_path, data)
    atomic_write(json_path, text.encode("utf-8"))
    return npz_path, json_path


def load_trajectory(path: str | os.PathLike) -> Trajectory:
    """Read a trajectory written by `save_trajectory` (format version 1 or 2), checking it.

    The checks, in order: both files exist; the sidecar is a JSON object of this format
    and a readable version with every key of the right type; the npz matches the
    sidecar's `npz_sha256` and is a readable zip of npy arrays (each member's CRC-32
    checked); the arrays have the documented names, dtypes and shapes, are finite,
    tau and the clock never decrease, `t` / `t_index` are the physical samples of the
    clock, and the sidecar's dimensions and `model` agree with them; finally (version 2)
    each array matches its recorded shape, dtype and SHA-256, and the sidecar its own
    `sidecar_sha256`.

    Args:
        path: `NAME`, `NAME.npz` or `NAME.json`.

    Returns:
        The trajectory (for version 1 files `model` and `task` are empty).

    Raises:
        TrajectoryFileError: a file is missing, damaged (truncated, changed, not npz/JSON),
            foreign (not a tfcontact trajectory) or of an unknown format version. The
            message names the file, the problem and the fix.
    """
    npz_path, json_path = sidecar_path(path)
    for p in (npz_path, json_path):
        if not p.is_file():
            raise TrajectoryFileError(
                f"{str(p)!r} does not exist: a trajectory is the pair {npz_path.name} + "
                f"{json_path.name}, written by tfcontact.plan_format.save_trajectory; "
                f"{RESTORE}"
            )
    meta = _read_sidecar(json_path)
    data = _read_bytes(npz_path)
    if hashlib.sha256(data).hexdigest() != meta["npz_sha256"]:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} does not match its sidecar {json_path.name} (checksum "
            f"differs): the npz was modified, truncated or belongs to another save; {RESTORE}"
        )
    arrays = _read_npz(npz_path, data)
    traj = _trajectory(meta, arrays, npz_path)
    # a version-2 sidecar whose version was edited to 1 keeps its digests: check them
    if meta["format_version"] >= 2 or "sidecar_sha256" in meta:
        _check_digests(meta, arrays, npz_path, json_path)
    return traj


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as err:
        raise TrajectoryFileError(f"{str(path)!r} cannot be read: {err}; {RESTORE}") from err


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a finite number")


def _read_sidecar(json_path: Path) -> dict[str, Any]:
    """The sidecar's JSON object, checked for format, version and the type of each key."""
    try:
        meta = json.loads(_read_bytes(json_path).decode("utf-8"), parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError) as err:  # JSONDecodeError is a ValueError
        raise TrajectoryFileError(
            f"{str(json_path)!r} is not valid JSON: {err}; {RESTORE}") from err
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise TrajectoryFileError(
            f"{str(json_path)!r} is not a tfcontact trajectory sidecar "
            f"(expected \"format\": \"{FORMAT}\"): pass the NAME.json written by "
            "tfcontact.plan_format.save_trajectory"
        )
    version = meta.get("format_version")
    if isinstance(version, bool) or version not in READABLE_VERSIONS:
        raise TrajectoryFileError(
            f"{str(json_path)!r} has format_version {version!r}; this tfcontact reads "
            f"versions {', '.join(map(str, READABLE_VERSIONS))} only: read it with the "
            f"tfcontact that wrote it, or re-run the plan with this one"
        )
    digests = version >= 2 or "sidecar_sha256" in meta
    dicts = (*_METADATA, "dimensions") + ((*_METADATA_V2, "arrays") if digests else ())
    keys = ("status", "npz_sha256", *dicts) + (
        ("frozen_rate_tol", "sidecar_sha256") if version >= 2 else ())
    for key in keys:
        if key not in meta:
            raise TrajectoryFileError(f"{str(json_path)!r} lacks the key `{key}`; {RESTORE}")
    problems = [f"`{key}` must be an object" for key in dicts if not isinstance(meta[key], dict)]
    if not isinstance(meta["status"], str):
        problems.append("`status` must be a string")
    for key in ("npz_sha256", "sidecar_sha256"):
        if key in meta and not (isinstance(meta[key], str) and _SHA256.fullmatch(meta[key])):
            problems.append(f"`{key}` must be 64 hexadecimal digits")
    try:
        _rate_tol(meta.get("frozen_rate_tol", VERSION_1_RATE_TOL))
    except InvalidInput:
        problems.append("`frozen_rate_tol` must be a finite number >= 0")
    if problems:
        raise TrajectoryFileError(f"{str(json_path)!r}: {'; '.join(problems)}; {RESTORE}")
    if _missing_robot_keys(meta["robot"]):
        raise TrajectoryFileError(
            f"{str(json_path)!r}: `robot` must be an object with the keys "
            f"{', '.join(ROBOT_KEYS)}; {RESTORE}"
        )
    return meta


def _read_npz(npz_path: Path, data: bytes) -> dict[str, np.ndarray]:
    """The arrays of the npz bytes; any damage becomes a TrajectoryFileError."""
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            for info in archive.infolist():
                name = info.filename[:-4]
                if (not info.filename.endswith(".npy") or not _ARRAY_NAME.fullmatch(name)
                        or name in arrays):
                    raise TrajectoryFileError(
                        f"{str(npz_path)!r} is not a readable npz file: unexpected member "
                        f"{info.filename!r}; {RESTORE}")
                arrays[name] = _parse_npy(npz_path, name, archive.read(info))
    except _DAMAGED_NPZ as err:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} is not a readable npz file: {type(err).__name__}: {err}; "
            f"{RESTORE}") from err
    return arrays


def _parse_npy(npz_path: Path, name: str, raw: bytes) -> np.ndarray:
    """One npy member, its size checked against its header before anything is allocated."""
    buffer = io.BytesIO(raw)
    version = np.lib.format.read_magic(buffer)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(buffer)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(buffer)
    else:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} is not a readable npz file: `{name}` has npy version "
            f"{version}; {RESTORE}")
    count = math.prod(shape)
    offset = buffer.tell()
    if dtype.hasobject or dtype.itemsize == 0 or len(raw) - offset != count * dtype.itemsize:
        raise TrajectoryFileError(
            f"{str(npz_path)!r} is not a readable npz file: `{name}` holds "
            f"{len(raw) - offset} bytes of data, its header announces {shape} of {dtype}; "
            f"{RESTORE}")
    value = np.frombuffer(raw, dtype=dtype, count=count, offset=offset)
    value = value.reshape(shape[::-1]).T if fortran else value.reshape(shape)
    return np.ascontiguousarray(value)


def _trajectory(meta: dict[str, Any], arrays: dict[str, np.ndarray],
                npz_path: Path) -> Trajectory:
    """The trajectory of checked arrays and sidecar; content problems are file errors."""
    where = str(npz_path)
    missing = [name for name in (*_ALL_ARRAYS, "t", "t_index") if name not in arrays]
    if missing:
        raise TrajectoryFileError(f"{where!r} lacks the arrays {', '.join(missing)}; {RESTORE}")
    unknown = [name for name in arrays if name not in (*_ALL_ARRAYS, "t", "t_index")
               and not (name.startswith("extra_") and name[len("extra_"):].isidentifier())]
    if unknown:
        raise TrajectoryFileError(
            f"{where!r} holds arrays this format does not have: {', '.join(unknown)}; {RESTORE}")
    wrong = [f"`{name}` is {arrays[name].dtype}" for name in (*_ALL_ARRAYS, "t")
             if arrays[name].dtype != np.float64]
    if not np.issubdtype(arrays["t_index"].dtype, np.integer):
        wrong.append(f"`t_index` is {arrays['t_index'].dtype}")
    if wrong:
        raise TrajectoryFileError(
            f"{where!r}: wrong dtype ({', '.join(wrong)}; expected float64, and an integer "
            f"`t_index`); {RESTORE}")
    extras = {name[len("extra_"):]: value for name, value in arrays.items()
              if name.startswith("extra_")}
    try:
        traj = Trajectory(
            **{name: arrays[name] for name in _ALL_ARRAYS}, status=meta["status"],
            **{key: meta[key] for key in _METADATA},
            **{key: meta.get(key, {}) for key in _METADATA_V2},
            extras=extras, frozen_rate_tol=meta.get("frozen_rate_tol", VERSION_1_RATE_TOL),
        )
    except InvalidInput as err:
        raise TrajectoryFileError(f"{where!r}: {err}; {RESTORE}") from err
    found = {"N": traj.n_samples, "nq": traj.q.shape[1], "nv": traj.v.shape[1],
             "nu": traj.u.shape[1], "nc": traj.n_contacts}
    dims = meta["dimensions"]
    if dims != found or any(isinstance(x, bool) for x in dims.values()):
        raise TrajectoryFileError(
            f"{where!r}: array shapes {found} differ from the sidecar's dimensions {dims}; "
            f"{RESTORE}")
    t, t_index = arrays["t"], arrays["t_index"]
    expected = _kept_samples(_frozen(traj.tau, traj.clock, traj.frozen_rate_tol))
    if (t_index.shape != expected.shape or not np.array_equal(t_index, expected)
            or t.shape != expected.shape or not np.array_equal(t, traj.clock[expected])):
        raise TrajectoryFileError(
            f"{where!r}: `t` / `t_index` are not the physical samples of `clock` (frozen "
            f"rate {traj.frozen_rate_tol:g}); {RESTORE}")
    return traj


def _check_digests(meta: dict[str, Any], arrays: dict[str, np.ndarray], npz_path: Path,
                   json_path: Path) -> None:
    """Each array as its sidecar records it (shape, dtype, SHA-256); the sidecar as its
    own `sidecar_sha256` records it."""
    listed = meta["arrays"]
    if set(listed) != set(arrays):
        raise TrajectoryFileError(
            f"{str(npz_path)!r} holds the arrays {sorted(arrays)} but its sidecar lists "
            f"{sorted(listed)}; {RESTORE}")
    for name, value in arrays.items():
        entry = listed[name]
        if (not isinstance(entry, dict) or entry.get("shape") != list(value.shape)
                or entry.get("dtype") != value.dtype.str
                or entry.get("sha256") != array_sha256(value)):
            raise TrajectoryFileError(
                f"{str(npz_path)!r}: `{name}` is not the array its sidecar records (shape, "
                f"dtype or SHA-256 differ): its content was changed after the save; {RESTORE}")
    if sidecar_sha256(meta) != meta["sidecar_sha256"]:
        raise TrajectoryFileError(
            f"{str(json_path)!r} was edited or damaged: its content does not match its "
            f"`sidecar_sha256`; {RESTORE}")


STANCE_GAP = 1e-3
"""[m] the largest gap at which a contact counts as touching in a contact diagram (as
`tfcontact.ocp.goals.LiftOffs.touch`)."""


def stance_intervals(t: np.ndarray, gaps: np.ndarray, touch: float = STANCE_GAP
                     ) -> tuple[tuple[tuple[float, float], ...], ...]:
    """Which contact touches when: per contact (a column of `gaps`), the physical time
    intervals [start, end] over which its gap stays at or below `touch` [m], from samples
    at physical times `t` (non-decreasing, e.g. `PhysicalSamples.t`). A touch seen at one
    sample alone (an impact and lift-off in one frozen piece) is an interval of length 0.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    gaps = np.asarray(gaps, dtype=float).reshape(t.size, -1)
    if not (isinstance(touch, int | float) and touch >= 0 and np.isfinite(touch)):
        raise InvalidInput(f"`touch` must be a finite gap >= 0 [m], got {touch!r}")
    from tfcontact.ocp.goals import sample_runs

    return tuple(tuple((float(t[a]), float(t[b])) for a, b in sample_runs(down))
                 for down in (gaps <= touch).T)
