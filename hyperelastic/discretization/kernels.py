"""ctypes bindings to the compiled element kernels (_kernels.c, built by setup.py): `Cells` (the local
cells' geometry and the kernels that need nothing else: mass matrix, inversion step bound, stored blocks),
`CellKernels` (a material on cells: force, energy, K v, tangent blocks and diagonal) and `RegionKernels`
(a material per region, the same interface)."""
import ctypes
import glob
import os

import numpy as np

_here = os.path.dirname(os.path.abspath(__file__))
IDX = np.int32  # vertex index type used by the kernels


_materials = os.path.join(os.path.dirname(_here), "physics", "materials")


def _sources():
    """The C sources the compiled kernels are built from (setup.py): a newer one means a stale build (an installed
    package may hold none of them)."""
    return ([os.path.join(_here, "_kernels.c")] + glob.glob(os.path.join(_here, "*.h"))
            + glob.glob(os.path.join(_materials, "*.h")))


def _load():
    libs = sorted(glob.glob(os.path.join(_here, "_kernels*.so")))
    if not libs:
        raise ImportError("hyperelastic: compiled kernels not found; run `make` (pip install -e .) to build them")
    lib = libs[0]
    sources = [p for p in _sources() if os.path.exists(p)]
    newest = max(sources, key=os.path.getmtime) if sources else lib
    if os.path.getmtime(newest) > os.path.getmtime(lib):
        raise ImportError(f"hyperelastic: {lib} is older than {os.path.basename(newest)}; run `make` to rebuild it")
    return ctypes.CDLL(lib)


_lib = _load()
_P = ctypes.c_void_p
_I = ctypes.c_int64
_D = ctypes.c_double
# per material NAME (materials/NAME.h): he_KIND_NAME(nc, cells, Dminv, vol, x, prm, ...), prm the material's
# parameter block (NPARAM doubles: its constants, zero-padded; see _kernels.c, HE_NPARAM)
_MATERIAL_KERNELS = {"forces": [_P], "energy": [_P], "kv": [_P, _P], "tangent": [_P, ctypes.c_int],
                     "tangent_diag": [_P], "forces_dg": [_P, _P], "fields": [_P], "pk2": [_P]}
NPARAM = 12
_lib.he_mass_apply.restype = None
_lib.he_mass_apply.argtypes = [_I, _P, _P, _D, _P, _P]
_lib.he_max_step.restype = _D
_lib.he_max_step.argtypes = [_I, _P, _P, _P, _P, _D]
_lib.he_apply_blocks.restype = None
_lib.he_apply_blocks.argtypes = [_I, _P, _P, _P, _P]
_lib.he_deformations.restype = None
_lib.he_deformations.argtypes = [_I, _P, _P, _P, _P]
_lib.he_fh_forces.restype = None
_lib.he_fh_forces.argtypes = [_I, _P, _P, _P, _P, _P, _P]
_lib.he_fh_tangent.restype = None
_lib.he_fh_tangent.argtypes = [_I, _P, _P, _P, _P, _P, _P]
_lib.he_add_mass_blocks.restype = None
_lib.he_add_mass_blocks.argtypes = [_I, _P, _D, _P]
_lib.he_scatter_blocks.restype = None
_lib.he_scatter_blocks.argtypes = [_I, _P, _P, _P, _P]
_lib.he_scatter_blocks_n.restype = None
_lib.he_scatter_blocks_n.argtypes = [_I, ctypes.c_int, _P, _P, _P, _P]
_lib.he_add_blocks.restype = None
_lib.he_add_blocks.argtypes = [_I, _P, _P, _P, _P]
_lib.he_gather_blocks.restype = None
_lib.he_gather_blocks.argtypes = [_I, _P, _P, _P, _P, ctypes.c_int]
_lib.he_scatter_upper.restype = None
_lib.he_scatter_upper.argtypes = [_I, ctypes.c_int, _P, _P, _P]
_lib.he_p1_galerkin.restype = None
_lib.he_p1_galerkin.argtypes = [_I, _P, _P, _P]
_lib.he_egeometry.restype = None
_lib.he_egeometry.argtypes = [_I, ctypes.c_int, ctypes.c_int, _P, _P, _P, _P, _P, _P]
_lib.he_adjacency.restype = ctypes.c_int
_lib.he_adjacency.argtypes = [_I, ctypes.c_int, _P, _I, _P, _I, _P, ctypes.c_int, _P, _P]
_lib.he_csr_union.restype = None
_lib.he_csr_union.argtypes = [_I, _P, _P, _P, _P, _P, _P]
_lib.he_expand_pattern.restype = None
_lib.he_expand_pattern.argtypes = [_I, _P, _P, ctypes.c_int, _P, _P]
_lib.he_cell_map.restype = _I
_lib.he_cell_map.argtypes = [_I, ctypes.c_int, _P, _P, _P, _P, ctypes.c_int, _P, _P]
_lib.he_upper_blocks.restype = _I
_lib.he_upper_blocks.argtypes = [_I, _P, _P, ctypes.c_int, _P, _P, _P, _P]
_lib.he_upper_map.restype = _I
_lib.he_upper_map.argtypes = [_I, ctypes.c_int, _P, _P, _P, _P, ctypes.c_int, _P]
_lib.he_pressure_terms.restype = None
_lib.he_pressure_terms.argtypes = [_I, ctypes.c_int, ctypes.c_int, _P, _P, _P, _P, _P, _P, _P, _P, _P, _P]


