"""Verification of `hyperelastic study price` (issue 35): on a case, the search's recommended setting against
an exhaustive grid over the same dimensions and an overkill reference kept out of the search.

    .venv/bin/python scripts/verify_price.py OUT --case bar|bracket|bend2|swing [--target 0.01]

For the case it runs (1) the price search as `study price` does, (2) every setting of the grid (orders x mesh
levels x, for dynamic scenes, time-step halvings x integrators, x tolerances x, for static scenes, preconditioners:
dynamic grids keep the default one, which changes the cost and not the answer, and the loose and default
tolerances), (3) the
reference: P2 one level finer than the grid's finest, tight tolerances, and for dynamic scenes generalized-alpha
at a quarter of the grid's smallest step. It prints and writes OUT/CASE/verify.md: the recommended setting's true
error (against the reference) and cost, the cheapest grid setting whose true error meets the target, their cost
ratio (goal <= 2), and the search's time against the grid's (goal <= 1/5), where each side's time is the wall
time of its runs.
"""
import argparse
import json
import os
import sys
import time
from dataclasses import astuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hyperelastic.study.price import SOLVERS, TOLERANCES, Search, Setting  # noqa: E402
from hyperelastic.study.price_report import price_report  # noqa: E402

# case: (part, scene, --size, watch, extra run options, grid levels per order, grid dt halvings)
CASES = {
    "bar": (f"{ROOT}/meshes/bar.geo", f"{ROOT}/options/scenes/bend2.opts", 2.0, "u_y:5,0,0",
            ["-quasistatic", "-dt", "0.0625", "-final_time", "0.25", "-material", "stvk"], {1: 3, 2: 2}, 0),
    "bracket": (f"{ROOT}/examples/bracket.geo", f"{ROOT}/examples/bracket.opts", 0.012, "u_z:0.1,0.03,0.005",
                [], {1: 3, 2: 2}, 0),
    "bend2": (f"{ROOT}/meshes/bar.geo", f"{ROOT}/options/scenes/bend2.opts", 2.0, "u_y:5,0,0@max",
              ["-final_time", "0.3", "-dt", "0.02", "-material", "stvk"], {1: 2, 2: 2}, 2),
    "swing": (f"{ROOT}/examples/bracket.geo", f"{ROOT}/examples/swing.opts", 0.012, "u_z:0.1,0.03,0.005@max",
              [], {1: 2, 2: 1}, 3),
}


REF_LEVEL = {"bend2": 2}   # bend2's reference: P2 r2 at dt/16 (its grid reaches P2 r2 at dt/4; P2's change r1 -> r2 is 1e-4)


def grid(case, search):
    _, _, _, _, _, levels, halvings = CASES[case]
    for o, top in levels.items():
        for lv in range(top + 1):
            for j in range(halvings + 1):
                for integ in search.integrators:
                    for t in range(len(TOLERANCES) if not search.dynamic else 2):
                        for pc in (SOLVERS if not search.dynamic else ("default",)):
                            yield Setting(o, lv, j, integ, t, pc)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--case", choices=CASES, required=True)
    ap.add_argument("--target", type=float, default=0.01)
    ap.add_argument("--budget", type=float, default=600.0)
    a = ap.parse_args()
    part, scene, size, watch, extra, levels, halvings = CASES[a.case]
    out = os.path.join(a.out, a.case)
    os.makedirs(out, exist_ok=True)
    log = lambda r: print(f"  run {r['run']} {r['setting'].label()}: {r['outcome']} "  # noqa: E731
                          f"{r.get('quantity', r['message'])} {r.get('solve_s', float('nan')):.3g} s", flush=True)
    print(f"search ({a.case}, target {a.target})", flush=True)
    s = Search(part, scene, watch, a.target, size, os.path.join(out, "search"), run_args=extra, budget=a.budget,
               log=log)
    s.search()
    summary = price_report(s, os.path.join(out, "search"), "verify_price.py")
    search_wall = sum(r["wall_s"] for r in s.rows)

    print("grid", flush=True)
    g = Search(part, scene, watch, a.target, size, os.path.join(out, "grid"), run_args=extra, budget=1e9, log=log)
    ref_lv = REF_LEVEL.get(a.case) or (max(levels.values()) + 1 if levels.get(2) is None else levels[2] + 1)
    ref = Setting(2, ref_lv, halvings + 2 if g.dynamic else 0, "alpha2" if g.dynamic else "beuler", 2, "gamg")
    cache = os.path.join(out, "grid", "rows.json")
    done = {}
    if os.path.exists(cache):            # the grid and the reference do not depend on the search: each runs once
        with open(cache) as fh:
            done = {tuple(r["setting"]): r | {"setting": Setting(*r["setting"])} for r in json.load(fh)}
    for st in list(grid(a.case, g)) + [ref]:
        if astuple(st) in done:
            g.rows.append(done[astuple(st)])
        else:
            g.run(st, "grid" if st != ref else "reference")
    with open(cache, "w") as fh:
        json.dump([r | {"setting": list(astuple(r["setting"]))} for r in g.rows], fh)
    rr = g.rows[-1]
    grid_wall = sum(r["wall_s"] for r in g.rows)
    if "quantity" not in rr:
        sys.exit(f"the reference failed: {rr['message']}")
    q_ref = rr["quantity"]
    true = lambda r: abs(r["quantity"] - q_ref) / abs(q_ref)  # noqa: E731
    ok = [r for r in g.rows if "quantity" in r and r is not rr and true(r) <= a.target]
    cheapest = min(ok, key=lambda r: r["solve_s"]) if ok else None
    b = summary["best"]
    lines = [f"# verify_price: {a.case}, target {a.target:g}, {time.strftime('%Y-%m-%d')}", "",
             f"reference ({ref.label()}, {rr['tets']:,} tets): {watch} = {q_ref:.9g}", ""]
    if b is None:
        lines.append("the search recommended nothing")
    else:
        lines.append(f"recommended: {b['setting'].label()}: q = {b['quantity']:.9g}, estimated error "
                     f"{b['est_total']:.3g}, true error {true(b):.3g} ({'meets' if true(b) <= a.target else 'MISSES'} "
                     f"the target), solve {b['solve_s']:.3g} s")
    if cheapest is not None:
        lines.append(f"cheapest grid setting meeting the target: {cheapest['setting'].label()}: true error "
                     f"{true(cheapest):.3g}, solve {cheapest['solve_s']:.3g} s")
    if b is not None and cheapest is not None:
        lines.append(f"cost ratio recommended / cheapest: {b['solve_s'] / cheapest['solve_s']:.3g} (goal <= 2)")
    lines += [f"search: {len(s.rows)} runs, {search_wall:.1f} s wall; grid: {len(g.rows) - 1} runs, "
              f"{grid_wall - rr['wall_s']:.1f} s "
              f"wall; ratio {search_wall / (grid_wall - rr['wall_s']):.3g} (goal <= 0.2)", "",
              "| grid setting | tets | q | true error | solve s |", "|---|---|---|---|---|"]
    for r in g.rows:
        if "quantity" in r:
            lines.append(f"| {r['setting'].label()} | {r['tets']} | {r['quantity']:.9g} | {true(r):.3g} | "
                         f"{r['solve_s']:.3g} |")
        else:
            lines.append(f"| {r['setting'].label()} | {r['tets']} | failed: {r['message'][:60]} | | |")
    with open(os.path.join(out, "verify.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines[:8]))


if __name__ == "__main__":
    main()
