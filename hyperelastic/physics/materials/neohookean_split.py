import numpy as np

from ._tensor import T
from .base import BULK, Material, SHEAR


def volumetric(J, kappa):
    """U(J) = kappa/4 (J^2 - 1 - 2 ln J) and J U'(J) = kappa/2 (J^2 - 1): the volumetric energy of Simo &
    Taylor (CMAME 85, 1991, eq. 3.6b; also deal.II's step-44). Convex, zero with zero slope at J = 1, and
    infinite as J -> 0+ or J -> infinity; U''(1) = kappa, so kappa is the small-strain bulk modulus."""
    return 0.25 * kappa * (J * J - 1 - 2 * np.log(J)), 0.5 * kappa * (J * J - 1)


class NeoHookeanSplit(Material):
    """Neo-Hookean with an isochoric/volumetric split: Psi = mu/2 (I1_bar - 3) + U(J), I1_bar =
    J^(-2/3) tr(F^T F), U(J) = kappa/4 (J^2 - 1 - 2 ln J) (Simo & Taylor 1991; Holzapfel, Nonlinear Solid
    Mechanics, 2000, sec. 6.5). P = mu J^(-2/3) (F - I1/3 F^-T) + kappa/2 (J^2 - 1) F^-T. The split lets a
    mixed formulation take the pressure as the volumetric part. Undefined for J <= 0."""
    name = "neohookean_split"
    summary = "μ, κ: isochoric/volumetric split"
    defined_when_inverted = False
    references = "Simo & Taylor, CMAME 85, 1991"
    volumetric = "J"
    moduli = (0,)
    parameters = (
        SHEAR,
        BULK,
    )

    fitted = ("mu",)

    @staticmethod
    def constants(v):
        return (v["mu"], v["kappa"])

    @classmethod
    def principal_tau(cls, stretches, v):
        """tau_i = mu lambda_i^2."""
        return v["mu"] * np.square(stretches)

    @staticmethod
    def split(v):
        return (v["mu"], 0.0), v["mu"], v["kappa"]

    @staticmethod
    def psi(F, c):
        mu, kappa = c
        J = np.linalg.det(F)
        I1 = np.einsum("...ij,...ij", F, F)
        return 0.5 * mu * (J ** (-2.0 / 3.0) * I1 - 3) + volumetric(J, kappa)[0]

    @staticmethod
    def P(F, c):
        mu, kappa = c
        J = np.linalg.det(F)
        I1 = np.einsum("...ij,...ij", F, F)
        Q = T(np.linalg.inv(F))
        a = (mu * J ** (-2.0 / 3.0))[..., None, None]
        return a * (F - (I1 / 3)[..., None, None] * Q) + volumetric(J, kappa)[1][..., None, None] * Q

    @staticmethod
    def dP(F, dF, c):
        mu, kappa = c
        J = np.linalg.det(F)
        I1 = np.einsum("...ij,...ij", F, F)
        Q = T(np.linalg.inv(F))
        a = mu * J ** (-2.0 / 3.0)
        qd = np.einsum("...ij,...ij", Q, dF)          # Q:dF = tr(F^-1 dF)
        fd = np.einsum("...ij,...ij", F, dF)
        QdQ = Q @ T(dF) @ Q
        s = lambda x: x[..., None, None]              # noqa: E731
        iso = s(a) * (dF - s(2.0 / 3.0 * qd) * F - s(2.0 / 3.0 * fd) * Q + s(2.0 / 9.0 * I1 * qd) * Q
                      + s(I1 / 3.0) * QdQ)
        return iso + s(kappa * J * J * qd) * Q - s(0.5 * kappa * (J * J - 1)) * QdQ


MATERIAL = NeoHookeanSplit
