"""Tests of tfcontact.viz: trajectory files, physical time, replay HTML, figures."""

from __future__ import annotations

import base64
import gzip
import hashlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from viz_hop import CONTACTS, hop_trajectory, hopper_models, project_hop_trajectory

from tfcontact.errors import InvalidInput, TrajectoryFileError
from tfcontact.plan_format import (
    FORMAT_VERSION,
    Trajectory,
    load_trajectory,
    physical_time,
    save_trajectory,
)
from tfcontact.plan_format.trajectory import sidecar_path
from tfcontact.viz import plot_trajectory, replay
from tfcontact.viz.meshcat_replay import HOLE_WIDTH, RecordingWindow, hole_meshes, simplify_mesh

#: Stated bounds on the standalone page of the hopper: plain, measured 0.89 MB (meshcat's
#: inlined viewer script main.min.js alone is 0.85 MB); compressed (the default), 0.30 MB.
HOPPER_HTML_MAX_BYTES = {False: 1_000_000, True: 400_000}


def _small(n: int = 6, clock=None, **changes) -> Trajectory:
    tau = np.linspace(0.0, 1.0, n)
    args = dict(
        tau=tau, clock=tau if clock is None else np.asarray(clock, dtype=float), s=np.ones(n),
        q=np.zeros((n, 2)), v=np.zeros((n, 2)), u=np.zeros((n, 1)), gap=np.ones((n, 1)),
        normal_velocity=np.zeros((n, 1)),
        robot={"source": "robots/x.urdf", "base": "fixed", "locked_joints": [],
               "contacts": [{"frame": "foot", "radius": 0.02}]},
    )
    args.update(changes)
    return Trajectory(**args)


# ------------------------------------------------------------------ files


def test_round_trip(tmp_path):
    traj = hop_trajectory()
    traj = Trajectory(**{**{f: getattr(traj, f) for f in traj.__dataclass_fields__},
                         "extras": {"alpha": np.arange(traj.n_samples * 2.0).reshape(-1, 2)}})
    npz, sidecar = save_trajectory(tmp_path / "hop", traj)
    assert (npz.name, sidecar.name) == ("hop.npz", "hop.json")
    back = load_trajectory(tmp_path / "hop.json")
    for name in ("tau", "clock", "s", "q", "v", "u", "gap", "normal_velocity", "force",
                 "impulse"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name), err_msg=name)
    np.testing.assert_array_equal(back.extras["alpha"], traj.extras["alpha"])
    for name in ("status", "robot", "scene", "solver", "verification"):
        assert getattr(back, name) == getattr(traj, name), name
    # the sidecar alone tells a user's script what it needs
    meta = json.loads(sidecar.read_text())
    assert meta["format_version"] == FORMAT_VERSION
    assert meta["robot"]["contacts"] == CONTACTS
    assert meta["dimensions"] == {"N": traj.n_samples, "nq": 5, "nv": 5, "nu": 2, "nc": 1}
    # plain numpy reads the physical samples
    with np.load(npz) as arrays:
        phys = physical_time(traj)
        np.testing.assert_array_equal(arrays["t"], phys.t)
        np.testing.assert_array_equal(arrays["q"][arrays["t_index"]], phys.q)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hop.json", "hop.npz"]


def test_save_keeps_old_files_when_interrupted(tmp_path, monkeypatch):
    first = _small()
    npz, sidecar = save_trajectory(tmp_path / "a.npz", first)
    before = (npz.read_bytes(), sidecar.read_bytes())

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("tfcontact.plan_format.trajectory.os.replace", boom)
    with pytest.raises(OSError, match="disk full"):
        save_trajectory(tmp_path / "a.npz", _small(n=9))
    assert (npz.read_bytes(), sidecar.read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "a.npz"]


