import numpy as np

from .base import Material


def constants(mu, lam):
    """Stable Neo-Hookean's own (mu, lambda, alpha) from the Lame pair, and Psi at rest. The
    reparameterisation ms = 4/3 mu, ls = lam + 5/6 mu makes the small-strain limit linear elasticity
    with (mu, lam) (Smith, de Goes, Kim 2018, sec. 3.4; checked in tests/test_stability.py);
    alpha = 1 + 3 ms / (4 ls) makes the rest state stress-free."""
    ms = 4.0 / 3.0 * mu
    ls = lam + 5.0 / 6.0 * mu
    alpha = 1 + 0.75 * ms / ls
    psi0 = 0.5 * ls * (1 - alpha) ** 2 - 0.5 * ms * np.log(4.0)
    return ms, ls, alpha, psi0


def cofactor(F):
    """dJ/dF = J F^-T, written with cross products of the columns of F so it exists for J <= 0."""
    f0, f1, f2 = F[..., :, 0], F[..., :, 1], F[..., :, 2]
    return np.stack([np.cross(f1, f2), np.cross(f2, f0), np.cross(f0, f1)], axis=-1)


def dcofactor(F, dF):
    f0, f1, f2 = F[..., :, 0], F[..., :, 1], F[..., :, 2]
    d0, d1, d2 = dF[..., :, 0], dF[..., :, 1], dF[..., :, 2]
    return np.stack([np.cross(d1, f2) + np.cross(f1, d2), np.cross(d2, f0) + np.cross(f2, d0),
                     np.cross(d0, f1) + np.cross(f0, d1)], axis=-1)


class StableNeoHookean(Material):
    """Stable Neo-Hookean (Smith, de Goes, Kim, "Stable Neo-Hookean Flesh Simulation", ACM TOG 37(2),
    2018, eq. 14): Psi = ms/2 (I_C - 3) + ls/2 (J - alpha)^2 - ms/2 ln(I_C + 1) - Psi(I), with
    I_C = tr(F^T F). Defined for every F, inverted elements included; its Hessian is not positive
    definite everywhere (see -hessian_projection)."""
    name = "snh"
    summary = "Stable Neo-Hookean, defined for J ≤ 0"
    defined_when_inverted = True

    @staticmethod
    def psi(F, c):
        mu, lam = c
        ms, ls, al, psi0 = constants(mu, lam)
        Ic = np.einsum("...ij,...ij", F, F)
        J = np.linalg.det(F)
        return 0.5 * ms * (Ic - 3) + 0.5 * ls * (J - al) ** 2 - 0.5 * ms * np.log(Ic + 1) - psi0

    @staticmethod
    def P(F, c):
        mu, lam = c
        ms, ls, al, _ = constants(mu, lam)
        Ic = np.einsum("...ij,...ij", F, F)
        J = np.linalg.det(F)
        return (ms * (1 - 1 / (Ic + 1)))[..., None, None] * F + (ls * (J - al))[..., None, None] * cofactor(F)

    @staticmethod
    def dP(F, dF, c):
        mu, lam = c
        ms, ls, al, _ = constants(mu, lam)
        Ic = np.einsum("...ij,...ij", F, F)
        J = np.linalg.det(F)
        C = cofactor(F)
        fd = np.einsum("...ij,...ij", F, dF)
        cd = np.einsum("...ij,...ij", C, dF)
        return ((ms * (1 - 1 / (Ic + 1)))[..., None, None] * dF
                + (2 * ms * fd / (Ic + 1) ** 2)[..., None, None] * F
                + (ls * cd)[..., None, None] * C + (ls * (J - al))[..., None, None] * dcofactor(F, dF))


MATERIAL = StableNeoHookean
