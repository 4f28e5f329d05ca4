"""hyperelastic report FILE.h5: what a run's output holds, printed again — how the run went, the forces table
of its end (reactions, load resultants, their sum), and on request the displacement and the cell fields at
material points of a frame and the quantities `study refinement --watch` takes. Reads only; writes nothing."""
import json
import os
from dataclasses import replace

import numpy as np

from ..solving import stats
from ..core.errors import ArgParser, UserError
from ..core.files import cell_blocks, completed_frames, open_output, read_rows
from ..solving.forces import table
from ..mesh.read import deepest, interpolate
from ..physics.effects.seams import SELF_STATUS
from .curves import curves, list_lines
from .watch import HELP as WATCH_HELP, parse_watch, point3, watched


def main(argv):
    ap = ArgParser(prog="hyperelastic report", description="Print what an output file holds: the run, its "
                   "forces, and values at material points.")
    ap.add_argument("file", help="an output FILE.h5 of hyperelastic run")
    ap.add_argument("--frame", type=int, default=None, help="the frame of --at and --forces (default: the last; -2 the "
                    "one before, ...)")
    ap.add_argument("--at", action="append", default=[], metavar="X,Y,Z",
                    help="a material point (reference coordinates): its displacement and its cell's fields")
    ap.add_argument("--watch", action="append", default=[], metavar="Q", help=f"a quantity: {WATCH_HELP}")
    ap.add_argument("--forces", action="store_true", help="the forces table at the time of --frame (from the "
                    "statistics: quasi-static runs record every step's, dynamic runs those of -step_forces)")
    ap.add_argument("--contact", action="store_true", help="per obstacle at --frame: its force on the body, contact "
                    "area, peak contact pressure, the contact patch's extent along x, y, z, and its translation")
    ap.add_argument("--curve", action="append", default=[], metavar="X,Y",
                    help="write Y against X as FILE_X_Y.csv and .png (beside FILE, or in --out): two quantities of "
                    "--list (statistics columns: a point per accepted step) or watched quantities (a point per frame)")
    ap.add_argument("--list", action="store_true", help="the quantities --curve takes from this file")
    ap.add_argument("--out", default=None, metavar="DIR", help="where --curve writes (default: FILE's folder)")
    a = ap.parse_args(argv)
    if a.list or a.curve:
        if a.out is not None and not os.path.isdir(a.out):
            raise UserError(f"report: --out '{a.out}' is not a directory")
        lines = list_lines(a.file) if a.list else []
        for line in lines + (curves(a.file, a.curve, a.out) if a.curve else []):
            print(line)
        if not (a.at or a.watch or a.forces or a.contact):
            return 0
    points = [_point(s) for s in a.at]
    watches = [parse_watch(w) for w in a.watch]
    if a.frame is not None and any(w.when is not None for w in watches):
        raise UserError("report: --frame and a --watch at a time (@T or @max): give the time once, in the watch or "
                        "as --frame")
    for line in report(a.file, a.frame, points, watches, a.forces, a.contact):
        print(line)
    return 0


def _point(spec):
    p = point3(spec)
    if p is None:
        raise UserError(f"report: --at {spec}: give three finite coordinates X,Y,Z")
    return p


def report(path, frame, points, watches, forces=False, contact=False):
    """The report's lines (UserError for a file that is not a readable output or a frame it lacks: --frame is
    checked whether or not --at or --forces read it)."""
    with open_output(path, "report") as f:
        n = completed_frames(f)
        lines = [_summary(path, f, n)]
        given = frame is not None
        frame = -1 if frame is None else frame
        if given and not -n <= frame < n:
            raise UserError(f"report: --frame {frame} out of range ({f'0..{n - 1}' if n else 'the file has no frames'})")
        i_frame = frame % n if given else None
        frame_time = float(f["time"][i_frame]) if given else None
        if "forces" in f.attrs and not forces:
            rec = json.loads(f.attrs["forces"])
            lines += table([(r["kind"], r["name"], np.array(r["F"]), np.array(r["M"])) for r in rec["forces"]],
                           rec["t"], holds(f))
        if points or forces or contact:
            if n == 0:
                raise UserError(f"report: '{path}' has no frames")
            i = frame if frame >= 0 else n + frame
            if not 0 <= i < n:
                raise UserError(f"report: --frame {frame} out of range (0..{n - 1})")
            if forces:
                lines += _forces_at(f, float(f["time"][i]), i)
            if contact:
                lines += contact_lines(f, i)
            lines += [_at(f, i, p) for p in points]
    for w in watches:
        if given:                         # (--frame N: the watch at that frame's time)
            w = replace(w, when=frame_time)
        lines.append(f"{w.spec} = {watched(path, w):.9g}" + (f" (frame {i_frame}, t = {frame_time:.12g})" if given
                                                                 else ""))
    return lines


