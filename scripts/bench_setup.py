"""The set-up's cost per tetrahedron (issue 74 item 1): the Setup stage of `bend` on prepared Kuhn boxes of three sizes,
P1 and P2, in µs a tet at each size and as slopes between sizes (fixed costs not counted per tet), with peak memory.

    python scripts/bench_setup.py OUT [--p1 25x10x10,50x20x20,100x40x40] [--p2 20x8x8,40x16x16,60x24x24]
        [--ranks 1] [--profile 25] [--repeat 5] [--code CHECKOUT]

Each box: a Kuhn-split box of NXxNYxNZ hexes (6 tets each; scripts/bench_output_ranks.py), prepared once
(`hyperelastic mesh BOX.msh --prepare`: the serial step a user pays once per mesh, not counted). Each run: `bend
-mesh BOX.h5 -order K -final_time 0 -ksp_type cg -pc_type gamg -log_view` — the Setup stage is everything before the
first frame: the slices read, the space (for P2 the edge nodes), the labels, the kernels' geometry, the operator's
exact pattern and the map of the cells' blocks into it (no step: no Jacobian, no preconditioner set-up). Printed per
run: tets, ranks, Setup seconds (PETSc's max over ranks; the median of --repeat runs), µs a tet (Setup over the global tets, times the ranks: a
rank's cost per own tet), the slope from the previous size, peak RSS of rank 0 (MB). --profile N: cProfile of the
largest one-rank run of each order, its N largest cumulative entries inside hyperelastic. --code: run that checkout's
package (PYTHONPATH; its kernels built) instead of this one, for before/after."""
import argparse
import logging
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from scripts.bench_output import stages  # noqa: E402
from scripts.bench_output_ranks import kuhn_box  # noqa: E402

import launch  # noqa: E402


# (runs start in $TMPDIR: `python -m` puts the working directory first on sys.path, so a run started in a checkout
# would import that checkout's package whatever --code's PYTHONPATH says)
CWD = tempfile.gettempdir()


def profile(args, code, n, prof):
    """The n largest cumulative cProfile entries of hyperelastic's own functions in one run of `hyperelastic ARGS`
    (one rank; the profile written to prof)."""
    import pstats
    env = dict(os.environ, **({"PYTHONPATH": code} if code else {}))
    p = subprocess.run([sys.executable, "-m", "cProfile", "-o", prof] + launch.command(args)[1:], capture_output=True,
                       text=True, env=env, cwd=CWD)
    if p.returncode:
        sys.exit(f"failed: cProfile of hyperelastic {' '.join(map(str, args))}\n{p.stderr[-2000:]}")
    st = pstats.Stats(prof)
    rows = [(v[3], v[2], k) for k, v in st.stats.items() if "hyperelastic" in k[0] and "/scripts/" not in k[0]]
    for cum, tot, (path, line, name) in sorted(rows, reverse=True)[:n]:
        rel = path[path.rfind("hyperelastic/"):]
        print(f"#   {cum:7.2f} s cumulative {tot:7.2f} s own  {rel}:{line}({name})", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--p1", default="25x10x10,50x20x20,100x40x40")
    ap.add_argument("--p2", default="20x8x8,40x16x16,60x24x24")
    ap.add_argument("--ranks", default="1")
    ap.add_argument("--profile", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=1, help="runs per size: their median Setup (this VM varies ±15%%)")
    ap.add_argument("--code", default=None, help="a checkout whose package runs instead of this one")
    a = ap.parse_args()
    logging.getLogger().setLevel(logging.ERROR)       # (meshio's note that the box has no physical tags)
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    code = os.path.abspath(a.code) if a.code else None
    print(f"{'order':>5} {'tets':>9} {'ranks':>5} {'Setup s':>8} {'us/tet':>7} {'slope':>7} {'rank0 MB':>9}", flush=True)
    for order, boxes in ((1, a.p1), (2, a.p2)):
        if not boxes:
            continue
        for n in map(int, a.ranks.split(",")):
            prev = None
            for box in boxes.split(","):
                nx, ny, nz = map(int, box.split("x"))
                msh, prep = os.path.join(out, f"box_{box}.msh"), os.path.join(out, f"box_{box}.h5")
                if not os.path.exists(prep):
                    kuhn_box(nx, ny, nz, msh)
                    launch.ok(["mesh", msh, "--prepare", "-o", prep], code=code, cwd=CWD)
                res, log = os.path.join(out, f"run_{order}_{box}_{n}.h5"), os.path.join(out, "log.txt")
                args = ["run", "bend", "-mesh", prep, "-order", order, "-final_time", 0, "-ksp_type", "cg",
                        "-pc_type", "gamg", "-output", res, "-log_view", f":{log}"]
                setups = []
                for _ in range(a.repeat):
                    launch.ok(args, nprocs=n, code=code, cwd=CWD)
                    setups.append(stages(log)["Setup"])
                with h5py.File(res) as f:
                    tets, mem = f["mesh/tetra"].shape[0], np.asarray(f.attrs["peak_rss_mb_per_rank"], float)
                s = float(np.median(setups))
                slope = (f"{1e6 * n * (s - prev[1]) / (tets - prev[0]):>7.1f}" if prev else f"{'':>7}")
                print(f"{order:>5} {tets:>9} {n:>5} {s:>8.2f} {1e6 * n * s / tets:>7.1f} {slope} {mem[0]:>9.0f}",
                      flush=True)
                prev = (tets, s)
            if a.profile and n == 1:
                profile(args, code, a.profile, os.path.join(out, "setup.prof"))


if __name__ == "__main__":
    main()
