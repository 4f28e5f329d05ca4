"""How the cells are split among the ranks (-partitioner), on rank 0's serial mesh before DMPlex distributes it.

- `morton`: the cells in the order of a Z-curve through their centroids (mesh.order.spatial_order: the serial mesh is
  always built in that order), cut into equal contiguous ranges: PETSc's `simple` partitioner.
- `metis`: METIS (the `pymetis` wheel) on the mesh's dual graph (cells joined by a shared face), seeded, so the
  same mesh on the same rank count gets the same parts; handed to DMPlex through PETSc's `shell` partitioner.
- PETSc's own graph partitioners (`parmetis`, `ptscotch`, `chaco`) where the PETSc in use was built with them (a
  cluster's PETSc module); this PETSc's list is in `run --help`.

Each partition's quality is measured the same way once the mesh is distributed, by every rank on its own cells
(`quality`): the faces cut between ranks and the largest part's cells against the mean; the start-up report
prints them."""
import numpy as np
from petsc4py import PETSc

from ..mesh.sets import face_incidence

OWN = ("morton", "metis")
PETSC_OWN = ("parmetis", "ptscotch", "chaco")       # PETSc's graph partitioners, where it was built with them
DEFAULT = "morton"
METIS_SEED = 0


def names():
    """The partitioners this installation offers: ours, then PETSc's that it was built with."""
    return OWN + tuple(n for n in PETSC_OWN if PETSc.Sys.hasExternalPackage(n))


def refusal(name):
    """Why -partitioner NAME cannot run here (None where it can)."""
    if name in names():
        return None
    if name in PETSC_OWN:
        return (f"'{name}' is a partitioner of PETSc, and the PETSc in use was built without it (it needs a PETSc "
                f"configured with --download-{name}, e.g. a cluster's: docs/guide/install.md, on a cluster's PETSc); here: "
                f"{', '.join(names())}")
    return f"'{name}': the partitioners are {', '.join(names())}"


def dual_graph(tets):
    """(xadj, adjncy) of the cells' dual graph in CSR form: cells i and j are neighbours where they share a face
    (mesh.sets.face_incidence's pairs), each cell's neighbours in ascending order."""
    nc = len(tets)
    _, i, j = face_incidence(np.asarray(tets)[:, :4])
    rows, cols = np.concatenate([i // 4, j // 4]), np.concatenate([j // 4, i // 4])
    o = np.lexsort((cols, rows))
    xadj = np.zeros(nc + 1, np.int64)
    xadj[1:] = np.cumsum(np.bincount(rows, minlength=nc))
    return xadj, cols[o]


def parts_of(name, tets, nparts):
    """The rank of each cell (in the serial mesh's order) under partitioner `name` (ours: morton or metis)."""
    nc = len(tets)
    if name == "morton":
        sizes = np.full(nparts, nc // nparts) + (np.arange(nparts) < nc % nparts)
        return np.repeat(np.arange(nparts), sizes)
    import pymetis      # deferred: only a METIS partition needs it
    xadj, adjncy = dual_graph(tets)
    opts = pymetis.Options(seed=METIS_SEED)
    if hasattr(pymetis, "CSRAdjacency"):        # (pymetis 2025.2: xadj=/adjncy= deprecated, to go in 2027)
        _, parts = pymetis.part_graph(nparts, pymetis.CSRAdjacency(xadj, adjncy), options=opts)
    else:
        _, parts = pymetis.part_graph(nparts, xadj=xadj, adjncy=adjncy, options=opts)
    return np.asarray(parts, np.int64)


def quality(mpi, cells, boundary_faces):
    """{cut_faces, faces, imbalance} of the distributed mesh, each rank counting its own cells (collective):
    a face of one local cell is on the mesh's boundary or cut, so the cut faces are (the ranks' one-cell faces -
    the mesh's boundary faces) / 2; faces: all interior faces; imbalance: the largest part's cells over the mean.
    cells: this rank's cells (corners first); boundary_faces: the mesh's (rank 0's count is used)."""
    cells = np.asarray(cells)[:, :4]
    own_boundary = len(face_incidence(cells)[0]) if len(cells) else 0
    one, nc = mpi.allreduce(own_boundary), mpi.allgather(len(cells))
    b = mpi.bcast(boundary_faces, root=0)
    total = sum(nc)
    return {"cut_faces": (one - b) // 2, "faces": (4 * total - b) // 2, "imbalance": max(nc) * len(nc) / total}


def describe(name, q, nparts):
    return (f"partition: {name} into {nparts} parts, {q['cut_faces']} of {q['faces']} interior faces cut "
            f"({100.0 * q['cut_faces'] / max(q['faces'], 1):.2f}%), largest part {q['imbalance']:.3f}x the mean")


def apply(dm, name, tets, nparts):
    """Set DMPlex `dm`'s partitioner to `name` before it is distributed (collective; tets: the serial mesh's
    cells on rank 0, none elsewhere)."""
    part = dm.getPartitioner()
    if name in PETSC_OWN:
        part.setType(name)
    elif name == "morton":
        part.setType(PETSc.Partitioner.Type.SIMPLE)
    else:
        part.setType(PETSc.Partitioner.Type.SHELL)
        if len(tets) == 0:
            part.setShellPartition(nparts, np.zeros(nparts, PETSc.IntType), np.zeros(0, PETSc.IntType))
            return
        parts = parts_of(name, tets, nparts)
        points = np.argsort(parts, kind="stable")                 # each part's cells in the serial (Morton) order
        part.setShellPartition(nparts, np.bincount(parts, minlength=nparts).astype(PETSc.IntType),
                               points.astype(PETSc.IntType))
