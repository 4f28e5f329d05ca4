"""Reference elements and quadrature: linear (P1, 4 nodes) and quadratic (P2, 10 nodes) tetrahedra and
their faces (3- and 6-node triangles).

Reference tetrahedron: vertices (0,0,0), (1,0,0), (0,1,0), (0,0,1), volume 1/6; barycentric coordinates
L0 = 1 - xi - eta - zeta, L1 = xi, L2 = eta, L3 = zeta. Node order (VTK's and meshio's `tetra10`, which is
gmsh's tetrahedron of order 2 as meshio reads it): the four vertices, then the midpoints of the edges
EDGES = (0,1), (1,2), (0,2), (0,3), (1,3), (2,3). P2 shape functions (Zienkiewicz, Taylor & Zhu, The
Finite Element Method, 7th ed., 2013, sec. 6.6): vertex N_i = L_i (2 L_i - 1), edge (i, j): 4 L_i L_j.
A face (triangle) has its three vertices and, for P2, the midpoints of (0,1), (1,2), (0,2).

Quadrature rules (weights summing to the reference measure; all weights positive), each with the
polynomial degree it integrates exactly (tests/test_quadratic.py checks every monomial up to that degree):
  tetrahedron  degree 1: the centroid; degree 2: 4 points (Keast 1986, rule 2; a = (5 + 3 sqrt 5)/20);
               degree 5: 14 points (Walkington, "Quadrature on simplices of arbitrary dimension", 2000;
               the rule of Keast 1986 without negative weights)
  triangle     degree 2: 3 interior points (Strang & Fix 1973); degree 4: 6 points (Dunavant 1985)
"""
import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import UserError

EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
FACE_EDGES = ((0, 1), (1, 2), (0, 2))


def cell_edges(corners):
    """(nc * 6, 2) each cell's edges in EDGES order by their ends (corners (nc, >= 4): ids of its corners first),
    the smaller first."""
    return np.sort(np.stack([corners[:, [i, j]] for i, j in EDGES], axis=1), axis=2).reshape(-1, 2)
# the reference nodes of a quadratic tetrahedron (the corners, then the midpoints of EDGES); a linear one's: the first 4
REFERENCE_NODES = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, 0, 0], [.5, .5, 0], [0, .5, 0],
                            [0, 0, .5], [.5, 0, .5], [0, .5, .5]])
ORDERS = (1, 2)


def p1_at_nodes():
    """(10, 4): the linear shape functions (the barycentric coordinates L0..L3) at the quadratic tetrahedron's
    reference nodes: 1 at a corner itself, 1/2 at both ends of an edge's midpoint, exactly. A cell's rows of the
    P2 -> P1 interpolation that p-multigrid's prolongation (solving/pmg.py) and the C p1_galerkin are made of."""
    X = REFERENCE_NODES
    return np.column_stack([1.0 - X.sum(axis=1), X])


def _perms(bary):
    """The distinct permutations of a barycentric point."""
    return sorted(set(itertools.permutations(bary)))


def _tet_rule(groups):
    """(points (n,3) in xi, eta, zeta; weights (n,)) from [(barycentric orbit generator, weight)]; the weights
    are fractions of the reference volume."""
    pts, w = [], []
    for bary, weight in groups:
        for p in _perms(bary):
            pts.append(p[1:])
            w.append(weight / 6.0)
    return np.array(pts, float), np.array(w, float)


_A2 = (5 + 3 * math.sqrt(5)) / 20
_B2 = (5 - math.sqrt(5)) / 20
_W14 = (0.0734930431163619495, 0.112687925718015850, 0.0425460207770814664)
_A14, _B14, _C14 = 0.0927352503108912264, 0.310885919263300610, 0.0455037041256496494
TET_RULES = {
    1: _tet_rule([((0.25, 0.25, 0.25, 0.25), 1.0)]),
    2: _tet_rule([((_A2, _B2, _B2, _B2), 0.25)]),
    5: _tet_rule([((1 - 3 * _A14, _A14, _A14, _A14), _W14[0]), ((1 - 3 * _B14, _B14, _B14, _B14), _W14[1]),
                  ((0.5 - _C14, 0.5 - _C14, _C14, _C14), _W14[2])]),
}


def _tri_rule(groups):
    pts, w = [], []
    for bary, weight in groups:
        for p in _perms(bary):
            pts.append(p[1:])
            w.append(weight / 2.0)
    return np.array(pts, float), np.array(w, float)


_D4 = ((0.445948490915964886318329253883, 0.223381589678011465944845405862),
       (0.091576213509770743459571463402, 0.109951743655321867388487927471))
TRI_RULES = {
    2: _tri_rule([((2 / 3, 1 / 6, 1 / 6), 1 / 3)]),
    4: _tri_rule([((1 - 2 * a, a, a), w) for a, w in _D4]),
}


