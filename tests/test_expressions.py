"""Expressions of time and reference coordinates (prescribed motion per component, load time
functions) and loads on any number of sets, each with its own time function (issue 14)."""
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok

VARS = ("t", "X", "Y", "Z", "A")


def test_expression_values_vectorized():
    from hyperelastic.core.expressions import Expression, TimeFunction
    X = np.linspace(0, 1, 5)
    e = Expression("cos(A*min(t, 1))*X - sin(A*min(t, 1))*Y", VARS)
    assert np.array_equal(e(t=0.3, X=X, Y=2 * X, Z=X, A=2.0), np.cos(0.6) * X - np.sin(0.6) * (2 * X))
    e = Expression("where(X > 0.5, 1, -1) + (2 if t >= 1 and not t > 3 else 0) + 7 % 4 + 2**-1 + pi - e", VARS)
    assert np.allclose(e(t=2.0, X=X, Y=X, Z=X, A=1), np.where(X > 0.5, 1, -1) + 2 + 3 + 0.5 + np.pi - np.e)
    assert np.allclose(Expression("0 < X <= 0.5", VARS)(t=0, X=X, Y=X, Z=X, A=1), (X > 0) & (X <= 0.5))
    assert TimeFunction("min(t/0.5, 1)", "f")(0.25) == 0.5


@pytest.mark.parametrize("text, words", [
    ("__import__('os').system('true')", ["is not a known function"]), ("__import__('os')", ["'__import__' is not"]),
    ("X.real", ["not allowed"]), ("[1, 2]", ["not allowed"]), ("'a'", ["not a number"]),
    ("lambda: 1", ["not allowed"]), ("(lambda: 1)()", ["not a known function"]), ("sin(X, Y)", ["takes 1 argument"]),
    ("min(X)", ["takes 2 arguments"]), ("sin(x=1)", ["plain arguments"]), ("W * t", ["unknown name 'W'"]),
    ("X +", ["not an expression"]), ("", ["empty"]), ("1e999 * t", ["not finite"]), ("9" * 400, ["not finite"]),
    ("X // 2", ["not allowed"]), ("X @ Y", ["not allowed"]), ("X is Y", ["not allowed"]), ("True", ["not a number"]),
    ("(" * 300 + "t" + ")" * 300, []), ("-" * 5000 + "t", ["longer than"]), ("t; 1", ["not an expression"]),
])
def test_expression_refuses_anything_else(text, words):
    from hyperelastic.core.errors import UserError
    from hyperelastic.core.expressions import Expression
    with pytest.raises(UserError) as e:
        Expression(text, VARS, "option -prescribe_ux")(t=0.5, X=np.ones(2), Y=np.ones(2), Z=np.ones(2), A=1.0)
    msg = str(e.value)
    assert msg.startswith("option -prescribe_ux: ") and "\n" not in msg
    assert all(w in msg for w in words), msg


def test_non_finite_value_names_the_time():
    from hyperelastic.core.errors import UserError
    from hyperelastic.core.expressions import Expression
    with pytest.raises(UserError, match="not finite at t=0.5"):
        Expression("1/(0.5 - t) * X", VARS, "f")(t=0.5, X=np.ones(3), Y=0, Z=0, A=1)


@pytest.fixture(scope="module")
def cube(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("cube") / "cube.msh")
    run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.35, "-o", path])
    return path


def run(cube, tmp_path, name, args, nprocs=1):
    """A run on the cube of a scene that names nothing but what `args` add."""
    out, scene = tmp_path / f"{name}.h5", tmp_path / "plain.opts"
    scene.write_text("-final_time 1\n")
    run_ok(["run", scene, "-mesh", cube, "-quiet", "-output", out, "-snes_rtol", 1e-14, "-snes_atol", 1e-13,
            "-ksp_rtol", 1e-14, *args], nprocs=nprocs)
    return read_h5(out)


ROLLERS = ["-fix", "xmin:x,ymin:y,zmin:z"]


@pytest.mark.parametrize("motion, spelled", [
    ("rotate_x", ["-prescribe_y", "cos(A*min(t, 1))*Y - sin(A*min(t, 1))*Z",
                  "-prescribe_z", "sin(A*min(t, 1))*Y + cos(A*min(t, 1))*Z"]),
    ("squeeze_x", ["-prescribe_x", "X/(1 + A*min(t, 1))"]),
])
def test_presets_are_expressions(cube, tmp_path, motion, spelled):
    """A preset and the same motion written as expressions give bitwise the same trajectory."""
    base = ["-fix", "xmin", "-prescribe_faces", "xmax", "-prescribe_amount", 0.3, "-final_time", 0.1]
    a = run(cube, tmp_path, "preset", [*base, "-prescribe_motion", motion])
    b = run(cube, tmp_path, "spelled", [*base, *spelled])
    assert np.abs(a["x"][-1] - a["x"][0]).max() > 1e-3
    assert np.array_equal(a["x"], b["x"])


