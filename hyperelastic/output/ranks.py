"""-output_layout ranks (the default on several ranks): every rank writes its own part of each frame to its own HDF5
file, and FILE.h5 presents the parts as one output through HDF5 virtual datasets (VDS, HDF5 >= 1.10).

    FILE.h5                the file users open (rank 0 writes it): the run's attributes, `time`, `stats/*`,
                           checkpoint attributes, and virtual datasets with the gathered layout's names and shapes:
                           mesh/points, mesh/tetra, mesh/region, x, frames/<i>/<field>, checkpoint/<slot>/<array>,
                           plus mesh/input_index (nv,) and mesh/cell_input_index (nc,)
    FILE.h5.d/TAG_rNNNNN.h5 rank N's part of a run (TAG: the run's or the restart's own): its rows of mesh/* (the first
                           part only), x and series/<field> (its frames, from the part's first), checkpoint/<slot>/*

The virtual datasets' node and cell order is the partition's (the ranks' owned nodes one rank after another, the
PETSc global vectors' order), not the input mesh's: mesh/input_index gives the input index of each row, and
mesh/tetra refers to the rows. A run restarted on another rank count keeps the file's order: each rank then writes a
contiguous block of it, its rows sent there by an exchange (discretization/exchange.py).

Rank 0's part of a frame is metadata only, and it does not grow with the rank count either: each field is a series
in every rank file (series/<field>: frames x rows, grown a frame at a time as x is), which FILE.h5 presents as one
virtual dataset series/<field> made once per part (one mapping per rank and part, unlimited in frames, as x); a
frame's frames/<i>/<field> is a virtual dataset of one mapping, row i of FILE.h5's own series/<field> (a virtual
dataset whose source is a virtual dataset of the same file: HDF5 resolves both). Outputs written before the series
(parts without "series") keep their frames' per-rank mappings, copied as they are into a restart's FILE.h5.
Its cost does not grow with the mesh. Crash safety as the gathered layout's: every file has its end-of-file reserve
(writer.Guard) and compact groups; a frame's virtual datasets are made after every rank has flushed its part, and
its time after them, so a frame is counted (files.completed_frames) only when it is whole in every file."""
import json
import os
import time

import h5py
import numpy as np
from h5py import h5d, h5p, h5s, h5t

from ..core.errors import UserError
from ..core.files import RANKS, parts, rank_file, rank_file_names
from ..discretization.exchange import Exchange
from .fields import cell_fields, cell_quantities, finish, is_point_field, needs_volumes, reference_volumes
from .writer import (EVENTS, FIELD_LINKS, FRAME_LINKS, ROOM_ATTR, ROOM_ATTR_BYTES, STATS_EVERY_S, Guard, Writer,
                     _compact_group, resumed_attrs, room_for, trim)

MESH = (("points", 3, "node", np.float64), ("input_index", 1, "node", np.int64), ("tetra", None, "cell", np.int64),
        ("region", 1, "cell", np.int64), ("cell_input_index", 1, "cell", np.int64))
FILL = {np.dtype(np.float64): np.nan, np.dtype(np.int64): -1}
SERIES_FRAMES = 2 ** 31 - 1   # the stored extent of FILE.h5's series/<field> in frames (virtual_series)


def _tail(width):
    return () if width == 1 else (width,)


def virtual(group, name, pieces, tail, dtype=np.float64, **attrs):
    """A virtual dataset `name` in `group`: the pieces [(file relative to the group's file, dataset, rows)]
    one after another along the first axis (tail: the rows' shape); unmapped or unreadable rows read as FILL."""
    dtype = np.dtype(dtype)
    n = sum(rows for _, _, rows in pieces)
    dcpl = h5p.create(h5p.DATASET_CREATE)
    dcpl.set_fill_value(np.array(FILL[dtype], dtype))
    space = h5s.create_simple((n,) + tail)
    at = 0
    for path, dset, rows in pieces:
        if rows:
            vs = h5s.create_simple((n,) + tail)
            vs.select_hyperslab((at,) + (0,) * len(tail), (rows,) + tail)
            src = h5s.create_simple((rows,) + tail)
            dcpl.set_virtual(vs, path.encode(), dset.encode(), src)
        at += rows
    if name in group:
        del group[name]
    h5d.create(group.id, name.encode(), h5t.py_create(dtype), space, dcpl=dcpl)
    for k, v in attrs.items():
        group[name].attrs[k] = v


