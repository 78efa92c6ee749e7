"""Tests of the replay page's own controls and of the terrain drawn by the replay
(tfcontact.viz.meshcat_replay); the browser test of the controls is in test_browser.py."""

from __future__ import annotations

import base64
import dataclasses
import gzip
import html
import re

import numpy as np
import pytest
import umsgpack
from viz_hop import hop_trajectory, hopper_models

from tfcontact.robot import Box, Hole, Plane, Terrain
from tfcontact.viz import replay

# ------------------------------------------------------------------ controls


def _unpacked(text: str) -> str:
    payload = re.search(r'<script id="tfcontact-payload"[^>]*>([^<]*)</script>', text)
    return gzip.decompress(base64.b64decode(payload.group(1))).decode("utf-8")


def _element(text: str, element_id: str) -> dict[str, str]:
    """The attributes of the element with this id (and its text as `_text`)."""
    m = re.search(r"<(\w+)\s([^>]*\bid=\"" + element_id + r"\"[^>]*)>([^<]*)", text)
    assert m, f"no element #{element_id} in the page"
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', m.group(2)))
    return {**attrs, "_tag": m.group(1), "_text": html.unescape(m.group(3))}


@pytest.mark.parametrize("compress", [True, False], ids=["compressed", "plain"])
def test_page_shows_play_pause_slider_and_physical_time(tmp_path, compress):
    """The controls are plain markup of the page (not in meshcat's menus), the slider
    spans the physical time of the motion, and the replay script wires them to meshcat's
    animator."""
    traj = hop_trajectory()
    shifted = dataclasses.replace(traj, clock=traj.clock + 2.0)  # physical t in [2, 3]
    page = tmp_path / "hop.html"
    replay(shifted, html=page, robot=hopper_models(), speed=0.5, compress=compress)
    text = page.read_text(encoding="utf-8")
    button = _element(text, "tfcontact-play")
    slider = _element(text, "tfcontact-time")
    readout = _element(text, "tfcontact-readout")
    assert button["_tag"] == "button" and button["_text"] in ("play", "pause")
    assert slider["_tag"] == "input" and slider["type"] == "range"
    assert (float(slider["min"]), float(slider["max"])) == pytest.approx((2.0, 3.0))
    assert readout["_tag"] == "output" and readout["_text"] == "t = 2.000 s"
    # the markup comes before any script, so it shows without unpacking or menus
    assert text.index('id="tfcontact-controls"') < text.index("<script")
    scripts = _unpacked(text) if compress else text
    for wiring in ('getElementById("tfcontact-time")', "animator.seek(a)", "animator.play()",
                   "animator.pause()", "t0: 2.0", "t1: 3.0", "speed: 0.5"):
        assert wiring in scripts, wiring


# ------------------------------------------------------------------ terrain


def _ground(result) -> list[tuple[dict, np.ndarray]]:
    """(BoxGeometry, 4 x 4 world placement) of every drawn terrain box (under the scene's
    root node, which only moves the whole scene to the camera's target)."""
    commands = [umsgpack.unpackb(c) for c in result.scene.commands()]
    objects = {c["path"]: c["object"]["geometries"][0] for c in commands
               if c["type"] == "set_object" and "/ground/" in c["path"]}
    placements = {c["path"]: np.array(c["matrix"]).reshape(4, 4).T for c in commands
                  if c["type"] == "set_transform" and c["path"] in objects}
    return [(objects[p], placements[p]) for p in sorted(objects)]


def _replayed(tmp_path, terrain: dict):
    traj = dataclasses.replace(hop_trajectory(), scene={"terrain": terrain})
    return _ground(replay(traj, robot=hopper_models(), html=tmp_path / "t.html", fps=5.0))


def _top(geometry: dict, placement: np.ndarray) -> float:
    return float(placement[2, 3] + geometry["depth"] / 2)


def test_flat_ground_looks_as_before(tmp_path):
    (ground,) = _replayed(tmp_path, {"type": "flat", "height": 0.0})
    geometry, placement = ground
    assert geometry["type"] == "BoxGeometry" and geometry["depth"] == pytest.approx(0.02)
    assert geometry["width"] == geometry["height"]  # a square slab
    np.testing.assert_array_equal(placement[:3, :3], np.eye(3))
    assert _top(geometry, placement) == pytest.approx(0.0)


def test_replay_draws_a_step_and_a_pit(tmp_path):
    terrain = Terrain((Plane(), Box(x=(0.6, 0.9), top=0.05), Hole(x=(0.2, 0.3), floor=-0.1)))
    drawn = _replayed(tmp_path, terrain.to_dict())
    tops = sorted(round(_top(g, p), 9) for g, p in drawn)
    assert tops.count(0.05) == 1 and tops.count(-0.1) == 1 and tops.count(0.0) == 2
    (step,) = [(g, p) for g, p in drawn if round(_top(g, p), 9) == 0.05]
    assert step[1][0, 3] - step[0]["width"] / 2 == pytest.approx(0.6)
    assert step[1][0, 3] + step[0]["width"] / 2 == pytest.approx(0.9)
    # the two ground pieces leave the pit's footprint open
    grounds = sorted((p[0, 3] - g["width"] / 2, p[0, 3] + g["width"] / 2)
                     for g, p in drawn if round(_top(g, p), 9) == 0.0)
    assert grounds[0][1] == pytest.approx(0.2) and grounds[1][0] == pytest.approx(0.3)


def test_replay_tilts_a_sloped_plane(tmp_path):
    plane = Plane.sloped(0.0, (0.25, 0.0))
    ((geometry, placement),) = _replayed(tmp_path, Terrain((plane,)).to_dict())
    normal = np.asarray(plane.normal)
    np.testing.assert_allclose(placement[:3, 2], normal, atol=1e-12)
    top = placement[:3, 3] + normal * geometry["depth"] / 2
    assert top[2] == pytest.approx(plane.height_at(top[0], top[1]))


def test_a_scene_of_boxes_only_has_no_ground(tmp_path):
    walls = [{"center": [0.5, 0.0, -0.1], "size": [1.5, 0.3, 0.05]},
             {"center": [1.2, 0.0, 0.3], "size": [0.05, 0.3, 0.8]}]
    traj = dataclasses.replace(hop_trajectory(), scene={"terrain": {"type": "none"},
                                                        "boxes": walls})
    drawn = _ground(replay(traj, robot=hopper_models(), html=tmp_path / "b.html", fps=5.0))
    assert [(g["width"], g["height"], g["depth"]) for g, _ in drawn] == [
        pytest.approx(w["size"]) for w in walls]
    assert [list(p[:3, 3]) for _, p in drawn] == [pytest.approx(w["center"]) for w in walls]
