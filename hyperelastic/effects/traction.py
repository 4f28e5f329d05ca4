import numpy as np

from .base import Effect, ramp, timed


def triangle_areas(X, tris):
    return 0.5 * np.linalg.norm(np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]), axis=1)


class Traction(Effect):
    """Dead-load surface traction t [Pa] per unit reference area on a face, scaled by
    ramp * min(t,1) when a ramp is given: f_a = int t N_a dA = t A/3 per triangle vertex."""
    name = "traction"

    def __init__(self, X, tris, traction, scale=None, nlv=0):
        super().__init__()
        self.scale_param = scale
        share = np.zeros(nlv)
        np.add.at(share, tris.ravel(), np.repeat(triangle_areas(X, tris) / 3.0, 3))
        self.f0 = (share[:, None] * np.asarray(traction, float)[None, :]).ravel()
        self.s = 1.0

    def begin_step(self, t, h, xn, vn):
        self.s = 1.0 if self.scale_param is None else ramp(t, self.scale_param)

    @timed("evals")
    def residual(self, x, r):
        r -= self.s * self.f0

    def potential(self, x):
        return -self.s * float(self.f0 @ x)

    def energy(self, x, v):
        return {"traction_work": self.s * float(self.f0 @ x)}


class FollowerTwist(Effect):
    """Follower traction depending on current positions: t_y = k z, t_z = -k y on a face, i.e.
    t(x) = T x with T = k [[0,0,0],[0,0,1],[0,-1,0]], integrated over the reference area:
    f_a = sum_b (int N_a N_b dA) T x_b, int N_a N_b dA = A (1 + delta_ab)/12. Optional ramp * min(t,1).
    Its Jacobian -dF/dx is not symmetric (T is skew): use GMRES with it."""
    name = "follower_traction"
    symmetric = False
    conservative = False   # t = T x with T skew has no potential

    def __init__(self, X, tris, k, scale=None, nlv=0):
        super().__init__()
        self.tris = tris
        self.A = triangle_areas(X, tris)
        self.T = float(k) * np.array([[0.0, 0, 0], [0, 0, 1], [0, -1, 0]])
        self.scale_param = scale
        self.s = 1.0
        self.Mf = (np.ones((3, 3)) + np.eye(3)) / 12.0

    def begin_step(self, t, h, xn, vn):
        self.s = 1.0 if self.scale_param is None else ramp(t, self.scale_param)

    def _force(self, x, out, sign):
        xt = x.reshape(-1, 3)[self.tris]                         # (ntri, 3 vertices, 3)
        mx = np.einsum("ab,tbj->taj", self.Mf, xt) * self.A[:, None, None]
        f = np.einsum("ij,taj->tai", self.T, mx) * (sign * self.s)
        np.add.at(out.reshape(-1, 3), self.tris, f)

    @timed("evals")
    def residual(self, x, r):
        self._force(x, r, -1.0)

    def linearize(self, x):
        pass  # the traction is linear in x

    @timed("applies")
    def apply(self, v, y):
        self._force(v, y, -1.0)

    @timed("applies")
    def diag(self, d):
        pass  # T has a zero diagonal

    def coo_pattern(self):
        dofs = (3 * self.tris[:, :, None] + np.arange(3)).reshape(-1, 9)   # (ntri, 9)
        rows = np.repeat(dofs, 9, axis=1).ravel()
        cols = np.tile(dofs, (1, 9)).ravel()
        return rows, cols

    def coo_values(self, out):
        blk = -self.s * np.einsum("t,ab,ij->taibj", self.A, self.Mf, self.T)  # (ntri,3,3,3,3)
        out[:] = blk.reshape(len(self.tris), 81).ravel()
