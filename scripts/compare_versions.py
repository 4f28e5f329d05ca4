"""Same answers before and after a change: runs every built-in scene (and a set of variants: GAMG, the
other Jacobian modes, -integrator ts, regions, loads) with the code of a git revision and with this
checkout, and compares the trajectories (positions of every frame), bitwise or to a relative tolerance.

    .venv/bin/python scripts/compare_versions.py REV [--out DIR] [--jobs N] [--only NAME,...]

REV is checked out into a temporary git worktree whose kernels are built with this venv's Python; both
versions run the same command lines (hyperelastic run ... -quiet) in separate processes. Prints one line per
case (bitwise / max relative difference / a failure on either side) and exits 1 if any case differs by more
than its tolerance (1e-14 relative; 1e-12 with GAMG, whose set-up sums in a different order when anything
about the matrix's creation changes)."""
import argparse
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

import launch

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ROOT + "/options/scenes"
EXAMPLES = ROOT + "/examples"
GAMG = ["-options_file", ROOT + "/options/gamg.opts"]

# name: (arguments after `run`, tolerance); every built-in scene, then variants that reach other paths
CASES = {s[:-5]: ([s[:-5]], 1e-14) for s in sorted(os.listdir(SCENES)) if s.endswith(".opts")}
CASES.update({
    "bend_gamg": (["bend", "-level", "3", "-final_time", "0.2"] + GAMG, 1e-12),
    "bend_shell": (["bend", "-jacobian", "shell", "-final_time", "0.2"], 1e-14),
    "bend_coo": (["bend", "-assembly", "coo", "-operator_storage", "aij", "-final_time", "0.2"], 1e-14),
    "bend_mf_operator": (["bend", "-snes_mf_operator", "-ksp_type", "gmres", "-final_time", "0.1"], 1e-14),
    "bend_neohookean": (["bend", "-material", "neohookean", "-final_time", "0.2"], 1e-14),
    "bend2_quasistatic": (["bend2", "-quasistatic", "-dt", "0.25", "-material", "neohookean"], 1e-14),
    "twist_ts": (["twist", "-integrator", "ts", "-final_time", "0.2"], 1e-14),
    "spin_energy_momentum": (["spin", "-integrator", "ts", "-energy_momentum", "-final_time", "0.2",
                              "-material", "neohookean"], 1e-14),
    "bend_loads": (["bend", "-effects", "elasticity,inertia,damping,fixed,traction,loads", "-loads", "a,b", "-a_traction",
                    "0,-3000,0", "-a_faces", "right", "-b_pressure", "200", "-b_faces", "top", "-b_time", "t",
                    "-final_time", "0.2"], 1e-14),
    "sag_lumped_rayleigh": (["sag", "-mass", "lumped", "-rayleigh_alpha", "0.5", "-rayleigh_beta", "1e-4",
                             "-final_time", "0.2"], 1e-14),
    "bend_projection_2ranks": (["-np2", "bend", "-material", "snh", "-hessian_projection", "-final_time", "0.1"],
                               1e-14),
    "bimaterial": (["MESH:bimaterial.geo:0.125", EXAMPLES + "/bimaterial.opts"], 1e-14),
    "bend_p2": (["bend", "-order", "2", "-final_time", "0.1"], 1e-14),
    "bend2_p2_quasistatic_gamg": (["bend2", "-order", "2", "-quasistatic", "-dt", "0.25", "-material", "neohookean"]
                                  + GAMG, 1e-12),
    "cook_mixed": (["MESH:cook.geo:8", EXAMPLES + "/cook.opts", "-order", "2", "-formulation", "mixed", "-final_time",
                    "0.5"], 1e-12),
    "bend2_mixed_2ranks": (["-np2", "bend2", "-order", "2", "-formulation", "mixed", "-material", "neohookean_split",
                            "-nu", "0.49", "-quasistatic", "-dt", "0.5"], 1e-12),
    # contact's and rigid faces' paths through the solver (limiters, start states, adaptive stiffness, couplings)
    "drop_floor_adaptive": (["drop_floor", "-contact_kappa", "adaptive", "-final_time", "0.6"], 1e-14),
    "drop_floor_ts": (["drop_floor", "-integrator", "ts", "-final_time", "0.6"], 1e-14),
    "bend_box_friction": (["bend", "-quasistatic", "-dt", "0.25", "-obstacle", "box:3,-4,-4,6,-2.3,4",
                           "-contact_friction", "0.3"], 1e-14),
    "stack_self_contact": (["MESH:stack.geo:0.25", EXAMPLES + "/stack.opts"], 1e-14),
    "invert_self_contact": (["invert", "-contact_self", "-final_time", "0.15", "-dt", "0.05"], 1e-14),
    "bend_rigid_loaded": (["bend", "-effects", "elasticity,fixed,rigid", "-fix", "left", "-rigid", "right",
                           "-rigid_fy", "-2000*t", "-quasistatic", "-dt", "0.25"], 1e-14),
    "bend_p2_static_default": (["bend", "-order", "2", "-quasistatic", "-dt", "0.5", "-level", "2"], 1e-6),
})


