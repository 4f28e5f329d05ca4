"""Reading and checking any tetrahedral mesh meshio reads (or an output of this application), quadratic meshes
and their corners, spatial ordering of cells, point location in a mesh."""
import json
import os
import sys
import warnings

import h5py
import numpy as np

from ..core.data import cache_dir
from ..core.errors import UserError
from ..core.arrays import unique
from ..core.files import completed_frames, is_output, require_parts
from ..element.reference import REFERENCE_NODES, TET_RULES, cell_edges, tet_shapes
from .prepared import is_prepared, read_whole
from .sets import FACE_VERTICES, Mesh, NamedSet, face_incidence, signed_volumes

def read(path):
    """Read a tetrahedral mesh with meshio and check it; returns (points (n,3) float64, tets (m,4) int64).
    Any defect raises UserError naming the file and the first bad element."""
    m = read_mesh(path)
    return m.points, m.tets


def read_mesh(path, frame=-1):
    """The checked tetrahedral mesh of `path` with its boundary facets and named sets (sets.Mesh). An
    output file of this application (.h5, or the .xdmf beside it) gives the mesh in the configuration
    of its frame `frame` (default: the last; None: the reference configuration), with its regions."""
    path = os.fspath(path)
    if os.path.exists(path) and not os.path.isfile(path) and not os.path.isdir(path):
        raise UserError(f"mesh '{path}': is not a regular file")
    if path.lower().endswith(".xdmf") and is_output(os.path.splitext(path)[0] + ".h5"):
        path = os.path.splitext(path)[0] + ".h5"
    if path.lower().endswith((".h5", ".hdf5")) and is_output(path):
        return _read_output(path, frame)
    if path.lower().endswith((".h5", ".hdf5")) and is_prepared(path):
        mesh = read_whole(path)                # (checked as any mesh: rank 0 reads it whole only on a fallback path)
        if mesh.nodes is None:
            check(mesh.points, mesh.tets, path)
        else:
            check_quadratic(mesh.points, mesh.nodes, path)
        return mesh
    cached = _parsed(path)
    if cached is not None:
        return cached
    points, tets, m, boundary, nodes = _read_meshio(path)
    mesh = Mesh.from_meshio(path, points, tets, boundary, m, nodes)
    _keep_parsed(path, mesh)
    return mesh


# Reading a mesh file with meshio's parsers (and importing them) and checking it took ~0.3 s of a 1.4 s run on the
# bar's 1.7k tets, for every run of a study on the same mesh: the checked mesh is kept in the user's cache
# (core.data.cache_dir("parsed")) as plain arrays, keyed by the file's path, size and modification time and by this
# reader's version (PARSED_FORMAT: raise it when what a Mesh holds changes). A file that fails its checks is never
# kept; a cache that cannot be written is skipped.
PARSED_FORMAT = 1
PARSED_KEPT = (256, 192)      # more files than the first: the least recently used are removed down to the second
_MESH_ARRAYS = ("points", "tets", "facet_cell", "facet_k", "nodes")


def _parsed_path(path):
    import hashlib
    st = os.stat(path)
    key = f"{os.path.realpath(path)}\0{st.st_size}\0{st.st_mtime_ns}\0{PARSED_FORMAT}"
    return os.path.join(cache_dir("parsed"), hashlib.sha1(key.encode()).hexdigest() + ".npz")


def _parsed(path):
    """The checked Mesh of `path` from the cache, or None."""
    try:
        cached = _parsed_path(path)
        with np.load(cached, allow_pickle=False) as z:
            groups = json.loads(str(z["groups"]))
            mesh = Mesh(path, **{k: (z[k] if z[k].size or k != "nodes" else None) for k in _MESH_ARRAYS})
            for i, g in enumerate(groups):
                mesh.groups[g["name"]] = NamedSet(g["name"], g["tag"], g["kind"], z[f"group{i}"], g["ignored"])
        os.utime(cached)              # (recently used: kept by _prune)
        return mesh
    except (OSError, KeyError, ValueError):
        return None


