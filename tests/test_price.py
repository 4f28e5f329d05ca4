"""`hyperelastic study price` (issue 35): the quick version on the thesis' bar bent quasi-statically, its
answer checked against a reference the search never sees; the error models on made-up sequences; bad
arguments."""
import math
import os

import h5py
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, run_ok
from hyperelastic.studies.experiments.table import read_csv
from hyperelastic.studies.price import DimModel, SolverModel, observed_order, solvers
from hyperelastic.mesh.read import interpolate, locate

BAR = ["--part", f"{ROOT}/meshes/bar.geo", "--scene", f"{ROOT}/options/scenes/bend2.opts", "--size", "2"]
STATIC = "-quasistatic -dt 0.0625 -final_time 0.25 -material stvk"
DYNAMIC = "-final_time 0.3 -dt 0.02 -material stvk"
TIP = (5.0, 0.0, 0.0)
PMG = ["-options_file", f"{ROOT}/options/pmg.opts"]     # the references' solver (P2: half GAMG's time)


@pytest.fixture(scope="module")
def price(tmp_path_factory):
    out = tmp_path_factory.mktemp("price")
    p = run_ok(["study", "price", *BAR, "--watch", "u_y:5,0,0", "--target", "0.03", "--run-args", STATIC,
                "--budget", "600", "-output_dir", out], timeout=1200)
    num = {k: float for k in ("quantity", "est_total", "solve_s")} | {k: int for k in ("order", "level", "tets",
                                                                                       "meets_target")}
    return out, p, read_csv(os.path.join(out, "price.csv"), num)


def reference(tmp_path):
    """u_y at the tip of P2 on the part's second refinement with tight tolerances (kept out of the search), the load
    reached in one step: a hyperelastic equilibrium does not depend on the load path, and the search's four steps
    gave the same u_y to 9 digits in three times the time (12.5 against 4.4 s)."""
    run_ok(["mesh", f"{ROOT}/meshes/bar.geo", "--size", "2", "--refine", "2", "--order", "2", "-o", tmp_path / "r.msh"])
    out = tmp_path / "ref.h5"
    run_ok(["run", f"{ROOT}/options/scenes/bend2.opts", *STATIC.split(), "-dt", "0.25", "-mesh", tmp_path / "r_r2.msh",
            "-order", "2", "-snes_rtol", "1e-10", "-ksp_rtol", "1e-10", *PMG, "-quiet", "-output", out], timeout=600)
    with h5py.File(out, "r") as f:
        X, tets, x = f["mesh/points"][:], f["mesh/tetra"][:], f["x"][-1]
    cells, w = locate(X, tets, np.array(TIP))
    return float(interpolate(tets, cells, w, x - X)[0][1])


def test_price_answers_first_and_its_answer_meets_the_target(price, tmp_path):
    out, p, rows = price
    text = open(os.path.join(out, "price.md")).read()
    first = text.split("\n\n")[1]
    assert first.startswith("**For u_y:5,0,0 within 0.03 (relative), the cheapest setting found is P"), first
    assert "estimated error" in first and "The defaults" in first and "x as much" in first
    assert os.path.getsize(os.path.join(out, "price.png")) > 10000
    for r in rows:
        assert r["outcome"] in ("finished", "failed") and (r["outcome"] == "finished" or r["message"])
    met = [r for r in rows if r["meets_target"] == 1]
    best = min(met, key=lambda r: r["solve_s"])
    assert best["est_total"] <= 0.03 and f"({best['tets']:,} tets)" in first
    # both orders started coarse, the solver tolerances were probed, and the answer is P2 (P1 locks in bending)
    assert {(r["order"], r["level"]) for r in rows} >= {(1, 0), (1, 1), (2, 0), (2, 1)}
    assert {r["tolerances"] for r in rows} >= {"loose", "default"}
    assert best["order"] == 2
    # the linear solvers priced on P2 include p-multigrid (Jacobi took ~970 CG iterations per Newton step at r2), and
    # none is on P1 (p-multigrid needs quadratic tetrahedra)
    assert {r["pc"] for r in rows if r["order"] == 2} == set(solvers(2)) and "pmg" in solvers(2)
    assert "pmg" not in {r["pc"] for r in rows if r["order"] == 1} and "pmg" not in solvers(1)
    q_ref = reference(tmp_path)
    true = abs(best["quantity"] - q_ref) / abs(q_ref)
    assert true <= 0.03, (best, q_ref, true)
    # the estimates are honest on every finished run: within a factor of 3 of the true error, or both tiny
    for r in rows:
        if r["outcome"] == "finished" and r["order"] == 2:
            t = abs(r["quantity"] - q_ref) / abs(q_ref)
            assert t <= 3 * r["est_total"] + 2e-3, (r, t)


