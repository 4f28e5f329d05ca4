import os

__version__ = "0.2.0"        # (setup.py reads it here; CHANGELOG.md says what each version changed)

# One BLAS/OpenMP thread per process: the parallelism here is MPI ranks. numpy's own OpenBLAS would start
# a thread per core in every rank, and its threads keep spinning after each vector product, on the
# cores where the other ranks compute: on 2 ranks at 660k tets every residual after a line search ran
# at half speed (40-48 ms instead of 18; BENCHMARKS.md). It also makes numpy's dot products independent
# of the core count. Set before numpy loads (an explicit setting in the environment wins).

# More ranks on this node than it has CPUs (`mpiexec -n 4` on a 2-core laptop): MPICH's progress engine polls without
# yielding, so a rank waiting in a collective keeps the CPU that a rank with work needs; a 3-rank run of the two-material
# bar took 16-18 s on 2 cores, with polling throttled after 100 idle polls 0.8 s, after every idle poll 0.7 s, and a
# 2-rank run on its own cores the same time either way; a 2-rank run beside a busy process 5.7 s unthrottled, 4.6 s
# (100) and 4.0 s (1) (BENCHMARKS.md, 2026-11-27). Set before MPI starts (mpi4py initializes it when imported); Hydra
# gives each process its node's rank count; an explicit setting in the environment wins; other MPIs ignore these.
MPICH_THROTTLE = {"MPIR_CVAR_CH4_PROGRESS_THROTTLE": "true", "MPIR_CVAR_CH4_PROGRESS_THROTTLE_NO_PROGRESS_COUNT": "1"}


def process_environment():
    """The settings above, in this process's environment (at import; again in a warm-started child, whose environment
    is its caller's: core/warm.py)."""
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    if int(os.environ.get("MPI_LOCALNRANKS", "1") or 1) > (os.cpu_count() or 1):
        for name, value in MPICH_THROTTLE.items():
            os.environ.setdefault(name, value)


process_environment()
