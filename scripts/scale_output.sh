#!/bin/bash
# The output layouts on the 16-core device machine (issue 45): scripts/bench_output_ranks.py on a 960k-tet and a
# 1.9M-tet box, gather and per-rank layouts, 1/4/16 ranks. Needs .scale/site.tar.xz (../shared/device/make_carry.sh:
# the Python 3.12 runtime) carried; prints to $OUT/output.txt.
#   run: command "bash scripts/scale_output.sh", carry [".scale"]
set -u
S=$PWD/.scale; R=/tmp/rt; mkdir -p $R && tar -xJf $S/site.tar.xz -C $R || exit 1
export PYTHONPATH=$R/sp:$PWD LD_LIBRARY_PATH=$R/lib:$R/lib/mpich:$R/sp/petsc/lib PATH=$R/bin:$PATH OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
O=${OUT:-/tmp/out}; mkdir -p $O
PY=$(command -v python3); echo "python $($PY -V 2>&1); nproc $(nproc); $(lscpu | grep 'Model name')" | tee $O/output.txt
B="$PY scripts/bench_output_ranks.py /tmp/bor --steps 1 --mpiexec $(command -v mpiexec)"
$B --boxes ${BIG:-100x40x40} --ranks ${RANKS_BIG:-1,4,16} 2>&1 | grep -v Warning | tee -a $O/output.txt
$B --boxes ${BIGGER:-125x50x50} --ranks ${RANKS_BIGGER:-16} 2>&1 | grep -v Warning | tee -a $O/output.txt
