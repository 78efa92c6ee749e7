"""The full-collision-model check (`tfcontact.verify.collision`) against closed forms.

Distances are compared with formulas written here (sphere over a plane, a tilted box over
a plane, sphere against box, two spheres), never with coal itself.
"""

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.plan_format.trajectory import Trajectory
from tfcontact.robot import ContactSpec, Ground, load_robot
from tfcontact.verify.collision import (
    CollisionOptions,
    CollisionReport,
    CollisionStatus,
    Obstacle,
    box_obstacle,
    check_collisions,
    check_robot_collisions,
    ground_obstacle,
    halfspace_obstacle,
)
from tfcontact.viz.collision_figure import (
    collision_figure,
    save_collision_figure,
    scene_obstacles,
    trajectory_collisions,
)

INERTIAL = ('<inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" '
            'iyz="0" izz="0.01"/></inertial>')


def _urdf(tmp_path, name, body):
    path = tmp_path / f"{name}.urdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{name}">{body}</robot>\n')
    return path


def _link(name, collision="", origin="0 0 0"):
    col = (f'<collision><origin xyz="{origin}"/><geometry>{collision}</geometry></collision>'
           if collision else "")
    return f'<link name="{name}">{INERTIAL}{col}</link>'


def _joint(name, kind, parent, child, origin="0 0 0", axis="0 0 1"):
    limit = '<limit lower="-10" upper="10" effort="1" velocity="1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{origin}"/><axis xyz="{axis}"/>{limit}</joint>')


# A box 0.2 x 0.1 x 0.06 m on a slider: prismatic z (height), then revolute y (tilt).
BOX = (0.2, 0.1, 0.06)


@pytest.fixture
def tilting_box(tmp_path):
    body = (_link("carriage") + _joint("lift", "prismatic", "carriage", "tilter")
            + _link("tilter") + _joint("tilt", "revolute", "tilter", "slab", axis="0 1 0")
            + _link("slab", f'<box size="{BOX[0]} {BOX[1]} {BOX[2]}"/>'))
    return load_robot(_urdf(tmp_path, "tilting_box", body))


@pytest.fixture
def sphere_slider(tmp_path):
    body = (_link("carriage") + _joint("lift", "prismatic", "carriage", "ball")
            + _link("ball", '<sphere radius="0.05"/>'))
    return load_robot(_urdf(tmp_path, "slider", body))


@pytest.fixture
def leg(tmp_path):
    """A planar (x, z) torso with a knee sphere (r 0.03) at (0.15, -0.2) and a foot sphere
    (r 0.02) at (0, -0.4) below it, both on fixed joints."""
    body = (_link("torso") + _joint("knee_fix", "fixed", "torso", "knee", "0.15 0 -0.2")
            + _link("knee", '<sphere radius="0.03"/>')
            + _joint("foot_fix", "fixed", "torso", "foot", "0 0 -0.4")
            + _link("foot", '<sphere radius="0.02"/>'))
    path = _urdf(tmp_path, "leg", body)
    return path, load_robot(path, base="planar_xz", contacts=(ContactSpec("foot", 0.02),))


@pytest.fixture
def arm(tmp_path):
    """A fixed base sphere (r 0.1 at (0, 0, -0.3)), a shoulder (revolute y at 0) carrying
    a sphere (r 0.08) on the shoulder itself, an elbow (revolute y at (0.5, 0, 0)) carrying a
    tip sphere (r 0.05) at (0.4, 0, 0)."""
    body = (_link("base", '<sphere radius="0.1"/>', origin="0 0 -0.3")
            + _joint("shoulder", "revolute", "base", "upper", axis="0 1 0")
            + _link("upper", '<sphere radius="0.08"/>')
            + _joint("elbow", "revolute", "upper", "fore", origin="0.5 0 0", axis="0 1 0")
            + _link("fore", '<sphere radius="0.05"/>', origin="0.4 0 0"))
    return load_robot(_urdf(tmp_path, "arm", body))


def _sphere_box(p, r, center, size):
    """Signed distance of a sphere (centre p, radius r) to an axis-aligned box."""
    d = np.abs(np.asarray(p) - center) - 0.5 * np.asarray(size)
    outside = np.linalg.norm(np.maximum(d, 0.0))
    return (outside if outside > 0 else float(np.max(d))) - r


# ----------------------------------------------------------------------------- closed forms


def test_sphere_over_plane_is_height_minus_radius(sphere_slider):
    heights = np.array([0.5, 0.2, 0.051, 0.05, 0.03, -0.01])
    report = check_robot_collisions(sphere_slider, np.linspace(0, 1, heights.size),
                                    heights[:, None], [halfspace_obstacle(height=0.0)])
    np.testing.assert_allclose(report.terrain_distance[:, 0], heights - 0.05, atol=1e-12)
    body = report.body("ball")
    assert body.min_distance == pytest.approx(-0.06, abs=1e-12) and body.time == 1.0
    assert not report.passed and report.status is CollisionStatus.PENETRATION
    assert report.worst == ("body 'ball_0' (link 'ball') 60.0 mm through obstacle 'ground' at "
                            "t = 1.000 s")


