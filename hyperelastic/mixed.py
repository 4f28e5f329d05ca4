"""The mixed displacement-pressure formulation (-formulation mixed): quadratic displacements and a continuous
linear pressure at the vertices (Taylor-Hood P2-P1, inf-sup stable: Brezzi & Fortin, Mixed and Hybrid Finite
Element Methods, 1991, sec. VI.6; Boffi, Brezzi & Fortin 2013, sec. 8.8).

A material with an isochoric/volumetric split (materials: `volumetric`, `split`) psi = psi_iso(F) + U(G),
G = J - 1 (the split Neo-Hookean, Mooney-Rivlin) or G = tr eps (linear, whose psi_iso is mu dev eps:dev eps),
takes the perturbed Lagrangian (Simo, Taylor & Pister, CMAME 51, 1985; Zienkiewicz & Taylor, vol. 2, ch. 5)

    Pi(u, p) = int [ psi_iso(F) + p G(F) - U*(p) ] dV  - (the loads' work),

U* the Legendre transform of U: U*(p) = p G_p - U(G_p) with U'(G_p) = p. Stationarity in p gives G = U*'(p),
i.e. p = U'(G), so eliminating p returns psi_iso + U exactly, at any bulk modulus: the mixed and the
displacement formulations are the same continuous problem, and p is the mean Cauchy stress (positive in
tension: sigma = sigma_iso + p I). For U = kappa/4 (J^2 - 1 - 2 ln J), U'(J) = kappa/2 (J - 1/J), so
J_p = s + sqrt(1 + s^2), s = p/kappa, U*'(p) = J_p - 1 and U*''(p) = 1 / U''(J_p) = 2 / (kappa (1 + J_p^-2));
for U = kappa/2 G^2, U* = p^2 / (2 kappa). The incompressible limit (-incompressible) is U* = 0: G = 0.

Discrete: with N_a the P2 shape functions (physical gradients g_a), M_b the P1 ones, h_a = F^-T g_a,
    r_u[a,i] += int p dG/dF : (e_i x g_a)          (J h_a,i for G = J - 1; g_a,i for tr eps)
    r_p[b]    = int (G - U*'(p)) M_b
    K_uu      += int p d2G[(e_i x g_a), (e_k x g_b)]  (J (h_a,i h_b,k - h_b,i h_a,k); 0 for tr eps)
    K_up[(a,i), b] = int dG/dF : (e_i x g_a) M_b,   K_pu = K_up^T,   K_pp[b,c] = -int U*''(p) M_b M_c
(the isochoric part is the material's own kernel with its volumetric modulus set to zero). The tangent is
symmetric and indefinite (a saddle point): Newton's line search uses the residual norm, and the linear
solver is a Schur-complement field split (solver.py) preconditioned by the pressure mass matrix scaled by
-(1/mu + 1/kappa) (Silvester & Wathen 1994; Elman, Silvester & Wathen 2014, ch. 4).

Unknowns: one global vector, on each rank its owned displacement dofs followed by its owned pressures
(`MixedSystem.is_u`, `is_p`); every effect sees the displacement part as before.
"""
import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import jacobians, kernels
from .effects.base import Effect, timed
from .element import EDGES, tet_shapes
from .errors import UserError
from .jacobians import effect_patterns, rigid_body_nullspace
from .system import System


def check_material(solid, where):
    """The (iso constants, mu, kappa) of a solid for the mixed formulation; UserError for a material without a
    volumetric split."""
    if solid.material.volumetric is None:
        raise UserError(f"option -formulation mixed: {where} material {solid.name} has no isochoric/volumetric "
                        "split; use neohookean_split, mooney_rivlin or linear")
    return solid.material.split(solid.values)


def iso_constants(solid):
    """The kernel's parameter block of a solid in the mixed formulation: its isochoric part where it has a split
    (the pressure carries the rest), else its own (a compressible region beside a mixed one)."""
    return solid.material.split(solid.values)[0] if solid.material.volumetric else solid.constants


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


