"""Dynamics through PETSc TS (-integrator ts): the second-order form
    F(t, x, v, a) = M a + C v + k(x) - f(t) = 0,   dF/dx + shift_v dF/dv + shift_a dF/da = K + shift_v C + shift_a M
registered with TSSetI2Function / TSSetI2Jacobian and integrated by TSALPHA2, the generalized-alpha
method for second-order systems (Chung & Hulbert 1993; -ts_alpha_radius rho_inf, -ts_alpha_alpha_m ...),
with PETSc's step adaptors (-ts_adapt_type none|basic|dsp, -ts_rtol, -ts_atol, -ts_adapt_monitor).

The same effects (effects/base.py: order 0, 1 and 2 terms), Jacobian modes, MFFD options and Dirichlet
elimination as backward Euler (system.residual_rates); the TS's own SNES and KSP read the usual options.
The run is stepped here, one TSStep at a time, so that frames land on their times, statistics rows
(rejected attempts included) are written, checkpoints and signals work as in backward Euler.

TSALPHA2 starts (and restarts) from (x, v) by estimating the acceleration with two backward Euler half
steps; it keeps the acceleration internally, with no call to read or set it. So a checkpoint stores
(x, v, t, h), and every -checkpoint_every checkpoint is also a TSRestartStep of the uninterrupted run:
a restart from it repeats exactly what the run did (bitwise on the same rank count). A stop by
SIGINT/SIGTERM between checkpoints restarts the acceleration estimate there, which the uninterrupted
run did not: the continued run then agrees with it to the integrator's accuracy, not bitwise.
"""
import ctypes
import math
import time

from petsc4py import PETSc

from ..core.errors import UserError
from .integrators import Integrator, step_count
from ..core.libpetsc import alpha2_params, evaluate_wlte, lib, set_function_domain_error
from .solver import enum_name

STARTUP = (1.0, 1.0, 1.0, 0.5)   # TSALPHA2's parameters during its starting backward Euler half steps
_POST_STAGE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_int32,
                               ctypes.c_void_p)


def apply_defaults():
    """This application's TS defaults, where the options database does not set them: generalized-alpha;
    a failed Newton solve is an ordinary rejected step (retried smaller) rather than the end of the run;
    at most 20 rejected attempts per step."""
    opts = PETSc.Options()
    for k, v in (("ts_type", "alpha2"), ("ts_max_snes_failures", "-1"), ("ts_max_step_rejections", "20")):
        if not opts.hasName(k):
            opts.setValue(k, v)


def make_ts(comm):
    """The TS of a run (before the Solver, which configures its SNES)."""
    apply_defaults()
    ts = PETSc.TS().create(comm=comm)
    ts.setType(PETSc.Options().getString("ts_type"))
    if ts.getType() != "alpha2":
        raise UserError(f"option -ts_type: '{ts.getType()}' is not supported (-integrator ts integrates the "
                        "second-order form with alpha2)")
    return ts


def check_energy_momentum(ts, scene):
    """-energy_momentum modifies the midpoint rule only: TSALPHA2 at rho_inf = 1."""
    p = alpha2_params(ts)
    if scene.energy_momentum and max(abs(a - b) for a, b in zip(p, (0.5, 0.5, 0.5, 0.25))) > 1e-12:
        raise UserError("option -energy_momentum: needs the midpoint rule, -ts_alpha_radius 1 (alpha_m = alpha_f "
                        "= gamma = 1/2, beta = 1/4); this run has alpha_m, alpha_f, gamma, beta = "
                        + ", ".join(f"{a:g}" for a in p))


