"""SNES / KSP / PC from the options database, with this application's defaults:
Newton with backtracking line search, CG + Jacobi (no PC under -snes_mf)."""
from mpi4py import MPI
from petsc4py import PETSc

from . import jacobians
from .libpetsc import set_function_domain_error

DEFAULTS = (("snes_linesearch_type", "bt"), ("ksp_type", "cg"), ("snes_max_it", "50"))


def apply_defaults():
    opts = PETSc.Options()
    for k, v in DEFAULTS:
        if not opts.hasName(k):
            opts.setValue(k, v)
    if not opts.hasName("pc_type"):
        opts.setValue("pc_type", "none" if opts.getBool("snes_mf", False) else "jacobi")


def matrix_free():
    """'mf', 'mf_operator' or '' from -snes_mf / -snes_mf_operator."""
    opts = PETSc.Options()
    if opts.getBool("snes_mf", False):
        return "mf"
    if opts.getBool("snes_mf_operator", False):
        return "mf_operator"
    return ""


class Solver:
    def __init__(self, system, jacobian, assembly="setvalues", guard=False):
        """SNES on the system's residual with Jacobian mode `jacobian` (scene.JACOBIANS; filled by
        `assembly` when assembled); guard: shorten Newton updates that would invert an element."""
        self.system = system
        sp = system.space
        apply_defaults()
        self.mf = matrix_free()
        self.R = sp.global_vec()
        self.snes = snes = PETSc.SNES().create(comm=sp.comm)
        snes.setFunction(self._residual, self.R)
        self.op = None
        if self.mf != "mf":   # under -snes_mf no Jacobian of ours is used: do not build one
            self.op = jacobians.make(system, jacobian, assembly)
            snes.setJacobian(self._jacobian, self.op.mat, self.op.mat)
        self.inversion_cuts = 0   # Newton updates shortened so that no element inverts
        self.guard = None
        if guard:
            self.guard = system.elastic_kernels()
            snes.setLineSearchPreCheck(self._precheck)
        snes.setFromOptions()
        self.ev_res = PETSc.Log.Event("HE_Residual")
        self.ev_jac = PETSc.Log.Event("HE_Jacobian")

    def _residual(self, snes, X, R):
        self.ev_res.begin()
        self.system.residual(X, R)
        if self.system.undefined_cells():
            set_function_domain_error(snes)
        self.ev_res.end()

    def _precheck(self, X, Y):
        """Shorten the Newton update (X_new = X - lambda Y) so that no element inverts: the material
        is undefined there (-inversion_guard; on by default for Neo-Hookean). The factor is the same
        on every rank."""
        sysm = self.system
        x = sysm.impose(sysm.local(X, sysm.xl).copy())
        d = -sysm.local(Y, sysm.vl).copy()
        d[sysm.cdofs] = 0.0
        t = sysm.space.mpi.allreduce(self.guard.max_step(x, d), op=MPI.MIN)
        if t < 1.0:
            Y.scale(t)
            self.inversion_cuts += 1
            return True
        return False

    def _jacobian(self, snes, X, J, P):
        self.ev_jac.begin()
        self.system.linearize(X)
        self.op.update()
        if J.handle != P.handle:
            J.assemble()   # MFFD operator (-snes_mf_operator): new base point
        self.ev_jac.end()

    def solve(self, X):
        self.snes.solve(None, X)
        return self.snes.getConvergedReason()

    def reason_name(self, reason):
        names = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
        return names.get(reason, str(reason))
