"""How the mixed formulation is solved (solving/solver.py's SolverPlan, for the saddle point): GMRES, preconditioned on
the right, with the augmented Lagrangian's upper block-triangular Schur-complement field split (operators.Augmented,
gamma = 3 mu) — p-multigrid on the augmented displacement block (its P1 level, the term added cell by cell, by four
Chebyshev iterations of GAMG with the rigid-body near null space), the lumped pressure mass scaled by -(1/(mu + gamma)
+ 1/kappa) as the Schur complement's preconditioner; with -mixed_augment 0 (or GAMG in the displacement split) the
lower factorization with the consistent pressure mass scaled by -(1/mu + 1/kappa) — a line search on the Lagrangian's
slope along the Newton step, the displacement split's multigrid set-up kept across Newton and load steps, and a
constant pressure's null space where the pressure is known only up to a constant."""
import math

from petsc4py import PETSc

from ...core.errors import UserError
from ...solving import pmg
from ...solving.integrators import RAN_OUT
from ...solving.solver import MERITS, SolverPlan
from .operators import MixedAssembled, MixedNest

SPLIT_U = "fieldsplit_u_"        # the displacement split's options prefix
# gamma/mu of the augmented Lagrangian by default (augment_factor; operators.Augmented), 0: off. The rubber bracket
# (thin walls) 48 -> 22 GMRES iterations per Newton step at 2e3 Pa and 68 -> 34 under its full load, Cook's membrane
# 27 -> 18, Lame's cylinder 19-21 -> 11-12 at every kappa/mu, the rod's torsion 31 -> 17, the block 20 -> 13; the time
# 0.76-0.88x on the bracket, 0.95-1.03x on Cook (9k-25k tets, 1 and 2 ranks), 1.1-1.25x on Lame's 876 tets (a 0.12 s
# solve). gamma = 2 mu: the full load 35, Cook 19.5; 5 mu: 41, 18.5 (BENCHMARKS.md, 2026-11-27 tenth session)
AUGMENT = 3.0
# under the augmented Lagrangian: GMRES preconditioned on the right, so that it measures the residual itself (on the
# left the preconditioned residual, T's gamma W^-1 scaling of the pressure rows in it, stayed flat for 100 iterations
# at the first solve of the rubber bracket's second load step under its full load, and GMRES broke down there), and
# p-multigrid's P1 operator (with the term: without it the thin bracket kept 43 GMRES iterations per Newton step)
# solved by four Chebyshev iterations of its GAMG, not one V-cycle: GAMG smooths the grad-div term poorly (the bracket
# under its full load: one V-cycle 66 per Newton step, two Chebyshev iterations 46, three 37, four 34)
AUGMENTED_DEFAULTS = (("ksp_pc_side", "right"), (SPLIT_U + "mg_coarse_ksp_type", "chebyshev"),
                      (SPLIT_U + "mg_coarse_ksp_max_it", "4"), (SPLIT_U + "mg_coarse_ksp_norm_type", "none"))

# the mixed formulation's linear solver: GMRES on the saddle point, a lower block-triangular Schur-complement
# factorization (one displacement solve per application, where the full one takes two: with p-multigrid fewer GMRES
# iterations too, and 0.6-0.7x the time on every case measured; BENCHMARKS.md "The lower factorization") with
# p-multigrid on the displacement block (P2 smoothed, its P1 Galerkin operator by a GAMG V-cycle: pmg.py, SplitLevels
# below; -fieldsplit_u_pc_type gamg: GAMG on the P2 block, the default before) and Jacobi on the scaled pressure mass
# matrix. p-multigrid against GAMG on the displacement block (BENCHMARKS.md, "p-multigrid inside the displacement
# split"): the rubber bracket's full load 5.4 -> 4.1 s on 973 tets, 20.4 -> 11.6 s on 2,560; Cook at 9k tets 14.6 ->
# 11.9 s; never slower on the eight cases measured
MIXED_DEFAULTS = (("ksp_type", "gmres"), ("pc_type", "fieldsplit"), ("pc_fieldsplit_type", "schur"),
                  ("pc_fieldsplit_schur_fact_type", "lower"), (SPLIT_U + "ksp_type", "preonly"),
                  (SPLIT_U + "pc_type", "mg"), ("fieldsplit_p_ksp_type", "preonly"),
                  ("fieldsplit_p_pc_type", "jacobi"))


