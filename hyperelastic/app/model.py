"""The discrete model of a scene, built in one direction: Scene -> mesh -> Element (decided once) -> Space ->
formulation -> effects -> the formulation's System, with the initial state the System is calibrated at. Shared by
the command line, the tests and the scripts (PETSc must already be initialized). The solver, the integrator and the
output build on it (app/run.py)."""
import os
import time
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..core.errors import UserError
from ..discretization.kernels import RegionKernels
from ..discretization.refine import refine_whole
from ..discretization.slices import MemorySource, read_slice, sliceable
from ..discretization.space import Space, make_space
from ..element.reference import Element
from ..formulations import choose
from ..formulations.base import Problem
from ..formulations.mixed import volume_bound
from ..mesh.generate import cached_bar
from ..mesh.prepared import prepared_arrays
from ..mesh.read import CURVED_ANGLES, bent_edges, corners, elevate, read_mesh
from ..mesh.sets import MATERIAL_LABEL, REGION_LABEL, VERTEX_VALUE, Mesh, cell_label, facet_label
from ..physics import effects as effects_pkg
from ..physics.materials import MeshField
from ..solving.system import System


def collective(comm, fn):
    """fn() run on rank 0: its result there (None on the other ranks), its UserError raised on every rank."""
    mpi = comm.tompi4py()
    res = err = None
    if mpi.rank == 0:
        try:
            res = fn()
        except UserError as e:
            err = str(e)
    err = mpi.bcast(err, root=0)
    if err is not None:
        raise UserError(err)
    return res


def rotation_matrix(r):
    """Rodrigues' formula: the rotation by |r| radians about r."""
    r = np.asarray(r, float)
    th = np.linalg.norm(r)
    if th == 0:
        return np.eye(3)
    k = r / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def centroid(space):
    """Mean of the mesh vertices (the same on every rank)."""
    own = space.X[space.lvid_of_owned]
    tot = space.mpi.allreduce(np.append(own.sum(axis=0), len(own)), op=MPI.SUM)
    return tot[:3] / tot[3]


def initial_state(scene, space):
    """Local positions and velocities at t = 0: the reference configuration at rest, unless
    -initial_scale (x = c + diag(s)(X - c)), -initial_rotation (x = c + R (x - c), R = exp([r]x)) or
    -initial_spin (v = w x (x - c)) ask otherwise; c is the centroid."""
    x, v = space.X.copy(), np.zeros_like(space.X)
    sc = scene
    if any(a is not None for a in (sc.initial_scale, sc.initial_rotation, sc.initial_spin)):
        c = centroid(space)
        if sc.initial_scale is not None:
            x = c + (x - c) * np.asarray(sc.initial_scale)
        if sc.initial_rotation is not None:
            x = c + (x - c) @ rotation_matrix(sc.initial_rotation).T
        if sc.initial_spin is not None:
            v = np.cross(np.asarray(sc.initial_spin), x - c)
    return x.ravel().copy(), v.ravel().copy()


@dataclass
class Model:
    """Everything of a run except the solver, the integrator and the output."""
    scene: object
    element: Element            # the run's element (its order and stiffness rule), decided once
    formulation: object         # the formulation's spec (formulations.REGISTRY) that runs the scene
    source: object              # where the mesh came from (a MeshSource: whole on rank 0, in slices, refined)
    space: Space
    kernels: object             # the material(s)' cell kernels on the space's cells (kernels.py)
    system: System
    x0: np.ndarray              # initial local positions and velocities
    v0: np.ndarray
    sets: list = None           # [{name, kind, count, measure, ...}] of the sets the run uses (all ranks)
    notes: list = None          # what the start-up report says of the model's choices, one line each

    @property
    def tets(self):
        """The whole input mesh's cells on rank 0 where rank 0 read it whole (None otherwise)."""
        return self.source.tets

    def whole_mesh(self):
        """(points, tets) of the whole input mesh in its own numbering on rank 0 (None elsewhere), for the gathered
        output: a mesh read in slices is read whole here, on rank 0, only where that output asks for it."""
        return self.source.whole(self.element, self.space.mpi.rank)

    def set_lines(self):
        """One line per set: name, facets or tets, area or volume."""
        return [s["line"] for s in self.sets]


