"""The assembled tangent filled by `-assembly setvalues` (jacobians.AssembledChunked), by responsibility:
its exact pattern (exact_pattern, on any number of ranks), the map of the interior cells' 12x12 blocks into
the diagonal part's CSR values (CellMap), the partition-boundary cells' blocks placed once and sent to
their rows' owners (BoundaryExchange), and the SBAIJ copy the Krylov method multiplies by where the tangent
is symmetric (SBAIJCopy). docs/design.md ("The assembled tangent's fill") has the measurements."""
import numpy as np
from petsc4py import PETSc

from .kernels import (add_blocks, adjacency, cell_map, csr_union, expand_pattern, gather_blocks, scatter_blocks,
                      upper_blocks)
from ..core.arrays import unique
from ..core.libpetsc import SeqAIJRowIJ, SeqAIJValues, mpiaij_off_diagonal, seqaij_from_pattern


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


def owned_index(sp):
    """Per local vertex, its index among this rank's owned vertices (the global numbering less the
    rank's first row), -1 for a vertex owned by another rank."""
    own = np.full(sp.nlv, -1, np.int64)
    own[sp.lvid_of_owned] = np.arange(len(sp.lvid_of_owned))
    return own


def vertex_pattern(sp, upper=False):
    """(ptr, cols): per vertex this rank owns (by index among its owned vertices), the sorted global numbers of the
    vertices sharing a cell with it — its columns cols[ptr[v]:ptr[v + 1]] (int64). upper: only the columns >= the
    row's own global number (the upper block triangle). Built in C from each vertex's cells (kernels.adjacency). On
    several ranks a vertex at a partition boundary also has neighbours in cells another rank holds: each rank sends
    the rows of its local vertices another rank owns to that rank (one alltoall of (row, column) pairs), and the
    owner adds them to its rows (kernels.csr_union), so every rank's rows are complete."""
    mpi = sp.mpi
    g = sp.lgmap.getBlockIndices().astype(np.int64)       # global vertex of each local vertex
    if mpi.size == 1:
        return adjacency(sp.cells, g, sp.lvid_of_owned, upper)
    others = np.flatnonzero(owned_index(sp) < 0)
    ptr, cols = adjacency(sp.cells, g, np.concatenate([sp.lvid_of_owned, others]), upper)
    n = sp.n_owned
    mine = (ptr[:n + 1], cols[:ptr[n]])
    starts = np.zeros(mpi.size + 1, np.int64)
    starts[1:] = np.cumsum(mpi.allgather(n))
    deg = np.diff(ptr[n:])
    rows = np.repeat(g[others], deg)                                       # the other rows' pairs, by global row
    ocols = cols[ptr[n]:]
    del cols
    owner = np.searchsorted(starts, rows, side="right") - 1
    order = np.argsort(owner, kind="stable")
    cut = np.searchsorted(owner[order], np.arange(mpi.size + 1))
    recv = mpi.alltoall([np.stack([rows[order[cut[r]:cut[r + 1]]], ocols[order[cut[r]:cut[r + 1]]]])
                         for r in range(mpi.size)])
    del rows, ocols, owner, order
    N = int(sp.nv_total)
    keys = unique(np.concatenate([x[0] * N + x[1] for x in recv]))       # (received rows, sorted, distinct)
    del recv
    r, c = keys // N - starts[mpi.rank], keys % N
    extra = np.zeros(n + 1, np.int64)
    extra[1:] = np.cumsum(np.bincount(r, minlength=n))
    return csr_union(mine, (extra, c))


def exact_pattern(sp):
    """(row pointers, global columns) of the tangent's exact pattern in this rank's owned rows: dof
    (3v + a, 3w + b) for every pair of vertices v, w sharing a cell (vertex_pattern), columns sorted in each row, in
    PETSc's index type (written in C straight from the vertices' pattern: no whole-pattern int64 index arrays)."""
    return expand_pattern(*vertex_pattern(sp), PETSc.IntType)


