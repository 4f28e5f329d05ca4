"""The incremental potential as SNES's objective (the line search's merit), the part of the System (system.py)
that measures energies."""
import math
import time

import numpy as np
from mpi4py import MPI


class Objective:
    """E(X) and the objective E(X) - E(Z) measured from the current Newton iterate Z (set_objective_base)."""

    def init_objective(self, effects):
        self.objective_evals = 0
        self.objective_seconds = 0.0
        self.base = None                 # the Newton iterate the objective is measured from ...
        self.measured = False            # ... when set (set_objective_base)
        self.trial = None                # the last point whose energy the objective computed (a Vec) ...
        self.trial_E = None              # ... and (E, |E|) there, within one solve (None: none kept)
        # the incremental potential exists when every effect has one (follower loads have none)
        self.conservative = all(e.conservative for e in effects)

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
