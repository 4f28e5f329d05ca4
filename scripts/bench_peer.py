#!/usr/bin/env python
"""Peer benchmark (issue 17): the same quasi-static Neo-Hookean problem solved by DOLFINx (or
scikit-fem) and by hyperelastic, on the same P1 mesh, timed per Newton step and per phase.

Problem: the 10 x 4 x 4 bar, left end (x = -5) clamped, a dead-load traction t = (0, -5000, 0) Pa on
the right end face (x = 5), compressible Neo-Hookean (Bonet & Wood 1997, sec. 6.4.3:
P = mu (F - F^-T) + lam ln J F^-T), E = 1e6 Pa, nu = 0.3, one load step, plain Newton (full steps)
to a relative residual of 1e-10; CG (ksp_rtol 1e-10) + GAMG (agg, one smoothing step, Chebyshev +
Jacobi levels, the six rigid-body modes as near null space), or LU on one rank.

DOLFINx (--peer dolfinx, default): scripts/peer_dolfinx.py, run with the Python of .venv-dolfinx, which
this script makes on first use from the dolfinx-solver-real wheel (DOLFINx 0.11 with its own PETSc
and MPICH; never mixed with ours). Its phases are timed around the calls (assemble_matrix, assemble_
vector + lifting, PC set-up, KSP solve); ours come from PETSc's -log_view (SNESJacobianEval,
SNESFunctionEval, PCSetUp, KSPSolve without the set-up, SNESSolve / Newton steps). The last two columns:
one residual evaluation of ours over one MatMult of the assembled AIJ tangent, and the residual's fixed
cost (SNESFunctionEval less the element force loop, HE_ElasticForces), per call, from CG + Jacobi runs of
the same problem, whose MatMults are all on the fine level (the smallest of --repeat runs). The runs are
interleaved (DOLFINx, ours, DOLFINx, ours, ...); each phase is the minimum of --repeat runs, and the step ratio
is also given per pair of consecutive runs (median and range: the machine's noise). --storage: ours with
-operator_storage aij and/or sbaij (the Krylov MatMults on an SBAIJ copy; a row each, one DOLFINx run).
scikit-fem (--peer skfem, `pip install -r requirements-bench.txt`): the earlier comparison (load
1000 Pa, its LinearForm / BilinearForm, SciPy's direct solver).

    .venv/bin/python scripts/bench_peer.py OUT [--levels 5,8] [--tets 250000] [--ranks 1,2] [--pcs gamg,lu]
        [--storage aij,sbaij] [--repeat 3]
    .venv/bin/python scripts/bench_peer.py OUT --full        # L5, L8, ~250k tets
"""
import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from hyperelastic.physics.materials import lame  # noqa: E402
from hyperelastic.mesh.read import read  # noqa: E402
from hyperelastic.mesh.generate import cached_bar  # noqa: E402
from hyperelastic.studies.experiments.runner import last_line, run_hyperelastic  # noqa: E402
from hyperelastic.studies.plan import PCS, pc_of  # noqa: E402

E, NU, T = 1e6, 0.3, 5000.0
T_SKFEM = 1000.0          # the scikit-fem comparison's load (earlier figures)
RTOL = 1e-10
AGREE = 1e-10             # max |u_ours - u_peer| / max |u_peer| the rows must meet (else exit 1)


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
        return dot(np.array([0.0, -T_SKFEM, 0.0])[:, None, None], v)

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


LOG_EVENTS = {"SNESSolve": "solve", "SNESJacobianEval": "jacobian", "SNESFunctionEval": "residual",
              "PCSetUp": "pc_setup", "KSPSolve": "ksp_solve", "MatMult": "matmult", "HE_ElasticForces": "forces"}


def parse_log_view(path):
    """{event: (count, max time s)} of the events LOG_EVENTS names, from a -log_view file."""
    out = {}
    for line in open(path):
        w = line.split()
        if len(w) > 4 and w[0] in LOG_EVENTS and w[0] not in out:
            out[w[0]] = (int(w[1]), float(w[3]))
    return out


