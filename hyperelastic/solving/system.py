"""The discrete system of one time step: residual R(x), its exact tangent J(x) applied or assembled, from the
effects' sums. Its other concerns live beside it: the held dofs by elimination (elimination.py), the incremental
potential as SNES's objective (objective.py), what a step's start needs from contact's seams (starts.py), the
statistics of the effects (stats.py)."""
import time

import numpy as np
from mpi4py import MPI

from .elimination import Elimination
from .objective import Objective
from .starts import Starts


class System(Elimination, Objective):
    def __init__(self, space, effects, constraints, x0, v0, dt):
        """The effects and constraints on the space; x0, v0 (local arrays) the initial state and dt
        the time step, at which the constrained rows' scale is set."""
        self.space = space
        self.effects = effects
        self.hold(space, constraints)
        self.volume_bound = None         # (|ln J| bound, kappa/mu) a converged state must keep (integrators.py)
        self.xl = space.local_vec()
        self.vl = space.local_vec()
        self.al = None                   # accelerations (second-order form only)
        # every residual counts where its effects are undefined: a material's inverted cells, contact's crossings
        self.domain_effects = [e for e in effects if e.domain]
        self.check_domain = bool(self.domain_effects)
        # (a material undefined for J <= 0: a converged state with an inverted cell is not a solution)
        self.material_domain = any(e.kernels is not None for e in self.domain_effects)
        self.starts = Starts(self)       # (contact's seams: held paths, pushes, domain checks, adaptive stiffness)
        # effects whose residual does not depend on x (dead loads): summed once per step into r_const
        self.varying = [e for e in effects if not e.constant]
        self.constant = [e for e in effects if e.constant]
        self.r_const = None
        self.residual_evals = 0
        self.residual_seconds = 0.0
        self.init_objective(effects)
        self.x_lin = None
        self.energy_momentum = False     # -energy_momentum: the discrete-gradient force in midpoint stages ...
        self.em_base = None              # ... from this start of step (begin_stage)
        self.stage = None                # (x^n, alpha_f) of a generalized-alpha stage (begin_stage), else None
        self._calibrate(x0, v0, dt)

    def _calibrate(self, x0, v0, dt):
        """The constrained rows' scale s from the tangent at the initial state (t = 0, step dt)."""
        self.begin_step(0.0, dt, x0, v0)
        X = self.global_state(x0)
        self.linearize(X)
        self.set_scale(self.space.global_vec())

    def unknown_vec(self):
        """A new global vector of the unknown (the positions; MixedSystem: and the pressure)."""
        return self.space.global_vec()

    def set_guess(self, X, x):
        """X = the state with local positions x (constrained dofs imposed); MixedSystem: and the accepted pressure."""
        X.getArray()[:] = self.space.owned_array(x)
        self.impose_global(X)

    def nodal_state(self):
        """{name: local scalar per node} of the state beyond positions and velocities (for checkpoints)."""
        return {}

    def cell_state(self):
        """{name: local rows per cell} of the effects' state carried by checkpoints (Effect.cell_state)."""
        out = {}
        for e in self.effects:
            out.update(e.cell_state())
        return out

    def accept_step(self, x, h):
        """The step of size h that ends at local positions x was accepted: the effects with a state of their own take
        it forward (Effect.accept_step)."""
        for e in self.effects:
            e.accept_step(x, h)

    def resume(self, state):
        """Continue from a checkpoint's state (files.read_checkpoint) beyond x and v."""
        for e in self.effects:
            e.resume_cells(state, self.space)

    def solved(self, X):
        """X is a solve's result: what follows (energies, forces) is evaluated there (MixedSystem: its pressure)."""

    def accept(self, X):
        """The solve's result X is the new state (MixedSystem keeps its pressure)."""

    def global_state(self, x):
        """A new global vector of the unknown holding local positions x, with the constrained dofs imposed."""
        X = self.unknown_vec()
        self.set_guess(X, x)
        return X

    # --- time dependence -----------------------------------------------------------------------
    def begin_step(self, t, h, xn, vn):
        self.r_const = None
        self.stage = None
        for e in self.effects:
            e.begin_step(t, h, xn, vn)
        if self.starts.adaptive and xn is not None:
            self.starts.adapt(t, h, xn, vn)
        self.targets(t)

    def begin_stage(self, t_stage, t1, h, xn, vn, alpha_f):
        """The second-order (PETSc TS, generalized-alpha) form at the stage time t_stage of a step of size h
        from (xn, vn) to t1: the loads at t_stage, and the constrained dofs' targets at the stage,
        x_a = xn + alpha_f (g(t1) - xn) (what TSALPHA2 computes from X1 when X1_c = g(t1))."""
        self.begin_step(t1, h, xn, vn)       # (drops r_const; the next residual sums it at t_stage)
        for e in self.effects:                   # (contact stays at the step's end: _end_state)
            e.begin_stage(t_stage, h, xn, vn, alpha_f)
        self.stage = (xn.copy(), alpha_f)
        c = self.cdofs
        self.g[c] = alpha_f * (self.g[c] - xn[c]) + xn[c]
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]
        # the energy-momentum force needs the step's start; only at the midpoint (not in TSALPHA2's starting
        # backward Euler half steps, alpha_f = 1, whose result the midpoint step does not depend on)
        self.em_base = xn.copy() if self.energy_momentum and abs(alpha_f - 0.5) <= 1e-12 else None

    def set_rate_weights(self, shift_v, shift_a):
        """Jacobian weights of the damping (shift_v) and inertia (shift_a) effects."""
        for e in self.effects:
            if e.order:
                e.set_weight(shift_v if e.order == 1 else shift_a)

    # --- residual ------------------------------------------------------------------------------
    def local(self, X, lvec):
        self.space.to_local(X, lvec)
        return lvec.getArray()

    def residual_local(self, x, effects=None):
        r = np.zeros_like(x)
        for e in (self.effects if effects is None else effects):
            e.residual(x, r)
        return r

    def residual(self, X, R):
        """R = F(X). The positions are imposed in the work vector xl and the effects add into the work
        vector vl's own array, or on one rank (local and global vectors in the same order) straight into
        R's: no temporaries, no pass over a vector that is not needed (at L8 each one is ~25 us once the
        Krylov solve has taken the cache; the residual's fixed cost is in scripts/bench_peer.py)."""
        t0 = time.perf_counter()
        if self.space.local_is_global:       # (then c_owned_pos is cdofs, g_owned_c is g[cdofs])
            x, Xa = self.xl.getArray(), X.getArray(readonly=True)
            x[:] = Xa
            x[self.c_owned_pos] = self.g_owned_c
            r = R.getArray()
        else:
            x = self.impose(self.local(X, self.xl))
            r = self.vl.getArray()
        self._start(r)
        for e in self.varying:
            e.residual(x, r)
        if self.space.local_is_global:
            self._dirichlet_rows(Xa, r)
        else:
            self.finish(r, X, R, in_vl=True)
        self.residual_evals += 1
        self.residual_seconds += time.perf_counter() - t0

    def _start(self, r):
        """r = the constant effects' residual (zero without any): summed once after begin_step, then
        copied in one pass (counted as an evaluation of each of those effects)."""
        if not self.constant:
            r.fill(0.0)
            return
        if self.r_const is None:
            self.r_const = np.zeros_like(r)
            for e in self.constant:
                e.add_constant(self.r_const)
        np.copyto(r, self.r_const)
        for e in self.constant:
            e.evals += 1

    def residual_rates(self, X, V, A, R, shift_v, shift_a):
        """R = F(x, v, a) = M a + C v + k(x) - f at the stage (begin_stage), with the constrained rows
        s (X_c - g_c). The free rows are evaluated at the state the step has when its constrained dofs
        are on target: x_c = g_c, and v_c, a_c moved by shift_v d, shift_a d (d = g_c - X_c), the
        derivatives of the stage velocity and acceleration with respect to the stage position. So
        they do not depend on X_c, and the Jacobian is [[J_ff, 0], [0, s I]] as in backward Euler.
        With -energy_momentum, at a midpoint stage (alpha_f = 1/2) the elastic force is the discrete
        gradient from the step's start (em_base) to x1 = 2 x - xn; its Jacobian stays the midpoint tangent."""
        t0 = time.perf_counter()
        x = self.local(X, self.xl).copy()
        v = self.local(V, self.vl).copy()
        if self.al is None:
            self.al = self.space.local_vec()
        a = self.local(A, self.al).copy()
        c = self.cdofs
        d = self.g[c] - x[c]
        x[c] = self.g[c]
        v[c] += shift_v * d
        a[c] += shift_a * d
        r = np.zeros_like(x)
        for e in self.effects:
            if e.order == 0 and self.em_base is not None and e.discrete_gradient:
                e.residual_discrete_gradient(x, self.em_base, r)
            elif e.order == 0 and e.end_state:
                e.residual(self._end_state(x), r)
            elif e.order == 0:
                e.residual(x, r)
            else:
                e.rate_residual(v if e.order == 1 else a, r)
        self.finish(r, X, R)
        self.residual_evals += 1
        self.residual_seconds += time.perf_counter() - t0

    def finish(self, r, X, R, in_vl=False):
        """Assemble local r into R and set the constrained rows to s (X_c - g_c); in_vl: r is the work
        vector vl's array (no copy)."""
        r[self.cdofs] = 0.0
        if in_vl:
            self.space.add_to_global(self.vl, R)
        else:
            self._add(r, R)
        if len(self.c_owned_pos):
            self._dirichlet_rows(X.getArray(readonly=True), R.getArray())

    def _add(self, r, R):
        self.vl.getArray()[:] = r
        self.space.add_to_global(self.vl, R)

    def defined_at(self, X):
        """Whether the material is defined in every cell at X (constrained dofs imposed), and every other domain
        effect (contact: no node at or through an obstacle) there, on all ranks."""
        x = self.impose(self.local(X, self.xl).copy())
        bad = sum(e.kernels.energy(x)[3] for e in self.effects if e.kernels is not None)
        return self.space.mpi.allreduce(bad + self.starts.through(x), op=MPI.SUM) == 0

    def undefined_cells(self):
        """Cells (on all ranks) where the material was undefined at the last residual; only
        materials undefined for J <= 0 are checked (one allreduce per residual for those)."""
        if self.check_domain:
            n = sum(e.undefined for e in self.domain_effects)
            return n if self.space.mpi.size == 1 else self.space.mpi.allreduce(n, op=MPI.SUM)
        return 0

    def elastic_kernels(self):
        return next(e.kernels for e in self.effects if e.kernels is not None)

    # --- tangent -------------------------------------------------------------------------------
    def _end_state(self, x):
        """The step's end x1 = x^n + (x - x^n)/alpha_f of a generalized-alpha stage state x (x itself otherwise):
        where contact acts (`Effect.end_state`), so that the pre-check's collision-free step on the SNES unknown x1
        keeps it off the obstacles."""
        if self.stage is None:
            return x
        xn, af = self.stage
        return xn + (x - xn) / af

    def linearize(self, X):
        x = self.impose(self.local(X, self.xl).copy())
        self.x_lin = x
        for e in self.effects:
            if e.end_state and self.stage is not None:
                e.linearize(self._end_state(x))
                if self.em_base is None or not e.discrete_gradient:
                    e.scale_tangent(1.0 / self.stage[1])      # (d x1 / d x = 1/alpha_f; a discrete gradient from
                                                              # x^n to x1 = 2x - x^n moves with H(x1) itself)
            else:
                e.linearize(x)

    def apply_local(self, v):
        v = v.copy()
        v[self.cdofs] = 0.0
        y = np.zeros_like(v)
        for e in self.effects:
            e.apply(v, y)
        return y

    def apply(self, V, Y):
        """Y = J V (exact tangent, matrix-free)."""
        y = self.apply_local(self.local(V, self.vl))
        y[self.cdofs] = 0.0
        self._add(y, Y)
        self._constrained_rows(V, Y)

    def diagonal_local(self):
        d = np.zeros(3 * self.space.nlv)
        for e in self.effects:
            e.diag(d)
        return d

    def diagonal(self, D):
        d = self.diagonal_local()
        d[self.cdofs] = 0.0
        self._add(d, D)
        if len(self.c_owned_pos):
            D.getArray()[self.c_owned_pos] = self.scale
