"""Quadratic tetrahedra (issue 32): the element layer (rules exact to their stated degree, shape functions),
the patch test (a quadratic displacement with its body force reproduced to round-off), a curved gmsh part's
volume, convergence orders on a manufactured nonlinear solution, the P1 closed-form path against the
quadrature path, and P2 through the Jacobian modes, on 2 ranks, with a restart and read back."""
import itertools
import math

import numpy as np
import pytest

from conftest import ROOT, make_model, read_h5, run_ok
from hyperelastic.core.expressions import Expression
from hyperelastic.element.reference import EDGES, TET_RULES, TRI_RULES, p1_at_nodes, tet_shapes, tri_shapes

REF_NODES = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]] + [[0.0] * 3] * 6, float)
REF_NODES[4:] = [0.5 * (REF_NODES[i] + REF_NODES[j]) for i, j in EDGES]


def test_rules_integrate_their_degree_exactly():
    """Every monomial up to the stated degree: int x^a y^b z^c over the reference tetrahedron is
    a! b! c! / (a+b+c+3)!, over the reference triangle a! b! / (a+b+2)!; and the next degree is not."""
    for deg, (p, w) in TET_RULES.items():
        errs = {}
        for a, b, c in itertools.product(range(deg + 2), repeat=3):
            if a + b + c <= deg + 1:
                exact = math.factorial(a) * math.factorial(b) * math.factorial(c) / math.factorial(a + b + c + 3)
                errs[(a, b, c)] = abs((w * p[:, 0] ** a * p[:, 1] ** b * p[:, 2] ** c).sum() - exact) / exact
        assert max(e for k, e in errs.items() if sum(k) <= deg) < 1e-13, deg
        assert max(e for k, e in errs.items() if sum(k) == deg + 1) > 1e-6, deg
        assert (w > 0).all()
    for deg, (p, w) in TRI_RULES.items():
        for a, b in itertools.product(range(deg + 1), repeat=2):
            if a + b <= deg:
                exact = math.factorial(a) * math.factorial(b) / math.factorial(a + b + 2)
                assert abs((w * p[:, 0] ** a * p[:, 1] ** b).sum() - exact) <= 1e-13 * exact


def test_shape_functions():
    """P2: one at its node and zero at the others, a partition of unity, gradients = central differences of
    the values; the face element likewise."""
    N, dN = tet_shapes(2, REF_NODES)
    assert np.abs(N - np.eye(10)).max() < 1e-15
    x = np.random.default_rng(3).random((7, 3)) / 3
    N, dN = tet_shapes(2, x)
    assert np.abs(N.sum(axis=1) - 1).max() < 1e-15 and np.abs(dN.sum(axis=1)).max() < 1e-14
    fd = np.stack([(tet_shapes(2, x + 1e-6 * e)[0] - tet_shapes(2, x - 1e-6 * e)[0]) / 2e-6 for e in np.eye(3)], -1)
    assert np.abs(fd - dN).max() < 1e-9
    Nf, _ = tri_shapes(2, np.array([[0, 0], [1, 0], [0, 1], [.5, 0], [.5, .5], [0, .5]]))
    assert np.abs(Nf - np.eye(6)).max() < 1e-15


def test_p1_at_nodes_is_the_linear_interpolation():
    """The P2 -> P1 cell rows (p-multigrid's prolongation, the augmented Schur term's coarse part): a linear field's
    P2 nodal values, exactly 1 and 1/2; the P2 interpolant through them is the linear field everywhere."""
    T = p1_at_nodes()
    assert set(np.unique(T)) == {0.0, 0.5, 1.0} and np.array_equal(T[:4], np.eye(4))
    assert all(T[4 + e, a] == T[4 + e, b] == 0.5 and T[4 + e].sum() == 1.0 for e, (a, b) in enumerate(EDGES))
    u = np.random.default_rng(5).standard_normal(4)              # a linear field's values at the corners
    x = np.random.default_rng(6).random((9, 3)) / 3
    N, _ = tet_shapes(2, x)
    lin = (1 - x.sum(axis=1)) * u[0] + x @ u[1:]
    assert np.abs(N @ (T @ u) - lin).max() < 1e-14


