"""The mixed formulation's pressure (its unknown, its terms, its law): U*(p) of a volumetric kind (Volumetric), the P1
pressure on the vertices of a quadratic space (PressureSpace) and the pressure's terms of the residual and the tangent
on the cells of one material with a split (PressureCoupling, an effect). The formulas: formulations/mixed/__init__.py."""
import math

import numpy as np
from petsc4py import PETSc

from ...discretization import kernels
from ...element.reference import EDGES, tet_shapes
from ...physics.effects.base import Effect, timed


class Volumetric:
    """U*(p) and its derivatives for a volumetric kind ("J" or "trace") and bulk modulus kappa (inf: the
    incompressible limit)."""

    def __init__(self, kind, kappa):
        self.kind, self.kappa = kind, float(kappa)

    def __call__(self, p):
        """(U*(p), U*'(p), U*''(p)) at the points' pressures p."""
        k = self.kappa
        if math.isinf(k):
            z = np.zeros_like(p)
            return z, z, z
        if self.kind == "trace":
            return 0.5 * p * p / k, p / k, np.full_like(p, 1.0 / k)
        s = p / k
        r = np.sqrt(1.0 + s * s)
        g = s + s * s / (r + 1.0)                       # J_p - 1 = s + sqrt(1 + s^2) - 1, without cancellation
        Jp = 1.0 + g
        U = 0.25 * k * (Jp * Jp - 1.0 - 2.0 * np.log1p(g))
        return p * g - U, g, 2.0 / (k * (1.0 + 1.0 / (Jp * Jp)))


class PressureSpace:
    """P1 pressure: one dof at each vertex of a QuadraticSpace (whose vertices are its first nv local nodes,
    numbered by their DMPlex point), on a clone of its DMPlex with one dof per vertex."""

    def __init__(self, space):
        self.space = space
        dm = space.dm
        v0, v1 = dm.getDepthStratum(0)
        self.nlp = v1 - v0
        pdm = dm.clone()
        sec = PETSc.Section().create(comm=PETSc.COMM_SELF)
        sec.setNumFields(1)
        sec.setFieldComponents(0, 1)
        sec.setChart(*dm.getChart())
        for v in range(v0, v1):
            sec.setDof(v, 1)
            sec.setFieldDof(v, 0, 1)
        sec.setUp()
        pdm.setLocalSection(sec)
        self.dm = pdm
        self.owned = np.ascontiguousarray(space.owned[:self.nlp])
        self.owned_idx = np.flatnonzero(self.owned)
        self.n_owned = len(self.owned_idx)
        self.lgmap = pdm.getLGMap()
        self.lvec = pdm.createLocalVec()

    def global_vec(self):
        return self.dm.createGlobalVec()

    def to_local(self, g):
        self.dm.globalToLocal(g, self.lvec, addv=PETSc.InsertMode.INSERT_VALUES)
        return self.lvec.getArray(readonly=True).copy()

    def add_to_global(self, local, g):
        self.lvec.getArray()[:] = local
        g.zeroEntries()
        self.dm.localToGlobal(self.lvec, g, addv=PETSc.InsertMode.ADD_VALUES)

    def nodal(self, p, cells):
        """The P1 pressure at every P2 node (nlv,): the vertices' values, each edge node of the mixed cells (`cells`,
        on any rank) the mean of its two ends, 0 elsewhere (edges of compressible regions' cells only). Collective:
        an edge node's mixed cells may all be on another rank, so the edges' values and counts are summed over
        the ranks through the displacement space's vectors."""
        sp = self.space
        acc = np.zeros((sp.nlv, 3))
        for e, (i, j) in enumerate(EDGES):
            node = cells[:, 4 + e]
            acc[:, 0] += np.bincount(node, 0.5 * (p[cells[:, i]] + p[cells[:, j]]), minlength=sp.nlv)
            acc[:, 1] += np.bincount(node, minlength=sp.nlv)
        L, G = sp.local_vec(), sp.global_vec()
        L.getArray()[:] = acc.ravel()
        sp.add_to_global(L, G)
        sp.to_local(G, L)
        tot = L.getArray(readonly=True).reshape(-1, 3)
        out = np.where(tot[:, 1] > 0, tot[:, 0] / np.maximum(tot[:, 1], 1.0), 0.0)
        out[:self.nlp] = p
        L.destroy()
        G.destroy()
        return out


