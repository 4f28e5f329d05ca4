#!/usr/bin/env python
"""Peer benchmark (issue: performance, target 5): the same quasi-static Neo-Hookean problem solved by
scikit-fem and by hyperelastic, on the same P1 mesh.

Problem: the 10 x 4 x 4 bar, left end (x = -5) clamped, a dead-load traction t = (0, -T, 0) Pa on the
right end face (x = 5), compressible Neo-Hookean (Bonet & Wood 1997, sec. 6.4.3:
P = mu (F - F^-T) + lam ln J F^-T), E = 1e6 Pa, nu = 0.3, one load step, Newton to a relative
residual of 1e-10.

scikit-fem (`pip install -r requirements-bench.txt`; a benchmark dependency, not a runtime one):
residual and tangent written as its LinearForm / BilinearForm, vector P1 elements, Dirichlet rows
by `condense`, linear solves by its default `solve` (SciPy's sparse direct solver), plain Newton.
hyperelastic: `hyperelastic run bend -quasistatic -material neohookean ...`, exact tangent, CG + GAMG,
plain Newton (-snes_linesearch_type basic -inversion_guard 0, as scikit-fem; our defaults, backtracking
and the Neo-Hookean inversion guard, take 8 damped
steps here instead of 4).

Prints displacement agreement and time per Newton step, ours / theirs.

    scripts/bench_peer.py OUT [--full] [--levels 5,8]
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.materials import lame  # noqa: E402
from hyperelastic.mesh import cached_bar, read  # noqa: E402
from hyperelastic.experiments.runner import last_line, run_hyperelastic  # noqa: E402
from hyperelastic.study.measure import read_cost  # noqa: E402
from hyperelastic.study.plan import PCS  # noqa: E402

E, NU, T = 1e6, 0.3, 1000.0
RTOL = 1e-10


def skfem_solve(points, tets):
    """(displacement (nv,3), Newton iterations, seconds per Newton step, residual history)."""
    from skfem import Basis, ElementTetP1, ElementVector, FacetBasis, MeshTet, asm, condense, solve
    from skfem.assembly import BilinearForm, LinearForm
    from skfem.helpers import ddot, det, dot, grad, identity, inv, mul, trace, transpose

    lam, mu = lame(E, NU)
    mesh = MeshTet(np.ascontiguousarray(points.T), np.ascontiguousarray(tets.T))
    basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=1)       # constant F per tet: exact
    right = mesh.facets_satisfying(lambda x: np.isclose(x[0], 5.0))
    fbasis = FacetBasis(mesh, ElementVector(ElementTetP1()), facets=right, intorder=2)
    clamped = basis.get_dofs(lambda x: np.isclose(x[0], -5.0)).all()

    def kin(w):
        F = identity(w["u"].grad) + grad(w["u"])
        Fi = inv(F)
        return F, Fi, transpose(Fi), np.log(det(F))

    @LinearForm
    def internal(v, w):
        F, _, FiT, lnJ = kin(w)
        return ddot(mu * F + (lam * lnJ - mu) * FiT, grad(v))

    @BilinearForm
    def tangent(u, v, w):
        F, Fi, FiT, lnJ = kin(w)
        dF = grad(u)
        dP = mu * dF + lam * trace(mul(Fi, dF)) * FiT - (lam * lnJ - mu) * mul(FiT, mul(transpose(dF), FiT))
        return ddot(dP, grad(v))

    @LinearForm
    def load(v, w):
        return dot(np.array([0.0, -T, 0.0])[:, None, None], v)

    f = asm(load, fbasis)
    u = np.zeros(basis.N)
    free = np.setdiff1d(np.arange(basis.N), clamped)
    hist, times = [], []
    for it in range(50):
        t0 = time.perf_counter()
        uw = basis.interpolate(u)
        r = asm(internal, basis, u=uw) - f
        rn = np.linalg.norm(r[free])
        hist.append(rn)
        if rn <= RTOL * hist[0]:
            times.append(time.perf_counter() - t0)   # (the last residual check is part of the cost)
            break
        K = asm(tangent, basis, u=uw)
        u += solve(*condense(K, -r, D=clamped))
        times.append(time.perf_counter() - t0)
    else:
        raise RuntimeError(f"scikit-fem Newton did not converge: {hist}")
    disp = u[basis.nodal_dofs].T                 # (nv, 3), vertex order of the mesh given
    return disp, len(hist) - 1, sum(times) / (len(hist) - 1), hist


def ours(mesh_path, out):
    path = os.path.join(out, f"peer_{os.path.basename(mesh_path)[:-4]}.h5")
    args = ["run", "bend", "-quasistatic", "-material", "neohookean", "-E", E, "-nu", NU, "-traction", f"0,{-T},0",
            "-mesh", mesh_path, "-dt", 1, "-final_time", 1, "-jacobian", "assembled", "-ksp_type", "cg",
            "-ksp_rtol", "1e-12", "-snes_linesearch_type", "basic", "-inversion_guard", "0", "-snes_rtol", RTOL, "-snes_atol", "1e-14", "-snes_stol", "0", "-step_control", "0",
            "-output", path, "-quiet"] + PCS["gamg"]
    rc, err, wall = run_hyperelastic(args, path)
    if rc != 0:
        raise RuntimeError(f"hyperelastic failed: {last_line(err, rc)}")
    import h5py
    with h5py.File(path, "r") as f:
        disp = f["x"][-1] - f["mesh/points"][:]
    c = read_cost(path)
    return disp, c["newton_its"], c["solve_s"] / c["newton_its"], c


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--full", action="store_true", help="levels 5, 8 and 10 instead of 5")
    ap.add_argument("--levels", default=None)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    try:
        import skfem
    except ImportError:
        sys.exit("bench_peer.py: scikit-fem is not installed (pip install -r requirements-bench.txt)")
    levels = [int(x) for x in (a.levels or ("5,8,10" if a.full else "5")).split(",")]
    print(f"scikit-fem {skfem.__version__}; problem: clamped bar, dead load {T:g} Pa, Neo-Hookean E={E:g} nu={NU}")
    print("| mesh | tets | max |u_ours - u_skfem| / max |u| | Newton ours / theirs | s per Newton step ours | "
          "theirs | ours / theirs |\n|---|---|---|---|---|---|---|")
    for L in levels:
        m = cached_bar(L)
        points, tets = read(m)[:2]
        u1, n1, s1, _ = ours(m, a.out)
        u2, n2, s2, _ = skfem_solve(points, tets)
        rel = np.abs(u1 - u2).max() / np.abs(u2).max()
        print(f"| L{L} | {len(tets):,} | {rel:.2g} | {n1} / {n2} | {s1:.3g} | {s2:.3g} | {s1 / s2:.2f} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
