/* St. Venant-Kirchhoff (thesis eqs. 3.35, 3.40): E = (F^T F - I)/2, P = F (2 mu E + lam tr(E) I).
 * Numpy reference: stvk.py. */
#include "_tensor.h"
typedef struct { double F[9], S[9]; } stvk_cache;

HE_INLINE int stvk_stress(const double *prm, const double *F, double *P, double *psi) {
  const double mu = prm[0], lam = prm[1];
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

HE_INLINE int stvk_prepare(const double *prm, const double *F, stvk_cache *d) {
  const double mu = prm[0], lam = prm[1];
  memcpy(d->F, F, sizeof d->F);
  double C[9];
  mtm(F, F, C);
  double tr = 0.5 * (C[0] + C[4] + C[8]) - 1.5;
  for (int k = 0; k < 9; k++) d->S[k] = mu * C[k];
  d->S[0] += lam * tr - mu; d->S[4] += lam * tr - mu; d->S[8] += lam * tr - mu;
  return 0;
}

/* dP = dF S + F (2 mu dE + lam tr(dE) I), dE = sym(F^T dF) */
HE_INLINE void stvk_dstress(const double *prm, const stvk_cache *d, const double *dF, double *dP) {
  const double mu = prm[0], lam = prm[1];
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

/* The 12x12 cell tangent in closed form (as neohookean.h's): along dF = e_k (x) G_b, with u_a = F G_a and
 * B = F F^T, dF S gives delta_ik G_a.S.G_b, F (lam tr(dE) I) gives lam u_b,k u_a,i and F (2 mu dE) gives
 * mu (B_ik G_a.G_b + u_b,i u_a,k), so
 *   K[(a,i),(b,k)] = V (delta_ik G_a.S.G_b + lam u_a,i u_b,k + mu B_ik G_a.G_b + mu u_a,k u_b,i). */
#define stvk_CELL_TANGENT 1
HE_INLINE void stvk_cell_tangent(const double *prm, const stvk_cache *d, double G[4][3], double V, double *K,
                                     int accumulate) {
  const double mu = prm[0], lam = prm[1];
  const double *F = d->F, *S = d->S;
  double u[4][3], SG[4][3], gsg[4][4], gg[4][4], B[9];
  m_grads(F, G, u);
  for (int i = 0; i < 3; i++)
    for (int k = 0; k < 3; k++) B[3 * i + k] = F[3 * i] * F[3 * k] + F[3 * i + 1] * F[3 * k + 1] + F[3 * i + 2] * F[3 * k + 2];
  m_grads(S, G, SG);
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) {
      gsg[a][b] = V * (G[a][0] * SG[b][0] + G[a][1] * SG[b][1] + G[a][2] * SG[b][2]);
      gg[a][b] = V * mu * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
    }
  const double vl = V * lam, vm = V * mu;
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++) {
      double *row = K + 12 * (3 * a + i);
      for (int b = 0; b < 4; b++)
        for (int k = 0; k < 3; k++) {
          double v = vl * u[a][i] * u[b][k] + vm * u[a][k] * u[b][i] + B[3 * i + k] * gg[a][b] +
                     (i == k ? gsg[a][b] : 0.0);
          if (accumulate) row[3 * b + k] += v;
          else row[3 * b + k] = v;
        }
    }
}

HE_INLINE void stvk_cell_tangent_diag(const double *prm, const stvk_cache *d, double G[4][3], double V,
                                          double diag[12]) {
  const double mu = prm[0], lam = prm[1];
  const double *F = d->F, *S = d->S;
  double u[4][3];
  m_grads(F, G, u);
  for (int a = 0; a < 4; a++) {
    double gsg = 0, g2 = 0;
    for (int m = 0; m < 3; m++) {
      g2 += G[a][m] * G[a][m];
      gsg += G[a][m] * (S[3 * m] * G[a][0] + S[3 * m + 1] * G[a][1] + S[3 * m + 2] * G[a][2]);
    }
    for (int i = 0; i < 3; i++) {
      double Bii = F[3 * i] * F[3 * i] + F[3 * i + 1] * F[3 * i + 1] + F[3 * i + 2] * F[3 * i + 2];
      diag[3 * a + i] = V * (gsg + (lam + mu) * u[a][i] * u[a][i] + mu * Bii * g2);
    }
  }
}
