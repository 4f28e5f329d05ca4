"""Issue 5: snh and corotational materials, Hessian projection, the inversion guard, step control, the
NaN/Inf guard, and the quick subset of the hard-case matrix (hyperelastic/studies/stability.py)."""

import numpy as np
import pytest

from conftest import hyperelastic, read_h5, run_ok
from hyperelastic.studies import stability as S
from hyperelastic.physics.materials import MATERIALS, get, lame

LAM, MU = lame(1e6, 0.3)
rng = np.random.default_rng(55)


def rotations(n):
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


@pytest.mark.parametrize("name", ["snh", "corotational", "neohookean", "stvk"])
def test_small_strain_limit_is_linear_elasticity(name):
    """At F = I every material's tangent is linear elasticity's with the same (mu, lambda): for snh
    this checks its Lame reparameterisation (mu' = 4/3 mu, lambda' = lambda + 5/6 mu); the rest state
    is stress- and energy-free."""
    m, lin = MATERIALS[name], MATERIALS["linear"]
    I = np.broadcast_to(np.eye(3), (6, 3, 3)).copy()
    dF = rng.standard_normal((6, 3, 3))
    assert np.abs(m.dP(I, dF, (MU, LAM)) - lin.dP(I, dF, (MU, LAM))).max() <= 1e-12 * np.abs(lin.dP(I, dF, (MU, LAM))).max()
    assert np.abs(m.P(I, (MU, LAM))).max() <= 1e-9 * MU
    assert np.abs(m.psi(I, (MU, LAM))).max() <= 1e-9 * MU


@pytest.mark.parametrize("name", ["snh", "corotational", "neohookean", "stvk"])
def test_rotation_invariance(name):
    """psi(R F) = psi(F) and P(R F) = R P(F); linear elasticity is not invariant (its artifact)."""
    m = MATERIALS[name]
    F = np.eye(3) + 0.2 * rng.standard_normal((10, 3, 3))
    F = F[np.linalg.det(F) > 0.3]
    R = rotations(len(F))
    assert np.allclose(m.psi(R @ F, (MU, LAM)), m.psi(F, (MU, LAM)), rtol=1e-10, atol=1e-6)
    assert np.allclose(m.P(R @ F, (MU, LAM)), R @ m.P(F, (MU, LAM)), rtol=1e-9, atol=1e-4)
    lin = MATERIALS["linear"]
    assert np.abs(lin.psi(R, (MU, LAM))).min() > 1e-3 * MU


def unit_tets(m, F):
    """One independent unit tetrahedron per F (Dm = I, V = 1/6) deformed by F: the kernels bound to
    them, the positions, and the reference forces V P(F) grad N_a from the numpy material."""
    from hyperelastic.discretization.kernels import CellKernels
    n = len(F)
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    x = np.einsum("nij,aj->nai", F, X).reshape(-1).copy()
    k = CellKernels(np.arange(4 * n, dtype=np.int32).reshape(-1, 4), np.broadcast_to(np.eye(3), (n, 3, 3)).copy(),
                    np.full(n, 1 / 6), m, (MU, LAM))
    G = np.concatenate([-np.ones((1, 3)), np.eye(3)])
    return k, x, np.einsum("nij,aj->nai", m.P(F, (MU, LAM)) / 6, G).reshape(-1)


@pytest.mark.parametrize("name", ["snh", "corotational"])
def test_defined_and_exact_when_inverted(name):
    """snh and corotational are defined for J <= 0: the compiled kernel matches the numpy reference
    there, and the tangent is the derivative of the forces (finite differences)."""
    m = MATERIALS[name]
    F = np.eye(3) + 0.8 * rng.standard_normal((40, 3, 3))
    assert (np.linalg.det(F) < 0).sum() >= 5
    k, x, ref = unit_tets(m, F)
    f = np.zeros_like(x)
    assert k.forces(x, f) == 0 and np.isfinite(f).all()
    assert np.abs(f - ref).max() <= 1e-10 * np.abs(ref).max()
    W, *_ = k.energy(x)
    assert np.isclose(W, (m.psi(F, (MU, LAM)) / 6).sum(), rtol=1e-10)
    v = rng.standard_normal(x.shape)
    y = np.zeros_like(x)
    k.kv(x, v, y)
    fp, fm = np.zeros_like(x), np.zeros_like(x)
    k.forces(x + 1e-6 * v, fp)
    k.forces(x - 1e-6 * v, fm)
    assert np.abs(y - (fp - fm) / 2e-6).max() <= 1e-5 * np.abs(y).max()