def worktree(rev, where):
    """A worktree of `rev` at `where` with its kernels built (setup.py build_ext --inplace)."""
    subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", where, rev], check=True,
                   capture_output=True)
    subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--inplace"], cwd=where, check=True,
                   capture_output=True)


def run(code, args, out, mesh_dir):
    """Run `hyperelastic run ARGS` with the package at `code`; (returncode, stderr's last line)."""
    nprocs, extra = 1, []
    if args[0] == "-np2":
        nprocs, args = 2, args[1:]
    if args[0].startswith("MESH:"):
        _, geo, size = args[0].split(":")
        mesh = os.path.join(mesh_dir, geo.replace(".geo", ".msh"))
        if not os.path.exists(mesh):
            launch.ok(["mesh", os.path.join(EXAMPLES, geo), "--size", size, "-o", mesh], code=code)
        args, extra = args[1:], ["-mesh", mesh]
    p, _ = launch.run(["run", *args, *extra, "-quiet", "-output", out], nprocs=nprocs, code=code, cwd=mesh_dir)
    return p.returncode, (p.stderr.strip().splitlines() or [""])[-1]


def compare(a, b):
    """(same number of frames, max |x_a - x_b| / max |x_b|) of two outputs."""
    def x(f):             # (in the input order: a per-rank output's rows put back through mesh/input_index)
        return f["x"][:][:, np.argsort(f["mesh/input_index"][:])] if "mesh/input_index" in f else f["x"][:]
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        xa, xb = x(fa), x(fb)
    if xa.shape != xb.shape:
        return False, np.inf
    return True, float(np.abs(xa - xb).max() / max(np.abs(xb).max(), 1e-300))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", help="the git revision to compare with (e.g. HEAD, main~3)")
    ap.add_argument("--out", default=None, help="directory for the outputs (default: a temporary one)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default="", help="comma-separated case names")
    a = ap.parse_args(argv)
    out = a.out or tempfile.mkdtemp(prefix="compare_")
    os.makedirs(out, exist_ok=True)
    old = os.path.join(out, "old_checkout")
    if not os.path.isdir(old):
        worktree(a.rev, old)
    cases = {k: v for k, v in CASES.items() if not a.only or k in a.only.split(",")}

    def one(item):
        name, (args, tol) = item
        res = []
        for tag, code in (("old", old), ("new", ROOT)):
            res.append(run(code, args, os.path.join(out, f"{name}_{tag}.h5"), out))
        if res[0][0] or res[1][0]:
            return name, f"exit old {res[0][0]} new {res[1][0]}: {res[0][1] or res[1][1]}", res[0][0] != res[1][0]
        same, rel = compare(os.path.join(out, f"{name}_new.h5"), os.path.join(out, f"{name}_old.h5"))
        text = "bitwise" if rel == 0 else f"max relative difference {rel:.2e}" if same else "frame counts differ"
        return name, text, not same or rel > tol

    bad = 0
    with ThreadPoolExecutor(a.jobs) as ex:
        for name, text, failed in ex.map(one, cases.items()):
            bad += failed
            print(f"{name:24s} {text}{'  <-- beyond tolerance' if failed else ''}", flush=True)
    subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", old], capture_output=True)
    print(f"{len(cases) - bad} of {len(cases)} cases the same")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
