"""`hyperelastic fit DATA.csv --model NAME`: a rubber model's constants from a laboratory's homogeneous tests.

The data: a CSV file with a header naming the columns `mode`, `stretch`, `stress` (and optionally `weight`), a row per
measured point: the test mode (uniaxial, equibiaxial, planar: planar tension, i.e. pure shear), the stretch lambda of
the loaded direction and the nominal stress (force per reference area) there. The tests are taken as incompressible
(Ogden, Non-linear Elastic Deformations, 1984, sec. 7.2): with the material's principal Kirchhoff stresses tau_i =
lambda_i dW/dlambda_i (`Material.principal_tau`) at lambda_1 = lambda and the mode's other stretches, the nominal stress
is (tau_1 - tau_f) / lambda, tau_f that of the stress-free direction (uniaxial lambda^-1/2, lambda^-1/2; equibiaxial
lambda, lambda^-2, planar 1, 1/lambda: the last one free).

The fit: least squares (scipy's trust-region reflective method, the parameters within their declared ranges and a
locking model's limit beyond the data) of the relative error P_model / P_data - 1 (Abaqus' choice: the small strains
count as much as the large; `--error absolute` for P_model - P_data), each point's weighted by its `weight`.

Drucker's stability (Abaqus, Analysis User's Guide, "Hyperelastic behavior of rubberlike materials"): the material is
stable where the work of every stress increment on its strain increment is positive, d sigma : d epsilon > 0. For an
incompressible isotropic material, with logarithmic strains e_1, e_2 (e_3 = -e_1 - e_2) and w(e_1, e_2) =
W(exp e_1, exp e_2, exp(-e_1 - e_2)), the pressure does no work on the isochoric increments and sigma_i - sigma_3 =
dw/de_i, so d sigma : d epsilon = de^T H de with H the Hessian of w: stable where H is positive definite. It is checked
along each mode's path (the Hessian by central differences of tau_i - tau_3, step 1e-6 in e) over a range of stretch,
and the first unstable stretch on each side of 1 is reported.

Writes an options file that `hyperelastic run SCENE -options_file FIT.opts` takes (the material, its fitted constants,
kappa = --bulk-ratio times the fitted small-strain shear modulus and the E and nu they give), and with --plot a PNG of
the fitted curves against the data."""
import csv
import math
import os
import sys

import numpy as np

from ..core.errors import ArgParser, UserError
from ..core.files import writable_dir
from ..physics import materials
from .prony import PronyFit

MODES = {"uniaxial": "uniaxial", "equibiaxial": "equibiaxial", "biaxial": "equibiaxial", "planar": "planar",
         "pure_shear": "planar", "planar_shear": "planar",
         # an equibiaxial test's stress along y (an anisotropic material's two axes differ: tissue's biaxial tests)
         "equibiaxial_y": "equibiaxial_y", "biaxial_y": "equibiaxial_y"}
RELAXATION = "_relaxation"     # a relaxation test: the stretch held from time 0 (or after --ramp), stress against time
MODES.update({"relaxation": "uniaxial" + RELAXATION,
              **{k + RELAXATION: v + RELAXATION for k, v in MODES.items()}})
ORDER = ("uniaxial", "equibiaxial", "planar", "equibiaxial_y")
STATES = ("uniaxial", "equibiaxial", "planar")         # the distinct states Drucker's check follows
UNITS = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6}
# the names `fit --model` takes beyond the fitted materials': (material, the parameters fitted; None: all it declares)
ALIASES = {"neohookean": ("neohookean_split", None),    # (the fit is of incompressible tests: the split model)
           **{f"ogden{n}": ("ogden", tuple(f"{k}{p}" for p in range(1, n + 1) for k in ("mu", "alpha")))
              for n in range(1, 6)}}
