#!/usr/bin/env bash
# Create .venv and install everything hyperelastic needs. Idempotent: a second run
# installs nothing new (pip reuses its cached PETSc wheel; the stamp file skips pip entirely).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
STAMP="$VENV/.hyperelastic-installed"
REQ=requirements.txt

have_lapack() {      # (not `ls … | grep`: under pipefail ls's status for the missing paths failed the test)
  for f in /usr/lib/*/liblapack.so /usr/lib/liblapack.so /usr/lib64/liblapack.so; do
    [ -e "$f" ] && return 0
  done
  return 1
}
# liblapack-dev for PETSc; strace for the test that kills a run at each of its writes (test_checkpoint)
APT=""
have_lapack || APT=" liblapack-dev"
command -v strace >/dev/null || APT="$APT strace"
if [ -n "$APT" ]; then
  echo "bootstrap: installing${APT} with apt-get"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  # shellcheck disable=SC2086
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $APT >/dev/null
fi

if [ -f "$STAMP" ] && [ "$STAMP" -nt "$REQ" ] && [ "$STAMP" -nt setup.py ]; then
  exit 0
fi

export PIP_DISABLE_PIP_VERSION_CHECK=1
# HYPERELASTIC_PETSC=system: the MPI, mpi4py, PETSc and petsc4py already importable by python3 (a cluster's modules,
# `module load petsc py-petsc4py py-mpi4py`: its ParMETIS, PT-Scotch, hypre, MUMPS with them) are used as they are:
# the venv sees them (--system-site-packages and the PYTHONPATH the modules set) and pip installs only the rest
if [ "${HYPERELASTIC_PETSC:-}" = "system" ]; then
  if ! python3 -c "import mpi4py, petsc4py; petsc4py.init([]); from petsc4py import PETSc" 2>/dev/null; then
    echo "bootstrap: HYPERELASTIC_PETSC=system, but python3 cannot import mpi4py and petsc4py (load the cluster's" \
         "modules first)" >&2
    exit 1
  fi
  [ -x "$VENV/bin/python" ] || python3 -m venv --system-site-packages "$VENV"
  # shellcheck disable=SC1091
  . "$VENV/bin/activate"
  python -m pip install -q --upgrade pip setuptools wheel
  REST="$VENV/requirements-without-petsc.txt"
  grep -vE '^(mpich|mpi4py|petsc|petsc4py)([<>=~ ]|$)' "$REQ" > "$REST"
  python -m pip install -q -r "$REST"
  python -m pip install -q --no-build-isolation --no-deps -e .
  python -c "from petsc4py import PETSc; print('bootstrap: using PETSc', '.'.join(map(str, PETSc.Sys.getVersion())), \
             'from', __import__('petsc4py').get_config()['PETSC_DIR'])"
  touch "$STAMP"
  echo "bootstrap: done"
  exit 0
fi
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
# shellcheck disable=SC1091
. "$VENV/bin/activate"
python -m pip install -q --upgrade pip setuptools wheel
# MPI first (provides mpicc/mpiexec in $VENV/bin), then mpi4py, then PETSc built against it.
python -m pip install -q "$(grep -E '^mpich' $REQ)"
python -m pip install -q "$(grep -E '^mpi4py' $REQ)"
# PETSc's default C flags are -g -O; build optimized. The wheel is cached by pip afterwards.
export PETSC_CONFIGURE_OPTIONS="${PETSC_CONFIGURE_OPTIONS:-COPTFLAGS=-O3 CXXOPTFLAGS=-O3 FOPTFLAGS=-O3}"
echo "bootstrap: installing PETSc/petsc4py (first build ~17 min; cached afterwards)"
python -m pip install -q "$(grep -E '^petsc[<>=]' $REQ)"
python -m pip install -q "$(grep -E '^petsc4py' $REQ)"
python -m pip install -q -r "$REQ"
python -m pip install -q --no-build-isolation -e .
touch "$STAMP"
echo "bootstrap: done"
