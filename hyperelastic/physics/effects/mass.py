"""Mass-like matrices coef int N^T N dV (MassOperator) and the effects whose operator is one (WeightedMass: inertia,
viscous damping)."""
import numpy as np

from .base import Effect, timed


class MassOperator:
    """coef * int N^T N dV on P1 tetrahedra, per vector component: consistent,
    M^e_ab = coef V/20 (1 + delta_ab) (thesis eqs. 4.39-4.40), or lumped, coef V/4 per vertex.
    cells: a kernels.Cells (the mass kernels need only the geometry); coef: a scalar, or one per cell
    (e.g. the density of each cell's region): then the kernels run on the volumes weighted by it."""

    def __init__(self, cells, coef, lumped, nlv):
        if np.ndim(coef):
            cells, coef = cells.weighted(coef), 1.0
        self.k = cells
        self.coef = float(coef)
        self.lumped = lumped
        # per node: P1 lumped V/4 per vertex, consistent 2V/20 = V/10; P2 consistent, or lumped by HRZ
        self.diagonal = np.repeat(cells.mass_diagonal(lumped, nlv) * self.coef, 3)

    def apply(self, v, y, scale=1.0):
        if self.lumped:
            y += (scale) * self.diagonal * v
        else:
            self.k.mass_apply(scale * self.coef, v, y)

    def quadratic(self, v):
        """v^T M v over the local cells (additive over ranks; lumped: the local vertex shares)."""
        if self.lumped:
            return float(self.diagonal @ (v * v))
        y = np.zeros_like(v)
        self.k.mass_apply(self.coef, v, y)
        return float(v @ y)

    def add_diag(self, d, scale=1.0):
        d += scale * self.diagonal

    def add_blocks(self, vals, scale=1.0, lo=0, hi=None):
        """Consistent mass: vals (hi-lo, 3nn, 3nn) += scale * M^e of cells lo..hi-1 (default: all)."""
        if not self.lumped:
            k = self.k if lo == 0 and hi in (None, self.k.nc) else self.k.part(lo, hi)
            k.add_mass_blocks(scale * self.coef, vals)

    def coo_pattern(self):
        """Lumped mass: one diagonal COO entry per local dof."""
        if not self.lumped:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        dofs = np.arange(len(self.diagonal), dtype=np.int64)
        return dofs, dofs

    def coo_values(self, out, scale=1.0):
        if self.lumped:
            out[:] = scale * self.diagonal


class WeightedMass(Effect):
    """An effect M (x - target) w whose operator is a mass-like matrix M = coef int N^T N dV (MassOperator, consistent or
    lumped) with the Jacobian weight w = 1/h^order: inertia (order 2: M/h^2 about x^n + h v^n) and viscous damping
    (order 1: C/h about x^n). Its potential 1/2 h^-order (x - target)^T M (x - target). Under PETSc TS the same
    operator applied to the rate (v for order 1, a for order 2) with the TS's shift as its weight (set_weight)."""
    cell_blocks = True

    def __init__(self, cells, coef, lumped, nlv):
        super().__init__()
        self.M = MassOperator(cells, coef, lumped, nlv)
        self.cell_blocks = not lumped

    def target_of(self, h, xn, vn):
        """What x is measured from in the step from (xn, vn) of size h."""
        raise NotImplementedError

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.w = 1.0 / h ** self.order      # weight of M in the Jacobian
        self.target = self.target_of(h, xn, vn)

    @timed("evals")
    def residual(self, x, r):
        self.M.apply(x - self.target, r, self.w)

    @timed("evals")
    def rate_residual(self, u, r):
        """r += M u (the second-order form M a + C v + k(x) - f of PETSc TS)."""
        self.M.apply(u, r, 1.0)

    def set_weight(self, w):
        """The Jacobian weight of M (TS: the shift of this effect's rate)."""
        self.w = w

    def potential(self, x):
        return 0.5 / self.h ** self.order * self.M.quadratic(x - self.target)

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
