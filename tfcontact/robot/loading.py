"""Load a robot: URDF or example-robot-data name -> Pinocchio models -> symbolic twin.

`load_robot` is the one entry point of the robot layer. It parses the URDF with
Pinocchio (kinematic model, collision and visual geometry), puts the requested base
joint under the root link, locks joints with `pinocchio.buildReducedModel`, builds the
CasADi twin (`RobotTwin`) and checks the contact frames. Before the twin is built the model
is checked to be a physical rigid-body system (finite, non-negative masses, realisable
inertias, M(q) positive definite), so that a bad URDF fails at load with the link to fix
instead of later as a LinAlgError or a failed solve.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin

from tfcontact.errors import (
    FrameNotFound,
    IncompatibleOptions,
    InvalidInput,
    InvalidRobotModel,
    RobotLoadError,
)
from tfcontact.robot.contact import ContactTerms, Ground, contact_terms
from tfcontact.robot.spec import BASES, PLANAR_BASES, ContactSpec, RobotSpec
from tfcontact.robot.terrain import Terrain
from tfcontact.robot.twin import RobotTwin

#: The repository root (relative URDF paths are tried against the cwd, then here).
REPO_ROOT = Path(__file__).resolve().parents[2]

#: Round-off allowed in the inertia checks, as a fraction of the model's largest moment of
#: inertia of a body about its frame origin: CAD exports leave residues such as icub's
#: `r_hip_2` (a point mass) with ixx = iyy = -5.4e-20 kg m^2.
INERTIA_RTOL = 1e-9
#: M(q) counts as singular when a Cholesky pivot is below this fraction of its largest
#: diagonal entry, i.e. a condition number beyond 1e12, past what double precision resolves.
MASS_MATRIX_RTOL = 1e-12
#: A contact frame moves in the x-z plane when its Jacobian's y row is below this fraction
#: of its largest translational entry (round-off of the URDF's axes and origins).
PLANAR_TOLERANCE = 1e-9


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
    _fixed_base_planar: bool | None = field(default=None, init=False, repr=False)

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
        """True when the contacts move in the world x-z plane only: a planar base
        (`PLANAR_BASES`), or a fixed base whose joints move no contact frame along y (an
        arm whose out-of-plane joints are locked). Such contacts get one tangent: a
        second, along y, would have no column in J(q) and make the Delassus matrix
        singular."""
        if self.spec.base in PLANAR_BASES:
            return True
        if self.spec.base != "fixed" or not self.contacts:
            return False
        if self._fixed_base_planar is None:
            self._fixed_base_planar = self._contacts_stay_in_xz_plane()
        return self._fixed_base_planar

    def _contacts_stay_in_xz_plane(self) -> bool:
        # J's y row of every contact frame vanishes at a few configurations (a revolute
        # joint about world y or a prismatic one in x-z moves a point in the plane only)
        model, data = self.model, self.model.createData()
        rng = np.random.default_rng(0)
        frames = [model.getFrameId(c.frame) for c in self.contacts]
        for _ in range(3):
            q = rng.uniform(-np.pi, np.pi, model.nq)
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            for frame in frames:
                jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
                if np.abs(jac[1]).max() > PLANAR_TOLERANCE * max(np.abs(jac[:3]).max(), 1.0):
                    return False
        return True

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the model's joints (without ``universe``), in q order."""
        return tuple(self.model.names[1:])

    def neutral(self) -> np.ndarray:
        """The neutral configuration `pin.neutral(model)` (all zeros here)."""
        return pin.neutral(self.model)

    def contact_terms(self, ground: Ground | Terrain | None = None) -> list[ContactTerms]:
        """Gap, normal, tangents and drift of every contact candidate against `ground`.

        Args:
            ground: the half-space, or a `Terrain` of primitives; default `Ground()`
                (z-up plane at height 0).

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
            ``"planar_xz"`` (x, z), ``"vertical"`` (z: a rail) or ``"floating"`` (x, y,
            z, ZYX Euler angles). The base
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
        InvalidRobotModel: a non-finite or negative mass, an inertia no rigid body has, a
            joint that moves no mass, or M(q) singular at the neutral configuration; the
            message names the URDF link to fix.
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
    inertials = _urdf_inertials(resolved.urdf)
    if resolved.armature_srdf is not None:
        pin.loadRotorParameters(model, str(resolved.armature_srdf), False)
        model.armature = np.multiply(model.rotorInertia.flat, np.square(model.rotorGearRatio.flat))
    if spec.locked_joints:
        model, collision, visual = _reduce(model, collision, visual, spec.locked_joints,
                                           spec.locked_positions)
    # After locking: the bodies that end up in M(q) are the merged ones of the final model.
    _check_bodies(model, resolved.urdf.name, inertials)
    _check_mass_matrix(model, resolved.urdf.name)
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
    if base == "vertical":
        return pin.JointModelPZ()
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


@dataclass(frozen=True)
class _Inertial:
    """One URDF link's <inertial>: mass [kg], centre of mass [m], inertia about it [kg m^2]."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray  # 3 x 3, symmetric by construction (URDF gives six entries)


