"""The peer problem of scripts/bench_peer.py in DOLFINx, run by that script with the Python of its own
virtual environment (.venv-dolfinx: DOLFINx and its own PETSc never mix with ours).

    .venv-dolfinx/bin/python scripts/peer_dolfinx.py MESH.npz OUT.npz [--pc gamg|lu] [--ksp-rtol R]

MESH.npz holds `points` (nv, 3) and `tets` (nc, 4) in the input numbering (rank 0 reads it; the mesh
is distributed by DOLFINx). The problem: the bar's end x = -5 clamped, a dead traction (0, -T, 0) Pa
on x = 5, compressible Neo-Hookean psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2 (Bonet & Wood 1997,
sec. 6.4.3) written in UFL, vector P1, one load step, plain Newton (full steps) to a relative residual
of RTOL, CG + GAMG (agg, one smoothing, Chebyshev/Jacobi levels) with the six rigid-body modes as near
null space, or LU. Timed per Newton step: residual assembly, Jacobian assembly, PC set-up, KSP solve.
OUT.npz gets the displacement at the input vertices (rank 0) and the timings.
"""
import argparse
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import basix.ufl
import dolfinx
import dolfinx.fem.petsc
import ufl

E, NU, T = 1e6, 0.3, 5000.0


def read_mesh(path):
    """(the DOLFINx mesh, the input points on rank 0) of MESH.npz (`points`, `tets`), read on rank 0, distributed."""
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        d = np.load(path)
        points, tets = d["points"].astype(np.float64), d["tets"].astype(np.int64)
    else:
        points, tets = np.zeros((0, 3)), np.zeros((0, 4), np.int64)
    coord = basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,))
    return dolfinx.mesh.create_mesh(comm, tets, coord, points), points


