/* Holzapfel-Gasser-Ogden fibre-reinforced tissue with dispersion (Gasser, Ogden & Holzapfel, J. R. Soc. Interface 3,
 * 2006), constants (mu, k1, k2, d, kappa, a1 (3), a2 (3), n families): Psi = mu/2 (I1_bar - 3) + k1/(2 k2) sum_i
 * (exp(k2 <E_i>^2) - 1) + kappa/4 (J^2 - 1 - 2 ln J), E_i = d (I1_bar - 3) + (1 - 3d)(J^(-2/3) |F a_i|^2 - 1).
 * P = W1 G1 + (1 - 3d) sum f'_i G4i + g Q, W1 = mu/2 + d sum f'_i, G1 = 2 J^(-2/3) (F - I1/3 Q), G4 = J^(-2/3)
 * (2 m (x) a - 2/3 I4 Q), m = F a; dP = split_dstress(2 J^(-2/3) W1) + sum_i ((1 - 3d) f'_i dG4i + f''_i (H_i:dF) H_i),
 * dG4 = J^(-2/3) (-2/3 (Q:dF)(2 m (x) a - 2/3 I4 Q) + 2 (dF a) (x) a - 4/3 (m.dF a) Q + 2/3 I4 Q dF^T Q),
 * H_i = d G1 + (1 - 3d) G4i. f', f'' are 0 where E_i <= 0 (no compression). Undefined for J <= 0 and where
 * k2 E^2 > 700. Numpy reference: hgo.py. Its fibre directions may vary from cell to cell (a field: -fibre1 with
 * expressions of X, Y, Z), so its loops also take a block of constants per cell (he_KIND_hgo_cells). */
#include "_tensor.h"
#define hgo_PER_CELL 1
typedef struct {
  double F[9], Q[9], a, I1, kJ2, g, j23, w;
  int n;
  double m[2][3], I4[2], f1[2], f2[2], H[2][9];
} hgo_cache;

/* The state of F (J > 0 and every family's exponent within range). */
HE_INLINE int hgo_scalars(const double *prm, const double *F, hgo_cache *d) {
  const double mu = prm[0], k1 = prm[1], k2 = prm[2], dp = prm[3], kappa = prm[4];
  double J, jm23;
  if (split_scalars(F, &J, d->Q, &jm23)) return 1;
  d->I1 = 0;
  for (int k = 0; k < 9; k++) d->I1 += F[k] * F[k];
  d->j23 = jm23;
  d->kJ2 = kappa * J * J;
  d->g = 0.5 * kappa * (J * J - 1);
  d->n = (int)prm[11];
  double W1 = 0.5 * mu;
  d->w = 0.5 * mu * (jm23 * d->I1 - 3) + 0.25 * kappa * (J * J - 1 - 2 * log(J));
  for (int i = 0; i < d->n; i++) {
    const double *a = prm + 5 + 3 * i;
    mv3(F, a, d->m[i]);
    const double I4 = d->m[i][0] * d->m[i][0] + d->m[i][1] * d->m[i][1] + d->m[i][2] * d->m[i][2];
    const double E = dp * (jm23 * d->I1 - 3) + (1 - 3 * dp) * (jm23 * I4 - 1), Ep = E > 0 ? E : 0;
    if (k2 * Ep * Ep > 700) return 1;
    const double ex = exp(k2 * Ep * Ep);
    d->I4[i] = I4;
    d->f1[i] = k1 * Ep * ex;
    d->f2[i] = E > 0 ? k1 * (1 + 2 * k2 * Ep * Ep) * ex : 0;
    d->w += k1 / (2 * k2) * (ex - 1);
    W1 += dp * d->f1[i];
    for (int r = 0; r < 3; r++)         /* H = d G1 + (1 - 3d) G4 */
      for (int c = 0; c < 3; c++)
        d->H[i][3 * r + c] = dp * 2 * jm23 * (F[3 * r + c] - d->I1 / 3 * d->Q[3 * r + c]) +
                             (1 - 3 * dp) * jm23 * (2 * d->m[i][r] * a[c] - 2.0 / 3.0 * I4 * d->Q[3 * r + c]);
  }
  d->a = 2 * W1 * jm23;
  return 0;
}

HE_INLINE int hgo_stress(const double *prm, const double *F, double *P, double *psi) {
  hgo_cache d;
  if (hgo_scalars(prm, F, &d)) {
    for (int k = 0; k < 9; k++) P[k] = NAN;
    if (psi) *psi = NAN;
    return 1;
  }
  const double s = d.g - d.a * d.I1 / 3.0, c4 = 1 - 3 * prm[3];
  for (int k = 0; k < 9; k++) P[k] = d.a * F[k] + s * d.Q[k];
  for (int i = 0; i < d.n; i++) {
    const double *a = prm + 5 + 3 * i, f = c4 * d.f1[i] * d.j23;
    for (int r = 0; r < 3; r++)
      for (int c = 0; c < 3; c++) P[3 * r + c] += f * (2 * d.m[i][r] * a[c] - 2.0 / 3.0 * d.I4[i] * d.Q[3 * r + c]);
  }
  if (psi) *psi = d.w;
  return 0;
}

HE_INLINE int hgo_prepare(const double *prm, const double *F, hgo_cache *d) {
  if (hgo_scalars(prm, F, d)) return 1;
  memcpy(d->F, F, sizeof d->F);
  return 0;
}

HE_INLINE void hgo_dstress(const double *prm, const hgo_cache *d, const double *dF, double *dP) {
  split_dstress(d->a, 0.0, d->I1, d->kJ2, d->g, d->F, d->Q, dF, dP);
  if (d->n == 0) return;
  double T1[9], U[9], qd = 0;
  mtm(dF, d->Q, T1);                      /* U = Q dF^T Q */
  mm(d->Q, T1, U);
  for (int k = 0; k < 9; k++) qd += d->Q[k] * dF[k];
  const double c4 = 1 - 3 * prm[3];
  for (int i = 0; i < d->n; i++) {
    const double *a = prm + 5 + 3 * i, *m = d->m[i], I4 = d->I4[i];
    double dm[3], hd = 0;
    mv3(dF, a, dm);
    const double md = m[0] * dm[0] + m[1] * dm[1] + m[2] * dm[2];
    for (int k = 0; k < 9; k++) hd += d->H[i][k] * dF[k];
    const double f = c4 * d->f1[i] * d->j23, r2 = d->f2[i] * hd;
    for (int r = 0; r < 3; r++)
      for (int c = 0; c < 3; c++) {
        const int k = 3 * r + c;
        const double dG4 = -2.0 / 3.0 * qd * (2 * m[r] * a[c] - 2.0 / 3.0 * I4 * d->Q[k]) + 2 * dm[r] * a[c]
                           - 4.0 / 3.0 * md * d->Q[k] + 2.0 / 3.0 * I4 * U[k];
        dP[k] += f * dG4 + r2 * d->H[i][k];
      }
  }
}
