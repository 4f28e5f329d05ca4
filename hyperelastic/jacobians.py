"""Jacobian operators, selected with -jacobian:

  assembled  exact tangent as AIJ (block size 3). -assembly setvalues (default): preallocated once
             from the cell adjacency, values added per Newton step in chunks of cells straight into
             the CSR values (a per-cell map of positions), ~1 KB per tet in all; with
             -operator_storage sbaij (the default where the tangent is symmetric) the Krylov method
             multiplies by an SBAIJ copy of it (~120 B/tet more). -assembly coo: COO pattern set once
             (setPreallocationCOOLocal), values set per Newton step (setValuesCOO): a ~3x faster
             fill, but PETSc's COO maps and the (nc,12,12) value array cost ~5 KB per tet
  shell      exact tangent as a MatShell applying J v cell by cell, with getDiagonal for Jacobi
  seed_fd    the thesis' operator: exact M/h^2 + C/h, and K v replaced by (k(x+v) - k(x))/||v||_2 (eq. 5.19)
  seed_fd2   the same with (-k(x+2v) + 4k(x+v) - 3k(x)) / (2||v||_2) (eq. 7.8)

PETSc's own MFFD needs nothing here: -snes_mf or -snes_mf_operator replace the operator.
"""
import numpy as np
from petsc4py import PETSc


def _sizes(space):
    n = 3 * space.n_owned
    return ((n, PETSc.DETERMINE), (n, PETSc.DETERMINE))


