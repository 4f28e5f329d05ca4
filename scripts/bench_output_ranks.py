"""The output's cost per frame by layout (issue 45): rank 0's share, the slowest rank's, and the bytes written,
against mesh size and rank count.

    python scripts/bench_output_ranks.py OUT [--boxes 25x10x10,50x20x20] [--ranks 1,2,4] [--layouts gather,ranks]
        [--steps 2] [--mpiexec mpiexec] [--code CHECKOUT]

Each run: `bend` on a Kuhn-split box [-5,5]x[-2,2]x[-2,2] of NXxNYxNZ hexes (6 tets each), -dt 0.01, a frame per
step, CG + GAMG, -log_view. Printed per run: tets, ranks, layout, frames, the Output stage's seconds per frame (the
slowest rank's, PETSc's max), HE_OutRank0 per frame (rank 0's HDF5 writes: the whole frame gathered, or the
metadata of the per-rank layout), HE_OutRankPart per frame (the slowest rank's own rows, per-rank layout),
HE_OutFields per frame (the cell fields), the bytes of the files (FILE.h5 and FILE.h5.d/) per frame, and wall.
Ranks beyond the cores are oversubscribed: their seconds are not a machine's, their bytes and rank 0's share are.
"""
import argparse
import os
import sys

import numpy as np

import launch  # noqa: E402

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from scripts.bench_output import stages  # noqa: E402


def kuhn_box(nx, ny, nz, path):
    """A box mesh of nx*ny*nz hexes, each split into 6 positively oriented tetrahedra around its main diagonal
    (Kuhn's subdivision), written as gmsh 2.2 through meshio."""
    import meshio
    g = [np.linspace(-5, 5, nx + 1), np.linspace(-2, 2, ny + 1), np.linspace(-2, 2, nz + 1)]
    pts = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    idx = np.arange(len(pts)).reshape(nx + 1, ny + 1, nz + 1)
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corner = [idx[i + a, j + b, k + c] for a, b, c in
              ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))]
    paths = ((1, 2), (2, 3), (3, 7), (7, 4), (4, 5), (5, 1))           # the hex's faces' walk around 0-6
    tets = np.concatenate([np.stack([corner[0], corner[a], corner[b], corner[6]], axis=1) for a, b in paths])
    P = pts[tets]
    vol = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    meshio.write(path, meshio.Mesh(pts, [("tetra", tets.astype(np.int64))]), file_format="gmsh22", binary=True)
    return len(tets)


def events(log, names):
    """{event: (count, seconds)} summed over the stages of -log_view (the time column is the max over ranks)."""
    out = {n: [0, 0.0] for n in names}
    with open(log) as fh:
        for line in fh:
            parts = line.split()
            if parts and parts[0] in out:
                out[parts[0]][0] += int(float(parts[1]))
                out[parts[0]][1] += float(parts[3])
    return out


def size(path):
    total = os.path.getsize(path) if os.path.exists(path) else 0
    d = path + ".d"
    if os.path.isdir(d):
        total += sum(os.path.getsize(os.path.join(d, f)) for f in os.listdir(d))
    return total


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--boxes", default="25x10x10,50x20x20")
    ap.add_argument("--ranks", default="1,2,4")
    ap.add_argument("--layouts", default="gather,ranks")
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--mpiexec", default=os.path.join(os.path.dirname(sys.executable), "mpiexec"))
    ap.add_argument("--code", default=None, help="a checkout whose package runs instead of this one (before/after)")
    a = ap.parse_args()
    a.out = os.path.abspath(a.out)
    os.makedirs(a.out, exist_ok=True)
    print(f"{'tets':>9} {'ranks':>5} {'layout':>7} {'frames':>6} {'Output s/fr':>11} {'rank0 s/fr':>10} "
          f"{'part s/fr':>9} {'fields s/fr':>11} {'MB/frame':>8} {'wall s':>7}", flush=True)
    for box in a.boxes.split(","):
        nx, ny, nz = map(int, box.split("x"))
        mesh = os.path.join(a.out, f"box_{box}.msh")
        ntet = kuhn_box(nx, ny, nz, mesh) if not os.path.exists(mesh) else 6 * nx * ny * nz
        for n in map(int, a.ranks.split(",")):
            for layout in a.layouts.split(","):
                tag = f"{box}_{n}_{layout}"
                path, log = os.path.join(a.out, f"{tag}.h5"), os.path.join(a.out, f"{tag}.log")
                cmd = ["run", "bend", "-mesh", mesh, "-dt", "0.01", "-final_time", 0.01 * a.steps,
                       "-frames_per_second", "100", "-output", path, "-output_layout", layout, "-quiet", "-ksp_type",
                       "cg", "-pc_type", "gamg", "-log_view", f":{log}"]
                p, wall = launch.run(cmd, n, cwd=a.out, launcher=a.mpiexec,    # (cwd: not the checkout's package)
                                     code=os.path.abspath(a.code) if a.code else None)
                if p.returncode:
                    print(f"{ntet:>9} {n:>5} {layout:>7} failed: {p.stderr.strip().splitlines()[-1:]}", flush=True)
                    continue
                ev = events(log, ("HE_OutRank0", "HE_OutRankPart", "HE_OutFields"))
                frames = a.steps + 1
                out = stages(log).get("Output", float("nan"))
                print(f"{ntet:>9} {n:>5} {layout:>7} {frames:>6} {out / a.steps:>11.4f} "
                      f"{ev['HE_OutRank0'][1] / frames:>10.4f} {ev['HE_OutRankPart'][1] / frames:>9.4f} "
                      f"{ev['HE_OutFields'][1] / frames:>11.4f} {size(path) / frames / 1e6:>8.2f} {wall:>7.1f}",
                      flush=True)
                for f in os.listdir(a.out):
                    if f.startswith(tag) and f.endswith((".h5", ".xdmf")):
                        os.remove(os.path.join(a.out, f))
                d = path + ".d"
                if os.path.isdir(d):
                    for f in os.listdir(d):
                        os.remove(os.path.join(d, f))
                    os.rmdir(d)


if __name__ == "__main__":
    main()
