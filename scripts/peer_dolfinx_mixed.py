"""The peer problem of scripts/bench_peer_mixed.py in DOLFINx: Cook's membrane, nearly incompressible, with the
Taylor-Hood P2-P1 mixed formulation of hyperelastic's `-formulation mixed` (docs/design.md), run by that script
with the Python of .venv-dolfinx (DOLFINx and its own PETSc never mix with ours).

    .venv-dolfinx/bin/python scripts/peer_dolfinx_mixed.py MESH.npz OUT.npz [--mu M] [--kappa K] [--traction T]
        [--matptap-via KERNEL]

MESH.npz: `points` (nv, 3) and `tets` (nc, 4), the corners of the P2 mesh ours solves (rank 0 reads it; DOLFINx
distributes it; Cook's panel has flat faces, so its P2 nodes are the edges' midpoints in both codes).
The energy, written in UFL: Pi(u, p) = int [mu/2 (J^(-2/3) tr(F^T F) - 3) + p (J - 1) - U*(p)] dV - int t.u dA,
U*(p) = p (J_p - 1) - U(J_p), J_p = p/kappa + sqrt(1 + (p/kappa)^2), U(J) = kappa/4 (J^2 - 1 - 2 ln J) (Simo &
Taylor 1991): U* is the Legendre transform of U, so eliminating p gives back the split Neo-Hookean material.
Clamped at x = 0, u_z = 0 on z = 0 and z = 10 (plane strain by rollers), a dead traction (0, T, 0) on x = 48;
one load step; Newton with full steps (newtonls, basic) to a relative residual RTOL; the quadrature rule of
degree 2 (the 4-point rule ours uses for P2) in cells and on faces. Solver: GMRES(100) (at most 1000 iterations) +
PCFIELDSPLIT Schur (full factorization), the displacement block by one GAMG V-cycle with the six rigid-body modes
as near null space, the Schur complement by Jacobi on -(1/mu + 1/kappa) M_p: ours' default options, set alike.
Phases per Newton step from PETSc's log events, as for ours (SNESJacobianEval, SNESFunctionEval, PCSetUp,
KSPSolve, SNESSolve). OUT.npz: every owned displacement dof's (coordinates, value) and every vertex's
(coordinates, pressure) on rank 0, the residual history, the events' times.
"""
import argparse
import sys

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc
import ufl
from peer_dolfinx import read_mesh, rigid_body_modes

EVENTS = ("SNESSolve", "SNESJacobianEval", "SNESFunctionEval", "PCSetUp", "KSPSolve", "MatMult")


