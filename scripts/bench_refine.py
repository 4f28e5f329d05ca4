"""Set-up time and memory per rank of -refine K (issue 44 item 3: the mesh distributed coarse, every rank refining
its own part) against reading a fine mesh of the same size (rank 0 reads the .msh; every rank its slice of the
prepared file), against refinement level and rank count.

    python scripts/bench_refine.py OUT [--coarse 25x10x10] [--levels 1,2,3] [--ranks 1,2,4] [--compare 1,2]
        [--setup-only] [--order 2] [--mpiexec mpiexec]

The coarse mesh: a Kuhn-split box of NXxNYxNZ hexes (6 tets each; scripts/bench_output_ranks.py) as .msh; each run
`bend -mesh COARSE.msh -refine K`, one step (-dt 0.01 -final_time 0.01; --setup-only: none), CG + GAMG, -log_view.
--compare K: also the Kuhn box of 2^K times the hexes per axis (8^K times the tets, the same count) as .msh and
prepared. Printed per run: tets, ranks, input, rank 0's serial read of the coarse mesh and the refinement's seconds
(the start-up note), the refinement's rate per rank, the Setup stage's seconds (PETSc's max over ranks), wall, peak
resident memory of rank 0 and the median rank (MB). Ranks beyond the cores are oversubscribed: their memory is a
machine's, their seconds are not."""
import argparse
import os
import re
import sys

import h5py
import numpy as np

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from scripts.bench_output import stages  # noqa: E402
from scripts.bench_output_ranks import kuhn_box  # noqa: E402
from scripts.bench_prepared import run  # noqa: E402

import launch  # noqa: E402     (the device machine runs the package from PYTHONPATH)
NOTE = re.compile(r"refined on \d+ rank\(s\) in ([0-9.]+) s \(([0-9]+)k tetrahedra/s a rank(?:; the coarse mesh "
                  r"read on rank 0 in ([0-9.]+) s)?")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--coarse", default="25x10x10")
    ap.add_argument("--levels", default="1,2,3")
    ap.add_argument("--ranks", default="1,2,4")
    ap.add_argument("--compare", default="1,2", help="levels whose fine mesh is also read (.msh and prepared)")
    ap.add_argument("--setup-only", action="store_true")
    ap.add_argument("--order", type=int, default=1)
    ap.add_argument("--mpiexec", default=os.path.join(os.path.dirname(sys.executable), "mpiexec"))
    a = ap.parse_args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    nx, ny, nz = map(int, a.coarse.split("x"))
    coarse = os.path.join(out, f"coarse_{a.coarse}.msh")
    n0 = kuhn_box(nx, ny, nz, coarse)
    print(f"# coarse {a.coarse}: {n0} tets; order {a.order}; {'set-up only' if a.setup_only else 'one step'}")
    print(f"{'tets':>9} {'ranks':>5} {'input':>10} {'read0 s':>7} {'refine s':>8} {'k tet/s':>7} {'Setup s':>8} "
          f"{'wall s':>7} {'rank0 MB':>9} {'median MB':>9} {'rank0/med':>9}", flush=True)
    compare = set(map(int, a.compare.split(","))) if a.compare else set()
    for k in map(int, a.levels.split(",")):
        inputs = [(f"refine {k}", coarse, ["-refine", str(k)])]
        if k in compare:
            f = 2 ** k
            fine = os.path.join(out, f"fine_{k}.msh")
            kuhn_box(nx * f, ny * f, nz * f, fine)
            t_prep, _ = run(launch.command(["mesh", fine, "--prepare", "-o", fine[:-4] + ".h5"]))
            print(f"# fine {nx * f}x{ny * f}x{nz * f}: --prepare {t_prep:.1f} s (once per mesh)", flush=True)
            inputs += [("msh", fine, []), ("prepared", fine[:-4] + ".h5", [])]
        for n in map(int, a.ranks.split(",")):
            for kind, mesh, extra in inputs:
                res, log = os.path.join(out, f"run_{k}_{n}.h5"), os.path.join(out, "log.txt")
                end = "0" if a.setup_only else "0.01"
                cmd = ["run", "bend", "-mesh", mesh, *extra, "-dt", "0.01", "-final_time", end, "-ksp_type", "cg",
                       "-pc_type", "gamg", "-order", a.order, "-output", res, "-log_view", f":{log}"]
                wall, err = run(launch.command(cmd, n, a.mpiexec))
                with h5py.File(res) as fh:
                    mem = np.asarray(fh.attrs["peak_rss_mb_per_rank"], float)
                    tets = fh["mesh/tetra"].shape[0]
                m = NOTE.search(err)
                read0, ref, rate = ((float(m.group(3) or 0), float(m.group(1)), m.group(2)) if m else
                                    (float("nan"), float("nan"), "-"))
                med = float(np.median(mem))
                print(f"{tets:>9} {n:>5} {kind:>10} {read0:>7.2f} {ref:>8.2f} {rate:>7} "
                      f"{stages(log).get('Setup', float('nan')):>8.2f} {wall:>7.1f} {mem[0]:>9.0f} {med:>9.0f} "
                      f"{mem[0] / med:>9.2f}", flush=True)


if __name__ == "__main__":
    main()
