"""Replay a trajectory in meshcat: a live local viewer or one standalone HTML file.

The robot's visual geometry is drawn by `pinocchio.visualize.MeshcatVisualizer`
(primitives as they are; mesh files, by default, re-meshed coarser by vertex clustering
to keep the HTML small), the scene's terrain as boxes (`ground_boxes`: flat ground, sloped
planes tilted, steps, holes as gaps in the ground), every contact candidate as two
spheres (green: in contact, grey: free) and optionally the contact forces as arrows.
The motion is a meshcat animation in physical time t (frozen pieces dropped,
DESIGN.md 4.1), played at `speed` times real time.

The standalone page needs no server and no network: meshcat's viewer script
(`main.min.js`) and every scene command are inlined; commands are decoded
synchronously from base64. By default both scripts are gzipped and base64-encoded in
the page, and unpacked by the browser (DecompressionStream), which makes the page
about three times smaller; `compress=False` inlines them as plain text. The page opens
at the start of the animation and plays it once; a URL fragment `#t=0.35` instead shows
the motion paused at physical time t = 0.35 s (used by the browser test, handy for
reports). A bar at the bottom of the page (`controls`, plain HTML outside meshcat's
menus) has a play/pause button, a time slider and a readout of the physical time t [s]
(not the animation's own time, which runs at `speed`); they drive meshcat's animation
(`viewer.animator`: `play`, `pause`, `seek`).
"""

from __future__ import annotations

import base64
import gzip
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from tfcontact.errors import InvalidInput
from tfcontact.plan_format.trajectory import Trajectory, load_trajectory, physical_time
from tfcontact.viz.terrain_view import DrawnBox, scene_terrain, terrain_boxes

ROOT = "tfcontact"
CONTACT_ON_COLOR = 0x2CA02C  # green: gap <= contact_tol
CONTACT_OFF_COLOR = 0xB0B0B0  # grey: free
FORCE_COLOR = 0xD62728
GROUND_COLOR = 0x8C8C8C
#: Colours of the drawn terrain: the ground (planes), steps and platforms, hole floors.
TERRAIN_COLORS = {"ground": GROUND_COLOR, "box": 0xA89A84, "floor": 0x5E5E5E}
HOLE_COLOR = 0xC44E52  # translucent red: where a foot's centre may not go
HOLE_WIDTH = 0.3  # [m] a hole's extent across the plane of motion (y), for drawing only


# ------------------------------------------------------------------- meshcat windows


