#!/bin/bash
# A 960k-tet per-rank output written on 16 ranks restarted on 16, 4 and 1 ranks (the 16-core machine: needs
# .scale/site.tar.xz carried, see scripts/scale_output.sh); prints to $OUT/restart.txt
set -u
S=$PWD/.scale; R=/tmp/rt; mkdir -p $R && [ -d $R/sp ] || tar -xJf $S/site.tar.xz -C $R
export PYTHONPATH=$R/sp LD_LIBRARY_PATH=$R/lib:$R/lib/mpich:$R/sp/petsc/lib PATH=$R/bin:$PATH OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
O=${OUT:-/tmp/out}; W=/tmp/rs; mkdir -p $W $O; cd $W
PY=$(command -v python3)
[ -f /tmp/bor/box_100x40x40.msh ] && M=/tmp/bor/box_100x40x40.msh || { $PY $S/boxmesh.py 100 40 40 big.msh; M=$W/big.msh; }
t() { local t0=$(date +%s.%N); "$@" > $W/o.txt 2>&1; local rc=$?; echo "rc=$rc wall=$(awk -v a=$t0 -v b=$(date +%s.%N) 'BEGIN{printf "%.1f", b-a}') $*" | tee -a $O/restart.txt; [ $rc = 0 ] || tail -3 $W/o.txt | tee -a $O/restart.txt; }
t mpiexec -n 16 $PY -m hyperelastic run bend -mesh $M -dt 0.01 -final_time 0.02 -checkpoint_every 1 -output $W/c.h5 -quiet -ksp_type cg -pc_type gamg
for n in 16 4 1; do
  rm -rf $W/r$n.h5*; cp $W/c.h5 $W/r$n.h5; cp -r $W/c.h5.d $W/r$n.h5.d
  t mpiexec -n $n $PY -m hyperelastic run --restart $W/r$n.h5 -final_time 0.03 -quiet -log_view :$W/log$n.txt
  grep -E "^ *[0-9]+: +(Main Stage|Setup|Step|Output):" $W/log$n.txt | tee -a $O/restart.txt
done
$PY - <<'PY' | tee -a $O/restart.txt
import h5py, numpy as np
a = h5py.File("/tmp/rs/r16.h5")
for n in (4, 1):
    b = h5py.File(f"/tmp/rs/r{n}.h5")
    print(n, "ranks: max |x - x(16 ranks)| =", float(np.abs(a["x"][-1] - b["x"][-1]).max()), "frames", b["x"].shape[0])
PY
