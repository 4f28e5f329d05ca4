"""Rigid faces (-rigid S, physics/effects/rigid.py, solving/rigid.py; issue 47): a face moved through its reference point
equals the same motion prescribed node by node; a face loaded by a torque or a force turns or moves until its reaction
equals the load — the prescribed run's answer again, and Rivlin's closed form for the twisted rubber rod; restarts are
bitwise, 2 ranks agree; bad input is one line."""
import json
import math
import os

import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok

MU, A, L = 5e5, 0.01, 0.04
ROD = ["-material", "neohookean_split", "-mu", MU, "-kappa", 5e9, "-quasistatic", "-dt", 0.25, "-final_time", 1,
       "-quiet"]


@pytest.fixture(scope="module")
def rod(tmp_path_factory):
    path = tmp_path_factory.mktemp("rod") / "rod.msh"
    run_ok(["mesh", os.path.join(ROOT, "examples", "rod.geo"), "--size", 0.005, "--order", 2, "-o", path])
    return path


def forces(out):
    """{name: row} of the output's end-of-run forces table."""
    return {r["name"]: r for r in json.loads(out["attrs"]["forces"])["forces"]}


def scene(tmp_path):
    """The rod clamped at its bottom, its top a rigid face (its motion or load given on the command line)."""
    path = tmp_path / "rigid.opts"
    path.write_text("-effects elasticity,fixed,rigid\n-fix bottom\n-rigid top\n")
    return path


