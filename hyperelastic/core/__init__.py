"""Layer 1, core: what every other layer stands on and nothing of the physics — the error types and the one-line
error contract's argument parser (errors.py), typed access to the PETSc options database and the scene/options
files (options.py), time and space expressions parsed from option values without `eval` (expressions.py), what an
output file is and the checks on output paths (files.py), where the package's own data lies (data.py) and the
PETSc C functions petsc4py lacks, through ctypes (libpetsc.py)."""
