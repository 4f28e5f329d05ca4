"""The effects added through their declarations (issue 31): elastic support (spring), a total force on a
surface, a body force per region; the rule by which effects switch on; the two new materials in runs.
Each new effect's tangent and potential are checked with the others in test_operators.py and
test_objective.py; here: what it does to a part, every Jacobian mode, both integrators, a restart, 2 ranks."""
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, make_model, read_h5, run_ok
from hyperelastic.output.plot import boundary_faces

# a bar [-5,5] x [-2,2] x [-2,2], linear, quasi-static: every answer is a linear solve
QUASI = ["-material", "linear", "-quasistatic", "-dt", 0.5, "-final_time", 1, "-snes_rtol", 1e-12, "-snes_atol",
         1e-10, "-ksp_rtol", 1e-13, "-quiet"]


def face_integral(points, tets, u, on_face):
    """(int_S u dA, area of S) over the boundary triangles whose vertices all satisfy on_face (P1)."""
    tri = boundary_faces(tets)
    tri = tri[on_face(points[tri]).all(axis=1)]
    a = 0.5 * np.linalg.norm(np.cross(points[tri[:, 1]] - points[tri[:, 0]], points[tri[:, 2]] - points[tri[:, 0]]),
                             axis=1)
    return (a[:, None] * u[tri].mean(axis=1)).sum(axis=0), a.sum()


def test_spring_foundation_carries_the_weight(tmp_path):
    """A block on an elastic foundation (springs on its bottom face, no clamp) under gravity: the springs'
    total force k int u dA balances the weight rho g V exactly, so the face's mean displacement is
    -rho g V / (k A) = -rho g H / k (H = 4: the bar's height)."""
    k, rho, g = 2e5, 1000.0, 9.81
    out = tmp_path / "s.h5"
    run_ok(["run", "sag", "-effects", "elasticity", "-gravity", f"0,0,{-g}", "-spring", k, "-spring_faces", "bottom",
            "-rho", rho, *QUASI, "-output", out])
    r = read_h5(out)
    u = r["x"][-1] - r["points"]
    bottom = lambda P: np.isclose(P[..., 2], -2.0)                     # noqa: E731
    integral, area = face_integral(r["points"], r["tetra"], u, bottom)
    assert area == pytest.approx(40.0, rel=1e-12)
    assert integral[2] / area == pytest.approx(-rho * g * 4.0 / k, rel=1e-9)
    assert abs(integral[0]) + abs(integral[1]) <= 1e-9 * abs(integral[2])
    assert r["attrs"]["effects"] == "elasticity,gravity,spring"


def test_stiff_springs_approach_the_clamp(tmp_path):
    """Springs in every component on the left end, k -> infinity: the clamped cantilever's deflection."""
    tip = {}
    for name, hold in (("clamp", ["-fix", "left"]), ("spring", ["-spring", 1e11, "-spring_faces", "left"])):
        out = tmp_path / f"{name}.h5"
        run_ok(["run", "bend", "-effects", "elasticity", "-traction", "0,-5000,0", *hold, *QUASI, "-output", out])
        r = read_h5(out)
        tip[name] = (r["x"][-1] - r["points"])[:, 1].min()
    assert tip["clamp"] < -1e-2
    assert tip["spring"] == pytest.approx(tip["clamp"], rel=1e-4)


def test_spring_components(tmp_path):
    """-spring_faces left:x holds x only (rollers hold y and z): with nu = 0 the answer is the uniaxial
    one: the left end moves by P / k (the springs' stretch) and the right end P L / E further."""
    P, k, E = 1e3, 1e6, 1e6
    out = tmp_path / "u.h5"
    run_ok(["run", "bend", "-effects", "elasticity", "-traction", f"{P},0,0", "-traction_face", "right",
            "-spring", k, "-spring_faces", "left:x", "-fix", "front:y,bottom:z", "-nu", 0, "-E", E, *QUASI,
            "-output", out])
    r = read_h5(out)
    u = r["x"][-1] - r["points"]
    right = np.isclose(r["points"][:, 0], 5.0)
    left = np.isclose(r["points"][:, 0], -5.0)
    assert np.allclose(u[left, 0], P / k, rtol=1e-9)
    assert np.allclose(u[right, 0], P / k + P * 10.0 / E, rtol=1e-9)


