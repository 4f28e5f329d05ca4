"""kill -9 at every write of the output, not at random moments: a run of `bend` is killed by strace at its
N-th pwrite64 (HDF5's writes) for every N in a range, and each file left behind must open, hold only the
reference's frames (x, time and every frame's fields), and give a bitwise restart from its checkpoint.

    python scripts/crash_writes.py [--first 1] [--last 0 (= every write)] [--every 1] [--jobs 2]
        [--restart-every 10] [--ranks 1]

--ranks N runs it under mpiexec -n N (the per-rank output layout on N > 1: FILE.h5 and FILE.h5.d/); strace counts
each process's writes on its own, so the N-th write of every rank that makes one is killed (mpiexec then ends the
others), and the restart runs on N ranks too.

Needs strace (apt-get install strace). Prints one line per failing N and a summary; exit 1 on a failure.
tests/test_checkpoint.py runs a few N of it; the whole range is this script's (about 0.6 s per N per job).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from hyperelastic.core.files import completed_frames  # noqa: E402
import launch  # noqa: E402

RUN = ["bend", "-level", "1", "-final_time", "0.6", "-checkpoint_every", "7", "-quiet"]


RANKS = [1]
# every process followed; only the traced calls stop them (a seccomp filter: without it every system call stops each
# process, and a 2-rank run's ranks, yielding the CPU between polls, ran several times slower under strace)
STRACE = ["-f", "--seccomp-bpf"]


def command(out):
    """The run, under the venv's mpiexec with --ranks ranks (as it is on one)."""
    return launch.command(["run", *RUN, "-output", out], RANKS[0])


def count_writes(out):
    p = subprocess.run(["strace", *STRACE, "-c", "-e", "trace=pwrite64", *command(out)], capture_output=True,
                       text=True, check=True)
    m = re.search(r"^\s*[\d.]+\s+[\d.]+\s+\d+\s+(\d+)\s+(?:\d+\s+)?pwrite64$", p.stderr, re.M)
    return int(m.group(1))


def read(path):
    """The completed frames of an output file, each frame's fields, the statistics and the checkpoint slot."""
    with h5py.File(path, "r") as f:
        n = completed_frames(f)
        out = {"n": n, "x": f["x"][:n], "time": f["time"][:n], "slot": int(f.attrs.get("checkpoint_slot", -1)),
               "fields": {(i, k): f[f"frames/{i}/{k}"][:] for i in range(n) for k in f[f"frames/{i}"]},
               "stats": {k: f["stats"][k][:] for k in f["stats"]}}
    return out


def check(n_write, ref, tmp, restart):
    """'' when the run killed at write n_write left a good file, else what is wrong."""
    d = os.path.join(tmp, f"w{n_write}")
    os.makedirs(d)
    out = os.path.join(d, "o.h5")
    subprocess.run(["strace", *STRACE, "-o", "/dev/null", "-e", "trace=pwrite64",
                    "-e", f"inject=pwrite64:signal=KILL:when={n_write}", *command(out)], capture_output=True)
    try:
        if not os.path.exists(out):              # killed before the first step completed: nothing replaced
            left = set(os.listdir(d)) - {"o.h5.partial", "o.h5.d"}       # (the rank files of a run never
            return "" if not left else f"left {sorted(left)}"                # committed: the next commit's to remove)
        try:
            r = read(out)
        except Exception as e:                   # noqa: BLE001 (any reader failure is the finding)
            return f"does not read: {e}"
        n = r["n"]
        if n > ref["n"] or not np.array_equal(r["x"], ref["x"][:n]) or not np.array_equal(r["time"], ref["time"][:n]):
            return f"frames differ from the reference's ({n} frames)"
        bad = [key for key, a in r["fields"].items() if not np.array_equal(a, ref["fields"][key])]
        if bad:
            return f"frame fields differ: {bad[:3]}"
        xdmf = os.path.splitext(out)[0] + ".xdmf"
        if os.path.exists(xdmf):
            grids = len(ET.parse(xdmf).getroot().findall("./Domain/Grid/Grid"))
            if not n - 1 <= grids <= n:
                return f"the XDMF has {grids} frames, the file {n}"
        if restart and r["slot"] >= 0:
            q, _ = launch.run(["run", "--restart", out, "-quiet"], RANKS[0])
            if q.returncode != 0:
                return f"restart failed: {q.stderr.strip()}"
            s = read(out)
            if not (np.array_equal(s["x"], ref["x"]) and np.array_equal(s["time"], ref["time"])):
                return "the restart does not end on the reference"
        return ""
    finally:
        shutil.rmtree(d, ignore_errors=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--last", type=int, default=0, help="the last write to kill at (0: the run's last)")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--restart-every", type=int, default=10, help="restart every K-th killed run (0: none)")
    ap.add_argument("--ranks", type=int, default=1, help="MPI ranks of the run (and of the restarts)")
    args = ap.parse_args(argv)
    RANKS[0] = args.ranks
    if shutil.which("strace") is None:
        sys.exit("crash_writes: needs strace (apt-get install strace)")
    tmp = tempfile.mkdtemp(prefix="crash_writes_")
    try:
        ref_path = os.path.join(tmp, "ref.h5")
        total = count_writes(ref_path)
        ref = read(ref_path)
        last = args.last or total
        ns = list(range(args.first, last + 1, args.every))
        print(f"{total} writes in the run, {ref['n']} frames; killing at {len(ns)} of them", flush=True)
        K = args.restart_every
        with ThreadPoolExecutor(args.jobs) as ex:
            results = list(ex.map(lambda n: (n, check(n, ref, tmp, K and n % K == 0)), ns))
        bad = [(n, why) for n, why in results if why]
        for n, why in bad:
            print(f"write {n}: {why}")
        print(f"{len(bad)} of {len(ns)} kills left a bad file")
        return 1 if bad else 0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