def pressure_terms(cells, g, w, x, pq, M, force=False, tangent=False, out=None):
    """The mixed formulation's pressure terms of volumetric kind "J" (_kernels.c, he_pressure_terms) on cells
    (nc, nn) int32 with gradients g (nc, nq, nn, 3), weights w (nc, nq), pressures pq (nc, nq) at the points, the
    pressure's shape functions M (nq, 4), local positions x: {"J": (nc, nq)}, with force: "f" (nc, 3nn), with
    tangent: "up" (nc, 3nn, 4) and "blocks" (nc, 3nn, 3nn); into the arrays of `out` where it has them (kept
    between calls: a new (nc, 30, 30) array costs more in page faults than the loop)."""
    nc, nq, nn = g.shape[:3]
    assert nn <= 10 and cells.dtype == IDX and cells.shape == (nc, nn) and M.shape == (nq, 4)
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (g, w, x, pq, M)]
    cells = np.ascontiguousarray(cells)
    out = {} if out is None else out
    shapes = {"J": (nc, nq)}
    if force:
        shapes["f"] = (nc, 3 * nn)
    if tangent:
        shapes.update(up=(nc, 3 * nn, 4), blocks=(nc, 3 * nn, 3 * nn))
    for k, shape in shapes.items():
        if k not in out:
            out[k] = np.empty(shape)
        assert out[k].shape == shape and out[k].dtype == np.float64 and out[k].flags.c_contiguous
    ptr = lambda k: out[k].ctypes.data if k in shapes else None     # noqa: E731
    _lib.he_pressure_terms(nc, nn, nq, cells.ctypes.data, *(a.ctypes.data for a in arrays), out["J"].ctypes.data,
                           ptr("f"), ptr("up"), ptr("blocks"))
    return out


def scatter_blocks(base, rowlen, vals, dst):
    """dst += the cells' blocks vals (nc, 3nn, 3nn) at CSR value positions base[e, nn a + b] + i rowlen[e, a]
    + j for dof (3a+i, 3b+j); cells with base[e, 0] < 0 are skipped (base (nc, nn^2), rowlen (nc, nn) int32)."""
    nc, nn = len(vals), rowlen.shape[1]
    if nn != 4:
        assert base.shape == (nc, nn * nn) and vals.shape == (nc, 3 * nn, 3 * nn)
        assert base.dtype == rowlen.dtype == np.int32 and vals.dtype == dst.dtype == np.float64
        assert base.flags.c_contiguous and rowlen.flags.c_contiguous and vals.flags.c_contiguous
        _lib.he_scatter_blocks_n(nc, nn, base.ctypes.data, rowlen.ctypes.data, vals.ctypes.data, dst.ctypes.data)
        return
    assert base.shape == (nc, 16) and rowlen.shape == (nc, 4) and vals.shape == (nc, 12, 12)
    assert base.dtype == rowlen.dtype == np.int32 and vals.dtype == dst.dtype == np.float64
    assert base.flags.c_contiguous and rowlen.flags.c_contiguous and vals.flags.c_contiguous
    _lib.he_scatter_blocks(nc, base.ctypes.data, rowlen.ctypes.data, vals.ctypes.data, dst.ctypes.data)


def gather_blocks(p0, L, src, dst, colmajor):
    """dst (nb*9) = the 3x3 blocks of the CSR values src whose row r starts at p0[k] + r L[k], each block
    column-major (as (S)BAIJ stores them) or row-major (p0, L int32)."""
    nb = len(p0)
    assert p0.dtype == L.dtype == np.int32 and len(L) == nb and dst.size == 9 * nb
    assert src.dtype == dst.dtype == np.float64 and dst.flags.c_contiguous
    _lib.he_gather_blocks(nb, p0.ctypes.data, L.ctypes.data, src.ctypes.data, dst.ctypes.data, int(colmajor))


def add_blocks(p0, L, vals, dst):
    """dst[p0[k] + r L[k] + c] += vals[k, 3r + c] for the 3x3 blocks vals (nb, 9) (p0, L int32), in order."""
    nb = len(p0)
    assert p0.dtype == L.dtype == np.int32 and len(L) == nb and vals.shape == (nb, 9)
    assert vals.dtype == dst.dtype == np.float64 and vals.flags.c_contiguous
    _lib.he_add_blocks(nb, p0.ctypes.data, L.ctypes.data, vals.ctypes.data, dst.ctypes.data)


def scatter_upper(pos, vals, dst):
    """dst (SBAIJ values, column-major 3x3 blocks) += the cells' blocks vals (nc, 3nn, 3nn) of node pairs (a, b) at
    block pos[e, nn a + b] where that is >= 0 (pos (nc, nn^2) int32)."""
    nc = len(vals)
    nn = vals.shape[1] // 3
    assert pos.shape == (nc, nn * nn) and pos.dtype == np.int32 and pos.flags.c_contiguous
    assert vals.dtype == dst.dtype == np.float64 and vals.flags.c_contiguous and vals.shape == (nc, 3 * nn, 3 * nn)
    _lib.he_scatter_upper(nc, nn, pos.ctypes.data, vals.ctypes.data, dst.ctypes.data)


def p1_galerkin(edges, vals, out):
    """out (nc, 12, 12) = P_e^T K_e P_e of quadratic tetrahedra's cell blocks vals (nc, 30, 30): their P1 operator
    on the cell's vertices (edges: the element's 6 edges as vertex pairs)."""
    nc = len(vals)
    e = np.ascontiguousarray(edges, dtype=np.int32)
    assert e.shape == (6, 2) and vals.shape == (nc, 30, 30) and out.shape == (nc, 12, 12)
    assert vals.dtype == out.dtype == np.float64 and vals.flags.c_contiguous and out.flags.c_contiguous
    _lib.he_p1_galerkin(nc, e.ctypes.data, vals.ctypes.data, out.ctypes.data)


def element_geometry(X, cells, dN, w, full=True):
    """Per (cell, point) of a rule (reference gradients dN (nq, nn, 3), weights w (nq,)) of cells (nc, nn) with node
    coordinates X: geo (nc, nq, 10) = J^-1 (row-major) and |det J| w_q when full, else the weights (nc, nq) alone, in
    C (element.reference.geometry is the same in numpy)."""
    X, cells = np.ascontiguousarray(X, np.float64), np.ascontiguousarray(cells, dtype=IDX)
    dN, w = np.ascontiguousarray(dN, np.float64), np.ascontiguousarray(w, np.float64)
    nc, nn = cells.shape
    nq = len(w)
    assert dN.shape == (nq, nn, 3)
    out = np.empty((nc, nq, 10) if full else (nc, nq))
    _lib.he_egeometry(nc, nn, nq, cells.ctypes.data, X.ctypes.data, dN.ctypes.data, w.ctypes.data,
                      out.ctypes.data if full else None, None if full else out.ctypes.data)
    return out


