"""Warm starts: a fork server that has imported the libraries a command needs (numpy, h5py, the package's
PETSc-free modules) and loaded PETSc's shared library without initializing it, and forks one child per
command. Each child is its own process, as an exec'd one: its own PETSc and MPI (initialized in the child,
from the child's own arguments: a fresh options database), its own file descriptors, working directory,
environment, exit status and signals. What it saves is the interpreter's start and the imports, ~0.4 s of
the ~0.75 s a one-step run on the bar costs here: the studies' child runs and the test suite start ~1,000
of them.

The server is started with `python -m hyperelastic.core.warm SOCKET ENTRY PRELOAD...` (ENTRY "module:function",
the function taking the argument list and returning the exit status, as `python -m hyperelastic` runs it; the
entry module's WARM_PRELOAD names more modules to import, those its commands import that initialize nothing)
and forks from a clean state: one thread, nothing of MPI or PETSc initialized (refused otherwise). Only
POSIX systems with pidfds (Linux >= 5.3): elsewhere `Server.start` returns None and callers exec.

Where a child would differ from an exec'd process, callers exec instead: an environment other than the server's (the
libraries read theirs when loaded), `HYPERELASTIC_WARM=0`.

An MPI rank starts warm too, under MPICH's mpiexec (Hydra): `mpiexec -n N` runs `server.rank_command(EXE) + ARGS`,
a small client (`python -S -I warm.py --rank`, no site, no package: ~0.03 s) that hands the server its standard
streams, its PMI socket (the descriptor named by PMI_FD, at the same number) and its environment; the child then
initializes MPI from them as the exec'd rank would. The client forwards the signals the launcher sends, ends with
the child's status, and where it dies (the launcher kills ranks with SIGKILL) the server kills its child. Where the
server refuses (edited files, another environment but for the launcher's variables, no PMI_FD) the client execs
EXE itself."""
import atexit
import ctypes
import fcntl
import gc
import glob
import importlib
import importlib.util
import json
import os
import selectors
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

# PETSc's own extension module (and through it libpetsc and libmpi): loaded, not imported (importing it
# initializes PETSc and MPI)
_SHARED = ("petsc4py", os.path.join("lib", "PETSc.*.so"))
_HEADER = struct.Struct("!I")
# what MPICH's launcher adds to a rank's environment (a rank's request is served where the rest is the server's);
# the descriptors it names are handed to the child at their numbers
_LAUNCHER_PREFIXES = ("PMI_", "MPI_LOCAL", "HYDI_", "HYDRA_")
_LAUNCHER_NAMES = ("GFORTRAN_UNBUFFERED_PRECONNECTED", "LINES", "COLUMNS", "_")
_LAUNCHER_FDS = ("PMI_FD", "HYDI_CONTROL_FD")
_FORWARDED = (signal.SIGHUP, signal.SIGINT, signal.SIGQUIT, signal.SIGTERM, signal.SIGUSR1, signal.SIGUSR2)


def _send(sock, obj, fds=()):
    data = json.dumps(obj).encode()
    socket.send_fds(sock, [_HEADER.pack(len(data)) + data], list(fds))


def _recv(sock, maxfds=0):
    """(the next message, the file descriptors sent with it); (None, []) at the end of the connection."""
    buf, fds = b"", []
    while len(buf) < _HEADER.size or len(buf) < _HEADER.size + _HEADER.unpack(buf[:_HEADER.size])[0]:
        data, got, _, _ = socket.recv_fds(sock, 1 << 16, maxfds)
        fds += got
        if not data:
            for fd in fds:
                os.close(fd)
            return None, []
        buf += data
    return json.loads(buf[_HEADER.size:]), fds


def _fixed(env, volatile, rank=False):
    """env without the variables a command may change: the volatile ones, and a rank's launcher's."""
    return {k: v for k, v in env.items() if k not in volatile
            and not (rank and (k.startswith(_LAUNCHER_PREFIXES) or k in _LAUNCHER_NAMES))}


