"""Trajectory files under damage: every damaged pair is refused with a TrajectoryFileError
(fuzzed), the sidecar describes the robot, and `tfcontact check` / the plain-Pinocchio
script tell intact (0), failed physics (1) and damaged files (2) apart."""

from __future__ import annotations

import argparse
import copy
import dataclasses
import hashlib
import io
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from viz_hop import project_hop_trajectory

from tfcontact.errors import InvalidInput, TrajectoryFileError
from tfcontact.plan_format import FORMAT_VERSION, Trajectory, load_trajectory, save_trajectory
from tfcontact.plan_format.adapters import (
    CheckTolerances,
    check_plan,
    describe_robot,
    file_sha256,
    find_impacts,
    urdf_location,
)
from tfcontact.plan_format.trajectory import array_sha256, sidecar_sha256
from tfcontact.viz import cli_check

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "check_trajectory.py"
ARRAYS = ("tau", "clock", "s", "q", "v", "u", "gap", "normal_velocity", "force", "impulse")
METADATA = ("status", "robot", "scene", "solver", "verification", "model", "task",
            "frozen_rate_tol")
#: Damaged variants per kind in the fuzz test (7 kinds, 700 in all).
VARIANTS_PER_KIND = 100

MODEL = {  # a valid `model` entry for the synthetic plan (q = x, z, pitch; u drives pitch)
    "urdf": {"locate": "project", "name": "hopper", "sha256": "0" * 64},
    "base": "planar", "base_meaning": "x, z, pitch", "gravity": [0.0, 0.0, -9.81],
    "coordinates": [{"name": n, "unit": u, "joint": "root_joint"}
                    for n, u in (("x", "m"), ("z", "m"), ("pitch", "rad"))],
    "velocities": [{"name": n, "unit": u, "joint": "root_joint"}
                   for n, u in (("v_x", "m/s"), ("v_z", "m/s"), ("v_pitch", "rad/s"))],
    "controls": [{"name": "u_hip", "unit": "N m", "joint": "root_joint",
                  "drives": [{"velocity": "v_pitch", "joint": "root_joint", "gain": 1.0}]}],
}


def _plan(**changes) -> Trajectory:
    """A small synthetic plan (no solve): 12 samples, one frozen piece over samples 5..7."""
    rng = np.random.default_rng(7)
    n = 12
    tau = np.linspace(0.0, 1.1, n)
    clock = tau.copy()
    clock[5:8] = clock[5]
    impulse = np.zeros((n, 1, 3))
    impulse[7, 0, 2] = 0.4
    args = dict(
        tau=tau, clock=clock, s=np.ones(n), q=rng.normal(size=(n, 3)), v=rng.normal(size=(n, 3)),
        u=rng.normal(size=(n, 1)), gap=np.abs(rng.normal(size=(n, 1))),
        normal_velocity=rng.normal(size=(n, 1)), impulse=impulse, status="converged",
        robot={"source": "hopper", "base": "planar", "locked_joints": [],
               "contacts": [{"frame": "foot", "radius": 0.02}], "locked_positions": []},
        scene={"terrain": {"type": "flat", "height": 0.0}}, solver={"iterations": 12},
        verification={"passed": True}, extras={"w": rng.normal(size=(n, 2))},
        model=copy.deepcopy(MODEL), task={"goal": [0.7, 0.0]}, frozen_rate_tol=1e-3,
    )
    args.update(changes)
    return Trajectory(**args)


def _same(a: Trajectory, b: Trajectory) -> bool:
    """Exactly the same content: every array (extras included) and every metadata entry."""
    return (all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ARRAYS)
            and a.extras.keys() == b.extras.keys()
            and all(np.array_equal(a.extras[k], b.extras[k]) for k in a.extras)
            and all(getattr(a, k) == getattr(b, k) for k in METADATA))


