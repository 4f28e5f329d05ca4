#!/usr/bin/env python
"""Thesis sec. 7.3, Figs. 6-9 and 14-15: cross-validation of the time step h against E, nu or the mesh
level L, with the thesis' seed formulas and with PETSc's MFFD (wp, ds); absolute delta and relative errors.

    python scripts/repro_crossval.py OUT [--param E|nu|L|all] [--full] [--no-plots]
"""
from hyperelastic.studies.repro.common import parser
from hyperelastic.studies.repro.crossval import main_crossval

if __name__ == "__main__":
    main_crossval(parser(__doc__.splitlines()[1],
                         **{"--param": dict(default="all", choices=["E", "nu", "L", "all"]),
                            "--vectors": dict(type=int, default=None, help="test vectors per family (30 with --full, else 5)"),
                            "--tol": dict(type=float, default=1e-3, help="tolerance on delta (thesis: 1e-3)"),
                            "--rel_tol": dict(type=float, default=1e-3, help="tolerance on the relative error of J v"),
                            "--no-plots": dict(action="store_true", help="the CSV tables only, no figures")}
                         ).parse_args())
