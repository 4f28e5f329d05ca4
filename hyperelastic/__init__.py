import os

__version__ = "0.1.0"

# One BLAS/OpenMP thread per process: the parallelism here is MPI ranks. numpy's own OpenBLAS would start
# a thread per core in every rank, and its threads keep spinning after each vector product, on the
# cores where the other ranks compute: on 2 ranks at 660k tets every residual after a line search ran
# at half speed (40-48 ms instead of 18; BENCHMARKS.md). It also makes numpy's dot products independent
# of the core count. Set before numpy loads (an explicit setting in the environment wins).
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
