"""`hyperelastic study accuracy|refinement`: the studies run for real (accuracy's --smoke sweep, refinement's quick
default) and what must hold of them is asserted."""
import json
import math
import os

import numpy as np
import pytest

from conftest import hyperelastic, run_ok
from hyperelastic.studies.experiments.table import read_csv
from hyperelastic.studies.command import measure, plan, report


@pytest.fixture(scope="module")
def accuracy(tmp_path_factory):
    out = tmp_path_factory.mktemp("accuracy")
    run_ok(["study", "accuracy", "--smoke", "-output_dir", out], timeout=900)      # (every part of the study, ~70 runs)
    return out, measure.read_csv(os.path.join(out, "accuracy.csv"))


@pytest.fixture(scope="module")
def refinement(tmp_path_factory):
    out = tmp_path_factory.mktemp("refinement")
    run_ok(["study", "refinement", "-output_dir", out], timeout=900)
    return out, read_csv(os.path.join(out, "refinement.csv"))


def finite(*vals):
    return all(v is not None and math.isfinite(v) for v in vals)


def test_every_sweep_point_is_a_run_with_numbers_or_a_recorded_failure(accuracy):
    out, rows = accuracy
    planned = plan.plan("smoke").runs
    sweep = {r["id"]: r for r in rows if r["role"] == "sweep"}
    assert set(sweep) == {r.id for r in planned}
    for r in sweep.values():
        if r["outcome"] == "failed":
            assert r["message"].startswith("hyperelastic: error:"), r
            assert "Traceback" not in r["message"]
        else:
            assert r["outcome"] in ("finished", "recovered")
            assert finite(r["rel_err"], r["err_final_max"], r["err_traj_rms"], r["energy_drift"], r["solve_s"],
                          r["wall_s"], r["peak_rss_mb"]), r
            assert r["newton_its"] > 0 and r["residual_evals"] > 0 and r["steps"] > 0
    # the thesis' operator fails at the default E = 1e6 (thesis ch. 7): its rows are there, as failures
    assert any(r["mode"] == "seed_fd" and r["outcome"] == "failed" for r in sweep.values())
    for name in ("accuracy.md", "accuracy_pareto.png", "accuracy_cost_vs_E.png"):
        assert os.path.getsize(os.path.join(out, name)) > 1000


def test_reference_is_the_most_accurate_of_its_sweep(accuracy):
    """The reference's own error (|x_h - x_2h| / 3 of its second-order time integration) is below every
    sweep point's error, down to where both are solver noise (< 1e-8 relative)."""
    _, rows = accuracy
    refs = [r for r in rows if r["role"] == "reference"]
    assert len(refs) == len(report.configs(rows))
    for ref in refs:
        cfg = (ref["scene"], ref["material"], ref["E"], ref["level"])
        errs = [r["rel_err"] for r in report.sweep_rows(rows, cfg) if r["outcome"] != "failed"]
        assert ref["outcome"] == "finished" and errs
        assert ref["ref_err_est"] <= max(min(errs), 1e-8), (cfg, ref["ref_err_est"], min(errs))


def test_tightening_the_newton_tolerance_never_increases_the_error_beyond_noise(accuracy):
    _, rows = accuracy
    groups = {}
    for r in report.sweep_rows(rows):
        if r["outcome"] != "failed":
            groups.setdefault((r["scene"], r["material"], r["E"], r["level"], r["mode"], r["pc"], r["h"],
                               r["ksp_rtol"], r["ts_rtol"]), []).append(r)
    ref_err = {(r["scene"], r["material"], r["E"], r["level"]): r["ref_err_est"] for r in rows
               if r["role"] == "reference"}
    compared = 0
    for key, rs in groups.items():
        rs.sort(key=lambda r: -r["snes_rtol"])
        noise = 0.1 * ref_err[key[:4]] + 1e-9
        for loose, tight in zip(rs, rs[1:]):
            compared += 1
            assert tight["rel_err"] <= loose["rel_err"] * (1 + 1e-3) + noise, (key, loose["snes_rtol"], tight["snes_rtol"])
    assert compared >= 20


def test_report_answers_in_numbers_and_the_mesh_error_shrinks(accuracy):
    out, rows = accuracy
    with open(os.path.join(out, "accuracy.md")) as fh:
        text = fh.read()
    first = text.split("\n\n")[1]
    assert "relative error on L1 bend2" in first and "s of solve time" in first and "× less than" in first
    main = report.sweep_rows(rows, ("bend2", "stvk", 1e6, 1))
    target = next(t for t in (1e-3, 1e-2, 1e-1) if report.cheapest(main, t) is not None)   # the tightest met
    best = report.cheapest(main, target)
    assert f"For {target:g} relative error" in first and f"`{report.label(best)}`" in first
    # second order buys the tight targets: generalized-alpha meets 1e-3, no backward-Euler setting does
    assert target == 1e-3 and best["mode"].startswith("alpha2")
    assert report.cheapest([r for r in main if not r["mode"].startswith("alpha2")], 1e-3) is None
    disc = {r["level"]: r["disc_err"] for r in rows if r["role"] == "disc" and r["E"] == 1e6 and r["scene"] == "bend2"}
    assert set(disc) == {1, 2, 3} and disc[3] == 0.0 and disc[1] > disc[2] > 0


