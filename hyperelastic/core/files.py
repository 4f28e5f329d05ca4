"""Files of this application's outputs, below every other module that touches them: what an output file
is (its names, the datasets it always holds), the checks an output path passes before any work is done
(mesh generation and runs alike), and reading a checkpoint back (before PETSc is initialized: no module
here imports it)."""
import json
import os
import re
import shlex

import h5py
import numpy as np

from .errors import UserError


def writable_dir(d, who):
    """Create directory d if needed; UserError naming `who` unless it can be written to."""
    if not os.path.isdir(d):
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as e:
            raise UserError(f"{who}: cannot create directory '{d}' ({e.strerror})") from None
    if not os.access(d, os.W_OK):
        raise UserError(f"{who}: directory '{d}' is not writable")


MAX_OPTION_LINE = 10_000      # characters of a line of an options file (a path is at most 4,096)


def option_lines(text, where):
    """[(line number, key without its '-', value or None)] of a PETSc options file's text: one
    `-option [value]` per line, `#` comments. UserError naming `where` and the line for anything else —
    PETSc itself prints a multi-line error for some (two options on a line), keeps others as options no
    one reads (`--name`) and skips the rest."""
    out = []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if len(line) > MAX_OPTION_LINE:     # (shlex takes time quadratic in a token's length: 76 s for 1 MB)
            raise UserError(f"{where} line {lineno}: {len(line):,} characters (at most {MAX_OPTION_LINE:,} for an "
                            f"option and its value): '{line[:40]}...'")
        try:
            toks = shlex.split(line)
        except ValueError as e:
            raise UserError(f"{where} line {lineno}: {e}") from None
        if toks[0].startswith("--"):
            raise UserError(f"{where} line {lineno}: '{toks[0][:40]}': an option starts with one '-'")
        if not toks[0].startswith("-") or toks[0] == "-" or len(toks) > 2:
            raise UserError(f"{where} line {lineno}: expected one '-option [value]' per line, got '{line[:80]}'")
        out.append((lineno, toks[0][1:], toks[1] if len(toks) == 2 else None))
    return out


# options that take a PETSc viewer, `[type]:FILE[:format]` (-log_view, -ksp_view, -snes_monitor, ...)
VIEWERS = re.compile(r"(?:^|_)(?:view|monitor|converged_reason|log_trace)(?:_|$)")
# what a restart does not replay of the recorded options: the viewers (what the first part printed or wrote: a
# replayed -log_view :FILE overwrote its profile), and where the command line gives another -mesh, the recorded
# mesh's recipe (a replayed -refine 2 built 10.5M tets of the new mesh before a vertex count refused it: issue 73)
MESH_RECIPE = ("level", "refine", "mesh_frame")


def replayed(recorded, given):
    """(options to replay, [the recorded options left out, as text]) of a restart: `recorded` [(key, value)] of the
    file's options (less -output), `given` the command line's keys."""
    out, left = [], []
    for key, val in recorded:
        if VIEWERS.search(key) or (key in MESH_RECIPE and "mesh" in given):
            left.append(f"-{key} {val}".rstrip())
        else:
            out.append((key, val))
    return out, left


PARTIAL = ".partial"      # a run writes FILE.h5.partial until it has completed a step (Writer._commit)
# an earlier output of the run's name (FILE.h5 and FILE.xdmf), moved aside to FILE.h5.earlier and FILE.xdmf.earlier
# when the run completes its first step: removed when the run ends, put back when it fails (Writer.close)
EARLIER = ".earlier"


def failed_path(path):
    """Where a run that fails after its first step leaves its own output when it puts an earlier one back:
    FILE.failed.h5 (its XDMF beside it, FILE.failed.xdmf)."""
    stem, ext = os.path.splitext(path)
    return stem + ".failed" + ext


RANKS = ".d"            # FILE.h5.d/: the per-rank files of a run written with -output_layout ranks (output/ranks.py)
RANK_FILE = re.compile(r"_r\d{5}\.h5$")       # what such a file's name ends in (rank_file)


def rank_file(tag, rank):
    """The name of rank `rank`'s file of the output part `tag`, in FILE.h5.d/."""
    return f"{tag}_r{rank:05d}.h5"


def parts(f):
    """The parts of an open per-rank output ([{tag, files, nodes, cells, first}], output/ranks.py), None for a
    gathered one."""
    return json.loads(f.attrs["parts"]) if "parts" in f.attrs else None


