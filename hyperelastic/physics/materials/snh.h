/* Stable Neo-Hookean (Smith, de Goes, Kim, ACM TOG 37(2), 2018, eq. 14 and sec. 3.4):
 * Psi = ms/2 (I_C-3) + ls/2 (J-a)^2 - ms/2 ln(I_C+1) - Psi(I), a = 1 + 3 ms/(4 ls), with
 * ms = 4/3 mu, ls = lam + 5/6 mu so that its small-strain limit is linear elasticity with the given
 * (mu, lam); defined for every F, inverted included. Numpy reference: snh.py. */
#include "_tensor.h"
typedef struct { double F[9], cof[9], c1, c2, c3, ls; } snh_cache;

/* Stable Neo-Hookean constants from the Lame pair (mu, lam): ms, ls, alpha and Psi(I). */
HE_INLINE void snh_constants(const double *prm, double *ms, double *ls, double *alpha, double *psi0) {
  const double mu = prm[0], lam = prm[1];
  *ms = 4.0 / 3.0 * mu;
  *ls = lam + 5.0 / 6.0 * mu;
  *alpha = 1 + 0.75 * (*ms) / (*ls);
  *psi0 = 0.5 * (*ls) * (1 - *alpha) * (1 - *alpha) - 0.5 * (*ms) * log(4.0);
}

HE_INLINE int snh_stress(const double *prm, const double *F, double *P, double *psi) {
  double ms, ls, al, psi0, cof[9], Ic = 0;
  snh_constants(prm, &ms, &ls, &al, &psi0);
  cof_mixed(F, F, cof);
  double J = det3(F);
  for (int k = 0; k < 9; k++) Ic += F[k] * F[k];
  double a = ms * (1 - 1 / (Ic + 1)), b = ls * (J - al);
  for (int k = 0; k < 9; k++) P[k] = a * F[k] + b * cof[k];
  if (psi) *psi = 0.5 * ms * (Ic - 3) + 0.5 * ls * (J - al) * (J - al) - 0.5 * ms * log(Ic + 1) - psi0;
  return 0;
}

HE_INLINE int snh_prepare(const double *prm, const double *F, snh_cache *d) {
  double ms, ls, al, psi0, Ic = 0;
  memcpy(d->F, F, sizeof d->F);
  snh_constants(prm, &ms, &ls, &al, &psi0);
  cof_mixed(F, F, d->cof); /* the cofactor matrix dJ/dF */
  for (int k = 0; k < 9; k++) Ic += F[k] * F[k];
  d->c1 = ms * (1 - 1 / (Ic + 1));        /* coefficient of dF */
  d->c2 = 2 * ms / ((Ic + 1) * (Ic + 1)); /* coefficient of (F:dF) F */
  d->c3 = ls * (det3(F) - al);            /* coefficient of d cof */
  d->ls = ls;                             /* coefficient of (cof:dF) cof */
  return 0;
}

/* dP = c1 dF + c2 (F:dF) F + ls (cof:dF) cof + c3 dcof[dF] */
HE_INLINE void snh_dstress(const double *prm, const snh_cache *d, const double *dF, double *dP) {
  (void)prm;
  const double *cof = d->cof;
  double A[9], B[9], fd = 0, cd = 0;
  cof_mixed(d->F, dF, A);
  cof_mixed(dF, d->F, B);
  for (int k = 0; k < 9; k++) { fd += d->F[k] * dF[k]; cd += cof[k] * dF[k]; }
  for (int k = 0; k < 9; k++)
    dP[k] = d->c1 * dF[k] + d->c2 * fd * d->F[k] + d->ls * cd * cof[k] + d->c3 * (A[k] + B[k]);
}

/* The 12x12 cell tangent in closed form: along dF = e_k (x) G_b, with u_a = F G_a and h_a = cof G_a,
 * F:dF = u_b,k, cof:dF = h_b,k, and (dcof[dF] G_a)_i = eps_imk w_m with w = F (G_b x G_a) (from
 * cof_ij = 1/2 eps_imn eps_jpq F_mp F_nq), so
 *   K[(a,i),(b,k)] = V (c1 delta_ik G_a.G_b + c2 u_a,i u_b,k + ls h_a,i h_b,k + c3 eps_imk w_m). */
#define snh_CELL_TANGENT 1
HE_INLINE void snh_cell_tangent(const double *prm, const snh_cache *d, double G[4][3], double V, double *K,
                                    int accumulate) {
  (void)prm;
  const double *F = d->F;
  double u[4][3], h[4][3];
  m_grads(d->F, G, u);
  m_grads(d->cof, G, h);
  const double v1 = V * d->c1, v2 = V * d->c2, vl = V * d->ls, v3 = V * d->c3;
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) {
      const double gg = v1 * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
      double c[3], w[3];   /* c = G_b x G_a, w = V c3 F c */
      cross3(G[b], G[a], c);
      mv3(F, c, w);
      for (int m = 0; m < 3; m++) w[m] *= v3;
      const double T[9] = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};   /* T_ik = eps_imk w_m */
      for (int i = 0; i < 3; i++) {
        double *row = K + 12 * (3 * a + i) + 3 * b;
        for (int k = 0; k < 3; k++) {
          double v = v2 * u[a][i] * u[b][k] + vl * h[a][i] * h[b][k] + T[3 * i + k] + (i == k ? gg : 0.0);
          if (accumulate) row[k] += v;
          else row[k] = v;
        }
      }
    }
}

HE_INLINE void snh_cell_tangent_diag(const double *prm, const snh_cache *d, double G[4][3], double V,
                                         double diag[12]) {
  (void)prm;
  double u[4][3], h[4][3];
  m_grads(d->F, G, u);
  m_grads(d->cof, G, h);
  for (int a = 0; a < 4; a++) {
    const double g2 = G[a][0] * G[a][0] + G[a][1] * G[a][1] + G[a][2] * G[a][2];
    for (int i = 0; i < 3; i++)
      diag[3 * a + i] = V * (d->c1 * g2 + d->c2 * u[a][i] * u[a][i] + d->ls * h[a][i] * h[a][i]);
  }
}
