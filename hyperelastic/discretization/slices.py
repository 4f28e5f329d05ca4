"""Every rank reads its own slice of a prepared mesh (mesh/prepared.py) and the ranks build one distributed DMPlex
from the slices: rank r reads the r-th contiguous range of cells (the ranges PETSc's `simple` partitioner would cut,
so the parts are the Morton partition of the source mesh) and the vertices they use first; the DM is built by
DMPlexBuildFromCellListParallel (core/libpetsc.py) and the vertices the ranks share get their positions and input
indices by an exchange (exchange.py). No rank reads more than its share and a few neighbouring rows. Each rank checks
its own part; a bad row is one error line on every rank (the first failing rank's)."""
import contextlib
import time
from dataclasses import dataclass

import h5py
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..core.errors import UserError, raise_agreed
from ..core.files import is_output, require_parts
from ..core.libpetsc import plex_from_slices
from ..mesh.prepared import add_group, face_mask, faces_of, is_prepared, open_prepared, read_groups
from ..mesh.read import flat_or_inverted, output_frame, region_names
from ..mesh.sets import FACE_VERTICES, Mesh, face_keys
from .exchange import Exchange, alltoallv
from .refine import Part, check_room, first_use_rows, refine


class SliceMesh(Mesh):
    """One rank's part of a prepared mesh (read_slice): its cells (`tets`, into its local vertices `points`), its
    boundary facets and groups as a sets.Mesh does, with `ids` the local vertices' source indices; counts, measures
    and the bounding box are the whole mesh's (collective), so sets are found and described as on the whole mesh.
    vertices: each local vertex's prepared (global) number, the DM's local vertex order; cell_ids: each local cell's
    source index; totals: (vertices, cells, boundary facets) of the whole mesh."""

    def total(self, n, op="sum"):
        return self.mpi.allreduce(n, op={"sum": MPI.SUM, "max": MPI.MAX, "min": MPI.MIN}[op])

    def extent(self):
        if self._extent is None:
            lo = self.points.min(axis=0) if len(self.points) else np.full(3, np.inf)
            hi = self.points.max(axis=0) if len(self.points) else np.full(3, -np.inf)
            glo, ghi = np.empty(3), np.empty(3)
            self.mpi.Allreduce(np.ascontiguousarray(lo), glo, op=MPI.MIN)
            self.mpi.Allreduce(np.ascontiguousarray(hi), ghi, op=MPI.MAX)
            self._extent = (glo, ghi)
        return self._extent


def cell_ranges(nc, size):
    """The first cell of each rank's slice (size + 1 offsets): the ranges of PETSc's `simple` partitioner."""
    sizes = np.full(size, nc // size) + (np.arange(size) < nc % size)
    return np.concatenate([[0], np.cumsum(sizes)])


def _hash_sum(ids):
    """The sum mod 2^64 of splitmix64 (Steele, Lea and Flood, OOPSLA 2014) of each index, as a Python int."""
    z = ids.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return int(np.sum(z ^ (z >> np.uint64(31)), dtype=np.uint64))


def check_slice(mpi, path, points, cells, cell_ids, nv):
    """Each rank's checks of its own rows (collective; the first failing rank's line raised on all): finite
    coordinates, vertex indices in range, no repeated vertex (cells named by source index; check_volumes follows once
    the positions of its cells' vertices are known)."""
    msg = None
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1) | (np.abs(points) > 1e30).any(axis=1))
    if len(bad):
        msg = f"mesh '{path}': a vertex has a non-finite or huge coordinate {points[bad[0]].tolist()}"
    raise_agreed(mpi, msg)
    bad = np.flatnonzero(((cells < 0) | (cells >= nv)).any(axis=1))
    if len(bad):
        msg = (f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} has a vertex index out of range "
               f"{cells[bad[0]].tolist()} (the mesh has {nv} vertices)")
    raise_agreed(mpi, msg)
    s = np.sort(cells, axis=1)
    bad = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if len(bad):
        msg = f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} repeats a vertex"
    raise_agreed(mpi, msg)


def check_volumes(mpi, path, points, cells, cell_ids):
    """No flat or inverted cell among this rank's (collective; points: local vertex positions, cells into them)."""
    msg = None
    if len(cells):
        V, tiny, negative = flat_or_inverted(points, cells)
        if tiny is not None:
            msg = f"mesh '{path}': tetrahedron {cell_ids[tiny]} has zero volume"
        elif negative is not None:
            msg = (f"mesh '{path}': tetrahedron {cell_ids[negative]} is inverted (negative volume "
                   f"{V[negative]:.3g})")
    raise_agreed(mpi, msg)


