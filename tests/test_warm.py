"""Warm starts (hyperelastic/core/warm.py): a forked child is the exec'd command, output for output."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import BIN, read_h5
from hyperelastic.core.warm import RUN_ENTRY, Server, entry_for

EXE = os.path.join(BIN, "hyperelastic")
RUN = ["run", "bend", "-final_time", "0.1", "-dt", "0.05", "-ksp_rtol", "1e-8"]


@pytest.fixture(scope="module")
def server():
    s = Server.start("hyperelastic.cli.main:main", volatile=("PYTEST_CURRENT_TEST",))
    if s is None:
        pytest.skip("no warm starts on this system (needs fork and pidfds)")
    yield s
    s.close()


@pytest.fixture(scope="module")
def run_server(server):
    """The runs' server (cli/warm_run.py): petsc4py's and mpi4py's modules imported, neither initialized, the modules
    a run uses loaded; it comes up wherever cli.main's does."""
    s = Server.start(RUN_ENTRY, volatile=("PYTEST_CURRENT_TEST",))
    assert s is not None
    yield s
    s.close()


def exec_run(args, cwd):
    return subprocess.run([EXE] + args, capture_output=True, text=True, cwd=cwd, timeout=120)


def lines(text, *names):
    """The lines of TEXT without their timings ([...]) and with the output names NAMES read as a.h5."""
    out = []
    for ln in text.splitlines():
        ln = ln.split("[")[0]
        for name in names:
            ln = ln.replace(name, "a.h5")
        out.append(ln)
    return out


def warm_run(server, args, cwd):
    p = server.popen(args, EXE, cwd=str(cwd), env=os.environ)
    out, err = p.communicate(timeout=120)
    return p.returncode, out, err


def test_a_warm_run_is_the_exec_run(server, run_server, tmp_path):
    """The same exit status, the same lines (but for the timings and the file name) and the same positions
    bit for bit, from either server; a bad option is the same one line; `scenes` prints the same. Runs go to the runs'
    server, everything else (`run --help` too) to cli.main's."""
    a = exec_run(RUN + ["-output", "a.h5"], tmp_path)
    rc, out, err = warm_run(server, RUN + ["-output", "b.h5"], tmp_path)
    assert a.returncode == rc == 0, err
    rc2, out2, err2 = warm_run(run_server, RUN + ["-output", "d.h5"], tmp_path)
    assert rc2 == 0 and out2 == out and err2.replace("d.h5", "b.h5").split("[")[0] == err.split("[")[0], err2
    assert np.array_equal(read_h5(tmp_path / "a.h5")["x"], read_h5(tmp_path / "d.h5")["x"])
    for args in (["run", "bend", "-E", "abc"], ["run", "bend", "-bogus", "1"], ["run", "--restart", "nosuch.h5"]):
        e = exec_run(args, tmp_path)
        assert (e.returncode, e.stdout, e.stderr) == warm_run(run_server, args, tmp_path), args
    assert entry_for(RUN) == RUN_ENTRY and entry_for(["run", "--help"]) != RUN_ENTRY
    assert entry_for(["scenes"]) != RUN_ENTRY and entry_for(["run"]) != RUN_ENTRY
    # PETSc is finalized as at an interpreter's exit: -log_view writes its report
    assert warm_run(server, RUN + ["-output", "c.h5", "-log_view", ":log.txt"], tmp_path)[0] == 0
    assert "SNESSolve" in (tmp_path / "log.txt").read_text()

    assert lines(a.stderr) == lines(err, "b.h5") and a.stdout == out
    x1, x2 = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    assert np.array_equal(x1["x"], x2["x"]) and x1["attrs"]["options"].replace("a.h5", "b.h5") == x2["attrs"]["options"]
    for args in (["run", "bend", "-E", "abc"], ["run", "bend", "-bogus", "1"], ["scenes"], ["nosuch"]):
        e = exec_run(args, tmp_path)
        assert (e.returncode, e.stdout, e.stderr) == warm_run(server, args, tmp_path), args


def test_signals_and_exit_statuses_reach_the_caller(server, tmp_path):
    """SIGTERM stops the run cleanly at a step (status 143, a checkpoint to continue from); SIGKILL is the
    signal's negative status, as Popen's; the child has its own process id and working directory."""
    p = server.popen(["run", "bend", "-final_time", "50", "-output", "long.h5"], EXE, cwd=str(tmp_path), env=os.environ)
    assert p.pid != os.getpid() and p.poll() is None
    time.sleep(2.0)
    p.terminate()
    _, err = p.communicate(timeout=60)
    assert p.returncode == 128 + signal.SIGTERM and "--restart long.h5" in err, err
    p = server.popen(["run", "bend", "-final_time", "50", "-output", "k.h5"], EXE, cwd=str(tmp_path), env=os.environ)
    time.sleep(1.0)
    p.kill()
    for _ in range(600):                   # poll() reads without blocking and sees the end
        if p.poll() is not None:
            break
        time.sleep(0.1)
    assert p.returncode == -signal.SIGKILL and p.wait(timeout=60) == -signal.SIGKILL
    p = server.popen(["run", "bend", "-final_time", "50", "-output", "t.h5"], EXE, cwd=str(tmp_path), env=os.environ)
    with pytest.raises(subprocess.TimeoutExpired):
        p.communicate(timeout=0.5)
    p.kill()                               # (not left running through the rest of the suite)
    assert p.wait(timeout=60) == -signal.SIGKILL


