import numpy as np

from ...core.errors import UserError
from ._tensor import T
from .base import BULK, Material, Parameter, shear_modulus
from .neohookean_split import volumetric

TERMS = 5              # terms at most (ogden.h: OGDEN_TERMS; 2 x 5 + 1 constants within the kernels' block)
MAX_ALPHA = 100.0      # an exponent's size (Ogden's fits: |alpha| <= ~10; 2^100 = 1e30, 10^100 still a double)


def _terms(c):
    """The (mu_p, alpha_p) of the terms in use (mu_p != 0) of the constants c."""
    return [(c[2 * p], c[2 * p + 1]) for p in range(TERMS) if c[2 * p] != 0]


def _f(c, cb, order):
    """Sums over the terms at the eigenvalues cb of C_bar: order 0 f = sum mu/alpha cb^(alpha/2), 1 f', 2 f'',
    'h' (c f')' = sum mu alpha/4 cb^(alpha/2 - 1)."""
    out = np.zeros_like(cb)
    for mu, al in _terms(c):
        k = al / 2
        out += {0: mu / al * cb ** k, 1: mu / 2 * cb ** (k - 1), 2: mu / 2 * (k - 1) * cb ** (k - 2),
                "h": mu * k / 2 * cb ** (k - 1)}[order]
    return out


