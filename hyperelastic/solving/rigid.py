"""The reference point of a rigid face (physics/effects/rigid.py): its reaction, and the balance of its loaded
components around each step's solve.

Balance: Newton on the loaded components q_f of the point's motion for e(q_f) = 0 (the face's reaction against the
applied force and moment, Rigid.imbalance), every iterate x(q) being the step's solve with the face placed by q: the
body condensed onto the reference point (static condensation), solved exactly. The derivative of e is the condensed
problem's: for each loaded component j the body follows the face as dx/dq_j = w_j + z_j, w_j = d(place)/dq_j on the
face's nodes and J z_j = -J_fs w_j on the free dofs (J the step's tangent at x, J_fs w_j the free rows' change with the
held targets, by a central difference of the residual in the targets); de/dq_j is the central difference of e along
(w_j + z_j, e_j). The next solve starts from x + sum_j dq_j (w_j + z_j), the linearized answer, so it takes a Newton
iteration or two. Cost per balance iteration: the solve, and per loaded component two residuals, a Krylov solve with
the step's preconditioner and two reactions. The answer depends only on e = 0 (to -rigid_rtol), not on the accuracy of
the derivative, which only sets how fast the iterates converge."""
import numpy as np
from mpi4py import MPI

STEP = 1e-6             # the central differences' step: this fraction of the face's extent, moved by its farthest node
COLUMNS = {
    **{f"rigid_{c}": (float, f"the rigid face's reference point: {m} after the step")
       for c, m in (("ux", "displacement x [m]"), ("uy", "displacement y [m]"), ("uz", "displacement z [m]"),
                    ("rx", "rotation vector x [rad]"), ("ry", "rotation vector y [rad]"),
                    ("rz", "rotation vector z [rad]"))},
    **{f"rigid_{c}": (float, f"the rigid face's reaction: {m} (what the face needs from outside; equal to the applied "
                             "load in a loaded component)")
       for c, m in (("Fx", "force x [N]"), ("Fy", "force y [N]"), ("Fz", "force z [N]"),
                    ("Mx", "moment x about the reference point [N m]"), ("My", "moment y [N m]"),
                    ("Mz", "moment z [N m]"))},
    "rigid_its": (int, "the rigid face's balance: solves of the step beyond its first (0: no loaded component)"),
}


def reaction(system, rb, X, q, impose=True):
    """(F, M about the point's position c(q), force scale, moment scale) of the rigid face rb at the unknown X: the
    residual of every effect summed over the face's nodes (forces.py: the force the face needs from outside), over all
    ranks. impose=False: the face's positions as X holds them (a perturbed state), not as the targets say."""
    system.solved(X)
    x = system.local(X, system.xl).copy()
    if impose:
        system.impose(x)
    r = system.residual_local(x).reshape(-1, 3)[rb.vertices]
    d = x.reshape(-1, 3)[rb.vertices] - rb.center(q)
    nr = np.linalg.norm(r, axis=1)
    part = np.concatenate([r.sum(axis=0), np.cross(d, r).sum(axis=0), [nr.sum(), (np.linalg.norm(d, axis=1) * nr).sum()]])
    tot = np.empty_like(part)
    system.space.mpi.Allreduce(part, tot, op=MPI.SUM)
    return tot[:3], tot[3:6], tot[6], tot[7]


def columns(system, rb, X):
    """The statistics' rigid_* values of an accepted state X."""
    F, M, _, _ = reaction(system, rb, X, rb.q)
    vals = list(rb.q) + list(F) + list(M)
    return dict(zip([k for k in COLUMNS if k != "rigid_its"], map(float, vals)))


def line(system, rb, x):
    """The end-of-run line of the rigid face at the accepted local positions x (collective; the line on every rank),
    and its record for the output's attribute."""
    F, M, _, _ = reaction(system, rb, system.global_state(x), rb.qn)
    u, th = rb.qn[:3], rb.qn[3:]
    c = rb.center(rb.qn)
    f = lambda v: ", ".join(f"{a:.6g}" for a in v)
    text = (f"rigid {rb.surface}: reference point ({f(rb.point)}) moved by ({f(u)}) m, rotated by ({f(th)}) rad "
            f"({np.degrees(np.linalg.norm(th)):.6g} deg); reaction F = ({f(F)}) N, M = ({f(M)}) N m about the point "
            f"at ({f(c)})")
    return text, {"surface": rb.surface, "point": list(map(float, rb.point)), "u": list(map(float, u)),
                  "rotation": list(map(float, th)), "F": list(map(float, F)), "M": list(map(float, M))}