def _frame_mappings(dcpl, parts, dset, n, tail, center):
    """Map into dcpl, for a dataset (frames, n) + tail, part p's rank files' rows of `dset` (frames from the part's
    first, rows `center`'s: nodes or cells) at frames first_p ... (up to the next part's first; the last part's
    unlimited, so that the dataset grows as its ranks extend their files); returns the frames the earlier parts'
    mappings reach (the dataset's least extent)."""
    U = h5s.UNLIMITED
    zeros, ones = (0,) * len(tail), (1,) * len(tail)
    fixed = 0
    for p, part in enumerate(parts):
        last = p == len(parts) - 1
        # (an earlier part's frames end where any later part's begin: a restart from an older checkpoint)
        frames = None if last else min(q["first"] for q in parts[p + 1:]) - part["first"]
        if frames is not None and frames <= 0:
            continue
        fixed = max(fixed, part["first"] + (frames or 0))
        at = 0
        for path, rows in zip(part["files"], part["nodes" if center == "node" else "cells"]):
            if rows:
                vs = h5s.create_simple((0, n) + tail, (U, n) + tail)
                src = h5s.create_simple((0, rows) + tail, (U, rows) + tail)
                count = U if last else frames
                vs.select_hyperslab((part["first"], at) + zeros, (count, 1) + ones, (1, 1) + ones, (1, rows) + tail)
                src.select_hyperslab((0, 0) + zeros, (count, 1) + ones, (1, 1) + ones, (1, rows) + tail)
                dcpl.set_virtual(vs, path.encode(), dset.encode(), src)
            at += rows
    return fixed


def virtual_x(f, parts, nv):
    """mesh x (frames, nv, 3): the parts' rank files' x (_frame_mappings)."""
    dcpl = h5p.create(h5p.DATASET_CREATE)
    dcpl.set_fill_value(np.array(np.nan))
    fixed = _frame_mappings(dcpl, parts, "x", nv, (3,), "node")
    if "x" in f:
        del f["x"]
    U = h5s.UNLIMITED
    h5d.create(f.id, b"x", h5t.NATIVE_DOUBLE, h5s.create_simple((fixed, nv, 3), (U, nv, 3)), dcpl=dcpl)


def virtual_series(f, parts, name, n, tail, dtype, center):
    """FILE.h5's series/<name> (frames, n) + tail: the parts' rank files' series/<name> (_frame_mappings), made once
    per part and field (a frame names it through frame_view). Only the parts that write series (part["series"]); an
    earlier part's frames have their own datasets."""
    dtype = np.dtype(dtype)
    dcpl = h5p.create(h5p.DATASET_CREATE)
    dcpl.set_fill_value(np.array(FILL[dtype], dtype))
    fixed = _frame_mappings(dcpl, [q for q in parts if q.get("series")], f"series/{name}", n, tuple(tail), center)
    g = f.require_group("series")
    if name in g:
        del g[name]
    # its stored extent: SERIES_FRAMES, not the frames written. A reader that opens series/<name> itself gets the
    # extent its sources have (HDF5's last-available view), but a frame's one-mapping view reads it as a source at
    # its stored extent, which rank 0 cannot bring up to date (the extent would open the rank files, which their
    # ranks hold open for writing): stored as 0, every frame read as fill values
    U = h5s.UNLIMITED
    h5d.create(g.id, name.encode(), h5t.py_create(dtype),
               h5s.create_simple((max(fixed, SERIES_FRAMES), n) + tuple(tail), (U, n) + tuple(tail)), dcpl=dcpl)
    g[name].attrs["center"] = center