# the fit's start: a modulus over the data's small-strain one (its 'mu' and an invariant's 'C10', W' = mu/2), an
# exponent itself; Ogden's terms start from the shape of his fit of Treloar's rubber (Ogden 1972: mu_p = 0.63, 0.0012,
# -0.01 MPa over its mu = 0.4225 MPa, alpha_p = 1.3, 5, -2), one term from the neo-Hookean (alpha 2). A parameter not
# here starts at 0, a locking one at three times its limit.
START = {"mu": 1.0, "C10": 0.5, "mu1": 1.49, "alpha1": 1.3, "mu2": 0.0028, "alpha2": 5.0, "mu3": -0.0237,
         "alpha3": -2.0, "mu4": 0.01, "alpha4": 8.0, "mu5": -0.01, "alpha5": -4.0, "k1": 1.0, "k2": 1.0}
START_ONE_TERM = {"mu1": 1.0, "alpha1": 2.0}
BULK_RATIO = 1000.0      # kappa / mu of a rubber (~2 GPa against ~1 MPa: Treloar 1975, ch. 1; the rubber preset's)
STABILITY = (0.1, 10.0)  # the stretches the stability check covers by default (Abaqus': nominal strain -0.9 to 9)
DE = 1e-6                # the logarithmic-strain step of the stability check's Hessian
STABLE, UNSTABLE, LOCKED = 1, 0, -1
LATERAL_ITERATIONS, LATERAL_STEP = 60, 1e-6   # an anisotropic uniaxial test's lateral stretch: Newton, its FD step


def fitted_models():
    """The models `fit` takes: the materials declaring fitted parameters, in registry order, and the aliases."""
    return [n for n, m in materials.MATERIALS.items() if m.fitted] + list(ALIASES)


def resolve(name):
    """(material name, the names of its fitted parameters) of a model name."""
    if name not in fitted_models():
        raise UserError(f"fit: unknown model '{name}' (choose from {', '.join(fitted_models())})")
    material, names = ALIASES.get(name, (name, None))
    return material, names or materials.MATERIALS[material].fitted


def stretches(mode, lam):
    """The principal stretches (..., 3) of an incompressible homogeneous test at loaded stretch lam, the loaded
    direction first and a stress-free one last."""
    lam = np.asarray(lam, dtype=float)
    if mode == "uniaxial":
        return np.stack([lam, lam ** -0.5, lam ** -0.5], axis=-1)
    if mode in ("equibiaxial", "equibiaxial_y"):
        return np.stack([lam, lam, lam ** -2.0], axis=-1)
    return np.stack([lam, np.ones_like(lam), 1 / lam], axis=-1)


def nominal(material, values, mode, lam):
    """The nominal stress (force per reference area) of the test `mode` at stretch lam: (tau_i - tau_3) / lam along
    its loaded axis i (x; y for equibiaxial_y), the pressure being the free direction's tau_3."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        tau = material.principal_tau(test_stretches(material, values, mode, lam), values)
    i = 1 if mode == "equibiaxial_y" else 0
    return (tau[..., i] - tau[..., 2]) / np.asarray(lam, dtype=float)


def test_stretches(material, values, mode, lam):
    """The principal stretches of the test `mode` at stretch lam (stretches()), where an anisotropic material's
    uniaxial test has its lateral stretches solved for: lambda_2 with tau_2 = tau_3 (both faces free), lambda_3 =
    1/(lambda lambda_2), by Newton's iteration in ln lambda_2 (central differences) from the isotropic lambda^-1/2."""
    base = stretches(mode, lam)
    if not material.anisotropic or mode != "uniaxial":
        return base
    lam = np.asarray(lam, dtype=float)
    ln1, s = np.log(lam), -0.5 * np.log(lam)

    def g(s):
        tau = material.principal_tau(np.stack([lam, np.exp(s), np.exp(-ln1 - s)], axis=-1), values)
        return tau[..., 1] - tau[..., 2]
    for _ in range(LATERAL_ITERATIONS):
        r = g(s)
        d = (g(s + LATERAL_STEP) - g(s - LATERAL_STEP)) / (2 * LATERAL_STEP)
        step = np.where(np.abs(d) > 0, r / np.where(d != 0, d, 1.0), 0.0)
        s = s - np.clip(step, -0.5, 0.5)
        if np.all(np.abs(step) <= 1e-14):
            break
    return np.stack([lam, np.exp(s), np.exp(-ln1 - s)], axis=-1)


