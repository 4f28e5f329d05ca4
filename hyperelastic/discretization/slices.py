"""Every rank reads its own slice of a prepared mesh (mesh/prepared.py) and the ranks build one distributed DMPlex
from the slices: rank r reads the r-th contiguous range of cells (the ranges PETSc's `simple` partitioner would cut,
so the parts are the Morton partition of the source mesh) and the vertices they use first; the DM is built by
DMPlexBuildFromCellListParallel (core/libpetsc.py) and the vertices the ranks share get their positions and input
indices by an exchange (exchange.py). No rank reads more than its share and a few neighbouring rows. Each rank checks
its own part; a bad row is one error line on every rank (the first failing rank's)."""
import h5py
import numpy as np
from mpi4py import MPI

from ..core.errors import UserError
from ..core.files import is_output, require_parts
from ..core.libpetsc import plex_from_slices
from ..mesh.prepared import add_group, faces_of, is_prepared, open_prepared, read_groups
from ..mesh.read import flat_or_inverted, output_frame, region_names
from ..mesh.sets import FACE_VERTICES, Mesh, face_keys
from .exchange import Exchange, alltoallv


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


def _first_error(mpi, message):
    """Raise on every rank the first (by rank) of the ranks' error lines, if any (collective)."""
    lines = mpi.allgather(message)
    first = next((m for m in lines if m is not None), None)
    if first is not None:
        raise UserError(first)


def check_slice(mpi, path, points, cells, cell_ids, nv):
    """Each rank's checks of its own rows (collective; the first failing rank's line raised on all): finite
    coordinates, vertex indices in range, no repeated vertex (cells named by source index; check_volumes follows once
    the positions of its cells' vertices are known)."""
    msg = None
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1) | (np.abs(points) > 1e30).any(axis=1))
    if len(bad):
        msg = f"mesh '{path}': a vertex has a non-finite or huge coordinate {points[bad[0]].tolist()}"
    _first_error(mpi, msg)
    bad = np.flatnonzero(((cells < 0) | (cells >= nv)).any(axis=1))
    if len(bad):
        msg = (f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} has a vertex index out of range "
               f"{cells[bad[0]].tolist()} (the mesh has {nv} vertices)")
    _first_error(mpi, msg)
    s = np.sort(cells, axis=1)
    bad = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if len(bad):
        msg = f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} repeats a vertex"
    _first_error(mpi, msg)


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
    _first_error(mpi, msg)


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
    _first_error(mpi, f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} shares a face with two others (duplicate or "
                      "overlapping tetrahedra)" if len(bad) else None)
    bad = np.flatnonzero((n >= 8).any(axis=1))
    _first_error(mpi, f"mesh '{path}': tetrahedron {cell_ids[bad[0]]} and its neighbour across a face lie on the "
                      "same side of it (overlapping tetrahedra)" if len(bad) else None)
    rank = np.argsort(np.argsort(ids, axis=1, kind="stable"), axis=1)       # rank of corner k among the cell's
    masks = ((n == 1) << rank).sum(axis=1)
    return masks, int(mpi.allreduce(int((n == 1).sum()), op=MPI.SUM))


def read_slice(path, comm, frame=-1):
    """(SliceMesh of this rank's part, the distributed DMPlex built from the slices) of a prepared mesh or a per-rank
    output (at frame `frame`, as rank 0's reader) `path` (collective; module docstring)."""
    mpi = comm.tompi4py()
    size, rank = mpi.size, mpi.rank
    try:
        src = PreparedSource(path) if is_prepared(path) else OutputSource(path, frame)
        nv, nc = src.nv, src.nc
        if nc < size:
            raise UserError(f"mesh '{path}': {nc} tetrahedra for {size} MPI ranks (each rank needs cells: run "
                            "on fewer ranks or refine the mesh)")
        off = cell_ranges(nc, size)
        lo, hi = int(off[rank]), int(off[rank + 1])
        with src.open() as f:
            cells, cell_ids, bmask = src.cells(f, lo, hi)
        err = None
    except UserError as e:
        err, cells = str(e), np.zeros((0, 4), np.int64)
    _first_error(mpi, err)
    # the vertices this rank holds for DMPlex, a contiguous range in rank order ending at nv: those its cells use
    # first where vertices are numbered by first use in the cells' order (a prepared mesh), else a valid range
    top = int(cells.max()) if len(cells) else -1
    first = mpi.exscan(top, op=MPI.MAX)
    a = 0 if rank == 0 else max(int(first) + 1, 0)
    b = nv if rank == size - 1 else max(a, min(top + 1, nv))
    with src.open() as f:
        held_points, held_ids = src.points(f, a, b)
        groups = src.groups(mpi, f, lo, hi)
        edges = src.edges(mpi, f, lo, hi)
    check_slice(mpi, path, held_points, cells, cell_ids, nv)
    dm, vertices = plex_from_slices(comm, cells, b - a, nv, held_points)
    ex = Exchange(mpi, np.arange(a, b), vertices, nv)
    if ex.missing:
        raise UserError(f"mesh '{path}': {ex.missing} vertices have no row in it (a damaged file: prepare it again)")
    X, ids = ex.move(held_points), ex.move(held_ids)
    local = np.searchsorted(vertices, cells)                                    # (vertices: ascending)
    check_volumes(mpi, path, X, local, cell_ids)
    nb = src.boundary_facets
    if bmask is None:
        bmask, nb = boundary_masks(mpi, path, cells, X[local], ids[local], cell_ids, nv)
    mesh = SliceMesh.from_meshio(path, X, local, faces_of(ids[local], bmask))
    mesh.ids, mesh.mpi, mesh._extent = ids, mpi, None
    mesh.vertices, mesh.cell_ids, mesh.totals = vertices, cell_ids, (nv, nc, nb)
    mesh.quadratic_edges, mesh.n_nodes = edges, src.n_nodes
    for group in groups:
        add_group(mesh, *group)
    return mesh, dm


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