def test_the_server_is_clean_and_ends_with_its_client(tmp_path):
    """Another environment is not served (libraries read theirs when loaded); a server that would hold MPI
    initialized does not start; the server ends when the process that started it ends."""
    code = ("import sys, time\nfrom hyperelastic.core.warm import Server\n"
            "s = Server.start('json:dumps')\nprint(s.proc.pid, s.path, flush=True)\n"
            "import os\nprint(s.accepts(os.environ), s.accepts(dict(os.environ, OMP_NUM_THREADS='4')), flush=True)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    (pid, path), ok = p.stdout.splitlines()[0].split(), p.stdout.splitlines()[1]
    assert ok == "True False", p.stderr
    for _ in range(100):
        if not os.path.exists(f"/proc/{pid}") or "Z" in open(f"/proc/{pid}/stat").read().split()[2]:
            break
        time.sleep(0.1)
    else:
        raise AssertionError("the server outlived its client")
    for _ in range(50):          # and it removed its socket's folder
        if not os.path.exists(os.path.dirname(path)):
            break
        time.sleep(0.1)
    else:
        raise AssertionError(f"{path} left behind")
    # a preload that initializes MPI is refused: the server does not come up, callers exec
    assert Server.start("hyperelastic.cli.main:main", preload=["mpi4py.MPI"]) is None


EDIT_PROBE = """
import os, sys, time
from hyperelastic.core.warm import Refused, Server
s = Server.start("hyperelastic.cli.main:main")
c = s.popen(["scenes"], sys.argv[1])
out, _ = c.communicate(timeout=60)
print(c.returncode == 0 and "bend" in out)
import hyperelastic.cli.main as m
os.utime(m.__file__, ns=(time.time_ns(), time.time_ns() + 10**9))
try:
    s.popen(["scenes"], sys.argv[1])
    print("started")
except Refused:
    print("refused")
print(Server.start("hyperelastic.cli.main:main", env=dict(os.environ, PYTHONPATH=sys.argv[2])) is None)
"""


def test_edited_sources_and_another_package_are_refused(tmp_path):
    """A package file edited after the server loaded it: the command is refused (the caller execs it), never run
    as a mix of loaded and edited code. A server whose import of the entry module finds another file than the
    client's (here: another copy first on its path) does not start."""
    import shutil
    import hyperelastic
    src = os.path.dirname(os.path.abspath(hyperelastic.__file__))
    for d in ("a", "b"):
        shutil.copytree(src, tmp_path / d / "hyperelastic", ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "a"))
    p = subprocess.run([sys.executable, "-c", EDIT_PROBE, EXE, str(tmp_path / "b")], capture_output=True, text=True,
                       timeout=180, cwd=str(tmp_path), env=env)
    assert p.stdout.split() == ["True", "refused", "True"], p.stdout + p.stderr


def ranks(server, n, args, cwd, env=None):
    """`mpiexec -n N` of ARGS, each rank started warm from `server` (MPICH_THROTTLE: conftest's environment)."""
    from conftest import mpiexec
    return subprocess.Popen([mpiexec(), "-n", str(n)] + server.rank_command(EXE) + args, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=str(cwd),
                            env=dict(os.environ if env is None else env))


def children(server):
    return subprocess.run(["pgrep", "-P", str(server.proc.pid)], capture_output=True, text=True).stdout.split()


def until(ready, p, timeout=60):
    """Wait for ready() while the mpiexec `p` runs."""
    t0 = time.time()
    while not ready():
        assert p.poll() is None and time.time() - t0 < timeout, p.communicate(timeout=60)
        time.sleep(0.05)


