"""What a step's start needs from the effects that reach beyond the body's cells (contact; the seams of
physics/effects/seams.py): the held paths they must not cross, the pushes of moving surroundings, a domain check of a
start, and the stiffness balanced between steps. The System owns one (`System.starts`); the integrators ask it before
each step is solved."""
import numpy as np
from mpi4py import MPI

from ..core.errors import UserError
from ..physics.effects.seams import AdaptiveStiffness, DomainCheck, StepStart, declaring

# a start whose pushes, this many times over, would invert a cell is refused (the step is retried shorter): on the
# quadratic O-ring's first touch (2,904 tets) a cell inverts at 1.56 times the push, and Newton then takes 10 iterations
PUSH_MARGIN = 1.25


def spread(d, cells):
    """The pushes d (local, 3 per node) with every unpushed node of a cell that has pushed nodes moved by half their
    mean push (averaged over such cells): the strain of a push shared by two layers of cells instead of one. On a
    rank, its cells' nodes (a node on a partition boundary may get a different share on each rank: a start, not a
    solution; the solve makes them agree)."""
    dn = d.reshape(-1, 3)
    pushed = np.abs(dn).max(axis=1) > 0
    has = pushed[cells]                                           # (nc, nn)
    touched = has.any(axis=1)
    if not touched.any():
        return d
    c = cells[touched]
    mean = (dn[c] * has[touched][:, :, None]).sum(axis=1) / has[touched].sum(axis=1)[:, None]     # (n, 3)
    total, count = np.zeros_like(dn), np.zeros(len(dn))
    np.add.at(total, c.ravel(), np.repeat(0.5 * mean, c.shape[1], axis=0))
    np.add.at(count, c.ravel(), 1.0)
    out = dn.copy()
    free = ~pushed & (count > 0)
    out[free] = total[free] / count[free, None]
    return out.reshape(d.shape)


