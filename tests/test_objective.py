"""Backward Euler as energy minimization (issue 16): the incremental potential registered with SNES is
the potential of the residual (its gradient, by central differences, per effect and for the whole
system with its Dirichlet rows), +inf where the material is undefined, decreasing along Newton's
iterates; effects without a potential fall back to the residual norm; a case that fails with the
residual-norm line search passes with the energy one; the solver recipes agree with the default."""
import math

import numpy as np
import pytest

from conftest import make_model, read_h5, hyperelastic, run_ok

# (scene, options): every effect with a potential, both mass matrices, every material
CASES = [("bend", [("material", m)]) for m in ("stvk", "neohookean", "linear", "snh", "corotational")]
CASES += [("bend", [("material", "mooney_rivlin"), ("C01", "1e5")]), ("bend", [("material", "neohookean_split")]),
          ("bend", [("spring", "2e5"), ("spring_faces", "top:z,back"), ("force", "0,10,-30"), ("force_faces", "front"),
                    ("body_force", "0,0,-100"), ("loads", "s"), ("s_spring", "1e4"), ("s_faces", "bottom:xy")])]
CASES += [("sag", []), ("sag", [("mass", "lumped")]), ("twist3", []),
          ("bend", [("rayleigh_alpha", "0.5"), ("rayleigh_beta", "1e-3")]),
          ("bend", [("rayleigh_alpha", "0.5"), ("mass", "lumped"), ("damping", "40")]),
          ("bend", [("quasistatic", "")])]


def perturbed(petsc, scene_name, options, seed=5):
    m = make_model(petsc, scene_name, options)
    sc, sp, system = m.scene, m.space, m.system
    rng = np.random.default_rng(seed)
    x = sp.X.ravel() + 0.01 * rng.standard_normal(3 * sp.nlv)
    v = 0.1 * rng.standard_normal(3 * sp.nlv)
    system.begin_step(0.3, sc.dt, sp.X.ravel() + 0.005 * rng.standard_normal(3 * sp.nlv), v)
    return m, x, rng


def central(f, x, d, eps):
    return (f(x + eps * d) - f(x - eps * d)) / (2 * eps)


@pytest.mark.parametrize("scene_name,options", CASES, ids=lambda c: str(c))
def test_potential_gradient_is_residual_per_effect(petsc, scene_name, options):
    m, x, rng = perturbed(petsc, scene_name, options)
    for e in m.system.effects:
        assert e.conservative
        r = np.zeros_like(x)
        e.residual(x, r)
        for _ in range(2):
            d = rng.standard_normal(len(x))
            fd = central(e.potential, x, d, 1e-6)
            exact = float(r @ d)
            assert abs(fd - exact) <= 1e-6 * (np.abs(r).max() * np.abs(d).sum()) + 1e-12, (e.name, fd, exact)


@pytest.mark.parametrize("scene_name,options", CASES[:1] + CASES[6:8], ids=lambda c: str(c))
def test_objective_gradient_is_system_residual(petsc, scene_name, options):
    """The whole objective, constrained rows included, against the residual SNES sees."""
    m, x, rng = perturbed(petsc, scene_name, options)
    system = m.system
    X = system.global_state(x)
    X.getArray()[:] += 1e-3 * rng.standard_normal(X.getLocalSize())   # constrained rows off their targets too
    R = X.duplicate()
    R.set(0.0)
    system.residual(X, R)
    for _ in range(2):
        D = X.duplicate()
        D.getArray()[:] = rng.standard_normal(X.getLocalSize())
        fd = central(lambda Y: system.energy(Y)[0], X, D, 1e-6)
        exact = R.dot(D)
        assert abs(fd - exact) <= 1e-6 * R.norm(3) * D.norm(1), (fd, exact)


def test_objective_infinite_where_material_undefined(petsc):
    """Mirrored cells (J < 0): +inf for Neo-Hookean (undefined), finite for Stable Neo-Hookean."""
    for material, finite in (("neohookean", False), ("snh", True)):
        m = make_model(petsc, "unfold", [("material", material)])
        E = m.system.energy(m.system.global_state(m.x0))[0]
        assert math.isfinite(E) == finite, (material, E)


