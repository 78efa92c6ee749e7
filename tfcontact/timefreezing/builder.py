"""The entry point of the layer: a CLS in, a time-freezing piecewise smooth system out."""

from __future__ import annotations

from tfcontact.errors import InvalidInput
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem
from tfcontact.timefreezing.elastic import Elastic
from tfcontact.timefreezing.inelastic import Inelastic
from tfcontact.timefreezing.system import TimeFreezingSystem


def time_freeze(
    cls: ComplementarityLagrangianSystem,
    *,
    method: Inelastic | Elastic | None = None,
) -> TimeFreezingSystem:
    """Reformulate a CLS with impacts as a time-freezing piecewise smooth system.

    Main arguments:
        cls: the complementarity Lagrangian system (contacts carry mu, restitution, a_n,
            eps_t).

    Other arguments:
        method: `Inelastic()` (Heaviside-step form, any number of contacts, Coulomb
            friction; DESIGN.md 4.3-4.4) or `Elastic(stiffness=...)` (Stewart form, one
            frictionless contact with restitution e > 0; DESIGN.md 4.2). Default: `Elastic()`
            when a contact has restitution > 0, else `Inelastic()`.

    Returns:
        The `TimeFreezingSystem`: `pss` in y = (q, v, t), `clock_index`, `q_index`,
        `v_index`, the modes and region names.

    Raises:
        InvalidInput: `cls` or `method` is of the wrong type.
        IncompatibleOptions: the method cannot represent the contacts (several or frictional
            contacts with restitution > 0; restitution > 0 with `Inelastic`).
    """
    if not isinstance(cls, ComplementarityLagrangianSystem):
        raise InvalidInput(
            f"`cls` must be a ComplementarityLagrangianSystem, got {type(cls).__name__}"
        )
    if method is None:
        elastic = any(c.restitution > 0 for c in cls.contacts)
        method = Elastic() if elastic else Inelastic()
    if not isinstance(method, Inelastic | Elastic):
        raise InvalidInput(
            f"`method` must be Inelastic() or Elastic(...), got {type(method).__name__}"
        )
    return method.build(cls)