@pytest.fixture
def saved(tmp_path):
    npz, sidecar = save_trajectory(tmp_path / "plan", _plan())
    return npz, sidecar


def _resign(meta: dict, data: bytes, *, arrays: bool = False) -> bytes:
    """The sidecar with its checksums recomputed for `data`, as a careful tool would:
    `npz_sha256`, optionally each array's entry (of what numpy can still read), and
    `sidecar_sha256`."""
    meta = copy.deepcopy(meta)
    meta["npz_sha256"] = hashlib.sha256(data).hexdigest()
    if arrays:
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as f:
                for name in f.files:
                    value = f[name]
                    meta["arrays"].setdefault(name, {}).update(
                        shape=list(value.shape), dtype=value.dtype.str,
                        sha256=array_sha256(value))
        except Exception:  # numpy cannot read it: the loader must refuse it anyway
            pass
    meta["sidecar_sha256"] = sidecar_sha256(meta)
    return json.dumps(meta, indent=2).encode()


def _signed(meta: dict) -> bytes:
    """The sidecar text with its `sidecar_sha256` recomputed."""
    return json.dumps({**meta, "sidecar_sha256": sidecar_sha256(meta)}, indent=2).encode()


def _edit(meta: dict, rng: np.random.Generator, *, checked_only: bool) -> dict:
    """`meta` with one field changed. `checked_only`: only fields the content checks tie
    to the arrays (so the change is caught even with every checksum recomputed)."""
    meta = copy.deepcopy(meta)
    checked = [
        lambda m: m["dimensions"].update(nq=m["dimensions"]["nq"] + 1),
        lambda m: m["robot"]["contacts"].append({"frame": "toe", "radius": 0.01}),
        lambda m: m.update(frozen_rate_tol=2.0),  # t / t_index no longer match
        lambda m: m.update(format_version=FORMAT_VERSION + 1),
        lambda m: m.update(npz_sha256="f" * 64),
        lambda m: m["arrays"]["q"].update(shape=[12, 2]),
        lambda m: m["arrays"].pop("extra_w"),
        lambda m: m["model"]["coordinates"].pop(),
        lambda m: m["model"].update(gravity=[0.0, -9.81]),
        lambda m: m["model"]["controls"][0].update(unit="kg"),
        lambda m: m.pop(["status", "robot", "arrays", "dimensions"][rng.integers(4)]),
        lambda m: m.update(status=5),
        lambda m: m.update(format="something-else"),
    ]
    free = [
        lambda m: m.update(status="failed"),
        lambda m: m["verification"].update(passed=False),
        lambda m: m["robot"]["contacts"][0].update(radius=0.05),
        lambda m: m["robot"].update(base="floating"),
        lambda m: m["task"].update(goal=[1.0, 0.0]),
        lambda m: m["scene"]["terrain"].update(height=-0.1),
        lambda m: m["model"]["urdf"].update(sha256="1" * 64),
        lambda m: m.update(comment="edited by hand"),
        lambda m: m.update(format_version=1),  # a downgrade does not drop the digests
    ]
    edits = checked if checked_only else checked + free
    edits[rng.integers(len(edits))](meta)
    return meta


def test_round_trip_of_format_2(saved):
    npz, sidecar = saved
    back = load_trajectory(npz)
    assert _same(back, _plan())
    meta = json.loads(sidecar.read_text())
    assert meta["format_version"] == FORMAT_VERSION == 2
    assert meta["sidecar_sha256"] == sidecar_sha256(meta)
    with np.load(npz) as f:
        for name in f.files:
            assert meta["arrays"][name]["sha256"] == array_sha256(f[name]), name
            assert meta["arrays"][name]["shape"] == list(f[name].shape)
    assert meta["arrays"]["t_index"]["dtype"] == "<i8"
    assert meta["model"] == MODEL and meta["task"] == {"goal": [0.7, 0.0]}
    assert meta["frozen_rate_tol"] == back.frozen_rate_tol == 1e-3


