#!/usr/bin/env python
"""The start of arruda_boyce.h's inverse Langevin iteration: Chebyshev fits, piece by piece in r, of g(r) = beta (1 - r)
/ r (beta = L^-1(r); g(0) = 3, g(1) = 1), against the numpy reference's Newton iteration to round-off
(hyperelastic/physics/materials/arruda_boyce.py). Prints the C table (INVLANGEVIN_EDGES, INVLANGEVIN_CHEB) and the
largest relative error of beta on each piece (one Newton step from it reaches round-off: error ~ e^2).

    python scripts/fit_inverse_langevin.py            # the table in arruda_boyce.h
"""
import os
import sys

import numpy as np
from numpy.polynomial import Chebyshev

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.physics.materials.arruda_boyce import inverse_langevin   # noqa: E402

EDGES = (0.0, 0.25, 0.5, 0.7, 0.8, 0.9, 0.97, 1.0)
DEGREE = 10


def main():
    rows, errs = [], []
    for lo, hi in zip(EDGES[:-1], EDGES[1:]):
        r = np.linspace(lo, hi, 8001)
        r = r[(r > 0) & (r < 1)]
        b = inverse_langevin(r)
        c = Chebyshev.fit(r, b * (1 - r) / r, DEGREE, domain=[lo, hi])
        errs.append(np.abs(c(r) * r / (1 - r) / b - 1).max())
        rows.append(c.coef)
    print("static const double INVLANGEVIN_EDGES[%d] = {%s};" % (len(EDGES), ", ".join(f"{e!r}" for e in EDGES)))
    print("static const double INVLANGEVIN_CHEB[%d][%d] = {" % (len(rows), DEGREE + 1))
    for c in rows:
        vals = [f"{v:.17g}" for v in c]
        print("  {" + ",\n   ".join(", ".join(vals[i:i + 4]) for i in range(0, len(vals), 4)) + "},")
    print("};")
    print("/* largest relative error of beta per piece: " + ", ".join(f"{e:.1e}" for e in errs) + " */")


if __name__ == "__main__":
    main()
