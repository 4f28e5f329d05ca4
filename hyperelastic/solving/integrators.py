"""Backward Euler in the unknown x^{n+1} (thesis eq. 5.3, see system.py), or quasi-static
loading steps, one SNES solve per step; v^{n+1} = (x^{n+1} - x^n)/h; with step control."""
import math
import signal
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..core.errors import Interrupted, SolveError
from .forces import surface_forces
from . import rigid
from ..physics.effects.seams import Results, declaring
from .stats import (effect_column, effect_counters, effect_energies, energy_sum, extremal, force_columns,
                    result_columns)


def step_count(final_time, dt):
    n = max(1, math.ceil(final_time / dt - 1e-9)) if final_time > 0 else 0
    return n


# the option most likely to fix a failed step: by KSP reason for a failed linear solve, else by SNES reason
RAN_OUT = ("DIVERGED_MAX_IT", "DIVERGED_ITS")     # KSP's reason for running out of iterations (new, old name)
KSP_HINTS = {
    **dict.fromkeys(RAN_OUT, "CG + GAMG (-options_file options/gamg.opts) or a larger -ksp_max_it"),
    "DIVERGED_BREAKDOWN": "-ksp_type gmres, or CG + GAMG (-options_file options/gamg.opts)",
    "DIVERGED_INDEFINITE_PC": "-pc_type jacobi, or CG + GAMG (-options_file options/gamg.opts)",
    "DIVERGED_INDEFINITE_MAT": "smaller steps (-dt), or -hessian_projection 1",
}      # (a formulation's solver plan may bring its own: SolverPlan.ksp_hints)
SNES_HINTS = {
    "DIVERGED_MAX_IT": "smaller steps (-dt: more load steps) or a larger -snes_max_it",
    "DIVERGED_FUNCTION_COUNT": "smaller steps (-dt) or a larger -snes_max_funcs",
    "DIVERGED_LINE_SEARCH": "smaller steps (-dt), or -inversion_guard 1",
    "DIVERGED_FNORM_NAN": "smaller steps (-dt), or -inversion_guard 1",
    "DIVERGED_FUNCTION_DOMAIN": "smaller steps (-dt), or -inversion_guard 1",
    "DIVERGED_DTOL": "smaller steps (-dt)",
}


# SNES's reasons that certify the residual itself (-snes_atol, -snes_rtol met): such a state is a solution of the
# discrete problem whatever its volume ratios (a nearly incompressible squeeze's P2-P1 solution has J from 0.17 to
# 3.1 at the quadrature points of the prescribed faces' corner cells, where the exact pressure is singular: the
# hard-case matrix's mixed squeezes at nu = 0.4999 were refused at J_max 1.65, t = 0.35); the others (ksponly's
# CONVERGED_ITS, a small update's SNORM_RELATIVE) say nothing about the residual, and there |ln J| is the check
RESIDUAL_MET = (PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS, PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE)


def volume_refusal(stats, system):
    """Why a converged state is not a solution of its material, judged by its volume ratios (the statistics' J_min and
    J_max): a cell inverted in a material undefined there, or, where the solve's reason does not certify its residual
    (RESIDUAL_MET), |ln J| beyond the bound a solid of its compressibility keeps (system.volume_bound,
    formulations/mixed: volume_bound); "" where neither."""
    lo, hi = stats.get("J_min"), stats.get("J_max")
    if lo is None or hi is None:
        return ""
    if lo <= 0:
        return (f"a converged solve left cells inverted (J_min = {lo:.3g}) in a material undefined there: not a "
                "solution" if system.material_domain else "")
    if system.volume_bound is None or stats.get("snes_reason") in RESIDUAL_MET:
        return ""
    bound, ratio = system.volume_bound
    worst = max(-math.log(lo), math.log(hi))
    if worst <= bound:
        return ""
    return (f"a converged solve left volume ratios J in [{lo:.3g}, {hi:.3g}] (|ln J| up to {worst:.3g}), beyond the "
            f"{bound:.3g} a solid with kappa/mu = {ratio:.3g} keeps: not a solution (a false convergence)")


