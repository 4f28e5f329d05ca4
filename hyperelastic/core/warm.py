"""Warm starts: a fork server that has imported the libraries a command needs (numpy, h5py, the package's
PETSc-free modules) and loaded PETSc's shared library without initializing it, and forks one child per
command. Each child is its own process, as an exec'd one: its own PETSc and MPI (initialized in the child,
from the child's own arguments: a fresh options database), its own file descriptors, working directory,
environment, exit status and signals. What it saves is the interpreter's start and the imports, ~0.4 s of
the ~0.75 s a one-step run on the bar costs here: the studies' child runs and the test suite start ~1,000
of them.

The server is started with `python -m hyperelastic.core.warm SOCKET ENTRY PRELOAD...` (ENTRY "module:function",
the function taking the argument list and returning the exit status, as `python -m hyperelastic` runs it)
and forks from a clean state: one thread, nothing of MPI or PETSc initialized (refused otherwise). Only
POSIX systems with pidfds (Linux >= 5.3): elsewhere `Server.start` returns None and callers exec.

Where a child would differ from an exec'd process, callers exec instead: more than one rank (mpiexec), an
environment other than the server's (the libraries read theirs when loaded), `HYPERELASTIC_WARM=0`."""
import atexit
import ctypes
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
        proc = subprocess.Popen([sys.executable, "-m", __name__, path, entry, spec.origin, *preload], env=env,
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
        def fixed(e):
            return {k: v for k, v in e.items() if k not in self.volatile}
        try:
            json.dumps(dict(env)).encode()
        except (UnicodeEncodeError, TypeError, ValueError):
            return False
        return self.proc.poll() is None and fixed(env) == fixed(self.env)

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


_SHARED_SERVERS = {}
_SHARED_LOCK = threading.Lock()


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
    with _SHARED_LOCK:
        server = _SHARED_SERVERS.get(entry, False)
        if server is False or (server is not None and server.proc.poll() is not None):
            server = _SHARED_SERVERS[entry] = Server.start(entry, env=env, volatile=volatile)
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


def _clean():
    """Nothing a child must initialize itself is initialized here."""
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
        for key in list(sel.get_map().values()):       # the server's sockets and the other children's pidfds
            if isinstance(key.data, tuple):
                key.data[1].close()
                os.close(key.fd)
            elif key.data is None:
                key.fileobj.close()
        sel.close()
        null = os.open(os.devnull, os.O_RDONLY)
        for fd, to in ((null, 0), (fds[0], 1), (fds[1], 2)):
            os.dup2(fd, to)
        os.closerange(3, os.sysconf("SC_OPEN_MAX") if hasattr(os, "sysconf") else 1024)   # (as Popen's close_fds)
        os.chdir(msg["cwd"])
        os.environ.clear()
        os.environ.update(msg["env"])
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


def _request(listener, sel, entry, sources):
    """Accept one command: fork its child (which leaves here with SystemExit) and watch it; or refuse it (a
    message without its two streams, or the package's files changed since they were loaded: the caller execs)."""
    conn, _ = listener.accept()
    msg, fds = _recv(conn, maxfds=2)
    if msg is None or len(fds) != 2 or not _current(sources):
        for fd in fds:
            os.close(fd)
        if msg is not None:
            _send(conn, {"error": "the package's files changed since the server loaded them"})
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
    sel.register(os.pidfd_open(pid), selectors.EVENT_READ, (pid, conn))


def _reap(sel, key):
    pid, conn = key.data
    sel.unregister(key.fd)
    os.close(key.fd)
    _, status = os.waitpid(pid, 0)
    try:
        _send(conn, {"returncode": os.waitstatus_to_exitcode(status)})
    except OSError:
        pass
    conn.close()


def serve(path, entry, expect, preload):
    """Import, check, then fork a child per command until the client's end of stdin closes. `expect`: the file
    the client's import of the entry module resolves to (another one here is refused: the children would run
    other code than the caller asked for)."""
    for name in preload:
        importlib.import_module(name)
    module = importlib.import_module(entry.split(":")[0])
    if os.path.abspath(module.__file__) != os.path.abspath(expect):
        raise SystemExit(f"warm server: {module.__name__} is {module.__file__} here, {expect} for the client")
    _load_shared()
    _clean()
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
                    _request(listener, sel, entry, sources)
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


if __name__ == "__main__":
    serve(sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:])
