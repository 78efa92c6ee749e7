"""tfcontact: contact-rich motion planning for URDF robots.

Layers, data flowing down the list:

* `tfcontact.robot`: Pinocchio models and their CasADi symbolic twin, contact candidates.
* `tfcontact.timefreezing`: complementarity Lagrangian systems -> piecewise smooth systems.
* `tfcontact.fesd`: piecewise smooth systems -> FESD discretisation, simulator.
* `tfcontact.mpcc`: relaxations and homotopy for MPCCs, solved with IPOPT.
* `tfcontact.ocp`: optimal control problems, results, verification.
* `tfcontact.viz`: trajectory files, meshcat replay, figures.
"""

__version__ = "0.1.0"
