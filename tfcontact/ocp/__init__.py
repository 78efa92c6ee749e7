"""Optimal control of piecewise smooth systems: problem statement, transcription, solution.

`OptimalControlProblem` states the problem; `build(problem, discretization=Transcription())`
transcribes it into an MPCC with FESD; `solve(problem, relaxation=..., homotopy=..., nlp=...)`
runs the MPCC homotopy and returns an `OcpResult`. The layer knows nothing about robots or
time-freezing.
"""

from tfcontact.ocp.problem import BoundaryHook, Constraint, OptimalControlProblem
from tfcontact.ocp.solve import OcpBuild, OcpResult, Transcription, build, solve

__all__ = [
    "BoundaryHook",
    "Constraint",
    "OcpBuild",
    "OcpResult",
    "OptimalControlProblem",
    "Transcription",
    "build",
    "solve",
]