def frame_view(group, name, n, tail, i):
    """group/<name>: frame i of FILE.h5's series/<name> ((frames, n) + tail), a virtual dataset of one mapping to
    row i of it. (Nothing of the series is read here: its extent would open the rank files, which their ranks hold
    open for writing.)"""
    dcpl = h5p.create(h5p.DATASET_CREATE)
    dcpl.set_fill_value(np.array(np.nan))
    U = h5s.UNLIMITED
    src = h5s.create_simple((i + 1, n) + tail, (U, n) + tail)
    src.select_hyperslab((i, 0) + (0,) * len(tail), (1, n) + tail)
    vs = h5s.create_simple((n,) + tail)
    dcpl.set_virtual(vs, b".", f"series/{name}".encode(), src)
    if name in group:
        del group[name]
    h5d.create(group.id, name.encode(), h5t.NATIVE_DOUBLE, vs, dcpl=dcpl)


def copy_virtual(src, dst_group, name):
    """A virtual dataset of another file made again in dst_group with the same mappings (the files it maps to are
    named relative to the file that holds it: both files lie in one directory)."""
    d = src.id
    h5d.create(dst_group.id, name.encode(), d.get_type(), d.get_space(), dcpl=d.get_create_plist())
    for k, v in src.attrs.items():
        dst_group[name].attrs[k] = v


