"""SNES / KSP / PC from the options database, with this application's defaults: Newton with a
backtracking line search on the incremental potential (energy merit, SNESSetObjective) where every
effect has one, else on the residual norm; CG (GMRES when an effect's tangent is not symmetric: follower
loads) + Jacobi (no PC under -snes_mf)."""
from mpi4py import MPI
from petsc4py import PETSc

from . import jacobians, mixed
from .errors import UserError
from .libpetsc import lag_preconditioner, lag_preconditioner_persists, set_function_domain_error

MERITS = ("energy", "residual norm")


# the mixed formulation's linear solver (mixed.py): GMRES on the saddle point, a full Schur-complement
# factorization with GAMG on the displacement block and Jacobi on the scaled pressure mass matrix
MIXED_DEFAULTS = (("ksp_type", "gmres"), ("pc_type", "fieldsplit"), ("pc_fieldsplit_type", "schur"),
                  ("pc_fieldsplit_schur_fact_type", "full"), ("fieldsplit_u_ksp_type", "preonly"),
                  ("fieldsplit_u_pc_type", "gamg"), ("fieldsplit_p_ksp_type", "preonly"),
                  ("fieldsplit_p_pc_type", "jacobi"))


# the mixed formulation's Newton: full steps (the load step halved where a solve fails), GMRES restarted every 100
# iterations, not PETSc's 30, and stopped at 1000, not 10,000. Measured on a rubber L-bracket (docs/mixed.md, "Thin
# parts"): a rotation's linearization changes the volume by ~theta^2, so a full step raises the residual norm ~10x
# before Newton converges quadratically, and the residual-norm backtracking takes lambda = 0.1 for ten steps;
# GMRES(30) stagnates there where GMRES(100) needs 60-150; a solve at a wild iterate that fails anyway fails at a
# tenth of the cost. Where full steps are accepted (Cook's membrane) both line searches cost alike.
MIXED_NEWTON = (("snes_linesearch_type", "basic"), ("ksp_gmres_restart", "100"), ("ksp_max_it", "1000"))
MIXED_MERITS = {"basic": "none (full Newton steps)", "nleqerr": "Newton correction (NLEQ-ERR)"}
# PETSc's kernel for the Galerkin products P^T A P of the field split's GAMG, which it forms at every Newton step:
# PETSc's default (`scalable`) took 1.6-2.3x as long as `rap` on one rank and 2.3-4x as long as `nonscalable` on
# two for the same products (Cook's membrane, BENCHMARKS.md "The Galerkin products' kernel"); the sequential and
# the parallel matrices offer different kernels
GALERKIN_KERNELS = ("rap", "nonscalable")      # (one rank, several)


def apply_mixed_defaults(ranks=1):
    """The mixed formulation's solver defaults where the options database does not set them: the field split's
    when no -pc_type or -pc_type fieldsplit is given (a user's -pc_type lu, say, replaces all of it), with the
    faster kernel for its GAMG's Galerkin products on this many ranks (GALERKIN_KERNELS); full Newton steps,
    GMRES(100), at most 1000 Krylov iterations (MIXED_NEWTON). Returns the line search merit."""
    opts = PETSc.Options()
    split = not opts.getBool("snes_mf", False) and opts.getString("pc_type", "fieldsplit") == "fieldsplit"
    for k, v in MIXED_DEFAULTS:
        if (k == "ksp_type" or split) and not opts.hasName(k):
            opts.setValue(k, v)
    if split and opts.getString("fieldsplit_u_pc_type", "") == "gamg" and not opts.hasName("matptap_via"):
        opts.setValue("matptap_via", GALERKIN_KERNELS[ranks > 1])
    if opts.getString("snes_type", "newtonls") == "newtonls":
        gmres = opts.getString("ksp_type", "") in ("gmres", "fgmres")
        for k, v in MIXED_NEWTON:
            if not opts.hasName(k) and (gmres or not k.startswith("ksp_")):   # (preonly reads neither)
                opts.setValue(k, v)
    return MIXED_MERITS.get(opts.getString("snes_linesearch_type", "bt"), MERITS[1])


