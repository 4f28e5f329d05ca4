"""Your own part: boundary facets, physical groups as sets, component-wise conditions (issue 14).

The meshes are made from examples/*.geo by `hyperelastic mesh`, as a user would."""
import json
import os

import numpy as np
import pytest

from conftest import ROOT, hyperelastic, make_model, read_h5, run_ok, tangent_and_fd


def one_line_error(p, *words):
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, (p.returncode, p.stderr)
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture(scope="session")
def parts(tmp_path_factory):
    """{name: .msh path} of the example parts, meshed once."""
    d = tmp_path_factory.mktemp("parts")
    out = {}
    for name, h in (("plate_hole", 0.008), ("bracket", 0.008), ("cube", 0.35)):
        out[name] = str(d / f"{name}.msh")
        run_ok(["mesh", f"{ROOT}/examples/{name}.geo", "--size", h, "-o", out[name]])
    return out


def held_vertices(model):
    """(input-mesh vertex ids, held components (n,3)) of the constrained dofs (1 rank)."""
    mask = model.system.cmask.reshape(-1, 3)
    v = np.flatnonzero(mask.any(axis=1))
    return model.space.orig[v], mask[v]


def traction_force(model):
    eff = next(e for e in model.system.effects if e.name == "traction")
    return eff.f0.reshape(-1, 3).sum(axis=0)


def test_mesh_command_keeps_physical_groups(parts, tmp_path):
    import meshio
    m = meshio.read(parts["plate_hole"])
    assert set(m.field_data) == {"clamp", "load", "solid"}
    p = run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.5, "--refine", 1, "-o", tmp_path / "c.msh"])
    assert "c_r1.msh" in p.stdout
    m0, m1 = meshio.read(tmp_path / "c.msh"), meshio.read(tmp_path / "c_r1.msh")
    n0, n1 = (sum(len(c.data) for c in mm.cells if c.type == "tetra") for mm in (m0, m1))
    assert n1 == 8 * n0 and set(m1.field_data) == set(m0.field_data)
    one_line_error(hyperelastic(["mesh", tmp_path / "nosuch.geo", "--size", 1, "-o", tmp_path / "x.msh"]),
                   "no such file")
    # a part too coarse for gmsh's refinement (the bracket's 1 cm hole in a 1 cm plate at 2 cm): one line that
    # says why and what to do, and none of the meshes written
    one_line_error(hyperelastic(["mesh", f"{ROOT}/examples/bracket.geo", "--size", 0.02, "--refine", 1, "-o",
                                 tmp_path / "b.msh"]), "b_r1.msh", "overlap", "give a --size below 0.02")
    assert not list(tmp_path.glob("b*"))


def test_mesh_keeps_a_graded_geometry_with_graded(tmp_path):
    """A geometry's own size field (examples/graded_cube.geo: 0.04 at a corner, 0.3 away from it) is kept with
    --graded, --size the largest edge; without it every edge is --size and a note says the field was overridden;
    uniform refinement keeps the grading (8x the tets)."""
    import meshio
    geo = f"{ROOT}/examples/graded_cube.geo"
    flat = run_ok(["mesh", geo, "--size", 0.3, "-o", tmp_path / "u.msh"])
    assert "declares its own mesh sizes" in flat.stdout and "--graded" in flat.stdout
    graded = run_ok(["mesh", geo, "--size", 0.3, "--graded", "--refine", 1, "-o", tmp_path / "g.msh"])
    assert "declares" not in graded.stdout

    def edges(path):
        m = meshio.read(path)
        t = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
        e = m.points[t[:, [0, 0, 0, 1, 1, 2]]] - m.points[t[:, [1, 2, 3, 2, 3, 3]]]
        return len(t), np.linalg.norm(e, axis=2)
    (nu, eu), (ng, eg), (n1, _) = edges(tmp_path / "u.msh"), edges(tmp_path / "g.msh"), edges(tmp_path / "g_r1.msh")
    assert eu.min() > 0.15 and eg.min() < 0.06 and eg.max() < 0.3 * 1.6, (eu.min(), eg.min(), eg.max())
    assert ng > 2 * nu and n1 == 8 * ng
    one_line_error(hyperelastic(["mesh", geo, "--level", 2, "--graded", "-o", tmp_path / "x.msh"]), "--graded",
                   "--size")


