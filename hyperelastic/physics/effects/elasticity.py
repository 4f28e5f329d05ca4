import numpy as np
from petsc4py import PETSc

from .base import Effect, Energy, Spec, timed


def project_psd(K):
    """Each symmetric cell block (12x12 for P1) with its negative eigenvalues set to zero (Teran, Sifakis, Irving,
    Fedkiw, "Robust quasistatic finite elements and flesh simulation", SCA 2005, sec. 5, applied to the
    element Hessian as in Smith, de Goes, Kim 2018, sec. 4). Returns the blocks and the number clamped."""
    w, Q = np.linalg.eigh(0.5 * (K + K.transpose(0, 2, 1)))
    neg = int((w < 0).any(axis=1).sum())
    return np.ascontiguousarray(np.einsum("nij,nj,nkj->nik", Q, np.maximum(w, 0.0), Q)), neg


class Elasticity(Effect):
    """Internal elastic force k(x) (thesis eq. 4.41) and its exact tangent K = dk/dx."""
    name = "elasticity"
    internal = True
    linear = False
    cell_blocks = True
    discrete_gradient = True

    def __init__(self, kernels, projection=False):
        super().__init__()
        self.projection = projection   # -hessian_projection: PSD-projected element tangents
        self.blocks = None
        self.projected_cells = 0
        self.k = self.kernels = kernels
        # every material of the scene, also those with no cells on this rank: what follows (the domain
        # check's collective, the linear flag) must be the same on every rank
        models = list(dict.fromkeys(kernels.materials))
        self.material = ",".join(m.name for m in models)     # the material name(s)
        self.linear = all(m.quadratic for m in models)
        # materials undefined for J <= 0: every residual counts the cells where they were evaluated there
        self.domain = not all(m.defined_when_inverted for m in models)
        self.defined_when_inverted = not self.domain
        self.x = None
        self.undefined = 0   # cells where the material was undefined at the last evaluation
        # the element force loop alone, in -log_view: the rest of SNESFunctionEval is the residual's
        # fixed cost (local vectors, Dirichlet rows, other effects; scripts/bench_peer.py reports it)
        self.ev_forces = PETSc.Log.Event("HE_ElasticForces")

    @timed("evals")
    def residual(self, x, r):
        self.ev_forces.begin()
        self.undefined = self.k.forces(x, r)
        self.ev_forces.end()

    @timed("evals")
    def residual_discrete_gradient(self, x, xn, r):
        """The energy-momentum force of the midpoint step from xn through x (kernels.forces_discrete_gradient)."""
        self.undefined = self.k.forces_discrete_gradient(x, xn, r)

    def potential(self, x):
        """Psi(x) = sum_e V_e psi(F_e); +inf where the material is undefined (inverted cells), so that
        an energy line search backs off from them."""
        W, _, _, bad = self.k.energy(x)
        return float("inf") if bad else W

    def linearize(self, x):
        self.x = x.copy()
        if self.projection:
            K, _ = self.k.tangent(self.x)
            self.blocks, self.projected_cells = project_psd(K)

    @timed("applies")
    def apply(self, v, y):
        if self.projection:
            self.k.apply_blocks(self.blocks, v, y)
        else:
            self.k.kv(self.x, v, y)

    @timed("applies")
    def diag(self, d):
        if self.projection:
            np.add.at(d.reshape(-1, 3), self.k.cells, np.einsum("nii->ni", self.blocks).reshape(-1, self.k.nn, 3))
        else:
            self.k.tangent_diag(self.x, d)

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        """vals (hi-lo, 3nn, 3nn) += the tangent blocks of cells lo..hi-1 (default: all)."""
        self._cell_blocks(vals, lo, hi, True)

    @timed("applies")
    def set_cell_blocks(self, vals, lo=0, hi=None):
        """vals (hi-lo, 3nn, 3nn) = the tangent blocks of cells lo..hi-1 (default: all), written by the kernels."""
        self._cell_blocks(vals, lo, hi, False)

    def _cell_blocks(self, vals, lo, hi, accumulate):
        whole = lo == 0 and hi in (None, self.k.nc)
        if self.projection:
            blocks = self.blocks if whole else self.blocks[lo:hi]
            if accumulate:
                vals += blocks
            else:
                vals[...] = blocks
        else:
            (self.k if whole else self.k.part(lo, hi)).tangent(self.x, vals, accumulate=accumulate)

    def energy(self, x, v):
        W, jmin, jmax, bad = self.k.energy(x)
        return {"elastic": W, "J_min": jmin, "J_max": jmax}


SPEC = Spec(
    "elasticity", "the elastic force of the material(s) (always built)",
    build=lambda p, ctx: [Elasticity(ctx.kernels, ctx.projection)],
    energies=(Energy("elastic", 1, "elastic energy after the step [J] (accepted attempts)"),
              Energy("J_min", 0, "smallest volume ratio det F over the cells after the step", combine="min"),
              Energy("J_max", 0, "largest volume ratio det F over the cells after the step", combine="max")))