def ours(mesh_path, out, ranks=1, pc="gamg", traction=T, storage="aij", order=1):
    """(displacement in input order (every node), Newton steps, {phase: seconds per Newton step}; "ksp_its":
    Krylov iterations in all; "points": the nodes)."""
    tag = f"{os.path.basename(mesh_path)[:-4]}_p{order}_{pc}_{storage}_n{ranks}"
    path, log = os.path.join(out, f"ours_{tag}.h5"), os.path.join(out, f"ours_{tag}.log")
    solver = (["-ksp_type", "preonly", "-pc_type", "lu"] if pc == "lu" else
              ["-ksp_type", "cg", "-ksp_rtol", "1e-10"] + (PCS[pc] if pc in PCS else pc_of(pc)))
    args = ["run", "bend", "-quasistatic", "-material", "neohookean", "-E", E, "-nu", NU, "-traction",
            f"0,{-traction},0", "-mesh", mesh_path, "-dt", 1, "-final_time", 1, "-jacobian", "assembled",
            "-snes_linesearch_type", "basic", "-objective", "0", "-inversion_guard", "0", "-snes_rtol", RTOL,
            "-snes_atol", "1e-14", "-snes_stol", "0", "-step_control", "0", "-output", path, "-quiet",
            "-log_view", f":{log}", "-operator_storage", storage, "-order", order] + solver
    if order == 2:
        args += ["-quadrature_degree", 2]
    rc, err, wall = run_hyperelastic(args, path, nprocs=ranks, timeout=3600)
    if rc != 0:
        raise RuntimeError(f"hyperelastic failed: {last_line(err, rc)}")
    import h5py
    with h5py.File(path, "r") as f:
        disp = f["x"][-1] - f["mesh/points"][:]
        nodes = f["mesh/points"][:]
        cells = f["mesh/tetra"][:]
        rss = float(f.attrs["peak_rss_mb"])
        its = int(f["stats/newton_its"][-1])
        ksp_its = int(f["stats/ksp_its"][-1])
    ev = parse_log_view(log)
    per = {LOG_EVENTS[k]: t / its for k, (n, t) in ev.items()}
    per["step"] = per.pop("solve")                        # (KSPSolve's event excludes the PCSetUp it calls)
    per["ksp_its"] = ksp_its
    call = {k: t / n for k, (n, t) in ev.items() if n}
    # (jacobi: fine-level MatMults only; LU (preonly) has none)
    per["residual_per_matmult"] = call["SNESFunctionEval"] / call["MatMult"] if "MatMult" in call else float("nan")
    # the residual's fixed cost per call: all of it but the element force loop
    per["residual_overhead"] = call["SNESFunctionEval"] - call["HE_ElasticForces"]
    per["nodes"] = nodes
    per["dofs"] = 3 * len(nodes)
    per["nnz_per_row"] = fill(cells, len(nodes)) / per["dofs"]
    per["rss_per_dof"] = rss * 2 ** 20 / per["dofs"] if ranks == 1 else float("nan")
    return disp, its, per


def fill(cells, nn):
    """Nonzeros of the assembled tangent (3x3 per pair of nodes sharing a cell)."""
    k = cells.shape[1]
    a = np.repeat(cells, k, axis=1).ravel().astype(np.int64)
    b = np.tile(cells, (1, k)).ravel().astype(np.int64)
    return 9 * len(np.unique(a * nn + b))


def matched(theirs, nodes):
    """A P2 peer's (coordinates, displacement) rows in the order of our nodes (matched by coordinates)."""
    key = lambda P: [tuple(np.round(p, 9)) for p in P]         # noqa: E731
    where = {k: i for i, k in enumerate(key(theirs[:, :3]))}
    idx = [where[k] for k in key(nodes)]
    return theirs[idx, 3:]


DOLFINX_VENV = os.path.join(ROOT, ".venv-dolfinx")


def dolfinx_python():
    """The Python of .venv-dolfinx, made on first use: DOLFINx 0.11 from the dolfinx-solver-real wheel
    (its own PETSc and MPICH; Python 3.12), a benchmark dependency only."""
    py = os.path.join(DOLFINX_VENV, "bin", "python")
    if not os.path.exists(py):
        import glob
        import shutil
        import subprocess
        # pyenv's shim answers `which` but fails unless 3.12 is selected: its versions/ directory first
        base = next(iter(sorted(glob.glob(os.path.expanduser("~/.pyenv/versions/3.12*/bin/python3.12")))),
                    None) or shutil.which("python3.12")
        if base is None:
            sys.exit("bench_peer.py: DOLFINx's wheel needs Python 3.12 (none found)")
        print(f"making {DOLFINX_VENV} (DOLFINx wheel, ~500 MB) ...", file=sys.stderr)
        subprocess.run([base, "-m", "venv", DOLFINX_VENV], check=True)
        subprocess.run([os.path.join(DOLFINX_VENV, "bin", "pip"), "install", "-q", "dolfinx-solver-real"], check=True)
    return py


