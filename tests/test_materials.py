"""Derivatives of every material against finite differences, and the compiled kernels against
the numpy reference path."""
import zlib

import numpy as np
import pytest

from hyperelastic.physics.materials import MATERIALS, default_solid, get, lame

rng = np.random.default_rng(1234)


@pytest.fixture(autouse=True)
def _own_draws(request):
    """Each test draws from its own generator, seeded by its name: the same states whatever ran before it in this
    process (under `pytest -n 2 --dist load` the tests of this file were split between workers in varying orders, and
    some orders drew near-degenerate cells that failed the 1e-12 comparisons)."""
    global rng
    rng = np.random.default_rng(zlib.crc32(request.node.name.encode()))
MU, LAM = lame(1e6, 0.3)[1], lame(1e6, 0.3)[0]
# each material's constants at E = 1e6, nu = 0.3 (Mooney-Rivlin with both invariants' moduli in use)
C = {n: default_solid(n).constants for n in MATERIALS}
C["mooney_rivlin"] = (MU / 4, MU / 4, C["mooney_rivlin"][2])
# Yeoh with a filled rubber's proportions (C20 ~ -C10/10, C30 ~ C10/50): its W'' term in use
C["yeoh"] = (MU / 2, -MU / 20, MU / 100, C["yeoh"][3])
# Gent and Arruda-Boyce near their locking (Jm = 10: I1_bar - 3 < 10; lambda_m = 2.5: I1_bar < 18.75), their W'' large
C["gent"] = default_solid("gent").material.constants({"mu": MU, "Jm": 10.0, "kappa": C["gent"][2]})
C["arruda_boyce"] = default_solid("arruda_boyce").material.constants({"mu": MU, "lambda_m": 2.5,
                                                                     "kappa": C["arruda_boyce"][3]})
# Ogden with the proportions of Ogden's 1972 fit of Treloar's rubber (three terms, a negative exponent) and two small
# terms more (five: its most), mu ~ MU
_r = MU / 0.4225e6
C["ogden"] = (0.63e6 * _r, 1.3, 0.0012e6 * _r, 5.0, -0.01e6 * _r, -2.0, 0.005e6 * _r, 3.0, -0.002e6 * _r, -1.0,
              C["ogden"][10])      # (all five terms)


# the compiled kernels against the numpy reference, relative to the largest value: round-off; Ogden's goes through the
# eigenvalues of C, each to round-off of |C| in LAPACK's (the reference) and in the kernel's closed-form solver alike, so
# the two differ by ~1e-16 cond(C) in the smallest, amplified by its c^-2 term: 1.9e-12 of the cell's largest force at
# cond(F) = 534, 8e-16 at the median of the random cells these tests draw (measured 2026-11-29)
AGREE = {"ogden": 1e-11, "hgo": 1e-11}   # (hgo: exp(k2 E^2) multiplies the round-off of E by k2 E^2, ~500 on the wildest cell)
# HGO with two dispersed families (k1 = 4 mu, k2 = 0.1: their exponential stiffening in use, within range on the random
# cells, whose stretches reach 10)
C["hgo"] = default_solid("hgo").material.constants({"mu": MU, "k1": 4 * MU, "k2": 0.1, "dispersion": 0.1,
                                                    "fibre1": (1.0, 1.0, 0.0), "fibre2": (1.0, -1.0, 0.3),
                                                    "kappa": default_solid("hgo").values["kappa"]})


def random_F(n, amp):
    F = np.eye(3) + amp * rng.standard_normal((n, 3, 3))
    return F[np.linalg.det(F) > 0.2]


@pytest.mark.parametrize("name", sorted(MATERIALS))
@pytest.mark.parametrize("amp", [0.05, 0.3])
def test_P_is_derivative_of_psi(name, amp):
    m = MATERIALS[name]
    F = random_F(20, amp)
    P = m.P(F, C[name])
    eps = 1e-6
    Pfd = np.zeros_like(F)
    for i in range(3):
        for j in range(3):
            d = np.zeros((3, 3))
            d[i, j] = eps
            Pfd[:, i, j] = (m.psi(F + d, C[name]) - m.psi(F - d, C[name])) / (2 * eps)
    assert np.abs(P - Pfd).max() <= 1e-6 * np.abs(P).max() + 1e-3