class RecordingWindow:
    """A stand-in for `meshcat.visualizer.ViewerWindow` that keeps the scene in memory.

    `meshcat.Visualizer(window=RecordingWindow())` then works without starting meshcat's
    server process; `Visualizer.static_html()` returns the standalone page. The scene
    tree follows meshcat's own server (`meshcat.servers.zmqserver`): a later
    `set_object` on a path replaces the earlier one, `delete` drops a subtree.

    Args:
        fragment_time_offset: physical time [s] at animation time 0 (for `#t=` and the
            time readout).
        speed: playback rate [-] of the animation (for `#t=` and the time readout).
        compress: gzip + base64 the scripts, unpacked in the browser.
        end_time: physical time [s] of the animation's end (the slider's maximum); None:
            from the animation's duration, in the browser.
    """

    def __init__(self, *, fragment_time_offset: float = 0.0, speed: float = 1.0,
                 compress: bool = False, end_time: float | None = None):
        from meshcat.servers.tree import SceneTree

        self._tree_factory = SceneTree
        self.tree = SceneTree()
        self.fragment_time_offset = fragment_time_offset
        self.speed = speed
        self.compress = compress
        self.end_time = end_time

    def send(self, command) -> None:
        import umsgpack
        from meshcat.servers.tree import find_node

        data = command.lower()
        packed = umsgpack.packb(data)
        path = [p for p in data["path"].split("/") if p]
        kind = data["type"]
        if kind == "set_object":
            node = find_node(self.tree, path)
            node.object = packed
            node.properties = []
        elif kind == "set_transform":
            find_node(self.tree, path).transform = packed
        elif kind == "set_property":
            find_node(self.tree, path).properties.append(packed)
        elif kind == "set_animation":
            find_node(self.tree, path).animation = packed
        elif kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree = self._tree_factory()
        else:
            raise InvalidInput(f"meshcat command `{kind}` cannot be recorded")

    def commands(self) -> list[bytes]:
        """The msgpack-encoded commands that rebuild the scene, in meshcat's order."""
        from meshcat.servers.tree import walk

        out = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
        for node in walk(self.tree):  # animations last: their targets must exist
            if node.animation is not None:
                out.append(node.animation)
        return out

    def get_scene(self) -> str:
        """The standalone HTML page (called by `meshcat.Visualizer.static_html`)."""
        import meshcat

        js_path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
        main_js = js_path.read_text(encoding="utf-8")
        if "</script" in main_js:
            raise InvalidInput(f"{js_path} contains `</script`: cannot inline it")
        commands = ",\n".join('"' + base64.b64encode(c).decode("ascii") + '"'
                               for c in self.commands())
        t0 = float(self.fragment_time_offset)
        t1 = None if self.end_time is None else float(self.end_time)
        viewer = (_VIEWER.replace("@T0@", repr(t0))
                  .replace("@T1@", "null" if t1 is None else repr(t1))
                  .replace("@SPEED@", repr(float(self.speed)))
                  .replace("@COMMANDS@", commands))
        head = _HEAD + (_CONTROLS.replace("@T0@", repr(t0))
                        .replace("@T1@", repr(t0 if t1 is None else t1))
                        .replace("@READOUT@", f"t = {t0:.3f} s"))
        if not self.compress:
            return head + f"<script>\n{main_js}\n</script>\n<script>{viewer}</script>\n" + _TAIL
        packed = gzip.compress((main_js + "\n;\n" + viewer).encode("utf-8"), mtime=0)
        payload = base64.b64encode(packed).decode("ascii")
        return head + _UNPACK.replace("@PAYLOAD@", payload) + _TAIL

    # meshcat.Visualizer calls these on its window in some paths
    def open(self):
        return self

    def close(self):
        pass


class _TeeWindow:
    """Forward every command to several meshcat windows."""

    def __init__(self, *windows):
        self.windows = windows

    def send(self, command) -> None:
        for window in self.windows:
            window.send(command)


_HEAD = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>tfcontact replay</title>
<style>body { margin: 0; } #meshcat-pane { width: 100vw; height: 100vh; overflow: hidden; }
</style></head>
<body>
<div id="meshcat-pane"></div>
"""

_TAIL = """</body>
</html>
"""

# The replay's own controls, outside meshcat's menus: plain markup (present before any
# script runs, in the compressed page too), wired by the replay script. The slider's
# value is the physical time t [s]. Placeholders: @T0@, @T1@, @READOUT@.
_CONTROLS = """<style>
#tfcontact-controls { position: fixed; left: 12px; bottom: 12px; display: flex;
  align-items: center; gap: 10px; padding: 6px 10px; border-radius: 6px;
  background: rgba(255, 255, 255, 0.85); font: 14px sans-serif; color: #222; z-index: 10; }
#tfcontact-play { min-width: 4.5em; font: inherit; }
#tfcontact-time { width: min(50vw, 480px); }
#tfcontact-readout { font-variant-numeric: tabular-nums; min-width: 11em; }
</style>
<div id="tfcontact-controls">
<button id="tfcontact-play" type="button" aria-label="play or pause the motion">pause</button>
<input id="tfcontact-time" type="range" min="@T0@" max="@T1@" step="any" value="@T0@"
 aria-label="physical time [s]">