def read_data(path, unit="Pa"):
    """{mode: (stretch, stress [Pa], weight)} of a CSV file, and under "relaxation" (time, stress [Pa], weight, the
    held stretch, the test's mode) where it holds a relaxation curve; one UserError line for anything wrong in it."""
    where = f"fit: data '{path}'"
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise UserError(f"{where}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{where}: is a directory") from None
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise UserError(f"{where}: cannot be read as CSV text ({getattr(e, 'strerror', None) or e})") from None
    rows = [r for r in rows if any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise UserError(f"{where}: is empty (a header 'mode,stretch,stress[,weight][,time]' and a row per point)")
    head = [c.strip().lower() for c in rows[0]]
    for need in ("mode", "stretch", "stress"):
        if need not in head:
            raise UserError(f"{where}: its header has no column '{need}' (it needs mode, stretch, stress and may have "
                            f"weight and time; got {','.join(head)[:80]})")
    col = {c: head.index(c) for c in ("mode", "stretch", "stress", "weight", "time") if c in head}
    data = {}
    for line, r in enumerate(rows[1:], start=2):
        if len(r) < len(head):
            raise UserError(f"{where}, row {line}: {len(r)} columns where the header has {len(head)}")
        mode, lam, stress, weight, time = _row(r, col, f"{where}, row {line}")
        data.setdefault(mode, []).append((lam, stress * UNITS[unit], weight, time))
    if not data:
        raise UserError(f"{where}: holds a header and no points")
    out = {mode: _curve(np.array(data[mode])[:, :3], mode, where) for mode in ORDER if mode in data}
    relax = [m for m in data if m.endswith(RELAXATION)]
    if len(relax) > 1:
        raise UserError(f"{where}: relaxation curves of two modes ({relax[0]}, {relax[1]}): fit one relaxation test")
    if relax:
        out["relaxation"] = (*_relaxation_curve(np.array(data[relax[0]]), where), relax[0][:-len(RELAXATION)])
    return out


def _row(r, col, where):
    """(mode, stretch, stress, weight, time) of a data row (time NaN where the row is not a relaxation test's)."""
    word = r[col["mode"]].strip().lower()
    if word not in MODES:
        raise UserError(f"{where}: unknown mode '{word[:40]}' (choose from uniaxial, equibiaxial, equibiaxial_y, planar, "
                        "relaxation)")
    mode = MODES[word]
    vals = []
    for c in ("stretch", "stress", "weight", "time"):
        if c not in col or (c == "time" and not mode.endswith(RELAXATION)):
            if c == "time" and mode.endswith(RELAXATION):
                raise UserError(f"{where}: a {word} row needs a column 'time' (the seconds since loading began)")
            vals.append(1.0 if c == "weight" else math.nan)
            continue
        try:
            v = float(r[col[c]])
        except ValueError:
            raise UserError(f"{where}: {c} '{r[col[c]].strip()[:40]}' is not a number") from None
        if not math.isfinite(v):
            raise UserError(f"{where}: {c} {v} is not a finite number")
        vals.append(v)
    if vals[0] <= 0:
        raise UserError(f"{where}: stretch {vals[0]:g} must be > 0")
    if vals[2] < 0:
        raise UserError(f"{where}: weight {vals[2]:g} must be >= 0")
    if vals[3] < 0:
        raise UserError(f"{where}: time {vals[3]:g} must be >= 0 (seconds since loading began)")
    return (mode, *vals)


def _curve(a, mode, where):
    """(stretch, stress, weight) of a mode's rows a (n, 3): two or more, the stretches monotone."""
    if len(a) < 2:
        raise UserError(f"{where}: one {mode} point (a curve needs two or more)")
    d = np.diff(a[:, 0])
    if not ((d > 0).all() or (d < 0).all()):
        k = int(np.flatnonzero(np.sign(d) != np.sign(d[0]))[0]) if (d != 0).all() else int(np.flatnonzero(d == 0)[0])
        raise UserError(f"{where}: the {mode} stretches are not monotone (stretch {a[k + 1, 0]:g} after "
                        f"{a[k, 0]:g}): one loading curve per mode, in order")
    return a[:, 0], a[:, 1], a[:, 2]


def _relaxation_curve(a, where):
    """(time, stress, weight, the held stretch) of a relaxation test's rows a (n, 4: stretch, stress, weight, time):
    the times increasing, one stretch held, the stresses of one sign."""
    lam, P, w, t = a.T
    if len(a) < 3:
        raise UserError(f"{where}: {len(a)} relaxation point(s) (a relaxation curve needs three or more)")
    if not (np.diff(t) > 0).all():
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise UserError(f"{where}: the relaxation times are not increasing (time {t[k + 1]:g} after {t[k]:g})")
    if np.ptp(lam) > 1e-9 * lam[0]:
        raise UserError(f"{where}: the relaxation rows' stretches differ ({lam.min():g} to {lam.max():g}): a "
                        "relaxation test holds one stretch")
    if lam[0] == 1.0 or not ((P > 0).all() or (P < 0).all()) or (P > 0).all() != (lam[0] > 1):
        raise UserError(f"{where}: the relaxation stresses must all have the sign of the held strain (stretch "
                        f"{lam[0]:g}; stresses {P.min():g} to {P.max():g})")
    return t, P, w, float(lam[0])


def _scale_of(data):
    """A small-strain shear modulus from the data (the neo-Hookean one each point gives, their median): the scale of
    the moduli, and the fit's start."""
    est = []
    for mode, (lam, P, _) in data.items():
        k = nominal(materials.MATERIALS["neohookean_split"], {"mu": 1.0}, mode, lam)
        ok = np.abs(k) > 1e-12
        est += list(P[ok] / k[ok])
    mu = float(np.median(est)) if est else 0.0
    if not mu > 0:
        raise UserError("fit: the data do not describe a solid (the stresses' signs against the stretches give no "
                        "positive shear modulus)")
    return mu


class Fit:
    """A model fitted to data: its values (all parameters, kappa included), the errors per mode, stability."""

    def __init__(self, name, data, error="relative", bulk_ratio=BULK_RATIO, given=None):
        """given: {parameter: value} held at that value, not fitted (an anisotropic model's fibres, its dispersion)."""
        name, fitted = resolve(name)
        self.name, self.material, self.data, self.error = name, materials.MATERIALS[name], data, error
        self.npoints = sum(len(v[0]) for v in data.values())
        params = [p for p in self.material.parameters if p.name in fitted]
        if self.npoints <= len(params):
            raise UserError(f"fit: {self.npoints} points for {name}'s {len(params)} constants (it needs more points "
                            "than constants)")
        self.mu_data = _scale_of(data)
        self.params = params
        self.start = START_ONE_TERM if len(params) == 2 and name == "ogden" else START
        # the parameters not fitted (but kappa): their defaults (Ogden's terms beyond those fitted: off)
        self.fixed = dict(given or {})
        for p in self.material.parameters:
            if p not in params and p.name != "kappa" and p.name not in self.fixed:
                self.fixed[p.name] = p.default({"E": 3 * self.mu_data, "nu": 0.5 - 1e-9, **self.fixed})
        if self.material.anisotropic:
            self._check_axes()
        self.values = self._solve(bulk_ratio)

    def _check_axes(self):
        """An anisotropic model's fibres must leave the tests without shear: along the axes, or mirrored pairs."""
        probe = {**self.fixed, **{p.name: self._start(p, {}, self._scale(p)) * self._scale(p) for p in self.params}}
        lam = np.array([[1.3, 1 / 1.3 ** 0.5, 1 / 1.3 ** 0.5], [1.2, 1.1, 1 / 1.32]])
        shear = self.material.principal_shear(lam, probe)
        scale = np.abs(self.material.principal_tau(lam, probe)).max()
        if not (shear <= 1e-9 * scale).all():
            raise UserError(f"fit: {self.name}'s fibres as given shear the tests' homogeneous states: give them along "
                            "the axes (x the loaded one), or as a pair mirrored about them (e.g. --fibre1 c,s,0 "
                            "--fibre2 c,-s,0)")

    def _bounds(self):
        I1max = max(float(np.square(stretches(m, lam)).sum(axis=-1).max()) for m, (lam, _, _) in self.data.items())
        lo, hi, start = [], [], []
        limits = self.material.fit_limits(I1max)
        for p in self.params:
            scale = self._scale(p)
            low = max(p.minimum, limits.get(p.name, -math.inf))
            if p.exclusive or p.name in limits:
                low = low + max(abs(low), scale) * 1e-9 if math.isfinite(low) else low
            lo.append(low / scale)
            hi.append(math.inf)
            start.append(self._start(p, limits, scale))
        return np.array(lo), np.array(hi), np.array(start)

    def _start(self, p, limits, scale):
        """The start of parameter p (START; three times its limit for a locking one)."""
        if p.name in limits:
            return 3 * max(limits[p.name], 1.0)
        return self.start.get(p.name, 0.0)

    def _scale(self, p):
        """The unit the fit takes parameter p in: the data's modulus for a modulus (the least squares' variables of
        order 1), else 1."""
        return self.mu_data if p.unit == "Pa" else 1.0

    def _values(self, z):
        return {**self.fixed, **{p.name: float(zi) * self._scale(p) for p, zi in zip(self.params, z)}}

    def model(self, mode, lam, values=None):
        return nominal(self.material, self.values if values is None else values, mode, lam)

    def residuals(self, values):
        out = []
        for mode, (lam, P, w) in self.data.items():
            Pm = self.model(mode, lam, values)
            if self.error == "relative":
                ok = np.abs(P) > 1e-12 * max(abs(P).max(), self.mu_data)
                r = np.where(ok, Pm / np.where(ok, P, 1.0) - 1, (Pm - P) / self.mu_data)
            else:
                r = (Pm - P) / self.mu_data
            out.append(np.sqrt(w) * r)
        r = np.concatenate(out)
        return np.where(np.isfinite(r), r, 1e6)

    def _solve(self, bulk_ratio):
        from scipy.optimize import least_squares    # deferred: only `fit` needs scipy
        lo, hi, start = self._bounds()
        start = np.clip(start, lo, hi)
        res = least_squares(lambda z: self.residuals(self._values(z)), start, bounds=(lo, hi), method="trf",
                            x_scale="jac", ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=20000)
        values = self._values(res.x)
        values["kappa"] = 0.0
        mu0 = self.material.split(values)[1]           # (every fitted material has the split)
        if not mu0 > 0:
            raise UserError(f"fit: {self.name} fitted to a small-strain shear modulus {mu0:g} <= 0: the data do not "
                            "suit this model")
        values["kappa"] = bulk_ratio * mu0
        self.mu0 = mu0
        return values

    def mode_errors(self):
        """{mode: (rms, max, stretch at max)} of the relative errors (absolute ones over the data's modulus with
        --error absolute)."""
        out = {}
        for mode, (lam, P, _) in self.data.items():
            Pm = self.model(mode, lam)
            e = np.abs(Pm / P - 1) if self.error == "relative" and (P != 0).all() else np.abs(Pm - P) / self.mu_data
            k = int(np.argmax(e))
            out[mode] = (float(np.sqrt(np.mean(e ** 2))), float(e[k]), float(lam[k]))
        return out

    def hessian(self, mode, lam):
        """The Hessian (..., 2, 2) of w(e_1, e_2) at the mode's state of stretch lam (central differences of
        tau_i - tau_3 in the logarithmic strains)."""
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            ls = np.log(test_stretches(self.material, self.values, mode, lam))
            H = np.zeros(np.shape(lam) + (2, 2))
            for j in range(2):
                d = np.zeros(3)
                d[j], d[2] = DE, -DE
                gp = self._tau_diff(np.exp(ls + d))
                gm = self._tau_diff(np.exp(ls - d))
                H[..., :, j] = (gp - gm) / (2 * DE)
            return 0.5 * (H + np.swapaxes(H, -1, -2))

    def _tau_diff(self, ls):
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            t = self.material.principal_tau(ls, self.values)
        return t[..., :2] - t[..., 2:3]

    def state(self, mode, lam):
        """Per stretch: STABLE (H positive definite), UNSTABLE, or LOCKED (beyond a locking model's limit: undefined)."""
        H = self.hessian(mode, np.asarray(lam, dtype=float))
        locked = ~np.isfinite(H).all(axis=(-1, -2))
        ev = np.linalg.eigvalsh(np.where(locked[..., None, None], 0.0, H))[..., 0]
        return np.where(locked, LOCKED, np.where(ev > 0, STABLE, UNSTABLE))

    def stable(self, mode, lam):
        return self.state(mode, lam) == STABLE

    def stability(self, lo=STABILITY[0], hi=STABILITY[1], n=400):
        """{mode: ((lowest stable stretch, why it ends), (highest, why))} of the interval around 1 where the mode's
        states are stable, each end to 1e-4 relative; why: None where stable up to lo or hi, else UNSTABLE or
        LOCKED (what the next stretch is)."""
        out = {}
        for mode in STATES:
            ends = []
            for edge in (lo, hi):
                grid = np.geomspace(1.0, edge, n)[1:]
                st = self.state(mode, grid)
                if (st == STABLE).all():
                    ends.append((edge, None))
                    continue
                k = int(np.argmax(st != STABLE))
                a, b = (1.0 if k == 0 else grid[k - 1]), grid[k]     # stable at a, not at b
                while abs(b / a - 1) > 1e-4:
                    m = math.sqrt(a * b)
                    a, b = (m, b) if self.state(mode, m) == STABLE else (a, m)
                ends.append((a, int(self.state(mode, b))))
            out[mode] = tuple(ends)
        return out

    def option_lines(self):
        """The options file's lines: the material, its fitted constants, kappa, and the E and nu they give."""
        mu, kappa = self.mu0, self.values["kappa"]
        E, nu = 9 * kappa * mu / (3 * kappa + mu), (3 * kappa - 2 * mu) / (2 * (3 * kappa + mu))
        lines = [f"-material {self.name}"]
        lines += [f"-{p.name} {_option_value(self.values[p.name])}" for p in self.material.parameters  # (every digit:
                  if p.name != "kappa" and not _absent(self.values[p.name])]                      # the run's
        lines += [f"-kappa {float(kappa)!r}", f"-E {float(E)!r}", f"-nu {float(nu)!r}"]  # constants, the fit's)
        return lines


def _option_value(v):
    """A parameter's value as an option takes it: every digit; a vector x,y,z."""
    return ",".join(repr(float(x)) for x in v) if isinstance(v, (tuple, list)) else repr(float(v))


def _absent(v):
    """A vector parameter not given (NaN: e.g. hgo's second family)."""
    return isinstance(v, (tuple, list)) and any(math.isnan(x) for x in v)


def _describe(fit, stab, lo, hi):
    unit = {p.name: p.unit for p in fit.params}
    lines = [f"fit: {fit.name} to {fit.npoints} points (" + ", ".join(f"{len(v[0])} {m}" for m, v in fit.data.items())
             + f"; {fit.error} error)"]
    lines.append("  " + ", ".join(f"{p.name} {fit.values[p.name]:.6g}" + (" Pa" if unit[p.name] == "Pa" else "")
                                  for p in fit.params) + f"; small-strain shear modulus {fit.mu0:.6g} Pa")
    what = "relative error" if fit.error == "relative" else "error / modulus"
    for mode, (rms, mx, at) in fit.mode_errors().items():
        lines.append(f"  {mode:12s} {what}: rms {100 * rms:.3g}%, max {100 * mx:.3g}% (at stretch {at:.4g})")
    lines.append(f"  Drucker stability, stretch {lo:g} to {hi:g}:")
    why = {UNSTABLE: "unstable", LOCKED: fit.material.undefined_text}
    for mode, ((a, wa), (b, wb)) in stab.items():
        if wa is None and wb is None:
            lines.append(f"    {mode:12s} stable throughout")
            continue
        lines.append(f"    {mode:12s} stable from {a:.4g} to {b:.4g}" + (f"; {why[wa]} below {a:.4g}" if wa is not None else "")
                     + (f"; {why[wb]} above {b:.4g}" if wb is not None else ""))
    return lines


def _write_text(path, text):
    """Write path whole or not at all (a temporary beside it, then renamed over it)."""
    tmp = path + ".partial"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except OSError as e:
        raise UserError(f"fit: cannot write '{path}' ({e.strerror})") from None


def _check_out(path, data_path, suffix, option):
    if os.path.isdir(path):
        raise UserError(f"fit: {option} '{path}' is a directory")
    if os.path.realpath(path) == os.path.realpath(data_path):
        raise UserError(f"fit: {option} '{path}' would overwrite the data")
    if not path.lower().endswith(suffix):
        raise UserError(f"fit: {option} '{path}' must end in {suffix}")
    writable_dir(os.path.dirname(os.path.abspath(path)) or ".", f"fit: {option} '{path}'")


def plot(fit, prony, path):
    """A PNG of the fitted curves against the data (the unstable stretches of each curve crossed), the relaxation
    curve's fit beside them."""
    from ..output.figures import legend, pyplot
    plt = pyplot()
    panels = [p for p in (fit, prony) if p is not None]
    fig, axes = plt.subplots(1, len(panels), figsize=(6.4 * len(panels), 4.6), squeeze=False)
    if fit is not None:
        _draw(fit, axes[0, 0])
    if prony is not None:
        prony.draw(axes[0, -1])
    for ax in axes[0]:
        legend(ax, fontsize=8)
    fig.tight_layout()
    tmp = path + ".partial.png"
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)