class Integrator:
    """What every time integrator of a run shares: the state (x, v, t, step), frames, statistics
    rows, checkpoints, clean stops on SIGINT/SIGTERM and the progress line."""

    def __init__(self, scene, system, solver, writer, x0, v0, quiet=False):
        self.scene, self.system, self.solver, self.writer = scene, system, solver, writer
        self.quiet = quiet
        self.sp = system.space
        self.x, self.v = x0, v0
        self.t = 0.0
        self.step = 0
        self.rejections = 0
        self.signal = 0        # set by request_stop (the SIGINT/SIGTERM handler of the command line)
        self.h_try = None      # step size of the next attempt (step control)
        self.streak = 0        # accepted steps since the last change of h_try
        # regrowing: after regrow_wait accepted steps (-dt_grow_after, doubled each time a regrown size fails at
        # once, reset where one holds: a 360-degree twist regrew into the same failure 11 times, issue 47);
        # regrown: the last change of h_try was a regrowth
        self.regrow_wait = scene.dt_grow_after
        self.regrown = False
        self.n0 = 0            # nominal steps already done (a restart starts later)
        self.t_end0 = None     # a restart inside a nominal step: that step's end (resume)
        self.run_notes = []    # the notes the output's attribute `notes` holds (run.py: the start-up's first)
        self.rigid = system.rigid[0] if system.rigid else None     # a rigid face (one per run), or None
        self.stages = {k: PETSc.Log.Stage(k) for k in ("Step", "Output")}
        system.begin_step(0.0, scene.dt, x0, v0)
        self.energy0 = energy_sum(effect_energies(system.effects, self.sp.mpi, x0, v0))   # for energy_dissipated

    def request_stop(self, signum):
        """Stop after the attempt under way, with a checkpoint of the last accepted state (honoured on every rank
        alike: the ranks agree after each attempt). A frame is no longer waited for: a run crawling between
        frames ignored SIGTERM for over 10 minutes (issue 47), longer than a scheduler's grace period."""
        self.signal = signum

    def _stop_signal(self):
        """The signal every rank agrees to stop on (0: none); collective."""
        return self.sp.mpi.allreduce(self.signal, op=MPI.MAX)

    def _interrupt(self, stop, n_done, t_end=None):
        """Stop on signal `stop`: a checkpoint of the state (with the nominal step's end t_end where it is
        written inside one), the output's attribute, and the one line."""
        if self.writer:
            self.stages["Output"].push()
            self.checkpoint(n_done, t_end)
            self.stages["Output"].pop()
        name = signal.Signals(stop).name
        if self.writer:
            self.writer.set_attr("interrupted", f"{name} at t={self.t:.6g} (step {self.step})")
        raise Interrupted(f"interrupted by {name} at t={self.t:.6g} (step {self.step}); state saved: "
                          f"continue with `hyperelastic run --restart {self.writer.final if self.writer else 'FILE'}`",
                          stop)

    def _say(self, line):
        """A progress line on stderr (rank 0; not with -quiet)."""
        if not self.quiet and self.sp.mpi.rank == 0:
            print(line, file=sys.stderr, flush=True)

    def _note(self, text):
        """A note the run must leave: on stderr (rank 0; -quiet too: it silences progress, never a note) and in the
        output's attribute `notes`."""
        if self.sp.mpi.rank == 0:
            print(f"note: {text}", file=sys.stderr, flush=True)
        self.run_notes = self.run_notes + [text]
        if self.writer:
            self.writer.set_attr("notes", "\n".join(self.run_notes))

    def _write_stats(self, stats):
        self.stages["Output"].push()
        if self.writer:
            self.writer.stats(stats)
        self.stages["Output"].pop()

    def _energy_stats(self, x1, v1, stats, t1):
        """The energies of the state (x1, v1) at time t1 (and the effects' results) into the stats row; False if they
        or x1 are not finite."""
        en = effect_energies(self.system.effects, self.sp.mpi, x1, v1)
        en.setdefault("kinetic", 0.0)
        finite = self.sp.mpi.allreduce(bool(np.isfinite(x1).all()), op=MPI.LAND) and all(
            math.isfinite(val) for k, val in en.items() if not extremal(k))
        if not finite:
            return False
        tot = energy_sum(en)
        stats.update(en)
        stats.update({"energy_total": tot, "energy_dissipated": self.energy0 - tot})
        stats.update(self._result_stats(x1, t1))
        return True

    def _result_stats(self, x, t):
        """The statistics columns of the effects' Results (seams.Results: each obstacle's force, contact area and
        translation) at the local positions x at time t (forces and areas summed over the ranks)."""
        effects = declaring(self.system.effects, Results)
        if not effects:
            return {}
        rows = [r for e in effects for r in e.result_rows(x, t)]
        summed = np.array([np.append(r.force, [r.area, r.carried or 0.0]) for r in rows], float).reshape(-1, 5)
        self.sp.mpi.Allreduce(MPI.IN_PLACE, summed, op=MPI.SUM)
        return result_columns([r._replace(force=s[:3], area=s[3], carried=None if r.carried is None else s[4])
                               for r, s in zip(rows, summed)])

    def _output(self, n_done, framed, last, x_frame=None):
        """After a completed step: the frame (x_frame, default the state's x), a checkpoint every
        -checkpoint_every steps, and a stop on a signal (all ranks agree). Returns whether a
        checkpoint was written."""
        sc = self.scene
        self.stages["Output"].push()
        if self.writer and framed:
            self.writer.frame(self.t, self.x if x_frame is None else x_frame, self.v)
        stop = self._stop_signal() if not last else 0
        ck = bool(sc.checkpoint_every and n_done % sc.checkpoint_every == 0 and not last)
        if self.writer and ck and not stop:
            self.checkpoint(n_done)
        self.stages["Output"].pop()
        if stop:
            self._interrupt(stop, n_done)
        return ck and self.writer is not None

    def _progress(self, state, n, nsteps, stats, t_start, force=False):
        """The progress line, every 2 s and at the end (state: {'last_print': time})."""
        now = time.perf_counter()
        if not self.quiet and self.sp.mpi.rank == 0 and (now - state["last_print"] > 2.0 or force):
            state["last_print"] = now
            rej = f" rejected {self.rejections}" if self.rejections else ""
            of = f"/{nsteps}" if nsteps else ""
            print(f"t={self.t:.4g}/{self.scene.final_time:.4g} step {n + 1}{of} newton {stats['newton_its']} "
                  f"ksp {stats['ksp_its']}{rej} [{now - t_start:.1f} s]", file=sys.stderr, flush=True)

    def _counters(self):
        s = self.system
        return (effect_counters(s.effects), s.residual_evals, s.residual_seconds, s.objective_evals, s.objective_seconds,
                dict(self.solver.cuts))

    def _counter_stats(self, c0):
        """The counters' increments since the snapshot c0 (_counters) as statistics columns (the step limiters' cuts:
        each limiter's column, seams.StepLimiter.counter)."""
        c1 = self._counters()
        keys = ("residual_evals", "residual_seconds", "objective_evals", "objective_seconds")
        stats = {k: b - a for k, a, b in zip(keys, c0[1:5], c1[1:5])}
        stats.update({k: n - c0[5][k] for k, n in c1[5].items()})
        for name, (ev, ap, sec) in c1[0].items():
            e0 = c0[0][name]
            stats[effect_column(name, "evals")] = ev - e0[0]
            stats[effect_column(name, "applies")] = ap - e0[1]
            stats[effect_column(name, "seconds")] = sec - e0[2]
        return stats

    def checkpoint(self, n, t_end=None):
        """The state, the step-size state and the output counters (-integrator ts: x and v as TS holds them;
        there the uninterrupted run restarts at the checkpoints too); t_end: the nominal step's end, where the
        checkpoint is written inside one."""
        self.solver.rebuild_preconditioner()     # where a restart begins: the same set-ups in both runs
        self.writer.checkpoint(self.x, self.carried_v(), nodal=self.system.nodal_state(),
                               cells=self.system.cell_state(), t=self.t, step=self.step, n=n,
                               h_try=self.h_try, streak=self.streak, rejections=self.rejections,
                               nframes=self.writer.nframes, nstats=self.writer.nstats, t_end=t_end,
                               regrow_wait=self.regrow_wait, regrown=int(self.regrown),
                               rigid=None if self.rigid is None else self.rigid.state())

    def carried_v(self):
        """What a checkpoint stores as v: the velocities."""
        return self.v

    def _resume(self, state):
        """Continue from a checkpoint (files.read_checkpoint): the same state, step control included."""
        sp = self.sp
        self.x, self.v = sp.read_state(state["x"]), sp.read_state(state["v"])
        self.system.resume(state)
        self.t, self.step, self.n0 = float(state["t"]), int(state["step"]), int(state["n"])
        self.h_try, self.streak, self.rejections = float(state["h_try"]), int(state["streak"]), int(state["rejections"])
        self.t_end0 = state.get("t_end")         # inside a nominal step: its end
        self.regrow_wait = int(state.get("regrow_wait", self.scene.dt_grow_after))
        self.regrown = bool(state.get("regrown", 0))

    def _fail(self, where, why):
        if self.writer:
            self.writer.set_attr("failure", f"{where}: {why}")
        raise SolveError(f"{where}: {why}")


