"""Finite-strain viscoelasticity: a Prony series on the isochoric stress (Simo, CMAME 60, 1987; Holzapfel, Nonlinear
Solid Mechanics, 2000, sec. 6.10), beside the elastic force of a material with an isochoric/volumetric split.

Each term i (-prony_beta b_i, -prony_tau tau_i) carries a non-equilibrium second Piola-Kirchhoff stress Q_i per cell,
Q_i' + Q_i / tau_i = b_i d/dt S_iso, S_iso the material's isochoric stress (its kernel with kappa = 0), so the
relaxation modulus of the isochoric part is mu (1 + sum_i b_i exp(-t/tau_i)). Over a step of h from t_n with S_iso
linear in time the update is exact: Q_i^(n+1) = exp(-h/tau_i) Q_i^n + g_i (S_iso^(n+1) - S_iso^n), g_i = b_i (1 -
exp(-h/tau_i)) tau_i/h (the exponential integrator). The effect adds P = F sum_i Q_i^(n+1) = F H + g P_iso(F), H =
sum_i (exp(-h/tau_i) Q_i^n - g_i S_iso^n), g = sum g_i, to the residual; its tangent is g K_iso + (dF H). The g P_iso
term is the elastic force's own pass with the isochoric moduli times 1 + g (every split material's isochoric energy is
linear in them: Material.moduli, kernels.scale_moduli): one pass over the cells, not two; the F H term is a C loop of
its own (kernels' fh_forces, fh_tangent). The Q_i and S_iso^n are taken forward once per accepted step, by its size
and its end state (accept_step). Checkpoints carry them per cell (core.files.CHECKPOINT_CELLS), in the input cells'
order:
a restart continues on any rank count. On quadratic tetrahedra the Q_i live at each quadrature point of the stiffness
rule. With -regions, the regions of a material with a split (a region of another material, a steel insert, takes no
part)."""
from dataclasses import dataclass

import numpy as np

from ...core.errors import UserError
from ...core.options import Row
from .base import Effect, Energy, Spec, timed

MAX_TERMS = 4


def _gammas(beta, tau, h):
    """(exp(-h/tau_i), g_i = beta_i (1 - exp(-h/tau_i)) tau_i/h) of each term (g_i -> beta_i as h -> 0)."""
    x = np.asarray(h) / np.asarray(tau)
    return np.exp(-x), np.asarray(beta) * (-np.expm1(-x)) / x


