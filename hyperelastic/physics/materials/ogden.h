/* Ogden's rubber (Ogden, Proc. R. Soc. A 326, 1972), up to OGDEN_TERMS (five) terms, with the isochoric/volumetric
 * split: constants (mu1, alpha1, ..., mu5, alpha5, kappa), W = tr f(C_bar), f(c) = sum_p mu_p/alpha_p c^(alpha_p/2),
 * C_bar = J^(-2/3) C with eigenvalues cb_a and eigenvectors N (the columns), a term with mu_p = 0 off.
 * P = 2 J^(-2/3) F T - 2/3 tau Q + g Q, T = N diag f'(cb) N^T, tau = sum_a f'(cb_a) cb_a, Q = F^-T,
 * g = kappa/2 (J^2 - 1). Its derivative along dF (Daleckii-Krein for the matrix function's: ogden.py):
 * dP = 2 J^(-2/3) (-2/3 (Q:dF) F T + dF T + F dT) - 2/3 dtau Q + (2/3 tau - g) Q dF^T Q + kappa J^2 (Q:dF) Q,
 * dT = N (f'[1] o D) N^T, D = N^T dC_bar N = J^(-2/3) ((dF N)^T F N + (F N)^T dF N - 2/3 (Q:dF) diag c),
 * dtau = sum_a (c f')'(cb_a) D_aa, f'[1] the divided differences of f' (f'' on the diagonal and at equal eigenvalues,
 * without cancellation: ogden_divided). Undefined for J <= 0. Numpy reference: ogden.py. */
#include "_tensor.h"
#define OGDEN_TERMS 5                    /* (2 x 5 + 1 = 11 constants: within HE_NPARAM) */
#define OGDEN_KAPPA (2 * OGDEN_TERMS)
typedef struct {
  double F[9], Q[9], FN[9], N[9], c[3], lc[3], ck[3 * OGDEN_TERMS], fp[3], h[3], dd[9], FT[9], j23, tau, kJ2, g;
} ogden_cache;

/* The unit eigenvector v of symmetric A for its eigenvalue l: the longest of the cross products of the rows of A - lI
 * (each is along v where l is a simple eigenvalue; the longest the best conditioned). */
HE_INLINE void sym3_vector(const double *A, double l, double *v) {
  const double r0[3] = {A[0] - l, A[1], A[2]}, r1[3] = {A[3], A[4] - l, A[5]}, r2[3] = {A[6], A[7], A[8] - l};
  double x[3][3], n[3];
  cross3(r0, r1, x[0]);
  cross3(r0, r2, x[1]);
  cross3(r1, r2, x[2]);
  int k = 0;
  for (int i = 0; i < 3; i++) n[i] = x[i][0] * x[i][0] + x[i][1] * x[i][1] + x[i][2] * x[i][2];
  if (n[1] > n[k]) k = 1;
  if (n[2] > n[k]) k = 2;
  if (!(n[k] > 0)) { v[0] = 1, v[1] = 0, v[2] = 0; return; }
  const double s = 1 / sqrt(n[k]);
  for (int i = 0; i < 3; i++) v[i] = x[k][i] * s;
}

/* The eigenvalues c and orthonormal eigenvectors (V's columns) of a symmetric 3x3 S, without iterating (after Eberly,
 * "A robust eigensolver for 3x3 symmetric matrices", 2014): the eigenvalues of B = (S - qI)/p, q = tr S/3, p^2 =
 * |S - qI|^2/6, are 2 cos(phi + 2 pi k/3), phi = acos(det B / 2)/3 (Smith, Comm. ACM 4, 1961); the one farthest from
 * the other two (the largest where det B >= 0, else the smallest: accurate to round-off, as are its vector's directions)
 * gives the first vector (sym3_vector), and the other two diagonalize S on the plane normal to it by one exact
 * rotation. So V^T S V is diagonal to round-off of |S| however close the eigenvalues (where they are equal, any
 * orthonormal basis of their space is one); the eigenvalues are the Rayleigh quotients. */