def rigid_body_modes(V):
    """The six rigid-body modes on the vector space V (translations, rotations about the origin) as PETSc Vecs."""
    x = V.tabulate_dof_coordinates()
    modes = []
    for k in range(6):
        w = dolfinx.fem.Function(V)
        arr = w.x.array.reshape(-1, 3)
        if k < 3:
            arr[:, k] = 1.0
        else:
            i, j = [(1, 2), (2, 0), (0, 1)][k - 3]
            arr[:, i] = -x[:, j]
            arr[:, j] = x[:, i]
        modes.append(w.x.petsc_vec.copy())
    return modes


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("out")
    ap.add_argument("--pc", default="gamg")
    ap.add_argument("--ksp-rtol", type=float, default=1e-10)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--traction", type=float, default=T)
    ap.add_argument("--degree", type=int, default=1, help="the element's degree: 1 (P1) or 2 (P2)")
    ap.add_argument("--qdegree", type=int, default=0, help="the quadrature degree (0: UFL's estimate)")
    ap.add_argument("--cflags", default="", help="the C flags of DOLFINx's JIT-compiled forms (e.g. '-O3 "
                    "-march=native'; default: DOLFINx's own, -O2)")
    a = ap.parse_args()
    jit = {"cffi_extra_compile_args": a.cflags.split()} if a.cflags else None
    mesh, points = read_mesh(a.mesh)
    V = dolfinx.fem.functionspace(mesh, ("Lagrange", a.degree, (3,)))
    dx = ufl.dx(metadata={"quadrature_degree": a.qdegree}) if a.qdegree else ufl.dx
    u, v, du = dolfinx.fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    lam = E * NU / ((1 + NU) * (1 - 2 * NU))
    mu = E / (2 * (1 + NU))
    F = ufl.Identity(3) + ufl.grad(u)
    J = ufl.det(F)
    psi = mu / 2 * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(J) + lam / 2 * ufl.ln(J) ** 2
    fdim = mesh.topology.dim - 1
    right = dolfinx.mesh.locate_entities_boundary(mesh, fdim, lambda x: np.isclose(x[0], 5.0))
    tags = dolfinx.mesh.meshtags(mesh, fdim, right, np.full(len(right), 1, np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    t = dolfinx.fem.Constant(mesh, np.array([0.0, -a.traction, 0.0]))
    Pi = psi * dx - ufl.dot(t, u) * ds(1)
    Rform = dolfinx.fem.form(ufl.derivative(Pi, u, v), jit_options=jit)
    Jform = dolfinx.fem.form(ufl.derivative(ufl.derivative(Pi, u, v), u, du), jit_options=jit)
    left = dolfinx.fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], -5.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(3), left, V)

    A = dolfinx.fem.petsc.create_matrix(Jform)
    b = dolfinx.fem.petsc.create_vector(V)
    du_f = dolfinx.fem.Function(V)
    # the six rigid-body modes (translations, rotations about the origin) as GAMG's near null space
    nloc = V.dofmap.index_map.size_local
    modes = rigid_body_modes(V)
    from dolfinx.la import orthonormalize
    try:
        orthonormalize(modes)
    except Exception:
        pass
    nullspace = PETSc.NullSpace().create(vectors=modes, comm=mesh.comm)

    ksp = PETSc.KSP().create(mesh.comm)
    ksp.setOperators(A)
    opts = PETSc.Options()
    if a.pc == "lu":
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
    else:
        ksp.setType("cg")
        pc = ksp.getPC()
        pc.setType("gamg")
        for k, val in (("pc_gamg_type", "agg"), ("pc_gamg_agg_nsmooths", "1"), ("mg_levels_ksp_type", "chebyshev"),
                       ("mg_levels_pc_type", "jacobi")):
            opts.setValue(k, val)
        ksp.setTolerances(rtol=a.ksp_rtol, atol=1e-50)
    ksp.setFromOptions()

    times = {"residual": [], "jacobian": [], "pc_setup": [], "ksp_solve": [], "step": [], "ksp_its": []}
    hist = []

    def residual():
        t0 = time.perf_counter()
        with b.localForm() as bl:
            bl.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, Rform)
        dolfinx.fem.petsc.apply_lifting(b, [Jform], [[bc]], x0=[u.x.petsc_vec], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        dolfinx.fem.petsc.set_bc(b, [bc], u.x.petsc_vec, -1.0)
        times["residual"].append(time.perf_counter() - t0)
        return b.norm()

    r = residual()
    hist.append(r)
    for it in range(50):
        if hist[-1] <= a.rtol * hist[0]:
            break
        t0 = time.perf_counter()
        A.zeroEntries()
        dolfinx.fem.petsc.assemble_matrix(A, Jform, bcs=[bc])
        A.assemble()
        if it == 0:
            A.setNearNullSpace(nullspace)
        t1 = time.perf_counter()
        b.scale(-1.0)
        ksp.setOperators(A)
        ksp.setUp()
        ksp.getPC().setUp()
        t2 = time.perf_counter()
        ksp.solve(b, du_f.x.petsc_vec)
        t3 = time.perf_counter()
        du_f.x.scatter_forward()
        u.x.array[:] += du_f.x.array
        r = residual()
        t4 = time.perf_counter()
        hist.append(r)
        times["jacobian"].append(t1 - t0)
        times["pc_setup"].append(t2 - t1)
        times["ksp_solve"].append(t3 - t2)
        times["step"].append(t4 - t0)
        times["ksp_its"].append(ksp.getIterationNumber())
    else:
        raise SystemExit(f"DOLFINx Newton did not converge: {hist}")

    # the displacement at the input vertices: for P1 the k-th dof of a cell sits on its k-th geometry
    # node, and geometry node g came from input vertex input_global_indices[g]; for P2, every owned dof with
    # its coordinates (the caller matches them to its nodes)
    vals = u.x.array.reshape(-1, 3)
    if a.degree == 1:
        gd = (mesh.geometry.dofmaps[0] if hasattr(mesh.geometry, "dofmaps") else mesh.geometry.dofmap).reshape(-1)
        vd = V.dofmap.list.reshape(-1)
        igi = np.asarray(mesh.geometry.input_global_indices)
        mine = np.column_stack([igi[gd], vals[vd]])
    else:
        mine = np.column_stack([V.tabulate_dof_coordinates()[:nloc], vals[:nloc]])
    allv = mesh.comm.gather(mine, root=0)
    tmax = {}
    for k, v in times.items():              # the slowest rank's time of each call
        arr = np.ascontiguousarray(v, dtype=float)
        tmax[k] = np.empty_like(arr)
        mesh.comm.Allreduce(arr, tmax[k], op=MPI.MAX)
    if mesh.comm.rank == 0:
        allv = np.concatenate([m for m in allv if len(m)])
        if a.degree == 1:
            disp = np.zeros((len(points), 3))
            disp[allv[:, 0].astype(np.int64)] = allv[:, 1:]
        else:
            disp = allv                                  # (ndofs, 6): coordinates, displacement
        np.savez(a.out, disp=disp, hist=np.array(hist), version=dolfinx.__version__,
                 petsc=".".join(map(str, PETSc.Sys.getVersion())), ranks=mesh.comm.size,
                 **{k: np.asarray(v) for k, v in tmax.items()})
        print(f"DOLFINx {dolfinx.__version__}: {len(hist) - 1} Newton steps, residual {hist[0]:.3g} -> {hist[-1]:.3g}",
              file=sys.stderr)


if __name__ == "__main__":
    main()
