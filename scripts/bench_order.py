#!/usr/bin/env python
"""What 1% costs with linear and with quadratic tetrahedra: the tip deflection of a part under a static load,
on a ladder of meshes at each element order, each run's error against a converged value, and the cheapest
run of each order within the target.

    .venv/bin/python scripts/bench_order.py OUT [--case bar|bracket|all] [--target 0.01] [--quick] [--p2-pc pmg|gamg]

bar: the cantilever bar [-5,5]x[-2,2]x[-2,2] (left end clamped, 5000 Pa down on the right end, linear
material, nu = 0.3, quasi-static in one step), watched: u_y at the tip's centre (5, 0, 0). Meshes: the bar
levels (P1 up to L12, P2 up to L8). bracket: examples/bracket.geo with examples/bracket.opts (aluminium,
St. Venant-Kirchhoff, 4 load steps), meshed by gmsh at decreasing sizes; watched: the largest |u|.
The converged value: q_inf of q(h) = q_inf + C h^p through the three finest P2 runs (Richardson with the
meshes' own size ratios). Cost: the
solve time (the steps' wall time, from the output's statistics) and the whole command's wall time; one rank; CG +
GAMG (options/gamg.opts) for P1, and for P2 CG + p-multigrid (options/pmg.opts; --p2-pc gamg: GAMG as P1's, the
figures of 2026-11-24/25). Writes OUT/order.csv and OUT/order.md.
"""
import argparse
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from hyperelastic.studies.experiments.runner import last_line, run_hyperelastic  # noqa: E402
from hyperelastic.studies.experiments.table import write_csv  # noqa: E402
from hyperelastic.mesh.read import interpolate, locate  # noqa: E402
from hyperelastic.mesh.generate import generate, level_size  # noqa: E402
from hyperelastic.studies.measure import read_cost  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GAMG = ["-options_file", os.path.join(ROOT, "options", "gamg.opts")]
PC = {1: GAMG, 2: GAMG}          # per element order (main: --p2-pc)
TIGHT = ["-snes_rtol", "1e-10", "-ksp_rtol", "1e-10", "-quiet"]
BAR = ["bend", "-effects", "elasticity,fixed,traction", "-material", "linear", "-quasistatic", "-dt", "1",
       "-final_time", "1"]


def tip_uy(path):
    with h5py.File(path, "r") as f:
        x, X, tets = f["x"][-1], f["mesh/points"][:], f["mesh/tetra"][:]
    cells, w = locate(X, tets[:, :4], np.array([[5.0, 0.0, 0.0]]))
    return float(interpolate(tets, cells, w, x - X)[0, 1])


def max_u(path):
    with h5py.File(path, "r") as f:
        return float(np.linalg.norm(f["x"][-1] - f["mesh/points"][:], axis=1).max())


def run(args, path, order, n=1):
    rc, err, wall = run_hyperelastic(args + ["-output", path] + PC[order] + TIGHT, path, nprocs=n, timeout=3600)
    row = {"rc": rc, "wall_s": wall, "ranks": n, "message": last_line(err, rc) if rc else ""}
    row.update(read_cost(path))
    return row


def bar(out, quick):
    rows = []
    levels = {1: range(1, 9 if quick else 13), 2: range(1, 6 if quick else 9)}
    for order, lv in levels.items():
        for L in lv:
            path = os.path.join(out, f"bar_p{order}_L{L}.h5")
            r = {"case": "bar", "order": order, "mesh": f"L{L}", "h": level_size(L)}
            r.update(run(["run"] + BAR + ["-level", str(L), "-order", str(order)], path, order))
            if r["rc"] == 0:
                r["quantity"] = tip_uy(path)
                with h5py.File(path, "r") as f:
                    r["dofs"] = 3 * f["mesh/points"].shape[0]
            rows.append(r)
            print(f"bar P{order} L{L}: {r.get('quantity')} ({r.get('tets')} tets, {r.get('solve_s')} s)", flush=True)
    return rows


def bracket(out, quick):
    rows = []
    sizes = (0.006, 0.004, 0.003, 0.002) if quick else (0.006, 0.004, 0.003, 0.002, 0.0015, 0.0012)
    scene = os.path.join(ROOT, "examples", "bracket.opts")
    for h in sizes:
        msh = os.path.join(out, f"bracket_{h:g}.msh")
        if not os.path.exists(msh):
            generate(os.path.join(ROOT, "examples", "bracket.geo"), None, msh, h)
        for order in (1, 2):
            if order == 2 and h < 0.002:
                continue
            path = os.path.join(out, f"bracket_p{order}_{h:g}.h5")
            r = {"case": "bracket", "order": order, "mesh": f"h={h:g}", "h": h}
            r.update(run(["run", scene, "-mesh", msh, "-order", str(order)], path, order))
            if r["rc"] == 0:
                r["quantity"] = max_u(path)
                with h5py.File(path, "r") as f:
                    r["dofs"] = 3 * f["mesh/points"].shape[0]
            rows.append(r)
            print(f"bracket P{order} h={h:g}: {r.get('quantity')} ({r.get('tets')} tets, {r.get('solve_s')} s)",
                  flush=True)
    return rows