def test_ground_obstacle_matches_the_contact_ground(sphere_slider):
    # Ground(height=-0.02): the sphere at height z is z - r + 0.02 from it.
    report = check_robot_collisions(sphere_slider, [0.0], [[0.3]],
                                    [ground_obstacle(Ground(height=-0.02))])
    assert report.bodies[0].min_distance == pytest.approx(0.3 - 0.05 + 0.02, abs=1e-12)


def test_tilted_box_over_plane(tilting_box):
    # A box of half sizes (a, b, c) tilted by theta about y reaches a*|sin| + c*|cos| down.
    theta = np.array([0.0, 0.3, -0.7, math.pi / 2, 2.5])
    z = np.array([0.2, 0.1, 0.08, 0.12, 0.05])
    reach = 0.5 * BOX[0] * np.abs(np.sin(theta)) + 0.5 * BOX[2] * np.abs(np.cos(theta))
    report = check_robot_collisions(tilting_box, np.arange(5.0), np.column_stack([z, theta]),
                                    [halfspace_obstacle(height=-0.01)])
    np.testing.assert_allclose(report.terrain_distance[:, 0], z - reach + 0.01, atol=1e-8)


def test_sphere_against_box_obstacle(sphere_slider):
    # The slider's ball at x = 0 over a box whose top is at 0.25: above, touching, inside.
    step = box_obstacle("step", (0.4, 0.4, 0.3), center=(0.1, 0.0, 0.1))
    heights = np.array([0.6, 0.3, 0.27, 0.2])
    report = check_robot_collisions(sphere_slider, np.arange(4.0), heights[:, None], [step])
    expected = [_sphere_box((0, 0, h), 0.05, (0.1, 0.0, 0.1), (0.4, 0.4, 0.3)) for h in heights]
    np.testing.assert_allclose(report.terrain_distance[:, 0], expected, atol=1e-9)
    assert report.bodies[0].obstacle == "step"


# ----------------------------------------------------------------------------- a knee in a step


def _leg_motion():
    """Base (x, z) samples; at t = 0.41 the knee is 4 mm into the step's top."""
    t = np.array([0.0, 0.2, 0.41, 0.6])
    q = np.array([[0.0, 0.42], [0.3, 0.5], [0.7, 0.426], [1.5, 0.6]])
    return t, q


STEP = dict(size=(0.4, 1.0, 0.2), center=(1.0, 0.0, 0.1))


def test_knee_through_a_step_fails_with_body_and_time(leg):
    _, robot = leg
    t, q = _leg_motion()
    obstacles = [halfspace_obstacle("ground"), box_obstacle("step", STEP["size"],
                                                            center=STEP["center"])]
    report = check_robot_collisions(robot, t, q, obstacles)
    assert not report.passed and report.status is CollisionStatus.PENETRATION
    assert report.worst == ("body 'knee_0' (link 'knee') 4.0 mm through obstacle 'step' at "
                            "t = 0.410 s")
    knee = np.array([[x + 0.15, 0.0, z - 0.2] for x, z in q])
    foot = np.array([[x, 0.0, z - 0.4] for x, z in q])
    for name, centres, r in (("knee_0", knee, 0.03), ("foot_0", foot, 0.02)):
        expected = [min(c[2] - r, _sphere_box(c, r, STEP["center"], STEP["size"]))
                    for c in centres]
        j = [b.body for b in report.bodies].index(name)
        np.testing.assert_allclose(report.terrain_distance[:, j], expected, atol=1e-9)
    assert report.body("foot").contact and not report.body("knee").contact
    # the knee also gets the missing-contact hint; the foot (a declared contact) does not
    assert report.hints == ("body 'knee_0' touches obstacle 'step' at t = 0.410 s (distance "
                            "-4.0 mm): declare a contact on it (ContactSpec on frame 'knee') "
                            "or keep it above the terrain (a task's [[bodies]])",)
    assert report.skipped_pairs == (("foot_0", "knee_0", "same joint"),)
    assert "4.0 mm through obstacle 'step'" in report.summary()


def test_declared_contact_touching_the_ground_passes(leg):
    _, robot = leg
    report = check_robot_collisions(robot, [0.0, 0.1], [[0.0, 0.42], [0.1, 0.4205]],
                                    [halfspace_obstacle("ground")])
    assert report.passed and report.status is CollisionStatus.CLEAR and report.hints == ()
    assert report.body("foot_0").min_distance == pytest.approx(0.0, abs=1e-12)
    assert report.worst.startswith("body 'foot_0' (link 'foot') 0.0 mm")


