"""The suite's one-rank `hyperelastic` commands start warm: forked from a server that has done the imports
(hyperelastic/core/warm.py, the studies' way of starting runs), ~0.4 s less each. Each is still its own
process (its own PETSc, options, file descriptors, exit status, signals). Commands whose arguments or
environment a warm start cannot carry as an exec'd one would (not UTF-8; another environment than the
server's) are exec'd, and so is everything under mpiexec."""
import os
import subprocess
import sys
import threading

from hyperelastic.core.warm import Server

BIN = os.path.dirname(sys.executable)
EXE = os.path.join(BIN, "hyperelastic")
_SERVER = []
_LOCK = threading.Lock()


def server():
    """This test process's warm server (started at its first command), or None."""
    with _LOCK:
        if not _SERVER:
            _SERVER.append(Server.start("hyperelastic.cli.main:main", volatile=("PYTEST_CURRENT_TEST",)))
        return _SERVER[0]


def _sendable(args):
    try:
        for a in args:
            a.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def run(args, cwd=None, timeout=600, text=True):
    """subprocess.run([hyperelastic] + ARGS, capture_output=True, ...) for one rank."""
    args = [str(a) for a in args]
    s = server()
    if s is None or not s.accepts(os.environ) or not _sendable(args):
        return subprocess.run([EXE] + args, capture_output=True, text=text, timeout=timeout, cwd=cwd)
    try:
        p = s.popen(args, EXE, cwd=None if cwd is None else str(cwd), env=os.environ, text=text)
    except OSError:            # refused (Refused: the package's files changed since the server loaded them), or gone
        return subprocess.run([EXE] + args, capture_output=True, text=text, timeout=timeout, cwd=cwd)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        raise
    return subprocess.CompletedProcess([EXE] + args, p.returncode, out, err)