HE_INLINE void sym3_eig(const double *S, double *c, double *V) {
  const double q = (S[0] + S[4] + S[8]) / 3, off = S[1] * S[1] + S[2] * S[2] + S[5] * S[5];
  const double b0 = S[0] - q, b1 = S[4] - q, b2 = S[8] - q;
  const double p = sqrt((b0 * b0 + b1 * b1 + b2 * b2 + 2 * off) / 6);
  if (!(p > 1e-300)) {                                       /* S = qI */
    for (int k = 0; k < 9; k++) V[k] = (k % 4 == 0);
    c[0] = S[0], c[1] = S[4], c[2] = S[8];
    return;
  }
  const double r = 1 / p, B[9] = {b0 * r, S[1] * r, S[2] * r, S[3] * r, b1 * r, S[5] * r, S[6] * r, S[7] * r, b2 * r};
  double h = 0.5 * det3(B);
  h = h > 1 ? 1 : h < -1 ? -1 : h;
  const double phi = acos(h) / 3;
  const double lam = q + 2 * p * (h >= 0 ? cos(phi) : cos(phi + 2.0943951023931957)); /* the isolated one */
  double v[3], u[3], w[3], Au[3], Aw[3], Av[3];
  sym3_vector(S, lam, v);
  if (fabs(v[0]) > fabs(v[1])) {                             /* u, w: an orthonormal basis of the plane normal to v */
    const double s = 1 / sqrt(v[0] * v[0] + v[2] * v[2]);
    u[0] = -v[2] * s, u[1] = 0, u[2] = v[0] * s;
  } else {
    const double s = 1 / sqrt(v[1] * v[1] + v[2] * v[2]);
    u[0] = 0, u[1] = v[2] * s, u[2] = -v[1] * s;
  }
  cross3(v, u, w);
  mv3(S, u, Au);
  mv3(S, w, Aw);
  mv3(S, v, Av);
  const double m00 = u[0] * Au[0] + u[1] * Au[1] + u[2] * Au[2], m11 = w[0] * Aw[0] + w[1] * Aw[1] + w[2] * Aw[2],
               m01 = u[0] * Aw[0] + u[1] * Aw[1] + u[2] * Aw[2];
  double cs = 1, sn = 0, t = 0;
  if (m01 != 0) {                                            /* the rotation zeroing m01 (the smaller angle) */
    const double th = (m11 - m00) / (2 * m01);
    t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1));
    cs = 1 / sqrt(t * t + 1), sn = t * cs;
  }
  c[0] = v[0] * Av[0] + v[1] * Av[1] + v[2] * Av[2];
  c[1] = m00 - t * m01;
  c[2] = m11 + t * m01;
  for (int i = 0; i < 3; i++) {
    V[3 * i] = v[i];
    V[3 * i + 1] = cs * u[i] - sn * w[i];
    V[3 * i + 2] = sn * u[i] + cs * w[i];
  }
}

/* The state of F (J > 0): Q, N, cb, ln cb, f'(cb), (c f')'(cb), each term's cb^(alpha/2) (ck), J^(-2/3), tau, F T,
 * kappa J^2, g; psi where wanted. The powers as exp(alpha/2 ln cb): three logarithms, an exponential per term. */
HE_INLINE int ogden_scalars(const double *prm, const double *F, ogden_cache *d, double *J, double *psi) {
  double jm23, C[9], cv[3];
  if (split_scalars(F, J, d->Q, &jm23)) return 1;
  mtm(F, F, C);
  sym3_eig(C, cv, d->N);
  double w = 0, T[9] = {0};
  d->tau = 0;
  for (int a = 0; a < 3; a++) {
    const double cb = jm23 * cv[a], lc = log(cb);
    double fp = 0, h = 0;
    for (int p = 0; p < OGDEN_TERMS; p++) {
      const double mu = prm[2 * p], al = prm[2 * p + 1];
      if (mu == 0) continue;
      const double ck = exp(0.5 * al * lc);
      d->ck[3 * p + a] = ck;
      w += mu / al * (ck - 1);
      fp += 0.5 * mu * ck;
      h += 0.25 * mu * al * ck;
    }
    d->c[a] = cb, d->lc[a] = lc, d->fp[a] = fp / cb, d->h[a] = h / cb;
    d->tau += fp;
  }
  for (int i = 0; i < 3; i++)        /* T = N diag(fp) N^T */
    for (int j = 0; j < 3; j++)
      for (int a = 0; a < 3; a++) T[3 * i + j] += d->N[3 * i + a] * d->fp[a] * d->N[3 * j + a];
  mm(F, T, d->FT);
  d->j23 = jm23;
  d->kJ2 = prm[OGDEN_KAPPA] * *J * *J;
  d->g = 0.5 * prm[OGDEN_KAPPA] * (*J * *J - 1);
  if (psi) *psi = w + 0.25 * prm[OGDEN_KAPPA] * (*J * *J - 1 - 2 * log(*J));
  return 0;
}

