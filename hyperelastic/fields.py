"""Output fields of a frame: point fields (displacement, velocity) and cell fields (J, strain-energy
density, von Mises stress of the Cauchy stress, region), evaluated on the local cells from the
material's numpy reference (materials/NAME.py) and gathered into the input numbering by the Writer.

Cauchy stress sigma = P F^T / J (Bonet & Wood, eq. 5.41); von Mises sqrt(3/2 s:s), s = dev sigma. Where
the material is undefined (J <= 0 for Neo-Hookean) the energy density and stress are NaN. On quadratic cells
each field is its mean over the cell's quadrature points weighted by their weights (|det J| w_q: the cell
integral divided by the cell's volume).
"""
import numpy as np


POINT_FIELDS = ("displacement", "velocity")
POINT_SCALARS = ("pressure",)     # scalar point fields: the mixed formulation's pressure (mean Cauchy stress)
CELL_FIELDS = ("J", "energy_density", "von_mises")


def deformation_gradients(cells, Dminv, x):
    """F = Ds Dm^-1 per cell (n, 3, 3) from local positions x (flat)."""
    xc = x.reshape(-1, 3)[cells]
    Ds = np.stack([xc[:, 1] - xc[:, 0], xc[:, 2] - xc[:, 0], xc[:, 3] - xc[:, 0]], axis=-1)
    return Ds @ Dminv.reshape(-1, 3, 3)


def _per_cell(fn, F, *args):
    """fn(F, ...) vectorized, NaN for the cells where it fails (a singular F in an inverse)."""
    try:
        return fn(F, *args)
    except np.linalg.LinAlgError:
        out = []
        for f in F:
            try:
                out.append(fn(f[None], *args)[0])
            except np.linalg.LinAlgError:
                out.append(np.full(np.shape(fn(np.eye(3)[None], *args))[1:], np.nan))
        return np.array(out)


CHUNK = 32768     # cells per vectorized evaluation: the (n,3,3) temporaries stay ~10 MB, not ~500 B/tet


def cell_fields(kernels, x):
    """{J, energy_density, von_mises}: (nc,) arrays on the local cells of `kernels` at positions x
    (with a material per region: each region's cells by its material), CHUNK cells at a time."""
    out = {k: np.full(kernels.nc, np.nan) for k in CELL_FIELDS}
    for idx, k in kernels.parts:             # one material (CellKernels), or one per region
        cells = np.arange(kernels.nc)[idx]   # the local cells of this material
        for lo in range(0, k.nc, CHUNK):
            part = (_cell_fields(k.cells[lo:lo + CHUNK], k.Dminv[lo:lo + CHUNK], k, x) if k.nn == 4 else
                    _element_fields(k, x, lo, min(lo + CHUNK, k.nc)))
            for name in CELL_FIELDS:
                out[name][cells[lo:lo + CHUNK]] = part[name]
    return out


def _element_fields(k, x, lo, hi):
    """The fields of cells lo..hi-1 of ElementKernels k: at every quadrature point, then their weighted mean."""
    geo = k.geometry.geo[lo:hi]                                         # (n, nq, 10)
    nq = geo.shape[1]
    G = np.einsum("cqmj,qam->cqaj", geo[:, :, :9].reshape(-1, nq, 3, 3), k.geometry.dN)
    F = np.einsum("cai,cqaj->cqij", x.reshape(-1, 3)[k.cells[lo:hi]], G).reshape(-1, 3, 3)
    w = geo[:, :, 9]
    point = _point_fields(F, k)
    return {name: (v.reshape(-1, nq) * w).sum(axis=1) / w.sum(axis=1) for name, v in point.items()}


def _cell_fields(cells, Dminv, kernels, x):
    return _point_fields(deformation_gradients(cells, Dminv, x), kernels)


def _point_fields(F, kernels):
    """{J, energy_density, von_mises} of deformation gradients F (n, 3, 3) of a material's kernels."""
    mat, c = kernels.model, kernels.constants
    with np.errstate(all="ignore"):
        J = np.linalg.det(F)
        psi = _per_cell(mat.psi, F, c)
        P = _per_cell(mat.P, F, c)
        sigma = P @ np.swapaxes(F, -1, -2) / J[:, None, None]
        s = sigma - np.trace(sigma, axis1=-2, axis2=-1)[:, None, None] / 3.0 * np.eye(3)
        vm = np.sqrt(1.5 * np.einsum("cij,cij->c", s, s))
    psi = np.where(np.isfinite(psi), psi, np.nan)
    vm = np.where(np.isfinite(vm), vm, np.nan)
    return {"J": J, "energy_density": psi, "von_mises": vm}
