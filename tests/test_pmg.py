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


@pytest.mark.parametrize("nprocs", [1, 2])
def test_sbaij_fill_and_cell_galerkin_equal_aij_and_ptap(nprocs):
    """Where p-multigrid runs, the P2 tangent is filled straight into SBAIJ (no AIJ) and the P1 operator summed from
    the cells: both equal the AIJ fill's (its upper triangle) and PETSc's P^T A P of it, on 1 and 2 ranks (a
    partition boundary's blocks through MatSetValuesBlocked), with an effect's own entries (springs) and the
    constrained diagonal (tests/mpi_sbaij_check.py)."""
    from conftest import run_mpi_script
    p = run_mpi_script("mpi_sbaij_check.py", ["bend2", "sag:spring=1e7,spring_faces=bottom"], nprocs=nprocs)
    assert p.returncode == 0, p.stdout + p.stderr
    assert [l.split(":")[0] for l in p.stdout.splitlines() if l.startswith("ok")] == ["ok bend2", "ok sag"], p.stdout
    assert (" 0 boundary cells" in p.stdout) == (nprocs == 1)


def test_p_multigrid_keeps_no_aij(petsc):
    """-pc_type mg on quadratic tetrahedra with the default P2 smoother: SNES gets one SBAIJ as operator and
    preconditioning matrix, and the levels sum the P1 operator from the cells; a smoother that needs an AIJ (SOR)
    keeps the AIJ beside the SBAIJ (and PETSc's PtAP)."""
    from petsc4py import PETSc
    from hyperelastic.solving import pmg
    from hyperelastic.solving.solver import Solver
    opts = PETSc.Options()
    for smoother, types in ((None, ("seqsbaij", "seqsbaij")), ("sor", ("seqsbaij", "seqaij"))):
        m = make_model(petsc, "bend2", [("level", "1"), ("order", "2")])
        opts.setValue("pc_type", "mg")
        if smoother:
            opts.setValue("mg_levels_pc_type", smoother)
        try:
            s = Solver(m.system, "assembled")
            J, P = s.snes.getKSP().getOperators()
            assert (J.getType(), P.getType()) == types
            assert (s.levels.galerkin is not None) == (smoother is None)
        finally:
            for k in ["pc_type", "pc_mg_levels", "mg_levels_pc_type"] + list(pmg.DEFAULTS):
                opts.delValue(k)


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
    aij = ("aij", PMG + ["-operator_storage", "aij"], 1)         # the AIJ and PETSc's PtAP
    return run_cases(tmp_path_factory.mktemp("pmg"), base, CASES + (alone, aij))


def test_same_answer_as_gamg_in_fewer_iterations(runs):
    a, b, c = runs["gamg"], runs["pmg"], runs["pmg2"]
    scale = np.abs(a["x"][-1] - a["points"]).max()
    for r in (b, c):
        assert np.abs(r["x"][-1] - a["x"][-1]).max() < 1e-8 * scale
    its = {k: r["stats"]["ksp_its"].sum() / r["stats"]["newton_its"].sum() for k, r in runs.items()
           if k in ("gamg", "pmg", "pmg2")}
    assert its["pmg"] < 0.75 * its["gamg"], its
    assert abs(its["pmg2"] - its["pmg"]) <= 0.25 * its["pmg"], its


def test_without_the_aij_as_with_it(runs):
    """p-multigrid on the SBAIJ alone (the P1 operator summed from the cells) iterates as with the AIJ and PETSc's
    PtAP (the coarse operators differ by rounding), to the same answer."""
    a, b = runs["pmg"], runs["aij"]
    assert abs(int(a["stats"]["ksp_its"].sum()) - int(b["stats"]["ksp_its"].sum())) <= 2
    assert np.abs(a["x"][-1] - b["x"][-1]).max() <= 1e-10 * np.abs(a["x"][-1] - a["points"]).max()


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
