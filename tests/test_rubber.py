"""Issue 71: the rubbers of one invariant (Yeoh, Gent, Arruda-Boyce) and Ogden's against their closed forms, through the
kernels and through the whole application; the inverse Langevin function Arruda-Boyce's model needs, and Ogden's
derivative where stretches are equal."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from conftest import ROOT, hyperelastic, read_h5, run_ok
from hyperelastic.physics.materials import default_solid
from hyperelastic.physics.materials.arruda_boyce import inverse_langevin, langevin

MU = 0.4e6
# each model's constants, from the options a user gives, and W'(I1_bar) written out here from the papers' formulas
MODELS = {
    "yeoh": ({"C10": MU / 2, "C20": -MU / 20, "C30": MU / 100},
             lambda I1, o: o["C10"] + 2 * o["C20"] * (I1 - 3) + 3 * o["C30"] * (I1 - 3) ** 2),
    "gent": ({"mu": MU, "Jm": 12.0}, lambda I1, o: o["mu"] / 2 / (1 - (I1 - 3) / o["Jm"])),
    # Arruda & Boyce 1993: the nominal uniaxial stress mu_n/3 lambda_m/lambda_c L^-1(lambda_c/lambda_m) (l - l^-2),
    # i.e. W' = mu_n lambda_m beta / (6 lambda_c); mu_n from the small-strain modulus mu = mu_n lambda_m L^-1(1/lm)/3
    "arruda_boyce": ({"mu": MU, "lambda_m": 3.0},
                     lambda I1, o: (3 * o["mu"] / (o["lambda_m"] * _inv_langevin(1 / o["lambda_m"])))
                     * o["lambda_m"] * _inv_langevin(math.sqrt(I1 / 3) / o["lambda_m"]) / (6 * math.sqrt(I1 / 3))),
}


def _bernoulli_series(terms=60):
    """coth b - 1/b = sum_n 2^(2n) B_2n / (2n)! b^(2n-1), converging for |b| < pi: its coefficients from Bernoulli's
    numbers, computed here exactly (B_m = -1/(m+1) sum_k<m C(m+1, k) B_k)."""
    from fractions import Fraction
    B = [Fraction(1)]
    for m in range(1, 2 * terms + 1):
        B.append(-sum(math.comb(m + 1, k) * B[k] for k in range(m)) / (m + 1))
    return [float(Fraction(4) ** n * B[2 * n] / math.factorial(2 * n)) for n in range(1, terms + 1)]


SERIES = _bernoulli_series()


def _langevin(b):
    """L(b) without cancellation: the 60-term series below b = 2 (error < (2/pi)^120), coth b - 1/b above."""
    if b < 2:
        return math.fsum(c * b ** (2 * n + 1) for n, c in enumerate(SERIES))
    return 1 / math.tanh(b) - 1 / b


# Ogden's 1972 fit of Treloar's rubber (mu_p in Pa, alpha_p): Psi = sum mu_p/alpha_p (l1^a + l2^a + l3^a - 3)
OGDEN = {"mu1": 0.63e6, "alpha1": 1.3, "mu2": 0.0012e6, "alpha2": 5.0, "mu3": -0.01e6, "alpha3": -2.0}


# HGO with one family along x (a = e_1), or across the pull (along y): Gasser, Ogden & Holzapfel 2006
HGO = {"mu": MU, "k1": 2 * MU, "k2": 2.0, "dispersion": 0.1}
FIBRE = {"hgo": 0, "hgo_across": 1}


def tau_bar(name, lb, o):
    """The principal Kirchhoff stresses of the isochoric energy at the isochoric stretches lb: 2 W'(I1_bar) lb^2 for
    the one-invariant models, sum_p mu_p lb^alpha_p for Ogden's; HGO's with its family along axis k: mu lb_i^2 +
    2 f'(E) lb_i^2 (d + (1 - 3d) delta_ik), E = d (I1_bar - 3) + (1 - 3d)(lb_k^2 - 1), f' = k1 <E> exp(k2 <E>^2)."""
    lb = np.asarray(lb, dtype=float)
    if name == "ogden":
        return sum(o[f"mu{p}"] * lb ** o[f"alpha{p}"] for p in (1, 2, 3))
    if name in FIBRE:
        k, d = FIBRE[name], o["dispersion"]
        E = max(d * ((lb ** 2).sum() - 3) + (1 - 3 * d) * (lb[k] ** 2 - 1), 0.0)
        f1 = o["k1"] * E * math.exp(o["k2"] * E * E)
        return o["mu"] * lb ** 2 + 2 * f1 * lb ** 2 * (d + (1 - 3 * d) * (np.arange(3) == k))
    return 2 * MODELS[name][1](float((lb ** 2).sum()), o) * lb ** 2


def _inv_langevin(r):
    """L^-1(r) by bisection (an independent evaluation: no Newton, no approximation to start from)."""
    return brentq(lambda b: _langevin(b) - r, 1e-9, 1e10, xtol=1e-300, rtol=1e-15, maxiter=500)


def _options(name):
    """A model's constants as the tests give them."""
    if name in FIBRE:
        return {**HGO, "fibre1": tuple(float(i == FIBRE[name]) for i in range(3))}
    return OGDEN if name == "ogden" else MODELS[name][0]


