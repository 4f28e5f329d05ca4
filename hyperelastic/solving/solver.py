"""SNES / KSP / PC from the options database, with this application's defaults: Newton with a
backtracking line search on the incremental potential (energy merit, SNESSetObjective) where every
effect has one, else on the residual norm; CG (GMRES when an effect's tangent is not symmetric: follower
loads) + Jacobi (no PC under -snes_mf)."""
import os

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import jacobians, pmg
from ..core.data import OPTIONS_DIR
from ..core.errors import UserError
from ..core.options import parse_options_file
from ..core.libpetsc import lag_preconditioner, lag_preconditioner_persists, set_function_domain_error
from ..physics.effects.seams import StepLimiter, declaring

MERITS = ("energy", "residual norm")


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
    for k in REPRODUCIBLE_VEC:
        if not opts.hasName(k):
            opts.setValue(k, "0")


# PETSc's multiple dot products and updates (GMRES's Gram-Schmidt) through BLAS gemv group the vectors by whether
# their arrays happen to lie next to each other in memory, so their sums' order, and a GMRES run's last bits, changed
# with the heap's layout: the same mixed run differed by 1e-13 with the length of an unrelated environment variable,
# and a restart was not bitwise (issue 47's promise). PETSc's own loops sum in one order; at 9k P2 tets (Cook's
# membrane, GMRES(100) in the field split) the runs took the same time (farm-bench 0.98, within noise).
REPRODUCIBLE_VEC = ("vec_mdot_use_gemv", "vec_maxpy_use_gemv")


def recipe_pc(recipe):
    """(the PC type, [(option, value)] of the PC's own options) of the recipe options/RECIPE.opts: the options that
    are neither -pc_type nor the Jacobian's or the Krylov method's."""
    rows = parse_options_file(os.path.join(OPTIONS_DIR, recipe + ".opts"))
    return dict(rows)["pc_type"], [(k, v) for k, v in rows if k not in ("pc_type", "jacobian", "ksp_type")]


def resolve_storage(storage, system, jacobian, assembly, mf):
    """-operator_storage: `aij`, or `sbaij` where it applies — the tangent's upper triangle is all the
    Krylov method sees of it, so it must be symmetric, assembled (by setvalues), and the operator SNES
    multiplies by (not MFFD's); or `shell` — the Krylov method multiplies by the cells' action, the
    preconditioner is built from the assembled AIJ (assembled by setvalues, not under MFFD). `auto`
    (default): sbaij where it applies, else aij; an explicit sbaij or shell where it does not is an error."""
    if storage == "aij":
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


def matrix_free():
    """'mf', 'mf_operator' or '' from -snes_mf / -snes_mf_operator."""
    opts = PETSc.Options()
    if opts.getBool("snes_mf", False):
        return "mf"
    if opts.getBool("snes_mf_operator", False):
        return "mf_operator"
    return ""


# the statistics columns of the limiters' cuts that every run writes (stats.COLUMNS)
CUT_COUNTERS = ("inversion_cuts", "contact_cuts")


class InversionGuard(StepLimiter):
    """-inversion_guard as a Newton-step limiter: the largest t <= 1 that keeps every (not already inverted) cell's
    det F > 0 along x + [0, t] dx, 0.9 of it where a cell would invert (the elastic kernels' bound: the cubic det F at
    every quadrature point). A cut anywhere in a solve makes its step-norm stop not convergence (issue 47)."""
    counter = "inversion_cuts"
    sticky = True

    def __init__(self, kernels):
        self.kernels = kernels

    def max_step(self, x, dx):
        return self.kernels.max_step(x, dx)


