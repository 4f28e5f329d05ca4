"""What accuracy costs in time: `hyperelastic study accuracy` and `hyperelastic study refinement`.

Accuracy versus time. Each sweep point is a real `python -m hyperelastic run` (sweep.py) of one
*configuration* (scene, material, E, mesh level) with one *setting* (Jacobian mode, PC, Newton and
Krylov tolerances, time step h). Its error is measured against the configuration's *reference*: the
same scene and mesh run with h = h_min / REF_FACTOR (h_min the smallest h swept), the tightest
tolerances and the exact tangent (assembled; GMRES + ILU(0) to ksp_rtol 1e-12: as exact as LU here and
4x cheaper). The reference's own error is
estimated against a *check* run at twice its step: backward Euler is first order, so
e(h) ~ |x_2h - x_h|. Every run writes frames every 0.1 s; errors compare the frames at the same
times:

  err_final_max / err_final_rms   max / RMS over vertices of |x - x_ref| at the final time [m]
  err_traj_max / err_traj_rms     the same over every frame of the trajectory [m]
  rel_err                         err_traj_max / (largest vertex displacement of the reference)
  energy_drift                    (total energy - the reference's) at the final time / the reference's
                                  largest |total energy|; total = kinetic + elastic + gravity
                                  potential - traction work (negative: extra numerical dissipation)

Cost: solve time (the sum of the steps' wall time, rejected attempts included: what the setting
costs, without the process start-up), wall time of the whole command, Newton and Krylov iterations,
residual evaluations, rejected attempts, peak memory. A run that fails is a row with outcome
'failed' and its one-line message, never dropped.

The discretisation error is separate: runs with the reference's solver settings at one step DISC_H
on each level, against the finest level's, P1-interpolated at fixed material points
(MATERIAL_POINTS, the thesis framework's test point first). The time error at DISC_H is nearly the
same on every mesh, so the difference is the mesh's.

Refinement: a quasi-static ramped bend on gmsh levels L1...; displacement at the material points
against the finest level, observed convergence order (least-squares slope of log error vs log
edge length) and time per load step vs tets.
"""
import csv
import json
import math
import os
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .errors import UserError
from .stability import fmt
from .sweep import last_line, parallel_map, run_hyperelastic

# (4.5, 1.5, 1.5): the thesis framework's test point, near the loaded end; then the centre of the
# loaded end face and the middle of the bar's top edge
MATERIAL_POINTS = np.array([[4.5, 1.5, 1.5], [5.0, 0.0, 0.0], [0.0, 2.0, 2.0]])
POINT_NAMES = ("test point (4.5,1.5,1.5)", "tip (5,0,0)", "top edge (0,2,2)")

MODES = {   # Jacobian mode -> options (the PC is set separately; -snes_mf has none)
    "assembled": ["-jacobian", "assembled"],
    "shell": ["-jacobian", "shell"],
    "snes_mf": ["-snes_mf", "-mat_mffd_type", "wp"],
    "snes_mf_operator": ["-snes_mf_operator", "-jacobian", "assembled", "-mat_mffd_type", "wp", "-ksp_type", "gmres"],
    # the thesis' operator, with fixed steps as in its framework (step control would retry each of
    # its failures ten times at 50 Newton iterations each)
    "seed_fd": ["-jacobian", "seed_fd", "-step_control", "0"],
    # the reference: exact tangent, linear solves to 1e-12 (GMRES: twist's follower load is not symmetric)
    "reference": ["-jacobian", "assembled", "-ksp_type", "gmres", "-ksp_gmres_restart", "100"],
}
PCS = {"jacobi": ["-pc_type", "jacobi"], "bjacobi_icc": ["-pc_type", "bjacobi", "-sub_pc_type", "icc"],
       "gamg": ["-pc_type", "gamg", "-pc_gamg_type", "agg", "-pc_gamg_agg_nsmooths", "1",
                "-mg_levels_ksp_type", "chebyshev", "-mg_levels_pc_type", "jacobi"],
       "none": ["-pc_type", "none"], "ilu": ["-pc_type", "bjacobi", "-sub_pc_type", "ilu"]}
SCENE_EXTRA = {"sag": ["-preset", "steel"]}    # sag is run stiff: steel's E, nu and rho
REF_FACTOR = 4              # reference h = smallest swept h / REF_FACTOR
REF_SNES_RTOL, REF_SNES_ATOL = 1e-10, 1e-12
TARGETS = (1e-1, 1e-2, 1e-3, 1e-4)
COST_TARGET = 1e-2          # the target of the cost-vs-E figure
FPS = 10                    # frames every 0.1 s: every swept h divides it
E_NAMES = {1e6: "1e6", 1e7: "rubber", 1e8: "1e8", 4.52e8: "cancellous bone", 1.616e10: "bone", 2.1e11: "steel"}