def divided(c, a, b):
    """The divided difference (f'(a) - f'(b)) / (a - b), f''(a) where a = b, without cancellation: for each term
    mu/2 (a^k - b^k)/(a - b) = mu/2 b^(k-1) expm1(k u) / expm1(u), u = ln(a/b), k = alpha/2 - 1 (k where u = 0)."""
    out = np.zeros(np.broadcast(a, b).shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.log(a / b)
        for mu, al in _terms(c):
            k = al / 2 - 1
            phi = np.where(u == 0, k, np.expm1(k * u) / np.where(u == 0, 1.0, np.expm1(u)))
            out = out + mu / 2 * b ** (k - 1) * phi
    return out


class Ogden(Material):
    """Ogden's rubber (Ogden, Proc. R. Soc. A 326, 1972), up to five terms, with the isochoric/volumetric split:
    Psi = sum_p mu_p/alpha_p (l1_bar^alpha_p + l2_bar^alpha_p + l3_bar^alpha_p - 3) + U(J), l_bar = J^(-1/3) l the
    isochoric principal stretches, U(J) = kappa/4 (J^2 - 1 - 2 ln J) (neohookean_split.volumetric); small-strain shear
    modulus mu = 1/2 sum_p mu_p alpha_p. As a function of C_bar = J^(-2/3) C (eigenvalues cb_a = l_bar_a^2):
    W = tr f(C_bar), f(c) = sum_p mu_p/alpha_p c^(alpha_p/2), so P = 2 J^(-2/3) F f'(C_bar) - 2/3 tau F^-T +
    kappa/2 (J^2 - 1) F^-T, tau = sum_a f'(cb_a) cb_a; the derivative of the matrix function f'(C_bar) along dC_bar
    is N (f'[1] o (N^T dC_bar N)) N^T (Daleckii & Krein; Bhatia, Matrix Analysis, 1997, V.3), f'[1] the divided
    differences of f' at the eigenvalues, f'' on the diagonal and where two are equal: exact and finite at equal
    stretches, where the principal directions are not defined. Undefined for J <= 0."""
    name = "ogden"
    moduli = (0, 2, 4, 6, 8)
    summary = "μ1..5, α1..5 (or -ogden_mu, -ogden_alpha lists), κ: rubber in principal stretches"
    defined_when_inverted = False
    references = "Ogden, Proc. R. Soc. A 326, 1972"
    volumetric = "J"
    fitted = ("mu1", "alpha1", "mu2", "alpha2", "mu3", "alpha3", "mu4", "alpha4", "mu5", "alpha5")
    # the terms as two lists (Abaqus' and FEBio's way): -ogden_mu 0.63e6,0.0012e6,-0.01e6 -ogden_alpha 1.3,5,-2
    list_options = {"ogden_mu": tuple(f"mu{p}" for p in range(1, TERMS + 1)),
                    "ogden_alpha": tuple(f"alpha{p}" for p in range(1, TERMS + 1))}
    parameters = (
        Parameter("mu1", "Pa", "the first term's modulus", shear_modulus, "μ = E/(2(1+ν)) (with α1 = 2: neo-Hookean)",
                  minimum=-np.inf),
        Parameter("alpha1", "-", "its exponent", lambda v: 2.0, "2", minimum=-np.inf),
        Parameter("mu2", "Pa", "the second term's (0: off)", lambda v: 0.0, "0", minimum=-np.inf),
        Parameter("alpha2", "-", "its exponent", lambda v: 4.0, "4", minimum=-np.inf),
        Parameter("mu3", "Pa", "the third term's (0: off)", lambda v: 0.0, "0", minimum=-np.inf),
        Parameter("alpha3", "-", "its exponent", lambda v: -2.0, "−2", minimum=-np.inf),
        Parameter("mu4", "Pa", "the fourth term's (0: off)", lambda v: 0.0, "0", minimum=-np.inf),
        Parameter("alpha4", "-", "its exponent", lambda v: 6.0, "6", minimum=-np.inf),
        Parameter("mu5", "Pa", "the fifth term's (0: off)", lambda v: 0.0, "0", minimum=-np.inf),
        Parameter("alpha5", "-", "its exponent", lambda v: -4.0, "−4", minimum=-np.inf),
        BULK,
    )

    @staticmethod
    def constants(v):
        return tuple(v[n] for p in range(1, TERMS + 1) for n in (f"mu{p}", f"alpha{p}")) + (v["kappa"],)

    @classmethod
    def split(cls, v):
        c = cls.constants(v)
        return c[:-1] + (0.0,), 0.5 * sum(mu * al for mu, al in _terms(c)), c[-1]

    @classmethod
    def check(cls, v, where):
        c = cls.constants(v)
        for p, (mu, al) in enumerate(zip(c[0:2 * TERMS:2], c[1:2 * TERMS:2]), start=1):
            if mu != 0 and al == 0:
                raise UserError(f"{where}: ogden's term {p} has mu{p} {mu:g} and alpha{p} 0 (an exponent of 0 is no "
                                "term: give it mu 0)")
            if mu != 0 and abs(al) > MAX_ALPHA:
                raise UserError(f"{where}: ogden's alpha{p} {al:g} is beyond +-{MAX_ALPHA:g} (a rubber's exponents are "
                                f"a few; lambda^alpha of a stretch of 2 overflows at |alpha| ~ 1000)")
        mu = cls.split(v)[1]
        if not mu > 0:
            raise UserError(f"{where}: ogden needs 1/2 sum mu_p alpha_p > 0 (its small-strain shear modulus); got "
                            f"{mu:g}")

    @classmethod
    def principal_tau(cls, stretches, v):
        """tau_i = sum_p mu_p lambda_i^alpha_p."""
        return sum(mu * stretches ** al for mu, al in _terms(cls.constants({**v, "kappa": 0.0})))

    @staticmethod
    def _state(F, c):
        J = np.linalg.det(F)
        j23 = J ** (-2.0 / 3.0)
        C = T(F) @ F
        cv, N = np.linalg.eigh(C)
        cb = j23[..., None] * cv
        return J, j23, C, N, cb, T(np.linalg.inv(F))

    @staticmethod
    def psi(F, c):
        J, _, _, _, cb, _ = Ogden._state(F, c)
        W = _f(c, cb, 0).sum(axis=-1) - sum(3 * mu / al for mu, al in _terms(c))
        return W + volumetric(J, c[-1])[0]

    @staticmethod
    def P(F, c):
        J, j23, _, N, cb, Q = Ogden._state(F, c)
        fp = _f(c, cb, 1)
        Tm = N @ (fp[..., :, None] * T(N))
        tau = (fp * cb).sum(axis=-1)
        s = lambda x: x[..., None, None]              # noqa: E731
        return s(2 * j23) * F @ Tm + s(volumetric(J, c[-1])[1] - 2.0 / 3.0 * tau) * Q

    @staticmethod
    def dP(F, dF, c):
        J, j23, C, N, cb, Q = Ogden._state(F, c)
        s = lambda x: x[..., None, None]              # noqa: E731
        fp, h = _f(c, cb, 1), _f(c, cb, "h")
        Tm = N @ (fp[..., :, None] * T(N))
        tau = (fp * cb).sum(axis=-1)
        qd = np.einsum("...ij,...ij", Q, dF)
        dCb = s(j23) * (T(dF) @ F + T(F) @ dF - s(2.0 / 3.0 * qd) * C)
        Dh = T(N) @ dCb @ N
        dT = N @ (divided(c, cb[..., :, None], cb[..., None, :]) * Dh) @ T(N)
        dtau = (h * np.einsum("...aa->...a", Dh)).sum(axis=-1)
        U = Q @ T(dF) @ Q
        kappa = c[-1]
        g = 0.5 * kappa * (J * J - 1)
        return (s(2 * j23) * (dF @ Tm + F @ dT - s(2.0 / 3.0 * qd) * F @ Tm) - s(2.0 / 3.0 * dtau) * Q
                + s(2.0 / 3.0 * tau - g) * U + s(kappa * J * J * qd) * Q)


MATERIAL = Ogden
