/* The cell loops of one material, instantiated once per material by the generated he_materials.h:
 *   #include "materials/NAME.h"
 *   #define MATERIAL NAME
 *   #include "_material_loops.h"
 * which defines he_forces_NAME, he_energy_NAME, he_kv_NAME, he_tangent_NAME, he_tangent_diag_NAME
 * (bound by name in kernels.py) from NAME_stress, NAME_prepare, NAME_dstress and NAME_cache.
 * No include guard: it is meant to be included once per material. */
#define HE_CAT_(a, b) a##b
#define HE_CAT(a, b) HE_CAT_(a, b)
#define HE_FN(kind) HE_CAT(HE_CAT(he_, kind), HE_CAT(_, MATERIAL))
#define HE_MAT(fn) HE_CAT(MATERIAL, HE_CAT(_, fn))

/* f += k(x). Returns the number of cells where the material is undefined (their force is skipped). */
int64_t HE_FN(forces)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      double mu, double lam, double *f) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], P[9];
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(stress)(mu, lam, F, P, NULL)) { bad++; continue; }
    scatter_force(c, Dminv + 9 * e, vol[e], P, f);
  }
  return bad;
}

/* Elastic energy sum_e V Psi(F_e), and min/max of J = det F. Returns the number of undefined cells.
 * The sum is compensated (Kahan): the energy line search compares energies that differ by far less
 * than the energy itself near convergence, so its rounding error must stay at one ulp, not nc ulps. */
int64_t HE_FN(energy)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      double mu, double lam, double *out /* [energy, Jmin, Jmax] */) {
  int64_t bad = 0;
  double W = 0, comp = 0, jmin = INFINITY, jmax = -INFINITY;
  for (int64_t e = 0; e < nc; e++) {
    double F[9], P[9], psi;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    double J = det3(F);
    jmin = J < jmin ? J : jmin;
    jmax = J > jmax ? J : jmax;
    if (HE_MAT(stress)(mu, lam, F, P, &psi)) { bad++; continue; }
    double term = vol[e] * psi - comp, sum = W + term;
    comp = (sum - W) - term;
    W = sum;
  }
  out[0] = W; out[1] = jmin; out[2] = jmax;
  return bad;
}

/* y += K(x) v, cell by cell, without assembling. */
int64_t HE_FN(kv)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                  double mu, double lam, const double *v, double *y) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], dF[9], dP[9];
    HE_MAT(cache) d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(mu, lam, F, &d)) { bad++; continue; }
    gather_F(c, Dminv + 9 * e, v, dF);
    HE_MAT(dstress)(mu, lam, &d, dF, dP);
    scatter_force(c, Dminv + 9 * e, vol[e], dP, y);
  }
  return bad;
}

/* Column (b,k) of the cell tangent: K[(a,i),(b,k)] = V sum_j dP(e_k (x) G_b)_ij G_a,j */
static inline void HE_FN(tangent_column)(double mu, double lam, const HE_MAT(cache) *d, double G[4][3], double V,
                                         int b, int k, double col[12]) {
  double dF[9] = {0}, dP[9];
  dF[3 * k + 0] = G[b][0];
  dF[3 * k + 1] = G[b][1];
  dF[3 * k + 2] = G[b][2];
  HE_MAT(dstress)(mu, lam, d, dF, dP);
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++)
      col[3 * a + i] = V * (dP[3 * i] * G[a][0] + dP[3 * i + 1] * G[a][1] + dP[3 * i + 2] * G[a][2]);
}

/* Cell tangents, 144 values per cell, row-major over local dofs (3a+i, 3b+k); written, or added to
 * vals when accumulate != 0. */
int64_t HE_FN(tangent)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                       double mu, double lam, double *vals, int accumulate) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    double F[9], G[4][3], col[12];
    HE_MAT(cache) d;
    double *K = vals + 144 * e;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(mu, lam, F, &d)) {
      for (int k = 0; k < 144; k++) K[k] = NAN;
      bad++;
      continue;
    }
    gradN(Dminv + 9 * e, G);
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        HE_FN(tangent_column)(mu, lam, &d, G, vol[e], b, k, col);
        if (accumulate)
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] += col[r];
        else
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] = col[r];
      }
  }
  return bad;
}

/* diag += diagonal of K(x) */
int64_t HE_FN(tangent_diag)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol,
                            const double *x, double mu, double lam, double *diag) {
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + 4 * e;
    double F[9], G[4][3], col[12];
    HE_MAT(cache) d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(mu, lam, F, &d)) { bad++; continue; }
    gradN(Dminv + 9 * e, G);
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        HE_FN(tangent_column)(mu, lam, &d, G, vol[e], b, k, col);
        diag[3 * (int64_t)c[b] + k] += col[3 * b + k];
      }
  }
  return bad;
}

#undef HE_CAT_
#undef HE_CAT
#undef HE_FN
#undef HE_MAT
