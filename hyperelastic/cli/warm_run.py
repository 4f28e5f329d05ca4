"""The entry of warm-started `hyperelastic run` commands (core/warm.py's `entry_for` picks it): cli.main's main, from a
fork server that holds petsc4py's and mpi4py's modules imported but neither PETSc nor MPI initialized, and the modules
a run imports loaded (~0.1 s of cpu per run: their imports and classes). Each child first initializes MPI as an exec'd
run's first import of mpi4py does (main._check_options_files), then runs `main`, which initializes PETSc from the run's
own arguments (main._petsc) before any PETSc call: the child is the exec'd run. Other commands (which would initialize
PETSc as its first import does, with no arguments) go to cli.main's server."""
from .main import WARM_PRELOAD as _BASE, main as _main

WARM_PRELOAD = _BASE + ("hyperelastic.app.run", "hyperelastic.app.catalog", "hyperelastic.core.libpetsc")
WARM_UNINITIALIZED = True


def main(args):
    """A warm child's run: MPI initialized as mpi4py's import would (its thread level; finalized at exit, after
    PETSc), then cli.main's main."""
    import mpi4py
    from mpi4py import MPI
    if not MPI.Is_initialized():
        if mpi4py.rc.threads:
            MPI.Init_thread(getattr(MPI, "THREAD_" + mpi4py.rc.thread_level.upper()))
        else:
            MPI.Init()
    return _main(args)
