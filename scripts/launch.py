"""The one way the scripts start hyperelastic (benchmarks, reproductions, device runs): a run is this venv's Python with
`-m hyperelastic` (the package of a given checkout on PYTHONPATH: compare_versions' older revision), under this venv's
mpiexec on more than one rank. `run` gives the finished process and its wall seconds, `ok` the same or stops the script
with the run's error. (The studies inside the package start theirs through hyperelastic/studies/experiments/runner.py,
warm; a benchmark times whole processes, so these are exec'd.)

    python scripts NAME [ARGS]      # scripts/__main__.py: every script by name; `python scripts` lists them"""
import os
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.dirname(sys.executable)
EXAMPLES = os.path.join(ROOT, "examples")
OPTIONS = os.path.join(ROOT, "options")


def mpiexec():
    """The venv's mpiexec (the mpich wheel's), else the one on PATH."""
    return shutil.which("mpiexec", path=BIN) or shutil.which("mpiexec") or "mpiexec"


def command(args, nprocs=1, launcher=None):
    """The command line of `hyperelastic ARGS` on nprocs ranks (launcher: an mpiexec of the caller's)."""
    cmd = [sys.executable, "-m", "hyperelastic", *map(str, args)]
    return [launcher or mpiexec(), "-n", str(nprocs)] + cmd if nprocs > 1 else cmd


def run(args, nprocs=1, code=None, timeout=None, cwd=None, launcher=None):
    """(CompletedProcess with text output, wall seconds) of `hyperelastic ARGS`; code: a checkout whose package runs
    instead of the installed one."""
    env = dict(os.environ, **({"PYTHONPATH": code} if code else {}))
    t0 = time.perf_counter()
    p = subprocess.run(command(args, nprocs, launcher), capture_output=True, text=True, timeout=timeout, cwd=cwd,
                       env=env)
    return p, time.perf_counter() - t0


def ok(args, **kw):
    """run(ARGS), the script stopped with the run's last error lines where it failed."""
    p, wall = run(args, **kw)
    if p.returncode:
        sys.exit(f"failed: hyperelastic {' '.join(map(str, args))}\n{p.stderr[-2000:]}")
    return p, wall
