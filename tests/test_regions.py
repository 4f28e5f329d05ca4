"""A material per region (-regions, issue 14): the bimaterial bar of examples/bimaterial.geo.

With nu = 0 (lam = 0) every material here has an exact homogeneous uniaxial state under a dead
traction P on the far end, the lateral stretch staying 1 (P22 = 0 at b = 1), so each half stretches
uniformly by its own closed form and the two halves' strains come out in the ratio of their moduli."""
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, make_model, read_h5, run_ok

P = 5e4          # traction [Pa]
E_SOFT, E_STIFF = 1e6, 4e6


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("bimaterial") / "bimaterial.msh")
    run_ok(["mesh", f"{ROOT}/examples/bimaterial.geo", "--size", 0.125, "-o", path])
    return path


def stretched(bar, tmp_path, materials, nprocs=1, extra=()):
    out = tmp_path / f"b{nprocs}.h5"
    run_ok(["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bar, "-soft_material", materials[0],
            "-stiff_material", materials[1], "-soft_E", E_SOFT, "-stiff_E", E_STIFF, "-traction", f"{P},0,0",
            "-snes_rtol", 1e-13, "-snes_atol", 1e-12, "-ksp_rtol", 1e-14, "-quiet", "-output", out, *extra],
           nprocs=nprocs)
    return read_h5(out), out


def piecewise(X, a_soft, a_stiff):
    """x = a_soft X on [0, 1], continued with stretch a_stiff on [1, 2]; y, z unchanged."""
    x = X.copy()
    x[:, 0] = np.where(X[:, 0] <= 1, a_soft * X[:, 0], a_soft + a_stiff * (X[:, 0] - 1))
    return x


def test_linear_strains_in_the_ratio_of_the_moduli(bar, tmp_path):
    r, _ = stretched(bar, tmp_path, ("linear", "linear"))
    X, x = r["points"], r["x"][-1]
    assert np.abs(x - piecewise(X, 1 + P / E_SOFT, 1 + P / E_STIFF)).max() < 1e-12
    ux = x[:, 0] - X[:, 0]
    interface, end = ux[np.isclose(X[:, 0], 1)].mean(), ux[np.isclose(X[:, 0], 2)].mean()
    strain_soft, strain_stiff = interface / 1.0, (end - interface) / 1.0
    assert strain_soft / strain_stiff == pytest.approx(E_STIFF / E_SOFT, rel=1e-10)


def test_two_materials_closed_forms_and_fields(bar, tmp_path):
    """Soft Neo-Hookean: mu (a - 1/a) = P; stiff St. Venant-Kirchhoff: mu a (a^2 - 1) = P. The cell
    fields use each region's material: energy density mu/2 (a^2 - 1) - mu ln a and mu/2 (a^2-1)^2/4*2."""
    import h5py
    r, out = stretched(bar, tmp_path, ("neohookean", "stvk"))
    mu1, mu2 = E_SOFT / 2, E_STIFF / 2
    a1 = (P / mu1 + np.sqrt((P / mu1) ** 2 + 4)) / 2
    lo, hi = 1.0, 2.0
    for _ in range(200):
        a2 = 0.5 * (lo + hi)
        lo, hi = (a2, hi) if mu2 * a2 * (a2 * a2 - 1) < P else (lo, a2)
    assert np.abs(r["x"][-1] - piecewise(r["points"], a1, a2)).max() < 1e-12
    with h5py.File(out, "r") as f:
        last = f[f"frames/{len(f['time']) - 1}"]
        psi, region = last["energy_density"][:], f["mesh/region"][:]
    psi_soft = mu1 / 2 * (a1 * a1 - 1) - mu1 * np.log(a1)       # NH with lam = 0, F = diag(a, 1, 1)
    psi_stiff = mu2 * ((a2 * a2 - 1) / 2) ** 2                  # St.VK: mu E:E, E11 = (a^2 - 1)/2
    assert np.allclose(psi[region == 1], psi_soft, rtol=1e-9)
    assert np.allclose(psi[region == 2], psi_stiff, rtol=1e-9)


def test_regions_same_on_two_ranks(bar, tmp_path):
    r1, _ = stretched(bar, tmp_path, ("neohookean", "stvk"), 1, ("-quasistatic", 0, "-dt", 0.01, "-final_time", 0.05))
    r2, _ = stretched(bar, tmp_path, ("neohookean", "stvk"), 2, ("-quasistatic", 0, "-dt", 0.01, "-final_time", 0.05))
    assert np.abs(r1["x"][-1] - r1["x"][0]).max() > 1e-4
    assert np.abs(r1["x"] - r2["x"]).max() <= 1e-8


def test_density_and_mass_per_region(petsc, bar):
    """Gravity's total force is g (rho_soft V_soft + rho_stiff V_stiff); the kinetic energy of a
    uniform velocity is (m_soft + m_stiff) |v|^2 / 2, consistent and lumped."""
    from mpi4py import MPI
    for mass in ("consistent", "lumped"):
        m = make_model(petsc, f"{ROOT}/examples/bimaterial.opts",
                       [("mesh", bar), ("quasistatic", "0"), ("gravity", "0,0,-10"), ("mass", mass)])
        mass_total = 1100 * 0.0625 + 7800 * 0.0625
        grav = next(e for e in m.system.effects if e.name == "gravity")
        fz = MPI.COMM_WORLD.allreduce(grav.f.reshape(-1, 3)[m.space.owned].sum(axis=0)[2])
        assert fz == pytest.approx(-10 * mass_total, rel=1e-12)
        inertia = next(e for e in m.system.effects if e.name == "inertia")
        v = np.tile([1.0, 2.0, 0.0], m.space.nlv)
        assert inertia.energy(m.x0, v)["kinetic"] == pytest.approx(0.5 * mass_total * 5.0, rel=1e-12)


@pytest.mark.parametrize("args, words", [
    (["-regions", "soft,glue"], ["-regions", "no volume 'glue'", "soft", "stiff"]),
    (["-regions", "soft,soft"], ["-regions", "twice"]),
    (["-regions", "soft, stiff", "-soft_nu", "0.5"], ["region 'soft'", "Poisson"]),
    (["-stiff_material", "rubbery"], ["-stiff_material", "unknown material 'rubbery'"]),
    (["-regions", "my soft"], ["-regions", "option prefix"]),
])
def test_bad_regions_one_line(bar, tmp_path, args, words):
    p = hyperelastic(["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bar, "-output", tmp_path / "x.h5", *args])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, (p.returncode, p.stderr)
    assert all(w in lines[0] for w in words), lines[0]
    assert not (tmp_path / "x.h5").exists()
