"""PNG of one frame of an output file: the deformed boundary surface, coloured by displacement,
over the reference shape's outline."""
import os

import numpy as np

from ..core.errors import UserError
from .figures import pyplot
from ..core.files import cell_blocks, check_output_path, completed_frames, open_output, read_rows


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


def render(path, out, frame=-1):
    plt = pyplot()
    if not out.lower().endswith(".png") or os.path.isdir(out):
        raise UserError(f"plot: -o '{out}' must be a .png file")
    with open_output(path, "plot") as f:
        n = completed_frames(f)
        if n == 0:
            raise UserError(f"plot: '{path}' has no frames")
        i = frame if frame >= 0 else n + frame
        if not 0 <= i < n:
            raise UserError(f"plot: frame {frame} out of range (0..{n - 1})")
        tri = boundary_surface(f)
        rows, tri = np.unique(tri, return_inverse=True)        # only the surface's rows are read
        tri = tri.reshape(-1, 3)
        X, x = read_rows(f["mesh/points"], rows), read_rows(f["x"], rows, frame=i)
        t = f["time"][i]
        scene = f.attrs.get("scene", "")
    if not np.isfinite(x).all() or not np.isfinite(X).all():
        raise UserError(f"plot: frame {i} of '{path}' holds non-finite positions (choose another with --frame)")
    check_output_path(out, [path], suffixes=())
    u = np.linalg.norm(x - X, axis=1)
    fig = plt.figure(figsize=(8, 5))
    ax = fig.add_subplot(111, projection="3d")
    norm = plt.Normalize(0, max(u[tri].mean(axis=1).max(), 1e-300))
    draw(ax, X, x, tri, norm)
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=norm)
    fig.colorbar(sm, ax=ax, shrink=0.7, label="|displacement| [m]")
    ax.set_title(f"{scene}  t = {t:.3g} s  (frame {i}; grey: reference shape)")
    fig.tight_layout()
    tmp = f"{out}.{os.getpid()}.tmp"
    try:                          # written whole, then renamed: an earlier PNG stays until the new one is complete
        fig.savefig(tmp, dpi=110, format="png")
        os.replace(tmp, out)
    except OSError as e:
        raise UserError(f"plot: cannot write '{out}' ({e.strerror})") from None
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.remove(tmp)
    return out


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