def upper_block_pattern(sp):
    """(block row pointers, global block columns) of the tangent's upper block triangle in this rank's owned rows
    (the SBAIJ pattern: vertex pairs v <= w, global numbers, sharing a cell)."""
    ptr, cols = vertex_pattern(sp, upper=True)
    return ptr.astype(PETSc.IntType), cols.astype(PETSc.IntType)


class CellMap:
    """For every cell whose four vertices this rank owns (all of them on one rank), where each of its 16
    vertex-pair 3x3 blocks starts in the CSR value array of the diagonal block (int32 `base`, -1 for the
    other cells, whose rows or columns are partly another rank's: `boundary`, see BoundaryExchange), and
    the length of each of its vertices' rows (`rowlen`): the three rows of a vertex have the same columns,
    and a vertex's three columns are consecutive, so entry (3a+i, 3b+j) is at base[4a+b] + i rowlen[a] + j.
    A Newton step adds the cell blocks straight into the values (kernels.scatter_blocks) instead of
    searching each row per block: 80 bytes per tet. The map is made in C (kernels.cell_map: a bisection per
    block), every entry's column checked (a missing one is an error, not a drop)."""

    def __init__(self, sp, blocks, ia, ja):
        if len(ja) >= 2 ** 31:
            raise RuntimeError(f"the tangent's diagonal block has {len(ja)} entries on one rank (the direct map "
                               "holds int32 positions): use more ranks or -assembly coo")
        base, rowlen, missing = cell_map(blocks, owned_index(sp), ia, ja)
        if missing:
            raise RuntimeError("a cell entry is missing from the assembled pattern")
        self.nnz, self.base, self.rowlen = len(ja), base, rowlen
        self.boundary = np.flatnonzero(base[:, 0] < 0)

    def scatter(self, vals, lo, hi, arr):
        """arr (the diagonal part's values) += the interior cells' blocks of cells lo..hi-1 (vals)."""
        scatter_blocks(self.base[lo:hi], self.rowlen[lo:hi], vals, arr)


def keep_boundary(boundary, vals, lo, hi, bvals):
    """bvals[k] = the blocks (in vals, cells lo..hi-1) of the partition-boundary cells boundary[k] among them
    (boundary: sorted cell indices)."""
    k0, k1 = np.searchsorted(boundary, lo), np.searchsorted(boundary, hi)
    if k1 > k0:
        bvals[k0:k1] = vals[boundary[k0:k1] - lo]


class CellFill:
    """An AIJ (block size 3, `A`) with the exact pattern of the space's cells `blocks` (exact_pattern), filled a chunk
    of cells at a time: `begin`, then `add` per chunk (the interior cells' blocks straight into the diagonal part's
    values, CellMap; the partition-boundary cells' kept), then `finish` (those sent to their rows' owners in one
    Alltoallv, BoundaryExchange). The tangent's fill (jacobians.AssembledChunked) and p-multigrid's P1 operator
    (pmg.GalerkinCells, on the vertices' space) are both this; the caller adds single entries and assembles."""

    def __init__(self, sp, blocks):
        A = self.A = PETSc.Mat().create(comm=sp.comm)
        n = 3 * sp.n_owned
        A.setSizes(((n, PETSc.DETERMINE), (n, PETSc.DETERMINE)), bsize=3)
        A.setType(PETSc.Mat.Type.AIJ)
        A.setLGMap(sp.lgmap, sp.lgmap)
        if sp.mpi.size == 1:                                # the exact pattern, assembled: the map can be made now
            seqaij_from_pattern(A, *exact_pattern(sp))
        else:
            A.setPreallocationCSR(exact_pattern(sp))
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)   # the pattern must be complete
        self.row0 = A.getOwnershipRange()[0] // 3         # this rank's first vertex (block row), global
        self.Ad = A.getDiagonalBlock() if sp.mpi.size > 1 else A
        with SeqAIJRowIJ(self.Ad) as (ia, ja):
            self.map = CellMap(sp, blocks, ia, ja)
            self.exchange = (BoundaryExchange(sp, A, blocks, self.map.boundary, self.row0, ia, ja)
                             if sp.mpi.size > 1 else None)
        self.n3 = 3 * blocks.shape[1]
        self.bvals = None

    def begin(self):
        self.A.zeroEntries()
        self.bvals = np.empty((len(self.map.boundary), self.n3, self.n3))

    def add(self, vals, lo, hi):
        """The blocks vals of cells lo..hi-1: the interior cells' into the values, the boundary cells' kept."""
        with SeqAIJValues(self.Ad, self.map.nnz) as arr:
            self.map.scatter(vals, lo, hi, arr)
        keep_boundary(self.map.boundary, vals, lo, hi, self.bvals)

    def finish(self):
        """The boundary cells' blocks into their rows (several ranks)."""
        if self.exchange is not None:
            self.exchange.add(self.bvals, self.Ad, self.map.nnz)
        self.bvals = None


