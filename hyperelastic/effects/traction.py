import numpy as np

from .base import Effect, load_factor, timed


def triangle_areas(X, tris):
    return 0.5 * np.linalg.norm(np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]), axis=1)


def triangle_coo_pattern(tris):
    """(rows, cols) of the dense 9x9 blocks coupling the dofs of each triangle's three vertices,
    row-major in (vertex a, component i) x (vertex b, component j)."""
    dofs = (3 * tris[:, :, None] + np.arange(3)).reshape(-1, 9)   # (ntri, 9)
    return np.repeat(dofs, 9, axis=1).ravel(), np.tile(dofs, (1, 9)).ravel()


class Traction(Effect):
    """Dead-load surface traction t [Pa] per unit reference area on a face, scaled by
    its time function (base.load_factor: a ramp A min(t,1) or -NAME_time): f_a = int t N_a dA = t A/3 per triangle vertex."""
    name = "traction"
    constant = True

    def __init__(self, X, tris, traction, scale=None, nlv=0):
        super().__init__()
        self.scale_param = scale
        share = np.zeros(nlv)
        np.add.at(share, tris.ravel(), np.repeat(triangle_areas(X, tris) / 3.0, 3))
        self.f0 = (share[:, None] * np.asarray(traction, float)[None, :]).ravel()
        self.loaded = np.flatnonzero(self.f0)            # the face's dofs: the residual touches only them
        self.f0_loaded = self.f0[self.loaded]
        self.s = 1.0

    def begin_step(self, t, h, xn, vn):
        self.s = load_factor(self.scale_param, t)

    @timed("evals")
    def residual(self, x, r):
        self.add_constant(r)

    def add_constant(self, r):
        r[self.loaded] -= self.s * self.f0_loaded

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
        self.s = load_factor(self.scale_param, t)

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
        return triangle_coo_pattern(self.tris)

    def coo_values(self, out):
        blk = -self.s * np.einsum("t,ab,ij->taibj", self.A, self.Mf, self.T)  # (ntri,3,3,3,3)
        out[:] = blk.reshape(len(self.tris), 81).ravel()


class Pressure(Effect):
    """Follower pressure p [Pa] on boundary facets, normal to the current surface (positive: pushing
    in): traction -p n da. On a triangle with current vertices x1, x2, x3 (ordered so that
    c = (x2 - x1) x (x3 - x1) points out of the body), int N_a n da = c/6 for each vertex a, so
    f_a = -p c/6 and the residual adds p c/6 to each of its three vertices. Exact tangent:
    dc/dx1 = [x3 - x2]x, dc/dx2 = [x1 - x3]x, dc/dx3 = [x2 - x1]x (the skew matrix [w]x u = w x u),
    the same for every row a; not symmetric. p scaled by ramp * min(t,1) when a ramp is given.
    (Bonet & Wood, Nonlinear Continuum Mechanics for FEA, 1997, sec. 8.4: the pressure load component.)"""
    name = "pressure"
    linear = False
    symmetric = False
    conservative = False   # only a closed surface's pressure has a potential (p times the enclosed volume)

    def __init__(self, X, tris, p, scale=None):
        super().__init__()
        self.tris = np.asarray(tris, np.int64)
        self.p = float(p)
        self.scale_param = scale
        self.s = 1.0
        self.x_lin = None

    def begin_step(self, t, h, xn, vn):
        self.s = load_factor(self.scale_param, t)

    def _corners(self, x):
        xt = x.reshape(-1, 3)[self.tris]
        return xt[:, 0], xt[:, 1], xt[:, 2]

    @timed("evals")
    def residual(self, x, r):
        x1, x2, x3 = self._corners(x)
        c = np.cross(x2 - x1, x3 - x1) * (self.s * self.p / 6.0)
        np.add.at(r.reshape(-1, 3), self.tris, np.repeat(c[:, None, :], 3, axis=1))

    def linearize(self, x):
        self.x_lin = x.copy()

    def _edges(self):
        """The vectors w_b with dc/dx_b = [w_b]x: (ntri, 3 corners, 3)."""
        x1, x2, x3 = self._corners(self.x_lin)
        return np.stack([x3 - x2, x1 - x3, x2 - x1], axis=1)

    @timed("applies")
    def apply(self, v, y):
        w = self._edges()
        vt = v.reshape(-1, 3)[self.tris]                               # (ntri, 3, 3)
        dc = np.cross(w, vt).sum(axis=1) * (self.s * self.p / 6.0)     # sum_b w_b x v_b
        np.add.at(y.reshape(-1, 3), self.tris, np.repeat(dc[:, None, :], 3, axis=1))

    @timed("applies")
    def diag(self, d):
        pass  # the diagonal entries of [w]x are zero

    def coo_pattern(self):
        return triangle_coo_pattern(self.tris)

    def coo_values(self, out):
        w = self._edges()                                               # (ntri, b, 3)
        skew = np.zeros(w.shape[:2] + (3, 3))
        skew[..., 0, 1], skew[..., 0, 2] = -w[..., 2], w[..., 1]
        skew[..., 1, 0], skew[..., 1, 2] = w[..., 2], -w[..., 0]
        skew[..., 2, 0], skew[..., 2, 1] = -w[..., 1], w[..., 0]
        blk = np.broadcast_to((self.s * self.p / 6.0) * skew[:, None].transpose(0, 1, 3, 2, 4),
                              (len(self.tris), 3, 3, 3, 3))              # (t, a, i, b, j)
        out[:] = np.ascontiguousarray(blk).reshape(len(self.tris), 81).ravel()