def _draw(fit, ax):
    for i, (mode, (lam, P, _)) in enumerate(fit.data.items()):
        c = f"C{i}"
        ax.plot(lam, P / 1e6, "o", color=c, ms=4, label=f"{mode} (data)")
        grid = np.linspace(min(lam.min(), 1.0), lam.max(), 200)
        ax.plot(grid, fit.model(mode, grid) / 1e6, "-", color=c, label=f"{mode} ({fit.name})")
        ok = fit.stable(mode, grid)
        if not ok.all():
            ax.plot(grid[~ok], fit.model(mode, grid[~ok]) / 1e6, "x", color="k", ms=3)
    ax.set_xlabel("stretch λ")
    ax.set_ylabel("nominal stress [MPa]")
    ax.set_title(f"{fit.name}: " + ", ".join(f"{p.name} {fit.values[p.name]:.4g}" for p in fit.params), fontsize=9)
    ax.grid(alpha=0.3)


def _parser():
    ap = ArgParser(prog="hyperelastic fit", description="A rubber model's constants fitted to homogeneous tests "
                   "(uniaxial, equibiaxial, planar: nominal stress against stretch), with Drucker's stability.")
    ap.add_argument("data", help="CSV with a header: mode,stretch,stress[,weight][,time]")
    ap.add_argument("--model", default=None, help="one of: " + ", ".join(fitted_models()) + " (neohookean: "
                    "neohookean_split; ogdenN: ogden's first N terms, the others off); needed where the data hold "
                    "uniaxial, equibiaxial or planar curves")
    ap.add_argument("--prony", type=int, default=None, metavar="N", help="a Prony series of N terms (1 to 4) fitted "
                    "to the data's relaxation curve (rows of mode 'relaxation' with a 'time' column): the "
                    "viscoelastic effect's -prony_beta and -prony_tau")
    ap.add_argument("--fibre1", default=None, help="an anisotropic model's (hgo) first fibre family's direction x,y,z "
                    "in the tests' axes (x the loaded one), held, not fitted")
    ap.add_argument("--fibre2", default=None, help="its second family's (a mirror of the first about an axis)")
    ap.add_argument("--dispersion", type=float, default=None, help="hgo's fibre dispersion d, 0 to 1/3 (default 0), "
                    "held")
    ap.add_argument("--ramp", type=float, default=0.0, help="the relaxation test's loading time in seconds (its "
                    "stretch reached at a constant rate; default 0: a step)")
    ap.add_argument("-o", "--output", default=None, help="the options file to write (default: DATA_MODEL.opts)")
    ap.add_argument("--plot", default=None, help="a PNG of the fit against the data")
    ap.add_argument("--unit", choices=tuple(UNITS), default="Pa", help="the data's stress unit (default Pa)")
    ap.add_argument("--error", choices=("relative", "absolute"), default="relative")
    ap.add_argument("--bulk-ratio", type=float, default=BULK_RATIO, help="kappa / mu written to the options file "
                    f"(default {BULK_RATIO:g}: a rubber's)")
    ap.add_argument("--stability", default=f"{STABILITY[0]:g}:{STABILITY[1]:g}", help="the stretches LO:HI the "
                    "stability check covers (default 0.1:10)")
    return ap