def test_corotational_polar_decomposition():
    """The C polar decomposition (Jacobi eigen-solver on F^T F) against numpy's SVD, through the
    forces P(F): also for nearly degenerate, repeated-singular-value and inverted F."""
    from hyperelastic.physics.materials.corotational import polar
    m = MATERIALS["corotational"]
    F = np.concatenate([np.eye(3) + 0.5 * rng.standard_normal((20, 3, 3)),
                        np.diag([1.0, 1.0, 1e-9])[None], np.diag([2.0, -0.5, 1.0])[None],
                        rotations(3) @ np.diag([1.0, 1.0 + 1e-12, 0.7]), rotations(2)])
    R, V, s = polar(F)
    assert np.allclose(np.linalg.det(R), 1) and np.allclose(R @ V @ (s[:, :, None] * np.swapaxes(V, 1, 2)), F)
    k, x, ref = unit_tets(m, F)
    f = np.zeros_like(x)
    k.forces(x, f)
    assert np.abs(f - ref).max() <= 1e-9 * MU


def test_hessian_projection_is_psd_and_exact_where_psd():
    from hyperelastic.physics.effects.elasticity import project_psd
    A = rng.standard_normal((30, 12, 12))
    K = A + A.transpose(0, 2, 1)
    K[:10] = A[:10] @ A[:10].transpose(0, 2, 1)        # already PSD: unchanged
    P, neg = project_psd(K)
    assert neg == 20
    assert np.linalg.eigvalsh(P).min() >= -1e-10 * np.abs(K).max()
    assert np.allclose(P[:10], K[:10], atol=1e-10 * np.abs(K).max())


def test_max_step_stops_before_inversion():
    """he_max_step: the largest fraction of an update that keeps every element's det F > 0."""
    from hyperelastic.discretization.kernels import CellKernels
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    k = CellKernels(np.arange(4, dtype=np.int32)[None], np.eye(3)[None], np.array([1 / 6]), get("stvk"), (MU, LAM))
    d = np.zeros(12)
    d[11] = -3.0                                 # vertex 3 moves through the opposite face: det F = 1 - 3 t
    assert np.isclose(k.max_step(X.ravel(), d, 0.9), 0.9 / 3, rtol=1e-12)
    d[11] = -0.5                                 # stays valid for the whole step
    assert k.max_step(X.ravel(), d, 0.9) == 1.0
    d = rng.standard_normal(12) * 2
    t = k.max_step(X.ravel(), d, 1.0)
    s = np.linspace(0, t, 200)[:-1]
    dets = [np.linalg.det((X + si * d.reshape(4, 3))[1:] - (X + si * d.reshape(4, 3))[0]) for si in s]
    assert min(dets) > 0


def test_step_control_rejects_halves_and_regrows(tmp_path):
    """twist3 with Neo-Hookean at h = 0.1: the first attempt inverts elements (domain error), it is
    rejected and retried with h/2, h grows back, and the run ends exactly at the final time."""
    out = tmp_path / "t.h5"
    run_ok(["run", "twist3", "-level", 1, "-material", "neohookean", "-dt", 0.1, "-quiet", "-output", out])
    r = read_h5(out)
    st = r["stats"]
    rej = st["rejected"].astype(bool)
    assert rej.sum() >= 1 and (st["snes_reason"][rej] < 0).all() and (st["snes_reason"][~rej] > 0).all()
    i = np.flatnonzero(rej)[0]
    assert np.isclose(st["dt"][i + 1], st["dt"][i] / 2)
    assert np.isclose(st["dt"][-1], 0.1, rtol=1e-12)                     # grew back to -dt
    assert np.isclose(r["time"][-1], 1.0, rtol=0, atol=1e-12) and np.isclose(st["dt"][~rej].sum(), 1.0)
    assert np.isfinite(r["x"]).all()


def test_step_control_off_stops_at_first_failure(tmp_path):
    out = tmp_path / "t.h5"
    p = hyperelastic(["run", "twist3", "-level", 1, "-material", "neohookean", "-dt", 0.1, "-step_control", 0,
                      "-quiet", "-output", out])
    assert p.returncode == 3
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "step 1 (t=0.1" in lines[0] and "DIVERGED_FUNCTION_DOMAIN" in lines[0]
    assert read_h5(out)["stats"]["rejected"].tolist() == [1]


