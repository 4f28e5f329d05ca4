#!/usr/bin/env python
"""arruda_boyce.h's chain functions of r = sqrt(I1_bar / 3) / lambda_m, by Chebyshev series piece by piece in r, fitted to
the numpy reference (hyperelastic/physics/materials/arruda_boyce.py: beta = L^-1(r) by Newton's iteration to round-off):
  g(r)   = beta (1 - r) / r                       (g(0) = 3; beta = g r / (1 - r))
  h(r)   = (1 - r)^2 / L'(beta)                   (h(0) = 3 ...; 1/L' = h / (1 - r)^2)
  psi(r) = r beta + ln(beta / sinh beta) + ln(1 - r)   (the energy's chain term phi = psi - ln(1 - r))
each smooth on [0, R_ASYMPTOTIC] once the poles at r = 1 are taken out. Beyond R_ASYMPTOTIC (beta > 20: exp(-2 beta) <
5e-18) L(beta) = 1 - 1/beta to round-off, so beta = 1/(1 - r), 1/L' = beta^2 and phi = ln(2 / (1 - r)) - 1 exactly
(arruda_boyce.h). PIECES pieces of equal width (the kernel finds its piece by one multiplication), on each a polynomial
of degree DEGREE in t in [-1, 1] interpolating at the piece's Chebyshev points, written in the power basis (the kernel
evaluates it by Estrin's scheme: a dependency chain of four multiplications, where a series of eleven terms by
Clenshaw's recurrence or Horner's rule waits on eleven); prints the C tables and the largest relative error of beta,
1/L' and phi on each piece, on a grid of 2,001 points per piece, evaluated in the power basis.

    python scripts/fit_inverse_langevin.py            # the tables in arruda_boyce.h
"""
import os
import sys

import numpy as np
from numpy.polynomial import Chebyshev, Polynomial

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.physics.materials.arruda_boyce import inverse_langevin, langevin   # noqa: E402

PIECES, R_ASYMPTOTIC = 19, 0.95
EDGES = tuple(R_ASYMPTOTIC * k / PIECES for k in range(PIECES + 1))
DEGREE = 10


def chain(r):
    """(g, h, psi, beta, 1/L', phi) at r (arrays, 0 < r < 1)."""
    b = inverse_langevin(r)
    _, dL, lbs = langevin(b)
    return b * (1 - r) / r, (1 - r) ** 2 / dL, r * b + lbs + np.log1p(-r), b, 1 / dL, r * b + lbs


def fit(lo, hi):
    """The three polynomials in t on [lo, hi] (power basis, interpolating at its Chebyshev points) and their largest
    relative errors."""
    n = DEGREE + 1
    r = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(n) + 0.5) / n)
    polys = [Chebyshev(Chebyshev.fit(r, y, DEGREE, domain=[lo, hi]).coef).convert(kind=Polynomial)
             for y in chain(r)[:3]]
    rr = np.linspace(lo, hi, 2001)
    rr = rr[rr > 1e-6]
    t = (2 * rr - lo - hi) / (hi - lo)
    g, h, psi, b, idL, phi = chain(rr)
    errs = (np.abs(polys[0](t) * rr / (1 - rr) / b - 1).max(), np.abs(polys[1](t) / (1 - rr) ** 2 / idL - 1).max(),
            np.abs(polys[2](t) - np.log1p(-rr) - phi).max() / np.abs(phi).max())
    return [np.pad(p.coef, (0, DEGREE + 1 - len(p.coef))) for p in polys], errs


def table(name, rows):
    print("static const double %s[%d][%d] = {" % (name, len(rows), DEGREE + 1))
    for c in rows:
        vals = [f"{v:.17g}" for v in c]
        print("  {" + ",\n   ".join(", ".join(vals[i:i + 4]) for i in range(0, len(vals), 4)) + "},")
    print("};")


def main():
    fits = [fit(lo, hi) for lo, hi in zip(EDGES[:-1], EDGES[1:])]
    print("#define AB_PIECES %d        /* of width AB_R / AB_PIECES on [0, AB_R] */" % PIECES)
    print("#define AB_R %r" % R_ASYMPTOTIC)
    print("#define AB_TERMS %d" % (DEGREE + 1))
    for k, name in enumerate(("AB_G", "AB_H", "AB_PSI")):
        table(name, [f[0][k] for f in fits])
    worst = np.max([f[1] for f in fits], axis=0)
    print("/* largest relative error over the pieces: beta %.1e, 1/L' %.1e, phi %.1e */" % tuple(worst))


if __name__ == "__main__":
    main()
