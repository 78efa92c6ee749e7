"""The MPCC handed from the discretisation layers to the homotopy solver.

    min_w  f(w, p)
    s.t.   lbg <= g(w, p) <= ubg,   lbw <= w <= ubw,
           0 <= G(w, p)  perp  H(w, p) >= 0   (componentwise: G_i H_i = 0).

The builder guarantees G >= 0 and H >= 0 through its own bounds or constraints
(for FESD they are multipliers and step variables with lbw = 0); the relaxation only
treats the products. Cross complementarity may pair a variable with a sum of
nonnegative variables; G_i H_i = 0 then still means every product vanishes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput


@dataclass(frozen=True, eq=False)
class RepeatedBlock:
    """Rows of g that one function gives for each of E elements:
    g[rows[e]] = function(arguments[0][:, e], arguments[1][:, e], ...).

    The solver then differentiates `function` once instead of E inlined copies
    (`tfcontact.mpcc.derivatives`). Optional: an MPCC without blocks is differentiated
    as a whole.

    Args:
        function: an SX Function of column-vector inputs with one output (n_r, 1).
        arguments: one SX matrix (numel of input i, E) per input; each entry an entry of
            w (plus a term free of w) or free of w (parameters, constants).
        rows: (E, n_r) indices into g.
    """

    function: ca.Function
    arguments: tuple[ca.SX, ...]
    rows: np.ndarray

    def __post_init__(self) -> None:
        fn = self.function
        if fn.n_out() != 1 or fn.size2_out(0) != 1:
            raise InvalidInput("a RepeatedBlock's function must have one column output")
        if len(self.arguments) != fn.n_in():
            raise InvalidInput(f"`arguments` has {len(self.arguments)} entries, the "
                               f"function {fn.n_in()} inputs")
        rows = np.asarray(self.rows, dtype=int)
        if rows.ndim != 2 or rows.shape[1] != fn.numel_out(0) or np.any(rows < 0):
            raise InvalidInput(f"`rows` must be nonnegative indices of shape "
                               f"(E, {fn.numel_out(0)}), got {rows.shape}")
        for i, argument in enumerate(self.arguments):
            if fn.size2_in(i) != 1 or argument.shape != (fn.numel_in(i), rows.shape[0]):
                raise InvalidInput(
                    f"argument {i} must be a ({fn.numel_in(i)}, {rows.shape[0]}) matrix "
                    f"for a column input, got {argument.shape} for {fn.size_in(i)}")
        object.__setattr__(self, "rows", rows)


@dataclass(frozen=True, eq=False)
class Mpcc:
    """A mathematical program with complementarity constraints, built but not solved.

    Args:
        w: decision variables, SX column (n_w, 1).
        f: objective, SX scalar in (w, p).
        g: general constraints, SX column (n_g, 1) in (w, p).
        lbg, ubg: bounds of g, arrays (n_g,).
        lbw, ubw: bounds of w, arrays (n_w,).
        w0: initial guess, array (n_w,).
        G, H: complementarity pairs, SX columns of equal length (n_comp, 1).
        p: parameters, SX column (n_p, 1) (may be empty); values given at solve time.
        blocks: named index arrays into w (for example "x", "u", "h", "theta"),
            so that a solution can be read and a build inspected and counted.
        repeated: rows of g that repeat one function over elements (`RepeatedBlock`),
            so that the solver differentiates it once.
    """

    w: ca.SX
    f: ca.SX
    g: ca.SX
    lbg: np.ndarray
    ubg: np.ndarray
    lbw: np.ndarray
    ubw: np.ndarray
    w0: np.ndarray
    G: ca.SX
    H: ca.SX
    p: ca.SX = field(default_factory=lambda: ca.SX(0, 1))
    blocks: dict[str, np.ndarray] = field(default_factory=dict)
    repeated: tuple[RepeatedBlock, ...] = ()

    def __post_init__(self) -> None:
        n_w = self.w.numel()
        n_g = self.g.numel()
        for name, n in (("lbw", n_w), ("ubw", n_w), ("w0", n_w), ("lbg", n_g), ("ubg", n_g)):
            value = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if value.size != n:
                raise InvalidInput(f"`{name}` has {value.size} entries, expected {n}")
            object.__setattr__(self, name, value)
        if self.G.numel() != self.H.numel():
            raise InvalidInput(
                f"`G` and `H` must have equal length, got {self.G.numel()} and {self.H.numel()}"
            )
        if any(int(block.rows.max(initial=-1)) >= n_g for block in self.repeated):
            raise InvalidInput(f"a RepeatedBlock names rows beyond g's {n_g}")
        if np.any(self.lbw > self.ubw):
            i = int(np.argmax(self.lbw > self.ubw))
            raise InvalidInput(f"`lbw[{i}]` = {self.lbw[i]} exceeds `ubw[{i}]` = {self.ubw[i]}")
        if np.any(self.lbg > self.ubg):
            i = int(np.argmax(self.lbg > self.ubg))
            raise InvalidInput(f"`lbg[{i}]` = {self.lbg[i]} exceeds `ubg[{i}]` = {self.ubg[i]}")

    @property
    def n_w(self) -> int:
        return self.w.numel()

    @property
    def n_g(self) -> int:
        return self.g.numel()

    @property
    def n_comp(self) -> int:
        return self.G.numel()
