"""P1 vector field (3 dofs per vertex) on a distributed, uninterpolated DMPlex of tetrahedra.

Rank 0 reads the mesh, orders it spatially and builds the serial DMPlex; `distribute` with the run's
partitioner (partition.py: by default the `simple` one, a contiguous range of the spatially ordered cells per
rank) hands each rank its cells. A prepared mesh or a per-rank output is instead read by every rank in slices
(slices.py) and the space adopts the DMPlex the ranks built from them (`_adopt`, `_adopt_elevated`). Every rank
then knows, for its local vertices (owned + ghosts): the local dof offsets, reference coordinates, the index of the
vertex in the input mesh, and ownership. Per-cell Dm^-1 and volumes are computed once here.

No rank but rank 0 (while it reads a mesh whole) holds an array of the whole mesh: what each rank needs of the
serial mesh (input indices, P2 node positions) travels point by point through the distribution's migration star
forest (`pull`), a restart's state is read by every rank in slices and sent to the ranks whose nodes the rows are
(`read_state`), and the output's gather plan is built on rank 0 when the output first gathers.
"""
import numpy as np
from petsc4py import PETSc

from mpi4py import MPI

from ..element.reference import EDGES, cell_edges
from . import partition
from .exchange import Exchange
from .exchange import cell_edge_numbers
from .kernels import IDX, Cells, ElementCells
from ..core.arrays import unique
from ..core.errors import UserError
from ..core.libpetsc import cell_cones, plex_cones
from ..mesh.order import spatial_order
from ..mesh.prepared import corner_ranks, faces_of
from ..mesh.sets import FACE_VERTICES, VERTEX_VALUE, cell_label, facet_label, orient_outward


def reference_geometry(X, cells):
    """Per cell, computed once: Dm^-1 (thesis eq. 4.29 in matrix form) and the volume |det Dm|/6
    (F = Ds Dm^-1 does not depend on vertex order; the volume must be > 0)."""
    Xc = X[cells]
    Dm = np.stack([Xc[:, 1] - Xc[:, 0], Xc[:, 2] - Xc[:, 0], Xc[:, 3] - Xc[:, 0]], axis=-1)
    return np.ascontiguousarray(np.linalg.inv(Dm)), np.abs(np.linalg.det(Dm)) / 6.0


def set_labels(dm, labels, corder, point_of_input):
    """The labels {name: {value: ("cells" | "vertices", input indices)}} on a serial DMPlex whose cell i is
    input cell corder[i] and whose point for input node k is point_of_input[k]."""
    cpos = np.empty(len(corder), np.int64)
    cpos[corder] = np.arange(len(corder))
    for name, strata in labels.items():
        dm.createLabel(name)
        lab = dm.getLabel(name)
        for value, (kind, idx) in strata.items():
            idx = np.asarray(idx, np.int64)
            pts = cpos[idx] if kind == "cells" else point_of_input[idx]
            lab.setStratumIS(int(value), PETSc.IS().createGeneral(np.sort(pts).astype(PETSc.IntType),
                                                                  comm=PETSc.COMM_SELF))


def set_slice_labels(dm, labels, c0, v0, more=None):
    """Labels on a DMPlex built from slices: {name: {value: ("cells" | "vertices", this rank's local cells or
    vertices)}} (cells from point c0, vertices from v0); more(strata): further points of a facet set's nodes (P2's
    edges); a facet set's nodes are then completed over the ranks (share_stratum)."""
    for name, strata in labels.items():
        dm.createLabel(name)
        lab = dm.getLabel(name)
        for value, (kind, idx) in strata.items():
            pts = (c0 if kind == "cells" else v0) + np.asarray(idx, np.int64)
            if kind == "vertices" and more is not None:
                pts = np.concatenate([pts, more(strata)])
            pts = unique(pts)
            if len(pts):
                lab.setStratumIS(int(value), PETSc.IS().createGeneral(pts.astype(PETSc.IntType),
                                                                      comm=PETSc.COMM_SELF))
        if name.startswith(facet_label("")):
            share_stratum(dm, lab, VERTEX_VALUE)


def share_stratum(dm, lab, value):
    """Complete stratum `value` of label `lab` over the ranks: a point any rank has in it is in it on every rank
    that has the point (through the point SF: the ranks' marks reduced to the point's owner, then sent back)."""
    n = dm.getChart()[1]
    mark = np.zeros(n, np.int64)
    if lab.hasStratum(value):
        mark[lab.getStratumIS(value).getIndices()] = 1
        lab.clearStratum(value)
    sf = dm.getPointSF()
    owner = mark.copy()
    sf.reduceBegin(MPI.INT64_T, mark, owner, MPI.MAX)
    sf.reduceEnd(MPI.INT64_T, mark, owner, MPI.MAX)
    sf.bcastBegin(MPI.INT64_T, owner, mark, MPI.REPLACE)
    sf.bcastEnd(MPI.INT64_T, owner, mark, MPI.REPLACE)
    mark |= owner
    pts = np.flatnonzero(mark)
    if len(pts):
        lab.setStratumIS(value, PETSc.IS().createGeneral(pts.astype(PETSc.IntType), comm=PETSc.COMM_SELF))