def _rewrite_npz(npz: Path, arrays: dict) -> None:
    """Replace the npz and update the sidecar's checksum, as a careless tool would."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    npz.write_bytes(buffer.getvalue())
    sidecar = npz.with_suffix(".json")
    meta = json.loads(sidecar.read_text())
    meta["npz_sha256"] = hashlib.sha256(buffer.getvalue()).hexdigest()
    sidecar.write_text(json.dumps(meta))


@pytest.fixture
def saved(tmp_path):
    npz, sidecar = save_trajectory(tmp_path / "traj", _small())
    with np.load(npz) as f:
        arrays = {k: f[k] for k in f.files}
    return npz, sidecar, arrays


def test_truncated_npz(saved):
    npz, _, _ = saved
    npz.write_bytes(npz.read_bytes()[:100])
    with pytest.raises(TrajectoryFileError, match=r"does not match its sidecar.*truncated"):
        load_trajectory(npz)


def test_truncated_npz_with_matching_checksum(saved):
    npz, sidecar, _ = saved
    data = npz.read_bytes()[:150]
    npz.write_bytes(data)
    meta = json.loads(sidecar.read_text())
    meta["npz_sha256"] = hashlib.sha256(data).hexdigest()
    sidecar.write_text(json.dumps(meta))
    with pytest.raises(TrajectoryFileError, match="is not a readable npz file"):
        load_trajectory(npz)


def test_wrong_format_version(saved):
    _, sidecar, _ = saved
    meta = json.loads(sidecar.read_text())
    meta["format_version"] = 99
    sidecar.write_text(json.dumps(meta))
    with pytest.raises(TrajectoryFileError, match="format_version 99; this tfcontact reads "
                       f"versions 1, {FORMAT_VERSION} only"):
        load_trajectory(sidecar)


@pytest.mark.parametrize("content, message", [
    ('{"hello": "world"}', "not a tfcontact trajectory sidecar"),
    ("[1, 2, 3]", "not a tfcontact trajectory sidecar"),
    ("not json at all", "is not valid JSON"),
])
def test_foreign_json(saved, content, message):
    _, sidecar, _ = saved
    sidecar.write_text(content)
    with pytest.raises(TrajectoryFileError, match=message):
        load_trajectory(sidecar)


def test_missing_sidecar(saved):
    npz, sidecar, _ = saved
    sidecar.unlink()
    with pytest.raises(TrajectoryFileError, match=r"traj\.json' does not exist"):
        load_trajectory(npz)


def test_missing_arrays(saved):
    npz, _, arrays = saved
    del arrays["q"], arrays["u"]
    _rewrite_npz(npz, arrays)
    with pytest.raises(TrajectoryFileError, match="lacks the arrays q, u"):
        load_trajectory(npz)


@pytest.mark.parametrize("name, value, message", [
    ("v", np.zeros((3, 2)), "`v` has 3 rows but `tau` has 6 samples"),
    ("q", np.zeros(6), "`q` must be 2-D"),
    ("force", np.zeros((6, 1, 2)), r"`force` must have shape \(6, 1, 3\)"),
    ("clock", np.array([0, 1, 2, 1.5, 3, 4.0]), "`clock` must be non-decreasing"),
    ("gap", np.full((6, 1), np.nan), "`gap` holds non-finite values"),
])
def test_mismatched_shapes(saved, name, value, message):
    npz, _, arrays = saved
    arrays[name] = value
    _rewrite_npz(npz, arrays)
    with pytest.raises(TrajectoryFileError, match=message):
        load_trajectory(npz)


def test_dimensions_must_match_sidecar(saved):
    npz, sidecar, arrays = saved
    meta = json.loads(sidecar.read_text())
    meta["dimensions"]["nq"] = 7
    sidecar.write_text(json.dumps(meta))
    with pytest.raises(TrajectoryFileError, match="differ from the sidecar's dimensions"):
        load_trajectory(npz)


def test_sidecar_needs_the_robot(saved, tmp_path):
    _, sidecar, _ = saved
    meta = json.loads(sidecar.read_text())
    del meta["robot"]["base"]
    sidecar.write_text(json.dumps(meta))
    with pytest.raises(TrajectoryFileError, match="`robot` must be an object with the keys "
                       "source, base, locked_joints, contacts"):
        load_trajectory(sidecar)
    with pytest.raises(InvalidInput, match=r"`traj.robot` lacks source, base"):
        save_trajectory(tmp_path / "x", _small(robot={"contacts": [{"frame": "foot"}]}))


def test_sidecar_paths():
    assert sidecar_path("out/plan") == (Path("out/plan.npz"), Path("out/plan.json"))
    assert sidecar_path("out/plan.json") == (Path("out/plan.npz"), Path("out/plan.json"))


@pytest.mark.parametrize("changes, message", [
    ({"q": np.zeros((5, 2))}, "`q` has 5 rows but `tau` has 6 samples"),
    ({"tau": np.array([0.0])}, "at least 2 samples"),
    ({"solver": {"x": np.zeros(2)}}, "`solver` must serialise to JSON"),
    ({"robot": {"contacts": [{"frame": "a"}, {"frame": "b"}]}},
     r"lists 2 contacts but `gap` has 1 columns"),
    ({"extras": {"bad": np.zeros(3)}}, r"`extras\['bad'\]` must have one row per sample"),
])
def test_trajectory_checks_input(changes, message):
    with pytest.raises(InvalidInput, match=message):
        _small(**changes)


# ---------------------------------------------------------- physical time


def test_physical_time_drops_frozen_piece():
    # samples 2..4 sit on a frozen piece (the clock is flat; a drift of 1e-9 is below tol)
    clock = [0.0, 0.1, 0.2, 0.2 + 1e-9, 0.2 + 2e-9, 0.3, 0.4]
    v = np.arange(7.0)[:, None] * np.ones((1, 2))
    traj = _small(n=7, clock=clock, v=v)
    phys = physical_time(traj)
    np.testing.assert_array_equal(phys.index, [0, 1, 2, 4, 5, 6])
    np.testing.assert_array_equal(phys.t, np.asarray(clock)[[0, 1, 2, 4, 5, 6]])
    assert phys.frozen == ((traj.tau[2], traj.tau[4]),)
    assert phys.impacts == (0.2,)
    # the impact is instantaneous: entry and exit states at the same physical time
    np.testing.assert_array_equal(phys.v[2:4, 0], [2.0, 4.0])
    # a strict tolerance keeps the drifting samples: nothing is frozen
    assert physical_time(traj, rate_tol=0.0).index.size == 7


def test_physical_time_without_freezing_keeps_everything():
    traj = _small(n=5)
    phys = physical_time(traj)
    np.testing.assert_array_equal(phys.index, np.arange(5))
    assert phys.frozen == () and phys.impacts == ()


def test_hop_impact_velocity_jump():
    """The hop's touchdown: v_z jumps from p'(0.4) = -2 m/s to the stance rate z'(0.4+)."""
    phys = physical_time(hop_trajectory())
    assert phys.impacts == pytest.approx((0.4,))
    k = int(np.flatnonzero(np.diff(phys.t) == 0)[0])
    assert phys.t[k] == pytest.approx(0.4)
    assert phys.v[k, 1] == pytest.approx(-2.0, abs=1e-6)
    assert phys.v[k + 1, 1] == pytest.approx(-0.12 * np.pi / 0.2, abs=1e-5)
    assert np.all(np.diff(phys.t) >= 0) and np.count_nonzero(np.diff(phys.t) == 0) == 1


