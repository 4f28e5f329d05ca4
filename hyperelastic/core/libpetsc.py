"""The few PETSc C functions petsc4py does not wrap, called through ctypes on the same libpetsc."""
import ctypes
import glob
import os

import numpy as np
import petsc4py
from petsc4py import PETSc

_lib = None
_INT = ctypes.c_int32            # PetscInt of the pip-built PETSc (checked against petsc4py in lib())


def lib():
    global _lib
    if _lib is None:
        cfg = petsc4py.get_config()
        d = os.path.join(cfg["PETSC_DIR"], cfg.get("PETSC_ARCH") or "", "lib")
        # the wheel ships libpetsc.so as a stub; the real library is libpetsc.so.X.Y (the largest file)
        path = max(glob.glob(os.path.join(d, "libpetsc.so*")), key=os.path.getsize)
        _lib = ctypes.CDLL(path)
        if np.dtype(PETSc.IntType).itemsize != ctypes.sizeof(_INT):
            raise RuntimeError("libpetsc: PetscInt is not 32-bit in this PETSc build (SeqAIJRowIJ assumes it)")
        _lib.SNESSetFunctionDomainError.argtypes = [ctypes.c_void_p]
        _lib.TSAlpha2GetParams.argtypes = [ctypes.c_void_p] + [ctypes.POINTER(ctypes.c_double)] * 4
        _lib.TSEvaluateWLTE.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_int),
                                        ctypes.POINTER(ctypes.c_double)]
        _lib.PetscErrorMessage.argtypes = [ctypes.c_int, ctypes.POINTER(ctypes.c_char_p),
                                           ctypes.POINTER(ctypes.c_char_p)]
        _lib.SNESSetLagPreconditionerPersists.argtypes = [ctypes.c_void_p, ctypes.c_int]
        _lib.SNESSetLagPreconditioner.argtypes = [ctypes.c_void_p, ctypes.c_int]
        for fn in ("MatSeqAIJGetArray", "MatSeqAIJRestoreArray", "MatSeqSBAIJGetArray", "MatSeqSBAIJRestoreArray"):
            getattr(_lib, fn).argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p)]
        _lib.DMPlexGetCones.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p)]
        _lib.MatMPIAIJGetSeqAIJ.argtypes = [ctypes.c_void_p] + [ctypes.POINTER(ctypes.c_void_p)] * 3
        _lib.MatGetSize.argtypes = [ctypes.c_void_p, ctypes.POINTER(_INT), ctypes.POINTER(_INT)]
        _lib.MatSeqAIJSetColumnIndices.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        _lib.MatSeqAIJSetPreallocation.argtypes = [ctypes.c_void_p, _INT, ctypes.c_void_p]
        for fn in ("MatGetRowIJ", "MatRestoreRowIJ"):
            getattr(_lib, fn).argtypes = [ctypes.c_void_p, ctypes.c_int64, ctypes.c_int, ctypes.c_int,
                                          ctypes.POINTER(_INT), ctypes.POINTER(ctypes.c_void_p),
                                          ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int)]
    return _lib


class SeqAIJRowIJ:
    """The row pointers and column indices of a SeqAIJ matrix as numpy views, without copies (petsc4py's
    getRowIJ copies them: at 660k tets that copy is ~100 B/tet of the peak), for `with`
    (MatGetRowIJ / MatRestoreRowIJ). blocks: of a (S)BAIJ matrix, its block rows and block columns."""

    def __init__(self, mat, blocks=False):
        self.mat, self.n, self.ia, self.ja, self.done = mat, _INT(), ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_int()
        self.blocks = int(blocks)

    def _call(self, fn):
        return getattr(lib(), fn)(_handle(self.mat), 0, 0, self.blocks, ctypes.byref(self.n),
                                  ctypes.byref(self.ia), ctypes.byref(self.ja), ctypes.byref(self.done))

    def __enter__(self):
        if self._call("MatGetRowIJ") or not self.done.value:
            raise RuntimeError("MatGetRowIJ failed")
        n = self.n.value
        ia = np.ctypeslib.as_array(ctypes.cast(self.ia, ctypes.POINTER(_INT)), shape=(n + 1,))
        nnz = int(ia[-1])
        ja = np.ctypeslib.as_array(ctypes.cast(self.ja, ctypes.POINTER(_INT)), shape=(nnz,)) if nnz else ia[:0]
        return ia, ja

    def __exit__(self, *exc):
        self._call("MatRestoreRowIJ")
        return False


