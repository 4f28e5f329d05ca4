#!/usr/bin/env python
"""Whole-run benchmarks (issue: performance), each a real `hyperelastic run` child process:

  memory       peak RSS per tet of one step with the assembled tangent (-assembly setvalues, the
               default, and -assembly coo) and with the shell tangent
  scalability  KSP iterations per Newton step for squeeze and bend with the exact tangent and CG +
               GAMG (rigid-body near-nullspace), Jacobi and bjacobi+ICC, over four gmsh refinements
  parallel     time per Newton step on 1 and 2 ranks (same options), and each rank's share of vertices
  scaling      time per step vs tets from L1 up, for each Jacobian mode; log-log PNG, fitted exponent
  crossover    GAMG (set-up kept across steps, -reuse_preconditioner auto) against Jacobi end to end on
               bend over refinement in four regimes: dynamic h = 1e-2 (the mass term dominates),
               2e-2, 5e-2, quasi-static (the stiffness alone); 4 steps each, 1 rank

    scripts/bench_solvers.py OUT [--full] [--only memory,scalability,parallel,scaling,crossover] [--repeat N]

Quick (default, < 1 min): small meshes. --full: up to ~660k tets (tens of minutes). Prints the
tables and writes OUT/bench_solvers.json and OUT/scaling.png.
"""
import argparse
import json
import math
import os
import platform
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.mesh.read import read  # noqa: E402
from hyperelastic.mesh.generate import cached_bar, size_for_tets  # noqa: E402
from hyperelastic.studies.experiments.recipes import MODES as JACOBIAN_MODES  # noqa: E402
from hyperelastic.studies.experiments.runner import last_line, run_hyperelastic  # noqa: E402
from hyperelastic.studies.measure import read_cost, slope  # noqa: E402
from hyperelastic.studies.plan import PCS  # noqa: E402

MODES = {m: JACOBIAN_MODES[m] for m in ("assembled", "shell", "snes_mf", "snes_mf_operator")}


BIG = 0.1029       # target edge of the ~660k-tet bar of BENCHMARKS.md (bench_kernels.py --full)


def mesh_for(tets):
    """A cached bar mesh with about `tets` tetrahedra (gmsh, generated once)."""
    return cached_bar(size=BIG if tets >= 600_000 else round(size_for_tets(tets), 4))


def run(out, tag, scene, mesh, args, nprocs=1, steps=1, dt=1e-2):
    path = os.path.join(out, "runs", tag + ".h5")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    rc, err, wall = run_hyperelastic(["run", scene, "-mesh", mesh, "-dt", dt, "-final_time", round(steps * dt, 12),
                                      "-output", path, "-quiet", "-step_control", "0"] + list(args), path, nprocs)
    r = {"tag": tag, "rc": rc, "wall_s": wall, "message": last_line(err, rc) if rc else ""}
    r.update(read_cost(path))
    if rc == 0:
        import h5py
        with h5py.File(path, "r") as f:
            r["vertices_per_rank"] = [int(v) for v in f.attrs["vertices_per_rank"]]
            r["vertices"] = int(f["mesh/points"].shape[0])
        r["s_per_newton"] = r["solve_s"] / max(r["newton_its"], 1)
        r["ksp_per_newton"] = r["ksp_its"] / max(r["newton_its"], 1)
        r["s_per_step"] = r["solve_s"] / max(r["steps"], 1)
    return r


def memory(out, full):
    tets = 660_000 if full else 60_000
    mesh = mesh_for(tets)
    rows = []
    for name, args in (("assembled (setvalues), AIJ operator", ["-jacobian", "assembled", "-operator_storage", "aij"]),
                       ("assembled (coo)", ["-jacobian", "assembled", "-assembly", "coo"]),
                       ("assembled (setvalues) + SBAIJ operator (default)", ["-jacobian", "assembled"]),
                       ("shell", ["-jacobian", "shell"])):
        r = run(out, f"memory_{name.split()[0]}_{args[-1]}", "bend", mesh, args)
        r["bytes_per_tet"] = r["peak_rss_mb"] * 2 ** 20 / r["tets"]
        rows.append((name, r))
    print(f"\n## Peak memory, one step of bend (St.VK), {rows[0][1]['tets']:,} tets")
    print("| tangent | peak RSS (MB) | bytes / tet | solve (s) |\n|---|---|---|---|")
    for name, r in rows:
        print(f"| {name} | {r['peak_rss_mb']:.0f} | {r['bytes_per_tet']:.0f} | {r['solve_s']:.2f} |")
    return {name: r for name, r in rows}


