/* Corotational linear elasticity: Psi = mu |S-I|^2 + lam/2 tr(S-I)^2, F = R S the polar decomposition
 * with det R = +1 (McAdams et al., SIGGRAPH 2011 tech. report "Efficient elasticity for character
 * skinning", sec. 3; inversion convention of Irving, Teran, Fedkiw 2004): P = 2 mu (F-R) + lam tr(S-I) R.
 * Numpy reference: corotational.py. */
#include "_tensor.h"
typedef struct { double R[9], V[9], sig[3], c1, inv_den[3]; } corotational_cache;

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
  cross3(u[0], u[1], u[2]);
  for (int i = 0; i < 3; i++) sig[i] = u[i][0] * fv[i][0] + u[i][1] * fv[i][1] + u[i][2] * fv[i][2];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) R[3 * r + c] = u[0][r] * V[3 * c] + u[1][r] * V[3 * c + 1] + u[2][r] * V[3 * c + 2];
}

/* The rotation R of F = R S where det F > 0, by Newton's iteration X <- (g X + X^-T / g) / 2 with the determinant
 * scaling g = det(X)^(-1/3) (Higham, "Computing the polar decomposition -- with applications", SIAM J. Sci. Stat.
 * Comput. 7, 1986, sec. 3): quadratic convergence, 3-6 iterations for strains up to ~1, about half the cost of the
 * eigen-decomposition above. Returns 1 (R unset) where det X <= 0 (an inverted cell: R must follow the inversion
 * convention, `polar`) or where 30 iterations do not converge. */
static int polar_rotation(const double *F, double *R) {
  double X[9];
  memcpy(X, F, sizeof X);
  for (int it = 0; it < 30; it++) {
    double c[9]; /* the cofactors: X^-T = c / det X */
    cof_mixed(X, X, c);
    double d = X[0] * c[0] + X[1] * c[1] + X[2] * c[2];
    if (!(d > 0)) return 1;
    double g = 1.0 / cbrt(d), h = 1.0 / (g * d), diff = 0, nrm = 0;
    for (int k = 0; k < 9; k++) {
      double xn = 0.5 * (g * X[k] + h * c[k]);
      diff += (xn - X[k]) * (xn - X[k]);
      nrm += xn * xn;
      X[k] = xn;
    }
    if (diff <= 1e-28 * nrm) { /* a change of 1e-14: the next would be at rounding */
      memcpy(R, X, sizeof X);
      return 0;
    }
  }
  return 1;
}

HE_INLINE int corotational_stress(const double *prm, const double *F, double *P, double *psi) {
  const double mu = prm[0], lam = prm[1];
  double R[9], trS, ss = 0;
  if (polar_rotation(F, R) == 0) { /* S = R^T F (symmetric positive definite): tr(S - I) and |S - I|^2 from it */
    double S[9];
    mtm(R, F, S);
    trS = S[0] + S[4] + S[8] - 3;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) {
        double e = 0.5 * (S[3 * i + j] + S[3 * j + i]) - (i == j);
        ss += e * e;
      }
  } else { /* inverted (or degenerate): the eigen-decomposition, sig[2] carrying the sign of det F */
    double V[9], sg[3];
    polar(F, R, V, sg);
    trS = sg[0] + sg[1] + sg[2] - 3;
    for (int i = 0; i < 3; i++) ss += (sg[i] - 1) * (sg[i] - 1);
  }
  for (int k = 0; k < 9; k++) P[k] = 2 * mu * (F[k] - R[k]) + lam * trS * R[k];
  if (psi) *psi = mu * ss + 0.5 * lam * trS * trS;
  return 0;
}

HE_INLINE int corotational_prepare(const double *prm, const double *F, corotational_cache *d) {
  (void)prm;
  polar(F, d->R, d->V, d->sig);
  d->c1 = d->sig[0] + d->sig[1] + d->sig[2] - 3;
  /* 1/(sig_j + sig_k): (tr S I - S)^-1 in the eigenbasis of S, guarded where a pair sums to ~0 */
  for (int i = 0; i < 3; i++) {
    double den = d->sig[(i + 1) % 3] + d->sig[(i + 2) % 3], tiny = 1e-12 * (fabs(d->sig[0]) + 1e-300);
    if (fabs(den) < tiny) den = den < 0 ? -tiny : tiny;
    d->inv_den[i] = 1 / den;
  }
  return 0;
}

/* dP = 2 mu (dF - dR) + lam tr(R^T dF) R + lam tr(S-I) dR, dR = R [w]x with
 * (tr S I - S) w = axial(R^T dF - dF^T R) (McAdams et al. 2011, sec. 3.3) */
