#!/usr/bin/env python
"""Thesis sec. 7.1, Table 3: fraction of vector pairs with |v^T A(u) - v^T J u| > tol for the thesis'
operator and PETSc's MFFD, unit / N(0,1) / "real" vectors, h in {1e-2, 1e-3, 1e-5}, St.VK and linear.

    python scripts/repro_symmetry.py OUT [--full]
"""
from hyperelastic.studies.repro.common import parser
from hyperelastic.studies.repro.symmetry import main

if __name__ == "__main__":
    main(parser(__doc__.splitlines()[1],
                **{"--pairs": dict(type=int, default=None, help="vector pairs (2500 with --full, else 200)"),
                   "--tol": dict(type=float, default=1e-5, help="tolerance (thesis: 1e-5)")}).parse_args())