def output_names(path):
    """The files an output path stands for: the HDF5 file, the XDMF beside it, the partial file, the earlier
    output's while it is aside and a failed run's pair."""
    xdmf, failed = os.path.splitext(path)[0] + ".xdmf", failed_path(path)
    return [path, xdmf, path + PARTIAL, path + EARLIER, xdmf + EARLIER, failed, os.path.splitext(failed)[0] + ".xdmf"]


def rank_file_names(parts_list):
    """The names of the per-rank files (in FILE.h5.d/) of an output's parts (`parts`)."""
    return {os.path.basename(p) for part in parts_list for p in part["files"]}


def named_rank_files(path):
    """The names of the per-rank files (in its FILE.h5.d/) that the output at `path` names: none where it is a
    gathered output, or not there, or not readable."""
    try:
        with h5py.File(path, "r") as f:
            return rank_file_names(parts(f) or [])
    except (OSError, ValueError, KeyError, TypeError):
        return set()


class StateRows:
    """A checkpoint array of an output file, not read yet: every rank reads a slice of it when the run is restarted
    (discretization/space.py: Space.read_state), whatever the rank count that wrote it. path, the dataset `name`,
    its row count n and width (3, or 1 for a scalar per node), and `keys`: the dataset holding each row's input
    index (the per-rank layout's mesh/input_index), None where the rows are in input order."""

    def __init__(self, path, name, n, width, keys=None):
        self.path, self.name, self.n, self.width, self.keys = path, name, n, width, keys

    def __len__(self):
        return self.n

    def read(self, lo, hi):
        """(rows lo..hi-1, their input indices)."""
        with h5py.File(self.path, "r") as f:
            rows = np.asarray(f[self.name][lo:hi], np.float64)
            keys = np.asarray(f[self.keys][lo:hi], np.int64) if self.keys else np.arange(lo, hi, dtype=np.int64)
        return rows, keys


OUTPUT_DATASETS = ("mesh/points", "mesh/tetra", "time", "x")     # what every output of `hyperelastic run` holds


def missing_datasets(f, more=()):
    """The datasets of OUTPUT_DATASETS (and `more`) that the open HDF5 file f lacks."""
    return [k for k in OUTPUT_DATASETS + tuple(more) if k not in f]


def require_parts(f, path, where):
    """UserError `where: ...` when a per-rank file that the open output f (at `path`) names is not there: its
    virtual datasets would read their fill values."""
    here = os.path.dirname(os.path.abspath(path))
    for part in parts(f) or []:
        for name in part["files"]:
            folder = os.path.dirname(name)
            if not os.path.isfile(os.path.join(here, name)):
                f.close()
                renamed = (f"; it was written as '{folder[:-len(RANKS)]}': a renamed output keeps its folder's name"
                           if folder != os.path.basename(path) + RANKS else "")
                raise UserError(f"{where}: written per rank, and its file '{name}' is missing (keep {folder}/ beside "
                                f"it{renamed})")
            try:
                with h5py.File(os.path.join(here, name), "r") as piece:
                    _check_piece(piece, part, name)
            except (OSError, KeyError, ValueError) as e:
                f.close()
                why = "truncated" if "truncated" in str(e) else " ".join(str(e).split())[:200]
                raise UserError(f"{where}: written per rank, and its file '{name}' cannot be read ({why}: a damaged "
                                "or partly copied output)") from None


def _check_piece(piece, part, name):
    """A per-rank file's mesh rows are the part's: its points and cells as many as the part says (ValueError)."""
    k = part["files"].index(name)
    for dset, n in (("mesh/points", part["nodes"][k]), ("mesh/tetra", part["cells"][k])):
        if dset in piece and piece[dset].shape[0] != n:
            raise ValueError(f"{dset} has {piece[dset].shape[0]} rows, the output says {n}")


def open_output(path, who):
    """The output file `path` open for reading (h5py.File); UserError, worded for command `who`, when it is not
    a regular file, not HDF5, or not an output of hyperelastic."""
    if not os.path.isfile(path):
        raise UserError(f"{who}: '{path}' " + ("is not a regular file" if os.path.exists(path) else "does not exist"))
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise UserError(f"{who}: cannot open '{path}' as HDF5 ({str(e).split('(')[0].strip()})") from None
    missing = missing_datasets(f)
    if missing:
        f.close()
        raise UserError(f"{who}: '{path}' is not an output of hyperelastic (no {', '.join(missing)})")
    require_parts(f, path, f"{who}: '{path}'")
    return f


