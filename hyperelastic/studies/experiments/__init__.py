"""The experiments layer, shared by every study (accuracy, refinement), the hard-case matrix
(stability), the thesis reproduction (repro) and the benchmark scripts:

  runner   `hyperelastic run` as a child process (1 or 2 ranks), its one-line failure, parallel maps
  recipes  Jacobian modes and solver/PC recipes, read from options/*.opts
  table    CSV rows written and read back with their types

The statistics columns a run writes are declared once in hyperelastic/stats.py. Each experiment is a
module with main(argv); the scripts under scripts/ and `hyperelastic study NAME` only call it.
"""
