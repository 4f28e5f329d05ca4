import numpy as np

from ._tensor import I3, sym, tr
from .base import Material, lame


class Linear(Material):
    """Linear elasticity: eps = sym(F) - I, Psi = mu eps:eps + lam/2 tr(eps)^2,
    P = 2 mu eps + lam tr(eps) I (thesis eqs. 3.23, 3.27, 3.34)."""
    name = "linear"
    defined_when_inverted = True
    quadratic = True               # the midpoint force is already the discrete gradient (-energy_momentum)
    volumetric = "trace"

    @staticmethod
    def split(v):
        """mu eps:eps + lam/2 (tr eps)^2 = mu dev eps:dev eps + kappa/2 (tr eps)^2, kappa = lam + 2 mu/3: the
        deviatoric part is this material's energy with lam = -2 mu/3."""
        lam, mu = lame(v["E"], v["nu"])
        return (mu, -2.0 * mu / 3.0), mu, lam + 2.0 * mu / 3.0

    @classmethod
    def scaled(cls, c, s):
        """The deviatoric part times s (its bulk modulus lam + 2 mu/3 kept): mu -> s mu, lam -> lam - (s - 1) 2 mu/3."""
        mu, lam = c
        return (s * mu, lam - (s - 1) * 2.0 * mu / 3.0)

    @staticmethod
    def psi(F, c):
        mu, lam = c
        e = sym(F) - I3
        return mu * np.einsum("...ij,...ij", e, e) + 0.5 * lam * tr(e) ** 2

    @staticmethod
    def P(F, c):
        mu, lam = c
        e = sym(F) - I3
        return 2 * mu * e + lam * tr(e)[..., None, None] * I3

    @staticmethod
    def dP(F, dF, c):
        mu, lam = c
        return 2 * mu * sym(dF) + lam * tr(dF)[..., None, None] * I3


MATERIAL = Linear