@dataclass(frozen=True)
class Run:
    scene: str
    material: str
    E: float
    level: int
    mode: str
    pc: str
    h: float
    snes_rtol: float
    ksp_rtol: float = 1e-5
    role: str = "sweep"              # sweep | reference | check | disc
    final_time: float = 0.3

    @property
    def config(self):
        return (self.scene, self.material, self.E, self.level)

    @property
    def id(self):
        return (f"{self.scene}-{self.material}-E{self.E:g}-L{self.level}-{self.mode}-{self.pc}-h{self.h:g}"
                f"-r{self.snes_rtol:g}-k{self.ksp_rtol:g}-{self.role}")

    def args(self, out):
        a = ["run", self.scene, "-level", self.level, "-material", self.material]
        a += SCENE_EXTRA.get(self.scene, [])
        a += ["-E", repr(self.E), "-dt", repr(self.h), "-final_time", repr(self.final_time),
              "-frames_per_second", FPS, "-snes_rtol", repr(self.snes_rtol), "-ksp_rtol", repr(self.ksp_rtol),
              "-output", out, "-quiet"]
        if self.role != "sweep":
            a += ["-snes_atol", repr(REF_SNES_ATOL), "-snes_max_it", "100"]
        return a + MODES[self.mode] + PCS[self.pc]


def reference_of(run, h_min):
    return Run(run.scene, run.material, run.E, run.level, "reference", "ilu", h_min / REF_FACTOR, REF_SNES_RTOL,
               1e-12, "reference", run.final_time)


@dataclass
class Plan:
    """The sweep: runs grouped by configuration, plus what the report should headline."""
    runs: list
    final_time: float
    finest_level: int
    main: tuple = None               # the configuration of the Pareto headline
    notes: list = field(default_factory=list)


def _grid(scene, material, E, level, modes, pcs, hs, rtols, ksps=(1e-5,), T=0.3):
    return [Run(scene, material, E, level, m, ("none" if m == "snes_mf" else pc), h, r, k, final_time=T)
            for m in modes for pc in pcs for h in hs for r in rtols for k in ksps]


