"""HDF5 output (rank 0 writes, flushed every frame) and an XDMF time series beside it.

Layout: mesh/points (nv,3), mesh/tetra (nc,4) in the input mesh's numbering, or (nc,10) of quadratic cells
(element.py's node order, VTK's: the corners, then the edges' nodes; nv then counts every node)
(mesh/region (nc,): the region tag of each tet, 0 for none); time (F,); x (F,nv,3) positions in the input
node order;
frames/<i>/<field> the fields of frame i (fields.py: displacement, velocity (nv,3); J, energy_density,
von_mises (nc,)); stats/<column> (S,) one entry per step attempt (the columns: stats.py);
attributes: see run_attributes.

The XDMF beside it is a temporal collection of uniform grids on the reference mesh, each frame with its
fields as attributes (the layout meshio's TimeSeriesReader and VTK's XDMF reader read; ParaView: Warp By
Vector with displacement shows the deformed body).
"""
import ctypes
import json
import os
import resource
import time

import h5py
import numpy as np
from petsc4py import PETSc

from .. import __version__
from ..core.errors import UserError
from .fields import (AT_NODES, DEFAULT_FIELDS, cell_fields, cell_quantities, finish, is_point_field,
                     needs_volumes, recover, reference_volumes)
from ..core.files import (CHECKPOINT_ATTRS, CHECKPOINT_OPTIONAL, CHECKPOINT_VECTORS, EARLIER, PARTIAL, RANK_FILE, RANKS,
                          failed_path, named_rank_files)
from ..core.options import all_options
from ..physics.effects import built as effects_built
from ..solving.stats import column_type


XDMF_HEAD = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n <Domain>\n'
             '  <Grid Name="hyperelastic" GridType="Collection" CollectionType="Temporal">\n')
XDMF_TAIL = "  </Grid>\n </Domain>\n</Xdmf>\n"
XDMF_FRAME_BYTES = 16384     # room asked for one frame's <Grid> in the XDMF (~1.5 kB with every field)
STATS_EVERY_S = 1.0         # the longest the statistics rows wait in memory for a frame to go in with
ROOM_MARGIN = 256 * 1024     # bytes kept free for HDF5's metadata, the statistics rows and the close
# HDF5 File Format Specification 3.0, "Version 0 Superblock" (and version 1): the end-of-file address is at
# byte 40 (signature 8, versions and sizes 8, B-tree K values 4, consistency flags 4, base address 8,
# free-space address 8), little-endian, with 8-byte offsets
SUPERBLOCK_EOA_AT = 40
ROOM_ATTR, ROOM_ATTR_BYTES = "_room", 8192     # room in the root group's header for set_attr's attributes
FRAME_LINKS = 4096       # the frames group's links kept in its header (made with room for them)
FIELD_LINKS = 16         # a frame's fields, the same


class Events:
    """PETSc log events of the output (-log_view): HE_OutFields (a frame's fields on the local cells, every rank),
    HE_OutRank0 (rank 0's writes of a frame or checkpoint: the whole frame in the gathered layout, metadata in the
    per-rank one), HE_OutRankPart (each rank's own rows, per-rank layout). Made at first use (after PETSc is
    initialised)."""
    _made = {}

    def __getattr__(self, name):
        if name not in self._made:
            self._made[name] = PETSc.Log.Event(f"HE_Out{name}")
        return self._made[name]


EVENTS = Events()


def _compact_group(parent, name, links):
    """A group whose links are kept in its own object header, made with room for `links` of them: adding a
    link rewrites that header in place. HDF5's default group adds each name to a heap, a symbol node and a
    B-tree, blocks that a kill in the middle of a flush left disagreeing (measured by scripts/crash_writes.py:
    every frame's fields unreadable). Past `links` links HDF5 moves them to its dense storage."""
    lib = _libhdf5()
    if lib is None:                 # (h5py on an HDF5 not in the process's maps: HDF5's default group)
        return parent.require_group(name)
    if name in parent:
        return parent[name]
    gcpl = h5py.h5p.create(h5py.h5p.GROUP_CREATE)
    gcpl.set_link_creation_order(h5py.h5p.CRT_ORDER_TRACKED)    # (what makes HDF5 use its newer group format)
    ok = lib.H5Pset_link_phase_change(ctypes.c_int64(gcpl.id), links, links - 1) >= 0
    ok = ok and lib.H5Pset_est_link_info(ctypes.c_int64(gcpl.id), links, 16) >= 0
    h5py.h5g.create(parent.id, name.encode(), gcpl=gcpl if ok else None)
    return parent[name]