def _index_args(*arrays):
    """PETSc's index arrays for the set-up's C functions: (is it 64-bit, their pointers)."""
    idx64 = arrays[0].dtype == np.int64
    assert all(a.dtype == arrays[0].dtype and a.dtype in (np.int32, np.int64) and a.flags.c_contiguous for a in arrays)
    return int(idx64), [a.ctypes.data for a in arrays]


def adjacency(cells, g, rows, upper=False):
    """(ptr (nr + 1), cols): for each row vertex rows[k] (local index), the sorted distinct global numbers g[w] of
    the local vertices sharing a cell with it (cells (nc, nn), local indices), only those >= g[rows[k]] when upper;
    its columns are cols[ptr[k]:ptr[k + 1]]. One pass over each vertex's cells (no key arrays of all the pairs)."""
    cells = np.ascontiguousarray(cells, dtype=IDX)
    g, rows = (np.ascontiguousarray(a, dtype=np.int64) for a in (g, rows))
    nc, nn = cells.shape
    ptr = np.empty(len(rows) + 1, np.int64)
    args = (nc, nn, cells.ctypes.data, len(g), g.ctypes.data, len(rows), rows.ctypes.data, int(upper), ptr.ctypes.data)
    if _lib.he_adjacency(*args, None):
        raise MemoryError("the tangent's pattern: out of memory")
    cols = np.empty(ptr[-1], np.int64)
    if _lib.he_adjacency(*args, cols.ctypes.data):
        raise MemoryError("the tangent's pattern: out of memory")
    return ptr, cols


def csr_union(a, b):
    """The union (ptr, cols) of two patterns (ptr, cols) of the same rows, each row's columns sorted and distinct."""
    (ia, ja), (ib, jb) = ((np.ascontiguousarray(p, np.int64), np.ascontiguousarray(c, np.int64)) for p, c in (a, b))
    n = len(ia) - 1
    ic = np.empty(n + 1, np.int64)
    _lib.he_csr_union(n, ia.ctypes.data, ja.ctypes.data, ib.ctypes.data, jb.ctypes.data, ic.ctypes.data, None)
    jc = np.empty(ic[-1], np.int64)
    _lib.he_csr_union(n, ia.ctypes.data, ja.ctypes.data, ib.ctypes.data, jb.ctypes.data, ic.ctypes.data,
                      jc.ctypes.data)
    return ic, jc


def expand_pattern(vptr, vcols, index_type):
    """(ia, ja) in index_type (PETSc's): the scalar pattern, 3 dofs a vertex, of a vertex pattern (vptr, vcols:
    global vertex numbers) — dof row 3v + a has the columns 3w + b of every w in v's row, in order."""
    vptr, vcols = np.ascontiguousarray(vptr, np.int64), np.ascontiguousarray(vcols, np.int64)
    n = len(vptr) - 1
    ia, ja = np.empty(3 * n + 1, index_type), np.empty(9 * len(vcols), index_type)
    idx64, (pi, pj) = _index_args(ia, ja)
    _lib.he_expand_pattern(n, vptr.ctypes.data, vcols.ctypes.data, idx64, pi, pj)
    return ia, ja


def cell_map(cells, own, ia, ja):
    """(base (nc, nn^2), rowlen (nc, nn), int32, the number of cells with an entry missing): for each cell whose
    nodes this rank all owns (own: per local node its index among the owned ones, -1 elsewhere), where its node
    pair (a, b)'s 3x3 block starts in the values of the scalar CSR pattern ia/ja (owned rows and columns 3 own + i)
    and the length of node a's rows; -1 and 0 for the other cells."""
    cells = np.ascontiguousarray(cells, dtype=IDX)
    own = np.ascontiguousarray(own, np.int64)
    nc, nn = cells.shape
    base, rowlen = np.empty((nc, nn * nn), np.int32), np.empty((nc, nn), np.int32)
    idx64, (pi, pj) = _index_args(ia, ja)
    missing = _lib.he_cell_map(nc, nn, cells.ctypes.data, own.ctypes.data, pi, pj, idx64, base.ctypes.data,
                               rowlen.ctypes.data)
    return base, rowlen, missing


def upper_blocks(ia, ja):
    """(bptr, bcols, p0, L): of a one-rank scalar CSR ia/ja of 3x3 blocks (3 rows a vertex), per block row v its blocks
    (v, w), w >= v — columns bcols[bptr[v]:bptr[v + 1]] (int64), where each block's first entry is in the values (p0)
    and its rows' length (L), int32. RuntimeError where the rows are not whole blocks."""
    idx64, (pi, pj) = _index_args(ia, ja)
    n = (len(ia) - 1) // 3
    bptr = np.empty(n + 1, np.int64)
    if _lib.he_upper_blocks(n, pi, pj, idx64, bptr.ctypes.data, None, None, None):
        raise RuntimeError("the tangent's pattern is not made of whole 3x3 blocks")
    nb = int(bptr[-1])
    bcols, p0, L = np.empty(nb, np.int64), np.empty(nb, np.int32), np.empty(nb, np.int32)
    _lib.he_upper_blocks(n, pi, pj, idx64, bptr.ctypes.data, bcols.ctypes.data, p0.ctypes.data, L.ctypes.data)
    return bptr, bcols, p0, L


