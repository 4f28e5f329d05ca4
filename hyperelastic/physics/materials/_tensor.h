/* 3x3 tensor helpers shared by the material kernels (row-major 3x3 arrays). */
#ifndef HE_TENSOR_H
#define HE_TENSOR_H
#include <math.h>
#include <stdint.h>
#include <string.h>

/* Every small function of the kernels is inlined into the cell loops, whatever the size of the translation
 * unit: GCC's inliner stops at its unit-growth limits, and with seven materials' loops in one unit it left
 * mm, mtm, gather_F, scatter_force and the materials' stresses as calls (St.VK's K v: 27 -> 17 M tets/s). */
#define HE_INLINE static inline __attribute__((always_inline))

HE_INLINE double det3(const double *A) {
  return A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
         A[2] * (A[3] * A[7] - A[4] * A[6]);
}

/* C = A B */
HE_INLINE void mm(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* C = A^T B */
HE_INLINE void mtm(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      C[3 * i + j] = A[i] * B[j] + A[3 + i] * B[3 + j] + A[6 + i] * B[6 + j];
}

/* y = M v (M row-major 3x3) */
HE_INLINE void mv3(const double *M, const double *v, double *y) {
  for (int i = 0; i < 3; i++) y[i] = M[3 * i] * v[0] + M[3 * i + 1] * v[1] + M[3 * i + 2] * v[2];
}

/* c = a x b */
HE_INLINE void cross3(const double *a, const double *b, double *c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

/* out[a] = M G[a] for the four shape-function gradients of a cell (the closed-form cell tangents'
 * u_a = F G_a, h_a = cof G_a, rho_a = R G_a, ...) */
HE_INLINE void m_grads(const double *M, double G[4][3], double out[4][3]) {
  for (int a = 0; a < 4; a++) mv3(M, G[a], out[a]);
}

/* C = "mixed cofactor" of (A, B): cof_mixed(F, F) is the cofactor matrix dJ/dF of F (row-major), and
 * the directional derivative of cof at F along dF is cof_mixed(F, dF) + cof_mixed(dF, F). */
HE_INLINE void cof_mixed(const double *A, const double *B, double *C) {
  C[0] = A[4] * B[8] - A[5] * B[7];
  C[1] = A[5] * B[6] - A[3] * B[8];
  C[2] = A[3] * B[7] - A[4] * B[6];
  C[3] = A[2] * B[7] - A[1] * B[8];
  C[4] = A[0] * B[8] - A[2] * B[6];
  C[5] = A[1] * B[6] - A[0] * B[7];
  C[6] = A[1] * B[5] - A[2] * B[4];
  C[7] = A[2] * B[3] - A[0] * B[5];
  C[8] = A[0] * B[4] - A[1] * B[3];
}
/* S = F^-1 P (the second Piola-Kirchhoff stress of a first one P at F, by F's cofactors); NaN where det F = 0 or
 * `undefined` (the material's stress returned nonzero). */
HE_INLINE void pk2_of(const double *F, const double *P, int undefined, double *S) {
  double Q[9], J = det3(F);
  if (undefined || J == 0) {
    for (int k = 0; k < 9; k++) S[k] = NAN;
    return;
  }
  cof_mixed(F, F, Q);               /* J F^-T */
  mtm(Q, P, S);
  for (int k = 0; k < 9; k++) S[k] /= J;
}
/* The volumetric split's common scalars of F: J = det F, Q = F^-T and J^(-2/3); returns 1 (nothing else
 * computed) where J <= 0, for the materials undefined there (neohookean_split.h, mooney_rivlin.h). */
HE_INLINE int split_scalars(const double *F, double *J, double *Q, double *jm23) {
  *J = det3(F);
  if (!(*J > 0)) return 1;
  const double rJ = 1.0 / *J, c = cbrt(*J);
  cof_mixed(F, F, Q);
  for (int k = 0; k < 9; k++) Q[k] *= rJ;
  *jm23 = 1.0 / (c * c);
  return 0;
}
/* The isochoric/volumetric split's directional derivative for an isochoric energy W(I1_bar) (neohookean_split.h,
 * yeoh.h): dP = a (dF - 2/3 (Q:dF) F - 2/3 (F:dF) Q + 2/9 I1 (Q:dF) Q + I1/3 Q dF^T Q) + kJ2 (Q:dF) Q - g Q dF^T Q
 *             + b (F:dF - I1/3 Q:dF) (F - I1/3 Q),
 * a = 2 W' J^(-2/3), b = 4 W'' J^(-4/3) (0: neo-Hookean), kJ2 = kappa J^2, g = kappa/2 (J^2 - 1), Q = F^-T. */
HE_INLINE void split_dstress(double a, double b, double I1, double kJ2, double g, const double *F, const double *Q,
                             const double *dF, double *dP) {
  double T[9], U[9], qd = 0, fd = 0;
  mtm(dF, Q, T); /* U = Q dF^T Q */
  mm(Q, T, U);
  for (int k = 0; k < 9; k++) { qd += Q[k] * dF[k]; fd += F[k] * dF[k]; }
  const double r = b * (fd - I1 / 3.0 * qd);
  const double cF = -2.0 / 3.0 * a * qd + r, cQ = a * (2.0 / 9.0 * I1 * qd - 2.0 / 3.0 * fd) + kJ2 * qd - r * I1 / 3.0,
               cU = a * I1 / 3.0 - g;
  for (int k = 0; k < 9; k++) dP[k] = a * dF[k] + cF * F[k] + cQ * Q[k] + cU * U[k];
}

/* The split's 12x12 cell tangent in closed form (the cell's K of split_dstress): along dF = e_k (x) G_b (Q:dF = h_b,k,
 * F:dF = u_b,k, Q dF^T Q G_a = h_b h_a,k with u_a = F G_a, h_a = Q G_a):
 *   K[(a,i),(b,k)] = V (a delta_ik G_a.G_b - 2/3 a (u_a,i h_b,k + h_a,i u_b,k) + c_hh h_a,i h_b,k + c_x h_b,i h_a,k
 *                       + b r_a,i r_b,k),
 * c_hh = 2/9 a I1 + kJ2, c_x = a I1/3 - g, r_a = u_a - I1/3 h_a (the W'' term's; none where b = 0). */
HE_INLINE void split_cell_tangent(double a_, double b_, double I1, double kJ2, double g, const double *F,
                                  const double *Q, double G[4][3], double V, double *K, int accumulate) {
  double u[4][3], h[4][3], r[4][3];
  m_grads(F, G, u);
  m_grads(Q, G, h);
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++) r[a][i] = u[a][i] - I1 / 3.0 * h[a][i];
  const double va = V * a_, c2 = -2.0 / 3.0 * va, chh = V * (2.0 / 9.0 * a_ * I1 + kJ2), cx = V * (a_ * I1 / 3.0 - g),
               vb = V * b_;
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) {
      const double gg = va * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
      for (int i = 0; i < 3; i++) {
        double *row = K + 12 * (3 * a + i) + 3 * b;
        for (int k = 0; k < 3; k++) {
          double v = c2 * (u[a][i] * h[b][k] + h[a][i] * u[b][k]) + chh * h[a][i] * h[b][k] + cx * h[b][i] * h[a][k]
                     + (i == k ? gg : 0.0);
          if (b_ != 0) v += vb * r[a][i] * r[b][k];
          if (accumulate) row[k] += v;
          else row[k] = v;
        }
      }
    }
}

/* Its diagonal. */
HE_INLINE void split_cell_tangent_diag(double a_, double b_, double I1, double kJ2, double g, const double *F,
                                       const double *Q, double G[4][3], double V, double diag[12]) {
  double u[4][3], h[4][3];
  m_grads(F, G, u);
  m_grads(Q, G, h);
  const double va = V * a_, c = V * (2.0 / 9.0 * a_ * I1 + kJ2 + a_ * I1 / 3.0 - g);
  for (int a = 0; a < 4; a++) {
    const double g2 = va * (G[a][0] * G[a][0] + G[a][1] * G[a][1] + G[a][2] * G[a][2]);
    for (int i = 0; i < 3; i++) {
      diag[3 * a + i] = g2 - 4.0 / 3.0 * va * u[a][i] * h[a][i] + c * h[a][i] * h[a][i];
      if (b_ != 0) {
        const double r = u[a][i] - I1 / 3.0 * h[a][i];
        diag[3 * a + i] += V * b_ * r * r;
      }
    }
  }
}

#endif
