"""Thesis Fig. 4 (sec. 7), run for real: the squeeze scene with every Jacobian mode, and the corrected
conclusion end to end: for which (E, h) does MFFD-Newton reproduce the exact tangent's trajectory?

Every run is a `hyperelastic run` subprocess; a run that stops (exit 3) is recorded with its error
line and the frames it wrote, never dropped.
"""
import os

import h5py
import numpy as np

from ...solving import stats
from ..experiments.recipes import MODES as JACOBIAN_MODES
from ..experiments.runner import last_line, run_hyperelastic
from ...output.plot import boundary_faces, draw
from ...output.figures import pyplot
from .common import outdir, write_csv

MODES = {m: JACOBIAN_MODES[m] for m in ("assembled", "shell", "snes_mf", "snes_mf_operator", "seed_fd")}


def run(scene, path, args):
    """One thesis run: fixed step size as in the thesis' framework (no step control), so a failing
    step ends the run as it did there."""
    args = ["-step_control", "0", *args]
    rc, err, wall = run_hyperelastic(["run", scene, "-output", path, "-quiet", *args], path, timeout=None)
    res = {"exit": rc, "error": last_line(err, rc) if rc else "", "wall_s": wall,
           "command": " ".join(["hyperelastic", "run", scene, *map(str, args)])}
    res.update(x=None, t=float("nan"), newton=0, ksp=0, J_min=float("nan"), steps=0)
    try:
        with h5py.File(path, "r") as f:
            res.update(X=f["mesh/points"][:], tets=f["mesh/tetra"][:], x=f["x"][-1], t=float(f["time"][-1]),
                       steps=int(f.attrs.get("steps_completed", 0)))
            st = stats.read(f)
            col = {k: st[k] for k in ("newton_its", "ksp_its", "J_min") if k in st and len(st[k])}
    except (OSError, KeyError, IndexError):
        return res
    res.update(newton=int(np.nansum(col.get("newton_its", 0))), ksp=int(np.nansum(col.get("ksp_its", 0))))
    if "J_min" in col and np.isfinite(col["J_min"]).any():
        res["J_min"] = float(np.nanmin(col["J_min"]))
    return res


def figure4(out, level, final_time, material, modes=tuple(MODES), solver=()):
    """Squeeze on mesh `level` for `final_time` s with each mode; distances to the assembled run."""
    rows, runs = [], {}
    for mode in modes:
        path = os.path.join(out, "runs", f"fig4_{material}_L{level}_{mode}.h5")
        runs[mode] = r = run("squeeze", path, ["-level", level, "-final_time", final_time, "-material", material,
                                              *solver, *MODES[mode]])
        ref = runs.get("assembled")
        same_t = ref is not None and r["x"] is not None and ref["x"] is not None and abs(r["t"] - ref["t"]) < 1e-12
        dist = float(np.linalg.norm(r["x"] - ref["x"], axis=1).max()) if same_t else float("nan")
        disp = float(np.linalg.norm(r["x"] - r["X"], axis=1).max()) if r["x"] is not None else float("nan")
        rows.append({"material": material, "level": level, "mode": mode, "finished": int(r["exit"] == 0),
                     "t_reached": r["t"], "final_time": final_time, "steps": r["steps"], "newton_its": r["newton"],
                     "ksp_its": r["ksp"], "J_min": r["J_min"], "max_displacement": disp,
                     "max_distance_to_assembled": dist, "wall_s": r["wall_s"], "error": r["error"],
                     "command": r["command"]})
        print(f"  {material} L{level} {mode:17s} {'finished' if r['exit'] == 0 else 'STOPPED '} t = {r['t']:.3g} "
              f"newton {r['newton']:5d} ksp {r['ksp']:6d} max|x - x_assembled| {dist:.3g} m  {r['wall_s']:.1f} s"
              + (f"\n      {r['error']}" if r["error"] else ""))
    _plot_shapes(runs, os.path.join(out, f"fig4_squeeze_{material}_L{level}.png"), material, level)
    return rows


