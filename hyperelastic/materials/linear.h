/* Linear elasticity (thesis eqs. 3.27, 3.34): eps = sym(F) - I, P = 2 mu eps + lam tr(eps) I.
 * Numpy reference: linear.py. The contract of a material header: see docs/design.md. */
typedef struct { char unused; } linear_cache;

static inline int linear_stress(double mu, double lam, const double *F, double *P, double *psi) {
  double e[9];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) e[3 * i + j] = 0.5 * (F[3 * i + j] + F[3 * j + i]) - (i == j);
  double tr = e[0] + e[4] + e[8];
  double ee = 0;
  for (int k = 0; k < 9; k++) { P[k] = 2 * mu * e[k]; ee += e[k] * e[k]; }
  P[0] += lam * tr; P[4] += lam * tr; P[8] += lam * tr;
  if (psi) *psi = mu * ee + 0.5 * lam * tr * tr;
  return 0;
}

static inline int linear_prepare(double mu, double lam, const double *F, linear_cache *d) {
  (void)mu; (void)lam; (void)F; (void)d;
  return 0;
}

static inline void linear_dstress(double mu, double lam, const linear_cache *d, const double *dF, double *dP) {
  (void)d;
  double tr = dF[0] + dF[4] + dF[8];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) dP[3 * i + j] = mu * (dF[3 * i + j] + dF[3 * j + i]);
  dP[0] += lam * tr; dP[4] += lam * tr; dP[8] += lam * tr;
}