def extrapolate(hs, qs):
    """(q_inf, p) of q(h) = q_inf + C h^p through three (h, q), h decreasing (Richardson with any ratios: p by
    bisection on (q1 - q2)/(q2 - q3) = (h1^p - h2^p)/(h2^p - h3^p)); (q3, nan) where the changes do not
    shrink monotonically."""
    (h1, h2, h3), (q1, q2, q3) = hs, qs
    if not (q1 - q2) * (q2 - q3) > 0:
        return q3, float("nan")
    want = (q1 - q2) / (q2 - q3)
    f = lambda p: (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - want      # noqa: E731 (increasing in p)
    lo, hi = 0.05, 10.0
    if f(lo) > 0 or f(hi) < 0:
        return q3, float("nan")
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    p = 0.5 * (lo + hi)
    C = (q1 - q2) / (h1 ** p - h2 ** p)
    return q3 - C * h3 ** p, p


def analyse(rows, target):
    """Per case: the converged value (extrapolated from the three finest P2 runs), each run's error, and the
    cheapest run of each order within the target."""
    out = []
    for case in dict.fromkeys(r["case"] for r in rows):
        rs = [r for r in rows if r["case"] == case and r["rc"] == 0]
        p2 = [r for r in rs if r["order"] == 2][-3:]
        limit, p = extrapolate([r["h"] for r in p2], [r["quantity"] for r in p2])
        for r in rs:
            r["error"] = abs(r["quantity"] - limit) / abs(limit)
            r["limit"], r["richardson_p"] = limit, p
        cheapest = {}
        for o in (1, 2):
            ok = [r for r in rs if r["order"] == o and r["error"] <= target]
            cheapest[o] = min(ok, key=lambda r: r["solve_s"]) if ok else None
        out.append((case, limit, p, cheapest))
    return out


def report(rows, summary, target, out, command):
    write_csv(os.path.join(out, "order.csv"), rows, ["case", "order", "mesh", "tets", "dofs", "ranks", "quantity",
                                                     "error", "solve_s", "wall_s", "newton_its", "ksp_its", "rc",
                                                     "message"])
    L = ["# What 1% costs: linear against quadratic tetrahedra", "", f"Command: `{command}`.", ""]
    for case, limit, p, cheapest in summary:
        c1, c2 = cheapest.get(1), cheapest.get(2)
        ratio = (c1["solve_s"] / c2["solve_s"]) if c1 and c2 else float("nan")
        L += [f"## {case}", "", f"Converged value {limit:.6g} (q_inf + C h^p through the three finest P2 runs, "
                                f"p = {p:.2f}).",
              f"Cheapest within {target:g}: P1 " + (f"{c1['mesh']} ({c1['tets']:,} tets, {c1['solve_s']:.3g} s, error "
                                                     f"{c1['error']:.2g})" if c1 else "none of the meshes run")
              + "; P2 " + (f"{c2['mesh']} ({c2['tets']:,} tets, {c2['solve_s']:.3g} s, error {c2['error']:.2g})"
                           if c2 else "none") + f": P2 {ratio:.3g}x cheaper (solve time).", "",
              "| order | mesh | tets | dofs | ranks | quantity | error | solve (s) | wall (s) |",
              "|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r["case"] == case:
                L.append(f"| P{r['order']} | {r['mesh']} | {r.get('tets', '')} | {r.get('dofs', '')} | {r['ranks']} | "
                         f"{r.get('quantity', r['message'])} | {r.get('error', float('nan')):.3g} | "
                         f"{r.get('solve_s', float('nan')):.3g} | {r['wall_s']:.3g} |")
        L.append("")
    with open(os.path.join(out, "order.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")
    print("\n".join(L))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--case", default="all", choices=("bar", "bracket", "all"))
    ap.add_argument("--target", type=float, default=0.01)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--p2-pc", default="pmg", choices=("pmg", "gamg"))
    a = ap.parse_args(argv)
    PC[2] = ["-options_file", os.path.join(ROOT, "options", f"{a.p2_pc}.opts")]
    os.makedirs(a.out, exist_ok=True)
    rows = []
    if a.case in ("bar", "all"):
        rows += bar(a.out, a.quick)
    if a.case in ("bracket", "all"):
        rows += bracket(a.out, a.quick)
    report(rows, analyse(rows, a.target), a.target, a.out, "scripts/bench_order.py " + " ".join(argv or sys.argv[1:]))


if __name__ == "__main__":
    main()