def plan(full=False):
    """The quick default (~2 min on 2 cores: bend2 and squeeze on L1/L2, St.VK and Neo-Hookean, E up
    to steel) or --full (four scenes, two materials, E up to steel, h 1e-1 ... 1e-4, L1-L3; hours)."""
    modes = ("assembled", "shell", "snes_mf", "snes_mf_operator", "seed_fd")
    if not full:
        T = 0.3
        hs, h4 = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002), (0.1, 0.05, 0.02, 0.01)
        main = ("bend2", "stvk", 1e6, 1)
        runs = _grid(*main, ("assembled",), ("jacobi",), hs, (1e-2, 1e-4, 1e-8), T=T)
        runs += _grid(*main, modes[1:], ("jacobi",), hs, (1e-6,), T=T)
        runs += _grid(*main, ("assembled",), ("bjacobi_icc", "gamg"), (0.05, 0.01, 0.002), (1e-6,), T=T)
        runs += _grid(*main, ("assembled",), ("jacobi",), (0.05, 0.01, 0.002), (1e-8,), (1e-2, 1e-8), T=T)
        runs += _grid("bend2", "stvk", 1e6, 2, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        for E in (1e8, 2.1e11):   # (MFFD at steel: ~10 s per run, so one h only)
            runs += _grid("bend2", "stvk", E, 1, ("assembled", "shell"), ("jacobi",), h4, (1e-6,), T=T)
            runs += _grid("bend2", "stvk", E, 1, ("snes_mf_operator",), ("jacobi",), (0.1,), (1e-6,), T=T)
        # at steel the motion is quasi-static and the time error tiny: there the tolerances matter
        runs += _grid("bend2", "stvk", 2.1e11, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-4, 1e-8), T=T)
        runs += _grid("bend2", "neohookean", 1e6, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        runs += _grid("squeeze", "stvk", 1e6, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        return Plan(list(dict.fromkeys(runs)), T, 3, main=main)
    T = 0.5
    hs = (1e-1, 5e-2, 2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 1e-4)
    rtols = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
    runs = []
    for scene in ("bend2", "squeeze", "twist", "sag"):
        for mat in ("stvk", "neohookean"):
            E0 = 2.1e11 if scene == "sag" else 1e6
            runs += _grid(scene, mat, E0, 1, modes, ("jacobi",), hs, rtols, T=T)
            runs += _grid(scene, mat, E0, 1, ("assembled",), ("bjacobi_icc", "gamg"), hs, (1e-6,), T=T)
            runs += _grid(scene, mat, E0, 1, ("assembled", "snes_mf"), ("jacobi",), hs, (1e-8,), (1e-2, 1e-8, 1e-10),
                          T=T)
            runs += _grid(scene, mat, E0, 2, ("assembled",), ("jacobi",), hs, rtols, T=T)
            runs += _grid(scene, mat, E0, 3, ("assembled", "snes_mf_operator"), ("jacobi", "gamg"), hs, (1e-6,), T=T)
            if scene != "sag":
                for E in (1e8, 4.52e8, 1.616e10, 2.1e11):
                    runs += _grid(scene, mat, E, 1, modes, ("jacobi",), hs, (1e-6,), T=T)
    return Plan(list(dict.fromkeys(runs)), T, 5, main=("bend2", "stvk", 1e6, 1))


DISC_H = 0.01       # time step of the discretisation-error runs (the same on every level)


def with_references(p):
    """(references by configuration, the extra runs): each configuration's reference and its check
    run (at twice the reference's step), and for each (scene, material, E) swept on more than one
    level or headlined, reference-setting runs at DISC_H on its levels and on the finest level."""
    by_cfg = {}
    for r in p.runs:
        by_cfg.setdefault(r.config, []).append(r)
    refs, extra = {}, []
    for cfg, rs in by_cfg.items():
        ref = reference_of(rs[0], min(r.h for r in rs))
        refs[cfg] = ref
        extra += [ref, replace(ref, h=ref.h * 2, role="check")]
    levels = {}
    for cfg in by_cfg:
        levels.setdefault(cfg[:3], set()).add(cfg[3])
    for key, lv in levels.items():
        if len(lv) > 1 or key == p.main[:3]:
            base = refs[next(c for c in by_cfg if c[:3] == key)]
            extra += [replace(base, level=L, h=DISC_H, role="disc") for L in sorted(lv | {p.finest_level})]
    return refs, extra


# ---- one run: launch and read back ------------------------------------------------------------------
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
    import h5py
    if not os.path.exists(path):
        return {}
    try:
        with h5py.File(path, "r") as f:
            st = {k: f["stats"][k][:] for k in f["stats"]}
            times = f["time"][:]
            rss = float(f.attrs.get("peak_rss_mb", float("nan")))
            tets = int(f["mesh/tetra"].shape[0])
    except OSError:
        return {}
    n = len(st.get("step", []))
    if not n:
        return {"t_end": float(times[-1]) if len(times) else None, "peak_rss_mb": rss, "tets": tets}
    rej = st["rejected"].astype(bool)
    return {"t_end": float(times[-1]) if len(times) else None, "solve_s": float(st["wall_s"].sum()),
            "steps": int((~rej).sum()), "rejections": int(rej.sum()), "newton_its": int(st["newton_its"].sum()),
            "ksp_its": int(st["ksp_its"].sum()), "residual_evals": int(st["residual_evals"].sum()),
            "peak_rss_mb": rss, "tets": tets}


def trajectory(path):
    """(times, frames (F,nv,3), reference points, tets, total energy at the accepted steps' ends)."""
    import h5py
    with h5py.File(path, "r") as f:
        st = f["stats"]
        acc = st["rejected"][:] == 0
        tot = st["kinetic"][:][acc] + st["elastic"][:][acc]
        if "gravity_potential" in st:
            tot = tot + st["gravity_potential"][:][acc]
        if "traction_work" in st:
            tot = tot - st["traction_work"][:][acc]
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
    from .mesh import interpolate, locate
    _, x, X, tets, _ = trajectory(path)
    cells, w = locate(X, tets, P)
    return interpolate(tets, cells, w, x[-1] - X)


# ---- the accuracy study -----------------------------------------------------------------------------
CSV_COLUMNS = ("id", "role", "scene", "material", "E", "level", "mode", "pc", "h", "snes_rtol", "ksp_rtol",
               "final_time", "outcome", "rc", "message", "rel_err", "err_final_max", "err_final_rms", "err_traj_max",
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
    for group in disc.values():        # each level's mesh error against the finest level's
        fine = max(group, key=lambda r: r["level"])
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
                r["ref_err_est"] = errors(r["path"], check["path"])["rel_err"]   # first order: e(h) ~ |x_2h - x_h|
        r.update(errors(r["path"], ref["path"]))


def pareto(points):
    """Indices of the Pareto front of (cost, error) pairs: no other point is cheaper and as accurate."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def label(r):
    pc = "" if r["pc"] in ("jacobi", "none", "ilu") else f"+{r['pc']}"
    ksp = f", ksp_rtol {r['ksp_rtol']:g}" if r["ksp_rtol"] != 1e-5 else ""
    return f"{r['mode']}{pc}, h={r['h']:g}, snes_rtol {r['snes_rtol']:g}{ksp}"


def cfg_name(cfg):
    scene, mat, E, level = cfg
    return f"L{level} {scene}, {mat}, E = {E:g} Pa" + (" (steel preset)" if scene == "sag" else "")


def sweep_rows(rows, cfg=None):
    return [r for r in rows if r["role"] == "sweep" and (cfg is None or
            (r["scene"], r["material"], r["E"], r["level"]) == cfg)]


def cheapest(rows, target, modes=None):
    ok = [r for r in rows if r["outcome"] != "failed" and r.get("rel_err") is not None
          and r["rel_err"] <= target and (modes is None or r["mode"] in modes)]
    return min(ok, key=lambda r: r["solve_s"]) if ok else None


def other_modes(rs, target, best):
    """{mode: its cheapest run meeting target, or None} for every mode of rs other than best's."""
    return {m: cheapest(rs, target, (m,)) for m in dict.fromkeys(r["mode"] for r in rs) if m != best["mode"]}


def configs(rows):
    return list(dict.fromkeys((r["scene"], r["material"], r["E"], r["level"]) for r in sweep_rows(rows)))


def write_csv(rows, path):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


INT_COLS = {"level", "rc", "steps", "rejections", "newton_its", "ksp_its", "residual_evals", "tets", "disc_level"}
STR_COLS = {"id", "role", "scene", "material", "mode", "pc", "outcome", "message", "path"}


def read_csv(path):
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            rows.append({k: (v if k in STR_COLS else (None if v in ("", None) else
                                                       (int(float(v)) if k in INT_COLS else float(v))))
                         for k, v in r.items()})
    return rows


def figures(rows, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cfgs = configs(rows)
    modes = list(dict.fromkeys(r["mode"] for r in sweep_rows(rows)))
    colors = dict(zip(modes, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    ncol = min(3, len(cfgs))
    nrow = math.ceil(len(cfgs) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    for ax, cfg in zip(axes.flat, cfgs):
        rs = [r for r in sweep_rows(rows, cfg) if r["outcome"] != "failed" and r.get("rel_err") is not None]
        failed = [r for r in sweep_rows(rows, cfg) if r["outcome"] == "failed"]
        for m in modes:
            pts = [(r["solve_s"], r["rel_err"]) for r in rs if r["mode"] == m]
            nf = sum(r["mode"] == m for r in failed)
            if pts or nf:
                ax.scatter(*zip(*pts) if pts else ([], []), s=14, color=colors[m], alpha=0.75,
                           label=m + (f" ({nf} failed)" if nf else ""))
        pts = [(r["solve_s"], max(r["rel_err"], 1e-16)) for r in rs]
        if pts:
            front = [pts[i] for i in pareto(pts)]
            ax.step(*zip(*front), where="post", color="k", lw=1.2, label="Pareto front")
        for t in TARGETS:
            ax.axhline(t, color="0.8", lw=0.6, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("solve time [s]")
        ax.set_ylabel("relative error (trajectory max)")
        ax.set_title(cfg_name(cfg), fontsize=9)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(cfgs):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "accuracy_pareto.png"), dpi=110)
    plt.close(fig)

    table = cost_vs_E(rows)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for (scene, mat, level), per_mode in table.items():
        for m, pts in per_mode.items():
            ok = [(E, r["solve_s"]) for E, r in pts if r is not None]
            if ok:
                ax.plot(*zip(*ok), "o-", label=f"L{level} {scene} {mat}: {m}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("Young's modulus E [Pa]")
    ax.set_ylabel(f"cheapest solve time for {COST_TARGET:g} relative error [s]")
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "accuracy_cost_vs_E.png"), dpi=110)
    plt.close(fig)


def cost_vs_E(rows, target=COST_TARGET):
    """{(scene, material, level): {mode: [(E, cheapest row or None)]}} over configurations that
    differ only in E (and have more than one E)."""
    groups = {}
    for cfg in configs(rows):
        groups.setdefault((cfg[0], cfg[1], cfg[3]), []).append(cfg)
    out = {}
    for key, cfgs in groups.items():
        if len(cfgs) < 2:
            continue
        modes = list(dict.fromkeys(r["mode"] for c in cfgs for r in sweep_rows(rows, c)))
        out[key] = {m: [(c[2], cheapest(sweep_rows(rows, c), target, (m,))) for c in sorted(cfgs, key=lambda c: c[2])]
                    for m in modes if all(any(r["mode"] == m for r in sweep_rows(rows, c)) for c in cfgs)}
    return out


def headline(rows, cfg):
    """The report's first paragraph: the cheapest setting for the tightest target that some run of
    the main configuration meets, against the alternatives, in numbers."""
    rs = sweep_rows(rows, cfg)
    ref = next((r for r in rows if r["role"] == "reference" and (r["scene"], r["material"], r["E"], r["level"]) == cfg),
               None)
    for target in (1e-3, 1e-2, 1e-1):
        best = cheapest(rs, target)
        if best is not None:
            break
    else:
        return f"No run of {cfg_name(cfg)} reached 10% relative error."
    per_mode = other_modes(rs, target, best)
    others = sorted([o for o in per_mode.values() if o is not None], key=lambda o: o["solve_s"])
    s = (f"**For {target:g} relative error on {cfg_name(cfg)}, the cheapest setting is `{label(best)}`: "
         f"{best['solve_s']:.3g} s of solve time ({best['newton_its']} Newton, {best['ksp_its']} Krylov iterations)")
    if others:
        o = others[0]
        s += f", {o['solve_s'] / best['solve_s']:.1f}× less than the cheapest {o['mode']} setting that meets it (`{label(o)}`)"
        worst = others[-1]
        if worst is not o:
            s += f" and {worst['solve_s'] / best['solve_s']:.1f}× less than the cheapest {worst['mode']} one"
    missing = [m for m, o in per_mode.items() if o is None]
    if missing:
        s += f"; {', '.join(missing)} never meet{'s' if len(missing) == 1 else ''} it"
    if ref is not None and ref.get("solve_s"):
        s += f". The reference settings cost {ref['solve_s'] / best['solve_s']:.0f}× more."
    disc = next((r for r in rows if r["role"] == "disc" and r.get("disc_err") is not None
                 and (r["scene"], r["material"], r["E"], r["level"]) == cfg), None)
    if disc is not None:
        s += (f" The mesh itself is off by {disc['disc_err']:.2g} relative (at the material points, against "
              f"L{disc['disc_level']}), so on this mesh a time-integration/solver error much below that buys nothing.")
    return s + "**"


def findings(rows, cfg):
    """Computed statements for the report: the observed order in h and the step (and cost) a target
    not reached would need, the effect of the Newton tolerance, the failures per mode."""
    out = []
    rs = [r for r in sweep_rows(rows, cfg) if r["outcome"] != "failed" and r["mode"] == "assembled"
          and r["pc"] == "jacobi" and r["ksp_rtol"] == 1e-5]
    tight = min((r["snes_rtol"] for r in rs), default=None)
    rs = sorted([r for r in rs if r["snes_rtol"] == tight], key=lambda r: r["h"])
    if len(rs) >= 3:
        order = slope([r["h"] for r in rs], [r["rel_err"] for r in rs])
        cost = slope([r["h"] for r in rs], [r["solve_s"] for r in rs])
        s = (f"Time step ({cfg_name(cfg)}, assembled, snes_rtol {tight:g}): the error falls as h^{order:.2f} "
             f"(h = {rs[-1]['h']:g} … {rs[0]['h']:g}) and the solve time as h^{cost:.2f}.")
        for t in TARGETS:
            if rs[0]["rel_err"] > t and order > 0:
                h = rs[0]["h"] * (t / rs[0]["rel_err"]) ** (1.0 / order)
                s += (f" {t:g} relative error would need h ≈ {h:.2g}, about {rs[0]['solve_s'] * (h / rs[0]['h']) ** cost:.2g} "
                      "s (extrapolated).")
                break
        out.append(s)
    groups, spread = {}, 0.0
    for r in sweep_rows(rows):
        if r["outcome"] != "failed":
            groups.setdefault((r["scene"], r["material"], r["E"], r["level"], r["mode"], r["pc"], r["h"], r["ksp_rtol"]),
                              []).append(r["rel_err"])
    n = 0
    for errs in groups.values():
        if len(errs) > 1 and min(errs) > 1e-8:     # (below: solver noise)
            n += 1
            spread = max(spread, (max(errs) - min(errs)) / max(errs))
    if n:
        out.append(f"Newton tolerance: over the {n} settings swept in snes_rtol (1e-2 … tightest) with errors above 1e-8, "
                   f"the error changes by "
                   f"at most {100 * spread:.2g}%: Newton converges quadratically, so a step that meets 1e-2 is "
                   "usually far past it, and the time step (or the mesh) sets the error.")
    fails = {}
    for r in sweep_rows(rows):
        if r["outcome"] == "failed":
            fails.setdefault(r["mode"], []).append(r)
    for m, fs in fails.items():
        out.append(f"{len(fs)} {m} run{'s' if len(fs) > 1 else ''} failed, e.g. {cfg_name((fs[0]['scene'], fs[0]['material'], fs[0]['E'], fs[0]['level']))}"
                   f", h = {fs[0]['h']:g}: \"{fs[0]['message'].replace('hyperelastic: error: ', '')}\"")
    return out


def report(rows, p, out_dir, command):
    cfgs = configs(rows)
    L = ["# Accuracy versus time", "", headline(rows, p.main if p.main in cfgs else cfgs[0]), "",
         f"Command: `{command}`. Figures: `accuracy_pareto.png` (error vs solve time per Jacobian mode, Pareto "
         f"front in black), `accuracy_cost_vs_E.png` (cost of {COST_TARGET:g} relative error vs E). All rows: "
         "`accuracy.csv`.", ""]
    nfail = sum(r["outcome"] == "failed" for r in rows if r["role"] == "sweep")
    L += [f"{len(sweep_rows(rows))} sweep runs ({nfail} failed, recorded below), final time {p.final_time:g} s, "
          f"frames every {1 / FPS:g} s. Error = largest vertex distance to the reference over the trajectory, "
          "relative to the reference's largest displacement; cost = solve time (steps' wall time including "
          "rejected attempts, without process start-up). The reference of each configuration: h = smallest "
          f"swept h / {REF_FACTOR}, snes_rtol {REF_SNES_RTOL:g}, exact tangent assembled, GMRES + ILU(0) to "
          "ksp_rtol 1e-12. Jacobi is the PC unless named; -snes_mf has none.", ""]
    L += ["## Findings", ""] + [f"- {f}" for f in findings(rows, p.main if p.main in cfgs else cfgs[0])] + [""]
    L += ["## Cheapest setting per error target", "",
          "| configuration | target | cheapest setting | solve (s) | Newton | Krylov | error | vs cheapest other mode |",
          "|---|---|---|---|---|---|---|---|"]
    for cfg in cfgs:
        rs = sweep_rows(rows, cfg)
        for t in TARGETS:
            b = cheapest(rs, t)
            if b is None:
                L.append(f"| {cfg_name(cfg)} | {t:g} | none of the {len(rs)} runs | - | - | - | - | - |")
                continue
            alt = min((a for a in other_modes(rs, t, b).values() if a is not None), key=lambda a: a["solve_s"],
                      default=None)
            vs = f"{alt['solve_s'] / b['solve_s']:.1f}× ({alt['mode']})" if alt else "-"
            L.append(f"| {cfg_name(cfg)} | {t:g} | `{label(b)}` | {b['solve_s']:.3g} | {b['newton_its']} | "
                     f"{b['ksp_its']} | {b['rel_err']:.2g} | {vs} |")
    table = cost_vs_E(rows)
    if table:
        L += ["", f"## Cost of {COST_TARGET:g} relative error versus stiffness", "",
              "| configuration | mode | " + " | ".join("E = " + E_NAMES.get(E, f"{E:g}")
                                                       for E, _ in next(iter(next(iter(table.values())).values()))) + " |",
              "|---|---|" + "---|" * len(next(iter(next(iter(table.values())).values())))]
        for (scene, mat, level), per_mode in table.items():
            for m, pts in per_mode.items():
                cells = [f"{r['solve_s']:.3g} s (h={r['h']:g})" if r else "not met" for _, r in pts]
                L.append(f"| L{level} {scene} {mat} | {m} | " + " | ".join(cells) + " |")
    L += ["", "## References and their own error", "",
          "| configuration | reference h | solve (s) | Newton | own error (|x_h − x_2h|, rel.) |", "|---|---|---|---|---|"]
    for r in rows:
        if r["role"] == "reference":
            cfg = (r["scene"], r["material"], r["E"], r["level"])
            L.append(f"| {cfg_name(cfg)} | {r['h']:g} | {fmt(r.get('solve_s'))} | {fmt(r.get('newton_its'))} | "
                     f"{fmt(r.get('ref_err_est'), '.2g')} |")
    disc = [r for r in rows if r["role"] == "disc"]
    if disc:
        L += ["", f"## Discretisation error (mesh) at h = {DISC_H:g}", "",
              "Displacement at the material points " + ", ".join(POINT_NAMES) + ", against the finest level, "
              "relative to the largest displacement there (reference solver settings).", "",
              "| scene, material, E | level | tets | mesh error (rel.) | solve (s) |", "|---|---|---|---|---|"]
        for r in disc:
            L.append(f"| {r['scene']}, {r['material']}, {r['E']:g} | L{r['level']} | {fmt(r.get('tets'), ',')} | "
                     f"{fmt(r.get('disc_err'), '.2g') if r['outcome'] != 'failed' else 'failed: ' + r['message']} | "
                     f"{fmt(r.get('solve_s'))} |")
    for cfg in cfgs:
        rs = sweep_rows(rows, cfg)
        fails = [r for r in rs if r["outcome"] == "failed"]
        L += ["", f"## {cfg_name(cfg)}: all {len(rs)} runs ({len(fails)} failed)", "",
              "| mode | pc | h | snes_rtol | ksp_rtol | outcome | rel. error | final max err (m) | energy drift "
              "| solve (s) | Newton | Krylov | res. evals | rejected | peak MB |", "|" + "---|" * 15]
        for r in sorted(rs, key=lambda r: (r["mode"], r["pc"], -r["h"], -r["snes_rtol"], -r["ksp_rtol"])):
            out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:90]}"
            L.append(f"| {r['mode']} | {r['pc']} | {r['h']:g} | {r['snes_rtol']:g} | {r['ksp_rtol']:g} | {out} | "
                     f"{fmt(r.get('rel_err'), '.2g')} | {fmt(r.get('err_final_max'), '.2g')} | "
                     f"{fmt(r.get('energy_drift'), '.2g')} | {fmt(r.get('solve_s'))} | {fmt(r.get('newton_its'))} | "
                     f"{fmt(r.get('ksp_its'))} | {fmt(r.get('residual_evals'))} | {fmt(r.get('rejections'))} | "
                     f"{fmt(r.get('peak_rss_mb'), '.0f')} |")
    with open(os.path.join(out_dir, "accuracy.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


# ---- the refinement study ---------------------------------------------------------------------------
REFINE_SCENE = ["bend2", "-quasistatic", "-dt", "0.0625", "-final_time", "0.25", "-material", "stvk"]
REFINE_T = 0.25
REFINE_SOLVER = ["-jacobian", "assembled", "-ksp_type", "cg", "-snes_rtol", "1e-10", "-snes_atol", "1e-12",
                 "-ksp_rtol", "1e-10"] + PCS["gamg"]


def refine_levels(full):
    return [1, 2, 3, 4, 5, 8] if not full else list(range(1, 16))


def refinement(out_dir, full=False, jobs=2, budget=600.0, parallel_from=20000, log=None):
    """Run the refinement levels (quick: L1-L4; --full: L1-L8 and finer gmsh levels while the
    total stays within `budget` seconds, under mpiexec -n 2 from `parallel_from` tets on).
    Returns rows, one per level (and a 1-rank twin of the first parallel level)."""
    from .mesh import cached_bar
    d = os.path.join(out_dir, "runs")
    os.makedirs(d, exist_ok=True)
    levels = refine_levels(full)
    meshes = {L: cached_bar(L) for L in levels[:8]}         # the cheap ones up front

    def one(level, nprocs):
        path = os.path.join(d, f"refine_L{level}_np{nprocs}.h5")
        rc, err, wall = run_hyperelastic(["run"] + REFINE_SCENE + ["-level", level, "-output", path, "-quiet"]
                                         + REFINE_SOLVER, path, nprocs=nprocs, timeout=3 * budget)
        row = {"level": level, "nprocs": nprocs, "rc": rc, "wall_s": wall, "path": path,
               "message": last_line(err, rc) if rc else ""}
        row.update(read_cost(path))
        row["outcome"] = "finished" if rc == 0 and abs((row.get("t_end") or 0.0) - REFINE_T) < 1e-9 else "failed"
        return row

    serial = [L for L in levels if L <= 8 and _tets(meshes[L]) < parallel_from]
    rows = parallel_map(lambda L: one(L, 1), serial, jobs, log)
    spent = sum(r["wall_s"] for r in rows)
    for L in [L for L in levels if L not in serial]:
        if rows and rows[-1]["outcome"] == "finished" and L > 8:
            # each level ~2x the tets: expect ~2.2x the time of the last one
            if spent + 2.2 * rows[-1]["wall_s"] > budget:
                break
        first_parallel = not any(r["nprocs"] == 2 for r in rows)
        r = one(L, 2)
        rows.append(r)
        if log:
            log(r)
        spent += r["wall_s"]
        if first_parallel:                      # the same level on one rank: is 2 ranks faster?
            r1 = one(L, 1)
            r1["twin"] = True
            rows.append(r1)
            if log:
                log(r1)
            spent += r1["wall_s"]
    analyse_refinement(rows)
    return rows


def _tets(path):
    from .mesh import read
    return len(read(path)[1])


def analyse_refinement(rows):
    """Errors at the material points against the finest finished level, the observed orders, and
    time per load step (in place); returns the fit {quantity: slope}."""
    from .mesh import level_size
    ok = [r for r in rows if r["outcome"] == "finished" and not r.get("twin")]
    if len(ok) < 3:
        return {}
    finest = max(ok, key=lambda r: r["tets"])
    uf = at_points(finest["path"])
    for r in rows:
        r["h_mesh"] = level_size(r["level"])
        if r["outcome"] == "finished":
            u = at_points(r["path"])
            r["u_points"] = json.dumps(u.round(9).tolist())
            err = np.linalg.norm(u - uf, axis=1)
            r["err_test_point"] = float(err[0])
            r["err_tip"] = float(err[1])
            r["err_points_max_rel"] = float(err.max() / np.linalg.norm(uf, axis=1).max())
            r["tip_displacement"] = float(np.linalg.norm(u[1]))
            r["s_per_step"] = r["solve_s"] / max(r["steps"], 1)
            r["finest_level"] = finest["level"]
    fit = [r for r in ok if r is not finest]
    out = {}
    for key in ("err_test_point", "err_tip"):
        out[key] = slope([r["h_mesh"] for r in fit], [r[key] for r in fit])
    out["s_per_step"] = slope([r["tets"] for r in ok], [r["s_per_step"] for r in ok])
    for r in rows:
        r["order_test_point"], r["order_tip"], r["time_exponent"] = out["err_test_point"], out["err_tip"], out["s_per_step"]
    return out


def slope(x, y):
    """Least-squares slope of log y against log x (nan with fewer than two positive points)."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(x, y) if a > 0 and b > 0]
    if len(pts) < 2:
        return float("nan")
    return float(np.polyfit(*zip(*pts), 1)[0])


REFINE_COLUMNS = ("level", "nprocs", "twin", "outcome", "message", "tets", "h_mesh", "tip_displacement",
                  "err_test_point", "err_tip", "err_points_max_rel", "order_test_point", "order_tip", "steps",
                  "newton_its", "ksp_its", "solve_s", "s_per_step", "time_exponent", "wall_s", "peak_rss_mb",
                  "finest_level", "u_points")


def refinement_report(rows, out_dir, command):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    with open(os.path.join(out_dir, "refinement.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, REFINE_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    ok = [r for r in rows if r["outcome"] == "finished" and not r.get("twin")]
    fit = [r for r in ok if r.get("err_tip")]
    o_tp = ok[0].get("order_test_point") if ok else float("nan")
    o_tip = ok[0].get("order_tip") if ok else float("nan")
    t_exp = ok[0].get("time_exponent") if ok else float("nan")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, name, o in (("err_test_point", POINT_NAMES[0], o_tp), ("err_tip", POINT_NAMES[1], o_tip)):
        if fit:
            h = np.array([r["h_mesh"] for r in fit])
            e = np.array([r[key] for r in fit])
            a1.loglog(h, e, "o-", label=f"{name}: slope {o:.2f}")
    a1.set_xlabel("target edge length h_mesh [m]")
    a1.set_ylabel("|u - u_finest| [m]")
    a1.set_title(f"displacement error vs mesh size (finest: L{ok[-1]['level'] if ok else '-'})", fontsize=9)
    a1.legend(fontsize=7)
    for n in (1, 2):
        rs = [r for r in rows if r["outcome"] == "finished" and r["nprocs"] == n]
        if rs:
            a2.loglog([r["tets"] for r in rs], [r["s_per_step"] for r in rs], "o-" if n == 1 else "s--",
                      label=f"{n} rank{'s' if n > 1 else ''}")
    a2.set_xlabel("tets")
    a2.set_ylabel("solve time per load step [s]")
    a2.set_title(f"time per step vs tets (fitted exponent {t_exp:.2f})", fontsize=9)
    a2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "refinement.png"), dpi=110)
    plt.close(fig)
    L = ["# Mesh refinement (gmsh)", ""]
    if ok:
        fin = ok[-1]
        L += [f"**Observed convergence order of the displacement at the thesis' test point (4.5, 1.5, 1.5): "
              f"{o_tp:.2f}; at the tip: {o_tip:.2f}** (least-squares slope of log error vs log edge length, "
              f"L{ok[0]['level']}–L{fit[-1]['level'] if fit else '-'} against the finest level L{fin['level']}, "
              f"{fin['tets']:,} tets). Time per load step grows as tets^{t_exp:.2f}.", ""]
    L += [f"Command: `{command}`. Problem: `hyperelastic run {' '.join(REFINE_SCENE)}` (four quasi-static load "
          f"steps of the ramped end traction, to 5 kPa), solver `{' '.join(REFINE_SOLVER)}`. Figure: `refinement.png`.", "",
          "| level | ranks | tets | h_mesh | tip displacement (m) | error at test point (m) | error at tip (m) | "
          "Newton | Krylov | solve (s) | s / step | wall (s) | peak MB | outcome |", "|" + "---|" * 14]
    for r in rows:
        out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:80]}"
        L.append(f"| L{r['level']} | {r['nprocs']} | {fmt(r.get('tets'), ',')} | {r.get('h_mesh', 0):.3g} | "
                 f"{fmt(r.get('tip_displacement'), '.5g')} | {fmt(r.get('err_test_point'), '.2g')} | "
                 f"{fmt(r.get('err_tip'), '.2g')} | {fmt(r.get('newton_its'))} | {fmt(r.get('ksp_its'))} | "
                 f"{fmt(r.get('solve_s'))} | {fmt(r.get('s_per_step'))} | {r['wall_s']:.3g} | "
                 f"{fmt(r.get('peak_rss_mb'), '.0f')} | {out} |")
    twins = [r for r in rows if r.get("twin") and r["outcome"] == "finished"]
    for t in twins:
        par = next((r for r in rows if r["level"] == t["level"] and r["nprocs"] == 2 and r["outcome"] == "finished"), None)
        if par:
            L += ["", f"L{t['level']} on 1 vs 2 ranks: {t['s_per_step']:.3g} vs {par['s_per_step']:.3g} s per load "
                      f"step ({t['s_per_step'] / par['s_per_step']:.2f}× on 2 ranks); the levels from there on run under "
                      "`mpiexec -n 2`."]
    with open(os.path.join(out_dir, "refinement.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


# ---- command line -----------------------------------------------------------------------------------
def main(argv):
    import argparse
    import sys
    import time

    class P(argparse.ArgumentParser):
        def error(self, message):
            raise UserError(f"hyperelastic study: {message}")
    ap = P(prog="hyperelastic study", description="What accuracy costs in time.")
    ap.add_argument("which", choices=("accuracy", "refinement"))
    ap.add_argument("-output_dir", "--output-dir", dest="output_dir", default=None)
    ap.add_argument("--full", action="store_true", help="the whole sweep (hours) instead of the quick default")
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time (default 2)")
    ap.add_argument("--budget", type=float, default=600.0, help="refinement: seconds for the finer levels")
    ap.add_argument("--from-csv", action="store_true", help="accuracy: redo report and figures from accuracy.csv")
    a = ap.parse_args(argv)
    if a.jobs < 1:
        raise UserError("hyperelastic study: --jobs must be >= 1")
    out = a.output_dir or os.path.join("output", f"study_{a.which}")
    from .output import writable_dir
    writable_dir(out, "-output_dir")
    command = "hyperelastic study " + " ".join(argv)
    t0 = time.perf_counter()

    def log(r):
        what = r.get("id") or f"L{r['level']} np{r['nprocs']}"
        extra = f": {r['message']}" if r["outcome"] == "failed" else ""
        print(f"[{time.perf_counter() - t0:6.1f} s] {what} {r['outcome']}{extra}", file=sys.stderr, flush=True)
    if a.which == "accuracy":
        if a.from_csv:
            path = os.path.join(out, "accuracy.csv")
            if not os.path.isfile(path):
                raise UserError(f"--from-csv: no {path}")
            rows, p = read_csv(path), plan(a.full)
        else:
            rows, p = accuracy(out, a.full, a.jobs, log)
            write_csv(rows, os.path.join(out, "accuracy.csv"))
        figures(rows, out)
        report(rows, p, out, command)
        print(os.path.join(out, "accuracy.md"))
    else:
        rows = refinement(out, a.full, a.jobs, a.budget, log=log)
        refinement_report(rows, out, command)
        print(os.path.join(out, "refinement.md"))
    return 0
