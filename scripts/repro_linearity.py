#!/usr/bin/env python
"""Thesis sec. 7.2, Fig. 5: kappa(tau) = k(x + tau t), tau in [0, 10], fitted with the least-squares line of
eqs. 7.5-7.6, for St.VK and the linear material; the fit's residual says how linear k really is.

    python scripts/repro_linearity.py OUT [--full]
"""
from hyperelastic.studies.repro.common import parser
from hyperelastic.studies.repro.linearity import main

if __name__ == "__main__":
    main(parser(__doc__.splitlines()[1],
                **{"--points": dict(type=int, default=None, help="tau samples (101 with --full, else 21)")}).parse_args())
