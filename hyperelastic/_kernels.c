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
 * All arrays are C-contiguous; vertex indices index a local vector with 3 dofs per vertex.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef int32_t idx_t;

enum { MAT_LINEAR = 0, MAT_STVK = 1, MAT_NEOHOOKEAN = 2 };

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

/* inverse-transpose of F and J = det F; returns J */
static inline double inv_t(const double *F, double *FinvT) {
  double J = det3(F), r = 1.0 / J;
  FinvT[0] = (F[4] * F[8] - F[5] * F[7]) * r;
  FinvT[1] = (F[5] * F[6] - F[3] * F[8]) * r;
  FinvT[2] = (F[3] * F[7] - F[4] * F[6]) * r;
  FinvT[3] = (F[2] * F[7] - F[1] * F[8]) * r;
  FinvT[4] = (F[0] * F[8] - F[2] * F[6]) * r;
  FinvT[5] = (F[1] * F[6] - F[0] * F[7]) * r;
  FinvT[6] = (F[1] * F[5] - F[2] * F[4]) * r;
  FinvT[7] = (F[2] * F[3] - F[0] * F[5]) * r;
  FinvT[8] = (F[0] * F[4] - F[1] * F[3]) * r;
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
  default:
    for (int k = 0; k < 9; k++) P[k] = NAN;
    return 1;
  }
}

/* Precomputed per-cell data for the directional derivative at fixed F. */
typedef struct {
  double F[9], S[9], FiT[9], c1, c2;
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
