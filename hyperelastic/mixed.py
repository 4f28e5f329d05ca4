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
from petsc4py import PETSc

from .effects.base import Effect, timed
from .element import EDGES, tet_shapes
from .errors import UserError
from .system import System


def check_material(solid, where):
    """The (iso constants, mu, kappa) of a solid for the mixed formulation; UserError for a material without a
    volumetric split."""
    if solid.material.volumetric is None:
        raise UserError(f"option -formulation mixed: {where} material {solid.name} has no isochoric/volumetric "
                        "split; use neohookean_split, mooney_rivlin or linear")
    return solid.material.split(solid.values)


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
        """The P1 pressure at every P2 node (nlv,): the vertices' values, and each edge node the mean of its two."""
        out = np.zeros(self.space.nlv)
        out[:self.nlp] = p
        for e, (i, j) in enumerate(EDGES):
            out[cells[:, 4 + e]] = 0.5 * (p[cells[:, i]] + p[cells[:, j]])
        return out


class PressureCoupling(Effect):
    """The pressure's terms of the mixed formulation (module docstring) on the local cells: its part of the
    displacement residual and tangent (an effect like the others, with cell blocks), and the pressure
    residual r_p, the coupling K_up and the block K_pp (for MixedSystem and the assembled operator)."""
    name = "volumetric"
    linear = False
    cell_blocks = True
    conservative = False      # a saddle point: the line search merit is the residual norm

    def __init__(self, geometry, kind, law, nlp):
        super().__init__()
        self.kind, self.law, self.nlp = kind, law, nlp
        self.cells = geometry.cells                                   # (nc, 10)
        self.dofs = (3 * self.cells[:, :, None].astype(np.int64) + np.arange(3)).ravel()
        self.corners = np.ascontiguousarray(geometry.cells[:, :4])
        geo = geometry.geo
        self.nc, self.nq = geo.shape[0], geo.shape[1]
        self.w = np.ascontiguousarray(geo[:, :, 9])                   # |det J| w_q
        Jinv = geo[:, :, :9].reshape(self.nc, self.nq, 3, 3)
        self.g = np.einsum("qak,cqkj->cqaj", geometry.dN, Jinv)       # physical gradients (nc, nq, 10, 3)
        pts = geometry.element.rule()[0]
        self.M = tet_shapes(1, pts)[0]                                # (nq, 4) the pressure's shape functions
        self.p = np.zeros(nlp)
        self.rp = np.zeros(nlp)
        self.x = None
        self.blocks = None

    def set_pressure(self, p):
        self.p = p

    def _points(self, x):
        """(F, p, dG/dF as (nc, nq, 10, 3) per node and component, G) at the quadrature points."""
        xc = x.reshape(-1, 3)[self.cells]
        F = np.einsum("cai,cqaj->cqij", xc, self.g)
        pq = self.p[self.corners] @ self.M.T                          # (nc, nq)
        if self.kind == "trace":
            return F, pq, self.g, np.trace(F, axis1=2, axis2=3) - 3.0, None
        J = np.linalg.det(F)
        h = np.einsum("cqji,cqaj->cqai", np.linalg.inv(F), self.g)    # h_a = F^-T g_a
        return F, pq, J[:, :, None, None] * h, J - 1.0, h

    @timed("evals")
    def residual(self, x, r):
        _, pq, dG, G, _ = self._points(x)
        f = np.einsum("cq,cqm->cm", self.w * pq, dG.reshape(self.nc, self.nq, 30))
        r += np.bincount(self.dofs, f.ravel(), minlength=len(r))
        _, du, _ = self.law(pq)
        self.rp = np.bincount(self.corners.ravel(), (np.einsum("cq,qb->cb", self.w * (G - du), self.M)).ravel(),
                              minlength=self.nlp)

    def linearize(self, x):
        self.x = x.copy()
        F, pq, dG, _, h = self._points(self.x)
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
        if self.blocks is not None:
            vals += self.blocks[lo:hi]

    def energy(self, x, v):
        """Its part of the elastic energy: int (p G - U*(p)) dV (at the solution, the volumetric energy)."""
        _, pq, _, G, _ = self._points(x)
        U, _, _ = self.law(pq)
        return {"elastic": float(np.sum(self.w * (pq * G - U)))}

    def mass(self):
        """(nc, 4, 4) the pressure mass blocks int M_b M_c dV."""
        return np.einsum("cq,qb,qd->cbd", self.w, self.M, self.M)


