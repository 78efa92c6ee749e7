"""A hand-made planar hopper and an analytic hop, for the viz tests (no solver involved).

The hop, in physical time t in [0, 1] s: flight from lift-off at t = 0, touchdown at
t = 0.4 (the impact is a frozen piece of numerical time 0.1 s: the clock stops, q stays,
v jumps), stance until 0.6, flight until 1.0. Foot height above ground (the gap):
p(t) = 5 (t - a)(b - t) on a flight [a, b], 0 in stance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from tfcontact.plan_format import Trajectory

HOPPER_URDF = Path(__file__).parent / "data" / "viz_hopper.urdf"

FOOT_RADIUS = 0.04
CONTACTS = [{"frame": "shin", "radius": FOOT_RADIUS}]


def hopper_models() -> tuple[pin.Model, pin.GeometryModel]:
    """(model, visual_model) of the hand-made planar hopper."""
    model, _, visual = pin.buildModelsFromUrdf(str(HOPPER_URDF))
    return model, visual


def _foot_height(t):
    t = np.asarray(t, dtype=float)
    first = 5.0 * t * (0.4 - t)
    second = 5.0 * (t - 0.6) * (1.0 - t)
    return np.where(t <= 0.4, first, np.where(t >= 0.6, second, 0.0))


def _configuration(t):
    """q(t) = (x, z, pitch, hip, leg) with the foot tip at height `_foot_height(t)`."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    stance = (t > 0.4) & (t < 0.6)
    leg = 0.45 - np.where(stance, 0.12 * np.sin(np.pi * (t - 0.4) / 0.2), 0.0)
    hip = 0.0 * t
    pitch = 0.0 * t
    # foot centre: body z - 0.3 (thigh) - leg; gap = foot centre height - radius
    z = _foot_height(t) + FOOT_RADIUS + 0.30 + leg
    x = 0.5 * t
    return np.stack([x, z, pitch, hip, leg], axis=1)