class Guard:
    """The end-of-file reserve of one open HDF5 file (h5py.File) being written by this process.

    HDF5 writes its superblock (with the file's end address) last in a flush, after the metadata that points into
    space it has just allocated; a kill between them left a file whose readers refused that space ('addr
    overflow'). So before each write the file is first extended (sparsely) by the write's bytes and a margin, then
    the superblock's end-of-file address is set to the new end: whatever HDF5 writes up to its own flush lies below
    it. HDF5 rewrites the address at that flush; `trim` cuts the closed file to it. Armed only when the superblock
    is where it is expected (HDF5 File Format Specification, version 0/1 superblock)."""

    def __init__(self, f):
        self.f = f
        f.flush()
        self.on = self._eoa() == os.fstat(self._fd()).st_size

    def _fd(self):
        return self.f.id.get_vfd_handle()

    def _eoa(self):
        return int.from_bytes(os.pread(self._fd(), 8, SUPERBLOCK_EOA_AT), "little")

    def reserve(self, nbytes):
        """Room in the file for the next writes of `nbytes`, recorded in the superblock before HDF5 allocates it."""
        if not self.on:
            return
        fd = self._fd()
        end = self.f.id.get_filesize() + int(1.5 * nbytes) + ROOM_MARGIN  # HDF5's own end + what room_for checked
        try:
            os.ftruncate(fd, end)        # (HDF5's writes go below `end`: a sparse tail left from the last one
        except OSError:                  # is cut, and the apparent size grows only with the data)
            return                       # (ulimit -f at the close: HDF5's own writes would fail the same way)
        os.pwrite(fd, end.to_bytes(8, "little"), SUPERBLOCK_EOA_AT)


def trim(path):
    """The closed file cut to the end HDF5 recorded (a Guard's sparse tail gone)."""
    with open(path, "r+b") as fh:
        end = int.from_bytes(os.pread(fh.fileno(), 8, SUPERBLOCK_EOA_AT), "little")
        if os.fstat(fh.fileno()).st_size > end:
            fh.truncate(end)


_LIB = []


def _libhdf5():
    """The HDF5 library h5py runs on (ctypes), for the two group-creation settings h5py does not wrap:
    H5Pset_link_phase_change and H5Pset_est_link_info (HDF5 reference manual, H5P)."""
    if not _LIB:
        h5py.h5p.create(h5py.h5p.GROUP_CREATE)            # (the library is loaded)
        with open("/proc/self/maps") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "/libhdf5" in ln and "libhdf5_hl" not in ln})
        lib = None
        for path in paths:
            try:
                lib = ctypes.CDLL(path)
                lib.H5Pset_link_phase_change, lib.H5Pset_est_link_info     # noqa: B018 (both there)
                break
            except (OSError, AttributeError):
                lib = None
        _LIB.append(lib)
    return _LIB[0]


def room_for(path, nbytes, extra_files=(), size=None):
    """None when `nbytes` more can be written to `path` with ROOM_MARGIN to spare — the disk's free space
    and the process's file size limit (ulimit -f, RLIMIT_FSIZE) — else why not. A write that fails half
    way leaves an HDF5 file unreadable, so the writer asks before every frame and checkpoint. size: the
    file's size as its writer counts it (HDF5's end, without the sparse tail of Writer._reserve)."""
    need = int(1.5 * nbytes) + ROOM_MARGIN
    d = os.path.dirname(os.path.abspath(path)) or "."
    st = os.statvfs(d)
    free = st.f_bavail * st.f_frsize
    if free < need + sum(nb for _, nb in extra_files):
        return f"{free / 1e6:.3g} MB free on the disk, {need / 1e6:.3g} MB needed"
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if soft != resource.RLIM_INFINITY:
        for p, nb in [(path, need)] + [(p, nb + ROOM_MARGIN) for p, nb in extra_files]:
            now = size if p == path and size is not None else os.path.getsize(p) if os.path.exists(p) else 0
            if now + nb > soft:
                return f"the file size limit (ulimit -f) is {soft} bytes"
    return None


