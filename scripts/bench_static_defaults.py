"""The default solver of quasi-static runs (issue 34): every quasi-static example part with the default options
(CG or GMRES + Jacobi, switching to GAMG when a quasi-static Krylov solve runs out of iterations), with an
explicit -pc_type jacobi (the default before: no switch), with options/gamg.opts and with GAMG as the default
would set it; each a real `hyperelastic run`; prints outcome, wall seconds, Newton steps and Krylov iterations
per Newton step as a markdown table.

    python scripts/bench_static_defaults.py [--out DIR] [--only lbracket,bracket,...] [--order 2]

--order 2: every part on quadratic tetrahedra (their default is then CG + p-multigrid; options/pmg.opts joins the
variants).

Parts: a steel L-bracket (0.2 m arms, 2 cm thick; the top of its upright clamped, 1e5 Pa on its arm's top face:
the user report of issue 34), examples/bracket (aluminium, two sizes), Cook's membrane (rubber, mixed where
the formulation rule takes it), the step-44 block, and a STEP part (a steel plate with a hole, by gmsh).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from hyperelastic.studies.measure import read_cost  # noqa: E402

import launch  # noqa: E402

LBRACKET = """// an L-bracket in metres: arm x 0..0.2 (z 0..0.02), upright x 0..0.02 (z 0..0.2), 0.05 thick in y
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.2, 0.05, 0.02};
Box(2) = {0, 0, 0, 0.02, 0.05, 0.2};
BooleanUnion{ Volume{1}; Delete; }{ Volume{2}; Delete; }
"""
STEP = """
import sys, gmsh
gmsh.initialize(); gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.occ.addBox(0, 0, 0, 0.1, 0.02, 0.03); gmsh.model.occ.addCylinder(0.05, 0.01, 0, 0, 0, 0.03, 0.005, 2)
gmsh.model.occ.cut([(3, 1)], [(3, 2)]); gmsh.model.occ.synchronize(); gmsh.write(sys.argv[1]); gmsh.finalize()
"""
STEEL = ["-material", "stvk", "-E", "2.1e11", "-nu", "0.3", "-rho", "7850"]
STATIC = ["-effects", "elasticity,fixed,pressure", "-quasistatic", "-dt", "0.25", "-final_time", "1"]
VARIANTS = {"default": [], "jacobi (no switch)": ["-pc_type", "jacobi"],
            "options/gamg.opts": ["-options_file", os.path.join(ROOT, "options", "gamg.opts")],
            "gamg (-pc_type gamg)": ["-pc_type", "gamg", "-pc_gamg_agg_nsmooths", "1", "-mg_levels_ksp_type",
                                     "chebyshev", "-mg_levels_pc_type", "jacobi"]}


def hyper(args, check=False, timeout=None):
    p = launch.ok(args)[0] if check else launch.run(args, timeout=timeout)[0]
    return p


def cases(d):
    """{name: (mesh, run arguments)}, meshing what is needed."""
    out = {}
    with open(os.path.join(d, "lbracket.geo"), "w") as fh:
        fh.write(LBRACKET)
    for name, geo, size in (("lbracket", os.path.join(d, "lbracket.geo"), 0.006),
                            ("bracket", os.path.join(ROOT, "examples", "bracket.geo"), 0.006),
                            ("bracket_fine", os.path.join(ROOT, "examples", "bracket.geo"), 0.003),
                            ("cook", os.path.join(ROOT, "examples", "cook.geo"), 2.0),
                            ("block", os.path.join(ROOT, "examples", "block.geo"), 0.1)):
        msh = os.path.join(d, name + ".msh")
        hyper(["mesh", geo, "--size", size, "-o", msh], check=True)
        out[name] = msh
    subprocess.run([sys.executable, "-c", STEP, os.path.join(d, "part.step")], check=True, capture_output=True)
    hyper(["mesh", os.path.join(d, "part.step"), "--size", 0.0025, "-o", os.path.join(d, "step.msh")], check=True)
    ex = lambda n: os.path.join(ROOT, "examples", n)  # noqa: E731
    return {
        "lbracket": ("bend", ["-mesh", out["lbracket"], *STEEL, *STATIC, "-fix", "z=0.2", "-pressure", "1e5",
                              "-pressure_faces", "box=0.02;0;0.02;0.2;0.05;0.02"]),
        "bracket": (ex("bracket.opts"), ["-mesh", out["bracket"]]),
        "bracket_fine": (ex("bracket.opts"), ["-mesh", out["bracket_fine"]]),
        "cook": (ex("cook.opts"), ["-mesh", out["cook"]]),
        "block": (ex("block.opts"), ["-mesh", out["block"]]),
        "step_part": ("bend", ["-mesh", os.path.join(d, "step.msh"), *STEEL, *STATIC, "-fix", "x=0", "-pressure",
                               "1e6", "-pressure_faces", "z=0.03"]),
        # the same part in the bend scene's soft material (E = 1 MPa) under a dead traction in one step: a
        # large deformation whose tangent turns indefinite
        "step_part_soft": ("bend", ["-mesh", os.path.join(d, "step.msh"), "-effects", "elasticity,fixed,traction",
                                    "-quasistatic", "-dt", "1", "-final_time", "1", "-traction", "0,0,-1e5",
                                    "-fix", "x=0", "-traction_face", "x=0.1"]),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=None)
    ap.add_argument("--only", default="")
    ap.add_argument("--order", default="1", choices=("1", "2"))
    a = ap.parse_args()
    variants = dict(VARIANTS, **({"options/pmg.opts": ["-options_file", os.path.join(ROOT, "options", "pmg.opts")]}
                                  if a.order == "2" else {}))
    d = a.out or tempfile.mkdtemp(prefix="static_defaults_")
    os.makedirs(d, exist_ok=True)
    todo = cases(d)
    only = [s for s in a.only.split(",") if s]
    print("| part | tets | solver | outcome | wall s | Newton steps | Krylov its / Newton step |")
    print("|---|---|---|---|---|---|---|")
    for name, (scene, args) in todo.items():
        if only and name not in only:
            continue
        for label, extra in variants.items():
            out = os.path.join(d, f"{name}_{label.split()[0].replace('/', '_')}.h5")
            t0 = time.perf_counter()
            p = hyper(["run", scene, *args, "-order", a.order, *extra, "-output", out, "-quiet"], timeout=1800)
            wall = time.perf_counter() - t0
            c = read_cost(out) if p.returncode == 0 else {}
            tets = h5py.File(out, "r")["mesh/tetra"].shape[0] if os.path.exists(out) else "?"
            outcome = "ok" if p.returncode == 0 else f"exit {p.returncode}: " + p.stderr.strip().splitlines()[-1][:90]
            its = c.get("ksp_its", np.nan) / max(c.get("newton_its", 0), 1) if c else np.nan
            print(f"| {name} | {tets} | {label} | {outcome} | {wall:.1f} | {c.get('newton_its', '-')} | {its:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
