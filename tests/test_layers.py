"""The shared layers: the declared statistics columns, the solver recipes read from options/*.opts,
the CSV tables."""
import numpy as np
import pytest

from hyperelastic import stats
from hyperelastic.experiments import recipes, table


def test_recipes_split_into_mode_and_pc():
    assert recipes.pc_of("gamg") == ["-pc_type", "gamg", "-pc_gamg_type", "agg", "-pc_gamg_agg_nsmooths", "1",
                                     "-mg_levels_ksp_type", "chebyshev", "-mg_levels_pc_type", "jacobi"]
    assert recipes.pc_of("bjacobi_icc") == ["-pc_type", "bjacobi", "-sub_pc_type", "icc"]
    assert recipes.without_pc("mffd_operator") == ["-snes_mf_operator", "-jacobian", "assembled", "-mat_mffd_type",
                                                   "wp", "-ksp_type", "gmres"]
    assert recipes.without_pc("reference") == ["-jacobian", "assembled", "-ksp_type", "gmres", "-ksp_gmres_restart",
                                               "100"]
    from hyperelastic.study.plan import MODES, PCS
    assert MODES["seed_fd"][-2:] == ["-step_control", "0"] and PCS["none"] == ["-pc_type", "none"]


def test_stats_columns_are_declared():
    assert stats.column_type("newton_its") is int and stats.column_type("wall_s") is float
    assert stats.column_type("effect_traction_evals") is int
    assert stats.column_type("effect_elasticity_seconds") is float
    with pytest.raises(KeyError):
        stats.column_type("newton_iterations")
    st = {"rejected": np.array([0, 1, 0]), "kinetic": np.array([1.0, 9.0, 2.0]), "elastic": np.array([3.0, 9.0, 4.0]),
          "traction_work": np.array([1.0, 9.0, 1.0])}
    assert stats.accepted(st).tolist() == [True, False, True]
    assert stats.total_energy(st).tolist() == [3.0, 5.0]
    assert stats.total_energy(st, with_work=False).tolist() == [4.0, 6.0]


def test_csv_round_trip(tmp_path):
    rows = [{"a": 1.0 / 3, "b": "x", "n": 3}, {"a": None, "b": "y", "n": 4, "extra": 1}]
    path = tmp_path / "t.csv"
    table.write_csv(path, rows, ["a", "b", "n"])
    back = table.read_csv(path, {"a": float, "n": int})
    assert back == [{"a": 0.333333, "b": "x", "n": 3}, {"a": None, "b": "y", "n": 4}]
    assert not (tmp_path / "t.csv.part").exists()