def test_price_of_a_dynamic_peak(tmp_path):
    """bend2 (dynamic): the largest tip deflection over 0.3 s within 3%, P2 only. Time is modelled per order on
    its coarsest mesh; backward Euler at the scene's step is 12% off there, so the answer is a second-order
    integrator, confirmed on three meshes and three steps, and within the target of a reference the search never
    sees (P2 on the first refinement, generalized-alpha at half the step, tight tolerances: 5e-5 from a quarter of the
    step, in half the time)."""
    out = tmp_path / "dyn"
    run_ok(["study", "price", *BAR, "--watch", "u_y:5,0,0@max", "--target", "0.03", "--order", "2", "--run-args",
            DYNAMIC, "--budget", "600", "-output_dir", out], timeout=1200)      # (70 s alone; the budget is wall time)
    rows = read_csv(os.path.join(out, "price.csv"), {"quantity": float, "est_total": float, "solve_s": float,
                                                      "level": int, "dt_halvings": int, "meets_target": int})
    text = open(os.path.join(out, "price.md")).read()
    assert "- time, P2 beuler: points at notches [0, 1]" in text, text
    assert any(f"- time, P2 {i}: points at notches [0, 1, 2]" in text for i in ("alpha2", "energy_momentum")), text
    best = min((r for r in rows if r["meets_target"] == 1), key=lambda r: r["solve_s"])
    assert best["integrator"] != "beuler" and best["est_total"] <= 0.03
    assert {r["level"] for r in rows if r["integrator"] == best["integrator"]
            and r["dt_halvings"] == best["dt_halvings"]} >= {0, 1, 2}
    run_ok(["mesh", f"{ROOT}/meshes/bar.geo", "--size", "2", "--refine", "1", "--order", "2", "-o", tmp_path / "r.msh"])
    ref = tmp_path / "ref.h5"
    run_ok(["run", f"{ROOT}/options/scenes/bend2.opts", *DYNAMIC.split(), "-dt", "0.01", "-integrator", "ts",
            "-mesh", tmp_path / "r_r1.msh", "-order", "2", "-snes_rtol", "1e-10", "-ksp_rtol", "1e-9", *PMG,
            "-frames_per_second", "50", "-quiet", "-output", ref], timeout=600)
    q_ref = float(hyperelastic(["report", ref, "--watch", "u_y:5,0,0@max"]).stdout.split()[-1])
    assert abs(best["quantity"] - q_ref) <= 0.03 * abs(q_ref), (best, q_ref)


def test_error_models_on_known_sequences():
    """Richardson along a dimension: exact for q = 1 + 2^(-p k) at the expected order, the observed order from
    three points (also with a gap), the smaller of observed and expected used, non-monotone changes taken
    as the error; the solver model."""
    seq = {k: (1 + 0.5 * 2 ** (-2 * k), 1.0) for k in (0, 1, 2)}
    m = DimModel(seq, 2)
    assert math.isclose(m.limit, 1.0) and math.isclose(m.error(2), 0.5 / 16) and math.isclose(m.error(3), 0.5 / 64)
    assert math.isclose(m.error(0), 0.5)
    gap = {k: (1 + 2 ** (-1.5 * k), 1.0) for k in (0, 1, 3)}
    assert math.isclose(observed_order(0, 1, 3, gap[1][0] - gap[0][0], gap[3][0] - gap[1][0]), 1.5, rel_tol=1e-9)
    slow = DimModel(gap, 3)               # observed 1.5 < expected 3: the observed order is used
    assert math.isclose(slow.p, 1.5, rel_tol=1e-9) and math.isclose(slow.limit, 1.0) and "below" in slow.note
    zigzag = DimModel({0: (1.0, 1), 1: (1.2, 1), 2: (1.1, 1)}, 2)
    assert math.isnan(zigzag.p) and math.isclose(zigzag.error(2), 0.1) and "do not shrink" in zigzag.note
    assert DimModel({0: (1.0, 1)}, 2).error(0) is None
    s = SolverModel({0: (1.001, 1), 1: (1.0, 1), 2: (1.0, 1)})
    assert math.isclose(s.error(0), 1e-3) and s.error(2) == 0.0