# ------------------------------------------------------------------ replay


@pytest.fixture(scope="module", params=[False, True], ids=["plain", "compressed"])
def hop_html(request, tmp_path_factory):
    path = tmp_path_factory.mktemp("replay") / "hop.html"
    result = replay(hop_trajectory(), html=path, robot=hopper_models(), forces=True,
                    compress=request.param)
    return path, result, request.param


def _page_scripts(text: str, compressed: bool) -> str:
    """The page with a compressed payload unpacked, as the browser will run it."""
    if not compressed:
        return text
    payload = re.search(r'<script id="tfcontact-payload"[^>]*>([^<]*)</script>', text)
    return text + gzip.decompress(base64.b64decode(payload.group(1))).decode("utf-8")


def test_html_is_self_contained_and_small(hop_html):
    path, result, compressed = hop_html
    text = path.read_text(encoding="utf-8")
    assert result.html_bytes == path.stat().st_size
    assert result.html_bytes < HOPPER_HTML_MAX_BYTES[compressed]
    assert ("DecompressionStream" in text) == compressed
    text = _page_scripts(text, compressed)
    assert not re.search(r"<script[^>]*\ssrc\s*=", text)
    assert not re.search(r"<link\b", text)
    assert not re.search(r"""(?:src|href|url)\s*[=(]\s*["']?(?:https?:)?//""", text)
    assert not re.search(r"""(?:fetch|import|XMLHttpRequest)\s*\(\s*["']https?:""", text)
    # every absolute URL left in the page is an XML namespace name, nothing fetched
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", text))
    assert urls <= {"http://www.w3.org/1999/xhtml", "http://www.w3.org/2000/svg"}, urls
    assert "viewer.handle_command_bytearray" in text
    assert "new MeshCat.Viewer" in text