def test_undeclared_body_on_the_ground_names_the_missing_contact(leg):
    _, robot = leg
    q = [[0.0, 0.4205], [0.1, 0.43]]  # the foot 0.5 mm above the ground
    report = check_collisions(robot.model, robot.collision_model, [0.0, 0.1], q,
                              [halfspace_obstacle("ground")])  # no contacts declared
    assert report.passed and report.status is CollisionStatus.UNDECLARED_CONTACT
    assert report.hints == ("body 'foot_0' touches obstacle 'ground' at t = 0.000 s (distance "
                            "+0.5 mm): declare a contact on it (ContactSpec on frame 'foot') "
                            "or keep it above the terrain (a task's [[bodies]])",)
    # ignoring the foot leaves the knee, 0.22 - 0.03 m up
    report = check_collisions(robot.model, robot.collision_model, [0.0, 0.1], q,
                              [halfspace_obstacle("ground")],
                              options=CollisionOptions(ignore_bodies=("foot",)))
    assert [b.body for b in report.bodies] == ["knee_0"]
    assert report.bodies[0].min_distance == pytest.approx(0.4205 - 0.2 - 0.03, abs=1e-12)
    assert report.status is CollisionStatus.CLEAR


def test_substeps_catch_a_body_between_samples(leg):
    _, robot = leg
    thin = [box_obstacle("wall", (0.02, 1.0, 1.0), center=(0.5, 0.0, 0.5))]
    t, q = [0.0, 1.0], [[0.0, 0.6], [1.0, 0.6]]
    assert check_robot_collisions(robot, t, q, thin).passed
    report = check_robot_collisions(robot, t, q, thin, options=CollisionOptions(substeps=10))
    assert report.times.size == 11 and not report.passed
    # At t = 0.5 the foot's centre (x = 0.5) is in the middle of the wall (faces at 0.49
    # and 0.51): d = -(0.01 + 0.02). The knee's centre (x + 0.15) comes within 0.04 of a
    # face at t = 0.3 and 0.4: d = 0.04 - 0.03.
    assert report.body("foot").min_distance == pytest.approx(-0.03, abs=1e-9)
    assert report.body("foot").time == pytest.approx(0.5)
    assert report.body("knee").min_distance == pytest.approx(0.01, abs=1e-9)


def test_a_body_holding_its_contacts_sphere_touches_there_only(tmp_path):
    """finger_edu's lower-link mesh holds its tip: a body on a contact's joint (not at the
    contact frame's place) may touch the terrain inside the contact's sphere. A stick
    (box 0.02 x 0.02 x 0.3 m below its joint, on a planar base) with the contact `tip` at
    its lower end (radius 0.015, above the bottom face's half diagonal 0.0141): standing
    on its tip it is the contact touching; upside down, touching with its top end, it
    gets the hint."""
    body = (_link("stick", '<box size="0.02 0.02 0.3"/>', origin="0 0 -0.15")
            + _joint("tip_fix", "fixed", "stick", "tip", "0 0 -0.3") + _link("tip"))
    robot = load_robot(_urdf(tmp_path, "stick", body), base="planar",
                       contacts=(ContactSpec("tip", 0.015),))
    ground = [halfspace_obstacle("ground")]
    standing = check_robot_collisions(robot, [0.0], [[0.0, 0.3, 0.0]], ground)
    assert standing.status is CollisionStatus.CLEAR and standing.hints == ()
    assert standing.body("stick_0").contact
    assert standing.body("stick_0").min_distance == pytest.approx(0.0, abs=1e-9)
    # without the radius the rule is the frame's place only: the old hint
    names_only = check_collisions(robot.model, robot.collision_model, [0.0],
                                  [[0.0, 0.3, 0.0]], ground, contacts=("tip",))
    assert names_only.status is CollisionStatus.UNDECLARED_CONTACT
    upside_down = check_robot_collisions(robot, [0.0, 0.1], [[0.0, 0.3, 0.0],
                                                             [0.0, 0.0, math.pi]], ground)
    assert upside_down.status is CollisionStatus.UNDECLARED_CONTACT
    assert not upside_down.body("stick_0").contact
    assert upside_down.hints == (
        "body 'stick_0' touches obstacle 'ground' at t = 0.100 s (distance +0.0 mm): declare "
        "a contact on it (ContactSpec on frame 'stick') or keep it above the terrain "
        "(a task's [[bodies]])",)


# ----------------------------------------------------------------------------- self-collision


def _tip(q1, q2):
    """The forearm sphere's centre: a rotation by q about y maps (x, 0, 0) to
    (x cos q, 0, -x sin q)."""
    return np.array([0.5 * np.cos(q1) + 0.4 * np.cos(q1 + q2), 0.0,
                     -(0.5 * np.sin(q1) + 0.4 * np.sin(q1 + q2))])