def offsets(mpi, n):
    """The first global index of each rank's n, and the total."""
    counts = np.array(mpi.allgather(int(n)), np.int64)
    return np.concatenate([[0], np.cumsum(counts)])


class MixedSystem(System):
    """System (system.py) of the mixed formulation: the unknown holds the displacement part and the pressure
    (module docstring); the effects, the Dirichlet elimination and the statistics act on the displacement
    part as in System, the PressureCoupling effect adds the pressure's terms."""
    mixed = True

    def __init__(self, space, effects, constraints, x0, v0, dt, coupling, shear, pspace):
        self.coupling = coupling
        self.shear = shear                       # the shear modulus (the Schur complement's scale)
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
        self.Xu = None
        super().__init__(space, effects, constraints, x0, v0, dt)

    def unknown_vec(self):
        n = self.nu_owned + self.pspace.n_owned
        v = PETSc.Vec().createMPI((n, PETSc.DETERMINE), comm=self.space.comm)
        return v

    def global_state(self, x):
        X = self.unknown_vec()
        a = X.getArray()
        a[:self.nu_owned] = self.space.owned_array(x)
        a[self.nu_owned:] = self.p_owned
        self.impose_global(X)
        return X

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
        if X.getLocalSize() == self.nu_owned:       # (the base class's calibration, on displacements alone)
            return super().residual(X, R)
        self.coupling.set_pressure(self.pressure_local(X))
        Xu, Ru = X.getSubVector(self.is_u), R.getSubVector(self.is_u)
        try:
            super().residual(Xu, Ru)
        finally:
            X.restoreSubVector(self.is_u, Xu)
            R.restoreSubVector(self.is_u, Ru)
        Rp = R.getSubVector(self.is_p)
        try:
            self.pspace.add_to_global(self.coupling.rp, Rp)
        finally:
            R.restoreSubVector(self.is_p, Rp)

    def linearize(self, X):
        if X.getLocalSize() != self.nu_owned:
            self.coupling.set_pressure(self.pressure_local(X))
        super().linearize(X)

    def solved(self, X):
        self.coupling.set_pressure(self.pressure_local(X))

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
        return self.pspace.nodal(p, self.space.cells)

    def pressure_mass(self):
        """The Schur complement's preconditioning matrix -(1/mu + 1/kappa) M_p (pressure numbering), assembled."""
        ps, cells = self.pspace, self.coupling.corners
        law = self.coupling.law
        scale = -(1.0 / self.shear + (0.0 if math.isinf(law.kappa) else 1.0 / law.kappa))
        rows = np.repeat(cells, 4, axis=1).ravel()
        cols = np.tile(cells, (1, 4)).ravel()
        A = PETSc.Mat().create(comm=self.space.comm)
        A.setSizes(((ps.n_owned, PETSc.DETERMINE), (ps.n_owned, PETSc.DETERMINE)))
        A.setType(PETSc.Mat.Type.AIJ)
        A.setLGMap(ps.lgmap, ps.lgmap)
        A.setPreallocationCOOLocal(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
        A.setValuesCOO(scale * self.coupling.mass().ravel(), addv=PETSc.InsertMode.INSERT_VALUES)
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
    effects' cell blocks and their extra entries, the coupling blocks, the constrained rows' s I (zero in
    their columns, as in jacobians.Assembled). The displacement block gets the rigid-body near null space
    through is_u (PCFIELDSPLIT hands it to the split's matrix)."""

    def __init__(self, system):
        self.system = s = system
        sp, c = s.space, s.coupling
        nlu = 3 * sp.nlv
        self.cell_effects = [e for e in s.effects if e.cell_blocks]
        cd = (3 * sp.cells[:, :, None].astype(np.int64) + np.arange(3)).reshape(-1, 30)
        pd = nlu + c.corners.astype(np.int64)
        rows = [np.repeat(cd, 30, axis=1).ravel(), np.repeat(cd, 4, axis=1).ravel(),
                np.repeat(pd, 30, axis=1).ravel(), np.repeat(pd, 4, axis=1).ravel()]
        cols = [np.tile(cd, (1, 30)).ravel(), np.tile(pd, (1, 30)).ravel(),
                np.tile(cd, (1, 4)).ravel(), np.tile(pd, (1, 4)).ravel()]
        n = sum(map(len, rows))
        self.other = []
        for e in s.effects:
            r, cc = e.coo_pattern()
            if len(r):
                self.other.append((e, slice(n, n + len(r))))
                rows.append(r)
                cols.append(cc)
                n += len(r)
        c_owned_local = (3 * sp.lvid_of_owned[:, None] + np.arange(3)).ravel()[s.c_owned_pos]
        self.diag_slice = slice(n, n + len(c_owned_local))
        rows.append(c_owned_local)
        cols.append(c_owned_local)
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        cm = np.concatenate([s.cmask, np.zeros(s.pspace.nlp, bool)])
        zero = cm[rows] | cm[cols]
        zero[self.diag_slice] = False
        self.zero = np.flatnonzero(zero)
        self.nc = len(cd)
        self.vals = np.zeros(len(rows))
        A = PETSc.Mat().create(comm=sp.comm)
        nloc = s.nu_owned + s.pspace.n_owned
        A.setSizes(((nloc, PETSc.DETERMINE), (nloc, PETSc.DETERMINE)))
        A.setType(PETSc.Mat.Type.AIJ)
        lg = s.combined_lgmap()
        A.setLGMap(lg, lg)
        A.setPreallocationCOOLocal(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
        self.mat = self.operator = A
        coords = sp.global_vec()
        coords.getArray()[:] = sp.owned_array(sp.X.ravel())
        self.nullspace = PETSc.NullSpace().createRigidBody(coords)
        s.is_u.compose("nearnullspace", self.nullspace)
        coords.destroy()

    def update(self):
        s, c, n = self.system, self.system.coupling, self.nc
        v = self.vals
        uu = v[:n * 900].reshape(n, 30, 30)
        uu[:] = 0.0
        for e in self.cell_effects:
            e.add_cell_blocks(uu)
        o = n * 900
        v[o:o + n * 120] = c.up.ravel()
        o += n * 120
        v[o:o + n * 120] = c.up.transpose(0, 2, 1).ravel()
        o += n * 120
        v[o:o + n * 16] = c.pp.ravel()
        for e, sl in self.other:
            e.coo_values(v[sl])
        v[self.diag_slice] = s.scale
        v[self.zero] = 0.0
        self.mat.setValuesCOO(v, addv=PETSc.InsertMode.INSERT_VALUES)
        self.mat.assemble()


def check_scene(scene, jacobian, integrator):
    """The paths the mixed formulation does not take, each refused with one line."""
    what = "option -formulation mixed"
    if scene.order != 2:
        raise UserError(f"{what}: needs quadratic tetrahedra (-order 2: Taylor-Hood P2-P1); equal-order P1-P1 is "
                        "not inf-sup stable")
    if jacobian != "assembled":
        raise UserError(f"{what}: the tangent is assembled (-jacobian assembled; -snes_mf_operator works), not "
                        f"-jacobian {jacobian}")
    if integrator != "beuler":
        raise UserError(f"{what}: quasi-static and backward Euler runs (-integrator beuler), not -integrator "
                        f"{integrator}")
    if scene.regions:
        raise UserError(f"{what}: not yet with -regions (one material for the whole part)")

