"""Constitutive models. Each module defines a Material with numpy reference functions
psi(F), P(F), dP(F, dF) vectorized over a leading cell axis, and the id of its compiled kernel.

Parameters are Young's modulus E, Poisson's ratio nu and density rho in SI units;
Lame constants from thesis eqs. 3.28-3.29.
"""
from ..errors import UserError
from .linear import Linear
from .stvk import StVK
from .neohookean import NeoHookean
from .snh import StableNeoHookean
from .corotational import Corotational

MATERIALS = {m.name: m for m in (Linear, StVK, NeoHookean, StableNeoHookean, Corotational)}

# Preset values of the thesis framework (K. Erleben, hyper-sim, simulate/create_params.m, 2011);
# "bone" is its "cortical bone". E [Pa], nu [-], rho [kg/m^3].
PRESETS = {
    "rubber": (0.01e9, 0.48, 1050.0),
    "steel": (210e9, 0.31, 7800.0),
    "cartilage": (0.69e6, 0.018, 1000.0),
    "cortical_bone": (16.16e9, 0.33, 1600.0),
    "bone": (16.16e9, 0.33, 1600.0),
    "cancellous_bone": (452e6, 0.3, 1600.0),
    "concrete": (30e9, 0.20, 2320.0),
    "copper": (125e9, 0.35, 8900.0),
    "aluminium": (72e9, 0.34, 2700.0),
    "glass": (50e9, 0.18, 2190.0),
}


def lame(E, nu):
    """Lame constants (lambda, mu) from Young's modulus and Poisson's ratio (thesis eqs. 3.28-3.29)."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def check_parameters(E, nu, rho, where="material"):
    import math
    for name, val in (("E", E), ("nu", nu), ("rho", rho)):
        if not math.isfinite(val):
            raise UserError(f"{where}: -{name} {val} is not a finite number")
    if E <= 0:
        raise UserError(f"{where}: Young's modulus -E {E:g} must be > 0")
    if not (-1 < nu < 0.5):
        raise UserError(f"{where}: Poisson's ratio -nu {nu:g} must satisfy -1 < nu < 0.5")
    if rho <= 0:
        raise UserError(f"{where}: density -rho {rho:g} must be > 0")


def get(name):
    try:
        return MATERIALS[name]
    except KeyError:
        raise UserError(f"unknown material '{name}' (choose from {', '.join(sorted(MATERIALS))})") from None