def _plot_shapes(runs, path, material, level):
    plt = pyplot()
    modes = [m for m in runs if runs[m]["x"] is not None]
    fig = plt.figure(figsize=(3.6 * len(modes), 3.8))
    any_run = runs[modes[0]]
    tri = boundary_faces(any_run["tets"])
    top = max(np.linalg.norm(runs[m]["x"] - runs[m]["X"], axis=1).max() for m in modes)
    norm = plt.Normalize(0, max(top, 1e-300))
    for i, m in enumerate(modes):
        r = runs[m]
        ax = fig.add_subplot(1, len(modes), i + 1, projection="3d")
        draw(ax, r["X"], r["x"], tri, norm)
        state = "finished" if r["exit"] == 0 else "stopped"
        ax.set_title(f"{m}\n{state} at t = {r['t']:.3g} s", fontsize=9)
    fig.suptitle(f"squeeze, {material}, L{level}: final shapes (grey: reference)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# (label, options) of the stiffness sweep: default rho 1000 except steel's preset
STIFFNESS = [("E=1e2", ["-E", "1e2"]), ("E=1e6", ["-E", "1e6"]), ("steel E=2.1e11", ["-preset", "steel"]),
             ("E=1e15", ["-E", "1e15"])]


NEWTON_STEPS = (1e-2, 1e-3)     # the Newton table's step sizes (repro_fig4.py --newton_steps)


def newton_table(out, level, final_time, steps=NEWTON_STEPS, scene="stretch",
                 modes=("assembled", "snes_mf_operator", "snes_mf", "seed_fd")):
    """Final-state distance of each mode to the assembled run, relative to the largest displacement."""
    rows = []
    for label, opts in STIFFNESS:
        for h in steps:
            ref = None
            for mode in modes:
                tag = f"{scene}_{label.split()[-1]}_h{h:g}_{mode}".replace("=", "")
                r = run(scene, os.path.join(out, "runs", tag + ".h5"),
                        ["-level", level, "-final_time", final_time, "-dt", h, *opts, *MODES[mode]])
                if mode == "assembled":
                    ref = r
                ok = r["exit"] == 0 and ref is not None and ref["exit"] == 0
                disp = float(np.linalg.norm(ref["x"] - ref["X"], axis=1).max()) if ok else float("nan")
                rel = float(np.linalg.norm(r["x"] - ref["x"], axis=1).max() / disp) if ok else float("nan")
                rows.append({"scene": scene, "material_case": label, "h": h, "mode": mode, "finished": int(r["exit"] == 0),
                             "t_reached": r["t"], "newton_its": r["newton"], "ksp_its": r["ksp"],
                             "rel_distance_to_assembled": rel, "wall_s": r["wall_s"], "error": r["error"]})
                print(f"  {label:15s} h={h:<6g} {mode:17s} {'finished' if r['exit'] == 0 else 'STOPPED '} "
                      f"newton {r['newton']:4d} ksp {r['ksp']:6d} rel. distance {rel:.2e}"
                      + (f"  [{r['error']}]" if r["error"] else ""))
    return rows


def main(args):
    out = outdir(args.output_dir)
    os.makedirs(os.path.join(out, "runs"), exist_ok=True)
    level = args.fig4_level or (5 if args.full else 1)
    T = args.final_time or (1.5 if args.full else 0.3)
    print(f"Fig. 4: squeeze on L{level} for {T:g} s with every Jacobian mode")
    rows = []
    for material, solver in (("neohookean", ()), ("stvk", ())):
        rows += figure4(out, level, T, material, solver=solver)
    write_csv(os.path.join(out, "fig4_squeeze.csv"), rows)
    lvl = 3 if args.full else 1
    Tn = 0.1 if args.full else 0.03
    print(f"MFFD-Newton vs the exact tangent: stretch on L{lvl} for {Tn:g} s")
    write_csv(os.path.join(out, "newton_vs_E_h.csv"), newton_table(out, lvl, Tn, tuple(args.newton_steps)))
    print(f"wrote {out}")
