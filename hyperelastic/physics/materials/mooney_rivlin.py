import numpy as np

from ...core.errors import UserError
from ._tensor import T
from .base import BULK, Material, Parameter, shear_modulus
from .neohookean_split import volumetric


class MooneyRivlin(Material):
    """Compressible Mooney-Rivlin: Psi = C10 (I1_bar - 3) + C01 (I2_bar - 3) + U(J), with I1_bar =
    J^(-2/3) I1, I2_bar = J^(-4/3) I2, I2 = (I1^2 - C:C)/2, C = F^T F, and U(J) = kappa/4 (J^2 - 1 - 2 ln J)
    (neohookean_split.volumetric). The small-strain shear modulus is 2 (C10 + C01), the bulk modulus kappa
    (Holzapfel, Nonlinear Solid Mechanics, 2000, sec. 6.5; Bonet & Wood, 2nd ed., 2008, sec. 6.6).
    P = 2 C10 a (F - I1/3 F^-T) + C01 b (2 (I1 F - F C) - 4/3 I2 F^-T) + kappa/2 (J^2 - 1) F^-T,
    a = J^(-2/3), b = J^(-4/3). Undefined for J <= 0."""
    name = "mooney_rivlin"
    summary = "C10, C01, κ"
    defined_when_inverted = False
    references = "Holzapfel 2000, sec. 6.5"
    volumetric = "J"
    moduli = (0, 1)
    parameters = (
        Parameter("C10", "Pa", "the first invariant's modulus", lambda v: shear_modulus(v) / 2 - v.get("C01", 0.0),
                  "μ/2 − C01 (μ = E/(2(1+ν)))", exclusive=False),
        Parameter("C01", "Pa", "the second invariant's modulus", lambda v: 0.0, "0", exclusive=False),
        BULK,
    )

    fitted = ("C10", "C01")

    @staticmethod
    def constants(v):
        return (v["C10"], v["C01"], v["kappa"])

    @classmethod
    def principal_tau(cls, stretches, v):
        """tau_i = 2 lambda_i^2 (C10 + C01 (I1 - lambda_i^2)) (dI2/dlambda_i = 2 lambda_i (I1 - lambda_i^2))."""
        sq = np.square(stretches)
        return 2 * sq * (v["C10"] + v["C01"] * (sq.sum(axis=-1, keepdims=True) - sq))

    @staticmethod
    def split(v):
        return (v["C10"], v["C01"], 0.0), 2.0 * (v["C10"] + v["C01"]), v["kappa"]

    @classmethod
    def check(cls, v, where):
        if not v["C10"] + v["C01"] > 0:
            raise UserError(f"{where}: mooney_rivlin needs C10 + C01 > 0 (the shear modulus is 2 (C10 + C01)); "
                            f"C10 {v['C10']:g}, C01 {v['C01']:g}")

    @staticmethod
    def _invariants(F):
        C = T(F) @ F
        I1 = np.trace(C, axis1=-2, axis2=-1)
        I2 = 0.5 * (I1 ** 2 - np.einsum("...ij,...ij", C, C))
        return C, I1, I2, np.linalg.det(F)

    @staticmethod
    def psi(F, c):
        C10, C01, kappa = c
        _, I1, I2, J = MooneyRivlin._invariants(F)
        return (C10 * (J ** (-2.0 / 3.0) * I1 - 3) + C01 * (J ** (-4.0 / 3.0) * I2 - 3)
                + volumetric(J, kappa)[0])

    @staticmethod
    def P(F, c):
        C10, C01, kappa = c
        C, I1, I2, J = MooneyRivlin._invariants(F)
        Q = T(np.linalg.inv(F))
        s = lambda x: x[..., None, None]              # noqa: E731
        a, b = J ** (-2.0 / 3.0), J ** (-4.0 / 3.0)
        W = s(I1) * F - F @ C
        return (s(2 * C10 * a) * (F - s(I1 / 3) * Q) + s(C01 * b) * (2 * W - s(4.0 / 3.0 * I2) * Q)
                + s(volumetric(J, kappa)[1]) * Q)

    @staticmethod
    def dP(F, dF, c):
        C10, C01, kappa = c
        C, I1, I2, J = MooneyRivlin._invariants(F)
        Q = T(np.linalg.inv(F))
        s = lambda x: x[..., None, None]              # noqa: E731
        a, b = J ** (-2.0 / 3.0), J ** (-4.0 / 3.0)
        qd = np.einsum("...ij,...ij", Q, dF)
        fd = np.einsum("...ij,...ij", F, dF)
        QdQ = Q @ T(dF) @ Q
        W = s(I1) * F - F @ C
        wd = np.einsum("...ij,...ij", W, dF)           # dI2 = 2 W:dF
        dC = T(dF) @ F + T(F) @ dF
        dW = s(2 * fd) * F + s(I1) * dF - dF @ C - F @ dC
        iso1 = s(2 * C10 * a) * (dF - s(2.0 / 3.0 * qd) * F - s(2.0 / 3.0 * fd) * Q
                                 + s(2.0 / 9.0 * I1 * qd) * Q + s(I1 / 3.0) * QdQ)
        iso2 = s(C01 * b) * (s(-4.0 / 3.0 * qd) * (2 * W - s(4.0 / 3.0 * I2) * Q) + 2 * dW
                             - s(8.0 / 3.0 * wd) * Q + s(4.0 / 3.0 * I2) * QdQ)
        return iso1 + iso2 + s(kappa * J * J * qd) * Q - s(0.5 * kappa * (J * J - 1)) * QdQ


MATERIAL = MooneyRivlin