def scalability(out, full):
    sizes = (60_000, 125_000, 250_000, 550_000) if full else (2_000, 4_000, 8_000, 16_000)
    pcs = ("gamg", "jacobi", "bjacobi_icc")
    res = {}
    for scene in ("squeeze", "bend"):
        for n in sizes:
            mesh = mesh_for(n)
            for pc in pcs:
                r = run(out, f"scal_{scene}_{n}_{pc}", scene, mesh, ["-jacobian", "assembled", "-ksp_type", "cg",
                                                                     "-ksp_max_it", "20000"] + PCS[pc], steps=2)
                res[(scene, n, pc)] = r
    print("\n## KSP iterations per Newton step (exact tangent, CG; 2 steps of h = 1e-2)")
    print("| scene | tets | " + " | ".join(pcs) + " | GAMG s / Newton | Jacobi s / Newton |")
    print("|---|---|" + "---|" * (len(pcs) + 2))
    for scene in ("squeeze", "bend"):
        g = []
        for n in sizes:
            rs = [res[(scene, n, pc)] for pc in pcs]
            g.append(rs[0].get("ksp_per_newton"))
            print(f"| {scene} | {rs[0].get('tets', 0):,} | " + " | ".join(f"{r.get('ksp_per_newton', float('nan')):.1f}"
                                                                    for r in rs)
                  + f" | {rs[0].get('s_per_newton', float('nan')):.3g} | {rs[1].get('s_per_newton', float('nan')):.3g} |")
        g = [x for x in g if x]
        if g:
            mid = (max(g) + min(g)) / 2
            print(f"| {scene} | GAMG spread | ±{100 * (max(g) - min(g)) / 2 / mid:.0f}% around {mid:.1f} | | | | |")
    return {f"{k[0]}/{k[1]}/{k[2]}": v for k, v in res.items()}


def parallel(out, full, repeat=1):
    """s per Newton step on 1 and 2 ranks; with repeat > 1 each the fastest of `repeat` runs (2-rank
    timings on a shared 2-core VM vary by ~25% from run to run)."""
    tets = 660_000 if full else 60_000
    mesh = mesh_for(tets)
    res = {}
    print(f"\n## 1 vs 2 ranks, bend, 2 steps, {tets:,}-tet target")
    print("| options | ranks | s / Newton | s / step | KSP / Newton | vertex share of the larger rank |\n|---|---|---|---|---|---|")
    aij = ["-jacobian", "assembled", "-operator_storage", "aij"]
    sbaij = ["-jacobian", "assembled", "-operator_storage", "sbaij"]
    for name, args in (("assembled, CG + Jacobi", aij), ("assembled, CG + GAMG", aij + PCS["gamg"]),
                       ("assembled_sbaij, CG + Jacobi", sbaij), ("assembled_sbaij, CG + GAMG", sbaij + PCS["gamg"]),
                       ("shell, CG + Jacobi", ["-jacobian", "shell"]),
                       ("MFFD, CG + Jacobi of the assembled tangent", ["-jacobian", "assembled", "-snes_mf_operator"])):
        for n in (1, 2):
            runs = [run(out, f"par_{name.split(',')[0]}_{args[-1].lstrip('-')}_np{n}", "bend", mesh, args,
                        nprocs=n, steps=2) for _ in range(repeat)]
            r = min(runs, key=lambda x: x.get("s_per_newton", float("inf")))
            res[(name, n)] = r
            share = max(r["vertices_per_rank"]) / r["vertices"] if r.get("vertices") else float("nan")
            print(f"| {name} | {n} | {r.get('s_per_newton', float('nan')):.3g} | {r.get('s_per_step', float('nan')):.3g} "
                  f"| {r.get('ksp_per_newton', float('nan')):.1f} | {share:.3f} |")
        print(f"| {name} | speed-up | {res[(name, 1)]['s_per_newton'] / res[(name, 2)]['s_per_newton']:.2f}× | | | |")
    return {f"{k[0]}/np{k[1]}": v for k, v in res.items()}


# (name, options, step size): the Jacobi-preconditioned tangent's condition number grows with
# dt^2 E / (rho h_mesh^2) (stiffness over mass), so Jacobi's iterations grow with dt / h_mesh; GAMG's stay flat
REGIMES = (("dynamic, h = 1e-2", [], 1e-2), ("dynamic, h = 2e-2", [], 2e-2), ("dynamic, h = 5e-2", [], 5e-2),
           ("quasi-static", ["-quasistatic"], 0.25))


