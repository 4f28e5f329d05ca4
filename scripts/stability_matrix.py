#!/usr/bin/env python
"""The hard-case matrix (issue 5): run every cell as `python -m hyperelastic run`, then write
OUT/stability.csv, OUT/stability.md (table, properties, locking) and OUT/stability.png (outcome heatmap).

    scripts/stability_matrix.py OUT            # the quick subset (the one `make test` checks), ~2 min
    scripts/stability_matrix.py OUT --full     # the whole matrix (see hyperelastic/studies/stability.py)
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.studies.stability import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
