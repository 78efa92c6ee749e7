import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.fesd.system import HeavisideSystem, StewartSystem


def test_sign_matrix_gives_indicators_minus_s_c():
    x = ca.SX.sym("x", 2)
    c = ca.vertcat(x[0], x[1] - 1)
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    system = StewartSystem.from_sign_matrix(x, ca.SX(0, 1), ca.SX.ones(2, 4), c, signs)
    g = ca.Function("g", [x], [system.indicators])
    # x = (2, -3): c = (2, -4), sign pattern (+, -) = region 1 has the smallest indicator
    values = np.asarray(g([2.0, -3.0])).ravel()
    assert int(np.argmin(values)) == 1
    np.testing.assert_allclose(values, -signs @ np.array([2.0, -4.0]))
    assert system.n_regions == 4 and system.n_x == 2 and system.n_u == 0
    assert system.state_names == ("x0", "x1")


def test_heaviside_system_records_dimensions():
    x = ca.SX.sym("x")
    u = ca.SX.sym("u")
    alpha = ca.SX.sym("alpha")
    system = HeavisideSystem(x=x, u=u, alpha=alpha, rhs=3 - 2 * alpha + u, switching=x,
                             state_names=("position",))
    assert system.n_x == 1 and system.n_u == 1 and system.n_switching == 1
    assert system.state_names == ("position",) and system.control_names == ("u0",)


def test_bad_systems_are_rejected_with_the_reason():
    x = ca.SX.sym("x", 2)
    u = ca.SX(0, 1)
    with pytest.raises(InvalidInput, match="`signs` must have shape"):
        StewartSystem.from_sign_matrix(x, u, ca.SX.ones(2, 2), x, np.ones((2, 3)))
    with pytest.raises(InvalidInput, match="`signs` has two equal rows"):
        StewartSystem.from_sign_matrix(x, u, ca.SX.ones(2, 2), x, np.ones((2, 2)))
    with pytest.raises(InvalidInput, match="`modes` must have one row per state"):
        StewartSystem(x=x, u=u, modes=ca.SX.ones(3, 2), indicators=x)
    with pytest.raises(InvalidInput, match="`indicators` has 2 entries but `modes` has 3"):
        StewartSystem(x=x, u=u, modes=ca.SX.ones(2, 3), indicators=x)
    with pytest.raises(InvalidInput, match="`x` must be a vector of pure symbols"):
        StewartSystem(x=2 * x, u=u, modes=ca.SX.ones(2, 2), indicators=x)
    stranger = ca.SX.sym("stranger")
    with pytest.raises(InvalidInput, match=r"depends on symbols \['stranger'\]"):
        StewartSystem(x=x, u=u, modes=ca.SX.ones(2, 2), indicators=x * stranger)
    alpha = ca.SX.sym("alpha", 1)
    with pytest.raises(InvalidInput, match="one step variable per switching function"):
        HeavisideSystem(x=x, u=u, alpha=alpha, rhs=x, switching=x)
    with pytest.raises(InvalidInput, match="`rhs` has 1 entries, expected n_x = 2"):
        HeavisideSystem(x=x, u=u, alpha=ca.SX.sym("a", 2), rhs=x[0], switching=x)