class MeshSource:
    """The one way in for a scene's mesh: a source reads it into the distributed space, and gives the whole mesh on
    rank 0 where the gathered output asks for it. Which source a scene takes is decided once, by mesh_source: the
    only place that reads -refine and the mesh's format.
      WholeMesh    rank 0 reads and checks the whole mesh (any format meshio reads) and distributes it
      SlicedMesh   every rank reads its own slice of a prepared mesh or a per-rank output
      RefinedMesh  -refine K: the coarse mesh distributed (in slices where it can be, else scattered from rank 0),
                   every rank refining its own part K times"""
    sliced_from = None           # the file every rank read its slice of (the output's `mesh_read`), or None
    points = tets = None         # the whole mesh on rank 0, where it was read whole

    def __init__(self, scene):
        self.scene = scene
        self.name = scene.mesh or f"bar L{scene.level}"

    def distribute(self, comm):
        """(Space, Element, the set report, notes) of the scene's mesh on the ranks of comm. Collective."""
        raise NotImplementedError

    def whole(self, element, rank):
        """(points, cells) of the whole mesh at the run's order on rank 0 (None, None elsewhere)."""
        return self.points, self.tets


class WholeMesh(MeshSource):
    def __init__(self, scene, why=None):
        """why: the note saying why a mesh that could be read in slices is read whole (or None)."""
        super().__init__(scene)
        self.why = why

    def distribute(self, comm):
        loaded = collective(comm, lambda: load_mesh(self.scene))
        mesh, element, labels, report, notes = loaded if loaded is not None else (None,) * 5
        mpi = comm.tompi4py()
        element, notes = mpi.bcast((element, notes), root=0)
        notes = notes + ([self.why] if self.why else [])
        space = make_space(comm, element, mesh, labels, self.scene.partitioner)
        if mesh is not None:
            self.points, self.tets = mesh.points, mesh.cell_nodes
        return space, element, mpi.bcast(report, root=0), notes


class SlicedMesh(MeshSource):
    levels = 0                   # -refine K of the slices (RefinedMesh)

    def __init__(self, scene):
        super().__init__(scene)
        self.sliced_from = scene.mesh

    def coarse_source(self, comm):
        """(where the slices come from: None, the file itself, or a slices.MemorySource; notes; seconds rank 0 read
        the mesh whole)."""
        return None, [], 0.0

    def distribute(self, comm):
        source, notes, serial = self.coarse_source(comm)
        mesh, dm = read_slice(self.scene.mesh, comm, self.scene.mesh_frame, source, self.levels,
                              lambda nv: check_index_range(nv, self.name))
        element = Element.decide(self.scene.order, self.scene.quadrature, mesh.source_order)
        check_index_range(mesh.totals[0] * (7 if element.order == 2 else 1), self.name)   # (P2: ~6 edges a vertex)
        labels, report = mesh_labels(self.scene, mesh)
        space = make_space(comm, element, mesh, labels, self.scene.partitioner, dm=dm)
        self.keep(mesh, comm)
        return space, element, report, self.note(mesh, serial) + notes

    def keep(self, mesh, comm):
        """Keep what whole() needs of this rank's slice (RefinedMesh: the one rank's fine mesh)."""

    def note(self, mesh, serial):
        return []

    def whole(self, element, rank):
        if rank != 0:
            return None, None
        m = read_mesh(self.sliced_from, self.scene.mesh_frame)
        m = elevate(m) if element.order == 2 and m.order == 1 else m     # (as the slices were)
        return m.points, m.cell_nodes