def completed_frames(f):
    """The number of complete frames in an open output file. The writer writes a frame's time last, in a flush
    of its own, after the frame's positions and fields are in (output.Writer._write_frame): after a kill -9, x
    may hold one row more than time, and a time extended before its data reached the file reads NaN, its fill
    value. A closed run's file has len(time) frames."""
    t = f["time"]
    n = min(t.shape[0], f["x"].shape[0])
    while n and not np.isfinite(t[n - 1]):
        n -= 1
    return n


def input_order(f):
    """(node rows, cell rows) that put an open output's arrays in the input mesh's order: a[nodes] is in input
    node order; slice(None) for both where they are already (the gathered layout). A per-rank output's mesh/tetra
    refers to its own rows: input_index[tetra[cells]] is the input mesh's cells."""
    if "mesh/input_index" not in f:
        return slice(None), slice(None)
    return np.argsort(f["mesh/input_index"][:]), np.argsort(f["mesh/cell_input_index"][:])


BLOCK = 1 << 20          # rows read at a time by the readers that go through an output in blocks


def cell_blocks(f, most=None):
    """[(lo, hi)] contiguous ranges of an open output's cells, each at most `most` long: within one rank's part in a
    per-rank output (its cells refer to few rows beyond its own), plain ranges in a gathered one."""
    nc, most = f["mesh/tetra"].shape[0], most or BLOCK
    ends = np.cumsum([0] + parts(f)[0]["cells"]) if parts(f) else np.array([0, nc])
    out = []
    for lo, hi in zip(ends[:-1], ends[1:]):
        out += [(int(a), int(min(a + most, hi))) for a in range(int(lo), int(hi), most)]
    return out


def read_rows(d, rows, frame=None, window=None):
    """d[rows] (or d[frame, rows]) of a dataset for sorted unique rows, read a window of rows at a time: memory for
    the rows asked and one window, not for the whole dataset."""
    rows, window = np.asarray(rows, np.int64), window or BLOCK
    shape = d.shape[1:] if frame is None else d.shape[2:]
    out = np.empty((len(rows),) + shape, d.dtype)
    n = d.shape[0] if frame is None else d.shape[1]
    for lo in range(0, n, window):
        a, b = np.searchsorted(rows, [lo, lo + window])
        if b > a:
            block = d[lo:lo + window] if frame is None else d[frame, lo:lo + window]
            out[a:b] = block[rows[a:b] - lo]
    return out


def is_output(path):
    """Whether `path` is an output file of `hyperelastic run` (HDF5 with OUTPUT_DATASETS)."""
    if not os.path.isfile(path):
        return False
    try:
        with h5py.File(path, "r") as f:
            return not missing_datasets(f)
    except (OSError, ValueError):
        return False


def check_output_path(path, inputs=(), suffixes=(".h5", ".hdf5")):
    """Raise UserError unless `path` can be written without touching an input (checked before any work
    is done). The name must end in .h5 or .hdf5, so that the XDMF beside it never is the HDF5 file;
    neither may be (or be the data of) an input file: the mesh, the scene or an options file."""
    if not path:
        raise UserError("output '': an empty file name")
    if os.path.isdir(path):
        raise UserError(f"output '{path}' is a directory")
    if os.path.lexists(path) and not os.path.isfile(path):
        raise UserError(f"output '{path}': exists and is not a regular file (not replacing it)")
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
    if os.path.lexists(path + RANKS) and not os.path.isdir(path + RANKS):     # (the per-rank layout's files)
        raise UserError(f"output '{path}': '{path + RANKS}' exists and is not a directory")
    if os.path.exists(path) and not is_output(path):
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


CHECKPOINT_ATTRS = ("t", "step", "n", "h_try", "streak", "rejections", "nframes", "nstats")
# where a checkpoint was written inside a nominal step (a stop on a signal between its attempts): that step's end,
# so that the restart keeps the nominal grid t_n = n dt; absent at a step's end
CHECKPOINT_OPTIONAL = ("t_end", "regrow_wait", "regrown")      # (step control's memory: see integrators.py)


# optional state of fixed length: a rigid face's reference point (its accepted motion and rate, physics/effects/rigid.py)
CHECKPOINT_VECTORS = {"rigid": 12}
CHECKPOINT_NODAL = ("pressure",)     # optional scalar state per node (the mixed formulation's pressure)
# optional state per cell, rows of any width (the viscoelastic effect's non-equilibrium stresses: Effect.cell_state)
CHECKPOINT_CELLS = ("viscoelastic",)