@pytest.fixture(scope="module")
def cube_meshes(tmp_path_factory):
    """The unit cube (examples/cube.geo) at size 0.5 and two uniform refinements, linear."""
    d = tmp_path_factory.mktemp("cube")
    run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.5, "--refine", 2, "-o", d / "c.msh"])
    return [str(d / "c.msh"), str(d / "c_r1.msh"), str(d / "c_r2.msh")]


# u = C (X^2 + Y Z / 2, Y^2 - X Z, X Y + 0.3 Z^2): linear elasticity's div sigma = (lam + 2 mu) C (2, 2, 0.6)
C = 1e-3
U = (f"{C}*(X*X + 0.5*Y*Z)", f"{C}*(Y*Y - X*Z)", f"{C}*(X*Y + 0.3*Z*Z)")
ALL = "xmin,xmax,ymin,ymax,zmin,zmax"
BOX = "left,right,front,back,bottom,top"


def patch(cube, tmp_path, order, extra=()):
    E, nu = 1e6, 0.3
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    b = -(lam + 2 * mu) * C * np.array([2, 2, 0.6])
    out = tmp_path / f"p{order}.h5"
    run_ok(["run", "rotated", "-mesh", cube, "-order", order, "-material", "linear", "-quasistatic", "-dt", 1,
            "-effects", "elasticity", "-prescribe_faces", ALL, "-prescribe_ux", U[0], "-prescribe_uy", U[1],
            "-prescribe_uz", U[2], "-body_force", ",".join(f"{v:.17g}" for v in b), "-snes_rtol", 1e-14, "-snes_atol", 1e-14,
            "-ksp_rtol", 1e-14, "-ksp_atol", 1e-20, "-initial_rotation", "0,0,0", "-quiet", "-output", out, *extra])
    r = read_h5(out)
    X, Y, Z = r["points"].T
    u = np.stack([np.broadcast_to(Expression(e, "XYZ")(X=X, Y=Y, Z=Z), X.shape) for e in U], axis=1)
    return np.abs(r["x"][-1] - r["points"] - u).max() / np.abs(u).max(), r


def test_patch_quadratic_field_reproduced(cube_meshes, tmp_path):
    """A quadratic displacement with its (constant) body force, the whole boundary prescribed, linear
    material: P2 reproduces it at every node to round-off (the 4-point rule integrates the stiffness exactly);
    P1 cannot."""
    err2, r = patch(cube_meshes[0], tmp_path, 2)
    assert r["tetra"].shape[1] == 10 and err2 < 1e-10
    err1, _ = patch(cube_meshes[0], tmp_path, 1)
    assert err1 > 1e-3


def test_curved_part_has_the_geometry_volume(tmp_path):
    """The plate with a hole meshed at order 2: its cells' curved volume (the degree-5 rule) is the geometry's
    to 1e-6, and its error falls as h^4 (the hole's arcs are quadratic); its corners alone (P1) miss by
    7.3e-4, as h^2."""
    from hyperelastic.mesh.read import corners, read_mesh
    run_ok(["mesh", f"{ROOT}/examples/plate_hole.geo", "--size", 0.006, "--order", 2, "--refine", 1,
            "-o", tmp_path / "p.msh"])
    V = 0.2 * 0.1 * 0.01 - math.pi * 0.02 ** 2 * 0.01
    e2, e1 = [], []
    for f in ("p.msh", "p_r1.msh"):
        m = read_mesh(str(tmp_path / f))
        all_ = np.arange(len(m.tets))
        e2.append(abs(m.volume(all_) - V) / V)
        e1.append(abs(corners(m).volume(all_) - V) / V)
    assert e2[0] < 1e-6 and e2[0] / e2[1] > 10
    assert e1[0] > 1e-4 and 3 < e1[0] / e1[1] < 5
    assert m.area(m.groups["load"].items) == pytest.approx(0.001, rel=1e-12)