# the mixed formulation's Newton: GMRES restarted every 100 iterations, not PETSc's 30, and stopped at 1000, not
# 10,000, and a line search on the Lagrangian's slope along the step (below). Measured on a rubber L-bracket
# (docs/mixed.md, "Thin parts"): a rotation's linearization changes the volume by ~theta^2, so a full step raises the
# residual norm ~10x before Newton converges quadratically, and the residual-norm backtracking takes lambda = 0.1 for
# ten steps; GMRES(30) stagnates there where GMRES(100) needs 60-150; a solve at a wild iterate that fails anyway
# fails at a tenth of the cost.
MIXED_NEWTON = (("snes_linesearch_type", "cp"), ("ksp_gmres_restart", "100"), ("ksp_max_it", "1000"))
# The line search (issue 49, item 3). The residual is the gradient of the Lagrangian Pi(u, p) (the loads' work
# included; a follower load's is not a potential, its slope is used alike), so F(x - lambda Y).Y is Pi's slope along the
# Newton step Y, an energy whatever mixes metres and pascals in Y. PETSc's critical-point search (`cp`) looks for its
# zero by secant steps. Here the full step is kept wherever its slope at lambda = 1 has fallen to half the start's (the
# curvature condition of a Wolfe line search, |g(1)| <= c2 |g(0)| with c2 = 0.5: Nocedal & Wright, Numerical
# Optimization, 2006, eq. 3.7), so a Newton step near the solution is the full step, bitwise; else up to two secant
# steps find where Pi stops changing along it: the spurious kappa theta^2 of a large linearized rotation makes that
# early on the step. atol 0: PETSc's absolute test compares F.Y with atol ||Y|| (pascals and metres mixed in the
# norm) and declares the solve converged (SNES_CONVERGED_FNORM_ABS) when it passes, which stopped Lame's cylinder
# at a residual of 6e-5 of its start under -snes_rtol 1e-10. Rubber bracket at its full load (973 tets): 61 Newton
# iterations, 3 halvings, 14 s with full steps -> 27 Newton, none, 5.4 s; Cook, the block, the rod's torsion, Lame,
# bend2 and squeeze bitwise as with full steps (BENCHMARKS.md, "The mixed Newton under large rotations").
CP_TUNING = (("snes_linesearch_max_it", "2"), ("snes_linesearch_rtol", "0.5"), ("snes_linesearch_atol", "0"))
MIXED_MERITS = {"cp": "the Lagrangian's slope along the step (critical point: the full step where it halves)",
                "basic": "none (full Newton steps)", "nleqerr": "Newton correction (NLEQ-ERR)"}
# PETSc's kernel for the Galerkin products P^T A P of the field split's GAMG, which it forms at every Newton step:
# PETSc's default (`scalable`) took 1.6-2.3x as long as `rap` on one rank and 2.3-4x as long as `nonscalable` on
# two for the same products (Cook's membrane, BENCHMARKS.md "The Galerkin products' kernel"); the sequential and
# the parallel matrices offer different kernels
GALERKIN_KERNELS = ("rap", "nonscalable")      # (one rank, several)