def test_rotation_and_its_left_jacobian():
    """R = exp([theta]x) is a rotation, R(theta e_z) turns by |theta| about z, and d exp = [J_l dtheta]x exp
    (central differences), also near theta = 0 where the series are used."""
    from hyperelastic.physics.effects.rigid import left_jacobian, rotation, skew
    rng = np.random.default_rng(3)
    for theta in (rng.normal(size=3), 1e-6 * rng.normal(size=3), np.zeros(3), np.array([0, 0, 2.5])):
        R = rotation(theta)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-14) and abs(np.linalg.det(R) - 1) < 1e-14
        for k in range(3):
            e, h = np.eye(3)[k], 1e-6
            dR = (rotation(theta + h * e) - rotation(theta - h * e)) / (2 * h)
            assert np.allclose(dR, skew(left_jacobian(theta) @ e) @ R, atol=1e-8)
    c, s = math.cos(2.5), math.sin(2.5)
    assert np.allclose(rotation(np.array([0, 0, 2.5])), [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-15)


def test_torsion_by_a_rigid_face(rod, tmp_path):
    """Rivlin's torsion (the README's walkthrough, 588 curved P2 tets, mixed, kappa/mu = 1e4): the top turned by
    -rigid_rz equals the same turn prescribed node by node (torque and axial force to 1e-9); driven by the torque that
    run measured, the face turns by the prescribed angle (to the balance's tolerance) and by Rivlin's
    psi = 2 M L / (pi mu a^4) to the mesh's accuracy; the forces balance; the rigid_* columns and the end line."""
    pres, turn, torque = (tmp_path / f"{n}.h5" for n in ("pres", "turn", "torque"))
    run_ok(["run", os.path.join(ROOT, "examples", "torsion.opts"), "-mesh", rod, "-output", pres, *ROD])
    base = ["run", scene(tmp_path), "-mesh", rod, *ROD]
    run_ok(base + ["-rigid_rz", "pi/2*t", "-output", turn])
    a, b = read_h5(pres), read_h5(turn)
    Fa, Fb = forces(a), forces(b)
    M, N = Fa["top"]["M"][2], Fa["top"]["F"][2]
    assert abs(Fb["top"]["M"][2] - M) < 1e-9 * abs(M) and abs(Fb["top"]["F"][2] - N) < 1e-9 * abs(N)
    sb = b["stats"]
    ok = sb["rejected"] == 0
    assert np.allclose(sb["rigid_rz"][ok], np.pi / 2 * sb["time"][ok]) and "rigid_its" not in sb
    assert abs(sb["rigid_Mz"][-1] - M) < 1e-9 * abs(M)          # (about the point (0, 0, L): the torque itself)
    run_ok(base[:-1] + ["-rigid_mz", f"{float(M)!r}*t", "-output", torque])
    c = read_h5(torque)
    st = c["stats"]
    psi = st["rigid_rz"][-1]
    assert abs(psi - np.pi / 2) < 1e-6, psi
    assert abs(st["rigid_Mz"][-1] - M) < 1e-7 * abs(M) and st["rigid_its"].max() >= 1
    assert abs(psi / (2 * M * L / (np.pi * MU * A ** 4)) - 1) < 2e-3
    assert np.abs(c["x"][-1] - a["x"][-1]).max() < 1e-6 * A
    rec = json.loads(c["attrs"]["rigid"])
    assert rec["surface"] == "top" and np.allclose(rec["point"], [0, 0, L], atol=1e-12)
    assert abs(rec["rotation"][2] - psi) < 1e-12 and abs(rec["M"][2] - M) < 1e-7 * abs(M)
    assert np.linalg.norm(forces(c)["all_held"]["F"]) < 1e-8 * abs(N)   # (every held row: they balance)


def test_a_loaded_face_restarts_bitwise_and_two_ranks_agree(rod, tmp_path):
    """A torque-driven run stopped at t = 0.5 and restarted (the point's motion and rate from the checkpoint) ends
    bitwise where the uninterrupted run does; 2 ranks turn the face by the same angle (to the balance's tolerance)."""
    base = ["run", scene(tmp_path), "-mesh", rod, "-rigid_mz", "0.3*t", *ROD, "-checkpoint_every", 1]
    whole, half, two = (tmp_path / f"{n}.h5" for n in ("whole", "half", "two"))
    run_ok(base + ["-output", whole])
    run_ok(base[:-5] + ["-final_time", 0.5, "-quiet", "-checkpoint_every", 1, "-output", half])
    run_ok(["run", "--restart", half, "-final_time", 1, "-quiet"])
    a, b = read_h5(whole), read_h5(half)
    assert np.array_equal(a["x"][-1], b["x"][-1])
    assert np.array_equal(a["stats"]["rigid_rz"], b["stats"]["rigid_rz"])
    run_ok(base + ["-output", two], nprocs=2)
    c = read_h5(two)
    assert abs(c["stats"]["rigid_rz"][-1] - a["stats"]["rigid_rz"][-1]) < 1e-7 * a["stats"]["rigid_rz"][-1]


def test_a_face_pulled_by_a_force_moves_as_when_moved(tmp_path):
    """The built-in bar (P1, neo-Hookean, quasi-static) with its right end rigid: moved by -rigid_ux it needs a force
    F_x and (the mesh is not symmetric) a moment M_y; pulled by that force and turned by that moment (two free
    components, balanced together) it moves by the same amount and does not turn."""
    common = ["run", "bend", "-effects", "elasticity,fixed,rigid", "-fix", "left", "-rigid", "right",
              "-material", "neohookean", "-quasistatic", "-dt", 0.5, "-final_time", 1, "-quiet"]
    moved, pulled = tmp_path / "moved.h5", tmp_path / "pulled.h5"
    run_ok(common + ["-rigid_ux", "0.002*t", "-output", moved])
    sm = read_h5(moved)["stats"]
    F, My = float(sm["rigid_Fx"][-1]), float(sm["rigid_My"][-1])
    assert F > 0 and My != 0
    run_ok(common + ["-rigid_fx", f"{F!r}*t", "-rigid_my", f"{My!r}*t", "-output", pulled])
    st = read_h5(pulled)["stats"]
    assert abs(st["rigid_ux"][-1] - 0.002) < 1e-6 * 0.002 and abs(st["rigid_ry"][-1]) < 1e-9
    assert abs(st["rigid_Fx"][-1] - F) < 1e-7 * F and st["rigid_its"].max() >= 1


@pytest.mark.parametrize("args, says", [
    (["-rigid", "right", "-rigid_ux", "t", "-rigid_fx", 1], "either moved or loaded, not both"),
    (["-rigid", "right,top"], "one surface (the rigid face), not 2"),
    (["-rigid", "right", "-rigid_rz", "t*"], "option -rigid_rz"),
    (["-rigid", "right", "-rigid_point", "1,2"], "option -rigid_point"),
    (["-rigid", "right", "-rigid_rtol", -1], "option -rigid_rtol"),
    (["-rigid", "right", "-rigid_mz", 1, "-integrator", "ts", "-effects", "elasticity,inertia,fixed,rigid"],
     "-integrator ts: a rigid face with loads"),
    (["-rigid", "left"], "options -fix and -rigid hold the same components"),
    (["-rigid", "nowhere"], "nowhere"),
])
def test_bad_rigid_input_is_one_line(args, says, tmp_path):
    out = tmp_path / "bad.h5"
    steps = [] if "-integrator" in args else ["-effects", "elasticity,fixed,rigid", "-quasistatic"]
    p = hyperelastic(["run", "bend", "-fix", "left", *steps, "-final_time", 0.1, "-dt", 0.1, "-output", out, *args])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and says in lines[0], p.stderr
    assert not out.exists()
