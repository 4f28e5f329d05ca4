"""A mesh prepared once to be read by every rank in slices (`hyperelastic mesh MESH --prepare -o FILE.h5`).

`prepare` reads and checks a mesh as a run would (mesh.read: every check of the whole mesh, once, here), orders it
spatially (mesh/order.py: cells along a Z-curve, vertices numbered by first use) and writes plain HDF5:

    points (nv, 3) float64, input_index (nv,) int64     the vertices in that order, each its index in the source
    cells (nc, 4) int64, cell_input_index (nc,) int64   the cells in that order (into points), each its source index
    edge_points, edge_input_index, cell_edges (nc, 6)  a quadratic mesh's edge nodes (by first use), each cell's six
    boundary (nc,) uint8                                each cell's boundary facets: bit j is its face without the
                                                        corner of j-th smallest input index (sets.Mesh.facet_mask)
    groups/<i> (nc,) uint8, attrs name, tag, kind       the physical surfaces (the bitmask of their facets) and
                                                        volumes (1 on their cells), attrs ignored (as sets.NamedSet)
    attrs: format, version, source, order, vertices, cells, boundary_facets, nodes (all of a quadratic mesh)

A run given `-mesh FILE.h5` reads it in slices (discretization/slices.py: `read_slice`, collective): rank r reads
the r-th contiguous range of cells (the ranges PETSc's `simple` partitioner would cut: the same parts as the Morton
partition of the source mesh) and the vertices they use first, the ranks build one distributed DMPlex
(DMPlexBuildFromCellListParallel) and exchange the input indices and positions of the vertices they share
(discretization/exchange.py); no rank reads more than its share and a few neighbouring rows. Each rank checks its
own part (finite coordinates, indices in range, no repeated, flat or inverted cell); the checks that need the whole
mesh (faces shared by three cells, overlapping pieces, unused vertices) ran when the file was prepared. A quadratic
mesh keeps its edge nodes (each rank then reads those of its cells). `read_whole` gives the whole Mesh back in the
source's numbering (the gathered output, `report`, `-partitioner metis`)."""
import os

import h5py
import numpy as np

from ..core.arrays import unique
from ..core.errors import UserError
from .order import spatial_order
from .sets import Mesh, NamedSet

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


def check_prepare_output(src, out):
    """The output of `--prepare` must be HDF5 by name and not its input (checked before the input is read)."""
    if not out.lower().endswith((".h5", ".hdf5")):
        raise UserError(f"hyperelastic mesh --prepare: the output '{out}' must end in .h5 or .hdf5")
    if os.path.realpath(out) == os.path.realpath(src):
        raise UserError(f"hyperelastic mesh --prepare: the output '{out}' is the input")
    if os.path.isdir(out):
        raise UserError(f"hyperelastic mesh --prepare: the output '{out}' is a directory")
    for data in _xdmf_data_files(src):
        if os.path.realpath(out) == os.path.realpath(data):
            raise UserError(f"hyperelastic mesh --prepare: the output '{out}' holds the data of the input '{src}' "
                            "(an XDMF file's arrays live in it): choose another name")


def _xdmf_data_files(src):
    """The HDF5 files an .xdmf file's DataItems name (FILE:/path, relative to the .xdmf's folder); [] for any other
    input or an XDMF that cannot be read (its reader says why later)."""
    if not src.lower().endswith((".xdmf", ".xmf")) or not os.path.isfile(src):
        return []
    import xml.etree.ElementTree as ET
    try:
        items = ET.parse(src).getroot().iter("DataItem")
        names = {(d.text or "").strip().split(":", 1)[0] for d in items if d.get("Format", "").upper() == "HDF"}
    except (ET.ParseError, OSError):
        return []
    return [os.path.join(os.path.dirname(os.path.abspath(src)), n) for n in names if n]