def test_p1_quadrature_path_agrees_with_the_closed_form(petsc):
    """The element loops (quadrature, dstress columns) on P1 cells with the one-point rule give the closed-
    form P1 loops' forces, energy, K v, tangent blocks and diagonal to round-off, for every material."""
    from hyperelastic.element.reference import Element
    from hyperelastic.discretization.kernels import Cells, ElementCells
    from hyperelastic.physics.materials import MATERIALS, default_solid, get
    rng = np.random.default_rng(11)
    X = rng.standard_normal((60, 4, 3))
    D = np.stack([X[:, a] - X[:, 0] for a in (1, 2, 3)], axis=-1)
    keep = np.linalg.det(D) > 0.1
    X, D = X[keep], D[keep]
    cells = np.arange(4 * len(X), dtype=np.int32).reshape(-1, 4)
    Xf = X.reshape(-1, 3)
    x = (X + 0.1 * rng.standard_normal(X.shape)).reshape(-1)
    v = rng.standard_normal(x.shape)
    p1 = Cells(cells, np.linalg.inv(D), np.abs(np.linalg.det(D)) / 6)
    pq = ElementCells(cells, Xf, Element(1, 1))
    for name in MATERIALS:
        c = default_solid(name).constants
        a, b = p1.kernels(get(name), c), pq.kernels(get(name), c)
        fa, fb = np.zeros_like(x), np.zeros_like(x)
        assert a.forces(x, fa) == b.forces(x, fb)
        assert np.abs(fa - fb).max() <= 1e-12 * np.abs(fa).max(), name
        ea, eb = a.energy(x), b.energy(x)
        assert abs(ea[0] - eb[0]) <= 1e-12 * abs(ea[0]) and abs(ea[1] - eb[1]) <= 1e-12, name
        ya, yb = np.zeros_like(x), np.zeros_like(x)
        a.kv(x, v, ya)
        b.kv(x, v, yb)
        assert np.abs(ya - yb).max() <= 1e-12 * np.abs(ya).max(), name
        Ka, Kb = a.tangent(x)[0], b.tangent(x)[0]
        assert np.array_equal(np.isnan(Ka), np.isnan(Kb)), name              # undefined cells: NaN in both
        ok = np.isfinite(Ka)
        assert np.abs(Ka[ok] - Kb[ok]).max() <= 1e-12 * np.abs(Ka[ok]).max(), name
        da, db = np.zeros_like(x), np.zeros_like(x)
        a.tangent_diag(x, da)
        b.tangent_diag(x, db)
        assert np.abs(da - db).max() <= 1e-12 * np.abs(da).max(), name
        ma, mb = np.zeros_like(x), np.zeros_like(x)
        p1.mass_apply(2.0, v, ma)
        pq.mass_apply(2.0, v, mb)
        assert np.abs(ma - mb).max() <= 1e-13 * np.abs(ma).max()


# a manufactured solution: u_i = A sin(pi X_i / 2) (1 + X_j X_k), (i, j, k) cyclic, on the unit cube
A = 0.05
U_MMS = (f"{A}*sin(pi*X/2)*(1 + Y*Z)", f"{A}*sin(pi*Y/2)*(1 + X*Z)", f"{A}*sin(pi*Z/2)*(1 + X*Y)")


def mms_u(P):
    X, Y, Z = P[..., 0], P[..., 1], P[..., 2]
    s = np.sin(np.pi * P / 2)
    return A * np.stack([s[..., 0] * (1 + Y * Z), s[..., 1] * (1 + X * Z), s[..., 2] * (1 + X * Y)], axis=-1)


def mms_grad(P):
    """du_i/dX_j."""
    X, Y, Z = P[..., 0], P[..., 1], P[..., 2]
    s, c = np.sin(np.pi * P / 2), np.cos(np.pi * P / 2) * np.pi / 2
    g = np.zeros(P.shape + (3,))
    g[..., 0, 0], g[..., 0, 1], g[..., 0, 2] = c[..., 0] * (1 + Y * Z), s[..., 0] * Z, s[..., 0] * Y
    g[..., 1, 0], g[..., 1, 1], g[..., 1, 2] = s[..., 1] * Z, c[..., 1] * (1 + X * Z), s[..., 1] * X
    g[..., 2, 0], g[..., 2, 1], g[..., 2, 2] = s[..., 2] * Y, s[..., 2] * X, c[..., 2] * (1 + X * Y)
    return A * g