def _recorded_animation(traj, robot, **kwargs):
    """Replay and decode the recorded set_animation command."""
    result = replay(traj, robot=robot, **kwargs)
    commands = [umsgpack.unpackb(c) for c in result.scene.commands()]
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    return result, clips


def test_animation_follows_the_robot_and_contact_state(tmp_path):
    traj = hop_trajectory()
    model, visual = hopper_models()
    result, clips = _recorded_animation(traj, (model, visual), html=tmp_path / "h.html",
                                        fps=20.0, speed=0.5, forces=True)
    assert result.n_frames == 41 and result.duration == pytest.approx(1.0)
    # frame k shows physical time k * speed / fps; compare with Pinocchio at q(t) directly
    data, gdata = model.createData(), pin.GeometryData(visual)
    name = visual.geometryObjects[0].name
    clip = clips[f"/meshcat/tfcontact/robot/visuals/{name}"]
    (position,) = [tr for tr in clip["tracks"] if tr["name"] == ".position"]
    phys = physical_time(traj)
    for key in position["keys"][::7]:
        t = key["time"] * 0.5 / 20.0
        q = np.array([np.interp(t, phys.t, phys.q[:, j]) for j in range(model.nq)])
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, visual, gdata)
        np.testing.assert_allclose(key["value"], gdata.oMg[0].translation, atol=1e-9)
    # the contact marker is green exactly where the gap is closed
    (visible,) = [tr for tr in clips["/meshcat/tfcontact/contacts/0/on"]["tracks"]
                  if tr["name"] == ".visible"]
    times = np.array([k["time"] * 0.5 / 20.0 for k in visible["keys"]])
    shown = np.array([k["value"] for k in visible["keys"]])
    gap = np.interp(times, phys.t, phys.gap[:, 0])
    np.testing.assert_array_equal(shown, gap <= 1e-3)
    assert shown.any() and not shown.all()
    # force arrows: 0.3 m for the largest force (60 N up in stance), hidden in flight
    tracks = {tr["name"]: tr for tr in clips["/meshcat/tfcontact/contacts/0/force"]["tracks"]}
    lengths = np.array([k["value"][1] for k in tracks[".scale"]["keys"]])
    stance = (times > 0.4) & (times < 0.6)
    np.testing.assert_allclose(lengths[stance], 0.3)
    np.testing.assert_array_equal([k["value"] for k in tracks[".visible"]["keys"]],
                                  lengths > 1e-4)


def _closed(faces: np.ndarray) -> bool:
    """Every edge of a triangle mesh is shared by exactly two faces."""
    edges: dict[tuple[int, int], int] = {}
    for face in faces:
        for a, b in ((face[0], face[1]), (face[1], face[2]), (face[2], face[0])):
            key = (min(a, b), max(a, b))
            edges[key] = edges.get(key, 0) + 1
    return set(edges.values()) == {2}


