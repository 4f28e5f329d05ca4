import numpy as np


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
