/* Element kernels for linear tetrahedra (P1), vectorized over cells in plain C.
 *
 * Geometry per cell: Dminv = Dm^{-1} (3x3, row-major), Dm = [X1-X0 | X2-X0 | X3-X0],
 * so grad N_a = row (a-1) of Dminv for a = 1..3 and grad N_0 = -(sum of the rows);
 * F = Ds Dminv with Ds = [x1-x0 | x2-x0 | x3-x0] (thesis eq. 3.3 / 4.29; Sifakis & Barbic,
 * SIGGRAPH 2012 course notes, sec. 4). Element force k_a = V P grad N_a (thesis eq. 4.41).
 *
 * Materials (P = dPsi/dF, dP = directional derivative of P along dF):
 *   0 linear      thesis eq. 3.27/3.34
 *   1 stvk        thesis eq. 3.35/3.40
 *   2 neohookean  compressible Neo-Hookean, Psi = mu/2 (I1-3) - mu lnJ + lam/2 (lnJ)^2
 *                 (Bonet & Wood, Nonlinear Continuum Mechanics, eq. 6.27); undefined for J <= 0.
 *   3 snh         Stable Neo-Hookean (Smith, de Goes, Kim, ACM TOG 37(2), 2018, eq. 14 and sec. 3.4):
 *                 Psi = ms/2 (I_C-3) + ls/2 (J-a)^2 - ms/2 ln(I_C+1) - Psi(I), a = 1 + 3 ms/(4 ls),
 *                 with ms = 4/3 mu, ls = lam + 5/6 mu so that its small-strain limit is linear
 *                 elasticity with the given (mu, lam); defined for every F, inverted included.
 *   4 corotational  Psi = mu |S-I|^2 + lam/2 tr(S-I)^2, F = R S the polar decomposition with
 *                 det R = +1 (McAdams et al., SIGGRAPH 2011 tech. report "Efficient elasticity for
 *                 character skinning", sec. 3; inversion convention of Irving, Teran, Fedkiw 2004):
 *                 P = 2 mu (F-R) + lam tr(S-I) R.
 * All arrays are C-contiguous; vertex indices index a local vector with 3 dofs per vertex.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef int32_t idx_t;

enum { MAT_LINEAR = 0, MAT_STVK = 1, MAT_NEOHOOKEAN = 2, MAT_SNH = 3, MAT_COROT = 4 };

static inline double det3(const double *A) {
  return A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
         A[2] * (A[3] * A[7] - A[4] * A[6]);
}

/* C = A B (3x3 row-major) */
static inline void mm(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* C = A^T B */
static inline void mtm(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      C[3 * i + j] = A[i] * B[j] + A[3 + i] * B[3 + j] + A[6 + i] * B[6 + j];
}


/* C = "mixed cofactor" of (A, B): cof_mixed(F, F) is the cofactor matrix dJ/dF of F (row-major), and
 * the directional derivative of cof at F along dF is cof_mixed(F, dF) + cof_mixed(dF, F). */
static inline void cof_mixed(const double *A, const double *B, double *C) {
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

/* Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations (Golub & Van Loan,
 * Matrix Computations, sec. 8.5): w eigenvalues in descending order, V columns eigenvectors, det V = +1. */
static void eig_sym3(const double *Ain, double *w, double *V) {
  double A[9];
  memcpy(A, Ain, sizeof A);
  for (int k = 0; k < 9; k++) V[k] = (k % 4 == 0);
  static const int PQ[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (int sweep = 0; sweep < 30; sweep++) {
    double off = A[1] * A[1] + A[2] * A[2] + A[5] * A[5];
    double dia = A[0] * A[0] + A[4] * A[4] + A[8] * A[8];
    if (off == 0 || off <= 1e-36 * dia) break;
    for (int r = 0; r < 3; r++) {
      int p = PQ[r][0], q = PQ[r][1];
      double apq = A[3 * p + q];
      if (apq == 0) continue;
      double theta = (A[3 * q + q] - A[3 * p + p]) / (2 * apq);
      double t = fabs(theta) > 1e150 ? 0.5 / theta : (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
      double c = 1 / sqrt(t * t + 1), s = t * c;
      for (int k = 0; k < 3; k++) {
        double akp = A[3 * k + p], akq = A[3 * k + q];
        A[3 * k + p] = c * akp - s * akq;
        A[3 * k + q] = s * akp + c * akq;
      }
      for (int k = 0; k < 3; k++) {
        double apk = A[3 * p + k], aqk = A[3 * q + k];
        A[3 * p + k] = c * apk - s * aqk;
        A[3 * q + k] = s * apk + c * aqk;
      }
      A[3 * p + q] = A[3 * q + p] = 0;
      for (int k = 0; k < 3; k++) {
        double vkp = V[3 * k + p], vkq = V[3 * k + q];
        V[3 * k + p] = c * vkp - s * vkq;
        V[3 * k + q] = s * vkp + c * vkq;
      }
    }
  }
  w[0] = A[0]; w[1] = A[4]; w[2] = A[8];
  for (int i = 0; i < 2; i++) /* selection sort, descending, columns follow */
    for (int j = i + 1; j < 3; j++)
      if (w[j] > w[i]) {
        double t = w[i]; w[i] = w[j]; w[j] = t;
        for (int k = 0; k < 3; k++) { t = V[3 * k + i]; V[3 * k + i] = V[3 * k + j]; V[3 * k + j] = t; }
      }
  if (det3(V) < 0)
    for (int k = 0; k < 3; k++) V[3 * k + 2] = -V[3 * k + 2];
}

/* Polar decomposition F = R S with det R = +1 and S = V diag(sig) V^T symmetric; sig[0] >= sig[1] >= 0
 * and sig[2] carries the sign of det F (an inverted element has sig[2] < 0). From the eigenvectors V
 * of F^T F: u0 = F v0 / |F v0|, u1 = the part of F v1 orthogonal to u0, normalized, u2 = u0 x u1,
 * R = U V^T, sig_i = u_i . F v_i. */
static void polar(const double *F, double *R, double *V, double *sig) {
  double C[9], lam[3], fv[3][3], u[3][3];
  mtm(F, F, C);
  eig_sym3(C, lam, V);
  for (int i = 0; i < 3; i++)
    for (int r = 0; r < 3; r++) fv[i][r] = F[3 * r] * V[i] + F[3 * r + 1] * V[3 + i] + F[3 * r + 2] * V[6 + i];
  double n0 = sqrt(fv[0][0] * fv[0][0] + fv[0][1] * fv[0][1] + fv[0][2] * fv[0][2]);
  if (n0 > 0) for (int r = 0; r < 3; r++) u[0][r] = fv[0][r] / n0;
  else { u[0][0] = V[0]; u[0][1] = V[3]; u[0][2] = V[6]; }
  double d = u[0][0] * fv[1][0] + u[0][1] * fv[1][1] + u[0][2] * fv[1][2];
  for (int r = 0; r < 3; r++) u[1][r] = fv[1][r] - d * u[0][r];
  double n1 = sqrt(u[1][0] * u[1][0] + u[1][1] * u[1][1] + u[1][2] * u[1][2]);
  if (n1 > 1e-14 * n0 && n1 > 0) for (int r = 0; r < 3; r++) u[1][r] /= n1;
  else { /* rank < 2: any unit vector orthogonal to u0 */
    int m = fabs(u[0][0]) < fabs(u[0][1]) ? (fabs(u[0][0]) < fabs(u[0][2]) ? 0 : 2) : (fabs(u[0][1]) < fabs(u[0][2]) ? 1 : 2);
    double e[3] = {0, 0, 0};
    e[m] = 1;
    double p = u[0][m];
    for (int r = 0; r < 3; r++) u[1][r] = e[r] - p * u[0][r];
    double nn = sqrt(u[1][0] * u[1][0] + u[1][1] * u[1][1] + u[1][2] * u[1][2]);
    for (int r = 0; r < 3; r++) u[1][r] /= nn;
  }
  u[2][0] = u[0][1] * u[1][2] - u[0][2] * u[1][1];
  u[2][1] = u[0][2] * u[1][0] - u[0][0] * u[1][2];
  u[2][2] = u[0][0] * u[1][1] - u[0][1] * u[1][0];
  for (int i = 0; i < 3; i++) sig[i] = u[i][0] * fv[i][0] + u[i][1] * fv[i][1] + u[i][2] * fv[i][2];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) R[3 * r + c] = u[0][r] * V[3 * c] + u[1][r] * V[3 * c + 1] + u[2][r] * V[3 * c + 2];
}

/* Stable Neo-Hookean constants from the Lame pair (mu, lam): ms, ls, alpha and Psi(I). */
static inline void snh_constants(double mu, double lam, double *ms, double *ls, double *alpha, double *psi0) {
  *ms = 4.0 / 3.0 * mu;
  *ls = lam + 5.0 / 6.0 * mu;
  *alpha = 1 + 0.75 * (*ms) / (*ls);
  *psi0 = 0.5 * (*ls) * (1 - *alpha) * (1 - *alpha) - 0.5 * (*ms) * log(4.0);
}

/* inverse-transpose of F and J = det F; returns J */
static inline double inv_t(const double *F, double *FinvT) {
  double J = det3(F), r = 1.0 / J;
  cof_mixed(F, F, FinvT);
  for (int k = 0; k < 9; k++) FinvT[k] *= r;
  return J;
}

/* Stress. Returns 0, or 1 when the material is undefined at F (J <= 0 for Neo-Hookean). */
static inline int stress(int mat, double mu, double lam, const double *F, double *P, double *psi) {
  switch (mat) {
  case MAT_LINEAR: {
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
  case MAT_STVK: {
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
  case MAT_NEOHOOKEAN: {
    double FiT[9];
    double J = det3(F);
    if (!(J > 0)) {
      for (int k = 0; k < 9; k++) P[k] = NAN;
      if (psi) *psi = NAN;
      return 1;
    }
    inv_t(F, FiT);
    double lnJ = log(J), c = lam * lnJ - mu, I1 = 0;
    for (int k = 0; k < 9; k++) { P[k] = mu * F[k] + c * FiT[k]; I1 += F[k] * F[k]; }
    if (psi) *psi = 0.5 * mu * (I1 - 3) - mu * lnJ + 0.5 * lam * lnJ * lnJ;
    return 0;
  }
  case MAT_SNH: {
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
  case MAT_COROT: {
    double R[9], V[9], sg[3];
    polar(F, R, V, sg);
    double trS = sg[0] + sg[1] + sg[2] - 3;
    for (int k = 0; k < 9; k++) P[k] = 2 * mu * (F[k] - R[k]) + lam * trS * R[k];
    if (psi) {
      double ss = 0;
      for (int i = 0; i < 3; i++) ss += (sg[i] - 1) * (sg[i] - 1);
      *psi = mu * ss + 0.5 * lam * trS * trS;
    }
    return 0;
  }
  default:
    for (int k = 0; k < 9; k++) P[k] = NAN;
    return 1;
  }
}

/* Precomputed per-cell data for the directional derivative at fixed F. */
typedef struct {
  double F[9], S[9], FiT[9], c1, c2, c3, R[9], V[9], sig[3];
} dpcache;

static inline int dp_prepare(int mat, double mu, double lam, const double *F, dpcache *d) {
  memcpy(d->F, F, sizeof d->F);
  if (mat == MAT_STVK) {
    double C[9];
    mtm(F, F, C);
    double tr = 0.5 * (C[0] + C[4] + C[8]) - 1.5;
    for (int k = 0; k < 9; k++) d->S[k] = mu * C[k];
    d->S[0] += lam * tr - mu; d->S[4] += lam * tr - mu; d->S[8] += lam * tr - mu;
  } else if (mat == MAT_NEOHOOKEAN) {
    double J = det3(F);
    if (!(J > 0)) return 1;
    inv_t(F, d->FiT);
    d->c1 = mu - lam * log(J); /* coefficient of F^-T dF^T F^-T */
    d->c2 = lam;               /* coefficient of tr(F^-1 dF) F^-T */
  } else if (mat == MAT_SNH) {
    double ms, ls, al, psi0, Ic = 0;
    snh_constants(mu, lam, &ms, &ls, &al, &psi0);
    cof_mixed(F, F, d->FiT); /* here: the cofactor matrix dJ/dF */
    for (int k = 0; k < 9; k++) Ic += F[k] * F[k];
    d->c1 = ms * (1 - 1 / (Ic + 1));        /* coefficient of dF */
    d->c2 = 2 * ms / ((Ic + 1) * (Ic + 1)); /* coefficient of (F:dF) F */
    d->c3 = ls * (det3(F) - al);            /* coefficient of d cof */
    d->S[0] = ls;                           /* coefficient of (cof:dF) cof */
  } else if (mat == MAT_COROT) {
    polar(F, d->R, d->V, d->sig);
    d->c1 = d->sig[0] + d->sig[1] + d->sig[2] - 3;
    /* 1/(sig_j + sig_k): (tr S I - S)^-1 in the eigenbasis of S, guarded where a pair sums to ~0 */
    for (int i = 0; i < 3; i++) {
      double den = d->sig[(i + 1) % 3] + d->sig[(i + 2) % 3], tiny = 1e-12 * (fabs(d->sig[0]) + 1e-300);
      if (fabs(den) < tiny) den = den < 0 ? -tiny : tiny;
      d->S[i] = 1 / den;
    }
  }
  return 0;
}

static inline void dstress(int mat, double mu, double lam, const dpcache *d, const double *dF, double *dP) {
  switch (mat) {
  case MAT_LINEAR: {
    double tr = dF[0] + dF[4] + dF[8];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) dP[3 * i + j] = mu * (dF[3 * i + j] + dF[3 * j + i]);
    dP[0] += lam * tr; dP[4] += lam * tr; dP[8] += lam * tr;
    return;
  }
  case MAT_STVK: {
    /* dP = dF S + F (2 mu dE + lam tr(dE) I), dE = sym(F^T dF) */
    double G[9], dS[9], A[9], B[9];
    mtm(d->F, dF, G);
    double tr = G[0] + G[4] + G[8];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) dS[3 * i + j] = mu * (G[3 * i + j] + G[3 * j + i]);
    dS[0] += lam * tr; dS[4] += lam * tr; dS[8] += lam * tr;
    mm(dF, d->S, A);
    mm(d->F, dS, B);
    for (int k = 0; k < 9; k++) dP[k] = A[k] + B[k];
    return;
  }
  case MAT_NEOHOOKEAN: {
    /* dP = mu dF + c1 F^-T dF^T F^-T + lam tr(F^-1 dF) F^-T */
    const double *Q = d->FiT;
    double T[9], U[9];
    /* T = dF^T Q ; U = Q T = F^-T dF^T F^-T */
    mtm(dF, Q, T);
    mm(Q, T, U);
    double tr = 0; /* tr(F^-1 dF) = sum_ij F^-T_ij dF_ij */
    for (int k = 0; k < 9; k++) tr += Q[k] * dF[k];
    for (int k = 0; k < 9; k++) dP[k] = mu * dF[k] + d->c1 * U[k] + d->c2 * tr * Q[k];
    return;
  }
  case MAT_SNH: {
    /* dP = c1 dF + c2 (F:dF) F + ls (cof:dF) cof + c3 dcof[dF] */
    const double *cof = d->FiT;
    double A[9], B[9], fd = 0, cd = 0;
    cof_mixed(d->F, dF, A);
    cof_mixed(dF, d->F, B);
    for (int k = 0; k < 9; k++) { fd += d->F[k] * dF[k]; cd += cof[k] * dF[k]; }
    for (int k = 0; k < 9; k++)
      dP[k] = d->c1 * dF[k] + d->c2 * fd * d->F[k] + d->S[0] * cd * cof[k] + d->c3 * (A[k] + B[k]);
    return;
  }
  case MAT_COROT: {
    /* dP = 2 mu (dF - dR) + lam tr(R^T dF) R + lam tr(S-I) dR, dR = R [w]x with
     * (tr S I - S) w = axial(R^T dF - dF^T R) (McAdams et al. 2011, sec. 3.3) */
    const double *R = d->R, *V = d->V;
    double A[9], a[3], wv[3], w[3], W[9], dR[9];
    mtm(R, dF, A);
    a[0] = A[7] - A[5]; a[1] = A[2] - A[6]; a[2] = A[3] - A[1];
    for (int i = 0; i < 3; i++) wv[i] = (V[i] * a[0] + V[3 + i] * a[1] + V[6 + i] * a[2]) * d->S[i];
    for (int r = 0; r < 3; r++) w[r] = V[3 * r] * wv[0] + V[3 * r + 1] * wv[1] + V[3 * r + 2] * wv[2];
    W[0] = 0; W[1] = -w[2]; W[2] = w[1];
    W[3] = w[2]; W[4] = 0; W[5] = -w[0];
    W[6] = -w[1]; W[7] = w[0]; W[8] = 0;
    mm(R, W, dR);
    double trA = A[0] + A[4] + A[8];
    for (int k = 0; k < 9; k++) dP[k] = 2 * mu * (dF[k] - dR[k]) + lam * trA * R[k] + lam * d->c1 * dR[k];
    return;
  }
  default: /* unknown material id: poison the result rather than leave it undefined */
    for (int k = 0; k < 9; k++) dP[k] = NAN;
  }
}

static inline void gather_F(const idx_t *c, const double *Dminv, const double *x, double *F) {
  const double *x0 = x + 3 * (int64_t)c[0], *x1 = x + 3 * (int64_t)c[1], *x2 = x + 3 * (int64_t)c[2],
               *x3 = x + 3 * (int64_t)c[3];
  double Ds[9];
  for (int i = 0; i < 3; i++) {
    Ds[3 * i + 0] = x1[i] - x0[i];
    Ds[3 * i + 1] = x2[i] - x0[i];
    Ds[3 * i + 2] = x3[i] - x0[i];
  }
  mm(Ds, Dminv, F);
}

/* H = V P Dminv^T: column a-1 is the force on vertex a (a = 1..3); vertex 0 gets minus the sum. */
static inline void scatter_force(const idx_t *c, const double *Dminv, double V, const double *P, double *f) {
  double H[9];
  for (int i = 0; i < 3; i++)
    for (int a = 0; a < 3; a++)
      H[3 * i + a] = V * (P[3 * i] * Dminv[3 * a] + P[3 * i + 1] * Dminv[3 * a + 1] + P[3 * i + 2] * Dminv[3 * a + 2]);
  double *f0 = f + 3 * (int64_t)c[0], *f1 = f + 3 * (int64_t)c[1], *f2 = f + 3 * (int64_t)c[2],
         *f3 = f + 3 * (int64_t)c[3];
  for (int i = 0; i < 3; i++) {
    f1[i] += H[3 * i];
    f2[i] += H[3 * i + 1];
    f3[i] += H[3 * i + 2];
    f0[i] -= H[3 * i] + H[3 * i + 1] + H[3 * i + 2];
  }
}

/* f += k(x). Returns the number of cells where the material is undefined (their force is skipped). */
int64_t he_forces(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                  int mat, double mu, double lam, double *f) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], P[9];
    gather_F(c, Dminv + 9 * e, x, F);
    if (stress(mat, mu, lam, F, P, NULL)) { bad++; continue; }
    scatter_force(c, Dminv + 9 * e, vol[e], P, f);
  }
  return bad;
}

/* Elastic energy sum_e V Psi(F_e), and min/max of J = det F. Returns the number of undefined cells. */
int64_t he_energy(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                  int mat, double mu, double lam, double *out /* [energy, Jmin, Jmax] */) {
  int64_t bad = 0;
  double W = 0, jmin = INFINITY, jmax = -INFINITY;
  for (int64_t e = 0; e < nc; e++) {
    double F[9], P[9], psi;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    double J = det3(F);
    jmin = J < jmin ? J : jmin;
    jmax = J > jmax ? J : jmax;
    if (stress(mat, mu, lam, F, P, &psi)) { bad++; continue; }
    W += vol[e] * psi;
  }
  out[0] = W; out[1] = jmin; out[2] = jmax;
  return bad;
}

/* y += K(x) v, cell by cell, without assembling. */
int64_t he_kv(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
              int mat, double mu, double lam, const double *v, double *y) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], dF[9], dP[9];
    dpcache d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (dp_prepare(mat, mu, lam, F, &d)) { bad++; continue; }
    gather_F(c, Dminv + 9 * e, v, dF);
    dstress(mat, mu, lam, &d, dF, dP);
    scatter_force(c, Dminv + 9 * e, vol[e], dP, y);
  }
  return bad;
}

