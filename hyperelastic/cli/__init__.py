"""Layer 11, cli: the commands (run, mesh, plot, report, scenes, study), the one-line error contract and the exit
codes (main.py). The only layer that imports PETSc's modules late on purpose: petsc4py reads the command line when
PETSc is first imported."""