def test_self_collision_of_a_two_link_arm(arm):
    q = np.array([[0.0, 0.0], [0.6, 1.2], [1.2, 2.0], [0.3, 2.6]])  # the last: 44 mm in
    report = check_robot_collisions(arm, np.arange(4.0), q, [])
    # base-upper and upper-fore are adjacent (parent and child joints): skipped
    assert report.skipped_pairs == (("base_0", "upper_0", "adjacent joints"),
                                    ("upper_0", "fore_0", "adjacent joints"))
    assert [(p.body_a, p.body_b) for p in report.pairs] == [("base_0", "fore_0")]
    expected = [np.linalg.norm(_tip(*qk) - (0, 0, -0.3)) - 0.1 - 0.05 for qk in q]
    np.testing.assert_allclose(report.pair_distance[:, 0], expected, atol=1e-12)
    assert expected[3] < -0.04 and report.pairs[0].time == 3.0 and not report.passed
    assert report.worst == (f"body 'base_0' {-1e3 * expected[3]:.1f} mm into body 'fore_0' "
                            "at t = 3.000 s")
    assert "no obstacles: the terrain was not checked" in report.notes


def test_adjacent_links_are_skipped_unless_asked(arm):
    # The shoulder sphere (r 0.08 at 0) and the base sphere (r 0.1 at z = -0.3) never
    # touch; the forearm folded back over the shoulder overlaps it: adjacent pairs only.
    q = np.array([[0.0, 0.0], [0.0, math.pi - 0.1]])
    assert check_robot_collisions(arm, [0.0, 1.0], q, []).passed
    report = check_robot_collisions(arm, [0.0, 1.0], q, [],
                                    options=CollisionOptions(skip_adjacent=False))
    upper_fore = next(p for p in report.pairs if (p.body_a, p.body_b) == ("upper_0", "fore_0"))
    expected = np.linalg.norm(_tip(0.0, math.pi - 0.1)) - 0.08 - 0.05
    assert upper_fore.min_distance == pytest.approx(expected, abs=1e-12) and expected < 0
    assert not report.passed
    assert report.worst == (f"body 'upper_0' {-1e3 * expected:.1f} mm into body 'fore_0' at "
                            "t = 1.000 s")
    ignored = CollisionOptions(skip_adjacent=False, ignore_pairs=(("upper", "fore_0"),))
    assert check_robot_collisions(arm, [0.0, 1.0], q, [], options=ignored).passed


# ----------------------------------------------------------------------------- trajectories, figure


def _trajectory(path, q, clock, scene):
    n = len(clock)
    return Trajectory(
        tau=np.linspace(0.0, 1.0, n), clock=np.asarray(clock, float), s=np.ones(n),
        q=np.asarray(q, float), v=np.zeros((n, 2)), u=np.zeros((n, 0)),
        gap=np.zeros((n, 1)), normal_velocity=np.zeros((n, 1)),
        robot={"source": str(path), "base": "planar_xz", "locked_joints": [],
               "contacts": [{"frame": "foot", "radius": 0.02}]},
        scene=scene)


def test_trajectory_collisions_from_the_scene(leg, tmp_path):
    path, _ = leg
    t, q = _leg_motion()
    scene = {"terrain": {"type": "flat", "height": 0.0},
             "boxes": [{"center": list(STEP["center"]), "size": list(STEP["size"])}]}
    # a frozen piece (the clock stops between samples 2 and 3) keeps its entry and exit
    traj = _trajectory(path, np.insert(q, 3, q[2], axis=0), np.insert(t, 3, t[2]), scene)
    assert [o.name for o in scene_obstacles(traj)] == ["ground", "box 1"]
    report = trajectory_collisions(traj)
    assert report.worst == ("body 'knee_0' (link 'knee') 4.0 mm through obstacle 'box 1' at "
                            "t = 0.410 s")
    fig = collision_figure(report)
    assert len(fig.axes) == 1 and len(fig.axes[0].lines) >= 2
    out = save_collision_figure(report, tmp_path / "fig" / "collisions.png")
    assert out.stat().st_size > 1000


def test_figure_has_a_self_collision_panel(arm, tmp_path):
    report = check_robot_collisions(arm, [0.0, 1.0], [[0.0, 0.0], [1.0, 2.0]],
                                    [halfspace_obstacle(height=-1.0)])
    fig = collision_figure(report)
    assert len(fig.axes) == 2
    assert save_collision_figure(report, tmp_path / "c.svg").read_text().startswith("<?xml")


# ----------------------------------------------------------------------------- input checks


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"tolerance": -1e-3}, r"`tolerance` must be a non-negative number \[m\], got -0.001"),
    ({"touch_distance": float("nan")}, r"`touch_distance` must be a non-negative number"),
    ({"self_collision": 1}, r"`self_collision` must be True or False, got 1"),
    ({"ignore_bodies": "foot"}, r"`ignore_bodies` must be a sequence of body names, got the "
                                r"string 'foot'; write \('foot',\)"),
    ({"ignore_bodies": ("",)}, r"`ignore_bodies` must hold body names, got ''"),
    ({"ignore_pairs": (("a",),)}, r"`ignore_pairs` must hold pairs of body names, got \('a',\)"),
    ({"substeps": 0}, r"`substeps` must be a positive integer, got 0"),
])
def test_options_are_validated(kwargs, match):
    with pytest.raises(InvalidInput, match=match):
        CollisionOptions(**kwargs)