def test_displacement_expression_uniaxial_linear(cube, tmp_path):
    """-prescribe_ux on the x max face (x held only) with rollers: the exact uniaxial state."""
    r = run(cube, tmp_path, "ux", [*ROLLERS, "-prescribe_faces", "zmax:z", "-prescribe_uz", "0.1*min(t, 1)*Z",
                                   "-material", "linear", "-quasistatic", "-dt", 0.5, "-final_time", 1,
                                   "-effects", "elasticity"])
    X, x, nu = r["points"], r["x"][-1], 0.3
    assert np.abs(x - X * np.array([1 - nu * 0.1, 1 - nu * 0.1, 1.1])).max() < 1e-12


def test_component_not_held_is_refused(cube, tmp_path):
    p = hyperelastic(["run", "stretch", "-mesh", cube, "-fix", "xmin", "-prescribe_faces", "xmax:x",
                      "-prescribe_uy", "0.1*t", "-output", tmp_path / "o.h5"])
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    assert "-prescribe_uy: component y is not held" in p.stderr


LINEAR = [*ROLLERS, "-material", "linear", "-quasistatic", "-dt", 0.25, "-final_time", 1, "-effects", "elasticity"]


def test_load_time_function(cube, tmp_path):
    """Linear and quasi-static: the displacement follows the load's time function exactly."""
    r = run(cube, tmp_path, "tf", [*LINEAR, "-traction_face", "xmax", "-traction", "1e4,0,0",
                                   "-traction_time", "sin(pi*t/2)"])
    u = r["x"] - r["points"]
    for t, ut in zip(r["time"], u):
        assert np.abs(ut - np.sin(np.pi * t / 2) * u[-1]).max() <= 1e-12 * np.abs(u[-1]).max()
    assert np.abs(u[-1]).max() > 1e-3


def test_several_loads_superpose(cube, tmp_path):
    """-loads pull,shear: two tractions with their own surfaces and time functions; with the linear
    material the response is the sum of each alone, at every frame."""
    pull = ["-pull_traction", "1e4,0,0", "-pull_faces", "xmax", "-pull_time", "t"]
    shear = ["-shear_traction", "0,2e3,0", "-shear_faces", "zmax,5", "-shear_time", "t*t"]
    both = run(cube, tmp_path, "both", [*LINEAR, "-loads", "pull,shear", *pull, *shear])
    a = run(cube, tmp_path, "a", [*LINEAR, "-loads", "pull", *pull])
    b = run(cube, tmp_path, "b", [*LINEAR, "-loads", "shear", *shear])
    X = both["points"]
    assert np.abs((both["x"] - X) - (a["x"] - X) - (b["x"] - X)).max() <= 1e-12
    assert np.abs(b["x"][-1] - X).max() > 1e-4 and np.abs(a["x"][-1] - X).max() > 1e-3


def test_named_pressure_load_same_as_pressure_option_on_two_ranks(cube, tmp_path):
    common = ["-fix", "xmin:x,ymin:y,zmin:z", "-material", "neohookean", "-quasistatic", "-dt", 0.5,
              "-final_time", 1, "-effects", "elasticity"]
    one = run(cube, tmp_path, "p", [*common, "-pressure", 1e5, "-pressure_faces", "xmax,ymax,zmax", "-pressure_ramp", 1])
    named = run(cube, tmp_path, "n", [*common, "-loads", "p", "-p_pressure", 1e5, "-p_faces", "xmax,ymax,zmax",
                                      "-p_time", "min(t, 1)"])
    two = run(cube, tmp_path, "n2", [*common, "-loads", "p", "-p_pressure", 1e5, "-p_faces", "xmax,ymax,zmax",
                                     "-p_time", "min(t, 1)"], nprocs=2)
    assert np.array_equal(one["x"], named["x"])
    assert np.abs(named["x"] - two["x"]).max() <= 1e-8
    assert np.abs(one["x"][-1] - one["x"][0]).max() > 1e-3


@pytest.mark.parametrize("args, words", [
    (["-traction", "1,0,0", "-traction_time", "t", "-traction_ramp", "1"], ["-traction_time and -traction_ramp"]),
    (["-loads", "a", "-a_traction", "1,0,0"], ["load 'a'", "-a_faces"]),
    (["-loads", "a", "-a_faces", "xmax"], ["load 'a'", "one of -a_traction"]),
    (["-loads", "a", "-a_faces", "nosuch", "-a_pressure", "1"], ["-a_faces", "no surface 'nosuch'"]),
    (["-loads", "a", "-a_faces", "xmax", "-a_pressure", "1", "-a_time", "t*W"], ["-a_time", "unknown name 'W'"]),
    (["-loads", "a b"], ["-loads", "option prefix"]),
])
def test_bad_loads_one_line(cube, tmp_path, args, words):
    p = hyperelastic(["run", "stretch", "-mesh", cube, "-fix", "xmin", "-output", tmp_path / "o.h5", *args])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, (p.returncode, p.stderr)
    assert all(w in lines[0] for w in words), lines[0]
    assert not (tmp_path / "o.h5").exists()