class RefinedMesh(SlicedMesh):
    def __init__(self, scene, levels):
        super().__init__(scene)
        self.levels = levels
        self.fine = None         # on one rank: its SliceMesh, the whole fine mesh

    def coarse_source(self, comm):
        if self.scene.mesh and sliceable(self.scene.mesh):
            return None, [], 0.0
        t0 = time.perf_counter()
        mpi = comm.tompi4py()

        def coarse():
            mesh = read_coarse(self.scene)
            return prepared_arrays(mesh), (straight_sided_note(mesh, self.levels) if mesh.order == 1 else [])
        data, notes = collective(comm, coarse) or (None, None)
        return MemorySource(mpi, data, self.name), mpi.bcast(notes, root=0), time.perf_counter() - t0

    def keep(self, mesh, comm):
        self.fine = mesh if comm.getSize() == 1 else None

    def note(self, mesh, serial):
        return [refine_note(self.levels, mesh, serial)]

    def whole(self, element, rank):
        """The whole -refine'd mesh on rank 0: the one rank's own part, else the coarse mesh read and refined again
        here (refine.refine_whole: the parts' numbering), at the run's order."""
        if rank != 0:
            return None, None
        if self.fine is not None:
            m = self.fine
            points = np.empty((m.totals[0], 3))
            points[m.ids] = m.points
            tets = np.empty((m.totals[1], 4), np.int64)
            tets[m.cell_ids] = m.ids[m.tets]
        else:
            points, tets = refine_whole(read_coarse(self.scene), self.levels)
        if element.order == 1:
            return points, tets
        m = elevate(Mesh(self.sliced_from, points, tets))
        return m.points, m.cell_nodes


def mesh_source(scene):
    """The scene's MeshSource: -refine K refines in slices; a prepared mesh or a per-rank output of linear cells
    (output/ranks.py; -order 2 elevates their cells) is read in slices, unless METIS partitions it (the whole dual graph
    on rank 0) or -order 1 asks for a quadratic mesh's corners; anything else is read whole on rank 0."""
    if scene.refine:
        return RefinedMesh(scene, scene.refine)
    order = sliceable(scene.mesh) if scene.mesh else None
    if order and not (order == 2 and scene.order == 1):
        if scene.partitioner != "metis":
            return SlicedMesh(scene)
        return WholeMesh(scene, f"-partitioner metis: mesh '{scene.mesh}' is read whole on rank 0 (METIS partitions the "
                                "whole mesh's dual graph there); with the default morton every rank reads its own slice")
    return WholeMesh(scene)


def load_mesh(scene):
    """(sets.Mesh, Element, DMPlex labels, set report, notes) of the scene's mesh, on rank 0: the run's element,
    decided here once (-order, else the mesh's own; -quadrature_degree), and the mesh at its order (a linear mesh
    elevated to straight-sided quadratic cells, a quadratic one reduced to its corners where the order asks); the
    facet and cell sets its effects name (an unknown name is a UserError listing the mesh's) and its regions."""
    mesh = read_coarse(scene)
    ranks = MPI.COMM_WORLD.size
    if len(mesh.tets) < ranks:
        name = scene.mesh or f"bar L{scene.level}"
        raise UserError(f"mesh '{name}': {len(mesh.tets)} tetrahedra for {ranks} MPI ranks (each rank needs "
                        "cells: run on fewer ranks or refine the mesh)")
    element = Element.decide(scene.order, scene.quadrature, mesh.order)
    notes = []
    if element.order == 2 and mesh.order == 1:
        notes += straight_sided_note(mesh)
        mesh = elevate(mesh)
    elif element.order == 1 and mesh.order == 2:
        mesh = corners(mesh)
    check_index_range(len(mesh.points), scene.mesh or f"bar L{scene.level}")
    labels, report = mesh_labels(scene, mesh)
    return mesh, element, labels, report, notes


def read_coarse(scene):
    """The scene's mesh read whole and checked (before -refine; -mesh, else the built-in bar at -level)."""
    return read_mesh(scene.mesh, scene.mesh_frame) if scene.mesh else read_mesh(cached_bar(scene.level))


def refine_note(levels, mesh, serial):
    """The start-up report's line on -refine: what it made, where and how fast (serial: the seconds rank 0 read the
    coarse mesh whole, where it did)."""
    nv, nc, _ = mesh.totals
    seconds = mesh.mpi.allreduce(mesh.refine_seconds, op=MPI.MAX)
    if mesh.source_order == 2:
        where = ("the quadratic mesh's edge nodes" + (", then at edge midpoints" if levels > 1 else "") +
                 ": curved surfaces are as faithful as its edge nodes make them")
    else:
        where = "edge midpoints: curved surfaces stay as faceted as the coarse mesh's"
    return (f"-refine {levels}: {nc // 8 ** levels} -> {nc} tetrahedra, {nv} vertices, refined on "
            f"{mesh.mpi.size} rank(s) in {seconds:.2f} s ({nc / max(seconds, 1e-9) / mesh.mpi.size / 1e3:.0f}k "
            f"tetrahedra/s a rank{f'; the coarse mesh read on rank 0 in {serial:.2f} s' if serial else ''}); "
            f"new vertices at {where}")