/* (f'(a) - f'(b)) / (a - b) (f''(a) where a = b) of the terms at eigenvalues a = cb_i, b = cb_j: each term's
 * mu/2 (a^k - b^k)/(a - b) = mu/2 b^(k-1) expm1(k u) / expm1(u), u = ln a - ln b, k = alpha/2 - 1, b^(k-1) = ck_j /
 * b^2 (k where u = 0): without cancellation. */
HE_INLINE double ogden_divided(const double *prm, const ogden_cache *d, int i, int j) {
  const double u = d->lc[i] - d->lc[j], e = expm1(u), b2 = d->c[j] * d->c[j];
  double s = 0;
  for (int p = 0; p < OGDEN_TERMS; p++) {
    const double mu = prm[2 * p], k = 0.5 * prm[2 * p + 1] - 1;
    if (mu == 0) continue;
    s += 0.5 * mu * d->ck[3 * p + j] / b2 * (u == 0 ? k : expm1(k * u) / e);
  }
  return s;
}

HE_INLINE int ogden_stress(const double *prm, const double *F, double *P, double *psi) {
  ogden_cache d;
  double J;
  if (ogden_scalars(prm, F, &d, &J, psi)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d.g - 2.0 / 3.0 * d.tau;
  for (int k = 0; k < 9; k++) P[k] = 2 * d.j23 * d.FT[k] + s * d.Q[k];
  return 0;
}

HE_INLINE int ogden_prepare(const double *prm, const double *F, ogden_cache *d) {
  double J;
  if (ogden_scalars(prm, F, d, &J, NULL)) return 1;
  memcpy(d->F, F, sizeof d->F);
  mm(F, d->N, d->FN);
  for (int a = 0; a < 3; a++)
    for (int b = a; b < 3; b++) {
      const double v = ogden_divided(prm, d, a, b);
      d->dd[3 * a + b] = d->dd[3 * b + a] = v;
    }
  return 0;
}

HE_INLINE void ogden_dstress(const double *prm, const ogden_cache *d, const double *dF, double *dP) {
  double G[9], X[9], D[9], E[9], H[9], W[9], T1[9], U[9], qd = 0, dtau = 0;
  for (int k = 0; k < 9; k++) qd += d->Q[k] * dF[k];
  mm(dF, d->N, G);                       /* G = dF N */
  mtm(G, d->FN, X);                      /* X = G^T F N */
  for (int a = 0; a < 3; a++)
    for (int b = 0; b < 3; b++)          /* D = J^(-2/3) (X + X^T) - 2/3 qd diag(cb) */
      D[3 * a + b] = d->j23 * (X[3 * a + b] + X[3 * b + a]) - (a == b ? 2.0 / 3.0 * qd * d->c[a] : 0.0);
  for (int a = 0; a < 3; a++) dtau += d->h[a] * D[4 * a];
  for (int k = 0; k < 9; k++) E[k] = d->dd[k] * D[k];     /* dT_hat = f'[1] o D */
  mm(d->FN, E, H);                       /* H = F N dT_hat + G diag(fp): (F dT + dF T) N */
  for (int i = 0; i < 3; i++)
    for (int a = 0; a < 3; a++) H[3 * i + a] += G[3 * i + a] * d->fp[a];
  for (int i = 0; i < 3; i++)            /* W = H N^T */
    for (int j = 0; j < 3; j++)
      W[3 * i + j] = H[3 * i] * d->N[3 * j] + H[3 * i + 1] * d->N[3 * j + 1] + H[3 * i + 2] * d->N[3 * j + 2];
  mtm(dF, d->Q, T1);                     /* U = Q dF^T Q */
  mm(d->Q, T1, U);
  const double a2 = 2 * d->j23, cF = -2.0 / 3.0 * qd * a2, cQ = -2.0 / 3.0 * dtau + d->kJ2 * qd,
               cU = 2.0 / 3.0 * d->tau - d->g;
  (void)prm;
  for (int k = 0; k < 9; k++) dP[k] = a2 * W[k] + cF * d->FT[k] + cQ * d->Q[k] + cU * U[k];
}

/* dP along the rank-one dF = e_k (x) Gb (the cell tangent's columns): ogden_dstress with dF N = e_k (x) g, g = N^T Gb,
 * so X = g (x) (F N)_k, Q:dF = (Q Gb)_k and Q dF^T Q = (Q Gb) (x) Q_k (outer products where the general path has
 * matrix products). */
HE_INLINE void ogden_rank_one(const double *prm, const ogden_cache *d, const double *Gb, int k, double *dP) {
  double g[3], hq[3], D[9], H[9], W[9];
  (void)prm;
  for (int a = 0; a < 3; a++) g[a] = d->N[a] * Gb[0] + d->N[3 + a] * Gb[1] + d->N[6 + a] * Gb[2];
  mv3(d->Q, Gb, hq);
  const double qd = hq[k], *fk = d->FN + 3 * k;
  double dtau = 0;
  for (int a = 0; a < 3; a++)
    for (int b = 0; b < 3; b++)
      D[3 * a + b] = d->j23 * (g[a] * fk[b] + g[b] * fk[a]) - (a == b ? 2.0 / 3.0 * qd * d->c[a] : 0.0);
  for (int a = 0; a < 3; a++) dtau += d->h[a] * D[4 * a];
  for (int m = 0; m < 9; m++) D[m] *= d->dd[m];                 /* dT_hat */
  mm(d->FN, D, H);                                              /* F N dT_hat + (dF N) diag(fp) */
  for (int a = 0; a < 3; a++) H[3 * k + a] += g[a] * d->fp[a];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      W[3 * i + j] = H[3 * i] * d->N[3 * j] + H[3 * i + 1] * d->N[3 * j + 1] + H[3 * i + 2] * d->N[3 * j + 2];
  const double a2 = 2 * d->j23, cF = -2.0 / 3.0 * qd * a2, cQ = -2.0 / 3.0 * dtau + d->kJ2 * qd,
               cU = 2.0 / 3.0 * d->tau - d->g;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      const int m = 3 * i + j;
      dP[m] = a2 * W[m] + cF * d->FT[m] + cQ * d->Q[m] + cU * hq[i] * d->Q[3 * k + j];
    }
}

