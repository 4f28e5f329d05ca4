"""HDF5 output (rank 0 writes, flushed every frame) and an XDMF time series beside it.

Layout: mesh/points (nv,3), mesh/tetra (nc,4) in the input mesh's numbering (mesh/region (nc,): the
region tag of each tet, 0 for none); time (F,); x (F,nv,3) positions in the input vertex order;
frames/<i>/<field> the fields of frame i (fields.py: displacement, velocity (nv,3); J, energy_density,
von_mises (nc,)); stats/<column> (S,) one entry per step attempt (the columns: stats.py);
attributes: see run_attributes.

The XDMF beside it is a temporal collection of uniform grids on the reference mesh, each frame with its
fields as attributes (the layout meshio's TimeSeriesReader and VTK's XDMF reader read; ParaView: Warp By
Vector with displacement shows the deformed body).
"""
import os

import numpy as np

from .errors import UserError
from .stats import column_type


def writable_dir(d, who):
    """Create directory d if needed; UserError naming `who` unless it can be written to."""
    if not os.path.isdir(d):
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as e:
            raise UserError(f"{who}: cannot create directory '{d}' ({e.strerror})") from None
    if not os.access(d, os.W_OK):
        raise UserError(f"{who}: directory '{d}' is not writable")


PARTIAL = ".partial"      # a run writes FILE.h5.partial until it has completed a step (Writer._commit)


def output_names(path):
    """The files an output path stands for: the HDF5 file, the XDMF beside it and the partial file."""
    return [path, os.path.splitext(path)[0] + ".xdmf", path + PARTIAL]


OUTPUT_DATASETS = ("mesh/points", "mesh/tetra", "time", "x")     # what every output of `hyperelastic run` holds


def missing_datasets(f, more=()):
    """The datasets of OUTPUT_DATASETS (and `more`) that the open HDF5 file f lacks."""
    return [k for k in OUTPUT_DATASETS + tuple(more) if k not in f]


ROOM_MARGIN = 256 * 1024     # bytes kept free for HDF5's metadata, the statistics rows and the close


def room_for(path, nbytes, extra_files=()):
    """None when `nbytes` more can be written to `path` with ROOM_MARGIN to spare — the disk's free space
    and the process's file size limit (ulimit -f, RLIMIT_FSIZE) — else why not. A write that fails half
    way leaves an HDF5 file unreadable, so the writer asks before every frame and checkpoint."""
    import resource
    need = int(1.5 * nbytes) + ROOM_MARGIN
    d = os.path.dirname(os.path.abspath(path)) or "."
    st = os.statvfs(d)
    free = st.f_bavail * st.f_frsize
    if free < need + sum(nb for _, nb in extra_files):
        return f"{free / 1e6:.3g} MB free on the disk, {need / 1e6:.3g} MB needed"
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if soft != resource.RLIM_INFINITY:
        for p, nb in [(path, need)] + [(p, nb + ROOM_MARGIN) for p, nb in extra_files]:
            size = os.path.getsize(p) if os.path.exists(p) else 0
            if size + nb > soft:
                return f"the file size limit (ulimit -f) is {soft} bytes"
    return None


