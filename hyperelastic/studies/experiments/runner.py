"""Running `hyperelastic run` as a child process for the studies (stability matrix, accuracy and
refinement studies): one process per run, so that every run starts from a clean PETSc options
database, and a run that fails or hangs is a recorded outcome rather than the end of the sweep.
One-rank runs start warm (core/warm.py: forked from a server that has done the imports, ~0.4 s less per
run); under mpiexec, or where warm starts are not available, they are exec'd."""
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from ...core import warm


def mpiexec():
    """mpiexec next to the Python running us (the mpich wheel puts it in the venv's bin), else on PATH."""
    here = os.path.join(os.path.dirname(sys.executable), "mpiexec")
    return here if os.path.exists(here) else (shutil.which("mpiexec") or "mpiexec")


def command(args, nprocs=1):
    """The command line of `python -m hyperelastic ARGS`, under mpiexec -n nprocs when nprocs > 1."""
    cmd = [sys.executable, "-m", "hyperelastic"] + [str(a) for a in args]
    return [mpiexec(), "-n", str(nprocs)] + cmd if nprocs > 1 else cmd


# after a run's time is up it gets SIGTERM (it stops after the step under way, its file closed and checkpointed:
# mpiexec forwards the signal to the ranks) and this long to end before SIGKILL
GRACE_S = 15.0


def run_hyperelastic(args, output, nprocs=1, timeout=900, grace=GRACE_S):
    """(exit status, stderr, wall seconds) of `python -m hyperelastic ARGS` writing `output` (removed
    first, so that a stale file is never read as this run's result); nprocs > 1 runs it under mpiexec. A run
    past `timeout` is stopped (SIGTERM, then SIGKILL after `grace` s; grace 0: SIGKILL at once, for a run nothing of
    which is kept): exit status -1, stderr 'timed out after ...'.
    On Ctrl-C (KeyboardInterrupt here; the child, in the same process group, got the SIGINT too) the child is
    given GRACE_S to end before it is killed, and the interrupt goes on: no child outlives the study."""
    if os.path.exists(output):
        os.remove(output)
    cmd = command(args, nprocs)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = warm.launch(warm.entry_for(cmd[3:]), cmd[3:], MAIN, env=env) if nprocs == 1 else None
    if p is None:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        _, err = p.communicate(timeout=timeout)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        if grace > 0:
            p.terminate()
        _end(p, grace)
        rc, err = -1, f"timed out after {timeout:g} s"
    except KeyboardInterrupt:
        _end(p)
        raise
    return rc, err, time.perf_counter() - t0


MAIN = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "__main__.py")


def _end(p, grace=GRACE_S):
    """Wait up to `grace` s for a signalled child, then kill it."""
    try:
        p.communicate(timeout=grace)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()


def last_line(stderr, rc):
    """The one-line message of a failed run (its last non-empty stderr line)."""
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else f"exit status {rc}"


def parallel_map(fn, items, jobs=2, log=None):
    """[fn(item)] in order, `jobs` at a time; log(result) as each arrives."""
    out = []
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
        for r in ex.map(fn, items):
            out.append(r)
            if log:
                log(r)
    return out