class BackwardEuler(Integrator):
    def __init__(self, scene, system, solver, writer, x0, v0, checkpoint=None, quiet=False):
        """Steps the system from the initial state (x0, v0: local arrays at t = 0), or from a
        checkpoint's state (files.read_checkpoint) when given, writing frames and statistics to
        `writer` (None: nothing is written). The scene gives the time settings."""
        super().__init__(scene, system, solver, writer, x0, v0, quiet)
        self.X = system.unknown_vec()
        # quasi-static: the last accepted step's rate dx/dt, the predictor of a step that moves prescribed nodes
        # (_initial_guess); a checkpoint stores it in v (a quasi-static run has no velocities)
        self.rate = np.zeros_like(x0)
        # a rigid face with loaded components: its reference point balanced around every step's solve (rigid.py)
        self.balance = rigid.Balance(system, solver, self.rigid) if self.rigid is not None and self.rigid.free.any() \
            else None
        if checkpoint is not None:
            self._resume(checkpoint)

    def carried_v(self):
        return self.rate if self.scene.quasistatic else self.v

    def _resume(self, state):
        super()._resume(state)
        if self.rigid is not None and state.get("rigid") is not None:
            self.rigid.resume(state["rigid"])
        if self.scene.quasistatic:
            self.rate, self.v = self.v, np.zeros_like(self.v)

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
            self.writer.frame(0.0, self.system.impose(self.x.copy()), self.v)
        t_start = time.perf_counter()
        progress = {"last_print": t_start}
        self.h_try = H if self.h_try is None else self.h_try
        stop = self._stop_signal()       # (a signal that came while the run was set up)
        if stop:
            self._interrupt(stop, self.n0, self.t_end0)
        for n in range(self.n0, nsteps):
            # (the nominal grid t_n = n H, the last step ending at -final_time: a frame's time has no summed drift,
            # 1/3 is 0.333... to the last digit, not 0.33333333333333304; issue 70)
            t_end = sc.final_time if n == nsteps - 1 else (n + 1) * H
            if n == self.n0 and self.t_end0 is not None:
                t_end = self.t_end0                  # (a restart inside a nominal step keeps its end)
            stats = self._nominal_step(t_end, H, n)
            self._output(n + 1, (n + 1) % every == 0 or n == nsteps - 1, n == nsteps - 1)
            self._progress(progress, n, nsteps, stats, t_start, force=n == nsteps - 1)
        return self

    def _nominal_step(self, t_end, H, n):
        """Attempts from t to t_end (halving after each rejection, regrowing after accepted streaks), the n-th
        nominal step; returns the stats row of the last attempt. A signal stops it between two attempts."""
        sc = self.scene
        first = True
        while self.t < t_end:
            if not first:                  # (inside the nominal step, after an attempt: the ranks agree on a signal)
                stop = self._stop_signal()
                if stop:
                    self._interrupt(stop, n, t_end)
            first = False
            h = min(self.h_try, t_end - self.t)
            last = t_end - self.t - h <= 1e-12 * H
            stats = self.advance(h, t_end if last else self.t + h)
            why = stats.pop("why", None)
            linear_only, hint = stats.pop("linear_only", False), stats.pop("hint", "")
            indefinite = stats.pop("indefinite", False)
            moves = stats.pop("moves_prescribed", False)
            # at the step's first Newton iteration the load step's size does not change the tangent, so halving
            # the step would not help (issue 34); at a later one the tangent is taken at an iterate that a smaller
            # step changes (a rubber part's Newton iterates under rotation); nor where the step moves prescribed
            # nodes: the first iterate moves them alone, and half the increment distorts the layer of cells beside
            # them half as much (issue 47: a rubber torsion failed its first GMRES solve at 11.25 degrees a step and
            # converged at 5.6, and the run was stopped instead of halved)
            no_halving = linear_only and stats["newton_its"] == 0 and not moves
            if stats["rejected"]:
                self._say(f"t={self.t:.4g}: step of h={h:.3g} rejected: {why}")
            self._write_stats(stats)
            regrown, self.regrown = self.regrown, False
            if stats["rejected"]:
                self.rejections += 1
                self.streak = 0
                self.h_try = 0.5 * h
                if regrown:              # it failed where it had just regrown to: wait twice as long next time
                    self.regrow_wait *= 2
                note = self.solver.escalate() if linear_only else self.solver.project_hessians() if indefinite else ""
                if note:                 # the same step again, with a preconditioner that fits a static stiffness
                    self._note(note)
                    self.h_try = h
                    continue
                if not sc.step_control or self.h_try < sc.dt_min or no_halving:
                    self._fail_step(stats, why, hint, halving=not no_halving)
                continue
            if regrown:                  # a regrown size that holds: back to -dt_grow_after
                self.regrow_wait = sc.dt_grow_after
            self.streak += 1
            if self.h_try < H and self.streak >= self.regrow_wait:
                self.h_try, self.streak, self.regrown = min(2 * self.h_try, H), 0, True
        return stats

    def _fail_step(self, stats, why, hint="", halving=True):
        sc = self.scene
        where = f"step {self.step + 1} (t={stats['time']:.6g}, h={stats['dt']:.3g})"
        if sc.step_control and halving:
            why += f"; step control reached -dt_min {sc.dt_min:.3g} after {self.rejections} rejected attempts"
        elif sc.step_control:
            why += "; not retried with a smaller load step (it would not change a quasi-static linear solve)"
        self._fail(where, why + (f"; try {hint}" if hint else ""))

    def advance(self, h, t1=None):
        """One attempt of a step of size h from (x, v, t) to t1 (default t + h). Returns its stats
        row; the state moves only when the attempt is accepted (stats['rejected'] == 0)."""
        self.stages["Step"].push()
        try:
            return self._advance(h, self.t + h if t1 is None else t1)
        finally:
            self.stages["Step"].pop()

    def _advance(self, h, t1):
        sysm = self.system
        c0 = self._counters()
        w0 = time.perf_counter()
        if self.rigid is not None:
            self.rigid.predict(h)          # (its loaded components along their last rate)
        sysm.begin_step(t1, h, self.x, self.v)
        refused = self._refused(h, t1, c0, w0)          # (or Newton's start is in self.X)
        if refused is not None:
            return refused
        indefinite = self.solver.indefinite_solves
        reason = self.solver.solve(self.X)
        indefinite = self.solver.indefinite_solves - indefinite
        newton, ksp = self.solver.iterations()
        stats = {"step": self.step + 1, "time": t1, "dt": h, "snes_reason": int(reason),
                 "newton_its": newton, "ksp_its": ksp + self.guess_ksp, "rejected": 1}
        if reason > 0 and self.balance is not None:
            ok, why, its, newton, ksp = self.balance.run(self.X, t1)
            stats.update(rigid_its=its, newton_its=stats["newton_its"] + newton, ksp_its=stats["ksp_its"] + ksp)
            if not ok:
                stats.update(self._counter_stats(c0), why=why)
                return self._rejected(stats, w0)
        stats.update(self._counter_stats(c0))
        if reason <= 0:
            return self._diverged(stats, reason, indefinite, w0)
        sysm.solved(self.X)
        x1 = sysm.impose(sysm.local(self.X, sysm.xl).copy())
        v1 = np.zeros_like(x1) if self.scene.quasistatic else (x1 - self.x) / h
        if not self._energy_stats(x1, v1, stats, t1):   # a NaN/Inf state never reaches the output
            stats["why"] = "non-finite positions or energies after a converged solve"
            return self._rejected(stats, w0)
        why = volume_refusal(stats, self.system)
        if why:
            stats["why"] = why
            return self._rejected(stats, w0)
        if self.scene.quasistatic:
            self.rate = (x1 - self.x) / h
        self.x, self.v, self.t = x1, v1, t1
        sysm.accept(self.X)
        sysm.accept_step(x1, h)
        if self.rigid is not None:
            self.rigid.accept(h)
            stats.update(rigid.columns(sysm, self.rigid, self.X))
        self.step += 1
        if self.writer is not None and self.scene.step_forces:   # the step's reactions and load resultants
            stats.update(force_columns(surface_forces(self.scene, sysm, x1)))
        stats.update({"rejected": 0, "wall_s": time.perf_counter() - w0})
        return stats

    def _diverged(self, stats, reason, indefinite, w0):
        """The stats row of an attempt whose solve did not converge: why, and what the step control may try (a
        preconditioner for a static stiffness, projected Hessians, or no halving: _nominal_step)."""
        name = self.solver.reason_name(reason)
        ksp = self.solver.ksp_reason_name() if name == "DIVERGED_LINEAR_SOLVE" else ""
        stats["why"] = (f"SNES did not converge ({name}{': KSP ' + ksp if ksp else ''}) after "
                        f"{stats['newton_its']} Newton iterations")
        # a Krylov solve that ran out of iterations on a quasi-static step: a preconditioner for a static
        # stiffness may fix it (Solver.escalate); halving the step may not (the caller)
        stats["linear_only"] = self.scene.quasistatic and ksp in RAN_OUT
        # most Newton directions from CG stopped at negative curvature: the tangent is indefinite (Solver.project_hessians)
        stats["indefinite"] = self.scene.quasistatic and indefinite > 0.5 * max(stats["newton_its"], 1)
        stats["moves_prescribed"] = self.system.moves_prescribed(self.x)
        hints = self.solver.plan.ksp_hints or KSP_HINTS
        stats["hint"] = hints.get(ksp, "") if ksp else SNES_HINTS.get(name, "")
        if ksp in RAN_OUT and self.solver.snes.getKSP().getPC().getType() == "gamg":
            stats["hint"] = "a larger -ksp_max_it"
        return self._rejected(stats, w0)

    def _refused(self, h, t1, c0, w0):
        """The stats row of an attempt refused before its solve, or None with Newton's start in self.X
        (_initial_guess): where the held nodes meet each other or an obstacle along the step (Starts.held_collision;
        the run stops where every prescribed path is straight in t: no smaller step helps), or no start is free of
        contact."""
        blocked = self.system.starts.held_collision(self.x, self.t, t1)
        if blocked is not None:
            why, certain = blocked
            if certain:
                self._fail(f"step {self.step + 1} (t={t1:.6g}, h={h:.3g})", why + " (no smaller step helps: the "
                           "scene passes them through each other)")
            why += " along the step's straight move"
        elif not self._initial_guess(h):
            held = " with the held nodes at their targets" if self.system.moves_prescribed(self.x) else ""
            what = self.system.starts.crossing(self.system.impose(self.x.copy())) or "contact is crossed"
            why = (f"no start of the step is free of contact (from the last state{held}, or with the nodes that moving "
                   f"obstacles reach pushed ahead of them where that fits the cells beside them): {what}")
        else:
            return None
        stats = {"step": self.step + 1, "time": t1, "dt": h, "snes_reason": 0, "newton_its": 0, "ksp_its": 0,
                 "rejected": 1, "why": why}
        stats.update(self._counter_stats(c0))
        return self._rejected(stats, w0)

    def _initial_guess(self, h):
        """Newton's start in self.X: the explicit predictor x^n + h v^n with the step's boundary
        positions. Where the material is undefined when inverted and that start inverts cells (fast
        prescribed ends outrunning their neighbours' predicted motion), the previous positions x^n
        instead, if they do not (the residual there is defined, so Newton can start). A quasi-static step
        that moves prescribed nodes starts from x^n + h r^n, r^n the last accepted step's rate (the interior carried
        along with its boundary, as the last step moved it: the first iterate no longer puts the whole boundary
        increment into the layer of cells beside them, issue 47), or, where there is no rate yet (the first step),
        from the linearized answer to the boundary's increment (_linearized_guess); other quasi-static steps from x^n.
        Where obstacles move (contact), the step's start must not lie inside one: the rate's start, else (and in
        dynamics after x^n + h v^n) the start with the nodes an obstacle reached pushed ahead of it
        (Starts.pushed); a start that is still infeasible is refused and the step retried shorter. False
        where no start is free of contact (x^n with the held nodes at their targets crosses the contact surface)."""
        sysm = self.system
        self.guess_ksp = 0
        # (every condition the same on every rank: defined_at is collective)
        if self.scene.quasistatic:
            guesses = []
            moving = sysm.starts.moving             # (moving obstacles: the body carried along as the last step did)
            if moving or sysm.moves_prescribed(self.x):
                if self.sp.mpi.allreduce(bool(self.rate.any()), op=MPI.LOR):
                    guesses = [self.x + h * self.rate]
                if moving:         # (the rate's start with the nodes it leaves in reach pushed, then x^n's pushed)
                    guesses += [g for g in [sysm.starts.pushed(s, self.x) for s in guesses[:1] + [self.x]]
                                if g is not None]
                elif not guesses and not all(e.linear for e in sysm.effects) and self._linearized_guess():
                    guesses = [None]           # (in self.X already; a linear problem's first iterate is the same solve)
                elif guesses and sysm.starts.checks:
                    # (contact: where the rate's start is refused — it carries a body through a face it has just met —
                    # the linearized answer, whose tangent at x^n holds the pairs' barrier; computed only then)
                    guesses.append(self._linearized_guess)
        else:
            guesses = [self.x + h * self.v] if self.sp.mpi.allreduce(bool(self.v.any()), op=MPI.LOR) else []
            if sysm.starts.moving:
                guesses += [g for g in [sysm.starts.pushed(guesses[0] if guesses else self.x)] if g is not None]
        for guess in guesses + [self.x]:
            if callable(guess):
                if not guess():
                    continue
            elif guess is not None:
                sysm.set_guess(self.X, guess)
            if guess is self.x:            # (the last resort: the material may be undefined there, contact may not)
                return not sysm.starts.checks or sysm.starts.free(sysm.impose(self.x.copy()))
            if not sysm.check_domain or sysm.defined_at(self.X):
                return True

    # the central difference of the residual in the held targets: this fraction of the part's size, moved by the
    # largest increment
    LINEARIZED_STEP = 1e-6

    def _linearized_guess(self):
        """self.X = x^n + d, d the held dofs' increment g - x^n_c carried into the interior by the tangent at x^n:
        J_ff d_f = -J_fc d_c (J_fc d_c by a central difference of the residual in the held targets; the mixed
        formulation's pressure follows too). On the rod's first 11.25-degree step at 7,725 P2 tets the first Newton
        iterate from x^n with only the boundary moved failed its Krylov solve twice (3,000 GMRES iterations, 80 s);
        this solve is at the undistorted x^n. False (self.X untouched) where its Krylov solve fails."""
        sysm, sp = self.system, self.sp
        c = sysm.cdofs
        g = sysm.g[c].copy()
        xc = self.x[c]
        d = g - xc
        dmax = sp.mpi.allreduce(float(np.abs(d).max(initial=0.0)), op=MPI.MAX)
        lo, hi = sp.bbox
        X0 = sysm.unknown_vec()
        try:
            sysm.set_held(xc)
            sysm.set_guess(X0, self.x)
            Z, self.guess_ksp, ok = self.solver.held_response(
                X0, lambda s: sysm.set_held(xc + s * d), self.LINEARIZED_STEP * float(np.linalg.norm(hi - lo)) / dmax)
        finally:
            sysm.set_held(g)
        if not ok:
            return False
        X0.axpy(1.0, Z)
        Z.destroy()
        sysm.impose_global(X0)
        X0.copy(self.X)
        X0.destroy()
        return True

    def _rejected(self, stats, w0):
        stats["wall_s"] = time.perf_counter() - w0
        return stats
