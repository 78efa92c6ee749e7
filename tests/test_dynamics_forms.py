"""The Heaviside right-hand side of `Inelastic` written with one M(q) solve (`OneSolve`,
the default) is the per-mode sum modes @ weights (`PerModeSolves`) regrouped: the same
function of (y, u, alpha) for planar, 3-D and no friction, several contacts at once."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from two_contact_box import box_urdf

from tfcontact.errors import InvalidInput
from tfcontact.timefreezing import Inelastic, from_robot, time_freeze
from tfcontact.timefreezing.inelastic import OneSolve, PerModeSolves


def _box_cls(folder, base: str, mu: tuple[float, float]):
    from tfcontact.robot import ContactSpec, load_robot

    path = folder / "box.urdf"
    path.write_text(box_urdf(0.3, 0.2))
    robot = load_robot(str(path), base=base, contacts=(ContactSpec("front", 0.05),
                                                       ContactSpec("back", 0.05)))
    return from_robot(robot, mu=list(mu), a_n=50.0, eps_t=1e-3, actuated=["root_joint"])


def _points(tf, rng: np.random.Generator, count: int) -> list[np.ndarray]:
    """Random (y, u, alpha) with alpha in [0, 1] and velocities of order 1 m/s (so the
    3-D slip modes, which divide by ||v_t||_eps, are exercised away from the ball)."""
    pss = tf.pss
    return [np.concatenate([rng.uniform(-0.5, 0.5, pss.n_x), rng.uniform(-5, 5, pss.n_u),
                            rng.uniform(0, 1, pss.alpha.numel())]) for _ in range(count)]


@pytest.mark.parametrize(("base", "mu"), [("floating", (0.7, 0.4)), ("planar", (0.5, 0.0)),
                                          ("floating", (0.0, 0.6))])
def test_one_solve_rhs_is_the_sum_of_the_modes(tmp_path, base, mu):
    cls = _box_cls(tmp_path, base, mu)
    tf = time_freeze(cls, method=Inelastic())
    assert tf.parameter("dynamics") == "one_solve"
    old = time_freeze(cls, method=Inelastic(dynamics=PerModeSolves())).pss
    pss = tf.pss
    z = ca.vertcat(pss.x, pss.u, pss.alpha)
    new = ca.Function("new", [z], [pss.rhs, ca.mtimes(tf.modes, tf.weights)])
    per_mode = ca.Function("old", [ca.vertcat(old.x, old.u, old.alpha)], [old.rhs])
    n_modes = 1 + sum(2 if m else 1 for m in mu)
    assert tf.modes.shape[1] == n_modes
    for point in _points(tf, np.random.default_rng(7), 5):
        one, summed = (np.asarray(value).ravel() for value in new(point))
        written = np.asarray(per_mode(point)).ravel()
        scale = np.max(np.abs(summed))
        assert scale > 1.0  # the auxiliary pushes act (a_n = 50), not a trivial zero
        np.testing.assert_allclose(one, summed, rtol=0, atol=1e-12 * scale)
        np.testing.assert_array_equal(written, summed)  # PerModeSolves is the sum as written


def test_the_stewart_form_is_unchanged_by_the_strategy(tmp_path):
    from tfcontact.robot import ContactSpec, load_robot

    path = tmp_path / "box.urdf"
    path.write_text(box_urdf(0.3, 0.2))
    robot = load_robot(str(path), base="planar", contacts=(ContactSpec("front", 0.05),))
    cls = from_robot(robot, mu=0.5, actuated=["root_joint"])
    a = time_freeze(cls, method=Inelastic(form="stewart", dynamics=OneSolve()))
    b = time_freeze(cls, method=Inelastic(form="stewart", dynamics=PerModeSolves()))
    assert a.pss.n_regions == b.pss.n_regions == 8
    assert str(a.modes) == str(b.modes)


def test_dynamics_must_be_a_strategy():
    with pytest.raises(InvalidInput, match="HeavisideDynamics"):
        Inelastic(dynamics="one_solve")  # type: ignore[arg-type]
