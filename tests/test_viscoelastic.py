"""Issue 71 item 3: finite-strain viscoelasticity, a Prony series on the isochoric stress (Simo 1987): a held stretch
relaxes as the series' closed form, the effect's tangent is its residual's derivative, and what it cannot do yet is
refused in one line."""
import math

import numpy as np
import pytest

from conftest import ROOT, hyperelastic, make_model, read_h5, run_ok, tangent_and_fd


def _confined(lam, mu, kappa):
    """F = diag(lam, 1, 1) of the split Neo-Hookean solid (J = lam): the elastic nominal stress P_11 = mu J^(-2/3)
    (lam - I1/(3 lam)) + kappa/2 (J^2 - 1)/lam and the isochoric second Piola-Kirchhoff stress S_11 = mu J^(-2/3)
    (1 - I1/(3 lam^2)), I1 = lam^2 + 2 (Holzapfel 2000, sec. 6.5)."""
    j23, I1 = lam ** (-2 / 3), lam * lam + 2
    return mu * j23 * (lam - I1 / (3 * lam)) + 0.5 * kappa * (lam * lam - 1) / lam, mu * j23 * (1 - I1 / (3 * lam * lam))


@pytest.fixture(scope="module")
def cube(tmp_path_factory):
    d = tmp_path_factory.mktemp("visco")
    msh = d / "cube.msh"
    run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.5, "-o", msh])
    return msh


CONFINED = ["-effects", "elasticity,fixed,prescribed,viscoelastic", "-fix", "xmin:x,ymin:y,ymax:y,zmin:z,zmax:z",
            "-prescribe_faces", "xmax:x", "-quasistatic", "-snes_rtol", "1e-13", "-snes_atol", "1e-9"]


@pytest.mark.parametrize("order", [1, 2])
def test_a_held_stretch_relaxes_as_the_prony_series(order, cube, tmp_path):
    """A unit cube held on its sides (F = diag(lambda, 1, 1)) stretched to lambda = 1.5 in the first step of h = 0.05 s
    and held: two Prony terms (b = 0.5, 0.3; tau = 0.2, 1 s). The reaction on xmax per reference area is the elastic
    P_11 plus lambda sum_i g_i S_11 exp(-(t - h)/tau_i), g_i = b_i (1 - exp(-h/tau_i)) tau_i/h (the ramp's update
    exact for a stress linear in the step, then the series' exponential decay), to 1e-9 at every frame; and it
    relaxes to the elastic stress (the long-term modulus). On linear and on quadratic tetrahedra (the stresses at each
    of the stiffness rule's points)."""
    mu, nu, E, h = 1e6, 0.45, 2.9e6, 0.05
    beta, tau = (0.5, 0.3), (0.2, 1.0)
    out = tmp_path / "relax.h5"
    run_ok(["run", "bend", "-mesh", cube, "-material", "neohookean_split", "-mu", mu, "-E", E, "-nu", nu, *CONFINED,
            "-prescribe_x", "X*1.5", "-prony_beta", "0.5,0.3", "-prony_tau", "0.2,1", "-final_time", 3, "-dt", h,
            "-order", order, "-formulation", "displacement", "-output", out, "-quiet"])
    st = read_h5(out)["stats"]
    kappa = E / (3 * (1 - 2 * nu))
    P_inf, S11 = _confined(1.5, mu, kappa)
    t = st["time"]
    visc = sum(b * (-math.expm1(-h / T)) * T / h * np.exp(-(t - h) / T) for b, T in zip(beta, tau))
    want = P_inf + 1.5 * S11 * visc
    got = st["reaction_xmax_Fx"]
    assert np.abs(got / want - 1).max() <= 1e-9, np.abs(got / want - 1).max()
    assert abs(got[-1] / P_inf - 1) < 0.002 and got[0] - P_inf > 0.05 * P_inf


