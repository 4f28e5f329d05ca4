"""Issue 71 item 2: a fibre-reinforced material's fibre directions per cell, from a field (-fibre1 'EX,EY,EZ':
expressions of the reference coordinates at each cell's centroid). The compiled loops that take a block of constants
per cell give each cell what the uniform loops give it alone; the numpy reference agrees per cell; a field that takes
two values on two halves of a bar is the run with those halves as -regions; a constant field is the vector run,
bitwise; 1 rank = 2 ranks; bad fields are one line."""
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok


def _cells(rng, n=40):
    X = rng.standard_normal((n, 4, 3))
    D = np.stack([X[:, a] - X[:, 0] for a in (1, 2, 3)], axis=-1)
    keep = np.linalg.det(D) > 0.1
    X, D = X[keep], D[keep]
    x = X + 0.04 * rng.standard_normal(X.shape)
    Dx = np.stack([x[:, a] - x[:, 0] for a in (1, 2, 3)], axis=-1)
    keep = np.linalg.det(Dx) > 0.5 * np.linalg.det(D)
    return X[keep], D[keep], x[keep].reshape(-1)


def _hgo(n, rng):
    """hgo's constants with two fibre families per cell (random directions), its own uniform values otherwise."""
    from hyperelastic.physics.materials import default_solid
    s = default_solid("hgo", nu=0.45)
    s.values.update({"k1": 4e5, "k2": 0.5, "dispersion": 0.1, "fibre1": rng.standard_normal((n, 3)),
                     "fibre2": rng.standard_normal((n, 3))})
    return s


@pytest.mark.parametrize("order", [1, 2])
def test_a_block_per_cell_is_each_cells_own(order):
    """The loops with constants per cell (he_KIND_hgo_cells) against the uniform loops run on each cell alone with its
    row: forces, K v, the tangent blocks and diagonal, the second Piola-Kirchhoff stress, the energy; and the numpy
    reference with a row per cell (P1: the forces to 1e-11)."""
    from hyperelastic.discretization.kernels import Cells, ElementCells
    from hyperelastic.element.reference import Element
    rng = np.random.default_rng(3)
    X, D, x = _cells(rng)
    n = len(X)
    cells = np.arange(4 * n, dtype=np.int32).reshape(-1, 4)
    geo = (Cells(cells, np.linalg.inv(D), np.linalg.det(D) / 6) if order == 1 else
           ElementCells(cells, X.reshape(-1, 3), Element(1, 2)))
    s = _hgo(n, rng)
    c = s.constants
    assert c.shape == (n, 12)
    k = geo.kernels(s.material, c)
    v = rng.standard_normal(x.shape)
    f, y, d = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    k.forces(x, f)
    k.kv(x, v, y)
    k.tangent_diag(x, d)
    K, S, W = k.tangent(x)[0], k.pk2(x), k.energy(x)[0]
    assert np.abs(f).max() > 0 and np.isfinite(K).all()
    Wsum = 0.0
    for e in range(n):
        one = geo.part(e, e + 1).kernels(s.material, tuple(c[e]))
        dofs = slice(12 * e, 12 * e + 12)
        fe, ye, de = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
        one.forces(x, fe)
        one.kv(x, v, ye)
        one.tangent_diag(x, de)
        assert np.array_equal(fe[dofs], f[dofs]) and np.array_equal(ye[dofs], y[dofs]), e
        assert np.array_equal(de[dofs], d[dofs]) and np.array_equal(one.tangent(x)[0][0], K[e]), e
        assert np.array_equal(one.pk2(x)[0], S[e]), e
        Wsum += one.energy(x)[0]
    assert abs(Wsum - W) <= 1e-13 * abs(W)
    if order == 1:                                   # the numpy reference with a row per cell
        F = geo.deformations(x)[:, 0]
        P = s.material.P(F, c)
        G = np.concatenate([-geo.Dminv.reshape(-1, 3, 3).sum(axis=1)[:, None], geo.Dminv.reshape(-1, 3, 3)], axis=1)
        ref = np.einsum("cij,caj,c->cai", P, G, geo.vol).reshape(-1)
        assert np.abs(f - ref).max() <= 1e-11 * np.abs(ref).max()


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    path = tmp_path_factory.mktemp("fibres") / "bimaterial.msh"
    run_ok(["mesh", f"{ROOT}/examples/bimaterial.geo", "--size", 0.25, "-o", path])
    return path