def _solid(name, E=1.2e6, nu=0.3):
    s = default_solid("hgo" if name in FIBRE else name, E=E, nu=nu)
    s.values.update(_options(name))
    return s


def test_inverse_langevin_to_round_off():
    """L^-1 (Newton from Cohen's Pade approximation) against bisection, from r = 1e-6 (the series' range) to r =
    1 - 1e-9 (beta = 1e9): within round-off and r's own, L(beta) = r to 5e-15 relative; and L, L' continuous where
    the series hands over to the closed forms (b = 0.3)."""
    r = np.concatenate([np.geomspace(1e-6, 0.5, 40), 1 - np.geomspace(0.5, 1e-9, 40)])
    got = inverse_langevin(r)
    want = np.array([_inv_langevin(v) for v in r])
    # (r itself is known to 1e-16: beta's relative condition number near r = 1 is ~beta)
    assert (np.abs(got / want - 1) <= 5e-14 + 4e-16 * want).all()
    assert max(abs(_langevin(b) - v) / v for b, v in zip(got, r)) <= 5e-15     # (coth b - 1/b: a digit lost at b < 2)
    assert np.isnan(inverse_langevin(np.array([0.0, 1.0, 1.5]))).all()
    lo, hi = langevin(np.array([0.3 * (1 - 1e-15)])), langevin(np.array([0.3 * (1 + 1e-15)]))
    for a, b in zip(lo, hi):
        assert abs(a[0] - b[0]) <= 1e-14 * abs(a[0])


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("stretch", [0.6, 1.3, 2.2])
def test_incompressible_closed_forms_at_J_one(name, stretch):
    """At J = 1 (the volumetric part's stress 0) the kernels' reference stress is the incompressible closed forms
    (Ogden, Non-linear Elastic Deformations, 1984, sec. 7.2): uniaxial (sigma_11 - sigma_22)/l = 2 (l - l^-2) W',
    equibiaxial (sigma_11 - sigma_33)/l = 2 (l - l^-5) W', planar (pure shear) 2 (l - l^-3) W', simple shear
    sigma_12 = 2 gamma W' with I1 = 3 + gamma^2 (gamma = stretch - 1), to 1e-12."""
    s = _solid(name)
    m, c, w1 = s.material, s.constants, MODELS[name][1]
    lam = stretch
    cases = [(np.diag([lam, lam ** -0.5, lam ** -0.5]), (0, 0), (1, 1), lam ** 2 + 2 / lam, 2 * (lam - lam ** -2)),
             (np.diag([lam, lam, lam ** -2]), (0, 0), (2, 2), 2 * lam ** 2 + lam ** -4, 2 * (lam - lam ** -5)),
             (np.diag([lam, 1.0, 1 / lam]), (0, 0), (2, 2), lam ** 2 + 1 + lam ** -2, 2 * (lam - lam ** -3))]
    for F, i, j, I1, k in cases:
        sigma = m.P(F[None], c)[0] @ F.T
        want = k * w1(I1, s.values)
        assert abs((sigma[i] - sigma[j]) / lam - want) <= 1e-12 * abs(want)
    g = lam - 1
    F = np.eye(3)
    F[0, 1] = g
    sigma = m.P(F[None], c)[0] @ F.T
    want = 2 * g * w1(3 + g * g, s.values)
    assert abs(sigma[0, 1] - want) <= 1e-12 * abs(want)