class GeneralizedAlpha(Integrator):
    def __init__(self, scene, system, solver, writer, x0, v0, ts, checkpoint=None, quiet=False):
        super().__init__(scene, system, solver, writer, x0, v0, quiet)
        sp = self.sp
        self.ts = ts
        self.snes = ts.getSNES()
        self.stage_key = None
        self.shifts = (0.0, 0.0)
        self.attempts = []                   # SNES solves of the current TSStep (_post_stage)
        self.c_last = self._counters()
        self.w_last = time.perf_counter()
        self.h_try = scene.dt
        ts.setI2Function(self._function, sp.global_vec())
        if system.starts.checks:
            self.snes.setInitialGuess(self._initial_guess)
        if solver.op is not None:
            ts.setI2Jacobian(self._jacobian, solver.op.operator, solver.op.mat)
        ts.setTimeStep(scene.dt)
        ts.setMaxTime(scene.final_time)
        ts.setExactFinalTime(PETSc.TS.ExactFinalTime.MATCHSTEP)
        ts.setStepLimits(scene.dt_min, max(scene.final_time, scene.dt))
        ts.setErrorIfStepFails(False)
        ts.setFromOptions()
        solver.plan.configure(solver)       # the PC's structure (p-multigrid's levels) once its type is read
        if solver.levels is not None:       # PCMG restricts the TS's state through the DMs (pmg.Levels.shell)
            ts.getDM().setGlobalVector(sp.global_vec())
        system.energy_momentum = scene.energy_momentum     # (its parameters checked by cli.run)
        opts = PETSc.Options()
        self.adaptive = opts.getString("ts_adapt_type", "none") != "none"
        self.wnorm = opts.getString("ts_adapt_wnormtype", "2")
        self._callback = _POST_STAGE(self._post_stage)      # kept alive as long as the TS
        lib().TSSetPostStage.argtypes = [ctypes.c_void_p, _POST_STAGE]
        err = lib().TSSetPostStage(ctypes.c_void_p(ts.handle), self._callback)
        if err:
            raise RuntimeError(f"TSSetPostStage failed ({err})")
        if checkpoint is not None:
            self._resume(checkpoint)
        self.U = sp.global_vec()
        self.U.getArray()[:] = sp.owned_array(self.x)      # the state as TS had it (constrained dofs too)
        self.V = sp.global_vec()
        self.V.getArray()[:] = sp.owned_array(self.v)
        ts.setTime(self.t)
        ts.setStepNumber(self.step)
        ts.setSolution2(self.U, self.V)
        ts.setUp()

    # --- the second-order form ------------------------------------------------------------------
    def _stage(self, ts, t):
        """Loads, constrained targets and Jacobian weights of the stage at time t of the current attempt."""
        h = ts.getTimeStep()
        p = alpha2_params(ts)
        key = (t, h, p)
        if key == self.stage_key:
            return
        self.stage_key = key
        am, af, gamma, beta = p
        t1 = t + (1.0 - af) * h               # the end of the step (stage time t = t_n + alpha_f h)
        self.system.begin_stage(t, t1, h, self.x, self.v, af)
        self.shifts = (gamma / (h * beta), am / (af * h * h * beta))   # dV/dX1, dA/dX1 over alpha_f (as TSALPHA2)
        self.system.set_rate_weights(*self.shifts)

    def _initial_guess(self, snes, X):
        """TSALPHA2's predictor for the step's end, unless it lies in or through an obstacle or the contact surface
        (contact's undefined_at, on some rank): then the step's start (from which the pre-check's collision-free
        steps go)."""
        if not self.system.starts.free(self.system.local(X, self.system.xl).copy()):
            X.getArray()[:] = self.sp.owned_array(self.x)

    def _function(self, ts, t, U, V, A, R):
        self._stage(ts, t)
        self.system.residual_rates(U, V, A, R, *self.shifts)
        if self.system.undefined_cells():
            set_function_domain_error(self.snes)

    def _jacobian(self, ts, t, U, V, A, shift_v, shift_a, J, P):
        self._stage(ts, t)
        self.system.set_rate_weights(shift_v, shift_a)
        self.system.linearize(U)
        self.solver.refresh_operator(P)
        if J.handle != self.solver.op.operator.handle:
            J.assemble()   # MFFD operator (-snes_mf_operator): new base point

    def _post_stage(self, ts_handle, t, stage, y):
        """After every SNES solve of a step (TSPostStage): one attempt's figures."""
        try:
            snes = self.snes
            reason = snes.getConvergedReason()
            row = {"dt": self.ts.getTimeStep(), "stage_time": t, "startup": alpha2_params(self.ts) == STARTUP,
                   "snes_reason": int(reason), "newton_its": snes.getIterationNumber(),
                   "ksp_its": snes.getLinearSolveIterations(), **self._counter_stats(self.c_last),
                   "wall_s": time.perf_counter() - self.w_last}
            if self.adaptive and not row["startup"] and not any(a.get("startup") for a in self.attempts):
                # the adaptor's estimate, as it is about to compute it (after the step, TSALPHA2 would
                # use the next step's size); not in a (re)starting step, where evaluating it changes it
                wlte = evaluate_wlte(self.ts, self.wnorm) if reason > 0 else -1.0
                row["error_estimate"] = wlte if wlte >= 0 else math.nan
            if reason <= 0:
                name = self.solver.reason_name(reason)
                if name == "DIVERGED_LINEAR_SOLVE":
                    name += f": KSP {self.solver.ksp_reason_name()}"
                row["why"] = f"SNES did not converge ({name}) after {row['newton_its']} Newton iterations"
            self.attempts.append(row)
            self.c_last, self.w_last = self._counters(), time.perf_counter()
        except Exception as e:          # an exception cannot cross the C callback: keep it for step()
            self.attempts.append({"error": e})
        return 0

    # --- stepping -----------------------------------------------------------------------------
    def run(self):
        """TSSteps until -final_time. Frames every round(1/(fps dt)) dt as in backward Euler: a step that
        would pass a frame time is shortened to end on it. Without an adaptor the step is -dt, shortened
        by PETSc after a failed solve and grown back (doubling) after -dt_grow_after accepted steps."""
        sc, sysm = self.scene, self.system
        every = max(1, int(round(1.0 / (sc.fps * sc.dt))))
        period = every * sc.dt
        nsteps = None if self.adaptive else step_count(sc.final_time, sc.dt)
        if self.writer and self.n0 == 0 and self.step == 0:
            sysm.begin_step(0.0, sc.dt, self.x, self.v)
            self.writer.frame(0.0, sysm.impose(self.x.copy()), self.v)
        t_start = time.perf_counter()
        progress = {"last_print": t_start}
        eps = 1e-9 * sc.dt
        while self.t < sc.final_time - eps:
            nxt = min((math.floor(self.t / period + 1e-6) + 1) * period, sc.final_time)   # the next frame time
            h = min(self.h_try, nxt - self.t)
            if nxt - (self.t + h) < eps:
                h = nxt - self.t                 # end on the frame time exactly
            stats = self._step(h, nxt)
            framed = abs(self.t - nxt) <= eps or self.t >= sc.final_time - eps
            if self._output(self.step, framed, self.t >= sc.final_time - eps, x_frame=self.x_out):
                self.ts.restartStep()            # a checkpoint is where a restart begins (module doc)
            self._progress(progress, self.step - 1, nsteps, stats, t_start, force=self.t >= sc.final_time - eps)
        return self

    def _step(self, h, t_frame=None):
        """One TSStep of (at most) size h: a stats row per attempt; the state moves to its end (t_frame where the step
        ends there to TS's rounding: a frame's time exact, not summed)."""
        sysm, ts = self.system, self.ts
        ts.setTimeStep(h)
        self.attempts = []
        self.c_last, self.w_last = self._counters(), time.perf_counter()
        t0, x0, v0 = self.t, self.x, self.v
        self.stages["Step"].push()
        try:
            ts.step()
        finally:
            self.stages["Step"].pop()
        errors = [a["error"] for a in self.attempts if "error" in a]
        if errors:
            raise errors[0]
        rows, startup = self._attempt_rows(t0)
        if ts.getConvergedReason() < 0 or not rows:
            self._fail_step(rows, startup, t0, h)
        for row, why in rows[:-1]:
            self._say(f"t={t0:.4g}: step of h={row['dt']:.3g} rejected: {why}")
            self._write_stats(row)
        self.rejections += len(rows) - 1
        row = rows[-1][0]
        if t_frame is not None and abs(ts.getTime() - t_frame) <= 1e-12 * max(1.0, abs(t_frame)):
            ts.setTime(t_frame)
        self.t = ts.getTime()
        row["time"] = self.t
        U, V = ts.getSolution2()
        x_raw, v1 = sysm.local(U, sysm.xl).copy(), sysm.local(V, sysm.vl).copy()
        sysm.begin_step(self.t, row["dt"], x0, v0)        # loads and constrained positions at the step's end
        x1 = sysm.impose(x_raw.copy())
        if not self._energy_stats(x1, v1, row, self.t):
            self._write_stats(row)
            self._fail(f"step {self.step + 1} (t={self.t:.6g}, h={row['dt']:.3g})",
                       "non-finite positions or energies after a converged solve")
        row["dt_next"] = ts.getTimeStep()
        self._write_stats(row)
        sysm.accept_step(x1, row["dt"])
        self.x, self.v = x_raw, v1
        self.x_out = x1
        self.step += 1
        self._next_h(len(rows) > 1, row["dt_next"], h)
        return row

    def _attempt_rows(self, t0):
        """([(stats row, why rejected)] of the step's attempts, the last one accepted unless the step
        failed; the starting half steps' attempts, whose counts go into the first row)."""
        failed = self.ts.getConvergedReason() < 0
        startup = [a for a in self.attempts if a["startup"]]
        tries = [a for a in self.attempts if not a["startup"]]
        for a in startup:                     # the starting half steps are part of the step that follows
            if tries:
                for k, v in a.items():
                    if k not in ("dt", "stage_time", "startup", "snes_reason", "why") and k in tries[0]:
                        tries[0][k] += v
        rows = []
        for i, a in enumerate(tries):
            accepted = i == len(tries) - 1 and not failed
            row = {k: v for k, v in a.items() if k not in ("stage_time", "startup", "why")}
            if "error_estimate" in a and not accepted and "why" not in a:
                a["why"] = f"the error estimate {a['error_estimate']:.3g} exceeds 1 (TS adaptor)"
            row.update({"step": self.step + 1, "time": t0 + a["dt"], "rejected": 0 if accepted else 1})
            rows.append((row, a.get("why", "the error estimate exceeds the tolerance (TS adaptor)")))
        return rows, startup

    def _fail_step(self, rows, startup, t0, h):
        """A step TS could not complete: its attempts' rows, then the one-line SolveError."""
        for row, why in rows:
            self._write_stats(row)
        self.rejections += len(rows)
        reason = self.ts.getConvergedReason()
        why = rows[-1][1] if rows else startup[-1].get("why", "?") + " (starting half step)" if startup else "?"
        self._fail(f"step {self.step + 1} (t={t0:.6g}, h={h:.3g})",
                   f"TS {enum_name(PETSc.TS.ConvergedReason, reason)} after {len(rows)} attempts; last: {why}")

    def _next_h(self, rejected, proposed, h):
        """The next step's size: the adaptor's proposal; without an adaptor -dt, or after rejections the
        size PETSc reduced to, doubled back toward -dt after -dt_grow_after accepted steps."""
        sc = self.scene
        if self.adaptive:
            self.h_try = proposed
            return
        if rejected:
            self.h_try, self.streak = proposed, 0
            return
        self.streak += 1
        if self.h_try < sc.dt and self.streak >= sc.dt_grow_after:
            self.h_try, self.streak = min(2 * self.h_try, sc.dt), 0