HE_INLINE void corotational_dstress(const double *prm, const corotational_cache *d, const double *dF, double *dP) {
  const double mu = prm[0], lam = prm[1];
  const double *R = d->R, *V = d->V;
  double A[9], a[3], wv[3], w[3], W[9], dR[9];
  mtm(R, dF, A);
  a[0] = A[7] - A[5]; a[1] = A[2] - A[6]; a[2] = A[3] - A[1];
  for (int i = 0; i < 3; i++) wv[i] = (V[i] * a[0] + V[3 + i] * a[1] + V[6 + i] * a[2]) * d->inv_den[i];
  for (int r = 0; r < 3; r++) w[r] = V[3 * r] * wv[0] + V[3 * r + 1] * wv[1] + V[3 * r + 2] * wv[2];
  W[0] = 0; W[1] = -w[2]; W[2] = w[1];
  W[3] = w[2]; W[4] = 0; W[5] = -w[0];
  W[6] = -w[1]; W[7] = w[0]; W[8] = 0;
  mm(R, W, dR);
  double trA = A[0] + A[4] + A[8];
  for (int k = 0; k < 9; k++) dP[k] = 2 * mu * (dF[k] - dR[k]) + lam * trA * R[k] + lam * d->c1 * dR[k];
}

/* The 12x12 cell tangent in closed form. dP = 2 mu dF + lam (R:dF) R + (lam tr(S-I) - 2 mu) dR. Along
 * dF = e_k (x) G_b: R:dF = (R G_b)_k; axial(R^T dF - dF^T R) = G_b x r_k (r_k the k-th row of R), so
 * w = Q (G_b x r_k) with Q = V diag(inv_den) V^T, and dR G_a = R (w x G_a) = (R w) x (R G_a) (det R = 1).
 * With rho_a = R G_a and p_bk = R Q (G_b x r_k):
 *   K[(a,i),(b,k)] = V (2 mu delta_ik G_a.G_b + lam rho_a,i rho_b,k + (lam tr(S-I) - 2 mu) (p_bk x rho_a)_i). */
#define corotational_CELL_TANGENT 1
HE_INLINE void corotational_cell_prep(const corotational_cache *d, double G[4][3], double rho[4][3],
                                          double p[4][3][3]) {
  const double *R = d->R, *V = d->V;
  double Q[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++)
      Q[3 * r + c] = V[3 * r] * d->inv_den[0] * V[3 * c] + V[3 * r + 1] * d->inv_den[1] * V[3 * c + 1] +
                     V[3 * r + 2] * d->inv_den[2] * V[3 * c + 2];
  m_grads(R, G, rho);
  for (int b = 0; b < 4; b++) {
    for (int k = 0; k < 3; k++) {
      double c[3], q[3];
      cross3(G[b], R + 3 * k, c);
      mv3(Q, c, q);
      mv3(R, q, p[b][k]);
    }
  }
}

HE_INLINE void corotational_cell_tangent(const double *prm, const corotational_cache *d, double G[4][3],
                                             double V, double *K, int accumulate) {
  const double mu = prm[0], lam = prm[1];
  double rho[4][3], p[4][3][3];
  corotational_cell_prep(d, G, rho, p);
  const double vm = 2 * V * mu, vl = V * lam, vr = V * (lam * d->c1 - 2 * mu);
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) {
      const double gg = vm * (G[a][0] * G[b][0] + G[a][1] * G[b][1] + G[a][2] * G[b][2]);
      for (int k = 0; k < 3; k++) {
        const double *ra = rho[a];
        double x[3];
        cross3(p[b][k], ra, x);
        for (int i = 0; i < 3; i++) {
          double v = vl * ra[i] * rho[b][k] + vr * x[i] + (i == k ? gg : 0.0);
          double *e = K + 12 * (3 * a + i) + 3 * b + k;
          if (accumulate) *e += v;
          else *e = v;
        }
      }
    }
}

HE_INLINE void corotational_cell_tangent_diag(const double *prm, const corotational_cache *d, double G[4][3],
                                                  double V, double diag[12]) {
  const double mu = prm[0], lam = prm[1];
  double rho[4][3], p[4][3][3];
  corotational_cell_prep(d, G, rho, p);
  const double vr = V * (lam * d->c1 - 2 * mu);
  for (int a = 0; a < 4; a++) {
    const double g2 = G[a][0] * G[a][0] + G[a][1] * G[a][1] + G[a][2] * G[a][2], *ra = rho[a];
    for (int i = 0; i < 3; i++) {
      double x[3];
      cross3(p[a][i], ra, x);
      diag[3 * a + i] = 2 * V * mu * g2 + V * lam * ra[i] * ra[i] + vr * x[i];
    }
  }
}