def test_obstacles_are_validated():
    with pytest.raises(InvalidInput, match=r"`geometry` of obstacle `x` must be a coal shape"):
        Obstacle("x", "box")
    with pytest.raises(InvalidInput, match=r"`name` must be a non-empty string, got ''"):
        Obstacle("", coal.Sphere(1.0))
    with pytest.raises(InvalidInput, match=r"`placement` of obstacle `x` must be a pinocchio.SE3"):
        Obstacle("x", coal.Sphere(1.0), np.eye(4))
    with pytest.raises(InvalidInput, match=r"`size` must hold three side lengths > 0 \[m\]"):
        box_obstacle("step", (0.1, 0.0, 0.1))
    with pytest.raises(InvalidInput, match=r"`rotation` must be a 3x3 rotation matrix"):
        box_obstacle("step", (0.1, 0.1, 0.1), rotation=2 * np.eye(3))
    with pytest.raises(InvalidInput, match=r"`normal` must be a non-zero 3-vector"):
        halfspace_obstacle(normal=(0, 0, 0))
    placement = pin.SE3.Identity()
    obstacle = Obstacle("x", coal.Sphere(1.0), placement)
    placement.translation = np.ones(3)
    assert np.all(obstacle.placement.translation == 0.0)  # an own copy


@pytest.mark.parametrize(("args", "kwargs", "match"), [
    (([0.0, 1.0], [[0.1]]), {}, r"`q` must have shape \(S, nq\) = \(2, 1\), got shape \(1, 1\)"),
    (([[0.0]], [[0.1]]), {}, r"`t` must have shape \(S,\) with S >= 1, got shape \(1, 1\)"),
    (([1.0, 0.0], [[0.1], [0.2]]), {},
     r"`t` must be non-decreasing, got t\[0\] = 1.0 > t\[1\] = 0.0"),
    (([0.0], [[np.nan]]), {}, r"`t` and `q` must be finite"),
    (([0.0], [[0.1]], ["ground"]), {}, r"`obstacles` must hold Obstacle objects, got str"),
    (([0.0], [[0.1]], [halfspace_obstacle(), halfspace_obstacle()]), {},
     r"`obstacles` share a name: \['ground', 'ground'\]"),
    (([0.0], [[0.1]]), {"contacts": ("toe",)},
     r"`contacts` names frame 'toe', which is not in the model"),
    (([0.0], [[0.1]]), {"contacts": "ball"}, r"`contacts` must be a sequence of frame names"),
    (([0.0], [[0.1]]), {"contacts": ("ball",), "contact_radii": (0.05, 0.01)},
     r"`contact_radii` must be one radius >= 0 \[m\] per contact \(1\)"),
    (([0.0], [[0.1]]), {"options": CollisionOptions(ignore_bodies=("knee",))},
     r"`CollisionOptions` names body `knee`, which is not in the collision model; bodies: ball_0"),
    (([0.0], [[0.1]]), {"options": {"tolerance": 1e-3}}, r"`options` must be a CollisionOptions"),
])
def test_inputs_are_validated(sphere_slider, args, kwargs, match):
    if len(args) == 2:
        args = (*args, [halfspace_obstacle()])
    with pytest.raises(InvalidInput, match=match):
        check_collisions(sphere_slider.model, sphere_slider.collision_model, *args, **kwargs)


def test_report_to_dict_is_plain(leg):
    import json

    _, robot = leg
    report = check_robot_collisions(robot, *_leg_motion(), [halfspace_obstacle()])
    assert isinstance(report, CollisionReport)
    data = json.loads(json.dumps(report.to_dict()))
    assert data["status"] == "clear" and data["passed"]
    assert {b["body"] for b in data["bodies"]} == {"knee_0", "foot_0"}


# ----------------------------------------------------------------------------- meshes, order


def _cube_obj(path, half):
    corners = [(x, y, z) for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    faces = [(1, 3, 4), (1, 4, 2), (5, 6, 8), (5, 8, 7), (1, 2, 6), (1, 6, 5),
             (3, 7, 8), (3, 8, 4), (1, 5, 7), (1, 7, 3), (2, 4, 8), (2, 8, 6)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in corners)
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))


def test_a_mesh_body_is_checked_as_its_hull_with_signed_depths(tmp_path):
    # A cube mesh (side 0.1) on the slider: d = z - 0.05, also when sunk 7 cm deep.
    _cube_obj(tmp_path / "cube.obj", 0.05)
    body = (_link("carriage") + _joint("lift", "prismatic", "carriage", "block")
            + _link("block", f'<mesh filename="{tmp_path / "cube.obj"}"/>'))
    robot = load_robot(_urdf(tmp_path, "mesh_slider", body))
    assert isinstance(robot.collision_model.geometryObjects[0].geometry, coal.BVHModelBase)
    heights = np.array([0.3, 0.06, 0.05, 0.0, -0.02])
    report = check_robot_collisions(robot, np.arange(5.0), heights[:, None],
                                    [halfspace_obstacle()])
    np.testing.assert_allclose(report.terrain_distance[:, 0], heights - 0.05, atol=1e-9)
    assert "1 mesh bodies checked as their convex hulls: their distances are lower bounds" \
        in report.notes