class SeqAIJValues:
    """The CSR value array of a SeqAIJ matrix as a numpy view, for `with` (MatSeqAIJGetArray /
    MatSeqAIJRestoreArray: PETSc then knows the values changed). kind "SBAIJ": of a SeqSBAIJ matrix
    (its blocks' values, each block column-major)."""

    def __init__(self, mat, nnz, kind="AIJ"):
        self.mat, self.nnz, self.ptr, self.kind = mat, nnz, ctypes.c_void_p(), kind

    def __enter__(self):
        err = getattr(lib(), f"MatSeq{self.kind}GetArray")(_handle(self.mat), ctypes.byref(self.ptr))
        if err or not self.ptr.value:
            raise RuntimeError(f"MatSeq{self.kind}GetArray failed ({err})")
        return np.ctypeslib.as_array(ctypes.cast(self.ptr, ctypes.POINTER(ctypes.c_double)), shape=(self.nnz,))

    def __exit__(self, *exc):
        getattr(lib(), f"MatSeq{self.kind}RestoreArray")(_handle(self.mat), ctypes.byref(self.ptr))
        return False


def _handle(mat):
    """A petsc4py Mat's C handle, or a raw one (an int) as mpiaij_off_diagonal gives."""
    return ctypes.c_void_p(mat if isinstance(mat, int) else mat.handle)


def seqaij_from_pattern(mat, ia, ja):
    """A SeqAIJ `mat` (type set, sizes given) preallocated with the exact pattern ia/ja (PETSc's index type, each row's
    columns sorted), assembled, zero: the row lengths to MatSeqAIJSetPreallocation, the columns copied in at once by
    MatSeqAIJSetColumnIndices — not entered row by row through MatSetValues, as MatSeqAIJSetPreallocationCSR does (1.4 s
    of a 207k-tet P2 set-up). The matrix owns its arrays (its MatGetInfo and memory figures are the usual). (The same
    for SBAIJ, MatSeqSBAIJSetColumnIndices after MatSeqSBAIJSetPreallocation, corrupted the heap here: not used.)"""
    ia, ja = np.ascontiguousarray(ia, PETSc.IntType), np.ascontiguousarray(ja, PETSc.IntType)
    nnz = np.ascontiguousarray(np.diff(ia), PETSc.IntType)
    if lib().MatSeqAIJSetPreallocation(_handle(mat), 0, nnz.ctypes.data):
        raise RuntimeError("MatSeqAIJSetPreallocation failed")
    if lib().MatSeqAIJSetColumnIndices(_handle(mat), ja.ctypes.data):
        raise RuntimeError("MatSeqAIJSetColumnIndices failed")
    mat.assemble()
    mat.zeroEntries()


def mpiaij_off_diagonal(mat, columns=True):
    """MatMPIAIJGetSeqAIJ: the raw handle of an MPIAIJ matrix's off-diagonal SeqAIJ part, which belongs to
    `mat` (valid while its pattern is), and with `columns` a copy of its columns' global indices:
    (handle, columns) or the handle alone."""
    ad, ao, colmap = ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_void_p()
    if lib().MatMPIAIJGetSeqAIJ(ctypes.c_void_p(mat.handle), ctypes.byref(ad), ctypes.byref(ao), ctypes.byref(colmap)):
        raise RuntimeError("MatMPIAIJGetSeqAIJ failed")
    if not columns:
        return ao.value
    m, n = _INT(), _INT()
    lib().MatGetSize(ao, ctypes.byref(m), ctypes.byref(n))
    cols = (np.ctypeslib.as_array(ctypes.cast(colmap, ctypes.POINTER(_INT)), shape=(n.value,)).copy()
            if n.value else np.zeros(0, np.int32))
    return ao.value, cols