@pytest.mark.parametrize("nprocs", [1, 2])
def test_below_dt_min_stops_with_one_line_and_valid_output(tmp_path, nprocs):
    """Neo-Hookean pushed through itself must fail (it cannot pass J = 0): below -dt_min the run stops
    with one line naming step, time and reason; the output up to there is valid and finite; both
    ranks exit."""
    out = tmp_path / "inv.h5"
    p = hyperelastic(["run", "invert", "-level", 1, "-material", "neohookean", "-dt_min", "1e-4", "-quiet",
                      "-output", out], nprocs=nprocs, timeout=300)
    assert p.returncode == 3
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "step control reached -dt_min" in lines[0] and "(t=" in lines[0], p.stderr
    r = read_h5(out)
    assert "failure" in r["attrs"] and np.isfinite(r["x"]).all() and len(r["time"]) > 1
    assert r["stats"]["J_min"][r["stats"]["rejected"] == 0].min() > 0      # it never inverted
    assert r["stats"]["inversion_cuts"].sum() > 0                           # the guard shortened updates


def test_nonfinite_residual_never_reaches_the_output(tmp_path):
    """An end pulled to 1e300 t overflows the stresses to Inf: every attempt is rejected
    (DIVERGED_FUNCTION_NANORINF) and the run stops cleanly; the file holds the finite initial frame only.
    (Options themselves are bounded by 1e30, so the overflow comes from a prescribed motion.)"""
    out = tmp_path / "inf.h5"
    p = hyperelastic(["run", "stretch", "-level", 1, "-prescribe_ux", "1e300*t*X", "-quiet", "-output", out])
    assert p.returncode == 3 and "NANORINF" in p.stderr
    r = read_h5(out)
    assert len(r["time"]) == 1 and np.isfinite(r["x"]).all() and r["stats"]["rejected"].all()


def test_hessian_projection_run_matches_exact(tmp_path):
    """Projected Newton converges to the same step solutions (the residual is unchanged)."""
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    common = ["run", "stretch", "-level", 1, "-material", "snh", "-final_time", 0.2, "-snes_rtol", "1e-10",
              "-snes_atol", "1e-9", "-ksp_rtol", "1e-10", "-quiet"]
    run_ok(common + ["-output", a])
    run_ok(common + ["-output", b, "-hessian_projection"])
    xa, xb = read_h5(a)["x"][-1], read_h5(b)["x"][-1]
    assert np.abs(xa - xb).max() <= 1e-6 * np.abs(xa).max()


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("stability")
    return S.run_matrix(S.quick_matrix(), str(out), jobs=2)


def test_quick_matrix_properties(quick):
    """No NaN/Inf anywhere; energy never grows without external work; rigid motions stay rigid;
    snh unfolds; no cell fails unless physics explains it (Neo-Hookean pushed through J = 0)."""
    assert S.violations(quick) == []
    assert [r["id"] for r in quick if r["outcome"] == "failed"] == ["invert-neohookean-E1e6-nu0.3-h0.01-assembled"]
    assert all(r["outcome"] in ("finished", "recovered", "failed") for r in quick)
    for r in quick:
        if r["outcome"] == "failed":
            assert r["message"].startswith("hyperelastic: error:") and "\n" not in r["message"]


def test_quick_matrix_reports_what_it_must(quick):
    by = {(r["scene"], r["material"], r["E"], r["nu"], r["mode"]): r for r in quick}
    # linear elasticity's rotation artifact is measured, not hidden
    lin = by[("rotated", "linear", "1e6", 0.3, "assembled")]
    assert lin["elastic_max_rel"] > 1e-3 and lin["strain_final"] > 1e-2
    # St.VK cannot tell a mirror image from the rest state (zero energy at F = diag(-1,1,1)); snh can
    assert by[("unfold", "stvk", "1e6", 0.3, "assembled")]["J_min_final"] < 0
    assert by[("unfold", "snh", "1e6", 0.3, "assembled")]["J_min_final"] > 0.5
    # near-incompressible Neo-Hookean keeps its volume better than nu = 0.3 when squeezed to half length
    v3 = by[("squeeze", "neohookean", "1e6", 0.3, "assembled")]["volume_ratio"]
    v499 = by[("squeeze", "neohookean", "1e6", 0.499, "assembled")]["volume_ratio"]
    assert abs(v499 - 1) < abs(v3 - 1) and abs(v499 - 1) < 0.05


