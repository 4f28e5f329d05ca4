import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import warmrun
from hyperelastic import MPICH_THROTTLE

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.dirname(sys.executable)

# The suite runs two workers on two cores, each starting 2-4-rank runs: the cores are oversubscribed, and MPICH's
# progress engine, polling without yielding, made a 3-rank run 20x slower (the package sets this only where one run's
# own ranks outnumber the node's CPUs: hyperelastic/__init__.py). Inherited by every process the tests start.
for _name, _value in MPICH_THROTTLE.items():
    os.environ.setdefault(_name, _value)
# Every rank the suite starts is on this one node, where MPICH's ranks talk through its shared memory whatever the
# network module; the mpich wheel has two (ch4:ucx,ofi) and picks UCX by default, whose set-up probes the node's
# devices: MPI_Init took 16-20 ms of cpu, with libfabric's 7 ms, in each of the suite's ~1,450 processes that
# initialize MPI (~20 cpu-s; BENCHMARKS.md). The product leaves the choice to MPICH (a cluster's network is UCX's).
os.environ.setdefault("MPIR_CVAR_CH4_NETMOD", "ofi")


def mpiexec():
    """The venv's mpiexec (the mpich wheel's), else the one on PATH."""
    return shutil.which("mpiexec", path=BIN) or shutil.which("mpiexec")


def hyperelastic(args, nprocs=1, timeout=600, cwd=None):
    """Run the `hyperelastic` console script, started warm (warmrun.py); under mpiexec when nprocs > 1."""
    if nprocs == 1:
        return warmrun.run(args, cwd=cwd, timeout=timeout)
    cmd = [mpiexec(), "-n", str(nprocs)] + warmrun.rank_command(args) + [str(a) for a in args]
    # (os.environ given, not inherited: gmsh.initialize() in this process appends to PATH and sets PYTHONPATH in the
    # C environment, which children inherit and os.environ does not show; the warm ranks' server would refuse them)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=cwd, env=dict(os.environ))


def tangent_and_fd(effect, x, v, eps):
    """(an effect's tangent applied to v at x, central differences of its residual along v with step eps)."""
    effect.linearize(x)
    y, rp, rm = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    effect.apply(v, y)
    effect.residual(x + eps * v, rp)
    effect.residual(x - eps * v, rm)
    return y, (rp - rm) / (2 * eps)


def run_mpi_script(name, args, nprocs=2, timeout=300):
    """Run tests/NAME (a driver that prints 'ok' lines on rank 0) under mpiexec with this Python."""
    return subprocess.run([mpiexec(), "-n", str(nprocs), sys.executable, os.path.join(ROOT, "tests", name)]
                          + [str(a) for a in args], capture_output=True, text=True, timeout=timeout)


def run_ok(args, nprocs=1, **kw):
    p = hyperelastic(args, nprocs, **kw)
    assert p.returncode == 0, f"exit {p.returncode}\nstdout:\n{p.stdout}\nstderr:\n{p.stderr}"
    return p


def read_h5(path, frames=False):
    """An output's x, time, mesh, attributes and statistics (frames: and every frame's fields), in the input mesh's
    node and cell order whatever the layout (a per-rank output's rows put back through mesh/input_index)."""
    import h5py
    from hyperelastic.core.files import completed_frames, input_order
    with h5py.File(path, "r") as f:
        n = completed_frames(f)          # (a killed run's file may hold one row of x more)
        nodes, cells = input_order(f)
        out = {"x": f["x"][:n][:, nodes], "time": f["time"][:n], "points": f["mesh/points"][:][nodes],
               "tetra": f["mesh/tetra"][:][cells], "attrs": dict(f.attrs), "stats": {k: f["stats"][k][:] for k in f["stats"]}}
        if "mesh/input_index" in f:
            out["tetra"] = f["mesh/input_index"][:][out["tetra"]]
        if frames:
            from hyperelastic.output.fields import is_point_field
            out["frames"] = [{k: d[:][nodes if is_point_field(k) else cells] for k, d in f[f"frames/{i}"].items()}
                             for i in range(n)]
    return out


@pytest.fixture(scope="session")
def l1_mesh():
    """Path of the cached L1 bar mesh (generated once)."""
    from hyperelastic.mesh.generate import cached_bar
    return cached_bar(1)


@pytest.fixture(scope="session")
def petsc():
    import petsc4py
    petsc4py.init([sys.argv[0]])
    from petsc4py import PETSc
    return PETSc


def make_model(petsc, scene_name="bend", options=()):
    """In-process set-up of a scene on COMM_WORLD, as `hyperelastic run` builds it: a model.Model."""
    from hyperelastic.app.model import build_model
    from hyperelastic.app.catalog import load_scene
    o = petsc.Options()
    for k in list(o.getAll()):
        o.delValue(k)
    for k, v in options:
        o.setValue(k, v)
    scene, _ = load_scene(scene_name)
    return build_model(scene, petsc.COMM_WORLD)