def test_fuzzed_files_raise_or_load_the_same_content(saved):
    """700 seeded damaged variants: each raises TrajectoryFileError (never another
    exception) or, where the damage left the content alone (zip metadata numpy ignores,
    JSON whitespace), loads exactly the original. Measured: 683 raised, 17 loaded equal
    (flips in zip metadata with the checksums recomputed), 0 loaded other content; 40 000
    more variants of the same kinds (other seeds) gave no other exception either."""
    npz, sidecar = saved
    original = load_trajectory(npz)
    good_npz, good_json = npz.read_bytes(), sidecar.read_bytes()
    meta = json.loads(good_json)
    rng = np.random.default_rng(20260428)

    def flipped(data: bytes) -> bytes:
        data = bytearray(data)
        for _ in range(rng.integers(1, 4)):
            data[rng.integers(len(data))] ^= int(rng.integers(1, 256))
        return bytes(data)

    kinds = {
        "npz flipped": lambda: (flipped(good_npz), good_json),
        "npz flipped, npz_sha256 recomputed": lambda: (
            data := flipped(good_npz), _resign(meta, data)),
        "npz flipped, every checksum recomputed": lambda: (
            data := flipped(good_npz), _resign(meta, data, arrays=True)),
        "npz truncated": lambda: (
            data := good_npz[:rng.integers(len(good_npz))],
            _resign(meta, data) if rng.random() < 0.5 else good_json),
        "json flipped": lambda: (good_npz, flipped(good_json)),
        "json field edited": lambda: (
            good_npz, json.dumps(_edit(meta, rng, checked_only=False)).encode()),
        "json field edited, sidecar_sha256 recomputed": lambda: (
            good_npz, _signed(_edit(meta, rng, checked_only=True))),
    }
    outcomes: Counter = Counter()
    for kind, damage in kinds.items():
        for _ in range(VARIANTS_PER_KIND):
            data, text = damage()
            npz.write_bytes(data)
            sidecar.write_bytes(text)
            try:
                loaded = load_trajectory(npz)
            except TrajectoryFileError as err:
                assert str(npz) in str(err) or str(sidecar) in str(err), err
                assert "re-run the plan" in str(err) or "tfcontact" in str(err), err
                outcomes[kind, "raised"] += 1
                continue
            assert (data, text) != (good_npz, good_json)
            assert _same(loaded, original), f"{kind}: a damaged pair loaded other content"
            outcomes[kind, "equal"] += 1
    print(sorted(outcomes.items()))  # the figures, shown by pytest -s
    assert sum(outcomes.values()) == len(kinds) * VARIANTS_PER_KIND
    raised = sum(v for (_, what), v in outcomes.items() if what == "raised")
    assert raised >= 0.9 * sum(outcomes.values()), outcomes
    for kind in ("npz truncated", "json field edited",
                 "json field edited, sidecar_sha256 recomputed"):
        assert outcomes[kind, "raised"] == VARIANTS_PER_KIND, kind


def _rewrite(sidecar: Path, change) -> None:
    meta = json.loads(sidecar.read_text())
    change(meta)
    meta["sidecar_sha256"] = sidecar_sha256(meta)
    sidecar.write_text(json.dumps(meta))