class Assembled:
    def __init__(self, system):
        self.system = system
        sp = system.space
        self.cell_effects = [e for e in system.effects if e.cell_blocks]
        self.other = []
        cd = (3 * sp.cells[:, :, None].astype(np.int64) + np.arange(3)).reshape(-1, 12)   # (nc, 12)
        rows = [np.repeat(cd, 12, axis=1).ravel()]
        cols = [np.tile(cd, (1, 12)).ravel()]
        n = len(rows[0])
        for e in system.effects:
            r, c = e.coo_pattern()
            if len(r):
                self.other.append((e, slice(n, n + len(r))))
                rows.append(r)
                cols.append(c)
                n += len(r)
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
        A = PETSc.Mat().create(comm=sp.comm)
        A.setSizes(_sizes(sp), bsize=3)
        A.setType(PETSc.Mat.Type.AIJ)
        A.setLGMap(sp.lgmap, sp.lgmap)
        A.setPreallocationCOOLocal(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
        del rows, cols
        self.vals = np.zeros(self.nvals)
        self.mat = A
        self._nullspace(sp)

    def _nullspace(self, sp):
        """The six rigid-body modes of the reference configuration, for GAMG."""
        coords = sp.global_vec()
        coords.getArray()[:] = sp.owned_array(sp.X.ravel())
        self.nullspace = PETSc.NullSpace().createRigidBody(coords)
        self.mat.setNearNullSpace(self.nullspace)
        coords.destroy()

    def assemble(self):
        vals = self.vals
        cell = vals[:self.ncell * 144].reshape(-1, 12, 12)
        cell.fill(0.0)
        for e in self.cell_effects:
            e.add_cell_blocks(cell)
        for e, sl in self.other:
            e.coo_values(vals[sl])
        vals[self.diag_slice] = self.system.scale
        vals[self.zero] = 0.0
        self.mat.setValuesCOO(vals, addv=PETSc.InsertMode.INSERT_VALUES)

    update = assemble     # after System.linearize: the tangent at the new point


def _row_search(ia, ja, rows, cols):
    """Per query, the position in ja of column cols[q] within row rows[q] of a CSR pattern whose rows'
    columns are sorted (vectorized bisection, no index array of the whole pattern); where a column is
    absent, the position it would take (callers check ja there)."""
    lo, hi = ia[rows], ia[rows + 1]
    while True:
        open_ = lo < hi
        if not open_.any():
            return np.minimum(lo, len(ja) - 1)
        mid = (lo + hi) // 2
        right = open_ & (ja[np.minimum(mid, len(ja) - 1)] < cols)
        lo = np.where(right, mid + 1, lo)
        hi = np.where(open_ & ~right, mid, hi)


class AssembledChunked:
    """The exact tangent as an AIJ matrix (block size 3) with its exact pattern preallocated (_csr, on any
    number of ranks), filled per Newton step CHUNK cells at a time: the 12x12 blocks of cells whose
    vertices this rank owns are added straight into the diagonal block's CSR values through a per-cell
    map of positions (_direct_map), the others (at a partition boundary) at positions found once, through
    one Alltoallv for the rows another rank owns (_exchange_setup). No per-entry index arrays and no
    whole-mesh (nc,12,12) value array stay alive: memory is the matrix, the maps and one chunk."""
    CHUNK = 8192

    def __init__(self, system, direct=True, storage="aij"):
        """direct: the exact pattern and the direct fill (_csr, _direct_map); False: a counted
        preallocation and MatSetValuesBlockedLocal for every cell and fill (for benchmarks).
        storage: `sbaij` also keeps the tangent's upper triangle as SBAIJ (`operator`, refreshed after
        every fill): the Krylov method's and the smoothers' MatMults read half the matrix, while the
        preconditioner is still built from the AIJ (`mat`). The tangent must be symmetric."""
        self.system = system
        self.direct = direct
        sp = system.space
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
        A = PETSc.Mat().create(comm=sp.comm)
        A.setSizes(_sizes(sp), bsize=3)
        A.setType(PETSc.Mat.Type.AIJ)
        A.setLGMap(sp.lgmap, sp.lgmap)
        if direct:
            A.setPreallocationCSR(self._csr(sp))   # the exact pattern, assembled: the map can be made now
        else:
            A.setPreallocationNNZ(self._nnz(sp))
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)   # the pattern must be complete
        self.row0 = A.getOwnershipRange()[0] // 3          # this rank's first vertex (block row), global
        self.mat = A
        self.filled = direct               # (zeros) once assembled: a fill starts from zeroEntries
        if direct:
            self._direct_map()
        Assembled._nullspace(self, sp)
        self.operator = A                  # the Mat the Krylov method multiplies by (SNES's Amat)
        if storage == "sbaij":
            if not direct:
                raise ValueError("SBAIJ storage needs the exact pattern (direct=True)")
            self._sbaij()

    @staticmethod
    def _owned_index(sp):
        """Per local vertex, its index among this rank's owned vertices (the global numbering less the
        rank's first row), -1 for a vertex owned by another rank."""
        own = np.full(sp.nlv, -1, np.int64)
        own[sp.lvid_of_owned] = np.arange(len(sp.lvid_of_owned))
        return own

    @staticmethod
    def _csr(sp):
        """(row pointers, global columns) of the tangent's exact pattern in this rank's owned rows: dof
        (3v + a, 3w + b) for every pair of vertices v, w sharing a cell, columns sorted in each row. On
        several ranks a vertex at a partition boundary also has pairs from cells another rank holds: each
        rank sends the pairs of its cells whose row vertex another rank owns to that rank (one alltoall of
        sorted int64 keys), so every rank's pattern is complete before the first fill."""
        mpi = sp.mpi
        g = sp.lgmap.getBlockIndices().astype(np.int64)       # global vertex of each local vertex
        N = int(sp.nv_total)
        c = g[sp.cells.astype(np.int64)]
        keys = np.unique((c[:, :, None] * N + c[:, None, :]).ravel())       # sorted by row vertex, column
        del c
        starts = np.zeros(mpi.size + 1, np.int64)
        starts[1:] = np.cumsum(mpi.allgather(sp.n_owned))
        if mpi.size > 1:
            cut = np.searchsorted(keys, starts * N)                          # the rows' owners, in rank order
            recv = mpi.alltoall([keys[cut[r]:cut[r + 1]] for r in range(mpi.size)])
            keys = np.unique(np.concatenate(recv))
            del recv
        row, col = keys // N - starts[mpi.rank], keys % N
        del keys
        n = sp.n_owned
        deg = np.bincount(row, minlength=n)                                  # neighbour vertices per vertex
        cols_v = (3 * col[:, None] + np.arange(3)).ravel()                   # vertex v's 3 deg dof columns
        first = np.repeat(3 * (np.cumsum(deg) - deg), 3)                     # where dof row 3v + a's are
        lens = np.repeat(3 * deg, 3)                                         # in cols_v (the same for a = 0..2)
        ia = np.zeros(3 * n + 1, np.int64)
        ia[1:] = np.cumsum(lens)
        ja = cols_v[np.repeat(first - ia[:-1], lens) + np.arange(ia[-1])]
        return ia.astype(PETSc.IntType), ja.astype(PETSc.IntType)

    @staticmethod
    def _nnz(sp):
        """(d_nnz, o_nnz) per owned row: 3 x the vertices sharing a cell with the row's vertex, split
        by whether they are owned here. A vertex on a partition boundary also gets rows from other
        ranks' cells: their counts are added into its owner (an over-estimate, on those rows only)."""
        nlv = sp.nlv
        c = sp.cells.astype(np.int64)
        pairs = np.unique((c[:, :, None] * nlv + c[:, None, :]).ravel())   # (row vertex, column vertex)
        row, col = pairs // nlv, pairs % nlv
        del pairs
        owned = sp.owned.astype(bool)
        d = np.bincount(row[owned[col]], minlength=nlv).astype(np.float64)
        o = np.bincount(row[~owned[col]], minlength=nlv).astype(np.float64)
        del row, col
        mine_d, mine_o = d[sp.lvid_of_owned], o[sp.lvid_of_owned]
        if sp.mpi.size > 1:
            loc, glob = sp.local_vec(), sp.global_vec()
            arr = loc.getArray()
            arr[:] = 0.0
            arr.reshape(-1, 3)[:, 0] = d + o
            glob.set(0.0)
            sp.add_to_global(loc, glob)
            remote = glob.getArray(readonly=True).reshape(-1, 3)[:, 0] - (mine_d + mine_o)   # other ranks' cells
            loc.destroy()
            glob.destroy()
            mine_d, mine_o = mine_d + remote, mine_o + remote    # their columns' owners are unknown here
        total = int(sp.nv_total)
        dn = np.minimum(3 * mine_d, 3 * sp.n_owned).astype(PETSc.IntType)
        on = np.minimum(3 * mine_o, 3 * (total - sp.n_owned)).astype(PETSc.IntType)
        return np.repeat(dn, 3), np.repeat(on, 3)

    _nullspace = Assembled._nullspace

    def _direct_map(self):
        """From the exact pattern (_csr): for every cell whose four vertices are owned here (all of them on
        one rank), where each of its 16 vertex-pair 3x3 blocks starts in the CSR value array of the
        diagonal block (int32 `base`, -1 for the other cells, whose rows or columns are partly another
        rank's: _exchange_setup), and the length of each of its vertices' rows (`rowlen`): the
        three rows of a vertex have the same columns, and a vertex's three columns are consecutive, so
        entry (3a+i, 3b+j) is at base[4a+b] + i rowlen[a] + j. A Newton step adds the cell blocks straight
        into the values (kernels.scatter_blocks) instead of searching each row per block: 80 bytes per tet.
        Every entry's column is checked when the map is made (a missing one is an error, not a drop)."""
        from .libpetsc import SeqAIJRowIJ
        sp = self.system.space
        Ad = self.mat.getDiagonalBlock() if sp.mpi.size > 1 else self.mat
        with SeqAIJRowIJ(Ad) as (ia, ja):
            self._make_map(sp, Ad, ia, ja)

    def _upper_blocks(self, part, global_col, lo, hi):
        """Of one CSR part of the AIJ (its diagonal block, or on several ranks its off-diagonal block), the
        3x3 blocks of owned block rows lo..hi-1 in the upper block triangle (global block column >= global
        block row): (row, global column, p0, L) with p0 the position of the block's first entry in the part's
        values and L the length of its rows (a vertex's three rows have the same columns)."""
        ia, ja = part
        rows = 3 * np.arange(lo, hi)
        start, L = ia[rows].astype(np.int64), (ia[rows + 1] - ia[rows]).astype(np.int64)
        pos = np.repeat(start, L) + np.arange(L.sum()) - np.repeat(np.cumsum(L) - L, L)
        I = np.repeat(np.arange(lo, hi), L)
        g = global_col(ja[pos].astype(np.int64))
        keep = (g % 3 == 0) & (g // 3 >= self.row0 + I)
        I, pos = I[keep], pos[keep]
        return I, g[keep] // 3, pos.astype(np.int32), L[I - lo].astype(np.int32)

    def _sbaij(self):
        """The SBAIJ copy (`operator`): the AIJ's upper block triangle, preallocated from the AIJ's own
        pattern, and per block where its first row starts in the AIJ's values and that row's length (p0, L:
        8 bytes per block). A refresh gathers the blocks of the SBAIJ's diagonal part straight into its
        values (kernels.gather_blocks); on several ranks the blocks whose column another rank owns (the
        SBAIJ's off-diagonal part, which PETSc does not expose) go through MatSetValuesBlocked, all rows
        owned here (no stash)."""
        from .libpetsc import SeqAIJRowIJ, mpiaij_off_diagonal
        sp = self.system.space
        A, n, several = self.mat, sp.n_owned, sp.mpi.size > 1
        r0 = 3 * self.row0
        d, o = [], []
        with SeqAIJRowIJ(self.Ad) as pd:
            for lo in range(0, n, self.CHUNK):
                d.append(self._upper_blocks(pd, lambda c: c + r0, lo, min(lo + self.CHUNK, n)))
        if several:
            ao, colmap = mpiaij_off_diagonal(A)
            with SeqAIJRowIJ(ao) as po:                         # (nnz_o: _exchange_setup)
                for lo in range(0, n, self.CHUNK):
                    o.append(self._upper_blocks(po, lambda c: colmap[c].astype(np.int64), lo,
                                                min(lo + self.CHUNK, n)))
        d = [np.concatenate(x) for x in zip(*d)]
        if several:
            o = [np.concatenate(x) for x in zip(*o)]
        else:
            o = [np.zeros(0, np.int64)] * 2 + [np.zeros(0, np.int32)] * 2
        rows = np.concatenate([d[0], o[0]])                     # (diagonal part, then off-diagonal: its columns
        order = np.argsort(rows, kind="stable")                 #  are all beyond this rank's: sorted per row)
        bi = np.zeros(n + 1, np.int64)
        bi[1:] = np.cumsum(np.bincount(rows, minlength=n))
        bj = np.concatenate([d[1], o[1]])[order]
        del rows, order
        S = PETSc.Mat().create(comm=sp.comm)
        S.setSizes(A.getSizes(), bsize=3)
        S.setType(PETSc.Mat.Type.SBAIJ)
        S.setPreallocationCSR((bi.astype(PETSc.IntType), bj.astype(PETSc.IntType)))
        S.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        if several:
            S.setOption(PETSc.Mat.Option.NO_OFF_PROC_ENTRIES, True)
        self.operator, self.Sd = S, (S.getDiagonalBlock() if several else S)
        with SeqAIJRowIJ(self.Sd, blocks=True) as (si, sj):     # the diagonal part as PETSc stores it
            if not (np.array_equal(si, np.concatenate([[0], np.cumsum(np.bincount(d[0], minlength=n))]))
                    and np.array_equal(sj, d[1] - self.row0)):
                raise RuntimeError("the SBAIJ copy's diagonal part is not the AIJ's upper block triangle")
        self.sb_d = (d[2], d[3])
        self.sb_o = ((o[0] + self.row0).astype(PETSc.IntType)[:, None], o[1].astype(PETSc.IntType)[:, None],
                     o[2], o[3]) if several and len(o[0]) else None

    def _refresh_sbaij(self):
        """The SBAIJ copy from the AIJ just filled (_sbaij)."""
        from .kernels import gather_blocks
        from .libpetsc import SeqAIJValues, mpiaij_off_diagonal
        p0, L = self.sb_d
        with SeqAIJValues(self.Ad, self.nnz_d) as a, SeqAIJValues(self.Sd, 9 * len(p0), "SBAIJ") as v:
            gather_blocks(p0, L, a, v, colmajor=True)
        if self.sb_o is not None:
            rows, cols, p0, L = self.sb_o
            vals = np.empty((len(p0), 9))
            with SeqAIJValues(mpiaij_off_diagonal(self.mat, columns=False), self.nnz_o) as a:
                gather_blocks(p0, L, a, vals, colmajor=False)
            self.operator.setValuesBlockedRCV(rows, cols, vals, PETSc.InsertMode.INSERT_VALUES)
        self.operator.assemble()

    def _make_map(self, sp, Ad, ia, ja):
        if len(ja) >= 2 ** 31:
            raise RuntimeError(f"the tangent's diagonal block has {len(ja)} entries on one rank (the direct map "
                               "holds int32 positions): use more ranks or -assembly coo")
        own = self._owned_index(sp)
        nc = len(self.blocks)
        base = np.full((nc, 16), -1, np.int32)
        rowlen = np.zeros((nc, 4), np.int32)
        interior = (own[self.blocks] >= 0).all(axis=1)
        ia64 = ia.astype(np.int64)
        i3, j3 = np.arange(3)[:, None], np.arange(3)[None, :]
        for lo in range(0, nc, self.CHUNK):
            hi = min(lo + self.CHUNK, nc)
            sel = np.flatnonzero(interior[lo:hi])
            r = 3 * own[self.blocks[lo:hi][sel]]                      # first dof row of each vertex (m, 4)
            L = ia64[r + 1] - ia64[r]
            # each (a, b): the position of column 3 w_b in row 3 v_a
            p = _row_search(ia64, ja, np.repeat(r, 4, axis=1).ravel(), np.tile(r, (1, 4)).ravel())
            pos = (p.reshape(-1, 4, 4)[:, :, :, None, None] + i3[None, None, None] * L[:, :, None, None, None]
                   + j3[None, None, None])                                   # (m, a, b, i, j)
            cols = r[:, None, :, None, None] + j3[None, None, None]     # column 3 w_b + j
            if not np.array_equal(ja[pos], np.broadcast_to(cols, pos.shape)):
                raise RuntimeError("a cell entry is missing from the assembled pattern")
            base[lo + sel] = p.reshape(-1, 16)
            rowlen[lo + sel] = L
        self.Ad, self.nnz_d, self.base, self.rowlen = Ad, len(ja), base, rowlen
        self.boundary = np.flatnonzero(~interior)
        self.exchange = None
        if sp.mpi.size > 1:
            self._exchange_setup(sp, ia, ja)

    def _block_places(self, ia, ja, ao, vrow, gcol):
        """For 3x3 blocks (owned row vertex vrow, by index among this rank's; global column vertex gcol):
        (in_off, p0, L) — in the diagonal or the off-diagonal part of the MPIAIJ, where the block's first
        entry is in that part's values and its rows' length. Checked entry by entry."""
        ia_o, ja_o, colmap = ao
        n = self.system.space.n_owned
        off = (gcol < self.row0) | (gcol >= self.row0 + n)
        p0, L = np.empty(len(vrow), np.int64), np.empty(len(vrow), np.int64)
        for sel, (pi, pj), col in ((~off, (ia, ja), 3 * (gcol - self.row0)),
                                   (off, (ia_o, ja_o), np.searchsorted(colmap, 3 * gcol))):
            r, c = 3 * vrow[sel], col[sel]
            pi = pi.astype(np.int64)
            p = _row_search(pi, pj, r, c)
            last = np.minimum(p + 2, len(pj) - 1)
            want = 3 * gcol[sel] if pj is ja_o else c
            got = (colmap[pj[p]], colmap[pj[last]]) if pj is ja_o else (pj[p], pj[last])
            if not (np.array_equal(got[0], want) and np.array_equal(got[1], want + 2)):
                raise RuntimeError("a partition-boundary block is missing from the assembled pattern")
            p0[sel], L[sel] = p, pi[r + 1] - pi[r]
        return off, p0.astype(np.int32), L.astype(np.int32)

    def _exchange_setup(self, sp, ia, ja):
        """Several ranks: the 16 blocks of each cell with a vertex another rank owns (`boundary`) are not
        added through MatSetValues and PETSc's stash but directly: blocks in this rank's rows into the
        diagonal or off-diagonal part's values (positions found once), the others sent to their row's
        owner in one Alltoallv per fill, in an order agreed once (each rank sends the global (row,
        column) vertex pairs of what it will send; the owner finds their positions)."""
        from .libpetsc import SeqAIJRowIJ, mpiaij_off_diagonal
        mpi, A = sp.mpi, self.mat
        starts = np.asarray(A.getOwnershipRanges(), np.int64) // 3              # each rank's first vertex
        g = sp.lgmap.getBlockIndices().astype(np.int64)
        c = g[self.blocks[self.boundary].astype(np.int64)]                     # (nb, 4) global vertices
        gr, gc = np.repeat(c, 4, axis=1).ravel(), np.tile(c, (1, 4)).ravel()    # block (cell, a, b)
        owner = np.searchsorted(starts, gr, side="right") - 1
        send = np.flatnonzero(owner != mpi.rank)
        send = send[np.argsort(owner[send], kind="stable")]
        scount = np.bincount(owner[send], minlength=mpi.size)
        cut = np.concatenate([[0], np.cumsum(scount)])
        got = mpi.alltoall([np.stack([gr[send[cut[q]:cut[q + 1]]], gc[send[cut[q]:cut[q + 1]]]])
                            for q in range(mpi.size)])
        rcount = np.array([x.shape[1] for x in got])
        rr, rc = np.concatenate([x[0] for x in got]), np.concatenate([x[1] for x in got])
        mine = np.flatnonzero(owner == mpi.rank)
        ao_handle, colmap = mpiaij_off_diagonal(A)
        with SeqAIJRowIJ(ao_handle) as (ia_o, ja_o):
            self.nnz_o = len(ja_o)
            ao = (ia_o, ja_o, colmap.astype(np.int64))
            own = self._block_places(ia, ja, ao, gr[mine] - self.row0, gc[mine])
            recv = self._block_places(ia, ja, ao, rr - self.row0, rc)
        # (which blocks, p0, L) into the diagonal and the off-diagonal part, from this rank's cells and received
        split = lambda idx, pl: [(idx[k], pl[1][k], pl[2][k]) for k in (~pl[0], pl[0])]
        self.exchange = {"own": split(mine, own), "recv": split(np.arange(len(rr)), recv), "send": send,
                         "scount": 9 * scount, "rcount": 9 * rcount}
        # PETSc's stash is then only for effects with their own entries (face blocks): skip its
        # communication where no rank has any
        if not mpi.allreduce(len(self.other)):
            A.setOption(PETSc.Mat.Option.NO_OFF_PROC_ENTRIES, True)

    def _exchange_add(self, bvals):
        """Add the partition-boundary cells' blocks bvals (nb, 12, 12) (_exchange_setup)."""
        from .kernels import add_blocks
        from .libpetsc import SeqAIJValues, mpiaij_off_diagonal
        x = self.exchange
        blocks = np.ascontiguousarray(bvals.reshape(-1, 4, 3, 4, 3).transpose(0, 1, 3, 2, 4)).reshape(-1, 9)
        sbuf = np.ascontiguousarray(blocks[x["send"]])
        rbuf = np.empty((x["rcount"].sum() // 9, 9))
        self.system.space.mpi.Alltoallv([sbuf, x["scount"]], [rbuf, x["rcount"]])
        ao = mpiaij_off_diagonal(self.mat, columns=False)
        with SeqAIJValues(self.Ad, self.nnz_d) as d, SeqAIJValues(ao, self.nnz_o) as o:
            for src, parts in ((blocks, x["own"]), (rbuf, x["recv"])):
                for (idx, p0, L), dst in zip(parts, (d, o)):
                    if len(idx):
                        add_blocks(p0, L, np.ascontiguousarray(src[idx]), dst)

    def assemble(self):
        from .kernels import scatter_blocks
        from .libpetsc import SeqAIJValues
        A = self.mat
        direct = self.direct
        if self.filled:
            A.zeroEntries()
        ADD = PETSc.InsertMode.ADD_VALUES
        nc = len(self.blocks)
        buf = np.empty((min(self.CHUNK, nc), 12, 12))
        bvals = np.empty((len(self.boundary) if direct else 0, 12, 12))      # partition-boundary cells
        for lo in range(0, nc, self.CHUNK):
            hi = min(lo + self.CHUNK, nc)
            vals = buf[:hi - lo]
            vals.fill(0.0)
            for e in self.cell_effects:
                e.add_cell_blocks(vals, lo, hi)
            cc = self.constrained_cells
            cc = cc[np.searchsorted(cc, lo):np.searchsorted(cc, hi)] - lo
            if len(cc):                                               # constrained rows/columns: 0
                cm = self.vmask[self.blocks[lo + cc]].reshape(-1, 12)
                sub = vals[cc]
                sub[cm] = 0.0
                sub.transpose(0, 2, 1)[cm] = 0.0
                vals[cc] = sub
            if not direct:
                A.setValuesBlockedLocalRCV(self.blocks[lo:hi], self.blocks[lo:hi], vals.reshape(-1, 144), ADD)
                continue
            with SeqAIJValues(self.Ad, self.nnz_d) as arr:
                scatter_blocks(self.base[lo:hi], self.rowlen[lo:hi], vals, arr)
            k0, k1 = np.searchsorted(self.boundary, lo), np.searchsorted(self.boundary, hi)
            if k1 > k0:
                bvals[k0:k1] = vals[self.boundary[k0:k1] - lo]
        if direct and self.exchange is not None:
            self._exchange_add(bvals)
        for e, n, keep, r, c in self.other:
            v = np.empty(n)
            e.coo_values(v)
            A.setValuesLocalRCV(r, c, v[keep][:, None], ADD)
        if len(self.c_local):
            A.setValuesLocalRCV(self.c_local, self.c_local,
                                np.full((len(self.c_local), 1), self.system.scale), ADD)
        A.assemble()
        self.filled = True
        if self.operator is not A:
            self._refresh_sbaij()

    update = assemble


class _ShellContext:
    """A MatShell (PETSc's Python matrix) whose mult is this object's; `mat` is the PETSc Mat."""

    def __init__(self, system):
        self.system = system
        self.mat = PETSc.Mat().createPython(_sizes(system.space), context=self, comm=system.space.comm)
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
        self.elastic = [e for e in system.effects if e.name == "elasticity"]
        self.exact = [e for e in system.effects if e.name != "elasticity"]
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


def make(system, mode, assembly="setvalues", storage="aij"):
    """The operator of Jacobian mode `mode` (scene.JACOBIANS) on the system: an object with `mat`
    (the PETSc Mat SNES preconditions with), `operator` (the one it multiplies by: `mat` itself, or
    with storage `sbaij` its SBAIJ copy) and `update()` (called after System.linearize)."""
    if mode == "assembled":
        if storage != "aij":
            return AssembledChunked(system, storage=storage)
        op = ASSEMBLIES[assembly](system)
    else:
        op = OPERATORS[mode](system)
    if not hasattr(op, "operator"):
        op.operator = op.mat
    return op