def tet_shapes(order, pts):
    """(N (n, nn), dN (n, nn, 3)): the shape functions and their reference gradients at points (n, 3)."""
    pts = np.atleast_2d(pts)
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    L = np.stack([1 - x - y - z, x, y, z], axis=1)                                 # (n, 4)
    dL = np.array([[-1.0, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]])                # (4, 3)
    if order == 1:
        return L, np.broadcast_to(dL, (len(pts), 4, 3)).copy()
    N = np.concatenate([L * (2 * L - 1)] + [4 * L[:, [i]] * L[:, [j]] for i, j in EDGES], axis=1)
    dN = np.concatenate([(4 * L - 1)[:, :, None] * dL[None]]
                        + [4 * (L[:, [i], None] * dL[None, [j]] + L[:, [j], None] * dL[None, [i]])
                           for i, j in EDGES], axis=1)
    return N, dN


def tri_shapes(order, pts):
    """(N (n, nf), dN (n, nf, 2)) of the face element (3- or 6-node triangle) at points (n, 2)."""
    pts = np.atleast_2d(pts)
    x, y = pts[:, 0], pts[:, 1]
    L = np.stack([1 - x - y, x, y], axis=1)
    dL = np.array([[-1.0, -1], [1, 0], [0, 1]])
    if order == 1:
        return L, np.broadcast_to(dL, (len(pts), 3, 2)).copy()
    N = np.concatenate([L * (2 * L - 1)] + [4 * L[:, [i]] * L[:, [j]] for i, j in FACE_EDGES], axis=1)
    dN = np.concatenate([(4 * L - 1)[:, :, None] * dL[None]]
                        + [4 * (L[:, [i], None] * dL[None, [j]] + L[:, [j], None] * dL[None, [i]])
                           for i, j in FACE_EDGES], axis=1)
    return N, dN


@dataclass(frozen=True)
class Element:
    """A Lagrange tetrahedron of `order` with the quadrature rule of `degree` for the stiffness (and the
    rules the mass matrix and the face integrals need to be exact on straight cells). Decided once per run
    (`decide`) and carried from there by the space to the kernels."""
    order: int
    degree: int

    @classmethod
    def decide(cls, order, degree, mesh_order):
        """The run's element: `order` (-order; 0: the mesh's own, `mesh_order`) with the stiffness rule of `degree`
        (-quadrature_degree; 0: DEFAULT_DEGREE). Refused with one line where the pair cannot be right: a rule on
        linear tetrahedra (integrated exactly at one point), or one point on quadratic ones (its zero-energy modes
        leave the stiffness singular: a bend "converged" to a tip 1e9 m away)."""
        order = order or mesh_order
        if order not in ORDERS:
            raise UserError(f"option -order: {order}: give 1 (linear, 4-node) or 2 (quadratic, 10-node tetrahedra)")
        if degree and degree not in TET_RULES:
            raise UserError(f"option -quadrature_degree: {degree}: the rules are of degree "
                            f"{', '.join(map(str, TET_RULES))}")
        if degree and order == 1:
            raise UserError("option -quadrature_degree: linear tetrahedra are integrated exactly at one point (it is "
                            "for -order 2, or a quadratic mesh)")
        if order == 2 and degree and degree < MIN_DEGREE[2]:
            raise UserError(f"option -quadrature_degree {degree}: {len(TET_RULES[degree][1])} point leaves quadratic "
                            "tetrahedra with zero-energy modes (the stiffness is singular); give "
                            + " or ".join(str(d) for d in TET_RULES if d >= MIN_DEGREE[2]))
        return cls(order, degree or DEFAULT_DEGREE[order])

    @property
    def nodes(self):
        return 4 if self.order == 1 else 10

    @property
    def face_nodes(self):
        return 3 if self.order == 1 else 6

    def rule(self):
        """(points, weights) of the stiffness rule."""
        return TET_RULES[self.degree]

    def tabulate(self):
        """(N (nq, nn), dN (nq, nn, 3)) at the stiffness rule's points."""
        return tet_shapes(self.order, self.rule()[0])

    def mass_rule(self):
        """The rule for N_a N_b (degree 2 order): exact on straight cells."""
        return TET_RULES[2 if self.order == 1 else 5]

    def face_rule(self):
        """The rule for face integrals (N_a N_b of the face element, and the follower pressure's N_a x_xi x x_eta)."""
        return TRI_RULES[2 if self.order == 1 else 4]


DEFAULT_DEGREE = {1: 1, 2: 2}      # P1: exact with one point; P2: see docs/design.md ("Quadratic tetrahedra")
MIN_DEGREE = {1: 1, 2: 2}          # the lowest stiffness rule without zero-energy modes


def geometry(X, cells, dN, w):
    """Per (cell, point): (Jinv (nc, nq, 3, 3), weights |det J| w (nc, nq), det J (nc, nq)) of the map
    X(xi) = sum_a X_a N_a(xi) of cells (nc, nn) with node coordinates X, at points with reference gradients
    dN (nq, nn, 3) and reference weights w (nq,)."""
    J = np.einsum("cai,qaj->cqij", X[cells], dN)           # dX_i / dxi_j
    det = np.linalg.det(J)
    return np.linalg.inv(J), np.abs(det) * w[None, :], det