def lag_preconditioner_persists(snes, flag=True):
    """SNESSetLagPreconditionerPersists: the preconditioner lag holds across SNESSolve calls (time steps)."""
    lib().SNESSetLagPreconditionerPersists(ctypes.c_void_p(snes.handle), int(bool(flag)))


def lag_preconditioner(snes, lag):
    """SNESSetLagPreconditioner: -1 keep the preconditioner, -2 set it up at the next Jacobian, then keep it."""
    err = lib().SNESSetLagPreconditioner(ctypes.c_void_p(snes.handle), int(lag))
    if err:
        raise RuntimeError(f"SNESSetLagPreconditioner failed ({err})")


def set_function_domain_error(snes):
    """SNESSetFunctionDomainError: the residual was asked for outside the material's domain
    (an inverted element for Neo-Hookean); SNES then stops with DIVERGED_FUNCTION_DOMAIN."""
    lib().SNESSetFunctionDomainError(ctypes.c_void_p(snes.handle))


def alpha2_params(ts):
    """TSAlpha2GetParams: (alpha_m, alpha_f, gamma, beta) in use now (TSALPHA2 sets (1, 1, 1, 1/2) while
    it computes its starting acceleration by two backward Euler half steps)."""
    v = [ctypes.c_double() for _ in range(4)]
    err = lib().TSAlpha2GetParams(ctypes.c_void_p(ts.handle), *[ctypes.byref(x) for x in v])
    if err:
        raise RuntimeError(f"TSAlpha2GetParams failed ({err})")
    return tuple(x.value for x in v)


def evaluate_wlte(ts, norm="2"):
    """TSEvaluateWLTE: the weighted local truncation error estimate of the step just solved, in the
    adaptor's norm (-ts_adapt_wnormtype 2 (default) or infinity), which it accepts when <= 1; -1 where
    the method has none (no adaptor)."""
    order, w = ctypes.c_int(), ctypes.c_double()
    kind = 3 if norm.lower() in ("infinity", "inf") else 1          # NORM_INFINITY, NORM_2
    err = lib().TSEvaluateWLTE(ctypes.c_void_p(ts.handle), kind, ctypes.byref(order), ctypes.byref(w))
    return w.value if not err else -1.0


def error_message(code):
    """PETSc's text for an error code, and the specific message of the last error raised."""
    text, specific = ctypes.c_char_p(), ctypes.c_char_p()
    try:
        lib().PetscErrorMessage(int(code), ctypes.byref(text), ctypes.byref(specific))
    except Exception:
        return f"PETSc error {code}"
    parts = [p.decode(errors="replace").strip() for p in (text.value, specific.value) if p]
    return ": ".join(parts) or f"PETSc error {code}"


def plex_cones(dm):
    """The cones of an interpolated DMPlex of tetrahedra as numpy copies: (cell -> 4 faces, face -> 3 edges,
    edge -> 2 vertices), point numbers of the DM. DMPlexGetCones gives all cones concatenated in chart order
    (cells, vertices (none), faces, edges here: each stratum's cone size is fixed); petsc4py has getCone per
    point only, which costs ~1 us a point."""
    ptr = ctypes.c_void_p()
    if lib().DMPlexGetCones(ctypes.c_void_p(dm.handle), ctypes.byref(ptr)):
        raise RuntimeError("DMPlexGetCones failed")
    strata = [dm.getHeightStratum(h) for h in range(4)]        # cells, faces, edges, vertices
    (c0, c1), (f0, f1), (e0, e1), (v0, v1) = strata
    if not (c0 == 0 and c1 <= v0 and v1 <= f0 and f1 <= e0):
        raise RuntimeError(f"unexpected point layout of the DMPlex: {strata}")
    total = 4 * (c1 - c0) + 3 * (f1 - f0) + 2 * (e1 - e0)
    if not total:
        return np.zeros((0, 4), np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 2), np.int64)
    cones = np.ctypeslib.as_array(ctypes.cast(ptr, ctypes.POINTER(_INT)), shape=(total,)).astype(np.int64)
    nc, nf = 4 * (c1 - c0), 3 * (f1 - f0)
    return cones[:nc].reshape(-1, 4), cones[nc:nc + nf].reshape(-1, 3), cones[nc + nf:].reshape(-1, 2)