def mesh_labels(scene, mesh):
    """(DMPlex labels, set report) of the sets the scene's effects name and of the mesh's regions: on the whole mesh
    (rank 0), or on a rank's part of a prepared mesh (every rank, its own cells and vertices; counts and measures
    the whole mesh's)."""
    labels, report = {}, []
    for option, name, kind in scene.set_uses():
        label = facet_label(name) if kind == "facets" else cell_label(name)
        if label in labels:
            continue
        s = mesh.find(name, kind, option)
        if kind == "facets":
            labels[label] = {v: ("vertices" if v == VERTEX_VALUE else "cells", idx)
                             for v, idx in mesh.label_strata(s).items()}
            report.append(_set_line(mesh, s, "facets", mesh.area(s.items)))
        else:
            labels[label] = {1: ("cells", s.items)}
    regions = [g for g in mesh.groups.values() if g.kind == "tets"]
    if regions:
        labels[REGION_LABEL] = {}
        for i, g in enumerate(regions):
            value = g.tag if g.tag is not None else i + 1
            labels[REGION_LABEL][value] = ("cells", g.items)
    material_regions(scene, mesh, labels, report)
    for i, g in enumerate(regions):
        if not any(r.get("group") == g.name for r in report):
            report.append({"name": g.name, "kind": "tets", "tag": int(g.tag if g.tag is not None else i + 1),
                           "count": mesh.total(len(g.items)), "measure": mesh.volume(g.items),
                           "line": mesh.describe(g)})
    return labels, report


def straight_sided_note(mesh, refine=0):
    """A note where a linear mesh run at order 2, or refined (-refine), has a boundary that looks curved
    (mesh.read.bent_edges): its cells get straight edges, so the curved surfaces stay faceted at the linear mesh's
    resolution."""
    bent, edges = bent_edges(mesh)
    if bent == 0 or bent < 0.01 * edges:
        return []
    lo, hi = CURVED_ANGLES
    if refine:
        return [f"-refine {refine} of a linear mesh: new vertices at straight edges' midpoints, and {bent} of its "
                f"{edges} boundary edges bend by {lo:g}-{hi:g} degrees (a faceted curved surface): the geometry stays "
                "as faceted as the coarse mesh; `hyperelastic mesh GEOMETRY --order 2` gives a coarse mesh whose edge "
                "nodes lie on the curved geometry, and -refine puts the first level's vertices there"]
    return [f"-order 2 on a linear mesh: the 10-node cells get straight edges, and {bent} of its {edges} boundary "
            f"edges bend by {lo:g}-{hi:g} degrees (a faceted curved surface): the geometry stays as faceted as the "
            "linear mesh (a twisted rod's torque came out 3.9% low that way); `hyperelastic mesh GEOMETRY --order 2` "
            "places the edge nodes on the curved geometry"]


def check_index_range(nodes, name, index_bits=None):
    """One line before PETSc's indices overflow: 3 unknowns per node must stay below 2^31 with the 32-bit indices of
    a PETSc built without --with-64-bit-indices (pip's default); index_bits: PETSc's (default: this PETSc's)."""
    bits = index_bits or 8 * np.dtype(PETSc.IntType).itemsize
    dofs = 3 * nodes
    if dofs >= 2 ** (bits - 1):
        raise UserError(f"mesh '{name}': {dofs:,} unknowns (3 per node) exceed the {bits}-bit indices of this PETSc "
                        f"(at most {2 ** (bits - 1) - 1:,}); build PETSc with 64-bit indices (PETSC_CONFIGURE_OPTIONS="
                        "'--with-64-bit-indices' for pip, or a cluster's 64-bit module)")