class Viscoelastic(Effect):
    name = "viscoelastic"
    linear = False
    conservative = False
    cell_blocks = True
    symmetric = True
    internal = True

    def __init__(self, kernels, parts, beta, tau):
        """kernels: the elastic force's (the effect scales their isochoric moduli by 1 + g over each step: the g
        P_iso term computed in the elastic pass itself); parts: [(the local cells (indices, ascending; None: all),
        Material, its isochoric constants)] of the materials with a split (the cells of any other material take no
        part)."""
        super().__init__()
        self.stiffness = kernels
        g = self.geometry = kernels.geometry
        every = np.arange(g.nc)
        self.parts = [(every if idx is None else np.asarray(idx, np.int64), m, c) for idx, m, c in parts]
        # each part's isochoric kernels on its cells (S_iso, once per accepted step)
        self.iso = [(idx, (g if len(idx) == g.nc else g.subset(idx)).kernels(m, c)) for idx, m, c in self.parts]
        self.beta, self.tau = np.array(beta), np.array(tau)
        self.cells = g.cells
        # each point's weight: |det J| w_q of the stiffness rule (P2: ElementCells), the volume (P1: one point)
        self.w = g.geo[:, :, 9].copy() if hasattr(g, "geo") else g.vol[:, None].copy()
        nc, nq = self.w.shape
        self.Q = np.zeros((len(beta), nc, nq, 3, 3))
        self.S = None          # S_iso at the last accepted state, per cell and point
        self.h = None          # the size of the step being solved
        self.H = None          # sum_i (exp(-h/tau_i) Q_i^n - g_i S_iso^n): the step's F H term (nc, nq, 3, 3)
        self.C = None          # C = F^T F at the last accepted state
        self.work = np.zeros(nc)   # each cell's non-equilibrium stresses' work up to the last accepted state
        self.memo = None       # the last _advanced (dt, x, its result): energy's, then accept_step's

    def _F(self, x):
        return self.geometry.deformations(x)                                 # (nc, nq, 3, 3)

    def _S_iso(self, x):
        """S_iso per cell and point at positions x (0 in the cells of a material without a split; NaN where the
        material is undefined), by the isochoric kernels."""
        S = np.zeros((len(self.w), self.w.shape[1], 3, 3))
        for idx, k in self.iso:
            S[idx] = k.pk2(x)
        return S

    def _advanced(self, x, dt):
        """(Q, S_iso, C, the viscous work) at the end of a step of dt from the committed state to positions x. The
        statistics ask for it after a step, then accept_step at the same state: the last one is kept (memo: a pass of
        the isochoric kernels over every cell and numpy products of mesh-sized arrays)."""
        if self.memo is not None and self.memo[0] == dt and np.array_equal(self.memo[1], x):
            return self.memo[2]
        F = self._F(x)
        C = np.matmul(np.swapaxes(F, -1, -2), F)
        S = self._S_iso(x)
        e, g = _gammas(self.beta, self.tau, dt)
        Q = e[:, None, None, None, None] * self.Q + g[:, None, None, None, None] * (S - self.S)
        # the work of the non-equilibrium stresses over the step, sum_c int sum_i Q_i : dC/2 (trapezoid in time)
        work = 0.25 * np.einsum("cq,icqjk,cqjk->c", self.w, self.Q + Q, C - self.C)
        self.memo = (dt, x.copy(), (Q, S, C, self.work + work))
        return self.memo[2]

    def begin_step(self, t, h, xn, vn):
        """The step's g = sum g_i and H: the elastic force's isochoric moduli times 1 + g (its pass computes the
        g P_iso term), this effect the F H term."""
        if self.S is None:
            F = self._F(xn)
            self.S, self.C = self._S_iso(xn), np.matmul(np.swapaxes(F, -1, -2), F)
        self.h = h
        self._carry(h)

    def begin_stage(self, t_stage, h, xn, vn, alpha_f):
        """A generalized-alpha stage (-integrator ts): the residual is taken at x_(n+alpha_f) and t_n + alpha_f h, so
        the stresses there are the committed ones carried alpha_f h forward (the step's end still commits over h:
        accept_step)."""
        self._carry(alpha_f * h)

    def _carry(self, dt):
        """g and H of the committed stresses carried dt forward; the elastic force's isochoric moduli times 1 + g."""
        e, g = _gammas(self.beta, self.tau, dt)
        self.g = float(g.sum())
        self.H = np.ascontiguousarray(np.einsum("i,icqjk->cqjk", e, self.Q) - self.g * self.S)
        self.stiffness.scale_moduli(1.0 + self.g)

    @timed("evals")
    def residual(self, x, r):
        self.geometry.fh_forces(self.H, x, r)

    @timed("applies")
    def apply(self, v, y):
        self.geometry.fh_forces(self.H, v, y)          # (linear in the positions: at v, its K v)

    @timed("applies")
    def diag(self, d):
        self.geometry.fh_tangent(self.H, diag=d)

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        hi = len(self.w) if hi is None else hi
        whole = lo == 0 and hi == len(self.w)
        (self.geometry if whole else self.geometry.part(lo, hi)).fh_tangent(self.H if whole else self.H[lo:hi],
                                                                            vals=vals)

    def accept_step(self, x, h):
        """The step of h that ends at positions x was accepted: its stresses and work are committed."""
        self.Q, self.S, self.C, self.work = self._advanced(x, h)
        self.memo = None

    def energy(self, x, v):
        """viscous_work up to the end of the step just taken (x its end state; committed by accept_step)."""
        return {"viscous_work": float(self._advanced(x, self.h)[3].sum())}

    def cell_state(self):
        """The checkpoint's rows per cell: Q_i (9 each), S_iso, C (9 each), the work (1), of the last accepted state."""
        if self.S is None:
            return {}
        Q, S, C, work = self.Q, self.S, self.C, self.work
        nc = len(self.w)
        return {"viscoelastic": np.concatenate([np.moveaxis(Q, 0, 1).reshape(nc, -1), S.reshape(nc, -1),
                                                C.reshape(nc, -1), work[:, None]], axis=1)}

    def row_width(self):
        """The width of a checkpoint's row per cell: Q_i, S_iso and C (9 each) at each point, and the work."""
        return 9 * self.w.shape[1] * (len(self.beta) + 2) + 1

    def check_resume(self, state, path):
        """UserError where the checkpoint's rows per cell are not this run's series' (a restart continues with the
        series it was written with): before anything is set up."""
        if "viscoelastic" in state and state["viscoelastic"].width != self.row_width():
            raise UserError(f"--restart '{path}': the checkpoint's viscoelastic state is not this run's "
                            f"({state['viscoelastic'].width} numbers a cell, where its Prony series takes "
                            f"{self.row_width()}): a restart continues with the series it was written with")

    def resume_cells(self, state, space):
        """The checkpoint's stresses per cell (any rank count wrote them; check_resume checked their width): the last
        accepted state's. Without them (a checkpoint of a run without this effect) the effect starts at the restart's
        state."""
        if "viscoelastic" not in state:
            return
        rows = space.read_cell_state(state["viscoelastic"])
        (nc, nq), nt = self.w.shape, len(self.beta)
        k = 9 * nq * nt
        self.Q = np.moveaxis(rows[:, :k].reshape(nc, nt, nq, 3, 3), 1, 0).copy()
        self.S = rows[:, k:k + 9 * nq].reshape(nc, nq, 3, 3).copy()
        self.C = rows[:, k + 9 * nq:k + 18 * nq].reshape(nc, nq, 3, 3).copy()
        self.work = rows[:, -1].copy()
        self.memo = None