/* grad N_b for b = 0..3 from Dminv */
static inline void gradN(const double *Dminv, double G[4][3]) {
  for (int j = 0; j < 3; j++) {
    G[1][j] = Dminv[j];
    G[2][j] = Dminv[3 + j];
    G[3][j] = Dminv[6 + j];
    G[0][j] = -(G[1][j] + G[2][j] + G[3][j]);
  }
}

/* Column (b,k) of the cell tangent: K[(a,i),(b,k)] = V sum_j dP(e_k (x) G_b)_ij G_a,j */
static inline void tangent_column(int mat, double mu, double lam, const dpcache *d, double G[4][3], double V,
                                  int b, int k, double col[12]) {
  double dF[9] = {0}, dP[9];
  dF[3 * k + 0] = G[b][0];
  dF[3 * k + 1] = G[b][1];
  dF[3 * k + 2] = G[b][2];
  dstress(mat, mu, lam, d, dF, dP);
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++)
      col[3 * a + i] = V * (dP[3 * i] * G[a][0] + dP[3 * i + 1] * G[a][1] + dP[3 * i + 2] * G[a][2]);
}

/* Cell tangents, 144 values per cell, row-major over local dofs (3a+i, 3b+k); written, or added to
 * vals when accumulate != 0. */
int64_t he_tangent(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                   int mat, double mu, double lam, double *vals, int accumulate) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    double F[9], G[4][3], col[12];
    dpcache d;
    double *K = vals + 144 * e;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    if (dp_prepare(mat, mu, lam, F, &d)) {
      for (int k = 0; k < 144; k++) K[k] = NAN;
      bad++;
      continue;
    }
    gradN(Dminv + 9 * e, G);
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        tangent_column(mat, mu, lam, &d, G, vol[e], b, k, col);
        if (accumulate)
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] += col[r];
        else
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] = col[r];
      }
  }
  return bad;
}