def check_output_path(path, inputs=(), suffixes=(".h5", ".hdf5")):
    """Raise UserError unless `path` can be written without touching an input (checked before any work
    is done). The name must end in .h5 or .hdf5, so that the XDMF beside it never is the HDF5 file;
    neither may be (or be the data of) an input file: the mesh, the scene or an options file."""
    if os.path.isdir(path):
        raise UserError(f"output '{path}' is a directory")
    if suffixes and not path.lower().endswith(suffixes):
        raise UserError(f"option -output: '{path}' must end in .h5 or .hdf5 (the .xdmf is written beside it)")
    taken = {}
    for name in inputs:
        if not name:
            continue
        stem, ext = os.path.splitext(name)
        for p in [name] + ([stem + ".h5", stem + ".hdf5", stem + ".xdmf"] if ext.lower() in (".h5", ".hdf5", ".xdmf") else []):
            taken[os.path.realpath(p)] = name
    for p in (output_names(path) if suffixes else [path]):
        if os.path.realpath(p) in taken:
            raise UserError(f"option -output: '{path}' would overwrite the input '{taken[os.path.realpath(p)]}'")
    writable_dir(os.path.dirname(os.path.abspath(path)) or ".", f"output '{path}'")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise UserError(f"output '{path}': not writable")
    if not suffixes:
        return
    for p in output_names(path):
        if os.path.lexists(p) and not os.path.isfile(p):
            raise UserError(f"output '{path}': '{p}' exists and is not a regular file")
    if os.path.exists(path):
        from .mesh import _is_output
        if not _is_output(path):
            raise UserError(f"output '{path}': exists and is not an output of hyperelastic (not overwriting it)")
    probe = path + PARTIAL
    try:                     # a name the file system refuses (too long, ...) is found now, not at the first write
        existed = os.path.exists(probe)
        with open(probe, "ab"):
            pass
        if not existed:
            os.remove(probe)
    except OSError as e:
        raise UserError(f"output '{path}': cannot be created ({e.strerror})") from None


def run_attributes(model, scene_file, solver):
    """The output file's root attributes: the full options database, the scene and what was built
    for it (effects_built: JSON {effect: instances}), versions, the rank count and the partition."""
    import json
    from petsc4py import PETSc
    from . import __version__
    from .options import all_options
    sc, space = model.scene, model.space
    built = model.system.built()
    return {"options": "\n".join(f"-{k} {v}".rstrip() for k, v in all_options()),
            "scene": sc.name, "scene_file": os.path.abspath(scene_file), "effects": ",".join(sc.effects),
            "effects_built": json.dumps(built, sort_keys=True), "hyperelastic_version": __version__,
            "petsc_version": ".".join(map(str, PETSc.Sys.getVersion())), "mpi_ranks": space.comm.getSize(),
            "jacobian": sc.jacobian + (f" ({solver.mf})" if solver.mf else ""), "integrator": sc.integrator,
            "operator_storage": solver.storage if solver.op is not None else "",
            "line_search_merit": solver.merit + (f" ({solver.merit_note})" if solver.merit_note else ""),
            "material": sc.material.name, "E": sc.E, "nu": sc.nu, "rho": sc.rho,
            "regions": json.dumps([{"name": r.name, "material": r.material.name, "E": r.E, "nu": r.nu, "rho": r.rho}
                                   for r in sc.regions]),
            "mesh": os.path.abspath(sc.mesh) if sc.mesh else f"bar level {sc.level}",
            "vertices_per_rank": np.array(space.mpi.allgather(space.nlv)),
            "cells_per_rank": np.array(space.mpi.allgather(space.nc)),
            "mass_matrix_builds": built.get("inertia", 0),
            "sets": json.dumps([{k: v for k, v in s.items() if k != "line"} for s in model.sets])}


CHECKPOINT_ATTRS = ("t", "step", "n", "h_try", "streak", "rejections", "nframes", "nstats")


