import math

import numpy as np

from ...core.errors import UserError
from ._tensor import T
from .base import BULK, Material, Parameter, SHEAR
from .neohookean_split import volumetric

NONE = (math.nan, math.nan, math.nan)      # a fibre family's direction not given: the family is absent
MAX_EXPONENT = 700.0                        # k2 E^2 beyond it: exp overflows (the state is refused)


def _unit(a, name, where):
    n = math.sqrt(sum(x * x for x in a))
    if not n > 0:
        raise UserError(f"{where}: hgo's -{name} {','.join(f'{x:g}' for x in a)} is no direction (its length is 0)")
    return tuple(x / n for x in a)


def _families(c):
    """The unit directions of the families present in the constants c: (3,) each, or (n, 3) where c has a row per
    cell (a fibre field)."""
    c = np.asarray(c, np.float64)
    return [c[..., 5 + 3 * i:8 + 3 * i] for i in range(int(c[..., 11].max(initial=0)))]


def _given(a):
    """Whether a fibre family's value is given: a field (CellField, or its values per cell) or a vector."""
    return not isinstance(a, tuple) or not any(math.isnan(x) for x in a)


def _vector(a):
    """A fibre value as the constants take it: (3,), or (n, 3) per cell; a field not yet at its cells (CellField)
    stands for (1, 0, 0) (only its presence counts before Solid.localized)."""
    return np.asarray(a, np.float64) if isinstance(a, (tuple, list, np.ndarray)) else np.array([1.0, 0.0, 0.0])


def _mv(M, a):
    """M a for matrices (..., 3, 3) and vectors (3,) or one per matrix (..., 3)."""
    return np.einsum("...ij,...j->...i", M, a)