def test_from_csv_redoes_the_report(accuracy, tmp_path):
    out, _ = accuracy
    os.remove(os.path.join(out, "accuracy.md"))
    run_ok(["study", "accuracy", "--smoke", "-output_dir", out, "--from-csv"])
    assert os.path.getsize(os.path.join(out, "accuracy.md")) > 1000


def test_refinement_converges_with_an_observed_order(refinement):
    out, rows = refinement
    main = [r for r in rows if not r["twin"]]
    assert [int(r["level"]) for r in main] == [1, 2, 3, 4, 5, 8]
    assert all(r["outcome"] == "finished" for r in rows)
    order = float(main[0]["order_test_point"])
    assert order > 0.5, order
    err = [float(r["err_test_point"]) for r in main[:-1]]
    assert err[0] > err[-1] > 0
    for name in ("refinement.md", "refinement.png"):
        assert os.path.getsize(os.path.join(out, name)) > 1000


def test_refinement_same_answer_on_one_and_two_ranks(refinement):
    _, rows = refinement
    par = [r for r in rows if r["nprocs"] == "2"]
    twin = [r for r in rows if r["twin"] == "True"]
    assert par and twin and par[0]["level"] == twin[0]["level"]
    u1, u2 = np.array(json.loads(twin[0]["u_points"])), np.array(json.loads(par[0]["u_points"]))
    assert np.abs(u1 - u2).max() <= 1e-7 * np.abs(u1).max()


