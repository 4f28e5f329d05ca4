"""The shared layers: the modules' import layers (no circles, nothing imported upward), the declared
statistics columns, the solver recipes read from options/*.opts, the CSV tables."""
import ast
import os
import re

import numpy as np
import pytest

from hyperelastic.solving import stats
from hyperelastic.studies.experiments import recipes, table


def test_recipes_split_into_mode_and_pc():
    assert recipes.pc_of("gamg") == ["-pc_type", "gamg", "-pc_gamg_type", "agg", "-pc_gamg_agg_nsmooths", "1",
                                     "-mg_levels_ksp_type", "chebyshev", "-mg_levels_pc_type", "jacobi"]
    assert recipes.pc_of("bjacobi_icc") == ["-pc_type", "bjacobi", "-sub_pc_type", "icc"]
    assert recipes.without_pc("mffd_operator") == ["-snes_mf_operator", "-jacobian", "assembled", "-mat_mffd_type",
                                                   "wp", "-ksp_type", "gmres"]
    assert recipes.without_pc("reference") == ["-jacobian", "assembled", "-ksp_type", "gmres", "-ksp_gmres_restart",
                                               "100"]
    from hyperelastic.studies.plan import MODES, PCS
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


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PKG = os.path.join(ROOT, "hyperelastic")
DATA = ("data",)                  # package data, not code: hyperelastic/data
ROOT_MODULES = {"__init__": 0, "__main__": None}     # the package's own (lowest) and `python -m` (the cli's layer)


def design_layers():
    """The layer folders of docs/design.md's table ("| N | `folder/` | ... |"), lowest first."""
    rows = []
    for line in open(os.path.join(ROOT, "docs", "design.md"), encoding="utf-8"):
        m = re.match(r"\|\s*(\d+)\s*\|\s*`([a-z_]+)/`\s*\|", line)
        if m:
            rows.append((int(m.group(1)), m.group(2)))
    assert [n for n, _ in rows] == list(range(1, len(rows) + 1)), rows
    return [f for _, f in rows]


def layer_of(rel, layers):
    """The layer index (1-based) of a package file given relative to hyperelastic/ (a module path list)."""
    if len(rel) == 1:
        return ROOT_MODULES[rel[0]] if ROOT_MODULES[rel[0]] is not None else len(layers)
    return layers.index(rel[0]) + 1


def python_modules():
    """{module path (tuple, relative to hyperelastic/, packages as their __init__): file}."""
    out = {}
    for root, dirs, files in os.walk(PKG):
        dirs[:] = [d for d in dirs if d != "__pycache__" and d not in DATA]
        for f in files:
            if f.endswith(".py"):
                out[tuple(os.path.relpath(os.path.join(root, f), PKG)[:-3].split(os.sep))] = os.path.join(root, f)
    return out


def resolve(mods, path):
    """The module file a dotted path (tuple) names: a module, or a package's __init__; None when neither."""
    if path in mods:
        return path
    if path + ("__init__",) in mods:
        return path + ("__init__",)
    return None


def python_imports():
    """{module: {modules of the package it imports}}, from every import statement, inside functions too; an
    import of names from a package counts as an import of those that are its modules, else of its __init__."""
    mods = python_modules()
    graph = {}
    for mod, path in mods.items():
        pkg = mod[:-1]
        edges = graph.setdefault(mod, set())
        for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = pkg[:len(pkg) - (node.level - 1)]
                target = base + tuple(node.module.split(".") if node.module else ())
            elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "hyperelastic":
                target = tuple(node.module.split(".")[1:])
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == "hyperelastic" and resolve(mods, tuple(a.name.split(".")[1:])):
                        edges.add(resolve(mods, tuple(a.name.split(".")[1:])))
                continue
            else:
                continue
            for a in node.names:
                sub = resolve(mods, target + (a.name,))
                hit = sub or resolve(mods, target)
                if hit and hit != mod:
                    edges.add(hit)
    return graph


def circle(graph):
    """A circle of the graph as a list of nodes, or None."""
    state = {}

    def visit(m, path):
        state[m] = 1
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state:
                found = visit(n, path + [n])
                if found:
                    return found
        state[m] = 2
        return None
    for m in sorted(graph):
        if m not in state:
            found = visit(m, [m])
            if found:
                return found
    return None