def upper_map(cells, own, si, sj):
    """(pos (nc, nn^2) int32, the number of pairs missing): for each cell whose nodes this rank all owns, the block
    index in the block CSR si/sj (the upper block triangle, owned indices) of its node pair (a, b) where own[a] <=
    own[b], -1 elsewhere."""
    cells = np.ascontiguousarray(cells, dtype=IDX)
    own = np.ascontiguousarray(own, np.int64)
    nc, nn = cells.shape
    pos = np.empty((nc, nn * nn), np.int32)
    idx64, (pi, pj) = _index_args(si, sj)
    missing = _lib.he_upper_map(nc, nn, cells.ctypes.data, own.ctypes.data, pi, pj, idx64, pos.ctypes.data)
    return pos, missing


_bound = {}


def material_kernels(name, per_cell=False):
    """{kind: C function} of material `name`, from its header materials/NAME.h; per_cell: the loops taking a block of
    constants per cell (he_KIND_NAME_cells: a header defining NAME_PER_CELL 1)."""
    if (name, per_cell) not in _bound:
        fns = {}
        for kind, extra in _MATERIAL_KERNELS.items():
            try:
                fn = getattr(_lib, f"he_{kind}_{name}" + ("_cells" if per_cell else ""))
            except AttributeError:
                what = "constants per cell" if per_cell else "compiled kernels"
                raise ImportError(f"hyperelastic: no {what} for material '{name}' (is there a materials/{name}.h"
                                  f"{' defining ' + name + '_PER_CELL' if per_cell else ''}? run `make` to "
                                  "rebuild)") from None
            fn.restype = _I
            fn.argtypes = [_I, _P, _P, _P, _P, _P] + extra
            fns[kind] = fn
        _bound[(name, per_cell)] = fns
    return _bound[(name, per_cell)]


def cell_constants(constants):
    """A material's constants as the kernels keep them: a tuple of floats, or (nc, k) floats where they vary from
    cell to cell (a field: hgo's fibre directions)."""
    if np.ndim(constants) == 2:
        return np.ascontiguousarray(constants, np.float64)
    return tuple(float(c) for c in constants)


def _ptr(a, dtype):
    assert a.dtype == dtype and a.flags.c_contiguous, (a.dtype, a.flags)
    return a.ctypes.data


def parameter_block(constants):
    """The C kernels' parameter block of a material's constants (NPARAM doubles, zero-padded), or (nc, NPARAM) of
    constants per cell (nc, k)."""
    c = np.asarray(constants, np.float64)
    c = c.reshape(len(c), -1) if c.ndim == 2 else c.ravel()
    if c.shape[-1] > NPARAM:
        raise ValueError(f"a material has at most {NPARAM} constants (HE_NPARAM in _kernels.c), not {c.shape[-1]}")
    out = np.zeros(c.shape[:-1] + (NPARAM,))
    out[..., :c.shape[-1]] = c
    return out


def _rows(constants, lo, hi):
    """The constants of cells lo..hi-1 (the same tuple where they do not vary per cell)."""
    return constants[lo:hi] if isinstance(constants, np.ndarray) else constants


class Cells:
    """Local cells (vertex indices into a local vector, 3 dofs per vertex), their Dm^-1 and volumes, and
    the kernels that need nothing else: the consistent mass matrix, the inversion guard's step bound and
    stored 12x12 blocks."""

    nn = 4          # nodes per cell

    def __init__(self, cells, Dminv, vol):
        self.cells = np.ascontiguousarray(cells, dtype=IDX)
        self.Dminv = np.ascontiguousarray(Dminv, dtype=np.float64).reshape(-1, 9)
        self.vol = np.ascontiguousarray(vol, dtype=np.float64)
        self.nc = len(self.vol)
        self._args = (self.nc, _ptr(self.cells, IDX), _ptr(self.Dminv, np.float64), _ptr(self.vol, np.float64))
        self._parts = {}

    def part(self, lo, hi):
        """The same cells lo..hi-1 (views, no copies; cached)."""
        if (lo, hi) not in self._parts:
            self._parts[(lo, hi)] = Cells(self.cells[lo:hi], self.Dminv[lo:hi], self.vol[lo:hi])
        return self._parts[(lo, hi)]

    def weighted(self, w):
        """The same cells with volumes w V (a coefficient per cell, e.g. each region's density)."""
        return Cells(self.cells, self.Dminv, np.asarray(w, np.float64) * self.vol)

    def subset(self, idx):
        """The cells idx (copies)."""
        return Cells(self.cells[idx], self.Dminv[idx], self.vol[idx])

    def kernels(self, material, constants):
        """A material's loops on these cells."""
        return CellKernels(self, material=material, constants=constants)

    def load_shares(self, coef=1.0, which=None):
        """(n, 4): int coef N_a dV = coef V/4 of the cells `which` (default all), coef a scalar or one per cell."""
        sel = slice(None) if which is None else which
        c = np.asarray(coef, float)
        per_cell = (c if c.ndim == 0 else c[sel]) * self.vol[sel] / 4.0
        return np.repeat(per_cell, 4).reshape(-1, 4)

    def mass_diagonal(self, lumped, nlv):
        """(nlv,) the mass matrix's diagonal per node (density 1): lumped V/4 (the row sums), consistent
        2V/20 = V/10 per vertex."""
        vertex_share = np.zeros(nlv)
        np.add.at(vertex_share, self.cells.ravel(), np.repeat(self.vol, 4))
        return vertex_share * (0.25 if lumped else 0.1)

    def deformations(self, x):
        """F (nc, 1, 3, 3) of each cell at positions x (one point per cell)."""
        F = np.empty((self.nc, 1, 3, 3))
        _lib.he_deformations(*self._args[:3], _ptr(x, np.float64), _ptr(F, np.float64))
        return F

    def fh_forces(self, H, x, f):
        """f += the force of the second Piola-Kirchhoff stresses H (nc, 1, 3, 3; symmetric) at positions x:
        sum_e V (F_e H_e) grad N_a. Linear in x: at a direction v it is the term's K v."""
        assert H.shape == (self.nc, 1, 3, 3) and H.flags.c_contiguous
        _lib.he_fh_forces(*self._args, _ptr(H, np.float64), _ptr(x, np.float64), _ptr(f, np.float64))

    def fh_tangent(self, H, diag=None, vals=None):
        """diag += the diagonal and vals (nc, 12, 12) += the blocks of fh_forces' tangent, delta_ik V G_a.H G_b."""
        assert H.shape == (self.nc, 1, 3, 3) and H.flags.c_contiguous
        assert vals is None or (vals.shape == (self.nc, 12, 12) and vals.flags.c_contiguous)
        _lib.he_fh_tangent(*self._args, _ptr(H, np.float64), None if diag is None else _ptr(diag, np.float64),
                           None if vals is None else _ptr(vals, np.float64))

    def max_step(self, x, d, frac=0.9):
        """Largest t <= 1 keeping every (not already inverted) cell's det F > 0 on x + [0, t] d, times
        frac when a cell would invert within the unit step."""
        return _lib.he_max_step(*self._args[:3], _ptr(x, np.float64), _ptr(d, np.float64), float(frac))

    def apply_blocks(self, blocks, v, y):
        """y += sum over cells of blocks[e] v_e (blocks: (nc,12,12), e.g. projected tangents)."""
        assert blocks.shape == (self.nc, 12, 12) and blocks.flags.c_contiguous
        _lib.he_apply_blocks(self.nc, _ptr(self.cells, IDX), _ptr(blocks, np.float64), _ptr(v, np.float64),
                             _ptr(y, np.float64))

    def add_mass_blocks(self, coef, vals):
        """vals (nc,12,12) += coef * consistent P1 mass blocks, in place."""
        assert vals.shape == (self.nc, 12, 12)
        _lib.he_add_mass_blocks(self.nc, _ptr(self.vol, np.float64), float(coef), _ptr(vals, np.float64))

    def mass_apply(self, coef, v, y):
        """y += coef * (consistent P1 mass pattern) v."""
        _lib.he_mass_apply(self.nc, _ptr(self.cells, IDX), _ptr(self.vol, np.float64), float(coef),
                           _ptr(v, np.float64), _ptr(y, np.float64))