def pull(sf, rootdata, n, width=1):
    """Each rank's copy of per-point data of the serial DMPlex (rootdata: (points, width) on rank 0, empty
    elsewhere) for its n local points, through the distribution's migration star forest (PetscSFBcast: every rank
    receives the values of its own points only); rootdata itself without one (one rank)."""
    if sf is None:
        return rootdata
    kind = np.asarray(rootdata).dtype
    unit = MPI.INT64_T if kind.kind in "iu" else MPI.DOUBLE
    root = np.ascontiguousarray(rootdata, np.int64 if kind.kind in "iu" else np.float64)
    leaf = np.full((n, width) if width > 1 else n, -1, root.dtype)
    if width > 1:
        unit = unit.Create_contiguous(width).Commit()
    sf.bcastBegin(unit, root, leaf, MPI.REPLACE)
    sf.bcastEnd(unit, root, leaf, MPI.REPLACE)
    if width > 1:
        unit.Free()
    return leaf


def make_space(comm, element, mesh=None, labels=None, partitioner=partition.DEFAULT, dm=None):
    """The distributed space of the element (element.reference.Element: its order picks P1 or P2) on the checked
    input mesh of rank 0 (a mesh.sets.Mesh at that order; None on the other ranks) with its labels, its cells
    split among the ranks by `partitioner` (partition.py). dm: the DMPlex every rank built from its slice of a
    prepared mesh (mesh: this rank's slices.SliceMesh of linear cells, labels its own cells' and vertices'; at order 2
    the cells get a node at every edge's midpoint, numbered as mesh.read.elevate numbers them)."""
    if dm is not None and element.order == 1:
        return Space(comm, element, labels=labels, partitioner=partitioner, sliced=(mesh, dm))
    if dm is not None:
        return QuadraticSpace(comm, element, labels=labels, partitioner=partitioner, sliced=(mesh, dm))
    points, tets, nodes = (mesh.points, mesh.tets, mesh.nodes) if mesh is not None else (None, None, None)
    boundary = len(mesh.facet_cell) if mesh is not None else None
    if element.order == 1:
        return Space(comm, element, points, tets, labels, partitioner, boundary)
    return QuadraticSpace(comm, element, points, tets, labels, nodes, partitioner, boundary)


def _vertex_offsets(section, vStart, vEnd):
    """The offsets of the vertices vStart:vEnd in a section of 3 values each: 3 (v - vStart) where the section lays
    them out contiguously in chart order (checked at both ends and by its size), else asked point by point."""
    n = vEnd - vStart
    if n and section.getOffset(vStart) == 0 and section.getOffset(vEnd - 1) == 3 * (n - 1) \
            and section.getStorageSize() == 3 * n:
        return 3 * np.arange(n, dtype=np.int64)
    return np.array([section.getOffset(v) for v in range(vStart, vEnd)], dtype=np.int64)


