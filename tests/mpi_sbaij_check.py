"""Run under `mpiexec -n N` by test_pmg.py (and alone on 1 rank): the symmetric tangent filled straight into SBAIJ
(jacobians.AssembledSBAIJ: no AIJ) equals the AIJ fill's upper triangle, and p-multigrid's P1 operator summed from
its cells (pmg.GalerkinCells) equals PETSc's P^T A P of that AIJ, after a second fill at another state too, with
the scene's own entries (its effects' and the constrained diagonal). usage: SCENE[:OPTION=VALUE,...] ... (each a
model of quadratic tetrahedra at level 2, filled 97 cells at a time). Prints 'ok SCENE' on rank 0 for each."""
import os
import sys

import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from petsc4py import PETSc  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from conftest import make_model  # noqa: E402

from hyperelastic.solving import jacobians, pmg  # noqa: E402


def difference(A, B):
    """||A - B||_F / ||B||_F (A, B of any storage PETSc converts to AIJ; copies: petsc4py converts in place
    unless given an `out`)."""
    A, B = A.convert("aij", out=PETSc.Mat()), B.convert("aij", out=PETSc.Mat())
    ref = B.norm(PETSc.NormType.FROBENIUS)
    A.axpy(-1.0, B, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    return A.norm(PETSc.NormType.FROBENIUS) / ref


def main(spec, chunk=97):
    scene, _, extra = spec.partition(":")
    extra = [tuple(kv.split("=")) for kv in extra.split(",") if kv]
    m = make_model(PETSc, scene, [("level", "2"), ("order", "2")] + extra)
    space, system = m.space, m.system
    X0 = space.X.ravel()
    system.begin_step(0.02, m.scene.dt, X0.copy(), np.zeros_like(X0))
    jacobians._CellFill.CHUNK = chunk                   # several chunks, a ragged last one
    a = jacobians.AssembledChunked(system)
    s = jacobians.AssembledSBAIJ(system)
    numbers = pmg.coarse_numbers(space)
    levels = pmg.GalerkinCells(space, chunk, numbers)
    s.coarse = levels
    P, _ = pmg.prolongation(space, numbers)
    for amp in (0.05, 0.08):
        x = X0 + amp * np.sin(1.3 * X0 + 0.4)            # the same state on every rank (a function of X)
        system.linearize(system.global_state(x))
        a.assemble()
        levels.wanted = True
        s.assemble()
        assert not levels.wanted
        assert s.mat.getType().endswith("sbaij") and s.mat.getInfo()["nz_unneeded"] == 0
        d_fine, d_coarse = difference(s.mat, a.mat), difference(levels.mat, a.mat.ptap(P))
        assert d_fine < 1e-14 and d_coarse < 1e-13, (d_fine, d_coarse)
    boundary, constrained = space.mpi.allreduce(len(s.fill.boundary)), space.mpi.allreduce(len(a.c_local))
    if space.mpi.rank == 0:
        print(f"ok {scene}: fine {d_fine:.1e}, coarse {d_coarse:.1e}, {boundary} boundary cells, {len(a.other)} "
              f"effects with own entries, {constrained} constrained dofs")


if __name__ == "__main__":
    for spec in sys.argv[1:]:
        main(spec)