def test_the_folders_are_the_layers_of_the_design():
    """docs/design.md's layer table lists exactly the package's folders; its root holds only the package's own
    modules."""
    layers = design_layers()
    folders = sorted(d for d in os.listdir(PKG) if os.path.isfile(os.path.join(PKG, d, "__init__.py")))
    assert sorted(layers) == folders, (layers, folders)
    loose = sorted(f[:-3] for f in os.listdir(PKG) if f.endswith(".py"))
    assert loose == sorted(ROOT_MODULES), loose
    for d in folders:                          # each layer says what it is
        doc = ast.get_docstring(ast.parse(open(os.path.join(PKG, d, "__init__.py"), encoding="utf-8").read()))
        assert doc and doc.startswith(f"Layer {layers.index(d) + 1}, {d}:"), (d, doc)


def test_no_import_circles_and_no_import_upward():
    layers = design_layers()
    graph = python_imports()
    up = [("/".join(a), "/".join(b)) for a, bs in graph.items() for b in bs
          if layer_of(b, layers) > layer_of(a, layers)]
    assert not up, f"imports from a lower layer to a higher one: {up}"
    found = circle(graph)
    assert found is None, "import circle: " + " -> ".join("/".join(m) for m in found)


def c_files():
    out = {}
    for root, _, files in os.walk(PKG):
        for f in files:
            if f.endswith((".c", ".h")):
                out[os.path.relpath(os.path.join(root, f), PKG)] = os.path.join(root, f)
    return out


GENERATED = ("he_materials.h",)     # setup.py's: each material's header, then the two loops (per material)


def c_includes(files):
    """{file: {files of the package it includes}}: a quoted include resolved from the file's folder, then from the
    build's include directories (discretization/, physics/); the generated header stands for what it includes."""
    graph = {}
    dirs = ["discretization", "physics"]
    materials = [f for f in files if f.startswith(os.path.join("physics", "materials")) and f.endswith(".h")
                 and not os.path.basename(f).startswith("_")]
    for f, path in files.items():
        edges = graph.setdefault(f, set())
        for inc in re.findall(r'^\s*#\s*include\s+"([^"]+)"', open(path, encoding="utf-8").read(), re.M):
            if inc in GENERATED:
                edges.update(materials + [os.path.join("discretization", "_material_loops.h"),
                                          os.path.join("discretization", "_element_loops.h")])
                continue
            for d in [os.path.dirname(f)] + dirs:
                cand = os.path.normpath(os.path.join(d, inc))
                if cand in files:
                    edges.add(cand)
                    break
            else:
                raise AssertionError(f"{f}: #include \"{inc}\" is not a file of the package")
    return graph


def closure(graph, f):
    seen, todo = set(), [f]
    while todo:
        for n in graph.get(todo.pop(), ()):
            if n not in seen:
                seen.add(n)
                todo.append(n)
    return seen


C_DEFINITION = re.compile(r"^\s*#\s*define\s+(\w+)|^(?:HE_INLINE|static inline)[^(=;]*?\b(\w+)\s*\(|"
                          r"^\}\s*(\w+)\s*;|^typedef\s+[^;{]*?\b(\w+)\s*;", re.M)


def test_c_headers_include_what_they_use_and_no_circle():
    """The kernels' C files in layers like the Python (discretization's loops include physics' material headers,
    never the other way), no include circle, and every helper a file uses defined in itself or in a file it
    includes (the loops once used helpers only _kernels.c defined: _kernels.c -> loops -> _kernels.c)."""
    layers = design_layers()
    files = c_files()
    graph = c_includes(files)
    found = circle(graph)
    assert found is None, "include circle: " + " -> ".join(found)
    up = [(a, b) for a, bs in graph.items() for b in bs
          if layers.index(b.split(os.sep)[0]) > layers.index(a.split(os.sep)[0])]
    assert not up, f"includes from a lower layer to a higher one: {up}"
    defined = {}
    for f, path in files.items():
        for m in C_DEFINITION.finditer(open(path, encoding="utf-8").read()):
            name = next(g for g in m.groups() if g)
            defined.setdefault(name, set()).add(f)
    for f, path in files.items():
        text = re.sub(r"/\*.*?\*/|//[^\n]*", "", open(path, encoding="utf-8").read(), flags=re.S)
        visible = closure(graph, f) | {f}
        for name in set(re.findall(r"\b[A-Za-z_]\w*\b", text)) & set(defined):
            if not defined[name] & visible and "MATERIAL" not in name:
                raise AssertionError(f"{f} uses {name}, defined in {sorted(defined[name])}, which it does not include")


