"""The mixed formulation's system: one unknown vector holding each rank's owned displacement dofs and then its owned
pressures (is_u, is_p), the residual and the state of both, the Schur complement's preconditioning matrix (the
pressure mass matrix scaled per material), and a constant pressure's null space where the boundary is all held."""
import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ...solving.system import System


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
        super().resume(state)
        if "pressure" in state:
            p = self.space.read_state(state["pressure"])[:self.pspace.nlp]
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

    def augmentation(self, factor):
        """(Gamma, S), Vecs over the owned pressures, of the augmented Lagrangian with gamma = factor * mu of each
        material (formulations/mixed/operators.Augmented): from the lumped pressure mass W_i = sum_c m_ci (m_ci =
        int_c N_i dV), Gamma_i = gamma_i / W_i with gamma_i = sum_c gamma_c m_ci / W_i (the augmentation's weight:
        gamma B^T W^-1 B for one material), and the Schur complement's preconditioner S_i = -sum_c (1 / (mu_c +
        gamma_c) + 1 / kappa_c) m_ci. The dead pressures: Gamma 0 (not augmented) and S their rows' c."""
        ps = self.pspace
        lumped = [np.einsum("cq,qb->cb", c.w, c.M).ravel() for c in self.couplings]      # m_ci, per cell corner
        sums = []
        for weight in ("mass", "gamma", "schur"):
            lp = np.zeros(ps.nlp)
            for c, m in zip(self.couplings, lumped):
                gamma = factor * c.shear
                inv_kappa = 0.0 if math.isinf(c.law.kappa) else 1.0 / c.law.kappa
                scale = {"mass": 1.0, "gamma": gamma, "schur": -(1.0 / (c.shear + gamma) + inv_kappa)}[weight]
                lp += np.bincount(c.corners.ravel(), scale * m, minlength=ps.nlp)
            G = ps.global_vec()
            ps.add_to_global(lp, G)
            sums.append(G)
        W, Gamma, S = sums
        w = W.getArray()
        w[self.dead_owned] = 1.0
        Gamma.getArray()[:] /= w * w
        Gamma.getArray()[self.dead_owned] = 0.0
        S.getArray()[self.dead_owned] = self.dead_scale
        W.destroy()
        return Gamma, S

    def unknown_numbers(self, g):
        """The unknowns' global numbers (displacements and pressures, rank by rank) of global displacement dof numbers
        g (the displacement formulation's numbering)."""
        g = np.asarray(g, np.int64)
        r = np.searchsorted(self.u_off, g, side="right") - 1
        return self.c_off[r] + g - self.u_off[r]

    def combined_lgmap(self):
        """The LGMap of the local numbering (displacement dofs 0..3 nlv-1, then the local pressures) into the
        unknown's global numbering."""
        sp, ps = self.space, self.pspace
        gu = np.asarray(sp.lgmap.getIndices(), np.int64)
        gp = np.asarray(ps.lgmap.getIndices(), np.int64)
        rp = np.searchsorted(self.p_off, gp, side="right") - 1
        cu = self.unknown_numbers(gu)
        cp = self.c_off[rp] + (self.u_off[rp + 1] - self.u_off[rp]) + gp - self.p_off[rp]
        idx = np.concatenate([cu, cp]).astype(PETSc.IntType)
        return PETSc.LGMap().create(idx, comm=sp.comm)
