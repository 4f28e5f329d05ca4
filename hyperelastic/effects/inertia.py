import numpy as np

from .base import Effect, timed
from .mass import MassOperator


class Inertia(Effect):
    """Inertia in backward Euler: M (x - x^n - h v^n) / h^2, Jacobian M / h^2, with the
    consistent (thesis eq. 4.39) or lumped mass matrix. Never built for -quasistatic."""
    name = "inertia"
    cell_blocks = True

    def __init__(self, kernels, rho, lumped, nlv):
        super().__init__()
        self.M = MassOperator(kernels, rho, lumped, nlv)
        self.cell_blocks = not lumped

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.target = xn + h * vn  # x^n + h v^n

    @timed("evals")
    def residual(self, x, r):
        self.M.apply(x - self.target, r, 1.0 / self.h ** 2)

    def potential(self, x):
        return 0.5 / self.h ** 2 * self.M.quadratic(x - self.target)

    @timed("applies")
    def apply(self, v, y):
        self.M.apply(v, y, 1.0 / self.h ** 2)

    @timed("applies")
    def diag(self, d):
        self.M.add_diag(d, 1.0 / self.h ** 2)

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        self.M.add_blocks(vals, 1.0 / self.h ** 2, lo, hi)

    def coo_pattern(self):
        return self.M.coo_pattern()

    def coo_values(self, out):
        self.M.coo_values(out, 1.0 / self.h ** 2)

    def energy(self, x, v):
        y = np.zeros_like(v)
        self.M.apply(v, y)
        return {"kinetic": 0.5 * float(v @ y)}  # additive over ranks: each cell counted once
