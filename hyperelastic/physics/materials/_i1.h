/* The rubbers whose isochoric energy is a function W(I1_bar) of the first invariant alone, with the volumetric part
 * kappa/4 (J^2 - 1 - 2 ln J) of neohookean_split (yeoh.h, gent.h, arruda_boyce.h; numpy reference _i1.py):
 * P = a (F - I1/3 Q) + g Q, Q = F^-T, a = 2 W' J^(-2/3), g = kappa/2 (J^2 - 1), and dP = split_dstress (_tensor.h)
 * with b = 4 W'' J^(-4/3). HE_I1_MATERIAL(NAME, KAPPA) defines NAME_cache, NAME_stress, NAME_prepare and
 * NAME_dstress (and the closed-form cell tangent, NAME_cell_tangent: _tensor.h's split_cell_tangent) from the model's
 *   int NAME_w(const double *prm, double s, double *w, double *w1, double *w2)
 * (W, W', W'' at s = I1_bar - 3, W only where w is not NULL, W'' only where w2 is not NULL (the stress needs
 * neither); returns 1 where W is undefined: a locking model beyond its limit), the bulk modulus being prm[KAPPA]. Stress and prepare return 1 where J <= 0 or W is undefined. */
#ifndef HE_I1_H
#define HE_I1_H
#include "_tensor.h"

typedef struct { double F[9], Q[9], a, I1, kJ2, g, b; } i1_cache;

/* Q, I1, kappa J^2, g and J^(-2/3) of F; returns 1 (nothing else computed) where J <= 0. */
HE_INLINE int i1_scalars(const double *F, double kappa, i1_cache *d, double *J, double *jm23) {
  if (split_scalars(F, J, d->Q, jm23)) return 1;
  d->I1 = 0;
  for (int k = 0; k < 9; k++) d->I1 += F[k] * F[k];
  d->kJ2 = kappa * *J * *J;
  d->g = 0.5 * kappa * (*J * *J - 1);
  return 0;
}

/* P = a F + (g - a I1/3) Q; psi = w + kappa/4 (J^2 - 1 - 2 ln J) where wanted (NaN, returning 1, where undefined). */
HE_INLINE int i1_stress(int undefined, const i1_cache *d, double kappa, double J, double w, const double *F,
                        double *P, double *psi) {
  if (undefined) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d->g - d->a * d->I1 / 3.0;
  for (int k = 0; k < 9; k++) P[k] = d->a * F[k] + s * d->Q[k];
  if (psi) *psi = w + 0.25 * kappa * (J * J - 1 - 2 * log(J));
  return 0;
}

#define HE_I1_MATERIAL(NAME, KAPPA)                                                                                 \
  typedef i1_cache NAME##_cache;                                                                                    \
  HE_INLINE int NAME##_scalars(const double *prm, const double *F, i1_cache *d, double *J, double *w, int tangent) { \
    double jm23, w1, w2 = 0;                                                                                        \
    if (i1_scalars(F, prm[KAPPA], d, J, &jm23) ||                                                                   \
        NAME##_w(prm, jm23 * d->I1 - 3, w, &w1, tangent ? &w2 : NULL)) return 1;                                   \
    d->a = 2 * w1 * jm23;                                                                                           \
    d->b = 4 * w2 * jm23 * jm23;                                                                                    \
    return 0;                                                                                                       \
  }                                                                                                                 \
  HE_INLINE int NAME##_stress(const double *prm, const double *F, double *P, double *psi) {                         \
    i1_cache d;                                                                                                     \
    double J, w = 0;                                                                                                \
    const int undefined = NAME##_scalars(prm, F, &d, &J, psi ? &w : NULL, 0);                                       \
    return i1_stress(undefined, &d, prm[KAPPA], J, w, F, P, psi);                                                   \
  }                                                                                                                 \
  HE_INLINE int NAME##_prepare(const double *prm, const double *F, i1_cache *d) {                                   \
    double J;                                                                                                       \
    if (NAME##_scalars(prm, F, d, &J, NULL, 1)) return 1;                                                           \
    memcpy(d->F, F, sizeof d->F);                                                                                   \
    return 0;                                                                                                       \
  }                                                                                                                 \
  HE_INLINE void NAME##_dstress(const double *prm, const i1_cache *d, const double *dF, double *dP) {               \
    (void)prm;                                                                                                      \
    split_dstress(d->a, d->b, d->I1, d->kJ2, d->g, d->F, d->Q, dF, dP);                                             \
  }                                                                                                                 \
  HE_INLINE void NAME##_cell_tangent(const double *prm, const i1_cache *d, double G[4][3], double V, double *K,      \
                                     int accumulate) {                                                              \
    (void)prm;                                                                                                      \
    split_cell_tangent(d->a, d->b, d->I1, d->kJ2, d->g, d->F, d->Q, G, V, K, accumulate);                           \
  }                                                                                                                 \
  HE_INLINE void NAME##_cell_tangent_diag(const double *prm, const i1_cache *d, double G[4][3], double V,            \
                                          double diag[12]) {                                                        \
    (void)prm;                                                                                                      \
    split_cell_tangent_diag(d->a, d->b, d->I1, d->kJ2, d->g, d->F, d->Q, G, V, diag);                               \
  }

#endif
