"""The mixed formulation's Newton under large rotations (issue 49, item 3): Newton and Krylov iterations, rejected
attempts (halvings) and wall time of nearly incompressible runs, for the default Newton and the variants given with
--variants. Cases (quasi-static unless said; P2-P1, one rank):

    bracket    examples/bracket.opts, split Neo-Hookean rubber (kappa/mu = 1000), 973 tets, the full load 2e5 Pa in
               4 load steps (the base folds); bracket2e3 / bracket2e4: the same at 2e3 / 2e4 Pa; bracket_fine: the
               full load on 2,560 tets (--size 0.006); bracket_fine2e3: 2e3 Pa on those
    cook       examples/cook.opts on the 4 mm mesh (1,267 tets, nu = 0.4999, 4 load steps); cook2: on 2 mm (9,049)
    block      examples/block.opts on the 0.25 mesh (378 tets, 10 load steps)
    torsion    examples/torsion.opts on rod.geo --size 0.005 (588 curved tets, 90 degrees in 8 steps)
    lame       Lame's cylinder (scripts/bench_mixed.py's run) at 0.02, kappa/mu = 1e4, one step
    bend2      the hard-case matrix's bend2, split Neo-Hookean, nu = 0.4999, backward Euler, 20 steps of 0.01
    squeeze    the hard-case matrix's squeeze, split Neo-Hookean, nu = 0.4999, 30 steps of 0.01
    squeeze03  the same at nu = 0.3 (compressible: -formulation auto would not choose mixed; the matrix's hardest cell)

    .venv/bin/python scripts/bench_mixed_newton.py [--cases bracket,cook,...] [--variants "NAME=OPTS;..."]
        [--out DIR] [--jobs 2]

Prints one row per case and variant: Newton iterations, Krylov iterations, rejected attempts, wall seconds, and the
largest difference of the final displacement from the first variant's (relative to its largest value)."""
import argparse
import os
import shlex
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

import launch

ROOT = launch.ROOT
EX = os.path.join(ROOT, "examples")
RUBBER = ["-material", "neohookean_split", "-preset", "rubber"]
MATRIX = ["-level", "1", "-material", "neohookean_split", "-E", "1e6", "-dt", "0.01", "-order", "2",
          "-formulation", "mixed"]
MESHES = {"bracket": ("bracket.geo", "0.01"), "bracket6": ("bracket.geo", "0.006"), "cook": ("cook.geo", "4"),
          "cook2": ("cook.geo", "2"), "block": ("block.geo", "0.25"), "rod": ("rod.geo", "0.005"),
          "cyl": ("cylinder.geo", "0.02")}
CASES = {
    "bracket": ("bracket", [f"{EX}/bracket.opts"] + RUBBER),
    "bracket2e3": ("bracket", [f"{EX}/bracket.opts"] + RUBBER + ["-traction", "0,0,-2e3"]),
    "bracket2e4": ("bracket", [f"{EX}/bracket.opts"] + RUBBER + ["-traction", "0,0,-2e4"]),
    "bracket_fine": ("bracket6", [f"{EX}/bracket.opts"] + RUBBER),
    "bracket_fine2e3": ("bracket6", [f"{EX}/bracket.opts"] + RUBBER + ["-traction", "0,0,-2e3"]),
    "cook": ("cook", [f"{EX}/cook.opts"]),
    "cook2": ("cook2", [f"{EX}/cook.opts"]),
    "block": ("block", [f"{EX}/block.opts"]),
    "torsion": ("rod", [f"{EX}/torsion.opts"]),
    "lame": ("cyl", ["bend", "-material", "neohookean_split", "-mu", "1e6", "-kappa", "1e10", "-E", "2.9e6",
                     "-nu", "0.45", "-quasistatic", "-dt", "1", "-final_time", "1", "-effects",
                     "elasticity,fixed,pressure", "-fix", "xsym:x,ysym:y,bottom:z,top:z", "-pressure", "100",
                     "-pressure_faces", "inner", "-snes_rtol", "1e-10", "-formulation", "mixed"]),
    "bend2": (None, ["bend2"] + MATRIX + ["-nu", "0.4999", "-final_time", "0.2"]),
    "squeeze": (None, ["squeeze"] + MATRIX + ["-nu", "0.4999", "-final_time", "0.3"]),
    "squeeze03": (None, ["squeeze"] + MATRIX + ["-nu", "0.3", "-final_time", "0.3"]),
}


def mesh(name, out):
    if name is None:
        return []
    geo, size = MESHES[name]
    path = os.path.join(out, f"{name}.msh")
    if not os.path.exists(path):
        launch.ok(["mesh", os.path.join(EX, geo), "--size", size, "--order", "2", "-o", path])
    return ["-mesh", path]


def run(case, variant, opts, out):
    where, args = CASES[case]
    h5 = os.path.join(out, f"{case}-{variant}.h5")
    p, _ = launch.run(["run"] + args + mesh(where, out) + shlex.split(opts) + ["-quiet", "-output", h5])
    try:
        with h5py.File(h5, "r") as f:
            s = f["stats"]
            row = (int(s["newton_its"][:].sum()), int(s["ksp_its"][:].sum()), int(s["rejected"][:].sum()),
                   float(s["wall_s"][:].sum()))
            u = f[f"frames/{len(f['time']) - 1}/displacement"][:]
            t = float(f["time"][-1])
    except (OSError, KeyError):
        return None, None, p.stderr.strip().splitlines()[-1:] or ["no output"]
    return row + (t,), u, ([] if p.returncode == 0 else p.stderr.strip().splitlines()[-1:])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="bracket,cook,block,torsion,lame,bend2,squeeze")
    ap.add_argument("--variants", default="default=")
    ap.add_argument("--out", default=None)
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="mixed_newton_")
    os.makedirs(out, exist_ok=True)
    variants = [v.split("=", 1) for v in a.variants.split(";") if v]
    cases = a.cases.split(",")
    for c in cases:
        if c not in CASES:
            sys.exit(f"unknown case {c}: one of {', '.join(CASES)}")
        mesh(CASES[c][0], out)
    jobs = [(c, n, o) for c in cases for n, o in variants]
    with ThreadPoolExecutor(a.jobs) as pool:
        results = list(pool.map(lambda j: run(*j, out), jobs))
    print("| case | variant | Newton | Krylov | rejected | wall s | t reached | max diff |")
    print("|---|---|---|---|---|---|---|---|")
    first = {}
    for (c, n, _), (row, u, err) in zip(jobs, results):
        if row is None:
            print(f"| {c} | {n} | failed: {' '.join(err)} | | | | | |")
            continue
        ref = first.setdefault(c, u)
        diff = float(np.abs(u - ref).max() / max(np.abs(ref).max(), 1e-300)) if u.shape == ref.shape else np.nan
        note = f" ({err[0]})" if err else ""
        print(f"| {c} | {n} | {row[0]} | {row[1]} | {row[2]} | {row[3]:.1f} | {row[4]:g}{note} | {diff:.1e} |")


if __name__ == "__main__":
    main()
