/* Yeoh's reduced polynomial (Yeoh, Rubber Chem. Technol. 66, 1993) with the isochoric/volumetric split:
 * Psi = C10 s + C20 s^2 + C30 s^3 + kappa/4 (J^2 - 1 - 2 ln J), s = J^(-2/3) I1 - 3, constants (C10, C20, C30, kappa);
 * P = m (F - I1/3 Q) + g Q with Q = F^-T, m = 2 W'(s) J^(-2/3), g = kappa/2 (J^2 - 1): the neo-Hookean split's stress
 * with mu = 2 W'. dP is that one's plus 4 W'' J^(-4/3) (F:dF - I1/3 Q:dF) (F - I1/3 Q). Undefined for J <= 0
 * (stress and prepare return 1 there). Numpy reference: yeoh.py. */
#include "_tensor.h"
typedef struct { double F[9], Q[9], a, I1, kJ2, g, b; } yeoh_cache;

/* The scalars of F (J > 0): Q, I1, a = 2 W' J^(-2/3), b = 4 W'' J^(-4/3), kappa J^2, g; psi's isochoric part. */
HE_INLINE int yeoh_scalars(const double *prm, const double *F, yeoh_cache *d, double *J, double *w) {
  const double C10 = prm[0], C20 = prm[1], C30 = prm[2], kappa = prm[3];
  double jm23;
  if (split_scalars(F, J, d->Q, &jm23)) return 1;
  d->I1 = 0;
  for (int k = 0; k < 9; k++) d->I1 += F[k] * F[k];
  const double s = jm23 * d->I1 - 3;
  *w = s * (C10 + s * (C20 + s * C30));
  d->a = 2 * (C10 + s * (2 * C20 + 3 * C30 * s)) * jm23;
  d->b = 4 * (2 * C20 + 6 * C30 * s) * jm23 * jm23;
  d->kJ2 = kappa * *J * *J;
  d->g = 0.5 * kappa * (*J * *J - 1);
  return 0;
}

HE_INLINE int yeoh_stress(const double *prm, const double *F, double *P, double *psi) {
  yeoh_cache d;
  double J, w;
  if (yeoh_scalars(prm, F, &d, &J, &w)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d.g - d.a * d.I1 / 3.0;
  for (int k = 0; k < 9; k++) P[k] = d.a * F[k] + s * d.Q[k];
  if (psi) *psi = w + 0.25 * prm[3] * (J * J - 1 - 2 * log(J));
  return 0;
}

HE_INLINE int yeoh_prepare(const double *prm, const double *F, yeoh_cache *d) {
  double J, w;
  if (yeoh_scalars(prm, F, d, &J, &w)) return 1;
  memcpy(d->F, F, sizeof d->F);
  return 0;
}

/* dP = a (dF - 2/3 (Q:dF) F - 2/3 (F:dF) Q + 2/9 I1 (Q:dF) Q + I1/3 Q dF^T Q) + b (F:dF - I1/3 Q:dF)(F - I1/3 Q)
 *      + kappa J^2 (Q:dF) Q - g Q dF^T Q */
HE_INLINE void yeoh_dstress(const double *prm, const yeoh_cache *d, const double *dF, double *dP) {
  (void)prm;
  split_dstress(d->a, d->b, d->I1, d->kJ2, d->g, d->F, d->Q, dF, dP);
}
