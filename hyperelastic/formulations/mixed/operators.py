"""The mixed formulation's tangent: one AIJ matrix filled by COO (MixedAssembled: any preconditioner of the whole), or
by blocks under the field split (MixedNest: K_uu the displacement formulation's assembled tangent, K_up, K_pu, K_pp
by COO). Self-contact's pairs between distant surface nodes act on the displacements alone: they are multiplied
beside the matrix (jacobians.Coupled), in K_uu's block or in the whole's numbering."""
import numpy as np
from petsc4py import PETSc

from ...discretization import aij
from ...element.reference import p1_at_nodes
from ...physics.effects.base import cell_blocks
from ...solving import jacobians, pmg
from ...solving.jacobians import effect_patterns, rigid_body_nullspace
from .system import coo_aij, coupling_patterns


class MixedAssembled:
    """The mixed tangent [[K_uu, K_up], [K_pu, K_pp]] as one AIJ matrix, filled by COO: the displacement
    effects' cell blocks and their extra entries, each coupling's blocks, the constrained rows' s I (zero in
    their columns, as in jacobians.Assembled), the dead pressures' c. The displacement block gets the rigid-body
    near null space through is_u (PCFIELDSPLIT hands it to the split's matrix). Any preconditioner (LU of the
    whole, the field split); the default under the field split is MixedNest."""
    augmented = None          # (MixedNest: the augmented Lagrangian's preconditioning matrix, where used)
    fills_coarse = False

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
        # (self-contact's pairs between surface nodes: multiplied beside the matrix, in the unknowns' numbering)
        jacobians.Coupled.around(self, s, numbering=s.unknown_numbers)

    def update(self):
        s, n = self.system, self.nc
        v = self.vals
        uu = v[:n * 900].reshape(n, 30, 30)
        cell_blocks(self.cell_effects, uu)
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
    augmented = None          # (set in the constructor where -mixed_augment > 0)
    fills_coarse = False

    def __init__(self, system, storage="sbaij", augment=0.0):
        self.system = s = system
        sp, ps = s.space, s.pspace
        # K_uu with self-contact's pairs between surface nodes beside it (jacobians.Coupled: in `operator`, what the
        # Krylov method multiplies by; the preconditioner is built from the cells' blocks)
        self.uu = jacobians.Coupled.around(jacobians.AssembledChunked(s, storage=storage), s)
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
        # (gamma/mu > 0: the preconditioner is built from the augmented Lagrangian's matrix, Augmented below)
        self.augmented = Augmented(self, augment) if augment > 0 else None
        if self.augmented is not None:
            self.mat = self.augmented.mat

    def _fill_coupling(self):
        s, o, q = self.system, 0, 0
        for c in s.couplings:
            k, m = len(c.idx) * 120, len(c.idx) * 16
            if c.up is not None:             # (linearized)
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
        self.uu.update()
        self._fill_coupling()
        if self.augmented is not None:
            self.augmented.update()
        self.mat.assemble()          # (a new state: the field split sets its blocks up again)
        if self.operator is not self.mat:
            self.operator.assemble()


