"""Run under `mpiexec -n N` by test_operators.py: the chunked direct fill of the assembled tangent on N ranks
(the exact pattern from every rank's cells, preallocated before the first fill) equals the COO assembly,
leaves no preallocated entry unused, and gives the same matrix when filled again; the SBAIJ copy of it
(-operator_storage sbaij) multiplies like it. Prints 'ok' on rank 0."""
import os
import sys

import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from petsc4py import PETSc  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from conftest import make_model  # noqa: E402

from hyperelastic.solving import jacobians  # noqa: E402


def main(scene):
    m = make_model(PETSc, scene, [("level", "2")])
    space, system = m.space, m.system
    X0 = space.X.ravel()
    x = X0 + 0.05 * np.sin(1.3 * X0 + 0.4)            # the same state on every rank (a function of X)
    system.begin_step(0.02, m.scene.dt, X0.copy(), np.zeros_like(X0))
    system.linearize(system.global_state(x))
    a = jacobians.AssembledChunked(system)
    a.assemble()
    first = a.mat.copy()
    a.assemble()
    b = jacobians.Assembled(system)
    b.assemble()
    ref = b.mat.norm(PETSc.NormType.FROBENIUS)
    for M in (a.mat, first):
        C = M.copy()
        C.axpy(-1.0, b.mat, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        assert C.norm(PETSc.NormType.FROBENIUS) <= 1e-13 * ref
    info = a.mat.getInfo()
    assert info["nz_unneeded"] == 0, info
    assert info["nz_used"] == b.mat.getInfo()["nz_used"], (info, b.mat.getInfo())
    # the SBAIJ copy (-operator_storage sbaij): its off-diagonal part set by MatSetValuesBlocked, refilled
    symmetric = all(e.symmetric for e in system.effects)       # (twist's follower load is not)
    sb = jacobians.AssembledChunked(system, storage="sbaij") if symmetric else None
    for _ in range(2 if symmetric else 0):
        sb.assemble()
        v = sb.mat.createVecRight()
        lo, hi = v.getOwnershipRange()
        v.setArray(np.sin(0.37 * np.arange(lo, hi)))
        y1, y2 = sb.mat.createVecLeft(), sb.mat.createVecLeft()
        b.mat.mult(v, y1)
        sb.operator.mult(v, y2)
        y2.axpy(-1.0, y1)
        assert y2.norm(PETSc.NormType.INFINITY) <= 1e-13 * y1.norm(PETSc.NormType.INFINITY)
    assert sb is None or sb.operator.getType() == "mpisbaij"
    boundary = space.mpi.allreduce(len(a.map.boundary))
    if space.mpi.rank == 0:
        print(f"ok {scene}: {int(info['nz_used'])} entries, {boundary} boundary cells")


if __name__ == "__main__":
    for name in sys.argv[1:]:
        main(name)
