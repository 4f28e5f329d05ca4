"""A second DOLFINx driver for the P2 peer problem of scripts/bench_peer.py, through DOLFINx's own SNES path
(dolfinx.fem.petsc.NonlinearProblem) instead of peer_dolfinx.py's hand-written Newton loop: a cross-check of the
peer's time per Newton step (issue 49: an independent comparison had found ours/DOLFINx 0.61 where bench_peer.py
gives 0.42). Run with the Python of .venv-dolfinx (LD_LIBRARY_PATH=.venv-dolfinx/lib):

    .venv-dolfinx/bin/python scripts/peer_dolfinx_snes.py MESH.npz [KSP_RTOL]

MESH.npz: bench_peer.py's mesh file (`points`, `tets`, e.g. OUT/mesh_L8.npz). The problem: the bar clamped at
x = -5, a dead traction (0, -5000, 0) Pa on x = 5, compressible Neo-Hookean (E = 1e6, nu = 0.3), P2 with the 4-point
rule, full Newton steps to 1e-10, CG + GAMG (agg, one smoothing step, Chebyshev/Jacobi) with the rigid-body modes as
near null space, set up at every Newton step. Prints the wall time per Newton step and PETSc's events."""
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import basix.ufl
import dolfinx
import dolfinx.fem.petsc
import ufl
from peer_dolfinx import rigid_body_modes

E, NU, T = 1e6, 0.3, 5000.0


def main():
    d = np.load(sys.argv[1])
    ksp_rtol = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-10
    comm = MPI.COMM_WORLD
    coord = basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,))
    tets, points = (d["tets"].astype(np.int64), d["points"]) if comm.rank == 0 else (np.zeros((0, 4), np.int64),
                                                                                      np.zeros((0, 3)))
    mesh = dolfinx.mesh.create_mesh(comm, tets, coord, points)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 2, (3,)))
    dx = ufl.dx(metadata={"quadrature_degree": 2})
    u, v = dolfinx.fem.Function(V), ufl.TestFunction(V)
    lam, mu = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    F = ufl.Identity(3) + ufl.grad(u)
    J = ufl.det(F)
    psi = mu / 2 * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(J) + lam / 2 * ufl.ln(J) ** 2
    right = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 5.0))
    tags = dolfinx.mesh.meshtags(mesh, 2, right, np.full(len(right), 1, np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    t = dolfinx.fem.Constant(mesh, np.array([0.0, -T, 0.0]))
    residual = ufl.derivative(psi * dx - ufl.dot(t, u) * ds(1), u, v)
    left = dolfinx.fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], -5.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(3), left, V)
    opts = {"snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": 1e-10, "snes_atol": 1e-14,
            "snes_stol": 0, "ksp_type": "cg", "ksp_rtol": ksp_rtol, "pc_type": "gamg", "pc_gamg_type": "agg",
            "pc_gamg_agg_nsmooths": 1}
    problem = dolfinx.fem.petsc.NonlinearProblem(residual, u, petsc_options_prefix="peer_", bcs=[bc],
                                                 petsc_options=opts)
    modes = rigid_body_modes(V)        # (peer_dolfinx.py's: translations, rotations about the origin)
    problem.A.setNearNullSpace(PETSc.NullSpace().create(vectors=modes, comm=comm))
    PETSc.Log.begin()
    t0 = time.perf_counter()
    problem.solve()
    wall = time.perf_counter() - t0
    snes = problem.solver
    its = snes.getIterationNumber()
    if comm.rank == 0:
        print(f"DOLFINx {dolfinx.__version__}: {its} Newton steps, {snes.getLinearSolveIterations()} CG iterations, "
              f"reason {snes.getConvergedReason()}; wall per Newton step {wall / its:.3f} s")
    for ev in ("SNESSolve", "SNESJacobianEval", "SNESFunctionEval", "PCSetUp", "KSPSolve"):
        info = PETSc.Log.Event(ev).getPerfInfo()
        if comm.rank == 0:
            print(f"  {ev}: {info['count']} calls, {info['time']:.3f} s")


if __name__ == "__main__":
    main()