class PreparedSource:
    """The rows of a prepared mesh (mesh/prepared.py): vertices numbered by first use, boundaries and groups stored."""

    def __init__(self, path):
        self.path = path
        with open_prepared(path) as f:
            self.nv, self.nc = int(f.attrs["vertices"]), int(f.attrs["cells"])
            self.boundary_facets = int(f.attrs["boundary_facets"])
            self.order, self.n_nodes = int(f.attrs.get("order", 1)), int(f.attrs.get("nodes", self.nv))

    def open(self):
        return open_prepared(self.path)

    def cells(self, f, lo, hi):
        """(cells by vertex row, their source indices, their boundary bitmasks or None) of rows lo:hi."""
        return (f["cells"][lo:hi].astype(np.int64), f["cell_input_index"][lo:hi].astype(np.int64),
                f["boundary"][lo:hi].astype(np.int64))

    def points(self, f, a, b):
        """(positions, source indices) of vertex rows a:b."""
        return f["points"][a:b], f["input_index"][a:b].astype(np.int64)

    def groups(self, mpi, f, lo, hi):
        return read_groups(f, lo, hi)

    def check_numbering(self, mpi):
        """The source indices are a numbering — each node (vertex or edge node) and each cell once — read by every
        rank in a slice (collective; one line on every rank where not). Each rank checks its slice's range; the
        counts add up; the slices' sums of a 64-bit hash of each index equal the sum over 0..n-1 (a repeated index
        in place of another changes it but with probability 2^-64). Read whole, the file gets the same check
        (mesh.prepared._check_numbering): on 2 ranks a repeated index ran, its output's input_index no numbering."""
        size, rank = mpi.size, mpi.rank
        with self.open() as f:
            parts = {"node": [(f["input_index"], self.nv)], "cell": [(f["cell_input_index"], self.nc)]}
            if self.order == 2:
                parts["node"].append((f["edge_input_index"], f["edge_input_index"].shape[0]))
            msg = None
            for what, n in (("node", self.n_nodes), ("cell", self.nc)):
                got = np.concatenate([d[len_ * rank // size:len_ * (rank + 1) // size].astype(np.int64)
                                      for d, len_ in parts[what]])
                ok = not len(got) or (got.min() >= 0 and got.max() < n)
                due = np.arange(n * rank // size, n * (rank + 1) // size)         # (this rank's share of 0..n-1)
                counts, oks, mine, expected = zip(*mpi.allgather((len(got), bool(ok), _hash_sum(got), _hash_sum(due))))
                if sum(counts) != n or not all(oks) or sum(mine) % 2**64 != sum(expected) % 2**64:
                    msg = msg or (f"mesh '{self.path}': its {what} indices are not a numbering of the source's {n} "
                                  f"{what}s (a damaged or hand-edited file: prepare it again)")
        raise_agreed(mpi, msg)

    def edges(self, mpi, f, lo, hi):
        """A quadratic mesh's edge nodes of cells lo:hi: (input ids (nc, 6), positions (nc, 6, 3)), every rank
        reading a slice of the edge rows and the rows travelling to the ranks whose cells have them; None when
        linear (collective)."""
        if f.attrs.get("order") != 2:
            return None
        rows = f["cell_edges"][lo:hi].astype(np.int64)
        ne, size, rank = f["edge_points"].shape[0], mpi.size, mpi.rank
        a, b = ne * rank // size, ne * (rank + 1) // size
        want, each = np.unique(rows, return_inverse=True)
        ex = Exchange(mpi, np.arange(a, b), want, ne)
        if ex.missing:
            raise UserError(f"mesh '{self.path}': {ex.missing} edge nodes have no row in it (prepare it again)")
        ids, X = ex.move(f["edge_input_index"][a:b].astype(np.int64)), ex.move(f["edge_points"][a:b])
        each = each.reshape(rows.shape)
        return ids[each], X[each]


class OutputSource:
    """The rows of a per-rank output of this application (output/ranks.py) at frame `frame` (None: the reference):
    its rows are its numbering (as rank 0's reader of an output takes them), its regions its groups, its boundary
    found by counting faces over the ranks (boundary_masks)."""

    def __init__(self, path, frame):
        self.path, self.boundary_facets, self.order = path, None, 1
        with h5py.File(path, "r") as f:
            require_parts(f, path, f"mesh '{path}'")
            self.frame = output_frame(f, path, frame)
            self.nv, self.nc = f["mesh/points"].shape[0], f["mesh/tetra"].shape[0]
            self.n_nodes = self.nv
            self.named = region_names(f)

    def open(self):
        return h5py.File(self.path, "r")

    def cells(self, f, lo, hi):
        return f["mesh/tetra"][lo:hi].astype(np.int64), np.arange(lo, hi, dtype=np.int64), None

    def points(self, f, a, b):
        x = f["mesh/points"][a:b] if self.frame is None else f["x"][self.frame, a:b]
        return x, np.arange(a, b, dtype=np.int64)

    def edges(self, mpi, f, lo, hi):
        return None                                 # (a quadratic output is read whole on rank 0: sliceable)

    def groups(self, mpi, f, lo, hi):
        """Its regions (mesh/region's tags, named as the run's `sets` attribute names them): 1 on their cells."""
        region = f["mesh/region"][lo:hi].astype(np.int64) if "mesh/region" in f else np.zeros(hi - lo, np.int64)
        tags = sorted(set().union(*mpi.allgather(set(np.unique(region[region != 0]).tolist()))))
        return [(self.named.get(t, str(t)), t, "tets", 0, (region == t).astype(np.int64)) for t in tags]


def sliceable(path):
    """The order of the cells of `path` where it can be read in slices (a prepared mesh: its own; a per-rank output
    of linear cells: 1), else 0."""
    if is_prepared(path):
        with h5py.File(path, "r") as f:
            return int(f.attrs.get("order", 1))
    if not (path.lower().endswith((".h5", ".hdf5")) and is_output(path)):
        return 0
    with h5py.File(path, "r") as f:
        return int(f.attrs.get("output_layout") == "ranks" and f["mesh/tetra"].shape[1:] == (4,))


def boundary_masks(mpi, path, cells, corners, ids, cell_ids, nv):
    """Each cell's boundary-facet bitmask (bit j: the face without its corner of j-th smallest id), its faces counted
    over every rank's cells at a directory rank chosen by the face's smallest vertex (collective; cells by global
    vertex row, corners (nc, 4, 3) their positions, ids the rows' ids). The checks rank 0 makes of a whole mesh's
    faces, made there: a face of three or more cells, or two cells on the same side of their face (each cell sends
    the side its opposite corner lies on, the face's corners taken in one order by all), is one error line.
    Returns (masks, the mesh's boundary facet count)."""
    size = mpi.size
    order_k = np.argsort(cells[:, FACE_VERTICES], axis=2, kind="stable")
    tri = np.take_along_axis(cells[:, FACE_VERTICES], order_k, axis=2)       # face 4 c + k: without corner k
    at = np.take_along_axis(np.broadcast_to(FACE_VERTICES, tri.shape), order_k, axis=2)
    rows = np.arange(len(cells))[:, None, None]
    a, b, c = (corners[rows[..., 0], at[..., i]] for i in range(3))
    opp = corners                                                            # (face k: its opposite corner k)
    side = np.sign(np.einsum("fkx,fkx->fk", np.cross(b - a, c - a), opp - a)).astype(np.int64)
    tri = tri.reshape(-1, 3)
    dest = np.minimum(tri[:, 0] * size // max(nv, 1), size - 1)
    order = np.argsort(dest, kind="stable")
    send = np.column_stack([tri, side.reshape(-1)])[order]
    got, got_counts = alltoallv(mpi, send, np.bincount(dest, minlength=size), width=4)
    got = got.reshape(-1, 4)
    _, inverse, counts = np.unique(face_keys(got[:, :3]), return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    same = (counts == 2) & (np.abs(np.bincount(inverse, weights=got[:, 3], minlength=len(counts))) == 2)
    back, _ = alltoallv(mpi, counts[inverse] + 8 * same[inverse], got_counts)
    n = np.empty(len(tri), np.int64)
    n[order] = back
    n = n.reshape(-1, 4)
    bad = np.flatnonzero(((n & 7) >= 3).any(axis=1))
    raise_agreed(mpi, f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} shares a face with two others (duplicate or "
                      "overlapping tetrahedra)" if len(bad) else None)
    bad = np.flatnonzero((n >= 8).any(axis=1))
    raise_agreed(mpi, f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} and its neighbour across a face lie on the "
                      "same side of it (overlapping tetrahedra)" if len(bad) else None)
    return face_mask(ids, n == 1), int(mpi.allreduce(int((n == 1).sum()), op=MPI.SUM))


class MemorySource(PreparedSource):
    """A mesh rank 0 has read and checked whole (a .msh, a geometry, the built-in bar) served in the prepared layout
    (mesh/prepared.py `prepared_arrays`, on rank 0; None elsewhere) by scatters, so that -refine distributes it coarse:
    every read is collective (each rank asks for its rows, rank 0 sends each its own)."""

    def __init__(self, mpi, data, name):
        self.mpi, self.data, self.path = mpi, data, name
        a = mpi.bcast(data["attrs"] if mpi.rank == 0 else None, root=0)
        self.nv, self.nc, self.boundary_facets = int(a["vertices"]), int(a["cells"]), int(a["boundary_facets"])
        self.order, self.n_nodes = int(a["order"]), int(a["nodes"])
        self.group_keys = mpi.bcast([g[:4] for g in data["groups"]] if mpi.rank == 0 else None, root=0)

    def open(self):
        return contextlib.nullcontext(self.data)

    def _rows(self, get, wanted):
        """Each rank's rows `wanted` (a slice, or row numbers) of the array get(data) of rank 0."""
        asked = self.mpi.gather(wanted, root=0)
        return self.mpi.scatter([get(self.data)[w] for w in asked] if self.mpi.rank == 0 else None, root=0)

    def cells(self, f, lo, hi):
        return tuple(self._rows(lambda d: d[k], slice(lo, hi)).astype(np.int64)
                     for k in ("cells", "cell_input_index", "boundary"))

    def points(self, f, a, b):
        return self._rows(lambda d: d["points"], slice(a, b)), self._rows(lambda d: d["input_index"], slice(a, b))

    def groups(self, mpi, f, lo, hi):
        return [key + (self._rows(lambda d: d["groups"][i][4], slice(lo, hi)).astype(np.int64),)
                for i, key in enumerate(self.group_keys)]

    def edges(self, mpi, f, lo, hi):
        if self.order != 2:
            return None
        rows = self._rows(lambda d: d["cell_edges"], slice(lo, hi))
        want, each = np.unique(rows, return_inverse=True)
        each = each.reshape(rows.shape)
        return (self._rows(lambda d: d["edge_input_index"], want)[each],
                self._rows(lambda d: d["edge_points"], want)[each])


@dataclass
class Rows:
    """A rank's rows of a mesh read in slices: its cells by vertex row and their source ids, boundary bitmasks (None:
    to be found) and groups; the contiguous vertex rows a:b it holds for DMPlex (their positions and ids); a quadratic
    mesh's edge nodes of its cells (or None); the whole mesh's vertex, cell and boundary facet counts and nodes."""
    cells: np.ndarray
    cell_ids: np.ndarray
    bmask: np.ndarray
    groups: list
    a: int
    b: int
    held_points: np.ndarray
    held_ids: np.ndarray
    edges: tuple
    nv: int
    nc: int
    nb: int
    n_nodes: int


def _read_rows(path, mpi, src):
    """This rank's Rows of the source `src` (collective; errors raised on every rank)."""
    size, rank = mpi.size, mpi.rank
    try:
        if src.nc < size:
            raise UserError(f"mesh '{path}': {src.nc} tetrahedra for {size} MPI ranks (each rank needs cells: run "
                            "on fewer ranks or refine the mesh)")
        err = None
    except UserError as e:
        err = str(e)
    raise_agreed(mpi, err)
    off = cell_ranges(src.nc, size)
    lo, hi = int(off[rank]), int(off[rank + 1])
    with src.open() as f:
        cells, cell_ids, bmask = src.cells(f, lo, hi)
    # the vertices this rank holds for DMPlex, a contiguous range in rank order ending at nv: those its cells use
    # first where vertices are numbered by first use in the cells' order (a prepared mesh), else a valid range
    top = int(cells.max()) if len(cells) else -1
    first = mpi.exscan(top, op=MPI.MAX)
    a = 0 if rank == 0 else max(int(first) + 1, 0)
    b = src.nv if rank == size - 1 else max(a, min(top + 1, src.nv))
    with src.open() as f:
        held_points, held_ids = src.points(f, a, b)
        groups = src.groups(mpi, f, lo, hi)
        edges = src.edges(mpi, f, lo, hi)
    return Rows(cells, cell_ids, bmask, groups, a, b, held_points, np.asarray(held_ids, np.int64), edges, src.nv,
                src.nc, src.boundary_facets, src.n_nodes)


def _positions(mpi, path, rows, vertices):
    """(positions, ids) of the vertex rows `vertices` (collective), from the ranks holding them."""
    ex = Exchange(mpi, np.arange(rows.a, rows.b), vertices, rows.nv)
    if ex.missing:
        raise UserError(f"mesh '{path}': {ex.missing} vertices have no row in it (a damaged file: prepare it again)")
    return ex.move(rows.held_points), ex.move(rows.held_ids)


def _refined(mpi, path, rows, levels, check):
    """The Rows of this rank's part of the mesh refined `levels` times (refine.py; collective): the coarse part's
    corners gathered and checked first, the fine vertices held by the lowest rank that uses them."""
    vertices, local = np.unique(rows.cells, return_inverse=True)
    X, ids = _positions(mpi, path, rows, vertices)
    local = local.reshape(rows.cells.shape)
    check_volumes(mpi, path, X, local, rows.cell_ids)
    bmask, nb = rows.bmask, rows.nb
    if bmask is None:
        bmask, nb = boundary_masks(mpi, path, rows.cells, X[local], ids[local], rows.cell_ids, rows.nv)
    edges = rows.edges
    part = Part(ids[local], X[local], rows.cell_ids, bmask, rows.groups, rows.n_nodes if edges else rows.nv,
                rows.nc, nb)
    t0 = time.perf_counter()
    part = refine(mpi, part, levels, edges, check)
    cells, a, held_points, held_ids = first_use_rows(mpi, part)
    seconds = time.perf_counter() - t0
    fine = Rows(cells, part.cell_ids, part.bmask, part.groups, a, a + len(held_ids), held_points, held_ids, None,
                part.nv, part.nc, part.nb, part.nv)
    return fine, seconds


def read_slice(path, comm, frame=-1, source=None, refine_levels=0, check=None):
    """(SliceMesh of this rank's part, the distributed DMPlex built from the slices) of a prepared mesh or a per-rank
    output (at frame `frame`, as rank 0's reader) `path`, or of `source` (MemorySource) (collective; module
    docstring); refine_levels: the part refined that many times first (refine.py; check: refine's), its time in
    the SliceMesh's `refine_seconds`."""
    mpi = comm.tompi4py()
    try:
        src = source or (PreparedSource(path) if is_prepared(path) else OutputSource(path, frame))
        err = None
    except UserError as e:
        err, src = str(e), None
    raise_agreed(mpi, err)
    if source is None and isinstance(src, PreparedSource):        # (a MemorySource's rows are made here)
        src.check_numbering(mpi)
    rows = _read_rows(path, mpi, src)
    check_slice(mpi, path, rows.held_points, rows.cells, rows.cell_ids, rows.nv)
    seconds = 0.0
    if refine_levels:
        check_room(mpi, src.path, rows.nc, refine_levels, 8 * np.dtype(PETSc.IntType).itemsize)
        rows, seconds = _refined(mpi, path, rows, refine_levels, check)
    dm, vertices = plex_from_slices(comm, rows.cells, rows.b - rows.a, rows.nv, rows.held_points)
    X, ids = _positions(mpi, path, rows, vertices)
    local = np.searchsorted(vertices, rows.cells)                                # (vertices: ascending)
    if not refine_levels:
        check_volumes(mpi, path, X, local, rows.cell_ids)
    bmask, nb = rows.bmask, rows.nb
    if bmask is None:
        bmask, nb = boundary_masks(mpi, path, rows.cells, X[local], ids[local], rows.cell_ids, rows.nv)
    mesh = SliceMesh.from_meshio(path, X, local, faces_of(ids[local], bmask))
    mesh.ids, mesh.mpi, mesh._extent = ids, mpi, None
    mesh.vertices, mesh.cell_ids, mesh.totals = vertices, rows.cell_ids, (rows.nv, rows.nc, nb)
    mesh.quadratic_edges, mesh.n_nodes = rows.edges, rows.n_nodes
    mesh.source_order, mesh.refine_seconds = 1 if src.order == 1 else 2, seconds
    for group in rows.groups:
        add_group(mesh, *group)
    return mesh, dm