@pytest.mark.parametrize("args, words", [
    (["--watch", "u_y:5,0,0"], "--target"),
    (["--watch", "u_y:5,0,0", "--target", "-0.1"], "--target"),
    (["--watch", "u_y:5,0,0", "--target", "nan"], "--target"),
    (["--watch", "u_q:5,0,0", "--target", "0.01"], "unknown quantity"),
    (["--watch", "u_y:5,0,0", "--target", "0.01", "--order", "3"], "--order"),
    (["--watch", "u_y:5,0,0", "--target", "0.01", "--max-runs", "1"], "--max-runs"),
])
def test_price_bad_arguments_are_one_line(tmp_path, args, words):
    p = hyperelastic(["study", "price", *BAR, *args, "-output_dir", tmp_path / "o"])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and words in lines[0], p.stderr
    assert not (tmp_path / "o" / "price.md").exists()


def test_price_on_a_surface_the_part_lacks_leaves_nothing(tmp_path):
    """The watch fails on the first run's output (no such surface): one line, and the study's runs are removed."""
    p = hyperelastic(["study", "price", *BAR, "--watch", "max_displacement:nowhere", "--target", "0.01",
                      "--run-args", STATIC, "-output_dir", tmp_path / "o"])
    assert p.returncode == 2 and "no surface 'nowhere'" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not os.path.exists(tmp_path / "o" / "runs")


def test_price_stops_its_probes_at_the_budget(tmp_path):
    """--budget is wall time for the whole search, its coarse probes included (issue 48: --budget 5 took 20.7 s):
    with a budget any run spends (0.01 s: a first run of 0.4 s fitted 0.5 s once the suite ran faster, and a second
    followed), the search stops after it, and the report says it stopped and why."""
    out = tmp_path / "o"
    run_ok(["study", "price", *BAR, "--watch", "u_y:5,0,0", "--target", "0.01", "--run-args", STATIC, "--budget",
            "0.01", "-output_dir", out])
    rows = read_csv(os.path.join(out, "price.csv"))
    assert len(rows) == 1, rows
    text = open(os.path.join(out, "price.md")).read()
    # (its one run is given at least 1 s: on a loaded machine it is stopped there too, and the report says so)
    assert "The search stopped early: --budget 0.01 s spent" in text, text.split("\n\n")[1]


def test_the_search_steps_toward_its_plan_one_notch_at_a_time():
    """Search.step (the move toward an order's plan; which run a real search makes depends on the measured times, so
    the rule is checked on stated errors and costs): one notch finer in a dimension where the plan is finer, straight
    back to the plan's value where it is coarser, the integrator with its step, and among several moves the one whose
    error falls most per predicted second; the plan itself where nothing differs."""
    from dataclasses import replace
    from hyperelastic.studies.price import Search, Setting
    search = Search.__new__(Search)
    cost = {}
    search.total = lambda s, m: 0.5 ** s.level + 0.1 * 0.5 ** s.dt + 0.01 * 0.5 ** s.tol     # (error by notches)
    search.predict_cost = lambda s, m: cost.get((s.level, s.dt, s.tol), 1.0)
    c = Setting(1, 1, 0, "beuler", 0)
    assert search.step(c, replace(c, level=4), None) == replace(c, level=2)
    assert search.step(replace(c, level=3), replace(c, level=1), None) == replace(c, level=1)
    p = replace(c, level=3, dt=2, tol=2)
    assert search.step(c, p, None) == replace(c, level=2)             # the level buys most error per second ...
    cost[(2, 0, 0)] = 100.0
    assert search.step(c, p, None) == replace(c, dt=1)                # ... unless it is predicted 100x dearer
    cost[(1, 1, 0)] = 100.0
    assert search.step(c, p, None) == replace(c, tol=1)
    q = Setting(1, 1, 2, "alpha2", 0)
    assert search.step(c, q, None) == replace(c, integrator="alpha2", dt=2)
    assert search.step(c, c, None) == c


