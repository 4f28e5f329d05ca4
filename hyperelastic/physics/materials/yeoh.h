/* Yeoh's reduced polynomial (Yeoh, Rubber Chem. Technol. 66, 1993) with the isochoric/volumetric split:
 * Psi = C10 s + C20 s^2 + C30 s^3 + kappa/4 (J^2 - 1 - 2 ln J), s = J^(-2/3) I1 - 3, constants (C10, C20, C30, kappa);
 * the stress and its derivative those of _i1.h. Undefined for J <= 0. Numpy reference: yeoh.py. */
#include "_i1.h"

HE_INLINE int yeoh_w(const double *prm, double s, double *w, double *w1, double *w2) {
  const double C10 = prm[0], C20 = prm[1], C30 = prm[2];
  if (w) *w = s * (C10 + s * (C20 + s * C30));
  *w1 = C10 + s * (2 * C20 + 3 * C30 * s);
  if (w2) *w2 = 2 * C20 + 6 * C30 * s;
  return 0;
}

#define yeoh_CELL_TANGENT 1
HE_I1_MATERIAL(yeoh, 3)