class _Fused:
    """The elastic force (its kernels, whose isochoric moduli the effect scales by 1 + g) and the effect's F H term
    together: what a viscoelastic run's residual and tangent hold."""

    def __init__(self, k, e):
        self.k, self.e, self.cells = k, e, e.cells

    def linearize(self, x):
        self.x = x.copy()
        self.e.linearize(x)

    def residual(self, x, r):
        self.k.forces(x, r)
        self.e.residual(x, r)

    def apply(self, v, y):
        self.k.kv(self.x, v, y)
        self.e.apply(v, y)

    def diag(self, d):
        self.k.tangent_diag(self.x, d)
        self.e.diag(d)

    def add_cell_blocks(self, K):
        self.k.tangent(self.x, K, accumulate=True)
        self.e.add_cell_blocks(K)


def _tangent_checks(f, x0, rng, a, b, reference):
    """Mid-way through a relaxation (a step from x0 accepted at x0 + a r1: Q != 0; linearized at x1 + b r2): the
    fused residual against the numpy reference (P(F) + g P_iso(F) + F H), its K v against central differences of it,
    its cell blocks (scattered) against K v, and its diagonal against the blocks'."""
    e = f.e
    x1 = x0 + a * rng.standard_normal(x0.shape)
    e.begin_step(0.05, 0.05, x0, None)
    e.accept_step(x1, 0.05)                             # (the step accepted at x1: Q != 0)
    e.begin_step(0.1, 0.05, x1, None)
    x = x1 + b * rng.standard_normal(x0.shape)
    r = np.zeros_like(x)
    f.residual(x, r)
    want = reference(x, e)
    assert np.abs(e.H).max() > 0 and np.abs(r - want).max() <= 1e-10 * np.abs(want).max()
    v = rng.standard_normal(x.shape)
    y, fd = tangent_and_fd(f, x, v, 1e-6)
    assert np.abs(y - fd).max() <= 1e-6 * np.abs(y).max()
    nc, nn = e.cells.shape
    K = np.zeros((nc, 3 * nn, 3 * nn))
    f.add_cell_blocks(K)
    dofs = (3 * e.cells[:, :, None] + np.arange(3)).reshape(nc, -1)
    yk, dk, d = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    np.add.at(yk, dofs, np.einsum("crs,cs->cr", K, v[dofs]))
    assert np.abs(yk - y).max() <= 1e-12 * np.abs(y).max()
    f.diag(d)
    np.add.at(dk, dofs, np.einsum("cii->ci", K))
    assert np.allclose(d, dk, rtol=1e-12, atol=1e-12 * np.abs(dk).max())


def _random_cells(rng, n=30):
    X = rng.standard_normal((n, 4, 3))
    D = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=-1)
    keep = np.linalg.det(D) > 0.1
    return X[keep], D[keep]


def test_the_tangent_is_the_residuals_derivative():
    """The elastic force with its isochoric moduli scaled by 1 + g and the effect's F H term, together: the residual
    against a numpy reference written from the effect's formula (P(F) + g P_iso(F) + F H, per cell), its K v, its
    diagonal and its 12x12 blocks against central differences of it, mid-way through a relaxation (Q != 0), on random
    cells of the split Neo-Hookean and of Ogden's rubber."""
    from hyperelastic.discretization.kernels import Cells
    from hyperelastic.physics.effects.viscoelastic import Viscoelastic, _gammas
    from hyperelastic.physics.materials import default_solid
    rng = np.random.default_rng(5)
    X, D = _random_cells(rng)
    n = len(X)
    cells = Cells(np.arange(4 * n, dtype=np.int32).reshape(-1, 4), np.linalg.inv(D), np.linalg.det(D) / 6)
    Dm = cells.Dminv.reshape(-1, 3, 3)
    G = np.concatenate([-Dm.sum(axis=1)[:, None], Dm], axis=1)                     # (nc, 4, 3): grad N_a
    for name in ("neohookean_split", "ogden"):
        s = default_solid(name)
        k = cells.kernels(s.material, s.constants)
        iso = s.material.split(s.values)[0]
        e = Viscoelastic(k, [(None, s.material, iso)], (0.4, 0.2), (0.1, 0.5))

        def reference(x, e):
            F = e._F(x)[:, 0]
            g = _gammas(e.beta, e.tau, 0.05)[1].sum()
            P = s.material.P(F, s.constants) + g * s.material.P(F, iso) + F @ e.H[:, 0]
            out = np.zeros_like(x)
            np.add.at(out.reshape(-1, 3), cells.cells, np.einsum("cij,caj,c->cai", P, G, cells.vol))
            return out
        _tangent_checks(_Fused(k, e), X.reshape(-1).copy(), rng, 0.03, 0.02, reference)


