"""Layer 10, studies: runs of runs — `hyperelastic study` (command.py: accuracy, refinement, price; measure.py,
part.py, plan.py, price.py, refinement.py and the reports), the hard-case matrix (stability.py), the thesis'
experiments (repro/) and the layer under every experiment (experiments/: child runs, recipes, CSV tables)."""