class Space:
    """P1: 3 dofs per vertex (make_space builds the space of the run's element)."""

    def __init__(self, comm, element, points=None, tets=None, labels=None, partitioner=partition.DEFAULT,
                 boundary_faces=None, sliced=None):
        """element: the run's (order 1); points/tets: the checked input mesh on rank 0 (ignored on other ranks);
        labels (rank 0): {label name: {value: ("cells" | "vertices", input indices)}}, set on the serial DMPlex and
        carried through distribution (see sets.py for the facet sets' values); partitioner: partition.py's name;
        boundary_faces (rank 0): the mesh's boundary facet count (for the partition's cut faces). sliced: (this
        rank's SliceMesh, the DMPlex built from the slices) of a prepared mesh instead of points/tets, labels then
        every rank's own {name: {value: ("cells" | "vertices", its local cells or vertices)}} (make_space)."""
        self.element = element
        self.comm = comm
        self.mpi = comm.tompi4py()
        self.partitioner, self._boundary_faces = partitioner, boundary_faces
        if sliced is None:
            serial_input, sf = self._distribute(points, tets, labels or {})
        else:
            serial_input, sf = self._adopt(*sliced, labels or {})
        dm = self.dm
        vStart, vEnd = dm.getDepthStratum(0)
        self.nlv = nlv = vEnd - vStart
        self.section = self._dof_section(vStart, vEnd)
        # local vertex index of each point (vertices are numbered by their dof offset / 3)
        lvid = _vertex_offsets(self.section, vStart, vEnd) // 3
        self._lvid, self._vStart = lvid, vStart
        cStart, cEnd = dm.getHeightStratum(0)
        self._cStart = cStart
        cones = cell_cones(dm)
        if cones is None:
            cones = np.array([dm.getCone(c) for c in range(cStart, cEnd)], np.int64).reshape(-1, 4)
        self.cells = lvid[cones - vStart].astype(IDX)
        # reference coordinates of local vertices
        carr = dm.getCoordinatesLocal().getArray(readonly=True)
        X = np.empty((nlv, 3))
        X[lvid] = carr[_vertex_offsets(dm.getCoordinateSection(), vStart, vEnd)[:, None] + np.arange(3)]
        self.X = X
        self.orig = self._input_indices(lvid, vStart, vEnd, serial_input, sf)
        self.owned = self._ownership(lvid, vStart, vEnd)
        self.Dminv, self.vol = reference_geometry(X, self.cells)
        self.nc = len(self.cells)
        self._finish(comm)

    def cell_geometry(self):
        """The local cells' geometry the kernels run on: P1's closed form (Dm^-1 and volumes, kernels.Cells)."""
        return Cells(self.cells, self.Dminv, self.vol)

    def _finish(self, comm):
        """What every space computes once its nodes are known: the local-to-global map, the bounding box,
        whether local and global vectors coincide (one rank, the same order: System.residual uses it), the
        partition's quality on several ranks (its start-up line)."""
        self.n_owned = int(self.owned.sum())
        self.lgmap = self.dm.getLGMap()
        self.bbox = self._bounding_box()
        self._gorder = self._corder_gather = None       # the output's gather plan (rank 0), built at first use
        self.lvid_of_owned = np.flatnonzero(self.owned)
        g = self.lgmap.getIndices()
        self.local_is_global = bool(comm.getSize() == 1 and len(g) == 3 * self.nlv
                                    and (g == np.arange(3 * self.nlv)).all())
        self.partition_quality, self.partition_line = {}, None        # (one rank: no partition)
        if comm.getSize() > 1:
            self.partition_quality = partition.quality(self.mpi, self.cells, self._boundary_faces)
            self.partition_line = partition.describe(self.partitioner, self.partition_quality, comm.getSize())

    def _gather_plan(self):
        """(input index of every owned node, input index of every cell) in the ranks' order, on rank 0 (None
        elsewhere): where the gathered pieces go (collective; built once, at the output's first gather)."""
        if self._gorder is None:
            ids = self.mpi.gather(self.orig[self.owned], root=0)
            cids = self.mpi.gather(self.cell_orig, root=0)
            if self.mpi.rank == 0:
                self._gorder, self._corder_gather = np.concatenate(ids), np.concatenate(cids)
            else:
                self._gorder = self._corder_gather = False      # (built: nothing to hold here)
        return self._gorder, self._corder_gather

    def _distribute(self, points, tets, labels):
        """The serial DMPlex of the spatially ordered mesh (rank 0) with its labels, distributed by the
        run's partitioner; returns (the input index of each serial point on rank 0: cells first, then
        vertices; the migration SF or None). -dm_view shows the distributed DMPlex and its labels."""
        comm = self.comm
        if comm.getRank() == 0:
            p, t, vperm, corder = spatial_order(points, tets)
            nv_total, nc_total = len(p), len(t)
            serial_input = np.concatenate([corder, vperm]).astype(np.int64)
        else:
            p, t = np.zeros((0, 3)), np.zeros((0, 4), np.int64)
            serial_input = np.zeros(0, np.int64)
            nv_total = nc_total = 0
        self.nv_total, self.nc_total = self.mpi.bcast((nv_total, nc_total), root=0)
        dm = PETSc.DMPlex().createFromCellList(3, t.astype(PETSc.IntType), p, interpolate=False, comm=comm)
        if comm.getRank() == 0 and labels:
            self._set_labels(dm, labels, corder, vperm)
        self.label_names = self.mpi.bcast(list(labels) if comm.getRank() == 0 else None, root=0)
        partition.apply(dm, self.partitioner, t, comm.getSize())
        sf = dm.distribute(overlap=0) if comm.getSize() > 1 else None
        self.dm = dm
        dm.viewFromOptions("-dm_view")
        return serial_input, sf

    def _adopt(self, mesh, dm, labels):
        """The DMPlex every rank built from its slice of a prepared mesh, with the labels of its own points (a facet
        set's vertices completed across the ranks: a rank may hold a vertex of a facet another rank's cell has),
        redistributed where a PETSc graph partitioner was asked for (the slices are the Morton parts already);
        returns (each point's input index, the migration SF or None) as _distribute does."""
        self.nv_total, self.nc_total, self._boundary_faces = mesh.totals
        (c0, c1), (v0, v1) = dm.getHeightStratum(0), dm.getDepthStratum(0)
        local = np.full(dm.getChart()[1], -1, np.int64)
        local[c0:c1], local[v0:v1] = mesh.cell_ids, mesh.ids
        return local, self._take_slices_dm(dm, labels, c0, v0)

    def _take_slices_dm(self, dm, labels, c0, v0, more=None):
        """Adopt a DMPlex built from slices: its labels (set_slice_labels), redistributed where a PETSc graph
        partitioner was asked for (the slices are the Morton parts already); the migration SF, or None."""
        set_slice_labels(dm, labels, c0, v0, more)
        self.label_names = list(labels)
        sf = None
        if self.partitioner in partition.PETSC_OWN:
            partition.apply(dm, self.partitioner, None, self.mpi.size)
            sf = dm.distribute(overlap=0)
        self.dm = dm
        dm.viewFromOptions("-dm_view")
        return sf

    @staticmethod
    def _set_labels(dm, labels, corder, vperm):
        """Labels on the serial DMPlex (cells first, then vertices, in the spatial order)."""
        nc = len(corder)
        vpos = np.empty(len(vperm), np.int64)
        vpos[vperm] = nc + np.arange(len(vperm))
        set_labels(dm, labels, corder, vpos)

    def _dof_section(self, vStart, vEnd):
        """3 dofs on each vertex."""
        sec = PETSc.Section().create(comm=PETSc.COMM_SELF)
        sec.setNumFields(1)
        sec.setFieldComponents(0, 3)
        sec.setChart(*self.dm.getChart())
        for v in range(vStart, vEnd):
            sec.setDof(v, 3)
            sec.setFieldDof(v, 0, 3)
        sec.setUp()
        self.dm.setLocalSection(sec)
        return sec

    def _input_indices(self, lvid, vStart, vEnd, serial_input, sf):
        """The input-mesh index of each local vertex, and of each local cell (cell_orig), pulled from the serial
        DM's points through the migration SF on several ranks."""
        cStart, cEnd = self.dm.getHeightStratum(0)
        local = pull(sf, serial_input, self.dm.getChart()[1])
        self.cell_orig = local[cStart:cEnd].copy()                  # input-mesh index of each local cell
        orig = np.empty(self.nlv, np.int64)
        orig[lvid] = local[vStart:vEnd]
        return orig

    def _ownership(self, lvid, vStart, vEnd):
        """Owned local vertices: a vertex is a ghost when it is a leaf of the point SF."""
        owned_pt = np.ones(self.nlv, bool)
        _, ilocal, _ = self.dm.getPointSF().getGraph()
        if ilocal is not None and len(ilocal):
            il = np.asarray(ilocal)
            il = il[(il >= vStart) & (il < vEnd)]
            owned_pt[lvid[il - vStart]] = False
        return owned_pt

    def _bounding_box(self):
        """Global min/max of the reference coordinates, for face selection."""
        X = self.X
        lo = X.min(axis=0) if self.nlv else np.full(3, np.inf)
        hi = X.max(axis=0) if self.nlv else np.full(3, -np.inf)
        glo, ghi = np.empty(3), np.empty(3)
        self.mpi.Allreduce(np.ascontiguousarray(lo, float), glo, op=MPI.MIN)
        self.mpi.Allreduce(np.ascontiguousarray(hi, float), ghi, op=MPI.MAX)
        return (glo, ghi)

    # --- vectors -----------------------------------------------------------------------------
    def global_vec(self):
        v = self.dm.createGlobalVec()
        v.setBlockSize(3)
        return v

    def local_vec(self):
        v = self.dm.createLocalVec()
        v.setBlockSize(3)
        return v

    def to_local(self, g, l):
        self.dm.globalToLocal(g, l, addv=PETSc.InsertMode.INSERT_VALUES)

    def add_to_global(self, l, g):
        """g = sum over ranks of local contributions l (g is zeroed first)."""
        g.zeroEntries()
        self.dm.localToGlobal(l, g, addv=PETSc.InsertMode.ADD_VALUES)

    def owned_array(self, local_array):
        """The owned part of a local array, in global-vector order."""
        return local_array.reshape(-1, 3)[self.lvid_of_owned].reshape(-1)

    def read_cell_state(self, rows):
        """(nc, width) array of a checkpoint's rows per cell (core.files.StateRows) for the local cells, whatever the
        rank count that wrote it (as read_state does for nodes)."""
        return self.read_state(rows, cells=True).reshape(len(self.cell_orig), -1)

    def read_state(self, rows, cells=False):
        """Local array (nlv*3, or nlv of a scalar) of a checkpoint array (core.files.StateRows) in any output file,
        whatever the rank count that wrote it: every rank reads one contiguous slice of the file's rows with their
        input indices, and the rows travel to the ranks whose nodes they are (exchange.Exchange: no rank reads or
        receives more than its share). UserError on every rank when a row is not finite or a node has no row.
        An array is taken as read already (this rank's local array)."""
        if isinstance(rows, np.ndarray):
            return rows
        n, size, rank = rows.n, self.mpi.size, self.mpi.rank
        lo, hi = n * rank // size, n * (rank + 1) // size
        vals, keys = rows.read(lo, hi)
        bad = self.mpi.allreduce(int(not np.isfinite(vals).all()), op=MPI.SUM)
        what = f"--restart '{rows.path}': checkpoint {rows.name.rsplit('/', 1)[-1]}"
        if bad:
            raise UserError(f"{what} holds non-finite values")
        ex = Exchange(self.mpi, keys, self.cell_orig if cells else self.orig, n)
        if ex.missing:
            raise UserError(f"{what}: {ex.missing} {'cells' if cells else 'nodes'} of this mesh have no row in it")
        return np.ascontiguousarray(ex.move(vals), np.float64).reshape(-1)

    def input_cells(self):
        """The local cells' nodes in their input cells' order (P1: the cells keep it)."""
        return self.cells

    def node_global(self):
        """The global index of every local node (owned and ghost) in the global vectors' node order: the ranks'
        owned nodes one rank after another, each rank's in its local order."""
        return self.lgmap.getIndices()[0::3] // 3

    def sum_owned(self, a, n=None):
        """(n_owned, k) sums over the ranks of a (local nodes, k) array (the first n local nodes given, the rest
        zero): every rank's contribution at a node, in the owner's rows, in the owned nodes' order. Collective."""
        a = np.asarray(a, np.float64).reshape(len(a), -1)
        k = a.shape[1]
        if self.mpi.size == 1:
            full = np.zeros((self.nlv, k))
            full[:len(a)] = a
            return full[self.lvid_of_owned]
        v = PETSc.Vec().createMPI((self.n_owned * k, PETSc.DECIDE), bsize=k, comm=self.comm)
        v.zeroEntries()
        g = self.node_global()[:len(a)].astype(PETSc.IntType)
        v.setValuesBlocked(g, np.ascontiguousarray(a).reshape(-1), addv=PETSc.InsertMode.ADD_VALUES)
        v.assemble()
        out = v.getArray(readonly=True).reshape(-1, k).copy()
        v.destroy()
        return out

    def gather(self, local_array):
        """(nv, 3) array in the input mesh's vertex order on rank 0; None elsewhere."""
        order, _ = self._gather_plan()
        mine = np.ascontiguousarray(local_array.reshape(-1, 3)[self.owned])
        parts = self.mpi.gather(mine, root=0)
        if self.mpi.rank != 0:
            return None
        out = np.empty((self.nv_total, 3))
        out[order] = np.concatenate(parts)
        return out

    def gather_nodal(self, local_array):
        """(nv,) array of a scalar per node in the input mesh's node order on rank 0; None elsewhere."""
        order, _ = self._gather_plan()
        parts = self.mpi.gather(np.ascontiguousarray(local_array[self.owned]), root=0)
        if self.mpi.rank != 0:
            return None
        out = np.empty(self.nv_total)
        out[order] = np.concatenate(parts)
        return out

    def gather_rows(self, owned_rows):
        """(nv, ...) array of the owned nodes' rows (in the owned nodes' order, as sum_owned gives them) in the input
        mesh's node order on rank 0; None elsewhere."""
        order, _ = self._gather_plan()
        parts = self.mpi.gather(np.ascontiguousarray(owned_rows), root=0)
        if self.mpi.rank != 0:
            return None
        cat = np.concatenate(parts)
        out = np.empty((self.nv_total,) + cat.shape[1:])
        out[order] = cat
        return out

    def gather_cells(self, local_array):
        """(nc_total, ...) array of per-cell values in the input mesh's cell order on rank 0; None elsewhere."""
        _, corder = self._gather_plan()
        parts = self.mpi.gather(np.ascontiguousarray(local_array), root=0)
        if self.mpi.rank != 0:
            return None
        cat = np.concatenate(parts)
        out = np.empty_like(cat)
        out[corder] = cat
        return out

    # --- labelled sets -------------------------------------------------------------------------
    def label_strata(self, name):
        """{value: local points} of label `name` on this rank ({} when it has none of its points)."""
        if name not in self.label_names or not self.dm.hasLabel(name):
            return {}
        lab = self.dm.getLabel(name)
        out = {}
        for v in lab.getValueIS().getIndices():
            pts = lab.getStratumIS(int(v)).getIndices()
            if len(pts):
                out[int(v)] = np.asarray(pts, np.int64)
        return out

    def cell_values(self, name):
        """(nc,) value of label `name` on each local cell (0: none)."""
        out = np.zeros(len(self.cells), np.int64)
        for v, pts in self.label_strata(name).items():
            pts = pts[pts < self._cStart + len(self.cells)]
            out[pts - self._cStart] = v
        return out

    def set_vertices(self, name):
        """Local vertices (owned and ghost) of the facet set labelled `name`."""
        pts = self.label_strata(facet_label(name)).get(VERTEX_VALUE, np.zeros(0, np.int64))
        return np.sort(self._lvid[pts - self._vStart])

    def set_cells(self, name):
        """Local cells of the volume set labelled `name` (sets.cell_label)."""
        return np.flatnonzero(self.cell_values(cell_label(name)) == 1)

    def set_triangles(self, names):
        """(ntri, 3) local vertex ids of the boundary facets of the named sets (a facet in several of
        them once) held by this rank's cells, ordered so that (b - a) x (c - a) points outward."""
        mask = np.zeros(len(self.cells), np.int64)
        for name in names:
            for v, pts in self.label_strata(facet_label(name)).items():
                if v != VERTEX_VALUE:
                    mask[pts - self._cStart] |= v
        cells = np.flatnonzero(mask)
        order = np.argsort(self.orig[self.cells[cells]], axis=1, kind="stable")   # by input vertex id
        tris, opp = [], []
        for j in range(4):
            sel = (mask[cells] >> j) & 1 == 1
            k = order[sel, j]                              # the local corner without the face
            c = self.cells[cells[sel]].astype(np.int64)
            tris.append(c[np.arange(len(k))[:, None], FACE_VERTICES[k]])
            opp.append(c[np.arange(len(k)), k])
        if not tris or not sum(map(len, tris)):
            return np.zeros((0, 3), np.int64)
        return orient_outward(self.X, np.concatenate(tris), np.concatenate(opp))