def cell_cones(dm):
    """The corners of an uninterpolated DMPlex's tetrahedra, (nc, 4) point numbers, from DMPlexGetCones in one call
    (petsc4py's getCone per cell costs ~3 us a cell in the space's set-up); None where the layout is not cells, then
    vertices."""
    (c0, c1), v0 = dm.getHeightStratum(0), dm.getDepthStratum(0)[0]
    if dm.getDepth() != 1 or c0 != 0 or v0 != c1 or c1 == c0:
        return None
    ptr = ctypes.c_void_p()
    if lib().DMPlexGetCones(ctypes.c_void_p(dm.handle), ctypes.byref(ptr)):
        raise RuntimeError("DMPlexGetCones failed")
    cones = np.ctypeslib.as_array(ctypes.cast(ptr, ctypes.POINTER(_INT)), shape=(4 * (c1 - c0),)).astype(np.int64)
    return cones.reshape(-1, 4)


def _petsc_free(ptr):
    """PetscFree of memory PETSc allocated for us (PetscFree is a macro over the function pointer PetscTrFree)."""
    fp = ctypes.c_void_p.in_dll(lib(), "PetscTrFree").value
    free = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)(fp)
    if free(ptr, 0, b"plex_from_slices", b"libpetsc.py"):
        raise RuntimeError("PetscFree failed")


def plex_from_slices(comm, cells, n_owned, n_vertices, coords):
    """A distributed, uninterpolated DMPlex of tetrahedra built from every rank's slice (collective;
    DMPlexBuildFromCellListParallel + DMPlexBuildCoordinatesFromCellListParallel, which petsc4py does not wrap):
    cells (nc, 4) this rank's cells by global vertex number, its local cells in that order; n_owned: the vertices
    this rank holds, a contiguous range in rank order (coords (n_owned, 3) their positions), n_vertices: all.
    Returns (dm, the global vertex number of each of the DM's local vertices, in their order)."""
    L = lib()
    for fn, args in (("DMPlexBuildFromCellListParallel", [ctypes.c_void_p] + [_INT] * 4 +
                      [ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_void_p)]),
                     ("DMPlexBuildCoordinatesFromCellListParallel", [ctypes.c_void_p, _INT, ctypes.c_void_p,
                                                                     ctypes.c_void_p]),
                     ("PetscSFDestroy", [ctypes.POINTER(ctypes.c_void_p)])):
        getattr(L, fn).argtypes = args
    dm = PETSc.DMPlex().create(comm=comm)
    dm.setDimension(3)
    c = np.ascontiguousarray(cells, np.int32)
    x = np.ascontiguousarray(coords, np.float64)
    sf, adj = ctypes.c_void_p(), ctypes.c_void_p()
    err = L.DMPlexBuildFromCellListParallel(ctypes.c_void_p(dm.handle), len(c), int(n_owned), int(n_vertices), 4,
                                            c.ctypes.data_as(ctypes.c_void_p), ctypes.byref(sf), ctypes.byref(adj))
    if err:
        raise RuntimeError(f"DMPlexBuildFromCellListParallel: {error_message(err)}")
    v0, v1 = dm.getDepthStratum(0)
    vertices = (np.ctypeslib.as_array(ctypes.cast(adj, ctypes.POINTER(_INT)), shape=(v1 - v0,)).astype(np.int64)
                if v1 > v0 else np.zeros(0, np.int64))
    _petsc_free(adj)
    err = L.DMPlexBuildCoordinatesFromCellListParallel(ctypes.c_void_p(dm.handle), 3, sf,
                                                       x.ctypes.data_as(ctypes.c_void_p))
    L.PetscSFDestroy(ctypes.byref(sf))
    if err:
        raise RuntimeError(f"DMPlexBuildCoordinatesFromCellListParallel: {error_message(err)}")
    return dm, vertices