def test_energy_decreases_along_newton_iterates(petsc):
    """Quasi-static bend at the full load in one step: the line search cuts steps (lambda < 1), and
    every Newton iterate lowers the energy: the objective at iterate k, measured from iterate k-1,
    is negative, down to the last iterate (where E itself cannot resolve the change)."""
    from hyperelastic.solving.solver import Solver
    m = make_model(petsc, "bend", [("quasistatic", ""), ("dt", "1"), ("final_time", "1"), ("snes_rtol", "1e-12")])
    solver = Solver(m.system, "assembled", objective=True)
    assert solver.merit == "energy"
    system = m.system
    system.begin_step(1.0, 1.0, m.x0, m.v0)
    X = system.global_state(m.x0)
    drops, energies = [], []

    def monitor(snes, its, fnorm):
        if its:
            drops.append(system.objective(snes.getSolution()))   # from the iterate before
        energies.append(system.energy(snes.getSolution())[0])
    solver.snes.setMonitor(monitor)
    assert solver.solve(X) > 0
    assert len(drops) >= 4
    assert all(d < 0 for d in drops), drops
    assert abs(drops[-1]) < 1e-12 * abs(energies[0] - energies[-1])   # resolved below E's rounding error


def test_the_accepted_trial_energy_is_not_computed_again(petsc, monkeypatch):
    """The line search's accepted trial is the next Newton iterate: its energy, computed for the search, is kept as
    the next iteration's base energy instead of computed again. A quasi-static Neo-Hookean bend at full load in one
    step (line search cuts, several Newton iterations): one energy evaluation per trial point plus the first
    iterate's, and the iterates bit for bit those of a solve that recomputes every base energy."""
    from hyperelastic.solving.solver import Solver
    from hyperelastic.solving.system import System

    def solve(keep):
        if not keep:
            monkeypatch.setattr(System, "_keep_trial", lambda self, X, E, mag: None)
        m = make_model(petsc, "bend", [("material", "neohookean"), ("quasistatic", ""), ("dt", "1"),
                                       ("final_time", "1"), ("snes_rtol", "1e-12")])
        solver = Solver(m.system, "assembled", objective=True)
        system = m.system
        system.begin_step(1.0, 1.0, m.x0, m.v0)
        calls, iterates = [], []
        energy = system.energy
        system.energy = lambda X: calls.append(1) or energy(X)
        objective = system.objective
        trials = []
        system.objective = lambda X: trials.append(not system._at_base(X)) or objective(X)
        solver.snes.setObjective(lambda snes, X: system.objective(X))
        solver.snes.setMonitor(lambda snes, its, fnorm: iterates.append(snes.getSolution().getArray(readonly=True).copy()))
        X = system.global_state(m.x0)
        assert solver.solve(X) > 0
        monkeypatch.undo()
        return len(calls), sum(trials), solver.snes.getIterationNumber(), iterates

    kept, trials, its, iterates = solve(True)
    again, trials_again, its_again, iterates_again = solve(False)
    assert its == its_again >= 4 and trials == trials_again
    assert kept == trials + 1 and again == 2 * trials, (kept, again, trials)
    assert all(np.array_equal(a, b) for a, b in zip(iterates, iterates_again)) and len(iterates) == len(iterates_again)


def test_objective_difference_resolves_below_rounding(petsc):
    """At a converged state Z (R ~ 0), a small step d changes E by 1/2 d.J d, far below E's rounding
    error; the objective measured from Z still gives it to 1e-6 (Neo-Hookean: not a polynomial)."""
    from hyperelastic.solving.solver import Solver
    m = make_model(petsc, "bend", [("material", "neohookean"), ("quasistatic", ""), ("snes_rtol", "1e-12")])
    solver = Solver(m.system, "assembled", objective=True)
    system = m.system
    system.begin_step(1.0, 1.0, m.x0, m.v0)
    Z = system.global_state(m.x0)
    assert solver.solve(Z) > 0
    system.set_objective_base(Z)
    R, D, JD = Z.duplicate(), Z.duplicate(), Z.duplicate()
    system.residual(Z, R)
    system.linearize(Z)
    rng = np.random.default_rng(7)
    scale = system.energy(Z)[1]
    for size in (1e-10, 1e-9):
        D.getArray()[:] = size * rng.standard_normal(Z.getLocalSize())
        system.apply(D, JD)
        model = R.dot(D) + 0.5 * D.dot(JD)
        assert 0 < model < 1e-12 * scale           # below what E(Z + d) - E(Z) can resolve directly
        W = Z.copy()
        W.axpy(1.0, D)
        got = system.objective(W)
        assert abs(got - model) <= 1e-6 * model, (size, got, model)


