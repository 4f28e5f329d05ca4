"""Run under `mpiexec -n 2` by test_output_readers.py: writing a frame or a checkpoint is collective to its
end, so rank 0's HDF5 writes (made slow here) are waited for inside the write on every rank and not in the
next step's first collective call, where -log_view would charge them to the residual. Prints 'ok' on rank 0.
`PATH fail`: rank 0's write of frame 1 raises (as an HDF5 error there would): the job ends with an error status and
the error's line (before, the other rank waited in the frame's end for ever)."""
import sys
import time

import petsc4py

ARGS = ["-level", "1", "-dt", "0.01", "-final_time", "0.03", "-checkpoint_every", "1", "-quiet"]
# as cli.main would: output imports petsc4py, which reads its options once (so -output is given here too: without it
# the run wrote the default output/bend.h5 in the suite's working directory, where other tests' runs write theirs)
petsc4py.init([sys.argv[0]] + ARGS + ["-output", sys.argv[1]])

from hyperelastic.cli import main as cli
from hyperelastic.output import writer as output  # noqa: E402
from hyperelastic.output.ranks import RankWriter  # noqa: E402

SLOW = 0.3


def slow(fn):
    def wrapper(self, *a, **k):
        time.sleep(SLOW)
        return fn(self, *a, **k)
    return wrapper


def timed(fn, spent):
    def wrapper(self, *a, **k):
        t0 = time.perf_counter()
        try:
            return fn(self, *a, **k)
        finally:
            spent.append((fn.__name__, time.perf_counter() - t0))
    return wrapper


def main(path):
    spent = []
    for cls in (output.Writer, RankWriter):          # (the gathered and the per-rank layout: 2 ranks write the latter)
        cls._write_frame = slow(cls._write_frame)             # (rank 0 only)
        cls._write_checkpoint = slow(cls._write_checkpoint)
        cls.frame = timed(cls.frame, spent)
        cls.checkpoint = timed(cls.checkpoint, spent)
    rc = cli.main(["run", "bend", *ARGS, "-output", path])
    assert rc == 0, rc
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    every = comm.gather(spent, root=0)
    if comm.rank == 0:
        names = [n for n, _ in every[0]]
        assert names.count("frame") >= 2 and names.count("checkpoint") >= 1, every
        assert all([n for n, _ in s] == names for s in every), every
        assert all(t >= 0.8 * SLOW for s in every for _, t in s), every
        print("ok")


def fail(path):
    write = RankWriter._write_frame

    def failing(self, t, shapes):
        if self.nframes == 1:
            raise OSError("Unable to synchronously create dataset (a write of rank 0 failed, as the test makes it)")
        return write(self, t, shapes)
    RankWriter._write_frame = failing
    sys.exit(cli.main(["run", "bend", *ARGS, "-output", path]))


if __name__ == "__main__":
    fail(sys.argv[1]) if sys.argv[2:] == ["fail"] else main(sys.argv[1])