def _set_line(mesh, s, kind, measure):
    return {"name": s.name, "kind": kind, "tag": None if s.tag is None else int(s.tag),
            "count": mesh.total(len(s.items)), "measure": measure, "line": mesh.describe(s)}


def material_regions(scene, mesh, labels, report):
    """The MATERIAL_LABEL of -regions (value i+1 on the cells of the i-th region; a cell in two of them
    is an error) and a report line per region with its material, and for the cells in none."""
    if not scene.regions:
        return
    owner = np.zeros(len(mesh.tets), np.int64)
    labels[MATERIAL_LABEL] = {}
    for i, r in enumerate(scene.regions):
        g = mesh.find(r.name, "tets", "regions")
        twice = owner[g.items] != 0
        shared = mesh.total(int(twice.sum()))
        if shared:
            first = mesh.total(int(owner[g.items][twice][0]) if twice.any() else len(scene.regions), op="min")
            raise UserError(f"option -regions: regions '{scene.regions[first - 1].name}' and '{r.name}' share "
                            f"{shared} tets; a tet can have one material")
        owner[g.items] = i + 1
        labels[MATERIAL_LABEL][i + 1] = ("cells", g.items)
        report.append({"name": r.name, "group": g.name, "kind": "tets", "tag": None if g.tag is None else int(g.tag),
                       "count": mesh.total(len(g.items)), "measure": mesh.volume(g.items), "material": r.describe(),
                       "line": f"{mesh.describe(g)}; {r.describe()}"})
    rest = np.flatnonzero(owner == 0)
    n_rest = mesh.total(len(rest))
    if n_rest:
        own, volume = scene.solid.describe(), mesh.volume(rest)
        report.append({"name": "(other cells)", "kind": "tets", "tag": None, "count": n_rest,
                       "measure": volume, "material": own,
                       "line": f"(other cells): {n_rest} tets, volume {volume:.6g}; the scene's {own}"})


def solids_in_use(scene, space):
    """[(where, solid)] of the scene's solids that some cell has, on any rank (the scene's own first, where some cell
    is in no listed region; then each listed region's)."""
    solids = [("the scene's", scene.solid)] + [(f"region '{r.name}'", r.solid) for r in scene.regions]
    if not scene.regions:
        return tuple(solids)
    which = space.cell_values(MATERIAL_LABEL)
    counts = space.mpi.allreduce(np.bincount(which, minlength=len(solids)))
    return tuple(s for s, n in zip(solids, counts) if n)


def cell_kernels(scene, space, constants):
    """(elastic cell kernels, density: a scalar, or per local cell with -regions, the solid of each of the kernels'
    parts: (its local cells, None for all; Solid)) of the scene's material(s) on the space's cells (its
    cell_geometry: the element's); constants: solid -> its parameter block (the formulation's: the mixed
    formulation's isochoric parts)."""
    sc = scene
    cells = space.cell_geometry()
    if not sc.regions:
        solid = _at_cells(sc, sc.solid, space, slice(None), {})
        return cells.kernels(solid.material, constants(solid)), solid.rho, ((None, solid),)
    which = space.cell_values(MATERIAL_LABEL)
    solids = [sc.solid] + [r.solid for r in sc.regions]
    unused = space.mpi.allreduce(int((which == 0).sum())) == 0     # every cell is in a listed region
    used = [(np.flatnonzero(which == i), m) for i, m in enumerate(solids) if i or not unused]
    cache = {}
    used = [(idx, _at_cells(sc, m, space, idx, cache)) for idx, m in used]
    density = np.array([m.rho for m in solids])[which]
    return RegionKernels(cells, [(idx, m.material, constants(m)) for idx, m in used]), density, tuple(used)


def _at_cells(scene, solid, space, idx, cache):
    """The solid on the local cells idx: its fields (a fibre direction per cell: CellField) at their reference
    centroids (the mean of their corners), the same on any rank count and partition."""
    if not solid.fields:
        return solid
    centroids = space.X[space.cells[idx, :4]].mean(axis=1)
    out, failed = None, None
    try:
        rows = {k: mesh_cell_data(scene, space, solid.values[k], cache)[idx] for k in solid.fields
                if isinstance(solid.values[k], MeshField)}
    except UserError as e:                       # (collective: every rank has the same line)
        rows, failed = None, str(e)
    try:
        out = solid.localized(centroids, rows) if failed is None else None
    except UserError as e:
        failed = str(e)
    why = space.mpi.allgather(failed)                 # (a cell without a direction on one rank: one line on all)
    first = next((w for w in why if w), None)
    if first:
        raise UserError(first)
    return out


