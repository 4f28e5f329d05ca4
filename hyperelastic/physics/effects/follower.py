from dataclasses import dataclass

import numpy as np

from ...core.options import Row, needs
from ...element import faces
from .base import Effect, Spec, load_factor, timed
from .traction import read_faces, surfaces


class FollowerTwist(Effect):
    """Follower traction depending on current positions: t_y = k z, t_z = -k y on a face, i.e.
    t(x) = T x with T = k [[0,0,0],[0,0,1],[0,-1,0]], integrated over the reference area:
    f_a = sum_b (int N_a N_b dA) T x_b, int N_a N_b dA = A (1 + delta_ab)/12 on a 3-node triangle (faces.mass
    on a 6-node one). Optional ramp * min(t,1). Its Jacobian -dF/dx is not symmetric (T is skew): use GMRES
    with it."""
    name = "follower_traction"
    symmetric = False
    conservative = False   # t = T x with T skew has no potential

    def __init__(self, X, tris, k, scale=None, nlv=0):
        super().__init__()
        self.tris = tris
        self.A = faces.areas(X, tris)
        self.T = float(k) * np.array([[0.0, 0, 0], [0, 0, 1], [0, -1, 0]])
        self.scale_param = scale
        self.s = 1.0
        self.Mf = (np.ones((3, 3)) + np.eye(3)) / 12.0
        self.Mt = None if tris.shape[1] == 3 else faces.mass(X, tris)     # 6-node faces: (ntri, 6, 6)

    def begin_step(self, t, h, xn, vn):
        self.s = load_factor(self.scale_param, t)

    def _force(self, x, out, sign):
        xt = x.reshape(-1, 3)[self.tris]                         # (ntri, nodes, 3)
        if self.Mt is None:
            mx = np.einsum("ab,tbj->taj", self.Mf, xt) * self.A[:, None, None]
        else:
            mx = np.einsum("tab,tbj->taj", self.Mt, xt)
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
        return faces.coo_pattern(self.tris)

    def coo_values(self, out):
        if self.Mt is None:
            blk = -self.s * np.einsum("t,ab,ij->taibj", self.A, self.Mf, self.T)  # (ntri, 3, 3, 3, 3)
        else:
            blk = -self.s * np.einsum("tab,ij->taibj", self.Mt, self.T)          # (ntri, 6, 3, 6, 3)
        out[:] = blk.reshape(len(self.tris), -1).ravel()


@dataclass(frozen=True)
class Twist:
    k: float          # [Pa/m]
    faces: tuple
    scale: object


def _read(opts, where):
    faces, scale = read_faces(opts)
    k = opts.real("traction_twist", None)
    if k is None:
        raise needs(where, "follower_traction", "-traction_twist k")
    return Twist(k, faces, scale)


SPEC = Spec(
    "follower_traction", "a follower twist t = T x on surfaces", implied_by=("traction_twist",), read=_read,
    sets=surfaces("traction_face"), shares=("traction_face", "traction_ramp", "traction_time"),
    build=lambda p, ctx: [FollowerTwist(ctx.space.X, ctx.space.set_triangles([n for n, _ in p.faces]), p.k,
                                        p.scale, ctx.space.nlv)],
    rows=(Row(("traction_twist",), "-traction_twist k", "follower twist t_y = k z, t_z = −k y (current positions) "
              "on the surfaces and with the time function of `-traction` (`-traction_face`, `-traction_ramp`, "
              "`-traction_time`); not symmetric: GMRES"),))
