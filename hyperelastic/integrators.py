"""Backward Euler in the unknown x^{n+1} (thesis eq. 5.3, see system.py), or quasi-static
loading steps, one SNES solve per step; v^{n+1} = (x^{n+1} - x^n)/h."""
import math
import sys
import time

import numpy as np
from petsc4py import PETSc

from .errors import SolveError


def step_count(final_time, dt):
    n = max(1, math.ceil(final_time / dt - 1e-9)) if final_time > 0 else 0
    return n


class BackwardEuler:
    def __init__(self, scene, system, solver, writer=None, quiet=False):
        self.scene, self.system, self.solver, self.writer = scene, system, solver, writer
        self.quiet = quiet
        sp = system.space
        self.sp = sp
        self.X = sp.global_vec()
        self.x = sp.X.ravel().copy()      # local positions (reference configuration at t = 0)
        self.v = np.zeros_like(self.x)
        self.t = 0.0
        self.step = 0
        self.stages = {k: PETSc.Log.Stage(k) for k in ("Step", "Output")}

    def run(self):
        sc = self.scene
        h = sc.dt
        nsteps = step_count(sc.final_time, h)
        every = max(1, int(round(1.0 / (sc.fps * h))))
        if self.writer:
            self.system.begin_step(0.0, h, self.x, self.v)
            self.writer.frame(0.0, self.system.impose(self.x.copy()))
        t_start = time.perf_counter()
        last_print = t_start
        for n in range(nsteps):
            hn = min(h, sc.final_time - self.t) if n == nsteps - 1 else h
            stats = self.advance(hn)
            self.stages["Output"].push()
            if self.writer:
                self.writer.stats(stats)
                if (n + 1) % every == 0 or n == nsteps - 1:
                    self.writer.frame(self.t, self.x)
            self.stages["Output"].pop()
            now = time.perf_counter()
            if not self.quiet and self.sp.mpi.rank == 0 and (now - last_print > 2.0 or n == nsteps - 1):
                last_print = now
                print(f"t={self.t:.4g}/{sc.final_time:.4g} step {n + 1}/{nsteps} newton {stats['newton_its']} "
                      f"ksp {stats['ksp_its']} [{now - t_start:.1f} s]", file=sys.stderr, flush=True)
        return self

    def advance(self, h):
        """One step of size h from (x, v, t); raises SolveError when SNES fails."""
        self.stages["Step"].push()
        try:
            return self._advance(h)
        finally:
            self.stages["Step"].pop()

    def _advance(self, h):
        sysm, sp = self.system, self.sp
        t1 = self.t + h
        c0 = sysm.effect_counters()
        r0, rs0 = sysm.residual_evals, sysm.residual_seconds
        w0 = time.perf_counter()
        sysm.begin_step(t1, h, self.x, self.v)
        guess = self.x + (0.0 if self.scene.quasistatic else h) * self.v
        self.X.getArray()[:] = sp.owned_array(guess)
        sysm.impose_global(self.X)
        reason = self.solver.solve(self.X)
        snes = self.solver.snes
        stats = {"step": self.step + 1, "time": t1, "dt": h, "snes_reason": int(reason),
                 "newton_its": snes.getIterationNumber(), "ksp_its": snes.getLinearSolveIterations(),
                 "residual_evals": sysm.residual_evals - r0, "residual_seconds": sysm.residual_seconds - rs0,
                 "wall_s": time.perf_counter() - w0}
        if reason <= 0:
            why = self.solver.reason_name(reason)
            if self.writer:   # the failed attempt is recorded, never dropped
                self.writer.stats(stats)
                self.writer.set_attr("failure", f"step {self.step + 1} t={t1:.6g}: {why}")
            raise SolveError(f"step {self.step + 1} (t={t1:.6g}, h={h:.3g}): SNES did not converge "
                             f"({why}) after {stats['newton_its']} Newton iterations")
        x1 = sysm.impose(sysm.local(self.X, sysm.xl).copy())
        if not np.isfinite(x1).all():
            raise SolveError(f"step {self.step + 1} (t={t1:.6g}): non-finite positions")
        v1 = (x1 - self.x) / h
        self.x, self.v, self.t = x1, (np.zeros_like(v1) if self.scene.quasistatic else v1), t1
        self.step += 1
        en = sysm.energies(self.x, self.v)
        stats.update({"kinetic": en.get("kinetic", 0.0), "elastic": en["elastic"], "J_min": en["J_min"],
                      "J_max": en["J_max"]})
        for k in ("gravity_potential", "traction_work"):
            if k in en:
                stats[k] = en[k]
        for name, (ev, ap, sec) in sysm.effect_counters().items():
            e0 = c0[name]
            stats[f"effect_{name}_evals"] = ev - e0[0]
            stats[f"effect_{name}_applies"] = ap - e0[1]
            stats[f"effect_{name}_seconds"] = sec - e0[2]
        return stats