def prepared_arrays(mesh):
    """The prepared layout of the checked mesh `mesh` (sets.Mesh, as mesh.read.read_mesh gives) as arrays: {attrs,
    the datasets by name, groups: [(name, tag, kind, ignored, mask)]} (the module's text). A quadratic mesh keeps its
    edge nodes (edge_points, edge_input_index, and cell_edges: each cell's six in element.EDGES order)."""
    used, compact = np.unique(mesh.tets, return_inverse=True)               # (a quadratic mesh: its corners)
    p, t, vperm, corder = spatial_order(mesh.points[used], compact.reshape(mesh.tets.shape))
    out = {"attrs": dict(format=FORMAT, version=VERSION, source=os.path.abspath(mesh.path), order=mesh.order,
                         vertices=len(p), cells=len(t), boundary_facets=len(mesh.facet_cell), nodes=len(mesh.points)),
           "points": p, "input_index": used[vperm].astype(np.int64), "cells": t.astype(np.int64),
           "cell_input_index": corder.astype(np.int64),
           "boundary": mesh.facet_mask(slice(None))[corder].astype(np.uint8), "groups": []}
    if mesh.order == 2:                   # the edge nodes: numbered by first use too, each cell's six into them
        edge = mesh.nodes[corder, 4:]
        uniq, first, inv = np.unique(edge.ravel(), return_index=True, return_inverse=True)
        by_use = np.argsort(first, kind="stable")
        number = np.empty(len(uniq), np.int64)
        number[by_use] = np.arange(len(uniq))
        out.update(edge_points=mesh.points[uniq[by_use]], edge_input_index=uniq[by_use].astype(np.int64),
                   cell_edges=number[inv.reshape(-1)].reshape(-1, 6))
    for g in mesh.groups.values():
        if g.kind == "facets":
            mask = mesh.facet_mask(g.items)
        else:
            mask = np.zeros(len(t), np.int64)
            mask[g.items] = 1
        out["groups"].append((g.name, g.tag, g.kind, int(g.ignored), mask[corder].astype(np.uint8)))
    return out


def prepare(mesh, out):
    """Write the prepared file of the checked mesh `mesh` (prepared_arrays) to `out` (.h5), atomically (a temporary
    file renamed: an existing `out` stays whole until the new one is). Returns {vertices, cells, boundary_facets,
    nodes, groups}."""
    data = prepared_arrays(mesh)
    tmp = f"{out}.{os.getpid()}.tmp"
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs.update(data["attrs"])
            for name, value in data.items():
                if name not in ("attrs", "groups"):
                    f.create_dataset(name, data=value)
            for i, (name, tag, kind, ignored, mask) in enumerate(data["groups"]):
                d = f.create_dataset(f"groups/{i}", data=mask)
                d.attrs.update(name=name, tag=-1 if tag is None else int(tag), kind=kind, ignored=ignored)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return {"vertices": data["attrs"]["vertices"], "cells": data["attrs"]["cells"],
            "boundary_facets": len(mesh.facet_cell), "nodes": len(mesh.points),
            "groups": [(g.name, g.kind, len(g.items)) for g in mesh.groups.values()]}


def open_prepared(path):
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
        if f.attrs.get("order") == 2:
            ne = f["edge_points"].shape[0] if "edge_points" in f else -1
            for name, shape in (("edge_points", (ne, 3)), ("edge_input_index", (ne,)), ("cell_edges", (nc, 6))):
                if name not in f or f[name].shape != shape:
                    raise UserError(f"mesh '{path}': prepared dataset '{name}' is missing or malformed (a damaged "
                                    "or hand-edited file: prepare it again)")
        for key, d in f.get("groups", {}).items():
            if d.shape != (nc,) or "name" not in d.attrs or d.attrs.get("kind") not in ("facets", "tets"):
                raise UserError(f"mesh '{path}': prepared group '{key}' is malformed (prepare it again)")
        return f
    except Exception:
        f.close()
        raise


def read_groups(f, lo=0, hi=None):
    """[(name, tag, kind, ignored, the rows lo:hi of its mask)] of a prepared file."""
    out = []
    for key in sorted(f.get("groups", {}), key=int):
        d = f["groups"][key]
        tag = int(d.attrs["tag"])
        out.append((str(d.attrs["name"]), None if tag < 0 else tag, str(d.attrs["kind"]), int(d.attrs["ignored"]),
                    d[lo:hi].astype(np.int64)))
    return out


def corner_ranks(ids):
    """(nc, 4) each corner's rank among its cell's corners by id (ids (nc, 4) the corners' input ids): the bit of the
    face without it in a cell's face bitmask."""
    return np.argsort(np.argsort(ids, axis=1, kind="stable"), axis=1)