def _keep_parsed(path, mesh):
    try:
        final = _parsed_path(path)
        tmp = f"{final}.{os.getpid()}.tmp.npz"
        arrays = {k: (getattr(mesh, k) if getattr(mesh, k) is not None else np.zeros((0, 10), np.int64))
                  for k in _MESH_ARRAYS}
        groups = list(mesh.groups.values())
        meta = [{"name": g.name, "tag": None if g.tag is None else int(g.tag), "kind": g.kind, "ignored": int(g.ignored)}
                for g in groups]
        arrays.update({f"group{i}": np.asarray(g.items) for i, g in enumerate(groups)})
        np.savez(tmp, groups=np.array(json.dumps(meta)), **arrays)
        os.replace(tmp, final)
        _prune(os.path.dirname(final))
    except OSError:
        pass


def _prune(d):
    """Keep the parsed meshes' cache bounded (PARSED_KEPT): the least recently read files go first."""
    files = [os.path.join(d, f) for f in os.listdir(d) if f.endswith(".npz")]
    if len(files) <= PARSED_KEPT[0]:
        return
    for f in sorted(files, key=os.path.getmtime)[:len(files) - PARSED_KEPT[1]]:
        try:
            os.remove(f)
        except OSError:
            pass


def _read_output(path, frame):
    """sets.Mesh of frame `frame` of an output file: its positions become the reference, its regions
    (mesh/region, named as the run's attribute `sets` names them) are kept."""
    with h5py.File(path, "r") as f:
        require_parts(f, path, f"mesh '{path}'")
        row = output_frame(f, path, frame)
        points = f["mesh/points"][:] if row is None else f["x"][row]
        cells = f["mesh/tetra"][:].astype(np.int64)
        region = f["mesh/region"][:] if "mesh/region" in f else np.zeros(len(cells), np.int64)
        named = region_names(f)
    if cells.ndim != 2 or cells.shape[1] not in (4, 10):
        raise UserError(f"mesh '{path}': mesh/tetra has shape {cells.shape} (4 or 10 nodes per cell expected)")
    if cells.shape[1] == 10:
        mesh = Mesh.from_meshio(path, points, cells[:, :4], check_quadratic(points, cells, path), nodes=cells)
    else:
        mesh = Mesh.from_meshio(path, points, cells, check(points, cells, path))
    for tag in np.unique(region[region != 0]):
        name = named.get(int(tag), str(int(tag)))
        mesh.groups[name] = NamedSet(name, int(tag), "tets", np.flatnonzero(region == tag))
    return mesh


def _read_meshio(path):
    if not os.path.exists(path):
        raise UserError(f"mesh '{path}': no such file")
    if os.path.isdir(path):
        raise UserError(f"mesh '{path}': is a directory")
    m = read_meshio(path, f"mesh '{path}'")
    points = np.asarray(m.points, dtype=np.float64)
    found = sorted({c.type for c in m.cells})
    if "tetra" in found and "tetra10" in found:
        raise UserError(f"mesh '{path}': mixes linear (tetra) and quadratic (tetra10) tetrahedra")
    kind = "tetra10" if "tetra10" in found else "tetra"
    blocks = [c.data for c in m.cells if c.type == kind]
    if not blocks:
        what = ", ".join(found) if found else "no cells"
        hint = ("; a gmsh file with physical surfaces but no 'Physical Volume' holds no tetrahedra"
                if "triangle" in found or "triangle6" in found else "")
        raise UserError(f"mesh '{path}': contains no tetrahedra (found: {what}){hint}")
    cells = np.concatenate(blocks).astype(np.int64)
    if kind == "tetra10":
        return points, cells[:, :4], m, check_quadratic(points, cells, path), cells
    return points, cells, m, check(points, cells, path), None


