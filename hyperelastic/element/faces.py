"""Integrals over boundary facets: 3-node triangles (P1) and 6-node triangles (P2, element.tri_shapes, possibly
curved), in the reference configuration X or the current one x. A facet's area element at a point of the
reference triangle is |x_xi x x_eta| dxi deta, x_xi = sum_a dN_a/dxi x_a; the face rule is exact for the
products of shape functions on straight facets (element.Element.face_rule)."""
import numpy as np

from .reference import TRI_RULES, tri_shapes


def order_of(tris):
    return 1 if tris.shape[1] == 3 else 2


def face_tabulation(tris):
    """(N (nq, k), dN (nq, k, 2), w (nq,)) of the facets' element at the face rule's points."""
    order = order_of(tris)
    pts, w = TRI_RULES[2 if order == 1 else 4]
    N, dN = tri_shapes(order, pts)
    return N, dN, w


def tangents(x, tris, dN):
    """(x_xi, x_eta) (ntri, nq, 3) at the rule's points, x the nodes' positions (n, 3)."""
    xt = x[tris]                                                   # (ntri, k, 3)
    return np.einsum("qa,tai->tqi", dN[:, :, 0], xt), np.einsum("qa,tai->tqi", dN[:, :, 1], xt)


def areas(X, tris):
    """(ntri,) each facet's area."""
    if order_of(tris) == 1:
        return 0.5 * np.linalg.norm(np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]), axis=1)
    N, dN, w = face_tabulation(tris)
    a, b = tangents(X, tris, dN)
    return np.linalg.norm(np.cross(a, b), axis=2) @ w


def shares(X, tris):
    """(ntri, k) int N_a dA over each facet (the nodal load of a unit traction)."""
    if order_of(tris) == 1:
        return np.repeat(areas(X, tris)[:, None] / 3.0, 3, axis=1)
    N, dN, w = face_tabulation(tris)
    a, b = tangents(X, tris, dN)
    return (np.linalg.norm(np.cross(a, b), axis=2) * w) @ N


def mass(X, tris):
    """(ntri, k, k) int N_a N_b dA over each facet."""
    if order_of(tris) == 1:
        return areas(X, tris)[:, None, None] * ((np.ones((3, 3)) + np.eye(3)) / 12.0)
    N, dN, w = face_tabulation(tris)
    a, b = tangents(X, tris, dN)
    da = np.linalg.norm(np.cross(a, b), axis=2) * w                  # (ntri, nq)
    return np.einsum("tq,qa,qb->tab", da, N, N)


def coo_pattern(tris):
    """(rows, cols) of the dense (3k x 3k) blocks coupling the dofs of each facet's k nodes, row-major in
    (node a, component i) x (node b, component j)."""
    k3 = 3 * tris.shape[1]
    dofs = (3 * tris[:, :, None] + np.arange(3)).reshape(-1, k3)
    return np.repeat(dofs, k3, axis=1).ravel(), np.tile(dofs, (1, k3)).ravel()