def test_hole_meshes_extrude_the_scene_profiles():
    """Each hole's profile (a convex polygon in the x-z plane) is extruded across y into a
    closed mesh whose two caps are the profile itself."""
    square = [[0.0, -0.1], [1.0, -0.1], [1.0, 0.1], [0.0, 0.1]]
    hexagon = [[2 + np.cos(a), 0.1 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 6,
                                                                   endpoint=False)]
    meshes = hole_meshes({"holes": [{"profile": square}, {"profile": hexagon, "x_c": 2}]})
    for (vertices, faces), profile in zip(meshes, (square, hexagon), strict=True):
        k = len(profile)
        assert vertices.shape == (2 * k, 3) and faces.shape == (2 * k + 2 * (k - 2), 3)
        for cap, y in ((vertices[:k], -HOLE_WIDTH / 2), (vertices[k:], HOLE_WIDTH / 2)):
            np.testing.assert_array_equal(cap[:, [0, 2]], profile)
            np.testing.assert_array_equal(cap[:, 1], y)
        assert faces.min() == 0 and faces.max() == 2 * k - 1
        assert _closed(faces)
    assert hole_meshes({"terrain": {"type": "flat"}}) == []
    assert hole_meshes({"holes": [{"x_c": 0.5}]}) == []  # an older sidecar: not drawn
    with pytest.raises(InvalidInput, match="a hole needs a `profile` of"):
        hole_meshes({"holes": [{"profile": [[0, "a"], [1, 0], [1, 1]]}]})
    with pytest.raises(InvalidInput, match="3 or more finite"):
        hole_meshes({"holes": [{"profile": [[0, 0], [1, 0]]}]})
    with pytest.raises(InvalidInput, match="3 or more finite"):
        hole_meshes({"holes": [{"profile": [[0, 0], [1, 0], [1, float("nan")]]}]})


def test_replay_draws_the_scene_holes(tmp_path):
    traj = hop_trajectory()
    traj.scene["holes"] = [{"profile": [[0.3, -0.1], [0.7, -0.1], [0.5, 0.1]]}]
    result = replay(traj, robot=hopper_models(), html=tmp_path / "h.html")
    commands = [umsgpack.unpackb(c) for c in result.scene.commands()]
    holes = [c for c in commands if c["type"] == "set_object" and "/holes/" in c["path"]]
    assert [c["path"] for c in holes] == ["/meshcat/tfcontact/holes/0"]
    (geometry,) = holes[0]["object"]["geometries"]
    assert geometry["type"] == "BufferGeometry"


def test_recording_window_gives_meshcat_static_html():
    import meshcat
    import meshcat.geometry as mg

    vis = meshcat.Visualizer(window=RecordingWindow())
    vis["a/b"].set_object(mg.Box([1, 1, 1]))
    vis["a/b"].set_object(mg.Sphere(0.5))  # replaces the box, as meshcat's server does
    vis["a/c"].set_object(mg.Box([1, 2, 3]))
    vis["a/c"].delete()
    objects = [umsgpack.unpackb(c) for c in vis.window.commands()]
    assert [o["object"]["geometries"][0]["type"] for o in objects] == ["SphereGeometry"]
    assert vis.static_html().startswith("<!DOCTYPE html>")


def test_replay_checks_input(tmp_path):
    traj = hop_trajectory()
    with pytest.raises(InvalidInput, match="needs `html=<path>` or `live=True`"):
        replay(traj, robot=hopper_models())
    with pytest.raises(InvalidInput, match="`speed` must be > 0"):
        replay(traj, html=tmp_path / "x.html", robot=hopper_models(), speed=0.0)
    model, visual = hopper_models()
    wrong = _small(n=4, q=np.zeros((4, 3)), v=np.zeros((4, 3)))
    with pytest.raises(InvalidInput, match="q has 3 columns but the robot has nq = 5"):
        replay(wrong, html=tmp_path / "x.html", robot=(model, visual))


