"""The boundary surface of an output's mesh (met once among its cells' faces, a block of cells at a time) and a
matplotlib drawing of a deformed surface over its reference (the thesis' figures: studies/repro). `hyperelastic plot`
renders with pyvista: picture.py."""
import numpy as np

from .figures import pyplot
from ..core.files import cell_blocks


def boundary_faces(tets):
    return met_once(np.concatenate([tets[:, [0, 2, 1]], tets[:, [0, 1, 3]], tets[:, [1, 2, 3]], tets[:, [0, 3, 2]]]))


def met_once(faces):
    """The faces (triangles) that appear once among `faces`, whatever their vertex order."""
    _, idx, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    return faces[idx[counts == 1]]


def boundary_surface(f):
    """The boundary triangles (rows of the output's nodes, outward) of an open output, its cells read a block at a
    time (files.cell_blocks): each block's faces met once are kept, and of those the ones met once overall (a face
    between two blocks is met once in each). Memory: one block and the surface."""
    return met_once(np.concatenate([boundary_faces(f["mesh/tetra"][lo:hi][:, :4]) for lo, hi in cell_blocks(f)]))


def draw(ax, X, x, tri, norm):
    """Boundary triangles `tri` of the deformed shape x (coloured by |x - X| with `norm`) over the
    reference shape X in grey, on a 3-D axis with equal aspect."""
    plt = pyplot()
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection    # (matplotlib: deferred, see figures.py)
    val = np.linalg.norm(x - X, axis=1)[tri].mean(axis=1)
    ref = Poly3DCollection(X[tri], facecolors=(0.5, 0.5, 0.5, 0.06), edgecolor=(0.3, 0.3, 0.3, 0.08), linewidths=0.2)
    ax.add_collection3d(ref)
    pc = Poly3DCollection(x[tri], facecolors=plt.cm.viridis(norm(val)), edgecolor=(0, 0, 0, 0.15), linewidths=0.2)
    ax.add_collection3d(pc)
    lo, hi = np.minimum(X.min(0), x.min(0)), np.maximum(X.max(0), x.max(0))
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    for setlim, ci in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), c):
        setlim(ci - r, ci + r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
