"""A Prony series fitted to a relaxation test (`hyperelastic fit DATA.csv --prony N`): the viscoelastic effect's
-prony_beta and -prony_tau.

The effect (physics/effects/viscoelastic.py) relaxes the isochoric stress with the modulus mu (1 + sum_i b_i
exp(-t/tau_i)), mu the material's long-term one. A relaxation test holds one stretch from the end of its loading ramp
on; for an incompressible solid in a homogeneous test the nominal stress is then the long-term one P_inf times a
function of time alone (every isochoric stress scales alike; the pressure is the free direction's):
  a step (--ramp 0):          P(t) = P_inf (1 + sum_i b_i exp(-t/tau_i))
  a ramp of t_r at constant rate, the isochoric stress linear in time over it (small strains, or the effect's own
  update over one step of t_r):
                              P(t) = P_inf (1 + sum_i b_i (tau_i/t_r)(1 - exp(-t_r/tau_i)) exp(-(t - t_r)/tau_i)),
for t >= t_r (Simo 1987's convolution integral with a linear S_iso; Holzapfel 2000, sec. 6.10). The fit: least squares
of the relative error P_model / P_data - 1 (each point's by its weight) in P_inf, b_i >= 0 and log tau_i, started from
the b_i and P_inf that non-negative least squares gives for relaxation times spaced evenly in log time over the data;
the times are then sorted. The long-term stress P_inf is reported beside the fitted elastic model's stress at the held
stretch (the material's constants are the long-term ones: fit them to slow tests, or to the relaxed ends)."""
import math

import numpy as np

from ..core.errors import UserError

MAX_TERMS = 4          # as the effect takes (viscoelastic.MAX_TERMS)


def decay(t, tau, ramp):
    """(n, N): each term's share of its modulus at times t (a step: exp(-t/tau); a ramp of `ramp`: its closed form)."""
    t, tau = np.asarray(t, dtype=float)[:, None], np.asarray(tau, dtype=float)[None, :]
    if ramp == 0:
        return np.exp(-t / tau)
    x = ramp / tau
    return (-np.expm1(-x) / x) * np.exp(-(t - ramp) / tau)