def apply_mixed_defaults(ranks=1, augment=0.0):
    """The mixed formulation's solver defaults where the options database does not set them: the field split's
    when no -pc_type or -pc_type fieldsplit is given (a user's -pc_type lu, say, replaces all of it), with the
    faster kernel for its GAMG's Galerkin products on this many ranks (GALERKIN_KERNELS) and, where the augmented
    Lagrangian applies (augment > 0: augment_factor), the upper Schur factorization it needs; the critical-point line
    search, GMRES(100), at most 1000 Krylov iterations (MIXED_NEWTON), and the line search's tuning where it is the
    critical-point one (CP_TUNING: a user's -snes_linesearch_type bt keeps PETSc's own). Returns the line search
    merit."""
    opts = PETSc.Options()
    split = not opts.getBool("snes_mf", False) and opts.getString("pc_type", "fieldsplit") == "fieldsplit"
    for k, v in MIXED_DEFAULTS:
        if (k == "ksp_type" or split) and not opts.hasName(k):
            # (p-multigrid's levels need the tangent by blocks: under -snes_mf_operator the split keeps GAMG)
            if k == "pc_fieldsplit_schur_fact_type" and augment > 0:
                v = "upper"
            opts.setValue(k, "gamg" if k == SPLIT_U + "pc_type" and opts.getBool("snes_mf_operator", False) else v)
    if augment > 0:
        for k, v in AUGMENTED_DEFAULTS:
            if not opts.hasName(k):
                opts.setValue(k, v)
    if split and opts.getString(SPLIT_U + "pc_type", "") in ("gamg", "mg") and not opts.hasName("matptap_via"):
        opts.setValue("matptap_via", GALERKIN_KERNELS[ranks > 1])
    if opts.getString("snes_type", "newtonls") == "newtonls":
        gmres = opts.getString("ksp_type", "") in ("gmres", "fgmres")
        for k, v in MIXED_NEWTON:
            if not opts.hasName(k) and (gmres or not k.startswith("ksp_")):   # (preonly reads neither)
                opts.setValue(k, v)
        if opts.getString("snes_linesearch_type", "") == "cp":
            for k, v in CP_TUNING:
                if not opts.hasName(k):
                    opts.setValue(k, v)
    return MIXED_MERITS.get(opts.getString("snes_linesearch_type", "bt"), MERITS[1])


def augment_factor(space):
    """gamma/mu of the augmented Lagrangian preconditioner (operators.Augmented; -mixed_augment, AUGMENT by
    default), or 0 where it does not apply: it needs the field split (no -snes_mf or -snes_mf_operator) with
    p-multigrid in its displacement split (quadratic tetrahedra; -fieldsplit_u_pc_type gamg smooths badly on the
    augmented block: BENCHMARKS.md) smoothed by Jacobi, and the upper Schur factorization with its own Schur
    preconditioner. Where the options choose otherwise (-pc_fieldsplit_schur_fact_type lower, say) it is off; asked
    for by -mixed_augment there, one line."""
    opts = PETSc.Options()
    given = opts.hasName("mixed_augment")
    try:
        g = float(opts.getString("mixed_augment")) if given else AUGMENT
    except ValueError:
        g = math.nan
    if not (math.isfinite(g) and g >= 0):
        raise UserError(f"option -mixed_augment {opts.getString('mixed_augment')}: gamma/mu of the augmented "
                        "Lagrangian, a number >= 0 (0: off)")
    why = None
    if opts.getBool("snes_mf", False) or opts.getBool("snes_mf_operator", False):
        why = "a tangent by blocks (no -snes_mf or -snes_mf_operator)"
    elif opts.getString("pc_type", "fieldsplit") != "fieldsplit":
        why = "the field split (-pc_type fieldsplit)"
    elif opts.getString(SPLIT_U + "pc_type", "mg") != "mg" or not pmg.applies(space):
        why = f"p-multigrid in the displacement split (-{SPLIT_U}pc_type mg, quadratic tetrahedra)"
    elif any(opts.getString(SPLIT_U + k, "jacobi") not in pmg.SBAIJ_SMOOTHERS
             for k in ("mg_levels_pc_type", "mg_levels_1_pc_type")):
        # (its P2 block is a sum of matrices PETSc multiplies and takes the diagonal of, no SOR or ILU)
        why = f"a P2-level smoother that only multiplies (-{SPLIT_U}mg_levels_pc_type jacobi or none)"
    elif opts.getString("pc_fieldsplit_schur_fact_type", "upper") != "upper":
        why = "the upper Schur factorization (-pc_fieldsplit_schur_fact_type upper)"
    elif opts.hasName("pc_fieldsplit_schur_precondition"):
        why = "its own Schur preconditioner (no -pc_fieldsplit_schur_precondition)"
    elif opts.getBool("pc_fieldsplit_diag_use_amat", False):
        why = "the split smoothed with the augmented block (no -pc_fieldsplit_diag_use_amat)"
    if g > 0 and why is not None:
        if given:
            raise UserError(f"option -mixed_augment {g:g}: the augmented Lagrangian needs {why}; -mixed_augment 0 "
                            "turns it off")
        return 0.0
    return g