def mesh_cell_data(scene, space, field, cache):
    """(local cells, 3) of a mesh field (`-fibre1 mesh:NAME`): rank 0 reads the mesh file's cell data NAME with meshio
    (the tetrahedra's rows, in the input cells' order), every rank receives it and takes each local cell's input
    cell's row (a -refine'd cell its coarse parent's: input index // 8^levels). One UserError line on every rank
    where the file has no such data or not three numbers a tetrahedron. Collective; read once per name (cache)."""
    key = field.name
    if key not in cache:
        mpi = space.mpi
        data, why = None, None
        if mpi.rank == 0:
            try:
                data = _read_cell_data(scene, field)
            except UserError as e:
                why = str(e)
        why = mpi.bcast(why, root=0)
        if why:
            raise UserError(why)
        n = mpi.bcast(None if data is None else len(data), root=0)
        data = np.ascontiguousarray(data if data is not None else np.empty((n, 3)), np.float64)
        mpi.Bcast(data, root=0)
        cache[key] = data
    data = cache[key]
    parent = space.cell_orig.astype(np.int64) // 8 ** scene.refine
    if len(parent) and parent.max() >= len(data):
        raise UserError(f"option -{field.option}: the mesh's cell data '{field.name}' has {len(data)} rows, fewer than "
                        "its tetrahedra")
    return data[parent]


def _read_cell_data(scene, field):
    """The mesh file's cell data field.name over its tetrahedra (n, 3), in their input order."""
    from ..mesh.read import read_meshio
    where = f"option -{field.option}: mesh:{field.name}"
    if not scene.mesh or not os.path.isfile(scene.mesh) or scene.mesh.lower().endswith((".h5", ".hdf5")):
        raise UserError(f"{where}: cell data are read from a mesh file meshio reads (-mesh FILE.msh, .vtu, ...), not "
                        f"{'the built-in bar' if not scene.mesh else repr(scene.mesh)}")
    m = read_meshio(scene.mesh, f"{where}: mesh '{scene.mesh}'")
    kinds = {c.type for c in m.cells} & {"tetra", "tetra10"}
    if field.name not in m.cell_data:
        raise UserError(f"{where}: the mesh '{scene.mesh}' has no cell data '{field.name}' (it has: "
                        f"{', '.join(sorted(m.cell_data)) or 'none'})")
    rows = [np.asarray(d, np.float64) for c, d in zip(m.cells, m.cell_data[field.name]) if c.type in kinds]
    rows = [r.reshape(len(r), -1) for r in rows]
    if not rows or any(r.shape[1] != 3 for r in rows):
        raise UserError(f"{where}: the mesh's cell data '{field.name}' is not three numbers a tetrahedron")
    return np.concatenate(rows)


def build_model(scene, comm):
    """Read the scene's mesh (its MeshSource) and decide its element, distribute it with the sets the scene uses, choose
    the formulation, build the effects the scene names and the formulation's System, calibrated at the initial
    state. The scene is read, never written."""
    source = mesh_source(scene)
    space, element, report, mesh_notes = source.distribute(comm)
    solids = solids_in_use(scene, space)
    problem = Problem(scene, element, solids)
    formulation, notes = choose(problem)
    k, density, part_solids = cell_kernels(scene, space, formulation.cell_constants)
    ctx = effects_pkg.Context(space, k, k.geometry, density, scene.lumped, scene.hessian_projection,
                              max(s.values["E"] for _, s in solids), scene.quasistatic, part_solids)
    effects, constraints = effects_pkg.build(scene, ctx)
    x0, v0 = initial_state(scene, space)
    system = formulation.system(problem, space, k, effects, constraints, x0, v0)
    system.volume_bound = volume_bound(problem, scene.incompressible)     # (every accepted state is checked)
    return Model(scene, element, formulation, source, space, k, system, x0, v0, report, mesh_notes + notes)