@pytest.mark.parametrize("name", sorted(MATERIALS))
@pytest.mark.parametrize("amp", [0.05, 0.3])
def test_dP_is_derivative_of_P(name, amp):
    m = MATERIALS[name]
    F = random_F(20, amp)
    dF = rng.standard_normal(F.shape)
    eps = 1e-6
    fd = (m.P(F + eps * dF, C[name]) - m.P(F - eps * dF, C[name])) / (2 * eps)
    dP = m.dP(F, dF, C[name])
    assert np.abs(dP - fd).max() <= 1e-7 * np.abs(dP).max()


def defined(name, D, *xs):
    """Per cell: the material is defined (its energy finite) at every one of the cells' positions xs."""
    ok = np.ones(len(D), bool)
    for x in xs:
        xs_ = x.reshape(-1, 4, 3)
        F = np.swapaxes(xs_[:, 1:] - xs_[:, :1], 1, 2) @ np.linalg.inv(D)
        with np.errstate(invalid="ignore", divide="ignore"):
            ok &= (np.linalg.det(F) > 0) & np.isfinite(MATERIALS[name].psi(F, C[name]))
    return ok


def tet_problem(n=50, amp=0.2):
    """n independent random tetrahedra with random current positions."""
    X = rng.standard_normal((n, 4, 3))
    D = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=-1)
    keep = np.linalg.det(D) > 0.1
    X, D = X[keep], D[keep]
    cells = np.arange(4 * len(X), dtype=np.int32).reshape(-1, 4)
    x = (X + amp * rng.standard_normal(X.shape)).reshape(-1)
    return X, D, cells, x


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_kernels_match_reference(name):
    from hyperelastic.discretization.kernels import CellKernels
    m = MATERIALS[name]
    X, D, cells, x = tet_problem()
    Dminv = np.linalg.inv(D)
    vol = np.linalg.det(D) / 6
    xs = x.reshape(-1, 4, 3)
    Ds = np.stack([xs[:, 1] - xs[:, 0], xs[:, 2] - xs[:, 0], xs[:, 3] - xs[:, 0]], axis=-1)
    F = Ds @ Dminv
    with np.errstate(invalid="ignore"):
        ok = (np.linalg.det(F) > 0.05) & np.isfinite(m.psi(F, C[name]))   # (a locking model's cells beyond its limit)
    X, D, Dminv, vol, F, xs = X[ok], D[ok], Dminv[ok], vol[ok], F[ok], xs[ok]
    cells = np.arange(4 * len(X), dtype=np.int32).reshape(-1, 4)
    x = xs.reshape(-1).copy()
    k = CellKernels(cells, Dminv, vol, m, C[name])
    # forces: k_a = V P grad N_a (thesis 4.41), grad N_a rows of Dminv, grad N_0 = -sum
    G = np.concatenate([-Dminv.sum(axis=1, keepdims=True), Dminv], axis=1)        # (n,4,3)
    P = m.P(F, C[name])
    ref = np.einsum("n,nij,naj->nai", vol, P, G).reshape(-1)
    f = np.zeros_like(x)
    assert k.forces(x, f) == 0
    assert np.abs(f - ref).max() <= AGREE.get(name, 1e-12) * np.abs(ref).max()
    # energy
    W, jmin, jmax, bad = k.energy(x)
    assert np.isclose(W, (vol * m.psi(F, C[name])).sum(), rtol=AGREE.get(name, 1e-12))
    assert np.isclose(jmin, np.linalg.det(F).min()) and np.isclose(jmax, np.linalg.det(F).max())
    # K v against the numpy dP and against finite differences of the forces
    v = rng.standard_normal(x.shape)
    dF = np.stack([(v.reshape(-1, 4, 3)[:, a] - v.reshape(-1, 4, 3)[:, 0]) for a in (1, 2, 3)], axis=-1) @ Dminv
    ref_kv = np.einsum("n,nij,naj->nai", vol, m.dP(F, dF, C[name]), G).reshape(-1)
    y = np.zeros_like(x)
    k.kv(x, v, y)
    assert np.abs(y - ref_kv).max() <= AGREE.get(name, 1e-12) * np.abs(ref_kv).max()
    eps = 1e-6
    fp, fm = np.zeros_like(x), np.zeros_like(x)
    k.forces(x + eps * v, fp)
    k.forces(x - eps * v, fm)
    assert np.abs(y - (fp - fm) / (2 * eps)).max() <= 1e-6 * np.abs(y).max()
    # 12x12 tangents reproduce K v, are symmetric (hyperelastic), and their diagonal matches
    K, bad = k.tangent(x)
    assert bad == 0
    yk = np.einsum("nrc,nc->nr", K, v.reshape(-1, 12)).reshape(-1)
    assert np.abs(yk - y).max() <= 1e-12 * np.abs(y).max()
    assert np.abs(K - K.transpose(0, 2, 1)).max() <= 1e-12 * np.abs(K).max()
    d = np.zeros_like(x)
    k.tangent_diag(x, d)
    assert np.allclose(d, np.einsum("nii->ni", K).reshape(-1), rtol=1e-13, atol=0)


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_discrete_gradient_force(name):
    """The energy-momentum force (kernels.forces_discrete_gradient) of a step xn -> x1 evaluated at the
    midpoint: its work over the step is exactly the change of the elastic energy (the midpoint force's is
    not), it is the ordinary force when the step is zero, and (objective materials) it has no net torque
    about the midpoint configuration's origin."""
    from hyperelastic.discretization.kernels import CellKernels
    X, D, cells, xn = tet_problem(amp=0.3)        # some cells inverted
    k = CellKernels(cells, np.linalg.inv(D), np.linalg.det(D) / 6, get(name), C[name])
    f0, fx = np.zeros_like(xn), np.zeros_like(xn)
    assert k.forces_discrete_gradient(xn, xn, f0) == k.forces(xn, fx)
    # (through C_bar's Cholesky factor: round-off of the stress there; Yeoh's polynomial in I1 reaches 1e11-1e12 on
    # the near-degenerate random cells, 3e-12 of which is the round-off of its largest)
    assert np.abs(f0 - fx).max() <= (1e-11 if name == "yeoh" else 1e-12) * np.abs(fx).max()
    X, D, cells, xn = tet_problem(amp=0.1)
    x1 = xn + 0.1 * rng.standard_normal(xn.shape)
    Dn, D1 = (np.swapaxes((y.reshape(-1, 4, 3)[:, 1:] - y.reshape(-1, 4, 3)[:, :1]), 1, 2) for y in (xn, x1))
    ok = (np.linalg.det(Dn) > 0) & (np.linalg.det(D1) > 0)    # the step keeps every cell's orientation
    ok &= defined(name, D, xn, x1, 0.5 * (xn + x1))            # (and a locking model's cells within their limit)
    cells = np.arange(4 * ok.sum(), dtype=np.int32).reshape(-1, 4)
    xn, x1 = (y.reshape(-1, 4, 3)[ok].reshape(-1) for y in (xn, x1))
    k = CellKernels(cells, np.linalg.inv(D[ok]), np.linalg.det(D[ok]) / 6, get(name), C[name])
    xm = 0.5 * (xn + x1)
    f, fm = np.zeros_like(xn), np.zeros_like(xn)
    assert k.forces_discrete_gradient(xm, xn, f) == 0
    k.forces(xm, fm)
    dW = k.energy(x1)[0] - k.energy(xn)[0]
    assert abs(f @ (x1 - xn) - dW) <= 1e-12 * abs(dW)
    if not MATERIALS[name].quadratic:      # quadratic energy: the midpoint force is the discrete gradient
        assert abs(fm @ (x1 - xn) - dW) > 1e-4 * abs(dW)
        torque = np.cross(xm.reshape(-1, 3), f.reshape(-1, 3)).sum(axis=0)
        assert np.abs(torque).max() <= 1e-10 * np.abs(f).max() * np.abs(xm).max()