def test_force_resultant_and_traction_equivalent(tmp_path, petsc):
    """-force F on a face is the traction F / area: its residual sums to -F, and a run equals the run with
    -traction F/A (to rounding: the area is summed over the ranks' triangles)."""
    F = np.array([0.0, -300.0, 120.0])
    m = make_model(petsc, "bend", [("effects", "elasticity,inertia,fixed,force"), ("fix", "left"),
                                   ("force", ",".join(map(str, F))), ("force_faces", "right")])
    force = [e for e in m.system.effects if e.name == "force"][0]
    r = np.zeros(3 * m.space.nlv)
    force.residual(m.x0, r)
    total = m.space.mpi.allreduce(r.reshape(-1, 3)[m.space.owned].sum(axis=0))
    assert np.allclose(total, -F, rtol=1e-13, atol=1e-12 * np.abs(F).max())
    assert force.area == pytest.approx(16.0, rel=1e-13)
    runs = {}
    for name, load in (("force", ["-force", ",".join(map(str, F)), "-force_faces", "right"]),
                       ("traction", ["-traction", ",".join(map(str, F / 16.0)), "-traction_face", "right"])):
        out = tmp_path / f"{name}.h5"
        run_ok(["run", "bend", "-effects", "elasticity,inertia,fixed", "-fix", "left", *load, "-final_time", 0.05,
                "-quiet", "-output", out])
        runs[name] = read_h5(out)["x"]
    assert np.abs(runs["force"] - runs["traction"]).max() <= 1e-12 * np.abs(runs["traction"]).max()


@pytest.fixture(scope="module")
def bimaterial(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("bimaterial") / "bimaterial.msh")
    run_ok(["mesh", f"{ROOT}/examples/bimaterial.geo", "--size", 0.25, "-o", path])
    return path


def test_body_force_on_a_region(petsc, bimaterial, tmp_path):
    """-body_force b -body_force_regions soft acts on the soft half only: its resultant is b V_soft; a run
    with it on both regions equals gravity with rho g = b (same density everywhere)."""
    b = np.array([0.0, -2000.0, 0.0])
    m = make_model(petsc, f"{ROOT}/examples/bimaterial.opts", [
        ("mesh", bimaterial), ("body_force", ",".join(map(str, b))), ("body_force_regions", "soft")])
    e = [e for e in m.system.effects if e.name == "body_force"][0]
    r = np.zeros(3 * m.space.nlv)
    e.add_constant(r)
    total = m.space.mpi.allreduce(r.reshape(-1, 3)[m.space.owned].sum(axis=0))
    assert np.allclose(total, -b * 0.0625, rtol=1e-12)                 # the soft half: 1 x 0.25 x 0.25
    common = ["-quasistatic", "0", "-final_time", 0.05, "-dt", 0.01, "-soft_rho", 1000, "-stiff_rho", 1000, "-quiet",
              "-mesh", bimaterial]
    out1, out2 = tmp_path / "b.h5", tmp_path / "g.h5"
    run_ok(["run", f"{ROOT}/examples/bimaterial.opts", *common, "-body_force", "0,-2000,0", "-body_force_regions",
            "soft,stiff", "-output", out1])
    run_ok(["run", f"{ROOT}/examples/bimaterial.opts", *common, "-gravity", "0,-2,0", "-output", out2])
    x1, x2 = read_h5(out1)["x"], read_h5(out2)["x"]
    assert np.abs(x1[-1] - x1[0]).max() > 1e-5
    assert np.abs(x1 - x2).max() <= 1e-12 * np.abs(x2).max()


# all three new effects at once, on a free bar: springs hold its left end, a force pulls its right end
# sideways and a body force pushes it down
NEW = ["bend", "-effects", "elasticity,inertia,damping", "-spring", 5e5, "-spring_faces", "left",
       "-force", "0,-2000,500", "-force_faces", "right", "-body_force", "0,0,-300", "-final_time", 0.1,
       "-snes_rtol", 1e-10, "-snes_atol", 1e-9, "-ksp_rtol", 1e-12, "-quiet"]


@pytest.fixture(scope="module")
def new_reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("new") / "ref.h5"
    run_ok(["run", *NEW, "-output", out])
    return read_h5(out)


@pytest.mark.parametrize("mode", [["-jacobian", "shell"], ["-snes_mf_operator", "-ksp_type", "gmres"],
                                  ["-snes_mf", "-ksp_type", "gmres", "-ksp_max_it", 2000],
                                  ["-assembly", "coo"], ["-options_file", f"{ROOT}/options/gamg.opts"], ["np2"]])