def _homogeneous(name, mode, lam, E, nu):
    """The model's nominal stress P_11 of a compressible homogeneous test: F = diag(lam, l2, l3), the free lateral
    stretches found by bisection on their nominal stress 0. Split material: sigma_i = (tau_i - mean tau) / J + U'(J),
    tau the isochoric energy's principal Kirchhoff stresses at lb = J^(-1/3) l, U'(J) = kappa/2 (J - 1/J),
    P_ii = J sigma_ii / l_i."""
    s = _solid(name, E, nu)
    o, kappa = s.values, s.values["kappa"]

    def P(l):
        J = l[0] * l[1] * l[2]
        t = tau_bar(name, J ** (-1 / 3) * np.asarray(l), o)
        return ((t - t.mean()) + 0.5 * kappa * (J * J - 1)) / np.asarray(l)

    if mode == "uniaxial":
        t = brentq(lambda t: P([lam, t, t])[1], 0.3, 1.2, xtol=1e-15)
        l = [lam, t, t]
    elif mode == "equibiaxial":
        t = brentq(lambda t: P([lam, lam, t])[2], 0.3, 1.2, xtol=1e-15)
        l = [lam, lam, t]
    else:
        t = brentq(lambda t: P([lam, 1.0, t])[2], 0.3, 1.2, xtol=1e-15)
        l = [lam, 1.0, t]
    return P(l)[0], l


@pytest.mark.parametrize("name", sorted(MODELS) + ["ogden", "hgo", "hgo_across"])
def test_homogeneous_tests_through_the_application(name, tmp_path):
    """Issue 71's closed forms through the whole application: a unit cube (symmetry planes xmin, ymin, zmin) stretched
    to lambda = 1.8 uniaxially (the other faces free), 1.4 equibiaxially (xmax and ymax moved, zmax free) and 1.8 in
    planar tension (ymax held: pure shear), at nu = 0.45 (kappa/mu = 9.7: the lateral stretches far from
    incompressible): the reaction on xmax per reference area is the model's P_11 (formula above) within 1e-8, and the
    free faces' stretches are the formula's. HGO with its fibres along the pull and across it (Gasser, Ogden & Holzapfel
    2006: across, its fibres shorten and bear nothing) and the output's fibre stretch."""
    msh = tmp_path / "cube.msh"
    run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.5, "-o", msh])
    opts = [a for k, v in _options(name).items()
            for a in (f"-{k}", ",".join(map(repr, v)) if isinstance(v, tuple) else repr(v))]
    E, nu = 1.2e6, 0.45
    for mode, lam, moved, held in (("uniaxial", 1.8, "xmax:x", ""), ("equibiaxial", 1.4, "xmax:x,ymax:y", ""),
                                   ("planar", 1.8, "xmax:x", ",ymax:y")):
        out = tmp_path / f"{mode}.h5"
        run_ok(["run", "bend", "-mesh", msh, "-material", _solid(name).name, *opts, "-E", E, "-nu", nu,
                "-effects", "elasticity,fixed,prescribed", "-fix", "xmin:x,ymin:y,zmin:z" + held,
                "-prescribe_faces", moved, "-prescribe_x", f"X*(1+{lam - 1!r}*t)",
                *(["-prescribe_y", f"Y*(1+{lam - 1!r}*t)"] if "ymax:y" in moved else []),
                "-quasistatic", "-final_time", 1, "-dt", 0.5, "-snes_rtol", 1e-13, "-snes_atol", 1e-9,
                *(["-output_fields", "default,fibre1_stretch,fibre2_stretch"] if name in FIBRE else []),
                "-output", out, "-quiet"])
        h = read_h5(out, frames=name in FIBRE)
        want, l = _homogeneous(name, mode, lam, E, nu)
        got = h["stats"]["reaction_xmax_Fx"][-1]
        assert abs(got - want) <= 1e-8 * abs(want), (mode, got, want)
        x, X = h["x"][-1].reshape(-1, 3), h["points"]
        assert np.abs(x - X * l).max() <= 1e-9, mode
        if name in FIBRE:                 # the output's fibre stretch |F a| (one family: the second's NaN)
            last = h["frames"][-1]
            assert np.abs(last["fibre1_stretch"] - l[FIBRE[name]]).max() <= 1e-9
            assert np.isnan(last["fibre2_stretch"]).all()