def _forces_at(f, t, i):
    """The forces table of the accepted step that ends at frame i's time t (the statistics' columns)."""
    st = stats.read(f)
    acc = stats.accepted_at(st, t)
    rows = stats.forces_of(st, acc[-1]) if len(acc) else []
    if not rows:
        why = "its start (t = 0)" if i == 0 else f"t = {t:.6g} ({_no_forces(f, st)})"
        raise UserError(f"report: --forces: the statistics record no forces at frame {i}, {why}")
    return table(rows, t, holds(f))


def holds(f):
    """{surface: the components it holds} from the output's `forces` attribute (written at a run's end; {} without)."""
    if "forces" not in f.attrs:
        return {}
    return {r["name"]: r["holds"] for r in json.loads(f.attrs["forces"])["forces"] if "holds" in r}


def contact_lines(f, i):
    """Per obstacle at frame i: its force on the body and contact area (the statistics of the accepted step that ends
    at the frame's time; 0 at the start), the peak contact pressure and the contact patch's extent along x, y, z (the
    frame's positions of the nodes whose contact_status is that obstacle: within dhat of it), and its translation.
    Then self-contact (a run with -contact_self or a triangulated obstacle), where its pairs carried force at some
    step: the force they carry, their area, the peak pressure and extent of the nodes in such a pair alone, and the
    sum of their forces (it balances: a check)."""
    st = stats.read(f)
    names = sorted({k[:-len("_area")] for k in st if k.startswith("obstacle") and k.endswith("_area")},
                   key=lambda s: int(s[len("obstacle"):] or 0))
    own = "self_carried" in st and bool(np.nan_to_num(st["self_carried"]).any())
    g = f[f"frames/{i}"]
    if not (names or own) or "contact_status" not in g:
        raise UserError("report: --contact: the run wrote no contact results (no -obstacle or self-contact pairs among "
                        "its effects, or an output of a version before 0.2.0)")
    t = float(f["time"][i])
    acc = stats.accepted_at(st, t)
    texts = _obstacle_texts(f)
    status, pressure, x = g["contact_status"][:], g["contact_pressure"][:], f["x"][i]
    lines = [f"contact at t = {t:.12g} (frame {i}; forces in N, areas in m^2 of the reference surface, pressures in "
             "Pa, lengths in m):"]

    def col(name, q):
        return float(st[f"{name}_{q}"][acc[-1]]) if len(acc) else 0.0

    def patch(on):
        peak = float(pressure[on].max()) if on.any() else 0.0
        ext = x[on].max(axis=0) - x[on].min(axis=0) if on.any() else np.zeros(3)
        return (f"peak pressure {peak:.6g}, {int(on.sum())} nodes in contact, patch extent "
                f"({ext[0]:.6g}, {ext[1]:.6g}, {ext[2]:.6g})")
    for name in names:
        k = int(name[len("obstacle"):])
        text = f" {texts[k - 1]}" if k <= len(texts) else ""
        lines.append(f"  {name}{text}: F = ({col(name, 'Fx'):.6g}, {col(name, 'Fy'):.6g}, {col(name, 'Fz'):.6g}), "
                     f"area {col(name, 'area'):.6g}, {patch(status == k)}, moved by ({col(name, 'ux'):.6g}, "
                     f"{col(name, 'uy'):.6g}, {col(name, 'uz'):.6g})")
    if own:
        lines.append(f"  self-contact (the surface against itself): carries {col('self', 'carried'):.6g}, area "
                     f"{col('self', 'area'):.6g}, {patch(status == SELF_STATUS)}; its forces sum to "
                     f"({col('self', 'Fx'):.3g}, {col('self', 'Fy'):.3g}, {col('self', 'Fz'):.3g})")
    return lines


def _obstacle_texts(f):
    """The -obstacle items of the run's recorded options, in order ([] where none is recorded)."""
    for line in str(f.attrs.get("options", "")).splitlines():
        if line.startswith("-obstacle "):
            return [t.strip() for t in line[len("-obstacle "):].split(";") if t.strip()]
    return []