def near_null_space(V):
    """The six rigid-body modes on V, orthonormalized (Gram-Schmidt, twice), as a PETSc NullSpace."""
    modes = rigid_body_modes(V)
    for i, m in enumerate(modes):
        for _ in range(2):
            for n in modes[:i]:
                m.axpy(-m.dot(n), n)
        m.scale(1.0 / m.norm())
    return PETSc.NullSpace().create(vectors=modes, comm=V.mesh.comm)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("out")
    ap.add_argument("--mu", type=float, default=80.194)
    ap.add_argument("--kappa", type=float, default=400889.8)
    ap.add_argument("--traction", type=float, default=6.25)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--ksp-rtol", type=float, default=1e-10)
    ap.add_argument("--fact", default="full", help="the Schur factorization (-pc_fieldsplit_schur_fact_type)")
    ap.add_argument("--matptap-via", default="", help="PETSc's kernel for GAMG's Galerkin products (-matptap_via; "
                    "ours sets rap on one rank, nonscalable on several: solver.GALERKIN_KERNELS); default PETSc's")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    mesh, _ = read_mesh(a.mesh)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", 2, (3,)))
    Q = dolfinx.fem.functionspace(mesh, ("Lagrange", 1))
    u, p = dolfinx.fem.Function(V), dolfinx.fem.Function(Q)
    v, q = ufl.TestFunction(V), ufl.TestFunction(Q)
    du, dp = ufl.TrialFunction(V), ufl.TrialFunction(Q)

    mu, kappa = a.mu, a.kappa
    F = ufl.Identity(3) + ufl.grad(u)
    J = ufl.det(F)
    psi_iso = mu / 2 * (J ** (-2.0 / 3.0) * ufl.tr(F.T * F) - 3)
    s = p / kappa
    Jp = s + ufl.sqrt(1 + s * s)
    Ustar = p * (Jp - 1) - kappa / 4 * (Jp * Jp - 1 - 2 * ufl.ln(Jp))
    fdim = mesh.topology.dim - 1
    right = dolfinx.mesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[0], 48.0))
    tags = dolfinx.mesh.meshtags(mesh, fdim, right, np.full(len(right), 1, np.int32))
    md = {"quadrature_degree": 2}
    dx = ufl.Measure("dx", domain=mesh, metadata=md)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags, metadata=md)
    t = dolfinx.fem.Constant(mesh, np.array([0.0, a.traction, 0.0]))
    Pi = (psi_iso + p * (J - 1) - Ustar) * dx - ufl.dot(t, u) * ds(1)
    R = [ufl.derivative(Pi, u, v), ufl.derivative(Pi, p, q)]
    K = [[ufl.derivative(R[0], u, du), ufl.derivative(R[0], p, dp)],
         [ufl.derivative(R[1], u, du), ufl.derivative(R[1], p, dp)]]

    left = dolfinx.mesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[0], 0.0))
    faces = dolfinx.mesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[2], 0.0) | np.isclose(x[2], 10.0))
    bcs = [dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, fdim, left), V),
           dolfinx.fem.dirichletbc(0.0, dolfinx.fem.locate_dofs_topological(V.sub(2), fdim, faces), V.sub(2))]

    opts = {"snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": a.rtol, "snes_atol": 1e-14,
            "snes_stol": 0, "snes_max_it": 50, "ksp_type": "gmres", "ksp_rtol": a.ksp_rtol, "pc_type": "fieldsplit",
            "ksp_gmres_restart": 100, "ksp_max_it": 1000,    # ours' defaults (solver.MIXED_NEWTON)
            "pc_fieldsplit_type": "schur", "pc_fieldsplit_schur_fact_type": a.fact,
            "fieldsplit_u_ksp_type": "preonly", "fieldsplit_u_pc_type": "gamg", "fieldsplit_p_ksp_type": "preonly",
            "fieldsplit_p_pc_type": "jacobi", "snes_error_if_not_converged": True}
    problem = dolfinx.fem.petsc.NonlinearProblem(R, [u, p], bcs=bcs, J=K, petsc_options_prefix="peer_")
    snes = problem.solver
    db = PETSc.Options()
    for k, val in opts.items():              # kept in the database: the field split reads its blocks' at set-up
        db[f"peer_{k}"] = val
    if a.matptap_via:
        db["matptap_via"] = a.matptap_via      # (read when GAMG forms its first Galerkin product)
    snes.setFromOptions()
    A = problem.A
    nu_own = 3 * V.dofmap.index_map.size_local
    np_own = Q.dofmap.index_map.size_local
    first = A.getOwnershipRange()[0]
    is_u = PETSc.IS().createStride(nu_own, first, 1, comm=comm)
    is_u.setBlockSize(3)
    is_p = PETSc.IS().createStride(np_own, first + nu_own, 1, comm=comm)
    is_u.compose("nearnullspace", near_null_space(V))
    pc = snes.getKSP().getPC()
    pc.setFieldSplitIS(("u", is_u), ("p", is_p))
    Mp = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(-(1 / mu + 1 / kappa) * dp * q * dx))
    Mp.assemble()
    pc.setFieldSplitSchurPreType(PETSc.PC.FieldSplitSchurPreType.USER, Mp)

    hist, kits = [], []
    snes.setMonitor(lambda s, it, r: hist.append(r))
    PETSc.Log.begin()
    problem.solve()
    kits = snes.getLinearSolveIterations()
    newton = snes.getIterationNumber()
    ev = {}
    for name in EVENTS:
        info = PETSc.Log.Event(name).getPerfInfo()
        ev[name] = comm.allreduce(float(info["time"]), op=MPI.MAX)
        ev[name + "_count"] = int(info["count"])
    if a.matptap_via and not db.used("matptap_via"):
        raise SystemExit("DOLFINx: -matptap_via was not read")
    if snes.getConvergedReason() <= 0:
        raise SystemExit(f"DOLFINx: SNES did not converge ({snes.getConvergedReason()})")

    nv_own = V.dofmap.index_map.size_local
    disp = np.column_stack([V.tabulate_dof_coordinates()[:nv_own], u.x.array.reshape(-1, 3)[:nv_own]])
    pres = np.column_stack([Q.tabulate_dof_coordinates()[:np_own], p.x.array[:np_own]])
    disp, pres = comm.gather(disp, root=0), comm.gather(pres, root=0)
    if comm.rank == 0:
        np.savez(a.out, disp=np.concatenate(disp), pressure=np.concatenate(pres), hist=np.array(hist),
                 newton=newton, ksp_its=kits, version=dolfinx.__version__,
                 petsc=".".join(map(str, PETSc.Sys.getVersion())), ranks=comm.size, **ev)
        print(f"DOLFINx {dolfinx.__version__}: {newton} Newton steps, {kits} GMRES its, residual "
              f"{hist[0]:.3g} -> {hist[-1]:.3g}", file=sys.stderr)


if __name__ == "__main__":
    main()
