"""Boundary facets and named sets of a tetrahedral mesh.

A boundary facet is a triangle that belongs to exactly one tetrahedron; nothing else is ever loaded or
treated as a face. Sets of boundary facets come from the mesh's physical surfaces (gmsh physical groups
of dimension 2, by name or tag; meshio cell sets or integer cell tags of other formats) or from the
bounding box (left/right = x min/max, front/back = y, bottom/top = z: the boundary facets whose three
vertices lie on that plane, to 1e-6 of the box diagonal) or from the geometry (`x=V`, `y=V`, `z=V`: the boundary
facets on that plane; `box=x0;y0;z0;x1;y1;z1`: those inside the box; `normal=+z` (or -x, ..., or a;b;c): those
whose outward normal is within 1 degree of the direction; the same tolerance). Regions are sets of tetrahedra (physical
volumes). Everything here works on the input mesh on rank 0; space.py carries the sets through
distribution as DMPlex labels.
"""
import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..element import faces
from ..element.reference import EDGES, TET_RULES, tet_shapes
from ..core.arrays import unique
from ..core.errors import UserError

WHOLE_BOUNDARY = "boundary"     # (facets) every boundary facet, where no physical surface has that name
BOX = {"left": (0, "min"), "right": (0, "max"), "front": (1, "min"), "back": (1, "max"),
       "bottom": (2, "min"), "top": (2, "max")}
BOX_TOL = 1e-6                 # of the bounding box diagonal
NORMAL_TOL_DEG = 1.0           # normal=DIR selects the facets whose outward normal is this close to DIR
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
SELECTORS = "x=V, y=V, z=V (a plane), box=x0;y0;z0;x1;y1;z1, normal=+x|-x|+y|-y|+z|-z|a;b;c"
FACE_VERTICES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])   # face k: opposite vertex k
VERTEX_VALUE = 16              # label value of a set's vertices (cells carry their faces' bitmask 1..15)
# integer cell data other formats use for region / boundary tags (meshio names)
TAG_KEYS = ("gmsh:physical", "medit:ref", "cell_tags", "CellEntityIds", "region", "tag")
MATERIAL_LABEL = "material"   # value i+1 on the cells of the i-th region of -regions (its material)
REGION_LABEL = "Cell Sets"     # the DMPlex label of the regions (value: physical tag), as PETSc's gmsh reader


def signed_volumes(points, tets, longest=False):
    """Volume of each tetrahedron (the first four columns of tets), positive when (X1-X0, X2-X0, X3-X0) is
    right-handed: the triple product (X1-X0) . ((X2-X0) x (X3-X0)) / 6 (a closed form, not LAPACK's LU of each
    3x3), on the coordinates' rows (3, n): contiguous vector arithmetic. longest: also each one's longest edge of
    (0,1), (0,2), (0,3), (1,2) (the mesh check's scale)."""
    P = np.ascontiguousarray(np.asarray(points, np.float64).T)
    x0 = P[:, tets[:, 0]]
    a, b, c = (P[:, tets[:, k]] - x0 for k in (1, 2, 3))
    del x0
    V = (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2])
         + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
    if not longest:
        return V
    sq = lambda e: e[0] * e[0] + e[1] * e[1] + e[2] * e[2]       # noqa: E731
    return V, np.sqrt(np.maximum.reduce([sq(a), sq(b), sq(c), sq(b - a)]))     # (edge (1, 2): X2 - X1 = b - a)


def facet_label(name):
    """The DMPlex label of facet set `name`."""
    return f"facets:{name}"


def cell_label(name):
    """The DMPlex label of the cells of volume set `name` (value 1) that an effect acts on."""
    return f"cells:{name}"