def read_checkpoint(path):
    """(state dict with x, v and CHECKPOINT_ATTRS, root attributes) of the last complete checkpoint
    in an output file; UserError when there is none."""
    import h5py
    if not os.path.isfile(path):
        raise UserError(f"--restart '{path}': no such file")
    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError) as e:
        raise UserError(f"--restart '{path}': cannot be opened as HDF5 ({str(e).split('(')[0].strip()})") from None
    with f:
        missing = missing_datasets(f, ("stats",))
        missing += [f"attribute {k}" for k in ("options", "scene_file") if k not in f.attrs]
        if missing:
            raise UserError(f"--restart '{path}': not an output of hyperelastic (no {', '.join(missing)})")
        slot = f.attrs.get("checkpoint_slot", -1)
        if slot < 0 or f"checkpoint/{slot}" not in f:
            raise UserError(f"--restart '{path}': holds no checkpoint (run with -checkpoint_every N)")
        g = f[f"checkpoint/{slot}"]
        bad = [k for k in ("x", "v") if k not in g] + [k for k in CHECKPOINT_ATTRS if k not in g.attrs]
        if bad:
            raise UserError(f"--restart '{path}': checkpoint {slot} is incomplete (no {', '.join(bad)})")
        nv = f["mesh/points"].shape[0]
        state = {}
        for k in ("x", "v"):
            a = g[k]
            if a.shape != (nv, 3) or a.dtype.kind != "f":
                raise UserError(f"--restart '{path}': checkpoint {k} has shape {a.shape} ({a.dtype}), the mesh "
                                f"needs ({nv}, 3) numbers")
            state[k] = a[:]
            if not np.isfinite(state[k]).all():
                raise UserError(f"--restart '{path}': checkpoint {k} holds non-finite values")
        for k in CHECKPOINT_ATTRS:
            v = np.asarray(g.attrs[k])
            if v.shape != () or v.dtype.kind not in "iuf" or not np.isfinite(v):
                raise UserError(f"--restart '{path}': checkpoint attribute {k} = {v!r} is not a finite number")
            state[k] = v.item()
        nstats = min((f["stats"][k].shape[0] for k in f["stats"]), default=0)
        limits = {"t": (0, None), "step": (0, None), "n": (0, None), "h_try": (0, None), "streak": (0, None),
                  "rejections": (0, None), "nframes": (1, f["time"].shape[0]), "nstats": (0, nstats)}
        for k, (lo, hi) in limits.items():
            v = state[k]
            if v < lo or (k == "h_try" and v <= 0) or (hi is not None and v > hi):
                raise UserError(f"--restart '{path}': checkpoint attribute {k} = {v:g} is out of range "
                                f"({'> 0' if k == 'h_try' else f'{lo}..{hi}' if hi is not None else f'>= {lo}'})")
        attrs = {k: (v.item() if hasattr(v, "item") and getattr(v, "shape", None) == () else v)
                 for k, v in f.attrs.items()}
    return state, attrs