class PressureCoupling(Effect):
    """The pressure's terms of the mixed formulation (module docstring) on the local cells: its part of the
    displacement residual and tangent (an effect like the others, with cell blocks), and the pressure
    residual r_p, the coupling K_up and the block K_pp (for MixedSystem and the assembled operator)."""
    name = "volumetric"
    linear = False
    cell_blocks = True
    conservative = False      # a saddle point: the line search merit is the residual norm
    internal = True           # the pressure's part of the stress: internal forces, not a load

    def __init__(self, geometry, law, nlp, shear, idx=None):
        """geometry: the local cells (an ElementCells); idx: those of one material with a split, sorted (default
        all); law: its Volumetric; nlp: the local pressures; shear: its shear modulus (the Schur complement's
        preconditioner)."""
        super().__init__()
        self.kind, self.law, self.nlp, self.shear = law.kind, law, nlp, shear
        self.idx = np.arange(geometry.nc) if idx is None else np.asarray(idx, np.int64)
        if idx is not None:
            geometry = geometry.subset(self.idx)
        self.cells = np.ascontiguousarray(geometry.cells, dtype=kernels.IDX)      # (nc, 10)
        self.dofs = (3 * self.cells[:, :, None].astype(np.int64) + np.arange(3)).ravel()
        self.corners = np.ascontiguousarray(geometry.cells[:, :4])
        geo = geometry.geo
        self.nc, self.nq = geo.shape[0], geo.shape[1]
        self.w = np.ascontiguousarray(geo[:, :, 9])                   # |det J| w_q
        Jinv = geo[:, :, :9].reshape(self.nc, self.nq, 3, 3)
        self.g = np.ascontiguousarray(np.einsum("qak,cqkj->cqaj", geometry.dN, Jinv))   # gradients (nc, nq, 10, 3)
        pts = geometry.element.rule()[0]
        self.M = tet_shapes(1, pts)[0]                                # (nq, 4) the pressure's shape functions
        self.p = np.zeros(nlp)
        self.rp = np.zeros(nlp)
        self.blocks = None
        self.up = self.pp = None      # (K_up's and K_pp's cell blocks, once linearized)
        self.buffers = {}         # the C loops' output arrays, kept

    def set_pressure(self, p):
        self.p = p

    def _points(self, x):
        """(F, p, dG/dF as (nc, nq, 10, 3) per node and component, G) at the quadrature points."""
        xc = x.reshape(-1, 3)[self.cells]
        F = np.einsum("cai,cqaj->cqij", xc, self.g)
        pq = self._pq()
        if self.kind == "trace":
            return F, pq, self.g, np.trace(F, axis1=2, axis2=3) - 3.0, None
        J = np.linalg.det(F)
        h = np.einsum("cqji,cqaj->cqai", np.linalg.inv(F), self.g)    # h_a = F^-T g_a
        return F, pq, J[:, :, None, None] * h, J - 1.0, h

    def _pq(self):
        return self.p[self.corners] @ self.M.T                            # (nc, nq)

    @timed("evals")
    def residual(self, x, r):
        if self.kind == "J":                    # (the C loops of _kernels.c; _points is their numpy reference)
            pq = self._pq()
            out = kernels.pressure_terms(self.cells, self.g, self.w, x, pq, self.M, force=True, out=self.buffers)
            f, G = out["f"], out["J"] - 1.0
        else:
            _, pq, dG, G, _ = self._points(x)
            f = np.einsum("cq,cqm->cm", self.w * pq, dG.reshape(self.nc, self.nq, 30))
        r += np.bincount(self.dofs, f.ravel(), minlength=len(r))
        _, du, _ = self.law(pq)
        self.rp = np.bincount(self.corners.ravel(), (np.einsum("cq,qb->cb", self.w * (G - du), self.M)).ravel(),
                              minlength=self.nlp)

    def linearize(self, x):
        if self.kind == "J":
            pq = self._pq()
            _, _, d2 = self.law(pq)
            out = kernels.pressure_terms(self.cells, self.g, self.w, x, pq, self.M, tangent=True, out=self.buffers)
            self.up, self.blocks = out["up"], out["blocks"]
            self.pp = -np.einsum("cq,qb,qd->cbd", self.w * d2, self.M, self.M)
            return
        self.linearize_reference(x)

    def linearize_reference(self, x):
        """linearize in numpy (the reference of the C loops for kind "J", the path of kind "trace")."""
        F, pq, dG, _, h = self._points(x)
        n = self.nc
        _, _, d2 = self.law(pq)
        self.up = np.einsum("cqm,qb->cmb", dG.reshape(n, self.nq, 30) * self.w[:, :, None], self.M)
        self.pp = -np.einsum("cq,qb,qd->cbd", self.w * d2, self.M, self.M)
        if self.kind == "trace":
            self.blocks = None
            return
        h = h.reshape(n, self.nq, 30)
        K1 = np.matmul((h * (self.w * pq * np.linalg.det(F))[:, :, None]).transpose(0, 2, 1), h)   # sum c h_ai h_bk
        K1 = K1.reshape(n, 10, 3, 10, 3)
        self.blocks = np.ascontiguousarray((K1 - K1.transpose(0, 1, 4, 3, 2)).reshape(n, 30, 30))

    @timed("applies")
    def apply(self, v, y):
        if self.blocks is not None:
            vc = v.reshape(-1, 3)[self.cells].reshape(self.nc, 30)
            y += np.bincount(self.dofs, np.einsum("cij,cj->ci", self.blocks, vc).ravel(), minlength=len(y))

    @timed("applies")
    def diag(self, d):
        if self.blocks is not None:
            d += np.bincount(self.dofs, np.einsum("cii->ci", self.blocks).ravel(), minlength=len(d))

    def add_cell_blocks(self, vals, lo=0, hi=None):
        """vals (hi-lo, 30, 30) += its blocks of the cells lo..hi-1 among all the local cells."""
        if self.blocks is None:
            return
        hi = len(vals) + lo if hi is None else hi
        k0, k1 = np.searchsorted(self.idx, (lo, hi))              # (idx is sorted)
        if k1 == k0:
            return
        a, b = self.idx[k0] - lo, self.idx[k1 - 1] - lo + 1
        if b - a == k1 - k0:                                      # consecutive cells (all of them, one material)
            vals[a:b] += self.blocks[k0:k1]
        else:
            vals[self.idx[k0:k1] - lo] += self.blocks[k0:k1]

    def energy(self, x, v):
        """Its part of the elastic energy: int (p G - U*(p)) dV (at the solution, the volumetric energy)."""
        _, pq, _, G, _ = self._points(x)
        U, _, _ = self.law(pq)
        return {"elastic": float(np.sum(self.w * (pq * G - U)))}

    def schur_blocks(self):
        """(nc, 4, 4): -(1/mu + 1/kappa) int M_b M_c dV, the Schur complement's preconditioning blocks."""
        scale = -(1.0 / self.shear + (0.0 if math.isinf(self.law.kappa) else 1.0 / self.law.kappa))
        return scale * np.einsum("cq,qb,qd->cbd", self.w, self.M, self.M)
