/* Stable Neo-Hookean (Smith, de Goes, Kim, ACM TOG 37(2), 2018, eq. 14 and sec. 3.4):
 * Psi = ms/2 (I_C-3) + ls/2 (J-a)^2 - ms/2 ln(I_C+1) - Psi(I), a = 1 + 3 ms/(4 ls), with
 * ms = 4/3 mu, ls = lam + 5/6 mu so that its small-strain limit is linear elasticity with the given
 * (mu, lam); defined for every F, inverted included. Numpy reference: snh.py. */
typedef struct { double F[9], cof[9], c1, c2, c3, ls; } snh_cache;

/* Stable Neo-Hookean constants from the Lame pair (mu, lam): ms, ls, alpha and Psi(I). */
static inline void snh_constants(double mu, double lam, double *ms, double *ls, double *alpha, double *psi0) {
  *ms = 4.0 / 3.0 * mu;
  *ls = lam + 5.0 / 6.0 * mu;
  *alpha = 1 + 0.75 * (*ms) / (*ls);
  *psi0 = 0.5 * (*ls) * (1 - *alpha) * (1 - *alpha) - 0.5 * (*ms) * log(4.0);
}

static inline int snh_stress(double mu, double lam, const double *F, double *P, double *psi) {
  double ms, ls, al, psi0, cof[9], Ic = 0;
  snh_constants(mu, lam, &ms, &ls, &al, &psi0);
  cof_mixed(F, F, cof);
  double J = det3(F);
  for (int k = 0; k < 9; k++) Ic += F[k] * F[k];
  double a = ms * (1 - 1 / (Ic + 1)), b = ls * (J - al);
  for (int k = 0; k < 9; k++) P[k] = a * F[k] + b * cof[k];
  if (psi) *psi = 0.5 * ms * (Ic - 3) + 0.5 * ls * (J - al) * (J - al) - 0.5 * ms * log(Ic + 1) - psi0;
  return 0;
}

static inline int snh_prepare(double mu, double lam, const double *F, snh_cache *d) {
  double ms, ls, al, psi0, Ic = 0;
  memcpy(d->F, F, sizeof d->F);
  snh_constants(mu, lam, &ms, &ls, &al, &psi0);
  cof_mixed(F, F, d->cof); /* the cofactor matrix dJ/dF */
  for (int k = 0; k < 9; k++) Ic += F[k] * F[k];
  d->c1 = ms * (1 - 1 / (Ic + 1));        /* coefficient of dF */
  d->c2 = 2 * ms / ((Ic + 1) * (Ic + 1)); /* coefficient of (F:dF) F */
  d->c3 = ls * (det3(F) - al);            /* coefficient of d cof */
  d->ls = ls;                             /* coefficient of (cof:dF) cof */
  return 0;
}

/* dP = c1 dF + c2 (F:dF) F + ls (cof:dF) cof + c3 dcof[dF] */
static inline void snh_dstress(double mu, double lam, const snh_cache *d, const double *dF, double *dP) {
  (void)mu; (void)lam;
  const double *cof = d->cof;
  double A[9], B[9], fd = 0, cd = 0;
  cof_mixed(d->F, dF, A);
  cof_mixed(dF, d->F, B);
  for (int k = 0; k < 9; k++) { fd += d->F[k] * dF[k]; cd += cof[k] * dF[k]; }
  for (int k = 0; k < 9; k++)
    dP[k] = d->c1 * dF[k] + d->c2 * fd * d->F[k] + d->ls * cd * cof[k] + d->c3 * (A[k] + B[k]);
}
