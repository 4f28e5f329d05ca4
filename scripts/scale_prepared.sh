#!/bin/bash
# Set-up time and per-rank memory of a mesh read by rank 0 (.msh) against a prepared mesh every rank reads its slice
# of (issue 44 item 4), on the 16-core device machine: scripts/bench_prepared.py on a 960k-tet and a 1.9M-tet box,
# 1/4/16 ranks. Needs .scale/site.tar.xz (../shared/device/make_carry.sh: the Python 3.12 runtime) carried; prints to
# $OUT/prepared.txt.
#   run: command "bash scripts/scale_prepared.sh", carry [".scale"]
set -u
source scripts/device_env.sh prepared.txt
B="$PY scripts/bench_prepared.py /tmp/bpr --mpiexec $(command -v mpiexec)"
$B --boxes ${BIG:-100x40x40} --ranks ${RANKS_BIG:-1,4,16} 2>&1 | grep -v Warning | tee -a $O/prepared.txt
$B --boxes ${BIGGER:-125x50x50} --ranks ${RANKS_BIGGER:-16} 2>&1 | grep -v Warning | tee -a $O/prepared.txt