def test_simplify_mesh():
    # a unit square split into 20 x 20 cells, two triangles each
    n = 21
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d.ravel()], 1)])
    # cells finer than the vertex spacing change nothing
    v_same, f_same = simplify_mesh(vertices, faces, 0.01)
    assert f_same.shape == faces.shape and v_same.shape == vertices.shape
    np.testing.assert_allclose(np.sort(v_same, axis=0), np.sort(vertices, axis=0), atol=1e-12)
    # coarse cells: fewer triangles, valid non-degenerate indices, still a flat sheet
    v_c, f_c = simplify_mesh(vertices, faces, 0.2)
    assert 0 < len(f_c) < len(faces) / 10
    assert f_c.min() >= 0 and f_c.max() < len(v_c)
    assert np.all((f_c[:, 0] != f_c[:, 1]) & (f_c[:, 1] != f_c[:, 2]) & (f_c[:, 0] != f_c[:, 2]))
    np.testing.assert_array_equal(v_c[:, 2], 0.0)
    with pytest.raises(InvalidInput, match="`cell` must be a positive length"):
        simplify_mesh(vertices, faces, 0.0)


@pytest.mark.slow
def test_live_viewer_serves_on_localhost():
    import urllib.request

    result = replay(hop_trajectory(), live=True, robot=hopper_models())
    try:
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/static/", result.url)
        with urllib.request.urlopen(result.url, timeout=10) as response:
            assert response.status == 200
    finally:
        result.close()
    assert result.visualizer.window.server_proc.poll() is not None


# ----------------------------------------------------------------- figures


def test_figures_are_written(tmp_path):
    paths = plot_trajectory(hop_trajectory(), tmp_path / "figs")
    names = sorted(p.name for p in paths)
    expected = sorted(f"{n}.{e}" for n in ("states", "clock", "contacts", "homotopy", "path",
                                           "contact_diagram", "force_shin")
                      for e in ("png", "svg"))
    assert names == expected
    for p in paths:
        assert p.is_file() and p.stat().st_size > 1000, p
        if p.suffix == ".png":
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        else:
            assert b"<svg" in p.read_bytes()[:2000]


def test_figures_without_history(tmp_path):
    paths = plot_trajectory(_small(), tmp_path, formats=("png",))
    assert sorted(p.name for p in paths) == ["clock.png", "contact_diagram.png",
                                             "contacts.png", "force_foot.png", "path.png",
                                             "states.png"]
    with pytest.raises(InvalidInput, match="`formats` must be a non-empty subset"):
        plot_trajectory(_small(), tmp_path, formats=("jpg",))


# --------------------------------------------------------------------- CLI


def test_cli_replay_writes_html(tmp_path, capsys):
    import argparse

    from tfcontact.viz import cli_replay

    save_trajectory(tmp_path / "hop", project_hop_trajectory())
    args = argparse.Namespace(trajectory=str(tmp_path / "hop.npz"),
                              html=str(tmp_path / "hop.html"), open=False, speed=0.5)
    assert cli_replay(args) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'hop.html'}" in out and "61 frames" in out
    assert 200_000 < (tmp_path / "hop.html").stat().st_size < HOPPER_HTML_MAX_BYTES[True]
    damaged = argparse.Namespace(trajectory=str(tmp_path / "nothing.npz"), html="x.html",
                                 open=False)
    with pytest.raises(TrajectoryFileError, match="nothing.npz' does not exist"):
        cli_replay(damaged)


def test_replay_rebuilds_the_robot_from_the_sidecar(tmp_path):
    """robot=None: tfcontact.robot.load_robot(RobotSpec.from_dict(sidecar['robot']))."""
    traj = project_hop_trajectory()
    save_trajectory(tmp_path / "hop", traj)
    result = replay(tmp_path / "hop.json", html=tmp_path / "hop.html", fps=10.0)
    commands = [umsgpack.unpackb(c) for c in result.scene.commands()]
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    (position,) = [tr for tr in clips["/meshcat/tfcontact/robot/visuals/base_0"]["tracks"]
                   if tr["name"] == ".position"]
    phys = physical_time(traj)
    for key in position["keys"]:  # the base box sits at (x, 0, z) of q = (x, z, pitch, l)
        t = key["time"] / 10.0
        x, z = (np.interp(t, phys.t, phys.q[:, j]) for j in (0, 1))
        np.testing.assert_allclose(key["value"], [x, 0.0, z], atol=1e-12)


