"""MPCCs: relaxations and the homotopy that solves them with IPOPT."""

from tfcontact.mpcc.derivatives import repeated_block_derivatives
from tfcontact.mpcc.problem import Mpcc, RepeatedBlock
from tfcontact.mpcc.relaxation import RELAXATIONS, L1Penalty, LinfPenalty, Relaxation, Scholtes
from tfcontact.mpcc.solver import (
    BARRIERS,
    LINEAR_SOLVERS,
    Homotopy,
    HomotopyStep,
    Ipopt,
    MpccResult,
    MpccSolver,
    MpccStatus,
    evaluation_seconds,
    solve,
)

__all__ = [
    "BARRIERS",
    "LINEAR_SOLVERS",
    "RELAXATIONS",
    "Homotopy",
    "HomotopyStep",
    "Ipopt",
    "L1Penalty",
    "LinfPenalty",
    "Mpcc",
    "MpccResult",
    "MpccSolver",
    "MpccStatus",
    "Relaxation",
    "RepeatedBlock",
    "Scholtes",
    "evaluation_seconds",
    "repeated_block_derivatives",
    "solve",
]
