"""Jacobian operators, selected with -jacobian:

  assembled  exact tangent as AIJ (block size 3). -assembly setvalues (default): preallocated once
             from the cell adjacency, values added per Newton step in chunks of cells straight into
             the CSR values (a per-cell map of positions), ~1 KB per tet in all; with
             -operator_storage sbaij (the default where the tangent is symmetric) the Krylov method
             multiplies by an SBAIJ copy of it (~120 B/tet more), and where p-multigrid preconditions
             it (Jacobi smoothing) it is filled straight into that SBAIJ, with no AIJ (AssembledSBAIJ).
             -assembly coo: COO pattern set once
             (setPreallocationCOOLocal), values set per Newton step (setValuesCOO): a ~3x faster
             fill, but PETSc's COO maps and the (nc,12,12) value array cost ~5 KB per tet
  shell      exact tangent as a MatShell applying J v cell by cell, with getDiagonal for Jacobi
  seed_fd    the thesis' operator: exact M/h^2 + C/h, and K v replaced by (k(x+v) - k(x))/||v||_2 (eq. 5.19)
  seed_fd2   the same with (-k(x+2v) + 4k(x+v) - 3k(x)) / (2||v||_2) (eq. 7.8)

PETSc's own MFFD needs nothing here: -snes_mf or -snes_mf_operator replace the operator.
"""
import numpy as np
from petsc4py import PETSc

from ..discretization import aij, sbaij
from ..physics.effects.base import cell_blocks
from ..physics.effects.seams import Couplings, declaring


def _sizes(space):
    n = 3 * space.n_owned
    return ((n, PETSc.DETERMINE), (n, PETSc.DETERMINE))


def rigid_body_nullspace(sp):
    """The six rigid-body modes of the space's reference configuration (a near null space for GAMG)."""
    coords = sp.global_vec()
    coords.getArray()[:] = sp.owned_array(sp.X.ravel())
    nullspace = PETSc.NullSpace().createRigidBody(coords)
    coords.destroy()
    return nullspace


def rigid_body_modes(sp, A):
    """The rigid-body modes as A's near null space."""
    nullspace = rigid_body_nullspace(sp)
    A.setNearNullSpace(nullspace)
    return nullspace


def effect_patterns(effects, rows, cols):
    """Append each effect's extra COO entries (Effect.coo_pattern) to the lists rows and cols; returns
    ([(effect, slice of its values)], the number of entries in all)."""
    n = sum(map(len, rows))
    other = []
    for e in effects:
        r, c = e.coo_pattern()
        if len(r):
            other.append((e, slice(n, n + len(r))))
            rows.append(r)
            cols.append(c)
            n += len(r)
    return other, n