def test_new_effects_in_every_jacobian_mode(tmp_path, new_reference, mode):
    out = tmp_path / "m.h5"
    nprocs = 2 if mode == ["np2"] else 1
    run_ok(["run", *NEW, *([] if nprocs == 2 else mode), "-output", out], nprocs=nprocs)
    r, ref = read_h5(out), new_reference
    move = np.abs(ref["x"][-1] - ref["x"][0]).max()
    assert move > 1e-3
    assert np.abs(r["x"] - ref["x"]).max() <= 1e-6 * move
    assert {"spring", "force", "body_force"} <= set(r["attrs"]["effects"].split(","))
    assert "spring_energy" in r["stats"] and "body_force_work" in r["stats"]


def test_new_effects_under_ts_and_restart(tmp_path):
    """generalized-alpha runs them; a run continued from its checkpoint equals the run made at once."""
    common = [*NEW, "-integrator", "ts", "-checkpoint_every", 4]
    run_ok(["run", *common, "-output", tmp_path / "a.h5"])
    run_ok(["run", "--restart", tmp_path / "a.h5", "-final_time", 0.15])
    run_ok(["run", *common, "-final_time", 0.15, "-output", tmp_path / "b.h5"])
    a, b = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    assert np.array_equal(a["x"], b["x"]) and np.array_equal(a["stats"]["spring_energy"], b["stats"]["spring_energy"])
    tot = b["stats"]["energy_total"]
    assert np.isfinite(tot).all()


def test_effects_rule(tmp_path):
    """A command-line -effects replaces the scene file's: the scene's -traction no longer loads the bar
    beside the command line's named load (a note names what was ignored); command-line options add their
    effects to the scene file's list; an option of an effect that is not on is one error line."""
    scene = tmp_path / "cook.opts"
    scene.write_text("-effects elasticity,fixed,traction\n-fix left\n-traction 0,100,0\n-traction_face right\n"
                     "-quasistatic\n-dt 1\n-final_time 1\n-material linear\n")
    out = tmp_path / "o.h5"
    p = run_ok(["run", scene, "-effects", "elasticity,fixed,loads", "-loads", "L1", "-L1_traction", "0,100,0",
                "-L1_faces", "right", "-output", out])
    assert "note: -effects elasticity,fixed,loads on the command line replaces the scene file's effects: " \
           "ignored its -traction -traction_face" in p.stderr
    r = read_h5(out)
    assert r["attrs"]["effects"] == "elasticity,fixed,loads" and '"traction": 1' in r["attrs"]["effects_built"]
    single = tmp_path / "single.h5"
    run_ok(["run", scene, "-output", single, "-quiet"])
    assert np.abs(r["x"] - read_h5(single)["x"]).max() <= 1e-12     # the same load once, not twice
    run_ok(["run", scene, "-gravity", "0,0,-1", "-output", out, "-quiet"])
    assert read_h5(out)["attrs"]["effects"] == "elasticity,fixed,traction,gravity"
    p = hyperelastic(["run", scene, "-effects", "elasticity,fixed", "-pressure_faces", "top", "-output", out])
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        "hyperelastic: error: option -pressure_faces: an option of effect 'pressure', which scene 'cook' does not "
        "switch on (give its main option, or list it in -effects)"]


@pytest.mark.parametrize("material,extra", [("mooney_rivlin", ["-C01", 1e5]), ("neohookean_split", ["-kappa", 5e6])])
def test_new_materials_run(tmp_path, material, extra):
    out = tmp_path / "m.h5"
    run_ok(["run", "bend2", "-material", material, *extra, "-final_time", 0.2, "-quiet", "-output", out])
    r = read_h5(out)
    assert np.abs(r["x"][-1] - r["x"][0]).max() > 1e-2
    assert r["attrs"]["material"] == material and np.all(r["stats"]["J_min"] > 0)