def _scale_moduli(k, s):
    """CellKernels/ElementKernels.scale_moduli: the force, K v, tangent and its diagonal take the material's
    isochoric moduli (Material.moduli) times s from now on (the viscoelastic effect's 1 + g over a step); the energy
    and the output's fields keep the material's own. s = 1: the material's. (The same s as now: nothing to redo; a
    run of equal steps sets it once.)"""
    if float(s) == k.scale:
        return
    k.scale = float(s)
    if k.scale == 1.0:
        k._prm_k = k._prm
    else:
        k.prm_k = parameter_block(k.material.scaled(k.constants, k.scale))
        k._prm_k = _ptr(k.prm_k, np.float64)
    for p in k._parts.values():
        p.scale_moduli(s)


def _unscaled(k):
    """The same material on the same cells (arrays shared) whose moduli scale_moduli on `k` leaves alone: for what
    needs the material's own stiffness (Rayleigh damping's beta K)."""
    out = type(k).__new__(type(k))
    out.__dict__.update(k.__dict__)
    out._parts = {}
    out.parts = [(slice(None), out)]
    out.scale_moduli(1.0)
    return out


class CellKernels:
    """A material (a Material, e.g. materials.get('stvk'), with its constants: materials/NAME.py `constants`) on
    cells (a Cells, or its arrays: local vertex indices, Dm^-1, volumes), bound to the C kernels. `materials` and
    `parts` are declared as RegionKernels declares them, so callers need not know which they hold."""
    nn = 4

    def __init__(self, cells, Dminv=None, vol=None, material=None, constants=()):
        self.geometry = cells if isinstance(cells, Cells) else Cells(cells, Dminv, vol)
        g = self.geometry
        self.cells, self.Dminv, self.vol, self.nc = g.cells, g.Dminv, g.vol, g.nc
        self._args = g._args
        self.set_material(material, constants)
        self._parts = {}

    def set_material(self, material, constants):
        """Switch to `material` (a physics.materials Material: its `name` picks the compiled loops, its `quadratic`
        the discrete gradient) with its constants."""
        self.material = material
        self.materials = (material,)
        self.constants = cell_constants(constants)
        self.fn = material_kernels(material.name, isinstance(self.constants, np.ndarray))
        self.prm = parameter_block(self.constants)
        self._prm = self._prm_k = _ptr(self.prm, np.float64)
        self.scale = 1.0
        self.parts = [(slice(None), self)]

    def part(self, lo, hi):
        """The same kernels on cells lo..hi-1 (views, no copies; cached)."""
        if (lo, hi) not in self._parts:
            self._parts[(lo, hi)] = CellKernels(self.geometry.part(lo, hi), material=self.material,
                                                constants=_rows(self.constants, lo, hi))
            self._parts[(lo, hi)].scale_moduli(self.scale)
        return self._parts[(lo, hi)]

    scale_moduli = _scale_moduli
    unscaled = _unscaled

    def _x(self, x):
        return _ptr(x, np.float64)

    def forces(self, x, f):
        """f += k(x); returns the number of cells where the material is undefined."""
        return self.fn["forces"](*self._args, self._x(x), self._prm_k, _ptr(f, np.float64))

    def forces_discrete_gradient(self, x, xn, f):
        """f += the energy-momentum force of the midpoint step from xn to x1 = 2 x - xn (x the midpoint):
        per cell V (F S) : grad N with F = F(x) = (F_n + F_1)/2 and the algorithmic stress
        S = S(C_bar) + (dW - S(C_bar) : dE) dE / (dE : dE), C_bar = (C_n + C_1)/2, dE = (C_1 - C_n)/2,
        dW = Psi(F_1) - Psi(F_n) (Simo & Tarnow, ZAMP 43, 1992; Gonzalez, CMAME 190, 2000, eq. 4.4).
        Since sym(F^T (F_1 - F_n)) = dE, the work of these forces over the step is exactly
        sum_e V (Psi(F_1) - Psi(F_n)): with the midpoint rule's inertia the step conserves energy, and S
        symmetric conserves angular momentum. For St.VK, S(C_bar) alone has that property (S is linear in
        E); the correction is then rounding. S(C) = Ft^-1 P(Ft) for any Ft^T Ft = C with det Ft of the sign
        of det F (objective materials; Ft from the Cholesky factor). A material whose energy is quadratic
        in F (`quadratic`: `linear`, which is not objective): the midpoint force, which is already exact.
        Returns the number of cells where the material is undefined at x_n or x_1 (their force is
        skipped)."""
        if self.material.quadratic:
            return self.forces(x, f)
        return self.fn["forces_dg"](*self._args, self._x(x), self._prm_k, _ptr(xn, np.float64), _ptr(f, np.float64))

    def energy(self, x):
        out = np.zeros(3)
        bad = self.fn["energy"](*self._args, self._x(x), self._prm, _ptr(out, np.float64))
        return out[0], out[1], out[2], bad

    def fields(self, x):
        """(nc, 15) per cell: J, Psi, von Mises, the Cauchy stress and the Green-Lagrange strain as Tensor6 (the
        output's cell fields, output/fields.py; NaN where the material is undefined)."""
        out = np.empty((self.nc, 15))
        self.fn["fields"](*self._args, self._x(x), self._prm, _ptr(out, np.float64))
        return out

    def pk2(self, x):
        """(nc, 1, 3, 3): each cell's second Piola-Kirchhoff stress F^-1 P(F) with the material's own constants (NaN
        where it is undefined)."""
        S = np.empty((self.nc, 1, 3, 3))
        self.fn["pk2"](*self._args, self._x(x), self._prm, _ptr(S, np.float64))
        return S

    def kv(self, x, v, y):
        """y += K(x) v."""
        return self.fn["kv"](*self._args, self._x(x), self._prm_k, _ptr(v, np.float64), _ptr(y, np.float64))

    def tangent(self, x, vals=None, accumulate=False):
        """12x12 cell tangents, shape (nc, 12, 12), dof order 3a+i; added to vals if accumulate."""
        if vals is None:
            vals = np.zeros((self.nc, 12, 12))
        assert vals.shape == (self.nc, 12, 12)
        bad = self.fn["tangent"](*self._args, self._x(x), self._prm_k, _ptr(vals, np.float64), int(accumulate))
        return vals, bad

    def tangent_diag(self, x, diag):
        return self.fn["tangent_diag"](*self._args, self._x(x), self._prm_k, _ptr(diag, np.float64))

    def max_step(self, x, d, frac=0.9):
        return self.geometry.max_step(x, d, frac)

    def apply_blocks(self, blocks, v, y):
        self.geometry.apply_blocks(blocks, v, y)