def test_follower_load_falls_back_to_residual_norm(tmp_path):
    out = tmp_path / "t.h5"
    p = run_ok(["run", "twist", "-final_time", "0.02", "-level", "1", "-output", out])
    assert "follower_traction has no potential" in p.stderr
    attrs = read_h5(out)["attrs"]
    assert attrs["line_search_merit"].startswith("residual norm")
    assert read_h5(out)["stats"]["objective_evals"].sum() == 0


QUASISTATIC_FULL_LOAD = ["run", "bend", "-quasistatic", "-dt", "1", "-final_time", "1", "-level", "1",
                         "-snes_max_it", "10", "-quiet"]


def test_energy_line_search_passes_where_residual_norm_fails(tmp_path):
    """The full load in one quasi-static step within 10 Newton iterations: the residual-norm line
    search crawls (lambda ~ 0.1) and fails; the energy line search converges in a few iterations."""
    p = hyperelastic(QUASISTATIC_FULL_LOAD + ["-objective", "0", "-step_control", "0", "-output",
                                              tmp_path / "r.h5"])
    assert p.returncode == 3, p.stderr
    assert "DIVERGED_MAX_IT" in p.stderr
    run_ok(QUASISTATIC_FULL_LOAD + ["-output", tmp_path / "e.h5"])
    st = read_h5(tmp_path / "e.h5")
    assert st["attrs"]["line_search_merit"] == "energy"
    assert st["stats"]["rejected"].sum() == 0
    assert st["stats"]["newton_its"][0] <= 6
    assert st["stats"]["objective_evals"][0] > 0


@pytest.mark.parametrize("recipe", ["projected_newton", "trust_region"])
def test_recipes_agree_with_default(tmp_path, recipe):
    """Projected Newton and the trust region reach the default's answer (to solver tolerance) on a
    St. Venant-Kirchhoff twist, and reject no step."""
    import os
    from hyperelastic.core.data import OPTIONS_DIR
    base = ["run", "twist3", "-level", "1", "-final_time", "0.1", "-material", "stvk", "-E", "2.1e11",
            "-snes_rtol", "1e-10", "-quiet"]
    run_ok(base + ["-output", tmp_path / "d.h5"])
    run_ok(base + ["-options_file", os.path.join(OPTIONS_DIR, f"{recipe}.opts"), "-output", tmp_path / "r.h5"])
    d, r = read_h5(tmp_path / "d.h5"), read_h5(tmp_path / "r.h5")
    assert r["stats"]["rejected"].sum() == 0
    assert d["x"].shape == r["x"].shape
    disp = np.abs(d["x"][-1] - d["points"]).max()
    assert np.abs(d["x"][-1] - r["x"][-1]).max() <= 1e-6 * disp


@pytest.mark.parametrize("scene", ["bend", "squeeze", "sag"])
def test_same_answer_as_the_residual_norm_merit(tmp_path, scene):
    """Where both merits converge without rejection, the trajectories agree to the solver tolerance."""
    base = ["run", scene, "-level", "1", "-final_time", "0.1", "-snes_rtol", "1e-10", "-snes_atol", "1e-9",
            "-ksp_rtol", "1e-10", "-snes_stol", "0", "-quiet"]
    run_ok(base + ["-output", tmp_path / "e.h5"])
    run_ok(base + ["-objective", "0", "-output", tmp_path / "r.h5"])
    e, r = read_h5(tmp_path / "e.h5"), read_h5(tmp_path / "r.h5")
    assert e["stats"]["rejected"].sum() == 0 and r["stats"]["rejected"].sum() == 0
    disp = np.abs(r["x"][-1] - r["points"]).max()
    assert np.abs(e["x"] - r["x"]).max() <= 1e-8 * disp