def _range(text):
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise UserError(f"fit: --stability '{text}': give LO:HI, two numbers (e.g. 0.1:10)") from None
    if not (0 < lo < 1 < hi and math.isfinite(hi)):
        raise UserError(f"fit: --stability '{text}': needs 0 < LO < 1 < HI")
    return lo, hi


def _given(a):
    """The held values --fibre1, --fibre2, --dispersion give (an anisotropic model needs --fibre1; the others take
    none)."""
    material = materials.MATERIALS[resolve(a.model)[0]]
    given = {}
    for name in ("fibre1", "fibre2"):
        text = getattr(a, name)
        if text is None:
            continue
        try:
            v = tuple(float(x) for x in text.split(","))
        except ValueError:
            v = ()
        if len(v) != 3 or not all(math.isfinite(x) for x in v) or not any(v):
            raise UserError(f"fit: --{name} '{text}': three numbers x,y,z of a direction")
        given[name] = v
    if a.dispersion is not None:
        if not 0 <= a.dispersion <= 1 / 3:
            raise UserError(f"fit: --dispersion {a.dispersion:g} must be within 0 to 1/3")
        given["dispersion"] = a.dispersion
    if given and not material.anisotropic:
        raise UserError(f"fit: --{next(iter(given))} is for an anisotropic model (hgo), not {material.name}")
    if material.anisotropic and "fibre1" not in given:
        raise UserError(f"fit: --model {a.model} needs --fibre1 x,y,z (the fibres' direction in the tests' axes: x "
                        "the loaded one)")
    return given