class SolverPlan:
    """How a formulation's system is solved, as far as the Solver asks (formulations/base.py: each formulation names
    its plan). This base is the displacement formulation's: this application's defaults (apply_defaults), the
    Jacobian operators of jacobians.py, a GAMG set-up kept by SNES's lag, and a quasi-static CG + Jacobi solve that
    runs out of iterations retried with GAMG. A formulation with other needs subclasses it (the mixed formulation's
    field split: formulations/mixed/solver.py); the Solver holds no formulation's branch."""
    escalates = True       # a quasi-static CG + Jacobi solve that runs out of iterations may switch to GAMG
    ksp_hints = None       # {KSP converged reason: what to try}, where the integrator's own do not fit

    def defaults(self, solver, objective):
        """Set this formulation's defaults in the options database (before apply_defaults), and the solver's
        `merit`, `merit_note` and `unrecorded` where they differ from the displacement formulation's. Here: a static
        run (no inertia, no damping) on quadratic tetrahedra with an assembled tangent and no -pc_type gets CG +
        p-multigrid (options/pmg.opts' preconditioner), chosen by measurement (docs/defaults.md: 807 CG + Jacobi
        iterations per Newton step against 13 on `bend -level 4 -order 2 -quasistatic`); every other run keeps
        Jacobi (apply_defaults)."""
        opts = PETSc.Options()
        if (pmg.applies(solver.system.space) and not any(e.order for e in solver.system.effects)
                and solver.jacobian == "assembled" and not matrix_free() and not opts.hasName("pc_type")):
            ptype, pc_options = recipe_pc("pmg")
            for k, v in pc_options:
                if not opts.hasName(k):
                    opts.setValue(k, v)
            opts.setValue("pc_type", ptype)

    def storage(self, storage, system, jacobian, assembly, mf):
        """The -operator_storage this run uses (resolve_storage)."""
        return resolve_storage(storage, system, jacobian, assembly, mf)

    def operator(self, system, jacobian, assembly, storage, mf):
        """The Jacobian operator SNES uses (`mat`, `operator`, `update()`), or None under -snes_mf (MFFD, no PC)."""
        return None if mf == "mf" else jacobians.make(system, jacobian, assembly, storage, pmg.requested(system.space))

    def before_options(self, solver):
        """Options the plan sets once the operator exists, before SNES reads the options database: -pc_type mg on
        quadratic tetrahedra gets the P2 -> P1 levels (pmg.py)."""
        if solver.op is not None:
            pmg.before_options(solver.system.space)

    def configure(self, solver):
        """After SNES has read the options: the preconditioner's structure (the field split's fields; p-multigrid's
        interpolation)."""
        if solver.op is not None:
            solver.levels = pmg.configure(solver.snes.getKSP().getPC(), solver.system.space, solver.op)

    def reuse(self, solver, ptype):
        """-reuse_preconditioner auto: the reuse state where this run's set-up is worth keeping (GAMG), kept by
        SNES's lag (persisting, rebuilt at the next Jacobian: lag -2); None where it is not."""
        if ptype not in solver.REUSED_PCS:
            return None
        lag_preconditioner_persists(solver.snes)
        lag_preconditioner(solver.snes, -2)
        return {"base": None, "pending": True, "setups": 0}

    def kept_split(self, ksp):
        """The split of a field-split PC whose set-up is kept (PCSetReusePreconditioner), or None: SNES's lag keeps
        the whole PC."""
        return None

    def rebuild(self, solver):
        """Set the preconditioner up again at the next Jacobian (the caller marked the reuse state pending)."""
        if solver.reuse is not None:
            lag_preconditioner(solver.snes, -2)


