"""The discrete system of one time step: residual R(x), its exact tangent J(x) applied or
assembled, and Dirichlet conditions by elimination.

Constrained dofs c with prescribed positions g: the residual of a free dof is evaluated with x_c
replaced by g, and R_c = s (x_c - g_c). Then dR_f/dx_c = 0 and J = [[J_ff, 0], [0, s I]] exactly,
for every Jacobian mode including PETSc's MFFD, and J stays symmetric when J_ff is. The scale s is
the mean diagonal of J at the initial state (computed once, in the constructor), so the constrained
block does not spoil conditioning.
"""
import math
import time

import numpy as np
from mpi4py import MPI

from ..physics import effects as effects_pkg
from ..core.errors import UserError

COMBINE = {"sum": sum, "min": min, "max": max}
REDUCE = {"min": MPI.MIN, "max": MPI.MAX}


class System:
    def __init__(self, space, effects, constraints, x0, v0, dt):
        """The effects and constraints on the space; x0, v0 (local arrays) the initial state and dt
        the time step, at which the constrained rows' scale is set."""
        self.space = space
        self.effects = effects
        self.constraints = constraints
        n = 3 * space.nlv
        mask = np.zeros(n, bool)
        for c in constraints:
            mask[c.dofs] = True
        self.cmask = mask
        self.cdofs = np.flatnonzero(mask)
        self.rigid = [c for c in constraints if c.name == "rigid"]    # rigid faces (their loads: solving/rigid.py)
        self.volume_bound = None         # (|ln J| bound, kappa/mu) a converged state must keep (integrators.py)
        owned_mask = mask.reshape(-1, 3)[space.lvid_of_owned].ravel()
        self.c_owned_pos = np.flatnonzero(owned_mask)          # positions in the global (owned) array
        self.g = np.zeros(n)                                    # prescribed positions (local)
        self.xl = space.local_vec()
        self.vl = space.local_vec()
        self.al = None                   # accelerations (second-order form only)
        self.scale = 1.0
        # materials undefined for J <= 0: every residual counts the cells where they were evaluated there
        self.domain_effects = [e for e in effects if e.domain]
        # (domain effects beyond the material's: contact, undefined at or through an obstacle or the surface itself)
        self.contact_domain = [e for e in self.domain_effects if e.kernels is None]
        self.check_domain = bool(self.domain_effects)
        self.adaptive = [e for e in self.contact_domain if getattr(e, "kappa_range", None) is not None]
        held = mask.copy()                               # (nodes whose path the scene gives: no rigid face's)
        for c in self.rigid:
            held[c.dofs] = False
        for e in self.contact_domain:
            e.hold(held.reshape(-1, 3).all(axis=1))
        # (a material undefined for J <= 0: a converged state with an inverted cell is not a solution)
        self.material_domain = any(e.kernels is not None for e in self.domain_effects)
        self.g_owned_c = np.zeros(len(self.c_owned_pos))
        # effects whose residual does not depend on x (dead loads): summed once per step into r_const
        self.varying = [e for e in effects if not e.constant]
        self.constant = [e for e in effects if e.constant]
        self.r_const = None
        self.residual_evals = 0
        self.residual_seconds = 0.0
        self.objective_evals = 0
        self.objective_seconds = 0.0
        self.base = None                 # the Newton iterate the objective is measured from ...
        self.measured = False            # ... when set (set_objective_base)
        self.trial = None                # the last point whose energy the objective computed (a Vec) ...
        self.trial_E = None              # ... and (E, |E|) there, within one solve (None: none kept)
        # the incremental potential exists when every effect has one (follower loads have none)
        self.conservative = all(e.conservative for e in effects)
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

    def resume(self, state):
        """Continue from a checkpoint's state (files.read_checkpoint) beyond x and v."""

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
        if self.adaptive and xn is not None:
            self._adapt_contact(t, h, xn, vn)
        err = None
        for c in self.constraints:
            try:
                self.g[c.dofs] = c.values(t)
            except UserError as e:         # an expression not finite at some rank's vertices
                err = err or str(e)
        if any(c.evaluates for c in self.constraints):    # raised on every rank, or none waits
            errs = [e for e in self.space.mpi.allgather(err) if e]
            if errs:
                raise UserError(errs[0])
        elif err:
            raise UserError(err)
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]   # targets of the owned rows

    def _adapt_contact(self, t, h, xn, vn):
        """-contact_kappa adaptive: each contact effect's barrier stiffness balanced against the rest of the
        incremental potential at the step's start x^n, as IPC chooses it (Li et al. 2020, sec. 4.3 and its supplement:
        kappa = -(g_E . g_B)/(g_B . g_B), g_B the barrier's gradient per unit kappa, g_E the other terms' gradient,
        both over the free dofs), clipped to [kappa_min, 100 kappa_min] (kappa_min: -contact_kappa's default,
        0.1 E / dhat); kappa_min where no pair is within dhat. IPC balances once and then doubles kappa where the
        distance keeps shrinking below 1e-9 of the scene's size; balanced at every step's start instead, kappa needs
        no state (a restart continues exactly), and at an equilibrium (a converged step's end, g_E = -kappa g_B) it
        is the kappa in use. Collective."""
        sp = self.space
        free = np.ones(3 * sp.n_owned, bool)
        free[self.c_owned_pos] = False
        gE = None                     # (the other terms' gradient: only where some pair is within dhat)
        for e in self.adaptive:
            gb = np.zeros_like(xn)
            e.barrier_gradient(xn, gb)
            gB = sp.sum_owned(gb.reshape(-1, 3)).ravel()[free]
            bb = sp.mpi.allreduce(float(gB @ gB), op=MPI.SUM)
            lo, hi = e.kappa_range
            kappa = lo
            if bb > 0:
                if gE is None:
                    others = [o for o in self.effects if o not in self.adaptive]
                    gE = sp.sum_owned(self.residual_local(xn, others).reshape(-1, 3)).ravel()[free]
                eb = sp.mpi.allreduce(float(gE @ gB), op=MPI.SUM)
                kappa = min(max(-eb / bb, lo), hi) if np.isfinite(eb) else lo
            if kappa != e.kappa:
                e.set_kappa(kappa)
                e.begin_step(t, h, xn, vn)       # (friction's lagged normal forces with it)

    def set_held(self, values):
        """The targets of every held dof (local, in the order of cdofs) set to `values` (the linearized predictor)."""
        self.g[self.cdofs] = values
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]

    def retarget(self, constraint, positions):
        """The held targets of one constraint set to (n, 3) positions of its vertices (a rigid face whose reference
        point moved inside a step: solving/rigid.py)."""
        self.g[constraint.dofs] = positions[constraint.comps]
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]

    def begin_stage(self, t_stage, t1, h, xn, vn, alpha_f):
        """The second-order (PETSc TS, generalized-alpha) form at the stage time t_stage of a step of size h
        from (xn, vn) to t1: the loads at t_stage, and the constrained dofs' targets at the stage,
        x_a = xn + alpha_f (g(t1) - xn) (what TSALPHA2 computes from X1 when X1_c = g(t1))."""
        self.begin_step(t1, h, xn, vn)       # (drops r_const; the next residual sums it at t_stage)
        for e in self.effects:
            if e.order == 0 and not e.end_state:     # (contact stays at the step's end: _end_state)
                e.begin_step(t_stage, h, xn, vn)
        self.stage = (xn.copy(), alpha_f)
        c = self.cdofs
        self.g[c] = alpha_f * (self.g[c] - xn[c]) + xn[c]
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]
        # the energy-momentum force needs the step's start; only at the midpoint (not in TSALPHA2's starting
        # backward Euler half steps, alpha_f = 1, whose result the midpoint step does not depend on)
        self.em_base = xn.copy() if self.energy_momentum and abs(alpha_f - 0.5) <= 1e-12 else None

    def held_collision(self, x, t0, t1):
        """(why, certain) where the step begun (begin_step, from local positions x at t0 to t1) cannot be solved:
        the nodes it holds (all three components prescribed) meet each other or an obstacle along their straight
        move to their targets, which contact cannot stop; certain where every prescribed path is straight in t over
        the step (checked at its midpoint): no smaller step gets past that point. None where they do not meet.
        Collective."""
        if not self.contact_domain:
            return None
        x1 = x.copy()
        x1[self.cdofs] = self.g[self.cdofs]
        hits = [h for h in (e.held_collision(x, x1) for e in self.contact_domain) if h is not None]
        first = min(hits, default=(np.inf, ""), key=lambda h: h[0])
        s, what = min(self.space.mpi.allgather(first), key=lambda h: h[0])
        if s > 1:
            return None
        why = (f"the prescribed motion (-fix, -prescribe_*, -obstacle_motion) brings {what} into contact at about "
               f"t={t0 + s * (t1 - t0):.6g}: contact cannot stop nodes whose path is given")
        return why, self._straight(x, t0, t1)

    def _straight(self, x, t0, t1):
        """Whether every held dof's target and every obstacle's translation is linear in t over [t0, t1] (at the
        midpoint, to 1e-9 of the move). Collective."""
        tm = 0.5 * (t0 + t1)
        ok = True
        for c in self.constraints:
            if c.name == "rigid":
                continue
            a, b = x[c.dofs], self.g[c.dofs]
            tol = 1e-9 * (1 + np.abs(b - a).max(initial=0))
            try:
                ok = ok and np.allclose(c.values(tm), 0.5 * (a + b), rtol=0, atol=tol)
            except UserError:
                ok = False
        for o in (o for e in self.contact_domain for o in e.obstacles if o.motion is not None):
            a, b = o.shift(t0), o.shift(t1)
            ok = ok and np.allclose(o.shift(tm), 0.5 * (a + b), rtol=0, atol=1e-9 * (1 + np.abs(b - a).max()))
        return bool(self.space.mpi.allreduce(ok, op=MPI.LAND))

    def moves_prescribed(self, x):
        """Whether the step begun (begin_step) moves a prescribed dof away from its place in the local positions x,
        on some rank. Collective."""
        c = self.cdofs
        moved = bool(len(c)) and not np.array_equal(self.g[c], x[c])
        return self.space.mpi.allreduce(moved, op=MPI.LOR)

    def moves_obstacles(self):
        """Whether an effect moves the body's surroundings with time (contact's -obstacle_motion)."""
        return any(getattr(e, "moving", False) for e in self.effects)

    def pushed_by_obstacles(self, x):
        """x with the nodes that moving obstacles reach pushed ahead of them (contact.Contact.pushed), or None where
        a push would be too long for the cells beside it on some rank (collective)."""
        ok = True
        for e in self.effects:
            if getattr(e, "moving", False):
                x, fits = e.pushed(x)
                ok = ok and fits
        return x if self.space.mpi.allreduce(ok, op=MPI.LAND) else None

    def set_rate_weights(self, shift_v, shift_a):
        """Jacobian weights of the damping (shift_v) and inertia (shift_a) effects."""
        for e in self.effects:
            if e.order:
                e.set_weight(shift_v if e.order == 1 else shift_a)

    def impose(self, x):
        """x (local array) with constrained dofs set to their prescribed positions."""
        x[self.cdofs] = self.g[self.cdofs]
        return x

    def impose_global(self, X):
        X.getArray()[self.c_owned_pos] = self.g_owned_c

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

    def _dirichlet_rows(self, Xa, Ra):
        """The constrained rows of the residual, Ra[c] = s (Xa[c] - g_c) (owned rows; global arrays)."""
        Ra[self.c_owned_pos] = self.scale * (Xa[self.c_owned_pos] - self.g_owned_c)

    def _add(self, r, R):
        self.vl.getArray()[:] = r
        self.space.add_to_global(self.vl, R)

    # --- objective -----------------------------------------------------------------------------
    def nonconservative(self):
        """Names of the effects without a potential."""
        return [e.name for e in self.effects if not e.conservative]

    def energy(self, X):
        """(E(X), |E|): the incremental potential at X, i.e. the effects' potentials at X with the
        constrained dofs imposed plus 1/2 s |X_c - g_c|^2 for the constrained rows (gradient
        s (X_c - g_c), as in `finish`), so that its gradient is the residual, constrained rows
        included; and the sum of the terms' magnitudes (the scale of its rounding error). +inf where
        the material is undefined. The ranks' parts are summed exactly (math.fsum of the gathered
        parts, in rank order): the same value on every rank."""
        x = self.impose(self.local(X, self.xl).copy())
        pots = [e.potential(x) for e in self.effects]
        if len(self.c_owned_pos):
            d = X.getArray(readonly=True)[self.c_owned_pos] - self.g_owned_c
            pots.append(0.5 * self.scale * float(d @ d))
        ok = all(map(math.isfinite, pots))
        part = (math.fsum(pots), math.fsum(map(abs, pots))) if ok else (math.inf, math.inf)
        parts = self.space.mpi.allgather(part)
        if not all(math.isfinite(p[0]) for p in parts):
            return math.inf, math.inf
        return math.fsum(p[0] for p in parts), math.fsum(p[1] for p in parts)

    def set_objective_base(self, X):
        """The Newton iterate Z the objective is measured from (None: absolute energies)."""
        self.measured = X is not None
        if X is None:
            self.trial_E = None               # (a solve's start: the energy's terms may have changed since)
            return
        if self.base is None:
            self.base = X.duplicate()
        X.copy(self.base)
        self.base_E = None                # E(Z), computed when first needed ...
        if self.trial_E is not None and self._equal(X, self.trial):
            self.base_E, self.base_mag = self.trial_E     # ... or already: Z is the point the line search accepted

    def objective(self, X):
        """The SNES objective: E(X) - E(Z), Z the current Newton iterate (set_objective_base), or E(X)
        before one is set. A line search compares energies that, near convergence, differ by less
        than the rounding error of E itself (a Newton step there changes E by ~|R|^2/|J|, i.e. 1e-16
        of E at |R| ~ 1e-8 |R_0|), and then backtracks on noise. So the difference is taken relative
        to Z, and where it is below 1e-9 of the energy's scale it is computed from the gradient
        instead: E(Z + d) - E(Z) = int_0^1 R(Z + s d).d ds by 2-point Gauss-Legendre, exact for
        energies quartic along the line (linear, St.VK, inertia, damping, dead loads) and accurate to
        O(|d|^5) for the others; its rounding error is ~eps |R| |d|, which vanishes at convergence."""
        t0 = time.perf_counter()
        if self.measured and self._at_base(X):
            out = 0.0                     # the line search's first evaluation: at Z itself
        else:
            E, mag = self.energy(X)
            out = E
            if self.measured:
                self._keep_trial(X, E, mag)
            if self.measured and math.isfinite(E):
                if self.base_E is None:
                    self.base_E, self.base_mag = self.energy(self.base)
                out = E - self.base_E
                if abs(out) <= 1e-9 * max(mag, self.base_mag):
                    out = self._difference_by_gradient(X)
        self.objective_evals += 1
        self.objective_seconds += time.perf_counter() - t0
        return out

    def _at_base(self, X):
        return self._equal(X, self.base)

    def _equal(self, X, Y):
        """Whether X and Y are equal bit for bit on every rank."""
        same = bool(np.array_equal(X.getArray(readonly=True), Y.getArray(readonly=True)))
        return self.space.mpi.allreduce(same, op=MPI.LAND)

    def _keep_trial(self, X, E, mag):
        """Keep the line search's trial point and its energy: where the search accepts it, it is the next Newton
        iterate, whose energy the next iteration's objective would otherwise compute again (the same terms within
        a solve: a barrier's stiffness, the held targets and the lagged friction change only between steps). Bit
        for bit the value it would compute: one energy evaluation fewer per Newton iteration after the first."""
        if self.trial is None:
            self.trial = X.duplicate()
        X.copy(self.trial)
        self.trial_E = (E, mag)

    def _difference_by_gradient(self, X):
        D = X.copy()
        D.axpy(-1.0, self.base)
        P, R = X.duplicate(), X.duplicate()
        total = 0.0
        for s in (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0)):
            P.waxpy(s, D, self.base)
            self.residual(P, R)
            total += 0.5 * R.dot(D)
        return total

    def defined_at(self, X):
        """Whether the material is defined in every cell at X (constrained dofs imposed), and every other domain
        effect (contact: no node at or through an obstacle) there, on all ranks."""
        x = self.impose(self.local(X, self.xl).copy())
        bad = sum(e.kernels.energy(x)[3] for e in self.effects if e.kernels is not None)
        return self.space.mpi.allreduce(bad + self._through(x), op=MPI.SUM) == 0

    def _through(self, x):
        """This rank's count of where the local positions x lie in or through an obstacle or the contact surface, as
        reached from the step's start (the contact effects' undefined_at)."""
        return sum(e.undefined_at(x) for e in self.contact_domain)

    def contact_free(self, x):
        """Whether the local positions x are reached from the step's start without passing through an obstacle or the
        contact surface itself, on all ranks."""
        return self.space.mpi.allreduce(self._through(x), op=MPI.SUM) == 0

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

    def _constrained_rows(self, V, Y):
        if len(self.c_owned_pos):
            Y.getArray()[self.c_owned_pos] = self.scale * V.getArray(readonly=True)[self.c_owned_pos]

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

    def set_scale(self, D):
        """s = mean |diag J| over the free owned dofs (D: a global vector to use as workspace)."""
        self.scale = 1.0
        self.diagonal(D)
        a = np.abs(D.getArray(readonly=True))
        free = np.ones(len(a), bool)
        free[self.c_owned_pos] = False
        tot = self.space.mpi.allreduce(np.array([a[free].sum(), free.sum()]), op=MPI.SUM)
        self.scale = float(tot[0] / max(tot[1], 1)) or 1.0

    # --- statistics ----------------------------------------------------------------------------
    def energies(self, x, v):
        """{column: value} of the effects' energies (effects.energies(): how instances and ranks combine)."""
        how = effects_pkg.energies()
        out = {}
        for e in self.effects:
            for k, val in e.energy(x, v).items():     # several instances (e.g. loads): combined
                out[k] = val if k not in out else COMBINE[how[k].combine]((out[k], val))
        mpi = self.space.mpi
        res = {k: mpi.allreduce(out.pop(k), op=REDUCE[how[k].combine]) for k in list(out)
               if how[k].combine != "sum"}
        keys = sorted(out)                       # everything else is additive over ranks: one reduction
        sums = np.array([out[k] for k in keys], dtype=float)
        tot = np.empty_like(sums)
        mpi.Allreduce(sums, tot, op=MPI.SUM)
        res.update(zip(keys, tot.tolist()))
        return res

    def effect_counters(self):
        out = {}
        for e in self.effects:               # several instances of an effect (e.g. loads): summed
            prev = out.get(e.name, (0, 0, 0.0))
            out[e.name] = (prev[0] + e.evals, prev[1] + e.applies, prev[2] + e.seconds)
        return out

    def built(self):
        """{effect name: instances built} of this run."""
        return effects_pkg.built(self.effects, self.constraints)
