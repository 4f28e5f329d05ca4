"""A mesh prepared once to be read by every rank in slices (`hyperelastic mesh MESH --prepare -o FILE.h5`).

`prepare` reads and checks a mesh as a run would (mesh.read: every check of the whole mesh, once, here), orders it
spatially (mesh.read.spatial_order: cells along a Z-curve, vertices numbered by first use) and writes plain HDF5:

    points (nv, 3) float64, input_index (nv,) int64     the vertices in that order, each its index in the source
    cells (nc, 4) int64, cell_input_index (nc,) int64   the cells in that order (into points), each its source index
    boundary (nc,) uint8                                each cell's boundary facets: bit j is its face without the
                                                        corner of j-th smallest input index (sets.Mesh.facet_mask)
    groups/<i> (nc,) uint8, attrs name, tag, kind       the physical surfaces (the bitmask of their facets) and
                                                        volumes (1 on their cells), attrs ignored (as sets.NamedSet)
    attrs: format, version, source, order, vertices, cells, boundary_facets

A run given `-mesh FILE.h5` reads it in slices (`read_slice`, collective): rank r reads the r-th contiguous range of
cells (the ranges PETSc's `simple` partitioner would cut: the same parts as the Morton partition of the source mesh)
and the vertices they use first, the ranks build one distributed DMPlex (DMPlexBuildFromCellListParallel) and
exchange the input indices and positions of the vertices they share (discretization/exchange.py); no rank reads more
than its share and a few neighbouring rows. Each rank checks its own part (finite coordinates, indices in range, no
repeated, flat or inverted cell); the checks that need the whole mesh (faces shared by three cells, overlapping
pieces, unused vertices) ran when the file was prepared. `read_whole` gives the whole Mesh back in the source's
numbering (the gathered output, `report`, the serial path of quadratic runs)."""
import os

import h5py
import numpy as np
from mpi4py import MPI

from ..core.errors import UserError
from .sets import FACE_VERTICES, Mesh, NamedSet, signed_volumes

FORMAT = "hyperelastic prepared mesh"
VERSION = 1
DATASETS = {"points": (3, "f"), "input_index": (None, "i"), "cells": (4, "i"), "cell_input_index": (None, "i"),
            "boundary": (None, "u")}


def is_prepared(path):
    """Whether `path` is a prepared mesh (HDF5 whose attribute `format` is FORMAT)."""
    if not os.path.isfile(path):
        return False
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == FORMAT
    except (OSError, ValueError):
        return False


def prepare(src, out, frame=-1):
    """Write the prepared mesh of mesh file `src` (any mesh read_mesh reads, checked) to `out` (.h5), atomically
    (a temporary file renamed: an existing `out` stays whole until the new one is). Returns {vertices, cells,
    boundary_facets, groups}."""
    from .read import read_mesh, spatial_order          # (read imports this module)
    if not out.lower().endswith((".h5", ".hdf5")):
        raise UserError(f"hyperelastic mesh --prepare: the output '{out}' must end in .h5 or .hdf5")
    if os.path.abspath(out) == os.path.abspath(src):
        raise UserError(f"hyperelastic mesh --prepare: the output '{out}' is the input")
    mesh = read_mesh(src, frame)
    if mesh.order != 1:
        raise UserError(f"mesh '{src}': quadratic (10-node) cells cannot be prepared yet; prepare a linear mesh (a "
                        "run at -order 2 elevates it, reading it whole on rank 0)")
    p, t, vperm, corder = spatial_order(mesh.points, mesh.tets)
    tmp = f"{out}.{os.getpid()}.tmp"
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs.update(format=FORMAT, version=VERSION, source=os.path.abspath(src), order=1,
                           vertices=len(p), cells=len(t), boundary_facets=len(mesh.facet_cell))
            f.create_dataset("points", data=p)
            f.create_dataset("input_index", data=vperm.astype(np.int64))
            f.create_dataset("cells", data=t.astype(np.int64))
            f.create_dataset("cell_input_index", data=corder.astype(np.int64))
            f.create_dataset("boundary", data=mesh.facet_mask(slice(None))[corder].astype(np.uint8))
            for i, g in enumerate(mesh.groups.values()):
                if g.kind == "facets":
                    mask = mesh.facet_mask(g.items)
                else:
                    mask = np.zeros(len(t), np.int64)
                    mask[g.items] = 1
                d = f.create_dataset(f"groups/{i}", data=mask[corder].astype(np.uint8))
                d.attrs.update(name=g.name, tag=-1 if g.tag is None else int(g.tag), kind=g.kind,
                               ignored=int(g.ignored))
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return {"vertices": len(p), "cells": len(t), "boundary_facets": len(mesh.facet_cell),
            "groups": [(g.name, g.kind, len(g.items)) for g in mesh.groups.values()]}