class Writer:
    def __init__(self, path, space, points, tets, attrs, resume=None, kernels=None, region=None):
        """A new output file, or (resume = a checkpoint's state) the existing one cut back to the
        frames and statistics rows the checkpoint had. kernels: the elastic cell kernels, for the cell
        fields (none without); region: the local cells' region tags (collective)."""
        self.space = space
        self.kernels = kernels
        self.points = None if points is None else np.asarray(points, np.float64)
        self.root = space.mpi.rank == 0
        # written under FILE.h5.partial until a step is complete (see _commit): a run that fails before
        # leaves an earlier FILE.h5 (and its XDMF) byte-identical
        self.final = path
        self.path = path + PARTIAL
        self.committed = False
        self.xdmf = os.path.splitext(path)[0] + ".xdmf"
        self.nframes = 0
        self.nstats = 0
        self._pending = []       # statistics rows not yet written (see stats())
        if resume is not None:
            self._resume(resume, attrs)
            return
        reg = space.gather_cells(np.zeros(space.nc, np.int64) if region is None else np.asarray(region, np.int64))
        if self.root:
            self.nv, self.nc = len(points), len(tets)
        self._ensure_room(lambda: 8 * (3 * self.nv + 5 * self.nc) + 65536, "the mesh")
        if not self.root:
            return
        import h5py
        self.f = f = h5py.File(self.path, "w")
        nv = len(points)
        f.create_dataset("mesh/points", data=np.asarray(points, np.float64))
        f.create_dataset("mesh/tetra", data=np.asarray(tets, np.int64))
        f.create_dataset("mesh/region", data=reg)
        f.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,))
        f.create_dataset("x", shape=(0, nv, 3), maxshape=(None, nv, 3), dtype=np.float64, chunks=(1, nv, 3))
        f.create_group("stats")
        for k, v in attrs.items():
            f.attrs[k] = v
        f.flush()
        self.nv, self.nc = nv, len(tets)

    def _resume(self, st, attrs):
        self.nframes, self.nstats = int(st["nframes"]), int(st["nstats"])
        self._ensure_room(lambda: os.path.getsize(self.final), "a copy of the checkpoint's file")
        if not self.root:
            return
        import shutil
        import h5py
        shutil.copyfile(self.final, self.path)        # the checkpoint's file stays as it is until _commit
        self.f = f = h5py.File(self.path, "r+")
        self.nv, self.nc = f["mesh/points"].shape[0], f["mesh/tetra"].shape[0]
        f["time"].resize((self.nframes,))
        f["x"].resize((self.nframes, self.nv, 3))
        self.points = f["mesh/points"][:]
        for k in list(f.get("frames", {})):
            if int(k) >= self.nframes:
                del f["frames"][k]
        for k in f["stats"]:
            f["stats"][k].resize((self.nstats,))
        for k in ("failure", "interrupted"):
            if k in f.attrs:
                del f.attrs[k]
        f.attrs["restarts"] = int(f.attrs.get("restarts", 0)) + 1
        f.attrs["options"] = attrs["options"]      # what this part ran with (a later restart uses it)
        f.flush()

    def checkpoint(self, x_local, v_local, **state):
        """The full state into checkpoint/<slot>, alternating two slots; the root attribute
        checkpoint_slot names the complete one and is written after its data is flushed, so a kill at
        any moment leaves the previous checkpoint intact. Collective."""
        x, v = self.space.gather(x_local), self.space.gather(v_local)
        self._ensure_room(lambda: 48 * len(x) + 16384, "a checkpoint")
        if self.root:
            self._write_checkpoint(x, v, state)
        self._leave_together()

    def _leave_together(self):
        """The end of a collective write: the other ranks wait here for rank 0's HDF5 writes, so that the
        wait is the output's and not charged to their next collective call (the next step's first
        residual in -log_view and the step timers)."""
        self.space.mpi.Barrier()

    def _write_checkpoint(self, x, v, state):
        f = self.f
        self._flush_stats()
        slot = 1 - int(f.attrs.get("checkpoint_slot", 1))
        g = f.require_group(f"checkpoint/{slot}")
        for name, a in (("x", x), ("v", v)):
            if name not in g:
                g.create_dataset(name, data=a)
            else:
                g[name][...] = a
        for k in CHECKPOINT_ATTRS:
            g.attrs[k] = state[k]
        f.flush()
        f.attrs["checkpoint_slot"] = slot
        f.flush()

    def frame(self, t, x_local, v_local=None):
        """Frame at time t: positions x, velocities v (local arrays) and the fields (fields.py). Collective."""
        from .fields import cell_fields
        full = self.space.gather(x_local)
        vel = self.space.gather(v_local) if v_local is not None else None
        cells = {}
        if self.kernels is not None:
            cells = {k: self.space.gather_cells(a) for k, a in cell_fields(self.kernels, x_local).items()}
        if self.root:
            nbytes = 8 * (3 * self.nv * (3 if vel is not None else 2) + sum(len(a) for a in cells.values())) + 16384
        self._ensure_room(lambda: nbytes, f"frame {self.nframes}")
        if self.root:
            self._write_frame(t, full, vel, cells)
        self._leave_together()

    def _write_frame(self, t, full, vel, cells):
        f = self.f
        i = self.nframes
        f["time"].resize((i + 1,))
        f["x"].resize((i + 1, self.nv, 3))
        f["x"][i] = full
        f["time"][i] = t
        g = f.require_group(f"frames/{i}")
        for k in list(g):
            del g[k]
        g.create_dataset("displacement", data=full - self.points)
        if vel is not None:
            g.create_dataset("velocity", data=vel)
        for k, a in cells.items():
            g.create_dataset(k, data=a)
        self.nframes += 1
        self._flush_stats()
        f.flush()
        if self.committed:
            self._write_xdmf()

    def _ensure_room(self, nbytes, what):
        """UserError on every rank unless rank 0 can write nbytes() more (room_for). Collective."""
        why = None
        if self.root:
            xdmf = [(self.xdmf, 2 * os.path.getsize(self.xdmf) + 4096)] if self.committed and os.path.exists(self.xdmf) else []
            why = room_for(self.path, nbytes(), xdmf)
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
        """The first completed step: FILE.h5.partial becomes FILE.h5 (an atomic rename of the open file)
        and the XDMF is written; from here on the run writes into FILE.h5."""
        self._flush_stats()
        self.f.flush()
        os.replace(self.path, self.final)
        self.path, self.committed = self.final, True
        self._write_xdmf()

    def _flush_stats(self):
        rows, self._pending = self._pending, []
        if not rows:
            return
        g = self.f["stats"]
        i0 = self.nstats - len(rows)
        for row in rows:
            for k in row:
                if k not in g:
                    is_int = column_type(k) is int
                    g.create_dataset(k, shape=(i0,), maxshape=(None,), chunks=(256,),
                                     dtype=np.int64 if is_int else np.float64, fillvalue=0 if is_int else np.nan)
        for k in g:                      # every column has one entry per step (missing: NaN / 0)
            d = g[k]
            fill = 0 if d.dtype.kind == "i" else np.nan
            d.resize((self.nstats,))
            d[i0:] = np.array([row.get(k, fill) for row in rows], dtype=d.dtype)

    def set_attr(self, key, value):
        if self.root:
            self.f.attrs[key] = value

    def close(self, keep=True):
        """Flush and close. A run that completed no step replaces an earlier FILE.h5 only when `keep`
        (it ended normally or was interrupted with a checkpoint); else its partial file is removed."""
        if self.root and getattr(self, "f", None) is not None:
            self._flush_stats()
            self.f.flush()
            if not self.committed and (keep or not os.path.exists(self.final)):
                self._commit()
            self.f.close()
            self.f = None
            if not self.committed and os.path.exists(self.path):
                os.remove(self.path)

    def _write_xdmf(self):
        """The XDMF of all frames so far (rewritten whole, atomically, at each frame)."""
        h5 = os.path.basename(self.final)
        times = self.f["time"][:]
        nv, nc = self.nv, self.nc
        mesh = (f'    <Topology TopologyType="Tetrahedron" NumberOfElements="{nc}">\n'
                f'     <DataItem Dimensions="{nc} 4" NumberType="Int" Precision="8" Format="HDF">{h5}:/mesh/tetra'
                '</DataItem>\n    </Topology>\n    <Geometry GeometryType="XYZ">\n'
                f'     <DataItem Dimensions="{nv} 3" NumberType="Float" Precision="8" Format="HDF">{h5}:/mesh/points'
                '</DataItem>\n    </Geometry>')
        grids = []
        for i, t in enumerate(times):
            g = self.f.get(f"frames/{i}", {})
            attrs = [self._attribute(h5, "/mesh/region", "region", (nc,), "Cell", "Int")]
            for name in g:
                shape = g[name].shape
                attrs.append(self._attribute(h5, f"/frames/{i}/{name}", name, shape,
                                             "Node" if len(shape) == 2 else "Cell", "Float"))
            grids.append(f'   <Grid Name="frame{i}" GridType="Uniform">\n{mesh}\n    <Time Value="{t:.17g}"/>\n'
                         + "\n".join(attrs) + "\n   </Grid>")
        text = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n <Domain>\n'
                '  <Grid Name="hyperelastic" GridType="Collection" CollectionType="Temporal">\n'
                + "\n".join(grids) + "\n  </Grid>\n </Domain>\n</Xdmf>\n")
        tmp = self.xdmf + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, self.xdmf)

    @staticmethod
    def _attribute(h5, dset, name, shape, center, number):
        kind = "Vector" if len(shape) == 2 else "Scalar"
        dims = " ".join(map(str, shape))
        return (f'    <Attribute Name="{name}" AttributeType="{kind}" Center="{center}">\n'
                f'     <DataItem Dimensions="{dims}" NumberType="{number}" Precision="8" Format="HDF">{h5}:{dset}'
                '</DataItem>\n    </Attribute>')
