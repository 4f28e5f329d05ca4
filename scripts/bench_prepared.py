"""Set-up time and memory per rank of a mesh read by rank 0 (.msh) against a prepared mesh every rank reads its slice
of (issue 44 item 4), against mesh size and rank count.

    python scripts/bench_prepared.py OUT [--boxes 50x20x20,100x40x40] [--ranks 1,2,4] [--setup-only] [--order 2]
        [--mpiexec mpiexec]

Each box: a Kuhn-split box of NXxNYxNZ hexes (6 tets each; scripts/bench_output_ranks.py) written as .msh, then
`hyperelastic mesh BOX.msh --prepare -o BOX.h5` (timed once: the serial step a user pays once per mesh). Each run:
`bend` with -mesh BOX.msh or -mesh BOX.h5, one step (-dt 0.01 -final_time 0.01), CG + GAMG, -log_view. Printed per
run: tets, ranks, input, the Setup stage's seconds (PETSc's max over ranks: reading, checking, distributing, the
space, the operator's set-up), wall, and the peak resident memory of rank 0 and of the median and smallest rank (MB,
getrusage; the output's peak_rss_mb_per_rank). Ranks beyond the cores are oversubscribed: their seconds are not a
machine's, their memory is. --order 2: the box's cells elevated (10-node, straight-sided). --setup-only: no step
(-final_time 0: the model, the output's first frame, no Krylov solve nor preconditioner), for memory on many
oversubscribed ranks."""
import argparse
import os
import subprocess
import sys
import time

import h5py
import numpy as np

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from scripts.bench_output import stages  # noqa: E402
from scripts.bench_output_ranks import kuhn_box  # noqa: E402

import launch  # noqa: E402     (the device machine runs the package from PYTHONPATH)


def run(cmd):
    """(wall seconds, standard error) of a command that must succeed (else the script exits with its error)."""
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode:
        sys.exit(f"failed: {' '.join(map(str, cmd))}\n{p.stderr[-2000:]}")
    return time.perf_counter() - t, p.stderr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--boxes", default="50x20x20,100x40x40")
    ap.add_argument("--ranks", default="1,2,4")
    ap.add_argument("--setup-only", action="store_true")
    ap.add_argument("--order", type=int, default=1, help="2: quadratic tetrahedra (the linear box elevated)")
    ap.add_argument("--mpiexec", default=os.path.join(os.path.dirname(sys.executable), "mpiexec"))
    a = ap.parse_args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    print(f"{'tets':>9} {'ranks':>5} {'input':>8} {'Setup s':>8} {'wall s':>7} {'rank0 MB':>9} {'median MB':>9} "
          f"{'min MB':>7} {'rank0/median':>12}", flush=True)
    for box in a.boxes.split(","):
        nx, ny, nz = map(int, box.split("x"))
        msh, prep = os.path.join(out, f"box_{box}.msh"), os.path.join(out, f"box_{box}.h5")
        tets = kuhn_box(nx, ny, nz, msh)
        t_prep, _ = run(launch.command(["mesh", msh, "--prepare", "-o", prep]))
        print(f"# {tets} tets: --prepare {t_prep:.1f} s (once per mesh)", flush=True)
        for n in map(int, a.ranks.split(",")):
            for kind, mesh in (("msh", msh), ("prepared", prep)):
                res, log = os.path.join(out, f"run_{box}_{n}_{kind}.h5"), os.path.join(out, "log.txt")
                end = "0" if a.setup_only else "0.01"
                cmd = ["run", "bend", "-mesh", mesh, "-dt", "0.01", "-final_time", end, "-ksp_type", "cg",
                       "-pc_type", "gamg", "-order", a.order, "-output", res, "-log_view", f":{log}"]
                wall, _ = run(launch.command(cmd, n, a.mpiexec))
                with h5py.File(res) as f:
                    mem = np.asarray(f.attrs["peak_rss_mb_per_rank"], float)
                    assert f.attrs["mesh_read"] == ("slices" if kind == "prepared" else "rank 0")
                med = float(np.median(mem))
                print(f"{tets:>9} {n:>5} {kind:>8} {stages(log).get('Setup', float('nan')):>8.2f} {wall:>7.1f} "
                      f"{mem[0]:>9.0f} {med:>9.0f} {mem.min():>7.0f} {mem[0] / med:>12.2f}", flush=True)


if __name__ == "__main__":
    main()