def mixed_blocks(mf):
    """The mixed tangent by blocks (MixedNest): under the field split without MFFD; else one AIJ."""
    return not mf and PETSc.Options().getString("pc_type", "") == "fieldsplit"


# what a failed Krylov solve of the saddle point suggests (GMRES + the Schur field split by default: CG and GAMG
# alone do not apply)
KSP_HINTS = {
    **dict.fromkeys(RAN_OUT, "a larger -ksp_max_it, or for a small problem the direct solve "
                             "(-options_file options/mixed_direct.opts)"),
    "DIVERGED_BREAKDOWN": "the direct solve (-options_file options/mixed_direct.opts), or -ksp_type fgmres",
    "DIVERGED_PCSETUP_FAILED": "the default field split (no -pc_type), or options/mixed_direct.opts",
}


class FieldSplitPlan(SolverPlan):
    """The Solver's questions, answered for the mixed formulation's system (system.MixedSystem)."""
    escalates = False          # its preconditioner is the field split, not Jacobi
    ksp_hints = KSP_HINTS

    def __init__(self):
        self.schur_pre = None      # the Schur complement's preconditioning matrix (assembled once, kept for a new KSP)
        self.augment = 0.0         # gamma/mu of the augmented Lagrangian (augment_factor), 0: off

    def defaults(self, solver, objective):
        had = PETSc.Options().hasName("matptap_via")
        self.augment = augment_factor(solver.system.space)
        solver.merit = apply_mixed_defaults(solver.system.space.comm.getSize(), self.augment)
        if not had and PETSc.Options().hasName("matptap_via"):
            solver.unrecorded = ("matptap_via",)
        if objective:
            how = {MIXED_MERITS["basic"]: "full Newton steps, a smaller load step where a solve fails",
                   MIXED_MERITS["cp"]: "each Newton step as long as the Lagrangian's slope along it says (the full "
                                       "step where it halves), a smaller load step where a solve fails"}.get(
                solver.merit, f"the line search merit is the {solver.merit}")
            solver.merit_note = ("the mixed formulation's solution is a saddle point, not a minimum: no energy "
                                 f"merit; {how}")

    def storage(self, storage, system, jacobian, assembly, mf):
        """sbaij: the Krylov method multiplies by a MatNest whose displacement block is an SBAIJ copy (the field
        split's GAMG smooths with it: -pc_fieldsplit_diag_use_amat); the PC is built from the AIJ."""
        if storage == "aij":
            return storage
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

    def operator(self, system, jacobian, assembly, storage, mf):
        if mf == "mf":
            return None
        return MixedNest(system, storage, self.augment) if mixed_blocks(mf) else MixedAssembled(system)

    def before_options(self, solver):
        if (solver.storage == "sbaij" and not self.augment
                and not PETSc.Options().hasName("pc_fieldsplit_diag_use_amat")):
            PETSc.Options().setValue("pc_fieldsplit_diag_use_amat", "1")     # GAMG smooths with the SBAIJ block
        if solver.op is not None and PETSc.Options().getString("pc_type", "") == "fieldsplit":
            pmg.before_options(solver.system.space, SPLIT_U)

    def configure(self, solver):
        self.field_split(solver)
        if solver.system.constant_pressure_free and solver.op is not None:
            self.constant_pressure(solver)
        if (solver.op is not None and solver.snes.getKSP().getPC().getType() == "fieldsplit"
                and PETSc.Options().getString(SPLIT_U + "pc_type", "") == "mg"):
            if not isinstance(solver.op, MixedNest):
                raise UserError(f"option -{SPLIT_U}pc_type mg: p-multigrid in the displacement split needs the "
                                "tangent by blocks (the field split without -snes_mf_operator); "
                                f"-{SPLIT_U}pc_type gamg")
            solver.levels = SplitLevels(solver)

    def field_split(self, solver):
        """Under -pc_type fieldsplit: the fields u (displacements, with the rigid-body near null space) and p
        (pressures), and the Schur complement preconditioned by -(1/mu + 1/kappa) M_p unless the options choose."""
        pc = solver.snes.getKSP().getPC()
        if pc.getType() != "fieldsplit":
            return
        sysm = solver.system
        pc.setFieldSplitIS(("u", sysm.is_u), ("p", sysm.is_p))
        if not PETSc.Options().hasName("pc_fieldsplit_schur_precondition"):
            if self.schur_pre is None:               # (constant: assembled once, kept for a new KSP)
                aug = solver.op.augmented
                self.schur_pre = aug.schur if aug is not None else sysm.pressure_mass()
            pc.setFieldSplitSchurPreType(PETSc.PC.FieldSplitSchurPreType.USER, self.schur_pre)

    def constant_pressure(self, solver):
        """A part whose whole boundary moves as prescribed, incompressible: the pressure is known up to a constant,
        the tangent singular. Its null space on the operators (the Krylov method keeps the constant out of every
        update: the pressure's constant stays where it starts) and on is_p (the field split's Schur complement)."""
        sysm, op = solver.system, solver.op
        ns, nsp = sysm.constant_pressure_nullspace()
        for A in {op.mat.handle: op.mat, op.operator.handle: op.operator}.values():
            A.setNullSpace(ns)
            A.setTransposeNullSpace(ns)
        sysm.is_p.compose("nullspace", nsp)
        self.nullspace = ns
        solver.notes.append("incompressible with every displacement of the boundary prescribed: the pressure is "
                            "known up to a constant (it stays at its start)")

    def reuse(self, solver, ptype):
        """The field split is set up again at every Jacobian (cheap: its blocks are the MatNest's); its displacement
        split's multigrid (p-multigrid or GAMG) is kept (PCSetReusePreconditioner on that split, not SNES's lag:
        PCFIELDSPLIT sets its splits up again whenever their blocks' values change)."""
        if ptype == "fieldsplit" and PETSc.Options().getString(SPLIT_U + "pc_type", "") in solver.REUSED_PCS:
            return {"base": None, "pending": True, "setups": 0}
        return None

    def kept_split(self, ksp):
        return ksp.getPC().getFieldSplitSubKSP()[0].getPC()

    def rebuild(self, solver):
        """The field split's GAMG keeps state from one set-up to the next (a ILU split does not): a new KSP where a
        restart begins, so that both runs continue bitwise alike (and its splits, new, are set up at the next solve
        whether or not the old ones were kept)."""
        if solver.snes.getKSP().getPC().getType() != "fieldsplit":
            return
        old = solver.snes.getKSP()
        ksp = PETSc.KSP().create(comm=old.getComm())
        ksp.setOptionsPrefix(old.getOptionsPrefix())
        solver.snes.setKSP(ksp)
        ksp.setFromOptions()
        ksp.setPostSolve(solver._after_linear_solve)
        self.field_split(solver)
        if isinstance(solver.levels, SplitLevels):
            solver.levels.levels = None             # (the new KSP's displacement split gets its own levels)


