"""Load a robot: URDF or example-robot-data name -> Pinocchio models -> symbolic twin.

`load_robot` is the one entry point of the robot layer. It parses the URDF with
Pinocchio (kinematic model, collision and visual geometry), puts the requested base
joint under the root link, locks joints with `pinocchio.buildReducedModel`, builds the
CasADi twin (`RobotTwin`) and checks the contact frames.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin

from tfcontact.errors import FrameNotFound, IncompatibleOptions, InvalidInput, RobotLoadError
from tfcontact.robot.contact import ContactTerms, Ground, contact_terms
from tfcontact.robot.spec import BASES, PLANAR_BASES, ContactSpec, RobotSpec
from tfcontact.robot.twin import RobotTwin

#: The repository root (relative URDF paths are tried against the cwd, then here).
REPO_ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class _Source:
    """A resolved URDF: file, mesh package directories, and what its origin allows."""

    urdf: Path
    package_dirs: tuple[str, ...]
    fixed_only: str  # empty, or the reason why only base="fixed" is allowed
    armature_srdf: Path | None  # SRDF with rotor parameters (example-robot-data)


@dataclass(eq=False)
class Robot:
    """A loaded robot: Pinocchio models, the CasADi twin and the contact candidates.

    Attributes:
        spec: the `RobotSpec` it was built from (serialisable, rebuilds the robot).
        model: the Pinocchio model (nq == nv), with the base joint ``root_joint`` unless
            the base is fixed.
        data: a `pinocchio.Data` of `model`.
        collision_model: `pinocchio.GeometryModel` of collision geometry.
        visual_model: `pinocchio.GeometryModel` of visual geometry.
        twin: the `RobotTwin` with the symbols `q`, `v`, `tau` and M, h, frame terms.
        contacts: the contact candidates (`ContactSpec`), as in `spec.contacts`.
    """

    spec: RobotSpec
    model: pin.Model
    data: pin.Data
    collision_model: pin.GeometryModel
    visual_model: pin.GeometryModel
    twin: RobotTwin
    contacts: tuple[ContactSpec, ...] = field(default=())

    @property
    def q(self) -> ca.SX:
        """Generalised position symbol (nq = nv column) of the twin."""
        return self.twin.q

    @property
    def v(self) -> ca.SX:
        """Generalised velocity symbol (nv column) of the twin."""
        return self.twin.v

    @property
    def tau(self) -> ca.SX:
        """Generalised force symbol (nv column) of the twin."""
        return self.twin.tau

    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Names of all frames of the model (contact candidates pick from these)."""
        return self.twin.frame_names

    @property
    def planar(self) -> bool:
        """True when the base keeps the robot in the world x-z plane."""
        return self.spec.base in PLANAR_BASES

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the model's joints (without ``universe``), in q order."""
        return tuple(self.model.names[1:])

    def neutral(self) -> np.ndarray:
        """The neutral configuration `pin.neutral(model)` (all zeros here)."""
        return pin.neutral(self.model)

    def contact_terms(self, ground: Ground | None = None) -> list[ContactTerms]:
        """Gap, normal, tangents and drift of every contact candidate against `ground`.

        Args:
            ground: the half-space; default `Ground()` (z-up plane at height 0).

        Returns:
            One `ContactTerms` per entry of `contacts`, in order, as SX expressions in
            `q` (and `v` for the drift).
        """
        return contact_terms(self.twin, self.contacts, Ground() if ground is None else ground,
                             planar=self.planar)


