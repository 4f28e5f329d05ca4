"""Rows moved between ranks by a key (an input-mesh index), no rank holding all of them: a plan made once by a
rendezvous through a directory distributed over the ranks by key range (the usual distributed-directory exchange:
each key's directory rank is key * size // n_keys), then any number of moves with one Alltoallv each.

Used where a rank must receive rows that others hold in another order: a restart's state read in slices of the file
(the rows of slice k go to the ranks whose nodes they are) and the per-rank output of a run restarted on another
rank count (each rank's nodes go to the rank writing that part of the file's order). `edge_numbers` numbers a
distributed mesh's edges as a whole mesh's would be numbered, by the same kind of rendezvous (P2 nodes of a mesh read
in slices, -refine's new vertices)."""
import numpy as np

from mpi4py import MPI


def alltoallv(mpi, send, counts, dtype=np.int64, width=1):
    """send (sum(counts) rows of `width`), grouped by destination rank in rank order, counts per destination ->
    (received rows grouped by source rank, counts per source)."""
    counts = np.asarray(counts, np.int64)
    got = np.empty(mpi.size, np.int64)
    mpi.Alltoall(counts, got)
    unit = MPI.INT64_T if np.dtype(dtype).kind in "iu" else MPI.DOUBLE
    recv = np.empty((int(got.sum()), width) if width > 1 else int(got.sum()), dtype)
    sdisp = np.concatenate([[0], np.cumsum(counts)[:-1]]) * width
    rdisp = np.concatenate([[0], np.cumsum(got)[:-1]]) * width
    mpi.Alltoallv([np.ascontiguousarray(send, dtype), (counts * width, sdisp), unit],
                  [recv, (got * width, rdisp), unit])
    return recv, got


