/* Compressible Neo-Hookean, Psi = mu/2 (I1-3) - mu lnJ + lam/2 (lnJ)^2 (Bonet & Wood, Nonlinear
 * Continuum Mechanics, eq. 6.27); undefined for J <= 0 (stress and prepare return 1 there).
 * Numpy reference: neohookean.py. */
#include "_tensor.h"
typedef struct { double FiT[9], c1, c2; } neohookean_cache;

/* The stress and energy density from F and the scalars of J = det F > 0: rJ = 1/J, lnJ = ln J (given:
 * the cell loops compute them for a block of cells at once, NAME_BATCH_J in _material_loops.h). */
#define neohookean_BATCH_J 1
HE_INLINE void neohookean_stress_j(const double *prm, const double *F, double rJ, double lnJ, double *P,
                                       double *psi) {
  const double mu = prm[0], lam = prm[1];
  double FiT[9];
  cof_mixed(F, F, FiT);
  double c = lam * lnJ - mu, I1 = 0;
  for (int k = 0; k < 9; k++) { P[k] = mu * F[k] + c * (FiT[k] * rJ); I1 += F[k] * F[k]; }
  if (psi) *psi = 0.5 * mu * (I1 - 3) - mu * lnJ + 0.5 * lam * lnJ * lnJ;
}

HE_INLINE int neohookean_stress(const double *prm, const double *F, double *P, double *psi) {
  double J = det3(F);
  if (!(J > 0)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  neohookean_stress_j(prm, F, 1.0 / J, log(J), P, psi);
  return 0;
}

HE_INLINE void neohookean_prepare_j(const double *prm, const double *F, double rJ, double lnJ,
                                        neohookean_cache *d) {
  const double mu = prm[0], lam = prm[1];
  cof_mixed(F, F, d->FiT);
  for (int k = 0; k < 9; k++) d->FiT[k] *= rJ;
  d->c1 = mu - lam * lnJ; /* coefficient of F^-T dF^T F^-T */
  d->c2 = lam;            /* coefficient of tr(F^-1 dF) F^-T */
}

HE_INLINE int neohookean_prepare(const double *prm, const double *F, neohookean_cache *d) {
  double J = det3(F);
  if (!(J > 0)) return 1;
  neohookean_prepare_j(prm, F, 1.0 / J, log(J), d);
  return 0;
}

/* dP = mu dF + c1 F^-T dF^T F^-T + lam tr(F^-1 dF) F^-T */
HE_INLINE void neohookean_dstress(const double *prm, const neohookean_cache *d, const double *dF, double *dP) {
  const double mu = prm[0];
  const double *Q = d->FiT;
  double T[9], U[9];
  mtm(dF, Q, T); /* T = dF^T Q ; U = Q T = F^-T dF^T F^-T */
  mm(Q, T, U);
  double tr = 0; /* tr(F^-1 dF) = sum_ij F^-T_ij dF_ij */
  for (int k = 0; k < 9; k++) tr += Q[k] * dF[k];
  for (int k = 0; k < 9; k++) dP[k] = mu * dF[k] + d->c1 * U[k] + d->c2 * tr * Q[k];
}

/* The 12x12 cell tangent in closed form. Column (b,k) differentiates along dF = e_k (x) G_b, which is rank
 * one, so with Q = F^-T and h_a = Q G_a: F^-T dF^T F^-T = h_b (x) Q_k (Q_k the k-th row of Q),
 * tr(F^-1 dF) = h_b,k, and K[(a,i),(b,k)] = V sum_j dP_ij G_a,j is
 *   V (mu delta_ik G_a.G_b + c1 h_b,i h_a,k + c2 h_b,k h_a,i)
 * (~0.4 kflop per cell against ~1.6 for twelve dP evaluations; the columns' result to rounding).
 * Its diagonal: V (mu |G_a|^2 + (c1 + c2) h_a,i^2). */
#define neohookean_CELL_TANGENT 1
HE_INLINE void neohookean_cell_tangent(const double *prm, const neohookean_cache *d, double G[4][3], double V,
                                           double *K, int accumulate) {
  const double mu = prm[0];
  double h[4][3], gg[4][4];
  m_grads(d->FiT, G, h);
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) gg[a][b] = V * mu * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
  const double c1 = V * d->c1, c2 = V * d->c2;
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++) {
      double *row = K + 12 * (3 * a + i);
      for (int b = 0; b < 4; b++)
        for (int k = 0; k < 3; k++) {
          double v = c1 * h[b][i] * h[a][k] + c2 * h[b][k] * h[a][i] + (i == k ? gg[a][b] : 0.0);
          if (accumulate) row[3 * b + k] += v;
          else row[3 * b + k] = v;
        }
    }
}

HE_INLINE void neohookean_cell_tangent_diag(const double *prm, const neohookean_cache *d, double G[4][3],
                                                double V, double diag[12]) {
  const double mu = prm[0];
  double h[4][3];
  m_grads(d->FiT, G, h);
  for (int a = 0; a < 4; a++) {
    double g2 = V * mu * (G[a][0] * G[a][0] + G[a][1] * G[a][1] + G[a][2] * G[a][2]);
    for (int i = 0; i < 3; i++) diag[3 * a + i] = g2 + V * (d->c1 + d->c2) * h[a][i] * h[a][i];
  }
}