def apply_defaults(merit="residual norm", symmetric=True):
    """This application's defaults, where the options database does not set them. With the energy
    merit, a Krylov solve that stops early (CG at negative curvature: DIVERGED_INDEFINITE_MAT) still
    gives a descent direction for the energy (Steihaug 1983), so it does not end the Newton solve:
    the line search decides; more Newton iterations are allowed for such steps."""
    opts = PETSc.Options()
    energy = merit == "energy"
    defaults = [("ksp_type", "cg" if symmetric else "gmres"), ("snes_max_it", "100" if energy else "50")]
    if opts.getString("snes_type", "newtonls") == "newtonls":
        defaults.append(("snes_linesearch_type", "bt"))
    for k, v in defaults:
        if not opts.hasName(k):
            opts.setValue(k, v)
    if energy and not opts.hasName("snes_max_linear_solve_fail"):
        opts.setValue("snes_max_linear_solve_fail", opts.getString("snes_max_it"))
    if not opts.hasName("pc_type"):
        opts.setValue("pc_type", "none" if opts.getBool("snes_mf", False) else "jacobi")


def resolve_storage(storage, system, jacobian, assembly, mf):
    """-operator_storage: `aij`, or `sbaij` where it applies — the tangent's upper triangle is all the
    Krylov method sees of it, so it must be symmetric, assembled (by setvalues), and the operator SNES
    multiplies by (not MFFD's); or `shell` — the Krylov method multiplies by the cells' action, the
    preconditioner is built from the assembled AIJ (assembled by setvalues, not under MFFD). `auto`
    (default): sbaij where it applies, else aij; an explicit sbaij or shell where it does not is an error."""
    if storage == "aij":
        return storage
    if getattr(system, "mixed", False):
        # sbaij: the Krylov method multiplies by a MatNest whose displacement block is an SBAIJ copy (the field
        # split's GAMG smooths with it: -pc_fieldsplit_diag_use_amat); the PC is built from the AIJ
        ok = mixed_blocks(mf) and all(e.symmetric for e in system.effects)
        if storage == "auto":
            return "sbaij" if ok else "aij"
        if storage == "sbaij" and not ok:
            raise UserError(f"option -operator_storage {storage}: the mixed formulation's SBAIJ displacement block "
                            "needs the field split (-pc_type fieldsplit), no MFFD and a symmetric tangent; use aij")
        if storage != "sbaij":
            raise UserError(f"option -operator_storage {storage}: the mixed formulation's tangent is stored as AIJ "
                            "(or sbaij: its displacement block)")
        return storage
    if storage == "auto":
        ok = (jacobian == "assembled" and assembly == "setvalues" and not mf
              and all(e.symmetric for e in system.effects))
        return "sbaij" if ok else "aij"
    what = f"option -operator_storage {storage}"
    if mf:
        raise UserError(f"{what}: the Krylov method multiplies by MFFD under -snes_{mf}; use -operator_storage aij")
    if jacobian != "assembled":
        raise UserError(f"{what}: stores the assembled tangent; not with -jacobian {jacobian}")
    if assembly != "setvalues":
        raise UserError(f"{what}: needs -assembly setvalues (the exact pattern), not {assembly}")
    unsym = [e.name for e in system.effects if not e.symmetric]
    if unsym and storage == "sbaij":
        raise UserError(f"{what}: the tangent of {', '.join(unsym)} is not symmetric; use -operator_storage aij")
    return storage


def mixed_blocks(mf):
    """The mixed tangent by blocks (mixed.MixedNest): under the field split without MFFD; else one AIJ."""
    return not mf and PETSc.Options().getString("pc_type", "") == "fieldsplit"


def matrix_free():
    """'mf', 'mf_operator' or '' from -snes_mf / -snes_mf_operator."""
    opts = PETSc.Options()
    if opts.getBool("snes_mf", False):
        return "mf"
    if opts.getBool("snes_mf_operator", False):
        return "mf_operator"
    return ""


