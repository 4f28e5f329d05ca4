"""The mixed formulation's solver and accuracy (issue 33), on Lame's thick-walled cylinder (examples/cylinder.geo,
plane strain, internal pressure): Krylov iterations per Newton step over mesh refinements and over kappa/mu,
for the default field split and the alternatives given with --variants; the radial displacement's error
against the closed form, beside displacement-only P1 and P2 on the same meshes.

    .venv/bin/python scripts/bench_mixed.py [--sizes 0.04,0.02,0.01] [--ratios 10,1e2,1e4,1e6]
        [--variants NAME=OPTS;...] [--displacement] [--out DIR]

Prints one row per run: mesh size, tets, kappa/mu, variant, Newton iterations, Krylov iterations per Newton
step, solve seconds, max relative error of u_r over the nodes."""
import argparse
import os
import shlex
import sys
import tempfile

import h5py
import numpy as np

import launch

ROOT = launch.ROOT
A_IN, B_OUT, MU, P = 0.1, 0.2, 1e6, 1e2


def lame_ur(r, mu, kappa):
    """Plane strain Lame: u_r = P a^2/(2 mu (b^2 - a^2)) ((1 - 2 nu) r + b^2/r), nu = (3k - 2mu)/(2(3k + mu))."""
    nu = 0.5 if np.isinf(kappa) else (3 * kappa - 2 * mu) / (2 * (3 * kappa + mu))
    return P * A_IN ** 2 / (2 * mu * (B_OUT ** 2 - A_IN ** 2)) * ((1 - 2 * nu) * r + B_OUT ** 2 / r)


def mesh(size, out_dir):
    path = os.path.join(out_dir, f"cyl_{size:g}.msh")
    if not os.path.exists(path):
        launch.ok(["mesh", os.path.join(ROOT, "examples", "cylinder.geo"), "--size", size, "--order", 2, "-o", path])
    return path


def run(msh, ratio, order, formulation, extra, out):
    kappa = np.inf if ratio == np.inf else ratio * MU
    args = ["run", "bend", "-mesh", msh, "-order", str(order), "-material", "neohookean_split", "-mu", str(MU),
            "-kappa", str(1e30 if ratio == np.inf else kappa), "-E", str(2.9 * MU), "-nu", "0.45",
            "-quasistatic", "-dt", "1", "-final_time", "1",
            "-effects", "elasticity,fixed,pressure", "-fix", "xsym:x,ysym:y,bottom:z,top:z", "-pressure", str(P),
            "-pressure_faces", "inner", "-snes_rtol", "1e-10", "-output", out, "-quiet"] + extra
    args += ["-formulation", formulation] + (["-incompressible"] if ratio == np.inf else [])
    p, _ = launch.run(args)
    if p.returncode:
        return None, p.stderr.strip().splitlines()[-1]
    with h5py.File(out, "r") as f:
        s = f["stats"]
        newton, ksp, wall = int(s["newton_its"][-1]), int(s["ksp_its"][-1]), float(s["wall_s"][-1])
        X = f["mesh/points"][:]
        u = f["x"][-1] - X
        ntet = f["mesh/tetra"].shape[0]
    r = np.hypot(X[:, 0], X[:, 1])
    ur = (u[:, 0] * X[:, 0] + u[:, 1] * X[:, 1]) / r
    err = float(np.abs(ur / lame_ur(r, MU, kappa) - 1).max())
    return (ntet, newton, ksp / max(newton, 1), wall, err), None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="0.04,0.02,0.01")
    ap.add_argument("--ratios", default="10,1e2,1e4,1e6,inf")
    ap.add_argument("--variants", default="default=")
    ap.add_argument("--displacement", action="store_true", help="also displacement-only P1 and P2 (CG + GAMG)")
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    out_dir = a.out or tempfile.mkdtemp(prefix="bench_mixed_")
    os.makedirs(out_dir, exist_ok=True)
    variants = [v.split("=", 1) for v in a.variants.split(";") if v]
    print(f"{'size':>6} {'tets':>7} {'k/mu':>6} {'variant':<18} {'newton':>6} {'ksp/newton':>10} {'solve s':>8} "
          f"{'max err u_r':>11}", flush=True)
    for size in map(float, a.sizes.split(",")):
        msh = mesh(size, out_dir)
        for ratio in (float(x) for x in a.ratios.split(",")):
            runs = [(f"mixed {name}", 2, "mixed", shlex.split(opts)) for name, opts in variants]
            if a.displacement and ratio != np.inf:
                gamg = ["-options_file", os.path.join(ROOT, "options", "gamg.opts")]
                runs += [("P1 displacement", 1, "displacement", gamg), ("P2 displacement", 2, "displacement", gamg)]
            for name, order, form, extra in runs:
                res, err = run(msh, ratio, order, form, extra, os.path.join(out_dir, "o.h5"))
                if res is None:
                    print(f"{size:6g} {'':>7} {ratio:6g} {name:<18} failed: {err}", flush=True)
                    continue
                ntet, newton, kpn, wall, e = res
                print(f"{size:6g} {ntet:7d} {ratio:6g} {name:<18} {newton:6d} {kpn:10.1f} {wall:8.2f} {e:11.2e}",
                      flush=True)


if __name__ == "__main__":
    sys.exit(main())
