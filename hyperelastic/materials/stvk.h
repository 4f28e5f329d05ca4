/* St. Venant-Kirchhoff (thesis eqs. 3.35, 3.40): E = (F^T F - I)/2, P = F (2 mu E + lam tr(E) I).
 * Numpy reference: stvk.py. */
typedef struct { double F[9], S[9]; } stvk_cache;

static inline int stvk_stress(double mu, double lam, const double *F, double *P, double *psi) {
  double C[9], S[9];
  mtm(F, F, C);
  double E[9], ee = 0;
  for (int k = 0; k < 9; k++) E[k] = 0.5 * C[k];
  E[0] -= 0.5; E[4] -= 0.5; E[8] -= 0.5;
  double tr = E[0] + E[4] + E[8];
  for (int k = 0; k < 9; k++) { S[k] = 2 * mu * E[k]; ee += E[k] * E[k]; }
  S[0] += lam * tr; S[4] += lam * tr; S[8] += lam * tr;
  mm(F, S, P);
  if (psi) *psi = mu * ee + 0.5 * lam * tr * tr;
  return 0;
}

static inline int stvk_prepare(double mu, double lam, const double *F, stvk_cache *d) {
  memcpy(d->F, F, sizeof d->F);
  double C[9];
  mtm(F, F, C);
  double tr = 0.5 * (C[0] + C[4] + C[8]) - 1.5;
  for (int k = 0; k < 9; k++) d->S[k] = mu * C[k];
  d->S[0] += lam * tr - mu; d->S[4] += lam * tr - mu; d->S[8] += lam * tr - mu;
  return 0;
}

/* dP = dF S + F (2 mu dE + lam tr(dE) I), dE = sym(F^T dF) */
static inline void stvk_dstress(double mu, double lam, const stvk_cache *d, const double *dF, double *dP) {
  double G[9], dS[9], A[9], B[9];
  mtm(d->F, dF, G);
  double tr = G[0] + G[4] + G[8];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) dS[3 * i + j] = mu * (G[3 * i + j] + G[3 * j + i]);
  dS[0] += lam * tr; dS[4] += lam * tr; dS[8] += lam * tr;
  mm(dF, d->S, A);
  mm(d->F, dS, B);
  for (int k = 0; k < 9; k++) dP[k] = A[k] + B[k];
}
