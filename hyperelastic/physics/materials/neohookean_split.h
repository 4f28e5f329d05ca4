/* Neo-Hookean with an isochoric/volumetric split (Simo & Taylor, CMAME 85, 1991):
 * Psi = mu/2 (J^(-2/3) I1 - 3) + kappa/4 (J^2 - 1 - 2 ln J), constants (mu, kappa);
 * P = a (F - I1/3 Q) + g Q with Q = F^-T, a = mu J^(-2/3), g = kappa/2 (J^2 - 1). Undefined for J <= 0
 * (stress and prepare return 1 there). Numpy reference: neohookean_split.py. */
#include "_tensor.h"
typedef struct { double F[9], Q[9], a, I1, kJ2, g; } neohookean_split_cache;

/* The scalars of F (J > 0): Q = F^-T, I1, a = mu J^(-2/3) (J^(-2/3) = 1/cbrt(J)^2), g and kappa J^2. */
HE_INLINE int neohookean_split_scalars(const double *prm, const double *F, neohookean_split_cache *d,
                                           double *J) {
  const double mu = prm[0], kappa = prm[1];
  double jm23;
  if (split_scalars(F, J, d->Q, &jm23)) return 1;
  d->I1 = 0;
  for (int k = 0; k < 9; k++) d->I1 += F[k] * F[k];
  d->a = mu * jm23;
  d->kJ2 = kappa * *J * *J;
  d->g = 0.5 * kappa * (*J * *J - 1);
  return 0;
}

HE_INLINE int neohookean_split_stress(const double *prm, const double *F, double *P, double *psi) {
  neohookean_split_cache d;
  double J;
  if (neohookean_split_scalars(prm, F, &d, &J)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d.g - d.a * d.I1 / 3.0;
  for (int k = 0; k < 9; k++) P[k] = d.a * F[k] + s * d.Q[k];
  if (psi) *psi = 0.5 * (d.a * d.I1 - 3 * prm[0]) + 0.25 * prm[1] * (J * J - 1 - 2 * log(J));
  return 0;
}

HE_INLINE int neohookean_split_prepare(const double *prm, const double *F, neohookean_split_cache *d) {
  double J;
  if (neohookean_split_scalars(prm, F, d, &J)) return 1;
  memcpy(d->F, F, sizeof d->F);
  return 0;
}

/* dP = a (dF - 2/3 (Q:dF) F - 2/3 (F:dF) Q + 2/9 I1 (Q:dF) Q + I1/3 Q dF^T Q) + kappa J^2 (Q:dF) Q - g Q dF^T Q */
HE_INLINE void neohookean_split_dstress(const double *prm, const neohookean_split_cache *d, const double *dF,
                                            double *dP) {
  (void)prm;
  split_dstress(d->a, 0.0, d->I1, d->kJ2, d->g, d->F, d->Q, dF, dP);
}

/* The 12x12 cell tangent in closed form (_tensor.h, split_cell_tangent with no W'' term). */
#define neohookean_split_CELL_TANGENT 1
HE_INLINE void neohookean_split_cell_tangent(const double *prm, const neohookean_split_cache *d, double G[4][3],
                                                 double V, double *K, int accumulate) {
  (void)prm;
  split_cell_tangent(d->a, 0.0, d->I1, d->kJ2, d->g, d->F, d->Q, G, V, K, accumulate);
}

HE_INLINE void neohookean_split_cell_tangent_diag(const double *prm, const neohookean_split_cache *d,
                                                      double G[4][3], double V, double diag[12]) {
  (void)prm;
  split_cell_tangent_diag(d->a, 0.0, d->I1, d->kJ2, d->g, d->F, d->Q, G, V, diag);
}
