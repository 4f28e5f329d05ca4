from dataclasses import dataclass

import numpy as np

from ...element import faces
from ...core.options import Row, facet_sets, needs, time_function
from .base import Effect, LoadKind, Spec, load_factor, timed
from .traction import surfaces


def skew(w):
    """(..., 3, 3) with skew(w) u = w x u."""
    out = np.zeros(w.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


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
        return faces.coo_pattern(self.tris)

    def coo_values(self, out):
        w = self._edges()                                               # (ntri, b, 3)
        blk = np.broadcast_to((self.s * self.p / 6.0) * skew(w)[:, None].transpose(0, 1, 3, 2, 4),
                              (len(self.tris), 3, 3, 3, 3))              # (t, a, i, b, j)
        out[:] = np.ascontiguousarray(blk).reshape(len(self.tris), 81).ravel()


class CurvedPressure(Pressure):
    """The follower pressure on 6-node (possibly curved) facets: with c(q) = x_xi x x_eta at the face rule's
    points (faces.py), int N_a n da = sum_q w_q N_a(q) c(q), so the residual adds p sum_q w_q N_a(q) c(q).
    Exact tangent: dc = v_xi x x_eta + x_xi x v_eta with v_xi = sum_b dN_b/dxi v_b, i.e. the block of
    nodes (a, b) is p sum_q w_q N_a (dN_b/dxi [-x_eta]x + dN_b/deta [x_xi]x); not symmetric."""

    def __init__(self, X, tris, p, scale=None):
        super().__init__(X, tris, p, scale)
        self.N, self.dN, self.w = faces.face_tabulation(self.tris)

    @timed("evals")
    def residual(self, x, r):
        a, b = faces.tangents(x.reshape(-1, 3), self.tris, self.dN)
        c = np.cross(a, b) * (self.s * self.p)                          # (ntri, nq, 3)
        np.add.at(r.reshape(-1, 3), self.tris, np.einsum("q,qa,tqi->tai", self.w, self.N, c))

    @timed("applies")
    def apply(self, v, y):
        a, b = faces.tangents(self.x_lin.reshape(-1, 3), self.tris, self.dN)
        va, vb = faces.tangents(v.reshape(-1, 3), self.tris, self.dN)
        dc = (np.cross(va, b) + np.cross(a, vb)) * (self.s * self.p)
        np.add.at(y.reshape(-1, 3), self.tris, np.einsum("q,qa,tqi->tai", self.w, self.N, dc))

    def coo_values(self, out):
        a, b = faces.tangents(self.x_lin.reshape(-1, 3), self.tris, self.dN)
        # (t, q, b, i, j): dN_b/dxi [-x_eta]x + dN_b/deta [x_xi]x
        dcdx = (np.einsum("qb,tqij->tqbij", self.dN[:, :, 0], skew(-b))
                + np.einsum("qb,tqij->tqbij", self.dN[:, :, 1], skew(a)))
        blk = (self.s * self.p) * np.einsum("q,qa,tqbij->taibj", self.w, self.N, dcdx)
        out[:] = blk.reshape(len(self.tris), -1).ravel()


def pressure(X, tris, p, scale=None):
    """The follower pressure effect of 3- or 6-node facets."""
    return (Pressure if tris.shape[1] == 3 else CurvedPressure)(X, tris, p, scale)


@dataclass(frozen=True)
class FollowerPressure:
    value: float      # [Pa], positive pushes in
    faces: tuple
    scale: object


def _read(opts, where):
    p = opts.real("pressure", None)
    if p is None or not opts.has("pressure_faces"):
        raise needs(where, "pressure", "-pressure p and -pressure_faces surfaces")
    return FollowerPressure(p, tuple(facet_sets(opts, "pressure_faces")), time_function(opts, "pressure"))


def build_pressure(p, ctx):
    return [pressure(ctx.space.X, ctx.space.set_triangles([n for n, _ in p.faces]), p.value, p.scale)]


SPEC = Spec(
    "pressure", "a follower pressure normal to the current surface", implied_by=("pressure",), read=_read,
    sets=surfaces("pressure_faces"), build=build_pressure,
    load=LoadKind("real", FollowerPressure, "`-L1_pressure p` (follower)"),
    rows=(Row(("pressure", "pressure_faces", "pressure_ramp", "pressure_time"), "-pressure p -pressure_faces S1,S2,…",
              "follower pressure [Pa] normal to the current surface (positive pushes in), exact tangent; "
              "`-pressure_ramp A` or `-pressure_time EXPR`"),))
