"""Spatial ordering of a mesh: cells along a Z-order (Morton) curve through their centroids, vertices numbered by
first use, so that contiguous ranges of cells are compact parts (the `morton` partition, prepared meshes' slices)."""
import numpy as np


def morton_order(centroids):
    """Order of points along a Z-order (Morton) curve, 21 bits per axis. The box is scaled by the
    same factor on every axis and the longest axis takes the most significant bit, so the first
    halving of the curve cuts across the longest extent (a bar splits into two shorter bars)."""
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    ext = hi - lo
    q = ((centroids - lo) / max(ext.max(), 1e-300) * (2 ** 21 - 1)).astype(np.uint64)

    def spread(v):
        v = v & np.uint64(0x1FFFFF)
        for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                            (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        return v
    axes = np.argsort(ext)          # shortest first: it gets the least significant position
    code = np.zeros(len(centroids), np.uint64)
    for pos, ax in enumerate(axes):
        code |= spread(q[:, ax]) << np.uint64(pos)
    return np.argsort(code, kind="stable")


def spatial_order(points, tets):
    """Reorder cells along a space-filling curve and number vertices by first use, so that the
    'simple' partitioner (contiguous cell ranges) gives compact parts. Returns (points', tets',
    vertex_perm) with points' = points[vertex_perm], and the cell permutation."""
    corder = morton_order(points[tets].mean(axis=1))
    t = tets[corder]
    flat = t.ravel()
    uniq, idx = np.unique(flat, return_index=True)
    vperm = uniq[np.argsort(idx, kind="stable")]  # vertices in order of first appearance
    inv = np.empty(len(points), np.int64)
    inv[vperm] = np.arange(len(vperm))
    return points[vperm], inv[t], vperm, corder
