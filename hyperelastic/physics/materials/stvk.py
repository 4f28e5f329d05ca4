import numpy as np

from ._tensor import I3, T, sym, tr
from .base import Material


class StVK(Material):
    """St. Venant-Kirchhoff: E = (F^T F - I)/2, Psi = mu E:E + lam/2 tr(E)^2,
    P = F (2 mu E + lam tr(E) I) (thesis eqs. 3.20, 3.35, 3.40)."""
    name = "stvk"
    defined_when_inverted = True

    @staticmethod
    def psi(F, c):
        mu, lam = c
        E = 0.5 * (T(F) @ F - I3)
        return mu * np.einsum("...ij,...ij", E, E) + 0.5 * lam * tr(E) ** 2

    @staticmethod
    def P(F, c):
        mu, lam = c
        E = 0.5 * (T(F) @ F - I3)
        return F @ (2 * mu * E + lam * tr(E)[..., None, None] * I3)

    @staticmethod
    def dP(F, dF, c):
        mu, lam = c
        E = 0.5 * (T(F) @ F - I3)
        S = 2 * mu * E + lam * tr(E)[..., None, None] * I3
        dE = sym(T(F) @ dF)
        dS = 2 * mu * dE + lam * tr(dE)[..., None, None] * I3
        return dF @ S + F @ dS


MATERIAL = StVK
