"""-refine K: the mesh is distributed coarse and every rank refines its own part K times, uniformly, no rank holding
the whole fine mesh.

Each level splits every tetrahedron into eight (Bey, "Tetrahedral grid refinement", Computing 55, 1995): a new vertex
at each edge's midpoint, four corner tetrahedra, and the inner octahedron cut along its shortest diagonal into four
(the choice that keeps the children's shapes from degrading level by level; ties go to the first diagonal, so every
rank and every rank count makes the same choice). At the first level of a quadratic (10-node) mesh the new vertices
are its own edge nodes, so a curved boundary is sampled where the quadratic mesh places its nodes; at later levels,
and on a linear mesh, at straight midpoints (a curved surface stays as faceted as that mesh).

Numbering, the same on any rank count: a child of cell c is cell 8 c + j; the new vertices are numbered after the
level's vertices in the order of their edges' first appearance in that cell order (exchange.cell_edge_numbers: the
numbers mesh.read.elevate gives a whole mesh), so the whole fine mesh refined on one rank (`refine_whole`) has the same
vertex and cell numbers, positions and cells as the union of the ranks' parts. Sets follow exactly: a child's face
on its parent's face inherits that face's boundary and surface bits (4 facets per facet a level), a volume's children
are in it (8 per cell). Each rank computes the positions of its cells' new vertices itself (a midpoint is the same
bits wherever it is computed), so a level costs the edge numbering's exchanges and no exchange of positions."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ..core.errors import UserError
from ..element.reference import EDGES, cell_edges
from ..mesh.prepared import face_flags, face_mask
from .exchange import Exchange, alltoallv, cell_edge_numbers


def _tables():
    """(CHILDREN (3, 8, 4), CHILD_FACE (3, 8, 4)) for each choice of the octahedron's diagonal: each child's corners
    as the parent's local nodes (0-3 its corners, 4 + e the midpoint of EDGES[e]), positively oriented when the
    parent is; and the parent face (the face without parent corner k) that child face m (without child corner m) lies
    on, or -1 inside the parent."""
    node = {frozenset(e): 4 + i for i, e in enumerate(EDGES)}

    def m(i, j):
        return node[frozenset((i, j))]
    corner = [(0, m(0, 1), m(0, 2), m(0, 3)), (m(0, 1), 1, m(1, 2), m(1, 3)),
              (m(0, 2), m(1, 2), 2, m(2, 3)), (m(0, 3), m(1, 3), m(2, 3), 3)]
    # the three diagonals of the inner octahedron and, around each, its other four vertices in a cycle
    cuts = [((m(0, 1), m(2, 3)), (m(0, 2), m(0, 3), m(1, 3), m(1, 2))),
            ((m(0, 2), m(1, 3)), (m(0, 1), m(0, 3), m(2, 3), m(1, 2))),
            ((m(0, 3), m(1, 2)), (m(0, 1), m(0, 2), m(2, 3), m(1, 3)))]
    ref = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    X = np.concatenate([ref, [0.5 * (ref[i] + ref[j]) for i, j in EDGES]])
    support = [{i} for i in range(4)] + [set(e) for e in EDGES]
    children, faces = np.zeros((3, 8, 4), np.int64), np.zeros((3, 8, 4), np.int64)
    for d, ((p, q), ring) in enumerate(cuts):
        kids = corner + [(p, q, ring[i], ring[(i + 1) % 4]) for i in range(4)]
        for j, kid in enumerate(kids):
            kid = list(kid)
            a, b, c, e = X[kid]
            if np.dot(np.cross(b - a, c - a), e - a) < 0:
                kid[2], kid[3] = kid[3], kid[2]
            children[d, j] = kid
            for mm in range(4):
                used = set().union(*(support[kid[i]] for i in range(4) if i != mm))
                faces[d, j, mm] = (set(range(4)) - used).pop() if len(used) == 3 else -1
    return children, faces


CHILDREN, CHILD_FACE = _tables()
DIAGONALS = np.array([[4 + EDGES.index((0, 1)), 4 + EDGES.index((2, 3))],
                      [4 + EDGES.index((0, 2)), 4 + EDGES.index((1, 3))],
                      [4 + EDGES.index((0, 3)), 4 + EDGES.index((1, 2))]])


@dataclass
class Part:
    """A rank's part of a mesh being refined: its cells' corners by input id (nc, 4) and their positions (nc, 4, 3),
    each cell's input id, its boundary-facet bitmask (bit j: its face without the corner of j-th smallest id) and
    its groups [(name, tag, kind, ignored, mask)] (a facet group: a bitmask as the boundary's; a volume: 0/1); the
    whole mesh's vertex, cell and boundary-facet counts."""
    ids: np.ndarray
    X: np.ndarray
    cell_ids: np.ndarray
    bmask: np.ndarray
    groups: list
    nv: int
    nc: int
    nb: int


def _child_masks(ids, child_ids, face_of, mask):
    """The children's bitmasks of the parents' bitmask `mask` (face_of: (nc, 8, 4) each child face's parent face,
    -1 inside)."""
    flags = face_flags(ids, mask)
    flags = np.concatenate([flags, np.zeros((len(flags), 1), bool)], axis=1)       # column 4: inside
    child = flags[np.arange(len(flags))[:, None, None], np.where(face_of < 0, 4, face_of)]      # (nc, 8, 4)
    return face_mask(child_ids.reshape(-1, 4), child.reshape(-1, 4))


def refine_level(mpi, part, edges=None):
    """The part one level finer (module text; collective). edges: a quadratic mesh's edge nodes, (input ids (nc, 6),
    positions (nc, 6, 3)), the new vertices instead of numbered midpoints (part.nv then counts all its nodes)."""
    nc = len(part.ids)
    if edges is None:
        number = cell_edge_numbers(mpi, cell_edges(part.ids), part.cell_ids, part.nv, part.nc)
        nv = part.nv + mpi.allreduce(int(number.max()) + 1 if len(number) else 0, op=MPI.MAX)
        edge_ids = part.nv + number.reshape(nc, 6)
        edge_X = np.stack([0.5 * (part.X[:, i] + part.X[:, j]) for i, j in EDGES], axis=1)
    else:
        (edge_ids, edge_X), nv = edges, part.nv
    node_ids = np.concatenate([part.ids, edge_ids], axis=1)                                       # (nc, 10)
    node_X = np.concatenate([part.X, edge_X], axis=1)                                            # (nc, 10, 3)
    rows = np.arange(nc)[:, None]
    lengths = np.linalg.norm(node_X[rows, DIAGONALS[:, 0][None]] - node_X[rows, DIAGONALS[:, 1][None]], axis=2)
    d = np.argmin(lengths, axis=1)                                                  # (the first of equal ones)
    pick = CHILDREN[d]                                                              # (nc, 8, 4)
    rows3 = np.arange(nc)[:, None, None]
    ids, X = node_ids[rows3, pick], node_X[rows3, pick]
    face_of = CHILD_FACE[d]
    groups = []
    for name, tag, kind, ignored, mask in part.groups:
        mask = (_child_masks(part.ids, ids, face_of, mask) if kind == "facets"
                else np.repeat(np.asarray(mask, np.int64), 8))
        groups.append((name, tag, kind, ignored, mask))
    return Part(ids.reshape(-1, 4), X.reshape(-1, 4, 3), (part.cell_ids[:, None] * 8 + np.arange(8)).reshape(-1),
                _child_masks(part.ids, ids, face_of, part.bmask), groups, nv, 8 * part.nc, 4 * part.nb)


# what a run needs a tetrahedron, measured: bend -level 1 -refine 3 (877,568 tets, P1, Jacobi) peaked at 996 MB of
# RSS, ~1.0 KB a tet past the ~100 MB a process starts with (GAMG and P2 need more: this is the least)
BYTES_PER_TET = 1000
# a refined tet mesh holds about one vertex per 5.5 tets (a cube's uniform refinement: 6); the index check's estimate
TETS_PER_VERTEX = 6


def available_bytes(mpi):
    """The memory this rank may take: its address-space limit (ulimit -v) less what it maps now, and the node's
    available memory (MemAvailable) shared among the node's ranks; the least over the ranks (collective)."""
    import resource
    room = []
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    status = _proc_kb("/proc/self/status", "VmSize:")
    if soft != resource.RLIM_INFINITY and status is not None:
        room.append(soft - 1024 * status)
    avail = _proc_kb("/proc/meminfo", "MemAvailable:")
    if avail is not None:
        local = mpi.Split_type(MPI.COMM_TYPE_SHARED)
        room.append(1024 * avail // local.size)
        local.Free()
    return mpi.allreduce(min(room) if room else float("inf"), op=MPI.MIN)


def _proc_kb(path, key):
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def check_room(mpi, name, nc, levels, index_bits):
    """Before refining: the fine mesh's size against this machine's memory (BYTES_PER_TET a tet, shared by the ranks)
    and its unknowns against PETSc's indices (3 per vertex, about nc / TETS_PER_VERTEX vertices), one line on every
    rank (collective): -refine 8 ran 30-58 s into a MemoryError (issue 73)."""
    fine = nc * 8 ** levels
    need = BYTES_PER_TET * fine / mpi.size
    have = available_bytes(mpi)
    if need > have:
        raise UserError(f"-refine {levels}: the {nc:,} tetrahedra of mesh '{name}' become {fine:,} (8^{levels} "
                        f"each), which need about {need / 1e9:.3g} GB a rank on {mpi.size} rank(s) (at least "
                        f"{BYTES_PER_TET / 1e3:g} KB a tetrahedron) where a rank here has {max(have, 0) / 1e9:.3g} GB "
                        "(the memory available, or its limit): refine less, or run on more ranks or machines")
    dofs = 3 * fine // TETS_PER_VERTEX
    if dofs >= 2 ** (index_bits - 1):
        raise UserError(f"-refine {levels}: the {nc:,} tetrahedra of mesh '{name}' become {fine:,}, about {dofs:,} "
                        "unknowns: "
                        f"more than the {index_bits}-bit indices of this PETSc hold (at most "
                        f"{2 ** (index_bits - 1) - 1:,}); build PETSc with 64-bit indices "
                        "(PETSC_CONFIGURE_OPTIONS='--with-64-bit-indices')")


def refine(mpi, part, levels, edges=None, check=None):
    """The part `levels` levels finer (collective); edges: a quadratic mesh's edge nodes (refine_level), the first
    level's new vertices;
    check(n_vertices): called with each level's vertex count before the next (a UserError there stops it)."""
    for level in range(levels):
        part = refine_level(mpi, part, edges if level == 0 else None)
        if check is not None:
            check(part.nv)
    return part


def first_use_rows(mpi, part):
    """A contiguous ownership of the part's vertices for DMPlexBuildFromCellListParallel (collective): each vertex
    belongs to the lowest rank whose cells use it, numbered there by first use in its cells, the ranks' blocks in rank
    order. Returns (cells by row (nc, 4), the first row this rank holds, the positions and ids of its rows)."""
    size, rank = mpi.size, mpi.rank
    u, first, inverse = np.unique(part.ids.reshape(-1), return_index=True, return_inverse=True)
    X = part.X.reshape(-1, 3)[first]
    dest = np.minimum(u * size // max(part.nv, 1), size - 1)
    got, got_counts = alltoallv(mpi, u, np.bincount(dest, minlength=size))         # (u sorted: dest ascending)
    src = np.repeat(np.arange(size), got_counts)
    key, at = np.unique(got, return_inverse=True)
    owner = np.full(len(key), size, np.int64)
    np.minimum.at(owner, at.reshape(-1), src)
    mine, _ = alltoallv(mpi, owner[at.reshape(-1)], got_counts)
    own = np.flatnonzero(mine == rank)
    own = own[np.argsort(first[own], kind="stable")]                                # by first use in its cells
    start = mpi.exscan(len(own), op=MPI.SUM) or 0
    rows = Exchange(mpi, u[own], u, part.nv).move(start + np.arange(len(own), dtype=np.int64))
    return rows[inverse.reshape(-1)].reshape(-1, 4), start, X[own], u[own]


def refine_whole(mesh, levels):
    """The whole mesh `mesh` (sets.Mesh, linear or quadratic) refined `levels` times on this process alone, in the
    numbering the ranks' parts have (module text): (points by vertex id, cells (nc, 4) by cell id)."""
    ids = mesh.tets
    part = Part(ids, mesh.points[ids], np.arange(len(ids)), np.zeros(len(ids), np.int64), [], len(mesh.points),
                len(ids), 0)
    edges = (mesh.nodes[:, 4:], mesh.points[mesh.nodes[:, 4:]]) if mesh.nodes is not None else None
    part = refine(MPI.COMM_SELF, part, levels, edges)
    points = np.empty((part.nv, 3))
    points[part.ids.reshape(-1)] = part.X.reshape(-1, 3)
    cells = np.empty_like(part.ids)
    cells[part.cell_ids] = part.ids
    return points, cells
