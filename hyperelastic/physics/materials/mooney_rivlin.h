/* Compressible Mooney-Rivlin (Holzapfel, Nonlinear Solid Mechanics, 2000, sec. 6.5), constants (C10, C01, kappa):
 * Psi = C10 (J^(-2/3) I1 - 3) + C01 (J^(-4/3) I2 - 3) + kappa/4 (J^2 - 1 - 2 ln J), I2 = (I1^2 - C:C)/2;
 * P = a2 (F - I1/3 Q) + b (2 W - 4/3 I2 Q) + g Q with Q = F^-T, C = F^T F, W = I1 F - F C, a2 = 2 C10 J^(-2/3),
 * b = C01 J^(-4/3), g = kappa/2 (J^2 - 1). Undefined for J <= 0. Numpy reference: mooney_rivlin.py. */
#include "_tensor.h"
typedef struct { double F[9], Q[9], C[9], B[9], W[9], a2, b, I1, I2, kJ2, g; } mooney_rivlin_cache;

/* Q, C, W and the scalars of F (J > 0). */
HE_INLINE int mooney_rivlin_scalars(const double *prm, const double *F, mooney_rivlin_cache *d, double *J) {
  const double C10 = prm[0], C01 = prm[1], kappa = prm[2];
  double j23;
  if (split_scalars(F, J, d->Q, &j23)) return 1;
  mtm(F, F, d->C);
  d->I1 = d->C[0] + d->C[4] + d->C[8];
  double cc = 0;
  for (int k = 0; k < 9; k++) cc += d->C[k] * d->C[k];
  d->I2 = 0.5 * (d->I1 * d->I1 - cc);
  mm(F, d->C, d->W); /* W = I1 F - F C */
  for (int k = 0; k < 9; k++) d->W[k] = d->I1 * F[k] - d->W[k];
  d->a2 = 2 * C10 * j23;
  d->b = C01 * j23 * j23;
  d->kJ2 = kappa * *J * *J;
  d->g = 0.5 * kappa * (*J * *J - 1);
  return 0;
}