def test_distances_do_not_depend_on_the_order_of_the_samples(tilting_box):
    # Deep penetrations of a tilted box into a step (EPA), forwards and backwards.
    step = box_obstacle("step", (0.3, 0.3, 0.2), center=(0.05, 0.0, 0.0))
    z = np.linspace(0.3, -0.1, 9)
    q = np.column_stack([z, np.linspace(0.0, 1.2, 9)])
    forwards = check_robot_collisions(tilting_box, np.arange(9.0), q, [step])
    backwards = check_robot_collisions(tilting_box, np.arange(9.0), q[::-1], [step])
    np.testing.assert_allclose(backwards.terrain_distance[::-1], forwards.terrain_distance,
                               atol=1e-9)
    assert forwards.terrain_distance.min() < -0.1


# ----------------------------------------------------------------------------- terrains

R_PROBE = 0.01  # radius of the probe sphere [m]


def _terrain_distance(obstacles, p):
    """coal's signed distance of a probe sphere centred at p to the nearest obstacle, plus
    the probe's radius: the distance of the point p to the terrain."""
    probe = coal.Sphere(R_PROBE)
    where = coal.Transform3s()
    where.setTranslation(np.asarray(p, dtype=float))
    best = math.inf
    for o in obstacles:
        placed = coal.Transform3s(o.placement.rotation, o.placement.translation)
        d = coal.distance(o.geometry, placed, probe, where, coal.DistanceRequest(),
                          coal.DistanceResult())
        best = min(best, d)
    return best + R_PROBE


def _terrain(*primitives):
    from tfcontact.robot import Terrain

    return Terrain(tuple(primitives))


SLOPE = 0.2  # dz/dx of the sloped plane below
S = math.hypot(1.0, SLOPE)


@pytest.mark.parametrize(("point", "expected"), [
    # z = 0.1 + 0.2 x: distance (z - 0.1 - 0.2 x) / sqrt(1 + 0.2^2)
    ((0.0, 0.0, 0.3), 0.2 / S),
    ((1.0, 0.5, 0.3), 0.0),
    ((-1.0, 0.0, -0.2), (-0.2 - 0.1 + 0.2) / S),
])
def test_terrain_obstacles_sloped_plane(point, expected):
    from tfcontact.robot import Plane
    from tfcontact.verify.collision import terrain_obstacles

    obstacles = terrain_obstacles(_terrain(Plane.sloped(0.1, (SLOPE, 0.0))))
    assert [o.name for o in obstacles] == ["plane[0]"]
    assert _terrain_distance(obstacles, point) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(("point", "expected"), [
    ((1.0, 0.0, 0.3), 0.2),                                 # over the step's top (0.1)
    ((0.3, 0.0, 0.09), 0.09),                               # before it: the ground
    ((0.4, 0.0, 0.2), math.hypot(0.12, 0.12) - 0.02),       # its rounded edge, centre (0.52, 0.08)
    ((0.45, 0.3, 0.05), 0.05),                              # its face (x = 0.5) and the ground
    ((1.0, 0.0, 0.05), -0.05),                              # 5 cm into the top
])
def test_terrain_obstacles_step_with_rounded_edge(point, expected):
    from tfcontact.robot import Box, Plane
    from tfcontact.verify.collision import terrain_obstacles

    obstacles = terrain_obstacles(_terrain(Plane(), Box(x=(0.5, math.inf), top=0.1,
                                                        rounding=0.02)))
    assert [o.name for o in obstacles] == ["plane[0]", "box[1]"]
    assert _terrain_distance(obstacles, point) == pytest.approx(expected, abs=1e-9)


def test_terrain_obstacles_platform_in_3d():
    from tfcontact.robot import Box
    from tfcontact.verify.collision import terrain_obstacles

    obstacles = terrain_obstacles(_terrain(Box(x=(0.0, 1.0), y=(-0.5, 0.5), top=0.1,
                                               rounding=0.0)))
    # a corner of the platform's top: the distance to the point (1, 0.5, 0.1)
    assert _terrain_distance(obstacles, (1.3, 0.9, 0.3)) == \
        pytest.approx(math.sqrt(0.3 ** 2 + 0.4 ** 2 + 0.2 ** 2), abs=1e-9)