def usable():
    return (os.environ.get("HYPERELASTIC_WARM", "1") != "0" and hasattr(os, "pidfd_open")
            and hasattr(socket, "send_fds") and hasattr(socket, "AF_UNIX"))


class Server:
    """The client's handle on a running fork server (one per process that starts commands; thread-safe)."""

    def __init__(self, proc, path, env, volatile):
        self.proc, self.path, self.env, self.volatile = proc, path, env, tuple(volatile)

    @classmethod
    def start(cls, entry, preload=(), env=None, timeout=60.0, volatile=()):
        """A server for ENTRY ("module:function") with the modules `preload` imported, in environment `env`
        (default: this one), or None where warm starts are not available or the server did not come up.
        `volatile`: variables a command's environment may change (no library reads them when it loads)."""
        if not usable():
            return None
        env = dict(os.environ if env is None else env)
        spec = importlib.util.find_spec(entry.split(":")[0])
        if spec is None or not spec.origin:
            return None
        path = os.path.join(tempfile.mkdtemp(prefix="hyperelastic-warm-"), "socket")
        # (its stdin is a pipe from here: the server ends when this process does, however it ends)
        proc = subprocess.Popen([sys.executable, "-m", __name__, path, entry, spec.origin, ",".join(volatile),
                                 *preload], env=env,
                                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        server = cls(proc, path, env, volatile)
        t0 = time.monotonic()
        while not os.path.exists(path + ".ready"):
            if proc.poll() is not None or time.monotonic() - t0 > timeout:
                server.close()          # (a refusal: another package first on its path, MPI held, no socket)
                return None
            time.sleep(0.01)
        atexit.register(server.close)
        return server

    def accepts(self, env):
        """Whether a command in environment `env` may start here: the server is up, the environment is its own
        (but for the volatile variables) and can be sent (text)."""
        try:
            json.dumps(dict(env)).encode()
        except (UnicodeEncodeError, TypeError, ValueError):
            return False
        return self.proc.poll() is None and _fixed(env, self.volatile) == _fixed(self.env, self.volatile)

    def rank_command(self, exe):
        """The command that starts one MPI rank of EXE warm from this server (followed by EXE's arguments, under
        MPICH's mpiexec; the rank execs EXE where the server refuses it)."""
        return [sys.executable, "-S", "-I", os.path.abspath(__file__), "--rank", self.path, exe]

    def popen(self, args, argv0, cwd=None, env=None, text=True):
        """A Child running ENTRY(args) with sys.argv = [argv0] + args, its stdout and stderr piped here (str
        where `text`, else bytes). Raises Refused where the server would not start it (the package's files
        changed since the server loaded them): exec it then."""
        return Child(self, args, argv0, cwd or os.getcwd(), dict(self.env if env is None else env), text)

    def close(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc.stdin.close()
        _remove(self.path)


# the package's commands: a run starts from a server with its modules loaded (cli/warm_run.py), anything else from
# cli.main's (`run --help` among them: it initializes PETSc as an import does, with no arguments)
ENTRY, RUN_ENTRY = "hyperelastic.cli.main:main", "hyperelastic.cli.warm_run:main"


def entry_for(args):
    """The warm server's entry for `hyperelastic ARGS`."""
    return RUN_ENTRY if len(args) > 1 and args[0] == "run" and args[1] not in ("--help", "-help", "-h") else ENTRY


_SHARED_SERVERS = {}
_SHARED_LOCK = threading.Lock()


def shared(entry, env=None, volatile=()):
    """This process's server for ENTRY (started at its first command, again if it has gone; in the environment of
    that first command), or None where warm starts are unavailable."""
    with _SHARED_LOCK:
        server = _SHARED_SERVERS.get(entry, False)
        if server is False or (server is not None and server.proc.poll() is not None):
            server = _SHARED_SERVERS[entry] = Server.start(entry, env=env, volatile=volatile)
    return server


def launch(entry, args, argv0, cwd=None, env=None, text=True, volatile=()):
    """ENTRY(args) started warm from this process's server for ENTRY (started at its first command, again if it
    has gone; in the environment of that first command): a Child; or None where the command is to be exec'd
    (warm starts unavailable, another environment, arguments that are not UTF-8, refused, the server gone)."""
    env = dict(os.environ if env is None else env)
    args = [str(a) for a in args]
    try:
        for a in args:
            a.encode("utf-8")
    except UnicodeEncodeError:
        return None
    server = shared(entry, env, volatile)
    if server is None or not server.accepts(env):
        return None
    try:
        return server.popen(args, argv0, cwd=None if cwd is None else str(cwd), env=env, text=text)
    except OSError:            # refused (Refused: the package's files changed since the server loaded them), or gone
        return None


class Refused(OSError):
    """The server did not start the command (callers exec it instead)."""


class Child:
    """A forked command, used like subprocess.Popen with stdout=PIPE, stderr=PIPE, text=True: pid,
    returncode, communicate(timeout), wait(timeout), poll(), send_signal/terminate/kill."""

    def __init__(self, server, args, argv0, cwd, env, text=True):
        self.returncode, self.text = None, text
        out_r, out_w = os.pipe()
        err_r, err_w = os.pipe()
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._sock.connect(server.path)
            _send(self._sock, {"args": [str(a) for a in args], "argv0": argv0, "cwd": cwd, "env": env},
                  [out_w, err_w])
        except OSError:
            for fd in (out_r, err_r):
                os.close(fd)
            self._sock.close()
            raise
        finally:
            os.close(out_w)
            os.close(err_w)
        msg, _ = _recv(self._sock)
        if msg is None or "pid" not in msg:
            for fd in (out_r, err_r):
                os.close(fd)
            self._sock.close()
            raise Refused(f"warm start refused: {msg and msg.get('error')}")
        self.pid = msg["pid"]
        self._bufs = {out_r: [], err_r: []}
        self._out, self._err = out_r, err_r
        self._sel = selectors.DefaultSelector()
        for fd in (out_r, err_r, self._sock.fileno()):
            self._sel.register(fd, selectors.EVENT_READ)
        self._lock = threading.Lock()

    def _pump(self, timeout):
        """Read what is there until both pipes are closed and the status has come; False at the timeout."""
        end = None if timeout is None else time.monotonic() + timeout
        while self._sel.get_map():
            left = None if end is None else max(0.0, end - time.monotonic())
            events = self._sel.select(left)
            if not events and left is not None and end - time.monotonic() <= 0:
                return False
            for key, _ in events:
                fd = key.fd
                if fd == self._sock.fileno():
                    msg, _ = _recv(self._sock)
                    # (no message: the server went before the child's status came; reported as a kill)
                    self.returncode = -signal.SIGKILL if msg is None else msg["returncode"]
                    self._sel.unregister(fd)
                    self._sock.close()
                    continue
                data = os.read(fd, 1 << 16)
                if data:
                    self._bufs[fd].append(data)
                else:
                    self._sel.unregister(fd)
                    os.close(fd)
        return True

    def communicate(self, timeout=None):
        with self._lock:
            if not self._pump(timeout):
                raise subprocess.TimeoutExpired(["hyperelastic"], timeout)
        out = tuple(b"".join(self._bufs[fd]) for fd in (self._out, self._err))
        return tuple(o.decode("utf-8", "replace") for o in out) if self.text else out

    def wait(self, timeout=None):
        self.communicate(timeout)
        return self.returncode

    def poll(self):
        with self._lock:
            self._pump(0)
        return self.returncode if not self._sel.get_map() else None

    def send_signal(self, sig):
        if self.returncode is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def terminate(self):
        self.send_signal(signal.SIGTERM)

    def kill(self):
        self.send_signal(signal.SIGKILL)


# ---- the server process ----

def _load_shared():
    """Load PETSc's extension module's shared objects (relocations done once, here) without running its
    initialization."""
    spec = importlib.util.find_spec(_SHARED[0])
    if spec is None or not spec.submodule_search_locations:
        return
    for path in glob.glob(os.path.join(spec.submodule_search_locations[0], _SHARED[1])):
        ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)


def _uninitialized_imports():
    """For an entry that initializes MPI and PETSc itself at the start of every command (WARM_UNINITIALIZED:
    cli/warm_run.main does it, as the exec'd command's first imports would): petsc4py's extension module imported
    without initializing PETSc (petsc4py.init but for its last step), and mpi4py's MPI module set to be imported
    without initializing MPI and to finalize it at exit (whoever initializes it); so that the modules the commands
    use, which import both, can be loaded here."""
    import mpi4py
    mpi4py.rc.initialize, mpi4py.rc.finalize = False, True
    import petsc4py.lib
    petsc4py.lib.ImportPETSc(None)


def _clean(uninitialized=False):
    """Nothing a child must initialize itself is initialized here: not MPI, not PETSc (their modules imported only
    where the entry says it initializes both, and then uninitialized)."""
    if uninitialized:
        if "mpi4py.MPI" in sys.modules and sys.modules["mpi4py.MPI"].Is_initialized():
            raise SystemExit("warm server: MPI initialized while preloading")
        if sys.modules["petsc4py.PETSc"].Sys.isInitialized():
            raise SystemExit("warm server: PETSc initialized while preloading")
    else:
        held = [m for m in ("petsc4py.PETSc", "mpi4py.MPI") if m in sys.modules]
        if held:
            raise SystemExit(f"warm server: {', '.join(held)} imported while preloading (it initializes MPI)")
    if threading.active_count() != 1:
        raise SystemExit("warm server: threads running after preloading (fork would copy their locks)")


def _child(msg, fds, entry, sel):
    """In the forked child: become the command; its exit status. The caller then leaves the server's loop with
    SystemExit, so that the interpreter ends as after `python -m`: atexit functions, Python's exit hooks
    (PETSc's finalization: -log_view's report, MPI_Finalize), the streams flushed."""
    try:
        for sig in (signal.SIGTERM, signal.SIGCHLD, signal.SIGHUP):
            signal.signal(sig, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        for key in list(sel.get_map().values()):       # the server's sockets, the other children's pidfds and clients
            if isinstance(key.data, Watch):
                key.data.conn.close()
                if key.data.kind == "pidfd":
                    os.close(key.fd)
            elif key.data is None:
                key.fileobj.close()
        sel.close()
        _place(fds, _targets(msg))
        os.chdir(msg["cwd"])
        os.environ.clear()
        os.environ.update(msg["env"])
        # what the package sets in its environment when imported, as an exec'd process would (MPICH's throttle: this
        # rank's launcher may count more ranks than CPUs)
        getattr(sys.modules[entry.split(".")[0]], "process_environment", lambda: None)()
        sys.argv = [msg["argv0"]] + msg["args"]
        module, func = entry.split(":")
        try:
            return getattr(sys.modules[module], func)(msg["args"])
        except SystemExit as e:
            return e.code
    except BaseException:
        import traceback
        traceback.print_exc()
        return 1


def _targets(msg):
    """The descriptor numbers a request's descriptors go to in the child: a rank's own list, else stdout and stderr."""
    return msg.get("fds", [1, 2])


def _place(fds, targets):
    """The received descriptors at their target numbers (stdin /dev/null where none is given for it), and no other
    descriptor above 2 left open (as Popen's close_fds)."""
    top = os.sysconf("SC_OPEN_MAX") if hasattr(os, "sysconf") else 1024
    if 0 not in targets:
        fds, targets = [os.open(os.devnull, os.O_RDONLY)] + list(fds), [0] + list(targets)
    # first above every target (a received descriptor may sit on another's target number), then onto them
    moved = [fcntl.fcntl(fd, fcntl.F_DUPFD, max(targets) + 1) for fd in fds]
    for fd in fds:
        os.close(fd)
    for fd, to in zip(moved, targets):
        os.dup2(fd, to)
        os.close(fd)
    keep = sorted(t for t in set(targets) if t > 2)
    for lo, hi in zip([3] + [t + 1 for t in keep], keep + [top]):
        os.closerange(lo, hi)


class Watch:
    """What the server's selector watches for a child: its pidfd (its end), and for a rank its client's connection
    (the client gone: the child is killed)."""

    def __init__(self, kind, pid, conn):
        self.kind, self.pid, self.conn = kind, pid, conn


def _sources(package):
    """{file: modification time} of the modules loaded from `package`'s folder: a child must not run a mix of
    the code loaded here and files edited since (it would import the rest from disk)."""
    root = os.path.dirname(os.path.abspath(package.__file__))
    files = [m.__file__ for m in list(sys.modules.values()) if getattr(m, "__file__", None)
             and os.path.abspath(m.__file__).startswith(root + os.sep)]
    return {f: os.stat(f).st_mtime_ns for f in files}


def _current(sources):
    try:
        return all(os.stat(f).st_mtime_ns == t for f, t in sources.items())
    except OSError:
        return False


def _refusal(msg, fds, sources, env, volatile):
    """Why the command is not started here (None: it is)."""
    if msg is None or len(fds) != len(_targets(msg)):
        return "its streams did not come"
    if not _current(sources):
        return "the package's files changed since the server loaded them"
    if _fixed(msg["env"], volatile, msg.get("rank")) != _fixed(env, volatile, msg.get("rank")):
        return "another environment than the server's"
    return None


def _request(listener, sel, entry, sources, env, volatile):
    """Accept one command: fork its child (which leaves here with SystemExit) and watch it (a rank: its client too);
    or refuse it (a message without its streams, the package's files changed since they were loaded, another
    environment: the caller execs)."""
    conn, _ = listener.accept()
    msg, fds = _recv(conn, maxfds=8)
    why = _refusal(msg, fds, sources, env, volatile)
    if why:
        for fd in fds:
            os.close(fd)
        if msg is not None:
            _send(conn, {"error": why})
        conn.close()
        return
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        conn.close()
        sys.exit(_child(msg, fds, entry, sel))
    for fd in fds:
        os.close(fd)
    _send(conn, {"pid": pid})
    sel.register(os.pidfd_open(pid), selectors.EVENT_READ, Watch("pidfd", pid, conn))
    if msg.get("rank"):
        sel.register(conn, selectors.EVENT_READ, Watch("client", pid, conn))


def _reap(sel, key):
    pid, conn = key.data.pid, key.data.conn
    sel.unregister(key.fd)
    os.close(key.fd)
    _, status = os.waitpid(pid, 0)
    if conn in sel.get_map():
        sel.unregister(conn)
    try:
        _send(conn, {"returncode": os.waitstatus_to_exitcode(status)})
    except OSError:
        pass
    conn.close()


def _client_gone(sel, key):
    """A rank's client sends nothing after its request: its connection readable means it has gone (killed by the
    launcher): so goes its child (reaped through its pidfd)."""
    sel.unregister(key.fd)
    try:
        os.kill(key.data.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def serve(path, entry, expect, volatile, preload):
    """Import, check, then fork a child per command until the client's end of stdin closes. `expect`: the file
    the client's import of the entry module resolves to (another one here is refused: the children would run
    other code than the caller asked for); `volatile`: the variables a command's environment may change."""
    env = dict(os.environ)
    module = importlib.import_module(entry.split(":")[0])
    if os.path.abspath(module.__file__) != os.path.abspath(expect):
        raise SystemExit(f"warm server: {module.__name__} is {module.__file__} here, {expect} for the client")
    uninitialized = getattr(module, "WARM_UNINITIALIZED", False)
    if uninitialized:
        _uninitialized_imports()
    else:
        _load_shared()
    for name in (*preload, *getattr(module, "WARM_PRELOAD", ())):
        importlib.import_module(name)
    _clean(uninitialized)
    # what is loaded here is never collected in a child: without this each child's first collections walk the
    # server's objects and copy the pages they lie on (a one-step run on the bar: 0.22 -> 0.175 s of cpu)
    gc.freeze()
    sources = _sources(sys.modules[module.__name__.split(".")[0]])
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C reaches the children (same process group)
    signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen(16)
    open(path + ".ready", "w").close()
    sel = selectors.DefaultSelector()
    sel.register(listener, selectors.EVENT_READ, None)
    sel.register(sys.stdin.fileno(), selectors.EVENT_READ, "client")
    me = os.getpid()
    try:
        while True:
            for key, _ in sel.select():
                if key.data == "client":
                    if not os.read(key.fd, 1024):
                        return                      # the client has ended
                elif key.data is None:
                    _request(listener, sel, entry, sources, env, volatile)
                elif key.data.kind == "client":
                    _client_gone(sel, key)
                else:
                    _reap(sel, key)
    finally:
        if os.getpid() == me:          # (a child leaves through here too, with SystemExit: not its business)
            _remove(path)


def _remove(path):
    """The socket, its ready mark and their folder."""
    for p in (path, path + ".ready"):
        if os.path.exists(p):
            os.remove(p)
    if os.path.isdir(os.path.dirname(path)) and not os.listdir(os.path.dirname(path)):
        os.rmdir(os.path.dirname(path))


# ---- an MPI rank's client (run by path with `python -S -I`: nothing above but the standard library) ----

def rank(path, exe, args):
    """Become one rank of `exe args` started warm by the server at PATH: hand it this process's streams, launcher
    descriptors and environment, forward the signals, and end as the child ends; exec EXE where it is refused."""
    env = dict(os.environ)
    targets = [0, 1, 2] + [int(env[v]) for v in _LAUNCHER_FDS if env.get(v, "").isdigit()]
    pid, pending = None, []

    def forward(sig, _frame):
        if pid is None:
            pending.append(sig)
            return
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            pass
    msg = None
    if "PMI_FD" in env and all(_is_open(fd) for fd in targets):
        for sig in _FORWARDED:
            signal.signal(sig, forward)
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sock.connect(path)
            _send(sock, {"args": args, "argv0": exe, "cwd": os.getcwd(), "env": env, "fds": targets, "rank": True},
                  targets)
            msg, _ = _recv(sock)
        except (OSError, UnicodeEncodeError, ValueError):
            msg = None
    if not msg or "pid" not in msg:
        for sig in _FORWARDED:
            signal.signal(sig, signal.SIG_DFL)
        for sig in pending:                 # (a signal that came first is the exec'd rank's first)
            os.kill(os.getpid(), sig)
        os.execv(exe, [exe] + args)
    pid = msg["pid"]
    for sig in pending:
        forward(sig, None)
    for fd in targets[3:] + [0]:           # (the child holds them now; the streams stay for the launcher)
        os.close(fd)
    msg, _ = _recv(sock)
    code = -signal.SIGKILL if msg is None else msg["returncode"]
    if code < 0:                           # killed by a signal: so is this process, for the launcher's report
        signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
    sys.exit(code if code >= 0 else 128 - code)


def _is_open(fd):
    try:
        os.fstat(fd)
        return True
    except OSError:
        return False


if __name__ == "__main__":
    if sys.argv[1] == "--rank":
        rank(sys.argv[2], sys.argv[3], sys.argv[4:])
    else:
        serve(sys.argv[1], sys.argv[2], sys.argv[3], [v for v in sys.argv[4].split(",") if v], sys.argv[5:])
