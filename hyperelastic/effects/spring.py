"""Elastic support (a spring or Robin boundary; Abaqus' "elastic foundation"): on named surfaces the
traction -k (x - X) per reference area, in all components or those named (`S:z`), so that a part can be
held without a rigid clamp. Energy 1/2 k int |x - X|^2 dA over the surfaces; with P1 triangles
int N_a N_b dA = A (1 + delta_ab) / 12, so on a triangle f_a = -k A/12 (d_a + sum_b d_b), d = x - X,
per held component. Its tangent k M_s (M_s the surface mass matrix) is constant and symmetric."""
from dataclasses import dataclass

import numpy as np

from ..options import Row, facet_sets, needs
from .base import Effect, Energy, Spec, timed
from .traction import triangle_areas


class Spring(Effect):
    name = "spring"
    symmetric = True

    def __init__(self, X, tris, k, mask):
        """tris (ntri, 3) local vertices; k [N/m^3]; mask (ntri, 3): the components each triangle holds."""
        super().__init__()
        self.tris = np.asarray(tris, np.int64)
        self.X = np.asarray(X, float).reshape(-1, 3)
        self.w = float(k) * triangle_areas(self.X, self.tris) / 12.0        # k A/12 per triangle
        self.mask = np.asarray(mask, float).reshape(-1, 3)

    def _apply(self, d, out, sign=1.0):
        """out += sign k M_s d (d: a local array, 3 per vertex)."""
        dt = d.reshape(-1, 3)[self.tris] * self.mask[:, None, :]                 # (ntri, 3 vertices, 3)
        f = self.w[:, None, None] * (dt + dt.sum(axis=1, keepdims=True)) * self.mask[:, None, :]
        np.add.at(out.reshape(-1, 3), self.tris, sign * f)

    @timed("evals")
    def residual(self, x, r):
        self._apply(x - self.X.ravel(), r)

    def potential(self, x):
        y = np.zeros_like(x)
        d = x - self.X.ravel()
        self._apply(d, y)
        return 0.5 * float(d @ y)

    @timed("applies")
    def apply(self, v, y):
        self._apply(v, y)

    @timed("applies")
    def diag(self, d):
        np.add.at(d.reshape(-1, 3), self.tris, np.repeat((2.0 * self.w[:, None] * self.mask)[:, None, :], 3, axis=1))

    def coo_pattern(self):
        """(a, i), (b, i) for every pair of a triangle's vertices and every component: 27 per triangle."""
        dofs = 3 * self.tris[:, :, None] + np.arange(3)                       # (ntri, a, i)
        rows = np.broadcast_to(dofs[:, :, None, :], (len(self.tris), 3, 3, 3))  # (t, a, b, i)
        cols = np.broadcast_to(dofs[:, None, :, :], (len(self.tris), 3, 3, 3))
        return rows.ravel().copy(), cols.ravel().copy()

    def coo_values(self, out):
        m = (np.ones((3, 3)) + np.eye(3))[None, :, :, None] * self.w[:, None, None, None] * self.mask[:, None, None, :]
        out[:] = m.ravel()

    def energy(self, x, v):
        return {"spring_energy": self.potential(x)}


@dataclass(frozen=True)
class Support:
    k: float          # stiffness per reference area [N/m^3 = Pa/m]
    faces: tuple      # ((set name, components), ...)


def spring_mask(space, faces, tris_of):
    """(triangles, (ntri, 3) held components) of [(set, components)]: a triangle in several sets holds the
    union of their components."""
    tris, masks = [], []
    for name, comps in faces:
        t = tris_of([name])
        tris.append(t)
        masks.append(np.broadcast_to(np.array([c in comps for c in "xyz"]), (len(t), 3)))
    if not tris:
        return np.zeros((0, 3), np.int64), np.zeros((0, 3), bool)
    t, m = np.concatenate(tris), np.concatenate(masks)
    key = np.sort(t, axis=1)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    held = np.zeros((len(first), 3), bool)
    np.logical_or.at(held, inv.ravel(), m)
    return t[first], held


def build_spring(k, faces, ctx):
    tris, mask = spring_mask(ctx.space, faces, ctx.space.set_triangles)
    return Spring(ctx.space.X, tris, k, mask)


def _read(opts, where):
    k = opts.real("spring", None, minimum=0)
    if k is None or not opts.has("spring_faces"):
        raise needs(where, "spring", "-spring k and -spring_faces surfaces")
    return Support(k, tuple(facet_sets(opts, "spring_faces", components=True)))


SPEC = Spec(
    "spring", "elastic support -k (x - X) per reference area on surfaces", implied_by=("spring",), read=_read,
    sets=lambda p: [("spring_faces", n, "facets") for n, _ in p.faces],
    build=lambda p, ctx: [build_spring(p.k, p.faces, ctx)],
    energies=(Energy("spring_energy", 1, "energy 1/2 k int |x - X|^2 dA of the elastic supports [J]"),),
    rows=(Row(("spring", "spring_faces"), "-spring k -spring_faces S[:xyz],…",
              "elastic support (elastic foundation): the traction −k (x − X) [k in Pa/m, per reference area] on "
              "the surfaces, in all components or those named (`bottom:z`); holds a part without a clamp"),))