@pytest.mark.parametrize(("point", "expected"), [
    ((0.5, 0.0, 0.2), 0.2),
    ((1.25, 0.0, 0.1), math.hypot(0.26, 0.11) - 0.01),  # mid-hole: both rims' arcs
    ((1.25, 0.0, -0.3), 0.25),                          # down the hole: its walls
    ((1.6, 0.0, -0.05), -0.05),                         # in the ground beyond it
])
def test_terrain_obstacles_a_planar_hole(point, expected):
    from tfcontact.robot import Hole, Plane
    from tfcontact.verify.collision import terrain_obstacles

    obstacles = terrain_obstacles(_terrain(Plane(), Hole(x=(1.0, 1.5), rounding=0.01)))
    assert len(obstacles) == 2
    assert _terrain_distance(obstacles, point) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(("point", "expected"), [
    ((1.75, 0.0, 0.05), 0.05),   # on the ground between the holes
    ((2.2, 0.0, -0.25), 0.05),   # over the second hole's floor (-0.3); walls 0.2 away
    ((1.2, 0.0, -0.5), -0.2),    # 0.2 m below the first hole's floor (-0.3)
])
def test_terrain_obstacles_planar_holes_with_floor(point, expected):
    from tfcontact.robot import Hole, Plane
    from tfcontact.verify.collision import terrain_obstacles

    terrain = _terrain(Plane(), Hole(x=(1.0, 1.5), floor=-0.3),
                       Hole(x=(2.0, 2.4), floor=-0.3))
    obstacles = terrain_obstacles(terrain)
    assert [o.name for o in obstacles][-2:] == ["floor of hole[1]", "floor of hole[2]"]
    assert _terrain_distance(obstacles, point) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(("holes", "point", "expected"), [
    # one hole x (1, 2), y (-0.5, 0.5): its rims are 0.5 m from the centre
    (1, (1.5, 0.0, 0.1), math.hypot(0.5, 0.1)),
    (1, (1.5, 0.4, -0.05), 0.1),
    (1, (0.5, 0.0, 0.1), 0.1),
    # and a second one, x (3, 4), y (0, 1)
    (2, (2.5, 0.0, 0.1), 0.1),
    (2, (1.5, 0.0, 0.1), math.hypot(0.5, 0.1)),
    (2, (3.5, 0.5, -0.1), 0.5),
    (2, (3.5, -0.3, 0.2), 0.2),
])
def test_terrain_obstacles_holes_in_3d(holes, point, expected):
    from tfcontact.robot import Hole, Plane
    from tfcontact.verify.collision import terrain_obstacles

    cut = [Hole(x=(1.0, 2.0), y=(-0.5, 0.5)), Hole(x=(3.0, 4.0), y=(0.0, 1.0))][:holes]
    obstacles = terrain_obstacles(_terrain(Plane(), *cut))
    assert _terrain_distance(obstacles, point) == pytest.approx(expected, abs=1e-9)


def test_terrain_obstacles_are_validated():
    from tfcontact.robot import Plane
    from tfcontact.verify.collision import terrain_obstacles

    with pytest.raises(InvalidInput, match="`terrain` must be a tfcontact.robot.Terrain"):
        terrain_obstacles(Ground())
    with pytest.raises(InvalidInput, match=r"`extent` must be a finite number > 0"):
        terrain_obstacles(_terrain(Plane()), extent=0.0)


def test_scene_obstacles_read_a_terrain_of_primitives(leg):
    """A plan's sidecar with `Terrain.to_dict()`: the torso at z = 0.42 puts the foot
    (r 0.02, 0.4 below) on the ground and the knee (r 0.03 at (0.15, -0.2)) over a 10 cm
    step: 0.22 - 0.03 - 0.1 = 9 cm clear of it."""
    from tfcontact.robot import Box, Plane

    path, _ = leg
    terrain = _terrain(Plane(), Box(x=(0.1, math.inf), top=0.1, rounding=0.01))
    t = np.array([0.0, 0.1])
    q = np.array([[0.0, 0.42], [0.0, 0.42]])
    traj = _trajectory(path, q, t, {"terrain": terrain.to_dict()})
    assert [o.name for o in scene_obstacles(traj)] == ["plane[0]", "box[1]"]
    report = trajectory_collisions(traj, options=CollisionOptions(self_collision=False))
    knee = next(b for b in report.bodies if b.body == "knee_0")
    assert knee.min_distance == pytest.approx(0.22 - 0.03 - 0.1, abs=1e-9)
    assert report.passed