def test_mpi_ranks_start_warm_and_are_the_exec_ranks(run_server, tmp_path):
    """Two ranks started warm under mpiexec: the exec'd ranks' status, lines and positions bit for bit, from children
    of the server; a rank the server refuses (here: another environment) execs itself and gives the same answer."""
    from conftest import mpiexec
    a = subprocess.run([mpiexec(), "-n", "2", EXE] + RUN + ["-output", "a.h5"], capture_output=True, text=True,
                       cwd=str(tmp_path), timeout=120)
    before = set(children(run_server))
    p = ranks(run_server, 2, RUN + ["-output", "b.h5", "-log_view", ":log.txt"], tmp_path)
    seen = set()
    while p.poll() is None:                  # (the ranks are the server's children while they run)
        seen.update(children(run_server))
        time.sleep(0.02)
    out, err = p.communicate(timeout=120)
    assert a.returncode == p.returncode == 0 and len(seen - before) == 2, (seen, before, err)
    assert "with 2 processes" in (tmp_path / "log.txt").read_text()

    assert lines(a.stderr) == lines(err, "b.h5") and a.stdout == out
    assert np.array_equal(read_h5(tmp_path / "a.h5")["x"], read_h5(tmp_path / "b.h5")["x"])
    q = ranks(run_server, 2, RUN + ["-output", "c.h5"], tmp_path, env=dict(os.environ, HYPERELASTIC_PROBE="1"))
    out, err = q.communicate(timeout=120)
    assert q.returncode == 0 and lines(err, "c.h5") == lines(a.stderr), err
    assert np.array_equal(read_h5(tmp_path / "a.h5")["x"], read_h5(tmp_path / "c.h5")["x"])


def _alive(pid):
    """Whether process pid runs (not a zombie); a process that ends while /proc is read is not (reading its stat then
    raised ProcessLookupError: the check raced the end it waits for)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return "Z" not in fh.read().split()[2]
    except OSError:
        return False


def test_mpi_ranks_started_warm_take_signals_and_die_with_their_clients(run_server, tmp_path):
    """SIGTERM to mpiexec reaches both warm ranks through their clients: the run stops cleanly at a step (143, one
    line naming the restart); a client killed with SIGKILL (as the launcher kills ranks) takes its child with it."""
    p = ranks(run_server, 2, ["run", "bend", "-final_time", "50", "-quiet", "-output", "long.h5"], tmp_path)
    until(lambda: (tmp_path / "long.h5").exists(), p)
    time.sleep(1.0)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 128 + signal.SIGTERM and "--restart long.h5" in err and len(err.splitlines()) == 1, err
    before = set(children(run_server))
    p = ranks(run_server, 2, ["run", "bend", "-final_time", "50", "-output", "k.h5"], tmp_path)
    until(lambda: len(set(children(run_server)) - before) >= 2, p)
    kids = set(children(run_server)) - before
    clients = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True, text=True).stdout.split()
    proxies = [c for c in clients if "proxy" in open(f"/proc/{c}/cmdline").read()] or clients
    rank_clients = subprocess.run(["pgrep", "-P", proxies[0]], capture_output=True, text=True).stdout.split()
    os.kill(int(rank_clients[0]), signal.SIGKILL)
    p.communicate(timeout=60)
    assert p.returncode != 0
    for _ in range(100):
        if not any(_alive(k) for k in kids):
            break
        time.sleep(0.1)
    else:
        raise AssertionError(f"a warm rank outlived its client: {kids}")


def test_a_warm_child_sets_the_packages_environment_as_an_exec_would(monkeypatch):
    """The package's environment settings (hyperelastic.process_environment) are made again in each warm child (its
    environment is its caller's): MPICH's throttle where the launcher counts more ranks on the node than CPUs; an
    explicit setting wins."""
    import hyperelastic
    from hyperelastic import MPICH_THROTTLE
    for name in MPICH_THROTTLE:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MPI_LOCALNRANKS", str(os.cpu_count()))
    hyperelastic.process_environment()
    assert not any(name in os.environ for name in MPICH_THROTTLE)
    monkeypatch.setenv("MPI_LOCALNRANKS", str(os.cpu_count() + 1))
    monkeypatch.setenv("MPIR_CVAR_CH4_PROGRESS_THROTTLE_NO_PROGRESS_COUNT", "7")
    hyperelastic.process_environment()
    assert os.environ["MPIR_CVAR_CH4_PROGRESS_THROTTLE"] == "true"
    assert os.environ["MPIR_CVAR_CH4_PROGRESS_THROTTLE_NO_PROGRESS_COUNT"] == "7"


ABORT_PROBE = """
from hyperelastic.core import warm
warm._uninitialized_imports()
import hyperelastic.cli.warm_run as w
from mpi4py import MPI
MPI.Init_thread(MPI.THREAD_MULTIPLE)
from hyperelastic.cli import main as m
m._abort_if_parallel(1)          # (an internal error before PETSc is initialized: one rank, nothing to abort)
print(m._comm() is None)
"""


def test_an_error_before_petsc_starts_in_a_warm_run_is_still_one_line():
    """In a child of the runs' server PETSc's module is imported before PETSc is initialized: an internal error raised
    before the run initializes it takes MPI's own world to decide whether to abort (as an exec'd run, which has not
    imported PETSc then), not PETSc's null one."""
    p = subprocess.run([sys.executable, "-c", ABORT_PROBE], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.split() == ["True"], p.stdout + p.stderr
