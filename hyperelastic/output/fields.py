"""Output fields of a frame: point fields (displacement, velocity) and cell fields (J, strain-energy
density, von Mises stress of the Cauchy stress, region), evaluated on the local cells from the
material's numpy reference (materials/NAME.py) and gathered into the input numbering by the Writer.

Cauchy stress sigma = P F^T / J (Bonet & Wood, eq. 5.41); von Mises sqrt(3/2 s:s), s = dev sigma. Where
the material is undefined (J <= 0 for Neo-Hookean) the energy density and stress are NaN. On quadratic cells
each field is its mean over the cell's quadrature points weighted by their weights (|det J| w_q: the cell
integral divided by the cell's volume).

`stress_recovered` (on request, a point field): the Cauchy stress recovered at the nodes at the element's accuracy. On
each cell the stress at its quadrature points is fitted by a linear field of the reference coordinates (the 4-point
rule of P2: interpolated; the gradient of a P2 displacement is linear on a straight cell) and evaluated at the cell's
nodes, then each node takes the volume-weighted mean of its cells' values: the extrapolate-and-average recovery that
Abaqus uses for nodal output (Abaqus Analysis User's Guide, "Output variables: nodal averaging"; for recovery in
general Zienkiewicz & Zhu, IJNME 33, 1992). Its error at the nodes falls as h^2 on P2 where a cell's mean falls as h
(tests/test_recovery.py on Rivlin's torsion); on P1 cells the stress is constant and it equals `stress_nodal`.
`von_mises_recovered` is the von Mises stress of it. With the mixed formulation its mean is the pressure at the node.

On request (-output_fields): `stress` the Cauchy stress tensor and `strain` the Green–Lagrange strain
E = (F^T F - I)/2 (Bonet & Wood, eq. 3.15), each as XDMF's Tensor6 (xx, xy, xz, yy, yz, zz); `fibre1_stretch`,
`fibre2_stretch` a fibre-reinforced material's fibre stretches |F a| (NaN in cells of a material without the family);
`principal_stress` the Cauchy stress's eigenvalues, largest first; `NAME_nodal` a cell field averaged at
the nodes, each cell weighted by its reference volume (rank-count independent: done on rank 0 in the input
numbering). With the mixed formulation the stress's mean is the pressure field's (p, the mean Cauchy stress,
averaged over the cell's corners), not the material's volumetric response to J.
"""
import numpy as np

from ..core.errors import UserError
from ..element.reference import REFERENCE_NODES