def crossover(out, full, steps=4):
    """End to end (the steps' wall time, set-up included) GAMG against Jacobi, bend, 1 rank."""
    sizes = (60_000, 125_000, 250_000, 550_000) if full else (2_000, 8_000)
    res = {}
    print(f"\n## GAMG against Jacobi end to end (bend, assembled tangent, CG, {steps} steps, 1 rank)")
    print("| regime | tets | KSP / Newton Jacobi | KSP / Newton GAMG | Jacobi s | GAMG s | GAMG / Jacobi |")
    print("|---|---|---|---|---|---|---|")
    won, lost = [], []
    for regime, extra, dt in REGIMES:
        for n in sizes:
            mesh = mesh_for(n)
            rs = {}
            for pc in ("jacobi", "gamg"):
                tag = f"cross_{regime.split(',')[0].replace('-', '')}_{dt:g}_{n}_{pc}"
                args = ["-jacobian", "assembled", "-ksp_type", "cg", "-ksp_max_it", "20000"] + extra + PCS[pc]
                rs[pc] = run(out, tag, "bend", mesh, args, steps=steps, dt=dt)
                res[(regime, n, pc)] = rs[pc]
            j, g = rs["jacobi"], rs["gamg"]
            nan = float("nan")
            ratio = g.get("solve_s", nan) / j.get("solve_s", nan)
            if ratio == ratio:
                (won if ratio < 1 else lost).append(j["ksp_per_newton"])
            bold = "**" if ratio < 1 else ""
            print(f"| {regime} | {j.get('tets', 0):,} | {j.get('ksp_per_newton', nan):.1f} "
                  f"| {g.get('ksp_per_newton', nan):.1f} | {j.get('solve_s', nan):.3g} "
                  f"| {g.get('solve_s', nan):.3g} | {bold}{ratio:.2f}{bold} |")
    if won or lost:
        print(f"\nGAMG won where Jacobi needed >= {min(won) if won else float('nan'):.0f} CG iterations per "
              f"Newton step; lost where it needed <= {max(lost) if lost else float('nan'):.0f}.")
    return {f"{k[0]}/{k[1]}/{k[2]}": v for k, v in res.items()}


def scaling(out, full):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    levels = [cached_bar(L) for L in (1, 3, 5, 8)]
    sizes = (60_000, 125_000, 250_000, 660_000) if full else (60_000,)
    meshes = levels + [mesh_for(n) for n in sizes]
    res = {}
    fig, ax = plt.subplots(figsize=(6, 4.5))
    print("\n## Time per step vs tets (bend, St.VK, 2 steps of h = 1e-2, CG, 1 rank)")
    print("| mode | " + " | ".join(f"{len(read(m)[1]):,}" for m in meshes) + " | exponent |")
    print("|---|" + "---|" * (len(meshes) + 1))
    for mode, args in MODES.items():
        pts = []
        for m in meshes:
            r = run(out, f"scaling_{mode}_{os.path.basename(m)[:-4]}", "bend", m, args, steps=2)
            res[(mode, m)] = r
            if r["rc"] == 0:
                pts.append((r["tets"], r["s_per_step"]))
        e = slope(*zip(*pts)) if len(pts) > 1 else float("nan")
        print(f"| {mode} | " + " | ".join(f"{res[(mode, m)].get('s_per_step', float('nan')):.3g}" for m in meshes)
              + f" | {e:.2f} |")
        if pts:
            ax.loglog(*zip(*pts), "o-", label=f"{mode} (slope {e:.2f})")
    ax.set_xlabel("tets")
    ax.set_ylabel("solve time per step [s]")
    ax.set_title("bend, St.VK, CG (+Jacobi where there is a matrix), 1 rank", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "scaling.png"), dpi=110)
    plt.close(fig)
    return {f"{k[0]}/{os.path.basename(k[1])}": v for k, v in res.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--only", default="memory,scalability,parallel,scaling")
    ap.add_argument("--repeat", type=int, default=1, help="parallel: the fastest of N runs per row")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; python {platform.python_version()}")
    results = {}
    for part in a.only.split(","):
        fn = {"memory": memory, "scalability": scalability, "parallel": parallel, "scaling": scaling,
              "crossover": crossover}.get(part)
        if fn is None:
            sys.exit(f"bench_solvers.py: unknown part '{part}'")
        results[part] = fn(a.out, a.full, a.repeat) if part == "parallel" else fn(a.out, a.full)
        sys.stdout.flush()
    with open(os.path.join(a.out, "bench_solvers.json"), "w") as fh:
        json.dump(results, fh, indent=1, default=lambda v: None if isinstance(v, float) and math.isnan(v) else str(v))


if __name__ == "__main__":
    main()