@pytest.mark.parametrize("args,words", [
    (["-C01", 1e5], "option -C01: a constant of mooney_rivlin, not of this scene's stvk"),
    (["-material", "neohookean_split", "-kappa", -1], "-kappa -1 must be > 0 (bulk modulus)"),
    (["-material", "mooney_rivlin", "-C10", 0, "-C01", 0], "mooney_rivlin needs C10 + C01 > 0"),
    (["-material", "mooney_rivlin", "-C01", 4e5], "C10 = -207692 (from μ/2 − C01"),
    (["-spring", -3, "-spring_faces", "left"], "option -spring: -3 must be > 0"),
    (["-force", "1,2", "-force_faces", "left"], "option -force: '1,2' is not a list of 3 finite numbers"),
    (["-body_force", "0,0,1", "-body_force_regions", "nosuch"], "has no volume 'nosuch'"),
    (["-loads", "a", "-a_force", "1,0,0", "-a_spring", "1", "-a_faces", "right"], "not -a_force and -a_spring"),
    (["-loads", "a", "-a_spring", "1e3", "-a_faces", "right", "-a_ramp", "1"], "a spring has no time function"),
])
def test_bad_new_options_are_one_line(tmp_path, args, words):
    out = tmp_path / "o.h5"
    p = hyperelastic(["run", "bend", "-quiet", "-output", out, *args])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and words in lines[0], p.stderr
    assert not out.exists()


def test_new_materials_per_region(bimaterial, tmp_path):
    """Each region its own material and constants (-soft_kappa, -stiff_C01): read from the declarations,
    printed in the set report and recorded in the output; a constant for a region whose material lacks it
    is one error line."""
    import json
    out = tmp_path / "r.h5"
    p = run_ok(["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bimaterial, "-soft_material", "neohookean_split",
                "-soft_kappa", 2e6, "-stiff_material", "mooney_rivlin", "-stiff_C01", 3e5, "-output", out])
    assert "neohookean_split, E 1e+06, nu 0, mu 500000, kappa 2e+06, rho 1100" in p.stderr
    assert "mooney_rivlin, E 4e+06, nu 0, C10 700000, C01 300000, kappa 1.33333e+06, rho 7800" in p.stderr
    r = read_h5(out)
    regions = {d["name"]: d for d in json.loads(r["attrs"]["regions"])}
    assert regions["soft"]["kappa"] == 2e6 and regions["stiff"]["C01"] == 3e5 and regions["stiff"]["C10"] == 7e5
    assert np.abs(r["x"][-1] - r["x"][0]).max() > 1e-3
    p = hyperelastic(["run", f"{ROOT}/examples/bimaterial.opts", "-mesh", bimaterial, "-soft_C01", 1,
                      "-output", tmp_path / "o.h5"])
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        "hyperelastic: error: option -soft_C01: a constant of mooney_rivlin, not of region 'soft''s neohookean"]


@pytest.mark.parametrize("case", ["damped", "projected", "quadratic", "regions"])
def test_cell_blocks_written_by_the_first_effect_equal_the_sum(petsc, bimaterial, case):
    """The Jacobian's cell blocks (effects.base.cell_blocks): the first effect writes its blocks over whatever the
    buffer held, the others add theirs; every entry equals the sum added to zeros, for the whole range and for a
    ragged chunk: P1 with inertia and Rayleigh damping, the projected tangent, P2, a material per region."""
    from hyperelastic.physics.effects.base import cell_blocks
    scene, options = {"damped": ("bend", [("rayleigh_alpha", "0.5"), ("rayleigh_beta", "1e-3")]),
                      "projected": ("bend", [("material", "snh"), ("hessian_projection", "")]),
                      "quadratic": ("bend", [("order", "2")]),
                      "regions": (f"{ROOT}/examples/bimaterial.opts", [("mesh", bimaterial), ("quasistatic", "0")])}[case]
    m = make_model(petsc, scene, options)
    system = m.system
    rng = np.random.default_rng(3)
    system.begin_step(0.1, m.scene.dt, m.x0, m.v0)
    system.linearize(system.global_state(m.x0 + 0.02 * rng.standard_normal(m.x0.shape)))
    effects = [e for e in system.effects if e.cell_blocks]
    assert len(effects) >= 2 and effects[0].name == "elasticity"
    nc = system.space.cells.shape[0]
    n3 = 3 * system.space.cells.shape[1]
    for lo, hi in ((0, nc), (7, nc // 2 + 3)):
        want = np.zeros((hi - lo, n3, n3))
        for e in effects:
            e.add_cell_blocks(want, lo, hi)
        got = np.full((hi - lo, n3, n3), np.nan)
        cell_blocks(effects, got, lo, hi)
        assert np.array_equal(got, want), case