def check_quadratic(points, nodes, path):
    """check() of quadratic cells (nc, 10): the corners a mesh of a solid, each edge one node shared by every
    cell that has the edge, no node both a corner and an edge's, every point a node, and the geometry map
    one-to-one (det J of the same sign as the corners' at every point of the degree-5 rule and at the
    nodes). Returns the boundary face indices."""
    if len(nodes) and ((nodes < 0) | (nodes >= len(points))).any():
        i = int(np.flatnonzero(((nodes < 0) | (nodes >= len(points))).any(axis=1))[0])
        raise UserError(f"mesh '{path}': tetrahedron {i} has a node index out of range {nodes[i].tolist()} "
                        f"(mesh has {len(points)} nodes)")
    corners = nodes[:, :4]
    used, compact = np.unique(corners, return_inverse=True)
    boundary = check(points[used], compact.reshape(corners.shape), path)
    pairs = cell_edges(corners)
    edge_nodes = nodes[:, 4:].reshape(-1)
    key, first, inv = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    bad = np.flatnonzero(edge_nodes != edge_nodes[first][inv.ravel()])
    if len(bad):
        c = int(bad[0] // 6)
        raise UserError(f"mesh '{path}': tetrahedron {c} gives edge {key[inv.ravel()[bad[0]]].tolist()} another "
                        f"node ({edge_nodes[bad[0]]}) than a neighbour does ({edge_nodes[first][inv.ravel()][bad[0]]})")
    enodes = edge_nodes[first]
    if len(unique(enodes)) != len(enodes) or np.isin(enodes, used).any():
        raise UserError(f"mesh '{path}': an edge node is also a corner or another edge's node")
    if len(used) + len(enodes) != len(points):
        raise UserError(f"mesh '{path}': {len(points) - len(used) - len(enodes)} nodes belong to no tetrahedron")
    sign = np.sign(signed_volumes(points, corners))
    for pts in (TET_RULES[5][0], REFERENCE_NODES):
        _, dN = tet_shapes(2, pts)
        det = np.linalg.det(np.einsum("cai,qaj->cqij", points[nodes], dN))
        bad = np.flatnonzero((det * sign[:, None] <= 0).any(axis=1))
        if len(bad):
            raise UserError(f"mesh '{path}': tetrahedron {int(bad[0])} is folded: its map from the reference "
                            "cell changes orientation inside it (an edge node too far from its edge)")
    return boundary


def elevate(mesh):
    """The quadratic (straight-sided) mesh of a linear one: a node at the midpoint of every edge, numbered
    after the vertices in the order of the edges' first appearance."""
    tets = mesh.tets
    pairs = cell_edges(tets)
    key, first, inv = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    ids = len(mesh.points) + rank[inv.ravel()].reshape(-1, 6)
    mids = 0.5 * (mesh.points[key[order, 0]] + mesh.points[key[order, 1]])
    out = Mesh(mesh.path, np.concatenate([mesh.points, mids]), tets, mesh.facet_cell, mesh.facet_k, mesh.groups,
               np.concatenate([tets, ids], axis=1))
    return out


# boundary edges whose two facets meet at an angle in this range (degrees) look like a faceted curved surface
# (a cylinder in 8 to 360 segments, a fillet); sharper ones are a part's own edges, flatter ones a plane's
CURVED_ANGLES = (0.5, 40.0)


def bent_edges(mesh):
    """(boundary edges where the two boundary facets meet at an angle in CURVED_ANGLES, all boundary edges) of a
    linear mesh: how much of its boundary is a faceted curved surface."""
    tri = mesh.facets()
    p = mesh.points
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    facet = np.tile(np.arange(len(tri)), 3)
    order = np.lexsort(edges.T[::-1])
    e, f = edges[order], facet[order]
    pair = np.flatnonzero((e[1:] == e[:-1]).all(axis=1))
    cos = np.clip((n[f[pair]] * n[f[pair + 1]]).sum(axis=1), -1.0, 1.0)
    angle = np.degrees(np.arccos(cos))
    lo, hi = CURVED_ANGLES
    return int(((angle > lo) & (angle < hi)).sum()), len(pair)


def corners(mesh):
    """The linear mesh of a quadratic one's corners (its edge nodes dropped, the vertices renumbered in their
    order)."""
    used, compact = np.unique(mesh.tets, return_inverse=True)
    return Mesh(mesh.path, mesh.points[used], compact.reshape(mesh.tets.shape), mesh.facet_cell, mesh.facet_k,
                mesh.groups)


def read_meshio(path, what):
    """meshio's mesh of the file, silently; one line (UserError, starting with `what`) where it cannot be read."""
    import meshio  # deferred on purpose: ~0.2 s to load its format readers, needed only for foreign meshes
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _quiet(meshio.read, path)
    except (Exception, SystemExit) as e:  # meshio raises many kinds of errors (even SystemExit) for malformed files
        msg = ("malformed file" if isinstance(e, SystemExit) else
               str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__)
        raise UserError(f"{what}: cannot be read ({msg[:200]})") from None


def _quiet(fn, *args):
    """Call fn with C-level stdout/stderr silenced (meshio and gmsh may print)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        os.dup2(null.fileno(), 2)
        try:
            return fn(*args)
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def locate(points, tets, P):
    """(cell index, barycentric weights (k,4)) of each point P (k,3) in the reference mesh; UserError
    for a point outside it. Brute force over cells (meant for a handful of material points)."""
    P = np.atleast_2d(np.asarray(P, np.float64))
    cells, weights = [], []
    for p in P:
        c, bary = deepest(points, tets, p)
        if bary.min() < -1e-9:
            raise UserError(f"material point ({', '.join(f'{v:g}' for v in p)}) lies outside the mesh")
        cells.append(c)
        weights.append(bary)
    return np.array(cells), np.array(weights)


def deepest(points, tets, p):
    """(cell, its barycentric weights of p): the cell p is deepest inside (its least weight the largest; negative
    where p is outside every cell)."""
    X0 = points[tets[:, 0]]
    D = np.stack([points[tets[:, a]] - X0 for a in (1, 2, 3)], axis=-1)       # (nc,3,3)
    lam = np.einsum("cij,cj->ci", np.linalg.inv(D), p - X0)
    bary = np.column_stack([1.0 - lam.sum(axis=1), lam])
    c = int(np.argmax(bary.min(axis=1)))
    return c, bary[c]


def interpolate(tets, cells, weights, values):
    """Interpolation of nodal `values` (nv, ...) at points given by locate(): P1 with the barycentric weights, or
    P2 for cells of 10 nodes (their shape functions at the point's reference coordinates: exact on
    straight cells; on curved ones the coordinates are the corners' affine estimate)."""
    if tets.shape[1] == 10:
        weights = tet_shapes(2, weights[:, 1:])[0]
    return np.einsum("ka,ka...->k...", weights, values[tets[cells]])


def flat_or_inverted(points, tets):
    """(signed volumes, the first cell of zero volume (|V| <= 1e-12 of its longest edge cubed) or None, the first
    inverted cell or None) of cells `tets`: check()'s test, and each rank's of its own cells (discretization.slices)."""
    V, lmax = signed_volumes(points, tets, longest=True)
    tiny, negative = np.flatnonzero(np.abs(V) <= 1e-12 * lmax ** 3), np.flatnonzero(V < 0)
    return V, int(tiny[0]) if len(tiny) else None, int(negative[0]) if len(negative) else None


def output_frame(f, path, frame):
    """The row of x an open output's frame `frame` is (negative: from the last), or None for its reference
    configuration (frame None, or an output without frames); UserError where it has no such frame."""
    nf = completed_frames(f)
    if nf == 0 or frame is None:
        return None
    if not -nf <= frame < nf:
        raise UserError(f"mesh '{path}': has no frame {frame} (it has {nf}: 0..{nf - 1})")
    return frame % nf


def region_names(f):
    """{tag: name} of an open output's regions (its `sets` attribute's volumes; {} where it cannot be read)."""
    try:
        return {int(s["tag"]): s["name"] for s in json.loads(f.attrs.get("sets", "[]")) if s["kind"] == "tets"}
    except (ValueError, KeyError, TypeError):
        return {}


def check(points, tets, path):
    """One line for whatever makes (points, tets) not a mesh of a solid; else its boundary face indices."""
    if points.ndim != 2 or points.shape[1] < 3 or len(points) == 0:
        raise UserError(f"mesh '{path}': has no 3-D vertices")
    points = points[:, :3]
    if len(tets) == 0:
        raise UserError(f"mesh '{path}': is empty (0 tetrahedra)")
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if len(bad):
        raise UserError(f"mesh '{path}': vertex {bad[0]} has a non-finite coordinate {points[bad[0]].tolist()}")
    bad = np.flatnonzero((np.abs(points) > 1e30).any(axis=1))
    if len(bad):
        raise UserError(f"mesh '{path}': vertex {bad[0]} has a coordinate beyond 1e30 {points[bad[0]].tolist()}")
    bad = np.flatnonzero(((tets < 0) | (tets >= len(points))).any(axis=1))
    if len(bad):
        raise UserError(f"mesh '{path}': tetrahedron {bad[0]} has a vertex index out of range "
                        f"{tets[bad[0]].tolist()} (mesh has {len(points)} vertices)")
    s = np.sort(tets, axis=1)
    bad = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if len(bad):
        raise UserError(f"mesh '{path}': tetrahedron {bad[0]} repeats a vertex {tets[bad[0]].tolist()}")
    used = np.zeros(len(points), bool)
    used[tets.ravel()] = True
    if not used.all():
        v = int(np.flatnonzero(~used)[0])
        raise UserError(f"mesh '{path}': vertex {v} is not used by any tetrahedron "
                        f"({int((~used).sum())} unused vertices)")
    order = np.lexsort(points.T[::-1])
    sp = points[order]
    dup = np.flatnonzero((sp[1:] == sp[:-1]).all(axis=1))
    if len(dup):
        a, b = sorted((int(order[dup[0]]), int(order[dup[0] + 1])))
        raise UserError(f"mesh '{path}': vertices {a} and {b} are duplicates at {points[a].tolist()}")
    V, tiny, negative = flat_or_inverted(points, tets)
    if tiny is not None:
        raise UserError(f"mesh '{path}': tetrahedron {tiny} has zero volume (vertices {tets[tiny].tolist()})")
    if negative is not None:
        i = negative
        raise UserError(f"mesh '{path}': tetrahedron {i} is inverted (negative volume {V[i]:.3g}, "
                        f"vertices {tets[i].tolist()})")
    boundary = check_faces(points, tets, path)
    check_pieces(points, tets, path)
    return boundary


def components(nv, tets):
    """The connected piece of each vertex (pieces share no vertex): labels 0..k-1 (numpy union-find,
    hooking each tetrahedron's vertices onto the smallest root, then pointer jumping)."""
    parent = np.arange(nv)
    u = np.repeat(tets[:, 0], tets.shape[1] - 1)
    v = tets[:, 1:].ravel()
    while True:
        pu, pv = parent[u], parent[v]
        m = pu != pv
        if not m.any():
            break
        np.minimum.at(parent, np.maximum(pu, pv)[m], np.minimum(pu, pv)[m])
        while True:
            pp = parent[parent]
            if (pp == parent).all():
                break
            parent = pp
    return np.unique(parent, return_inverse=True)[1]


def check_pieces(points, tets, path):
    """Separate pieces (sharing no vertex) must not overlap: a cell centre of one strictly inside a
    tetrahedron of another is one error line (the face check above cannot see them)."""
    comp = components(len(points), tets)
    if comp.max() == 0:
        return
    cell_comp = comp[tets[:, 0]]
    X = points[tets]
    centres = X.mean(axis=1)
    lo, hi = X.min(axis=1), X.max(axis=1)
    k = comp.max() + 1
    blo = np.full((k, 3), np.inf)
    bhi = np.full((k, 3), -np.inf)
    np.minimum.at(blo, cell_comp, lo)
    np.maximum.at(bhi, cell_comp, hi)
    order = np.argsort(cell_comp, kind="stable")
    members = np.split(order, np.searchsorted(cell_comp[order], np.arange(1, k)))     # each piece's cells
    for a in range(k):
        for b in range(a + 1, k):
            if (np.minimum(bhi[a], bhi[b]) <= np.maximum(blo[a], blo[b])).any():
                continue                                    # the boxes do not overlap
            for p, q in ((a, b), (b, a)):
                hit = inside_cells(points, tets[members[q]], centres[members[p]])
                if hit is not None:
                    c, other = int(members[p][hit[0]]), int(members[q][hit[1]])
                    raise UserError(f"mesh '{path}': tetrahedra {min(c, other)} and {max(c, other)} overlap (in "
                                    "separate pieces of the mesh: the centre of one lies inside the other)")


def inside_cells(points, tets, P, tol=1e-9):
    """(index into P, index into tets) of a point strictly inside one of the tetrahedra, or None. Cells and
    points are binned on a grid of the largest cell's extent (each cell in at most 2x2x2 bins)."""
    X = points[tets]
    lo, hi = X.min(axis=1), X.max(axis=1)
    h = max(float((hi - lo).max()), 1e-300)
    origin = lo.min(axis=0)
    nb = np.floor((hi.max(axis=0) - origin) / h).astype(np.int64) + 2
    key = lambda B: B[:, 0] + nb[0] * (B[:, 1] + nb[1] * B[:, 2])        # noqa: E731
    blo = np.floor((lo - origin) / h).astype(np.int64)
    bhi = np.floor((hi - origin) / h).astype(np.int64)
    keys, cells = [], []
    for off in np.ndindex(2, 2, 2):
        B = blo + off
        m = (B <= bhi).all(axis=1)
        keys.append(key(B[m]))
        cells.append(np.flatnonzero(m))
    keys, cells = np.concatenate(keys), np.concatenate(cells)
    order = np.argsort(keys, kind="stable")
    keys, cells = keys[order], cells[order]
    Bp = np.floor((P - origin) / h).astype(np.int64)
    ok = ((Bp >= 0) & (Bp < nb)).all(axis=1)
    pk = np.where(ok, key(np.clip(Bp, 0, nb - 1)), -1)
    start, stop = np.searchsorted(keys, pk, "left"), np.searchsorted(keys, pk, "right")
    n = stop - start
    pi = np.repeat(np.arange(len(P)), n)
    ci = cells[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    chunk = 1 << 20                                  # (point, cell) pairs per batch: bounded temporaries
    for lo_ in range(0, len(pi), chunk):
        pp, cc = pi[lo_:lo_ + chunk], ci[lo_:lo_ + chunk]
        X0 = X[cc, 0]
        D = np.stack([X[cc, a] - X0 for a in (1, 2, 3)], axis=-1)
        lam = np.linalg.solve(D, (P[pp] - X0)[..., None])[..., 0]
        bary = np.column_stack([1.0 - lam.sum(axis=1), lam])
        inside = np.flatnonzero(bary.min(axis=1) > tol)
        if len(inside):
            return int(pp[inside[0]]), int(cc[inside[0]])
    return None


def check_faces(points, tets, path):
    """A conforming mesh of a solid: every triangle is a face of one tetrahedron (the boundary) or of
    two on opposite sides of it. A face of three or more tetrahedra, or two on the same side, means
    duplicate or overlapping tetrahedra. Returns the boundary face indices (sets.face_incidence)."""
    boundary, i, j = face_incidence(tets, path)
    opposite = tets.reshape(-1)                     # the vertex of the tet not on each face
    bad, chunk = [], 1 << 20
    for lo in range(0, len(i), chunk):              # in chunks: the per-face (n,3) temporaries stay small
        ii, jj = i[lo:lo + chunk], j[lo:lo + chunk]
        f = tets[ii // 4][np.arange(len(ii))[:, None], FACE_VERTICES[ii % 4]]    # face vertices, i's order
        a, b, c = (points[f[:, k]] for k in range(3))
        nrm = np.cross(b - a, c - a)
        bad = np.flatnonzero(np.einsum("ij,ij->i", nrm, points[opposite[ii]] - a)
                             * np.einsum("ij,ij->i", nrm, points[opposite[jj]] - a) >= 0)
        if len(bad):
            i, j, f = ii, jj, f
            break
    if len(bad):
        c1, c2 = sorted((int(i[bad[0]] // 4), int(j[bad[0]] // 4)))
        what = "are the same tetrahedron" if sorted(tets[c1]) == sorted(tets[c2]) else "overlap"
        raise UserError(f"mesh '{path}': tetrahedra {c1} and {c2} {what} (on the same side of their shared face "
                        f"{sorted(f[bad[0]].tolist())})")
    return boundary