class RegionKernels:
    """Cell kernels of several materials, each on a subset of the local cells (a material per region,
    -regions), with CellKernels' interface: sums over all cells, per-cell arrays in the local cell
    order. `materials`: every material of the scene, also those without cells on this rank (what
    depends on them must be the same on every rank)."""

    def __init__(self, cells, parts):
        """cells: a Cells; parts: [(local cell indices, Material, constants: a tuple, or a row per cell of the part)];
        each cell in exactly one."""
        self.geometry = cells
        self.cells, self.nc, self.nn = cells.cells, cells.nc, cells.nn
        self.spec = [(np.asarray(idx, np.int64), m, cell_constants(c)) for idx, m, c in parts]
        self.materials = tuple(m for _, m, _ in self.spec)
        self.parts = [(idx, cells.subset(idx).kernels(m, c)) for idx, m, c in self.spec if len(idx)]
        self._parts = {}
        self.scale = 1.0

    def part(self, lo, hi):
        """The same kernels on cells lo..hi-1 (cached)."""
        if (lo, hi) not in self._parts:
            sub = []
            for idx, m, c in self.spec:
                inside = (idx >= lo) & (idx < hi)
                sub.append((idx[inside] - lo, m, c[inside] if isinstance(c, np.ndarray) else c))
            self._parts[(lo, hi)] = RegionKernels(self.geometry.part(lo, hi), sub)
            self._parts[(lo, hi)].scale_moduli(self.scale)
        return self._parts[(lo, hi)]

    def scale_moduli(self, s):
        """Each part's (CellKernels.scale_moduli)."""
        if float(s) == self.scale:
            return
        self.scale = float(s)
        for _, k in self.parts:
            k.scale_moduli(s)
        for r in self._parts.values():
            r.scale_moduli(s)

    def unscaled(self):
        out = type(self).__new__(type(self))
        out.__dict__.update(self.__dict__)
        out.parts = [(idx, k.unscaled()) for idx, k in self.parts]
        out._parts = {}
        out.scale = 1.0
        return out

    def forces(self, x, f):
        return sum(k.forces(x, f) for _, k in self.parts)

    def forces_discrete_gradient(self, x, xn, f):
        return sum(k.forces_discrete_gradient(x, xn, f) for _, k in self.parts)

    def energy(self, x):
        W, jmin, jmax, bad = 0.0, np.inf, -np.inf, 0
        for _, k in self.parts:
            w, lo, hi, b = k.energy(x)
            W, jmin, jmax, bad = W + w, min(jmin, lo), max(jmax, hi), bad + b
        return W, jmin, jmax, bad

    def kv(self, x, v, y):
        return sum(k.kv(x, v, y) for _, k in self.parts)

    def tangent(self, x, vals=None, accumulate=False):
        n3 = 3 * self.nn
        if vals is None:
            vals = np.zeros((self.nc, n3, n3))
        assert vals.shape == (self.nc, n3, n3)
        bad = 0
        for idx, k in self.parts:
            K, b = k.tangent(x)
            bad += b
            if accumulate:
                vals[idx] += K
            else:
                vals[idx] = K
        return vals, bad

    def tangent_diag(self, x, diag):
        return sum(k.tangent_diag(x, diag) for _, k in self.parts)

    def max_step(self, x, d, frac=0.9):
        return self.geometry.max_step(x, d, frac)

    def apply_blocks(self, blocks, v, y):
        self.geometry.apply_blocks(blocks, v, y)