@pytest.mark.parametrize("order", [1, 2])
def test_scaled_moduli_scale_the_isochoric_part_alone(order):
    """Issue 71 (the effect in the elastic pass): for every material with a split, the compiled force, K v, tangent
    blocks and diagonal with the isochoric moduli times s (kernels.scale_moduli) equal the material's own plus (s - 1)
    times its isochoric part's (the split's constants), on linear tetrahedra and quadratic ones; the energy keeps the
    material's own, `unscaled()` (Rayleigh damping's kernels) ignores the scale, and s = 1 is bitwise the
    material's."""
    from hyperelastic.discretization.kernels import Cells, ElementCells
    from hyperelastic.element.reference import Element
    from hyperelastic.physics.materials import MATERIALS, default_solid
    rng = np.random.default_rng(8)
    X, D = _random_cells(rng, 60)
    x = X + 0.05 * rng.standard_normal(X.shape)
    keep = np.linalg.det(np.stack([x[:, a] - x[:, 0] for a in (1, 2, 3)], axis=-1)) > 0.5 * np.linalg.det(D)
    X, D, x = X[keep], D[keep], x[keep].reshape(-1)            # (every cell defined: J > 1/2)
    cells = np.arange(4 * len(X), dtype=np.int32).reshape(-1, 4)
    geo = (Cells(cells, np.linalg.inv(D), np.linalg.det(D) / 6) if order == 1 else
           ElementCells(cells, X.reshape(-1, 3), Element(1, 2)))
    v = rng.standard_normal(x.shape)
    names = [n for n, m in MATERIALS.items() if m.volumetric]
    assert {"neohookean_split", "yeoh", "ogden", "hgo", "linear"} <= set(names)
    for name in names:
        sol = default_solid(name, nu=0.45)
        if name == "hgo":
            sol.values.update({"k1": 2e5, "k2": 0.8, "fibre1": (1.0, 0.0, 0.0), "fibre2": (0.0, 0.6, 0.8)})
        c = sol.material.constants(sol.values)
        iso = sol.material.split(sol.values)[0]
        k, ki = geo.kernels(sol.material, c), geo.kernels(sol.material, iso)
        before = _evaluations(k, x, v)
        damp = k.unscaled()
        k.scale_moduli(1.7)
        got, own, part = _evaluations(k, x, v), _evaluations(damp, x, v), _evaluations(ki, x, v)
        for what in ("f", "y", "K", "d"):
            want = before[what] + 0.7 * part[what]
            assert np.isfinite(want).all() and np.abs(got[what] - want).max() <= 1e-11 * np.abs(want).max(), \
                (name, what)
            assert np.array_equal(own[what], before[what]), (name, what)
        assert got["W"] == before["W"]
        k.scale_moduli(1.0)
        again = _evaluations(k, x, v)
        assert all(np.array_equal(again[w], before[w]) for w in before), name
        F = geo.deformations(x)                    # the effect's S_iso: the compiled F^-1 P(F) against numpy's
        want = np.linalg.solve(F, sol.material.P(F, iso))
        assert np.abs(ki.pk2(x) - want).max() <= 1e-10 * np.abs(want).max(), name
    Dx = np.stack([x.reshape(-1, 4, 3)[:, a] - x.reshape(-1, 4, 3)[:, 0] for a in (1, 2, 3)], axis=-1)
    assert np.allclose(geo.deformations(x)[:, 0], Dx @ np.linalg.inv(D), rtol=0, atol=1e-12)


def _evaluations(k, x, v):
    f, y, d = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    k.forces(x, f)
    k.kv(x, v, y)
    k.tangent_diag(x, d)
    return {"f": f, "y": y, "d": d, "K": k.tangent(x)[0], "W": k.energy(x)[0]}