def _open(path):
    """The prepared file, its layout checked: one UserError line for a file this module did not write whole."""
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise UserError(f"mesh '{path}': cannot be read as HDF5 ({e})") from None
    try:
        if f.attrs.get("version") != VERSION:
            raise UserError(f"mesh '{path}': prepared mesh version {f.attrs.get('version')}, this reader reads "
                            f"{VERSION} (prepare it again)")
        nv, nc = int(f.attrs.get("vertices", -1)), int(f.attrs.get("cells", -1))
        for name, (width, kind) in DATASETS.items():
            n = nv if name in ("points", "input_index") else nc
            d = f.get(name)
            shape = (n,) if width is None else (n, width)
            if d is None or d.shape != shape or d.dtype.kind not in kind + ("i" if kind == "u" else ""):
                got = "missing" if d is None else f"{d.dtype} {d.shape}"
                raise UserError(f"mesh '{path}': prepared dataset '{name}' is {got}, expected {shape} "
                                "(a damaged or hand-edited file: prepare it again)")
        for key, d in f.get("groups", {}).items():
            if d.shape != (nc,) or "name" not in d.attrs or d.attrs.get("kind") not in ("facets", "tets"):
                raise UserError(f"mesh '{path}': prepared group '{key}' is malformed (prepare it again)")
        return f
    except Exception:
        f.close()
        raise


def _groups(f, lo=0, hi=None):
    """[(name, tag, kind, ignored, the rows lo:hi of its mask)] of a prepared file."""
    out = []
    for key in sorted(f.get("groups", {}), key=int):
        d = f["groups"][key]
        tag = int(d.attrs["tag"])
        out.append((str(d.attrs["name"]), None if tag < 0 else tag, str(d.attrs["kind"]), int(d.attrs["ignored"]),
                    d[lo:hi].astype(np.int64)))
    return out


def faces_of(ids, masks):
    """The face indices 4 c + k (face k: without corner k) of each cell's faces in `masks` (bit j: the face without
    the corner of j-th smallest id; ids (nc, 4) the corners' input ids), ascending."""
    rank = np.argsort(np.argsort(ids, axis=1, kind="stable"), axis=1)           # rank of corner k
    has = (masks[:, None] >> rank) & 1 == 1                                      # (nc, 4): face k in the mask
    return np.flatnonzero(has.reshape(-1))


