"""Installed as a package (pip install ., not editable: a wheel built and copied out of the repository), the
application finds its scenes, recipes and geometries from any directory (issue 48), and an internal error on two
ranks is one line."""
import os
import subprocess
import sys

from conftest import ROOT, mpiexec


def test_installed_package_runs_from_any_directory(tmp_path):
    site, work = tmp_path / "site", tmp_path / "elsewhere"
    work.mkdir()
    env = dict(os.environ, HYPERELASTIC_CFLAGS="-O0", PIP_DISABLE_PIP_VERSION_CHECK="1")   # (a quick compile)
    p = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target",
                        site, ROOT], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    env = dict(os.environ, PYTHONPATH=str(site), HYPERELASTIC_MESH_CACHE=str(tmp_path / "cache"))
    exe = str(site / "bin" / "hyperelastic")           # the console script of the installed package

    def run(*args):
        p = subprocess.run([exe, *map(str, args)], cwd=work, env=env, capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, (args, p.stderr[-2000:])
        return p
    where = subprocess.run([sys.executable, "-c", "import hyperelastic; print(hyperelastic.__file__)"], cwd=work,
                           env=env, capture_output=True, text=True).stdout
    assert where.startswith(str(site)), where             # the copy, not the repository
    assert "bend" in run("scenes").stdout.split()
    assert "tets" in run("mesh", "bar", "--level", "1", "-o", "bar.msh").stdout
    out = run("run", "bend", "-final_time", "0.02", "-options_file", "options/gamg.opts", "-output", "o.h5")
    assert "wrote o.h5" in out.stderr and (work / "o.h5").stat().st_size > 0
    run("run", "twist", "-mesh", "bar.msh", "-final_time", "0.02", "-options_file", "direct", "-output", "t.h5")
    bad = subprocess.run([exe, "run", "bend", "-options_file", "nosuch"], cwd=work, env=env, capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "the package's recipes" in bad.stderr and "gamg" in bad.stderr, bad.stderr


def test_an_internal_error_on_two_ranks_is_one_line():
    """Every rank raises the same internal error: it is printed once (rank 0's abort ends the job before the
    others print theirs), not once per rank run together on a line."""
    code = ("import sys, hyperelastic.cli.main as m\n"
            "m.COMMANDS['scenes'] = lambda argv: 1 / 0\n"
            "sys.exit(m.main(['scenes']))\n")
    p = subprocess.run([mpiexec(), "-n", "2", sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    lines = [ln for ln in p.stderr.splitlines() if "hyperelastic: error:" in ln]
    assert p.returncode != 0 and len(lines) == 1 and lines[0].startswith("hyperelastic: error: internal error: "
                                                                           "ZeroDivisionError"), p.stderr