@pytest.mark.parametrize("args,want", [
    (["-material", "stvk"], "no material of the run (stvk) has an isochoric/volumetric split"),
    (["-material", "neohookean_split", "-prony_tau", "0.1,0.2"], "1 and 2 terms"),
    (["-material", "neohookean_split", "-prony_tau", "-1"], "must be > 0"),
])
def test_what_it_cannot_do_is_one_line(args, want, cube, tmp_path):
    base = ["run", "bend", "-mesh", cube, *CONFINED, "-prescribe_x", "X*1.2", "-prony_beta", "0.5", "-final_time",
            0.1, "-dt", 0.05, "-output", tmp_path / "o.h5"]
    if "-prony_tau" not in args:
        base += ["-prony_tau", "0.1"]
    p = hyperelastic(base + args)
    assert p.returncode == 2 and want in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


@pytest.mark.parametrize("layout,ranks,order", [("gather", 1, 1), ("ranks", 2, 1), ("gather", 1, 2)])
def test_a_restart_continues_the_relaxation(layout, ranks, order, cube, tmp_path):
    """The held stretch's relaxation stopped at t = 0.3 (a checkpoint at every step, the non-equilibrium stresses per
    cell in it) and restarted to t = 0.6: on the rank count that wrote it, bitwise the uninterrupted run's trajectory
    and statistics; from a 2-rank per-rank output on 1 rank (the rows moved by their input cell index), the same
    reactions to 1e-10."""
    common = ["-material", "yeoh", "-E", 2.9e6, "-nu", 0.45, *CONFINED, "-prescribe_x", "X*1.3", "-prony_beta",
              "0.5,0.2", "-prony_tau", "0.1,0.5", "-dt", 0.05, "-output_layout", layout, "-order", order, "-quiet"]
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    run_ok(["run", "bend", "-mesh", cube, *common, "-final_time", 0.6, "-output", whole], nprocs=ranks)
    run_ok(["run", "bend", "-mesh", cube, *common, "-final_time", 0.3, "-checkpoint_every", 1, "-output", part],
           nprocs=ranks)
    run_ok(["run", "--restart", part, "-final_time", 0.6], nprocs=ranks)
    a, b = read_h5(whole), read_h5(part)
    assert np.array_equal(a["x"], b["x"])
    for k in ("reaction_xmax_Fx", "viscous_work"):
        assert np.array_equal(a["stats"][k], b["stats"][k]), k
    if ranks == 2:                            # the 2-rank checkpoint continued on 1 rank
        one = tmp_path / "one.h5"
        run_ok(["run", "bend", "-mesh", cube, *common, "-final_time", 0.3, "-checkpoint_every", 1, "-output", one],
               nprocs=2)
        run_ok(["run", "--restart", one, "-final_time", 0.6])
        c = read_h5(one)["stats"]
        assert np.abs(c["reaction_xmax_Fx"] - a["stats"]["reaction_xmax_Fx"]).max() <= \
            1e-10 * np.abs(a["stats"]["reaction_xmax_Fx"]).max()


def test_the_same_answer_on_two_ranks(tmp_path):
    """The bend scene of Yeoh rubber with a Prony term on 1 and 2 ranks: the same trajectory (to 1e-10 of its size)."""
    from conftest import read_h5 as read
    out = {}
    for n in (1, 2):
        out[n] = tmp_path / f"r{n}.h5"
        run_ok(["run", "bend", "-level", 2, "-material", "yeoh", "-prony_beta", "0.3", "-prony_tau", "0.05",
                "-final_time", 0.1, "-output", out[n], "-quiet"], nprocs=n)
    a, b = read(out[1])["x"], read(out[2])["x"]
    assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max()