@dataclass(frozen=True)
class Prony:
    beta: tuple       # each term's relative modulus b_i (>= 0)
    tau: tuple        # its relaxation time [s] (> 0)


def _read(opts, where):
    def reals(name):
        vals = opts.numbers(name, MAX_TERMS, "0.3,0.1")
        if vals is None:
            raise UserError(f"{where}: the viscoelastic effect needs -prony_beta and -prony_tau (lists of the same "
                            "length: each term's relative modulus and relaxation time)")
        return vals
    beta, tau = reals("prony_beta"), reals("prony_tau")
    if len(beta) != len(tau):
        raise UserError(f"options -prony_beta and -prony_tau: {len(beta)} and {len(tau)} terms (give each term both)")
    if min(beta) < 0:
        raise UserError(f"option -prony_beta: {min(beta):g} must be >= 0 (a term's share of the modulus)")
    if min(tau) <= 0:
        raise UserError(f"option -prony_tau: {min(tau):g} must be > 0 (a relaxation time in seconds)")
    return Prony(beta, tau)


def _build(p, ctx):
    parts = [(idx, s.material, s.material.split(s.values)[0]) for idx, s in ctx.part_solids if s.material.volumetric]
    if not parts:
        names = ", ".join(dict.fromkeys(s.name for _, s in ctx.part_solids))
        raise UserError(f"the viscoelastic effect (-prony_beta): no material of the run ({names}) has an "
                        "isochoric/volumetric split (take neohookean_split, mooney_rivlin, yeoh, gent, arruda_boyce, "
                        "ogden or hgo)")
    return [Viscoelastic(ctx.kernels, parts, p.beta, p.tau)]     # (the elastic force's kernels: Elasticity's)


SPEC = Spec(
    "viscoelastic", "a Prony series on the isochoric stress (finite-strain viscoelasticity)",
    implied_by=("prony_beta", "prony_tau"), read=_read, build=_build,
    energies=(Energy("viscous_work", 0, "the work of the viscoelastic effect's non-equilibrium stresses since the start "
                     "[J]: over a closed cycle of deformation, the energy the cycle dissipates (its hysteresis loop's "
                     "area)"),),
    rows=(Row(("prony_beta", "prony_tau"), "-prony_beta b1,b2,… -prony_tau t1,t2,…",
              "finite-strain viscoelasticity: the isochoric stress relaxes as mu (1 + Σ b_i exp(−t/τ_i)) (Simo 1987; "
              "up to 4 terms; the regions of a material with an isochoric/volumetric split)"),))
