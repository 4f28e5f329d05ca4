"""`report FILE.h5 --curve X,Y`: one quantity of a run against another, as a CSV and a PNG (issue 70 item 3: a
force-displacement curve without a script). A quantity is a statistics column (every accepted step: `time`, a
reaction `reaction_S_Fx`, a load `load_traction_Fz`, an obstacle's `obstacle1_ux` or `obstacle1_Fz`, an energy,
`newton_its`, ...; `report FILE.h5 --list` names the file's), or a watched quantity (`u_x:X,Y,Z`, `max_displacement`,
`von_mises:X,Y,Z`, ...: output/watch.py), read at every frame. A curve of two statistics columns has a point per
accepted step; one with a watched quantity a point per frame (the columns read at the step that ends there)."""
import csv
import os
import re
from dataclasses import replace

import numpy as np

from ..core.errors import UserError
from ..core.files import check_output_path, completed_frames, open_output
from ..solving import stats
from .figures import pyplot
from .watch import parse_watch, watched


def columns(f):
    """The statistics columns a curve may take: the float and int columns of accepted steps, `time` first."""
    st = stats.read(f)
    names = [k for k in st if k not in ("step", "rejected") and np.asarray(st[k]).dtype.kind in "fi"]
    return ["time"] + sorted(n for n in names if n != "time")


def list_lines(path):
    """`report --list`: the quantities a curve of this file can take."""
    with open_output(path, "report") as f:
        names = columns(f)
    return [f"{path}: quantities for --curve X,Y (statistics of every accepted step; or a watched quantity read at "
            "every frame: u_x:X,Y,Z, max_displacement[:S], von_mises:X,Y,Z, ...)"] + [f"  {n}" for n in names]


def _series(path, f, name, frame_times):
    """The values of quantity `name`: at the accepted steps (frame_times None), or at the frames' times."""
    st = stats.read(f)
    if name in columns(f):
        acc = np.flatnonzero(stats.accepted(st))
        if frame_times is None:
            return np.asarray(st[name], float)[acc]
        out = []
        for t in frame_times:
            at = stats.accepted_at(st, t)
            out.append(float(st[name][at[-1]]) if len(at) else (0.0 if t == 0 else float("nan")))
        return np.array(out)
    if frame_times is None:
        raise AssertionError("a watched quantity is read at the frames")
    w = parse_watch(name)
    return np.array([watched(path, replace(w, when=float(t))) for t in frame_times])


def _is_watch(f, name):
    if name in columns(f):
        return False
    try:
        parse_watch(name)
    except UserError:
        raise UserError(f"report: --curve: '{name}' is neither a statistics column of this file nor a watched "
                        "quantity (report FILE.h5 --list names them)") from None
    return True


def curves(path, specs, out_dir=None):
    """Write each --curve X,Y of `specs` as OUT_DIR/STEM_X_Y.csv and .png (out_dir: the output's own folder where
    None); every quantity is checked before anything is written. Returns the lines to print."""
    pairs = []
    for spec in specs:
        parts = spec.split(",") if spec.count(",") == 1 else _split_pair(spec)
        if len(parts) != 2 or not all(p.strip() for p in parts):
            raise UserError(f"report: --curve '{spec}': give two quantities X,Y (report FILE.h5 --list names them)")
        pairs.append(tuple(p.strip() for p in parts))
    out_dir = out_dir or os.path.dirname(os.path.abspath(path))
    stem = os.path.splitext(os.path.basename(path))[0]
    data = []
    with open_output(path, "report") as f:
        n = completed_frames(f)
        times = f["time"][:n]
        for x, y in pairs:
            per_frame = _is_watch(f, x) or _is_watch(f, y)
            at = times if per_frame else None
            data.append((x, y, _series(path, f, x, at), _series(path, f, y, at), "frame" if per_frame else "step"))
    lines = []
    for x, y, xs, ys, kind in data:
        base = os.path.join(out_dir, f"{stem}_{_safe(x)}_{_safe(y)}")
        for p in (base + ".csv", base + ".png"):
            check_output_path(p, [path], suffixes=())
        _write_csv(base + ".csv", x, y, xs, ys)
        _write_png(base + ".png", x, y, xs, ys, stem, kind)
        lines.append(f"wrote {base}.csv and .png ({len(xs)} points, one per {kind})")
    return lines


def _split_pair(spec):
    """X,Y where a watched quantity holds commas of its own (u_x:5,0,0): split after the first complete quantity."""
    m = re.fullmatch(r"(\w+(?::[^,]*(?:,[^,]*){2})?(?:@\S+?)?),(.+)", spec)
    return [m.group(1), m.group(2)] if m else [spec]


def _safe(name):
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", name).strip("-")


def _write_csv(path, x, y, xs, ys):
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([x, y])
        w.writerows(zip(map(repr, map(float, xs)), map(repr, map(float, ys))))
    os.replace(tmp, path)


def _write_png(path, x, y, xs, ys, title, kind):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(xs, ys, "o-", ms=3)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(f"{title}: {y} against {x} (one point per {kind})", fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        fig.savefig(tmp, dpi=100, format="png")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.remove(tmp)