POINT_FIELDS = ("displacement", "velocity")
# scalar point fields: the mixed formulation's pressure (the mean Cauchy stress); contact's pressure (the barrier's force
# per unit reference area at a contact node) and status (the number of the nearest obstacle within dhat, -1 where the
# node is in a self-contact pair only, 0: none), seams.Results
POINT_SCALARS = ("pressure", "contact_pressure", "contact_status")
CELL_FIELDS = ("J", "energy_density", "von_mises")
TENSOR_FIELDS = ("stress", "strain")              # Tensor6 cell fields, on request
# a fibre-reinforced material's fibre stretches |F a_i| (hgo), on request; NaN in a cell with no such family
FIBRE_FIELDS = ("fibre1_stretch", "fibre2_stretch")
EXTRA_CELL_FIELDS = TENSOR_FIELDS + ("principal_stress",) + FIBRE_FIELDS
NODAL = "_nodal"
NODAL_OF = CELL_FIELDS + EXTRA_CELL_FIELDS        # the cell fields that have a NAME_nodal
RECOVERED = ("stress_recovered", "von_mises_recovered")    # point fields recovered from the quadrature points
AT_NODES = "stress_at_nodes"        # (the cell quantity they need: each cell's stress at its nodes, (nc, nn * 6))
OUTPUT_FIELDS = POINT_FIELDS + CELL_FIELDS + EXTRA_CELL_FIELDS + tuple(n + NODAL for n in NODAL_OF) + RECOVERED
DEFAULT_FIELDS = POINT_FIELDS + CELL_FIELDS
TENSOR6 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def is_point_field(name):
    """Whether the written field `name` has a value per node (else per cell)."""
    return name in POINT_FIELDS + POINT_SCALARS + RECOVERED or name.endswith(NODAL)


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
    stresses come from the stress) and AT_NODES (the recovered fields)."""
    base = {n[:-len(NODAL)] if n.endswith(NODAL) else n for n in fields}
    if "principal_stress" in base:
        base.add("stress")
    if base & set(RECOVERED):
        base.add(AT_NODES)
    return tuple(n for n in CELL_FIELDS + TENSOR_FIELDS + FIBRE_FIELDS + (AT_NODES,) if n in base)


def needs_volumes(fields):
    """Whether `fields` are averaged at the nodes (weighted by the cells' reference volumes)."""
    return any(n.endswith(NODAL) or n in RECOVERED for n in fields)


def finish(cells, fields, tets=None, volume=None, pressure=None, total=None):
    """The written fields from the cell quantities `cells` of the cells `tets` (rank 0's gathered ones in input
    order, or each rank's own): the stress's mean from the mixed pressure (node values; its P1 corners), the
    principal stresses, the nodal averages (volume: the cells' reference volumes; total: with each rank's own
    cells, sums a (local nodes, k) array over the ranks into the rows of the nodes it owns, Space.sum_owned);
    only `fields` are kept."""
    out = dict(cells)
    if "stress" in out and pressure is not None:
        out["stress"] = with_mean(out["stress"], pressure[tets[:, :4]].mean(axis=1))
    if AT_NODES in out and set(fields) & set(RECOVERED):
        out.update(recover(out[AT_NODES], tets, volume, pressure, total))
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


def recover(at_nodes, cells, volume, pressure=None, total=None):
    """{stress_recovered, von_mises_recovered} at the nodes from each cell's stress at its nodes (nc, nn * 6; the
    cells' own node order: `cells` must be the cells the values were computed on), averaged with the cells' volumes
    (total: over the ranks, into the owned nodes' rows, as in finish); pressure: the mixed formulation's at the
    nodes, which becomes the mean there."""
    sn = at_nodes.reshape(len(cells), cells.shape[1], 6)
    if pressure is not None:
        sn = with_mean(sn, pressure[cells])
    rec = nodal_average(sn, cells, volume, total, per_node=True)
    dev = with_mean(rec, 0.0)
    vm = np.sqrt(1.5 * (dev[:, 0] ** 2 + dev[:, 3] ** 2 + dev[:, 5] ** 2)
                 + 3.0 * (dev[:, 1] ** 2 + dev[:, 2] ** 2 + dev[:, 4] ** 2))
    return {"stress_recovered": rec, "von_mises_recovered": vm}


def with_mean(s, p):
    """Tensor6 stresses s (..., 6) with their mean (xx + yy + zz)/3 replaced by p (the mixed formulation's pressure;
    0: the deviator), a copy."""
    s = s.copy()
    shift = p - (s[..., 0] + s[..., 3] + s[..., 5]) / 3.0
    for k in (0, 3, 5):
        s[..., k] += shift
    return s


def nodal_average(values, tets, volume, total=None, per_node=False):
    """Cell values averaged at every node of the cells (weights: the cells' volumes); NaN cells left out. total:
    sums the (nodes, k + 1) numerators and weights over the ranks (see finish): the owned nodes' averages.
    per_node: values (nc, nn, ...) hold each cell's value at each of its nodes (else one per cell)."""
    nv = int(tets.max()) + 1 if len(tets) else 0
    nn = tets.shape[1]
    v = values.reshape(len(values), nn, -1) if per_node else values.reshape(len(values), 1, -1)
    ok = np.isfinite(v).all(axis=(1, 2))
    w = np.where(ok, volume, 0.0)
    num = np.zeros((nv, v.shape[2]))
    den = np.zeros(nv)
    for a in range(nn):
        np.add.at(num, tets[:, a], np.nan_to_num(v[:, a if per_node else 0]) * w[:, None])
        np.add.at(den, tets[:, a], w)
    if total is not None:
        both = total(np.concatenate([num, den[:, None]], axis=1), nv)
        num, den = both[:, :-1], both[:, -1]
    with np.errstate(all="ignore"):
        out = num / den[:, None]
    return out.reshape((len(out),) + values.shape[2 if per_node else 1:])


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
        for i, f in enumerate(F):
            row = [a[i:i + 1] if isinstance(a, np.ndarray) and len(a) == len(F) else a for a in args]  # (per F)
            try:
                out.append(fn(f[None], *row)[0])
            except np.linalg.LinAlgError:
                out.append(np.full(np.shape(fn(np.eye(3)[None], *row))[1:], np.nan))
        return np.array(out)


CHUNK = 32768     # points per vectorized evaluation: the (n,3,3) temporaries stay ~10 MB, not ~500 B/tet (P2: the
#                   cells' quadrature points, 8,192 cells of 4: a frame of 28k P2 cells in one piece peaked 52 MB higher)


def cell_fields(kernels, x, names=CELL_FIELDS):
    """{name: (nc,) or (nc, 6) array} of `names` (CELL_FIELDS, TENSOR_FIELDS) on the local cells of `kernels`
    at positions x (with a material per region: each region's cells by its material), CHUNK points at a time."""
    nn = kernels.parts[0][1].nn if kernels.parts else 4
    shape = {**{k: (kernels.nc, 6) for k in TENSOR_FIELDS}, AT_NODES: (kernels.nc, 6 * nn)}
    out = {k: np.full(shape.get(k, kernels.nc), np.nan) for k in names}
    for idx, k in kernels.parts:             # one material (CellKernels), or one per region
        cells = np.arange(kernels.nc)[idx]   # the local cells of this material
        n = CHUNK if k.nn == 4 else max(1, CHUNK // k.geometry.nq)
        for lo in range(0, k.nc, n):
            part = (_compiled_fields(k, x, lo, min(lo + n, k.nc), names) if k.nn == 4 else
                    _element_fields(k, x, lo, min(lo + n, k.nc), names))
            for name in names:
                out[name][cells[lo:lo + n]] = part[name]
    return out


def _element_fields(k, x, lo, hi, names):
    """The fields of cells lo..hi-1 of ElementKernels k: at every quadrature point, then their weighted mean."""
    geo = k.geometry.geo[lo:hi]                                         # (n, nq, 10)
    nq = geo.shape[1]
    # G_cqaj = sum_m dN_qam Jinv_cqmj and F_cqij = sum_a x_cai G_cqaj as batched matrix products (numpy's einsum
    # loops: ~7x slower, 54 ms a frame at 10.5k P2 cells)
    G = np.matmul(k.geometry.dN[None], geo[:, :, :9].reshape(-1, nq, 3, 3))
    F = np.matmul(np.swapaxes(x.reshape(-1, 3)[k.cells[lo:hi]], 1, 2)[:, None], G).reshape(-1, 3, 3)
    w = geo[:, :, 9]
    point = _point_fields(F, k, tuple(n for n in names if n != AT_NODES) + (("stress",) if AT_NODES in names else ()),
                          _constants(k, lo, hi, nq))
    out = {}
    if AT_NODES in names:                # each cell's stress at its nodes: the quadrature points' linear fit
        at_q = point["stress"].reshape(-1, nq, 6)
        out[AT_NODES] = np.einsum("aq,cqk->cak", extrapolation(k.geometry.element), at_q).reshape(len(at_q), -1)
        if "stress" not in names:
            del point["stress"]
    for name, v in point.items():
        v = v.reshape((-1, nq) + v.shape[1:])
        out[name] = np.einsum("cq...,cq->c...", v, w) / w.sum(axis=1).reshape((-1,) + (1,) * (v.ndim - 2))
    return out


# the columns of the compiled loop (discretization/_material_loops.h: he_fields_NAME) by field
COMPILED = {"J": 0, "energy_density": 1, "von_mises": 2, "stress": slice(3, 9), "strain": slice(9, 15)}


def _compiled_fields(k, x, lo, hi, names=CELL_FIELDS):
    """The fields of P1 cells lo..hi-1 of CellKernels k by the material's compiled loop (its C stress; ~10x the
    numpy reference's speed, which _cell_fields keeps for the tests); AT_NODES: the cell's constant stress at its
    four nodes."""
    out = k.part(lo, hi).fields(x) if (lo, hi) != (0, k.nc) else k.fields(x)
    res = {n: out[:, COMPILED[n]] for n in names if n in COMPILED}
    if AT_NODES in names:
        res[AT_NODES] = np.tile(out[:, COMPILED["stress"]], (1, 4))
    if set(names) & set(FIBRE_FIELDS):
        res.update(_fibre_stretches(deformation_gradients(k.cells[lo:hi], k.Dminv[lo:hi], x), k.material,
                                    _constants(k, lo, hi), names))
    return res


def _constants(k, lo, hi, nq=1):
    """The constants of kernels k's cells lo..hi-1, as a tuple or (where they vary per cell: a fibre field) a row per
    cell, each repeated for its nq points."""
    c = k.constants
    return np.repeat(c[lo:hi], nq, axis=0) if isinstance(c, np.ndarray) else c


def _fibre_stretches(F, material, c, names):
    """{fibreI_stretch: |F a_I|} of `names` for deformation gradients F (n, 3, 3) of a material with constants c (a
    tuple, or a row per F) (NaN where it has no family I: Material.fibres)."""
    dirs = material.fibres(c)
    out = {}
    for i, name in enumerate(FIBRE_FIELDS):
        if name in names:
            if i >= len(dirs):
                out[name] = np.full(len(F), np.nan)
            else:                               # (a direction per row where it is a field)
                a = dirs[i]
                out[name] = np.linalg.norm(F @ a if a.ndim == 1 else np.einsum("nij,nj->ni", F, a), axis=-1)
    return out


def extrapolation(element):
    """(nn, nq): a cell's values at its nodes from its values at the stiffness rule's points, through the linear
    field of the reference coordinates that fits them (by least squares where the rule has more than 4 points)."""
    pts, _ = element.rule()
    nodes = REFERENCE_NODES[:element.nodes]
    fit = np.linalg.pinv(np.column_stack([np.ones(len(pts)), pts]))      # (4, nq)
    return np.column_stack([np.ones(len(nodes)), nodes]) @ fit


def _cell_fields(cells, Dminv, kernels, x, names=CELL_FIELDS):
    """The fields of P1 cells by the materials' numpy reference (what _compiled_fields is checked against)."""
    return _point_fields(deformation_gradients(cells, Dminv, x), kernels, names, kernels.constants)


def _point_fields(F, kernels, names, c):
    """{name: value} of `names` (CELL_FIELDS, TENSOR_FIELDS) of deformation gradients F (n, 3, 3) of a
    material's kernels, with its constants c (a tuple, or a row per F)."""
    mat = kernels.material
    with np.errstate(all="ignore"):
        J = np.linalg.det(F)
        psi = _per_cell(mat.psi, F, c)
        P = _per_cell(mat.P, F, c)
        sigma = P @ np.swapaxes(F, -1, -2) / J[:, None, None]
        s = sigma - np.trace(sigma, axis1=-2, axis2=-1)[:, None, None] / 3.0 * np.eye(3)
        vm = np.sqrt(1.5 * np.einsum("cij,cij->c", s, s))
    psi = np.where(np.isfinite(psi), psi, np.nan)
    vm = np.where(np.isfinite(vm), vm, np.nan)
    out = {"J": J, "energy_density": psi, "von_mises": vm, **_fibre_stretches(F, mat, c, names)}
    if "stress" in names:
        out["stress"] = _tensor6(np.where(np.isfinite(sigma), sigma, np.nan))
    if "strain" in names:
        out["strain"] = _tensor6(0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(3)))
    return {n: out[n] for n in names}


def _tensor6(T):
    return np.stack([T[:, i, j] for i, j in TENSOR6], axis=1)