class HGO(Material):
    """Holzapfel, Gasser and Ogden's fibre-reinforced tissue with dispersed fibres (Gasser, Ogden & Holzapfel, J. R.
    Soc. Interface 3, 2006; Holzapfel, Gasser & Ogden, J. Elasticity 61, 2000): Psi = mu/2 (I1_bar - 3) +
    k1/(2 k2) sum_i (exp(k2 <E_i>^2) - 1) + U(J), E_i = d (I1_bar - 3) + (1 - 3d)(I4i_bar - 1), I4i_bar = J^(-2/3)
    |F a_i|^2, a_i the unit mean direction of family i in the reference (one or two families), d the dispersion (0:
    aligned, 1/3: isotropic), <E> = max(E, 0): the fibres bear no compression. U(J) = kappa/4 (J^2 - 1 - 2 ln J). With
    G1 = dI1_bar/dF = 2 J^(-2/3) (F - I1/3 Q), G4 = dI4_bar/dF = J^(-2/3) (2 m (x) a - 2/3 I4 Q), m = F a, Q = F^-T,
    f'(E) = k1 E exp(k2 E^2), f'' = k1 (1 + 2 k2 E^2) exp(k2 E^2) (both 0 where E <= 0):
    P = (mu/2 + d sum f'_i) G1 + (1 - 3d) sum f'_i G4i + kappa/2 (J^2 - 1) Q, and dP = W1 dG1 + (1 - 3d) sum f'_i dG4i
    + sum f''_i (H_i:dF) H_i + the volumetric part's, H_i = d G1 + (1 - 3d) G4i. The energy is C1, not C2, where a
    family starts to stretch (E = 0). Undefined for J <= 0 and where k2 E^2 > 700 (exp overflows)."""
    name = "hgo"
    moduli = (0, 1)
    summary = "μ, k1, k2, dispersion, fibre1, fibre2, κ: fibre-reinforced soft tissue"
    defined_when_inverted = False
    references = "Gasser, Ogden & Holzapfel, J. R. Soc. Interface 3, 2006"
    volumetric = "J"
    parameters = (
        SHEAR,
        Parameter("k1", "Pa", "the fibres' stiffness (0: no fibres)", lambda v: 0.0, "0", exclusive=False),
        Parameter("k2", "-", "the fibres' exponential stiffening", lambda v: 1.0, "1"),
        Parameter("dispersion", "-", "the fibres' dispersion d, 0 (aligned) to 1/3 (isotropic)", lambda v: 0.0, "0",
                  exclusive=False),
        Parameter("fibre1", "-", "the first family's mean direction x,y,z in the reference, or a field: three "
                  "expressions of X, Y, Z (at each cell's centroid)", lambda v: NONE, "none (needed where k1 > 0)",
                  minimum=-math.inf, size=3, field=True),
        Parameter("fibre2", "-", "the second family's (none: one family)", lambda v: NONE, "none",
                  minimum=-math.inf, size=3, field=True),
        BULK,
    )

    @staticmethod
    def constants(v):
        """(mu, k1, k2, d, kappa, a1 (3), a2 (3), the number of families): the directions made unit; a row per cell
        (n, 12) where a family is a field at its cells (Solid.localized)."""
        fams = [_vector(v[n]) for n in ("fibre1", "fibre2") if _given(v[n])]
        fams = [a / np.sqrt(a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1] + a[..., 2] * a[..., 2])[..., None]
                for a in fams]                 # (x / sqrt(x^2 + y^2 + z^2) in that order: as before fields)
        n = max((len(a) for a in fams if a.ndim == 2), default=None)
        out = np.zeros(12 if n is None else (n, 12))
        out[..., :5] = v["mu"], v["k1"], v["k2"], v["dispersion"], v["kappa"]
        for i, a in enumerate(fams):
            out[..., 5 + 3 * i:8 + 3 * i] = a
        out[..., 11] = len(fams)
        return out if n is not None else tuple(float(x) for x in out)

    @staticmethod
    def fibres(c):
        return _families(c)

    fitted = ("mu", "k1", "k2")
    anisotropic = True
    undefined_text = "undefined (the fibres' exp(k2 E^2) beyond exp(700))"

    @classmethod
    def principal_tau(cls, stretches, v):
        """The diagonal of the Kirchhoff stress P F^T of the isochoric energy at F = diag(stretches) (J = 1), the fibres
        along v's directions in those axes (`hyperelastic fit`; its off-diagonal part: principal_shear)."""
        return np.diagonal(cls._kirchhoff(stretches, v), axis1=-2, axis2=-1)

    @classmethod
    def principal_shear(cls, stretches, v):
        """The largest off-diagonal Kirchhoff stress at F = diag(stretches): zero where the fibres lie along the axes or
        in pairs mirrored about them (a homogeneous test then has no shear)."""
        tau = cls._kirchhoff(stretches, v)
        return np.abs(tau - np.diagonal(tau, axis1=-2, axis2=-1)[..., None] * np.eye(3)).max(axis=(-1, -2))

    @classmethod
    def _kirchhoff(cls, stretches, v):
        lam = np.asarray(stretches, np.float64)
        F = lam[..., :, None] * np.eye(3)
        return cls.P(F, cls.constants({**v, "kappa": 0.0})) @ np.swapaxes(F, -1, -2)

    @classmethod
    def split(cls, v):
        c = cls.constants(v)
        if isinstance(c, np.ndarray):
            iso = c.copy()
            iso[:, 4] = 0.0
            return iso, v["mu"], v["kappa"]
        return c[:4] + (0.0,) + c[5:], v["mu"], v["kappa"]

    @classmethod
    def check(cls, v, where):
        if not v["dispersion"] <= 1 / 3:
            raise UserError(f"{where}: hgo's -dispersion {v['dispersion']:g} must be <= 1/3 (1/3: fibres in every "
                            "direction)")
        given = [n for n in ("fibre1", "fibre2") if _given(v[n])]
        for n in given:
            if isinstance(v[n], tuple):          # (a field: checked at each cell, Solid.localized)
                _unit(v[n], n, where)
        if v["k1"] > 0 and "fibre1" not in given:
            raise UserError(f"{where}: hgo with k1 {v['k1']:g} > 0 needs -fibre1 x,y,z (the first fibre family's mean "
                            "direction)")
        if "fibre2" in given and "fibre1" not in given:
            raise UserError(f"{where}: hgo's -fibre2 without -fibre1 (give the first family first)")

    @staticmethod
    def _state(F, c):
        J = np.linalg.det(F)
        I1 = np.einsum("...ij,...ij", F, F)
        return J, I1, J ** (-2.0 / 3.0), T(np.linalg.inv(F))

    @staticmethod
    def _fibres(F, c, I1, j23):
        """Per family: (a, m = F a, I4, E, f', f'')."""
        mu, k1, k2, d = _scalars(c, 4)
        out = []
        for a in _families(c):
            m = _mv(F, a)
            I4 = np.einsum("...i,...i", m, m)
            E = d * (j23 * I1 - 3) + (1 - 3 * d) * (j23 * I4 - 1)
            Ep = np.maximum(E, 0.0)
            with np.errstate(over="ignore"):
                ex = np.where(k2 * Ep * Ep <= MAX_EXPONENT, np.exp(k2 * Ep * Ep), np.nan)
            out.append((a, m, I4, Ep, k1 * Ep * ex, np.where(E > 0, k1 * (1 + 2 * k2 * Ep * Ep) * ex, 0.0), ex))
        return out

    @staticmethod
    def psi(F, c):
        mu, k1, k2, d, kappa = _scalars(c, 5)
        J, I1, j23, _ = HGO._state(F, c)
        W = 0.5 * mu * (j23 * I1 - 3)
        for a, m, I4, Ep, f1, f2, ex in HGO._fibres(F, c, I1, j23):
            W = W + k1 / (2 * k2) * (ex - 1)
        return W + volumetric(J, kappa)[0]

    @staticmethod
    def P(F, c):
        mu, k1, k2, d, kappa = _scalars(c, 5)
        J, I1, j23, Q = HGO._state(F, c)
        s = lambda x: np.asarray(x)[..., None, None]      # noqa: E731
        G1 = s(2 * j23) * (F - s(I1 / 3) * Q)
        out = s(0.5 * mu) * G1 + s(volumetric(J, kappa)[1]) * Q
        for a, m, I4, Ep, f1, f2, ex in HGO._fibres(F, c, I1, j23):
            G4 = s(j23) * (2 * m[..., :, None] * a[..., None, :] - s(2.0 / 3.0 * I4) * Q)
            out = out + s(f1) * (s(d) * G1 + s(1 - 3 * d) * G4)
        return out

    @staticmethod
    def dP(F, dF, c):
        mu, k1, k2, d, kappa = _scalars(c, 5)
        J, I1, j23, Q = HGO._state(F, c)
        s = lambda x: np.asarray(x)[..., None, None]      # noqa: E731
        qd = np.einsum("...ij,...ij", Q, dF)
        fd = np.einsum("...ij,...ij", F, dF)
        U = Q @ T(dF) @ Q
        G1 = s(2 * j23) * (F - s(I1 / 3) * Q)
        dG1 = s(2 * j23) * (dF - s(2.0 / 3.0 * qd) * F - s(2.0 / 3.0 * fd) * Q + s(2.0 / 9.0 * I1 * qd) * Q
                            + s(I1 / 3.0) * U)
        W1 = 0.5 * mu
        out = s(kappa * J * J * qd) * Q - s(0.5 * kappa * (J * J - 1)) * U
        for a, m, I4, Ep, f1, f2, ex in HGO._fibres(F, c, I1, j23):
            W1 = W1 + d * f1
            dm = _mv(dF, a)
            md = np.einsum("...i,...i", m, dm)
            ma = m[..., :, None] * a[..., None, :]
            G4 = s(j23) * (2 * ma - s(2.0 / 3.0 * I4) * Q)
            dG4 = s(j23) * (-s(2.0 / 3.0 * qd) * (2 * ma - s(2.0 / 3.0 * I4) * Q)
                            + 2 * dm[..., :, None] * a[..., None, :] - s(4.0 / 3.0 * md) * Q + s(2.0 / 3.0 * I4) * U)
            H = s(d) * G1 + s(1 - 3 * d) * G4
            out = out + s(f1 * (1 - 3 * d)) * dG4 + s(f2 * np.einsum("...ij,...ij", H, dF)) * H
        return out + s(W1) * dG1


def _scalars(c, k):
    """The first k constants: numbers, or an array per cell (constants with a row per cell)."""
    c = np.asarray(c, np.float64)
    return tuple(c[..., i] for i in range(k))


MATERIAL = HGO