def _urdf_number(text: str | None, what: str, link: str, urdf: str, fix: str) -> np.ndarray:
    """The numbers of one URDF attribute; InvalidRobotModel when one is not finite."""
    try:
        values = np.array([float(x) for x in (text or "").split()], dtype=float)
    except ValueError:
        values = np.array([np.nan])
    if values.size == 0 or not np.all(np.isfinite(values)):
        raise InvalidRobotModel(
            f"`{urdf}`: link `{link}` has {what} \"{text}\", not a finite number "
            f"(urdfdom would drop the whole <inertial> without a word); {fix}",
            link=link, value=text,
        )
    return values


def _urdf_inertials(urdf: Path) -> dict[str, _Inertial]:
    """Read and check every link's <inertial> of the URDF file itself.

    The raw file is read because the parsed model hides two faults: urdfdom drops an
    <inertial> holding a non-finite number (the link then weighs 0 kg), and Pinocchio merges
    fixed links into their parent joint's body, where a negative mass or moment can hide
    behind a positive one. Checked here: finite mass, centre of mass and inertia; mass >= 0
    (0 is a massless frame, normal in URDFs); no negative principal moment. The triangle
    inequality is checked on the merged bodies (`_check_bodies`) only: example-robot-data's
    anymal, hyq and go1 carry 1e-6 kg placeholder links whose inertia (all six entries 1e-6)
    is rank one, which no rigid body has, but which vanishes in the body it is fixed to.

    Returns:
        The links that have an <inertial>, by URDF link name.
    """
    name = urdf.name
    found: dict[str, _Inertial] = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        lname = link.get("name", "?")
        mass_el = inertial.find("mass")
        mass_fix = f"give link `{lname}` a positive <mass value=...> [kg]"
        mass = 0.0 if mass_el is None else float(_urdf_number(
            mass_el.get("value"), "<mass> value", lname, name, mass_fix)[0])
        if mass < 0:
            raise InvalidRobotModel(
                f"`{name}`: link `{lname}` has a negative mass {mass:g} kg; {mass_fix}",
                link=lname, value=mass,
            )
        origin = inertial.find("origin")
        com_fix = f"give link `{lname}` a finite centre of mass <origin xyz=... rpy=...>"
        com = np.zeros(3)
        if origin is not None:
            com = _urdf_number(origin.get("xyz", "0 0 0"), "<inertial><origin> xyz", lname,
                               name, com_fix)
            _urdf_number(origin.get("rpy", "0 0 0"), "<inertial><origin> rpy", lname, name,
                         com_fix)
        el = inertial.find("inertia")
        inertia_fix = f"give link `{lname}` a finite <inertia ixx=... izz=...> [kg m^2]"
        entries = {k: 0.0 if el is None or el.get(k) is None else float(_urdf_number(
            el.get(k), f"<inertia> {k}", lname, name, inertia_fix)[0])
            for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        inertia = np.array([[entries["ixx"], entries["ixy"], entries["ixz"]],
                            [entries["ixy"], entries["iyy"], entries["iyz"]],
                            [entries["ixz"], entries["iyz"], entries["izz"]]])
        found[lname] = _Inertial(mass, com if com.size == 3 else np.zeros(3), inertia)
    scale = max((float(np.linalg.eigvalsh(i.inertia)[-1]) + i.mass * float(i.com @ i.com)
                 for i in found.values()), default=0.0)
    for lname, i in found.items():
        moments = np.linalg.eigvalsh(i.inertia)
        if moments[0] < -INERTIA_RTOL * scale:
            raise InvalidRobotModel(
                f"`{name}`: link `{lname}` has an inertia matrix with a negative principal "
                f"moment {moments[0]:.6g} kg m^2 (principal moments "
                f"{', '.join(f'{m:.6g}' for m in moments)}), which no body has; give link "
                f"`{lname}` an <inertia> whose principal moments are >= 0 and satisfy "
                "I1 + I2 >= I3 (e.g. from its CAD model)",
                link=lname, value=tuple(float(m) for m in moments),
            )
    return found


def _joint_links(model: pin.Model) -> list[tuple[str, ...]]:
    """The URDF links each joint moves rigidly: its child link first, then the links fixed
    to it (Pinocchio merged their inertias into the joint's body)."""
    links: list[list[str]] = [[] for _ in range(model.njoints)]
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY:
            links[frame.parentJoint].append(frame.name)
    return [tuple(names) for names in links]


def _blame(links: tuple[str, ...], inertials: dict[str, _Inertial], joint: str,
           faulty: Callable[[_Inertial], bool]) -> str:
    """The link to name in a message about a joint's merged body: the one whose own
    <inertial> shows the fault, else the first with an <inertial>, else the child link."""
    for name in links:
        if name in inertials and faulty(inertials[name]):
            return name
    with_inertial = [n for n in links if n in inertials]
    return (with_inertial or list(links) or [joint])[0]


def _check_bodies(model: pin.Model, urdf: str, inertials: dict[str, _Inertial]) -> None:
    """Check every body that moves (`model.inertias[j]`, j >= 1) is a physical rigid body.

    The rule (Wensing, Kim and Slotine, "Linear matrix inequalities for physically
    consistent inertial parameter identification", IEEE RA-L 2018): mass m >= 0; the
    rotational inertia I about the centre of mass symmetric and positive semidefinite with
    principal moments obeying the triangle inequality I1 + I2 >= I3 (I1 + I2 - I3 is twice a
    second moment of the mass distribution, which cannot be negative); a massless body
    carries no inertia. Point masses and thin rods (a zero moment) are physical, so
    semidefinite is allowed; M(q)'s definiteness is `_check_mass_matrix`'s concern. Each
    joint must also move some mass (its own body or one below it: a massless link between
    two joints, such as the hopper's `hip_link`, is fine), unless a rotor inertia
    (armature) gives its row of M(q) a diagonal.
    """
    links = _joint_links(model)
    subtree_mass = [sum(model.inertias[k].mass for k in model.subtrees[j])
                    for j in range(model.njoints)]
    scale = max((float(np.linalg.eigvalsh(model.inertias[j].inertia)[-1])
                 + model.inertias[j].mass * float(model.inertias[j].lever
                                                   @ model.inertias[j].lever)
                 for j in range(1, model.njoints)
                 if np.all(np.isfinite(model.inertias[j].inertia))), default=0.0)
    tol = INERTIA_RTOL * scale
    for j in range(1, model.njoints):
        body, joint = model.inertias[j], model.names[j]
        mass, com, inertia = float(body.mass), np.asarray(body.lever), np.asarray(body.inertia)
        moved = ", ".join(f"`{n}`" for n in links[j]) or "no link"
        where = f"the body of joint `{joint}` (links {moved})"
        if not (np.isfinite(mass) and np.all(np.isfinite(com))
                and np.all(np.isfinite(inertia))):
            link = _blame(links[j], inertials, joint, lambda i: False)
            raise InvalidRobotModel(
                f"`{urdf}`: {where} has a non-finite mass {mass}, centre of mass {com} or "
                f"inertia {inertia.tolist()}; give link `{link}` a finite <mass value=...>, "
                "<origin xyz=...> and <inertia .../>",
                link=link, value=(mass, com.tolist(), inertia.tolist()), joint=joint,
            )
        if mass < 0:
            link = _blame(links[j], inertials, joint, lambda i: i.mass < 0)
            raise InvalidRobotModel(
                f"`{urdf}`: {where} has a negative mass {mass:g} kg; give link `{link}` a "
                "positive <mass value=...> [kg]",
                link=link, value=mass, joint=joint,
            )
        if mass == 0:
            if np.max(np.abs(inertia)) > tol:
                link = _blame(links[j], inertials, joint,
                              lambda i: i.mass == 0 and bool(np.any(i.inertia)))
                raise InvalidRobotModel(
                    f"`{urdf}`: {where} has mass 0 kg but a rotational inertia "
                    f"{inertia.tolist()} kg m^2, which no body has; give link `{link}` a "
                    "positive <mass value=...> [kg] or a zero <inertia>",
                    link=link, value=inertia.tolist(), joint=joint,
                )
            continue
        if np.max(np.abs(inertia - inertia.T)) > tol:  # Pinocchio stores six entries
            link = _blame(links[j], inertials, joint, lambda i: False)
            raise InvalidRobotModel(
                f"`{urdf}`: {where} has a non-symmetric inertia {inertia.tolist()}; fix the "
                f"<inertia> of link `{link}`",
                link=link, value=inertia.tolist(), joint=joint,
            )
        moments = np.linalg.eigvalsh(inertia)
        shown = ", ".join(f"{m:.6g}" for m in moments)
        if moments[0] < -tol:
            link = _blame(links[j], inertials, joint,
                          lambda i: np.linalg.eigvalsh(i.inertia)[0] < 0)
            raise InvalidRobotModel(
                f"`{urdf}`: {where} has a negative principal moment of inertia "
                f"{moments[0]:.6g} kg m^2 (principal moments {shown}); give link `{link}` an "
                "<inertia> whose principal moments are >= 0 and satisfy I1 + I2 >= I3",
                link=link, value=tuple(float(m) for m in moments), joint=joint,
            )
        if moments[0] + moments[1] - moments[2] < -tol:
            link = _blame(links[j], inertials, joint, _breaks_triangle)
            raise InvalidRobotModel(
                f"`{urdf}`: {where} has principal moments of inertia {shown} kg m^2, which "
                f"break the triangle inequality I1 + I2 >= I3 ({moments[0] + moments[1]:.6g} "
                f"< {moments[2]:.6g}), so no rigid body has them; give link `{link}` an "
                "<inertia> that a body of its shape has (e.g. from its CAD model)",
                link=link, value=tuple(float(m) for m in moments), joint=joint,
            )
    # Leaves first, so that the joint named is the last one of a massless chain.
    for j in reversed(range(1, model.njoints)):
        joint, idx_v, nvj = model.names[j], model.joints[j].idx_v, model.joints[j].nv
        if subtree_mass[j] > 0 or np.all(model.armature[idx_v:idx_v + nvj] > 0):
            continue
        moved = [n for k in model.subtrees[j] for n in links[k]]
        link = next((n for n in moved if n in inertials), moved[0] if moved else joint)
        raise InvalidRobotModel(
            f"`{urdf}`: joint `{joint}` moves links {', '.join(f'`{n}`' for n in moved)}, "
            f"whose mass is {subtree_mass[j]:g} kg in all, so M(q) is singular in the row "
            f"of `{joint}`; give link `{link}` a positive <mass value=...> [kg] and an "
            "<inertia>, or lock the joint with `locked_joints`",
            link=link, value=subtree_mass[j], joint=joint,
        )


def _breaks_triangle(i: _Inertial) -> bool:
    moments = np.linalg.eigvalsh(i.inertia)
    return bool(moments[0] + moments[1] - moments[2] < -INERTIA_RTOL * max(moments[2], 0.0))


def _check_mass_matrix(model: pin.Model, urdf: str) -> None:
    """Final guard: M(q) positive definite at the neutral configuration.

    The neutral configuration is moved into the joint limits first (the hopper's leg length
    0 is outside [0.1, 0.5] m), so that the check judges a configuration the robot can take.
    M(q) is factored by Cholesky in joint order without pivoting: the first pivot
    D_k = M_kk - L_k,:k L_k,:k^T below MASS_MATRIX_RTOL * max M_ii is the row that depends on
    the rows before it, i.e. a joint whose motion moves no mass or inertia (a point mass on
    a revolute axis, say) given the joints above it.
    """
    if model.nv == 0:
        return
    q = np.clip(pin.neutral(model), model.lowerPositionLimit, model.upperPositionLimit)
    m = pin.crba(model, model.createData(), q)  # includes the rotor inertias (armature)
    m = np.triu(m) + np.triu(m, 1).T  # some Pinocchio versions fill the upper triangle only
    largest = float(np.max(m.diagonal()))
    chol = np.zeros_like(m)
    for k in range(model.nv):
        pivot = float(m[k, k] - chol[k, :k] @ chol[k, :k])
        if not pivot > MASS_MATRIX_RTOL * largest:  # also catches NaN
            j = next(j for j in range(1, model.njoints)
                     if model.joints[j].idx_v <= k < model.joints[j].idx_v + model.joints[j].nv)
            joint, nvj = model.names[j], model.joints[j].nv
            coordinate = f" (velocity {k - model.joints[j].idx_v + 1} of {nvj})" if nvj > 1 else ""
            links = _joint_links(model)[j]
            link = links[0] if links else joint
            raise InvalidRobotModel(
                f"`{urdf}`: the mass matrix M(q) at the neutral configuration is singular in "
                f"the row of joint `{joint}`{coordinate}, which moves links "
                f"{', '.join(f'`{n}`' for n in links) or 'none'}: Cholesky pivot {pivot:.3g} "
                f"against a largest diagonal entry {largest:.3g}; the joint's motion moves no "
                "mass or inertia (e.g. a point mass on a revolute axis, or massless links): "
                f"give link `{link}` a mass and an <inertia> that the joint moves, or lock "
                "the joint with `locked_joints`",
                link=link, value=pivot, joint=joint,
            )
        chol[k, k] = np.sqrt(pivot)
        chol[k + 1:, k] = (m[k + 1:, k] - chol[k + 1:, :k] @ chol[k, :k]) / chol[k, k]