/* The 12x12 cell tangent, column (b, k) = V dP[e_k (x) G_b] G_a (ogden_rank_one). */
#define ogden_CELL_TANGENT 1
HE_INLINE void ogden_cell_tangent(const double *prm, const ogden_cache *d, double G[4][3], double V, double *K,
                                  int accumulate) {
  for (int b = 0; b < 4; b++)
    for (int k = 0; k < 3; k++) {
      double dP[9];
      ogden_rank_one(prm, d, G[b], k, dP);
      for (int a = 0; a < 4; a++)
        for (int i = 0; i < 3; i++) {
          const double v = V * (dP[3 * i] * G[a][0] + dP[3 * i + 1] * G[a][1] + dP[3 * i + 2] * G[a][2]);
          double *e = K + 12 * (3 * a + i) + 3 * b + k;
          if (accumulate) *e += v;
          else *e = v;
        }
    }
}

HE_INLINE void ogden_cell_tangent_diag(const double *prm, const ogden_cache *d, double G[4][3], double V,
                                       double diag[12]) {
  for (int b = 0; b < 4; b++)
    for (int k = 0; k < 3; k++) {
      double dP[9];
      ogden_rank_one(prm, d, G[b], k, dP);
      diag[3 * b + k] = V * (dP[3 * k] * G[b][0] + dP[3 * k + 1] * G[b][1] + dP[3 * k + 2] * G[b][2]);
    }
}