class BoundaryExchange:
    """Several ranks: the 16 blocks of each cell with a vertex another rank owns (CellMap.boundary) are not
    added through MatSetValues and PETSc's stash but directly: blocks in this rank's rows into the diagonal
    or off-diagonal part's values (positions found once), the others sent to their row's owner in one
    Alltoallv per fill, in an order agreed once (each rank sends the global (row, column) vertex pairs of
    what it will send; the owner finds their positions)."""

    def __init__(self, sp, A, blocks, boundary, row0, ia, ja):
        mpi = sp.mpi
        self.mpi, self.A, self.row0, self.n_owned = mpi, A, row0, sp.n_owned
        starts = np.asarray(A.getOwnershipRanges(), np.int64) // 3              # each rank's first vertex
        g = sp.lgmap.getBlockIndices().astype(np.int64)
        nn = blocks.shape[1]
        self.nn = nn
        c = g[blocks[boundary].astype(np.int64)]                               # (nb, nn) global nodes
        gr, gc = np.repeat(c, nn, axis=1).ravel(), np.tile(c, (1, nn)).ravel()  # block (cell, a, b)
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
            own = self._places(ia, ja, ao, gr[mine] - row0, gc[mine])
            recv = self._places(ia, ja, ao, rr - row0, rc)
        # (which blocks, p0, L) into the diagonal and the off-diagonal part, from this rank's cells and received
        split = lambda idx, pl: [(idx[k], pl[1][k], pl[2][k]) for k in (~pl[0], pl[0])]    # noqa: E731
        self.own, self.recv = split(mine, own), split(np.arange(len(rr)), recv)
        self.send, self.scount, self.rcount = send, 9 * scount, 9 * rcount

    def _places(self, ia, ja, ao, vrow, gcol):
        """For 3x3 blocks (owned row vertex vrow, by index among this rank's; global column vertex gcol):
        (in_off, p0, L) — in the diagonal or the off-diagonal part of the MPIAIJ, where the block's first
        entry is in that part's values and its rows' length. Checked entry by entry."""
        ia_o, ja_o, colmap = ao
        off = (gcol < self.row0) | (gcol >= self.row0 + self.n_owned)
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

    def add(self, bvals, Ad, nnz_d):
        """Add the boundary cells' blocks bvals (nb, 3nn, 3nn) (their order: CellMap.boundary's)."""
        nn = self.nn
        blocks = np.ascontiguousarray(bvals.reshape(-1, nn, 3, nn, 3).transpose(0, 1, 3, 2, 4)).reshape(-1, 9)
        sbuf = np.ascontiguousarray(blocks[self.send])
        rbuf = np.empty((self.rcount.sum() // 9, 9))
        self.mpi.Alltoallv([sbuf, self.scount], [rbuf, self.rcount])
        ao = mpiaij_off_diagonal(self.A, columns=False)
        with SeqAIJValues(Ad, nnz_d) as d, SeqAIJValues(ao, self.nnz_o) as o:
            for src, parts in ((blocks, self.own), (rbuf, self.recv)):
                for (idx, p0, L), dst in zip(parts, (d, o)):
                    if len(idx):
                        add_blocks(p0, L, np.ascontiguousarray(src[idx]), dst)


class SBAIJCopy:
    """The SBAIJ copy of a symmetric AIJ tangent (`S`, what the Krylov method multiplies by): the AIJ's
    upper block triangle, preallocated from the AIJ's own pattern, and per block where its first row starts
    in the AIJ's values and that row's length (p0, L: 8 bytes per block). A refresh gathers the blocks of
    the SBAIJ's diagonal part straight into its values (kernels.gather_blocks); on several ranks the blocks
    whose column another rank owns (the SBAIJ's off-diagonal part, which PETSc does not expose) go through
    MatSetValuesBlocked, all rows owned here (no stash)."""

    def __init__(self, sp, A, Ad, row0, chunk):
        n, several = sp.n_owned, sp.mpi.size > 1
        self.A, self.Ad, self.row0 = A, Ad, row0
        if not several:
            self._one_rank(sp, A)
            return
        r0 = 3 * row0
        d, o = [], []
        with SeqAIJRowIJ(Ad) as pd:
            for lo in range(0, n, chunk):
                d.append(self._upper_blocks(pd, lambda c: c + r0, lo, min(lo + chunk, n)))
        if several:
            ao, colmap = mpiaij_off_diagonal(A)
            with SeqAIJRowIJ(ao) as po:
                self.nnz_o = len(po[1])
                for lo in range(0, n, chunk):
                    o.append(self._upper_blocks(po, lambda c: colmap[c].astype(np.int64), lo, min(lo + chunk, n)))
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
        self.S, self.Sd = S, (S.getDiagonalBlock() if several else S)
        with SeqAIJRowIJ(self.Sd, blocks=True) as (si, sj):     # the diagonal part as PETSc stores it
            if not (np.array_equal(si, np.concatenate([[0], np.cumsum(np.bincount(d[0], minlength=n))]))
                    and np.array_equal(sj, d[1] - row0)):
                raise RuntimeError("the SBAIJ copy's diagonal part is not the AIJ's upper block triangle")
        self.sb_d = (d[2], d[3])
        self.sb_o = ((o[0] + row0).astype(PETSc.IntType)[:, None], o[1].astype(PETSc.IntType)[:, None],
                     o[2], o[3]) if several and len(o[0]) else None

    def _one_rank(self, sp, A):
        """One rank: the AIJ's upper blocks found in C (kernels.upper_blocks: the numpy path below took 1.0 of the copy's
        1.5 s at 207k P2 tets), preallocated and checked as there."""
        with SeqAIJRowIJ(A) as (ia, ja):
            bptr, bcols, p0, L = upper_blocks(ia, ja)
        S = PETSc.Mat().create(comm=sp.comm)
        S.setSizes(A.getSizes(), bsize=3)
        S.setType(PETSc.Mat.Type.SBAIJ)
        S.setPreallocationCSR((bptr.astype(PETSc.IntType), bcols.astype(PETSc.IntType)))
        S.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        with SeqAIJRowIJ(S, blocks=True) as (si, sj):
            if not (np.array_equal(si, bptr) and np.array_equal(sj, bcols)):
                raise RuntimeError("the SBAIJ copy's pattern is not the AIJ's upper block triangle")
        self.S = self.Sd = S
        self.sb_d, self.sb_o = (p0, L), None

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

    def refresh(self, nnz_d):
        """The SBAIJ copy from the AIJ just filled."""
        p0, L = self.sb_d
        with SeqAIJValues(self.Ad, nnz_d) as a, SeqAIJValues(self.Sd, 9 * len(p0), "SBAIJ") as v:
            gather_blocks(p0, L, a, v, colmajor=True)
        if self.sb_o is not None:
            rows, cols, p0, L = self.sb_o
            vals = np.empty((len(p0), 9))
            with SeqAIJValues(mpiaij_off_diagonal(self.A, columns=False), self.nnz_o) as a:
                gather_blocks(p0, L, a, vals, colmajor=False)
            self.S.setValuesBlockedRCV(rows, cols, vals, PETSc.InsertMode.INSERT_VALUES)
        self.S.assemble()
