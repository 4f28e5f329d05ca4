"""The recipes of docs/design.md hold: a throw-away material added by 'Add a material' in a copy of the package
(its NAME.py, its NAME.h and one registry line) is everywhere the registry reaches — its option value, -help, the
mixed formulation's split materials, the hard-case matrix, the compiled kernels (checked against its numpy
reference) — and a run with it finishes (issue 48)."""
import difflib
import os
import shutil
import subprocess
import sys

from conftest import ROOT

CHECK = r"""
import numpy as np
from hyperelastic.app.catalog import markdown_table
from hyperelastic.discretization.kernels import CellKernels
from hyperelastic.formulations.mixed import split_materials
from hyperelastic.physics.materials import MATERIALS, default_solid
from hyperelastic.studies.stability import MATERIALS as MATRIX, SPLIT_MATERIALS
assert "`toy` (a throw-away copy of linear)" in markdown_table()
assert "toy" in split_materials() and "toy" in MATRIX and "toy" in SPLIT_MATERIALS
m, c = MATERIALS["toy"], default_solid("toy").constants
rng = np.random.default_rng(1)
F = np.eye(3) + 0.1 * rng.standard_normal((5, 3, 3))
x = np.einsum("nij,aj->nai", F, np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])).reshape(-1).copy()
k = CellKernels(np.arange(20, dtype=np.int32).reshape(5, 4), np.broadcast_to(np.eye(3), (5, 3, 3)).copy(),
                np.full(5, 1 / 6), m, c)
f = np.zeros_like(x)
k.forces(x, f)
G = np.concatenate([-np.ones((1, 3)), np.eye(3)])
ref = np.einsum("nij,aj->nai", m.P(F, c) / 6, G).reshape(-1)
assert np.abs(f - ref).max() <= 1e-12 * np.abs(ref).max()
print("ok")
"""


def test_a_material_added_by_its_recipe_reaches_everything(tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(os.path.join(ROOT, "hyperelastic"), copy / "hyperelastic",
                    ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    shutil.copy(os.path.join(ROOT, "setup.py"), copy)
    mats = copy / "hyperelastic" / "physics" / "materials"
    (mats / "toy.py").write_text("from .linear import Linear\n\n\nclass Toy(Linear):\n    name = \"toy\"\n"
                                 "    summary = \"a throw-away copy of linear\"\n\n\nMATERIAL = Toy\n")
    (mats / "toy.h").write_text((mats / "linear.h").read_text().replace("linear_", "toy_"))
    before = (mats / "__init__.py").read_text()
    after = before.replace('REGISTRY = ("linear", ', 'REGISTRY = ("linear", "toy", ')
    (mats / "__init__.py").write_text(after)
    changed = [ln for ln in difflib.unified_diff(before.splitlines(), after.splitlines(), n=0)
               if ln[:1] in "+-" and not ln.startswith(("+++", "---"))]
    assert len(changed) == 2, changed                     # the registry line, nothing else
    env = dict(os.environ, HYPERELASTIC_CFLAGS="-O0", PYTHONPATH=str(copy))
    p = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--inplace"], cwd=copy, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    p = subprocess.run([sys.executable, "-c", CHECK], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert p.stdout.split() == ["ok"], p.stderr[-2000:]
    p = subprocess.run([sys.executable, "-m", "hyperelastic", "run", "bend", "-material", "toy", "-final_time", "0.02",
                        "-output", tmp_path / "o.h5", "-quiet"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert p.returncode == 0 and (tmp_path / "o.h5").stat().st_size > 0, p.stderr[-2000:]