def test_consistent_mass_kernel():
    from hyperelastic.discretization.kernels import Cells
    X, D, cells, x = tet_problem(10)
    vol = np.linalg.det(D) / 6
    k = Cells(cells, np.linalg.inv(D), vol)                  # the mass kernels need only the geometry
    v = rng.standard_normal(x.shape)
    y = np.zeros_like(v)
    k.mass_apply(2.0, v, y)
    Me = (np.ones((4, 4)) + np.eye(4)) / 20
    ref = 2.0 * np.einsum("n,ab,nbi->nai", vol, Me, v.reshape(-1, 4, 3)).reshape(-1)
    assert np.allclose(y, ref, rtol=1e-14, atol=1e-14)
    # total mass: 1^T M 1 = coef * volume
    ones = np.zeros_like(v)
    ones[0::3] = 1
    y[:] = 0
    k.mass_apply(1.0, ones, y)
    assert np.isclose(y[0::3].sum(), vol.sum())


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_kernels_cell_independent_of_block(name):
    """Neo-Hookean's force, energy and K v loops go by blocks of 32 cells, taking the block's 1/J and ln J at
    once (glibc's vector log where there is one: _kernels.c, he_jscalars); the others go cell by cell.
    Either way a cell's force (and K v) does not depend on where it sits in a block: all cells at once
    equal two parts split anywhere, bitwise, with the same count of undefined (inverted) cells, and an inverted
    cell in a block leaves the others' forces and energies as the numpy reference has them."""
    from hyperelastic.discretization.kernels import CellKernels
    m = MATERIALS[name]
    X, D, cells, x = tet_problem(300, amp=0.35)             # 2-3 hundred cells, some inverted
    n = len(D) - (len(D) % 32 == 0)                         # and a partial last block
    D, cells, x = D[:n], cells[:n], x[:12 * n]
    Dminv, vol = np.linalg.inv(D), np.linalg.det(D) / 6
    k = CellKernels(cells, Dminv, vol, m, C[name])
    f_all = np.zeros_like(x)
    bad_all = k.forces(x, f_all)
    w = rng.standard_normal(x.shape)
    y_all = np.zeros_like(x)
    assert k.kv(x, w, y_all) == bad_all
    for lo in (1, 13, 37, 64):
        f, y = np.zeros_like(x), np.zeros_like(x)
        bad = k.part(0, lo).forces(x, f) + k.part(lo, k.nc).forces(x, f)
        assert bad == bad_all and np.array_equal(f, f_all)
        assert k.part(0, lo).kv(x, w, y) + k.part(lo, k.nc).kv(x, w, y) == bad_all and np.array_equal(y, y_all)
    xs = x.reshape(-1, 4, 3)
    F = np.stack([xs[:, 1] - xs[:, 0], xs[:, 2] - xs[:, 0], xs[:, 3] - xs[:, 0]], axis=-1) @ Dminv
    J = np.linalg.det(F)
    ok = defined(name, D, x) if not m.defined_when_inverted else np.ones(len(J), bool)   # (J > 0, within a lock)
    if not m.defined_when_inverted:
        assert bad_all == (~ok).sum() > 0
    G = np.concatenate([-Dminv.sum(axis=1, keepdims=True), Dminv], axis=1)
    ref = np.einsum("n,nij,naj->nai", vol[ok], m.P(F[ok], C[name]), G[ok])
    got = f_all.reshape(-1, 4, 3)[ok]
    assert np.abs(got - ref).max() <= AGREE.get(name, 1e-12) * np.abs(ref).max()
    assert np.abs(f_all.reshape(-1, 4, 3)[~ok]).max(initial=0.0) == 0.0
    W, jmin, jmax, bad = k.energy(x)
    assert bad == bad_all and np.isclose(W, (vol[ok] * m.psi(F[ok], C[name])).sum(), rtol=AGREE.get(name, 1e-12))
    assert np.allclose([jmin, jmax], [J.min(), J.max()], rtol=1e-13)


