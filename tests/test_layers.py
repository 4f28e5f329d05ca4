"""The shared layers: the modules' import layers (no circles, nothing imported upward), the declared
statistics columns, the solver recipes read from options/*.opts, the CSV tables."""
import ast
import os

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


# The layers of docs/design.md ("Map of the code"), lowest first: a module imports only modules of its own
# layer or below. Sub-packages count as one module (their inside is their own business).
LAYERS = [
    ["errors", "libpetsc", "__init__", "element"],
    ["expressions", "sets", "files", "faces"],
    ["options", "mesh", "plot", "figures"],
    ["materials"],
    ["kernels", "effects"],
    ["scene", "stats", "space", "system", "fields"],
    ["catalog", "model", "mixed", "aij", "jacobians", "solver", "output", "integrators", "forces"],
    ["ts_integrator", "run", "stability", "study", "repro", "experiments", "report"],
    ["cli", "__main__"],
]


def imports_of_package():
    """{module: {modules of the package it imports}} from every import statement, inside functions too."""
    pkg = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "hyperelastic")
    graph = {}
    for root, _, files in os.walk(pkg):
        for f in files:
            if not f.endswith(".py"):
                continue
            rel = os.path.relpath(os.path.join(root, f), pkg)[:-3].split(os.sep)
            name = rel[0]
            level_base = rel[:-1]                             # the package the file is in, relative to pkg
            tree = ast.parse(open(os.path.join(root, f), encoding="utf-8").read())
            for node in ast.walk(tree):
                targets = []
                if isinstance(node, ast.ImportFrom) and node.level:
                    base = level_base[:len(level_base) - (node.level - 1)] if node.level > 1 else level_base
                    mod = base + (node.module.split(".") if node.module else [])
                    targets = [mod + [a.name] for a in node.names] if not node.module else [mod]
                elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hyperelastic"):
                    targets = [node.module.split(".")[1:]]
                for t in targets:
                    if t and t[0] != name and os.path.exists(os.path.join(pkg, t[0])) or \
                            t and t[0] != name and os.path.exists(os.path.join(pkg, t[0] + ".py")):
                        graph.setdefault(name, set()).add(t[0])
            graph.setdefault(name, set())
    return graph


def test_no_import_circles_and_no_import_upward():
    graph = imports_of_package()
    layer = {m: i for i, ms in enumerate(LAYERS) for m in ms}
    assert set(graph) <= set(layer), f"modules missing from LAYERS (docs/design.md): {set(graph) - set(layer)}"
    up = [(a, b) for a, bs in graph.items() for b in bs if layer[b] > layer[a]]
    assert not up, f"imports from a lower layer to a higher one: {up}"
    state = {}

    def visit(m, path):
        state[m] = 1
        for n in graph.get(m, ()):
            if state.get(n) == 1:
                raise AssertionError(f"import circle: {' -> '.join(path[path.index(n):] + [n])}")
            if n not in state:
                visit(n, path + [n])
        state[m] = 2
    for m in graph:
        if m not in state:
            visit(m, [m])
