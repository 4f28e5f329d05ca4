"""The suite's one-rank `hyperelastic` commands start warm: forked from a server that has done the imports
(hyperelastic/core/warm.py, the studies' way of starting runs), ~0.4 s less each. Each is still its own
process (its own PETSc, options, file descriptors, exit status, signals). Commands whose arguments or
environment a warm start cannot carry as an exec'd one would (not UTF-8; another environment than the
server's) are exec'd. Under mpiexec each rank starts warm from the server for its command (rank_command)."""
import os
import subprocess
import sys

from hyperelastic.core.warm import entry_for, launch, shared

BIN = os.path.dirname(sys.executable)
EXE = os.path.join(BIN, "hyperelastic")
VOLATILE = ("PYTEST_CURRENT_TEST",)


def rank_command(args):
    """The command each rank under mpiexec runs to start `hyperelastic ARGS` warm (ARGS follow it), or [EXE] where
    warm starts are unavailable."""
    server = shared(entry_for([str(a) for a in args]), volatile=VOLATILE)
    if server is None or not server.accepts(os.environ):
        return [EXE]
    cmd = server.rank_command(EXE)
    # under coverage (its subprocess patch sets COVERAGE_PROCESS_START or _CONFIG) the client keeps `site`, through
    # which coverage enters a Python process: `-S` would leave the client's lines unmeasured
    measured = os.environ.get("COVERAGE_PROCESS_START") or os.environ.get("COVERAGE_PROCESS_CONFIG")
    return [a for a in cmd if a != "-S"] if measured else cmd


def run(args, cwd=None, timeout=600, text=True):
    """subprocess.run([hyperelastic] + ARGS, capture_output=True, ...) for one rank."""
    args = [str(a) for a in args]
    p = launch(entry_for(args), args, EXE, cwd=cwd, text=text, volatile=VOLATILE)
    if p is None:
        return subprocess.run([EXE] + args, capture_output=True, text=text, timeout=timeout, cwd=cwd)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        raise
    return subprocess.CompletedProcess([EXE] + args, p.returncode, out, err)
