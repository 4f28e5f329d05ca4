"""p-multigrid for quadratic tetrahedra (-pc_type mg, options/pmg.opts; hyperelastic/solving/pmg.py): the P1 -> P2
interpolation is exact for P1 fields, the coarse operator is P^T A P with the rigid-body modes, and a run with it
gives the answer GAMG gives in fewer Krylov iterations, on 1 and 2 ranks."""
import os

import numpy as np
import pytest

from conftest import ROOT, make_model, read_h5, run_ok

PMG = ["-options_file", os.path.join(ROOT, "options", "pmg.opts")]
GAMG = ["-options_file", os.path.join(ROOT, "options", "gamg.opts")]


def test_interpolation_is_exact_for_linear_fields(petsc):
    """P times the vertex values of u = A X + b is u at every P2 node (vertices and edge midpoints); every row of P
    sums to 1 per component."""
    from hyperelastic.solving import pmg
    m = make_model(petsc, "bend", [("level", "2"), ("order", "2")])
    sp = m.space
    P, coords = pmg.prolongation(sp)
    A = np.array([[0.3, -0.2, 0.1], [0.05, 0.4, -0.3], [0.2, 0.1, 0.25]])
    b = np.array([0.1, -0.2, 0.3])
    uc, uf = P.createVecs()
    uc.getArray()[:] = (coords @ A.T + b).ravel()
    P.mult(uc, uf)
    want = sp.owned_array((sp.X @ A.T + b).ravel())
    assert np.abs(uf.getArray() - want).max() < 1e-13
    ones = uc.duplicate()
    ones.set(1.0)
    P.mult(ones, uf)
    assert np.allclose(uf.getArray(), 1.0, atol=1e-15)
    assert P.getBlockSizes() == (3, 3) and P.getSize() == (3 * sp.nv_total, 3 * len(coords))


CASES = (("gamg", GAMG, 1), ("pmg", PMG, 1), ("pmg2", PMG, 2))      # (name, options, ranks)


def run_cases(d, base, cases):
    """{name: the output} of the command `base` with each case's options on its rank count, written in folder d."""
    out = {}
    for name, opts, n in cases:
        path = str(d / f"{name}.h5")
        run_ok(base + opts + ["-output", path], nprocs=n)
        out[name] = read_h5(path)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The quasi-static Neo-Hookean bend2 on quadratic tetrahedra with GAMG and with p-multigrid (1 and 2 ranks)."""
    base = ["run", "bend2", "-order", "2", "-quasistatic", "-dt", "0.5", "-material", "neohookean", "-level", "3",
            "-quiet"]
    alone = ("alone", ["-pc_type", "mg", "-ksp_type", "cg"], 1)
    return run_cases(tmp_path_factory.mktemp("pmg"), base, CASES + (alone,))


def test_same_answer_as_gamg_in_fewer_iterations(runs):
    a, b, c = runs["gamg"], runs["pmg"], runs["pmg2"]
    scale = np.abs(a["x"][-1] - a["points"]).max()
    for r in (b, c):
        assert np.abs(r["x"][-1] - a["x"][-1]).max() < 1e-8 * scale
    its = {k: r["stats"]["ksp_its"].sum() / r["stats"]["newton_its"].sum() for k, r in runs.items() if k != "alone"}
    assert its["pmg"] < 0.75 * its["gamg"], its
    assert abs(its["pmg2"] - its["pmg"]) <= 0.25 * its["pmg"], its


def test_pc_type_mg_alone_is_options_pmg(runs):
    """-pc_type mg without options/pmg.opts gets its smoothers and coarse solve (pmg.DEFAULTS, the same as the file:
    PETSc's own defaults solve the P1 level directly on one rank), so the same iterates."""
    from hyperelastic.solving import pmg
    text = open(PMG[1]).read().split()
    given = {a[1:]: b for a, b in zip(text, text[1:]) if a.startswith("-mg_")}
    assert given == pmg.DEFAULTS
    a, b = runs["pmg"], runs["alone"]
    assert np.array_equal(a["stats"]["ksp_its"], b["stats"]["ksp_its"])
    assert np.abs(a["x"][-1] - b["x"][-1]).max() <= 1e-12 * np.abs(a["x"][-1]).max()


def test_under_generalized_alpha_as_under_backward_euler_s_solver(tmp_path):
    """-integrator ts with p-multigrid: the TS's SNES reads the options after the solver is made, so the levels are
    given once the TS has read them (they were not, and PCMG then asked the TS's DMShell to coarsen itself: one PETSc
    error line, no run), and PCMG's restriction of the state goes through DMs with vectors; the answer is GAMG's, in
    fewer Krylov iterations, on 1 and 2 ranks."""
    base = ["run", "bend2", "-order", "2", "-level", "2", "-integrator", "ts", "-dt", "0.01", "-final_time", "0.03",
            "-quiet", "-snes_rtol", "1e-10", "-ksp_rtol", "1e-10"]
    out = run_cases(tmp_path, base, CASES)
    a = out["gamg"]
    scale = np.abs(a["x"][-1] - a["points"]).max()
    assert scale > 1e-4
    for k in ("pmg", "pmg2"):
        assert np.abs(out[k]["x"][-1] - a["x"][-1]).max() < 1e-8 * scale
    assert out["pmg"]["stats"]["ksp_its"].sum() < out["gamg"]["stats"]["ksp_its"].sum()
