import numpy as np

from ._tensor import T
from .base import Material


class NeoHookean(Material):
    """Compressible Neo-Hookean: Psi = mu/2 (tr(F^T F) - 3) - mu ln J + lam/2 (ln J)^2,
    P = mu (F - F^-T) + lam ln J F^-T (Bonet & Wood, Nonlinear Continuum Mechanics for FEA,
    1997, sec. 6.4.3). Undefined for J <= 0."""
    name = "neohookean"
    defined_when_inverted = False

    @staticmethod
    def psi(F, c):
        mu, lam = c
        J = np.linalg.det(F)
        lnJ = np.log(J)
        return 0.5 * mu * (np.einsum("...ij,...ij", F, F) - 3) - mu * lnJ + 0.5 * lam * lnJ ** 2

    @staticmethod
    def P(F, c):
        mu, lam = c
        FiT = T(np.linalg.inv(F))
        lnJ = np.log(np.linalg.det(F))
        return mu * F + (lam * lnJ - mu)[..., None, None] * FiT

    @staticmethod
    def dP(F, dF, c):
        mu, lam = c
        FiT = T(np.linalg.inv(F))
        lnJ = np.log(np.linalg.det(F))
        trm = np.einsum("...ij,...ij", FiT, dF)
        return (mu * dF + (mu - lam * lnJ)[..., None, None] * (FiT @ T(dF) @ FiT)
                + lam * trm[..., None, None] * FiT)


MATERIAL = NeoHookean
