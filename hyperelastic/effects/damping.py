import numpy as np

from .base import Effect, timed
from .mass import MassOperator


class ViscousDamping(Effect):
    """Viscous damping C (x - x^n)/h, C = c int N^T N dV (thesis eqs. 4.15, 4.40); Jacobian C/h."""
    name = "damping"
    cell_blocks = True

    def __init__(self, kernels, c, lumped, nlv):
        super().__init__()
        self.C = MassOperator(kernels, c, lumped, nlv)
        self.cell_blocks = not lumped

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.xn = xn

    @timed("evals")
    def residual(self, x, r):
        self.C.apply(x - self.xn, r, 1.0 / self.h)

    def potential(self, x):
        return 0.5 / self.h * self.C.quadratic(x - self.xn)

    @timed("applies")
    def apply(self, v, y):
        self.C.apply(v, y, 1.0 / self.h)

    @timed("applies")
    def diag(self, d):
        self.C.add_diag(d, 1.0 / self.h)

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        self.C.add_blocks(vals, 1.0 / self.h, lo, hi)

    def coo_pattern(self):
        return self.C.coo_pattern()

    def coo_values(self, out):
        self.C.coo_values(out, 1.0 / self.h)


class RayleighDamping(Effect):
    """Rayleigh damping (alpha M + beta K(x^n)) (x - x^n)/h. The stiffness is frozen at the start
    of the step, so the residual is affine in x and its Jacobian (alpha M + beta K(x^n))/h is exact."""
    name = "rayleigh"
    cell_blocks = True

    def __init__(self, kernels, rho, alpha, beta, lumped, nlv):
        super().__init__()
        self.k = kernels
        self.alpha, self.beta = alpha, beta
        self.M = MassOperator(kernels, alpha * rho, lumped, nlv)

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.xn = xn.copy()

    def _apply(self, v, y):
        self.M.apply(v, y, 1.0 / self.h)
        if self.beta:
            tmp = np.zeros_like(y)
            self.k.kv(self.xn, v, tmp)
            y += (self.beta / self.h) * tmp

    @timed("evals")
    def residual(self, x, r):
        self._apply(x - self.xn, r)

    def potential(self, x):
        d = x - self.xn
        y = np.zeros_like(d)
        self._apply(d, y)
        return 0.5 * float(d @ y)

    @timed("applies")
    def apply(self, v, y):
        self._apply(v, y)

    @timed("applies")
    def diag(self, d):
        self.M.add_diag(d, 1.0 / self.h)
        if self.beta:
            tmp = np.zeros_like(d)
            self.k.tangent_diag(self.xn, tmp)
            d += (self.beta / self.h) * tmp

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        self.M.add_blocks(vals, 1.0 / self.h, lo, hi)
        if self.beta:
            k = self.k if lo == 0 and hi in (None, self.k.nc) else self.k.part(lo, hi)
            K, _ = k.tangent(self.xn)             # scaled by beta/h, so not accumulated in place
            vals += (self.beta / self.h) * K

    def coo_pattern(self):
        return self.M.coo_pattern()

    def coo_values(self, out):
        self.M.coo_values(out, 1.0 / self.h)
