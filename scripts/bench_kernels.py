#!/usr/bin/env python
"""Element-kernel throughput on one core: tets/s of the residual (elastic forces), the exact K v
shell product and the 12x12 tangent values for COO, against MatMult of the assembled tangent.

    python scripts/bench_kernels.py                 # quick: L8 (~28k tets)
    python scripts/bench_kernels.py --full          # L8 and a ~700k-tet bar
    python scripts/bench_kernels.py --tets 200000 --material neohookean

Prints one table row per mesh; with --csv FILE also writes them as CSV.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def best(fn, reps, min_time=0.3):
    """Best-of wall time of fn() over `reps` runs (repeated until min_time has passed)."""
    times = []
    t_all = time.perf_counter()
    while len(times) < reps or time.perf_counter() - t_all < min_time:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if len(times) > 200:
            break
    return min(times)


def numpy_residual(prob, x):
    """The same elastic forces with numpy only (einsum + add.at): the reference path."""
    import numpy as np
    k, sc = prob.kernels, prob.scene
    xs = x.reshape(-1, 3)[k.cells]                                          # (nc, 4, 3)
    Ds = np.stack([xs[:, 1] - xs[:, 0], xs[:, 2] - xs[:, 0], xs[:, 3] - xs[:, 0]], axis=-1)
    Dminv = k.Dminv.reshape(-1, 3, 3)
    F = Ds @ Dminv
    P = sc.solid.material.P(F, sc.solid.constants)
    H = np.einsum("n,nij,naj->nia", k.vol, P, Dminv)                        # columns: forces on 1..3
    fe = np.concatenate([-H.sum(axis=2, keepdims=True), H], axis=2).transpose(0, 2, 1)
    f = np.zeros((len(x) // 3, 3))
    np.add.at(f, k.cells, fe)
    return f


def bench(mesh_arg, material, reps):
    import numpy as np
    from petsc4py import PETSc
    from hyperelastic.solving import jacobians
    from hyperelastic.app.model import build_model
    from hyperelastic.app.catalog import load_scene
    o = PETSc.Options()
    for k in list(o.getAll()):
        o.delValue(k)
    o.setValue("material", material)
    o.setValue("mesh", mesh_arg)
    t0 = time.perf_counter()
    prob = build_model(load_scene("bend")[0], PETSc.COMM_WORLD)
    setup_s = time.perf_counter() - t0
    x = prob.x0
    sp, sysm, k = prob.space, prob.system, prob.kernels
    rng = np.random.default_rng(0)
    xd = x + 0.01 * rng.standard_normal(x.shape)       # a deformed state
    w = rng.standard_normal(x.shape)
    f = np.zeros_like(x)
    nc = k.nc
    t_res = best(lambda: (f.fill(0.0), k.forces(xd, f)), reps)
    t_np = best(lambda: numpy_residual(prob, xd), 2)
    t_kv = best(lambda: (f.fill(0.0), k.kv(xd, w, f)), reps)
    vals = np.empty((nc, 12, 12))
    t_tan = best(lambda: k.tangent(xd, vals), reps)
    # full-system residual (all effects + scatter) and the assembled tangent
    X = sysm.global_state(xd)
    R = X.duplicate()
    t_sysres = best(lambda: sysm.residual(X, R), reps)
    sysm.linearize(X)
    fills = {}
    for name, op in (("coo", jacobians.Assembled(sysm)), ("setvalues", jacobians.AssembledChunked(sysm))):
        op.assemble()                                   # the pattern (and the direct map) once
        fills[name] = best(lambda: op.assemble(), max(2, reps // 3))
        actx = op
    A = actx.mat
    t_coo = fills["coo"]
    V, Y = X.duplicate(), X.duplicate()
    V.setRandom()
    t_mult = best(lambda: A.mult(V, Y), reps)
    S = jacobians.make(sysm, "shell").mat
    t_shell = best(lambda: S.mult(V, Y), reps)
    from hyperelastic.app.run import peak_rss_kib
    peak_mb = peak_rss_kib() / 1024.0
    return {"tets": nc, "vertices": sp.nlv, "setup_s": setup_s,
            "residual_Mtets_s": nc / t_res / 1e6, "numpy_residual_Mtets_s": nc / t_np / 1e6, "kv_Mtets_s": nc / t_kv / 1e6, "tangent_Mtets_s": nc / t_tan / 1e6,
            "system_residual_ms": 1e3 * t_sysres, "shell_mult_ms": 1e3 * t_shell, "coo_assemble_ms": 1e3 * t_coo,
            "setvalues_fill_ms": 1e3 * fills["setvalues"],
            "matmult_ms": 1e3 * t_mult, "mffd_over_matmult": t_sysres / t_mult,
            "peak_rss_MB": peak_mb}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="L8 and a ~700k-tet bar")
    ap.add_argument("--tets", type=int, action="append", help="also a bar with about this many tets")
    ap.add_argument("--material", default="stvk")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--csv", help="write the table as CSV")
    a = ap.parse_args()
    import petsc4py
    petsc4py.init([sys.argv[0]])
    from hyperelastic.mesh.generate import cached_bar, size_for_tets
    meshes = [("L8", cached_bar(8))]
    for n in (a.tets or []) + ([700000] if a.full else []):
        meshes.append((f"~{n // 1000}k", cached_bar(size=round(size_for_tets(n), 4))))
    cols = ["mesh", "tets", "numpy_residual_Mtets_s", "residual_Mtets_s", "kv_Mtets_s", "tangent_Mtets_s", "system_residual_ms",
            "shell_mult_ms", "coo_assemble_ms", "setvalues_fill_ms", "matmult_ms", "mffd_over_matmult", "peak_rss_MB"]
    print(f"# material {a.material}, one process; M tets/s = million tetrahedra per second (best of {a.reps})")
    print(" | ".join(cols))
    rows = []
    for name, path in meshes:
        r = bench(path, a.material, a.reps)
        r["mesh"] = name
        rows.append(r)
        print(" | ".join(f"{r[c]:.3g}" if isinstance(r[c], float) else str(r[c]) for c in cols), flush=True)
    if a.csv:
        import csv
        with open(a.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["mesh"] + [k for k in rows[0] if k != "mesh"])
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