def mms_body_force(P, mat, consts, h=1e-5):
    """b = -Div P(I + grad u) by central differences of the first Piola stress (error ~1e-10)."""
    div = np.zeros(P.shape)
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        Pp = mat.P(np.eye(3) + mms_grad(P + e), consts)
        Pm = mat.P(np.eye(3) + mms_grad(P - e), consts)
        div += (Pp[..., :, j] - Pm[..., :, j]) / (2 * h)
    return -div


def kuhn_cube(n, path):
    """The unit cube in n^3 sub-cubes of 6 tetrahedra each (Kuhn's subdivision: every refinement the same
    shapes, so the errors are in their asymptotic range from the first), as a .vtu; its faces are the box's."""
    import meshio
    g = np.linspace(0, 1, n + 1)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    tets = []
    for perm in itertools.permutations(range(3)):
        path_ = [ijk]
        for ax in perm:
            nxt = path_[-1].copy()
            nxt[:, ax] += 1
            path_.append(nxt)
        t = np.stack([(v[:, 0] * (n + 1) + v[:, 1]) * (n + 1) + v[:, 2] for v in path_], axis=1)
        X = P[t]
        flip = np.linalg.det(np.stack([X[:, a] - X[:, 0] for a in (1, 2, 3)], -1)) < 0
        t[flip, 1], t[flip, 2] = t[flip, 2], t[flip, 1].copy()
        tets.append(t)
    meshio.write(path, meshio.Mesh(P, [("tetra", np.concatenate(tets))]))
    return str(path)


def mms_errors(petsc, mesh, order, material="neohookean"):
    """(L2 norm of u_h - u, H1 seminorm of it) of the quasi-static solution with u's body force and u on the
    whole boundary, on `mesh` at `order` (Newton to 1e-12, CG + GAMG)."""
    from hyperelastic.physics.effects.base import DeadLoad
    from hyperelastic.element.reference import Element
    from hyperelastic.solving.integrators import BackwardEuler
    from hyperelastic.solving.solver import Solver
    from hyperelastic.solving.system import System
    # the boundary values and the body force ramped over 4 load steps (P2's edge nodes moved by the full
    # boundary displacement at once fold the cells beside them on the finer meshes)
    ramp = [f"min(t, 1)*{e}" for e in U_MMS]
    opts = [("mesh", mesh), ("order", str(order)), ("material", material), ("quasistatic", ""), ("dt", "0.25"),
            ("effects", "elasticity"), ("prescribe_faces", BOX), ("prescribe_ux", ramp[0]),
            ("prescribe_uy", ramp[1]), ("prescribe_uz", ramp[2]), ("snes_rtol", "1e-11"), ("snes_atol", "1e-13"),
            ("ksp_rtol", "1e-10"), ("pc_type", "gamg"), ("initial_rotation", "0,0,0")]
    m = make_model(petsc, "rotated", opts)
    sp = m.space
    el = Element(order, 5)                                              # the degree-5 rule for loads and errors
    pts, w = el.rule()
    N, dN = el.tabulate()
    Xn = sp.X[sp.cells]                                                 # (nc, nn, 3)
    J = np.einsum("cai,qaj->cqij", Xn, dN)
    wq = np.abs(np.linalg.det(J)) * w                                   # (nc, nq)
    Xq = np.einsum("qa,cai->cqi", N, Xn)
    mat = m.scene.solid.material
    b = mms_body_force(Xq, mat, m.scene.solid.constants)
    f0 = np.zeros((sp.nlv, 3))
    np.add.at(f0, sp.cells, np.einsum("cq,qa,cqi->cai", wq, N, b))
    load = DeadLoad(f0.ravel(), scale=1.0)           # (scale A: A min(t, 1); the body force of u itself at t = 1:
                                                     #  the intermediate steps need not be solutions of anything)
    load.work_column = "body_force_work"                                # (a declared statistics column)
    system = System(sp, m.system.effects + [load], m.system.constraints, m.x0, m.v0, 0.25)
    integ = BackwardEuler(m.scene, system, Solver(system, "assembled"), None, m.x0, m.v0, quiet=True).run()
    uh = (integ.x.reshape(-1, 3) - sp.X)[sp.cells]                      # (nc, nn, 3)
    e0 = np.einsum("qa,cai->cqi", N, uh) - mms_u(Xq)
    G = np.einsum("cqmj,qam->cqaj", np.linalg.inv(J), dN)                # physical gradients of N
    e1 = np.einsum("cai,cqaj->cqij", uh, G) - mms_grad(Xq)
    return math.sqrt((wq * (e0 ** 2).sum(-1)).sum()), math.sqrt((wq * (e1 ** 2).sum((-1, -2))).sum())