def face_keys(tris):
    """One int64 (or row) key per triangle of sorted vertex ids."""
    t = np.sort(tris, axis=1).astype(np.int64)
    if t.size and t.max() < 2 ** 21:
        return (t[:, 0] << 42) | (t[:, 1] << 21) | t[:, 2]
    return np.ascontiguousarray(t).view([("a", np.int64), ("b", np.int64), ("c", np.int64)]).ravel()


def face_incidence(tets, path="mesh"):
    """The tetrahedra of every triangle, from one sort of the 4 faces of each tetrahedron (face index
    4 c + k: face k, opposite vertex k, of tetrahedron c): (boundary, i, j) with `boundary` the sorted face
    indices of the triangles of exactly one tetrahedron, and i, j the two sides of each triangle of two.
    A triangle of three or more tetrahedra (duplicate or overlapping cells) is a UserError."""
    small = tets.size == 0 or int(tets.max()) < 2 ** 31
    faces = (tets.astype(np.int32) if small else tets)[:, FACE_VERTICES].reshape(-1, 3)
    key = face_keys(faces)
    order = np.argsort(key, kind="stable")
    key = key[order]
    same = key[1:] == key[:-1]
    del key
    triple = np.flatnonzero(same[1:] & same[:-1])
    if len(triple):
        cells = sorted(int(c) for c in order[triple[0]:triple[0] + 3] // 4)
        raise UserError(f"mesh '{path}': tetrahedra {cells[0]}, {cells[1]} and {cells[2]} share a face "
                        f"{sorted(faces[order[triple[0]]].tolist())} (duplicate or overlapping tetrahedra)")
    paired = np.zeros(len(order), bool)
    paired[:-1] |= same
    paired[1:] |= same
    return np.sort(order[~paired]), order[:-1][same], order[1:][same]


@dataclass
class NamedSet:
    name: str
    tag: object                 # int physical tag, or None
    kind: str                   # "facets" or "tets"
    items: np.ndarray           # boundary facet indices, or tetrahedron indices
    ignored: int = 0            # triangles of the group that are not boundary facets


@dataclass
class Mesh:
    path: str
    points: np.ndarray          # every node: the vertices, and for quadratic cells the edge nodes
    tets: np.ndarray            # (nc, 4) the corner vertices of each cell (indices into points)
    facet_cell: np.ndarray = None
    facet_k: np.ndarray = None
    groups: dict = field(default_factory=dict)     # name -> NamedSet (physical surfaces and volumes)
    nodes: np.ndarray = None    # (nc, 10) of quadratic cells (element.py's node order), None for linear
    ids: np.ndarray = None      # each point's input-mesh index where `points` is not the input's numbering

    # a Mesh is the whole mesh; a subclass may hold one rank's part of it (discretization.slices.SliceMesh):
    # these hooks then make counts, measures and the bounding box the whole mesh's (collective there)
    def total(self, n, op="sum"):
        """n (a count or measure of this part) over the whole mesh."""
        return n

    def extent(self):
        """(lo, hi): the whole mesh's bounding box."""
        return self.points.min(axis=0), self.points.max(axis=0)

    @property
    def order(self):
        return 1 if self.nodes is None else 2

    @property
    def cell_nodes(self):
        """(nc, 4) corners of linear cells, (nc, 10) nodes of quadratic ones."""
        return self.tets if self.nodes is None else self.nodes

    @classmethod
    def from_meshio(cls, path, points, tets, boundary, m=None, nodes=None):
        """boundary: the boundary face indices 4 cell + k (face k, opposite vertex k, of exactly one
        tetrahedron) that the mesh check found (mesh.check, face_incidence), in cell order. nodes: the
        (nc, 10) nodes of quadratic cells (their first four are tets)."""
        mesh = cls(path, np.ascontiguousarray(points[:, :3], np.float64), tets, nodes=nodes)
        mesh.facet_cell, mesh.facet_k = boundary // 4, boundary % 4
        if m is not None:
            mesh._read_groups(m)
        return mesh

    # --- geometry ----------------------------------------------------------------------------
    def facets(self, idx=None):
        """(n, 3) vertex ids of boundary facets `idx` (all by default), ordered so that the normal
        (b - a) x (c - a) points out of the body."""
        idx = slice(None) if idx is None else idx
        cell, k = self.facet_cell[idx], self.facet_k[idx]
        tri = self.tets[cell[:, None], FACE_VERTICES[k]]
        opp = self.tets[cell, k]
        return orient_outward(self.points, tri, opp)

    def area(self, idx):
        """The facets' area (curved 6-node facets of a quadratic mesh by the face rule)."""
        tri = self.facets(idx) if self.nodes is None else self.face_nodes(idx)
        return self.total(float(faces.areas(self.points, tri).sum()))

    def volume(self, cells):
        """The cells' volume (quadratic cells by the degree-5 rule: their curved volume)."""
        if self.nodes is None:
            return self.total(float(np.abs(signed_volumes(self.points, self.tets[cells])).sum()))
        pts, w = TET_RULES[5]
        nodes = self.nodes[np.atleast_1d(cells)]
        det = np.linalg.det(np.einsum("cai,qaj->cqij", self.points[nodes], tet_shapes(2, pts)[1]))
        return self.total(float((np.abs(det) @ w).sum()))

    # --- named sets --------------------------------------------------------------------------
    def _read_groups(self, m):
        """Physical surfaces (boundary facets) and volumes (tetrahedra) of a meshio mesh."""
        names = {(int(v[0]), int(v[1])): k for k, v in getattr(m, "field_data", {}).items()
                 if np.ndim(v) == 1 and len(v) >= 2}
        key = next((k for k in TAG_KEYS if k in m.cell_data), None)
        tri_sets, tet_sets = {}, {}
        off = 0
        tet_types, tri_types = ("tetra", "tetra10"), ("triangle", "triangle6")     # (quadratic: corners first)
        for i, block in enumerate(m.cells):
            n = len(block.data)
            if block.type in tet_types:
                ids = np.arange(off, off + n)
                off += n
            if key is not None and block.type in tri_types + tet_types:
                tags = np.asarray(m.cell_data[key][i]).astype(np.int64)
                dim = 2 if block.type in tri_types else 3
                for tag in np.unique(tags):
                    name = names.get((int(tag), dim), str(int(tag)))
                    sel = tags == tag
                    dst = tri_sets if dim == 2 else tet_sets
                    part = block.data[sel][:, :3] if dim == 2 else ids[sel]
                    dst.setdefault((name, int(tag)), []).append(part)
        if key is None:                 # named cell sets (e.g. from XDMF / MED), no tags
            for name, per_block in getattr(m, "cell_sets", {}).items():
                if name.startswith("gmsh:"):
                    continue
                off = 0
                for block, sel in zip(m.cells, per_block):
                    sel = np.asarray(sel, np.int64)
                    if block.type in tri_types and len(sel):
                        tri_sets.setdefault((name, None), []).append(block.data[sel][:, :3])
                    elif block.type in tet_types:
                        if len(sel):
                            tet_sets.setdefault((name, None), []).append(off + sel)
                        off += len(block.data)
        bkeys = face_keys(self.facets())
        order = np.argsort(bkeys)
        for (name, tag), parts in tri_sets.items():
            k = face_keys(np.concatenate(parts).astype(np.int64))
            pos = np.clip(np.searchsorted(bkeys[order], k), 0, len(order) - 1)
            found = bkeys[order][pos] == k
            self.groups[name] = NamedSet(name, tag, "facets", np.unique(order[pos[found]]), int((~found).sum()))
        for (name, tag), parts in tet_sets.items():
            self.groups[name] = NamedSet(name, tag, "tets", np.unique(np.concatenate(parts)))

    def names(self, kind):
        return [g.name for g in self.groups.values() if g.kind == kind]

    def box_facets(self, name):
        """Boundary facets on a bounding-box plane: all three vertices within BOX_TOL of the diagonal."""
        return box_pick(self.points[self.facets()], name, *self.extent())

    def find(self, spec, kind, option):
        """The NamedSet `spec` names: a physical group's name or tag, or (facets) a box face name.
        UserError listing what the mesh has when there is no such set."""
        for g in self.groups.values():
            if g.kind == kind and (g.name == spec or (g.tag is not None and str(g.tag) == spec)):
                if kind == "facets" and not self.total(len(g.items)):     # (a run would hold or load nothing there)
                    raise UserError(f"option -{option}: surface '{spec}' of mesh '{self.path}' holds no boundary "
                                    "facet (an empty physical group, or a damaged file)")
                return g
        if kind == "facets" and spec in BOX:
            items = self.box_facets(spec)
            if not self.total(len(items)):
                axis, side = BOX[spec]
                raise UserError(f"option -{option}: box face '{spec}' (the bounding box's {'xyz'[axis]} = {side}) "
                                f"holds no boundary facet of mesh '{self.path}'")
            return NamedSet(spec, None, "facets", items)
        if kind == "facets" and spec == WHOLE_BOUNDARY:
            return NamedSet(spec, None, "facets", np.arange(len(self.facet_cell)))
        if kind == "facets" and "=" in spec:
            return NamedSet(spec, None, "facets", self.select(spec, option))
        have = [f"{g.name}" + (f" ({g.tag})" if g.tag is not None and str(g.tag) != g.name else "")
                for g in self.groups.values() if g.kind == kind]
        what = "surfaces" if kind == "facets" else "volumes"
        listed = ", ".join(have) if have else "none"
        extra = (f"; box faces: {', '.join(BOX)}; {WHOLE_BOUNDARY} (all of it); or by geometry: {SELECTORS}"
                 if kind == "facets" else "")
        raise UserError(f"option -{option}: mesh '{self.path}' has no {what[:-1]} '{spec}' "
                        f"(physical {what}: {listed}{extra})")

    def select(self, spec, option):
        """The boundary facets a geometric selector picks (SELECTORS; sets' module docstring); UserError
        for a malformed one or one that picks nothing (with the part's extent)."""
        lo, hi = self.extent()
        picked = select_pick(self.points[self.facets()], spec, option, lo, hi)
        if not self.total(len(picked)):
            raise none_selected(spec, option, lo, hi)
        return picked

    def describe(self, s):
        """One line about a set: name, size and area or volume."""
        if s.kind == "facets":
            line = f"{s.name}: {self.total(len(s.items))} facets, area {self.area(s.items):.6g}"
            if s.ignored:
                line += f" ({s.ignored} interior triangles of the group ignored)"
            return line
        return f"{s.name}: {self.total(len(s.items))} tets, volume {self.volume(s.items):.6g}"

    def face_nodes(self, idx=None):
        """(n, 6) nodes of boundary facets `idx` of a quadratic mesh: the corners as facets() orders them,
        then the nodes of their edges (0,1), (1,2), (0,2)."""
        idx = slice(None) if idx is None else idx
        tri = self.facets(idx)
        cell = self.facet_cell[idx]
        local = np.argmax(self.tets[cell][:, None, :] == tri[:, :, None], axis=2)     # corner -> cell corner
        edge = np.full((4, 4), -1)
        for e, (i, j) in enumerate(EDGES):
            edge[i, j] = edge[j, i] = 4 + e
        mids = [self.nodes[cell, edge[local[:, a], local[:, b]]] for a, b in ((0, 1), (1, 2), (0, 2))]
        return np.column_stack([tri] + mids)

    def facet_mask(self, items):
        """(nc,) the bitmask of each cell's facets among boundary facets `items`: bit j is the face without the
        cell's corner of j-th smallest input vertex id (so any cone order gives the same faces)."""
        cell, k = self.facet_cell[items], self.facet_k[items]
        ids = self.tets[cell] if self.ids is None else self.ids[self.tets[cell]]
        rank = (ids < ids[np.arange(len(k)), k][:, None]).sum(axis=1)
        masks = np.zeros(len(self.tets), np.int64)
        np.bitwise_or.at(masks, cell, 1 << rank)
        return masks

    def label_strata(self, s):
        """{value: input cell or node indices} of a facet set as a DMPlex label: each cell holding
        facets of the set gets the bitmask of which of its faces (bit j: the face without the cell's
        j-th smallest input vertex id, so any cone order gives the same faces), the set's nodes (its
        vertices, and the edge nodes of a quadratic mesh) get VERTEX_VALUE."""
        masks = self.facet_mask(s.items)
        cell = self.facet_cell[s.items]
        out = {int(v): np.flatnonzero(masks == v) for v in np.unique(masks[cell])}
        out[VERTEX_VALUE] = unique(self.facets(s.items) if self.nodes is None else self.face_nodes(s.items))
        return out


def box_pick(corners, name, lo, hi):
    """The facets (corners (n, 3, 3)) on bounding-box face `name` (BOX) of the box lo..hi: all three corners within
    BOX_TOL of its diagonal."""
    axis, side = BOX[name]
    tol = BOX_TOL * float(np.linalg.norm(hi - lo))
    ref = lo[axis] if side == "min" else hi[axis]
    return np.flatnonzero((np.abs(corners[:, :, axis] - ref) <= tol).all(axis=1))


def select_pick(corners, spec, option, lo, hi):
    """The facets (corners (n, 3, 3), outward order) a geometric selector picks, in a part spanning lo..hi;
    UserError for a malformed selector (an empty pick is the caller's to report: none_selected)."""
    key, _, arg = spec.partition("=")
    nums = [float(v) for v in re.findall(NUMBER, arg)] if re.fullmatch(f"{NUMBER}(;{NUMBER})*", arg) else None
    tol = BOX_TOL * float(np.linalg.norm(hi - lo))
    if key in ("x", "y", "z") and nums and len(nums) == 1:
        on = np.abs(corners[:, :, "xyz".index(key)] - nums[0]) <= tol
        return np.flatnonzero(on.all(axis=1))
    if key == "box" and nums and len(nums) == 6:
        a, b = np.minimum(nums[:3], nums[3:]), np.maximum(nums[:3], nums[3:])
        return np.flatnonzero(((corners >= a - tol) & (corners <= b + tol)).all(axis=(1, 2)))
    if key == "normal" and (re.fullmatch("[-+][xyz]", arg) or (nums and len(nums) == 3 and any(nums))):
        d = np.eye(3)["xyz".index(arg[1])] * (1 if arg[0] == "+" else -1) if nums is None else np.array(nums)
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        cos = n @ (d / np.linalg.norm(d)) / np.linalg.norm(n, axis=1)
        return np.flatnonzero(cos >= math.cos(math.radians(NORMAL_TOL_DEG)))
    raise UserError(f"option -{option}: '{spec}' is not a surface selector ({SELECTORS})")


def none_selected(spec, option, lo, hi):
    """The UserError of a selector that picks no boundary facet of a part spanning lo..hi."""
    ext = ", ".join(f"{c} {lo[i]:.6g}..{hi[i]:.6g}" for i, c in enumerate("xyz"))
    return UserError(f"option -{option}: '{spec}' selects no boundary facet (the part spans {ext})")


def orient_outward(points, tri, opp):
    """Triangles (n,3) with the vertex order that makes (b - a) x (c - a) point away from `opp`."""
    tri = np.array(tri, np.int64, copy=True)
    a, b, c = (points[tri[:, i]] for i in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), points[opp] - a) > 0
    tri[inward, 1], tri[inward, 2] = tri[inward, 2].copy(), tri[inward, 1].copy()
    return tri

