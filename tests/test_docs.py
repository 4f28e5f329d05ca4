"""The user guide (issue 69 item 5): every command its pages show runs as written, page by page, in order, each page in
a scratch directory that holds the project's .venv, examples/ and scripts/ and nothing else; what a page says a command
prints, it prints; the README's first runs are lines of the guide; the site builds with `mkdocs build --strict` (no
warning, no link to a page or an anchor that is not there)."""
import glob
import math
import os
import re
import shlex
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT

GUIDE = os.path.join(ROOT, "docs", "guide")
# commands the guide shows that other tests run on smaller grids (their time would add minutes to the suite), or run as
# written and check (their time would be paid twice): the key, the test (checked to exist) and how it runs the command
LONG = {"examples/coil.opts": ("test_contact.py::test_a_twisted_rod_coils_onto_itself_and_never_through", "coarser"),
        "study price": ("test_price.py::test_price_answers_first_and_its_answer_meets_the_target", "another part"),
        "examples/stack.opts": ("test_contact.py::test_blocks_pressed_together_carry_one_blocks_homogeneous_compression",
                                "as written"),
        "examples/slot.opts": ("test_contact.py::test_a_slot_pressed_shut_never_passes_through_itself", "as written"),
        "examples/tube.opts": ("test_contact.py::test_a_flattened_rubber_tube_closes_on_itself_with_the_mixed_formulation",
                               "as written")}


def commands(path):
    """The lines of a page's ```sh blocks that start with .venv/bin/ (a trailing comment cut), in order."""
    text = open(path, encoding="utf-8").read()
    out = []
    for block in re.findall(r"```sh\n(.*?)```", text, re.S):
        for line in block.splitlines():
            if line.startswith(".venv/bin/"):
                out.append(re.sub(r"\s+#.*$", "", line.strip()))
    return out


def pages():
    return sorted(os.path.basename(p)[:-3] for p in glob.glob(os.path.join(GUIDE, "*.md")))


def run_page(name, tmp_path, timeout=600):
    """[(command, CompletedProcess)] of the page's commands run in tmp_path (LONG ones left out)."""
    for d in ("examples", "scripts"):
        os.symlink(os.path.join(ROOT, d), tmp_path / d)
    os.symlink(os.path.dirname(BIN), tmp_path / ".venv")
    (tmp_path / "output").mkdir()
    done = []
    for c in commands(os.path.join(GUIDE, name + ".md")):
        if any(key in c for key in LONG):
            continue
        p = subprocess.run(c, shell=True, cwd=tmp_path, capture_output=True, text=True, timeout=timeout,
                           stdin=subprocess.DEVNULL)
        assert p.returncode == 0, f"{name}: {c}\n{p.stderr[-2000:]}"
        done.append((c, p))
    return done


CHECKED = ("your-part", "rubber", "scenes")        # (the pages with checks of their own below)


@pytest.mark.parametrize("page", [p for p in pages() if p not in CHECKED and commands(os.path.join(GUIDE, p + ".md"))])
def test_a_guide_page_runs_as_written(page, tmp_path):
    assert run_page(page, tmp_path)


def test_the_commands_left_out_are_run_elsewhere():
    """Each LONG command's test exists; where it runs the command as written, its file holds the guide's mesh size."""
    import ast
    guide = [c for p in pages() for c in commands(os.path.join(GUIDE, p + ".md"))]
    for key, (test, how) in LONG.items():
        assert any(key in c for c in guide), key
        name, func = test.split("::")
        src = open(os.path.join(ROOT, "tests", name), encoding="utf-8").read()
        assert func in {n.name for n in ast.walk(ast.parse(src)) if isinstance(n, ast.FunctionDef)}, test
        if how == "as written":
            example = key.split("/")[1].split(".")[0]
            size = [c for c in guide if f"examples/{example}.geo" in c][0].split("--size ")[1].split()[0]
            assert f'"{example}.geo"), "--size", {size},' in src, (key, size)


def test_scenes_page_runs_as_written(tmp_path):
    done = run_page("scenes", tmp_path)
    assert len(done) >= 9 and any("mpiexec" in c for c, _ in done)
    for f in ("output/bend.h5", "output/twist3.h5", "output/bar8.msh", "output/bracket.h5", "output/bend.png",
              "output/twist3.png"):
        assert (tmp_path / f).stat().st_size > 0, f


def test_your_part_runs_as_written_and_prints_what_it_shows(tmp_path):
    """The bracket meshed and run prints what the page shows: its set lines, the STEP part's surfaces table, the forces
    table from `report`; both pictures are drawn."""
    text = open(os.path.join(GUIDE, "your-part.md"), encoding="utf-8").read()
    shown = {"bracket": [ln.strip() for ln in text.split("loads `load`", 1)[1].split("```text\n", 1)[1]
                         .split("```", 1)[0].splitlines()],
             "bimaterial": [text.split("prints `", 1)[1].split("`", 1)[0]]}
    done = run_page("your-part", tmp_path)
    assert len(done) == 9 and done[0][0].startswith(".venv/bin/hyperelastic mesh examples/")
    for c, p in done:
        if "bracket.step" in c:              # the STEP part's surfaces table
            assert "surface_1          326      0.0048  (0, 0.03, 0.04)" in p.stdout, p.stdout
            assert "surface_8           42      0.0006  (0.1, 0.03, 0.005)                   +x" in p.stdout, p.stdout
        if "bracket_step.msh -fix surface_1" in c:
            assert "reaction surface_1 (holds xyz): F = (" in p.stderr and "set surface_8: 42 facets" in p.stderr, p.stderr
        if " report " in c:
            assert "forces at t = 1" in p.stdout and "at (0.1, 0.03, 0.005), frame" in p.stdout, p.stdout
        if " run " in c and "bracket_step" not in c:
            for line in shown["bracket" if "bracket" in c else "bimaterial"]:
                assert line in p.stderr, line                       # the set lines the page shows
    assert (tmp_path / "output" / "bracket.png").stat().st_size > 10000
    assert (tmp_path / "output" / "bracket_von_mises.png").stat().st_size > 10000


