import math

from ._i1 import IsochoricI1
from .base import BULK, Parameter, shear_modulus


class Yeoh(IsochoricI1):
    """Yeoh's reduced polynomial (Yeoh, Rubber Chem. Technol. 66, 1993: filled rubber, whose shear modulus falls and
    rises again with strain, to large strains): Psi = sum_i Ci0 (I1_bar - 3)^i, i = 1..3, + U(J), I1_bar =
    J^(-2/3) I1, U(J) = kappa/4 (J^2 - 1 - 2 ln J) (neohookean_split.volumetric). With W' = dW/dI1_bar and
    m = 2 W' J^(-2/3): P = m (F - I1/3 F^-T) + kappa/2 (J^2 - 1) F^-T, the neo-Hookean split's with mu = 2 W'; its
    derivative that one's plus 4 W'' J^(-4/3) (F:dF - I1/3 F^-T:dF) (F - I1/3 F^-T). Small-strain shear modulus
    2 C10; C20 may be negative (typical of filled rubber: C10 > 0, C20 < 0, C30 > 0), and such constants are Drucker
    stable only over some range of strain. Undefined for J <= 0."""
    name = "yeoh"
    moduli = (0, 1, 2)
    summary = "C10, C20, C30, κ: filled rubber to large strains"
    references = "Yeoh, Rubber Chem. Technol. 66, 1993"
    fitted = ("C10", "C20", "C30")
    parameters = (
        Parameter("C10", "Pa", "the first invariant's modulus", lambda v: shear_modulus(v) / 2,
                  "μ/2 (μ = E/(2(1+ν)))"),
        Parameter("C20", "Pa", "its square's", lambda v: 0.0, "0", minimum=-math.inf),
        Parameter("C30", "Pa", "its cube's", lambda v: 0.0, "0", minimum=-math.inf),
        BULK,
    )

    @staticmethod
    def constants(v):
        return (v["C10"], v["C20"], v["C30"], v["kappa"])

    @staticmethod
    def w(I1b, c):
        """(W, W', W'') of W(I1_bar) = C10 (I1_bar - 3) + C20 (I1_bar - 3)^2 + C30 (I1_bar - 3)^3."""
        C10, C20, C30 = c[:3]
        s = I1b - 3
        return (C10 * s + C20 * s ** 2 + C30 * s ** 3, C10 + 2 * C20 * s + 3 * C30 * s ** 2, 2 * C20 + 6 * C30 * s)


MATERIAL = Yeoh
