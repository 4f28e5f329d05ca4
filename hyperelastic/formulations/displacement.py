"""The displacement formulation: the positions of the P1 or P2 nodes are the unknowns, every effect adds its residual
and tangent (solving/system.py), and the base spec (base.py) is all it needs. It runs every scene; for nearly
incompressible materials on linear tetrahedra it locks (too stiff: docs/mixed.md), which `-formulation auto` notes."""
from .base import Formulation
from .mixed import AUTO_RATIO, bulk_to_shear


class Displacement(Formulation):
    name = "displacement"
    summary = "the positions alone (every element order, Jacobian mode and integrator)"
    auto_rank = 100          # -formulation auto's fallback: it runs every scene

    def notes(self, problem):
        """Named with a nearly incompressible material (kappa/mu >= the mixed formulation's AUTO_RATIO): what
        displacements alone give up (the same line -formulation auto's fallback says)."""
        ratio = max(bulk_to_shear(sol) for _, sol in problem.solids)
        if ratio < AUTO_RATIO:
            return []
        nu = (3 * ratio - 2) / (2 * (3 * ratio + 1))
        what = f"-formulation displacement with a nearly incompressible material (kappa/mu = {ratio:.3g}, nu = {nu:.5g})"
        if problem.element.order == 1:
            return [f"{what}: linear tetrahedra lock (too stiff: displacements and stresses too small); -order 2 "
                    "-formulation mixed does not (docs/mixed.md)"]
        return [f"{what}: quadratic tetrahedra lock less than linear ones but still stiffen as nu -> 0.5, and their "
                "stresses oscillate; -formulation mixed does neither (docs/mixed.md)"]


FORMULATION = Displacement()