def _check_parts(a, data, relax):
    """One line where the data and the models asked for do not go together."""
    if data and not a.model:
        raise UserError(f"fit: the data hold {', '.join(data)} curves: give --model (one of "
                        f"{', '.join(fitted_models())})")
    if a.model and not data:
        raise UserError(f"fit: --model {a.model}, but the data hold no uniaxial, equibiaxial or planar curve to fit it "
                        "to")
    if relax is not None and a.prony is None:
        raise UserError("fit: the data hold a relaxation curve: give --prony N (1 to 4 terms) to fit a Prony series "
                        "to it")
    if a.prony is not None and relax is None:
        raise UserError(f"fit: --prony {a.prony}, but the data hold no relaxation curve (rows of mode 'relaxation' "
                        "with a 'time' column)")


def main(argv):
    a = _parser().parse_args(argv)
    lo, hi = _range(a.stability)
    if not (math.isfinite(a.bulk_ratio) and a.bulk_ratio > 0):
        raise UserError(f"fit: --bulk-ratio {a.bulk_ratio:g} must be a positive number")
    model = resolve(a.model)[0] if a.model else "prony"
    out = a.output or os.path.splitext(a.data)[0] + f"_{model}.opts"
    _check_out(out, a.data, ".opts", "--output")
    if a.plot:
        _check_out(a.plot, a.data, ".png", "--plot")
    data = read_data(a.data, a.unit)
    relax = data.pop("relaxation", None)
    _check_parts(a, data, relax)
    fit = Fit(a.model, data, a.error, a.bulk_ratio, _given(a)) if a.model else None
    prony = PronyFit(relax, a.prony, a.ramp) if a.prony is not None else None
    lines, options = [], []
    if fit is not None:
        lines += _describe(fit, fit.stability(lo, hi), lo, hi)
        options += fit.option_lines()
    if prony is not None:
        lines += prony.describe(fit)
        options += prony.option_lines()
    print("\n".join(lines))
    head = ["# " + "hyperelastic fit " + " ".join(argv), *("# " + ln for ln in lines),
            "# (kappa: --bulk-ratio times the small-strain shear modulus; E and nu: the ones mu and kappa give)"]
    _write_text(out, "\n".join(head[:len(head) - (fit is None)] + options) + "\n")
    print(f"wrote {out} (hyperelastic run SCENE -options_file {out})")
    if a.plot:
        plot(fit, prony, a.plot)
        print(f"wrote {a.plot}")
    sys.stdout.flush()
    return 0
