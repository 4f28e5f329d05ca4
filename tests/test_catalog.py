"""The option catalog (hyperelastic/app/catalog.py) is the one list of the application's options: the
options reference (docs/reference/options.md) is generated from it, `run --help` prints it, and every option the source reads is in it."""
import os
import re

import pytest

from conftest import ROOT, hyperelastic, run_ok
from hyperelastic.app import catalog
from hyperelastic.physics import materials
from hyperelastic.app.scene import ASSEMBLIES, EFFECTS, INTEGRATORS, JACOBIANS, STORAGES
from hyperelastic.formulations import NAMES as FORMULATIONS


def test_the_options_reference_is_the_catalog():
    """docs/reference/options.md is the catalog's page as `python -m hyperelastic.app.catalog --reference` writes it."""
    text = open(os.path.join(ROOT, "docs", "reference", "options.md"), encoding="utf-8").read()
    assert text == catalog.reference_page(), "docs/reference/options.md drifted: make docs"
    assert text.count("\n| `-") == len(catalog.ROWS)


def source_option_names():
    """Every option name the application reads through Options (literal names, and the f-string
    templates of prefixed ones with their placeholder)."""
    names = set()
    pkg = os.path.join(ROOT, "hyperelastic")
    mods = [os.path.relpath(os.path.join(r, f), pkg) for r, _, fs in os.walk(pkg) for f in fs if f.endswith(".py")]
    for mod in mods:
        src = open(os.path.join(ROOT, "hyperelastic", mod), encoding="utf-8").read()
        for m in re.finditer(r'opts\.(?:string|real|integer|flag|choice|vector|names|has)\((f?)"([^"]+)"', src):
            f, name = m.groups()
            if not f:
                names.add(name)
        names |= set(re.findall(r'(?:facet|volume)_sets\(opts, "([a-z_]+)"', src))
        names |= {f"{p}_{k}" for p in re.findall(r'time_function\(opts, "([a-z_]+)"\)', src) for k in ("time", "ramp")}
    return names - {"snes_mf", "snes_mf_operator"}           # PETSc's, read to refuse combinations


def test_every_option_read_is_in_the_catalog():
    known = set(catalog.option_names())
    missing = source_option_names() - known
    assert not missing, f"options read but not in the catalog: {sorted(missing)}"
    for prefix, names in (("REGION_", ("material", "preset", "E", "nu", "rho", "C10", "C01", "kappa", "mu")),
                          ("LOAD_", ("traction", "pressure", "force", "spring", "faces", "time", "ramp"))):
        assert {prefix + n for n in names} <= {n for r in catalog.ROWS for n in r.names}
    for prefix in ("traction", "pressure", "force", "body_force"):   # time functions of the un-named loads
        assert {f"{prefix}_time", f"{prefix}_ramp"} <= known
    assert catalog.CHOICES == {"material": materials.REGISTRY, "jacobian": JACOBIANS, "assembly": ASSEMBLIES,
                               "operator_storage": STORAGES, "integrator": INTEGRATORS, "effects": EFFECTS,
                               "formulation": FORMULATIONS}
    for row in catalog.ROWS:
        if row.names[0] in ("material", "jacobian", "assembly", "operator_storage", "integrator", "formulation"):
            for choice in catalog.CHOICES[row.names[0]]:
                assert choice in row.help + row.synopsis, (row.names[0], choice)


def test_help_lists_every_option_and_runs_nothing(tmp_path):
    p = run_ok(["run", "--help"])
    for name in catalog.option_names(["REGION"], ["LOAD"]):
        if not name.startswith(("REGION", "LOAD")):
            assert f"-{name}" in p.stdout, name
    assert "<1e+06, 0.3, 1000>" in p.stdout and "<stvk>" in p.stdout
    from hyperelastic.app.scene import EFFECTS_RULE
    assert "replaces the scene file's effects" in EFFECTS_RULE and EFFECTS_RULE.replace("`", "")[:40] in " ".join(p.stdout.split())
    out = tmp_path / "o.h5"
    p = run_ok(["run", "bend", "-help", "-dt", "0.02", "-output", out])
    assert "<dt=0.02>" in p.stdout                       # the scene's value, not the default
    assert "-ksp_rtol" in p.stdout and "-snes_linesearch_type" in p.stdout     # PETSc's own
    assert not out.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("args,words", [
    (["-materail", "neohookean"], ["unknown option -materail", "did you mean -material?"]),
    (["-prescribe_face", "right"], ["unknown option -prescribe_face", "did you mean -prescribe_faces?"]),
    (["-snes_rtoll", "1e-3"], ["-snes_rtoll", "did you mean -snes_rtol?"]),
    (["-pc_tpye", "lu"], ["-pc_tpye", "did you mean -pc_type?"]),
    (["-ts_type", "alpha2"], ["-ts_type", "-integrator ts"]),
    (["-regions", "soft", "-sotf_E", "1e5"], ["-sotf_E", "did you mean -soft_E?"]),
    (["-soft_E", "1e5"], ["unknown option -soft_E"]),
    (["-loads", "pull", "-pull_traction", "1,0,0", "-pull_faces", "right", "-pull_tme", "t"],
     ["-pull_tme", "did you mean -pull_time?"]),
])
def test_unknown_options_are_refused_before_anything_runs(tmp_path, args, words):
    out = tmp_path / "o.h5"
    p = hyperelastic(["run", "bend", "-quiet", "-output", out, *args], timeout=30)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and all(w in lines[0] for w in words), p.stderr
    assert not out.exists()


def test_lazily_read_petsc_options_still_work(tmp_path):
    """Options PETSc reads only at PCSetUp or at the end of a solve (sub-solvers, multigrid levels,
    viewers, MFFD) pass the check and take effect."""
    out = tmp_path / "o.h5"
    p = run_ok(["run", "bend", "-final_time", "0.02", "-output", out, "-quiet", "-pc_type", "bjacobi",
                "-sub_pc_type", "icc", "-sub_ksp_type", "preonly", "-snes_view", "-snes_linesearch_order", "2"])
    assert "PC Object: (sub_)" in p.stdout and "type: icc" in p.stdout
    p = run_ok(["run", "bend", "-final_time", "0.02", "-output", out, "-quiet", "-pc_type", "gamg",
                "-pc_gamg_threshold", "0.01", "-mg_levels_ksp_type", "richardson", "-ksp_view"])
    assert "type: gamg" in p.stdout and "richardson" in p.stdout
    run_ok(["run", "bend", "-final_time", "0.02", "-output", out, "-quiet", "-snes_mf_operator", "-mat_mffd_type",
            "ds", "-integrator", "ts", "-ts_adapt_type", "basic", "-ts_rtol", "1e-3", "-ts_view"])


def test_the_guide_lists_every_preset_with_its_values():
    """Issue 70 item 6: docs/guide/scenes.md's table of presets is materials.PRESETS."""
    text = open(os.path.join(ROOT, "docs", "guide", "scenes.md"), encoding="utf-8").read()
    rows = re.findall(r"^\| `(\w+)` \| (\S+) \| (\S+) \| (\S+) \|$", text, re.M)
    assert {name: tuple(map(float, v)) for name, *v in rows} == materials.PRESETS