def run_attributes(model, scene_file, solver):
    """The output file's root attributes: the full options database, the scene and what was built
    for it (effects_built: JSON {effect: instances}), versions, the rank count and the partition."""
    sc, space = model.scene, model.space
    built = effects_built(model.system.effects, model.system.constraints)
    # the options of the run, less the scene file's that a command-line -effects overrode: a restart replays
    # these on its command line, where they would switch their effects on (scene.EFFECTS_RULE); and less the
    # defaults chosen by the rank count (solver.GALERKIN_KERNELS), which a restart on other ranks chooses anew
    left = set(sc.ignored) | set(solver.unrecorded)
    return {"options": "\n".join(f"-{k} {v}".rstrip() for k, v in all_options() if k not in left),
            "scene": sc.name, "scene_file": os.path.abspath(scene_file), "effects": ",".join(sc.effects),
            "effects_built": json.dumps(built, sort_keys=True), "hyperelastic_version": __version__,
            "petsc_version": ".".join(map(str, PETSc.Sys.getVersion())), "mpi_ranks": space.comm.getSize(),
            "jacobian": sc.jacobian + (f" ({solver.mf})" if solver.mf else ""), "integrator": sc.integrator,
            "formulation": model.formulation.describe(sc), "element_order": model.element.order,
            "quadrature_degree": model.element.degree,
            "operator_storage": solver.storage if solver.op is not None else "",
            "line_search_merit": solver.merit + (f" ({solver.merit_note})" if solver.merit_note else ""),
            "material": sc.solid.name, "E": sc.solid.values["E"], "nu": sc.solid.values["nu"], "rho": sc.solid.rho,
            "material_parameters": json.dumps(sc.solid.record()),
            "regions": json.dumps([{"name": r.name, **r.solid.record()} for r in sc.regions]),
            "mesh": os.path.abspath(sc.mesh) if sc.mesh else f"bar level {sc.level}",
            "mesh_read": "slices" if model.source.sliced_from else "rank 0",
            "vertices_per_rank": np.array(space.mpi.allgather(space.nlv)),
            "cells_per_rank": np.array(space.mpi.allgather(space.nc)),
            "partitioner": space.partitioner,
            "partition": json.dumps(space.partition_quality),
            "mass_matrix_builds": built.get("inertia", 0),
            "notes": "\n".join(list(model.notes or []) + list(solver.notes)),
            "sets": json.dumps([{k: v for k, v in s.items() if k != "line"} for s in model.sets])}


# the attributes that describe the part of a run one process ran: a restart (on another rank count, partitioner or
# version) writes its own, and keeps the earlier parts' in `earlier_parts` (a 3-rank restart's file said mpi_ranks 2,
# with 2 ranks' cells_per_rank and partition, beside its own 3 ranks' peak memory: issue 73)
PART_ATTRS = ("mpi_ranks", "vertices_per_rank", "cells_per_rank", "partitioner", "partition", "mesh_read",
              "hyperelastic_version", "petsc_version", "operator_storage", "peak_rss_mb", "peak_rss_mb_per_rank")


def resumed_attrs(old, attrs, drop=()):
    """A restart's attributes: the checkpoint's file's `old` (less `drop`), one more restart, and this part's options
    (what a later restart replays) and PART_ATTRS from `attrs`, the earlier parts' appended to earlier_parts."""
    keep = {k: v for k, v in old.items() if k not in drop}
    keep["restarts"] = int(old.get("restarts", 0)) + 1
    keep["options"] = attrs["options"]
    earlier = json.loads(old.get("earlier_parts", "[]"))
    earlier.append({k: np.asarray(old[k]).tolist() for k in PART_ATTRS if k in old})
    keep["earlier_parts"] = json.dumps(earlier)
    keep.update({k: attrs[k] for k in PART_ATTRS if k in attrs})
    return keep


