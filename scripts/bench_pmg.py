"""p-multigrid for quadratic tetrahedra against GAMG (issue 49, item 1): Krylov iterations and seconds per Newton
step over refinements of the bar, P1 with GAMG, P2 with GAMG and P2 with p-multigrid (options/gamg.opts,
options/pmg.opts), each a real `hyperelastic run` child process: the quasi-static Neo-Hookean bend2 (the bar clamped
at one end, its other end pulled down), 2 load steps, PETSc's default tolerances (CG to a 1e-5 relative residual), the preconditioner's set-up kept across
Newton steps (-reuse_preconditioner auto) in every run.

    .venv/bin/python scripts/bench_pmg.py [--levels 3,5,7,9] [--ranks 1] [--cases P1:gamg,P2:gamg,P2:pmg]
                                          [--extra "-mg_coarse_pc_gamg_threshold 0.05"] [--mesh FILE.msh]

--extra: options added to every run (for p-multigrid variants); --mesh: a mesh file instead of the bar's levels.
"""
import argparse
import os
import sys
import tempfile

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from hyperelastic.studies.experiments.runner import run_hyperelastic  # noqa: E402

OPTS = {"gamg": os.path.join(ROOT, "options", "gamg.opts"), "pmg": os.path.join(ROOT, "options", "pmg.opts")}
CASES = (("P1", "1", "gamg"), ("P2", "2", "gamg"), ("P2", "2", "pmg"))


def run(level, order, pc, ranks, out, extra=()):
    where = ["-mesh", level] if str(level).endswith(".msh") else ["-level", str(level)]
    args = ["run", "bend2", "-quasistatic", "-dt", "0.5", "-material", "neohookean", *where, "-order",
            order, "-options_file", OPTS[pc], "-output", out, "-quiet", *extra]
    rc, err, wall = run_hyperelastic(args, out, ranks)
    if rc:
        raise SystemExit(f"failed: {' '.join(args)} on {ranks} ranks\n{err}")
    with h5py.File(out, "r") as f:
        s = {k: f["stats"][k][:] for k in ("newton_its", "ksp_its", "wall_s")}
        dofs, tets = 3 * f["mesh/points"].shape[0], f["mesh/tetra"].shape[0]
        peak = float(f.attrs.get("peak_rss_mb", 0.0))
    newton = max(int(s["newton_its"].sum()), 1)
    return {"dofs": dofs, "tets": tets, "newton": newton, "ksp": s["ksp_its"].sum() / newton,
            "s_newton": s["wall_s"].sum() / newton, "wall": wall, "peak": peak}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", default="3,5,7,9")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--cases", default="P1:gamg,P2:gamg,P2:pmg")
    ap.add_argument("--extra", default="")
    ap.add_argument("--mesh", action="append", default=[])
    ns = ap.parse_args()
    cases = [c for c in CASES if f"{c[0]}:{c[2]}" in ns.cases.split(",")]
    levels = ns.mesh or [int(v) for v in ns.levels.split(",")]
    with tempfile.TemporaryDirectory() as d:
        print(f"{'level':>5s} {'tets':>7s} {'element':>7s} {'PC':>5s} {'dofs':>8s} {'Newton':>6s} {'KSP/Newton':>10s} "
              f"{'s/Newton':>9s} {'run s':>7s} {'peak MB':>8s}")
        for level in levels:
            for name, order, pc in cases:
                r = run(level, order, pc, ns.ranks, os.path.join(d, "out.h5"), ns.extra.split())
                print(f"{os.path.basename(str(level)):>5s} {r['tets']:7d} {name:>7s} {pc:>5s} {r['dofs']:8d} "
                      f"{r['newton']:6d} {r['ksp']:10.1f} {r['s_newton']:9.3f} {r['wall']:7.2f} {r['peak']:8.0f}", flush=True)


if __name__ == "__main__":
    main()
