"""Every solver default against its alternatives (issue 69 item 4): P1, P2 and mixed P2-P1, dynamic and quasi-static,
small and large, each run with the application's default preconditioner and with the alternatives a user would try
(Jacobi, GAMG, p-multigrid where it applies; the field split's displacement block by GAMG or p-multigrid); every one a
real `hyperelastic run` on the bar (`bend`: clamped left end, a traction on the right end). Prints a markdown table:
outcome, wall seconds of the solve, Newton steps, Krylov iterations per Newton step, and which variant was fastest;
docs/defaults.md keeps the table and what each default was chosen by.

    python scripts/bench_defaults.py [--out DIR] [--only p1_dynamic_small,...] [--repeat N]

--table DIR: the table again from DIR/rows.json (a run's --out). --repeat N: each small or soft case's runs N times, the smallest solve time kept (default 3; the large ones once)."""
import argparse
import json
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from hyperelastic.core.data import OPTIONS_DIR  # noqa: E402
from hyperelastic.studies.experiments.runner import last_line, run_hyperelastic  # noqa: E402
from hyperelastic.studies.measure import read_cost  # noqa: E402

RECIPE = {k: ["-options_file", os.path.join(OPTIONS_DIR, k + ".opts")] for k in ("gamg", "pmg")}
JACOBI = ["-pc_type", "jacobi"]
STATIC = ["-quasistatic", "-dt", "0.25"]
MIXED = ["-formulation", "mixed", "-material", "neohookean_split", "-nu", "0.49", "-order", "2"]
SPLIT_GAMG = ["-fieldsplit_u_pc_type", "gamg"]

# name: (arguments after `run bend`, {variant: extra arguments}); "default" is the application's own choice. Sizes: the
# bar at level 3 (3,083 tets) and 11 (P1, ~220k tets) or 2 and 8 (P2 and mixed: ~1.8k and ~28k tets, 128k dofs: the
# size the DOLFINx comparison uses)
SMALL, LARGE = {1: 3, 2: 2}, {1: 11, 2: 8}
DYNAMIC_T = {"small": "0.5", "large": "0.02"}
CASES = {}
for order in (1, 2):
    alternatives = {"default": [], "jacobi": JACOBI, "gamg": RECIPE["gamg"]}
    if order == 2:
        alternatives["pmg"] = RECIPE["pmg"]
    for size, levels in (("small", SMALL), ("large", LARGE)):
        common = ["-level", str(levels[order]), "-order", str(order)]
        CASES[f"p{order}_dynamic_{size}"] = (common + ["-final_time", DYNAMIC_T[size]], alternatives)
        CASES[f"p{order}_static_{size}"] = (common + STATIC, alternatives)
# a hard case: a soft Neo-Hookean cantilever under four times bend's load in four steps (a large deformation whose
# tangent turns indefinite: where GAMG as a default failed, docs/defaults.md)
for order in (1, 2):
    alternatives = {"default": [], "jacobi": JACOBI, "gamg": RECIPE["gamg"]} | ({"pmg": RECIPE["pmg"]} if order == 2
                                                                                 else {})
    CASES[f"p{order}_static_soft"] = (["-level", "3", "-order", str(order), "-material", "neohookean", "-E", "2e5",
                                       "-traction", "0,-20000,0"] + STATIC, alternatives)
for size, level in (("small", 2), ("large", 8)):
    common = MIXED + ["-level", str(level)]
    mixed_alternatives = {"default": [], "split u: gamg": SPLIT_GAMG}
    CASES[f"mixed_dynamic_{size}"] = (common + ["-final_time", DYNAMIC_T[size]], mixed_alternatives)
    CASES[f"mixed_static_{size}"] = (common + STATIC, mixed_alternatives)


def measure(name, variant, args, out, repeat):
    best = None
    for i in range(repeat):
        path = os.path.join(out, f"{name}_{variant.replace(' ', '_').replace(':', '')}.h5")
        rc, err, wall = run_hyperelastic(["run", "bend"] + args + ["-output", path, "-quiet"], path, timeout=1800)
        row = {"case": name, "variant": variant, "rc": rc, "wall_s": wall,
               "message": "" if rc == 0 else last_line(err, rc)} | read_cost(path)
        if best is None or (rc == 0 and row.get("solve_s", 1e300) < best.get("solve_s", 1e300)):
            best = row
    return best


def table(rows):
    """The markdown table: each case's variants, and how the default's solve time compares with the fastest's."""
    lines = ["| case | tets | variant | outcome | solve [s] | steps (rejected) | Newton | Krylov / Newton | default / fastest |",
             "|---|---|---|---|---|---|---|---|---|"]
    by_case = {}
    for r in rows:
        by_case.setdefault(r["case"], []).append(r)
    for case, rs in by_case.items():
        ok = [r for r in rs if r["rc"] == 0 and not r.get("rejections")]
        best = min(ok, key=lambda r: r["solve_s"]) if ok else None
        default = next((r for r in ok if r["variant"] == "default"), None)
        for r in rs:
            outcome = "finished" if r["rc"] == 0 else f"failed: {r['message'][:60]}"
            its = r.get("ksp_its", 0) / max(r.get("newton_its", 0), 1)
            ratio = ""
            if r["variant"] == "default" and best is not None and default is not None:
                ratio = f"{default['solve_s'] / best['solve_s']:.2f} ({best['variant']})"
            lines.append(f"| {case} | {r.get('tets', '')} | {r['variant']} | {outcome} | "
                         f"{r.get('solve_s', float('nan')):.2f} | {r.get('steps', '')} ({r.get('rejections', '')}) | "
                         f"{r.get('newton_its', '')} | {its:.0f} | {ratio} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--only", default="")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--table", default=None)
    a = ap.parse_args(argv)
    if a.table:
        with open(os.path.join(a.table, "rows.json")) as fh:
            print(table(json.load(fh)))
        return
    out = a.out or tempfile.mkdtemp(prefix="bench_defaults_")
    os.makedirs(out, exist_ok=True)
    names = [n for n in CASES if not a.only or n in a.only.split(",")]
    rows = []
    for name in names:
        args, variants = CASES[name]
        for variant, extra in variants.items():
            r = measure(name, variant, args + extra, out, 1 if "large" in name else a.repeat)
            print(f"{name:22s} {variant:16s} rc={r['rc']} solve={r.get('solve_s', float('nan')):.2f}s "
                  f"newton={r.get('newton_its')} ksp={r.get('ksp_its')}", file=sys.stderr, flush=True)
            rows.append(r)
    with open(os.path.join(out, "rows.json"), "w") as fh:
        json.dump(rows, fh, indent=1)
    print(table(rows))


if __name__ == "__main__":
    main()