/* diag += diagonal of K(x) */
int64_t he_tangent_diag(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                        int mat, double mu, double lam, double *diag) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], G[4][3], col[12];
    dpcache d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (dp_prepare(mat, mu, lam, F, &d)) { bad++; continue; }
    gradN(Dminv + 9 * e, G);
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        tangent_column(mat, mu, lam, &d, G, vol[e], b, k, col);
        diag[3 * (int64_t)c[b] + k] += col[3 * b + k];
      }
  }
  return bad;
}

/* y += coef * M_e v over cells, with the consistent P1 matrix int N_a N_b dV = V (1 + delta_ab) / 20
 * (thesis eq. 4.39/4.40), applied per vector component. */
void he_mass_apply(int64_t nc, const idx_t *cells, const double *vol, double coef, const double *v, double *y) {
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double w = coef * vol[e] / 20.0;
    for (int i = 0; i < 3; i++) {
      double s = v[3 * (int64_t)c[0] + i] + v[3 * (int64_t)c[1] + i] + v[3 * (int64_t)c[2] + i] +
                 v[3 * (int64_t)c[3] + i];
      for (int a = 0; a < 4; a++) y[3 * (int64_t)c[a] + i] += w * (v[3 * (int64_t)c[a] + i] + s);
    }
  }
}

