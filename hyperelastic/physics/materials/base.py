"""What every material declares (materials/NAME.py subclasses Material) and the moduli its defaults
follow from."""
from dataclasses import dataclass
from typing import Callable

import numpy as np


def lame(E, nu):
    """Lame constants (lambda, mu) from Young's modulus and Poisson's ratio (thesis eqs. 3.28-3.29)."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def shear_modulus(v):
    """mu = E / (2 (1 + nu)) of a parameter set."""
    return v["E"] / (2 * (1 + v["nu"]))


def bulk_modulus(v):
    """kappa = E / (3 (1 - 2 nu)) of a parameter set."""
    return v["E"] / (3 * (1 - 2 * v["nu"]))


@dataclass(frozen=True)
class Parameter:
    """A constant of a material beyond E, nu, rho: read as -NAME (a region's as -REGION_NAME), else its
    default from the values resolved before it (E and nu first, then the parameters in declared order)."""
    name: str
    unit: str
    meaning: str
    default: Callable           # (values: dict) -> float
    default_text: str           # how the default follows, for -help
    minimum: float = 0.0        # the value must be > minimum (>= when not exclusive)
    exclusive: bool = True
    size: int = 1               # a vector of `size` numbers (-NAME x,y,z): no range; the material's check judges it
    field: bool = False         # a direction that may vary per cell: three expressions of X, Y, Z (CellField)


# the two moduli several materials declare (the same option, -mu and -kappa, with the same meaning and default)
SHEAR = Parameter("mu", "Pa", "shear modulus", shear_modulus, "E/(2(1+ν))")
BULK = Parameter("kappa", "Pa", "bulk modulus", bulk_modulus, "E/(3(1−2ν))")


class Material:
    """The declarations every material shares; a material subclasses it (materials/NAME.py)."""
    name = "material"
    summary = ""                   # a few words for -help beside the name (its own constants, its domain)
    defined_when_inverted = True   # the energy exists for J <= 0 (else the kernels skip such cells, +inf energy)
    quadratic = False              # energy quadratic in F: the midpoint force is the discrete gradient
    parameters = ()                # Parameter: its constants beyond E, nu, rho
    references = ""                # where the model comes from (for -help)
    # the mixed displacement-pressure formulation (-formulation mixed, mixed.py) takes the volumetric part of
    # the energy as an independent pressure: "J" (the constraint G = J - 1, U(J) = kappa/4 (J^2 - 1 - 2 ln J)),
    # "trace" (G = tr eps, U = kappa/2 (tr eps)^2: the linear material); None: no split, no mixed formulation
    volumetric = None
    # the positions in the parameter block (`constants`, and the isochoric one of `split`) of the moduli the
    # isochoric energy is linear in (mu, C10, C01, Ogden's mu_p, HGO's k1): scaled all by s, the isochoric energy is
    # s times its own and the volumetric one unchanged (the viscoelastic effect's 1 + g over a step)
    moduli = ()

    @classmethod
    def scaled(cls, c, s):
        """The parameter block c with its isochoric moduli (`moduli`) times s (c: a tuple, or a row per cell)."""
        if np.ndim(c) == 2:
            out = np.array(c, np.float64)
            out[:, list(cls.moduli)] *= s
            return out
        return tuple(v * s if i in cls.moduli else v for i, v in enumerate(c))

    @staticmethod
    def constants(v):
        """The kernel's parameter block (a tuple of floats, in the C header's order) from the values."""
        lam, mu = lame(v["E"], v["nu"])
        return (mu, lam)

    @classmethod
    def check(cls, v, where):
        """Conditions on the parameters together (beyond each one's range): UserError where they fail."""

    @staticmethod
    def split(v):
        """(the kernel's parameter block of the isochoric part alone, shear modulus mu, bulk modulus kappa):
        for the mixed formulation, of a material with `volumetric`."""
        raise NotImplementedError

    # the parameters `hyperelastic fit` fits (the material's own, but for the bulk modulus), and the incompressible
    # principal Kirchhoff stresses they give; none: the material is not fitted
    fitted = ()
    # options that give several parameters as one list: {option: the parameters' names, in order} (ogden's terms)
    list_options = {}
    # anisotropic (fibres): a homogeneous test's free lateral stretches are solved for, not taken equal, and its fibre
    # directions (in the tests' axes, x the loaded one) are given to `fit`
    anisotropic = False
    # what `fit`'s stability report calls the states where the energy is undefined (a locking model's limit)
    undefined_text = "locked (the chains' limit)"

    @classmethod
    def principal_tau(cls, stretches, v):
        """tau_i = lambda_i dW/dlambda_i of the isochoric energy at the principal stretches (..., 3) of an
        incompressible state (lambda_1 lambda_2 lambda_3 = 1), v the parameter values: the principal Cauchy stresses
        up to the pressure (Ogden, Non-linear Elastic Deformations, 1984, sec. 4.3.4). For `hyperelastic fit`."""
        raise NotImplementedError

    @classmethod
    def fit_limits(cls, I1max):
        """{parameter: the value it must exceed} for the fitted state of largest I1 to be within a locking model's
        limit (`hyperelastic fit`'s bounds); none for a model without one."""
        return {}

    @staticmethod
    def fibres(c):
        """The unit reference directions (3,) of the material's fibre families for its constants c (the output's
        fibreI_stretch); none for an isotropic material."""
        return []