class Balance:
    """The balance of a rigid face with loaded components (module docstring)."""

    def __init__(self, system, solver, rb):
        self.system, self.solver, self.rb = system, solver, rb
        self.free = np.flatnonzero(rb.free)
        self.wl = np.zeros(3 * system.space.nlv)        # (a local array: one direction at a time)

    def error(self, X, q, t, impose=True):
        """(e, scale): the loaded components' imbalance and each one's scale (the face's force or moment scale plus
        the applied load's size)."""
        rb = self.rb
        F, M, sF, sM = reaction(self.system, rb, X, q, impose)
        a = rb.applied(t)
        scale = np.array([sF + np.linalg.norm(a[:3])] * 3 + [sM + np.linalg.norm(a[3:])] * 3)[self.free]
        return rb.imbalance(F, M, q, t), scale

    def run(self, X, t):
        """Balance the point from the step's converged solve in X (updated in place). Returns (converged, why,
        balance iterations, Newton iterations, Krylov iterations) of the solves it added."""
        rb, sysm, solver = self.rb, self.system, self.solver
        newton = ksp_its = 0
        for it in range(rb.max_it + 1):
            e, scale = self.error(X, rb.q, t)
            if np.all(np.abs(e) <= rb.rtol * scale):
                sysm.solved(X)
                return True, "", it, newton, ksp_its
            if it == rb.max_it:
                break
            cond = self.condensed(X, t)
            if isinstance(cond, str):
                return False, cond, it, newton, ksp_its
            A, D, its = cond
            ksp_its += its
            try:
                dq = np.linalg.solve(A, -e)
            except np.linalg.LinAlgError:
                return False, f"rigid face {rb.surface}: the loaded components' stiffness is singular", it, newton, ksp_its
            for k, Dk in zip(dq, D):
                X.axpy(float(k), Dk)
            rb.q[self.free] += dq
            sysm.retarget(rb, rb.place(rb.q))
            sysm.impose_global(X)
            reason = solver.solve(X)
            n, k = solver.iterations()
            newton += n
            ksp_its += k
            if reason <= 0:
                return (False, f"rigid face {rb.surface}: the solve of balance iteration {it + 1} did not converge "
                               f"({solver.reason_name(reason)})", it + 1, newton, ksp_its)
        worst = float(np.max(np.abs(e) / np.maximum(scale, 1e-300)))
        return (False, f"rigid face {rb.surface}: its reference point not balanced after {rb.max_it} iterations "
                       f"(imbalance {worst:.2g} of its scale, -rigid_rtol {rb.rtol:g})", rb.max_it, newton, ksp_its)

    def condensed(self, X, t):
        """(de/dq_f (nf, nf), [w_j + z_j as unknown vectors], Krylov iterations) at the solve X, or the reason a
        Krylov solve failed."""
        rb, sysm, sp = self.rb, self.system, self.system.space
        q0 = rb.q.copy()
        g0 = rb.place(q0)
        A = np.empty((len(self.free), len(self.free)))
        D, its = [], 0
        for k, j in enumerate(self.free):
            w = rb.direction(j, q0)
            wmax = sp.mpi.allreduce(float(np.abs(w).max(initial=0.0)), op=MPI.MAX) or 1.0
            delta = STEP * rb.extent / wmax
            Dj, n, ok = self.solver.held_response(X, lambda s: sysm.retarget(rb, g0 + s * w), delta, tangent=k == 0)
            its += n
            if not ok:
                return (f"rigid face {rb.surface}: the Krylov solve of its stiffness did not converge "
                        f"({self.solver.ksp_reason_name()})")
            self.wl[:] = 0.0
            self.wl.reshape(-1, 3)[rb.vertices] = w
            owned = sp.owned_array(self.wl)
            Dj.getArray()[:len(owned)] += owned
            D.append(Dj)
            dq = np.zeros(6)
            dq[j] = delta
            Xs = X.copy()
            Xs.axpy(delta, Dj)
            ep, _ = self.error(Xs, q0 + dq, t, impose=False)
            Xs.axpy(-2.0 * delta, Dj)
            em, _ = self.error(Xs, q0 - dq, t, impose=False)
            A[:, k] = (ep - em) / (2.0 * delta)
            Xs.destroy()
        return A, D, its
