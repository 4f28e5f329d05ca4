"""Backward Euler in the unknown x^{n+1} (thesis eq. 5.3, see system.py), or quasi-static
loading steps, one SNES solve per step; v^{n+1} = (x^{n+1} - x^n)/h; with step control."""
import math
import signal
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .errors import Interrupted, SolveError
from .stats import effect_column


def step_count(final_time, dt):
    n = max(1, math.ceil(final_time / dt - 1e-9)) if final_time > 0 else 0
    return n


class BackwardEuler:
    def __init__(self, scene, system, solver, writer, x0, v0, checkpoint=None, quiet=False):
        """Steps the system from the initial state (x0, v0: local arrays at t = 0), or from a
        checkpoint's state (output.read_checkpoint) when given, writing frames and statistics to
        `writer` (None: nothing is written). The scene gives the time settings."""
        self.scene, self.system, self.solver, self.writer = scene, system, solver, writer
        self.quiet = quiet
        sp = system.space
        self.sp = sp
        self.X = sp.global_vec()
        self.x, self.v = x0, v0
        self.t = 0.0
        self.step = 0
        self.h_try = None      # step size of the next attempt (step control)
        self.streak = 0        # accepted steps since the last change of h_try
        self.rejections = 0
        self.n0 = 0            # nominal steps already done (a restart starts later)
        self.signal = 0        # set by request_stop (the SIGINT/SIGTERM handler of the command line)
        self.stages = {k: PETSc.Log.Stage(k) for k in ("Step", "Output")}
        if checkpoint is not None:
            self._resume(checkpoint)

    def request_stop(self, signum):
        """Stop at the next frame with a checkpoint (honoured on every rank)."""
        self.signal = signum

    def run(self):
        """Steps of the nominal size -dt; frames every round(1/(fps dt)) of them. With step control
        (default), a step whose solve fails (SNES diverged, a non-finite residual or state) is
        rejected and retried with half the size; after -dt_grow_after accepted steps the size doubles
        again, up to -dt. Every attempt is a row in stats (rejected = 1 for the refused ones). Below
        -dt_min the run stops with a SolveError naming time, step and reason."""
        sc = self.scene
        H = sc.dt
        nsteps = step_count(sc.final_time, H)
        every = max(1, int(round(1.0 / (sc.fps * H))))
        if self.writer and self.n0 == 0:
            self.system.begin_step(0.0, H, self.x, self.v)
            self.writer.frame(0.0, self.system.impose(self.x.copy()))
        t_start = time.perf_counter()
        last_print = t_start
        self.h_try = H if self.h_try is None else self.h_try
        for n in range(self.n0, nsteps):
            t_end = self.t + (min(H, sc.final_time - self.t) if n == nsteps - 1 else H)
            stats = self._nominal_step(t_end, H)
            self._after_step(n, nsteps, every)
            now = time.perf_counter()
            if not self.quiet and self.sp.mpi.rank == 0 and (now - last_print > 2.0 or n == nsteps - 1):
                last_print = now
                rej = f" rejected {self.rejections}" if self.rejections else ""
                print(f"t={self.t:.4g}/{sc.final_time:.4g} step {n + 1}/{nsteps} newton {stats['newton_its']} "
                      f"ksp {stats['ksp_its']}{rej} [{now - t_start:.1f} s]", file=sys.stderr, flush=True)
        return self

    def _nominal_step(self, t_end, H):
        """Attempts from t to t_end (halving after each rejection, regrowing after accepted streaks);
        returns the stats row of the last attempt."""
        sc = self.scene
        while self.t < t_end:
            h = min(self.h_try, t_end - self.t)
            last = t_end - self.t - h <= 1e-12 * H
            stats = self.advance(h, t_end if last else self.t + h)
            why = stats.pop("why", None)
            if stats["rejected"]:
                self._say(f"t={self.t:.4g}: step of h={h:.3g} rejected: {why}")
            self.stages["Output"].push()
            if self.writer:
                self.writer.stats(stats)
            self.stages["Output"].pop()
            if stats["rejected"]:
                self.rejections += 1
                self.streak = 0
                self.h_try = 0.5 * h
                if not sc.step_control or self.h_try < sc.dt_min:
                    self._fail(stats, why)
                continue
            self.streak += 1
            if self.h_try < H and self.streak >= sc.dt_grow_after:
                self.h_try, self.streak = min(2 * self.h_try, H), 0
        return stats

    def _say(self, line):
        """A progress line on stderr (rank 0; not with -quiet)."""
        if not self.quiet and self.sp.mpi.rank == 0:
            print(line, file=sys.stderr, flush=True)

    def _after_step(self, n, nsteps, every):
        """After nominal step n: the frame, a checkpoint, and a stop on a signal (all ranks agree)."""
        sc = self.scene
        self.stages["Output"].push()
        framed = (n + 1) % every == 0 or n == nsteps - 1
        if self.writer and framed:
            self.writer.frame(self.t, self.x)
        # a signal is honoured at a frame (all ranks agree), after a checkpoint of that state
        stop = framed and self.sp.mpi.allreduce(self.signal, op=MPI.MAX)
        ck = sc.checkpoint_every and (n + 1) % sc.checkpoint_every == 0 and n < nsteps - 1
        if self.writer and (stop or ck):
            self.checkpoint(n + 1)
        self.stages["Output"].pop()
        if stop:
            name = signal.Signals(stop).name
            if self.writer:
                self.writer.set_attr("interrupted", f"{name} at t={self.t:.6g} (step {self.step})")
            raise Interrupted(f"interrupted by {name} at t={self.t:.6g} (step {self.step}); state saved: "
                              f"continue with `hyperelastic run --restart {self.writer.path if self.writer else 'FILE'}`",
                              stop)

    def checkpoint(self, n):
        self.writer.checkpoint(self.x, self.v, t=self.t, step=self.step, n=n, h_try=self.h_try, streak=self.streak,
                               rejections=self.rejections, nframes=self.writer.nframes, nstats=self.writer.nstats)

    def _resume(self, state):
        """Continue from a checkpoint (output.read_checkpoint): the same state, step control included."""
        sp = self.sp
        self.x, self.v = sp.scatter(state["x"]), sp.scatter(state["v"])
        self.t, self.step, self.n0 = float(state["t"]), int(state["step"]), int(state["n"])
        self.h_try, self.streak, self.rejections = float(state["h_try"]), int(state["streak"]), int(state["rejections"])

    def _fail(self, stats, why):
        sc = self.scene
        where = f"step {self.step + 1} (t={stats['time']:.6g}, h={stats['dt']:.3g})"
        if sc.step_control:
            why += f"; step control reached -dt_min {sc.dt_min:.3g} after {self.rejections} rejected attempts"
        if self.writer:
            self.writer.set_attr("failure", f"{where}: {why}")
        raise SolveError(f"{where}: {why}")

    def advance(self, h, t1=None):
        """One attempt of a step of size h from (x, v, t) to t1 (default t + h). Returns its stats
        row; the state moves only when the attempt is accepted (stats['rejected'] == 0)."""
        self.stages["Step"].push()
        try:
            return self._advance(h, self.t + h if t1 is None else t1)
        finally:
            self.stages["Step"].pop()

    def _advance(self, h, t1):
        sysm, sp = self.system, self.sp
        c0 = sysm.effect_counters()
        r0, rs0 = sysm.residual_evals, sysm.residual_seconds
        o0, os0 = sysm.objective_evals, sysm.objective_seconds
        cuts0 = self.solver.inversion_cuts
        w0 = time.perf_counter()
        sysm.begin_step(t1, h, self.x, self.v)
        self._initial_guess(h)
        reason = self.solver.solve(self.X)
        snes = self.solver.snes
        stats = {"step": self.step + 1, "time": t1, "dt": h, "snes_reason": int(reason),
                 "newton_its": snes.getIterationNumber(), "ksp_its": snes.getLinearSolveIterations(),
                 "residual_evals": sysm.residual_evals - r0, "residual_seconds": sysm.residual_seconds - rs0,
                 "objective_evals": sysm.objective_evals - o0, "objective_seconds": sysm.objective_seconds - os0,
                 "inversion_cuts": self.solver.inversion_cuts - cuts0, "rejected": 1}
        for name, (ev, ap, sec) in sysm.effect_counters().items():
            e0 = c0[name]
            stats[effect_column(name, "evals")] = ev - e0[0]
            stats[effect_column(name, "applies")] = ap - e0[1]
            stats[effect_column(name, "seconds")] = sec - e0[2]
        if reason <= 0:
            name = self.solver.reason_name(reason)
            if name == "DIVERGED_LINEAR_SOLVE":
                name += f": KSP {self.solver.ksp_reason_name()}"
            stats["why"] = f"SNES did not converge ({name}) after {stats['newton_its']} Newton iterations"
            return self._rejected(stats, w0)
        x1 = sysm.impose(sysm.local(self.X, sysm.xl).copy())
        v1 = np.zeros_like(x1) if self.scene.quasistatic else (x1 - self.x) / h
        en = sysm.energies(x1, v1)
        vals = [en.get("kinetic", 0.0), en["elastic"]] + [en[k] for k in ("gravity_potential", "traction_work")
                                                        if k in en]
        finite = sp.mpi.allreduce(bool(np.isfinite(x1).all()), op=MPI.LAND) and all(map(math.isfinite, vals))
        if not finite:   # a NaN/Inf state never reaches the output
            stats["why"] = "non-finite positions or energies after a converged solve"
            return self._rejected(stats, w0)
        self.x, self.v, self.t = x1, v1, t1
        self.step += 1
        stats.update({"rejected": 0, "kinetic": en.get("kinetic", 0.0), "elastic": en["elastic"],
                      "J_min": en["J_min"], "J_max": en["J_max"], "wall_s": time.perf_counter() - w0})
        for k in ("gravity_potential", "traction_work"):
            if k in en:
                stats[k] = en[k]
        return stats

    def _initial_guess(self, h):
        """Newton's start in self.X: the explicit predictor x^n + h v^n with the step's boundary
        positions. Where the material is undefined when inverted and that start inverts cells (fast
        prescribed ends outrunning their neighbours' predicted motion), the previous positions x^n
        instead, if they do not (the residual there is defined, so Newton can start)."""
        sysm, sp = self.system, self.sp
        guesses = [self.x + h * self.v] if not self.scene.quasistatic and self.v.any() else []
        for guess in guesses + [self.x]:
            self.X.getArray()[:] = sp.owned_array(guess)
            sysm.impose_global(self.X)
            if not sysm.check_domain or guess is self.x or sysm.defined_at(self.X):
                return

    def _rejected(self, stats, w0):
        stats["wall_s"] = time.perf_counter() - w0
        return stats
