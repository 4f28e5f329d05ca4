/* Linear elasticity (thesis eqs. 3.27, 3.34): eps = sym(F) - I, P = 2 mu eps + lam tr(eps) I.
 * Numpy reference: linear.py. The contract of a material header: see docs/design.md. */
#include "_tensor.h"
typedef struct { char unused; } linear_cache;

HE_INLINE int linear_stress(const double *prm, const double *F, double *P, double *psi) {
  const double mu = prm[0], lam = prm[1];
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

HE_INLINE int linear_prepare(const double *prm, const double *F, linear_cache *d) {
  (void)prm; (void)F; (void)d;
  return 0;
}

HE_INLINE void linear_dstress(const double *prm, const linear_cache *d, const double *dF, double *dP) {
  const double mu = prm[0], lam = prm[1];
  (void)d;
  double tr = dF[0] + dF[4] + dF[8];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) dP[3 * i + j] = mu * (dF[3 * i + j] + dF[3 * j + i]);
  dP[0] += lam * tr; dP[4] += lam * tr; dP[8] += lam * tr;
}

/* The 12x12 cell tangent in closed form: along dF = e_k (x) G_b, dP_ij = mu (delta_ik G_b,j + delta_jk G_b,i)
 * + lam G_b,k delta_ij, so row (a,i) of the force, V dP_ij G_a,j, gives
 *   K[(a,i),(b,k)] = V (mu delta_ik G_a.G_b + mu G_a,k G_b,i + lam G_a,i G_b,k)   (independent of x). */
#define linear_CELL_TANGENT 1
HE_INLINE void linear_cell_tangent(const double *prm, const linear_cache *d, double G[4][3], double V, double *K,
                                       int accumulate) {
  const double mu = prm[0], lam = prm[1];
  (void)d;
  const double vl = V * lam, vm = V * mu;
  for (int a = 0; a < 4; a++) {
    for (int b = 0; b < 4; b++) {
      const double gg = vm * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
      for (int i = 0; i < 3; i++) {
        double *row = K + 12 * (3 * a + i) + 3 * b;
        for (int k = 0; k < 3; k++) {
          double v = vm * G[a][k] * G[b][i] + vl * G[a][i] * G[b][k] + (i == k ? gg : 0.0);
          if (accumulate) row[k] += v;
          else row[k] = v;
        }
      }
    }
  }
}

HE_INLINE void linear_cell_tangent_diag(const double *prm, const linear_cache *d, double G[4][3], double V,
                                            double diag[12]) {
  const double mu = prm[0], lam = prm[1];
  (void)d;
  for (int a = 0; a < 4; a++) {
    const double g2 = G[a][0] * G[a][0] + G[a][1] * G[a][1] + G[a][2] * G[a][2];
    for (int i = 0; i < 3; i++) diag[3 * a + i] = V * (mu * g2 + (lam + mu) * G[a][i] * G[a][i]);
  }
}
