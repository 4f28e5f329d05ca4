import numpy as np

from .base import Energy, Spec
from .mass import WeightedMass


class Inertia(WeightedMass):
    """Inertia in backward Euler: M (x - x^n - h v^n) / h^2, Jacobian M / h^2, with the
    consistent (thesis eq. 4.39) or lumped mass matrix. Never built for -quasistatic. Under PETSc TS
    (ts_integrator.py) the same operator gives M a, with Jacobian weight shift_a instead of 1/h^2."""
    name = "inertia"
    order = 2

    def target_of(self, h, xn, vn):
        return xn + h * vn          # x^n + h v^n

    def energy(self, x, v):
        y = np.zeros_like(v)
        self.M.apply(v, y)
        return {"kinetic": 0.5 * float(v @ y)}  # additive over ranks: each cell counted once


SPEC = Spec("inertia", "the mass matrix M (-mass consistent|lumped) of the density; not in -quasistatic runs",
            build=lambda p, ctx: [Inertia(ctx.cells, ctx.density, ctx.lumped, ctx.space.nlv)], dynamic=True,
            energies=(Energy("kinetic", 1, "kinetic energy 1/2 v^T M v after the step [J] (accepted attempts)"),))