def coo_aij(comm, n_rows, n_cols, rmap, cmap, rows, cols):
    """An AIJ matrix of n_rows x n_cols owned rows/columns, preallocated for the COO entries (rows, cols) in the
    local numberings of the LGMaps rmap and cmap."""
    A = PETSc.Mat().create(comm=comm)
    A.setSizes(((n_rows, PETSc.DETERMINE), (n_cols, PETSc.DETERMINE)))
    A.setType(PETSc.Mat.Type.AIJ)
    A.setLGMap(rmap, cmap)
    A.setPreallocationCOOLocal(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
    return A


def coupling_patterns(system):
    """Per coupling of the system: (its cells' displacement dofs (nc, 30), their local pressures (nc, 4)), and the
    COO entries of its blocks: K_up as (np.repeat(u, 4), np.tile(p, 30)) and K_pp as (np.repeat(p, 4),
    np.tile(p, 4)), each (rows, cols), both in cell order."""
    sp = system.space
    cd = (3 * sp.cells[:, :, None].astype(np.int64) + np.arange(3)).reshape(-1, 30)
    out = []
    for c in system.couplings:
        u, p = cd[c.idx], c.corners.astype(np.int64)
        out.append(((np.repeat(u, 4, axis=1).ravel(), np.tile(p, (1, 30)).ravel()),
                    (np.repeat(p, 4, axis=1).ravel(), np.tile(p, (1, 4)).ravel())))
    return cd, out


def offsets(mpi, n):
    """The first global index of each rank's n, and the total."""
    counts = np.array(mpi.allgather(int(n)), np.int64)
    return np.concatenate([[0], np.cumsum(counts)])


class MixedSystem(System):
    """System (system.py) of the mixed formulation: the unknown holds the displacement part and the pressure
    (module docstring); the effects, the Dirichlet elimination and the statistics act on the displacement
    part as in System, a PressureCoupling effect per material with a split adds the pressure's terms. With
    -regions, pressures at vertices no mixed cell touches (on any rank) are not unknowns of the problem: their
    rows are c p = 0 (c: the Schur preconditioner's mean diagonal), decoupled from the rest."""
    mixed = True

    def __init__(self, space, effects, constraints, x0, v0, dt, couplings, pspace):
        self.couplings = couplings
        self.pspace = ps = pspace
        mpi = space.mpi
        nu, npo = 3 * space.n_owned, ps.n_owned
        self.nu_owned = nu
        self.c_off = offsets(mpi, nu + npo)
        self.u_off = offsets(mpi, nu)
        self.p_off = offsets(mpi, npo)
        first = int(self.c_off[mpi.rank])
        self.is_u = PETSc.IS().createStride(nu, first, 1, comm=space.comm)
        self.is_u.setBlockSize(3)
        self.is_p = PETSc.IS().createStride(npo, first + nu, 1, comm=space.comm)
        self.p_owned = np.zeros(npo)             # the pressure of the current state (owned; global order)
        self._dead_pressures(mpi)
        super().__init__(space, effects, constraints, x0, v0, dt)
        self.constant_pressure_free = self._constant_pressure_free(mpi)

    def _constant_pressure_free(self, mpi):
        """Whether a constant pressure is a null vector of the tangent: every material incompressible (K_pp = 0),
        no dead pressures, and every displacement the volume depends on prescribed (d vol/dx = sum_q w g_a, the same
        in every configuration since the volume depends on the boundary only, zero on the free dofs: a part whose
        whole boundary moves as prescribed). Then the pressure is known up to a constant (kept at its start)."""
        if any(not math.isinf(c.law.kappa) for c in self.couplings) or mpi.allreduce(len(self.dead_owned)):
            return False
        dv = np.zeros(3 * self.space.nlv)
        scale = 0.0
        for c in self.couplings:
            f = np.einsum("cq,cqai->cai", c.w, c.g).reshape(c.nc, 3 * c.cells.shape[1])
            dv += np.bincount(c.dofs, f.ravel(), minlength=len(dv))
            scale = max(scale, float(np.abs(f).max(initial=0.0)))
        sp = self.space
        lv, gv = sp.local_vec(), sp.global_vec()
        lv.getArray()[:] = dv
        sp.add_to_global(lv, gv)                    # (a node's cells may be on several ranks)
        held = sp.owned_array(self.cmask.astype(float)) > 0
        free = float(np.abs(gv.getArray(readonly=True)[~held]).max(initial=0.0))
        return mpi.allreduce(free, op=MPI.MAX) <= 1e-10 * mpi.allreduce(scale, op=MPI.MAX)

    def constant_pressure_nullspace(self):
        """(the unknown's null space: a constant pressure, zero displacement; the pressures' own constant)."""
        z = self.unknown_vec()
        z.getArray()[self.nu_owned:] = 1.0
        z.normalize()
        zp = PETSc.NullSpace().create(constant=True, comm=self.space.comm)
        return PETSc.NullSpace().create(vectors=[z], comm=self.space.comm), zp

    def _dead_pressures(self, mpi):
        """The owned pressures no mixed cell touches on any rank (`dead_owned`: positions in the owned array) and
        their rows' scale c (the mean diagonal of the Schur preconditioner's blocks, the same on every rank)."""
        ps = self.pspace
        use = np.zeros(ps.nlp)
        diag, n = 0.0, 0
        for c in self.couplings:
            use += np.bincount(c.corners.ravel(), minlength=ps.nlp)
            d = np.einsum("cbb->cb", c.schur_blocks())
            diag, n = diag + float(d.sum()), n + d.size
        G = ps.global_vec()
        ps.add_to_global(use, G)
        self.dead_owned = np.flatnonzero(G.getArray(readonly=True) == 0)
        self.dead_local = ps.owned_idx[self.dead_owned]
        G.destroy()
        tot = mpi.allreduce(np.array([diag, n]))
        self.dead_scale = float(tot[0] / max(tot[1], 1.0)) or -1.0

    def set_pressure(self, p):
        for c in self.couplings:
            c.set_pressure(p)

    def unknown_vec(self):
        n = self.nu_owned + self.pspace.n_owned
        v = PETSc.Vec().createMPI((n, PETSc.DETERMINE), comm=self.space.comm)
        return v

    def set_guess(self, X, x):
        a = X.getArray()
        a[:self.nu_owned] = self.space.owned_array(x)
        a[self.nu_owned:] = self.p_owned
        self.impose_global(X)

    def local(self, X, lvec):
        if X.getLocalSize() == self.nu_owned:
            return super().local(X, lvec)
        Xu = X.getSubVector(self.is_u)
        try:
            return super().local(Xu, lvec)
        finally:
            X.restoreSubVector(self.is_u, Xu)

    def pressure_local(self, X):
        Xp = X.getSubVector(self.is_p)
        try:
            return self.pspace.to_local(Xp)
        finally:
            X.restoreSubVector(self.is_p, Xp)

    def residual(self, X, R):
        self.set_pressure(self.pressure_local(X))
        Xu, Ru = X.getSubVector(self.is_u), R.getSubVector(self.is_u)
        try:
            super().residual(Xu, Ru)
        finally:
            X.restoreSubVector(self.is_u, Xu)
            R.restoreSubVector(self.is_u, Ru)
        Rp = R.getSubVector(self.is_p)
        try:
            self.pspace.add_to_global(sum(c.rp for c in self.couplings), Rp)
            if len(self.dead_owned):
                Rp.getArray()[self.dead_owned] = (
                    self.dead_scale * X.getArray(readonly=True)[self.nu_owned:][self.dead_owned])
        finally:
            R.restoreSubVector(self.is_p, Rp)

    def linearize(self, X):
        self.set_pressure(self.pressure_local(X))
        super().linearize(X)

    def solved(self, X):
        self.set_pressure(self.pressure_local(X))

    def accept(self, X):
        """The state X was accepted: its pressure is the next step's start (and the output's)."""
        self.p_owned = X.getArray(readonly=True)[self.nu_owned:].copy()

    def nodal_state(self):
        return {"pressure": self.pressure_nodal()}

    def resume(self, state):
        if "pressure" in state:
            p = self.space.scatter(state["pressure"])[:self.pspace.nlp]
            self.p_owned = p[self.pspace.owned_idx].copy()

    def pressure_nodal(self):
        """The current pressure at every local P2 node (the output's point field)."""
        G = self.pspace.global_vec()
        G.getArray()[:] = self.p_owned
        p = self.pspace.to_local(G)
        G.destroy()
        return self.pspace.nodal(p, np.concatenate([c.cells for c in self.couplings]))

    def pressure_mass(self):
        """The Schur complement's preconditioning matrix -(1/mu + 1/kappa) M_p (pressure numbering; each material's
        own moduli), with c on the dead pressures' diagonal, assembled."""
        ps = self.pspace
        cells = np.concatenate([c.corners for c in self.couplings])
        dead = self.dead_local.astype(cells.dtype)
        rows = np.concatenate([np.repeat(cells, 4, axis=1).ravel(), dead])
        cols = np.concatenate([np.tile(cells, (1, 4)).ravel(), dead])
        vals = np.concatenate([c.schur_blocks().ravel() for c in self.couplings]
                              + [np.full(len(dead), self.dead_scale)])
        A = coo_aij(self.space.comm, ps.n_owned, ps.n_owned, ps.lgmap, ps.lgmap, rows, cols)
        A.setValuesCOO(vals, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()
        return A

    def combined_lgmap(self):
        """The LGMap of the local numbering (displacement dofs 0..3 nlv-1, then the local pressures) into the
        unknown's global numbering."""
        sp, ps = self.space, self.pspace
        gu = np.asarray(sp.lgmap.getIndices(), np.int64)
        gp = np.asarray(ps.lgmap.getIndices(), np.int64)
        ru = np.searchsorted(self.u_off, gu, side="right") - 1
        rp = np.searchsorted(self.p_off, gp, side="right") - 1
        cu = self.c_off[ru] + gu - self.u_off[ru]
        cp = self.c_off[rp] + (self.u_off[rp + 1] - self.u_off[rp]) + gp - self.p_off[rp]
        idx = np.concatenate([cu, cp]).astype(PETSc.IntType)
        return PETSc.LGMap().create(idx, comm=sp.comm)


class MixedAssembled:
    """The mixed tangent [[K_uu, K_up], [K_pu, K_pp]] as one AIJ matrix, filled by COO: the displacement
    effects' cell blocks and their extra entries, each coupling's blocks, the constrained rows' s I (zero in
    their columns, as in jacobians.Assembled), the dead pressures' c. The displacement block gets the rigid-body
    near null space through is_u (PCFIELDSPLIT hands it to the split's matrix). Any preconditioner (LU of the
    whole, the field split); the default under the field split is MixedNest."""

    def __init__(self, system):
        self.system = s = system
        sp = s.space
        nlu = 3 * sp.nlv
        self.cell_effects = [e for e in s.effects if e.cell_blocks]
        cd, patterns = coupling_patterns(s)
        rows, cols = [np.repeat(cd, 30, axis=1).ravel()], [np.tile(cd, (1, 30)).ravel()]
        for (ur, pc), (pr, pcc) in patterns:            # K_up, K_pu (K_up's pairs swapped), K_pp; pressures after nlu
            rows += [ur, nlu + pc, nlu + pr]
            cols += [nlu + pc, ur, nlu + pcc]
        self.other, n = effect_patterns(s.effects, rows, cols)
        c_owned_local = (3 * sp.lvid_of_owned[:, None] + np.arange(3)).ravel()[s.c_owned_pos]
        dead = nlu + s.dead_local.astype(np.int64)
        self.diag_slice = slice(n, n + len(c_owned_local))
        self.dead_slice = slice(n + len(c_owned_local), n + len(c_owned_local) + len(dead))
        rows += [c_owned_local, dead]
        cols += [c_owned_local, dead]
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        cm = np.concatenate([s.cmask, np.zeros(s.pspace.nlp, bool)])
        zero = cm[rows] | cm[cols]
        zero[self.diag_slice] = False
        self.zero = np.flatnonzero(zero)
        self.nc = len(cd)
        self.vals = np.zeros(len(rows))
        nloc, lg = s.nu_owned + s.pspace.n_owned, s.combined_lgmap()
        self.mat = self.operator = coo_aij(sp.comm, nloc, nloc, lg, lg, rows, cols)
        self.nullspace = rigid_body_nullspace(sp)
        s.is_u.compose("nearnullspace", self.nullspace)

    def update(self):
        s, n = self.system, self.nc
        v = self.vals
        uu = v[:n * 900].reshape(n, 30, 30)
        uu[:] = 0.0
        for e in self.cell_effects:
            e.add_cell_blocks(uu)
        o = n * 900
        for c in s.couplings:
            k = len(c.idx) * 120
            v[o:o + k] = c.up.ravel()
            v[o + k:o + 2 * k] = v[o:o + k]                        # (K_pu's entries: K_up's, row and column swapped)
            v[o + 2 * k:o + 2 * k + len(c.idx) * 16] = c.pp.ravel()
            o += 2 * k + len(c.idx) * 16
        for e, sl in self.other:
            e.coo_values(v[sl])
        v[self.diag_slice] = s.scale
        v[self.dead_slice] = s.dead_scale
        v[self.zero] = 0.0
        self.mat.setValuesCOO(v, addv=PETSc.InsertMode.INSERT_VALUES)
        self.mat.assemble()


class MixedNest:
    """The mixed tangent by blocks (under the field split): `mat` (what the preconditioner is built from) is a
    MatNest [[K_uu, K_up], [K_pu, K_pp]] over is_u and is_p; with storage `sbaij` (the default where K_uu is
    symmetric) `operator` (what the Krylov method multiplies by) has the same blocks with K_uu's SBAIJ copy. K_uu is
    the displacement formulation's assembled tangent (jacobians.AssembledChunked: cell blocks straight into the CSR
    values, with the rigid-body near null space), the couplings' geometric blocks among its cell effects; K_up, K_pu
    and K_pp (with the dead pressures' c) are filled by COO, zero in the constrained displacement rows. PCFIELDSPLIT
    takes the blocks without copies (-pc_fieldsplit_diag_use_amat: the displacement split's GAMG smooths with the
    SBAIJ copy)."""

    def __init__(self, system, storage="sbaij"):
        self.system = s = system
        sp, ps = s.space, s.pspace
        self.uu = jacobians.AssembledChunked(s, storage=storage)
        _, patterns = coupling_patterns(s)
        dead = s.dead_local.astype(np.int64)
        up_r, up_c = (np.concatenate(x) for x in zip(*(up for up, _ in patterns)))
        pp_r, pp_c = (np.concatenate(list(x) + [dead]) for x in zip(*(pp for _, pp in patterns)))
        self.up_zero = np.flatnonzero(s.cmask[up_r])              # constrained displacement rows (columns of K_pu)
        self.up_vals = np.zeros(len(up_r))
        self.pp_vals = np.zeros(len(pp_r))
        self.n_pp = len(pp_r) - len(dead)
        nu, npo = s.nu_owned, ps.n_owned
        self.K_up = coo_aij(sp.comm, nu, npo, sp.lgmap, ps.lgmap, up_r, up_c)
        self.K_pu = coo_aij(sp.comm, npo, nu, ps.lgmap, sp.lgmap, up_c, up_r)
        self.K_pp = coo_aij(sp.comm, npo, npo, ps.lgmap, ps.lgmap, pp_r, pp_c)
        self._fill_coupling()                                     # (the nests want assembled blocks)
        self.uu.mat.assemble()
        if self.uu.copy is not None:
            self.uu.copy.refresh(self.uu.map.nnz)
        fields = [s.is_u, s.is_p]
        self.mat = self.operator = PETSc.Mat().createNest([[self.uu.mat, self.K_up], [self.K_pu, self.K_pp]],
                                                          isrows=fields, iscols=fields, comm=sp.comm)
        if self.uu.operator is not self.uu.mat:
            self.operator = PETSc.Mat().createNest([[self.uu.operator, self.K_up], [self.K_pu, self.K_pp]],
                                                   isrows=fields, iscols=fields, comm=sp.comm)
        self.nullspace = self.uu.nullspace
        s.is_u.compose("nearnullspace", self.nullspace)

    def _fill_coupling(self):
        s, o, q = self.system, 0, 0
        for c in s.couplings:
            k, m = len(c.idx) * 120, len(c.idx) * 16
            if getattr(c, "up", None) is not None:             # (linearized)
                self.up_vals[o:o + k] = c.up.ravel()
                self.pp_vals[q:q + m] = c.pp.ravel()
            o, q = o + k, q + m
        self.up_vals[self.up_zero] = 0.0
        self.pp_vals[self.n_pp:] = s.dead_scale
        INSERT = PETSc.InsertMode.INSERT_VALUES
        self.K_up.setValuesCOO(self.up_vals, addv=INSERT)
        self.K_pu.setValuesCOO(self.up_vals, addv=INSERT)
        self.K_pp.setValuesCOO(self.pp_vals, addv=INSERT)
        for A in (self.K_up, self.K_pu, self.K_pp):
            A.assemble()

    def update(self):
        self.uu.assemble()
        self._fill_coupling()
        self.mat.assemble()          # (a new state: the field split sets its blocks up again)
        if self.operator is not self.mat:
            self.operator.assemble()


# -formulation auto takes the mixed formulation from this bulk-to-shear ratio kappa/mu up (nu >= 0.495), where the
# element order and the solver allow it: measured on Lame's cylinder, docs/mixed.md "Which formulation by default"
AUTO_RATIO = 100.0


def bulk_to_shear(solid):
    """kappa/mu of a solid: its split's moduli where it has one, else from E and nu."""
    if solid.material.volumetric:
        _, mu, kappa = solid.material.split(solid.values)
        return kappa / mu
    nu = solid.values["nu"]
    return 2 * (1 + nu) / (3 * (1 - 2 * nu))


def choose_formulation(scene):
    """(formulation, note or None) for the scene, its mesh's order known: -formulation auto is `mixed` where some
    material has kappa/mu >= AUTO_RATIO and a split, the elements are quadratic and the run's paths allow it (the
    note says so), else `displacement` (with a note where linear tetrahedra would lock)."""
    if scene.formulation != "auto":
        return scene.formulation, None
    solids = [scene.solid] + [r.solid for r in scene.regions]
    ratio = max(bulk_to_shear(sol) for sol in solids)
    if ratio < AUTO_RATIO:
        return "displacement", None
    nu = (3 * ratio - 2) / (2 * (3 * ratio + 1))
    what = f"nearly incompressible (kappa/mu = {ratio:.3g}, nu = {nu:.5g})"
    if scene.order != 2:
        return "displacement", (f"{what}: linear tetrahedra lock (too stiff); -order 2 takes the mixed "
                                "displacement-pressure formulation (docs/mixed.md)")
    try:
        check_scene(scene, scene.jacobian, scene.integrator)
    except UserError as e:
        return "displacement", f"{what}, displacements alone: the mixed formulation {str(e).split(': ', 1)[1]}"
    return "mixed", (f"{what}: -formulation auto takes the mixed displacement-pressure formulation (-formulation "
                     "displacement: displacements alone)")


def check_scene(scene, jacobian, integrator):
    """The paths the mixed formulation does not take, each refused with one line."""
    what = "option -incompressible (a pressure field)" if scene.incompressible else "option -formulation mixed"
    if scene.order != 2:
        raise UserError(f"{what}: needs quadratic tetrahedra (-order 2: Taylor-Hood P2-P1); equal-order P1-P1 is "
                        "not inf-sup stable")
    if jacobian != "assembled":
        raise UserError(f"{what}: the tangent is assembled (-jacobian assembled; -snes_mf_operator works), not "
                        f"-jacobian {jacobian}")
    if integrator != "beuler":
        raise UserError(f"{what}: quasi-static and backward Euler runs (-integrator beuler), not -integrator "
                        f"{integrator}")
    solids = [("the scene's", scene.solid)] + [(f"region '{r.name}'", r.solid) for r in scene.regions]
    if not any(sol.material.volumetric for _, sol in solids):
        where, sol = solids[0]
        check_material(sol, where)