@pytest.mark.parametrize("stretch", [0.6, 1.3, 2.2, 4.0])
def test_ogden_closed_forms_at_J_one(stretch):
    """Ogden's model at J = 1 against the incompressible closed forms in principal stretches (Ogden, Non-linear Elastic
    Deformations, 1984, sec. 7.2; Ogden 1972's Treloar constants): sigma_i - sigma_j = sum_p mu_p (l_i^a_p - l_j^a_p)
    in uniaxial, equibiaxial and planar tension, and in simple shear of amount g (principal stretches l, 1/l with
    l - 1/l = g) sigma_12 = (tau_1 - tau_2) / (l + 1/l), to 1e-12; with one term (alpha 2) it is neohookean_split."""
    s = _solid("ogden")
    m, c = s.material, s.constants
    lam = stretch
    for ls, (i, j) in (([lam, lam ** -0.5, lam ** -0.5], (0, 1)), ([lam, lam, lam ** -2], (0, 2)),
                       ([lam, 1.0, 1 / lam], (0, 2))):
        F = np.diag(ls)
        sigma = m.P(F[None], c)[0] @ F.T
        t = tau_bar("ogden", ls, OGDEN)
        assert abs((sigma[i, i] - sigma[j, j]) - (t[i] - t[j])) <= 1e-12 * abs(t[i] - t[j])
    g = lam - 1
    F = np.eye(3)
    F[0, 1] = g
    sigma = m.P(F[None], c)[0] @ F.T
    lp = g / 2 + math.sqrt(1 + g * g / 4)
    t = tau_bar("ogden", [lp, 1 / lp, 1.0], OGDEN)
    want = (t[0] - t[1]) / (lp + 1 / lp)
    assert abs(sigma[0, 1] - want) <= 1e-12 * abs(want)
    nh = default_solid("neohookean_split")
    one = default_solid("ogden")                       # (mu1 = mu, alpha1 = 2, the other terms off)
    F = np.eye(3) + 0.3 * np.random.default_rng(3).standard_normal((20, 3, 3))
    F = F[np.linalg.det(F) > 0.2]
    assert np.allclose(one.material.P(F, one.constants), nh.material.P(F, nh.constants), rtol=1e-13, atol=1e-4)


