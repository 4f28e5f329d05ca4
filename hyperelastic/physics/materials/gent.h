/* Gent's model (Gent, Rubber Chem. Technol. 69, 1996) with the isochoric/volumetric split: constants (mu, Jm, kappa),
 * W = -mu Jm/2 ln(1 - s/Jm), s = J^(-2/3) I1 - 3 < Jm; W' = mu/2 / x, W'' = mu/(2 Jm) / x^2, x = 1 - s/Jm. The stress
 * and its derivative those of _i1.h. Undefined for J <= 0 and for s >= Jm. Numpy reference: gent.py. */
#include "_i1.h"

HE_INLINE int gent_w(const double *prm, double s, double *w, double *w1, double *w2) {
  const double mu = prm[0], Jm = prm[1];
  if (!(s < Jm)) return 1;
  const double x = 1 - s / Jm;
  if (w) *w = -0.5 * mu * Jm * log1p(-s / Jm);
  *w1 = 0.5 * mu / x;
  if (w2) *w2 = 0.5 * mu / (Jm * x * x);
  return 0;
}

#define gent_CELL_TANGENT 1
HE_I1_MATERIAL(gent, 2)
