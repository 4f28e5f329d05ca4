"""Run under `mpiexec -n N` by test_partition.py: what each rank receives and allocates while the model of a scene
is built and a restart's state is read from a file (every rank a slice, the rows sent where they belong). Every message the space's mpi4py communicator delivers
(bcast, scatter, gather, allgather, alltoall, ...) is looked at: the longest numpy array in it is recorded, so a
whole-mesh array sent to a rank shows up whatever else the rank holds. tracemalloc counts the Python/numpy bytes
(PETSc's own memory is not traced). Prints one JSON line per rank on rank 0: {rank, received (longest array
received), peak, held (bytes, from just before the build), cells, nodes, nc_total, nv_total}.
ARGS: scene, a scratch file for the state, then option=value pairs."""
import json
import os
import sys
import tracemalloc

import h5py
import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from petsc4py import PETSc  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from conftest import make_model  # noqa: E402

from hyperelastic.core.files import StateRows  # noqa: E402
from hyperelastic.discretization.space import Space  # noqa: E402

BUFFERED = ("Alltoallv", "Allgatherv", "Gatherv", "Scatterv", "Recv", "Bcast")
RECEIVING = ("bcast", "scatter", "gather", "allgather", "alltoall", "allreduce", "reduce", "recv", "sendrecv")


class Recording:
    """An mpi4py communicator that records the longest array in every object it delivers."""
    longest = 0

    def __init__(self, comm):
        self._comm = comm

    def __getattr__(self, name):
        attr = getattr(self._comm, name)
        if name in BUFFERED:                 # the receive buffer (its rows) of an exchange
            def buffered(*args, **kw):
                out = attr(*args, **kw)
                Recording.longest = max(Recording.longest, longest(args[1][0]))
                return out
            return buffered
        if name not in RECEIVING:
            return attr

        def call(*args, **kw):
            out = attr(*args, **kw)
            Recording.longest = max(Recording.longest, longest(out))
            return out
        return call


def longest(obj):
    if isinstance(obj, np.ndarray):
        return len(obj) if obj.ndim else 1
    if isinstance(obj, dict):
        obj = list(obj.values())
    if isinstance(obj, (list, tuple)):
        return max((longest(o) for o in obj), default=0)
    return 0


def recorded(self, comm):
    self.__dict__["_mpi"] = Recording(comm)


Space.mpi = property(lambda self: self.__dict__["_mpi"], recorded)


def main(scene, options, state_file):
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    m = make_model(PETSc, scene, options)
    held, peak = tracemalloc.get_traced_memory()
    sp = m.space
    if sp.mpi.rank == 0:                 # a restart's state: an (nv, 3) array in a file, rows in input order
        with h5py.File(state_file, "w") as f:
            f["x"] = m.whole_mesh()[0]
    sp.mpi.Barrier()
    mine = sp.read_state(StateRows(state_file, "x", sp.nv_total, 3))
    assert np.array_equal(mine.reshape(-1, 3), sp.X), "read_state: a rank received another node's row"
    rows = sp.mpi.gather({"rank": sp.mpi.rank, "received": Recording.longest, "peak": peak - base,
                          "held": held - base, "cells": sp.nc, "nodes": sp.nlv, "nc_total": sp.nc_total,
                          "nv_total": sp.nv_total}, root=0)
    if sp.mpi.rank == 0:
        for r in rows:
            print(json.dumps(r))


if __name__ == "__main__":
    main(sys.argv[1], [tuple(a.split("=", 1)) for a in sys.argv[3:]], sys.argv[2])