HE_INLINE int mooney_rivlin_stress(const double *prm, const double *F, double *P, double *psi) {
  mooney_rivlin_cache d;
  double J;
  if (mooney_rivlin_scalars(prm, F, &d, &J)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d.g - d.a2 * d.I1 / 3.0 - 4.0 / 3.0 * d.b * d.I2;
  for (int k = 0; k < 9; k++) P[k] = d.a2 * F[k] + 2 * d.b * d.W[k] + s * d.Q[k];
  if (psi)
    *psi = 0.5 * d.a2 * d.I1 - 3 * prm[0] + d.b * d.I2 - 3 * prm[1] + 0.25 * prm[2] * (J * J - 1 - 2 * log(J));
  return 0;
}

HE_INLINE int mooney_rivlin_prepare(const double *prm, const double *F, mooney_rivlin_cache *d) {
  double J;
  if (mooney_rivlin_scalars(prm, F, d, &J)) return 1;
  memcpy(d->F, F, sizeof d->F);
  /* B = F F^T */
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      d->B[3 * i + j] = F[3 * i] * F[3 * j] + F[3 * i + 1] * F[3 * j + 1] + F[3 * i + 2] * F[3 * j + 2];
  return 0;
}

/* dP = a2 (dF - 2/3 qd F - 2/3 fd Q + 2/9 I1 qd Q + I1/3 U) + b (-4/3 qd (2 W - 4/3 I2 Q) + 2 dW - 8/3 wd Q
 *      + 4/3 I2 U) + kappa J^2 qd Q - g U, with qd = Q:dF, fd = F:dF, wd = W:dF, U = Q dF^T Q and
 * dW = 2 fd F + I1 dF - dF C - F (dF^T F + F^T dF). */
HE_INLINE void mooney_rivlin_dstress(const double *prm, const mooney_rivlin_cache *d, const double *dF,
                                         double *dP) {
  (void)prm;
  const double *Q = d->Q, *F = d->F, *W = d->W;
  double T[9], U[9], dFC[9], dC[9], FdC[9], qd = 0, fd = 0, wd = 0;
  mtm(dF, Q, T);
  mm(Q, T, U);
  mm(dF, d->C, dFC);
  mtm(dF, F, dC); /* dC = dF^T F + F^T dF */
  for (int i = 0; i < 3; i++)
    for (int j = i; j < 3; j++) dC[3 * i + j] = dC[3 * j + i] = dC[3 * i + j] + dC[3 * j + i];
  mm(F, dC, FdC);
  for (int k = 0; k < 9; k++) { qd += Q[k] * dF[k]; fd += F[k] * dF[k]; wd += W[k] * dF[k]; }
  const double a2 = d->a2, b = d->b;
  const double cF = -2.0 / 3.0 * a2 * qd + 4 * b * fd;
  const double cQ = a2 * (2.0 / 9.0 * d->I1 * qd - 2.0 / 3.0 * fd) + b * (16.0 / 9.0 * d->I2 * qd - 8.0 / 3.0 * wd)
                    + d->kJ2 * qd;
  const double cU = a2 * d->I1 / 3.0 + 4.0 / 3.0 * b * d->I2 - d->g, cW = -8.0 / 3.0 * b * qd;
  const double cdF = a2 + 2 * b * d->I1;
  for (int k = 0; k < 9; k++)
    dP[k] = cdF * dF[k] + cF * F[k] + cQ * Q[k] + cU * U[k] + cW * W[k] - 2 * b * (dFC[k] + FdC[k]);
}

/* The 12x12 cell tangent in closed form: along dF = e_k (x) G_b, with u_a = F G_a, h_a = Q G_a, w_a = W G_a,
 *   K[(a,i),(b,k)] = V (delta_ik ((a2 + 2 b I1) G_a.G_b - 2 b G_a.C G_b) - 2/3 a2 (u_a,i h_b,k + h_a,i u_b,k)
 *                       - 8/3 b (w_a,i h_b,k + h_a,i w_b,k) + c_hh h_a,i h_b,k + c_x h_b,i h_a,k
 *                       + 4 b u_a,i u_b,k - 2 b u_b,i u_a,k - 2 b B_ik G_a.G_b),
 * c_hh = 2/9 a2 I1 + kappa J^2 + 16/9 b I2, c_x = a2 I1/3 - g + 4/3 b I2 (the dF, F dC and dF C terms of dW
 * give the delta_ik, B and u u terms). */
#define mooney_rivlin_CELL_TANGENT 1
HE_INLINE void mooney_rivlin_cell_tangent(const double *prm, const mooney_rivlin_cache *d, double G[4][3],
                                              double V, double *K, int accumulate) {
  (void)prm;
  double u[4][3], h[4][3], w[4][3], cg[4][3];
  m_grads(d->F, G, u);
  m_grads(d->Q, G, h);
  m_grads(d->W, G, w);
  m_grads(d->C, G, cg);
  const double a2 = V * d->a2, b = V * d->b, c2 = -2.0 / 3.0 * a2, c8 = -8.0 / 3.0 * b;
  const double chh = 2.0 / 9.0 * a2 * d->I1 + V * d->kJ2 + 16.0 / 9.0 * b * d->I2;
  const double cx = a2 * d->I1 / 3.0 - V * d->g + 4.0 / 3.0 * b * d->I2;
  for (int a = 0; a < 4; a++)
    for (int bb = 0; bb < 4; bb++) {
      const double gg = G[a][0] * G[bb][0] + G[a][1] * G[bb][1] + G[a][2] * G[bb][2];
      const double gcg = G[a][0] * cg[bb][0] + G[a][1] * cg[bb][1] + G[a][2] * cg[bb][2];
      const double diag = (a2 + 2 * b * d->I1) * gg - 2 * b * gcg;
      for (int i = 0; i < 3; i++) {
        double *row = K + 12 * (3 * a + i) + 3 * bb;
        for (int k = 0; k < 3; k++) {
          double v = c2 * (u[a][i] * h[bb][k] + h[a][i] * u[bb][k]) + c8 * (w[a][i] * h[bb][k] + h[a][i] * w[bb][k])
                     + chh * h[a][i] * h[bb][k] + cx * h[bb][i] * h[a][k] + 4 * b * u[a][i] * u[bb][k]
                     - 2 * b * u[bb][i] * u[a][k] - 2 * b * d->B[3 * i + k] * gg + (i == k ? diag : 0.0);
          if (accumulate) row[k] += v;
          else row[k] = v;
        }
      }
    }
}

HE_INLINE void mooney_rivlin_cell_tangent_diag(const double *prm, const mooney_rivlin_cache *d, double G[4][3],
                                                   double V, double diag[12]) {
  double K[144];
  mooney_rivlin_cell_tangent(prm, d, G, V, K, 0);
  for (int r = 0; r < 12; r++) diag[r] = K[13 * r];
}
