"""Forces on the body at the end of a run (issue 34, forces.py): the reaction of each constrained surface
and the resultant of each load balance — reactions + loads + inertia + damping = 0 to the solver's
tolerance — statically on the bracket (P1 and P2, 1 and 2 ranks) and dynamically on the bar."""
import json

import h5py
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, run_ok


def forces(path):
    with h5py.File(path, "r") as f:
        rec = json.loads(f.attrs["forces"])
    return rec["t"], {(r["kind"], r["name"]): (np.array(r["F"]), np.array(r["M"])) for r in rec["forces"]}


@pytest.fixture(scope="module")
def bracket_mesh(tmp_path_factory):
    m = tmp_path_factory.mktemp("forces") / "bracket.msh"
    run_ok(["mesh", f"{ROOT}/examples/bracket.geo", "--size", 0.01, "-o", m])
    return m


@pytest.mark.parametrize("order,nprocs", [(1, 1), (1, 2), (2, 1)])
def test_bracket_reaction_balances_the_load(tmp_path, bracket_mesh, order, nprocs):
    out = tmp_path / "b.h5"
    p = hyperelastic(["run", f"{ROOT}/examples/bracket.opts", "-mesh", bracket_mesh, "-order", order, "-output", out,
                      "-options_file", f"{ROOT}/options/gamg.opts", "-snes_rtol", "1e-10", "-ksp_rtol", "1e-12"],
                     nprocs=nprocs)
    assert p.returncode == 0, p.stderr
    t, F = forces(out)
    assert t == 1.0 and set(F) == {("reaction", "clamp"), ("load", "traction")}
    (Fr, Mr), (Fl, Ml) = F[("reaction", "clamp")], F[("load", "traction")]
    with h5py.File(out, "r") as f:
        area = [s["measure"] for s in json.loads(f.attrs["sets"]) if s["name"] == "load"][0]
    assert np.allclose(Fl, [0, 0, -2e5 * area], rtol=1e-12, atol=1e-9)        # the dead traction's resultant
    assert np.abs(Fr + Fl).max() <= 1e-6 * np.abs(Fl).max()                     # equilibrium of forces
    assert np.abs(Mr + Ml).max() <= 1e-6 * np.abs(Ml).max()                     # and of moments
    assert "reaction clamp: F = (" in p.stderr and "sum: F = (" in p.stderr


def test_dynamic_balance_includes_inertia_and_damping(tmp_path):
    out = tmp_path / "d.h5"
    run_ok(["run", "bend", "-level", 2, "-final_time", 0.1, "-snes_rtol", "1e-10", "-ksp_rtol", "1e-12", "-quiet",
            "-output", out])
    _, F = forces(out)
    assert set(F) == {("reaction", "left"), ("load", "inertia"), ("load", "damping"), ("load", "traction")}
    total = sum(f for f, _ in F.values())
    big = max(np.abs(f).max() for f, _ in F.values())
    assert np.abs(total).max() <= 1e-8 * big and np.abs(F[("load", "inertia")][0]).max() > 0.1 * big