class Solver:
    mixed = False        # the system is the mixed formulation's (mixed.py): its field split
    schur_pre = None     # its Schur complement's preconditioning matrix (MixedSystem.pressure_mass)
    unrecorded = ()      # options this application set by the rank count (a restart on other ranks sets its own)
    def __init__(self, system, jacobian, assembly="setvalues", guard=False, objective=True, snes=None,
                 reuse_pc="auto", storage="auto"):
        """SNES on the system's residual with Jacobian mode `jacobian` (scene.JACOBIANS; filled by
        `assembly` when assembled); guard: shorten Newton updates that would invert an element;
        objective: register the system's incremental potential as the SNES objective (the line
        search merit) when every effect has one (`merit`; `merit_note` says why not otherwise).
        snes: a PETSc TS's SNES (ts_integrator.py), whose function and Jacobian the TS sets and whose
        options the TS reads; the operator `op` is built here all the same.
        storage: `sbaij` multiplies by an SBAIJ copy of the assembled tangent (jacobians.AssembledChunked;
        the PC is built from the AIJ): only for a symmetric tangent, assembled by setvalues; `auto`: sbaij
        where it applies, else aij (`self.storage`: the one chosen)."""
        self.system = system
        sp = system.space
        self.merit_note = ""
        self.notes = []              # what the run should say at its start (run.py), one line each
        if snes is not None and objective:
            self.merit_note = "under -integrator ts the line search merit is the residual norm"
        elif objective and not system.conservative:
            self.merit_note = (f"{', '.join(system.nonconservative())} has no potential: the line search "
                               "merit is the residual norm")
        self.mixed = getattr(system, "mixed", False)
        self.merit = MERITS[0] if objective and system.conservative and snes is None else MERITS[1]
        if self.mixed:
            had = PETSc.Options().hasName("matptap_via")
            self.merit = apply_mixed_defaults(sp.comm.getSize())
            if not had and PETSc.Options().hasName("matptap_via"):
                self.unrecorded = ("matptap_via",)
            if objective:
                how = ("full Newton steps, a smaller load step where a solve fails"
                       if self.merit == MIXED_MERITS["basic"] else f"the line search merit is the {self.merit}")
                self.merit_note = ("the mixed formulation's solution is a saddle point, not a minimum: no energy "
                                   f"merit; {how}")
        self.pc_chosen = PETSc.Options().hasName("pc_type")       # (by the user or a recipe: never changed)
        self.reuse_mode = reuse_pc
        apply_defaults(self.merit, all(e.symmetric for e in system.effects))
        self.mf = matrix_free()
        self.R = system.unknown_vec()
        own = snes is None
        self.snes = snes = PETSc.SNES().create(comm=sp.comm) if own else snes
        if own:
            snes.setFunction(self._residual, self.R)
        if self.merit == "energy":
            snes.setObjective(self._objective)
            snes.setUpdate(self._newton_iterate)
        self.op = None
        self.storage = resolve_storage(storage, system, jacobian, assembly, self.mf)
        if self.mf != "mf":   # under -snes_mf no Jacobian of ours is used: do not build one
            self.op = ((mixed.MixedNest(system, self.storage) if mixed_blocks(self.mf) else
                        mixed.MixedAssembled(system)) if self.mixed else
                       jacobians.make(system, jacobian, assembly, self.storage))
            if own:
                snes.setJacobian(self._jacobian, self.op.operator, self.op.mat)
        self.inversion_cuts = 0   # Newton updates shortened so that no element inverts
        self.guard = None
        if guard:
            self.guard = system.elastic_kernels()
            snes.setLineSearchPreCheck(self._precheck)
        if self.mixed and self.storage == "sbaij" and not PETSc.Options().hasName("pc_fieldsplit_diag_use_amat"):
            PETSc.Options().setValue("pc_fieldsplit_diag_use_amat", "1")     # GAMG smooths with the SBAIJ block
        if own:
            snes.setFromOptions()
        if self.mixed:
            self._field_split()
            if system.constant_pressure_free and self.op is not None:
                self._constant_pressure(system)
        self.reuse = None
        self.linear_solves, self.linear_its = 0, 0
        if self.op is not None:
            self.snes.getKSP().setPostSolve(self._after_linear_solve)
        self._setup_reuse(reuse_pc)
        self.ev_res = PETSc.Log.Event("HE_Residual")
        self.ev_jac = PETSc.Log.Event("HE_Jacobian")

    def _field_split(self):
        """Under -pc_type fieldsplit: the fields u (displacements, with the rigid-body near null space) and p
        (pressures), and the Schur complement preconditioned by -(1/mu + 1/kappa) M_p unless the options choose."""
        pc = self.snes.getKSP().getPC()
        if pc.getType() != "fieldsplit":
            return
        sysm = self.system
        pc.setFieldSplitIS(("u", sysm.is_u), ("p", sysm.is_p))
        if not PETSc.Options().hasName("pc_fieldsplit_schur_precondition"):
            if self.schur_pre is None:               # (constant: assembled once, kept for a new KSP)
                self.schur_pre = sysm.pressure_mass()
            pc.setFieldSplitSchurPreType(PETSc.PC.FieldSplitSchurPreType.USER, self.schur_pre)

    def _constant_pressure(self, sysm):
        """A part whose whole boundary moves as prescribed, incompressible: the pressure is known up to a constant,
        the tangent singular. Its null space on the operators (the Krylov method keeps the constant out of every
        update: the pressure's constant stays where it starts) and on is_p (the field split's Schur complement)."""
        ns, nsp = sysm.constant_pressure_nullspace()
        for A in {self.op.mat.handle: self.op.mat, self.op.operator.handle: self.op.operator}.values():
            A.setNullSpace(ns)
            A.setTransposeNullSpace(ns)
        sysm.is_p.compose("nullspace", nsp)
        self.constant_pressure = ns
        self.notes.append("incompressible with every displacement of the boundary prescribed: the pressure is known "
                          "up to a constant (it stays at its start)")

    # preconditioner set-ups worth keeping across Newton iterations and time steps (multigrid hierarchies)
    REUSED_PCS = ("gamg",)
    REBUILD_RATIO = 1.5

    def _setup_reuse(self, mode):
        """-reuse_preconditioner auto: where the PC's set-up is expensive (GAMG), keep it across Newton
        iterations and steps (SNESSetLagPreconditioner -1, persisting) until a Krylov solve needs more
        than REBUILD_RATIO x the iterations of the first solve after the last set-up, or fails; then
        rebuild at the next Jacobian (lag -2). The mixed formulation's field split is set up again at every
        Jacobian (cheap: its blocks are the MatNest's), and its displacement split's GAMG is kept the same way
        (PCSetReusePreconditioner on that split, not SNES's lag). `never`: PETSc's default, a set-up per
        Jacobian."""
        opts = PETSc.Options()
        if mode == "never" or self.op is None or opts.hasName("snes_lag_preconditioner"):
            return                          # (or the user chose a lag)
        pc = self.snes.getKSP().getPC()
        ptype = pc.getType() or opts.getString("pc_type", "")
        if self.mixed:
            if ptype == "fieldsplit" and opts.getString("fieldsplit_u_pc_type", "") in self.REUSED_PCS:
                self.reuse = {"base": None, "pending": True, "setups": 0}
            return
        if ptype not in self.REUSED_PCS:
            return                          # cheap set-up
        self.reuse = {"base": None, "pending": True, "setups": 0}
        lag_preconditioner_persists(self.snes)
        lag_preconditioner(self.snes, -2)

    # what a quasi-static step whose CG + Jacobi solve ran out of iterations is retried with (options/gamg.opts)
    ESCALATION = (("pc_gamg_type", "agg"), ("pc_gamg_agg_nsmooths", "1"), ("mg_levels_ksp_type", "chebyshev"),
                  ("mg_levels_pc_type", "jacobi"))

    def escalate(self):
        """CG + Jacobi ran out of iterations on a quasi-static step: switch the preconditioner of the assembled
        tangent to GAMG with the rigid-body near null space (its set-up kept across steps) and say so; the
        caller retries the step. Only for the default Jacobi (no -pc_type given), not the mixed formulation's
        field split, and once. Returns the note, or "" when it does not apply. Jacobi stays the default: it is
        faster on dynamic and small runs and keeps its Krylov directions descent directions on indefinite
        tangents, where GAMG's Chebyshev smoothing became an indefinite preconditioner (a soft cantilever at
        full load: docs/design.md, "Solver defaults")."""
        ksp = self.snes.getKSP()
        pc = ksp.getPC()
        if (self.pc_chosen or self.mixed or self.op is None or self.mf or pc.getType() != "jacobi"
                or self.op.mat.getType() not in ("seqaij", "mpiaij")):
            return ""
        opts = PETSc.Options()
        for k, v in self.ESCALATION:
            if not opts.hasName(k):
                opts.setValue(k, v)
        opts.setValue("pc_type", "gamg")
        its = ksp.getIterationNumber()
        pc.setType("gamg")
        pc.setFromOptions()
        self._setup_reuse(self.reuse_mode)
        self.notes.append("switched to GAMG")
        return (f"{ksp.getType().upper()} + Jacobi ran out of iterations ({its}) on a quasi-static step: retrying "
                "it with GAMG (rigid-body modes; -options_file options/gamg.opts from the start saves the failed "
                "attempt)")

    def rebuild_preconditioner(self):
        """Set the preconditioner up again at the next Jacobian (also where a restart would begin, so
        that a restarted run and the uninterrupted one build it at the same point)."""
        if self.reuse is not None:
            self.reuse["pending"] = True
            if not self.mixed:
                lag_preconditioner(self.snes, -2)
        if self.mixed and self.snes.getKSP().getPC().getType() == "fieldsplit":
            # the field split's GAMG keeps state from one set-up to the next (a ILU split does not): a new KSP
            # where a restart begins, so that both runs continue bitwise alike (and its splits, new, are set up
            # at the next solve whether or not the old ones were kept)
            old = self.snes.getKSP()
            ksp = PETSc.KSP().create(comm=old.getComm())
            ksp.setOptionsPrefix(old.getOptionsPrefix())
            self.snes.setKSP(ksp)
            ksp.setFromOptions()
            ksp.setPostSolve(self._after_linear_solve)
            self._field_split()

    def _after_linear_solve(self, ksp, b, x):
        its = ksp.getIterationNumber()
        self.linear_solves += 1
        self.linear_its += its
        r = self.reuse
        if r is None:
            return
        split = ksp.getPC().getFieldSplitSubKSP()[0].getPC() if self.mixed else None   # (kept only under the split)
        if r["pending"]:
            r.update(base=max(its, 1), pending=False, setups=r["setups"] + 1)
            if split is not None:           # keep the displacement split's set-up from now on
                split.setReusePreconditioner(True)
        elif ksp.getConvergedReason() < 0 or its > self.REBUILD_RATIO * r["base"]:
            if split is not None:           # set it up at the next solve (not a new KSP: this one is still solving)
                r["pending"] = True
                split.setReusePreconditioner(False)
            else:
                self.rebuild_preconditioner()

    # CG + Jacobi iterations per Newton step above which CG + GAMG, its set-up kept across steps, was
    # faster end to end (bend, 60k-521k tets, four regimes: BENCHMARKS.md, bench_solvers.py --only crossover)
    GAMG_PAYS_ABOVE = 100

    def advice(self):
        """A line for the user when the run's own Krylov iterations say another preconditioner of the
        assembled tangent would have been faster ("" otherwise)."""
        if self.op is None or self.mf or not self.linear_solves:
            return ""
        pc = self.snes.getKSP().getPC()
        if pc.getType() != "jacobi" or self.op.mat.getType() not in ("seqaij", "mpiaij"):
            return ""
        its = self.linear_its / self.linear_solves
        if its <= self.GAMG_PAYS_ABOVE:
            return ""
        return (f"{self.snes.getKSP().getType()} + Jacobi took {its:.0f} Krylov iterations per Newton step; "
                f"above ~{self.GAMG_PAYS_ABOVE} CG + GAMG with its set-up kept (-options_file options/gamg.opts) "
                "was faster end to end (measured at 60k-521k tets, BENCHMARKS.md)")

    def _residual(self, snes, X, R):
        self.ev_res.begin()
        self.system.residual(X, R)
        if self.system.undefined_cells():
            set_function_domain_error(snes)
        self.ev_res.end()

    def _objective(self, snes, X):
        return self.system.objective(X)

    def _newton_iterate(self, snes, its):
        """At the start of every Newton iteration: the objective is measured from this iterate."""
        self.system.set_objective_base(snes.getSolution())

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
        if J.handle != self.op.operator.handle:
            J.assemble()   # MFFD operator (-snes_mf_operator): new base point
        self.ev_jac.end()

    def solve(self, X):
        self.system.set_objective_base(None)
        self.snes.solve(None, X)
        return self.snes.getConvergedReason()

    def reason_name(self, reason):
        return enum_name(PETSc.SNES.ConvergedReason, reason)

    def ksp_reason_name(self):
        """The last Krylov solve's converged reason, by name."""
        return enum_name(PETSc.KSP.ConvergedReason, self.snes.getKSP().getConvergedReason())


def enum_name(enum, value):
    names = {v: k for k, v in vars(enum).items() if isinstance(v, int) and not k.startswith("_")}
    return names.get(value, str(value))