def test_matrix_script_writes_report(tmp_path, quick):
    """The matrix's writers (scripts/stability_matrix.py calls hyperelastic.studies.stability.main): CSV, markdown
    table and heatmap from the same rows; the CSV reads back to the same rows."""
    from hyperelastic.studies import stability as sm
    sm.write_csv(quick, tmp_path / "s.csv")
    back = sm.read_rows(tmp_path / "s.csv")
    assert [r["id"] for r in back] == [r["id"] for r in quick]
    assert all(b["steps"] == q["steps"] and b["outcome"] == q["outcome"] for b, q in zip(back, quick))
    # two matrices side by side: the totals, and the cells whose outcome changed
    altered = [dict(r, outcome="failed", rejections=7) if r["id"] == back[0]["id"] else r for r in back]
    lines = sm.compare(back, altered)
    assert f"| failed | {sum(r['outcome'] == 'failed' for r in back)} | " \
           f"{sum(r['outcome'] == 'failed' for r in altered)} |" in lines
    assert [ln for ln in lines if ln.startswith(f"| {back[0]['id']} |")]
    sm.heatmap(quick, tmp_path / "s.png")
    assert sm.report(quick, str(tmp_path), "test") == []
    text = (tmp_path / "stability.md").read_text()
    assert text.count("\n| ") >= len(quick) and (tmp_path / "s.png").stat().st_size > 1000


def test_a_small_step_after_an_inversion_cut_is_not_convergence():
    """SNES's CONVERGED_SNORM_RELATIVE after the inversion guard shortened an update of the same solve is refused
    (issue 47: such a step was accepted at J_min 0.107 in an incompressible rubber); after contact's never-through cut
    it is refused where the cut shortened the solve's last update (a barrier's first iterations are cut, then Newton
    converges to updates below -snes_stol: issue 46); without a cut, or with a converged residual, the reason is
    SNES's own."""
    from petsc4py import PETSc
    from hyperelastic.physics.effects.seams import StepLimiter
    from hyperelastic.solving.solver import CUT_COUNTERS, InversionGuard, Solver
    R = PETSc.SNES.ConvergedReason
    ITS = 5                                       # the mock solve's Newton iterations (updates 0..4)

    class Snes:
        def __init__(self, solver, reason, cut_at):
            self.solver, self.reason, self.cut_at = solver, reason, cut_at

        def solve(self, b, X):
            if self.cut_at is not None:           # (what Solver._precheck records when it cuts update k)
                self.solver._count_cut(limiter, self.cut_at)

        def getConvergedReason(self):
            return self.reason

        def getIterationNumber(self):
            return ITS

    class System:
        def set_objective_base(self, X):
            pass
    s = Solver.__new__(Solver)
    s.system, s.cuts, s.sticky_cuts = System(), dict.fromkeys(CUT_COUNTERS, 0), 0
    s.imbalance = lambda X: 0.0                   # (a residual at its rounding floor: the step-norm stop stands)
    for limiter, early in ((InversionGuard(None), Solver.GUARDED_SNORM), (StepLimiter(), R.CONVERGED_SNORM_RELATIVE)):
        for reason, cut_at, want in ((R.CONVERGED_SNORM_RELATIVE, ITS - 1, Solver.GUARDED_SNORM),
                                     (R.CONVERGED_SNORM_RELATIVE, 1, early),
                                     (R.CONVERGED_SNORM_RELATIVE, None, R.CONVERGED_SNORM_RELATIVE),
                                     (R.CONVERGED_FNORM_RELATIVE, ITS - 1, R.CONVERGED_FNORM_RELATIVE)):
            s.snes = Snes(s, reason, cut_at)
            assert s.solve(None) == want, (limiter.counter, reason, cut_at)
    assert Solver.GUARDED_SNORM < 0 and "not convergence" in s.reason_name(Solver.GUARDED_SNORM)
    # a step-norm stop without a cut whose residual is not small against the forces is not the end (issue 72): Newton
    # goes on (_newton_on), and its reason is the solve's; a stop that cannot go on is refused
    s.snes, s.imbalance = Snes(s, R.CONVERGED_SNORM_RELATIVE, None), lambda X: 2e-3
    s._newton_on = lambda X, reason: R.DIVERGED_MAX_IT
    assert s.solve(None) == R.DIVERGED_MAX_IT
    s.imbalance = lambda X: 0.5 * Solver.SNORM_EQUILIBRIUM
    assert s.solve(None) == R.CONVERGED_SNORM_RELATIVE
    s.last_imbalance = 2e-3
    assert Solver.UNBALANCED_SNORM < 0 and "not an equilibrium" in s.reason_name(Solver.UNBALANCED_SNORM)