class Augmented:
    """The augmented-Lagrangian preconditioning matrix of a MixedNest (issue 49 item 2: thin walls). The saddle point
    J = [[A, B^T], [B, C]] (A = K_uu, B = K_pu, C = K_pp) is, after T = [[I, B^T Gamma], [0, I]] (Gamma: the lumped
    pressure mass's inverse times gamma, MixedSystem.augmentation), T J = [[A + B^T Gamma B, B^T + B^T Gamma C], [B,
    C]], with the same solution; for gamma of a few mu its Schur complement is close to -(1/(mu + gamma) + 1/kappa) W
    (W the lumped pressure mass) whatever the part's shape, where -(1/mu + 1/kappa) M_p is not on thin walls (the
    inf-sup constant of a thin domain is small): Benzi & Olshanskii, SIAM J. Sci. Comput. 28 (2006); Farrell, Mitchell
    & Wechsung, SIAM J. Sci. Comput. 41 (2019). The upper block-triangular preconditioner P of T J, applied to T r,
    is P^-1 T = (T^-1 P)^-1 with T^-1 P = [[A + B^T Gamma B, B^T + B^T Gamma (C - S)], [0, S]]: PCFIELDSPLIT's upper
    Schur factorization of J with that preconditioning matrix, `mat` here (the Krylov method still multiplies by J).
    Nothing wider than the tangent's pattern is assembled: A + B^T Gamma B is a MATCOMPOSITE of K_uu and the MATNORMAL
    of Gamma^(1/2) B (its diagonal for the smoother's Jacobi), the coupling a MATCOMPOSITE of products; p-multigrid's
    P1 operator gets the term cell by cell (coarse_term, added to P^T K_uu P). The displacement split's p-multigrid
    holds under it where its P1 operator is solved well (four Chebyshev iterations of its GAMG: solver.py
    AUGMENTED_DEFAULTS): the rubber bracket 48 -> 22 GMRES iterations per Newton step at gamma = 3 mu (BENCHMARKS.md;
    GAMG on the assembled augmented block did not hold: 64 -> 68)."""

    def __init__(self, nest, factor):
        s = nest.system
        self.nest, self.factor = nest, factor
        gamma, S = s.augmentation(factor)
        self.gamma, self.root = gamma, gamma.copy()
        self.root.sqrtabs()
        self.minus_S = S.copy()
        self.minus_S.scale(-1.0)
        comm = s.space.comm
        self.G = nest.K_pu.duplicate(copy=True)              # Gamma^(1/2) B
        self.E = nest.K_pp.duplicate(copy=True)              # Gamma (C - S)
        self._refresh()
        self.normal = PETSc.Mat().createNormal(self.G)       # B^T Gamma B
        self.uu = PETSc.Mat().createComposite([nest.uu.operator, self.normal], comm=comm)
        product = PETSc.Mat().createComposite([self.E, nest.K_up], comm=comm)    # (applied in order: K_up (E x))
        product.setCompositeType(PETSc.Mat.CompositeType.MULTIPLICATIVE)
        product.assemble()
        self.up = PETSc.Mat().createComposite([nest.K_up, product], comm=comm)
        self.schur = PETSc.Mat().createAIJ(((S.getLocalSize(), PETSc.DETERMINE),) * 2, nnz=(1, 0), comm=comm)
        self.schur.setDiagonal(S)
        self.schur.assemble()
        S.destroy()
        fields = [s.is_u, s.is_p]
        self.mat = PETSc.Mat().createNest([[self.uu, self.up], [nest.K_pu, nest.K_pp]], isrows=fields,
                                          iscols=fields, comm=comm)
        self.uu.setNearNullSpace(nest.nullspace)
        self.p0 = None             # (the P1 term, its P_c, the cells' held dofs: coarse_term)

    def _refresh(self):
        SAME = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        self.nest.K_pu.copy(self.G, structure=SAME)
        self.G.diagonalScale(L=self.root)
        self.nest.K_pp.copy(self.E, structure=SAME)
        self.E.setDiagonal(self.minus_S, addv=PETSc.InsertMode.ADD_VALUES)
        self.E.diagonalScale(L=self.gamma)

    def update(self):
        """After the nest's blocks took a new state's values."""
        self._refresh()
        for A in (self.uu, self.up, self.mat):
            A.assemble()

    def coarse_term(self, P):
        """The augmentation of p-multigrid's P1 operator P^T K_uu P, cell by cell: sum_c gamma_c / |c| (P_c^T b_c)
        (P_c^T b_c)^T, b_c = sum_i K_up[c][:, i] (the cell's rate of volume change: its grad-div with the divergence
        projected on constants; P_c the cell's rows of P), the held dofs' entries zero. Its pattern is P1's own (the
        Galerkin product (Gamma^(1/2) B P)^T (Gamma^(1/2) B P) couples each vertex to its 2-ring: denser than the P2
        operator at 9k tets, and Cook's membrane 1.38x slower with it), and the coarse correction holds as well (the
        bracket 20.9 GMRES per Newton step with the Galerkin product, 22.0 with this; BENCHMARKS.md). Filled as
        p-multigrid's own P1 operator is (pmg.VertexSpace, aij.CellFill: the layout of P's columns), set up at the
        first call; P is the interpolation on the same vertices."""
        s = self.nest.system
        sp = s.space
        if self.p0 is None:
            Pc = np.kron(p1_at_nodes(), np.eye(3))        # (30, 12): a cell's rows of P, per component
            vs = pmg.VertexSpace(sp, pmg.coarse_numbers(sp))
            idx = np.concatenate([c.idx for c in s.couplings])
            chunk = self.nest.uu.chunk
            fill = aij.CellFill(vs, np.ascontiguousarray(vs.cells[idx]))
            cd = (3 * sp.cells[:, :, None].astype(np.int64) + np.arange(3)).reshape(-1, 30)
            self.p0 = (fill, Pc, [s.cmask[cd[c.idx]] for c in s.couplings], chunk)
        fill, Pc, held, chunk = self.p0
        blocks = []
        for c, h in zip(s.couplings, held):
            b = c.up.sum(axis=2)
            b[h] = 0.0
            b1 = b @ Pc
            g = self.factor * c.shear / c.w.sum(axis=1)
            blocks.append(g[:, None, None] * b1[:, :, None] * b1[:, None, :])
        blocks = np.concatenate(blocks)
        fill.begin()
        for lo in range(0, len(blocks), chunk):
            hi = min(lo + chunk, len(blocks))
            fill.add(np.ascontiguousarray(blocks[lo:hi]), lo, hi)
        fill.finish()
        fill.A.assemble()
        return fill.A