def test_rubber_runs_as_written_and_meets_rivlin(tmp_path):
    """Cook's membrane: the tip "within 0.5% of the converged 6.92 mm"; the rod's torque within 0.1% of Rivlin's
    closed form M = (pi/2) mu (psi/L) a^4 for an incompressible neo-Hookean cylinder, as the page says."""
    done = run_page("rubber", tmp_path)
    with h5py.File(tmp_path / "output" / "cook.h5", "r") as f:
        X, x = f["mesh/points"][:], f["x"][-1]
    tip = (abs(X[:, 0] - 48) < 1e-9) & (abs(X[:, 1] - 60) < 1e-9)
    assert abs((x - X)[tip, 1].mean() / 6.922 - 1) < 0.005
    # the O-ring (issue 70 item 7): the forces table's rows add up to all_held and balance the plate; report --contact's
    # patch half-width is the largest x of the nodes the last frame has within dhat of the plate (computed here from
    # the positions and the plate's place), and its force per slice the statistics'
    import h5py as _h5
    with _h5.File(tmp_path / "output" / "oring.h5", "r") as f:
        x, st = f["x"][-1], {k: f["stats"][k][:] for k in f["stats"]}
        rec = {r["name"]: np.array(r["F"]) for r in __import__("json").loads(f.attrs["forces"])["forces"]}
    rows = sum(F for n, F in rec.items() if n not in ("all_held", "contact"))
    assert np.abs(rows - rec["all_held"]).max() <= 1e-12 * np.abs(rec["all_held"]).max()
    assert abs(rec["all_held"][1] + rec["contact"][1]) <= 1e-8 * abs(rec["contact"][1])
    plate = 0.00177 - 0.3 * 0.001765                  # (its y at t = 1)
    dhat = 1e-3 * np.sqrt(0.001765 ** 2 * 2 + 0.0002 ** 2)
    width = x[plate - x[:, 1] < dhat, 0].max()
    line = [p for c, p in done if "--contact" in c][0].stdout.splitlines()[-1]
    assert f"patch extent ({width:.6g}, " in line and f"F = (-0, {st['obstacle1_Fy'][-1]:.6g}, " in line, line
    report = [p for c, p in done if "moment_z:top" in c][0]
    m = re.search(r"moment_z:top:0,0,0\.04 = (\S+)", report.stdout)
    assert m, report.stdout
    mu, a, L, psi = 5e5, 0.01, 0.04, math.pi / 2
    assert abs(float(m.group(1)) / (math.pi / 2 * mu * (psi / L) * a ** 4) - 1) < 1e-3, m.group(1)


def test_the_readmes_first_runs_are_lines_of_the_guide():
    """Every command of the README runs as the guide's same line does (those run above)."""
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    readme = [ln.strip() for ln in text.split("## Three first runs", 1)[1].split("\n## ", 1)[0].splitlines()
              if ln.startswith("    .venv/bin/")]
    guide = {c for p in pages() for c in commands(os.path.join(GUIDE, p + ".md"))}
    assert len(readme) == 9 and [c for c in readme if c not in guide] == []
    assert len(text.splitlines()) <= 200


def test_the_site_builds_without_warnings_or_dead_links(tmp_path):
    """`mkdocs build --strict` (mkdocs.yml: a link to a missing page or anchor, a page outside the navigation, an
    absolute link are warnings, and --strict makes a warning an error); the options reference is the catalog's
    (test_catalog.py)."""
    p = subprocess.run([os.path.join(BIN, "mkdocs"), "build", "--strict", "-d", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    assert (tmp_path / "site" / "index.html").exists() and (tmp_path / "site" / "guide" / "contact.html").exists()
    bad = subprocess.run([os.path.join(BIN, "mkdocs"), "build", "--strict", "-d", str(tmp_path / "bad"),
                          "-f", str(_broken_config(tmp_path))], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert bad.returncode != 0 and "nowhere.md" in bad.stdout + bad.stderr      # (the check can fail)


def _broken_config(tmp_path):
    """A copy of the site with one dead link, to show that the strict build refuses it."""
    import shutil
    docs = tmp_path / "docs"
    shutil.copytree(os.path.join(ROOT, "docs"), docs)
    (docs / "index.md").write_text((docs / "index.md").read_text() + "\n[gone](nowhere.md)\n")
    cfg = open(os.path.join(ROOT, "mkdocs.yml"), encoding="utf-8").read().replace("docs_dir: docs",
                                                                                    f"docs_dir: {shlex.quote(str(docs))}")
    path = tmp_path / "mkdocs.yml"
    path.write_text(cfg)
    return path
