#!/bin/bash
# p-multigrid on the 16-core device machine (issue 49): P2 + p-multigrid against P1 + GAMG and P2 + GAMG over four
# Kuhn-box refinements of the bar up to 1.1M P2 dofs (phase 1: 1 rank each, pinned one per core, side by side; the
# two 1.1M-dof P2 runs on cores whose hyperthread siblings stay idle), then (phase 2, quiet cores) P2 + p-multigrid
# at 374k dofs on 1 and 2 ranks. The quasi-static Neo-Hookean bend2, one load step to full load, options/gamg.opts /
# options/pmg.opts, PETSc's default tolerances. Needs .scale (../shared/device/make_carry.sh) carried; the table
# goes to $OUT/table.txt after every run (what a cut-off run leaves is still read).
#   run: command "bash scripts/scale_pmg.sh", carry [".scale"], timeout_s ~590 (phase 1 ~7 min there)
#   PHASE=2 LEVELS=3: phase 2 only (~2 min), with P2 + GAMG's 1 and 2 ranks after it; PHASE=3 LEVELS="3 4": phase 2's
#   p-multigrid pair, then P2 + p-multigrid at 1.1M dofs on 16, 8, 4, 2 and 1 ranks (~7 min; PAIR=0 without the pair,
#   SWEEP="2 1" those rank counts only, LEVELS=4 then); SMALL=1: a dry run on tiny
#   boxes, anywhere (here: PATH=/tmp/venv312/bin:$PATH, the 3.12 venv make_carry.sh builds).
# Count cores with /proc/cpuinfo: `nproc` obeys OMP_NUM_THREADS=1 and says 1 (2026-11-27 that pinned all twelve
# runs of phase 1 to core 0, and the call timed out).
set -u
source scripts/device_env.sh pmg.txt
S=$PWD/.scale; W=/tmp/w; mkdir -p $W; cd $W
OPT=$R/sp/hyperelastic/data/options
# SMALL=1: a dry run of this script on tiny boxes (any machine)
if [ "${SMALL:-0}" = 1 ]; then B=("6 3 3" "8 3 3" "10 4 4" "12 5 5"); else B=("20 8 8" "30 12 12" "45 18 18" "65 26 26"); fi
for L in ${LEVELS:-1 2 3 4}; do $PY $S/boxmesh.py ${B[$((L-1))]} L$L.msh & done; wait
NP=$(grep -c ^processor /proc/cpuinfo)   # (nproc obeys OMP_NUM_THREADS=1)
one() {  # core tag mesh order pc [mpiexec ranks]
  local core=$1 tag=$2 m=$3 o=$4 pc=$5 n=${6:-1} t0 t1 rc
  t0=$(date +%s.%N)
  local how=(taskset -c $((core % NP)) timeout ${T1:-420})      # one rank, pinned; several: mpiexec binds them
  [ $n = 1 ] || how=(timeout ${T2:-300} mpiexec -n $n -bind-to core)
  "${how[@]}" $PY -m hyperelastic run bend2 -quasistatic -dt 0.5 -final_time 0.5 -material neohookean -mesh $m \
    -order $o -options_file $OPT/$pc.opts -output $W/$tag.h5 -quiet -log_view :$W/log_$tag.txt > $W/out_$tag.txt 2>&1
  rc=$?; t1=$(date +%s.%N); echo "$tag rc=$rc wall=$(awk -v a=$t0 -v b=$t1 'BEGIN{printf "%.1f", b-a}')" >> $W/walls.txt
  [ $rc = 0 ] || { echo "$tag failed rc=$rc"; tail -3 $W/out_$tag.txt; } | tee -a $O/pmg.txt
}
table() { $PY - <<'PY' > $O/table.txt

import glob, os, re, h5py
walls = dict(l.split(" rc=")[0:1] + [l.split("wall=")[1].strip()] for l in open("walls.txt"))
def stage(tag, name):
    try:
        for l in open(f"log_{tag}.txt"):
            m = re.match(rf"\s*\d+:\s+{name}:\s+(\S+)", l)
            if m: return float(m.group(1))
    except OSError: pass
    return float("nan")
print(f"{'run':14s} {'tets':>7s} {'dofs':>8s} {'Newton':>6s} {'KSP/N':>6s} {'s/Newton':>8s} {'Step s':>7s} {'wall s':>7s} {'peak MB':>8s}")
for t in sorted(walls):
    try: f = h5py.File(f"{t}.h5", "r")
    except OSError: print(t, "no output"); continue
    s = f["stats"]; n = max(int(s["newton_its"][:].sum()), 1)
    print(f"{t:14s} {f['mesh/tetra'].shape[0]:7d} {3*f['mesh/points'].shape[0]:8d} {n:6d} {s['ksp_its'][:].sum()/n:6.1f} "
          f"{s['wall_s'][:].sum()/n:8.3f} {stage(t,'Step'):7.1f} {float(walls[t]):7.1f} {float(f.attrs.get('peak_rss_mb',0)):8.0f}")
PY
}
if [ "${PHASE:-1}" = 1 ]; then
# phase 1: 12 single-rank runs side by side, one per core; the two L4 P2 runs on cores 0 and 1 with their
# hyperthread siblings left idle, the other ten on the remaining cores
sib() { cat /sys/devices/system/cpu/cpu$1/topology/thread_siblings_list 2>/dev/null | tr ',-' '  '; }
SKIP=" 0 1 $(sib 0) $(sib 1) "; POOL=(); for c in $(seq 0 $((NP-1))); do [[ "$SKIP" == *" $c "* ]] || POOL+=($c); done
[ ${#POOL[@]} -gt 0 ] || POOL=(0)
echo "cores: L4 P2 on 0 and 1 (siblings $(sib 0) / $(sib 1) idle), pool ${POOL[*]}" | tee -a $O/pmg.txt
one 0 L4_P2_gamg L4.msh 2 gamg & one 1 L4_P2_pmg L4.msh 2 pmg &
c=0; for run in "L4 P1 1 gamg" "L1 P1 1 gamg" "L1 P2 2 gamg" "L1 P2 2 pmg" "L2 P1 1 gamg" "L2 P2 2 gamg" "L2 P2 2 pmg" \
               "L3 P1 1 gamg" "L3 P2 2 gamg" "L3 P2 2 pmg"; do set -- $run
  one ${POOL[$((c % ${#POOL[@]}))]} $1_$2_$4 $1.msh $3 $4 & c=$((c+1)); done
wait
echo "phase 1 done $(date +%T)" | tee -a $O/pmg.txt
fi
# phase 2, quiet cores: P2 + p-multigrid at L3 on 1 then 2 ranks
[ "${PAIR:-1}" = 1 ] && { one 0 Q1_P2_pmg L3.msh 2 pmg; table; one 0 Q2_P2_pmg L3.msh 2 pmg 2; table; }
[ "${PHASE:-1}" = 2 ] && { one 0 Q1_P2_gamg L3.msh 2 gamg; table; one 0 Q2_P2_gamg L3.msh 2 gamg 2; table; }
# phase 3: P2 + p-multigrid at L4 over rank counts, the cheapest first (a cut-off run keeps the table so far)
[ "${PHASE:-1}" = 3 ] && for n in ${SWEEP:-16 8 4 2 1}; do [ $n -le $NP ] && { one 0 R${n}_P2_pmg L4.msh 2 pmg $n; table; }; done
cp $W/log_L4_P2_pmg.txt $W/log_Q2_P2_pmg.txt $W/walls.txt $O/ 2>/dev/null