@pytest.mark.slow
def test_check_script_with_plain_pinocchio(tmp_path):
    """scripts/check_trajectory.py rebuilds the robot from the sidecar and checks the plan."""
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[1] / "scripts" / "check_trajectory.py"
    npz, sidecar = save_trajectory(tmp_path / "hop", project_hop_trajectory())

    def run():
        done = subprocess.run([sys.executable, str(script), str(sidecar)], capture_output=True,
                              text=True, timeout=120)
        return done.returncode, done.stdout

    code, out = run()
    assert code == 0, out
    assert "ok   fk" in out and "ok   impacts  1 impact(s)" in out
    # changed arrays saved again (format 2 records each array's SHA-256: a changed npz
    # with only its npz_sha256 recomputed is a damaged file, exit code 2)
    traj = project_hop_trajectory()
    fields = {f: getattr(traj, f) for f in traj.__dataclass_fields__}
    # a wrong impulse breaks the momentum balance
    save_trajectory(tmp_path / "hop", Trajectory(**{**fields, "impulse": 1.01 * traj.impulse}))
    code, out = run()
    assert code == 1 and "FAIL impacts" in out and "ok   fk" in out, out
    save_trajectory(tmp_path / "hop", Trajectory(**{**fields, "gap": traj.gap + 1e-3}))
    code, out = run()
    assert code == 1 and "FAIL fk" in out, out
    with np.load(npz) as f:
        arrays = {k: f[k] for k in f.files}
    _rewrite_npz(npz, arrays)
    assert run()[0] == 2


def test_cli_live_viewer_takes_a_sigterm_sent_on_its_ready_line():
    """A SIGTERM sent the moment the viewer says it runs (as the slow test below, or a
    supervisor, does on reading that line) stops it cleanly: exit 0, server closed. Made
    deterministic by sending the signal from inside that print (the replay faked); before
    the handler went in first, this process died of the signal (exit -15)."""
    import subprocess
    import sys

    code = """
import argparse, os, signal, sys, types
import tfcontact.viz.cli as viz_cli
closed = []
viz_cli.load_trajectory = lambda path: None
viz_cli.replay = lambda traj, **kw: types.SimpleNamespace(
    url="http://127.0.0.1:1/static/", close=lambda: closed.append(True))
def ready(*args, **kwargs):
    if any("Ctrl-C" in str(a) for a in args):
        os.kill(os.getpid(), signal.SIGTERM)
viz_cli.print = ready
code = viz_cli.cli_replay(argparse.Namespace(trajectory="x.npz", html=None, open=False))
sys.stdout.write(f"closed={closed} code={code}")
sys.exit(code)
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, (proc.returncode, proc.stderr)
    assert "closed=[True] code=0" in proc.stdout


@pytest.mark.slow
def test_cli_live_viewer_stops_its_server_on_sigterm(tmp_path):
    """`tfcontact replay X` without --html serves until stopped, then ends meshcat's server."""
    import os
    import signal
    import subprocess
    import sys
    import time
    import urllib.request

    save_trajectory(tmp_path / "hop", project_hop_trajectory())
    code = ("import argparse, sys; from tfcontact.viz import cli_replay; "
            "sys.exit(cli_replay(argparse.Namespace(trajectory=sys.argv[1], html=None, "
            "open=False)))")
    proc = subprocess.Popen([sys.executable, "-u", "-c", code, str(tmp_path / "hop.npz")],
                            stdout=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not any("Ctrl-C" in x for x in lines):
            lines.append(proc.stdout.readline())
        url = next(m.group(0) for x in lines
                   if (m := re.search(r"http://127\.0\.0\.1:\d+/static/", x)))
        with urllib.request.urlopen(url, timeout=10) as response:
            assert response.status == 200
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0
        with pytest.raises(OSError):
            urllib.request.urlopen(url, timeout=5)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        proc.stdout.close()
