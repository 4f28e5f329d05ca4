"""The isotropic rubbers whose isochoric energy is a function W(I1_bar) of the first invariant alone (Yeoh, Gent,
Arruda-Boyce), with the volumetric part U(J) of neohookean_split: Psi = W(I1_bar) + U(J), I1_bar = J^(-2/3) tr(F^T F).
Their numpy reference in one place; a model supplies w(I1_bar, c) -> (W, W', W'') (its constants c, kappa last).

With Q = F^-T and m = 2 W' J^(-2/3): P = m (F - I1/3 Q) + kappa/2 (J^2 - 1) Q, the neo-Hookean split's stress with
mu = 2 W'; its derivative along dF is that one's plus 4 W'' J^(-4/3) (F:dF - I1/3 Q:dF) (F - I1/3 Q) (the C kernels'
split_dstress, _tensor.h). Undefined for J <= 0, and where W is (a locking model's energy beyond its limit)."""
import numpy as np

from ._tensor import T
from .base import Material
from .neohookean_split import volumetric


def _scalars(F):
    J = np.linalg.det(F)
    I1 = np.einsum("...ij,...ij", F, F)
    return J, I1, J ** (-2.0 / 3.0), T(np.linalg.inv(F))


def _s(x):
    return x[..., None, None]


class IsochoricI1(Material):
    """A rubber W(I1_bar) + U(J): subclasses define `w` and their parameters (kappa the last constant)."""
    defined_when_inverted = False
    volumetric = "J"

    @staticmethod
    def w(I1b, c):
        """(W, W', W'') at I1_bar for the constants c (numpy arrays; NaN where W is undefined)."""
        raise NotImplementedError

    @classmethod
    def split(cls, v):
        c = cls.constants(v)
        return c[:-1] + (0.0,), cls.shear_modulus(v), c[-1]

    @classmethod
    def shear_modulus(cls, v):
        """The small-strain shear modulus 2 W'(3)."""
        return float(2 * cls.w(np.array(3.0), cls.constants(v))[1])

    @classmethod
    def principal_tau(cls, stretches, v):
        """tau_i = 2 lambda_i^2 W'(I1) (dI1/dlambda_i = 2 lambda_i)."""
        sq = np.square(stretches)
        return 2 * sq * cls.w(sq.sum(axis=-1), cls.constants({**v, "kappa": 0.0}))[1][..., None]

    @classmethod
    def psi(cls, F, c):
        J, I1, j23, _ = _scalars(F)
        return cls.w(j23 * I1, c)[0] + volumetric(J, c[-1])[0]

    @classmethod
    def P(cls, F, c):
        J, I1, j23, Q = _scalars(F)
        m = 2 * cls.w(j23 * I1, c)[1] * j23
        return _s(m) * (F - _s(I1 / 3) * Q) + _s(volumetric(J, c[-1])[1]) * Q

    @classmethod
    def dP(cls, F, dF, c):
        J, I1, j23, Q = _scalars(F)
        _, w1, w2 = cls.w(j23 * I1, c)
        a, kappa = 2 * w1 * j23, c[-1]
        qd = np.einsum("...ij,...ij", Q, dF)
        fd = np.einsum("...ij,...ij", F, dF)
        QdQ = Q @ T(dF) @ Q
        D = F - _s(I1 / 3) * Q
        iso = _s(a) * (dF - _s(2.0 / 3.0 * qd) * F - _s(2.0 / 3.0 * fd) * Q + _s(2.0 / 9.0 * I1 * qd) * Q
                       + _s(I1 / 3.0) * QdQ)
        rank1 = _s(4 * w2 * j23 * j23 * (fd - I1 / 3 * qd)) * D
        return iso + rank1 + _s(kappa * J * J * qd) * Q - _s(0.5 * kappa * (J * J - 1)) * QdQ