def dolfinx_solve(points, tets, out, tag, ranks=1, pc="gamg", traction=T, order=1, cflags=""):
    """(displacement in input order (P1) or (coordinates, displacement) of every dof (P2), Newton steps,
    {phase: seconds per Newton step}, versions). P2: the same 4-point rule as ours (quadrature degree 2)."""
    import subprocess
    py = dolfinx_python()
    mesh_npz, res = os.path.join(out, f"mesh_{tag}.npz"), os.path.join(out, f"dolfinx_{tag}_p{order}_{pc}_n{ranks}.npz")
    np.savez(mesh_npz, points=points, tets=tets)
    cmd = [py, os.path.join(ROOT, "scripts", "peer_dolfinx.py"), mesh_npz, res, "--pc", pc, "--rtol", str(RTOL),
           "--traction", str(traction), "--degree", str(order)] + (["--qdegree", "2"] if order == 2 else [])
    if cflags:
        cmd += ["--cflags", cflags]
    if ranks > 1:
        cmd = [os.path.join(DOLFINX_VENV, "bin", "mpiexec"), "-n", str(ranks)] + cmd
    env = dict(os.environ, LD_LIBRARY_PATH=os.path.join(DOLFINX_VENV, "lib"), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    env.pop("PETSC_DIR", None)
    env.pop("PYTHONPATH", None)
    env["PATH"] = os.path.join(DOLFINX_VENV, "bin") + os.pathsep + env.get("PATH", "")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    if p.returncode != 0:
        raise RuntimeError(f"DOLFINx failed: {p.stderr[-1500:]}")
    d = np.load(res)
    its = len(d["hist"]) - 1
    per = {k: float(np.sum(d[k])) / its for k in ("step", "jacobian", "residual", "pc_setup", "ksp_solve")}
    per["residual"] = float(np.mean(d["residual"]))      # one per Newton step and the first
    per["ksp_its"] = int(np.sum(d["ksp_its"]))
    return d["disp"], its, per, f"DOLFINx {d['version']} (PETSc {d['petsc']})"


def skfem_row(L, out):
    m = cached_bar(L)
    points, tets = read(m)[:2]
    u1, n1, per = ours(m, out, traction=T_SKFEM)
    u2, n2, s2, _ = skfem_solve(points, tets)
    rel = np.abs(u1 - u2).max() / np.abs(u2).max()
    print(f"| L{L} | {len(tets):,} | {rel:.2g} | {n1} / {n2} | {per['step']:.3g} | {s2:.3g} | {per['step'] / s2:.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--peer", choices=("dolfinx", "skfem"), default="dolfinx")
    ap.add_argument("--levels", default="5", help="bar levels (comma list); --full: 5,8 and ~250k tets")
    ap.add_argument("--tets", type=int, action="append", help="also a bar with about this many tets")
    ap.add_argument("--ranks", default="1", help="rank counts, e.g. 1,2")
    ap.add_argument("--pcs", default="gamg,lu", help="gamg (CG + GAMG) and/or lu (1 rank only); pmg (P2: ours with "
                    "p-multigrid, options/pmg.opts, against the peer's GAMG: an algorithmic advantage, not like "
                    "for like)")
    ap.add_argument("--storage", default="aij,sbaij", help="ours: -operator_storage aij, sbaij and/or shell (a row each)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each code per row; each phase's minimum")
    ap.add_argument("--order", type=int, default=1, choices=(1, 2), help="element order: 1 (P1) or 2 (P2, both "
                    "with the 4-point rule of degree 2)")
    ap.add_argument("--no-jacobi", action="store_true", help="skip the CG + Jacobi runs (the last two columns "
                    "then come from the GAMG runs)")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--peer-cflags", default="", help="the C flags of DOLFINx's JIT-compiled forms (e.g. '-O3 "
                    "-march=native'; default: DOLFINx's own)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    levels = [int(x) for x in ("5,8" if a.full else a.levels).split(",") if x]     # (--levels "": --tets only)
    if a.peer == "skfem":
        try:
            import skfem
        except ImportError:
            sys.exit("bench_peer.py: scikit-fem is not installed (pip install -r requirements-bench.txt)")
        print(f"scikit-fem {skfem.__version__}; problem: clamped bar, dead load 1000 Pa, Neo-Hookean E={E:g} nu={NU}")
        print("| mesh | tets | max |u_ours - u_skfem| / max |u| | Newton ours / theirs | s per Newton step ours | "
              "theirs | ours / theirs |\n|---|---|---|---|---|---|---|")
        for L in levels:
            skfem_row(L, a.out)
        return
    from hyperelastic.mesh.generate import size_for_tets
    meshes = [(f"L{L}", cached_bar(L)) for L in levels]
    for n in (a.tets or []) + ([250000] if a.full else []):
        meshes.append((f"~{n // 1000}k", cached_bar(size=round(size_for_tets(n), 4))))
    ranks = [int(r) for r in a.ranks.split(",")]
    print(f"problem: clamped bar, dead load {T:g} Pa, Neo-Hookean E={E:g} nu={NU}, quasi-static, full load, "
          f"Newton to {RTOL:g}; ms per Newton step (PETSc -log_view events for ours, timers around the same "
          "calls for DOLFINx)")
    hdr = ("| mesh | tets | ranks | PC | storage | max|du|/max|u| | Newton ours/peer | Krylov its ours/peer | step ours | "
           "peer | ratio | step ratio of paired runs: median (range) | Jacobian ours | peer | ratio | residual ours | "
           "peer | ratio | PC set-up ours | peer | ratio | "
           "Krylov solve ours | peer | ratio | residual / MatMult ours | residual fixed cost ours (ms) | dofs | "
           "tangent nonzeros / row | peak RSS B/dof ours (1 rank) |")
    print(hdr)
    print("|" + "---|" * (hdr.count("|") - 1))
    version = ""
    disagree = []
    for name, m in meshes:
        points, tets = read(m)[:2]
        for pc in a.pcs.split(","):
            for n in ranks:
                if pc == "lu" and n > 1:
                    continue
                storages = [st for st in a.storage.split(",") if pc != "lu" or st == "aij"]   # (LU factors the AIJ)
                # the runs interleaved (DOLFINx, ours CG + Jacobi, ours per storage, and again), so that a slow
                # spell of the machine falls on both codes; GAMG's MatMults include the coarse levels': residual /
                # MatMult from CG + Jacobi runs (AIJ)
                peer, jr, mine = [], [], {st: [] for st in storages}
                for _ in range(a.repeat):
                    peer.append(dolfinx_solve(points, tets, a.out, name, n, "gamg" if pc == "pmg" else pc,
                                              order=a.order, cflags=a.peer_cflags))
                    if pc == "gamg" and not a.no_jacobi:
                        jr.append(ours(m, a.out, n, "jacobi", order=a.order)[2])
                    for st in storages:
                        mine[st].append(ours(m, a.out, n, pc, storage=st, order=a.order))
                u2, n2, version = peer[0][0], peer[0][1], peer[0][3]
                p2 = {k: min(r[2][k] for r in peer) for k in peer[0][2]}
                # the smallest ratio and fixed cost of --repeat runs
                rm = min(r["residual_per_matmult"] for r in jr) if jr else None
                ro = min(r["residual_overhead"] for r in jr) if jr else None
                for st in storages:
                    runs = mine[st]
                    u1, n1 = runs[0][:2]
                    p1 = {k: min(r[2][k] for r in runs) for k in runs[0][2] if k != "nodes"}
                    p1["rss_per_dof"] = runs[0][2]["rss_per_dof"]
                    u2m = u2 if a.order == 1 else matched(u2, runs[0][2]["nodes"])
                    rel = np.abs(u1 - u2m).max() / np.abs(u2m).max()
                    if not rel <= AGREE:
                        disagree.append(f"{name} {n} rank(s) {pc} {st}: {rel:.2g}")
                    # each run's step over the DOLFINx run just before it: their spread is the machine's noise
                    paired = sorted(r[2]["step"] / q[2]["step"] for r, q in zip(runs, peer))
                    cells = []
                    for k in ("step", "jacobian", "residual", "pc_setup", "ksp_solve"):
                        cells += [f"{1e3 * p1[k]:.3g}", f"{1e3 * p2[k]:.3g}", f"{p1[k] / p2[k]:.2f}"]
                        if k == "step":
                            cells.append(f"{np.median(paired):.2f} ({paired[0]:.2f}-{paired[-1]:.2f})")
                    cells.append(f"{rm if rm is not None else p1['residual_per_matmult']:.2f}")
                    cells.append(f"{1e3 * (ro if ro is not None else p1['residual_overhead']):.3f}")
                    cells += [f"{p1['dofs']:,}", f"{p1['nnz_per_row']:.1f}", f"{p1['rss_per_dof']:.0f}"]
                    print(f"| {name} | {len(tets):,} | {n} | {pc} | {st} | {rel:.1e} | {n1}/{n2} | "
                          f"{p1['ksp_its']}/{p2['ksp_its']} | " + " | ".join(cells) + " |")
                    sys.stdout.flush()
    print(f"peer: {version}")
    if disagree:
        sys.exit(f"bench_peer.py: the displacements differ by more than {AGREE:g} (relative): " + "; ".join(disagree))


if __name__ == "__main__":
    main()