class Exchange:
    """A plan to move rows from the ranks that have them (have_keys: this rank's rows' keys) to the ranks that want
    them (want_keys: the keys of the rows this rank wants, in the order it wants them). Keys are integers in
    [0, n_keys); every wanted key must be had by exactly one rank (else `missing` counts the ones that are not, on
    every rank). Collective."""

    def __init__(self, mpi, have_keys, want_keys, n_keys):
        self.mpi = mpi
        size = mpi.size
        have = np.asarray(have_keys, np.int64)
        want = np.asarray(want_keys, np.int64)
        self.n_have, self.n_want = len(have), len(want)

        def directory(keys):
            return np.minimum(keys * size // max(n_keys, 1), size - 1)

        # 1. the directory learns who has each key: (key, rank, slot)
        order = np.argsort(directory(have), kind="stable")
        counts = np.bincount(directory(have), minlength=size)
        rows = np.stack([have[order], np.full(len(have), mpi.rank), order], axis=1)
        known, _ = alltoallv(mpi, rows, counts, width=3)
        # 2. the directory is asked for the wanted keys, and answers (rank, slot) in the order asked
        order_w = np.argsort(directory(want), kind="stable")
        counts_w = np.bincount(directory(want), minlength=size)
        asked, asked_counts = alltoallv(mpi, want[order_w], counts_w)
        known = known.reshape(-1, 3)
        by_key = np.argsort(known[:, 0], kind="stable")
        pos = np.searchsorted(known[by_key, 0], asked)
        pos = np.minimum(pos, max(len(known) - 1, 0))
        found = len(known) > 0
        hit = (known[by_key[pos], 0] == asked) if found else np.zeros(len(asked), bool)
        answer = np.full((len(asked), 2), -1, np.int64)
        if found:
            answer[hit] = known[by_key[pos[hit]], 1:]
        back, _ = alltoallv(mpi, answer, asked_counts, width=2)
        where = np.empty((len(want), 2), np.int64)
        where[order_w] = back.reshape(-1, 2)
        self.missing = int(mpi.allreduce(int((where[:, 0] < 0).sum()), op=MPI.SUM))
        if self.missing:
            return
        # 3. each owner learns which of its slots go to which rank, in the order the wanting rank will unpack
        by_src = np.argsort(where[:, 0], kind="stable")
        self._recv_order = by_src                        # received row j goes to wanted position by_src[j]
        self._recv_counts = np.bincount(where[:, 0], minlength=size)
        slots, self._send_counts = alltoallv(mpi, where[by_src, 1], self._recv_counts)
        self._send_slots = slots
        self.identity = bool(mpi.allreduce(
            int(np.array_equal(self._recv_counts, np.bincount([mpi.rank] * len(want), minlength=size))
                and np.array_equal(slots, np.arange(len(want))) and len(want) == len(have)), op=MPI.MIN))

    def move(self, rows):
        """The wanted rows (n_want, ...) from this rank's had rows (n_have, ...). Collective."""
        rows = np.asarray(rows)
        if self.identity:
            return rows.copy()
        tail = rows.shape[1:]
        width = int(np.prod(tail)) if tail else 1
        kind = np.int64 if rows.dtype.kind in "iu" else np.float64
        flat = rows.reshape(len(rows), width)[self._send_slots]
        got, _ = alltoallv(self.mpi, flat, self._send_counts, kind, width)
        out = np.empty((self.n_want, width), kind)
        out[self._recv_order] = got.reshape(-1, width)
        return out.reshape((self.n_want,) + tail)


def cell_edge_numbers(mpi, ends, cell_ids, n_vertices, n_cells):
    """edge_numbers of the cells' edges (ends: element.reference.cell_edges of the cells whose input ids are cell_ids; n_cells: the
    whole mesh's), each met at cell id * 6 + its place in EDGES: the order of first appearance in the cells' order."""
    occurrence = (np.asarray(cell_ids, np.int64)[:, None] * 6 + np.arange(6)).reshape(-1)
    return edge_numbers(mpi, ends, occurrence, n_vertices, 6 * n_cells)


def edge_numbers(mpi, ends, occurrence, n_vertices, n_slots):
    """The global number of each edge (ends: (m, 2) its vertices' input ids, ascending; occurrence: where this rank
    meets it, cell * 6 + its edge in element.EDGES, unique per (cell, edge) over the ranks; slots: 6 * cells), as
    mesh.read.elevate numbers a linear mesh's edges: in the order of their first appearance, from 0. Collective: the
    edges meet at a directory rank by their smaller end (each keeps its first appearance), which sends that to the
    rank holding its range of appearances; those ranks sort, count, and the numbers travel back."""
    size = mpi.size
    ends = np.asarray(ends, np.int64).reshape(-1, 2)
    mine, each = np.unique(ends[:, 0] * n_vertices + ends[:, 1], return_inverse=True)   # this rank's edges once
    each = each.reshape(-1)
    occurrence_of = np.full(len(mine), np.iinfo(np.int64).max)
    np.minimum.at(occurrence_of, each, np.asarray(occurrence, np.int64))
    ends, occurrence = np.column_stack([mine // n_vertices, mine % n_vertices]), occurrence_of
    d1 = np.minimum(ends[:, 0] * size // max(n_vertices, 1), size - 1)
    o1 = np.argsort(d1, kind="stable")
    got, got1 = alltoallv(mpi, np.column_stack([ends, occurrence])[o1], np.bincount(d1, minlength=size), width=3)
    got = got.reshape(-1, 3)
    key = got[:, 0] * n_vertices + got[:, 1]
    ukey, inverse = np.unique(key, return_inverse=True)
    inverse = inverse.reshape(-1)
    first = np.full(len(ukey), np.iinfo(np.int64).max)
    np.minimum.at(first, inverse, got[:, 2])
    d2 = np.minimum(first * size // max(n_slots, 1), size - 1)
    o2 = np.argsort(d2, kind="stable")
    slots, got2 = alltoallv(mpi, first[o2], np.bincount(d2, minlength=size))
    pos = np.argsort(slots, kind="stable")
    number = np.empty(len(slots), np.int64)
    number[pos] = np.arange(len(slots)) + (mpi.exscan(len(slots), op=MPI.SUM) or 0)
    back, _ = alltoallv(mpi, number, got2)
    edge_number = np.empty(len(ukey), np.int64)
    edge_number[o2] = back
    out, _ = alltoallv(mpi, edge_number[inverse], got1)
    result = np.empty(len(ends), np.int64)
    result[o1] = out
    return result[each]