def test_the_defaults_comparison_run_is_stopped_at_its_limit(tmp_path, monkeypatch):
    """The defaults' setting is run for the comparison where its predicted cost is small, but a prediction from coarser
    runs can be far off (P1 r4 on the bar, predicted under 30 s, took ~260 s): the run is stopped at DEFAULTS_STOP (here
    0.05 s, so that it is), its row says so, the search is not taken for out of budget, and the report's first
    paragraph gives the defaults' cost as more than the limit."""
    from hyperelastic.studies import price
    from hyperelastic.studies.price_report import price_report
    monkeypatch.setattr(price, "DEFAULTS_STOP", 0.05)
    s = price.Search(f"{ROOT}/meshes/bar.geo", f"{ROOT}/options/scenes/bend2.opts", "u_y:5,0,0", 0.15, 2.0,
                     str(tmp_path), orders=(1,), run_args=STATIC.split(), max_runs=4, max_level=3)
    s.search()
    last = s.rows[-1]
    assert last["why"] == "the defaults, for comparison" and last["outcome"] == "failed", last
    assert last["stopped_at"] == 0.05 and "stopped at 0.05 s, the limit of this run" in last["message"]
    # (a linear solver trial may be stopped too, by design, where the first run's solve took over PC_TRIAL: under the
    # suite's load it did once)
    assert "budget" not in (s.stopped or "") and all(r["outcome"] == "finished" for r in s.rows[:-1]
                                                      if r["why"] != "linear solver trial"), s.rows
    price_report(s, str(tmp_path), "test")
    first = open(tmp_path / "price.md").read().split("\n\n")[1]
    assert f"({last['setting'].label()}) cost more than 0.05 s: their run, predicted under 30 s, was stopped" in first


def test_price_leaves_linear_tetrahedra_that_lock(tmp_path):
    """A nearly incompressible material (split Neo-Hookean, kappa/mu = 1000): the first P1 run's start-up note says
    linear tetrahedra lock (the output records its notes), so the search runs P2 only from then on and its report
    says why (issue 47: price spent its runs on P1, which locks on rubber)."""
    out = tmp_path / "o"
    args = STATIC.replace("-material stvk", "-material neohookean_split -mu 1e6 -kappa 1e9")
    run_ok(["study", "price", *BAR, "--watch", "u_y:5,0,0", "--target", "0.05", "--run-args", args, "--max-runs",
            "4", "-output_dir", out], timeout=600)
    rows = read_csv(os.path.join(out, "price.csv"), {"order": int})
    assert [r["order"] for r in rows].count(1) == 1 and rows[0]["order"] == 1, rows
    text = open(os.path.join(out, "price.md")).read()
    assert "was left" in text and "linear tetrahedra lock" in text, text.split("\n\n")[1]
    with h5py.File(rows[0]["path"] if "path" in rows[0] else next((out / "runs").glob("p1_*.h5")), "r") as f:
        assert "linear tetrahedra lock" in f.attrs["notes"]


def test_price_stops_a_run_at_the_budget_and_reports_on_ctrl_c(tmp_path):
    """A run under way when --budget ends is stopped there (SIGTERM, its file closed), and the report says so; Ctrl-C
    (SIGINT to the study's process group, as a terminal sends it) ends the run under way, writes the report of
    the runs so far (exit 130) and leaves no child process (issue 47: a run overran the budget by minutes; Ctrl-C
    left no report and an orphaned run)."""
    import signal
    import subprocess
    import time
    from conftest import BIN
    out = tmp_path / "b"
    slow = STATIC.replace("-dt 0.0625", "-dt 0.0002")       # 1,250 load steps: the first run outlasts the budget
    t0 = time.perf_counter()
    run_ok(["study", "price", *BAR, "--watch", "u_y:5,0,0", "--target", "0.001", "--run-args", slow, "--budget",
            "3", "-output_dir", out])
    assert time.perf_counter() - t0 < 3 + 20, "the run was not stopped at the budget"
    text = open(os.path.join(out, "price.md")).read()
    rows = read_csv(os.path.join(out, "price.csv"))
    assert len(rows) == 1 and "stopped at the end of --budget" in rows[0]["message"], rows
    assert "was stopped at it" in text, text.split("\n\n")[1]
    out = tmp_path / "c"
    p = subprocess.Popen([os.path.join(BIN, "hyperelastic"), "study", "price", *BAR, "--watch", "u_y:5,0,0", "--target",
                          "0.001", "--run-args", slow, "-output_dir", str(out)], start_new_session=True,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while not list((out / "runs").glob("*.h5*")) if (out / "runs").exists() else True:   # a run under way
        time.sleep(0.2)
    time.sleep(1.0)
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    text = open(os.path.join(out, "price.md")).read()
    assert "interrupted (Ctrl-C)" in text, text.split("\n\n")[1]
    left = []                                   # processes still in the study's process group (/proc: no pgrep needed)
    for d in os.listdir("/proc"):
        try:
            if d.isdigit() and int(open(f"/proc/{d}/stat").read().rsplit(")", 1)[1].split()[2]) == p.pid:
                left.append(d)
        except (OSError, IndexError, ValueError):
            pass
    assert not left, left