def test_second_order_meshes(tmp_path):
    """`hyperelastic mesh --order 2`: 10-node tetrahedra with the physical groups on their 6-node triangles, run
    as quadratic cells (the set report's areas and volumes are the curved ones); a gmsh order-2 mesh without any
    physical group runs on the box faces; -order 1 takes its corners; a mesh mixing tetra and tetra10, or one
    whose neighbours disagree on an edge's node, is one error line."""
    import gmsh
    import meshio
    p = run_ok(["mesh", f"{ROOT}/examples/bracket.geo", "--size", 0.008, "--order", 2, "-o", tmp_path / "b.msh"])
    assert "nodes of 10-node tets" in p.stdout
    m = meshio.read(tmp_path / "b.msh")
    assert {c.type for c in m.cells} == {"tetra10", "triangle6"} and set(m.field_data) == {"clamp", "load", "solid"}
    p = run_ok(["run", f"{ROOT}/examples/bracket.opts", "-mesh", tmp_path / "b.msh", "-dt", 1, "-final_time", 1,
                "-output", tmp_path / "b.h5"])
    assert "set load: " in p.stderr and read_h5(tmp_path / "b.h5")["tetra"].shape[1] == 10
    path = str(tmp_path / "t10.msh")
    gmsh.initialize(["gmsh", "-v", "0"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        gmsh.write(path)
    finally:
        gmsh.finalize()
    for order, nodes in (("2", 10), ("1", 4)):
        run_ok(["run", "bend", "-mesh", path, "-order", order, "-final_time", 0.02, "-quiet",
                "-output", tmp_path / f"o{order}.h5"])
        assert read_h5(tmp_path / f"o{order}.h5")["tetra"].shape[1] == nodes
    m = meshio.read(path)
    t10 = [c.data for c in m.cells if c.type == "tetra10"][0]
    bad = t10.copy()
    bad[0, 4] = bad[0, 5]                                  # one cell's edge node taken from its other edge
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(m.points, [("tetra10", bad)]))
    one_line_error(hyperelastic(["run", "bend", "-mesh", tmp_path / "bad.vtu", "-output", tmp_path / "x.h5"]),
                   "mesh ", "another node")
    meshio.write(tmp_path / "mixed.vtu", meshio.Mesh(m.points, [("tetra10", t10), ("tetra", t10[:3, :4])]))
    one_line_error(hyperelastic(["run", "bend", "-mesh", tmp_path / "mixed.vtu", "-output", tmp_path / "x.h5"]),
                   "mixes linear (tetra) and quadratic (tetra10)")


@pytest.mark.parametrize("part,clamp_axis,load_area", [("plate_hole", 0, 0.1 * 0.01), ("bracket", 0, 0.06 * 0.01)])
def test_thin_part_sets(petsc, parts, part, clamp_axis, load_area):
    """The regression of the issue: on a 1 cm part, a box face is exactly its boundary facets (not a
    slab of vertices within 0.01), and a load integrates over exactly the named facets."""
    import meshio
    pts = meshio.read(parts[part]).points
    common = [("mesh", parts[part]), ("traction_face", "load"), ("traction", "0,0,-1000"), ("quasistatic", "1")]
    model = make_model(petsc, "bend", common + [("fix", "bottom")])
    v, comps = held_vertices(model)
    assert comps.all()
    assert set(v) == set(np.flatnonzero(pts[:, 2] == pts[:, 2].min()))
    f = traction_force(model)
    assert abs(f[2] + 1000 * load_area) <= 1e-12 * 1000 * load_area and f[0] == f[1] == 0
    model = make_model(petsc, "bend", common + [("fix", "clamp")])
    v, _ = held_vertices(model)
    assert set(v) == set(np.flatnonzero(pts[:, clamp_axis] == 0.0))
    sets = {s["name"]: s for s in model.sets}
    assert sets["load"]["kind"] == "facets" and abs(sets["load"]["measure"] - load_area) <= 1e-12 * load_area
    assert sets["solid"]["kind"] == "tets" and sets["solid"]["count"] == len(model.tets)
    # the box face at x max is the load face of both parts: the same facets
    model = make_model(petsc, "bend", common[:1] + [("traction_face", "right"), ("traction", "0,0,-1000"),
                                                    ("quasistatic", "1"), ("fix", "1")])
    assert np.array_equal(traction_force(model), f)


def test_unknown_set_names_what_the_mesh_has(parts, tmp_path):
    line = one_line_error(hyperelastic(["run", "bend", "-mesh", parts["bracket"], "-fix", "clamps",
                                        "-output", tmp_path / "o.h5"]), "-fix", "'clamps'")
    assert "clamp (1), load (2)" in line and "box faces: left" in line
    assert not (tmp_path / "o.h5").exists()


def test_geometric_selectors_pick_the_physical_groups_facets(parts, tmp_path):
    """A part without usable names (a STEP file) is loaded by geometry: the bracket with its clamp as the plane
    x=0 and its load as a box around the base's free end gives bitwise the run by physical names; normal=DIR
    picks the cube's faces; selectors that pick nothing or are malformed are one line naming the part's extent."""
    base = ["run", f"{ROOT}/examples/bracket.opts", "-mesh", parts["bracket"], "-dt", 0.5, "-quiet"]
    run_ok([*base, "-output", tmp_path / "a.h5"])
    p = run_ok([*base[:-1], "-output", tmp_path / "b.h5", "-fix", "x=0", "-traction_face", "box=0.1;0;0;0.1;0.06;0.01"])
    a, b = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    assert np.array_equal(a["x"], b["x"]) and np.abs(a["x"][-1] - a["points"]).max() > 1e-6
    assert "set x=0: " in p.stderr and "set box=0.1;0;0;0.1;0.06;0.01: " in p.stderr
    scene = tmp_path / "c.opts"
    scene.write_text("-effects elasticity,fixed,traction\n-quasistatic\n-dt 1\n-final_time 1\n-traction 0,0,1e4\n")
    c = [["-fix", "xmin:x,ymin:y,zmin:z", "-traction_face", "zmax"],
         ["-fix", "normal=-x:x,normal=0;-1;0:y,z=0:z", "-traction_face", "normal=+z"]]
    for i, extra in enumerate(c):
        run_ok(["run", scene, "-mesh", parts["cube"], "-output", tmp_path / f"c{i}.h5", "-quiet", *extra])
    assert np.array_equal(read_h5(tmp_path / "c0.h5")["x"], read_h5(tmp_path / "c1.h5")["x"])
    for spec, words in (("x=0.5", ["selects no boundary facet", "x 0..1"]), ("box=0;0;1", ["not a surface selector"]),
                        ("normal=+w", ["not a surface selector"]), ("y=1e", ["not a surface selector"])):
        one_line_error(hyperelastic(["run", scene, "-mesh", parts["cube"], "-fix", spec, "-output", tmp_path / "e.h5"]),
                       "option -fix", f"'{spec}'", *words)
    assert not (tmp_path / "e.h5").exists()


STEP_PART = """
import sys, gmsh
gmsh.initialize(); gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.occ.addBox(0, 0, 0, 0.1, 0.02, 0.03); gmsh.model.occ.addCylinder(0.05, 0.01, 0, 0, 0, 0.03, 0.005, 2)
gmsh.model.occ.cut([(3, 1)], [(3, 2)]); gmsh.model.occ.synchronize(); gmsh.write(sys.argv[1]); gmsh.finalize()
"""


def test_step_part_gets_a_name_per_surface_and_a_table(tmp_path):
    """A STEP part (no physical groups): `hyperelastic mesh` names every surface and volume by its tag, keeps
    them in the .msh and prints name, facets, area, centroid and outward normal; a run by those names is the
    run by geometric selectors, bitwise."""
    import subprocess
    import sys
    subprocess.run([sys.executable, "-c", STEP_PART, str(tmp_path / "part.step")], check=True, capture_output=True)
    p = run_ok(["mesh", tmp_path / "part.step", "--size", 0.005, "-o", tmp_path / "part.msh"])
    rows = {ln.split()[0]: ln.split() for ln in p.stdout.splitlines() if ln.strip().startswith("surface_")}
    assert len(rows) == 7 and "no physical groups" in p.stdout
    normals = sorted(r[-1] for r in rows.values() if r[-1] != "planar)")
    assert normals == ["+x", "+y", "+z", "-x", "-y", "-z"], normals
    hole = [r for r in rows.values() if r[-1] == "planar)"][0]
    assert abs(float(hole[2]) / (2 * np.pi * 0.005 * 0.03) - 1) < 0.03           # the faceted cylinder's area
    end = [r for r in rows.values() if r[-1] == "+x"][0]
    assert abs(float(end[2]) - 0.02 * 0.03) < 1e-12 and end[3] == "(0.1,"
    clamp = [n for n, r in rows.items() if r[-1] == "-x"][0]
    base = ["run", "bend", "-mesh", tmp_path / "part.msh", "-effects", "elasticity,fixed,traction", "-quasistatic",
            "-dt", 1, "-final_time", 1, "-traction", "0,0,-1e5", "-quiet"]
    run_ok([*base, "-fix", clamp, "-traction_face", end[0], "-output", tmp_path / "a.h5"])
    run_ok([*base, "-fix", "x=0", "-traction_face", "x=0.1", "-output", tmp_path / "b.h5"])     # (normal=+x: also
    # the 5 facets of the hole facing +x)
    a, b = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    assert np.array_equal(a["x"], b["x"]) and np.abs(a["x"][-1] - a["points"]).max() > 0
    assert json.loads(a["attrs"]["sets"])[-1]["name"] == "volume_1"


def test_sets_printed_and_stored(parts, tmp_path):
    out = tmp_path / "o.h5"
    p = run_ok(["run", "bend", "-mesh", parts["plate_hole"], "-fix", "clamp", "-traction_face", "load",
                "-final_time", 0.01, "-dt", 0.01, "-output", out, "-dm_view"])
    assert "set clamp: " in p.stderr and " facets, area 0.001" in p.stderr
    assert "set solid: " in p.stderr and "tets, volume" in p.stderr
    assert "facets:clamp" in p.stdout and "Cell Sets" in p.stdout        # -dm_view shows the labels
    sets = json.loads(read_h5(out)["attrs"]["sets"])
    assert [s["name"] for s in sets] == ["clamp", "load", "solid"]


def cube_stretch(parts, tmp_path, material, nprocs=1, amount=0.1):
    """A cube stretched along x by its x max face (x held only), on three symmetry rollers: the
    state is homogeneous. Returns (reference points, final positions)."""
    scene = tmp_path / "uniaxial.opts"
    scene.write_text("-effects elasticity,fixed,prescribed\n-quasistatic\n-dt 1\n-final_time 1\n"
                     "-fix xmin:x,ymin:y,zmin:z\n-prescribe_faces xmax:x\n-prescribe_motion stretch_x\n"
                     f"-prescribe_amount {amount}\n-snes_rtol 1e-14\n-snes_atol 1e-13\n-ksp_rtol 1e-14\n")
    out = tmp_path / f"u{nprocs}.h5"
    run_ok(["run", scene, "-mesh", parts["cube"], "-material", material, "-E", 1e6, "-nu", 0.3,
            "-output", out, "-quiet"], nprocs=nprocs)
    r = read_h5(out)
    return r["points"], r["x"][-1]


def test_uniaxial_stretch_on_rollers_linear(parts, tmp_path):
    """Linear elasticity: u = (e X, -nu e Y, -nu e Z) exactly (the patch test)."""
    X, x = cube_stretch(parts, tmp_path, "linear")
    e, nu = 0.1, 0.3
    exact = X * np.array([1 + e, 1 - nu * e, 1 - nu * e])
    assert np.abs(x - exact).max() < 1e-10


def test_uniaxial_stretch_on_rollers_neohookean(parts, tmp_path):
    """Compressible Neo-Hookean (Bonet & Wood 6.4.3), F = diag(a, b, b) with a = 1.1: the lateral
    stretch b solves P22 = mu (b - 1/b) + lam ln(a b^2) / b = 0."""
    X, x = cube_stretch(parts, tmp_path, "neohookean")
    E, nu, a = 1e6, 0.3, 1.1
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    lo, hi = 0.5, 1.0                       # P22 < 0 at lo, > 0 at hi: bisect to rounding
    for _ in range(200):
        b = 0.5 * (lo + hi)
        lo, hi = (b, hi) if mu * (b - 1 / b) + lam * np.log(a * b * b) / b < 0 else (lo, b)
    exact = X * np.array([a, b, b])
    assert np.abs(x - exact).max() < 1e-10


@pytest.mark.parametrize("case", ["cube", "plate"])
def test_sets_same_on_two_ranks(parts, tmp_path, case):
    if case == "cube":
        _, x1 = cube_stretch(parts, tmp_path, "stvk", 1)
        _, x2 = cube_stretch(parts, tmp_path, "stvk", 2)
    else:
        args = ["run", "bend", "-mesh", parts["plate_hole"], "-fix", "clamp:xyz,bottom:z", "-traction_face",
                "load", "-traction", "0,0,-1e4", "-E", 70e9, "-rho", 2700, "-dt", 1e-4, "-final_time", 5e-4,
                "-quiet", "-snes_rtol", 1e-12, "-ksp_rtol", 1e-12]
        run_ok([*args, "-output", tmp_path / "p1.h5"])
        run_ok([*args, "-output", tmp_path / "p2.h5"], nprocs=2)
        x1, x2 = read_h5(tmp_path / "p1.h5")["x"], read_h5(tmp_path / "p2.h5")["x"]
        assert np.abs(x1[-1] - x1[0]).max() > 1e-9          # it moved
    assert np.abs(x1 - x2).max() <= 1e-8 * max(1.0, np.abs(x1).max())


def pressure_effect(model):
    return next(e for e in model.system.effects if e.name == "pressure")


def test_pressure_on_a_closed_surface_has_zero_net_force_and_exact_tangent(petsc, parts):
    """Follower pressure on all six faces of a free cube: the net force vanishes in any configuration
    (the surface stays closed); its tangent (apply and the assembled COO values) equals central
    differences of the residual, which are exact for a force quadratic in x."""
    faces = "xmin,xmax,ymin,ymax,zmin,zmax"
    model = make_model(petsc, "bend", [("mesh", parts["cube"]), ("effects", "elasticity,pressure"),
                                       ("pressure", "1e5"), ("pressure_faces", faces), ("quasistatic", "1")])
    eff = pressure_effect(model)
    rng = np.random.default_rng(7)
    x = model.space.X.ravel() + 0.05 * rng.standard_normal(model.space.X.size)
    r = np.zeros_like(x)
    eff.residual(x, r)
    area = 6.0
    assert np.abs(r.reshape(-1, 3).sum(axis=0)).max() <= 1e-12 * 1e5 * area
    assert np.abs(r).max() > 1e2                                   # it does push
    v = rng.standard_normal(x.size)
    y, fd = tangent_and_fd(eff, x, v, 1e-3)
    assert np.abs(y - fd).max() <= 1e-8 * np.abs(fd).max()
    rows, cols = eff.coo_pattern()
    vals = np.zeros(len(rows))
    eff.coo_values(vals)
    ycoo = np.zeros_like(x)
    np.add.at(ycoo, rows, vals * v[cols])
    assert np.abs(ycoo - y).max() <= 1e-12 * np.abs(y).max()


def test_hydrostatic_pressure_on_rollers_neohookean(parts, tmp_path):
    """Pressure p on the three far faces of a cube on three symmetry rollers: a homogeneous
    compression F = b I whose Cauchy stress is -p I; for compressible Neo-Hookean
    mu (b^2 - 1) + lam ln(b^3) = -p b^3 (Bonet & Wood 6.4.3). Only a follower pressure (on the
    current area) gives this b."""
    scene = tmp_path / "hydro.opts"
    scene.write_text("-effects elasticity,fixed,pressure\n-quasistatic\n-dt 0.25\n-final_time 1\n"
                     "-fix xmin:x,ymin:y,zmin:z\n-pressure_faces xmax,ymax,zmax\n-pressure 2e5\n-pressure_ramp 1\n"
                     "-snes_rtol 1e-14\n-snes_atol 1e-12\n-ksp_rtol 1e-14\n")
    outs = []
    for n in (1, 2):
        out = tmp_path / f"h{n}.h5"
        run_ok(["run", scene, "-mesh", parts["cube"], "-material", "neohookean", "-E", 1e6, "-nu", 0.3,
                "-output", out, "-quiet"], nprocs=n)
        outs.append(read_h5(out))
    E, nu, p = 1e6, 0.3, 2e5
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    lo, hi = 0.5, 1.0
    for _ in range(200):
        b = 0.5 * (lo + hi)
        lo, hi = (b, hi) if mu * (b * b - 1) + lam * np.log(b ** 3) + p * b ** 3 < 0 else (lo, b)
    X = outs[0]["points"]
    assert np.abs(outs[0]["x"][-1] - b * X).max() < 1e-9
    assert abs(b - 1) > 0.03
    assert np.abs(outs[0]["x"] - outs[1]["x"]).max() <= 1e-8


def test_tags_of_other_formats(petsc, parts, tmp_path):
    """A .vtu with integer cell tags (no names): sets by tag; the same clamp as the .msh by name."""
    import meshio
    m = meshio.read(parts["plate_hole"])
    vtu = str(tmp_path / "plate.vtu")
    meshio.write(vtu, meshio.Mesh(m.points, [(c.type, c.data) for c in m.cells],
                                  cell_data={"cell_tags": [np.asarray(a) for a in m.cell_data["gmsh:physical"]]}))
    by_tag = held_vertices(make_model(petsc, "bend", [("mesh", vtu), ("fix", "1"), ("traction_face", "2"),
                                                      ("traction", "0,0,-1")]))[0]
    by_name = held_vertices(make_model(petsc, "bend", [("mesh", parts["plate_hole"]), ("fix", "clamp"),
                                                       ("traction_face", "load"), ("traction", "0,0,-1")]))[0]
    assert len(by_tag) > 0 and set(by_tag) == set(by_name)


def test_free_cube_under_pressure_keeps_its_centre_of_mass_on_two_ranks(parts, tmp_path):
    """Follower pressure on all six faces of a free cube, dynamic: the net force is zero at every
    configuration, so the mass-weighted centre (row sums of M: V/4 per tet vertex) stays put while
    the cube is compressed; 1 and 2 ranks agree to 1e-8."""
    scene = tmp_path / "free.opts"
    scene.write_text("-effects elasticity,inertia,pressure\n")
    args = ["run", scene, "-mesh", parts["cube"], "-pressure", 2e5,
            "-pressure_faces", "xmin,xmax,ymin,ymax,zmin,zmax", "-pressure_time", "min(20*t, 1)", "-material",
            "neohookean", "-dt", 0.005, "-final_time", 0.05, "-snes_rtol", 1e-13, "-snes_atol", 1e-12,
            "-ksp_rtol", 1e-14, "-quiet"]
    r = []
    for n in (1, 2):
        run_ok([*args, "-output", tmp_path / f"f{n}.h5"], nprocs=n)
        r.append(read_h5(tmp_path / f"f{n}.h5"))
    X, tets, x = r[0]["points"], r[0]["tetra"], r[0]["x"]
    D = np.stack([X[tets[:, k]] - X[tets[:, 0]] for k in (1, 2, 3)], axis=-1)
    w = np.zeros(len(X))
    np.add.at(w, tets.ravel(), np.repeat(np.abs(np.linalg.det(D)) / 24.0, 4))
    centre = np.einsum("a,fai->fi", w, x) / w.sum()
    assert np.abs(centre - centre[0]).max() <= 1e-12
    assert np.abs(x[-1] - X).max() > 1e-3                  # it was compressed
    assert np.abs(r[0]["x"] - r[1]["x"]).max() <= 1e-8


def test_part_size_line_and_the_millimetre_note(tmp_path):
    """The start-up report gives the part's size; the bracket drawn in millimetres (its mesh scaled by 1000)
    with the aluminium modulus in pascals gets a note naming the likely unit mix-up, the same bracket in
    metres does not (issue 34)."""
    import meshio
    m = tmp_path / "m.msh"
    run_ok(["mesh", f"{ROOT}/examples/bracket.geo", "--size", 0.012, "-o", m])
    mesh = meshio.read(m)
    mesh.points = mesh.points * 1000.0
    mm = tmp_path / "mm.msh"
    meshio.write(mm, mesh, file_format="gmsh22", binary=False)
    for path, note in ((m, False), (mm, True)):
        p = hyperelastic(["run", f"{ROOT}/examples/bracket.opts", "-mesh", path, "-final_time", 0.25,
                          "-output", tmp_path / "o.h5"])
        assert p.returncode == 0, p.stderr
        part = [ln for ln in p.stderr.splitlines() if ln.startswith("part: ")]
        assert len(part) == 1 and ("x 0.0" in part[0]) != note, p.stderr
        assert ("drawn in millimetres" in p.stderr) == note, p.stderr


def test_a_checked_mesh_is_read_again_from_the_cache(parts, tmp_path, monkeypatch):
    """The second read of a mesh file comes from the parsed-mesh cache (no meshio) and is the same Mesh, groups and
    boundary included; a file changed since is read again; a file that fails its checks is never kept."""
    import shutil
    from hyperelastic.mesh import read
    monkeypatch.setenv("HYPERELASTIC_MESH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "part.msh"
    shutil.copy(parts["plate_hole"], path)
    first = read.read_mesh(str(path))
    calls = []
    monkeypatch.setattr(read, "_read_meshio", lambda p: calls.append(p) or (_ for _ in ()).throw(AssertionError))
    again = read.read_mesh(str(path))
    assert calls == [] and again.path == first.path and again.order == first.order
    for k in ("points", "tets", "facet_cell", "facet_k"):
        a, b = getattr(first, k), getattr(again, k)
        assert a.dtype == b.dtype and np.array_equal(a, b), k
    assert list(first.groups) == list(again.groups)
    for name, g in first.groups.items():
        h = again.groups[name]
        assert (g.tag, g.kind, g.ignored) == (h.tag, h.kind, h.ignored) and np.array_equal(g.items, h.items), name
    monkeypatch.undo()
    monkeypatch.setenv("HYPERELASTIC_MESH_CACHE", str(tmp_path / "cache"))
    shutil.copy(parts["cube"], path)                      # another mesh at the same path: read, not the cached one
    assert len(read.read_mesh(str(path)).tets) != len(first.tets)
    n = len(os.listdir(tmp_path / "cache" / "parsed"))
    bad = tmp_path / "bad.msh"
    text = open(parts["cube"]).read()
    bad.write_text(text.replace("$Nodes", "$Nodes\n", 1)[: len(text) // 2])      # truncated
    with pytest.raises(Exception):
        read.read_mesh(str(bad))
    assert len(os.listdir(tmp_path / "cache" / "parsed")) == n


def test_the_parsed_mesh_cache_stays_bounded(parts, tmp_path, monkeypatch):
    """Past PARSED_KEPT[0] files the least recently used go, down to PARSED_KEPT[1]; a read refreshes a file."""
    import shutil
    import time
    from hyperelastic.mesh import read
    monkeypatch.setenv("HYPERELASTIC_MESH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(read, "PARSED_KEPT", (3, 2))
    paths = []
    for i in range(3):
        paths.append(tmp_path / f"m{i}.msh")
        shutil.copy(parts["cube"], paths[-1])
        read.read_mesh(str(paths[-1]))
        time.sleep(0.01)
    read.read_mesh(str(paths[0]))                    # the oldest, read again: now the most recent
    cache = tmp_path / "cache" / "parsed"
    assert len(os.listdir(cache)) == 3
    shutil.copy(parts["cube"], tmp_path / "m3.msh")
    read.read_mesh(str(tmp_path / "m3.msh"))         # a fourth: down to two, m0 and m3 kept
    kept = sorted(os.listdir(cache))
    assert len(kept) == 2 and os.path.basename(read._parsed_path(str(paths[0]))) in kept


EMPTY_GROUPS = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1000, 200, 100};
e = 1e-9;
Physical Surface("clamp", 1) = Surface In BoundingBox{-e, -e, -e, e, 200 + e, 100 + e};
Physical Surface("load", 2) = Surface In BoundingBox{1000.001 - e, -e, -e, 1000.001 + e, 200 + e, 100 + e};
Physical Surface("top", 4) = Surface In BoundingBox{-1, -1, 99, 1001, 201, 101};
Physical Volume("solid", 3) = {1};
"""


def test_mesh_lists_its_groups_and_names_the_empty_ones(tmp_path):
    """Issue 70 item 6: `mesh` lists every physical group it wrote, and warns by name (one line each, on stderr) of a
    group the .geo declares that caught nothing (a bounding-box tolerance of 1e-9 on a part 1,000 units across:
    gmsh writes no such group, and a run naming it failed only later); the mesh is still written (exit 0)."""
    (tmp_path / "p.geo").write_text(EMPTY_GROUPS)
    p = run_ok(["mesh", tmp_path / "p.geo", "--size", 100, "-o", tmp_path / "p.msh"])
    assert "physical groups written: top (surface), solid (volume)" in p.stdout, p.stdout
    warnings = [ln for ln in p.stderr.splitlines() if ln.startswith("warning:")]
    assert [w.split("'")[1] for w in warnings] == ["clamp", "load"], p.stderr
    assert all("BoundingBox" in w and "1.02e+03 across" in w for w in warnings)
    assert (tmp_path / "p.msh").stat().st_size > 0


def test_help_shows_the_presets_values_and_quiet_keeps_the_notes(tmp_path):
    """Issue 70 item 6: `-help` after `-preset rubber` shows the values the preset sets (and the constants that follow
    from them), not the defaults; `-quiet` silences the start-up report and the forces table but not a note (the
    warning that linear tetrahedra lock)."""
    p = run_ok(["run", "bend", "-preset", "rubber", "-material", "neohookean_split", "-help"])
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("  -E -nu -rho")][0]
    assert "E=1e+07 (-preset rubber)" in line and "nu=0.4995 (-preset rubber)" in line, line
    assert "kappa=3.33333e+09 (-preset rubber)" in p.stdout
    q = run_ok(["run", "bend", "-preset", "rubber", "-material", "neohookean_split", "-final_time", 0.02, "-quiet",
                "-output", tmp_path / "q.h5"])
    assert "note: nearly incompressible" in q.stderr and "linear tetrahedra lock" in q.stderr
    assert "part:" not in q.stderr and "forces at" not in q.stderr and "wrote" not in q.stderr