def test_a_cycles_hysteresis_loop_is_the_viscous_work(cube, tmp_path):
    """The same held-sides cube stretched cyclically, lambda = 1 + 0.3 sin(2 pi t), three cycles of 1 s in steps of
    0.02 s (b = 0.5, tau = 0.2 s): the area of the last cycle's force-stretch loop (the external work over a closed
    cycle: the elastic part returns) is the statistics' viscous_work over that cycle, within 1e-3 (both trapezoidal in
    time: O(h^2); measured 7e-5 at h = 0.01), and positive (energy is dissipated)."""
    out = tmp_path / "cycle.h5"
    run_ok(["run", "bend", "-mesh", cube, "-material", "neohookean_split", "-mu", 1e6, "-E", 2.9e6, "-nu", 0.45,
            *CONFINED, "-prescribe_x", "X*(1+0.3*sin(2*pi*t))", "-prony_beta", "0.5", "-prony_tau", "0.2",
            "-final_time", 3, "-dt", 0.02, "-output", out, "-quiet"])
    st = read_h5(out)["stats"]
    ok = st["rejected"] == 0
    t, P, w = st["time"][ok], st["reaction_xmax_Fx"][ok], st["viscous_work"][ok]
    lam = 1 + 0.3 * np.sin(2 * np.pi * t)
    i0, i1 = int(np.argmin(abs(t - 2))), len(t) - 1
    area = float(np.sum(0.5 * (P[i0 + 1:i1 + 1] + P[i0:i1]) * np.diff(lam[i0:i1 + 1])))
    assert area > 0 and abs((w[i1] - w[i0]) / area - 1) <= 1e-3, (area, w[i1] - w[i0])


def test_a_restart_with_another_series_is_one_line(cube, tmp_path):
    """A checkpoint of two Prony terms restarted with one (-prony_beta given again): one line, exit 2."""
    out = tmp_path / "v.h5"
    run_ok(["run", "bend", "-mesh", cube, "-material", "neohookean_split", *CONFINED, "-prescribe_x", "X*1.2",
            "-prony_beta", "0.5,0.1", "-prony_tau", "0.1,1", "-final_time", 0.1, "-dt", 0.05, "-checkpoint_every", 1,
            "-output", out, "-quiet"])
    p = hyperelastic(["run", "--restart", out, "-final_time", 0.2, "-prony_beta", "0.5", "-prony_tau", "0.1"])
    errors = [ln for ln in p.stderr.splitlines() if ln.startswith("hyperelastic: error")]
    assert p.returncode == 2 and len(errors) == 1 and "37 numbers a cell, where its Prony series takes 28" in errors[0], \
        p.stderr
    assert "viscoelastic has no potential" not in p.stderr          # (refused before the solver is set up)


def test_a_region_of_another_material_takes_no_part(tmp_path):
    """examples/bimaterial.opts with its soft half of split Neo-Hookean rubber with a Prony term (b = 0.5, tau = 0.05
    s) and its stiff half of St. Venant-Kirchhoff (no split: no viscoelasticity there), under the scene's dead traction
    ramped over the first second: the soft half lags (its first step's extension smaller than the elastic run's), and
    20 relaxation times after the ramp the bar is where the purely elastic run puts it (to 1e-7 of the displacement)."""
    bar = tmp_path / "bimaterial.msh"
    run_ok(["mesh", f"{ROOT}/examples/bimaterial.geo", "--size", 0.25, "-o", bar])
    common = ["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bar, "-soft_material", "neohookean_split",
              "-stiff_material", "stvk", "-snes_rtol", 1e-13, "-snes_atol", 1e-12, "-final_time", 2, "-dt", 0.05,
              "-quiet"]
    run_ok(common + ["-prony_beta", "0.5", "-prony_tau", "0.05", "-output", tmp_path / "v.h5"])
    run_ok(common + ["-output", tmp_path / "e.h5"])
    v, e = read_h5(tmp_path / "v.h5"), read_h5(tmp_path / "e.h5")
    u = e["x"][-1] - e["points"]
    assert np.abs(v["x"][-1] - e["x"][-1]).max() <= 1e-7 * np.abs(u).max()
    soft = v["points"][:, 0] <= 1
    assert (v["x"][1][soft, 0] - v["points"][soft, 0]).max() < 0.9 * (e["x"][1][soft, 0] - e["points"][soft, 0]).max()