class Writer:
    """-output_layout gather: rank 0 gathers every frame in the input mesh's order and writes the one file."""
    layout = "gather"

    def _common(self, path, space, kernels, fields):
        """What every layout's writer holds."""
        self.space = space
        self.kernels = kernels
        self.fields = tuple(fields)
        self.point_scalars = None      # (x) -> {name: local array per node}: scalar point fields of a frame
        self.f = None            # the HDF5 file (rank 0, once opened)
        self.h5 = None           # the file's end-of-file reserve (Guard; rank 0, once opened)
        self.root = space.mpi.rank == 0
        # written under FILE.h5.partial until a step is complete (see _commit), the earlier FILE.h5 (and its XDMF)
        # aside from then until the run ends (close): a run that fails leaves them byte-identical
        self.final = path
        self.path = path + PARTIAL
        self.committed = False
        self.aside = []          # (rank 0) the earlier output's files this run moved aside (_commit)
        self.moved = None        # (after close) where a failed run left its own output, as a clause of its error line
        self.xdmf = os.path.splitext(path)[0] + ".xdmf"
        self.nframes = 0
        self.nstats = 0
        self._mesh_text = None   # the XDMF's <Topology>/<Geometry> block (the same in every frame)
        self._pending = []       # statistics rows not yet written (see stats())
        self._columns = {}       # the open statistics datasets by name
        self._stats_flushed = time.monotonic()

    def __init__(self, path, space, points, tets, attrs, resume=None, kernels=None, region=None,
                 fields=DEFAULT_FIELDS):
        """A new output file, or (resume = a checkpoint's state) the existing one cut back to the
        frames and statistics rows the checkpoint had. kernels: the elastic cell kernels, for the cell
        fields (none without); region: the local cells' region tags (collective); fields: what each frame
        holds (fields.output_fields)."""
        self._common(path, space, kernels, fields)
        self._tets = None        # (rank 0) the cells' nodes, for the fields that need them (fields.finish)
        self._volume = None
        self.points = None if points is None else np.asarray(points, np.float64)
        if resume is not None:
            self._resume(resume, attrs)
            return
        reg = space.gather_cells(np.zeros(space.nc, np.int64) if region is None else np.asarray(region, np.int64))
        if self.root:
            self.nv, self.nc = len(points), len(tets)
        self._ensure_room(lambda: 8 * (3 * self.nv + 5 * self.nc) + 65536, "the mesh")
        if not self.root:
            return
        self._tets = np.asarray(tets) if self._needs_tets() else None
        self.f = self._new_file(points, tets, reg, attrs)
        self.nv, self.nc = len(points), len(tets)
        self.h5 = Guard(self.f)

    def _new_file(self, points, tets, region, attrs):
        """The file's layout, made before the first step (a kill after that only meets writes into it)."""
        f = h5py.File(self.path, "w")
        nv = len(points)
        f.create_dataset("mesh/points", data=np.asarray(points, np.float64))
        f.create_dataset("mesh/tetra", data=np.asarray(tets, np.int64))
        f.create_dataset("mesh/region", data=region)
        # NaN fill: a frame's row extended before its data reached the file reads NaN (files.completed_frames)
        f.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,), fillvalue=np.nan)
        f.create_dataset("x", shape=(0, nv, 3), maxshape=(None, nv, 3), dtype=np.float64, chunks=(1, nv, 3),
                         fillvalue=np.nan)
        f.create_group("stats")
        _compact_group(f, "frames", FRAME_LINKS)
        ck = f.create_group("checkpoint")
        for slot in (0, 1):                 # made before the first step: a checkpoint only fills them
            _compact_group(ck, str(slot), FIELD_LINKS)
        for k, v in attrs.items():
            f.attrs[k] = v
        f.attrs["output_layout"] = self.layout
        f.attrs["checkpoint_slot"] = -1     # made here: a checkpoint then rewrites it in place
        f.attrs[ROOM_ATTR] = np.zeros(ROOM_ATTR_BYTES, np.uint8)
        return f

    def _resume(self, st, attrs):
        self.nframes, self.nstats = int(st["nframes"]), int(st["nstats"])
        self._ensure_room(lambda: os.path.getsize(self.final), "a copy of the checkpoint's file")
        if not self.root:
            return
        with h5py.File(self.final, "r") as src:      # the checkpoint's file stays as it is until _commit
            self.f = f = self._copy_until_checkpoint(src, attrs)
        self.h5 = Guard(f)

    def _copy_until_checkpoint(self, src, attrs):
        """A new file with what `src` held up to its checkpoint: the mesh, the checkpoint's frames and
        statistics rows, the checkpoint, the run's attributes. Only those objects are read: a file left by
        a kill may hold a frame or a checkpoint slot that was being written (unreadable), which a copy of
        the whole file would carry on and cutting it back in place would have to open."""
        keep = resumed_attrs(src.attrs, attrs, ("failure", "interrupted", "checkpoint_slot", ROOM_ATTR))
        self.points = src["mesh/points"][:]
        tets = src["mesh/tetra"][:]
        self.nv, self.nc = len(self.points), len(tets)
        self._tets = tets if self._needs_tets() else None
        region = src["mesh/region"][:] if "mesh/region" in src else np.zeros(self.nc, np.int64)
        f = self._new_file(self.points, tets, region, keep)
        n = self.nframes
        f["time"].resize((n,))
        f["time"][:] = src["time"][:n]
        f["x"].resize((n, self.nv, 3))
        for i in range(n):
            f["x"][i] = src["x"][i]
            g = _compact_group(f["frames"], str(i), FIELD_LINKS)
            for k, d in src[f"frames/{i}"].items():
                g.create_dataset(k, data=d[:])
        for k, d in src["stats"].items():
            f["stats"].create_dataset(k, data=d[:self.nstats], maxshape=(None,), chunks=(256,),
                                      fillvalue=0 if d.dtype.kind == "i" else np.nan)
        slot = int(src.attrs["checkpoint_slot"])
        g, h = src[f"checkpoint/{slot}"], f[f"checkpoint/{slot}"]
        for k, d in g.items():
            h.create_dataset(k, data=d[:])
        for k, v in g.attrs.items():
            h.attrs[k] = v
        f.attrs.modify("checkpoint_slot", slot)
        return f

    def checkpoint(self, x_local, v_local, nodal=None, cells=None, **state):
        """The full state into checkpoint/<slot>, alternating two slots; the root attribute
        checkpoint_slot names the complete one and is written after its data is flushed, so a kill at
        any moment leaves the previous checkpoint intact; nodal: {name: local scalar per node} of the state
        beyond x and v (the mixed formulation's pressure); cells: {name: local rows per cell} (the viscoelastic
        effect's stresses), in the input cells' order. Collective."""
        x, v = self.space.gather(x_local), self.space.gather(v_local)
        extra = {k: self.space.gather_nodal(a) for k, a in (nodal or {}).items()}
        extra.update({k: self.space.gather_cells(a) for k, a in (cells or {}).items()})
        if self.root:
            nbytes = 8 * (6 * len(x) + sum(a.size for a in extra.values())) + 16384
        self._ensure_room(lambda: nbytes, "a checkpoint")

        def write():
            self._reserve(nbytes)
            self._write_checkpoint(x, v, state, extra)
        self._root_part(write)

    def _root_part(self, write):
        """write() on rank 0 (its HDF5 writes of a frame or a checkpoint, timed as HE_OutRank0), then the ranks leave
        together: an exception rank 0 raises there is raised on every rank (the others used to wait in the next
        collective call forever while rank 0 went on to its error's own collective calls: a 2-rank run hung)."""
        err = None
        if self.root:
            EVENTS.Rank0.begin()
            try:
                write()
            except Exception as e:       # noqa: BLE001 (raised again below, on every rank)
                err = e
            finally:
                EVENTS.Rank0.end()
        self._leave_together(err)

    def _leave_together(self, err=None):
        """The end of a collective write: the other ranks wait here for rank 0's HDF5 writes, so that the
        wait is the output's and not charged to their next collective call (the next step's first
        residual in -log_view and the step timers); rank 0's error `err` raised on every rank."""
        why = self.space.mpi.bcast(None if err is None else (isinstance(err, UserError), str(err)), root=0)
        if err is not None:
            raise err
        if why is not None:
            user, text = why
            raise UserError(text) if user else RuntimeError(f"rank 0's output write failed: {text}")

    def _write_checkpoint(self, x, v, state, extra):
        f = self.f
        self._flush_stats()
        slot = 1 if int(f.attrs.get("checkpoint_slot", -1)) == 0 else 0
        g = f.require_group(f"checkpoint/{slot}")
        for name, a in (("x", x), ("v", v), *extra.items()):
            if name not in g:
                g.create_dataset(name, data=a)
            else:
                g[name][...] = a
        self._complete_checkpoint(g, slot, state)

    def _complete_checkpoint(self, g, slot, state):
        """A checkpoint slot's data written: its attributes, a flush, then the root attribute that names it."""
        for k in CHECKPOINT_ATTRS:
            g.attrs[k] = state[k]
        for k in (*CHECKPOINT_OPTIONAL, *CHECKPOINT_VECTORS):     # (the slot may hold an older checkpoint's)
            if state.get(k) is not None:
                g.attrs[k] = state[k]
            elif k in g.attrs:
                del g.attrs[k]
        self.f.flush()
        self.f.attrs.modify("checkpoint_slot", slot)
        self.f.flush()

    def frame(self, t, x_local, v_local=None):
        """Frame at time t: positions x, velocities v (local arrays) and the fields (fields.py). Collective."""
        full = self.space.gather(x_local)
        vel = self.space.gather(v_local) if v_local is not None else None
        cells, nodal = {}, {}
        if self.kernels is not None:
            EVENTS.Fields.begin()
            local = cell_fields(self.kernels, x_local, cell_quantities(self.fields))
            EVENTS.Fields.end()
        scalars = self.point_scalars(x_local) if self.point_scalars is not None else {}  # (mixed: pressure; contact)
        if self.kernels is not None:
            if AT_NODES in local:         # recovered on each rank's own cells (their node order), then gathered
                sp = self.space
                rec = recover(local.pop(AT_NODES), sp.cells, self._local_volumes(), scalars.get("pressure"),
                              total=lambda a, n: sp.sum_owned(a, n))
                nodal.update({k: sp.gather_rows(a) for k, a in rec.items() if k in self.fields})
            cells = {k: self.space.gather_cells(a) for k, a in local.items()}
        nodal.update({k: self.space.gather_nodal(a) for k, a in scalars.items()})
        if self.root:
            if self.kernels is not None:
                cells = finish(cells, self.fields, self._tets, self._volumes(), nodal.get("pressure"))
            cells.update(nodal)
            nbytes = 8 * (3 * self.nv * (3 if vel is not None else 2) + sum(a.size for a in cells.values())) + 16384
        self._ensure_room(lambda: nbytes, f"frame {self.nframes}")

        def write():
            self._reserve(nbytes)
            self._write_frame(t, full, vel, cells)
        self._root_part(write)

    def _write_frame(self, t, full, vel, cells):
        """The positions and the fields, a flush, then the time and a flush of its own: a frame counts once
        its time is in (files.completed_frames), so a kill in the first flush leaves at most a row of x that
        no reader counts."""
        f = self.f
        i = self.nframes
        times, xs = f["time"], f["x"]
        xs.resize((i + 1, self.nv, 3))
        xs[i] = full
        g = _compact_group(f["frames"], str(i), FIELD_LINKS)
        for k in list(g):
            del g[k]
        fields = {"displacement": full - self.points} if "displacement" in self.fields else {}
        if vel is not None and "velocity" in self.fields:
            fields["velocity"] = vel
        fields.update(cells)
        for k, a in fields.items():
            g.create_dataset(k, data=a)
        self.nframes += 1
        # the statistics rows go in with a frame at most every STATS_EVERY_S seconds (and at every
        # checkpoint and the close): ~30 columns x 2 HDF5 calls cost more than a small mesh's frame
        if time.monotonic() - self._stats_flushed >= STATS_EVERY_S:
            self._flush_stats()
        f.flush()
        times.resize((i + 1,))
        times[i] = t
        f.flush()
        if self.committed:
            self._append_xdmf(i, t, sorted((k, a.shape) for k, a in fields.items()))

    def _ensure_room(self, nbytes, what):
        """UserError on every rank unless rank 0 can write nbytes() more (room_for). Collective."""
        why = None
        if self.root:
            xdmf = [(self.xdmf, XDMF_FRAME_BYTES)] if self.committed and os.path.exists(self.xdmf) else []
            why = room_for(self.path, nbytes(), xdmf, self.f.id.get_filesize() if self.f is not None else None)
        why = self.space.mpi.bcast(why, root=0)
        if why:
            held = f"it holds frames 0..{self.nframes - 1}" if self.nframes else "it holds no frame"
            raise UserError(f"output '{self.final}': no room for {what} ({why}); {held}")

    def stats(self, row):
        """One statistics row; rows are kept in memory and written with the next frame, checkpoint
        or close (one resize per column then, instead of one per row: ~25 columns x 2 HDF5 calls
        per step cost more than a small mesh's step)."""
        if not self.root:
            return
        for k in row:
            column_type(k)        # only declared columns (stats.py)
        self._pending.append(dict(row))
        self.nstats += 1
        if not self.committed and not row.get("rejected", 0):
            self._commit()

    def _commit(self):
        """The first completed step: the earlier FILE.h5 and FILE.xdmf go aside (FILE.h5.earlier, FILE.xdmf.earlier),
        FILE.h5.partial becomes FILE.h5 (an atomic rename of the open file) and the XDMF is written; from here on the
        run writes into FILE.h5 (a kill leaves it readable, its checkpoint usable). close() removes what is aside
        when the run ends, or puts it back when the run fails."""
        self._flush_stats()
        self.f.flush()
        self.aside = [p for p in (self.final, self.xdmf) if os.path.exists(p)]
        for p in self.aside:
            os.replace(p, p + EARLIER)
        os.replace(self.path, self.final)
        self.path, self.committed = self.final, True
        self._write_xdmf()

    def _set_failed_aside(self):
        """(rank 0, the file open) A run that failed after its first step, where it had moved an earlier output
        aside: its own FILE.h5 becomes FILE.failed.h5 with an XDMF of that name (its per-rank files stay in
        FILE.h5.d/, named from there as before), and the earlier output is put back. Returns the error line's clause."""
        own, xdmf = self.final, self.xdmf
        self.final = failed_path(own)
        self.xdmf = os.path.splitext(self.final)[0] + ".xdmf"
        os.replace(own, self.final)
        self.path, self._mesh_text = self.final, None       # (the XDMF's mesh block names the file)
        try:
            self._write_xdmf()
        except OSError:          # (a full disk: the HDF5 file holds the frames; the renames below need no room)
            if os.path.exists(self.xdmf + ".tmp"):
                os.remove(self.xdmf + ".tmp")
        if os.path.exists(xdmf):
            os.remove(xdmf)
        for p in self.aside:
            os.replace(p + EARLIER, p)
        frames = {0: "no frame is", 1: "frame 0 is"}.get(self.nframes, f"frames 0..{self.nframes - 1} are")
        return f"the earlier '{os.path.basename(own)}' is kept as it was; this run's {frames} in '{self.final}'"

    def _drop_earlier(self):
        """(rank 0) The run ended (or stopped with a checkpoint): the earlier output that was aside, and the per-rank
        files no output of this name refers to, are removed."""
        for p in (self.final, self.xdmf):
            if os.path.exists(p + EARLIER):
                os.remove(p + EARLIER)
        self._clean()

    def _rank_files(self):
        """The per-rank files (in FILE.h5.d/) that this run's FILE.h5 names: none in the gathered layout."""
        return set()

    def _clean(self):
        """(rank 0, once this run has ended) The per-rank files in FILE.h5.d/ that neither FILE.h5 nor FILE.failed.h5
        names: an earlier run's, replaced now (a run that fails leaves them); the directory too once empty."""
        d = self.final + RANKS
        if not os.path.isdir(d):
            return
        keep = self._rank_files() | named_rank_files(failed_path(self.final))
        for name in os.listdir(d):
            if name not in keep and RANK_FILE.search(name):
                try:
                    os.remove(os.path.join(d, name))
                except OSError:
                    pass
        if not os.listdir(d):
            os.rmdir(d)

    def _flush_stats(self):
        rows, self._pending = self._pending, []
        self._stats_flushed = time.monotonic()
        if not rows:
            return
        g = self.f["stats"]
        cols = self._columns
        if not cols:
            cols.update((k, g[k]) for k in g)
        i0 = self.nstats - len(rows)
        for row in rows:
            for k in row:
                if k not in cols:
                    is_int = column_type(k) is int
                    cols[k] = g.create_dataset(k, shape=(i0,), maxshape=(None,), chunks=(256,),
                                               dtype=np.int64 if is_int else np.float64,
                                               fillvalue=0 if is_int else np.nan)
        for d in cols.values():          # every column has one entry per step (missing: NaN / 0)
            k = d.name.rsplit("/", 1)[-1]
            fill = 0 if d.dtype.kind == "i" else np.nan
            d.resize((self.nstats,))
            d[i0:] = np.array([row.get(k, fill) for row in rows], dtype=d.dtype)

    def set_attr(self, key, value):
        """An attribute of the run (written with the next flush). The root group's header was made with room
        (ROOM_ATTR): it is given up here, so the new attribute goes into that room and the header is rewritten
        in place, in one write, instead of growing by a continuation block that a kill could leave unwritten
        while the header already points to it (the whole file unreadable)."""
        if self.root:
            self._reserve(len(str(value)) + 16384)
            if ROOM_ATTR in self.f.attrs:
                del self.f.attrs[ROOM_ATTR]
            self.f.attrs[key] = value

    def _needs_tets(self):
        return needs_volumes(self.fields) or "stress" in cell_quantities(self.fields)

    def _local_volumes(self):
        """The reference volumes of this rank's own cells (the weights of the recovered fields)."""
        if getattr(self, "_local_volume", None) is None:
            self._local_volume = reference_volumes(self.space.X.reshape(-1, 3), self.space.cells)
        return self._local_volume

    def _volumes(self):
        if self._volume is None and self._tets is not None and needs_volumes(self.fields):
            self._volume = reference_volumes(self.points, self._tets)
        return self._volume

    def _reserve(self, nbytes):
        """Room for the next writes (Guard.reserve)."""
        if self.h5 is not None:
            self.h5.reserve(nbytes)

    def close(self, keep=True):
        """Flush and close (collective). `keep`: the run ended normally or was interrupted with a checkpoint; it then
        replaces an earlier FILE.h5 for good. A run that fails (not `keep`) leaves an earlier FILE.h5 and XDMF as they
        were: before its first step its partial file is removed (kept as FILE.h5 where there was none), after it its
        own output becomes FILE.failed.h5 (self.moved then says so, for the error line)."""
        moved = None
        if self.root and self.f is not None:
            self._reserve(65536)
            self._flush_stats()
            self.f.flush()
            if not self.committed and (keep or not os.path.exists(self.final)):
                self._commit()
            if self.committed and not keep and self.aside:
                moved = self._set_failed_aside()
            self.f.close()
            self.f = None
            if not self.committed and os.path.exists(self.path):
                os.remove(self.path)
            elif self.h5.on:
                trim(self.path)
            if self.committed and keep:
                self._drop_earlier()
        self.moved = self.space.mpi.bcast(moved, root=0)

    def _mesh_xml(self):
        h5 = os.path.basename(self.final)
        nv, nc = self.nv, self.nc
        npc = self.f["mesh/tetra"].shape[1]          # 4, or 10 for quadratic cells (VTK's node order)
        kind = "Tetrahedron" if npc == 4 else "Tetrahedron_10"
        return (f'    <Topology TopologyType="{kind}" NumberOfElements="{nc}">\n'
                f'     <DataItem Dimensions="{nc} {npc}" NumberType="Int" Precision="8" Format="HDF">{h5}:/mesh/tetra'
                '</DataItem>\n    </Topology>\n    <Geometry GeometryType="XYZ">\n'
                f'     <DataItem Dimensions="{nv} 3" NumberType="Float" Precision="8" Format="HDF">{h5}:/mesh/points'
                '</DataItem>\n    </Geometry>')

    def _grid_xml(self, i, t, fields):
        """Frame i's <Grid> (one line-terminated block): fields is [(name, shape)] of frames/i."""
        h5 = os.path.basename(self.final)
        if self._mesh_text is None:
            self._mesh_text = self._mesh_xml()
        attrs = [self._attribute(h5, "/mesh/region", "region", (self.nc,), "Cell", "Int")]
        for name, shape in fields:
            node = is_point_field(name)
            attrs.append(self._attribute(h5, f"/frames/{i}/{name}", name, shape, "Node" if node else "Cell", "Float"))
        return (f'   <Grid Name="frame{i}" GridType="Uniform">\n{self._mesh_text}\n    <Time Value="{t:.17g}"/>\n'
                + "\n".join(attrs) + "\n   </Grid>\n")

    def _write_xdmf(self):
        """The XDMF of all frames so far, written whole and atomically (a temporary file renamed over it):
        at the first completed step and after a restart. Later frames are appended (_append_xdmf)."""
        grids = []
        for i, t in enumerate(self.f["time"][:]):
            g = self.f.get(f"frames/{i}", {})
            grids.append(self._grid_xml(i, t, [(name, g[name].shape) for name in sorted(g)]))
        tmp = self.xdmf + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(XDMF_HEAD + "".join(grids) + XDMF_TAIL)
        os.replace(tmp, self.xdmf)

    def _append_xdmf(self, i, t, fields):
        """Frame i appended to the XDMF in one write over its closing tags (the file is a complete document
        before and after that write, so a kill at any moment leaves it readable; the cost of a frame does
        not grow with the frames before it). A file that does not end as this writer left it, and a write
        that fails (the disk filled up), fall back to the whole atomic rewrite / restore the closing tags."""
        tail = XDMF_TAIL.encode()
        try:
            fh = open(self.xdmf, "r+b")
        except FileNotFoundError:
            return self._write_xdmf()
        with fh:
            end = fh.seek(0, os.SEEK_END)
            fh.seek(max(end - len(tail), 0))
            if end < len(tail) or fh.read() != tail:
                fh.close()
                return self._write_xdmf()
            at = end - len(tail)
            fh.seek(at)
            try:
                fh.write(self._grid_xml(i, t, fields).encode() + tail)
                fh.flush()
            except OSError:
                fh.seek(at)
                fh.truncate()
                fh.write(tail)
                raise

    @staticmethod
    def _attribute(h5, dset, name, shape, center, number):
        kind = {1: "Scalar", 3: "Vector", 6: "Tensor6"}[1 if len(shape) == 1 else shape[1]]
        dims = " ".join(map(str, shape))
        return (f'    <Attribute Name="{name}" AttributeType="{kind}" Center="{center}">\n'
                f'     <DataItem Dimensions="{dims}" NumberType="{number}" Precision="8" Format="HDF">{h5}:{dset}'
                '</DataItem>\n    </Attribute>')
