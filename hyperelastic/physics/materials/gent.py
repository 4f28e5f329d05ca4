import numpy as np

from ._i1 import IsochoricI1
from .base import BULK, Parameter, SHEAR

# Jm's default: the chains' extensibility of arruda_boyce's default (N = 26.5 segments, Arruda & Boyce's fit of
# Treloar's rubber): the two models lock at the same I1 = 3 N where Jm = 3 (N - 1) (Horgan & Saccomandi, Rubber Chem.
# Technol. 75, 2002). `hyperelastic fit` of the Treloar curves Ogden's 1972 constants give: Jm 102 (uniaxial alone),
# 122 (all three modes); docs/guide/rubber.md
JM_DEFAULT = 3 * (26.5 - 1)


class Gent(IsochoricI1):
    """Gent's limiting-chain-extensibility model (Gent, Rubber Chem. Technol. 69, 1996): W(I1_bar) = -mu Jm/2
    ln(1 - (I1_bar - 3)/Jm) + U(J), U(J) = kappa/4 (J^2 - 1 - 2 ln J) (neohookean_split.volumetric). W' = mu/2 /
    (1 - s/Jm), W'' = mu/(2 Jm) / (1 - s/Jm)^2, s = I1_bar - 3: the neo-Hookean model at small strain (shear modulus
    mu), the energy infinite as I1_bar - 3 -> Jm (the chains' full extension), undefined beyond (as for J <= 0: the
    state is refused and the step retried smaller). Jm -> infinity is neohookean_split."""
    name = "gent"
    moduli = (0,)
    summary = "μ, Jm, κ: rubber that stiffens up to a locking stretch"
    references = "Gent, Rubber Chem. Technol. 69, 1996"
    fitted = ("mu", "Jm")
    parameters = (
        SHEAR,
        Parameter("Jm", "-", "the limit of I1 - 3 (the chains' extensibility)", lambda v: JM_DEFAULT,
                  f"{JM_DEFAULT:g} (3 (N − 1), N = 26.5: arruda_boyce's λm²)"),
        BULK,
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
    def fit_limits(cls, I1max):
        return {"Jm": I1max - 3}


MATERIAL = Gent