def test_manufactured_solution_convergence_orders(petsc, tmp_path):
    """Neo-Hookean, a 5% smooth deformation, uniform refinements of a structured cube: P2 on 2^3 to 8^3 sub-cubes
    (its L2 error falls with order >= 2.8 and its energy-norm (H1) error with >= 1.9 at each refinement; 16^3 took
    47 s and showed the same 3.0 and 2.0), P1 on 2^3 to 16^3 (about 2 and 1 at its last); P2 is the more accurate on
    every mesh."""
    meshes = [kuhn_cube(n, tmp_path / f"k{n}.vtu") for n in (2, 4, 8, 16)]
    errs = {1: np.array([mms_errors(petsc, msh, 1) for msh in meshes]),
            2: np.array([mms_errors(petsc, msh, 2) for msh in meshes[:3]])}
    rates = {o: np.log2(e[:-1] / e[1:]) for o, e in errs.items()}        # per refinement: L2, H1
    assert (rates[2][:, 0] >= 2.8).all() and (rates[2][:, 1] >= 1.9).all(), (rates, errs)
    assert (np.abs(rates[1][-1] - [2, 1]) < 0.35).all(), (rates, errs)
    assert (errs[2] < errs[1][:3]).all()


@pytest.mark.parametrize("options", [[], [("material", "neohookean")], [("mass", "lumped"), ("damping", "40")],
                                     [("rayleigh_alpha", "0.5"), ("rayleigh_beta", "1e-3")],
                                     [("spring", "3e5"), ("spring_faces", "bottom:z,back"), ("force", "0,-50,20"),
                                      ("force_faces", "front"), ("body_force", "0,0,-200")],
                                     [("effects", "elasticity,inertia,fixed,pressure"), ("fix", "left"),
                                      ("pressure", "300"), ("pressure_faces", "top,right")],
                                     [("effects", "elasticity,inertia,fixed,follower_traction"), ("fix", "left"),
                                      ("traction_twist", "5000")]],
                         ids=["stvk", "neohookean", "lumped", "rayleigh", "new-effects", "pressure", "twist"])
def test_p2_tangent_in_every_form(petsc, options):
    """P2 on the bar: the shell and the assembled tangent agree (operator and diagonal), the tangent is the
    residual's derivative (central differences), PETSc's MFFD agrees to 1e-5, every effect's potential is the
    gradient of its residual."""
    from test_operators import apply, check_is_derivative, check_shell_equals_assembled, petsc_mffd, state
    scene, space, system, X = state(petsc, "bend", [("order", "2")] + options, amp=0.01)    # (no cell folded)
    assert space.cells.shape[1] == 10
    A, S, V, Jv = check_shell_equals_assembled(system, X)
    Da, Ds = X.duplicate(), X.duplicate()
    A.getDiagonal(Da)
    S.getDiagonal(Ds)
    assert np.abs(Da.getArray() - Ds.getArray()).max() <= 1e-12 * np.abs(Da.getArray()).max()
    check_is_derivative(system, X, V, Jv)
    M, _ = petsc_mffd(system, X)
    assert np.linalg.norm(apply(M, V) - Jv) <= 1e-5 * np.linalg.norm(Jv)
    rng = np.random.default_rng(2)
    x = system.x_lin + 0.001 * rng.standard_normal(len(system.x_lin))
    for e in system.effects:
        if not e.conservative:
            continue
        r = np.zeros_like(x)
        e.residual(x, r)
        d = rng.standard_normal(len(x))
        fd = (e.potential(x + 1e-6 * d) - e.potential(x - 1e-6 * d)) / 2e-6
        assert abs(fd - r @ d) <= 1e-6 * np.abs(r).max() * np.abs(d).sum() + 1e-10, e.name