def read_checkpoint(path):
    """(state dict with x, v and CHECKPOINT_ATTRS, root attributes) of the last complete checkpoint
    in an output file; UserError when there is none."""
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
        require_parts(f, path, f"--restart '{path}'")
        slot = f.attrs.get("checkpoint_slot", -1)
        if slot < 0 or f"checkpoint/{slot}" not in f:
            raise UserError(f"--restart '{path}': holds no checkpoint (run with -checkpoint_every N)")
        g = f[f"checkpoint/{slot}"]
        bad = [k for k in ("x", "v") if k not in g] + [k for k in CHECKPOINT_ATTRS if k not in g.attrs]
        if bad:
            raise UserError(f"--restart '{path}': checkpoint {slot} is incomplete (no {', '.join(bad)})")
        nv = f["mesh/points"].shape[0]
        state = {"cell_nodes": int(f["mesh/tetra"].shape[1]) if "mesh/tetra" in f else 0,   # 4 or 10
                 "layout": str(f.attrs.get("output_layout", "gather"))}
        keys = "mesh/input_index" if "mesh/input_index" in f else None
        for k in ("x", "v"):
            a = g[k]
            if a.shape != (nv, 3) or a.dtype.kind != "f":
                raise UserError(f"--restart '{path}': checkpoint {k} has shape {a.shape} ({a.dtype}), the mesh "
                                f"needs ({nv}, 3) numbers")
            state[k] = StateRows(path, a.name, nv, 3, keys)     # (read in slices by every rank: non-finite
        for k in CHECKPOINT_NODAL:                                  # values are refused there)
            if k in g:
                a = g[k]
                if a.shape != (nv,) or a.dtype.kind != "f":
                    raise UserError(f"--restart '{path}': checkpoint {k} is not {nv} numbers")
                state[k] = StateRows(path, a.name, nv, 1, keys)
        ckeys = "mesh/cell_input_index" if "mesh/cell_input_index" in f else None
        nc = f["mesh/tetra"].shape[0] if "mesh/tetra" in f else 0
        for k in CHECKPOINT_CELLS:
            if k in g:
                a = g[k]
                if a.ndim != 2 or a.shape[0] != nc or a.dtype.kind != "f":
                    raise UserError(f"--restart '{path}': checkpoint {k} is not a row of numbers per cell ({nc})")
                state[k] = StateRows(path, a.name, nc, a.shape[1], ckeys)
        _checkpoint_numbers(f, g, path, state)
        attrs = {k: (v.item() if hasattr(v, "item") and getattr(v, "shape", None) == () else v)
                 for k, v in f.attrs.items()}
    return state, attrs


def _checkpoint_numbers(f, g, path, state):
    """state[k] for the checkpoint group g's scalar attributes (required and optional) and vectors, each checked:
    finite, of the right shape, within its range (UserError naming it otherwise)."""
    for k in CHECKPOINT_ATTRS:
        v = np.asarray(g.attrs[k])
        if v.shape != () or v.dtype.kind not in "iuf" or not np.isfinite(v):
            raise UserError(f"--restart '{path}': checkpoint attribute {k} = {v!r} is not a finite number")
        state[k] = v.item()
    for k in CHECKPOINT_OPTIONAL:
        if k in g.attrs:
            v = np.asarray(g.attrs[k])
            if v.shape != () or v.dtype.kind not in "iuf" or not np.isfinite(v) or v < 0 or (
                    k == "t_end" and v < state["t"]):
                raise UserError(f"--restart '{path}': checkpoint attribute {k} = {v!r} is out of range")
            state[k] = v.item()
    for k, n in CHECKPOINT_VECTORS.items():
        if k in g.attrs:
            v = np.asarray(g.attrs[k])
            if v.shape != (n,) or v.dtype.kind not in "iuf" or not np.isfinite(v).all():
                raise UserError(f"--restart '{path}': checkpoint attribute {k} is not {n} finite numbers")
            state[k] = v.astype(float)
    nstats = min((f["stats"][k].shape[0] for k in f["stats"]), default=0)
    limits = {"t": (0, None), "step": (0, None), "n": (0, None), "h_try": (0, None), "streak": (0, None),
              "rejections": (0, None), "nframes": (1, f["time"].shape[0]), "nstats": (0, nstats)}
    for k, (lo, hi) in limits.items():
        v = state[k]
        if v < lo or (k == "h_try" and v <= 0) or (hi is not None and v > hi):
            raise UserError(f"--restart '{path}': checkpoint attribute {k} = {v:g} is out of range "
                            f"({'> 0' if k == 'h_try' else f'{lo}..{hi}' if hi is not None else f'>= {lo}'})")
