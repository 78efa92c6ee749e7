"""Tests of tfcontact.viz.terrain_view: the scene's terrain as drawn boxes and sections."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.robot import Box, Hole, Plane, Terrain
from tfcontact.viz.terrain_view import (
    BOTTOMLESS_DEPTH,
    SLAB,
    scene_terrain,
    surface_normals,
    terrain_boxes,
    terrain_section,
)


def _extent(box, axis: int) -> tuple[float, float]:
    return box.center[axis] - box.lengths[axis] / 2, box.center[axis] + box.lengths[axis] / 2


def test_flat_ground_is_the_slab_drawn_before():
    boxes = terrain_boxes(scene_terrain({}), (0.3, -0.1), 4.0)
    assert len(boxes) == 1
    (box,) = boxes
    assert box.center == pytest.approx((0.3, -0.1, -SLAB / 2))
    assert box.lengths == pytest.approx((4.0, 4.0, SLAB))
    assert np.array_equal(box.rotation, np.eye(3)) and box.role == "ground"
    raised = scene_terrain({"terrain": {"type": "flat", "height": 0.25}})
    assert terrain_boxes(raised, (0, 0), 1.0)[0].center[2] == pytest.approx(0.25 - SLAB / 2)


def test_flat_ground_with_a_normal_is_the_grounds_plane():
    # tfcontact.robot.Ground: n . p >= h; the plane crosses the z axis at h / n_z
    n = np.array([-0.3, 0.0, 1.0]) / math.hypot(0.3, 1.0)
    terrain = scene_terrain({"terrain": {"type": "flat", "height": 0.1, "normal": list(n)}})
    assert terrain.height_at(0.0) == pytest.approx(0.1 / n[2])
    assert terrain.height_at(1.0) == pytest.approx(0.1 / n[2] + 0.3)


def test_sloped_plane_is_a_tilted_slab_whose_top_is_the_plane():
    plane = Plane.sloped(0.1, (0.3, 0.0))
    (box,) = terrain_boxes(Terrain((plane,)), (0.5, 0.0), 2.0)
    n = np.asarray(plane.normal)
    assert box.rotation[:, 2] == pytest.approx(n)
    assert box.rotation.T @ box.rotation == pytest.approx(np.eye(3))
    top = np.asarray(box.center) + n * SLAB / 2
    assert top[2] == pytest.approx(plane.height_at(top[0], top[1]))
    # the tilted slab still spans the square along x
    assert box.lengths[0] * box.rotation[0, 0] >= 2.0


def test_a_ditch_is_a_gap_in_the_ground():
    terrain = Terrain((Plane(height=0.1), Hole(x=(0.2, 0.5))))
    boxes = terrain_boxes(terrain, (0.0, 0.0), 2.0)
    assert {b.role for b in boxes} == {"ground"}
    spans = sorted(_extent(b, 0) for b in boxes)
    assert spans == [pytest.approx((-1.0, 0.2)), pytest.approx((0.5, 1.0))]
    for b in boxes:
        assert _extent(b, 1) == pytest.approx((-1.0, 1.0))
        assert _extent(b, 2) == pytest.approx((0.1 - BOTTOMLESS_DEPTH - SLAB, 0.1))


def test_a_pit_with_a_floor_leaves_its_footprint_open():
    hole = Hole(x=(0.2, 0.4), y=(-0.1, 0.3), floor=-0.15)
    boxes = terrain_boxes(Terrain((Plane(), hole)), (0.0, 0.0), 2.0)
    ground = [b for b in boxes if b.role == "ground"]
    (floor,) = [b for b in boxes if b.role == "floor"]
    assert _extent(floor, 0) == pytest.approx((0.2, 0.4))
    assert _extent(floor, 1) == pytest.approx((-0.1, 0.3))
    assert _extent(floor, 2)[1] == pytest.approx(-0.15)
    # the ground's area is the square minus the footprint, and no box covers the pit
    area = sum(b.lengths[0] * b.lengths[1] for b in ground)
    assert area == pytest.approx(4.0 - 0.2 * 0.4)
    for b in ground:
        (x0, x1), (y0, y1) = _extent(b, 0), _extent(b, 1)
        assert x1 <= 0.2 + 1e-12 or x0 >= 0.4 - 1e-12 or y1 <= -0.1 + 1e-12 or y0 >= 0.3 - 1e-12
        assert _extent(b, 2)[0] == pytest.approx(-0.15 - SLAB)


def test_a_step_reaches_down_to_the_ground_and_is_cut_to_the_square():
    terrain = Terrain((Plane(), Box(x=(0.5, math.inf), top=0.05), Box(x=(9.0, 10.0), top=1.0)))
    boxes = terrain_boxes(terrain, (0.0, 0.0), 2.0)
    (step,) = [b for b in boxes if b.role == "box"]  # the far box is outside the square
    assert _extent(step, 0) == pytest.approx((0.5, 1.0))
    assert _extent(step, 2) == pytest.approx((-SLAB, 0.05))


def test_section_and_normals():
    terrain = Terrain((Plane(), Hole(x=(0.2, 0.3)), Hole(x=(0.6, 0.7), floor=-0.1),
                       Box(x=(1.0, 1.5), top=0.2)))
    z = terrain_section(terrain, np.array([0.0, 0.25, 0.65, 1.2]))
    assert z[0] == 0.0 and math.isnan(z[1]) and z[2] == -0.1 and z[3] == 0.2
    normals = surface_normals(terrain, np.array([[1.25, 0.0, 0.3], [0.0, 0.0, 0.1]]))
    assert normals == pytest.approx(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]), abs=1e-9)
    wall = surface_normals(terrain, np.array([[0.9, 0.0, 0.1]]))  # beside the box
    assert wall == pytest.approx(np.array([[-1.0, 0.0, 0.0]]), abs=1e-9)


def test_scene_terrain_refuses_what_it_cannot_draw():
    with pytest.raises(InvalidInput, match="of type 'heightmap' cannot be drawn"):
        scene_terrain({"terrain": {"type": "heightmap"}})
    with pytest.raises(InvalidInput, match="n_z > 0"):
        scene_terrain({"terrain": {"type": "flat", "normal": [1.0, 0.0, 0.0]}})
