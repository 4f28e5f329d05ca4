"""The symmetric tangent filled straight into SBAIJ, with no AIJ beside it (`UpperFill`): where the preconditioner
reads the SBAIJ too (p-multigrid: Chebyshev/Jacobi on it; its P1 operator is formed from the cells' blocks,
solving/pmg.py's GalerkinCells), the AIJ that `-operator_storage sbaij` otherwise keeps for the preconditioner — two
thirds of the tangent's memory — is not made. docs/design.md ("The assembled tangent's fill") has the measurements."""
import numpy as np
from petsc4py import PETSc

from .aij import keep_boundary, owned_index, upper_block_pattern
from .kernels import scatter_upper, upper_map
from ..core.libpetsc import SeqAIJRowIJ, SeqAIJValues


class UpperFill:
    """(aij.CellFill's counterpart: `begin`, `add` per chunk of cells, `finish`.) The SBAIJ `S` (block size 3) of a
    symmetric tangent, preallocated with its exact upper block pattern
    (aij.upper_block_pattern), and where each cell's upper blocks go: for a cell whose vertices this rank owns, the
    block index in the diagonal part's values of its node pair (a, b) where a's global number is <= b's (`pos`,
    int32, -1 for the others: their transposes are the cell's (b, a)), 400 bytes per P2 cell; the cells at a
    partition boundary (`boundary`) add their upper blocks through MatSetValuesBlocked (PETSc's stash sends those
    in rows another rank owns). Single entries (effects' own, the constrained diagonal) go through MatSetValues:
    their lower-triangle halves are ignored (MAT_IGNORE_LOWER_TRIANGULAR; the tangent is symmetric)."""

    def __init__(self, sp, blocks):
        several = sp.mpi.size > 1
        S = self.S = PETSc.Mat().create(comm=sp.comm)
        n = 3 * sp.n_owned
        S.setSizes(((n, PETSc.DETERMINE), (n, PETSc.DETERMINE)), bsize=3)
        S.setType(PETSc.Mat.Type.SBAIJ)
        S.setLGMap(sp.lgmap, sp.lgmap)
        S.setPreallocationCSR(upper_block_pattern(sp))
        S.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)    # the pattern must be complete
        S.setOption(PETSc.Mat.Option.IGNORE_LOWER_TRIANGULAR, True)
        self.Sd = S.getDiagonalBlock() if several else S
        nn = blocks.shape[1]
        with SeqAIJRowIJ(self.Sd, blocks=True) as (si, sj):
            self.nblocks = len(sj)
            pos, missing = upper_map(blocks, owned_index(sp), si, sj)
        if missing:
            raise RuntimeError("a cell block is missing from the SBAIJ pattern")
        self.pos = pos
        self.boundary = np.flatnonzero(pos[:, 0] < 0)           # (an owned cell's pair (0, 0) is upper)
        g = sp.lgmap.getBlockIndices().astype(np.int64)
        cb = g[blocks[self.boundary].astype(np.int64)]
        r, c = np.repeat(cb, nn, axis=1).ravel(), np.tile(cb, (1, nn)).ravel()
        self.b_keep = np.flatnonzero(r <= c)                                    # (boundary cell, a, b), upper
        self.b_rows = r[self.b_keep].astype(PETSc.IntType)[:, None]
        self.b_cols = c[self.b_keep].astype(PETSc.IntType)[:, None]
        self.nn = nn
        self.bvals = None

    def begin(self):
        self.S.zeroEntries()
        self.bvals = np.empty((len(self.boundary), 3 * self.nn, 3 * self.nn))

    def add(self, vals, lo, hi):
        """S's diagonal part += the upper blocks of the interior cells among lo..hi-1 (vals: their blocks); the
        partition-boundary cells' blocks kept."""
        with SeqAIJValues(self.Sd, 9 * self.nblocks, "SBAIJ") as arr:
            scatter_upper(self.pos[lo:hi], vals, arr)
        keep_boundary(self.boundary, vals, lo, hi, self.bvals)

    def finish(self):
        """S += the upper blocks of the partition-boundary cells."""
        bvals, self.bvals = self.bvals, None
        if not len(self.b_keep):
            return
        nn = self.nn
        blocks = bvals.reshape(-1, nn, 3, nn, 3).transpose(0, 1, 3, 2, 4).reshape(-1, 9)[self.b_keep]
        self.S.setValuesBlockedRCV(self.b_rows, self.b_cols, np.ascontiguousarray(blocks), PETSc.InsertMode.ADD_VALUES)
