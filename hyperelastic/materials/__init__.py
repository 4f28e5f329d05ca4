"""Constitutive models, one home each: materials/NAME.py holds the numpy reference (psi(F), P(F),
dP(F, dF) vectorized over a leading cell axis) in a class named by its module's MATERIAL, and
materials/NAME.h the C kernel (stress, derivative preparation, directional derivative) that setup.py
compiles into he_forces_NAME, he_kv_NAME, ... (see _kernels.c). A material is registered by adding
NAME to REGISTRY below: its order is the order the hard-case matrix and the help list them in.

Parameters are Young's modulus E, Poisson's ratio nu and density rho in SI units;
Lame constants from thesis eqs. 3.28-3.29.
"""
import importlib

from ..errors import UserError

REGISTRY = ("linear", "stvk", "neohookean", "snh", "corotational")
MATERIALS = {n: importlib.import_module(f".{n}", __name__).MATERIAL for n in REGISTRY}

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
