"""The accuracy study's measurements: each run launched as a child process, its cost and
trajectory read back, its error against its configuration's reference; the rows' CSV."""
import math
import os
from dataclasses import asdict, replace

import h5py
import numpy as np

from ..solving import stats
from .experiments.runner import last_line, parallel_map, run_hyperelastic
from .experiments.table import read_csv as _read_table, write_csv as _write_table
from ..mesh.read import interpolate, locate
from .plan import MATERIAL_POINTS, plan, with_references

def launch(run, out_dir, timeout=1800):
    d = os.path.join(out_dir, "runs")
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, run.id + ".h5")
    rc, err, wall = run_hyperelastic(run.args(path), path, timeout=timeout)
    row = asdict(run) | {"id": run.id, "rc": rc, "wall_s": wall, "message": "", "path": path}
    if rc != 0:
        row["message"] = last_line(err, rc)
    row.update(read_cost(path))
    ok = rc == 0 and row.get("t_end") is not None and abs(row["t_end"] - run.final_time) < 1e-9
    row["outcome"] = "failed" if not ok else ("recovered" if row.get("rejections") else "finished")
    if rc == 0 and not ok:
        row["message"] = row["message"] or f"ended at t={row.get('t_end')} instead of {run.final_time}"
    return row


def read_cost(path):
    if not os.path.exists(path):
        return {}
    try:
        with h5py.File(path, "r") as f:
            st = stats.read(f)
            times = f["time"][:]
            rss = float(f.attrs.get("peak_rss_mb", float("nan")))
            tets = int(f["mesh/tetra"].shape[0])
    except OSError:
        return {}
    n = len(st.get("step", []))
    if not n:
        return {"t_end": float(times[-1]) if len(times) else None, "peak_rss_mb": rss, "tets": tets}
    acc = stats.accepted(st)
    return {"t_end": float(times[-1]) if len(times) else None, "solve_s": float(st["wall_s"].sum()),
            "steps": int(acc.sum()), "rejections": int((~acc).sum()), "newton_its": int(st["newton_its"].sum()),
            "ksp_its": int(st["ksp_its"].sum()), "residual_evals": int(st["residual_evals"].sum()),
            "peak_rss_mb": rss, "tets": tets}


def trajectory(path):
    """(times, frames (F,nv,3), reference points, tets, total energy at the accepted steps' ends)."""
    with h5py.File(path, "r") as f:
        tot = stats.total_energy(stats.read(f))
        return f["time"][:], f["x"][:], f["mesh/points"][:], f["mesh/tetra"][:], tot


def errors(path, ref_path):
    """The error columns of a run against a reference run on the same mesh (see the module doc)."""
    t, x, X, _, en = trajectory(path)
    tr, xr, Xr, _, enr = trajectory(ref_path)
    if X.shape != Xr.shape:
        raise ValueError(f"{path}: not the reference's mesh")
    scale = float(np.linalg.norm(xr - Xr, axis=2).max())
    pairs = [(i, j) for i, ti in enumerate(t) for j, tj in enumerate(tr) if abs(ti - tj) < 1e-9 and ti > 0]
    if not pairs:
        raise ValueError(f"{path}: no frame at a time of the reference's")
    d = np.stack([np.linalg.norm(x[i] - xr[j], axis=1) for i, j in pairs])      # (frames, nv)
    escale = float(np.abs(enr).max()) or 1.0
    return {"err_final_max": float(d[-1].max()), "err_final_rms": float(np.sqrt((d[-1] ** 2).mean())),
            "err_traj_max": float(d.max()), "err_traj_rms": float(np.sqrt((d ** 2).mean())),
            "rel_err": float(d.max()) / scale if scale > 0 else float("nan"),
            "energy_drift": float((en[-1] - enr[-1]) / escale), "ref_displacement": scale}


def at_points(path, P=MATERIAL_POINTS):
    """Displacement (k,3) at material points P in the last frame of a run."""
    _, x, X, tets, _ = trajectory(path)
    cells, w = locate(X, tets, P)
    return interpolate(tets, cells, w, x[-1] - X)


CSV_COLUMNS = ("id", "role", "scene", "material", "E", "level", "order", "mode", "pc", "h", "snes_rtol", "ksp_rtol",
               "ts_rtol", "final_time", "outcome", "rc", "message", "rel_err", "err_final_max", "err_final_rms", "err_traj_max",
               "err_traj_rms", "energy_drift", "ref_displacement", "solve_s", "wall_s", "steps", "rejections",
               "newton_its", "ksp_its", "residual_evals", "peak_rss_mb", "tets", "disc_err", "disc_level", "ref_err_est")


def accuracy(out_dir, full=False, jobs=2, log=None):
    """Run the study; returns (rows, plan)."""
    p = plan(full)
    refs, extra = with_references(p)
    first = parallel_map(lambda r: launch(r, out_dir), extra, jobs, log)   # references first: the longest
    rows = parallel_map(lambda r: launch(r, out_dir), p.runs, jobs, log)
    rows = first + rows
    analyse_accuracy(rows, refs)
    return rows, p


def analyse_accuracy(rows, refs):
    """Fill in each row's error columns from the run files (in place)."""
    by_id = {r["id"]: r for r in rows}
    ref_row = {cfg: by_id[ref.id] for cfg, ref in refs.items()}
    disc = {}
    for r in rows:
        if r["role"] == "disc" and r["outcome"] != "failed":
            disc.setdefault((r["scene"], r["material"], r["E"]), []).append(r)
    for group in disc.values():        # each level's mesh error against the finest level's (quadratic) run
        fine = max(group, key=lambda r: (r["level"], r.get("order", 1)))
        uf = at_points(fine["path"])
        for r in group:
            r["disc_err"] = float(np.linalg.norm(at_points(r["path"]) - uf, axis=1).max()
                                  / np.linalg.norm(uf, axis=1).max())
            r["disc_level"] = fine["level"]
    for r in rows:
        cfg = (r["scene"], r["material"], r["E"], r["level"])
        ref = ref_row.get(cfg)
        if r["outcome"] == "failed" or ref is None or ref["outcome"] == "failed" or r["role"] in ("disc", "check"):
            continue
        if r["role"] == "disc":
            continue
        if r["role"] == "reference":
            check = by_id[replace(refs[cfg], h=refs[cfg].h * 2, role="check").id]
            if check["outcome"] != "failed":
                # second order (generalized-alpha): x_2h - x = 4 (x_h - x), so e(h) ~ |x_2h - x_h| / 3
                r["ref_err_est"] = errors(r["path"], check["path"])["rel_err"] / 3.0
        r.update(errors(r["path"], ref["path"]))


def slope(x, y):
    """Least-squares slope of log y against log x (nan with fewer than two positive points)."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(x, y) if a > 0 and b > 0]
    if len(pts) < 2:
        return float("nan")
    return float(np.polyfit(*zip(*pts), 1)[0])


def write_csv(rows, path):
    _write_table(path, rows, CSV_COLUMNS)


INT_COLS = {"level", "order", "rc", "steps", "rejections", "newton_its", "ksp_its", "residual_evals", "tets", "disc_level"}
STR_COLS = {"id", "role", "scene", "material", "mode", "pc", "outcome", "message", "path"}


def _int(v):
    return int(float(v))


def read_csv(path):
    """The rows of an accuracy.csv with their types (to redo the report)."""
    return _read_table(path, {c: (_int if c in INT_COLS else float) for c in CSV_COLUMNS if c not in STR_COLS})