class Starts:
    def __init__(self, system):
        """system: its effects, constraints, held dofs and targets (read when asked, never kept apart)."""
        self.system = system
        effects = system.effects
        self.checks = declaring(effects, DomainCheck)            # (domain checks beyond the material's)
        self.starts = declaring(effects, StepStart)
        self.adaptive = [e for e in declaring(effects, AdaptiveStiffness) if e.kappa_range is not None]
        self.moving = any(e.moving for e in self.starts)         # surroundings that move with time
        # the nodes whose path the scene gives: held in all three components by a constraint that is not a body of
        # its own (dirichlet.HeldBody: a rigid face's nodes follow its reference point, which the solve balances)
        held = np.zeros(len(system.cmask), bool)
        for c in system.constraints:
            if c.path_given:
                held[c.dofs] = True
        for e in self.starts:
            e.hold(held.reshape(-1, 3).all(axis=1))

    def held_collision(self, x, t0, t1):
        """(why, certain) where the step begun (begin_step, from local positions x at t0 to t1) cannot be solved:
        the nodes it holds (all three components prescribed) meet each other or an obstacle along their straight
        move to their targets, which contact cannot stop; certain where every prescribed path is straight in t over
        the step (checked at its midpoint): no smaller step gets past that point. None where they do not meet.
        Collective."""
        if not self.starts:
            return None
        sysm = self.system
        x1 = x.copy()
        x1[sysm.cdofs] = sysm.g[sysm.cdofs]
        hits = [h for h in (e.held_collision(x, x1) for e in self.starts) if h is not None]
        first = min(hits, default=(np.inf, ""), key=lambda h: h[0])
        s, what = min(sysm.space.mpi.allgather(first), key=lambda h: h[0])
        if s > 1:
            return None
        why = (f"the prescribed motion (-fix, -prescribe_*, -obstacle_motion) brings {what} into contact at about "
               f"t={t0 + s * (t1 - t0):.6g}: contact cannot stop nodes whose path is given")
        return why, self._straight(x, t0, t1)

    def _straight(self, x, t0, t1):
        """Whether every given path's target and every surrounding's move is linear in t over [t0, t1] (at the
        midpoint, to 1e-9 of the move). Collective."""
        sysm = self.system
        tm = 0.5 * (t0 + t1)
        ok = True
        for c in sysm.constraints:
            if not c.path_given:
                continue
            a, b = x[c.dofs], sysm.g[c.dofs]
            tol = 1e-9 * (1 + np.abs(b - a).max(initial=0))
            try:
                ok = ok and np.allclose(c.values(tm), 0.5 * (a + b), rtol=0, atol=tol)
            except UserError:
                ok = False
        for e in self.starts:
            ok = ok and e.moves_linearly(t0, t1)
        return bool(sysm.space.mpi.allreduce(ok, op=MPI.LAND))

    def pushed(self, x, base=None):
        """x (a start of the step; base: the step's start state, default x) with the nodes that moving surroundings
        reach pushed ahead of them (StepStart.pushed), or None where a
        push would be too long for the cells beside it on some rank (collective): longer than PUSH_LIMIT of a surface
        edge, or a cell of the material would invert under PUSH_MARGIN times the pushes (Newton starts from a strained
        layer, not a flattened one)."""
        x0, ok = x, True
        for e in self.starts:
            if e.moving:
                x, fits = e.pushed(x, base)
                ok = ok and fits
        if ok and x is not x0:
            k = self.system.elastic_kernels()
            ok = k.max_step(x0, PUSH_MARGIN * (x - x0), 1.0) >= 1.0
            if not ok:               # (the pushes carried half-way into the cells beside them: a gentler layer)
                x = x0 + spread(x - x0, k.cells)
                ok = k.max_step(x0, PUSH_MARGIN * (x - x0), 1.0) >= 1.0
        return x if self.system.space.mpi.allreduce(ok, op=MPI.LAND) else None

    def through(self, x):
        """This rank's count of where the local positions x lie outside the checks' domains (in or through an obstacle
        or the contact surface, as reached from the step's start)."""
        return sum(e.undefined_at(x) for e in self.checks)

    def crossing(self, x):
        """In words, the first place (the lowest rank's) where the local positions x leave a check's domain; "" where
        none does. Collective."""
        said = [e.crossing(x) for e in self.checks]       # (every check on every rank: self-contact's gathers)
        mine = next((w for w in said if w), "")
        return next((w for w in self.system.space.mpi.allgather(mine) if w), "")

    def free(self, x):
        """Whether the local positions x pass every check, on all ranks."""
        return self.system.space.mpi.allreduce(self.through(x), op=MPI.SUM) == 0

    def adapt(self, t, h, xn, vn):
        """-contact_kappa adaptive: each adaptive effect's stiffness balanced against the rest of the incremental
        potential at the step's start x^n, as IPC chooses it (Li et al. 2020, sec. 4.3 and its supplement:
        kappa = -(g_E . g_B)/(g_B . g_B), g_B the barrier's gradient per unit kappa, g_E the other terms' gradient,
        both over the free dofs), clipped to its kappa_range [kappa_min, 100 kappa_min] (kappa_min: -contact_kappa's
        default, 0.1 E / dhat); kappa_min where no pair is within dhat. IPC balances once and then doubles kappa where
        the distance keeps shrinking below 1e-9 of the scene's size; balanced at every step's start instead, kappa
        needs no state (a restart continues exactly), and at an equilibrium (a converged step's end, g_E = -kappa g_B)
        it is the kappa in use. Collective."""
        sysm = self.system
        sp = sysm.space
        free = np.ones(3 * sp.n_owned, bool)
        free[sysm.c_owned_pos] = False
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
                    others = [o for o in sysm.effects if o not in self.adaptive]
                    gE = sp.sum_owned(sysm.residual_local(xn, others).reshape(-1, 3)).ravel()[free]
                eb = sp.mpi.allreduce(float(gE @ gB), op=MPI.SUM)
                kappa = min(max(-eb / bb, lo), hi) if np.isfinite(eb) else lo
            if kappa != e.kappa:
                e.set_kappa(kappa)
                e.begin_step(t, h, xn, vn)       # (friction's lagged normal forces with it)
