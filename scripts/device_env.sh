# Sourced by the device machine's scripts (scale_output.sh, scale_prepared.sh): unpacks the carried Python 3.12
# runtime (.scale/site.tar.xz, ../shared/device/make_carry.sh) into /tmp/rt, puts it and the checkout on the
# paths, sets O (the folder that comes back) and PY, and starts the report $O/$1 with the machine's line.
S=$PWD/.scale; R=/tmp/rt; mkdir -p $R && tar -xJf $S/site.tar.xz -C $R || exit 1
export PYTHONPATH=$R/sp:$PWD LD_LIBRARY_PATH=$R/lib:$R/lib/mpich:$R/sp/petsc/lib PATH=$R/bin:$PATH OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
O=${OUT:-/tmp/out}; mkdir -p $O
PY=$(command -v python3); echo "python $($PY -V 2>&1); cores $(grep -c ^processor /proc/cpuinfo); $(lscpu | grep 'Model name')" | tee $O/$1
