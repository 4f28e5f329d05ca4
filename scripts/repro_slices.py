#!/usr/bin/env python
"""Thesis sec. 7.4, Figs. 10-13: delta at fixed time step h (E at 1e-4, nu at 1e-2, L at 1e-4) and at fixed
mesh L3, for the eight curves of Table 5 plus PETSc's MFFD.

    python scripts/repro_slices.py OUT [--full]
"""
from hyperelastic.studies.repro.common import parser
from hyperelastic.studies.repro.crossval import main_slices

if __name__ == "__main__":
    main_slices(parser(__doc__.splitlines()[1],
                       **{"--vectors": dict(type=int, default=None, help="test vectors per family (30 with --full, else 5)"),
                          "--tol": dict(type=float, default=1e-3, help="tolerance on delta (thesis: 1e-3)")}
                       ).parse_args())