def _no_forces(f, st):
    """Why a run's statistics hold no forces: its integrator, -step_forces off, or an older file."""
    if str(f.attrs.get("integrator", "")) == "ts":
        return "-integrator ts records none"
    if not any(k.startswith(("reaction_", "load_")) for k in st):
        return "the run did not record them: -step_forces is off by default for dynamic runs; rerun with -step_forces"
    return "no accepted step ends there"


def _summary(path, f, n):
    a = f.attrs
    t = float(f["time"][n - 1]) if n else float("nan")
    steps = a.get("steps_completed", None)
    how = ("failed: " + str(a["failure"]) if "failure" in a else "interrupted: " + str(a["interrupted"])
           if "interrupted" in a else "finished" if steps is not None else "did not finish (killed?)")
    scene = a.get("scene", "?")
    extra = f", formulation {a['formulation']}" if "formulation" in a else ""
    tets = f["mesh/tetra"]
    return (f"{path}: scene {scene}, {tets.shape[0]} tets ({'quadratic' if tets.shape[1] == 10 else 'linear'})"
            f"{extra}; {n} frames to t = {t:.6g}; {steps if steps is not None else '?'} steps; {how}")


def locate_in(f, p):
    """(cell, barycentric weights, the cell's nodes (their rows)) of material point p in an open output, going
    through its cells a block at a time (files.cell_blocks: one rank's part of a per-rank output): one process never
    holds the whole mesh. UserError when p lies outside it."""
    best = None
    for lo, hi in cell_blocks(f):
        T = f["mesh/tetra"][lo:hi]
        rows, local = np.unique(T, return_inverse=True)
        local = local.reshape(T.shape)
        c, bary = deepest(read_rows(f["mesh/points"], rows), local[:, :4], p)
        if best is None or bary.min() > best[1].min():
            best = (lo + c, bary, rows[local[c]])
        if bary.min() >= 0:
            break
    if best is None or best[1].min() < -1e-9:
        raise UserError(f"material point ({', '.join(f'{v:g}' for v in p)}) lies outside the mesh")
    return best


def _at(f, i, p):
    """One line: the displacement at material point p in frame i, the other point fields interpolated there (the
    mixed formulation's pressure: the mean stress, positive in tension; Abaqus' pressure is its negative), and its
    cell's fields. Reads the mesh a block of cells at a time and then only the rows of p's cell."""
    try:
        c, w, nodes = locate_in(f, p)
    except UserError as e:
        raise UserError(f"report: --at {','.join(f'{v:g}' for v in p)}: {e}") from None
    order = np.argsort(nodes)
    cell = np.empty(len(nodes), np.int64)
    cell[order] = np.arange(len(nodes))
    sorted_rows = nodes[order]

    def at_nodes(d, frame=None):        # the cell's nodes' values, in the cell's node order
        return (d[sorted_rows] if frame is None else d[frame, sorted_rows])[cell]
    one, w = np.arange(len(nodes))[None], w[None]       # the cell alone, its nodes 0..k-1 in its own order
    u = interpolate(one, [0], w, at_nodes(f["x"], i) - at_nodes(f["mesh/points"]))[0]
    words = [f"at ({', '.join(f'{v:g}' for v in p)}), frame {i} (t = {f['time'][i]:.6g}): "
             f"u = ({u[0]:.6g}, {u[1]:.6g}, {u[2]:.6g}), |u| = {np.linalg.norm(u):.6g}"]
    g = f.get(f"frames/{i}", {})
    nv, nc = f["mesh/points"].shape[0], f["mesh/tetra"].shape[0]
    for name in sorted(g):
        d = g[name]
        if d.shape[0] == nv and name not in ("displacement", "velocity") and d.ndim == 1:   # a point field
            v = float(interpolate(one, [0], w, at_nodes(d))[0])
            sign = " (mean stress, positive in tension; Abaqus' pressure is -p)" if name == "pressure" else ""
            words.append(f"{name} {v:.6g}{sign}")
    for name in sorted(g):
        d = g[name]
        if d.shape[0] == nc:          # a cell field: its value in the cell holding the point
            v = np.atleast_1d(d[c])
            words.append(f"{name} " + (f"{v[0]:.6g}" if v.size == 1 else "(" + ", ".join(f"{x:.6g}" for x in v) + ")"))
    return "; ".join(words)
