"""What a converged solve must also be before its state is accepted (issue 47: a quasi-static step of a rubber at
kappa/mu = 1e4 was accepted at J_min 0.107, J_max 2.05 and every later step failed): no cell inverted in a material
undefined there, and volume ratios a solid of its compressibility keeps (integrators.volume_refusal,
formulations.mixed.volume_bound)."""
from types import SimpleNamespace

import numpy as np

from conftest import hyperelastic, read_h5


def test_volume_refusal_follows_the_compressibility():
    from hyperelastic.solving.integrators import volume_refusal
    rubber = SimpleNamespace(check_domain=True, volume_bound=(max(0.5, 1000 / 1e4), 1e4))
    soft = SimpleNamespace(check_domain=True, volume_bound=(1000 / 2.17, 2.17))
    stvk = SimpleNamespace(check_domain=False, volume_bound=(0.5, 1e4))
    assert volume_refusal({"J_min": 0.99, "J_max": 1.011}, rubber) == ""          # the rod's coarse P2 mesh
    assert "false convergence" in volume_refusal({"J_min": 0.107, "J_max": 2.05}, rubber)   # the step
    assert volume_refusal({"J_min": 0.107, "J_max": 2.05}, soft) == ""           # nu = 0.3 may be squeezed so
    assert "inverted" in volume_refusal({"J_min": -0.5, "J_max": 1.2}, soft)
    assert volume_refusal({"J_min": -0.5, "J_max": 1.2}, stvk) == ""             # defined when inverted
    assert volume_refusal({}, rubber) == ""                                        # no elasticity, no J


def test_a_false_convergence_is_not_accepted(tmp_path):
    """One linear solve per step (-snes_type ksponly: SNES reports convergence after it) of a nearly incompressible
    bar whose end is turned 86 degrees: the steps whose linearized rotation inverts cells or changes their volume
    by far more than kappa/mu = 5000 allows are refused and halved, every accepted state keeps |ln J| <= 0.5, and the
    run ends with the one line that says why rather than writing such states."""
    out = tmp_path / "ks.h5"
    p = hyperelastic(["run", "bend", "-effects", "elasticity,fixed,prescribed", "-fix", "left", "-prescribe_faces",
                      "right", "-prescribe_motion", "rotate_x", "-prescribe_amount", 1.5, "-material", "neohookean",
                      "-nu", 0.4999, "-quasistatic", "-snes_type", "ksponly", "-dt", 1, "-final_time", 1,
                      "-output", out, "-quiet"])
    st = read_h5(out)["stats"]
    ok = st["rejected"] == 0
    assert ok.any() and (st["J_min"][ok] > 0).all()
    assert (np.maximum(-np.log(st["J_min"][ok]), np.log(st["J_max"][ok])) <= 0.5).all()
    bad = ~ok & (st["snes_reason"] > 0)
    assert bad.any() and ((st["J_min"][bad] <= 0) | (np.maximum(-np.log(np.abs(st["J_min"][bad])),
                                                               np.log(st["J_max"][bad])) > 0.5)).all()
    lines = p.stderr.strip().splitlines()
    assert p.returncode != 0 and len(lines) == 1 and "not a solution" in lines[0], p.stderr
