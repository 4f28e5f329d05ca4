"""Output fields of a frame: point fields (displacement, velocity) and cell fields (J, strain-energy
density, von Mises stress of the Cauchy stress, region), evaluated on the local cells from the
material's numpy reference (materials/NAME.py) and gathered into the input numbering by the Writer.

Cauchy stress sigma = P F^T / J (Bonet & Wood, eq. 5.41); von Mises sqrt(3/2 s:s), s = dev sigma. Where
the material is undefined (J <= 0 for Neo-Hookean) the energy density and stress are NaN. On quadratic cells
each field is its mean over the cell's quadrature points weighted by their weights (|det J| w_q: the cell
integral divided by the cell's volume).

On request (-output_fields): `stress` the Cauchy stress tensor and `strain` the Green–Lagrange strain
E = (F^T F - I)/2 (Bonet & Wood, eq. 3.15), each as XDMF's Tensor6 (xx, xy, xz, yy, yz, zz);
`principal_stress` the Cauchy stress's eigenvalues, largest first; `NAME_nodal` a cell field averaged at
the nodes, each cell weighted by its reference volume (rank-count independent: done on rank 0 in the input
numbering). With the mixed formulation the stress's mean is the pressure field's (p, the mean Cauchy stress,
averaged over the cell's corners), not the material's volumetric response to J.
"""
import numpy as np

from ..core.errors import UserError


POINT_FIELDS = ("displacement", "velocity")
POINT_SCALARS = ("pressure",)     # scalar point fields: the mixed formulation's pressure (mean Cauchy stress)
CELL_FIELDS = ("J", "energy_density", "von_mises")
TENSOR_FIELDS = ("stress", "strain")              # Tensor6 cell fields, on request
EXTRA_CELL_FIELDS = TENSOR_FIELDS + ("principal_stress",)
NODAL = "_nodal"
NODAL_OF = CELL_FIELDS + EXTRA_CELL_FIELDS        # the cell fields that have a NAME_nodal
OUTPUT_FIELDS = POINT_FIELDS + CELL_FIELDS + EXTRA_CELL_FIELDS + tuple(n + NODAL for n in NODAL_OF)
DEFAULT_FIELDS = POINT_FIELDS + CELL_FIELDS
TENSOR6 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def is_point_field(name):
    """Whether the written field `name` has a value per node (else per cell)."""
    return name in POINT_FIELDS + POINT_SCALARS or name.endswith(NODAL)


def output_fields(words):
    """The fields a run writes: -output_fields' words (names of OUTPUT_FIELDS, `default`, `all`) in
    OUTPUT_FIELDS' order; UserError on an unknown name."""
    if not words:
        return DEFAULT_FIELDS
    chosen = set()
    for w in words:
        if w == "default":
            chosen.update(DEFAULT_FIELDS)
        elif w == "all":
            chosen.update(OUTPUT_FIELDS)
        elif w in OUTPUT_FIELDS:
            chosen.add(w)
        else:
            raise UserError(f"option -output_fields: unknown field '{w}' (choose from default, all, "
                            f"{', '.join(OUTPUT_FIELDS)})")
    return tuple(n for n in OUTPUT_FIELDS if n in chosen)


def cell_quantities(fields):
    """What the cells must evaluate for `fields`: names among CELL_FIELDS + TENSOR_FIELDS (the principal
    stresses come from the stress)."""
    base = {n[:-len(NODAL)] if n.endswith(NODAL) else n for n in fields}
    if "principal_stress" in base:
        base.add("stress")
    return tuple(n for n in CELL_FIELDS + TENSOR_FIELDS if n in base)


def finish(cells, fields, tets=None, volume=None, pressure=None, total=None):
    """The written fields from the cell quantities `cells` of the cells `tets` (rank 0's gathered ones in input
    order, or each rank's own): the stress's mean from the mixed pressure (node values; its P1 corners), the
    principal stresses, the nodal averages (volume: the cells' reference volumes; total: with each rank's own
    cells, sums a (local nodes, k) array over the ranks into the rows of the nodes it owns, Space.sum_owned);
    only `fields` are kept."""
    out = dict(cells)
    if "stress" in out and pressure is not None:
        s = out["stress"]
        mean = (s[:, 0] + s[:, 3] + s[:, 5]) / 3.0
        p = pressure[tets[:, :4]].mean(axis=1)
        s = s.copy()
        for k in (0, 3, 5):
            s[:, k] += p - mean
        out["stress"] = s
    if "principal_stress" in fields:
        S = np.empty((len(out["stress"]), 3, 3))
        for k, (i, j) in enumerate(TENSOR6):
            S[:, i, j] = S[:, j, i] = out["stress"][:, k]
        ok = np.isfinite(S).all(axis=(1, 2))
        ev = np.full((len(S), 3), np.nan)
        ev[ok] = np.linalg.eigvalsh(S[ok])[:, ::-1]
        out["principal_stress"] = ev
    for name in fields:
        if name.endswith(NODAL):
            out[name] = nodal_average(out[name[:-len(NODAL)]], tets, volume, total)
    return {n: out[n] for n in fields if n in out}


