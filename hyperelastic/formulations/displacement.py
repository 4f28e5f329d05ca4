"""The displacement formulation: the positions of the P1 or P2 nodes are the unknowns, every effect adds its residual
and tangent (solving/system.py), and the base spec (base.py) is all it needs. It runs every scene; for nearly
incompressible materials on linear tetrahedra it locks (too stiff: docs/mixed.md), which `-formulation auto` notes."""
from .base import Formulation


class Displacement(Formulation):
    name = "displacement"
    summary = "the positions alone (every element order, Jacobian mode and integrator)"
    auto_rank = 100          # -formulation auto's fallback: it runs every scene


FORMULATION = Displacement()