def test_hrz_lumped_mass_is_positive_and_the_mass(petsc):
    """HRZ lumping of P2: every node's mass > 0 (the row sums give the vertices -V/20 each) and the total is
    rho V per component; the consistent matrix has the same total."""
    m = make_model(petsc, "bend", [("order", "2"), ("mass", "lumped")])
    inertia = [e for e in m.system.effects if e.name == "inertia"][0]
    d = inertia.M.diagonal.reshape(-1, 3)[m.space.owned, 0]
    assert (d > 0).all()
    total = m.space.mpi.allreduce(d.sum())
    assert total == pytest.approx(1000.0 * 160.0, rel=1e-12)
    rows = m.kernels.geometry.mass_w @ m.kernels.geometry.Nm      # consistent row sums per cell: int N_a dV
    assert rows[:, :4].max() < 0 and rows[:, 4:].min() > 0


def test_p2_same_on_two_ranks_restart_and_readers(tmp_path):
    """A P2 run on 1 and 2 ranks agrees to the solver tolerance; a restart from its checkpoint is bitwise;
    VTK's XDMF reader sees quadratic tetrahedra with every field and meshio reads every frame; the output
    read back as -mesh is a quadratic mesh at the last frame."""
    import h5py
    import meshio
    import vtk
    args = ["run", "bend", "-order", 2, "-final_time", 0.1, "-checkpoint_every", 4, "-snes_rtol", 1e-10,
            "-ksp_rtol", 1e-12, "-quiet"]
    run_ok(args + ["-output", tmp_path / "a.h5"])
    run_ok(args + ["-output", tmp_path / "b.h5"], nprocs=2)
    a, b = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    assert a["tetra"].shape[1] == 10 and np.array_equal(a["tetra"], b["tetra"])
    assert np.abs(a["x"] - b["x"]).max() <= 1e-8 * np.abs(a["x"]).max()
    run_ok(["run", "--restart", tmp_path / "a.h5", "-final_time", 0.15])
    run_ok(args[:5] + [0.15] + args[6:] + ["-output", tmp_path / "c.h5"])
    assert np.array_equal(read_h5(tmp_path / "a.h5")["x"], read_h5(tmp_path / "c.h5")["x"])
    rd = vtk.vtkXdmfReader()
    rd.SetFileName(str(tmp_path / "c.xdmf"))
    rd.Update()
    grid = rd.GetOutputDataObject(0)
    assert grid.GetCellType(0) == vtk.VTK_QUADRATIC_TETRA and grid.GetNumberOfPoints() == len(a["points"])
    assert grid.GetPointData().GetArray("displacement") and grid.GetCellData().GetArray("von_mises")
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "c.xdmf")) as r:
        pts, cells = r.read_points_cells()
        assert cells[0].type == "tetra10"
        frames = [r.read_data(k) for k in range(r.num_steps)]
    with h5py.File(tmp_path / "c.h5", "r") as f:
        assert np.allclose(frames[-1][1]["displacement"], f["x"][-1] - f["mesh/points"][:], atol=1e-14)
    run_ok(["run", "sag", "-mesh", tmp_path / "c.h5", "-final_time", 0.02, "-output", tmp_path / "d.h5"])
    d = read_h5(tmp_path / "d.h5")
    assert d["tetra"].shape[1] == 10 and np.array_equal(d["points"], read_h5(tmp_path / "c.h5")["x"][-1])


def test_the_element_is_decided_once_with_its_rule():
    """Element.decide: -order, else the mesh's own; the default rule per order; a rule on linear tetrahedra, one
    point on quadratic ones, an unknown order or degree: one line each."""
    from hyperelastic.core.errors import UserError
    from hyperelastic.element.reference import DEFAULT_DEGREE, Element
    assert Element.decide(0, 0, 1) == Element(1, DEFAULT_DEGREE[1]) and Element.decide(0, 0, 2) == Element(2, 2)
    assert Element.decide(2, 5, 1) == Element(2, 5) and Element.decide(1, 0, 2) == Element(1, 1)
    for args, words in (((0, 2, 1), "linear tetrahedra"), ((1, 5, 2), "linear tetrahedra"), ((2, 1, 1), "zero-energy"),
                        ((3, 0, 1), "-order: 3"), ((2, 4, 1), "the rules are of degree")):
        with pytest.raises(UserError, match=words):
            Element.decide(*args)
