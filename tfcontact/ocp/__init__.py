"""Optimal control of piecewise smooth systems: problem statement, transcription, solution.

`OptimalControlProblem` states the problem; `build(problem, discretization=Transcription())`
transcribes it into an MPCC with FESD; `solve(problem, relaxation=..., homotopy=..., nlp=...)`
runs the MPCC homotopy and returns an `OcpResult`; that core knows nothing about robots or
time-freezing. On top of it, `ContactProblem` + `solve_contact` state and solve a
time-freezing OCP in physical time (speed of time, clock constraints) and verify the plan
independently with `tfcontact.verify` (`Verification`, re-exported here; the settings are
`ContactSolverOptions.verify`, a `tfcontact.verify.VerifyOptions`).
"""

from tfcontact.ocp.contact import (
    Attempt,
    ContactProblem,
    ContactResult,
    ContactSolverOptions,
    Periodicity,
    solve_contact,
    verify_plan,
)
from tfcontact.ocp.problem import BoundaryHook, Constraint, OptimalControlProblem
from tfcontact.ocp.solve import OcpBuild, OcpResult, Transcription, build, solve
from tfcontact.verify import Verification

__all__ = [
    "Attempt",
    "BoundaryHook",
    "Constraint",
    "ContactProblem",
    "ContactResult",
    "ContactSolverOptions",
    "OcpBuild",
    "OcpResult",
    "OptimalControlProblem",
    "Periodicity",
    "Transcription",
    "Verification",
    "build",
    "solve",
    "solve_contact",
    "verify_plan",
]