class RankWriter(Writer):
    """The writer of -output_layout ranks (see the module's text): the same interface as Writer."""
    layout = "ranks"

    def __init__(self, path, space, attrs, resume=None, kernels=None, region=None, fields=()):
        self._common(path, space, kernels, fields)
        mpi = self.mpi = space.mpi
        here = os.path.dirname(os.path.abspath(path))
        # the part's own name: its start, and 8 random hex digits (two runs of one process in one second differ)
        self.tag = mpi.bcast(f"{time.strftime('%Y%m%d-%H%M%S')}-{os.urandom(4).hex()}" if self.root else None, root=0)
        names = [os.path.join(os.path.basename(path) + RANKS, rank_file(self.tag, r)) for r in range(mpi.size)]
        self.rank_path = os.path.join(here, names[mpi.rank])
        self.nv, self.nc = space.nv_total, space.nc_total
        self._rows = {"node": self.nv, "cell": self.nc}      # the file's rows by a field's center
        self._volume = None
        self._slot = -1
        node_keys, cell_keys = space.orig[space.owned], space.cell_orig
        self._nodes = self._cells = None          # the exchanges to the file's order (None: the ranks' own rows)
        old = None
        if resume is None:
            first = 0
            counts = (space.n_owned, space.nc)
        else:
            old = mpi.bcast(self._old_parts() if self.root else None, root=0)
            first = self.nframes = int(resume["nframes"])
            self.nstats = int(resume["nstats"])
            self._slot = old["slot"]
            counts = self._blocks(old, node_keys, cell_keys)
        nodes, cells = (np.array(mpi.allgather(c)) for c in counts)
        self.part = {"tag": self.tag, "files": names, "nodes": nodes.tolist(), "cells": cells.tolist(), "first": first,
                     "series": True}
        self._series = set()              # (rank 0) the fields whose series/<field> FILE.h5 maps for this part
        self._series_ds = {}              # this rank file's series/<field> datasets
        self.parts = (old["parts"] if old else []) + [self.part]
        self._make_dir(here, path)
        mesh = None if resume is not None else self._mesh_rows(region)
        need = sum(a.nbytes for a in mesh.values()) if mesh else 0
        self._ensure_room(lambda: need + 65536, "the mesh" if mesh else "a copy of the checkpoint's file")
        self.rf = h5py.File(self.rank_path, "w")
        rf = self.rf
        for k, a in (mesh or {}).items():
            rf.create_dataset(f"mesh/{k}", data=a)
        n = self.part["nodes"][mpi.rank]
        rf.create_dataset("x", shape=(0, n, 3), maxshape=(None, n, 3), dtype=np.float64, chunks=(1, max(n, 1), 3),
                          fillvalue=np.nan)
        _compact_group(rf, "frames", FRAME_LINKS)
        ck = rf.create_group("checkpoint")
        for slot in (0, 1):
            _compact_group(ck, str(slot), FIELD_LINKS)
        rf.attrs.update({"rank": mpi.rank, "ranks": mpi.size, "part": self.tag, "first_frame": first})
        self.rh5 = Guard(rf)
        self._written = 0                 # frames in this rank's file
        mpi.Barrier()                     # (every rank file exists before the virtual datasets name them)
        if self.root:
            self.f = self._new_master(attrs) if resume is None else self._copy_master(attrs, old)
            self.h5 = Guard(self.f)

    # --- set-up ------------------------------------------------------------------------------
    def _make_dir(self, here, path):
        err = None
        if self.root:
            try:
                os.makedirs(os.path.join(here, os.path.basename(path) + RANKS), exist_ok=True)
            except OSError as e:
                err = f"output '{path}': cannot create its ranks' directory ({e.strerror})"
        err = self.mpi.bcast(err, root=0)
        if err:
            raise UserError(err)

    def _mesh_rows(self, region):
        """This rank's rows of mesh/*: its owned nodes and its cells (their nodes by their rows in the file)."""
        sp = self.space
        g = sp.node_global()
        reg = np.zeros(sp.nc, np.int64) if region is None else np.asarray(region, np.int64)
        return {"points": np.ascontiguousarray(sp.X[sp.owned]), "input_index": sp.orig[sp.owned].astype(np.int64),
                "tetra": g[sp.input_cells()].astype(np.int64), "region": reg, "cell_input_index": sp.cell_orig.astype(np.int64)}

    def _old_parts(self):
        """(rank 0) What the checkpoint's file says of its parts and checkpoint."""
        with h5py.File(self.final, "r") as src:
            return {"parts": parts(src), "slot": int(src.attrs["checkpoint_slot"])}

    def _blocks(self, old, node_keys, cell_keys):
        """A restart: this rank's block of the file's node and cell order (part 0's blocks on its rank count, else
        even ones), and the exchanges that bring the rows there."""
        mpi = self.mpi
        first = old["parts"][0]
        if len(first["nodes"]) == mpi.size:
            nb, cb = np.cumsum([0] + first["nodes"]), np.cumsum([0] + first["cells"])
            (nlo, nhi), (clo, chi) = nb[mpi.rank:mpi.rank + 2], cb[mpi.rank:mpi.rank + 2]
        else:
            nlo, nhi = self.nv * mpi.rank // mpi.size, self.nv * (mpi.rank + 1) // mpi.size
            clo, chi = self.nc * mpi.rank // mpi.size, self.nc * (mpi.rank + 1) // mpi.size
        with h5py.File(self.final, "r") as src:
            want_n = src["mesh/input_index"][nlo:nhi]
            want_c = src["mesh/cell_input_index"][clo:chi]
        self._nodes = Exchange(mpi, node_keys, want_n, self.nv)
        self._cells = Exchange(mpi, cell_keys, want_c, self.nc)
        if self._nodes.missing or self._cells.missing:
            raise UserError(f"--restart '{self.final}': its mesh/input_index does not cover this run's mesh")
        self._nodes = None if self._nodes.identity else self._nodes
        self._cells = None if self._cells.identity else self._cells
        return int(nhi - nlo), int(chi - clo)

    def _pieces(self, dset, center, part=None):
        part = part or self.part
        return list(zip(part["files"], [dset] * len(part["files"]), part["nodes" if center == "node" else "cells"]))

    def _new_master(self, attrs):
        f = h5py.File(self.path, "w")
        npc = self.space.cells.shape[1]
        mesh = f.create_group("mesh")
        for name, width, center, dtype in MESH:
            virtual(mesh, name, self._pieces(f"mesh/{name}", center), _tail(npc if width is None else width), dtype)
        self._master_common(f, attrs)
        return f

    def _master_common(self, f, attrs):
        f.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,), fillvalue=np.nan)
        virtual_x(f, self.parts, self.nv)
        if "stats" not in f:
            f.create_group("stats")
        _compact_group(f, "frames", FRAME_LINKS)
        ck = f.require_group("checkpoint")
        for slot in (0, 1):
            _compact_group(ck, str(slot), FIELD_LINKS)
        for k, v in attrs.items():
            f.attrs[k] = v
        f.attrs["output_layout"] = self.layout
        f.attrs["parts"] = json.dumps(self.parts)
        if "checkpoint_slot" not in f.attrs:
            f.attrs["checkpoint_slot"] = -1
        f.attrs[ROOM_ATTR] = np.zeros(ROOM_ATTR_BYTES, np.uint8)

    def _copy_master(self, attrs, old):
        """(rank 0) A restart's new FILE.h5 (partial until its first step): the checkpoint's frames, statistics rows
        and checkpoint, mapping to the earlier parts' files, which are not touched."""
        with h5py.File(self.final, "r") as src:
            keep = resumed_attrs(src.attrs, attrs, ("failure", "interrupted", "checkpoint_slot", ROOM_ATTR, "parts"))
            f = h5py.File(self.path, "w")
            mesh = f.create_group("mesh")
            for name in src["mesh"]:
                copy_virtual(src[f"mesh/{name}"], mesh, name)
            n = self.nframes
            self._master_common(f, keep)
            for name, d in src.get("series", {}).items():     # (the earlier parts' series, which their frames name)
                center = d.attrs["center"]
                virtual_series(f, self.parts, name, self._rows[center], d.shape[2:], d.dtype, center)
            f["time"].resize((n,))
            f["time"][:] = src["time"][:n]
            for i in range(n):
                g = _compact_group(f["frames"], str(i), FIELD_LINKS)
                for k, d in src[f"frames/{i}"].items():
                    copy_virtual(d, g, k)
            for k, d in src["stats"].items():
                f["stats"].create_dataset(k, data=d[:self.nstats], maxshape=(None,), chunks=(256,),
                                          fillvalue=0 if d.dtype.kind == "i" else np.nan)
            slot = old["slot"]
            g, h = src[f"checkpoint/{slot}"], f[f"checkpoint/{slot}"]
            for k, d in g.items():
                copy_virtual(d, h, k)
            for k, v in g.attrs.items():
                h.attrs[k] = v
            f.attrs.modify("checkpoint_slot", slot)
        return f

    # --- frames and checkpoints --------------------------------------------------------------
    def _node_rows(self, a):
        a = np.ascontiguousarray(a)
        return a if self._nodes is None else self._nodes.move(a)

    def _cell_rows(self, a):
        a = np.ascontiguousarray(a)
        return a if self._cells is None else self._cells.move(a)

    def _owned(self, local, width=3):
        sp = self.space
        return np.asarray(local).reshape(sp.nlv, -1)[sp.owned].reshape((-1,) + _tail(width))

    def _volumes(self):
        if self._volume is None:
            self._volume = reference_volumes(self.space.X, self.space.cells)
        return self._volume

    def frame(self, t, x_local, v_local=None):
        """Frame at time t (collective): every rank writes its rows to its file, then rank 0 the frame's virtual
        datasets and its time."""
        sp = self.space
        x = self._owned(x_local)
        nodes = {}
        if "displacement" in self.fields:
            nodes["displacement"] = x - sp.X[sp.owned]
        if v_local is not None and "velocity" in self.fields:
            nodes["velocity"] = self._owned(v_local)
        cells = {}
        scalars = self.point_scalars(x_local) if self.point_scalars is not None else {}
        if self.kernels is not None:
            EVENTS.Fields.begin()
            local = cell_fields(self.kernels, x_local, cell_quantities(self.fields))
            nodal = needs_volumes(self.fields)          # (the volumes weigh nodal averages)
            done = finish(local, self.fields, sp.cells, self._volumes() if nodal else None, scalars.get("pressure"),
                          total=lambda a, n: sp.sum_owned(a, n))
            EVENTS.Fields.end()
            for k, a in done.items():
                (nodes if is_point_field(k) else cells)[k] = a
        for k, a in scalars.items():
            nodes[k] = self._owned(a, 1)
        rows = {"x": self._node_rows(x)}
        rows.update({f"frames/{self.nframes}/{k}": self._node_rows(a) for k, a in nodes.items()})
        rows.update({f"frames/{self.nframes}/{k}": self._cell_rows(a) for k, a in cells.items()})
        nbytes = sum(a.nbytes for a in rows.values()) + 16384
        self._ensure_room(lambda: nbytes, f"frame {self.nframes}")
        self._write_rows(rows)
        shapes = [(k, a.shape[1:], "node" if k in nodes else "cell") for k, a in
                  [(k.rsplit("/", 1)[1], a) for k, a in rows.items() if k != "x"]]
        self.mpi.Barrier()            # (every rank's part is flushed before the frame's virtual datasets name it)

        def write():
            new = sum(1 for name, _, _ in shapes if name not in self._series)
            self._reserve(4096 * (1 + len(shapes)) + 64 * self.mpi.size * len(self.parts) * new)
            self._write_frame(t, shapes)
        if not self.root:
            self.nframes += 1
        self._root_part(write)

    def _write_rows(self, rows):
        EVENTS.RankPart.begin()
        try:
            self._write_rank_rows(rows)
        finally:
            EVENTS.RankPart.end()

    def _write_rank_rows(self, rows):
        rf = self.rf
        self.rh5.reserve(sum(a.nbytes for a in rows.values()) + 16384)
        for k, a in rows.items():
            if k == "x":
                j = self._written
                rf["x"].resize((j + 1,) + rf["x"].shape[1:])
                rf["x"][j] = a
                self._written += 1
                continue
            group, name = k.rsplit("/", 1)
            if group.startswith("frames/"):        # a frame's field: row (frame - the part's first) of its series
                self._append_series(rf, name, int(group.split("/")[1]) - self.part["first"], a)
                continue
            g = _compact_group(rf[group.rsplit("/", 1)[0]], group.rsplit("/", 1)[1], FIELD_LINKS)
            if name in g:
                del g[name]
            g.create_dataset(name, data=a)
        rf.flush()

    def _append_series(self, rf, name, row, a):
        """Row `row` of this rank file's series/<name> = a (made at its first row; rows before it read as fill)."""
        d = self._series_ds.get(name)
        if d is None:
            g = rf.require_group("series")
            d = self._series_ds[name] = g.create_dataset(
                name, shape=(0,) + a.shape, maxshape=(None,) + a.shape, dtype=a.dtype,
                chunks=(1, max(a.shape[0], 1)) + a.shape[1:], fillvalue=FILL.get(np.dtype(a.dtype), 0))
        if d.shape[1:] != a.shape:
            raise RuntimeError(f"output field {name}: its rows changed shape from {d.shape[1:]} to {a.shape}")
        if d.shape[0] <= row:
            d.resize(row + 1, axis=0)
        if a.size:
            d.write_direct(np.ascontiguousarray(a), dest_sel=np.s_[row])

    def _write_frame(self, t, shapes):
        """(rank 0) Frame i's virtual datasets (one mapping each, to FILE.h5's series), a flush, then its time and a
        flush."""
        f = self.f
        i = self.nframes
        g = _compact_group(f["frames"], str(i), FIELD_LINKS)
        for k in list(g):
            del g[k]
        for name, tail, center in shapes:
            if name not in self._series:              # (once per part and field: one mapping per rank)
                virtual_series(f, self.parts, name, self._rows[center], tuple(tail), np.float64, center)
                self._series.add(name)
            frame_view(g, name, self._rows[center], tuple(tail), i)
        self.nframes += 1
        if time.monotonic() - self._stats_flushed >= STATS_EVERY_S:
            self._flush_stats()
        f.flush()
        f["time"].resize((i + 1,))
        f["time"][i] = t
        f.flush()
        if self.committed:
            self._append_xdmf(i, t, sorted((k, (self._rows[c],) + tuple(tail)) for k, tail, c in shapes))

    def checkpoint(self, x_local, v_local, nodal=None, cells=None, **state):
        """The full state into checkpoint/<slot> of every rank's file, then (rank 0) the slot's virtual datasets
        and attributes, and last the root attribute checkpoint_slot that names it. Collective."""
        slot = 1 if self._slot == 0 else 0
        arrays = {"x": self._node_rows(self._owned(x_local)), "v": self._node_rows(self._owned(v_local))}
        arrays.update({k: self._node_rows(self._owned(a, 1)) for k, a in (nodal or {}).items()})
        arrays.update({k: self._cell_rows(a) for k, a in (cells or {}).items()})
        nbytes = sum(a.nbytes for a in arrays.values()) + 16384
        self._ensure_room(lambda: nbytes, "a checkpoint")
        self._write_rows({f"checkpoint/{slot}/{k}": a for k, a in arrays.items()})
        self.mpi.Barrier()

        def write():
            self._reserve(8192 + 64 * self.mpi.size * len(arrays))
            self._write_checkpoint(slot, state, [(k, a.shape[1:], "cell" if k in (cells or {}) else "node")
                                                 for k, a in arrays.items()])
        self._root_part(write)
        self._slot = slot

    def _write_checkpoint(self, slot, state, arrays):
        """(rank 0) The slot's virtual datasets (made once per part and slot), its attributes, checkpoint_slot."""
        f = self.f
        self._flush_stats()
        g = f[f"checkpoint/{slot}"]
        for name, tail, center in arrays:
            if name not in g or g[name].attrs.get("part") != self.tag:     # (made once per part and slot)
                virtual(g, name, self._pieces(f"checkpoint/{slot}/{name}", center), tail, part=self.tag)
        self._complete_checkpoint(g, slot, state)

    def _ensure_room(self, nbytes, what):
        """UserError on every rank unless every rank can write nbytes() more to its file (and rank 0 to FILE.h5)."""
        size = self.rf.id.get_filesize() if getattr(self, "rf", None) is not None else None
        why = room_for(self.rank_path, nbytes(), size=size)
        if why is None and self.root:
            why = room_for(self.path, 65536 + 64 * self.mpi.size * 16,
                           size=self.f.id.get_filesize() if self.f is not None else None)
        whys = self.mpi.allgather(why)
        why = next((w for w in whys if w), None)
        if why:
            held = f"it holds frames 0..{self.nframes - 1}" if self.nframes else "it holds no frame"
            raise UserError(f"output '{self.final}': no room for {what} ({why}); {held}")

    # --- the end -----------------------------------------------------------------------------
    def _rank_files(self):
        return rank_file_names(self.parts)

    def close(self, keep=True):
        """Flush and close every file (collective). A run that completed no step and is not kept leaves no file of
        its own (its rank files are removed with its partial FILE.h5)."""
        if getattr(self, "rf", None) is not None:
            self.rh5.reserve(65536)
            self.rf.flush()
            self.rf.close()
            self.rf = None
            if self.rh5.on:
                trim(self.rank_path)
        self.mpi.Barrier()
        super().close(keep)
        committed = self.mpi.bcast(self.committed, root=0)
        if not committed and os.path.exists(self.rank_path):
            os.remove(self.rank_path)
