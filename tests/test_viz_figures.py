"""Tests of tfcontact.viz.figures and tfcontact.viz.labels: names with units, force and
path figures, read back from the matplotlib figures themselves."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from viz_hop import hop_trajectory, hopper_models, project_hop_trajectory

from tfcontact.plan_format import Trajectory
from tfcontact.robot import Box, Hole, Plane, Terrain
from tfcontact.viz.figures import force_figure_names, robot_model, trajectory_figures
from tfcontact.viz.labels import trajectory_labels

MODEL = {
    "urdf": {"locate": "path", "name": "knee.urdf", "sha256": "0" * 64},
    "base": "planar_xz", "base_meaning": "x, z", "gravity": [0.0, 0.0, -9.81],
    "coordinates": [{"name": "x", "unit": "m", "joint": "root_joint"},
                    {"name": "knee", "unit": "rad", "joint": "knee"}],
    "velocities": [{"name": "v_x", "unit": "m/s", "joint": "root_joint"},
                   {"name": "v_knee", "unit": "rad/s", "joint": "knee"}],
    "controls": [{"name": "u_knee", "unit": "N m", "joint": "knee", "drives": []}],
}


def _small(**changes) -> Trajectory:
    n = 6
    tau = np.linspace(0.0, 1.0, n)
    args = dict(
        tau=tau, clock=tau, s=np.ones(n), q=np.zeros((n, 2)), v=np.zeros((n, 2)),
        u=np.zeros((n, 1)), gap=np.ones((n, 1)), normal_velocity=np.zeros((n, 1)),
        robot={"source": "robots/missing.urdf", "base": "fixed", "locked_joints": [],
               "contacts": [{"frame": "foot", "radius": 0.02}]},
    )
    args.update(changes)
    return Trajectory(**args)


def _legend(ax) -> list[str]:
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


def _line(ax, label: str):
    lines = [line for line in ax.get_lines() if line.get_label() == label]
    assert len(lines) == 1, [line.get_label() for line in ax.get_lines()]
    return lines[0]


# ------------------------------------------------------------------ names and units


def test_states_name_the_sidecar_coordinates_with_units():
    fig = trajectory_figures(_small(model=MODEL))["states"]
    right = [ax for ax in fig.axes if ax.get_xlabel() == "t [s]" or ax.get_legend()]
    legends = [_legend(ax) for ax in right if _legend(ax)]
    assert legends == [["x [m]", "knee [rad]"], ["v_x [m/s]", "v_knee [rad/s]"],
                       ["u_knee [N m]"]]
    assert [ax.get_ylabel() for ax in fig.axes[::2]] == [
        "configuration q [m, rad]", "velocity v [m/s, rad/s]", "control u [N m]"]


def test_labels_from_the_robot_without_a_sidecar_model():
    hop = project_hop_trajectory()  # planar base + the project hopper's leg joint
    labels = trajectory_labels(hop, robot_model(hop))
    assert labels.source == "robot"
    assert labels.q == ("x [m]", "z [m]", "pitch [rad]", "leg_joint [m]")
    assert labels.v == ("v_x [m/s]", "v_z [m/s]", "v_pitch [rad/s]", "v_leg_joint [m/s]")
    assert labels.contacts == ("foot",)
    model, _ = hopper_models()  # a fixed base: the URDF's own joints
    assert trajectory_labels(hop_trajectory(), model).q == (
        "base_x [m]", "base_z [m]", "base_pitch [rad]", "hip [rad]", "leg [m]")


def test_labels_fall_back_to_indices():
    traj = _small()
    assert robot_model(traj) is None  # its URDF does not exist
    labels = trajectory_labels(traj)
    assert (labels.q, labels.v, labels.u, labels.source) == (
        ("q[0]", "q[1]"), ("v[0]", "v[1]"), ("u[0]",), "index")
    fig = trajectory_figures(traj)["contacts"]
    assert ["gap foot"] in [_legend(ax) for ax in fig.axes]


def test_force_figure_names():
    assert force_figure_names(["foot", "foot", "left toe/1", "***"]) == [
        "force_foot", "force_foot_1", "force_left_toe_1", "force_3"]


# ------------------------------------------------------------------ contact forces


def _stance_force(traj: Trajectory, force: np.ndarray) -> Trajectory:
    """`traj` with the world force `force` [N] on its stance samples (0.4 < t < 0.6)."""
    forces = np.zeros_like(traj.force)
    stance = (traj.clock > 0.4) & (traj.clock < 0.6)
    forces[stance, 0] = force
    return dataclasses.replace(traj, force=forces)


SLOPE = 0.2  # dz/dx of the sloped ground


@pytest.mark.parametrize("scene", [
    {"terrain": {"type": "flat", "height": 0.0, "normal": [-SLOPE, 0.0, 1.0]}},
    {"terrain": Terrain((Plane.sloped(0.0, (SLOPE, 0.0), friction=0.5),)).to_dict()},
], ids=["flat-dict", "terrain"])
def test_force_figure_splits_along_the_slope(scene):
    n = np.array([-SLOPE, 0.0, 1.0]) / math.hypot(SLOPE, 1.0)
    t1 = np.array([1.0, 0.0, SLOPE]) / math.hypot(SLOPE, 1.0)
    world = 50.0 * n + 10.0 * t1
    traj = dataclasses.replace(_stance_force(project_hop_trajectory(), world), scene=scene)
    fig = trajectory_figures(traj)["force_foot"]
    ax = fig.axes[0]
    normal = _line(ax, "normal $f_n$ [N]").get_ydata()
    tangential = _line(ax, "tangential $f_{t1}$ [N]").get_ydata()
    assert normal.max() == pytest.approx(50.0) and normal.min() == pytest.approx(0.0, abs=1e-12)
    assert tangential.max() == pytest.approx(10.0)
    assert "tangential $f_{t2}$ [N]" not in _legend(ax)  # planar: no second tangent
    cone = [line for line in ax.get_lines() if line.get_label() == r"cone $\pm\mu f_n$"]
    if scene["terrain"].get("kind") == "terrain":  # the terrain's friction 0.5
        assert np.nanmax(cone[0].get_ydata()) == pytest.approx(25.0)
    else:
        assert cone == []


def test_force_figure_shows_the_impulse_at_its_time():
    hop = hop_trajectory()  # impulse 11.4 N s along z at the touchdown, t = 0.4
    fig = trajectory_figures(hop)["force_shin"]
    marker = _line(fig.axes[1], r"normal $\Lambda_n$ [N s]")
    assert marker.get_xdata() == pytest.approx([0.4])
    assert marker.get_ydata() == pytest.approx([11.4])
    assert _line(fig.axes[1], r"tangential $\Lambda_{t1}$ [N s]").get_ydata() == \
        pytest.approx([0.0])


# ------------------------------------------------------------- contact diagram


def test_stance_intervals_of_two_feet_in_turn():
    """Front foot down over [0, 0.2] and [0.6, 0.8] s, hind foot over [0.3, 0.5] and at
    1 s alone (a touch seen at one sample); 1 mm of gap still counts as touching."""
    from tfcontact.errors import InvalidInput
    from tfcontact.plan_format import stance_intervals

    t = np.linspace(0.0, 1.0, 11)
    front = np.array([0, 1e-3, 0, .02, .05, .02, 0, 0, 0, .01, .02])
    hind = np.array([.02, .02, .03, 0, 0, 0, .01, .02, .03, .02, 0])
    front_down, hind_down = stance_intervals(t, np.column_stack([front, hind]))
    np.testing.assert_allclose(front_down, [(0.0, 0.2), (0.6, 0.8)])
    np.testing.assert_allclose(hind_down, [(0.3, 0.5), (1.0, 1.0)])
    assert stance_intervals(t, np.full((11, 1), 0.1)) == ((),)
    with pytest.raises(InvalidInput, match="`touch` must be a finite gap >= 0"):
        stance_intervals(t, front, touch=-1.0)


def test_contact_diagram_shows_the_hops_stance():
    """The hop takes off at t = 0, stands in 0.4 < t < 0.6 and lands at T = 1: three bars,
    the instants drawn as slivers."""
    hop = project_hop_trajectory()
    ax = trajectory_figures(hop)["contact_diagram"].axes[0]
    (bars,) = ax.collections
    spans = [(p.vertices[:, 0].min(), p.vertices[:, 0].max()) for p in bars.get_paths()]
    np.testing.assert_allclose(spans, [(0.0, 0.002), (0.4, 0.6), (1.0, 1.002)], atol=1e-9)
    assert [label.get_text() for label in ax.get_yticklabels()] == ["foot"]
    fig = ax.figure  # its title within the figure (a longer one was cut at the right)
    title = ax.title.get_window_extent(fig.canvas.get_renderer())
    assert fig.bbox.x0 <= title.x0 and title.x1 <= fig.bbox.x1


# ----------------------------------------------------------------------- path


def _section(fig):
    ax = fig.axes[0]
    line = next(line for line in ax.get_lines() if line.get_color() == "0.35")
    return ax, np.asarray(line.get_xdata()), np.asarray(line.get_ydata())


def test_path_figure_follows_the_foot_over_the_terrain():
    hop = project_hop_trajectory()  # foot radius 0.02 m, on the ground in 0.4 < t < 0.6
    step = Terrain((Plane(), Box(x=(0.6, 0.8), top=0.05)))
    traj = dataclasses.replace(hop, scene={"terrain": step.to_dict()})
    fig = trajectory_figures(traj)["path"]
    ax, x, z = _section(fig)
    foot = _line(ax, "foot (centre)")
    assert np.min(foot.get_ydata()) == pytest.approx(0.02, abs=1e-9)
    assert foot.get_xdata()[0] == pytest.approx(0.0, abs=0.05)
    on_step = (x > 0.6) & (x < 0.8)
    assert np.all(z[on_step] == 0.05) and np.all(z[x < 0.6] == 0.0)
    assert _line(ax, "base (x, z)").get_ydata()[0] == pytest.approx(hop.q[0, 1])


def test_path_figure_draws_a_hole_as_a_gap():
    hole = Terrain((Plane(), Hole(x=(0.2, 0.3))))
    traj = dataclasses.replace(project_hop_trajectory(), scene={"terrain": hole.to_dict()})
    _, x, z = _section(trajectory_figures(traj)["path"])
    inside = (x > 0.2) & (x < 0.3)
    assert inside.any() and np.all(np.isnan(z[inside]))
    assert np.all(z[~inside & (x > 0.0)] == 0.0)


def test_path_figure_without_the_robot_keeps_the_terrain():
    fig = trajectory_figures(_small())["path"]
    assert "contacts unknown" in fig.axes[0].get_title()
    _, _, z = _section(fig)
    assert np.all(z == 0.0)


def test_a_floating_quadruped_gets_every_name_and_a_force_figure_per_foot():
    from tfcontact.robot import ContactSpec, RobotSpec

    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    spec = RobotSpec(source="solo12", base="floating",
                     contacts=tuple(ContactSpec(f, 0.016) for f in feet))
    n = 4
    q = np.zeros((n, 18))
    q[:, 0] = np.linspace(0.0, 0.2, n)
    traj = _small(q=q, v=np.zeros((n, 18)), u=np.zeros((n, 12)), gap=np.ones((n, 4)),
                  normal_velocity=np.zeros((n, 4)), tau=np.linspace(0, 1, n),
                  clock=np.linspace(0, 1, n), s=np.ones(n), robot=spec.to_dict())
    figures = trajectory_figures(traj)
    assert [k for k in figures if k.startswith("force_")] == [f"force_{f}" for f in feet]
    legend = _legend(figures["states"].axes[1])
    assert len(legend) == 18
    assert legend[:7] == ["x [m]", "y [m]", "z [m]", "yaw [rad]", "pitch [rad]", "roll [rad]",
                          "FL_HAA [rad]"]
    path = figures["path"].axes[0]
    assert _line(path, "FL_FOOT (centre)").get_xdata()[-1] > _line(
        path, "FL_FOOT (centre)").get_xdata()[0]


def test_path_figure_of_a_scene_of_boxes_only():
    walls = [{"center": [0.5, 0.0, -0.1], "size": [1.5, 0.3, 0.05]}]
    traj = dataclasses.replace(project_hop_trajectory(),
                               scene={"terrain": {"type": "none"}, "boxes": walls})
    figures = trajectory_figures(traj)
    ax = figures["path"].axes[0]
    (wall,) = [p for p in ax.patches if p.get_label() == "scene box"]
    assert (wall.get_x(), wall.get_y(), wall.get_width(), wall.get_height()) == pytest.approx(
        (-0.25, -0.125, 1.5, 0.05))
    assert not any(line.get_color() == "0.35" for line in ax.get_lines())  # no section
    assert "force_foot" in figures
