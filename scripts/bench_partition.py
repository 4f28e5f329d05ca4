"""Which partitioner by default (issue 44, item 2): `-partitioner morton` (a Z-curve cut into equal ranges) against
`metis` (METIS on the dual graph) on the bar, a plate with a hole, the bracket and Cook's membrane, on 2 ranks and
oversubscribed 4. Every run is a real `hyperelastic run` child process: a quasi-static Neo-Hookean bend (left face clamped, a
traction on the right face; the Cook mesh with its own scene, kappa = 400 MPa: nu = 0.4 rather than 0.4999, which locks P1), CG + GAMG (options/gamg.opts), P1. Prints per run:
cut faces (% of interior faces), ghost vertices (% of vertices), the largest part over the mean, Krylov iterations
per Newton step, seconds per Newton step (wall_s summed over the steps / Newton iterations) and the set-up seconds.

    .venv/bin/python scripts/bench_partition.py [--ranks 2,4] [--quick]
"""
import argparse
import json
import os
import sys
import tempfile

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from hyperelastic.studies.experiments.runner import run_hyperelastic  # noqa: E402
import launch  # noqa: E402

EX = os.path.join(ROOT, "examples")
GAMG = ["-options_file", os.path.join(ROOT, "options", "gamg.opts")]
BEND = ["bend", "-quasistatic", "-dt", "0.25", "-final_time", "1", "-material", "neohookean"]

# name: (mesh command args or None for the bar, scene args)
MESHES = {
    "bar": (None, BEND + ["-level", "9"]),
    "plate_hole": ([os.path.join(EX, "plate_hole.geo"), "--size", "0.003"], BEND),
    "bracket": ([os.path.join(EX, "bracket.geo"), "--size", "0.004"], BEND),
    "cook": ([os.path.join(EX, "cook.geo"), "--size", "1"], [os.path.join(EX, "cook.opts"), "-kappa", "400"]),
}


def run(args, nprocs, out):
    rc, err, wall = run_hyperelastic(["run"] + args + GAMG + ["-output", out, "-quiet"], out, nprocs)
    if rc:
        raise SystemExit(f"failed: run {' '.join(args)} on {nprocs} ranks\n{err}")
    with h5py.File(out, "r") as f:
        a = dict(f.attrs)
        s = {k: f["stats"][k][:] for k in ("newton_its", "ksp_its", "wall_s")}
        nv = f["mesh/points"].shape[0]
    q = json.loads(a["partition"])
    newton = max(int(s["newton_its"].sum()), 1)
    return {"cut": 100.0 * q["cut_faces"] / q["faces"], "cut_faces": q["cut_faces"],
            "ghost": 100.0 * (a["vertices_per_rank"].sum() - nv) / nv, "imbalance": q["imbalance"],
            "ksp_per_newton": s["ksp_its"].sum() / newton, "s_per_newton": s["wall_s"].sum() / newton,
            "setup": wall - s["wall_s"].sum(), "cells": int(a["cells_per_rank"].sum())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ranks", default="2,4")
    ap.add_argument("--quick", action="store_true", help="the bar and the plate only, 2 ranks")
    ap.add_argument("--meshes", default=",".join(MESHES), help="which of " + ", ".join(MESHES))
    ns = ap.parse_args()
    ranks = [2] if ns.quick else [int(r) for r in ns.ranks.split(",")]
    names = ["bar", "plate_hole"] if ns.quick else ns.meshes.split(",")
    with tempfile.TemporaryDirectory() as d:
        print(f"{'mesh':11s} {'tets':>7s} {'ranks':>5s} {'partitioner':>11s} {'cut faces':>15s} {'ghost v':>8s} "
              f"{'max/mean':>8s} {'KSP/Newton':>10s} {'s/Newton':>9s} {'set-up s':>8s}")
        for name in names:
            geo, args = MESHES[name]
            if geo is not None:
                msh = os.path.join(d, f"{name}.msh")
                launch.ok(["mesh"] + geo + ["-o", msh])
                args = args + ["-mesh", msh]
            for n in ranks:
                for part in ("morton", "metis"):
                    r = run(args + ["-partitioner", part], n, os.path.join(d, "out.h5"))
                    print(f"{name:11s} {r['cells']:7d} {n:5d} {part:>11s} {r['cut_faces']:7d} ({r['cut']:4.2f}%) "
                          f"{r['ghost']:7.2f}% {r['imbalance']:8.3f} {r['ksp_per_newton']:10.1f} "
                          f"{r['s_per_newton']:9.3f} {r['setup']:8.2f}", flush=True)


if __name__ == "__main__":
    main()
