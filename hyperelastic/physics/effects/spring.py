"""Elastic support (a spring or Robin boundary; Abaqus' "elastic foundation"): on named surfaces the
traction -k (x - X) per reference area, in all components or those named (`S:z`), so that a part can be
held without a rigid clamp. Energy 1/2 k int |x - X|^2 dA over the surfaces = 1/2 k d^T M_s d, d = x - X per
held component, M_s the facets' mass matrix int N_a N_b dA (faces.mass: A (1 + delta_ab)/12 on a 3-node
triangle). Its tangent k M_s is constant and symmetric."""
from dataclasses import dataclass

import numpy as np

from ...core.options import Row, facet_sets, needs
from .base import Energy, LoadKind, QuadraticEffect, Spec, timed
from ...element import faces


class Spring(QuadraticEffect):
    name = "spring"
    symmetric = True

    def __init__(self, X, tris, k, mask):
        """tris (ntri, 3 or 6) local nodes; k [N/m^3]; mask (ntri, 3): the components each facet holds."""
        super().__init__()
        self.tris = np.asarray(tris, np.int64)
        self.X = np.asarray(X, float).reshape(-1, 3)
        self.Mk = float(k) * faces.mass(self.X, self.tris)                    # (ntri, k, k)
        self.mask = np.asarray(mask, float).reshape(-1, 3)

    def _apply(self, d, out, sign=1.0):
        """out += sign k M_s d (d: a local array, 3 per node)."""
        dt = d.reshape(-1, 3)[self.tris] * self.mask[:, None, :]                 # (ntri, nodes, 3)
        f = np.einsum("tab,tbi->tai", self.Mk, dt) * self.mask[:, None, :]
        np.add.at(out.reshape(-1, 3), self.tris, sign * f)

    def origin(self):
        return self.X.ravel()

    @timed("applies")
    def diag(self, d):
        diag = np.einsum("taa->ta", self.Mk)[:, :, None] * self.mask[:, None, :]
        np.add.at(d.reshape(-1, 3), self.tris, diag)

    def coo_pattern(self):
        """(a, i), (b, i) for every pair of a facet's nodes and every component."""
        t, k = self.tris.shape
        dofs = 3 * self.tris[:, :, None] + np.arange(3)                       # (ntri, a, i)
        rows = np.broadcast_to(dofs[:, :, None, :], (t, k, k, 3))              # (t, a, b, i)
        cols = np.broadcast_to(dofs[:, None, :, :], (t, k, k, 3))
        return rows.ravel().copy(), cols.ravel().copy()

    def coo_values(self, out):
        out[:] = (self.Mk[:, :, :, None] * self.mask[:, None, None, :]).ravel()

    def energy(self, x, v):
        return {"spring_energy": self.potential(x)}


@dataclass(frozen=True)
class Support:
    k: float          # stiffness per reference area [N/m^3 = Pa/m]
    faces: tuple      # ((set name, components), ...)


def spring_mask(faces_, tris_of):
    """(facets, (ntri, 3) held components) of [(set, components)]: a facet in several sets holds the union of
    their components."""
    tris, masks = [], []
    for name, comps in faces_:
        t = tris_of([name])
        tris.append(t)
        masks.append(np.broadcast_to(np.array([c in comps for c in "xyz"]), (len(t), 3)))
    t, m = np.concatenate(tris), np.concatenate(masks)
    key = np.sort(t, axis=1)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    held = np.zeros((len(first), 3), bool)
    np.logical_or.at(held, inv.ravel(), m)
    return t[first], held


def build_spring(k, faces_, ctx):
    tris, mask = spring_mask(faces_, ctx.space.set_triangles)
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
    load=LoadKind("real", lambda k, faces_, scale: Support(k, faces_), "`-L1_spring k` (elastic support; faces may "
                  "name components, no time function)", components=True, timed=False, minimum=0),
    rows=(Row(("spring", "spring_faces"), "-spring k -spring_faces S[:xyz],…",
              "elastic support (elastic foundation): the traction −k (x − X) [k in Pa/m, per reference area] on "
              "the surfaces, in all components or those named (`bottom:z`); holds a part without a clamp"),))