def test_neohookean_undefined_when_inverted():
    from hyperelastic.discretization.kernels import CellKernels
    X, D, cells, x = tet_problem(5, amp=0.0)
    xs = x.reshape(-1, 4, 3).copy()
    xs[0, 0], xs[0, 1] = xs[0, 1].copy(), xs[0, 0].copy()    # swap two vertices: J < 0
    k = CellKernels(cells, np.linalg.inv(D), np.linalg.det(D) / 6, get("neohookean"), C["neohookean"])
    f = np.zeros(xs.size)
    assert k.forces(xs.reshape(-1), f) == 1
    assert np.isfinite(f).all()


def test_registry_one_home_per_material():
    """Each registered material has its numpy reference (materials/NAME.py, MATERIAL.name == NAME)
    and its C kernel (materials/NAME.h, compiled into he_*_NAME); every material header is registered."""
    import glob
    import os
    from hyperelastic.physics import materials
    from hyperelastic.discretization.kernels import material_kernels
    here = os.path.dirname(materials.__file__)
    headers = {os.path.basename(p)[:-2] for p in glob.glob(os.path.join(here, "*.h"))
               if not os.path.basename(p).startswith("_")}
    assert headers == set(materials.REGISTRY)
    for name in materials.REGISTRY:
        assert MATERIALS[name].name == name
        assert set(material_kernels(name)) == {"forces", "energy", "kv", "tangent", "tangent_diag", "forces_dg",
                                               "fields", "pk2"}
    with pytest.raises(ImportError, match="no compiled kernels for material 'nosuch'"):
        material_kernels("nosuch")


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_compiled_output_fields_match_the_numpy_reference(name):
    """The output's P1 cell fields from the material's compiled loop (he_fields_NAME: J, energy density, von Mises,
    Cauchy stress, Green-Lagrange strain) equal the numpy reference's (output/fields.py) to rounding (1e-11 of the
    largest; the cells are strained far, some inverted), NaN in the
    same cells (some cells inverted: where the material is undefined)."""
    from hyperelastic.discretization.kernels import CellKernels
    from hyperelastic.output.fields import CELL_FIELDS, TENSOR_FIELDS, _cell_fields, _compiled_fields
    X, D, cells, x = tet_problem(amp=0.3)
    k = CellKernels(cells, np.linalg.inv(D), np.linalg.det(D) / 6, get(name), C[name])
    names = CELL_FIELDS + TENSOR_FIELDS
    ref, got = _cell_fields(k.cells, k.Dminv, k, x, names), _compiled_fields(k, x, 0, k.nc, names)
    assert (np.linalg.det(D) > 0).all() and (np.linalg.det(
        np.swapaxes(x.reshape(-1, 4, 3)[:, 1:] - x.reshape(-1, 4, 3)[:, :1], 1, 2)) < 0).any()   # some inverted
    for n in names:
        a, b = np.asarray(ref[n]), got[n]
        assert np.array_equal(np.isnan(a), np.isnan(b)), n
        ok = ~np.isnan(a)
        assert np.abs(a[ok] - b[ok]).max() <= 1e-11 * max(1.0, np.abs(a[ok]).max()), n     # (rounding: 1e-12 seen)