# ---- elements with quadrature (P2 tetrahedra) ----------------------------------------------------------
# per material NAME: he_eKIND_NAME(nc, nn, nq, cells, dN, geo, x, prm, ...) (_element_loops.h)
_ELEMENT_KERNELS = {"forces": [_P], "energy": [_P], "kv": [_P, _P], "tangent": [_P, ctypes.c_int],
                    "tangent_diag": [_P], "forces_dg": [_P, _P], "pk2": [_P]}
_C = ctypes.c_int
_lib.he_emass_apply.restype = None
_lib.he_emass_apply.argtypes = [_I, _C, _C, _P, _P, _P, _D, _P, _P]
_lib.he_emass_blocks.restype = None
_lib.he_emass_blocks.argtypes = [_I, _C, _C, _P, _P, _D, _P]
_lib.he_eapply_blocks.restype = None
_lib.he_eapply_blocks.argtypes = [_I, _C, _P, _P, _P, _P]
_lib.he_emax_step.restype = _D
_lib.he_emax_step.argtypes = [_I, _C, _C, _P, _P, _P, _P, _P, _D]
_lib.he_edeformations.restype = None
_lib.he_edeformations.argtypes = [_I, _C, _C, _P, _P, _P, _P, _P]
_lib.he_efh_forces.restype = None
_lib.he_efh_forces.argtypes = [_I, _C, _C, _P, _P, _P, _P, _P, _P]
_lib.he_efh_tangent.restype = None
_lib.he_efh_tangent.argtypes = [_I, _C, _C, _P, _P, _P, _P, _P, _P]
_ebound = {}


def element_kernels(name, per_cell=False):
    """{kind: C function} of material `name`'s element loops (per_cell: material_kernels')."""
    if (name, per_cell) not in _ebound:
        fns = {}
        for kind, extra in _ELEMENT_KERNELS.items():
            fn = getattr(_lib, f"he_e{kind}_{name}" + ("_cells" if per_cell else ""))
            fn.restype = _I
            fn.argtypes = [_I, _C, _C, _P, _P, _P, _P, _P] + extra
            fns[kind] = fn
        _ebound[(name, per_cell)] = fns
    return _ebound[(name, per_cell)]


class ElementCells:
    """Local cells of an element with quadrature (element.Element): their nodes (nc, nn), per (cell, point)
    of the stiffness rule J^-1 and the weight |det J| w_q (`geo`, nc x nq x 10), the mass rule's weights, and
    the kernels needing nothing else — Cells' interface for P2: the consistent mass matrix, the nodal
    integrals of a body load, the inversion guard's step bound, stored blocks."""

    def __init__(self, nodes, X, element, geo=None, mass_w=None):
        self.element = element
        self.cells = np.ascontiguousarray(nodes, dtype=IDX)
        self.nc, self.nn = self.cells.shape
        pts, w = element.rule()
        self.N, dN = element.tabulate()
        self.dN = np.ascontiguousarray(dN, dtype=np.float64)
        self.nq = len(w)
        if geo is None:
            geo = element_geometry(X, self.cells, self.dN, w)
        self.geo = np.ascontiguousarray(geo, dtype=np.float64)
        mp, mw = element.mass_rule()
        from ..element.reference import tet_shapes
        self.Nm = np.ascontiguousarray(tet_shapes(element.order, mp)[0])
        if mass_w is None:
            mass_w = element_geometry(X, self.cells, tet_shapes(element.order, mp)[1], mw, full=False)
        self.mass_w = np.ascontiguousarray(mass_w, dtype=np.float64)
        self.nqm = len(mw)
        self.vol = self.mass_w.sum(axis=1)
        self._args = (self.nc, self.nn, self.nq, _ptr(self.cells, IDX), _ptr(self.dN, np.float64),
                      _ptr(self.geo, np.float64))
        self._parts = {}

    def part(self, lo, hi):
        """The same cells lo..hi-1 (cached)."""
        if (lo, hi) not in self._parts:
            self._parts[(lo, hi)] = ElementCells(self.cells[lo:hi], None, self.element, self.geo[lo:hi],
                                                 self.mass_w[lo:hi])
        return self._parts[(lo, hi)]

    def weighted(self, w):
        """The same cells with their mass weights times w (a coefficient per cell: each region's density)."""
        return ElementCells(self.cells, None, self.element, self.geo,
                            np.asarray(w, np.float64)[:, None] * self.mass_w)

    def node_integrals(self, coef=1.0, which=None):
        """(n, nn): int coef N_a dV of the cells `which` (default all; the mass rule), coef a scalar or one
        per cell."""
        sel = slice(None) if which is None else which
        c = np.asarray(coef, float)
        return (self.mass_w[sel] * (c if c.ndim == 0 else c[sel][:, None])) @ self.Nm

    def subset(self, idx):
        """The cells idx (copies)."""
        return ElementCells(self.cells[idx], None, self.element, self.geo[idx], self.mass_w[idx])

    def kernels(self, material, constants):
        """A material's loops on these cells."""
        return ElementKernels(self, material, constants)

    load_shares = node_integrals

    def mass_diagonal(self, lumped, nlv):
        """(nlv,) the mass matrix's diagonal per node (density 1): consistent, or lumped by HRZ diagonal
        scaling (Hinton, Rock & Zienkiewicz, "A note on mass lumping and related processes in the finite
        element method", Earthquake Eng. Struct. Dyn. 4, 1976): each element's consistent diagonal scaled to
        the element's mass, which stays positive for P2, where the row sums give the vertices zero or
        negative mass (-V/20 on a straight tetrahedron)."""
        d = self.mass_w @ (self.Nm * self.Nm)                            # (nc, nn) consistent diagonals
        if lumped:
            d = d * (self.vol / d.sum(axis=1))[:, None]
        out = np.zeros(nlv)
        np.add.at(out, self.cells.ravel(), d.ravel())
        return out

    def max_step(self, x, d, frac=0.9):
        return _lib.he_emax_step(*self._args, _ptr(x, np.float64), _ptr(d, np.float64), float(frac))

    def deformations(self, x):
        """F (nc, nq, 3, 3) at each point of the stiffness rule, at positions x."""
        F = np.empty((self.nc, self.nq, 3, 3))
        _lib.he_edeformations(*self._args, _ptr(x, np.float64), _ptr(F, np.float64))
        return F

    def fh_forces(self, H, x, f):
        """Cells.fh_forces at each point of the stiffness rule (H: nc, nq, 3, 3)."""
        assert H.shape == (self.nc, self.nq, 3, 3) and H.flags.c_contiguous
        _lib.he_efh_forces(*self._args, _ptr(H, np.float64), _ptr(x, np.float64), _ptr(f, np.float64))

    def fh_tangent(self, H, diag=None, vals=None):
        """Cells.fh_tangent at each point of the stiffness rule."""
        n3 = 3 * self.nn
        assert H.shape == (self.nc, self.nq, 3, 3) and H.flags.c_contiguous
        assert vals is None or (vals.shape == (self.nc, n3, n3) and vals.flags.c_contiguous)
        _lib.he_efh_tangent(*self._args, _ptr(H, np.float64), None if diag is None else _ptr(diag, np.float64),
                            None if vals is None else _ptr(vals, np.float64))

    def apply_blocks(self, blocks, v, y):
        n3 = 3 * self.nn
        assert blocks.shape == (self.nc, n3, n3) and blocks.flags.c_contiguous
        _lib.he_eapply_blocks(self.nc, self.nn, _ptr(self.cells, IDX), _ptr(blocks, np.float64),
                              _ptr(v, np.float64), _ptr(y, np.float64))

    def add_mass_blocks(self, coef, vals):
        n3 = 3 * self.nn
        assert vals.shape == (self.nc, n3, n3)
        _lib.he_emass_blocks(self.nc, self.nn, self.nqm, _ptr(self.Nm, np.float64), _ptr(self.mass_w, np.float64),
                             float(coef), _ptr(vals, np.float64))

    def mass_apply(self, coef, v, y):
        _lib.he_emass_apply(self.nc, self.nn, self.nqm, _ptr(self.cells, IDX), _ptr(self.Nm, np.float64),
                            _ptr(self.mass_w, np.float64), float(coef), _ptr(v, np.float64), _ptr(y, np.float64))


