"""P1 vector field (3 dofs per vertex) on a distributed, uninterpolated DMPlex of tetrahedra.

Rank 0 reads the mesh, orders it spatially and builds the serial DMPlex; `distribute` with the
`simple` partitioner hands each rank a contiguous range of (spatially ordered) cells. Every rank
then knows, for its local vertices (owned + ghosts): the local dof offsets, reference coordinates,
the index of the vertex in the input mesh, and ownership. Per-cell Dm^-1 and volumes are computed
once here.
"""
import numpy as np
from petsc4py import PETSc

from .kernels import IDX
from .mesh import spatial_order


def reference_geometry(X, cells):
    """Per cell, computed once: Dm^-1 (thesis eq. 4.29 in matrix form) and the volume |det Dm|/6
    (F = Ds Dm^-1 does not depend on vertex order; the volume must be > 0)."""
    Xc = X[cells]
    Dm = np.stack([Xc[:, 1] - Xc[:, 0], Xc[:, 2] - Xc[:, 0], Xc[:, 3] - Xc[:, 0]], axis=-1)
    return np.ascontiguousarray(np.linalg.inv(Dm)), np.abs(np.linalg.det(Dm)) / 6.0


class Space:
    def __init__(self, comm, points=None, tets=None):
        """points/tets: the checked input mesh on rank 0 (ignored on other ranks)."""
        self.comm = comm
        self.mpi = comm.tompi4py()
        vperm, sf = self._distribute(points, tets)
        dm = self.dm
        vStart, vEnd = dm.getDepthStratum(0)
        self.nlv = nlv = vEnd - vStart
        self.section = self._dof_section(vStart, vEnd)
        # local vertex index of each point (vertices are numbered by their dof offset / 3)
        lvid = np.array([self.section.getOffset(v) // 3 for v in range(vStart, vEnd)], dtype=np.int64)
        cStart, cEnd = dm.getHeightStratum(0)
        self.cells = np.empty((cEnd - cStart, 4), dtype=IDX)
        for c in range(cStart, cEnd):
            self.cells[c - cStart] = lvid[dm.getCone(c) - vStart]
        # reference coordinates of local vertices
        csec = dm.getCoordinateSection()
        carr = dm.getCoordinatesLocal().getArray(readonly=True)
        X = np.empty((nlv, 3))
        for v in range(vStart, vEnd):
            o = csec.getOffset(v)
            X[lvid[v - vStart]] = carr[o:o + 3]
        self.X = X
        self.orig = self._input_indices(lvid, vStart, vEnd, vperm, sf)
        self.owned = self._ownership(lvid, vStart, vEnd)
        self.n_owned = int(self.owned.sum())
        self.Dminv, self.vol = reference_geometry(X, self.cells)
        self.nc = len(self.cells)
        self.lgmap = dm.getLGMap()
        self.bbox = self._bounding_box()
        # gather plan for output on rank 0 (input vertex order)
        ids = self.orig[self.owned]
        self._counts = self.mpi.gather(len(ids), root=0)
        allids = self.mpi.gather(ids, root=0)
        self._gorder = np.concatenate(allids) if self.mpi.rank == 0 else None
        self.lvid_of_owned = np.flatnonzero(self.owned)

    def _distribute(self, points, tets):
        """The serial DMPlex of the spatially ordered mesh (rank 0), distributed with the `simple`
        partitioner; returns (vertex permutation of the ordering on rank 0, migration SF or None)."""
        comm = self.comm
        if comm.getRank() == 0:
            p, t, vperm, _ = spatial_order(points, tets)
            nv_total, nc_total = len(p), len(t)
        else:
            p, t = np.zeros((0, 3)), np.zeros((0, 4), np.int64)
            vperm = None
            nv_total = nc_total = 0
        self.nv_total, self.nc_total = self.mpi.bcast((nv_total, nc_total), root=0)
        dm = PETSc.DMPlex().createFromCellList(3, t.astype(PETSc.IntType), p, interpolate=False, comm=comm)
        part = dm.getPartitioner()
        part.setType(PETSc.Partitioner.Type.SIMPLE)
        sf = dm.distribute(overlap=0) if comm.getSize() > 1 else None
        self.dm = dm
        return vperm, sf

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

    def _input_indices(self, lvid, vStart, vEnd, vperm, sf):
        """The input-mesh index of each local vertex (through the migration SF on several ranks)."""
        if sf is None:
            serial_vertex = np.arange(vStart, vEnd) - vStart
        else:
            nroots, ilocal, iremote = sf.getGraph()
            leaves = np.arange(len(iremote)) if ilocal is None else np.asarray(ilocal)
            orig_point = np.full(self.dm.getChart()[1], -1, np.int64)
            orig_point[leaves] = np.asarray(iremote).reshape(-1, 2)[:, 1]
            serial_vertex = orig_point[vStart:vEnd] - self.nc_total  # serial DM: cells first, then vertices
        vperm = self.mpi.bcast(vperm, root=0)
        orig = np.empty(self.nlv, np.int64)
        orig[lvid] = vperm[serial_vertex]
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
        from mpi4py import MPI
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

    def scatter(self, full):
        """Local array (nlv*3) from an (nv, 3) array in the input vertex order given on rank 0."""
        full = self.mpi.bcast(full if self.mpi.rank == 0 else None, root=0)
        return np.ascontiguousarray(np.asarray(full, np.float64)[self.orig]).reshape(-1)

    def gather(self, local_array):
        """(nv, 3) array in the input mesh's vertex order on rank 0; None elsewhere."""
        mine = np.ascontiguousarray(local_array.reshape(-1, 3)[self.owned])
        parts = self.mpi.gather(mine, root=0)
        if self.mpi.rank != 0:
            return None
        out = np.empty((self.nv_total, 3))
        out[self._gorder] = np.concatenate(parts)
        return out

    def face_vertices(self, axis, side, tol=0.01):
        """Local vertices within tol of the min (side='min') or max face of the bounding box."""
        ref = self.bbox[0][axis] if side == "min" else self.bbox[1][axis]
        return np.flatnonzero(np.abs(self.X[:, axis] - ref) < tol)

    def boundary_triangles(self, vset):
        """Faces of local cells whose three vertices all lie in the local vertex set `vset`
        (a face on a planar boundary belongs to exactly one cell). Returns (ntri, 3) local ids."""
        mark = np.zeros(self.nlv, bool)
        mark[vset] = True
        m = mark[self.cells]
        tris = []
        for drop in range(4):
            keep = [i for i in range(4) if i != drop]
            sel = m[:, keep].all(axis=1)
            tris.append(self.cells[sel][:, keep])
        return np.concatenate(tris).astype(np.int64)