def nodal_average(values, tets, volume, total=None):
    """Cell values averaged at every node of the cells (weights: the cells' volumes); NaN cells left out. total:
    sums the (nodes, k + 1) numerators and weights over the ranks (see finish): the owned nodes' averages."""
    nv = int(tets.max()) + 1 if len(tets) else 0
    v = values.reshape(len(values), -1)
    w = np.where(np.isfinite(v).all(axis=1), volume, 0.0)
    num = np.zeros((nv, v.shape[1]))
    den = np.zeros(nv)
    for a in range(tets.shape[1]):
        np.add.at(num, tets[:, a], np.nan_to_num(v) * w[:, None])
        np.add.at(den, tets[:, a], w)
    if total is not None:
        both = total(np.concatenate([num, den[:, None]], axis=1), nv)
        num, den = both[:, :-1], both[:, -1]
    with np.errstate(all="ignore"):
        out = num / den[:, None]
    return out.reshape((len(out),) + values.shape[1:])


def reference_volumes(points, tets):
    """The cells' volumes from their corners (the weights of nodal_average)."""
    X = points[tets[:, :4]]
    return np.abs(np.einsum("ci,ci->c", X[:, 1] - X[:, 0], np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]))) / 6


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


def cell_fields(kernels, x, names=CELL_FIELDS):
    """{name: (nc,) or (nc, 6) array} of `names` (CELL_FIELDS, TENSOR_FIELDS) on the local cells of `kernels`
    at positions x (with a material per region: each region's cells by its material), CHUNK cells at a time."""
    out = {k: np.full((kernels.nc, 6) if k in TENSOR_FIELDS else kernels.nc, np.nan) for k in names}
    for idx, k in kernels.parts:             # one material (CellKernels), or one per region
        cells = np.arange(kernels.nc)[idx]   # the local cells of this material
        for lo in range(0, k.nc, CHUNK):
            part = (_compiled_fields(k, x, lo, min(lo + CHUNK, k.nc), names) if k.nn == 4 else
                    _element_fields(k, x, lo, min(lo + CHUNK, k.nc), names))
            for name in names:
                out[name][cells[lo:lo + CHUNK]] = part[name]
    return out


def _element_fields(k, x, lo, hi, names):
    """The fields of cells lo..hi-1 of ElementKernels k: at every quadrature point, then their weighted mean."""
    geo = k.geometry.geo[lo:hi]                                         # (n, nq, 10)
    nq = geo.shape[1]
    G = np.einsum("cqmj,qam->cqaj", geo[:, :, :9].reshape(-1, nq, 3, 3), k.geometry.dN)
    F = np.einsum("cai,cqaj->cqij", x.reshape(-1, 3)[k.cells[lo:hi]], G).reshape(-1, 3, 3)
    w = geo[:, :, 9]
    point = _point_fields(F, k, names)
    out = {}
    for name, v in point.items():
        v = v.reshape((-1, nq) + v.shape[1:])
        out[name] = np.einsum("cq...,cq->c...", v, w) / w.sum(axis=1).reshape((-1,) + (1,) * (v.ndim - 2))
    return out


# the columns of the compiled loop (discretization/_material_loops.h: he_fields_NAME) by field
COMPILED = {"J": 0, "energy_density": 1, "von_mises": 2, "stress": slice(3, 9), "strain": slice(9, 15)}


def _compiled_fields(k, x, lo, hi, names=CELL_FIELDS):
    """The fields of P1 cells lo..hi-1 of CellKernels k by the material's compiled loop (its C stress; ~10x the
    numpy reference's speed, which _cell_fields keeps for the tests)."""
    out = k.part(lo, hi).fields(x) if (lo, hi) != (0, k.nc) else k.fields(x)
    return {n: out[:, COMPILED[n]] for n in names}


def _cell_fields(cells, Dminv, kernels, x, names=CELL_FIELDS):
    """The fields of P1 cells by the materials' numpy reference (what _compiled_fields is checked against)."""
    return _point_fields(deformation_gradients(cells, Dminv, x), kernels, names)


def _point_fields(F, kernels, names=CELL_FIELDS):
    """{name: value} of `names` (CELL_FIELDS, TENSOR_FIELDS) of deformation gradients F (n, 3, 3) of a
    material's kernels."""
    mat, c = kernels.material, kernels.constants
    with np.errstate(all="ignore"):
        J = np.linalg.det(F)
        psi = _per_cell(mat.psi, F, c)
        P = _per_cell(mat.P, F, c)
        sigma = P @ np.swapaxes(F, -1, -2) / J[:, None, None]
        s = sigma - np.trace(sigma, axis1=-2, axis2=-1)[:, None, None] / 3.0 * np.eye(3)
        vm = np.sqrt(1.5 * np.einsum("cij,cij->c", s, s))
    psi = np.where(np.isfinite(psi), psi, np.nan)
    vm = np.where(np.isfinite(vm), vm, np.nan)
    out = {"J": J, "energy_density": psi, "von_mises": vm}
    if "stress" in names:
        out["stress"] = _tensor6(np.where(np.isfinite(sigma), sigma, np.nan))
    if "strain" in names:
        out["strain"] = _tensor6(0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(3)))
    return {n: out[n] for n in names}


def _tensor6(T):
    return np.stack([T[:, i, j] for i, j in TENSOR6], axis=1)