def _velocity(t, stance):
    """dq/dt at times t; `stance` picks the one-sided derivative at phase boundaries."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    stance = np.broadcast_to(stance, t.shape)
    dfoot = np.where(t <= 0.5, 5.0 * (0.4 - 2.0 * t), 5.0 * (1.6 - 2.0 * t))
    dleg = -0.12 * np.pi / 0.2 * np.cos(np.pi * (t - 0.4) / 0.2)
    dleg = np.where(stance, dleg, 0.0)
    dz = np.where(stance, 0.0, dfoot) + dleg
    zero = 0.0 * t
    return np.stack([0.5 + zero, dz, zero, zero, dleg], axis=1)


def hop_trajectory(*, n_flight: int = 41, n_frozen: int = 6) -> Trajectory:
    """The analytic hop as a Trajectory in numerical time (one frozen piece at t = 0.4)."""
    t_a = np.linspace(0.0, 0.4, n_flight)
    t_b = np.linspace(0.4, 1.0, int(1.5 * n_flight))[1:]
    q_a, q_b = _configuration(t_a), _configuration(t_b)
    v_a = _velocity(t_a, False)
    v_b = _velocity(t_b, (t_b > 0.4) & (t_b < 0.6))
    v_post = _velocity(0.4, True)[0]
    # the frozen piece: q constant, v moves from the pre- to the post-impact value
    w = np.linspace(0.0, 1.0, n_frozen)[1:, None]
    q_f = np.repeat(q_a[-1:], n_frozen - 1, axis=0)
    v_f = (1 - w) * v_a[-1] + w * v_post
    frozen_dtau = 0.1
    tau = np.concatenate([t_a, 0.4 + frozen_dtau * w[:, 0], t_b + frozen_dtau])
    clock = np.concatenate([t_a, np.full(n_frozen - 1, 0.4), t_b])
    q = np.concatenate([q_a, q_f, q_b])
    v = np.concatenate([v_a, v_f, v_b])
    n = tau.size
    s = np.ones(n)  # speed of time 1; the clock itself stops during the impact
    gap = _foot_height(clock)[:, None]
    normal_velocity = (v[:, 1] - v[:, 4])[:, None]  # foot height rate: z' - leg'  [m/s]
    force = np.zeros((n, 1, 3))
    stance = (clock > 0.4) & (clock < 0.6)
    force[stance, 0, 2] = 60.0
    impulse = np.zeros((n, 1, 3))
    impulse[n_flight + n_frozen - 2, 0, 2] = 5.7 * 2.0
    u = np.stack([np.sin(2 * np.pi * clock), 20 * np.cos(np.pi * clock)], axis=1)
    return Trajectory(
        tau=tau, clock=clock, s=s, q=q, v=v, u=u, gap=gap, normal_velocity=normal_velocity,
        force=force, impulse=impulse, status="success",
        robot={"source": "tests/data/viz_hopper.urdf", "base": "fixed",
               "locked_joints": [], "contacts": CONTACTS},
        scene={"terrain": {"type": "flat", "height": 0.0}},
        solver={"nlp_count": 3, "iterations": 42, "complementarity_residual": 1e-9,
                "history": [{"sigma": 1e-1, "residual": 3e-2, "iterations": 20},
                            {"sigma": 1e-2, "residual": 4e-4, "iterations": 12},
                            {"sigma": 1e-3, "residual": 1e-9, "iterations": 10}]},
        verification={"note": "hand-made analytic hop"},
    )


PROJECT_HOPPER = {"source": "robots/hopper.urdf", "base": "planar",
                  "locked_joints": ["hip_joint"], "contacts": [{"frame": "foot", "radius": 0.02}],
                  "locked_positions": []}


def project_hop_trajectory() -> Trajectory:
    """A hop of the project's TF-8 hopper (q = x, z, pitch, l), gap from the closed form.

    Foot centre (x - l sin(pitch), z - l cos(pitch)), gap = z - l cos(pitch) - r with
    r = 0.02 m. The touchdown at t = 0.4 is an inelastic impact whose impulse is
    consistent with the momentum balance M(q) (v+ - v-) = J(q)^T Lambda (Lambda along +z,
    chosen so that the foot's normal velocity becomes 0).
    """
    from tfcontact.robot import RobotSpec, load_robot

    robot = load_robot(RobotSpec.from_dict(PROJECT_HOPPER))
    model, data = robot.model, robot.model.createData()
    foot = model.getFrameId("foot")
    radius = 0.02

    def configuration(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        stance = (t > 0.4) & (t < 0.6)
        leg = 0.4 - np.where(stance, 0.15 * np.sin(np.pi * (t - 0.4) / 0.2), 0.0)
        pitch = 0.1 * np.sin(2 * np.pi * t)
        z = _foot_height(t) + radius + leg * np.cos(pitch)
        return np.stack([0.5 * t, z, pitch, leg], axis=1)

    def velocity(t):
        h = 1e-6
        return (configuration(t + h) - configuration(t - h)) / (2 * h)

    t_a = np.linspace(0.0, 0.4, 41)
    t_b = np.linspace(0.4, 1.0, 61)[1:]
    v_pre = (configuration(0.4) - configuration(0.4 - 1e-6))[0] / 1e-6
    q_imp = configuration(0.4)[0]
    pin.computeAllTerms(model, data, q_imp, v_pre)
    J = pin.getFrameJacobian(model, data, foot, pin.LOCAL_WORLD_ALIGNED)[:3]
    M = data.M
    n = J[2]  # normal direction: world z
    minv_n = np.linalg.solve(M, n)
    lam = -(n @ v_pre) / (n @ minv_n)  # inelastic: the foot's normal velocity becomes 0
    v_post = v_pre + lam * minv_n
    w = np.linspace(0.0, 1.0, 6)[1:, None]
    tau = np.concatenate([t_a, 0.4 + 0.1 * w[:, 0], t_b + 0.1])
    clock = np.concatenate([t_a, np.full(5, 0.4), t_b])
    q = np.concatenate([configuration(t_a), np.repeat(q_imp[None], 5, 0), configuration(t_b)])
    v_a = velocity(t_a)
    v_a[-1] = v_pre
    v = np.concatenate([v_a, (1 - w) * v_pre + w * v_post, velocity(t_b)])
    N = tau.size
    pitch, leg = q[:, 2], q[:, 3]
    gap = (q[:, 1] - leg * np.cos(pitch) - radius)[:, None]
    normal_velocity = (v[:, 1] - v[:, 3] * np.cos(pitch) + leg * np.sin(pitch) * v[:, 2])[:, None]
    impulse = np.zeros((N, 1, 3))
    impulse[40 + 5, 0, 2] = lam  # at the exit sample of the frozen piece
    return Trajectory(
        tau=tau, clock=clock, s=np.ones(N), q=q, v=v, u=np.zeros((N, 1)), gap=gap,
        normal_velocity=normal_velocity, impulse=impulse, status="success",
        robot=dict(PROJECT_HOPPER), scene={"terrain": {"type": "flat", "height": 0.0}},
    )
