#!/usr/bin/env python
"""Thesis Fig. 4 run for real: squeeze (L5, 1.5 s with --full) with assembled, shell, -snes_mf,
-snes_mf_operator and seed_fd, final shapes side by side and distances to the exact tangent's result;
then MFFD-Newton against the exact tangent for E from 1e2 to 1e15 (steel included) and h in {1e-2, 1e-3}.

    python scripts/repro_fig4.py OUT [--full]
"""
from hyperelastic.studies.repro.common import parser
from hyperelastic.studies.repro.simulation import NEWTON_STEPS, main

if __name__ == "__main__":
    main(parser(__doc__.splitlines()[1],
                **{"--fig4_level": dict(type=int, default=None, help="mesh level of the squeeze runs (5 with --full, else 1)"),
                   "--final_time": dict(type=float, default=None, help="squeeze duration (1.5 s with --full, else 0.3)"),
                   "--newton_steps": dict(type=float, nargs="+", default=NEWTON_STEPS,
                                          help="the Newton table's step sizes (default %(default)s)")}
                ).parse_args())
