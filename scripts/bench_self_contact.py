"""What self-contact (-contact_self, issue 46) costs beside the elastic work, and how its broad phase grows with the
contact surface.

    python scripts/bench_self_contact.py OUT [--sizes 0.25,0.125,0.0625] [--refine 0] [--final-time 0.4]

Part 1, per mesh size: examples/stack.geo meshed at that size (optionally -refine K), examples/stack.opts to
--final-time (the gap closed and both blocks squeezed), one rank; printed: tets, contact surface triangles (the two
facing faces, linear triangles), Newton iterations, the contact effect's seconds in its residuals and tangent products (its
`effect_contact_seconds` statistic, summed; not its objective, linearization and step-size calls, which part 2
times) against the elastic effect's, and the wall time.
Part 2, per size: on the faces of that run's last frame (pressed within dhat), the broad phase and pair build
(ipctk NormalCollisions.build), the barrier's gradient and Hessian, and one additive-CCD step size for a move of dhat
toward each other: seconds against the number of surface triangles (no quadratic growth: the ratio per triangle)."""
import argparse
import os
import time

import h5py
import numpy as np

import launch

ROOT = launch.ROOT


def best(fn, repeat=5):
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--sizes", default="0.25,0.125,0.0625")
    ap.add_argument("--refine", type=int, default=0)
    ap.add_argument("--final-time", type=float, default=0.4)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    import ipctk
    ipctk.set_num_threads(1)
    print("| size | tets | surface tris | Newton | contact s | elastic s | wall s | build s | grad s | hess s | CCD s | "
          "build us/tri |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for size in map(float, a.sizes.split(",")):
        msh = os.path.join(a.out, f"stack_{size:g}.msh")
        launch.ok(["mesh", os.path.join(ROOT, "examples", "stack.geo"), "--size", size, "-o", msh])
        h5 = os.path.join(a.out, f"stack_{size:g}.h5")
        for f in (h5, h5 + ".partial"):
            if os.path.exists(f):
                os.remove(f)
        t = time.perf_counter()
        launch.ok(["run", os.path.join(ROOT, "examples", "stack.opts"), "-mesh", msh, "-refine", a.refine,
                   "-final_time", a.final_time, "-output", h5])
        wall = time.perf_counter() - t
        with h5py.File(h5, "r") as f:
            st = {k: f["stats"][k][:] for k in f["stats"]}
            X, tets, x = f["mesh/points"][:], f["mesh/tetra"][:], f["x"][-1]
        faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
        key = np.sort(faces, axis=1)
        _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
        surf = faces[first[count == 1]]
        zc = X[surf].mean(axis=1)[:, 2]
        surf = surf[(zc > 1 - 1e-6) & (zc < 1.05 + 1e-6)]            # the two facing faces
        used = np.unique(surf)
        F = np.searchsorted(used, surf)
        V, V0 = x[used], X[used]
        mesh = ipctk.CollisionMesh(V0, ipctk.edges(F), F)
        dhat = 1e-3 * float(np.linalg.norm(X.max(0) - X.min(0)))
        c = ipctk.NormalCollisions()
        c.use_area_weighting = True
        c.collision_set_type = ipctk.NormalCollisions.CollisionSetType.IMPROVED_MAX_APPROX
        tb = best(lambda: c.build(mesh, V, dhat))
        P = ipctk.BarrierPotential(dhat, 1.0, True)
        tg = best(lambda: P.gradient(c, mesh, V))
        th = best(lambda: P.hessian(c, mesh, V, ipctk.PSDProjectionMethod.CLAMP))
        V1 = V.copy()
        V1[V0[:, 2] > 1.02, 2] -= dhat
        tc = best(lambda: ipctk.compute_collision_free_stepsize(mesh, V, V1, 0.0, None, ipctk.AdditiveCCD()))
        print(f"| {size:g} | {len(tets)} | {len(F)} | {int(st['newton_its'].sum())} | "
              f"{st['effect_contact_seconds'].sum():.2f} | {st['effect_elasticity_seconds'].sum():.2f} | {wall:.1f} | "
              f"{tb:.4f} | {tg:.4f} | {th:.4f} | {tc:.4f} | {1e6 * tb / len(F):.1f} |", flush=True)


if __name__ == "__main__":
    main()
