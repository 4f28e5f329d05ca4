import math

import numpy as np

from ...core.errors import UserError
from ._tensor import T
from .base import Material, Parameter, bulk_modulus, shear_modulus
from .neohookean_split import volumetric


def _w(I1b, c):
    """(W, W', W'') of W(I1_bar) = C10 (I1_bar - 3) + C20 (I1_bar - 3)^2 + C30 (I1_bar - 3)^3."""
    C10, C20, C30 = c[:3]
    s = I1b - 3
    return (C10 * s + C20 * s ** 2 + C30 * s ** 3, C10 + 2 * C20 * s + 3 * C30 * s ** 2, 2 * C20 + 6 * C30 * s)


class Yeoh(Material):
    """Yeoh's reduced polynomial (Yeoh, Rubber Chem. Technol. 66, 1993: filled rubber, whose shear modulus falls and
    rises again with strain, to large strains): Psi = sum_i Ci0 (I1_bar - 3)^i, i = 1..3, + U(J), I1_bar =
    J^(-2/3) I1, U(J) = kappa/4 (J^2 - 1 - 2 ln J) (neohookean_split.volumetric). With W' = dW/dI1_bar and
    m = 2 W' J^(-2/3): P = m (F - I1/3 F^-T) + kappa/2 (J^2 - 1) F^-T, the neo-Hookean split's with mu = 2 W'; its
    derivative that one's plus 4 W'' J^(-4/3) (F:dF - I1/3 F^-T:dF) (F - I1/3 F^-T). Small-strain shear modulus
    2 C10; C20 may be negative (typical of filled rubber: C10 > 0, C20 < 0, C30 > 0), and such constants are Drucker
    stable only over some range of strain. Undefined for J <= 0."""
    name = "yeoh"
    summary = "C10, C20, C30, κ: filled rubber to large strains"
    defined_when_inverted = False
    references = "Yeoh, Rubber Chem. Technol. 66, 1993"
    volumetric = "J"
    parameters = (
        Parameter("C10", "Pa", "the first invariant's modulus", lambda v: shear_modulus(v) / 2,
                  "μ/2 (μ = E/(2(1+ν)))"),
        Parameter("C20", "Pa", "its square's", lambda v: 0.0, "0", minimum=-math.inf),
        Parameter("C30", "Pa", "its cube's", lambda v: 0.0, "0", minimum=-math.inf),
        Parameter("kappa", "Pa", "bulk modulus", bulk_modulus, "E/(3(1−2ν))"),
    )

    @staticmethod
    def constants(v):
        return (v["C10"], v["C20"], v["C30"], v["kappa"])

    @staticmethod
    def split(v):
        return (v["C10"], v["C20"], v["C30"], 0.0), 2.0 * v["C10"], v["kappa"]

    @classmethod
    def check(cls, v, where):
        if not v["C10"] > 0:
            raise UserError(f"{where}: yeoh needs C10 > 0 (the small-strain shear modulus is 2 C10); C10 {v['C10']:g}")

    @staticmethod
    def _scalars(F):
        J = np.linalg.det(F)
        I1 = np.einsum("...ij,...ij", F, F)
        return J, I1, J ** (-2.0 / 3.0), T(np.linalg.inv(F))

    @staticmethod
    def psi(F, c):
        J, I1, j23, _ = Yeoh._scalars(F)
        return _w(j23 * I1, c)[0] + volumetric(J, c[3])[0]

    @staticmethod
    def P(F, c):
        J, I1, j23, Q = Yeoh._scalars(F)
        m = (2 * _w(j23 * I1, c)[1] * j23)[..., None, None]
        return m * (F - (I1 / 3)[..., None, None] * Q) + volumetric(J, c[3])[1][..., None, None] * Q

    @staticmethod
    def dP(F, dF, c):
        J, I1, j23, Q = Yeoh._scalars(F)
        _, w1, w2 = _w(j23 * I1, c)
        a, kappa = 2 * w1 * j23, c[3]
        qd = np.einsum("...ij,...ij", Q, dF)
        fd = np.einsum("...ij,...ij", F, dF)
        QdQ = Q @ T(dF) @ Q
        s = lambda x: x[..., None, None]              # noqa: E731
        D = F - s(I1 / 3) * Q
        iso = s(a) * (dF - s(2.0 / 3.0 * qd) * F - s(2.0 / 3.0 * fd) * Q + s(2.0 / 9.0 * I1 * qd) * Q
                      + s(I1 / 3.0) * QdQ)
        rank1 = s(4 * w2 * j23 * j23 * (fd - I1 / 3 * qd)) * D
        return iso + rank1 + s(kappa * J * J * qd) * Q - s(0.5 * kappa * (J * J - 1)) * QdQ


MATERIAL = Yeoh
