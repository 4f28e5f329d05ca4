import numpy as np

from ...core.errors import UserError
from ._i1 import IsochoricI1
from .base import Parameter, bulk_modulus, shear_modulus

# Jm's default, the one of Gent's own rubber (I1 - 3 <= Jm ~ 100 for a lightly cross-linked rubber, Gent 1996; a fit of
# Treloar's curves gives a similar value: docs/guide/rubber.md)
JM_DEFAULT = 100.0


class Gent(IsochoricI1):
    """Gent's limiting-chain-extensibility model (Gent, Rubber Chem. Technol. 69, 1996): W(I1_bar) = -mu Jm/2
    ln(1 - (I1_bar - 3)/Jm) + U(J), U(J) = kappa/4 (J^2 - 1 - 2 ln J) (neohookean_split.volumetric). W' = mu/2 /
    (1 - s/Jm), W'' = mu/(2 Jm) / (1 - s/Jm)^2, s = I1_bar - 3: the neo-Hookean model at small strain (shear modulus
    mu), the energy infinite as I1_bar - 3 -> Jm (the chains' full extension), undefined beyond (as for J <= 0: the
    state is refused and the step retried smaller). Jm -> infinity is neohookean_split."""
    name = "gent"
    summary = "μ, Jm, κ: rubber that stiffens up to a locking stretch"
    references = "Gent, Rubber Chem. Technol. 69, 1996"
    parameters = (
        Parameter("mu", "Pa", "shear modulus", shear_modulus, "E/(2(1+ν))"),
        Parameter("Jm", "-", "the limit of I1 - 3 (the chains' extensibility)", lambda v: JM_DEFAULT,
                  f"{JM_DEFAULT:g}"),
        Parameter("kappa", "Pa", "bulk modulus", bulk_modulus, "E/(3(1−2ν))"),
    )

    @staticmethod
    def constants(v):
        return (v["mu"], v["Jm"], v["kappa"])

    @staticmethod
    def w(I1b, c):
        """(W, W', W''): NaN where I1_bar - 3 >= Jm."""
        mu, Jm = c[0], c[1]
        s = np.asarray(I1b) - 3
        with np.errstate(invalid="ignore", divide="ignore"):
            x = np.where(s < Jm, 1 - s / Jm, np.nan)
            return np.where(s < Jm, -0.5 * mu * Jm * np.log1p(-s / Jm), np.nan), 0.5 * mu / x, 0.5 * mu / (Jm * x * x)

    @classmethod
    def check(cls, v, where):
        if not v["mu"] > 0:
            raise UserError(f"{where}: gent needs mu > 0 (its small-strain shear modulus); mu {v['mu']:g}")


MATERIAL = Gent