def load_robot(
    source: str | os.PathLike | RobotSpec,
    *,
    base: str = "fixed",
    locked_joints: tuple[str, ...] | list[str] = (),
    contacts: tuple[ContactSpec, ...] | list[ContactSpec] = (),
    locked_positions: tuple[float, ...] | list[float] = (),
) -> Robot:
    """Load a robot from a URDF or example-robot-data and build its symbolic twin.

    Main arguments:
        source: a URDF path (absolute, or relative to the current directory or to the
            repository root, e.g. ``"robots/hopper.urdf"``), the name of one of the
            project's URDFs (``"hopper"``, ``"ball"``, ``"monoped"``: `project_robots()`),
            an example-robot-data name (``"solo12"``, ``"talos"``, ...), or a `RobotSpec`
            (then the keyword arguments must stay at their defaults).
        base: ``"fixed"`` (the URDF as written), ``"planar"`` (x, z, pitch),
            ``"planar_xz"`` (x, z) or ``"floating"`` (x, y, z, ZYX Euler angles). The base
            joint is named ``root_joint``. example-robot-data's quaternion free-flyer is
            replaced by the chosen base.

    Other arguments:
        locked_joints: joint names fixed and removed from the model.
        contacts: contact candidates; their frames must exist in the reduced model.
        locked_positions: positions [rad or m] of the locked joints (1-DoF joints), in
            the order of `locked_joints`; default: the neutral configuration (0).

    Returns:
        A `Robot`.

    Raises:
        RobotLoadError: missing or malformed URDF, unknown robot name, unsupported joints.
        IncompatibleOptions: a base the model cannot take.
        InvalidInput: an unknown base name or locked joint.
        FrameNotFound: a contact frame that is not in the model.
    """
    if isinstance(source, RobotSpec):
        if base != "fixed" or tuple(locked_joints) or tuple(contacts) or tuple(locked_positions):
            raise IncompatibleOptions(
                "`load_robot(spec)` takes base, locked_joints, contacts and locked_positions "
                "from the RobotSpec; do not pass them as keyword arguments too"
            )
        spec = source
    else:
        if isinstance(source, os.PathLike):
            source = os.fspath(source)
        spec = RobotSpec(source=source, base=base, locked_joints=tuple(locked_joints),
                         contacts=tuple(contacts), locked_positions=tuple(locked_positions))
    resolved = _resolve(spec.source)
    if spec.base != "fixed" and resolved.fixed_only:
        raise IncompatibleOptions(
            f"`base`={spec.base!r} cannot be used with `{spec.source}`: {resolved.fixed_only}; "
            "use base='fixed'"
        )
    model, collision, visual = _parse(resolved, spec.base)
    if resolved.armature_srdf is not None:
        pin.loadRotorParameters(model, str(resolved.armature_srdf), False)
        model.armature = np.multiply(model.rotorInertia.flat, np.square(model.rotorGearRatio.flat))
    if spec.locked_joints:
        model, collision, visual = _reduce(model, collision, visual, spec.locked_joints,
                                           spec.locked_positions)
    twin = RobotTwin(model)
    frames = tuple(f.name for f in model.frames)
    for c in spec.contacts:
        if not model.existFrame(c.frame):
            raise FrameNotFound(c.frame, frames)
    return Robot(spec=spec, model=model, data=model.createData(), collision_model=collision,
                 visual_model=visual, twin=twin, contacts=spec.contacts)


def _resolve(source: str) -> _Source:
    """Find the URDF of a path or an example-robot-data name."""
    looks_like_path = source.endswith(".urdf") or "/" in source or os.sep in source
    if looks_like_path:
        path = Path(source).expanduser()
        candidates = [path] if path.is_absolute() else [Path.cwd() / path, REPO_ROOT / path]
        for c in candidates:
            if c.is_file():
                return _Source(c.resolve(), (str(c.resolve().parent),), _anchored(c), None)
        raise RobotLoadError(
            f"URDF file `{source}` not found (tried {', '.join(str(c) for c in candidates)}); "
            "pass an existing path or an example-robot-data name such as 'solo12'"
        )
    project = REPO_ROOT / "robots" / f"{source}.urdf"
    if project.is_file():  # the project's own robots by name: "hopper", "ball", "monoped"
        return _Source(project, (str(project.parent),), _anchored(project), None)
    from example_robot_data.robots_loader import ROBOTS  # heavy import, only when needed

    if source not in ROBOTS:
        raise RobotLoadError(
            f"`{source}` is neither a URDF path, a robot of the project's `robots/` "
            f"({', '.join(project_robots())}) nor an example-robot-data robot; "
            f"known example-robot-data robots: {', '.join(sorted(ROBOTS))}"
        )
    loader_cls = ROBOTS[source]
    if not loader_cls.urdf_filename:
        raise RobotLoadError(
            f"example-robot-data robot `{source}` ships an SDF, not a URDF; tfcontact reads "
            "URDFs only: pick another robot"
        )
    from example_robot_data.utils import getModelPath

    sub = os.path.join(loader_cls.path, loader_cls.urdf_subpath, loader_cls.urdf_filename)
    try:
        model_path = loader_cls.model_path or getModelPath(sub)
    except OSError as err:
        raise RobotLoadError(
            f"example-robot-data robot `{source}`: {err}; reinstall example-robot-data"
        ) from err
    urdf = Path(model_path) / sub
    srdf = None
    if loader_cls.has_rotor_parameters and loader_cls.srdf_filename:
        srdf = (Path(model_path) / loader_cls.path / loader_cls.srdf_subpath
                / loader_cls.srdf_filename)
    fixed_only = "" if loader_cls.free_flyer else (
        "example-robot-data describes it as fixed to the world (no free-flyer)"
    )
    if source in ("talos_legs",):
        raise RobotLoadError(
            "example-robot-data's `talos_legs` is built in Python from `talos`; load 'talos' "
            "with locked_joints naming the torso, arm, gripper and head joints instead"
        )
    return _Source(urdf, (str(Path(model_path).parent.parent),), fixed_only or _anchored(urdf),
                   srdf)