def test_study_bad_arguments_are_one_line():
    for args in (["study"], ["study", "speed"], ["study", "accuracy", "--jobs", "0"]):
        p = hyperelastic(args)
        assert p.returncode == 2, (args, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("hyperelastic: error: hyperelastic study"), p.stderr


def test_refinement_of_a_users_part(tmp_path):
    """`study refinement --part --order 1,2`: the bimaterial bar's .geo meshed and refined twice, the scene run
    on each mesh with linear and with quadratic tetrahedra (10-node meshes of the same cells), the watched end displacement converging (P1: the
    changes shrink, positive order, Richardson), and P2 on the coarsest mesh nearer P1's limit than P1 on the
    finest. (Linear materials: the load in one step, -dt 1, the same displacements as the scene's four steps.)"""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = tmp_path / "study"
    run_ok(["study", "refinement", "--part", f"{root}/examples/bimaterial.geo", "--scene",
            f"{root}/examples/bimaterial.opts", "--size", 0.35, "--refine", 2, "--watch", "point:2,0.125,0.125",
            "--run-args", "-soft_material linear -stiff_material linear -traction 0,2e3,0 -dt 1", "--order", "1,2",
            "-output_dir", out])
    rows = read_csv(out / "refinement.csv")
    p2 = [r for r in rows if r["element_order"] == "2"]
    rows = [r for r in rows if r["element_order"] == "1"]
    assert [r["outcome"] for r in rows + p2] == ["finished"] * 6
    tets = [int(r["tets"]) for r in rows]
    assert tets[1] == 8 * tets[0] and tets[2] == 8 * tets[1]
    q = [float(r["quantity"]) for r in rows]
    assert 0 < q[0] < q[1] < q[2]                       # P1 is too stiff: the deflection grows with refinement
    change = [float(r["change"]) for r in rows]
    assert change[0] > change[1] > change[2] == 0
    assert float(rows[0]["order"]) > 0.5 and float(rows[0]["richardson_limit"]) > q[2]
    limit = float(rows[0]["richardson_limit"])
    assert abs(float(p2[0]["quantity"]) - limit) < abs(q[2] - limit)
    assert (out / "refinement.png").stat().st_size > 1000
    assert "P1: " in (out / "refinement.md").read_text() and "P2: " in (out / "refinement.md").read_text()
    # P2 runs on its own 10-node meshes (as study price's: edge nodes on the geometry), not elevated linear ones
    import meshio
    assert all("_p2" in r["mesh"] for r in p2) and not any("_p2" in r["mesh"] for r in rows)
    assert {c.type for c in meshio.read(p2[0]["mesh"]).cells} >= {"tetra10"}
    assert [int(r["tets"]) for r in p2] == tets


@pytest.mark.parametrize("args, words", [
    (["--part", "x.geo", "--size", "1"], ["--part goes with"]),
    (["--scene", "x.opts"], ["--scene belongs to"]),
    (["--part", "EX/bimaterial.geo", "--scene", "EX/bimaterial.opts", "--size", "0.25", "--watch", "tip"], ["--watch tip"]),
    (["--part", "EX/bimaterial.geo", "--scene", "EX/bimaterial.opts", "--size", "0.25", "--refine", "1"], ["at least 3"]),
    (["--part", "EX/bimaterial.geo", "--scene", "EX/bimaterial.opts", "--size", "-1"], ["--size -1"]),
])
def test_part_refinement_bad_arguments(tmp_path, args, words):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    args = [a.replace("EX/", f"{root}/examples/") for a in args]
    p = hyperelastic(["study", "refinement", "-output_dir", tmp_path / "o", *args])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert all(w in lines[0] for w in words), lines[0]


def test_refinement_says_when_the_meshes_are_not_asymptotic():
    """The report's verdict: q = 1 - h^2 on P1 (expected order 2) is asymptotic and gets Richardson's limit;
    a sequence with p = 0.36 (the bracket of issue 34) or non-monotone changes is not, and no limit is
    presented as the answer; both say what the next refinement would cost."""
    from hyperelastic.studies.part import _verdict, analyse

    def rows(qs):
        return [{"outcome": "finished", "h": 0.5 / 2 ** i, "tets": 100 * 8 ** i, "quantity": q, "solve_s": 0.1 * 9 ** i}
                for i, q in enumerate(qs)]
    good = rows([1 - (0.5 / 2 ** i) ** 2 for i in range(4)])
    analyse(good, expected=2)
    text = _verdict(1, "max_displacement", [r for r in good if r["outcome"] == "finished"])
    assert good[0]["asymptotic_note"] == "" and abs(good[0]["richardson_limit"] - 1) < 1e-12
    assert "Richardson's limit from the three finest: 1 " in text and "next refinement (~409,600 tets)" in text
    assert "about 656 s" in text
    for qs, why in (([3.1e-5, 4.1e-5, 4.9e-5, 5.5e-5], "far from the element's 2"),
                    ([1.0, 1.5, 1.4, 1.45], "do not shrink monotonically")):
        bad = rows(qs)
        analyse(bad, expected=2)
        text = _verdict(1, "max_displacement", bad)
        assert why in bad[0]["asymptotic_note"] and "Not in the asymptotic range" in text
        assert "no limit is extrapolated" in text and "Richardson's limit from" not in text


def test_refinement_of_a_mesh_independent_quantity():
    """A quantity that does not change with the mesh (a reaction balancing a dead load) is said to be so,
    not 'refine further'."""
    from hyperelastic.studies.part import _verdict, analyse
    rows = [{"outcome": "finished", "h": 0.5 / 2 ** i, "tets": 100 * 8 ** i, "quantity": 120 * (1 + d),
             "solve_s": 0.1 * 9 ** i} for i, d in enumerate((3e-9, -2e-9, 4e-9, 1e-9))]
    analyse(rows, expected=2)
    text = _verdict(1, "reaction_z:clamp", rows)
    assert "does not depend on the mesh" in text and "refine further" not in text


def test_the_three_accuracy_plans():
    """--smoke, the quick default and --full (planned, not run): every mode and preconditioner of each is there,
    the thesis' operator in the quick plan at its two largest steps only, each plan's runs distinct, --smoke a subset
    of the quick plan's configurations, and the references' extra runs on the plans' levels."""
    smoke, quick, full = (plan.plan(k) for k in ("smoke", False, True))
    modes = {"assembled", "shell", "snes_mf", "snes_mf_operator", "seed_fd", "alpha2", "alpha2_adapt"}
    for p in (smoke, quick, full):
        assert modes <= {r.mode for r in p.runs} and len(set(p.runs)) == len(p.runs)
        refs, extra = plan.with_references(p)
        assert set(refs) == {r.config for r in p.runs} and {r.role for r in extra} >= {"reference", "check", "disc"}
        disc = {r.level for r in extra if r.role == "disc"}
        assert min(disc) == 1 and max(disc) == p.finest_level and {r.order for r in extra if r.role == "disc"} == {1, 2}
    assert sorted({r.h for r in quick.runs if r.mode == "seed_fd"}) == [0.05, 0.1]
    assert {r.config for r in smoke.runs} <= {r.config for r in quick.runs} and len(smoke.runs) < len(quick.runs) / 2
    assert len(full.runs) > 10 * len(quick.runs)


def test_an_empty_figure_warns_nothing():
    """A study whose runs give nothing to plot draws an empty panel without matplotlib's "No artists with labels"
    warning on stderr (issue 47: it leaked into a study's output); a panel with a labelled line keeps its legend."""
    import warnings
    from hyperelastic.output.figures import legend, pyplot
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2)
    b.plot([1, 2], [1, 2], label="runs")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        legend(a, fontsize=7)
        legend(b, fontsize=7)
    assert a.get_legend() is None and b.get_legend() is not None
    plt.close(fig)