@pytest.mark.parametrize("stretch", [0.6, 1.5, 3.0, 6.0])
def test_yeoh_in_uniaxial_tension_is_its_closed_form(stretch):
    """Incompressible uniaxial tension of Yeoh's model (Yeoh 1993; Ogden, Non-linear Elastic Deformations, 1984,
    eq. 7.2.7 with W(I1)): the nominal stress 2 (l - l^-2) W'(I1), I1 = l^2 + 2/l, W' = C10 + 2 C20 (I1 - 3) + 3 C30
    (I1 - 3)^2. At F = diag(l, l^-1/2, l^-1/2) (J = 1: the volumetric part's stress is 0) the Cauchy stress's axial
    minus lateral component, over l (the hydrostatic pressure the constraint would add cancels), is it to 1e-12;
    with C20 = C30 = 0 the model is the neo-Hookean split's, bitwise in stress."""
    m = MATERIALS["yeoh"]
    c = C["yeoh"]
    F = np.diag([stretch, stretch ** -0.5, stretch ** -0.5])[None]
    sigma = m.P(F, c)[0] @ F[0].T                    # J = 1
    I1 = stretch ** 2 + 2 / stretch
    w1 = c[0] + 2 * c[1] * (I1 - 3) + 3 * c[2] * (I1 - 3) ** 2
    want = 2 * (stretch - stretch ** -2) * w1
    got = (sigma[0, 0] - sigma[1, 1]) / stretch
    assert abs(got - want) <= 1e-12 * abs(want) + 1e-9, (got, want)
    F = random_F(20, 0.3)
    nh = MATERIALS["neohookean_split"]
    mu, kappa = C["neohookean_split"]
    assert np.allclose(m.P(F, (mu / 2, 0.0, 0.0, kappa)), nh.P(F, (mu, kappa)), rtol=1e-14, atol=0)