class Assembled:
    fills_coarse = False     # (AssembledSBAIJ: sums p-multigrid's coarse operator as it fills)

    def __init__(self, system):
        self.system = system
        sp = system.space
        self.cell_effects = [e for e in system.effects if e.cell_blocks]
        n3 = 3 * sp.cells.shape[1]
        cd = (3 * sp.cells[:, :, None].astype(np.int64) + np.arange(3)).reshape(-1, n3)   # (nc, 3nn)
        rows = [np.repeat(cd, n3, axis=1).ravel()]
        cols = [np.tile(cd, (1, n3)).ravel()]
        self.other, n = effect_patterns(system.effects, rows, cols)
        # the constrained block s I: one entry per owned constrained dof
        c_owned_local = (3 * sp.lvid_of_owned[:, None] + np.arange(3)).ravel()[system.c_owned_pos]
        self.diag_slice = slice(n, n + len(c_owned_local))
        rows.append(c_owned_local)
        cols.append(c_owned_local)
        rows = np.concatenate(rows)
        cols = np.concatenate(cols)
        cm = system.cmask
        zero = cm[rows] | cm[cols]
        zero[self.diag_slice] = False
        self.zero = np.flatnonzero(zero)          # entries in constrained rows/columns (few)
        del zero
        self.nvals = len(rows)
        self.ncell = len(cd)
        self.n3 = n3                              # dofs per cell
        A = PETSc.Mat().create(comm=sp.comm)
        A.setSizes(_sizes(sp), bsize=3)
        A.setType(PETSc.Mat.Type.AIJ)
        A.setLGMap(sp.lgmap, sp.lgmap)
        A.setPreallocationCOOLocal(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
        del rows, cols
        self.vals = np.zeros(self.nvals)
        self.mat = self.operator = A
        self.nullspace = rigid_body_modes(sp, A)

    def assemble(self):
        vals = self.vals
        n3 = self.n3
        cell = vals[:self.ncell * n3 * n3].reshape(-1, n3, n3)
        cell_blocks(self.cell_effects, cell)
        for e, sl in self.other:
            e.coo_values(vals[sl])
        vals[self.diag_slice] = self.system.scale
        vals[self.zero] = 0.0
        self.mat.setValuesCOO(vals, addv=PETSc.InsertMode.INSERT_VALUES)

    update = assemble     # after System.linearize: the tangent at the new point


class _CellFill:
    """What the direct fills share: the cell effects' blocks a chunk of cells at a time with the constrained rows and
    columns zeroed (`_cell_blocks`), the effects' own entries (`other`: effect, count, kept, local rows, columns)
    and the constrained dofs' diagonal (`c_local`)."""
    CHUNK = 8192                 # cells a chunk at most (linear tetrahedra: 9.4 MB of 12x12 blocks)
    CHUNK_BYTES = 16 * 2 ** 20   # and its blocks at most this (P2's 30x30: 2,330 cells, not 8,192 in 59 MB)
    fills_coarse = False

    def __init__(self, system):
        self.system = system
        sp = system.space
        n3 = 3 * sp.cells.shape[1]
        self.chunk = max(256, min(self.CHUNK, self.CHUNK_BYTES // (8 * n3 * n3)))
        self._buf = None                                       # the chunk's cell blocks (_fill)
        self.cell_effects = [e for e in system.effects if e.cell_blocks]
        cm = system.cmask
        self.other = []
        for e in system.effects:
            r, c = e.coo_pattern()
            if len(r):
                keep = ~(cm[r] | cm[c])                       # entries in constrained rows/columns are 0
                self.other.append((e, len(r), np.flatnonzero(keep), r[keep].astype(PETSc.IntType)[:, None],
                                   c[keep].astype(PETSc.IntType)[:, None]))
        self.c_local = ((3 * sp.lvid_of_owned[:, None] + np.arange(3)).ravel()[system.c_owned_pos]
                        .astype(PETSc.IntType)[:, None])
        self.vmask = cm.reshape(-1, 3)                         # constrained dofs per local vertex
        self.constrained_cells = np.flatnonzero(self.vmask[sp.cells].any(axis=(1, 2)))   # (sorted)
        self.blocks = np.ascontiguousarray(sp.cells, dtype=PETSc.IntType)

    def _add_entries(self, M):
        """M += the effects' own entries and the constrained diagonal, then M assembled; returns them as
        [(local rows, local columns, values)] (each (n, 1))."""
        out = []
        for e, n, keep, r, c in self.other:
            v = np.empty(n)
            e.coo_values(v)
            out.append((r, c, v[keep][:, None]))
        if len(self.c_local):
            out.append((self.c_local, self.c_local, np.full((len(self.c_local), 1), self.system.scale)))
        for r, c, v in out:
            M.setValuesLocalRCV(r, c, v, PETSc.InsertMode.ADD_VALUES)
        M.assemble()
        return out

    def _fill(self, *fills):
        """Each of `fills` (begin, add(vals, lo, hi), finish: aij.CellFill, sbaij.UpperFill, pmg.GalerkinCells) given
        the cell blocks a chunk of cells at a time (_cell_blocks)."""
        nc, n3 = len(self.blocks), 3 * self.blocks.shape[1]
        shape = (min(self.chunk, nc), n3, n3)
        if self._buf is None or self._buf.shape != shape:
            # kept from one Jacobian to the next: a P2 chunk is 59 MB, above glibc's largest mmap threshold (32 MB),
            # so a new one each time was a fresh mapping, faulted in again (0.5 s of system time in a 10 s P2 run)
            self._buf = np.empty(shape)
        buf = self._buf
        for f in fills:
            f.begin()
        for lo in range(0, nc, self.chunk):
            hi = min(lo + self.chunk, nc)
            vals = self._cell_blocks(buf[:hi - lo], lo, hi)
            for f in fills:
                f.add(vals, lo, hi)
        for f in fills:
            f.finish()

    def _cell_blocks(self, vals, lo, hi):
        """vals = the cell effects' 12x12 blocks of cells lo..hi-1, constrained rows and columns zeroed."""
        cell_blocks(self.cell_effects, vals, lo, hi)
        cc = self.constrained_cells
        cc = cc[np.searchsorted(cc, lo):np.searchsorted(cc, hi)] - lo
        if len(cc):                                               # constrained rows/columns: 0
            cm = self.vmask[self.blocks[lo + cc]].reshape(len(cc), -1)
            sub = vals[cc]
            sub[cm] = 0.0
            sub.transpose(0, 2, 1)[cm] = 0.0
            vals[cc] = sub
        return vals


class AssembledChunked(_CellFill):
    """The exact tangent as an AIJ matrix (block size 3) with its exact pattern preallocated
    (aij.exact_pattern, on any number of ranks), filled per Newton step a chunk of cells at a time: the 12x12
    blocks of cells whose vertices this rank owns are added straight into the diagonal block's CSR values
    (aij.CellMap), the others (at a partition boundary) at positions found once, through one Alltoallv for
    the rows another rank owns (aij.BoundaryExchange). No per-entry index arrays and no whole-mesh
    (nc,12,12) value array stay alive: memory is the matrix, the maps and one chunk."""

    def __init__(self, system, storage="aij"):
        """storage: `sbaij` also keeps the tangent's upper triangle as SBAIJ (`operator`, refreshed after
        every fill, aij.SBAIJCopy): the Krylov method's and the smoothers' MatMults read half the matrix,
        while the preconditioner is still built from the AIJ (`mat`). The tangent must be symmetric.
        `shell`: the Krylov method multiplies by the exact tangent applied cell by cell (ExactShell, the
        action per quadrature point), the preconditioner is built from the AIJ."""
        super().__init__(system)
        sp = system.space
        self.fill = aij.CellFill(sp, self.blocks)
        A = self.mat = self.fill.A
        self.Ad, self.map, self.exchange = self.fill.Ad, self.fill.map, self.fill.exchange
        # PETSc's stash is then only for effects with their own entries (face blocks): skip its communication
        # where no rank has any
        if self.exchange is not None and not sp.mpi.allreduce(len(self.other)):
            A.setOption(PETSc.Mat.Option.NO_OFF_PROC_ENTRIES, True)
        self.nullspace = rigid_body_modes(sp, A)
        self.copy = aij.SBAIJCopy(sp, A, self.Ad, self.fill.row0, self.chunk) if storage == "sbaij" else None
        # the Mat the Krylov method multiplies by: the AIJ, its SBAIJ copy, or (shell) the cells' action
        self.operator = (ExactShell(system).mat if storage == "shell" else A if self.copy is None else self.copy.S)

    def assemble(self):
        self._fill(self.fill)
        self._add_entries(self.mat)
        if self.copy is not None:
            self.copy.refresh(self.map.nnz)

    update = assemble


class AssembledSBAIJ(_CellFill):
    """The exact symmetric tangent straight into SBAIJ (its upper block triangle, sbaij.UpperFill), with no AIJ:
    `mat` and `operator` are the one SBAIJ. For a preconditioner that reads SBAIJ (p-multigrid: the P2 level's
    Chebyshev/Jacobi; its P1 operator is summed from the same chunks of cell blocks by `coarse`, pmg.GalerkinCells,
    which pmg.Levels attaches and marks `wanted` at a Jacobian that sets the preconditioner up). At 374k P2 dofs
    the AIJ and its exact pattern's computation were ~1 GB of a 1.07 GB run's peak (BENCHMARKS.md)."""
    fills_coarse = True

    def __init__(self, system):
        super().__init__(system)
        sp = system.space
        self.fill = sbaij.UpperFill(sp, self.blocks)
        self.mat = self.operator = self.fill.S
        self.nullspace = rigid_body_modes(sp, self.mat)
        self.coarse = None

    def assemble(self):
        S, coarse = self.mat, self.coarse
        coarse = coarse if coarse is not None and coarse.wanted else None
        self._fill(self.fill, *([coarse] if coarse is not None else []))
        entries = self._add_entries(S)
        if coarse is not None:
            coarse.close(entries)

    update = assemble


class _ShellContext:
    """A MatShell (PETSc's Python matrix) whose mult is this object's; `mat` is the PETSc Mat."""
    fills_coarse = False

    def __init__(self, system):
        self.system = system
        self.mat = self.operator = PETSc.Mat().createPython(_sizes(system.space), context=self,
                                                            comm=system.space.comm)
        self.mat.setUp()

    def getDiagonal(self, mat, D):
        self.system.diagonal(D)

    def update(self):
        """After System.linearize: nothing to do for an operator that reads the system's state."""


class ExactShell(_ShellContext):
    """J v by the elements' exact tangents, cell by cell, never assembled."""

    def mult(self, mat, X, Y):
        self.system.apply(X, Y)


class SeedFD(_ShellContext):
    """The thesis' matrix-free operator: exact linear terms plus the unscaled difference of the
    elastic forces (eqs. 5.19/5.20, first order; eq. 7.8, second order)."""

    def __init__(self, system, order):
        self.order = order
        self.elastic = [e for e in system.effects if e.kernels is not None]      # (the material's forces)
        self.exact = [e for e in system.effects if e.kernels is None]
        self.k0 = None
        super().__init__(system)

    def update(self):
        self.k0 = self.system.residual_local(self.system.x_lin, self.elastic)

    def mult(self, mat, X, Y):
        s = self.system
        v = s.local(X, s.vl).copy()
        v[s.cdofs] = 0.0
        nv = X.norm()
        y = np.zeros_like(v)
        for e in self.exact:
            e.apply(v, y)
        if nv > 0:
            y += seed_difference(lambda z: s.residual_local(z, self.elastic), s.x_lin, v, self.k0, nv, self.order)
        y[s.cdofs] = 0.0
        s._add(y, Y)
        s._constrained_rows(X, Y)


def seed_difference(k, x, v, k0, nv, order):
    """The thesis' replacement for K v: (k(x+v) - k(x))/nv (eq. 5.19) or
    (-k(x+2v) + 4k(x+v) - 3k(x))/(2 nv) (eq. 7.8), with k0 = k(x) and nv = ||v||_2. There is no
    differencing step: v itself is the step."""
    k1 = k(x + v)
    if order == 1:
        return (k1 - k0) / nv
    return (-k(x + 2 * v) + 4 * k1 - 3 * k0) / (2 * nv)


class PetscMFFD:
    """PETSc's own MFFD operator for a function F (what -snes_mf builds): a SNES with options prefix
    `prefix`, -snes_mf and -mat_mffd_type `kind`, differencing around the base point X.
    `function(x, f)` fills the Vec f with F(x). `mat` is the MFFD matrix."""

    def __init__(self, function, X, kind="wp", prefix="mffd_"):
        opts = PETSc.Options(prefix)
        opts.setValue("snes_mf", True)
        opts.setValue("mat_mffd_type", kind)
        snes = PETSc.SNES().create(comm=X.getComm())
        snes.setOptionsPrefix(prefix)
        self.R = X.duplicate()
        snes.setFunction(lambda s, x, f: function(x, f), self.R)
        snes.setFromOptions()
        snes.setSolution(X)
        snes.setUp()
        self.snes, self.X = snes, X
        self.mat, self.P, _ = snes.getJacobian()
        self.rebase()

    def rebase(self):
        """Recompute F(X), the value MFFD differences against (after F itself changed)."""
        self.snes.computeFunction(self.X, self.R)
        self.snes.computeJacobian(self.X, self.mat, self.P)


OPERATORS = {"shell": ExactShell, "seed_fd": lambda s: SeedFD(s, 1), "seed_fd2": lambda s: SeedFD(s, 2)}
ASSEMBLIES = {"setvalues": AssembledChunked, "coo": Assembled}


class Coupled:
    """An assembled operator plus the couplings between nodes that the cell pattern does not join (self-contact's
    pairs: effects that declare seams.Couplings): the Krylov method multiplies by both (a MATCOMPOSITE, their sum: PETSc's
    own products, no Python per iteration), the preconditioner is still built from the assembled matrix (which holds
    each node's own block). The couplings are an AIJ of their own in global numbering, its pattern set again from the
    effects' entries whenever the operator is updated after a linearization: on N ranks only the columns a rank's rows
    need travel. (Multiplied in Python at every Krylov iteration, with the whole surface
    gathered to every rank, they took a third of a self-contact run's time: BENCHMARKS.md.)"""

    def __init__(self, inner, system, effects, numbering=None):
        """numbering: where `inner` is not a matrix of the displacement dofs alone (the mixed formulation's one AIJ of
        displacements and pressures), the map of global displacement dof numbers to its global numbers."""
        self.inner, self.effects, self.numbering = inner, effects, numbering
        sp = system.space
        self.constrained = system.cmask.reshape(-1, 3)[sp.lvid_of_owned].ravel()
        self.coupling = PETSc.Mat().createAIJ(inner.getSizes(), comm=sp.comm)
        self.entries = None                          # (the couplings' count over the ranks; None: no pattern set yet)
        self.refresh()
        self.mat = PETSc.Mat().createComposite([inner, self.coupling], comm=sp.comm)

    @classmethod
    def around(cls, op, system, numbering=None):
        """op with its `operator` wrapped where some effect couples distant nodes and op multiplies by a matrix (and
        its `update` refreshing the couplings too); numbering as in the constructor."""
        effects = declaring(system.effects, Couplings)
        if effects and op.operator.getType() != PETSc.Mat.Type.PYTHON:
            coupled = cls(op.operator, system, effects, numbering)
            op.operator, update = coupled.mat, op.update

            def update_both():
                update()
                coupled.refresh()
            op.update = update_both
        return op

    def refresh(self):
        """The couplings as the effects hold them now (after System.linearize; none where no effect has any, the
        pattern then left as it is if already empty). Collective."""
        if any(e.coupled for e in self.effects):
            rows, cols, vals = (np.concatenate(a) for a in
                                zip(*(e.coupling_entries(self.constrained) for e in self.effects)))
        elif self.entries == 0:
            return
        else:
            rows = cols = np.zeros(0, np.int64)
            vals = np.zeros(0)
        if self.numbering is not None:
            rows, cols = self.numbering(rows), self.numbering(cols)
        self.coupling.setPreallocationCOO(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
        self.coupling.setValuesCOO(vals)
        self.entries = self.coupling.getComm().tompi4py().allreduce(len(vals))


def make(system, mode, assembly="setvalues", storage="aij", pc_reads_sbaij=False):
    """The operator of Jacobian mode `mode` (scene.JACOBIANS) on the system: an object with `mat`
    (the PETSc Mat SNES preconditions with), `operator` (the one it multiplies by: `mat` itself, or
    with storage `sbaij` its SBAIJ copy; with couplings between distant nodes, `Coupled` around it) and
    `update()` (called after System.linearize). pc_reads_sbaij: with storage `sbaij`, the preconditioner is
    built from the SBAIJ too (p-multigrid), so no AIJ is made (AssembledSBAIJ)."""
    if mode == "assembled":
        if storage == "sbaij" and pc_reads_sbaij:
            return Coupled.around(AssembledSBAIJ(system), system)
        op = AssembledChunked(system, storage=storage) if storage != "aij" else ASSEMBLIES[assembly](system)
        return Coupled.around(op, system)
    return OPERATORS[mode](system)