def project_robots() -> tuple[str, ...]:
    """Names of the project's own URDFs in `robots/` (load them by name)."""
    return tuple(sorted(p.stem for p in (REPO_ROOT / "robots").glob("*.urdf")))


def _anchored(urdf: Path) -> str:
    """Reason why a URDF only takes a fixed base (its root link is ``world``), else ''."""
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as err:
        raise RobotLoadError(
            f"URDF file `{urdf}` is not valid XML ({err}); fix the file"
        ) from err
    links = {link.get("name") for link in root.iter("link")}
    children = {c.get("link") for j in root.iter("joint") for c in j.iter("child")}
    roots = links - children
    if roots == {"world"}:
        return "its root link is `world`, i.e. it is bolted to the world"
    return ""


def _base_joint(base: str) -> pin.JointModel | None:
    if base == "fixed":
        return None
    if base == "planar":
        joint = pin.JointModelComposite(pin.JointModelPX())
        joint.addJoint(pin.JointModelPZ())
        joint.addJoint(pin.JointModelRY())
        return joint
    if base == "planar_xz":
        joint = pin.JointModelComposite(pin.JointModelPX())
        joint.addJoint(pin.JointModelPZ())
        return joint
    if base == "floating":
        joint = pin.JointModelComposite(pin.JointModelTranslation())
        joint.addJoint(pin.JointModelSphericalZYX())
        return joint
    raise InvalidInput(f"`base` must be one of {', '.join(BASES)}, got {base!r}")


@contextlib.contextmanager
def _captured_stderr():
    """Collect what C++ code writes to file descriptor 2 (urdfdom's parse errors)."""
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = os.dup(2)
        try:
            os.dup2(tmp.fileno(), 2)
            text: list[str] = []
            yield text
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            text.append(tmp.read().decode(errors="replace"))


def _parse(src: _Source, base: str) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    root_joint = _base_joint(base)
    args: dict = {"package_dirs": list(src.package_dirs)}
    if root_joint is not None:
        args["root_joint"] = root_joint
    with _captured_stderr() as err:
        try:
            model, collision, visual = pin.buildModelsFromUrdf(str(src.urdf), **args)
            failure = None
        except ValueError as exc:  # Pinocchio's only parse failure type
            failure = exc
    if failure is not None:
        details = " ".join(line.strip() for line in err[0].splitlines()
                           if line.strip().startswith("Error:"))
        raise RobotLoadError(
            f"URDF file `{src.urdf}` could not be parsed: {failure} "
            f"{details.replace('Error:', '').strip()}; fix the file"
        ) from failure
    bad = [f"`{model.names[i]}` ({model.joints[i].shortname()})"
           for i in range(1, model.njoints) if model.joints[i].nq != model.joints[i].nv]
    if bad:
        raise IncompatibleOptions(
            f"`{src.urdf.name}` has joints with nq != nv: {', '.join(bad)}; the symbolic "
            "twin needs nq == nv: replace `continuous` by `revolute` and `floating`/`planar` "
            "URDF joints by a base chosen with `base=`"
        )
    return model, collision, visual


def _reduce(model: pin.Model, collision: pin.GeometryModel, visual: pin.GeometryModel,
            names: tuple[str, ...], positions: tuple[float, ...]
            ) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    known = [n for n in model.names[1:]]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InvalidInput(
            f"`locked_joints` names joints that are not in the model: {unknown}; "
            f"joints: {', '.join(known)}"
        )
    if "root_joint" in names:
        raise InvalidInput(
            "`locked_joints` cannot lock the base `root_joint`; use base='fixed' instead"
        )
    ids = [model.getJointId(n) for n in names]
    q_ref = pin.neutral(model)
    for name, jid, x in zip(names, ids, positions, strict=False):
        if model.joints[jid].nq != 1:
            raise InvalidInput(
                f"`locked_positions` sets joint `{name}` which has nq={model.joints[jid].nq}; "
                "only 1-DoF joints take a locked position: leave `locked_positions` empty"
            )
        q_ref[model.joints[jid].idx_q] = x
    reduced, (collision, visual) = pin.buildReducedModel(model, [collision, visual], ids, q_ref)
    return reduced, collision, visual