class Solver:
    unrecorded = ()      # options this application set by the rank count (a restart on other ranks sets its own)

    def __init__(self, system, jacobian, assembly="setvalues", guard=False, objective=True, snes=None,
                 reuse_pc="auto", storage="auto", plan=None, diverging=3):
        """SNES on the system's residual with Jacobian mode `jacobian` (scene.JACOBIANS; filled by
        `assembly` when assembled); guard: shorten Newton updates that would invert an element;
        objective: register the system's incremental potential as the SNES objective (the line
        search merit) when every effect has one (`merit`; `merit_note` says why not otherwise).
        snes: a PETSc TS's SNES (ts_integrator.py), whose function and Jacobian the TS sets and whose
        options the TS reads; the operator `op` is built here all the same.
        storage: `sbaij` multiplies by an SBAIJ copy of the assembled tangent (jacobians.AssembledChunked;
        the PC is built from the AIJ): only for a symmetric tangent, assembled by setvalues; `auto`: sbaij
        where it applies, else aij (`self.storage`: the one chosen). plan: the formulation's SolverPlan
        (default: the displacement formulation's)."""
        self.system = system
        self.jacobian = jacobian
        self.plan = plan or SolverPlan()
        self.notes = []              # what the run should say at its start (run.py), one line each
        self._merit(objective, snes is not None)
        self.pc_chosen = PETSc.Options().hasName("pc_type")       # (by the user or a recipe: never changed)
        self.reuse_mode = reuse_pc
        apply_defaults(self.merit, all(e.symmetric for e in system.effects))
        self.mf = matrix_free()
        self.R = system.unknown_vec()
        own = snes is None
        self.snes = snes = PETSc.SNES().create(comm=system.space.comm) if own else snes
        if own:
            snes.setFunction(self._residual, self.R)
        if self.merit == "energy":
            snes.setObjective(self._objective)
            snes.setUpdate(self._newton_iterate)
        self.storage = self.plan.storage(storage, system, jacobian, assembly, self.mf)
        self.op = self.plan.operator(system, jacobian, assembly, self.storage, self.mf)
        if self.op is not None and own:
            snes.setJacobian(self._jacobian, self.op.operator, self.op.mat)
        self.levels = None        # p-multigrid's levels (pmg.py), where the run uses them
        self._set_limiters(guard)
        self.plan.before_options(self)
        if own:
            snes.setFromOptions()
            self.plan.configure(self)       # (a TS's SNES: once the TS has read the options, ts_integrator.py)
        self.reuse = None
        self.last_imbalance = 0.0        # the last step-norm stop's residual against the largest force (imbalance)
        self.carried = (0, 0)            # the (Newton, Krylov) iterations of a solve before Newton went on (_newton_on)
        self.snes.setConvergenceHistory(reset=True)     # (|F0| of each solve: _newton_on's target)
        self.linear_solves, self.linear_its = 0, 0
        self.indefinite_solves = 0       # Krylov solves that stopped at negative curvature (DIVERGED_INDEFINITE_MAT)
        if self.op is not None:
            self.snes.getKSP().setPostSolve(self._after_linear_solve)
        self._setup_reuse(reuse_pc)
        self.diverging = diverging if snes.getLineSearch().getType() in self.UNGUARDED and own else 0
        self.diverged_early = False      # the last solve was stopped by _watch_divergence
        if self.diverging:
            snes.setMonitor(self._watch_divergence)
        self.ev_res = PETSc.Log.Event("HE_Residual")
        self.ev_jac = PETSc.Log.Event("HE_Jacobian")

    def _set_limiters(self, guard):
        """The Newton-step limiters (seams.StepLimiter), applied in the line search's pre-check: the inversion guard
        first (a tie is its cut), then the effects'; their cuts counted by column."""
        self.limiters = ([InversionGuard(self.system.elastic_kernels())] if guard else []) + \
            declaring(self.system.effects, StepLimiter)
        self.cuts = dict.fromkeys(CUT_COUNTERS + tuple(lim.counter for lim in self.limiters), 0)
        self.sticky_cuts = 0      # cuts by a sticky limiter (the inversion guard) over the run ...
        self.last_cut_at = -1     # ... and the Newton iteration of this solve's last cut by any limiter
        if self.limiters:
            self.snes.setLineSearchPreCheck(self._precheck)

    def _merit(self, objective, under_ts):
        """The line search merit: the energy where every effect has a potential and SNES is ours, else the residual
        norm, and the note that says why (the plan may choose otherwise)."""
        system = self.system
        self.merit_note = ""
        if under_ts and objective:
            self.merit_note = "under -integrator ts the line search merit is the residual norm"
        elif objective and not system.conservative:
            self.merit_note = (f"{', '.join(system.nonconservative())} has no potential: the line search "
                               "merit is the residual norm")
        self.merit = MERITS[0] if objective and system.conservative and not under_ts else MERITS[1]
        self.plan.defaults(self, objective)

    # preconditioner set-ups worth keeping across Newton iterations and time steps (multigrid hierarchies)
    REUSED_PCS = ("gamg", "mg")
    REBUILD_RATIO = 1.5

    def _setup_reuse(self, mode):
        """-reuse_preconditioner auto: where the PC's set-up is expensive (GAMG), keep it across Newton
        iterations and steps until a Krylov solve needs more than REBUILD_RATIO x the iterations of the first
        solve after the last set-up, or fails; then rebuild at the next Jacobian. How it is kept is the plan's
        (SolverPlan.reuse: SNES's lag; the mixed formulation's: PCSetReusePreconditioner on its displacement
        split). `never`: PETSc's default, a set-up per Jacobian."""
        opts = PETSc.Options()
        if mode == "never" or self.op is None or opts.hasName("snes_lag_preconditioner"):
            return                          # (or the user chose a lag)
        pc = self.snes.getKSP().getPC()
        self.reuse = self.plan.reuse(self, pc.getType() or opts.getString("pc_type", ""))

    # what a quasi-static step whose CG + Jacobi solve ran out of iterations is retried with: the preconditioner of a
    # recipe (its PC options; the run keeps its Jacobian and Krylov method), GAMG. (Quadratic tetrahedra start static
    # runs with p-multigrid: SolverPlan.defaults.)
    ESCALATION = ("gamg", "GAMG")

    def escalate(self):
        """CG + Jacobi ran out of iterations on a quasi-static step: switch the preconditioner of the assembled
        tangent to GAMG with the rigid-body near null space (its set-up kept across steps) and say so; the caller
        retries the step. Only for the default Jacobi (no -pc_type given), where the plan allows it (not the mixed
        formulation's field split), and once. Returns the note, or "" when it does not apply. Jacobi stays the
        default of linear tetrahedra: it is faster on dynamic and small runs and keeps its Krylov directions descent
        directions on indefinite tangents, where GAMG's Chebyshev smoothing became an indefinite preconditioner (a soft
        cantilever at full load: docs/defaults.md)."""
        ksp = self.snes.getKSP()
        pc = ksp.getPC()
        if (self.pc_chosen or not self.plan.escalates or self.op is None or self.mf or pc.getType() != "jacobi"
                or self.op.mat.getType() not in ("seqaij", "mpiaij")):
            return ""
        opts = PETSc.Options()
        recipe, name = self.ESCALATION
        ptype, pc_options = recipe_pc(recipe)
        for k, v in pc_options:
            if not opts.hasName(k):
                opts.setValue(k, v)
        opts.setValue("pc_type", ptype)
        its = ksp.getIterationNumber()
        pc.setType(ptype)
        pc.setFromOptions()
        self.levels = pmg.configure(pc, self.system.space, self.op)      # (None but for p-multigrid)
        self._setup_reuse(self.reuse_mode)
        self.notes.append(f"switched to {name}")
        return (f"{ksp.getType().upper()} + Jacobi ran out of iterations ({its}) on a quasi-static step: retrying "
                f"it with {name} (rigid-body modes; -options_file options/{recipe}.opts from the start saves the "
                "failed attempt)")

    def project_hessians(self):
        """A quasi-static attempt failed with most of its CG solves stopped at negative curvature (an indefinite tangent:
        a P2 rubber twisted with -formulation displacement took 50-100 Newton iterations a step and failed steps):
        switch the elastic tangent to its cells' positive semi-definite projections (-hessian_projection) for the rest
        of the run and say so; the caller retries the step. The minimizer is the same (the projection changes Newton's
        direction, not the energy). Only with the energy merit, where -hessian_projection was not given, and once.
        Returns the note, or ""."""
        if self.merit != MERITS[0] or PETSc.Options().hasName("hessian_projection"):
            return ""
        turned = [e for e in self.system.effects if e.projection is False]
        if not turned:
            return ""
        for e in turned:
            e.projection = True
        self.notes.append("switched to -hessian_projection 1")
        return ("CG stopped at negative curvature in most Newton iterations of a failed quasi-static step (an "
                "indefinite tangent): retrying it with the cells' tangents projected to positive semi-definite "
                "(-hessian_projection 1 from the start saves the failed attempt)")

    def held_response(self, X, move, delta, tangent=True):
        """(Z, Krylov iterations, converged): the free dofs' linear response at X to moving the held targets along a
        direction, J(X) Z = -(R(X; +delta) - R(X; -delta)) / (2 delta) with the held rows zero (J_fc applied by a
        central difference of the residual in the targets). move(s) sets the targets s along the direction (move(0):
        back where they were); tangent: compute the Jacobian at X first (else the one computed last). Used by the
        first step's linearized start (integrators.py) and a rigid face's balance (rigid.py)."""
        sysm, snes = self.system, self.snes
        Rp, B = X.duplicate(), X.duplicate()
        try:
            move(delta)
            sysm.residual(X, Rp)
            move(-delta)
            sysm.residual(X, B)
        finally:
            move(0.0)
        B.axpy(-1.0, Rp)
        B.scale(0.5 / delta)
        B.getArray()[sysm.c_owned_pos] = 0.0
        if tangent:
            J, P = snes.getJacobian()[:2]
            snes.computeJacobian(X, J, P)
        ksp = snes.getKSP()
        Rp.zeroEntries()
        ksp.solve(B, Rp)
        B.destroy()
        return Rp, ksp.getIterationNumber(), ksp.getConvergedReason() >= 0

    def rebuild_preconditioner(self):
        """Set the preconditioner up again at the next Jacobian (also where a restart would begin, so
        that a restarted run and the uninterrupted one build it at the same point)."""
        if self.reuse is not None:
            self.reuse["pending"] = True
        self.plan.rebuild(self)

    def _after_linear_solve(self, ksp, b, x):
        its = ksp.getIterationNumber()
        self.linear_solves += 1
        self.linear_its += its
        if ksp.getConvergedReason() == PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT:
            self.indefinite_solves += 1
        r = self.reuse
        if r is None:
            return
        split = self.plan.kept_split(ksp)
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
        if pmg.applies(self.system.space):
            return (f"{self.snes.getKSP().getType()} + Jacobi took {its:.0f} Krylov iterations per Newton step; on "
                    "quadratic tetrahedra CG + p-multigrid (-options_file options/pmg.opts) needs about as many as "
                    "P1 with GAMG on the same mesh, at half the time per Newton step of GAMG (BENCHMARKS.md)")
        return (f"{self.snes.getKSP().getType()} + Jacobi took {its:.0f} Krylov iterations per Newton step; "
                f"above ~{self.GAMG_PAYS_ABOVE} CG + GAMG with its set-up kept (-options_file options/gamg.opts) "
                "was faster end to end (measured at 60k-521k tets, BENCHMARKS.md)")

    def _residual(self, snes, X, R):
        self.ev_res.begin()
        self.system.residual(X, R)
        if self.system.undefined_cells():
            set_function_domain_error(snes)
        self.ev_res.end()

    # line searches that do not ask the residual norm to fall (full steps; the critical point's, on the Lagrangian's
    # slope: the mixed formulation's default)
    UNGUARDED = ("basic", "cp")
    # full Newton steps (no line search) may raise the residual norm for an iteration or two and still converge (the
    # mixed formulation under rotation: 1.3 -> 170 -> 40 -> 1.0 -> 0.01 on the rubber bracket); an attempt whose norm
    # stays above DIVERGING_FACTOR x the smallest it has had for `diverging` iterations in a row has not come back in
    # any run measured (docs/design.md, "Diverging full Newton steps"), and ran on to -snes_max_it or a failed Krylov
    # solve (issue 47: a failed mixed attempt burnt 50 Newton and 6,000 GMRES iterations)
    DIVERGING_FACTOR = 10.0

    def _watch_divergence(self, snes, its, fnorm):
        """SNES monitor (UNGUARDED line searches only): stop the solve as DIVERGED_DTOL once the residual norm has
        stayed above DIVERGING_FACTOR x its smallest so far for self.diverging iterations in a row."""
        if its == 0:
            self._best, self._above, self.diverged_early = fnorm, 0, False
            return
        self._above = self._above + 1 if fnorm > self.DIVERGING_FACTOR * self._best else 0
        self._best = min(self._best, fnorm)
        if self._above >= self.diverging and not snes.getConvergedReason():
            self.diverged_early = True
            snes.setConvergedReason(PETSc.SNES.ConvergedReason.DIVERGED_DTOL)

    def _objective(self, snes, X):
        return self.system.objective(X)

    def _newton_iterate(self, snes, its):
        """At the start of every Newton iteration: the objective is measured from this iterate."""
        self.system.set_objective_base(snes.getSolution())

    def _precheck(self, X, Y):
        """Shorten the Newton update (X_new = X - lambda Y) to the smallest step the limiters allow (seams.StepLimiter):
        the inversion guard (no element inverts where the material is undefined there; -inversion_guard, on by
        default for Neo-Hookean), contact's continuous collision detection (no contact node reaches an obstacle, the
        surface does not pass through itself). The factor is the same on every rank (one reduction); the cut is
        counted in the column of the limiter that set it (the first of them on a tie)."""
        sysm = self.system
        x = sysm.impose(sysm.local(X, sysm.xl).copy())
        d = -sysm.local(Y, sysm.vl).copy()
        d[sysm.cdofs] = 0.0
        steps = np.array([lim.max_step(x, d) for lim in self.limiters], float)
        sysm.space.mpi.Allreduce(MPI.IN_PLACE, steps, op=MPI.MIN)
        k = int(np.argmin(steps))
        if steps[k] < 1.0:
            Y.scale(float(steps[k]))
            self._count_cut(self.limiters[k], self.snes.getIterationNumber())
            return True
        return False

    def _count_cut(self, limiter, iteration):
        """The limiter shortened the update of Newton iteration `iteration`."""
        self.cuts[limiter.counter] += 1
        self.sticky_cuts += limiter.sticky
        self.last_cut_at = iteration

    @property
    def inversion_cuts(self):
        return self.cuts["inversion_cuts"]

    @property
    def contact_cuts(self):
        return self.cuts["contact_cuts"]

    def _jacobian(self, snes, X, J, P):
        self.ev_jac.begin()
        self.system.linearize(X)
        self.refresh_operator(P)
        if J.handle != self.op.operator.handle:
            J.assemble()   # MFFD operator (-snes_mf_operator): new base point
        self.ev_jac.end()

    def refresh_operator(self, P):
        """After System.linearize: the operator's values, and at a Jacobian where the PC is set up again p-multigrid's
        coarse operator (from the preconditioning matrix P, or summed from the cells as the operator is filled)."""
        due = self.levels is not None and (self.reuse is None or self.reuse["pending"])
        if due:
            self.levels.prepare()
        self.op.update()
        if due:
            self.levels.update(P)

    # SNES's CONVERGED_SNORM_RELATIVE after the inversion guard cut an update in the solve: the update was small
    # because the guard shortened it, not because Newton converged (PETSc reports SNORM only where the residual norm
    # met neither -snes_rtol nor -snes_atol). Such a solve is refused (issue 47: a loosely toleranced quasi-static
    # step was accepted at J_min 0.107, J_max 2.05 in an incompressible rubber, and every later step failed).
    GUARDED_SNORM = -101

    # A step-norm stop (CONVERGED_SNORM_RELATIVE: the update fell below -snes_stol of |x|) certifies nothing about the
    # residual, and with the positions as the unknown stol |x| is an absolute step (1e-8 of the part's size times the
    # square root of its node count): a barrier that stiff made Newton's updates that small while a node 3e-16 m from
    # a sphere carried 4.4e4 N against held reactions of 4e-6 N, and the step was accepted (issue 72). So a step-norm
    # stop is measured against the forces on the body (`imbalance`: the free dofs' residual against the largest force
    # an effect exerts there, that force at least what a move of -snes_stol times the part's size takes): at or below
    # SNORM_EQUILIBRIUM (0.01%) it stands; above it Newton goes on from there without the step-norm test, to the
    # residual the first solve aimed at (max(atol, rtol |F0|)), within the solve's iterations left (SNORM_MORE at most)
    # and while its residual keeps halving every SNORM_STALL iterations (a barrier's stiff start makes Newton's first
    # updates tiny; quadratic convergence follows: the sphere pressed into a cube, 4-19 iterations a step, balanced to
    # 1e-9; against a triangulated obstacle the IPC toolkit's additive CCD lets each update take ~0.4 of the way, so
    # Newton converges linearly, 0.62 a step: `press` against two triangles, whose steps had stopped at 5e-4 to 2e-3 of
    # the largest force, now takes 38-55 iterations a step to balance, 6.7 s instead of 1.8). Where Newton cannot get
    # there, the stop stands if it was within SNORM_BALANCE, else the solve failed (UNBALANCED_SNORM: two blocks pressed
    # together had stopped after one iteration at 0.17, the sphere at 1) and the step is retried shorter.
    SNORM_EQUILIBRIUM, SNORM_BALANCE, SNORM_MORE = 1e-4, 1e-3, 100
    UNBALANCED_SNORM = -102

    def solve(self, X):
        """Solve for the step's state in X; SNES's converged reason, or GUARDED_SNORM or UNBALANCED_SNORM (a step-norm
        stop refused)."""
        self.system.set_objective_base(None)
        sticky = self.sticky_cuts
        self.last_cut_at = -1
        self.carried = (0, 0)
        self.snes.solve(None, X)
        reason = self.snes.getConvergedReason()
        # (a sticky limiter's cut anywhere in the solve; any cut in its last update: a barrier's stiff start is cut
        # in its first iterations and then converges quadratically to updates below -snes_stol)
        guarded = self.sticky_cuts > sticky or 0 <= self.last_cut_at >= self.snes.getIterationNumber() - 1
        if reason == PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE and guarded:
            return self.GUARDED_SNORM
        if reason == PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE and self.imbalance(X) > self.SNORM_EQUILIBRIUM:
            reason = self._newton_on(X, reason)
        return reason

    def _newton_on(self, X, reason):
        """Newton on from X after a step-norm stop that is not an equilibrium (the comment above): -snes_stol 0, the
        first solve's residual target as the absolute tolerance, at most SNORM_MORE iterations, the first solve's
        iterations carried into `iterations()`. Its reason where it converges; else `reason` with X back at the stop
        where that was within SNORM_BALANCE, or UNBALANCED_SNORM."""
        snes = self.snes
        its, lits = snes.getIterationNumber(), snes.getLinearSolveIterations()
        stop, first = X.copy(), self.last_imbalance
        history = snes.getConvergenceHistory()[0]
        rtol, atol, stol, max_it = snes.getTolerances()
        if len(history):
            seen = []
            snes.setTolerances(max_it=min(self.SNORM_MORE, max(max_it - its, 1)))
            snes.setConvergenceTest(self._going_on, args=(max(atol, rtol * float(history[0])), seen))
            try:
                self.system.set_objective_base(None)
                snes.solve(None, X)
            finally:
                snes.setConvergenceTest("default")
                snes.setTolerances(rtol=rtol, atol=atol, stol=stol, max_it=max_it)
            self.carried = (self.carried[0] + its, self.carried[1] + lits)
            if snes.getConvergedReason() > 0:
                stop.destroy()
                return snes.getConvergedReason()
        self.last_imbalance = first
        if first <= self.SNORM_BALANCE:
            stop.copy(X)
            reason = PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE
        else:
            reason = self.UNBALANCED_SNORM
        stop.destroy()
        return reason

    # Newton going on after a step-norm stop gives up where its residual has not halved in this many iterations: a
    # barrier's rounding floor, not a stiff start (the triangulated plate's stops at 1.4e-4 of the largest force ran
    # 25 iterations in vain a step: its run took 10 s instead of 1.7)
    SNORM_STALL = 3

    def _going_on(self, snes, its, norms, target, seen):
        """The convergence test of Newton going on (_newton_on): the residual at `target`, or stalled, or out of
        iterations; no step-norm test."""
        R = PETSc.SNES.ConvergedReason
        fnorm = norms[2]
        seen.append(fnorm)
        if not np.isfinite(fnorm):
            return R.DIVERGED_FNORM_NAN
        if fnorm <= target:
            return R.CONVERGED_FNORM_ABS
        if len(seen) > self.SNORM_STALL and fnorm > 0.5 * seen[-1 - self.SNORM_STALL]:
            return R.DIVERGED_DTOL
        if its >= snes.getTolerances()[3]:
            return R.DIVERGED_MAX_IT
        return R.ITERATING

    def imbalance(self, X):
        """|R| over the free dofs at X against the largest |r_e| of an effect there (0 where no effect exerts a
        force): how far X is from an equilibrium, as the forces table's balance measures it. Collective."""
        sysm = self.system
        sp = sysm.space
        x = sysm.impose(sysm.local(X, sysm.xl).copy())
        free = np.ones(3 * sp.n_owned, bool)
        free[sysm.c_owned_pos] = False
        total, squares = 0.0, []
        for e in sysm.effects:
            r = sp.sum_owned(sysm.residual_local(x, [e]).reshape(-1, 3)).ravel()[free]
            total = total + r
            squares.append(float(r @ r))
        sq = np.array(squares + [float(np.dot(total, total))])
        sp.mpi.Allreduce(MPI.IN_PLACE, sq, op=MPI.SUM)
        lo, hi = sp.bbox
        floor = sysm.scale * self.snes.getTolerances()[2] * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
        scale = max(float(np.sqrt(sq[:-1].max(initial=0.0))), floor)
        self.last_imbalance = float(np.sqrt(sq[-1])) / scale if scale > 0 else 0.0
        return self.last_imbalance

    def iterations(self):
        """(Newton, Krylov) iterations of the last solve (Newton's continuation included: _newton_on)."""
        return (self.carried[0] + self.snes.getIterationNumber(),
                self.carried[1] + self.snes.getLinearSolveIterations())

    def reason_name(self, reason):
        if reason == PETSc.SNES.ConvergedReason.DIVERGED_DTOL and self.diverged_early:
            return (f"DIVERGED_DTOL: the residual norm stayed above {self.DIVERGING_FACTOR:g}x its smallest for "
                    f"{self.diverging} Newton iterations, -diverging_newton")
        if reason == self.GUARDED_SNORM:
            return "CONVERGED_SNORM_RELATIVE after an update cut by the inversion guard (or, in its last update, by contact): a small step, not convergence"
        if reason == self.UNBALANCED_SNORM:
            return (f"CONVERGED_SNORM_RELATIVE with the residual at {self.last_imbalance:.2g} of the largest force on "
                    "the body: a small step, not an equilibrium")
        return enum_name(PETSc.SNES.ConvergedReason, reason)

    def ksp_reason_name(self):
        """The last Krylov solve's converged reason, by name."""
        return enum_name(PETSc.KSP.ConvergedReason, self.snes.getKSP().getConvergedReason())


def enum_name(enum, value):
    names = {v: k for k, v in vars(enum).items() if isinstance(v, int) and not k.startswith("_")}
    return names.get(value, str(value))
