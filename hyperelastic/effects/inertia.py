import numpy as np

from .base import Effect, Energy, Spec, timed
from .mass import MassOperator


class Inertia(Effect):
    """Inertia in backward Euler: M (x - x^n - h v^n) / h^2, Jacobian M / h^2, with the
    consistent (thesis eq. 4.39) or lumped mass matrix. Never built for -quasistatic. Under PETSc TS
    (ts_integrator.py) the same operator gives M a, with Jacobian weight shift_a instead of 1/h^2."""
    name = "inertia"
    cell_blocks = True
    order = 2

    def __init__(self, cells, rho, lumped, nlv):
        super().__init__()
        self.M = MassOperator(cells, rho, lumped, nlv)
        self.cell_blocks = not lumped

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.w = 1.0 / h ** 2      # weight of M in the Jacobian
        self.target = xn + h * vn  # x^n + h v^n

    @timed("evals")
    def residual(self, x, r):
        self.M.apply(x - self.target, r, self.w)

    @timed("evals")
    def rate_residual(self, a, r):
        """r += M a (the second-order form M a + C v + k(x) - f of PETSc TS)."""
        self.M.apply(a, r, 1.0)

    def set_weight(self, w):
        """The Jacobian weight of M (TS: shift_a = dA/dX)."""
        self.w = w

    def potential(self, x):
        return 0.5 / self.h ** 2 * self.M.quadratic(x - self.target)

    @timed("applies")
    def apply(self, v, y):
        self.M.apply(v, y, self.w)

    @timed("applies")
    def diag(self, d):
        self.M.add_diag(d, self.w)

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        self.M.add_blocks(vals, self.w, lo, hi)

    def coo_pattern(self):
        return self.M.coo_pattern()

    def coo_values(self, out):
        self.M.coo_values(out, self.w)

    def energy(self, x, v):
        y = np.zeros_like(v)
        self.M.apply(v, y)
        return {"kinetic": 0.5 * float(v @ y)}  # additive over ranks: each cell counted once


SPEC = Spec("inertia", "the mass matrix M (-mass consistent|lumped) of the density; not in -quasistatic runs",
            build=lambda p, ctx: [Inertia(ctx.cells, ctx.density, ctx.lumped, ctx.space.nlv)], dynamic=True,
            energies=(Energy("kinetic", 1, "kinetic energy 1/2 v^T M v after the step [J] (accepted attempts)"),))