def test_no_function_over_60_lines():
    """Issue 48 item 7: every function and method of the package fits on a screen (60 lines with its docstring)."""
    long = []
    for d, _, files in os.walk(PKG):
        for f in files:
            if f.endswith(".py"):
                path = os.path.join(d, f)
                for n in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
                    if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno >= 60:
                        long.append(f"{os.path.relpath(path, PKG)}:{n.lineno} {n.name} ({n.end_lineno - n.lineno + 1})")
    assert long == [], long


def probes(source):
    """Where a module's code probes an object instead of asking a declared seam (issue 69 item 1): `hasattr`, `getattr`
    with a default, or a comparison of some `.name` with a string. [(line, what)]"""
    out = []
    for n in ast.walk(ast.parse(source)):
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name):
            if n.func.id == "hasattr" or (n.func.id == "getattr" and len(n.args) + len(n.keywords) >= 3):
                out.append((n.lineno, n.func.id))
        elif isinstance(n, ast.Compare):
            sides = [n.left] + list(n.comparators)
            named = any(isinstance(s, ast.Attribute) and s.attr == "name" for s in sides)
            strings = any(isinstance(s, ast.Constant) and isinstance(s.value, str) or
                          isinstance(s, (ast.Tuple, ast.List, ast.Set)) and
                          any(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in s.elts) for s in sides)
            if named and strings:
                out.append((n.lineno, "name comparison"))
    return out


def test_the_solver_reaches_effects_and_constraints_through_declared_seams():
    """Issue 69 item 1: solving/ and formulations/ ask effects and constraints only what they declare (base.Effect, the
    seams of physics/effects/seams.py, dirichlet.HeldBody): no hasattr, no getattr with a default, no comparison of a
    name with a string. The checker itself finds each of the three forms."""
    bad = "hasattr(e, 'max_step')\ngetattr(e, 'kappa_range', None)\nc.name == 'rigid'\ne.name in ('a', 'b')\n"
    assert [w for _, w in probes(bad)] == ["hasattr", "getattr", "name comparison", "name comparison"]
    assert probes("getattr(e, name)\nx.name == y\nx.kind == 'plane'\n") == []
    found = []
    for layer in ("solving", "formulations"):
        for d, _, files in os.walk(os.path.join(PKG, layer)):
            for f in sorted(files):
                if f.endswith(".py"):
                    path = os.path.join(d, f)
                    found += [f"{os.path.relpath(path, PKG)}:{line} {what}"
                              for line, what in probes(open(path, encoding="utf-8").read())]
    assert found == [], found


def test_scripts_have_one_entry_point_and_one_launcher():
    """Issue 69 item 6: `python scripts` lists every script of the folder by name with its first line; `python scripts
    NAME ARGS` runs it (an unknown name: exit 2); no script builds a launch command of hyperelastic of its own (each
    goes through scripts/launch.py, or the package's studies runner)."""
    import subprocess
    import sys
    here = os.path.join(os.path.dirname(PKG), "scripts")
    names = sorted(f[:-3] for f in os.listdir(here) if f.endswith((".py", ".sh")) and f not in ("__main__.py",
                                                                                               "launch.py"))
    p = subprocess.run([sys.executable, here], capture_output=True, text=True, timeout=60)
    listed = [ln.split()[0] for ln in p.stdout.splitlines()[1:]]
    assert p.returncode == 0 and listed == names and all(len(ln.split()) > 1 for ln in p.stdout.splitlines()[1:])
    assert subprocess.run([sys.executable, here, "compare_versions", "--help"], capture_output=True,
                          timeout=60).returncode == 0
    assert subprocess.run([sys.executable, here, "nowhere"], capture_output=True, timeout=60).returncode == 2
    own = []
    for f in names:
        path = os.path.join(here, f + ".py")
        if os.path.exists(path):
            text = open(path, encoding="utf-8").read()
            if re.search(r'"-m", "hyperelastic"|bin", "hyperelastic"|\(BIN, "hyperelastic"\)', text):
                own.append(f)
    assert own == [], own