def test_a_plan_through_the_terrain_is_not_a_success(leg, tmp_path, monkeypatch):
    """`run_plan`: a plan marked converged and verified whose knee goes 4 mm through a
    step ends with status "collision", exit code 1's success False, the body and time in
    its summary and summary.json."""
    import json

    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import Plan, PlanOutcome, Stage
    from tfcontact.scenes.plans import COLLISION

    class Given(Stage):  # a stage whose outcome is given
        name = "given"

        def __init__(self, solve):
            self.solve = solve

        def run(self, given):
            return self.solve()

    path, robot = leg
    t, q = _leg_motion()
    scene = {"terrain": {"type": "flat", "height": 0.0},
             "boxes": [{"center": list(STEP["center"]), "size": list(STEP["size"])}]}

    def solve():
        return PlanOutcome(_trajectory(path, q, t, scene), robot, "converged", True,
                           "verification PASSED")

    monkeypatch.setitem(plans.PLANS, "leg", Plan("leg", "a leg", ("only",), (Given(solve),)))
    report = plans.run_plan("leg", tmp_path / "out", verbose=False)
    assert (report.success, report.status) == (False, COLLISION)
    assert "knee_0" in report.summary and "t = 0.410 s" in report.summary
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "collision" and summary["collisions"]["passed"] is False

    clear = {"terrain": {"type": "flat", "height": 0.0}}  # no step: the same motion is fine

    def solve_clear():
        return PlanOutcome(_trajectory(path, q, t, clear), robot, "converged", True, "ok")

    monkeypatch.setitem(plans.PLANS, "leg", Plan("leg", "a leg", ("only",),
                                                    (Given(solve_clear),)))
    report = plans.run_plan("leg", tmp_path / "clear", verbose=False)
    assert (report.success, report.status) == (True, "converged")

    # A plan that failed already keeps its first cause (measured: the reduced monoped's
    # discovery at IPOPT's cap, its iterate 5 mm in the ground, was reported "collision").
    def solve_failed():
        return PlanOutcome(_trajectory(path, q, t, scene), robot, "nlp_failed", False,
                           "IPOPT: Maximum_Iterations_Exceeded")

    monkeypatch.setitem(plans.PLANS, "leg", Plan("leg", "a leg", ("only",),
                                                    (Given(solve_failed),)))
    report = plans.run_plan("leg", tmp_path / "failed", verbose=False)
    assert (report.success, report.status) == (False, "nlp_failed")
    assert "Maximum_Iterations_Exceeded" in report.summary and "knee_0" in report.summary
    summary = json.loads((tmp_path / "failed" / "summary.json").read_text())
    assert summary["status"] == "nlp_failed" and summary["collisions"]["passed"] is False


def _l_bracket_obj(path):
    """Two overlapping closed boxes as one mesh, an L in the x-z plane: a bottom bar
    [0, 0.2] x [-0.05, 0.05] x [0, 0.02] and an upright [0, 0.02] x [-0.05, 0.05] x
    [0, 0.2]. Its convex hull fills the notch between them."""
    lines, faces = [], [(1, 3, 4), (1, 4, 2), (5, 6, 8), (5, 8, 7), (1, 2, 6), (1, 6, 5),
                        (3, 7, 8), (3, 8, 4), (1, 5, 7), (1, 7, 3), (2, 4, 8), (2, 8, 6)]
    for k, (x, z) in enumerate(((0.2, 0.02), (0.02, 0.2))):
        lines += [f"v {a} {b} {c}\n" for a in (0.0, x) for b in (-0.05, 0.05) for c in (0.0, z)]
        lines += [f"f {a + 8 * k} {b + 8 * k} {c + 8 * k}\n" for a, b, c in faces]
    path.write_text("".join(lines))


def test_hulls_that_overlap_are_no_collision_when_the_meshes_stay_apart(tmp_path):
    # A ball (r 0.02) on an x-z slider in the notch of an L-shaped mesh: 5 cm from both of
    # its bars, deep inside its hull. Then 1 cm above the bottom bar's top: through it.
    _l_bracket_obj(tmp_path / "bracket.obj")
    body = (_link("base", f'<mesh filename="{tmp_path / "bracket.obj"}"/>')
            + _joint("slide_x", "prismatic", "base", "carriage", axis="1 0 0")
            + _link("carriage")
            + _joint("slide_z", "prismatic", "carriage", "ball", axis="0 0 1")
            + _link("ball", '<sphere radius="0.02"/>'))
    robot = load_robot(_urdf(tmp_path, "bracket", body))
    in_notch = check_robot_collisions(robot, [0.0], np.array([[0.07, 0.07]]), [])
    pair = in_notch.pairs[0]
    assert (pair.body_a, pair.body_b) == ("base_0", "ball_0")
    # out of the hull by its nearer face: x + z = 0.22 (through (0.2, 0, 0.02) and
    # (0.02, 0, 0.2)) or y = +-0.05
    depth = min((0.22 - 0.14) / math.sqrt(2), 0.05) + 0.02
    assert pair.min_distance == pytest.approx(-depth, abs=1e-6)
    assert pair.meshes_apart and in_notch.passed
    assert any("meshes do not intersect" in note and "'base_0' and 'ball_0'" in note
               for note in in_notch.notes)
    through = check_robot_collisions(robot, [0.0, 1.0], np.array([[0.07, 0.07],
                                                                [0.07, 0.03]]), [])
    assert not through.pairs[0].meshes_apart and not through.passed
    # a ball (r 5 mm) wholly inside the bottom bar crosses no surface: still a collision
    small = load_robot(_urdf(tmp_path, "bracket_small", body.replace(
        '<sphere radius="0.02"/>', '<sphere radius="0.005"/>')))
    inside = check_robot_collisions(small, [0.0], np.array([[0.1, 0.01]]), [])
    assert not inside.pairs[0].meshes_apart and not inside.passed
    beside = check_robot_collisions(small, [0.0], np.array([[0.1, 0.05]]), [])
    assert beside.pairs[0].meshes_apart and beside.passed