class PronyFit:
    """A Prony series of N terms fitted to a relaxation curve (time, stress, weight, held stretch, mode)."""

    def __init__(self, curve, terms, ramp=0.0):
        self.t, self.P, self.w, self.stretch, self.mode = curve
        self.terms, self.ramp = terms, ramp
        if not 1 <= terms <= MAX_TERMS:
            raise UserError(f"fit: --prony {terms}: 1 to {MAX_TERMS} terms (the viscoelastic effect takes up to "
                            f"{MAX_TERMS})")
        if not (math.isfinite(ramp) and ramp >= 0):
            raise UserError(f"fit: --ramp {ramp:g} must be a time >= 0 (seconds: 0 for a step)")
        if self.t[0] < ramp:
            raise UserError(f"fit: the relaxation curve starts at time {self.t[0]:g}, inside the loading ramp of "
                            f"{ramp:g} s (give the held part: times from --ramp on)")
        if len(self.t) <= 2 * terms + 1:
            raise UserError(f"fit: {len(self.t)} relaxation points for {terms} Prony terms' {2 * terms + 1} constants "
                            "(it needs more points than constants)")
        self.beta, self.tau, self.P_inf = self._solve()

    def model(self, t, beta=None, tau=None, P_inf=None):
        beta = self.beta if beta is None else beta
        return (self.P_inf if P_inf is None else P_inf) * (1 + decay(t, self.tau if tau is None else tau,
                                                                      self.ramp) @ np.asarray(beta))

    def _unpack(self, z):
        n = self.terms
        return z[1:1 + n], np.exp(z[1 + n:]), self.scale * z[0]

    def _residuals(self, z):
        beta, tau, P_inf = self._unpack(z)
        return np.sqrt(self.w) * (self.model(self.t, beta, tau, P_inf) / self.P - 1)

    def _start(self, tau):
        """(P_inf, b) of relaxation times tau by non-negative least squares of the relative error: P / P_data =
        P_inf + sum_i (P_inf b_i) r_i / P_data, linear in P_inf and P_inf b_i."""
        from scipy.optimize import nnls
        sw = np.sqrt(self.w)
        A = np.column_stack([np.ones_like(self.t), decay(self.t, tau, self.ramp)]) / np.abs(self.P)[:, None]
        c, _ = nnls(A * sw[:, None], sw * np.sign(self.P))
        P_inf = math.copysign(max(c[0], 1e-300), self.P[0])
        return P_inf, c[1:] / abs(P_inf)

    def _solve(self):
        from scipy.optimize import least_squares     # deferred: only `fit` needs scipy
        n = self.terms
        elapsed = self.t - self.ramp
        first = elapsed[elapsed > 0].min() if (elapsed > 0).any() else 1.0
        last = max(elapsed[-1], first)
        lo_tau, hi_tau = first / 10, 10 * last
        a = max(first, last / 1e3)
        tau0 = np.geomspace(a, max(last / 2, 4 * a), n + 2)[1:-1]     # spaced evenly in log time within the data
        P0, b0 = self._start(tau0)
        self.scale = abs(P0)
        z0 = np.concatenate([[math.copysign(1.0, P0)], b0, np.log(tau0)])
        lo = np.concatenate([[-np.inf], np.zeros(n), np.full(n, math.log(lo_tau))])
        hi = np.concatenate([[np.inf], np.full(n, np.inf), np.full(n, math.log(hi_tau))])
        res = least_squares(self._residuals, np.clip(z0, lo, hi), bounds=(lo, hi), method="trf", x_scale="jac",
                            ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=20000)
        beta, tau, P_inf = self._unpack(res.x)
        order = np.argsort(tau)
        return beta[order], tau[order], float(P_inf)

    def errors(self):
        """(rms, max, time at max) of the relative errors."""
        e = np.abs(self.model(self.t) / self.P - 1)
        k = int(np.argmax(e))
        return float(np.sqrt(np.mean(e ** 2))), float(e[k]), float(self.t[k])

    def describe(self, elastic=None):
        """The report's lines; `elastic` a fitted elastic model (studies.fit.Fit) to compare the long-term stress
        with."""
        rms, mx, at = self.errors()
        how = "a step" if self.ramp == 0 else f"a ramp of {self.ramp:g} s"
        lines = [f"fit: a Prony series of {self.terms} term(s) to {len(self.t)} relaxation points ({self.mode}, "
                 f"stretch {self.stretch:g} held after {how})",
                 "  " + ", ".join(f"b{i + 1} {b:.6g} tau{i + 1} {t:.6g} s" for i, (b, t) in
                                  enumerate(zip(self.beta, self.tau))),
                 f"  long-term stress {self.P_inf:.6g} Pa; instantaneous modulus / long-term 1 + sum b = "
                 f"{1 + self.beta.sum():.6g}",
                 f"  relaxation relative error: rms {100 * rms:.3g}%, max {100 * mx:.3g}% (at time {at:.4g} s)"]
        if elastic is not None:
            Pm = float(elastic.model(self.mode, np.array([self.stretch]))[0])
            lines.append(f"  the fitted {elastic.name}'s {self.mode} stress at stretch {self.stretch:g}: {Pm:.6g} Pa, "
                         f"{100 * (Pm / self.P_inf - 1):+.3g}% from the long-term stress (its constants act as the "
                         "long-term ones)")
        return lines

    def option_lines(self):
        return [f"-prony_beta {','.join(repr(float(b)) for b in self.beta)}",
                f"-prony_tau {','.join(repr(float(t)) for t in self.tau)}"]

    def draw(self, ax):
        ax.plot(self.t, self.P / 1e6, "o", ms=4, label=f"{self.mode} relaxation (data)")
        grid = np.geomspace(max(self.t[0], self.t[self.t > 0].min() if (self.t > 0).any() else 1.0), self.t[-1], 200)
        ax.plot(grid, self.model(grid) / 1e6, "-", label=f"Prony, {self.terms} term(s)")
        ax.axhline(self.P_inf / 1e6, color="k", lw=0.6, ls="--", label="long-term")
        ax.set_xscale("log")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("nominal stress [MPa]")
        ax.set_title(", ".join(f"b{i + 1} {b:.3g} τ{i + 1} {t:.3g} s" for i, (b, t) in
                               enumerate(zip(self.beta, self.tau))), fontsize=9)
        ax.grid(alpha=0.3)