def _replace_npz(npz: Path, arrays: dict, *, digests: bool) -> None:
    """Write other arrays with the npz checksum (and optionally every digest) recomputed."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    npz.write_bytes(buffer.getvalue())

    def change(meta):
        meta["npz_sha256"] = hashlib.sha256(buffer.getvalue()).hexdigest()
        if digests:
            for name, value in arrays.items():
                meta["arrays"][name] = {"meaning": "", "shape": list(np.shape(value)),
                                        "dtype": np.asarray(value).dtype.str,
                                        "sha256": array_sha256(np.asarray(value))}
    _rewrite(npz.with_suffix(".json"), change)


def _arrays(npz: Path) -> dict:
    with np.load(npz) as f:
        return {k: f[k] for k in f.files}


@pytest.mark.parametrize("change, message", [
    (lambda a: a.update(q=a["q"] + 1e-9), r"`q` is not the array its sidecar records"),
    (lambda a: a.update(gap=np.full_like(a["gap"], np.nan)), "`gap` holds non-finite values"),
    (lambda a: a.update(tau=a["tau"][::-1].copy()), "`tau` must be non-decreasing"),
    (lambda a: a.update(clock=a["clock"] * np.r_[1.0, 1.0, 0.2, np.ones(9)]),
     "`clock` must be non-decreasing, but it drops"),
    (lambda a: a.update(v=a["v"].astype(np.float32)), r"wrong dtype \(`v` is float32"),
    (lambda a: a.update(t_index=a["t_index"][1:], t=a["t"][1:]),
     "`t` / `t_index` are not the physical samples of `clock`"),
    (lambda a: a.update(u=np.zeros((12, 2))), "`model\\['controls'\\]` must list one entry per "
     "column of `u` \\(2\\), got 1"),
    (lambda a: a.update(extra_x=np.zeros(12), **{"bad name": np.zeros(3)}),
     "unexpected member 'bad name.npy'"),
])
def test_content_checks_catch_changes_with_recomputed_npz_checksum(saved, change, message):
    npz, _ = saved
    arrays = _arrays(npz)
    change(arrays)
    _replace_npz(npz, arrays, digests=False)
    with pytest.raises(TrajectoryFileError, match=message):
        load_trajectory(npz)
    if "sidecar records" not in message:  # caught by the content, not only by the digest
        _replace_npz(npz, arrays, digests=True)
        with pytest.raises(TrajectoryFileError, match=message):
            load_trajectory(npz)


@pytest.mark.parametrize("change, message", [
    (lambda m: m.update(npz_sha256="0" * 64), r"plan\.npz' does not match its sidecar "
     r"plan\.json \(checksum differs\).*re-run the plan"),
    (lambda m: m["verification"].update(passed=False),
     r"plan\.json' was edited or damaged: its content does not match its `sidecar_sha256`"),
    (lambda m: m.update(format_version=7),
     "has format_version 7; this tfcontact reads versions 1, 2 only"),
    (lambda m: m.pop("arrays"), "lacks the key `arrays`"),
    (lambda m: m.update(frozen_rate_tol=-1.0), "`frozen_rate_tol` must be a finite number"),
    (lambda m: m["dimensions"].update(N=13), "differ from the sidecar's dimensions"),
])
def test_sidecar_damage_is_named(saved, change, message):
    npz, sidecar = saved
    meta = json.loads(sidecar.read_text())
    change(meta)
    sidecar.write_text(json.dumps(meta))  # sidecar_sha256 not recomputed
    with pytest.raises(TrajectoryFileError, match=message):
        load_trajectory(npz)


def test_non_finite_json_is_refused(saved):
    _, sidecar = saved
    sidecar.write_text(sidecar.read_text().replace('"iterations": 12', '"iterations": NaN'))
    with pytest.raises(TrajectoryFileError, match="not valid JSON: NaN is not a finite number"):
        load_trajectory(sidecar)


def test_truncated_and_missing_files(saved):
    npz, sidecar = saved
    data = npz.read_bytes()
    npz.write_bytes(data[: len(data) // 2])
    _rewrite(sidecar, lambda m: m.update(npz_sha256=hashlib.sha256(npz.read_bytes())
                                         .hexdigest()))
    with pytest.raises(TrajectoryFileError, match=r"is not a readable npz file: BadZipFile"):
        load_trajectory(npz)
    npz.unlink()
    with pytest.raises(TrajectoryFileError, match=r"plan\.npz' does not exist.*restore the pair"):
        load_trajectory(sidecar)


def test_version_1_files_still_load(tmp_path):
    """The saved plans in benchmarks/ are version 1; a version-1 pair has neither digests
    nor `model` / `task`, and loads with those empty."""
    old = REPO / "benchmarks" / "plans_particles" / "throwing_ball" / "trajectory.json"
    assert json.loads(old.read_text())["format_version"] == 1
    traj = load_trajectory(old)
    assert traj.model == {} and traj.task == {} and traj.frozen_rate_tol == 1e-3
    assert traj.n_samples == 401
    # a version-1 pair written now: the version-2 sidecar without its new keys
    npz, sidecar = save_trajectory(tmp_path / "v1", _plan(model={}, task={}))
    meta = json.loads(sidecar.read_text())
    for key in ("model", "task", "sidecar_sha256"):
        del meta[key]
    meta["arrays"] = {name: entry["meaning"] for name, entry in meta["arrays"].items()}
    meta["format_version"] = 1
    sidecar.write_text(json.dumps(meta))
    assert _same(load_trajectory(npz), _plan(model={}, task={}))


def test_model_must_describe_the_arrays():
    with pytest.raises(InvalidInput, match=r"`model\['coordinates'\]` must list one entry per "
                       r"column of `q` \(3\), got 2"):
        _plan(model={**MODEL, "coordinates": MODEL["coordinates"][:2]})
    with pytest.raises(InvalidInput, match=r"`model` lacks gravity"):
        _plan(model={k: v for k, v in MODEL.items() if k != "gravity"})


# ------------------------------------------------------------------ robot description


def test_describe_robot_of_the_hopper():
    """The sidecar's `model` names q, v and u with units, the joint each control drives,
    gravity, and the URDF by its SHA-256 (TF-8 hopper: u = hip torque on the pitch, leg
    force on the prismatic leg)."""
    from tfcontact.scenes.hopper import hopper_cls, hopper_robot, hopper_task

    robot, ground = hopper_robot()
    cls = hopper_cls(robot, ground, hopper_task("short"))
    model = describe_robot(robot.spec, cls)
    locate, urdf = urdf_location("hopper")
    assert (locate, urdf) == ("project", REPO / "robots" / "hopper.urdf")
    assert model["urdf"] == {"locate": "project", "name": "hopper", "sha256": file_sha256(urdf)}
    assert model["base"] == "planar" and "pitch [rad]" in model["base_meaning"]
    assert model["gravity"] == pytest.approx([0.0, 0.0, -9.81])
    assert [(c["name"], c["unit"]) for c in model["coordinates"]] == [
        ("x", "m"), ("z", "m"), ("pitch", "rad"), ("l", "m")]
    assert [v["unit"] for v in model["velocities"]] == ["m/s", "m/s", "rad/s", "m/s"]
    hip, leg = model["controls"]
    assert (hip["name"], hip["unit"], hip["joint"]) == ("u_hip", "N m", "root_joint")
    assert hip["drives"] == [{"velocity": "v_pitch", "joint": "root_joint", "gain": 1.0}]
    assert (leg["name"], leg["unit"], leg["joint"]) == ("u_leg", "N", "leg_joint")
    # the description is stored and checked against the arrays
    n = 5
    traj = Trajectory(tau=np.linspace(0, 1, n), clock=np.linspace(0, 1, n), s=np.ones(n),
                      q=np.zeros((n, 4)), v=np.zeros((n, 4)), u=np.zeros((n, 2)),
                      gap=np.zeros((n, 1)), normal_velocity=np.zeros((n, 1)),
                      robot=robot.spec.to_dict(), model=model)
    assert traj.model["controls"][1]["drives"][0]["velocity"] == "v_l"


# ------------------------------------------------------------------ plan checks


def test_cli_check_intact_damaged_and_failed(tmp_path, capsys):
    """`tfcontact check`: 0 intact and physical, 2 damaged (one line, no traceback),
    1 when the physics fails (a negative gap, or an impulse that breaks the momentum
    balance, saved with every checksum recomputed)."""
    traj = project_hop_trajectory()
    npz, sidecar = save_trajectory(tmp_path / "hop", traj)
    assert cli_check(argparse.Namespace(trajectory=str(npz))) == 0
    out = capsys.readouterr().out
    assert "ok   impacts  1 impact(s) (1 frozen pieces" in out and "at t = 0.4 s" in out
    assert "ok   fk" in out and "ok   robot    robots/hopper.urdf (path: hopper.urdf)" in out

    meta = json.loads(sidecar.read_text())
    sidecar.write_text(json.dumps({**meta, "npz_sha256": "0" * 64}))
    assert cli_check(argparse.Namespace(trajectory=str(npz))) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    assert captured.err.startswith("damaged: ") and "checksum differs" in captured.err

    gap = traj.gap.copy()
    gap[60] = -0.01  # a stance sample 1 cm inside the ground
    save_trajectory(tmp_path / "hop", dataclasses.replace(traj, gap=gap))
    assert cli_check(argparse.Namespace(trajectory=str(npz))) == 1
    out = capsys.readouterr().out
    assert "FAIL gaps     min gap -1.00e-02 m" in out and "FAIL fk" in out

    save_trajectory(tmp_path / "hop", dataclasses.replace(traj, impulse=1.01 * traj.impulse))
    assert cli_check(argparse.Namespace(trajectory=str(npz))) == 1
    assert "FAIL impacts" in capsys.readouterr().out


def test_check_names_a_changed_urdf_and_a_failed_verification(tmp_path):
    traj = project_hop_trajectory()
    stale = dataclasses.replace(traj, verification={"passed": False},
                                model={**_hop_model(), "urdf": {**_hop_model()["urdf"],
                                                               "sha256": "0" * 64}})
    result = check_plan(stale)
    failed = {item.name: item.detail for item in result.items if not item.passed}
    assert set(failed) == {"status", "robot"}
    assert "verification FAILED" in failed["status"]
    assert "differs from the plan's" in failed["robot"]


def _hop_model() -> dict:
    from tfcontact.scenes.hopper import hopper_cls, hopper_robot, hopper_task

    robot, ground = hopper_robot()
    model = describe_robot(robot.spec, hopper_cls(robot, ground, hopper_task("short")))
    model["urdf"]["locate"], model["urdf"]["name"] = "path", "robots/hopper.urdf"
    model["controls"] = model["controls"][1:]  # the synthetic hop has the leg force only
    return model


def test_impacts_from_the_recorded_data():
    """Frozen pieces whose clock creeps (rate 1e-5 < frozen_rate_tol 1e-3: the exact
    equality of consecutive `t` of the old check missed them), recorded impulses, and a
    touchdown inside a sampling interval as in `tfcontact plan hopper` (the foot at the
    ground approaching at 0.245 m/s, stopped at the next sample, the clock still running:
    no frozen sample interval and no impulse)."""
    n = 10
    tau = np.linspace(0.0, 0.9, n)
    clock = tau.copy()
    clock[3:6] = clock[2] + 1e-5 * (tau[3:6] - tau[2])  # frozen over samples 2..5, creeping
    clock[6:] = clock[5] + (tau[6:] - tau[5])
    gap = np.full((n, 1), 0.1)
    gap[2:6] = 0.0
    gap[7:] = 0.0
    vn = np.zeros((n, 1))
    vn[2], vn[7] = -1.0, -0.245
    impulse = np.zeros((n, 1, 3))
    impulse[5, 0, 2] = 1.0
    traj = _plan(tau=tau, clock=clock, s=np.ones(n), q=np.zeros((n, 3)), v=np.zeros((n, 3)),
                 u=np.zeros((n, 1)), gap=gap, normal_velocity=vn, impulse=impulse,
                 extras={}, frozen_rate_tol=1e-3)
    impacts = find_impacts(traj)
    assert [(i.kind, i.samples, i.contacts) for i in impacts] == [
        ("frozen piece", (2, 5), (0,)), ("inside interval", (7, 8), (0,))]
    assert impacts[0].impulse.tolist() == [[0.0, 0.0, 1.0]]
    assert impacts[1].time == pytest.approx(0.4, abs=1e-4)  # the frozen piece took 0.3 s of tau
    assert len(find_impacts(traj, tolerances=CheckTolerances(approach_speed=0.5))) == 1
    # a foot flying on towards the ground within closed_gap of it (a trot's swing foot
    # 0.08 mm up 1 ms before its landing: -0.02 then -0.04 m/s) has not landed yet; one
    # that reaches the ground still approaching has, and still approaches after it
    gap[6:, 0], vn[6:, 0] = (8e-5, 5e-5, 2e-5, 0.0), (-0.02, -0.04, -0.06, 0.0)
    skimming = find_impacts(dataclasses.replace(traj, gap=gap, normal_velocity=vn))
    assert [(i.kind, i.samples) for i in skimming] == [("frozen piece", (2, 5)),
                                                       ("inside interval", (8, 9))]
    gap[7, 0] = -1e-6
    through = find_impacts(dataclasses.replace(traj, gap=gap, normal_velocity=vn))
    assert [(i.kind, i.samples) for i in through][1] == ("inside interval", (6, 7))
    # the pair's other foot, closed but flying on, is not one of that touchdown's contacts
    # (whose approach after it `check_plan` judges)
    pair = find_impacts(dataclasses.replace(
        traj, gap=np.column_stack([gap, gap[:, 0] + 1e-5]),
        normal_velocity=np.column_stack([vn, np.full(n, -0.02)]),
        impulse=np.zeros((n, 2, 3)), force=np.zeros((n, 2, 3)),
        robot={**traj.robot, "contacts": 2 * traj.robot["contacts"]}))
    assert [(i.samples, i.contacts) for i in pair if i.kind == "inside interval"][0] == (
        (6, 7), (0,))


def test_check_tolerances_are_validated():
    with pytest.raises(InvalidInput, match=r"`penetration` must be a finite number > 0, got -1"):
        CheckTolerances(penetration=-1)


@pytest.mark.slow
def test_check_script_exit_codes(tmp_path):
    """scripts/check_trajectory.py (plain Pinocchio) agrees with `tfcontact check`."""
    traj = project_hop_trajectory()
    npz, sidecar = save_trajectory(tmp_path / "hop", traj)

    def run() -> tuple[int, str, str]:
        done = subprocess.run([sys.executable, str(SCRIPT), str(sidecar)], capture_output=True,
                              text=True, timeout=120)
        return done.returncode, done.stdout, done.stderr

    code, out, err = run()
    assert code == 0 and "ok   impacts  1 impact(s) (1 frozen" in out, out + err
    data = npz.read_bytes()
    npz.write_bytes(data[:-1] + bytes([data[-1] ^ 1]))
    code, out, err = run()
    assert code == 2 and out == "" and err.startswith("damaged: ") and "Traceback" not in err
    gap = traj.gap.copy()
    gap[60] = -0.01
    save_trajectory(tmp_path / "hop", dataclasses.replace(traj, gap=gap))
    code, out, err = run()
    assert code == 1 and "FAIL gaps" in out, out + err
    meta = json.loads(sidecar.read_text())
    sidecar.write_text(json.dumps({**meta, "npz_sha256": "0" * 64}))
    assert run()[0] == 2


# ---- the node file of an exact re-solve (tfcontact.plan_format.resolved) ----------------

def test_an_exact_plan_s_node_file_reads_back_what_was_written(tmp_path):
    """The saved TF-9 plan read, written with `save_resolved_plan` and read again: the same
    arrays, phases, integrator and mesh."""
    import types

    from stand_in_plans import SAVED_PLAN, saved_plan

    from tfcontact.plan_format.resolved import load_resolved_plan, save_resolved_plan

    saved = load_resolved_plan(SAVED_PLAN)
    assert [p.mode for p in saved.phases] == ["stick", "flight"] * 3 + ["stick"]
    assert saved.phases[-1].end == saved.t[-1] == pytest.approx(2.5)
    plan = saved_plan(types.SimpleNamespace(local_defects=saved.local_defects))
    again = load_resolved_plan(save_resolved_plan(plan, tmp_path / "plan.npz"))
    for name in ("t", "x", "u", "boundary_states", "local_defects"):
        np.testing.assert_array_equal(getattr(again, name), getattr(saved, name))
    assert again.phases == saved.phases and again.integrator == "radau"
    assert again.substeps == saved.substeps


def test_a_node_file_that_is_not_one_is_refused_with_the_fix(tmp_path):
    from tfcontact.plan_format.resolved import load_resolved_plan

    np.savez(tmp_path / "trajectory.npz", t=np.zeros(3), q=np.zeros((3, 2)))
    with pytest.raises(TrajectoryFileError, match="lacks x, u, boundary.*load_trajectory"):
        load_resolved_plan(tmp_path / "trajectory.npz")
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(TrajectoryFileError, match="not a readable node file"):
        load_resolved_plan(tmp_path / "text.npz")
    arrays = {"t": np.zeros(3), "x": np.zeros((3, 8)), "u": np.zeros((2, 2)),
              "boundary": np.zeros((2, 8)), "phase_modes": np.array(["stick"]),
              "phase_starts": np.zeros(1), "local_defects": np.zeros(2),
              "integrator": "rk4", "substeps": np.ones(2, dtype=int)}
    np.savez(tmp_path / "short.npz", **arrays)
    with pytest.raises(TrajectoryFileError, match="do not fit together"):
        load_resolved_plan(tmp_path / "short.npz")


def test_a_failed_stance_plans_decreasing_node_times_are_repaired_a_solved_ones_refused():
    """`stance_clock`: a failed re-solve's last iterate whose piece ran backwards (solo12's
    planar jump from a perturbed start: nodes 0.451, 0.4509994, ..., 0.452) keeps each
    node at the latest time so far and reports how far behind it lay, so its file is
    written; its impacts (tau's steps of IMPACT_TAU) are the nodes that repeat a time,
    not the repaired ones. A solved plan with such times is refused. Increasing times
    pass unchanged."""
    from tfcontact.errors import InvalidInput
    from tfcontact.plan_format import stance_clock
    from tfcontact.plan_format.adapters import IMPACT_TAU

    times = np.array([0.45, 0.451, 0.451, 0.4509994, 0.4509937, 0.452, 0.452, 0.5])
    clock, tau, drop = stance_clock(times, solved=False)
    np.testing.assert_array_equal(clock, [0.45, 0.451, 0.451, 0.451, 0.451, 0.452, 0.452,
                                          0.5])
    assert drop == pytest.approx(0.451 - 0.4509937)  # the furthest a node lies behind
    # two touchdowns (0.451 and 0.452 repeated), none at the repaired nodes
    np.testing.assert_allclose(tau - clock, IMPACT_TAU * np.array([0, 0, 1, 1, 1, 1, 2, 2]))
    assert np.all(np.diff(tau) >= 0)
    with pytest.raises(InvalidInput, match="node times decrease"):
        stance_clock(times, solved=True)
    fine = np.array([0.0, 0.1, 0.1, 0.2])
    clock, tau, drop = stance_clock(fine, solved=True)
    np.testing.assert_array_equal(clock, fine)
    np.testing.assert_allclose(tau, [0.0, 0.1, 0.1 + IMPACT_TAU, 0.2 + IMPACT_TAU])
    assert drop == 0.0
