"""Arruda and Boyce's eight-chain model and the inverse Langevin function it needs."""
import numpy as np

from ._i1 import IsochoricI1
from .base import BULK, Parameter, SHEAR

# L(x) = coth x - 1/x = sum_n C_n x^(2n-1), C_n = 2^(2n) B_2n / (2n)! (B_2n Bernoulli's numbers; Abramowitz & Stegun
# 4.5.67): below SERIES the first eight terms (the next one is < 1e-17 relative there), where coth x - 1/x loses
# digits; ln(sinh x / x) = sum_n C_n x^(2n) / (2n) (its integral)
SERIES = 0.3
LANGEVIN = (1 / 3, -1 / 45, 2 / 945, -1 / 4725, 2 / 93555, -1382 / 638512875, 4 / 18243225, -3617 / 162820783125)
# the inverse's Newton iterations in this reference (the C kernel stops at convergence: arruda_boyce.h)
NEWTON = 40
# lambda_m's default: Arruda and Boyce's own fit of Treloar's natural rubber (N = 26.5 chain segments: lambda_m =
# sqrt(N), Arruda & Boyce, J. Mech. Phys. Solids 41, 1993)
LAMBDA_M_DEFAULT = 26.5 ** 0.5


def _poly(x2, coef):
    out = np.zeros_like(x2)
    for c in coef[::-1]:
        out = out * x2 + c
    return out


def langevin(b):
    """(L(b), L'(b), ln(b / sinh b)) for b > 0 (arrays)."""
    b = np.asarray(b, dtype=float)
    x2 = b * b
    n = np.arange(1, len(LANGEVIN) + 1)
    series = (b * _poly(x2, LANGEVIN), _poly(x2, [c * (2 * k - 1) for c, k in zip(LANGEVIN, n)]),
              -x2 * _poly(x2, [c / (2 * k) for c, k in zip(LANGEVIN, n)]))
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        direct = (1 / np.tanh(b) - 1 / b, 1 / (b * b) - 1 / np.sinh(b) ** 2,
                  np.log(2 * b) - b - np.log1p(-np.exp(-2 * b)))
    small = b < SERIES
    return tuple(np.where(small, s, d) for s, d in zip(series, direct))


def inverse_langevin(r):
    """beta with L(beta) = r, 0 < r < 1 (NaN elsewhere): Newton's iteration from Cohen's Pade approximation r (3 - r^2)
    / (1 - r^2) (Rheol. Acta 30, 1991; within 5%). L is increasing and concave on b > 0, so from the first iterate on
    the iterates rise monotonically to the root."""
    r = np.asarray(r, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (r > 0) & (r < 1)
        rr = np.where(ok, r, 0.5)
        b = rr * (3 - rr * rr) / (1 - rr * rr)
        for _ in range(NEWTON):
            L, dL, _ = langevin(b)
            b = b - (L - rr) / dL
        return np.where(ok, b, np.nan)


class ArrudaBoyce(IsochoricI1):
    """Arruda and Boyce's eight-chain model (J. Mech. Phys. Solids 41, 1993), with the volumetric part U(J) = kappa/4
    (J^2 - 1 - 2 ln J) of neohookean_split: W(I1_bar) = mu_n lambda_m^2 (w(r) - w(1/lambda_m)), w(r) = r beta +
    ln(beta / sinh beta), beta = L^-1(r), r = lambda_c / lambda_m, the chain stretch lambda_c = sqrt(I1_bar / 3),
    L(b) = coth b - 1/b (Langevin's function). dw/dr = beta, so W' = mu_n lambda_m beta / (2 q), q = sqrt(3 I1_bar),
    and W'' = mu_n / (4 q^2) (1/L'(beta) - 3 lambda_m beta / q). The inverse Langevin function is evaluated to
    round-off (Newton's iteration), not by the five-term series Abaqus and FEBio use. The option -mu is the
    small-strain shear modulus mu = 2 W'(3) = mu_n lambda_m L^-1(1/lambda_m) / 3 = mu_n (1 + 3/(5 lambda_m^2) + ...),
    not the network's mu_n that Abaqus and FEBio take (their initial modulus mu_0 is this mu). Undefined for J <= 0 and
    at the locking stretch lambda_c >= lambda_m (I1_bar >= 3 lambda_m^2)."""
    name = "arruda_boyce"
    moduli = (0,)
    summary = "μ, λm, κ: eight-chain rubber network"
    references = "Arruda & Boyce, J. Mech. Phys. Solids 41, 1993"
    fitted = ("mu", "lambda_m")
    parameters = (
        SHEAR,
        Parameter("lambda_m", "-", "the chains' locking stretch (sqrt of the segments per chain)",
                  lambda v: LAMBDA_M_DEFAULT, f"{LAMBDA_M_DEFAULT:.4g} (√26.5)", minimum=1.0),
        BULK,
    )

    @staticmethod
    def constants(v):
        """(mu_n, lambda_m, the energy's reference value w(1/lambda_m), kappa): mu_n of the small-strain shear modulus
        mu = mu_n lambda_m L^-1(1/lambda_m) / 3."""
        lm = v["lambda_m"]
        b0 = float(inverse_langevin(1 / lm))
        return (3 * v["mu"] / (lm * b0), lm, float(b0 / lm + langevin(b0)[2]), v["kappa"])

    @staticmethod
    def w(I1b, c):
        mun, lm, w0 = c[0], c[1], c[2]
        I1b = np.asarray(I1b, dtype=float)
        q = np.sqrt(3 * I1b)
        r = q / (3 * lm)
        b = inverse_langevin(r)
        L, dL, lnb = langevin(b)
        return (mun * lm * lm * (r * b + lnb - w0), mun * lm * b / (2 * q),
                mun / (4 * q * q) * (1 / dL - 3 * lm * b / q))

    @classmethod
    def fit_limits(cls, I1max):
        return {"lambda_m": (I1max / 3) ** 0.5}


MATERIAL = ArrudaBoyce