CORNER_CODE = 256      # a P2 cell's input index travels as index * 256 + the code of its corners' order (4 x 2 bits)
# edge index (element.EDGES) of a pair of corner positions i < j: EDGE_OF[4 i + j]
EDGE_OF = np.full(16, -1)
for _e, (_i, _j) in enumerate(EDGES):
    EDGE_OF[4 * _i + _j] = EDGE_OF[4 * _j + _i] = _e


class QuadraticSpace(Space):
    """P2 vector field (3 dofs per node: every vertex and every edge) on a distributed interpolated DMPlex:
    the same interface as Space, with `cells` (nc, 10) the nodes of each cell in element.py's order (its
    corners by ascending input index, then the nodes of its edges), `X` every local node's reference
    position and `orig` its index among the input mesh's points (mesh.nodes: a quadratic mesh's nodes, or
    a linear mesh's with a node at every edge midpoint, mesh.elevate)."""

    def __init__(self, comm, element, points=None, tets=None, labels=None, nodes=None, partitioner=partition.DEFAULT,
                 boundary_faces=None, sliced=None):
        """element: the run's (order 2, its stiffness rule); points, tets (corners), nodes (nc, 10): the checked
        quadratic input mesh on rank 0; labels as Space's, the sets' nodes ("vertices" kind) being vertices and
        edge nodes; partitioner, boundary_faces as Space's; sliced: (SliceMesh, DM) of a prepared linear mesh, as
        Space's, its cells elevated (a node at each edge's midpoint)."""
        self.element = element
        self.comm = comm
        self.mpi = comm.tompi4py()
        self.partitioner, self._boundary_faces = partitioner, boundary_faces
        if sliced is None:
            serial = self._distribute_quadratic(points, tets, nodes, labels or {})
        else:
            serial = self._adopt_elevated(*sliced, labels or {})
        dm = self.dm
        cf, fe, ev = plex_cones(dm)
        (c0, c1), (f0, f1), (e0, e1), (v0, v1) = (dm.getHeightStratum(h) for h in range(4))
        nv, ne = v1 - v0, e1 - e0
        self.nlv = nv + ne
        self.section = self._node_section(v0, v1, e0, e1)
        node_of_point = np.full(dm.getChart()[1], -1, np.int64)
        node_of_point[v0:v1] = np.arange(nv)
        node_of_point[e0:e1] = nv + np.arange(ne)
        self._node_of_point, self._cStart = node_of_point, c0
        n = dm.getChart()[1]
        local = pull(serial["sf"], serial["input"], n)                    # each point's input index ...
        X = pull(serial["sf"], serial["position"], n, width=3)             # ... and its node's position
        self.orig = np.concatenate([local[v0:v1], local[e0:e1]])
        self.cell_orig = local[c0:c1] // CORNER_CODE
        self._corner_code = local[c0:c1] % CORNER_CODE
        self.X = np.concatenate([X[v0:v1], X[e0:e1]])
        self.cells = self._cell_nodes(cf - f0, fe - e0, ev - v0, node_of_point[v0:v1], nv)
        self.nc = len(self.cells)
        self.owned = np.ones(self.nlv, bool)
        _, ilocal, _ = dm.getPointSF().getGraph()
        if ilocal is not None and len(ilocal):
            il = np.asarray(ilocal)
            il = il[((il >= v0) & (il < v1)) | ((il >= e0) & (il < e1))]
            self.owned[node_of_point[il]] = False
        self._finish(comm)

    def cell_geometry(self):
        """The local cells' geometry the kernels run on: per quadrature point of the element's rule
        (kernels.ElementCells)."""
        return ElementCells(self.cells, self.X, self.element)

    def _distribute_quadratic(self, points, tets, nodes, labels):
        """The serial interpolated DMPlex of the spatially ordered corners (rank 0), its labels (facet sets'
        nodes: vertices and edges), distributed by the run's partitioner; returns, on rank 0, the input index
        ("input": cells, vertices and edges their input cell and node, faces -1) and the node position
        ("position") of every serial point, for `pull`, and the migration SF (every rank)."""
        comm, rank0 = self.comm, self.comm.getRank() == 0
        out = {"input": np.zeros(0, np.int64), "position": np.zeros((0, 3))}
        if rank0:
            used, compact = np.unique(tets, return_inverse=True)
            p, t, vperm, corder = spatial_order(points[used], compact.reshape(tets.shape))
        else:
            p, t = np.zeros((0, 3)), np.zeros((0, 4), np.int64)
        dm = PETSc.DMPlex().createFromCellList(3, t.astype(PETSc.IntType), p, interpolate=True, comm=comm)
        totals = None
        if rank0:
            _, _, ev = plex_cones(dm)
            (v0, v1), (e0, e1) = dm.getDepthStratum(0), dm.getDepthStratum(1)
            vertex_input = used[vperm]
            edge_node = edge_nodes(nodes, vertex_input[ev - v0], len(points))
            point_input = np.full(dm.getChart()[1], -1, np.int64)
            # cells come first in the chart: each its input cell, and (CORNER_CODE) where the input cell has each
            # of its corners among them sorted by input index (the order `cells` keeps): input_cells restores it
            corners = nodes[corder, :4]
            rank = corner_ranks(corners)
            point_input[:len(corder)] = corder * CORNER_CODE + rank @ (4 ** np.arange(4))
            point_input[v0:v1], point_input[e0:e1] = vertex_input, edge_node
            position = np.zeros((len(point_input), 3))
            position[v0:v1], position[e0:e1] = points[vertex_input], points[edge_node]
            out.update(input=point_input, position=position)
            point_of_input = np.full(len(points), -1, np.int64)
            point_of_input[vertex_input] = np.arange(v0, v1)
            point_of_input[edge_node] = np.arange(e0, e1)
            set_labels(dm, labels, corder, point_of_input)
            totals = (len(points), len(corder))
        self.nv_total, self.nc_total = self.mpi.bcast(totals, root=0)
        self.label_names = self.mpi.bcast(list(labels) if rank0 else None, root=0)
        partition.apply(dm, self.partitioner, t, comm.getSize())
        out["sf"] = dm.distribute(overlap=0) if comm.getSize() > 1 else None
        self.dm = dm
        dm.viewFromOptions("-dm_view")
        return out

    def _adopt_elevated(self, mesh, dm, labels):
        """The DMPlex built from the slices of a prepared mesh, interpolated: a quadratic mesh's edge nodes where it
        has them (read in slices), else each edge's node at its midpoint, numbered after the vertices as
        mesh.read.elevate numbers it (exchange.cell_edge_numbers: the same numbers on any rank count); a facet set's nodes
        its facets' vertices and edges; returns what _distribute_quadratic returns (a migration SF only where a
        PETSc graph partitioner redistributes the slices, which are the Morton parts)."""
        nv, nc, self._boundary_faces = mesh.totals
        given = mesh.quadratic_edges                    # a quadratic mesh's own edge nodes (else midpoints)
        span = mesh.n_nodes                             # input ids are below it: keys of id pairs
        dm.interpolate()
        _, _, ev = plex_cones(dm)
        (c0, c1), (e0, e1), (v0, v1) = dm.getHeightStratum(0), dm.getDepthStratum(1), dm.getDepthStratum(0)
        ids = mesh.ids
        corner_ids = ids[mesh.tets]                                       # (the input's corner order)
        ends = cell_edges(corner_ids)
        if given is None:
            number = cell_edge_numbers(self.mpi, ends, mesh.cell_ids, nv, nc)
        key = ends[:, 0] * span + ends[:, 1]
        ukey, first = np.unique(key, return_index=True)
        dm_ends = np.sort(ids[ev - v0], axis=1)
        at = np.searchsorted(ukey, dm_ends[:, 0] * span + dm_ends[:, 1])
        if not np.array_equal(ukey[np.minimum(at, len(ukey) - 1)], dm_ends[:, 0] * span + dm_ends[:, 1]):
            raise RuntimeError("an edge of the DMPlex is not an edge of this rank's cells")
        if given is None:
            n_edges = self.mpi.allreduce(int(number.max()) + 1 if len(number) else 0, op=MPI.MAX)
            self.nv_total, self.nc_total = nv + n_edges, nc
        else:
            self.nv_total, self.nc_total = mesh.n_nodes, nc
        point_input = np.full(dm.getChart()[1], -1, np.int64)
        rank = corner_ranks(corner_ids)
        point_input[c0:c1] = mesh.cell_ids * CORNER_CODE + rank @ (4 ** np.arange(4))
        position = np.zeros((len(point_input), 3))
        position[v0:v1] = mesh.points
        if given is None:
            point_input[v0:v1], point_input[e0:e1] = ids, nv + number[first[at]]
            position[e0:e1] = 0.5 * (mesh.points[ev[:, 0] - v0] + mesh.points[ev[:, 1] - v0])
        else:
            point_input[v0:v1], point_input[e0:e1] = ids, given[0].reshape(-1)[first[at]]
            position[e0:e1] = given[1].reshape(-1, 3)[first[at]]
        edge_keys = dm_ends[:, 0] * span + dm_ends[:, 1]
        order = np.argsort(edge_keys)

        def set_edges(strata):                         # the edges of a facet set's facets, as DM points
            mask = np.zeros(len(corner_ids), np.int64)
            for v, (kind, idx) in strata.items():
                if kind == "cells":
                    mask[np.asarray(idx, np.int64)] = v
            face = faces_of(corner_ids, mask)               # 4 c + k: cell c's face without corner k
            t = corner_ids[face // 4][np.arange(len(face))[:, None], FACE_VERTICES[face % 4]]
            pairs = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [0, 2]]]), axis=1)
            want = pairs[:, 0] * span + pairs[:, 1]
            return e0 + order[np.searchsorted(edge_keys[order], want)]
        sf = self._take_slices_dm(dm, labels, c0, v0, set_edges)
        return {"input": point_input, "position": position, "sf": sf}

    def _node_section(self, v0, v1, e0, e1):
        """3 dofs on each vertex and each edge; their offsets follow the chart (vertices, then edges)."""
        sec = PETSc.Section().create(comm=PETSc.COMM_SELF)
        sec.setNumFields(1)
        sec.setFieldComponents(0, 3)
        sec.setChart(*self.dm.getChart())
        for lo, hi in ((v0, v1), (e0, e1)):
            for pt in range(lo, hi):
                sec.setDof(pt, 3)
                sec.setFieldDof(pt, 0, 3)
        sec.setUp()
        self.dm.setLocalSection(sec)
        for pt, node in ((v0, 0), (v1 - 1, v1 - 1 - v0), (e0, v1 - v0), (e1 - 1, v1 - v0 + e1 - 1 - e0)):
            if v0 <= pt < v1 or e0 <= pt < e1:
                if sec.getOffset(pt) != 3 * node:
                    raise RuntimeError("the node section's offsets do not follow the chart")
        return sec

    def _cell_nodes(self, cf, fe, ev, vnode, nv):
        """(nc, 10) nodes of each cell: its 4 vertices by ascending input index, then its edges in
        element.EDGES order (cf, fe, ev: cones relative to the face, edge and vertex strata)."""
        nc = len(cf)
        edges = np.sort(fe[cf].reshape(nc, 12), axis=1)[:, ::2]                  # each edge twice among faces
        verts = np.sort(ev[edges].reshape(nc, 12), axis=1)[:, ::3]               # each vertex thrice
        order = np.argsort(self.orig[vnode[verts]], axis=1, kind="stable")
        verts = np.take_along_axis(verts, order, axis=1)
        ends = ev[edges]                                                         # (nc, 6, 2)
        pos = np.argmax(ends[:, :, :, None] == verts[:, None, None, :], axis=3)   # corner positions
        ref = EDGE_OF[4 * pos[:, :, 0] + pos[:, :, 1]]
        out = np.empty((nc, 10), IDX)
        out[:, :4] = vnode[verts]
        rows = np.arange(nc)[:, None]
        out[rows, 4 + ref] = nv + edges
        return out


    def input_cells(self):
        """The local cells' nodes in their input cells' order (the input's corner order, its edges after them):
        `cells` has the corners sorted by input index."""
        pos = (self._corner_code[:, None] // 4 ** np.arange(4)) % 4        # input corner k is sorted corner pos[k]
        out = np.empty_like(self.cells)
        rows = np.arange(len(self.cells))[:, None]
        out[:, :4] = self.cells[rows, pos]
        edge = EDGE_OF[4 * pos[:, [i for i, _ in EDGES]] + pos[:, [j for _, j in EDGES]]]
        out[:, 4:] = self.cells[rows, 4 + edge]
        return out

    def set_vertices(self, name):
        """Local nodes (owned and ghost: vertices and edge nodes) of the facet set labelled `name`."""
        pts = self.label_strata(facet_label(name)).get(VERTEX_VALUE, np.zeros(0, np.int64))
        return np.sort(self._node_of_point[pts])

    def set_triangles(self, names):
        """(ntri, 6) local nodes of the boundary facets of the named sets held by this rank's cells: the
        corners ordered so that (b - a) x (c - a) points outward, then the nodes of edges (0,1), (1,2), (0,2)."""
        mask = np.zeros(len(self.cells), np.int64)
        for name in names:
            for v, pts in self.label_strata(facet_label(name)).items():
                if v != VERTEX_VALUE:
                    mask[pts - self._cStart] |= v
        out = []
        for j in range(4):                             # bit j: the face without corner j (ascending input index)
            sel = np.flatnonzero((mask >> j) & 1 == 1)
            if not len(sel):
                continue
            f = FACE_VERTICES[j]
            c = self.cells[sel].astype(np.int64)
            tri = c[:, f]
            mids = c[:, [4 + EDGE_OF[4 * f[a] + f[b]] for a, b in ((0, 1), (1, 2), (0, 2))]]
            oriented = orient_outward(self.X, tri, c[:, j])
            flip = oriented[:, 1] != tri[:, 1]
            mids[flip] = mids[flip][:, ::-1]
            out.append(np.concatenate([oriented, mids], axis=1))
        return np.concatenate(out) if out else np.zeros((0, 6), np.int64)


def edge_nodes(nodes, ends, n_points):
    """The input node of each edge given by its two end points (ne, 2), from the quadratic cells' nodes."""
    pairs = cell_edges(nodes)
    keys = pairs[:, 0] * n_points + pairs[:, 1]
    ukeys, first = np.unique(keys, return_index=True)
    e = np.sort(ends, axis=1)
    want = e[:, 0] * n_points + e[:, 1]
    pos = np.searchsorted(ukeys, want)
    if not np.array_equal(ukeys[np.minimum(pos, len(ukeys) - 1)], want):
        raise RuntimeError("an edge of the DMPlex is not an edge of the quadratic mesh")
    return nodes[:, 4:].reshape(-1)[first[pos]]