class SplitLevels:
    """p-multigrid inside the displacement split (-fieldsplit_u_pc_type mg, with pmg.DEFAULTS under that prefix):
    the split's PCMG gets pmg.Levels (the P2 -> P1 interpolation; the coarse operator P^T K_uu P with the rigid-body
    modes). The split exists once the field split is set up, and PCFIELDSPLIT sets its splits up only when they are
    first applied: so at the first Jacobian the field split is set up here, the split's levels made, and at every
    Jacobian that sets the preconditioner up the coarse operator is formed from K_uu as it is then."""

    def __init__(self, solver):
        self.solver = solver
        self.levels = None

    def prepare(self):
        """(K_uu is an AIJ: its coarse operator is PETSc's PtAP, nothing to ask of the fill)"""

    def update(self, P):
        """(P: the whole preconditioning matrix, as for pmg.Levels; the coarse operator is K_uu's)"""
        sol = self.solver
        if self.levels is None:
            ksp = sol.snes.getKSP()
            ksp.setOperators(sol.op.operator, sol.op.mat)     # (a new KSP gets them from SNES only after this)
            pc = ksp.getPC()
            pc.setUp()
            self.levels = pmg.Levels(pc.getFieldSplitSubKSP()[0].getPC(), sol.system.space)
        aug = sol.op.augmented
        self.levels.update(sol.op.uu.mat, add=None if aug is None else aug.coarse_term)