class ElementKernels:
    """A material on ElementCells: CellKernels' interface (forces, energy, kv, tangent blocks (nc, 3nn, 3nn),
    tangent_diag, forces_discrete_gradient, max_step, apply_blocks, part, materials, parts, geometry)."""

    def __init__(self, cells, material, constants):
        self.geometry = cells
        self.cells, self.nc, self.nn = cells.cells, cells.nc, cells.nn
        self.material = material
        self.materials = (material,)
        self.constants = cell_constants(constants)
        self.fn = element_kernels(material.name, isinstance(self.constants, np.ndarray))
        self.prm = parameter_block(self.constants)
        self._prm = self._prm_k = _ptr(self.prm, np.float64)
        self.scale = 1.0
        self._args = cells._args
        self.parts = [(slice(None), self)]
        self._parts = {}

    def part(self, lo, hi):
        if (lo, hi) not in self._parts:
            self._parts[(lo, hi)] = ElementKernels(self.geometry.part(lo, hi), self.material,
                                                   _rows(self.constants, lo, hi))
            self._parts[(lo, hi)].scale_moduli(self.scale)
        return self._parts[(lo, hi)]

    scale_moduli = _scale_moduli
    unscaled = _unscaled

    def forces(self, x, f):
        return self.fn["forces"](*self._args, _ptr(x, np.float64), self._prm_k, _ptr(f, np.float64))

    def forces_discrete_gradient(self, x, xn, f):
        """The energy-momentum force, point by point (CellKernels.forces_discrete_gradient has the formulas)."""
        if self.material.quadratic:
            return self.forces(x, f)
        return self.fn["forces_dg"](*self._args, _ptr(x, np.float64), self._prm_k, _ptr(xn, np.float64),
                                    _ptr(f, np.float64))

    def energy(self, x):
        out = np.zeros(3)
        bad = self.fn["energy"](*self._args, _ptr(x, np.float64), self._prm, _ptr(out, np.float64))
        return out[0], out[1], out[2], bad

    def kv(self, x, v, y):
        return self.fn["kv"](*self._args, _ptr(x, np.float64), self._prm_k, _ptr(v, np.float64), _ptr(y, np.float64))

    def pk2(self, x):
        """(nc, nq, 3, 3): F^-1 P(F) at each point of the stiffness rule (CellKernels.pk2)."""
        S = np.empty((self.nc, self.geometry.nq, 3, 3))
        self.fn["pk2"](*self._args, _ptr(x, np.float64), self._prm, _ptr(S, np.float64))
        return S

    def tangent(self, x, vals=None, accumulate=False):
        n3 = 3 * self.nn
        if vals is None:
            vals = np.zeros((self.nc, n3, n3))
        assert vals.shape == (self.nc, n3, n3)
        bad = self.fn["tangent"](*self._args, _ptr(x, np.float64), self._prm_k, _ptr(vals, np.float64),
                                 int(accumulate))
        return vals, bad

    def tangent_diag(self, x, diag):
        return self.fn["tangent_diag"](*self._args, _ptr(x, np.float64), self._prm_k, _ptr(diag, np.float64))

    def max_step(self, x, d, frac=0.9):
        return self.geometry.max_step(x, d, frac)

    def apply_blocks(self, blocks, v, y):
        self.geometry.apply_blocks(blocks, v, y)