def test_ogden_tangent_exact_where_stretches_are_equal():
    """Where two or three principal stretches are equal (the reference, a rotated uniaxial state diag(2, 0.7, 0.7), an
    equal dilatation, and a pair that differs by 1e-9) the principal directions are not defined, yet the compiled
    kernel's K v is finite and equals central differences of its forces (to 1e-7: their truncation), and the 12x12
    tangent is symmetric."""
    from hyperelastic.discretization.kernels import CellKernels
    s = _solid("ogden")
    rng = np.random.default_rng(7)
    R = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    states = [np.eye(3), R @ np.diag([2.0, 0.7, 0.7]) @ R.T, 1.3 * np.eye(3), R @ np.diag([1.2, 0.9, 0.9 + 1e-9]) @ R]
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    D = np.stack([X[1] - X[0], X[2] - X[0], X[3] - X[0]], axis=-1)
    for F in states:
        x = (X @ F.T).reshape(-1).copy()
        k = CellKernels(np.arange(4, dtype=np.int32)[None], np.linalg.inv(D)[None], np.array([1 / 6]), s.material,
                        s.constants)
        v = rng.standard_normal(12)
        y = np.zeros(12)
        k.kv(x, v, y)
        eps = 1e-6
        fp, fm = np.zeros(12), np.zeros(12)
        k.forces(x + eps * v, fp)
        k.forces(x - eps * v, fm)
        assert np.isfinite(y).all()
        assert np.abs(y - (fp - fm) / (2 * eps)).max() <= 1e-7 * np.abs(y).max()
        K, bad = k.tangent(x)
        assert bad == 0 and np.abs(K - K.transpose(0, 2, 1)).max() <= 1e-12 * np.abs(K).max()


def test_ogden_terms_as_lists(tmp_path):
    """-ogden_mu/-ogden_alpha give the terms as two lists (five at most): the run is the one with -mu1 .. -alpha3,
    bitwise; five terms run; a list too long, or a term given both ways, is one line."""
    base = ["run", "bend", "-material", "ogden", "-final_time", 0.02, "-quiet"]
    run_ok(base + ["-ogden_mu", "0.63e6,0.0012e6,-0.01e6", "-ogden_alpha", "1.3,5,-2", "-output", tmp_path / "l.h5"])
    run_ok(base + ["-mu1", 0.63e6, "-alpha1", 1.3, "-mu2", 0.0012e6, "-alpha2", 5, "-mu3", -0.01e6, "-alpha3", -2,
                   "-output", tmp_path / "s.h5"])
    assert np.array_equal(read_h5(tmp_path / "l.h5")["x"], read_h5(tmp_path / "s.h5")["x"])
    run_ok(base + ["-ogden_mu", "0.63e6,0.0012e6,-0.01e6,5e3,-2e3", "-ogden_alpha", "1.3,5,-2,3,-1", "-output",
                   tmp_path / "five.h5"])
    for args, want in ((["-ogden_mu", "1,2,3,4,5,6"], "must be 1 to 5 finite numbers"),
                       (["-ogden_mu", "0.63e6", "-mu1", "1e5"], "gives mu1, and so does -mu1"),
                       (["-material", "yeoh", "-ogden_mu", "1e5"], "a list of ogden's constants, not of this scene's")):
        p = hyperelastic(base + args + ["-output", tmp_path / "bad.h5"])
        assert p.returncode == 2 and want in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_ogden_lists_per_region(tmp_path):
    """-R_ogden_mu/-R_ogden_alpha per region (examples/bimaterial.opts' halves both Ogden rubber, two terms and three):
    the run with the terms given one by one, bitwise."""
    bar = tmp_path / "bar.msh"
    run_ok(["mesh", f"{ROOT}/examples/bimaterial.geo", "--size", 0.25, "-o", bar])
    base = ["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bar, "-soft_material", "ogden", "-stiff_material",
            "ogden", "-final_time", 0.5, "-quiet"]
    run_ok(base + ["-soft_ogden_mu", "3e5,1e3", "-soft_ogden_alpha", "1.5,5", "-stiff_ogden_mu", "1e6,2e3,-1e4",
                   "-stiff_ogden_alpha", "2,4,-2", "-output", tmp_path / "l.h5"])
    run_ok(base + ["-soft_mu1", 3e5, "-soft_alpha1", 1.5, "-soft_mu2", 1e3, "-soft_alpha2", 5, "-stiff_mu1", 1e6,
                   "-stiff_alpha1", 2, "-stiff_mu2", 2e3, "-stiff_alpha2", 4, "-stiff_mu3", -1e4, "-stiff_alpha3", -2,
                   "-output", tmp_path / "s.h5"])
    assert np.array_equal(read_h5(tmp_path / "l.h5")["x"], read_h5(tmp_path / "s.h5")["x"])