/* vals (nc,12,12) += coef * V/20 (1 + delta_ab) I3: the consistent P1 mass pattern, in place. */
void he_add_mass_blocks(int64_t nc, const double *vol, double coef, double *vals) {
  for (int64_t e = 0; e < nc; e++) {
    double w = coef * vol[e] / 20.0;
    double *K = vals + 144 * e;
    for (int a = 0; a < 4; a++)
      for (int b = 0; b < 4; b++) {
        double m = (a == b) ? 2.0 * w : w;
        for (int i = 0; i < 3; i++) K[12 * (3 * a + i) + 3 * b + i] += m;
      }
  }
}

/* y += B v with per-cell 12x12 blocks B (row-major over local dofs 3a+i), scattered by cells; used
 * for projected element Hessians (-hessian_projection), which are stored rather than recomputed. */
void he_apply_blocks(int64_t nc, const idx_t *cells, const double *B, const double *v, double *y) {
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    const double *K = B + 144 * e;
    double ve[12];
    for (int a = 0; a < 4; a++)
      for (int i = 0; i < 3; i++) ve[3 * a + i] = v[3 * (int64_t)c[a] + i];
    for (int a = 0; a < 4; a++)
      for (int i = 0; i < 3; i++) {
        const double *row = K + 12 * (3 * a + i);
        double s = 0;
        for (int k = 0; k < 12; k++) s += row[k] * ve[k];
        y[3 * (int64_t)c[a] + i] += s;
      }
  }
}