def test_the_quadratic_tangent_is_the_residuals_derivative(petsc):
    """On quadratic tetrahedra (the bend scene at level 1, -order 2, Yeoh rubber with two Prony terms) mid-way through a
    relaxation: the elastic force (its moduli scaled) with the effect's F H term, against the numpy reference at each
    point of the stiffness rule; K v against central differences of the residual, its 30x30 blocks and diagonal
    against K v."""
    from hyperelastic.physics.effects.elasticity import Elasticity
    from hyperelastic.physics.effects.viscoelastic import Viscoelastic, _gammas
    m = make_model(petsc, "bend", [("level", "1"), ("order", "2"), ("material", "yeoh"), ("prony_beta", "0.4,0.2"),
                                   ("prony_tau", "0.1,0.5")])
    e = next(x for x in m.system.effects if isinstance(x, Viscoelastic))
    k = next(x for x in m.system.effects if isinstance(x, Elasticity)).k
    assert k is e.stiffness
    g = k.geometry
    _, mat, iso = e.parts[0]
    c = k.constants

    def reference(x, e):
        F = e._F(x)
        gsum = _gammas(e.beta, e.tau, 0.05)[1].sum()
        P = mat.P(F, c) + gsum * mat.P(F, iso) + F @ e.H
        G = np.matmul(g.dN[None], g.geo[:, :, :9].reshape(g.nc, g.nq, 3, 3))          # (nc, nq, nn, 3)
        f = np.einsum("cqij,cqaj,cq->cai", P, G, g.geo[:, :, 9])
        out = np.zeros_like(x)
        np.add.at(out.reshape(-1, 3), g.cells, f)
        return out
    _tangent_checks(_Fused(k, e), m.x0.copy(), np.random.default_rng(11), 0.01, 0.005, reference)


def test_nearly_incompressible_rubber_relaxes_in_the_mixed_formulation(cube, tmp_path):
    """Yeoh rubber at nu = 0.4999 (kappa/mu = 5,000), the mixed P2-P1 formulation, a unit cube on symmetry planes
    stretched to lambda = 1.5 in its first step of h = 0.05 s (its sides free) and held; one Prony term (b = 0.4, tau =
    0.2 s). Incompressible uniaxial closed form (J = 1, F = diag(l, l^-1/2, l^-1/2)): the reaction per reference area
    P(t) = 2 (l - l^-2) W'(I1) + (l^2 Q11 - Q22 / l) / l, Q = g S_iso exp(-(t - h)/tau), g = b (1 - exp(-h/tau)) tau/h,
    S_iso = 2 W' (I - I1/3 C^-1); within 2e-4 (the compressibility of kappa/mu = 5,000) at every frame."""
    C10, C20, C30, E, nu, h, lam = 0.5e6 / 1.4999 / 2, -2e4, 1e3, 1e6, 0.4999, 0.05, 1.5
    out = tmp_path / "mixed.h5"
    run_ok(["run", "bend", "-mesh", cube, "-order", 2, "-formulation", "mixed", "-material", "yeoh", "-C10", C10,
            "-C20", C20, "-C30", C30, "-E", E, "-nu", nu, "-effects", "elasticity,fixed,prescribed,viscoelastic",
            "-fix", "xmin:x,ymin:y,zmin:z", "-prescribe_faces", "xmax:x", "-prescribe_x", f"X*{lam!r}",
            "-prony_beta", "0.4", "-prony_tau", "0.2", "-quasistatic", "-final_time", 1, "-dt", h,
            "-output", out, "-quiet"])
    st = read_h5(out)["stats"]
    I1 = lam ** 2 + 2 / lam
    w1 = C10 + 2 * C20 * (I1 - 3) + 3 * C30 * (I1 - 3) ** 2
    S11, S22 = 2 * w1 * (1 - I1 / (3 * lam ** 2)), 2 * w1 * (1 - I1 * lam / 3)
    g = 0.4 * (-math.expm1(-h / 0.2)) * 0.2 / h * np.exp(-(st["time"] - h) / 0.2)
    want = 2 * (lam - lam ** -2) * w1 + (lam ** 2 * g * S11 - g * S22 / lam) / lam
    got = st["reaction_xmax_Fx"]
    assert np.abs(got / want - 1).max() <= 2e-4, np.abs(got / want - 1).max()


