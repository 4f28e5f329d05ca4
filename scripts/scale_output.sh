#!/bin/bash
# The output layouts on the 16-core device machine (issue 45): scripts/bench_output_ranks.py on a 960k-tet and a
# 1.9M-tet box, gather and per-rank layouts, 1/4/16 ranks. Needs .scale/site.tar.xz (../shared/device/make_carry.sh:
# the Python 3.12 runtime) carried; prints to $OUT/output.txt.
#   run: command "bash scripts/scale_output.sh", carry [".scale"]
set -u
source scripts/device_env.sh output.txt
B="$PY scripts/bench_output_ranks.py /tmp/bor --steps 1 --mpiexec $(command -v mpiexec)"
$B --boxes ${BIG:-100x40x40} --ranks ${RANKS_BIG:-1,4,16} 2>&1 | grep -v Warning | tee -a $O/output.txt
$B --boxes ${BIGGER:-125x50x50} --ranks ${RANKS_BIGGER:-16} 2>&1 | grep -v Warning | tee -a $O/output.txt