/* Largest t in (0, 1] such that every cell keeps det F > 0 along x + s d for s in [0, t], times frac
 * when a cell would reach det F = 0 within the unit step. det F(x + s d) = det(A + s B) is the cubic
 * det A + s cof(A):B + s^2 cof(B):A + s^3 det B (A = F(x), B = F(d), F linear in positions). Its first
 * root in (0, 1] is found by splitting at the critical points (roots of the derivative) and bisecting
 * the first monotone piece whose end is <= 0. Cells already inverted at x are skipped. */
double he_max_step(int64_t nc, const idx_t *cells, const double *Dminv, const double *x, const double *d,
                   double frac) {
  double tmin = 1.0;
  for (int64_t e = 0; e < nc; e++) {
    double A[9], B[9], cA[9], cB[9];
    gather_F(cells + 4 * e, Dminv + 9 * e, x, A);
    double c0 = det3(A);
    if (!(c0 > 0)) continue;
    gather_F(cells + 4 * e, Dminv + 9 * e, d, B);
    cof_mixed(A, A, cA);
    cof_mixed(B, B, cB);
    double c1 = 0, c2 = 0, c3 = det3(B);
    for (int k = 0; k < 9; k++) { c1 += cA[k] * B[k]; c2 += cB[k] * A[k]; }
#define CUBIC(s) (c0 + (s) * (c1 + (s) * (c2 + (s) * c3)))
    double pts[4] = {0, 1, 1, 1};
    int np = 1;
    /* critical points: c1 + 2 c2 s + 3 c3 s^2 = 0 */
    double qa = 3 * c3, qb = 2 * c2, qc = c1, r[2];
    int nr = 0;
    if (qa != 0) {
      double disc = qb * qb - 4 * qa * qc;
      if (disc >= 0) {
        double sq = sqrt(disc), q = -0.5 * (qb + (qb >= 0 ? sq : -sq));
        if (q != 0) { r[nr++] = q / qa; r[nr++] = qc / q; }
        else r[nr++] = 0;
      }
    } else if (qb != 0) r[nr++] = -qc / qb;
    if (nr == 2 && r[0] > r[1]) { double t = r[0]; r[0] = r[1]; r[1] = t; }
    for (int i = 0; i < nr; i++)
      if (r[i] > 0 && r[i] < 1) pts[np++] = r[i];
    pts[np++] = 1;
    for (int i = 1; i < np; i++) {
      if (CUBIC(pts[i]) > 0) continue;
      double lo = pts[i - 1], hi = pts[i]; /* CUBIC(lo) > 0 >= CUBIC(hi) */
      for (int it = 0; it < 60; it++) {
        double mid = 0.5 * (lo + hi);
        if (CUBIC(mid) > 0) lo = mid; else hi = mid;
      }
      if (frac * lo < tmin) tmin = frac * lo;
      break;
    }
#undef CUBIC
  }
  return tmin;
}