HGO = ["-k1", 2e5, "-k2", 0.8, "-dispersion", 0.05, "-mu", 2e5, "-nu", 0.45]
PULL = ["-quasistatic", "-fix", "end_soft:x,front:y,bottom:z", "-traction_face", "end_stiff", "-traction", "4e4,0,0",
        "-traction_ramp", 1, "-final_time", 1, "-dt", 0.5, "-snes_rtol", 1e-12, "-snes_atol", 1e-10,
        "-output_fields", "fibre1_stretch"]


@pytest.mark.parametrize("order", [1, 2])
def test_a_field_of_two_values_is_two_regions(order, bar, tmp_path):
    """The bimaterial bar (x < 1 and x > 1) of one hgo whose first family points along (1, 1, 0) where x < 1 and
    (1, -1, 0.5) beyond, pulled along x: the run with the field equals the run with the two halves as -regions, each
    with its direction as a vector (positions and reactions to 1e-10; the fibre stretch per cell), P1 and P2."""
    field = ["-material", "hgo", *HGO, "-fibre1", "1,where(X<1,1,-1),where(X<1,0,0.5)"]
    regions = ["-regions", "soft,stiff"] + [a for r in ("soft", "stiff") for a in
                                            (f"-{r}_material", "hgo", *sum(([f"-{r}_{k[1:]}", v] for k, v in
                                                                             zip(HGO[::2], HGO[1::2])), []),
                                             f"-{r}_fibre1", "1,1,0" if r == "soft" else "1,-1,0.5")]
    for tag, args in (("field", field), ("regions", regions)):
        run_ok(["run", "bend", "-mesh", bar, "-effects", "elasticity,fixed,traction", *PULL, *args, "-order", order,
                "-output", tmp_path / f"{tag}.h5", "-quiet"])
    a, b = read_h5(tmp_path / "field.h5"), read_h5(tmp_path / "regions.h5")
    u = a["x"][-1] - a["points"]
    assert np.abs(u).max() > 0.01
    assert np.abs(a["x"] - b["x"]).max() <= 1e-10 * np.abs(u).max()
    ra, rb = a["stats"]["reaction_end_soft_Fx"], b["stats"]["reaction_end_soft_Fx"]
    assert np.allclose(ra, rb, rtol=1e-10, atol=0)
    import h5py
    with h5py.File(tmp_path / "field.h5") as fa, h5py.File(tmp_path / "regions.h5") as fb:
        sa, sb = fa["frames/2/fibre1_stretch"][:], fb["frames/2/fibre1_stretch"][:]
    assert np.allclose(sa, sb, rtol=1e-10, atol=0) and np.ptp(sa) > 0.01


def test_a_constant_field_is_the_vector_bitwise_and_two_ranks_are_one(bar, tmp_path):
    """A field that is the same everywhere ('1+0*X,1,0') gives the vector run (1,1,0) bitwise; a varying field (a
    helix about x) gives the same trajectory on 2 ranks as on 1 (1e-10)."""
    base = ["run", "bend", "-mesh", bar, "-effects", "elasticity,fixed,traction", *PULL, "-material", "hgo", *HGO,
            "-quiet"]
    run_ok(base + ["-fibre1", "1,1,0", "-output", tmp_path / "v.h5"])
    run_ok(base + ["-fibre1", "1+0*X,1,0", "-output", tmp_path / "f.h5"])
    assert np.array_equal(read_h5(tmp_path / "v.h5")["x"], read_h5(tmp_path / "f.h5")["x"])
    helix = ["-fibre1", "0.5,-sin(atan2(Z-0.125,Y-0.125)),cos(atan2(Z-0.125,Y-0.125))"]
    run_ok(base + helix + ["-output", tmp_path / "h1.h5"])
    run_ok(base + helix + ["-output", tmp_path / "h2.h5"], nprocs=2)
    one, two = read_h5(tmp_path / "h1.h5"), read_h5(tmp_path / "h2.h5")
    u = one["x"][-1] - one["points"]
    assert np.abs(one["x"] - two["x"]).max() <= 1e-10 * np.abs(u).max()