<output id="tfcontact-readout" for="tfcontact-time">@READOUT@</output>
</div>
"""

# The replay script: meshcat scene commands (msgpack + base64) applied synchronously,
# then the `#t=` fragment handler. Placeholders: @T0@, @SPEED@, @COMMANDS@.
_VIEWER = """
// tfcontact replay: meshcat scene commands, msgpack + base64, applied synchronously.
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var tfcontactReplay = {
  t0: @T0@,      // physical time [s] of animation time 0
  t1: @T1@,      // physical time [s] of its end (null: from the animation's duration)
  speed: @SPEED@,    // physical seconds per animation second
  commands: [
@COMMANDS@
  ]
};
(function () {
  function bytes(text) {
    var raw = atob(text), out = new Uint8Array(raw.length);
    for (var i = 0; i < raw.length; i++) out[i] = raw.charCodeAt(i);
    return out;
  }
  tfcontactReplay.commands.forEach(function (c) { viewer.handle_command_bytearray(bytes(c)); });
  tfcontactReplay.commands = null;
  // `#t=<physical time [s]>`: pause the animation at that time.
  function showFragmentTime() {
    var m = /(?:^#|&)t=([-+0-9.eE]+)/.exec(window.location.hash);
    if (!m) return;
    var t = parseFloat(m[1]);
    var a = (t - tfcontactReplay.t0) / tfcontactReplay.speed;
    viewer.animator.pause();
    viewer.animator.seek(a);
    viewer.animator.display_progress(a);
    viewer.set_dirty();
    document.title = "tfcontact replay t=" + t;
  }
  showFragmentTime();
  window.addEventListener("hashchange", showFragmentTime);
  wireControls();
  document.body.setAttribute("data-tfcontact-ready", "1");

  // The bar of _CONTROLS: play/pause, the slider and the readout, all in physical time.
  function wireControls() {
    var animator = viewer.animator, R = tfcontactReplay;
    var button = document.getElementById("tfcontact-play");
    var slider = document.getElementById("tfcontact-time");
    var readout = document.getElementById("tfcontact-readout");
    if (!button || !slider || !readout) return;
    if (R.t1 === null) R.t1 = R.t0 + animator.duration * R.speed;
    slider.min = R.t0;
    slider.max = R.t1;
    function physical(a) { return Math.min(Math.max(R.t0 + a * R.speed, R.t0), R.t1); }
    function show(t) {
      readout.textContent = "t = " + t.toFixed(3) + " s";
      readout.setAttribute("data-t", String(t));
    }
    function sync() {
      var t = physical(animator.time);
      slider.value = t;
      show(t);
      button.textContent = animator.playing ? "pause" : "play";
      button.setAttribute("aria-pressed", animator.playing ? "true" : "false");
    }
    button.addEventListener("click", function () {
      if (animator.playing) {
        animator.pause();
      } else {
        // at the end meshcat rewinds its clips but keeps the last time shown: start over
        if (animator.time >= animator.duration) animator.reset();
        animator.play();
      }
      sync();
    });
    slider.addEventListener("input", function () {
      var t = parseFloat(slider.value);
      var a = (t - R.t0) / R.speed;
      animator.pause();
      animator.seek(a);
      animator.display_progress(a);
      viewer.set_dirty();
      sync();
      show(t);  // the slider's own value, not its round trip through animation time
    });
    window.addEventListener("hashchange", sync);
    sync();
    var was = animator.playing;
    (function loop() {  // follow the playing animation, and its stop at the end
      if (animator.playing || was !== animator.playing) sync();
      was = animator.playing;
      requestAnimationFrame(loop);
    })();
  }
})();
"""

# Compressed page: meshcat's viewer script and the replay script, gzip + base64, unpacked
# by the browser's DecompressionStream (Chromium 80, Firefox 113, Safari 16.4 and later).
_UNPACK = """<script id="tfcontact-payload" type="application/octet-stream">@PAYLOAD@</script>
<script>
(function () {
  var raw = atob(document.getElementById("tfcontact-payload").textContent.trim());
  var data = new Uint8Array(raw.length);
  for (var i = 0; i < raw.length; i++) data[i] = raw.charCodeAt(i);
  var stream = new Blob([data]).stream().pipeThrough(new DecompressionStream("gzip"));
  new Response(stream).text().then(function (code) {
    var script = document.createElement("script");
    script.text = code;
    document.body.appendChild(script);
  });
})();
</script>
"""


# ------------------------------------------------------------------------ geometry


def simplify_mesh(vertices: np.ndarray, faces: np.ndarray, cell: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Coarsen a triangle mesh by vertex clustering on a grid of `cell` [m].

    Vertices in one grid cell merge into their mean; triangles that collapse or repeat
    are dropped. Cheap, robust, and good enough to show a robot link.

    Args:
        vertices: (V, 3) positions [m].
        faces: (F, 3) vertex indices.
        cell: grid spacing [m], > 0.

    Returns:
        (vertices, faces) of the coarse mesh.
    """
    if not (math.isfinite(cell) and cell > 0):
        raise InvalidInput(f"`cell` must be a positive length [m], got {cell!r}")
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    keys = np.floor(vertices / cell).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    merged = np.zeros((counts.size, 3))
    np.add.at(merged, inverse, vertices)
    merged /= counts[:, None]
    f = inverse[faces]
    good = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[good]
    if f.size:
        _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
        f = f[np.sort(first)]
    used = np.unique(f)
    remap = np.full(merged.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return merged[used], remap[f]


def _mesh_arrays(geometry_object) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (scaled by meshScale) and faces of a mesh-file geometry object, via coal."""
    import coal

    mesh = coal.MeshLoader().load(geometry_object.meshPath, np.asarray(geometry_object.meshScale))
    vertices = np.array(mesh.vertices(), dtype=float)
    faces = np.empty((mesh.num_tris, 3), dtype=np.int64)
    for k in range(mesh.num_tris):
        tri = mesh.tri_indices(k)
        faces[k] = (tri[0], tri[1], tri[2])
    return vertices, faces


def _make_visualizer_class():
    from pinocchio.visualize import MeshcatVisualizer
    from pinocchio.visualize.meshcat_visualizer import hasMeshFileInfo

    class _Visualizer(MeshcatVisualizer):
        """Pinocchio's meshcat visualizer, with each geometry under `<group>/<name>/shape`
        (the parent node carries the animated placement, the child the static mesh
        scale) and mesh files optionally coarsened."""

        def __init__(self, model, visual_model, mesh_detail):
            super().__init__(model, None, visual_model)
            self.mesh_detail = mesh_detail
            self._prescaled: set[str] = set()

        def getViewerNodeName(self, geometry_object, geometry_type):
            return f"{self.viewerVisualGroupName}/{geometry_object.name}/shape"

        def loadMeshFromFile(self, geometry_object):
            if self.mesh_detail is None:
                return super().loadMeshFromFile(geometry_object)
            import meshcat.geometry as mg

            vertices, faces = _mesh_arrays(geometry_object)
            extent = float(np.linalg.norm(np.ptp(vertices, axis=0)))
            if extent > 0:
                vertices, faces = simplify_mesh(vertices, faces, self.mesh_detail * extent)
            self._prescaled.add(geometry_object.name)
            # flat shading: a clustered mesh's shared vertex normals would smear its shading
            rgba = np.clip(np.asarray(geometry_object.meshColor, dtype=float), 0.0, 1.0)
            color = int(rgba[0] * 255) * 65536 + int(rgba[1] * 255) * 256 + int(rgba[2] * 255)
            material = mg.MeshPhongMaterial(color=color, opacity=float(rgba[3]),
                                            flatShading=True)
            return mg.Mesh(mg.TriangularMeshGeometry(vertices, faces), material)

        def shape_scale(self, geometry_object) -> np.ndarray | None:
            """The static scale of the shape node, or None (primitives, coarsened meshes)."""
            if geometry_object.name in self._prescaled or not hasMeshFileInfo(geometry_object):
                return None
            return np.asarray(geometry_object.meshScale, dtype=float)

    return _Visualizer


# -------------------------------------------------------------------------- replay


@dataclass(frozen=True)
class ReplayResult:
    """What `replay` produced.

    Attributes:
        html: path of the standalone page, or None.
        html_bytes: its size [bytes], or None.
        url: the live viewer's URL, or None.
        visualizer: the live `meshcat.Visualizer` (keep it alive to keep the server), or None.
        n_frames: animation key frames.
        fps: key frames per second of animation time [1/s].
        duration: physical duration shown [s].
        speed: playback rate [-] (1 = real time).
        scene: the recorded scene (`scene.commands()`: meshcat's msgpack commands,
            `scene.get_scene()`: the standalone page).
    """

    html: Path | None
    html_bytes: int | None
    url: str | None
    visualizer: Any
    n_frames: int
    fps: float
    duration: float
    speed: float
    scene: RecordingWindow

    def close(self) -> None:
        """Stop the live viewer's server process (started by `replay(live=True)`)."""
        if self.visualizer is None:
            return
        window = self.visualizer.window
        window.zmq_socket.close(linger=0)
        if window.server_proc is not None:
            window.server_proc.kill()
            window.server_proc.wait()


def _robot_models(traj: Trajectory, robot):
    """(model, visual_model) from `robot` or, if None, from the trajectory's robot spec."""
    if robot is None:
        if not traj.robot:
            raise InvalidInput(
                "the trajectory has no `robot` entry: pass `robot=(model, visual_model)`"
            )
        from tfcontact.robot import RobotSpec, load_robot  # the layer above; imported on use

        loaded = load_robot(RobotSpec.from_dict(traj.robot))
        return loaded.model, loaded.visual_model
    if isinstance(robot, tuple) and len(robot) == 2:
        return robot
    if hasattr(robot, "model") and hasattr(robot, "visual_model"):
        return robot.model, robot.visual_model
    raise InvalidInput(
        "`robot` must be None, a (model, visual_model) pair or an object with `.model` and "
        f"`.visual_model`, got {type(robot).__name__}"
    )


def _contacts(traj: Trajectory, model) -> list[tuple[int, float]]:
    """(frame id, radius) per contact, from `traj.robot['contacts']`."""
    specs = traj.robot.get("contacts", [])
    out = []
    for spec in specs:
        if isinstance(spec, dict):
            name, radius = spec.get("frame"), float(spec.get("radius", 0.0))
        else:
            name, radius = spec[0], float(spec[1])
        if not model.existFrame(name):
            from tfcontact.errors import FrameNotFound

            raise FrameNotFound(name, [f.name for f in model.frames])
        out.append((model.getFrameId(name), radius))
    if out and len(out) != traj.n_contacts:
        raise InvalidInput(
            f"`robot['contacts']` names {len(out)} frames but the trajectory has "
            f"{traj.n_contacts} contact columns"
        )
    return out


def ground_boxes(scene: dict, center_xy: np.ndarray, size: float) -> list[DrawnBox]:
    """Boxes drawing the scene's terrain over a square of side `size` [m] at `center_xy`.

    Reads `scene['terrain']`: flat ground {"type": "flat", "height", "normal"} (default:
    flat at 0), none ({"type": "none"}) or a `tfcontact.robot.Terrain.to_dict()` (planes,
    sloped ones tilted; boxes; holes as gaps in the ground, with their floors), see
    `tfcontact.viz.terrain_view`; and the optional `scene['boxes']`:
    [{"center": [x, y, z], "size": [lx, ly, lz]}, ...].

    Raises:
        InvalidInput: a terrain that cannot be drawn (`scene_terrain`).
    """
    terrain = scene_terrain(scene)
    boxes = [] if terrain is None else terrain_boxes(terrain, center_xy, size)
    for box in scene.get("boxes", []):
        boxes.append(DrawnBox(tuple(box["center"]), tuple(box["size"]), np.eye(3), "box"))
    return boxes


def hole_meshes(scene: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    """Triangle meshes (vertices (k, 3), faces (m, 3)) drawing the scene's holes.

    Reads the optional `scene['holes']`: [{"profile": [[x, z], ...], ...}, ...], each a
    convex polygon in the x-z plane (world coordinates, at least 3 points in order) that
    a foot's centre must stay out of, as the scene that wrote it states it (e.g.
    `tfcontact.scenes.monoped.hole_profile`); each is extruded across y in
    +-HOLE_WIDTH / 2. A hole without a profile (sidecars written before profiles were
    stored) is not drawn.

    Raises:
        InvalidInput: a profile that is not at least 3 finite (x, z) points.
    """
    meshes = []
    for hole in scene.get("holes", []):
        if not isinstance(hole, dict) or "profile" not in hole:
            continue
        try:
            profile = np.asarray(hole["profile"], dtype=float)
        except (TypeError, ValueError) as err:
            raise InvalidInput(
                f"a hole needs a `profile` of (x, z) points, got {hole!r}") from err
        shaped = profile.ndim == 2 and profile.shape[0] >= 3 and profile.shape[1] == 2
        if not (shaped and np.all(np.isfinite(profile))):
            raise InvalidInput(f"a hole's `profile` must be 3 or more finite (x, z) points, "
                               f"got shape {profile.shape}")
        k = len(profile)
        vertices = np.vstack([np.column_stack([profile[:, 0], np.full(k, y), profile[:, 1]])
                              for y in (-HOLE_WIDTH / 2, HOLE_WIDTH / 2)])
        nxt = (np.arange(k) + 1) % k
        sides = ([(i, nxt[i], k + nxt[i]) for i in range(k)]
                 + [(i, k + nxt[i], k + i) for i in range(k)])
        caps = ([(0, i, i + 1) for i in range(1, k - 1)]  # fans: the profiles are convex
                + [(k, k + i + 1, k + i) for i in range(1, k - 1)])
        meshes.append((vertices, np.array(sides + caps, dtype=np.int64)))
    return meshes


def _interp_index(t: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left index i and weight w in [0, 1] of each time in `times` on the grid `t`.

    At an instantaneous jump (t[i] == t[i+1]) the later sample wins.
    """
    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.size - 2)
    span = t[i + 1] - t[i]
    w = np.ones_like(times)
    np.divide(times - t[i], span, out=w, where=span > 0)
    return i, np.clip(w, 0.0, 1.0)


def replay(
    trajectory: Trajectory | str | os.PathLike,
    *,
    html: str | os.PathLike | None = None,
    live: bool = False,
    speed: float = 1.0,
    fps: float = 30.0,
    robot=None,
    forces: bool = False,
    contact_tol: float = 1e-3,
    mesh_detail: float | None = 0.03,
    max_frames: int = 3000,
    compress: bool = True,
    rate_tol: float | None = None,
) -> ReplayResult:
    """Animate a trajectory in meshcat, in physical time.

    Main arguments:
        trajectory: a `Trajectory` or the path of a saved one.
        html: write a standalone page here (plays offline, no server).
        live: start meshcat's local server on 127.0.0.1 and send the scene to it (the URL
            is printed and returned; the server lives as long as this Python process).
        speed: playback rate [-]: 1 is real time, 0.25 four times slower (slow motion).
        fps: animation key frames per second of playback [1/s]; the browser interpolates
            between key frames.

    Other arguments:
        robot: (model, visual_model), or an object with `.model` / `.visual_model` (e.g.
            `tfcontact.robot.load_robot(...)`); None rebuilds it from `trajectory.robot`.
        forces: draw the contact forces as arrows (longest = 0.3 m).
        contact_tol: a contact counts as closed (green) when its gap is <= this [m].
        mesh_detail: re-mesh mesh files by vertex clustering on cells of this fraction of
            each mesh's bounding-box diagonal [-], drawn flat-shaded in the URDF colour
            (meshes are read by coal, as Pinocchio reads them); None sends the files as
            they are (textures and Collada materials kept, but three.js's Collada loader
            may place a DAE differently from Pinocchio: ur5's base, for one).
        max_frames: key frames at most; `fps` is lowered to fit.
        compress: gzip the page's scripts (about 3 times smaller; unpacked by the browser's
            DecompressionStream: Chromium 80, Firefox 113, Safari 16.4 or later); False
            writes them as plain text, as meshcat's own static page does.
        rate_tol: clock-rate tolerance for dropping frozen pieces (see `physical_time`);
            default the trajectory's own `frozen_rate_tol`.

    Returns:
        A `ReplayResult`.

    Raises:
        InvalidInput: bad arguments, or neither `html` nor `live` asked for.
        TrajectoryFileError: `trajectory` is a path to a damaged file.
    """
    import meshcat
    import meshcat.geometry as mg
    from meshcat.animation import Animation

    if not isinstance(trajectory, Trajectory):
        trajectory = load_trajectory(trajectory)
    if html is None and not live:
        raise InvalidInput("`replay` needs `html=<path>` or `live=True` (or both)")
    if not (math.isfinite(speed) and speed > 0):
        raise InvalidInput(f"`speed` must be > 0 (1 = real time), got {speed!r}")
    if not (math.isfinite(fps) and fps > 0):
        raise InvalidInput(f"`fps` must be > 0 [1/s], got {fps!r}")
    if mesh_detail is not None and not (0 < mesh_detail < 1):
        raise InvalidInput(f"`mesh_detail` must be in (0, 1) or None, got {mesh_detail!r}")
    if int(max_frames) < 2:
        raise InvalidInput(f"`max_frames` must be >= 2, got {max_frames!r}")
    if html is not None and not Path(html).parent.is_dir():
        raise InvalidInput(f"`html`: folder {str(Path(html).parent)!r} does not exist")

    traj = trajectory
    model, visual_model = _robot_models(traj, robot)
    if traj.q.shape[1] != model.nq:
        raise InvalidInput(
            f"the trajectory's q has {traj.q.shape[1]} columns but the robot has nq = "
            f"{model.nq}: wrong robot for this trajectory"
        )
    contacts = _contacts(traj, model)
    phys = physical_time(traj, rate_tol=rate_tol)
    t0, t1 = float(phys.t[0]), float(phys.t[-1])
    duration = t1 - t0
    n_frames = max(2, int(math.ceil(duration / speed * fps - 1e-9)) + 1)
    if n_frames > max_frames:
        n_frames = int(max_frames)
        fps = (n_frames - 1) * speed / duration
    times = np.minimum(t0 + np.arange(n_frames) * speed / fps, t1)

    # scene receivers
    recorder = RecordingWindow(fragment_time_offset=t0, speed=speed, compress=compress,
                               end_time=t1)
    live_vis = None
    window: Any = recorder
    if live:
        live_vis = meshcat.Visualizer()
        window = _TeeWindow(recorder, live_vis.window)
    vis = meshcat.Visualizer(window=window)
    root = vis[ROOT]

    # robot
    Visualizer = _make_visualizer_class()
    pviz = Visualizer(model, visual_model, mesh_detail)
    pviz.initViewer(viewer=vis)
    pviz.loadViewerModel(rootNodeName=f"{ROOT}/robot")
    for g in visual_model.geometryObjects:  # static shape nodes: identity or mesh scale
        scale = pviz.shape_scale(g)
        scale = np.ones(3) if scale is None else scale
        vis[f"{ROOT}/robot/visuals/{g.name}/shape"].set_transform(np.diag([*scale, 1.0]))

    # configurations at the key frames
    i, w = _interp_index(phys.t, times)
    data = model.createData()
    gdata = pin.GeometryData(visual_model)
    placements = np.empty((n_frames, len(visual_model.geometryObjects), 4, 4))
    contact_pos = np.empty((n_frames, len(contacts), 3))
    for f in range(n_frames):
        q = pin.interpolate(model, phys.q[i[f]], phys.q[i[f] + 1], float(w[f]))
        pin.framesForwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, visual_model, gdata)
        for k, placement in enumerate(gdata.oMg):
            placements[f, k] = placement.homogeneous
        for k, (frame_id, _) in enumerate(contacts):
            contact_pos[f, k] = data.oMf[frame_id].translation
    gap = phys.gap[i] * (1 - w[:, None]) + phys.gap[i + 1] * w[:, None]
    force = phys.force[i] * (1 - w[:, None, None]) + phys.force[i + 1] * w[:, None, None]

    # ground and camera from the motion's extent
    # the visual bodies and the contacts: a URDF may have no visual geometry at all
    base = np.concatenate([placements[:, :, :3, 3].reshape(-1, 3), contact_pos.reshape(-1, 3)])
    base = base if base.size else np.zeros((1, 3))
    lo, hi = base.min(axis=0), base.max(axis=0)
    center = (lo + hi) / 2
    extent = float(max(np.max(hi - lo), 0.3))
    for k, box in enumerate(ground_boxes(traj.scene, center[:2], 4 * extent + 1)):
        node = root[f"ground/{k}"]
        node.set_object(mg.Box(box.lengths),
                        mg.MeshLambertMaterial(color=TERRAIN_COLORS[box.role]))
        placement = _translation(box.center)
        placement[:3, :3] = box.rotation
        node.set_transform(placement)
    for k, (vertices, faces) in enumerate(hole_meshes(traj.scene)):
        root[f"holes/{k}"].set_object(
            mg.TriangularMeshGeometry(vertices, faces),
            mg.MeshLambertMaterial(color=HOLE_COLOR, opacity=0.45, transparent=True))
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    # meshcat's orbit controls look at the origin: move the scene so the motion is centred
    # there (the ground and the robot alike, under one root node)
    root.set_transform(_translation(-center))
    dist = 1.0 * extent + 0.35
    # the camera node is y-up (three.js): [x, z, -y] in the world's z-up coordinates
    vis["/Cameras/default/rotated/<object>"].set_property(
        "position", [0.15 * dist, 0.3 * dist, 1.0 * dist])

    # contact markers and force arrows
    for k, (_, radius) in enumerate(contacts):
        r = 1.15 * radius if radius > 0 else 0.02
        root[f"contacts/{k}/on"].set_object(
            mg.Sphere(r), mg.MeshLambertMaterial(color=CONTACT_ON_COLOR))
        root[f"contacts/{k}/off"].set_object(
            mg.Sphere(r), mg.MeshLambertMaterial(color=CONTACT_OFF_COLOR, opacity=0.6,
                                                 transparent=True))
        if forces:
            shaft = root[f"contacts/{k}/force/shaft"]
            shaft.set_object(mg.Cylinder(1.0, 0.006), mg.MeshLambertMaterial(color=FORCE_COLOR))
            shaft.set_transform(_translation((0.0, 0.5, 0.0)))
    f_norm = np.linalg.norm(force, axis=2) if contacts else np.zeros((n_frames, 0))
    force_scale = 0.3 / f_norm.max() if f_norm.size and f_norm.max() > 0 else 0.0

    animation = Animation(default_framerate=fps)
    for f in range(n_frames):
        with animation.at_frame(vis, f) as frame:
            for k, g in enumerate(visual_model.geometryObjects):
                frame[f"{ROOT}/robot/visuals/{g.name}"].set_transform(placements[f, k])
            for k in range(len(contacts)):
                at = _translation(contact_pos[f, k])
                closed = bool(gap[f, k] <= contact_tol)
                for state, shown in (("on", closed), ("off", not closed)):
                    node = frame[f"{ROOT}/contacts/{k}/{state}"]
                    node.set_transform(at)
                    node.set_property("visible", "boolean", shown)
                if forces:
                    node = frame[f"{ROOT}/contacts/{k}/force"]
                    length = float(f_norm[f, k] * force_scale)
                    node.set_transform(_arrow_pose(contact_pos[f, k], force[f, k]))
                    node.set_property("scale", "vector3", [1.0, max(length, 1e-6), 1.0])
                    node.set_property("visible", "boolean", length > 1e-4)
    vis.set_animation(animation, play=True, repetitions=1)

    html_path = html_bytes = None
    if html is not None:
        html_path = Path(html)
        from tfcontact.plan_format.trajectory import atomic_write

        text = vis.static_html()
        data_bytes = text.encode("utf-8")
        atomic_write(html_path, data_bytes)
        html_bytes = len(data_bytes)
    url = None
    if live_vis is not None:
        url = live_vis.url()
        print(f"tfcontact replay: meshcat viewer at {url}")
    return ReplayResult(html=html_path, html_bytes=html_bytes, url=url, visualizer=live_vis,
                        n_frames=n_frames, fps=float(fps), duration=duration, speed=speed,
                        scene=recorder)


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _arrow_pose(p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Placement at `p` whose y axis (a three.js cylinder's axis) points along `f`."""
    T = _translation(p)
    n = np.linalg.norm(f)
    if n > 0:
        T[:3, :3] = pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]), f / n).matrix()
    return T