def face_flags(ids, masks):
    """(nc, 4) whether face k (without corner k) is in each cell's bitmask `masks` (bit j: the face without the corner
    of j-th smallest id)."""
    return (np.asarray(masks, np.int64)[:, None] >> corner_ranks(ids)) & 1 == 1


def face_mask(ids, flags):
    """Each cell's bitmask of the faces `flags` (nc, 4) marks (face_flags' inverse)."""
    return (np.asarray(flags, np.int64) << corner_ranks(ids)).sum(axis=1)


def faces_of(ids, masks):
    """The face indices 4 c + k (face k: without corner k) of each cell's faces in `masks` (bit j: the face without
    the corner of j-th smallest id; ids (nc, 4) the corners' input ids), ascending."""
    return np.flatnonzero(face_flags(ids, masks).reshape(-1))


def _check_numbering(path, node_ids, n_nodes, cell_ids, cells, nv, cell_edges, ne):
    """The source indices are a numbering (each node and cell once) and the cells' rows are in range: one line."""
    for what, ids, n in (("node", node_ids, n_nodes), ("cell", cell_ids, len(cell_ids))):
        if len(ids) != n or (len(ids) and (ids.min() < 0 or ids.max() >= n or len(unique(ids)) != n)):
            raise UserError(f"mesh '{path}': its {what} indices are not a numbering of the source's {n} {what}s "
                            "(a damaged or hand-edited file: prepare it again)")
    for what, rows, n in (("cells", cells, nv), ("cell_edges", cell_edges, ne)):
        if rows.size and (rows.min() < 0 or rows.max() >= n):
            raise UserError(f"mesh '{path}': '{what}' refers to rows beyond its {n} (a damaged or hand-edited file: "
                            "prepare it again)")


def add_group(mesh, name, tag, kind, ignored, mask):
    """A prepared group (read_groups) as mesh's NamedSet: a facet set's items its facets' positions among the mesh's
    boundary facets (faces_of of its cells' bitmasks), a volume's its cells; mask: one value per cell of `mesh`, whose
    corners' input ids are mesh.ids[mesh.tets] (mesh.tets where ids is None)."""
    ids = mesh.tets if mesh.ids is None else mesh.ids[mesh.tets]
    boundary = 4 * mesh.facet_cell + mesh.facet_k
    items = np.searchsorted(boundary, faces_of(ids, mask)) if kind == "facets" else np.flatnonzero(mask)
    mesh.groups[name] = NamedSet(name, tag, kind, items, ignored)


def read_whole(path):
    """The whole prepared mesh as the checked source's sets.Mesh: its points, cells, boundary facets and groups in
    the source's numbering (the same arrays read_mesh gives of the source)."""
    with open_prepared(path) as f:
        vin, cin = f["input_index"][:], f["cell_input_index"][:]
        n_nodes = int(f.attrs.get("nodes", len(vin)))
        quadratic = f.attrs.get("order") == 2
        ein = f["edge_input_index"][:] if quadratic else np.zeros(0, np.int64)
        cells = f["cells"][:]
        cell_edges = f["cell_edges"][:] if quadratic else np.zeros((len(cin), 0), np.int64)
        _check_numbering(path, np.concatenate([vin, ein]), n_nodes, cin, cells, len(vin), cell_edges, len(ein))
        points = np.empty((n_nodes, 3))
        points[vin] = f["points"][:]
        tets = np.empty((len(cin), 4), np.int64)
        tets[cin] = vin[cells]
        nodes = None
        if quadratic:
            points[ein] = f["edge_points"][:]
            nodes = np.empty((len(cin), 10), np.int64)
            nodes[:, :4] = tets
            nodes[cin, 4:] = ein[cell_edges]
        bmask = np.empty(len(cin), np.int64)
        bmask[cin] = f["boundary"][:]
        groups = read_groups(f)
    mesh = Mesh.from_meshio(path, points, tets, faces_of(tets, bmask), nodes=nodes)
    for name, tag, kind, ignored, mask in groups:
        m = np.empty_like(mask)
        m[cin] = mask
        add_group(mesh, name, tag, kind, ignored, m)
    return mesh