@pytest.mark.parametrize("value,want", [
    ("X,Y", "is not three numbers nor three expressions of X, Y, Z"),
    ("0*X,0,0", "is no direction at the cell centred at"),
    ("log(X-5),1,0", "is not finite"),
    ("sqrt(0.5-X),1,0", "is not finite at the cell centred at"),
    ("foo(X),1,0", "option -fibre1"),
])
def test_a_bad_field_is_one_line(value, want, bar, tmp_path):
    p = hyperelastic(["run", "bend", "-mesh", bar, "-effects", "elasticity,fixed,traction", *PULL, "-material", "hgo",
                      *HGO, "-fibre1", value, "-output", tmp_path / "o.h5"])
    assert p.returncode == 2 and want in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


@pytest.fixture(scope="module")
def bar_with_data(bar, tmp_path_factory):
    """The bimaterial bar as a .vtu whose tetrahedra carry cell data 'fibres' ((1, 1, 0) where x < 1, (1, -1, 0.5)
    beyond) and 'flat' (two numbers a cell)."""
    import meshio
    m = meshio.read(bar)
    t = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    centre = m.points[t].mean(axis=1)
    fibres = np.where(centre[:, :1] < 1, [[1.0, 1.0, 0.0]], [[1.0, -1.0, 0.5]])
    path = tmp_path_factory.mktemp("fibre_data") / "bar.vtu"
    meshio.write(path, meshio.Mesh(m.points, [("tetra", t)], cell_data={"fibres": [fibres], "flat": [fibres[:, :2]]}))
    return path


BOX = ["-effects", "elasticity,fixed,traction", "-quasistatic", "-fix", "left:x,front:y,bottom:z", "-traction_face",
       "right", "-traction", "4e4,0,0", "-traction_ramp", 1, "-final_time", 1, "-dt", 0.5, "-snes_rtol", 1e-12,
       "-snes_atol", 1e-10, "-material", "hgo", *HGO, "-quiet"]


@pytest.mark.parametrize("refine,ranks", [(0, 1), (1, 1), (0, 2)])
def test_a_mesh_field_is_its_cells_data(refine, ranks, bar_with_data, tmp_path):
    """-fibre1 mesh:fibres takes each cell's row of the mesh file's cell data (a -refine'd cell its parent's): the same
    trajectory as the expression that gives those rows (bitwise on one rank; a 2-rank run = the 1-rank run, 1e-10)."""
    base = ["run", "bend", "-mesh", bar_with_data, *BOX, "-refine", refine]
    run_ok(base + ["-fibre1", "mesh:fibres", "-output", tmp_path / "m.h5"], nprocs=ranks)
    run_ok(base + ["-fibre1", "1,where(X<1,1,-1),where(X<1,0,0.5)", "-output", tmp_path / "e.h5"])
    m, e = read_h5(tmp_path / "m.h5"), read_h5(tmp_path / "e.h5")
    assert np.abs(e["x"][-1] - e["points"]).max() > 0.01
    if ranks == 1:
        assert np.array_equal(m["x"], e["x"])
    else:
        assert np.abs(m["x"] - e["x"]).max() <= 1e-10 * np.abs(e["x"][-1] - e["points"]).max()


@pytest.mark.parametrize("value,want", [
    ("mesh:nothere", "has no cell data 'nothere' (it has: fibres, flat)"),
    ("mesh:flat", "is not three numbers a tetrahedron"),
])
def test_a_bad_mesh_field_is_one_line(value, want, bar_with_data, tmp_path):
    p = hyperelastic(["run", "bend", "-mesh", bar_with_data, *BOX, "-fibre1", value, "-output", tmp_path / "o.h5"])
    assert p.returncode == 2 and want in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
    p = hyperelastic(["run", "bend", *BOX, "-fibre1", "mesh:fibres", "-output", tmp_path / "o.h5"])
    assert p.returncode == 2 and "not the built-in bar" in p.stderr and len(p.stderr.strip().splitlines()) == 1