def read_whole(path):
    """The whole prepared mesh as the checked source's sets.Mesh: its points, cells, boundary facets and groups in
    the source's numbering (the same arrays read_mesh gives of the source)."""
    with _open(path) as f:
        vin, cin = f["input_index"][:], f["cell_input_index"][:]
        points = np.empty((len(vin), 3))
        points[vin] = f["points"][:]
        tets = np.empty((len(cin), 4), np.int64)
        tets[cin] = vin[f["cells"][:]]
        bmask = np.empty(len(cin), np.int64)
        bmask[cin] = f["boundary"][:]
        groups = _groups(f)
    boundary = faces_of(tets, bmask)
    mesh = Mesh.from_meshio(path, points, tets, boundary)
    for name, tag, kind, ignored, mask in groups:
        m = np.empty_like(mask)
        m[cin] = mask
        if kind == "facets":
            items = np.searchsorted(boundary, faces_of(tets, m))
        else:
            items = np.flatnonzero(m)
        mesh.groups[name] = NamedSet(name, tag, kind, items, ignored)
    return mesh


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
    """Each rank's checks of its own part (collective; the first failing rank's line raised on all): finite
    coordinates, vertex indices in range, no repeated vertex, no flat or inverted cell (named by source index)."""
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
        V = signed_volumes(points, cells)
        e = np.stack([points[cells[:, b]] - points[cells[:, a]] for a, b in ((0, 1), (0, 2), (0, 3), (1, 2))])
        lmax = np.linalg.norm(e, axis=-1).max(axis=0)
        tiny = np.flatnonzero(np.abs(V) <= 1e-12 * lmax ** 3)
        neg = np.flatnonzero(V < 0)
        if len(tiny):
            msg = f"mesh '{path}': tetrahedron {cell_ids[tiny[0]]} has zero volume"
        elif len(neg):
            msg = (f"mesh '{path}': tetrahedron {cell_ids[neg[0]]} is inverted (negative volume "
                   f"{V[neg[0]]:.3g})")
    _first_error(mpi, msg)


def read_slice(path, comm):
    """(SliceMesh of this rank's part, the distributed DMPlex built from the slices) of prepared mesh `path`
    (collective; module docstring)."""
    from ..core.libpetsc import plex_from_slices
    from ..discretization.exchange import Exchange
    mpi = comm.tompi4py()
    size, rank = mpi.size, mpi.rank
    try:
        with _open(path) as f:
            nv, nc, nb = int(f.attrs["vertices"]), int(f.attrs["cells"]), int(f.attrs["boundary_facets"])
            if nc < size:
                raise UserError(f"mesh '{path}': {nc} tetrahedra for {size} MPI ranks (each rank needs cells: run "
                                "on fewer ranks or refine the mesh)")
            off = cell_ranges(nc, size)
            lo, hi = int(off[rank]), int(off[rank + 1])
            cells = f["cells"][lo:hi].astype(np.int64)
            cell_ids = f["cell_input_index"][lo:hi].astype(np.int64)
            bmask = f["boundary"][lo:hi].astype(np.int64)
            groups = _groups(f, lo, hi)
            err = None
    except UserError as e:
        err, cells = str(e), np.zeros((0, 4), np.int64)
    _first_error(mpi, err)
    # the vertices this rank holds for DMPlex: those its cells use first (vertices are numbered by first use in
    # the cells' order), a contiguous range in rank order; the last rank's range ends at nv
    top = int(cells.max()) if len(cells) else -1
    first = mpi.exscan(top, op=MPI.MAX)
    a = 0 if rank == 0 else max(int(first) + 1, 0)
    b = nv if rank == size - 1 else max(a, min(top + 1, nv))
    with _open(path) as f:
        held_points, held_ids = f["points"][a:b], f["input_index"][a:b].astype(np.int64)
    check_slice(mpi, path, held_points, cells, cell_ids, nv)
    dm, vertices = plex_from_slices(comm, cells, b - a, nv, held_points)
    ex = Exchange(mpi, np.arange(a, b), vertices, nv)
    if ex.missing:
        raise UserError(f"mesh '{path}': {ex.missing} vertices have no row in it (a damaged file: prepare it again)")
    X, ids = ex.move(held_points), ex.move(held_ids)
    local = np.searchsorted(vertices, cells)                                    # (vertices: ascending)
    check_volumes(mpi, path, X, local, cell_ids)
    boundary = faces_of(ids[local], bmask)
    mesh = SliceMesh.from_meshio(path, X, local, boundary)
    mesh.ids, mesh.mpi, mesh._extent = ids, mpi, None
    mesh.vertices, mesh.cell_ids, mesh.totals = vertices, cell_ids, (nv, nc, nb)
    for name, tag, kind, ignored, mask in groups:
        if kind == "facets":
            items = np.searchsorted(boundary, faces_of(ids[local], mask))
        else:
            items = np.flatnonzero(mask)
        mesh.groups[name] = NamedSet(name, tag, kind, items, ignored)
    return mesh, dm