def test_each_accepted_step_is_taken_forward_by_its_own_size():
    """Steps of unequal size (step control halves and regrows them): each accepted step takes the stresses forward by
    its own h, Q^(n+1) = exp(-h_n/tau) Q^n + g(h_n) (S^(n+1) - S^n), whatever the next step's size (one cell of the
    split Neo-Hookean, one term; S_iso by the numpy reference)."""
    from hyperelastic.discretization.kernels import Cells
    from hyperelastic.physics.effects.viscoelastic import Viscoelastic
    from hyperelastic.physics.materials import default_solid
    s = default_solid("neohookean_split")
    iso = s.material.split(s.values)[0]
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    cells = Cells(np.arange(4, dtype=np.int32)[None], np.eye(3)[None], np.array([1 / 6]))
    e = Viscoelastic(cells.kernels(s.material, s.constants), [(None, s.material, iso)], (0.5,), (0.1,))
    Fs = [np.eye(3), np.diag([1.2, 0.95, 0.95]), np.diag([1.3, 0.9, 0.92])]
    xs = [(X @ F.T).reshape(-1).copy() for F in Fs]
    S = [np.linalg.solve(F, s.material.P(F[None], iso)[0]) for F in Fs]
    Q, t = np.zeros((3, 3)), 0.0
    e.begin_step(0.0, 0.04, xs[0], None)
    for n, h in ((1, 0.04), (2, 0.01)):
        e.begin_step(t + h, 0.02 if n == 1 else 0.08, xs[n - 1], None)      # (a rejected attempt of another size)
        e.begin_step(t + h, h, xs[n - 1], None)
        e.accept_step(xs[n], h)
        t += h
        Q = np.exp(-h / 0.1) * Q + 0.5 * (-math.expm1(-h / 0.1)) * 0.1 / h * (S[n] - S[n - 1])
        assert np.abs(e.Q[0, 0, 0] - Q).max() <= 1e-12 * np.abs(Q).max()


def test_generalized_alpha_converges_with_the_series(cube, tmp_path):
    """Issue 71 (-integrator ts): a dynamic pull of the cube (rho 1000, its xmax face taken smoothly to 1.3 in 0.05 s,
    the sides free) with two Prony terms (tau 0.02 and 0.1 s, the order of the part's period) under generalized-alpha
    (rho_inf 0.5; a stage carries the committed stresses alpha_f h forward, the step's end commits over h): the
    positions at t = 0.1 converge to the run at dt = 1e-4 as dt halves, as the elastic material's alone do (measured
    1.0e-2, 1.7e-3, 6.4e-4 at dt 0.002, 0.001, 0.0005; elastic alone 4.3e-3, 2.7e-3, 1.3e-3)."""
    common = ["-mesh", cube, "-material", "neohookean_split", "-mu", 1e6, "-E", 2.9e6, "-nu", 0.45, "-rho", 1000,
              "-effects", "elasticity,fixed,prescribed,viscoelastic,inertia", "-fix", "xmin:x,ymin:y,zmin:z",
              "-prescribe_faces", "xmax:x", "-prescribe_x", "X*(1+0.15*(1-cos(3.141592653589793*min(t/0.05,1))))",
              "-prony_beta", "0.5,0.3", "-prony_tau", "0.02,0.1", "-final_time", 0.1, "-integrator", "ts",
              "-ts_alpha_radius", 0.5, "-snes_rtol", 1e-12, "-snes_atol", 1e-10, "-ksp_type", "preonly",
              "-pc_type", "lu", "-quiet"]
    last = {}
    for dt in (1e-4, 2e-3, 1e-3, 5e-4):
        run_ok(["run", "bend", *common, "-dt", dt, "-output", tmp_path / f"{dt}.h5"])
        last[dt] = read_h5(tmp_path / f"{dt}.h5")["x"][-1]
    err = [np.abs(last[dt] - last[1e-4]).max() for dt in (2e-3, 1e-3, 5e-4)]
    assert err[0] > err[1] > err[2] and err[2] <= 0.1 * err[0] and err[2] < 1e-3, err
    assert np.ptp(last[1e-4][:, 1]) < 0.95          # (it moved: the sides contracted)
