import numpy as np

from ._tensor import T
from .base import Material


def polar(F):
    """F = R S with det R = +1 (rotation) and S symmetric: (R, V, sig) with S = V diag(sig) V^T,
    sig descending except that the last one carries the sign of det F (Irving, Teran, Fedkiw,
    "Invertible finite elements", SCA 2004, sec. 4)."""
    U, s, Vt = np.linalg.svd(F)
    s = s.copy()
    fu = np.linalg.det(U) < 0
    U[fu, :, 2] *= -1
    s[fu, 2] *= -1
    fv = np.linalg.det(Vt) < 0
    Vt[fv, 2, :] *= -1
    s[fv, 2] *= -1
    return U @ Vt, T(Vt), s


def skew(w):
    z = np.zeros_like(w[..., 0])
    return np.stack([np.stack([z, -w[..., 2], w[..., 1]], -1), np.stack([w[..., 2], z, -w[..., 0]], -1),
                     np.stack([-w[..., 1], w[..., 0], z], -1)], -2)


class Corotational(Material):
    """Corotational linear elasticity: Psi = mu |S - I|^2 + lam/2 tr(S - I)^2 with F = R S the polar
    decomposition, P = 2 mu (F - R) + lam tr(S - I) R (McAdams, Zhu, Selle, Empey, Tamstorf, Teran,
    Sifakis, "Efficient elasticity for character skinning with contact and collisions", SIGGRAPH 2011).
    The element rotation is taken per element, as in the thesis framework's corotational model; the
    tangent includes the derivative of R, so it is the exact Hessian of Psi."""
    name = "corotational"
    defined_when_inverted = True

    @staticmethod
    def psi(F, c):
        mu, lam = c
        _, _, s = polar(F)
        return mu * ((s - 1) ** 2).sum(-1) + 0.5 * lam * (s.sum(-1) - 3) ** 2

    @staticmethod
    def P(F, c):
        mu, lam = c
        R, _, s = polar(F)
        return 2 * mu * (F - R) + (lam * (s.sum(-1) - 3))[..., None, None] * R

    @staticmethod
    def dP(F, dF, c):
        mu, lam = c
        R, V, s = polar(F)
        A = T(R) @ dF
        a = np.stack([A[..., 2, 1] - A[..., 1, 2], A[..., 0, 2] - A[..., 2, 0], A[..., 1, 0] - A[..., 0, 1]], -1)
        den = np.stack([s[..., 1] + s[..., 2], s[..., 0] + s[..., 2], s[..., 0] + s[..., 1]], -1)
        w = np.einsum("...ij,...j->...i", V, np.einsum("...ji,...j->...i", V, a) / den)
        dR = R @ skew(w)
        trA = np.trace(A, axis1=-2, axis2=-1)
        return 2 * mu * (dF - dR) + (lam * trA)[..., None, None] * R + (lam * (s.sum(-1) - 3))[..., None, None] * dR


MATERIAL = Corotational
