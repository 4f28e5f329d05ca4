/* Element kernels for linear tetrahedra (P1), vectorized over cells in plain C.
 *
 * Geometry per cell: Dminv = Dm^{-1} (3x3, row-major), Dm = [X1-X0 | X2-X0 | X3-X0],
 * so grad N_a = row (a-1) of Dminv for a = 1..3 and grad N_0 = -(sum of the rows);
 * F = Ds Dminv with Ds = [x1-x0 | x2-x0 | x3-x0] (thesis eq. 3.3 / 4.29; Sifakis & Barbic,
 * SIGGRAPH 2012 course notes, sec. 4). Element force k_a = V P grad N_a (thesis eq. 4.41).
 *
 * Materials: each one is a header materials/NAME.h (its stress P = dPsi/dF, the preparation of a
 * cell's derivative data, and the directional derivative dP), beside its numpy reference
 * materials/NAME.py. setup.py generates he_materials.h, which instantiates the cell loops of
 * _material_loops.h once per material header: he_forces_NAME, he_energy_NAME, he_kv_NAME,
 * he_tangent_NAME, he_tangent_diag_NAME, he_forces_dg_NAME, he_fields_NAME (the output's cell fields), each taking the material's parameter block
 * (HE_NPARAM below). The kernels below do not depend on the material.
 * All arrays are C-contiguous; vertex indices index a local vector with 3 dofs per vertex.
 */
#include "_cells.h"
#include "he_materials.h"

#include <stdlib.h>

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
/* The largest t in (0, 1] keeping det(A + s B) > 0 for s in [0, t] (A = F(x), B = F(d)), times frac when
 * det reaches 0 within the unit step; 1 when it does not, or when det A <= 0 already (the cell is skipped). */
HE_INLINE double det_step(const double *A, const double *B, double frac) {
  double cA[9], cB[9];
  double c0 = det3(A);
  if (!(c0 > 0)) return 1.0;
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
    return frac * lo < 1.0 ? frac * lo : 1.0;
  }
#undef CUBIC
  return 1.0;
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
    double A[9], B[9];
    gather_F(cells + 4 * e, Dminv + 9 * e, x, A);
    if (!(det3(A) > 0)) continue;
    gather_F(cells + 4 * e, Dminv + 9 * e, d, B);
    double t = det_step(A, B, frac);
    if (t < tmin) tmin = t;
  }
  return tmin;
}

/* dst block k (9 values) = the 3x3 block of a CSR value array src whose row r starts at p0[k] + r L[k]:
   dst[9k + 3c + r] (column-major, as (S)BAIJ stores blocks) when colmajor, else dst[9k + 3r + c]. */
void he_gather_blocks(int64_t nb, const int32_t *p0, const int32_t *L, const double *src, double *dst,
                      int colmajor) {
  for (int64_t k = 0; k < nb; k++) {
    const double *s = src + p0[k];
    double *d = dst + 9 * k;
    const int64_t l = L[k];
    for (int r = 0; r < 3; r++)
      for (int c = 0; c < 3; c++)
        d[colmajor ? 3 * c + r : 3 * r + c] = s[r * l + c];
  }
}

/* dst[p0[k] + r L[k] + c] += vals[9k + 3r + c]: 3x3 blocks (row-major) added into CSR values, in order
   (blocks at the same place accumulate). */
void he_add_blocks(int64_t nb, const int32_t *p0, const int32_t *L, const double *vals, double *dst) {
  for (int64_t k = 0; k < nb; k++) {
    double *d = dst + p0[k];
    const double *v = vals + 9 * k;
    const int64_t l = L[k];
    for (int r = 0; r < 3; r++)
      for (int c = 0; c < 3; c++)
        d[r * l + c] += v[3 * r + c];
  }
}

/* dst += the 12x12 blocks vals (nc x 144, dof order 3a+i) of the cells with base[16 e] >= 0, into CSR
 * values: the 3x3 block of vertices (a, b) starts at base[16 e + 4 a + b] and its row i at + i * len[4 e + a]
 * (the three rows of a vertex have the same columns, the three columns of a vertex are consecutive); the
 * map is computed once (jacobians.AssembledChunked). */
void he_scatter_blocks(int64_t nc, const int32_t *base, const int32_t *len, const double *vals, double *dst) {
  for (int64_t e = 0; e < nc; e++) {
    const int32_t *p = base + 16 * e, *L = len + 4 * e;
    if (p[0] < 0) continue;
    const double *v = vals + 144 * e;
    for (int a = 0; a < 4; a++)
      for (int i = 0; i < 3; i++) {
        const double *row = v + 12 * (3 * a + i);
        int64_t off = (int64_t)i * L[a];
        for (int b = 0; b < 4; b++) {
          double *d = dst + p[4 * a + b] + off;
          d[0] += row[3 * b];
          d[1] += row[3 * b + 1];
          d[2] += row[3 * b + 2];
        }
      }
  }
}

/* ---- elements with quadrature (P2 tetrahedra; _element_loops.h has the material loops and the helpers) ---- */

/* y += coef * M v per vector component, M_ab = sum_q w_q N_a(q) N_b(q) (N: nq x nn at the mass rule's points,
 * w: nc x nq, |det J| times the rule's weights). */
void he_emass_apply(int64_t nc, int nn, int nq, const idx_t *cells, const double *N, const double *w, double coef,
                    const double *v, double *y) {
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    double ve[HE_MAXN][3], ye[HE_MAXN][3] = {{0}};
    e_gather(c, nn, v, ve);
    for (int q = 0; q < nq; q++) {
      const double *Nq = N + nn * q, wq = coef * w[(int64_t)nq * e + q];
      double s[3] = {0, 0, 0};
      for (int b = 0; b < nn; b++)
        for (int i = 0; i < 3; i++) s[i] += Nq[b] * ve[b][i];
      for (int a = 0; a < nn; a++)
        for (int i = 0; i < 3; i++) ye[a][i] += wq * Nq[a] * s[i];
    }
    e_scatter(c, nn, ye, y);
  }
}

/* vals (nc, 3nn, 3nn) += coef * M_ab I3 of each cell (the consistent mass blocks), in place. */
#define HE_MAXQM 32 /* points of a mass rule whose products w_q N_a are tabulated per cell (degree 5: 14) */
void he_emass_blocks(int64_t nc, int nn, int nq, const double *N, const double *w, double coef, double *vals) {
  const int n3 = 3 * nn;
  for (int64_t e = 0; e < nc; e++) {
    double *K = vals + (int64_t)n3 * n3 * e;
    const double *we = w + (int64_t)nq * e;
    if (nq <= HE_MAXQM) { /* the products w_q N_a once per cell, not once per (a, b): the same values, bit for bit */
      double wN[HE_MAXQM][HE_MAXN];
      for (int q = 0; q < nq; q++)
        for (int a = 0; a < nn; a++) wN[q][a] = we[q] * N[nn * q + a];
      for (int a = 0; a < nn; a++)
        for (int b = 0; b < nn; b++) {
          double m = 0;
          for (int q = 0; q < nq; q++) m += wN[q][a] * N[nn * q + b];
          for (int i = 0; i < 3; i++) K[n3 * (3 * a + i) + 3 * b + i] += coef * m;
        }
      continue;
    }
    for (int a = 0; a < nn; a++)
      for (int b = 0; b < nn; b++) {
        double m = 0;
        for (int q = 0; q < nq; q++) m += we[q] * N[nn * q + a] * N[nn * q + b];
        for (int i = 0; i < 3; i++) K[n3 * (3 * a + i) + 3 * b + i] += coef * m;
      }
  }
}

/* y += B v with per-cell (3nn x 3nn) blocks B (row-major), scattered by cells. */
void he_eapply_blocks(int64_t nc, int nn, const idx_t *cells, const double *B, const double *v, double *y) {
  const int n3 = 3 * nn;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    const double *K = B + (int64_t)n3 * n3 * e;
    double ve[HE_MAXN][3], ye[HE_MAXN][3];
    e_gather(c, nn, v, ve);
    for (int r = 0; r < n3; r++) {
      double s = 0;
      for (int k = 0; k < n3; k++) s += K[n3 * r + k] * ve[k / 3][k % 3];
      ye[r / 3][r % 3] = s;
    }
    e_scatter(c, nn, ye, y);
  }
}

/* he_max_step on elements: det F > 0 at every quadrature point along x + s d (F is linear in the positions at
 * each point, so det_step applies point by point); cells with a point already inverted at x are skipped. */
double he_emax_step(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                    const double *x, const double *d, double frac) {
  double tmin = 1.0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], de[HE_MAXN][3], t = 1.0;
    int skip = 0;
    e_gather(c, nn, x, xe);
    e_gather(c, nn, d, de);
    for (int q = 0; q < nq && !skip; q++) {
      double G[HE_MAXN][3], A[9], B[9];
      e_point(geo, dN, e, q, nn, nq, xe, G, A);
      if (!(det3(A) > 0)) { skip = 1; break; }
      e_deformation(de, G, nn, B);
      double tq = det_step(A, B, frac);
      if (tq < t) t = tq;
    }
    if (!skip && t < tmin) tmin = t;
  }
  return tmin;
}

/* he_scatter_blocks for cells of nn nodes: dst += vals (nc x 3nn x 3nn), the 3x3 block of nodes (a, b) at
 * base[nn^2 e + nn a + b] + i len[nn e + a] + j for entry (3a+i, 3b+j); cells with base[nn^2 e] < 0 skipped. */
void he_scatter_blocks_n(int64_t nc, int nn, const int32_t *base, const int32_t *len, const double *vals,
                         double *dst) {
  const int n3 = 3 * nn;
  for (int64_t e = 0; e < nc; e++) {
    const int32_t *p = base + (int64_t)nn * nn * e, *L = len + (int64_t)nn * e;
    if (p[0] < 0) continue;
    const double *v = vals + (int64_t)n3 * n3 * e;
    for (int a = 0; a < nn; a++)
      for (int i = 0; i < 3; i++) {
        const double *row = v + n3 * (3 * a + i);
        int64_t off = (int64_t)i * L[a];
        for (int b = 0; b < nn; b++) {
          double *d = dst + p[nn * a + b] + off;
          d[0] += row[3 * b];
          d[1] += row[3 * b + 1];
          d[2] += row[3 * b + 2];
        }
      }
  }
}

/* The mixed formulation's pressure terms (mixed.PressureCoupling, volumetric kind "J": G = J - 1, docs/design.md)
 * on nc cells of nn nodes with nq quadrature points: g (nc, nq, nn, 3) the physical shape-function gradients,
 * w (nc, nq) |det J| w_q, pq (nc, nq) the pressure at the points, M (nq, 4) the pressure's shape functions. With
 * H_a = cof(F) g_a = dJ/dx_a (cof(F) = J F^-T): Jq (nc, nq) = J; where not NULL, f (nc, 3nn) = sum_q w p H_a (the
 * pressure's force), up (nc, 3nn, 4) = sum_q w H_a M_b (the coupling block) and blocks (nc, 3nn, 3nn) =
 * sum_q (w p / J) (H_ai H_bk - H_ak H_bi) (p d2J/dx_a dx_b, the geometric block). */
void he_pressure_terms(int64_t nc, int nn, int nq, const idx_t *cells, const double *g, const double *w,
                       const double *x, const double *pq, const double *M, double *Jq, double *f, double *up,
                       double *blocks) {
  const int nd = 3 * nn;
  double H[3 * 10];
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    if (f) memset(f + nd * e, 0, sizeof(double) * nd);
    if (up) memset(up + 4 * nd * e, 0, sizeof(double) * 4 * nd);
    if (blocks) memset(blocks + (int64_t)nd * nd * e, 0, sizeof(double) * nd * nd);
    for (int q = 0; q < nq; q++) {
      const double *gq = g + ((e * nq + q) * nn) * 3;
      double F[9] = {0}, C[9];
      for (int a = 0; a < nn; a++) {
        const double *xa = x + 3 * (int64_t)c[a];
        for (int i = 0; i < 3; i++)
          for (int j = 0; j < 3; j++) F[3 * i + j] += xa[i] * gq[3 * a + j];
      }
      const double J = det3(F);
      Jq[e * nq + q] = J;
      cof_mixed(F, F, C);
      for (int a = 0; a < nn; a++) mv3(C, gq + 3 * a, H + 3 * a);
      const double wq = w[e * nq + q], p = pq[e * nq + q];
      if (f) {
        double *fe = f + nd * e;
        for (int k = 0; k < nd; k++) fe[k] += wq * p * H[k];
      }
      if (up) {
        double *ue = up + 4 * nd * e;
        const double *Mq = M + 4 * q;
        for (int k = 0; k < nd; k++)
          for (int b = 0; b < 4; b++) ue[4 * k + b] += wq * H[k] * Mq[b];
      }
      if (blocks) {                           /* K1 += s H H^T here; blocks = K1 - its swap of i and k below */
        double *be = blocks + (int64_t)nd * nd * e;
        const double s = wq * p / J;
        for (int m = 0; m < nd; m++) {
          const double hm = s * H[m];
          double *row = be + (int64_t)m * nd;
          for (int k = 0; k < nd; k++) row[k] += hm * H[k];
        }
      }
    }
    if (blocks) {                             /* [a,i,b,k] = K1[a,i,b,k] - K1[a,k,b,i], for each pair of nodes */
      double *be = blocks + (int64_t)nd * nd * e;
      for (int a = 0; a < nn; a++)
        for (int b = 0; b < nn; b++) {
          double K[9], *B = be + (int64_t)3 * a * nd + 3 * b;
          for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) K[3 * i + k] = B[(int64_t)i * nd + k];
          for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) B[(int64_t)i * nd + k] = K[3 * i + k] - K[3 * k + i];
        }
    }
  }
}

/* ---- a second Piola-Kirchhoff stress given per cell and point (the viscoelastic effect's F H term) ----
 * H (nc x nq x 9, symmetric, row-major) held fixed over a step: the force f_a = sum_q w_q (F_q H_q) G_a(q) is
 * linear in the positions, so the same loop gives the force (at x) and K v (at v); its tangent is the
 * geometric one, K_(a,i),(b,k) = delta_ik sum_q w_q G_a.H_q G_b. Linear tetrahedra (one point: Dminv, vol)
 * and elements with quadrature (dN, geo). F (nc x nq x 9) of positions x: he_deformations / he_edeformations. */
void he_deformations(int64_t nc, const idx_t *cells, const double *Dminv, const double *x, double *F) {
  for (int64_t e = 0; e < nc; e++) gather_F(cells + 4 * e, Dminv + 9 * e, x, F + 9 * e);
}

void he_fh_forces(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *H,
                  const double *x, double *f) {
  for (int64_t e = 0; e < nc; e++) {
    double F[9], P[9];
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    mm(F, H + 9 * e, P);
    scatter_force(cells + 4 * e, Dminv + 9 * e, vol[e], P, f);
  }
}

/* s[a][b] = w G_a.H G_b of one point's gradients G (nn of them) */
HE_INLINE void fh_products(const double *H, double G[HE_MAXN][3], int nn, double w, double s[HE_MAXN][HE_MAXN]) {
  for (int a = 0; a < nn; a++) {
    double hg[3];
    for (int i = 0; i < 3; i++) hg[i] = w * (H[3 * i] * G[a][0] + H[3 * i + 1] * G[a][1] + H[3 * i + 2] * G[a][2]);
    for (int b = 0; b < nn; b++) s[b][a] += G[b][0] * hg[0] + G[b][1] * hg[1] + G[b][2] * hg[2];
  }
}

/* A cell's products s (fh_products over its points) into the diagonal d at its nodes c and into its block K
 * (3nn x 3nn): delta_ik s[a][b] at (3a+i, 3b+k) (d NULL or K NULL: not that one). */
HE_INLINE void fh_add(double s[HE_MAXN][HE_MAXN], const idx_t *c, int nn, double *d, double *K) {
  const int n3 = 3 * nn;
  for (int a = 0; a < nn; a++) {
    if (d)
      for (int i = 0; i < 3; i++) d[3 * (int64_t)c[a] + i] += s[a][a];
    if (K)
      for (int b = 0; b < nn; b++)
        for (int i = 0; i < 3; i++) K[n3 * (3 * a + i) + 3 * b + i] += s[a][b];
  }
}

/* d += the diagonal of the F H term's tangent; vals (nc, 3nn, 3nn) += its blocks (diag NULL or vals NULL: not
 * that one). */
void he_fh_tangent(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *H,
                   double *d, double *vals) {
  for (int64_t e = 0; e < nc; e++) {
    double G[HE_MAXN][3], s[HE_MAXN][HE_MAXN] = {{0}};
    gradN(Dminv + 9 * e, (double(*)[3])G);
    fh_products(H + 9 * e, G, 4, vol[e], s);
    fh_add(s, cells + 4 * e, 4, d, vals ? vals + 144 * e : NULL);
  }
}

void he_edeformations(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                      const double *x, double *F) {
  for (int64_t e = 0; e < nc; e++) {
    double xe[HE_MAXN][3], G[HE_MAXN][3];
    e_gather(cells + (int64_t)nn * e, nn, x, xe);
    for (int q = 0; q < nq; q++) e_point(geo, dN, e, q, nn, nq, xe, G, F + 9 * ((int64_t)nq * e + q));
  }
}

void he_efh_forces(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                   const double *H, const double *x, double *f) {
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], fe[HE_MAXN][3] = {{0}};
    e_gather(c, nn, x, xe);
    for (int q = 0; q < nq; q++) {
      double G[HE_MAXN][3], F[9], P[9];
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      mm(F, H + 9 * ((int64_t)nq * e + q), P);
      e_add_force(P, G, nn, g[9], fe);
    }
    e_scatter(c, nn, fe, f);
  }
}

void he_efh_tangent(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                    const double *H, double *d, double *vals) {
  const int n3 = 3 * nn;
  for (int64_t e = 0; e < nc; e++) {
    double s[HE_MAXN][HE_MAXN] = {{0}};
    for (int q = 0; q < nq; q++) {
      double G[HE_MAXN][3];
      const double *g = geo + 10 * ((int64_t)nq * e + q);
      e_grads(g, dN + 3 * nn * q, nn, G);
      fh_products(H + 9 * ((int64_t)nq * e + q), G, nn, g[9], s);
    }
    fh_add(s, cells + (int64_t)nn * e, nn, d, vals ? vals + (int64_t)n3 * n3 * e : NULL);
  }
}

/* ---- the symmetric tangent straight into SBAIJ, and p-multigrid's P1 operator from the P2 cells ---- */

/* dst += the upper block triangle of the cells' blocks vals (nc x 3nn x 3nn, dof order 3a+i) into SBAIJ values
 * (blocks of 9, each column-major): the 3x3 block of nodes (a, b) goes to block pos[nn^2 e + nn a + b] where that
 * is >= 0 (-1: a lower block, whose transpose is the cell's (b, a); or a cell another rank's rows share: its
 * blocks go through MatSetValuesBlocked). The map is computed once (sbaij.UpperFill). */
void he_scatter_upper(int64_t nc, int nn, const int32_t *pos, const double *vals, double *dst) {
  const int n3 = 3 * nn;
  for (int64_t e = 0; e < nc; e++) {
    const int32_t *p = pos + (int64_t)nn * nn * e;
    const double *v = vals + (int64_t)n3 * n3 * e;
    for (int a = 0; a < nn; a++)
      for (int b = 0; b < nn; b++) {
        int32_t k = p[nn * a + b];
        if (k < 0) continue;
        double *d = dst + 9 * (int64_t)k;
        const double *blk = v + n3 * 3 * a + 3 * b;
        for (int i = 0; i < 3; i++)
          for (int j = 0; j < 3; j++) d[3 * j + i] += blk[n3 * i + j];
      }
  }
}

/* out (nc x 12 x 12) = P_e^T K_e P_e for quadratic tetrahedra (K_e: vals, nc x 30 x 30): the P1 operator of the
 * cell on its four vertices, P_e the P2 element's interpolation of the P1 one (a vertex node takes its vertex's
 * value, the edge node k the mean of its ends edges[2k], edges[2k+1]). p-multigrid's coarse operator is the sum of
 * these over the cells (pmg.GalerkinCells), exactly P^T K P. */
void he_p1_galerkin(int64_t nc, const int32_t *edges, const double *vals, double *out) {
  double R[12 * 30];
  for (int64_t e = 0; e < nc; e++) {
    const double *K = vals + 900 * e;
    double *C = out + 144 * e;
    for (int r = 0; r < 12; r++)                 /* rows: R = P_e^T K */
      for (int c = 0; c < 30; c++) R[30 * r + c] = K[30 * r + c];
    for (int k = 0; k < 6; k++)
      for (int s = 0; s < 2; s++) {
        int v = edges[2 * k + s];
        for (int i = 0; i < 3; i++)
          for (int c = 0; c < 30; c++) R[30 * (3 * v + i) + c] += 0.5 * K[30 * (12 + 3 * k + i) + c];
      }
    for (int r = 0; r < 12; r++) {               /* columns: C = R P_e */
      for (int c = 0; c < 12; c++) C[12 * r + c] = R[30 * r + c];
      for (int k = 0; k < 6; k++)
        for (int s = 0; s < 2; s++) {
          int w = edges[2 * k + s];
          for (int j = 0; j < 3; j++) C[12 * r + 3 * w + j] += 0.5 * R[30 * r + 12 + 3 * k + j];
        }
    }
  }
}

/* ---- the cells' reference geometry, once per run ---- */

/* Ai = A^-1 (3x3, row-major) by the cofactors, cof(A)^T / det A; returns det A. */
HE_INLINE double inv3(const double *A, double *Ai) {
  double C[9];
  cof_mixed(A, A, C);
  const double d = A[0] * C[0] + A[1] * C[1] + A[2] * C[2];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) Ai[3 * i + j] = C[3 * j + i] / d;
  return d;
}

/* Elements with quadrature: per (cell, point) of a rule with reference gradients dN (nq x nn x 3) and weights w (nq),
 * J = dX/dxi = sum_a X_a dN_a^T; where not NULL, geo (nc x nq x 10) = J^-1 (9, row-major) and |det J| w_q, and
 * wq (nc x nq) = |det J| w_q. */
void he_egeometry(int64_t nc, int nn, int nq, const idx_t *cells, const double *X, const double *dN, const double *w,
                  double *geo, double *wq) {
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    for (int q = 0; q < nq; q++) {
      double J[9] = {0}, Ji[9];
      const double *dq = dN + 3 * nn * q;
      for (int a = 0; a < nn; a++) {
        const double *xa = X + 3 * (int64_t)c[a];
        for (int i = 0; i < 3; i++)
          for (int j = 0; j < 3; j++) J[3 * i + j] += xa[i] * dq[3 * a + j];
      }
      const double d = fabs(inv3(J, Ji)) * w[q];
      if (geo) {
        double *g = geo + 10 * ((int64_t)nq * e + q);
        for (int k = 0; k < 9; k++) g[k] = Ji[k];
        g[9] = d;
      }
      if (wq) wq[(int64_t)nq * e + q] = d;
    }
  }
}

/* ---- the set-up's integer work: the tangent's exact pattern and where each cell's blocks go in it ----
 * (aij.vertex_pairs, aij.exact_pattern, aij.CellMap, sbaij.UpperFill: one pass over the cells in place of numpy sorts
 * of mesh-sized key arrays). PETSc's index arrays are read and written through PI/PW below: 32- or 64-bit (idx64). */
#define PI(p, k) (idx64 ? ((const int64_t *)(p))[k] : (int64_t)((const int32_t *)(p))[k])
#define PW(p, k, v) do { if (idx64) ((int64_t *)(p))[k] = (v); else ((int32_t *)(p))[k] = (int32_t)(v); } while (0)

static int cmp_i64(const void *a, const void *b) {
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

static void sort_i64(int64_t *a, int64_t n) {
  if (n > 48) { qsort(a, (size_t)n, sizeof(int64_t), cmp_i64); return; }
  for (int64_t i = 1; i < n; i++) {                /* insertion sort: rows are short (P2: ~30-70 vertices) */
    int64_t v = a[i], j = i - 1;
    while (j >= 0 && a[j] > v) { a[j + 1] = a[j]; j--; }
    a[j + 1] = v;
  }
}

/* The cells of each local vertex (nlv vertices; cells nc x nn, local indices): ptr (nlv + 1), list (nc nn), in cell
 * order. Returns 0, or -1 where memory ran out (nothing allocated then). */
static int vertex_cells(int64_t nc, int nn, const idx_t *cells, int64_t nlv, int64_t **ptr_out, int64_t **list_out) {
  int64_t *ptr = calloc((size_t)nlv + 1, sizeof(int64_t)), *list = malloc(sizeof(int64_t) * (size_t)(nc * nn + 1));
  if (!ptr || !list) { free(ptr); free(list); return -1; }
  for (int64_t k = 0; k < nc * nn; k++) ptr[cells[k] + 1]++;
  for (int64_t v = 0; v < nlv; v++) ptr[v + 1] += ptr[v];
  int64_t *fill = malloc(sizeof(int64_t) * (size_t)(nlv + 1));
  if (!fill) { free(ptr); free(list); return -1; }
  memcpy(fill, ptr, sizeof(int64_t) * (size_t)(nlv + 1));
  for (int64_t e = 0; e < nc; e++)
    for (int a = 0; a < nn; a++) list[fill[cells[nn * e + a]]++] = e;
  free(fill);
  *ptr_out = ptr;
  *list_out = list;
  return 0;
}

/* For each row vertex rows[k] (local index; nr of them), the distinct global numbers g[w] of the local vertices w
 * sharing a cell with it, sorted; with upper, only those >= the row's own g[rows[k]] (the upper block triangle).
 * Called twice: with cols NULL it writes the row pointers ptr (nr + 1, ptr[0] = 0); then, cols sized ptr[nr], the
 * columns. Returns 0, or -1 where memory ran out. */
int he_adjacency(int64_t nc, int nn, const idx_t *cells, int64_t nlv, const int64_t *g, int64_t nr,
                 const int64_t *rows, int upper, int64_t *ptr, int64_t *cols) {
  int64_t *vptr, *vlist, *mark = malloc(sizeof(int64_t) * (size_t)(nlv + 1));
  if (!mark || vertex_cells(nc, nn, cells, nlv, &vptr, &vlist)) { free(mark); return -1; }
  for (int64_t v = 0; v < nlv; v++) mark[v] = -1;
  if (!cols) ptr[0] = 0;
  for (int64_t k = 0; k < nr; k++) {
    const int64_t r = rows[k], gr = g[r];
    int64_t n = 0, *out = cols ? cols + ptr[k] : NULL;
    for (int64_t q = vptr[r]; q < vptr[r + 1]; q++) {
      const idx_t *c = cells + (int64_t)nn * vlist[q];
      for (int a = 0; a < nn; a++) {
        const int64_t w = c[a];
        if (mark[w] == k) continue;
        mark[w] = k;
        if (upper && g[w] < gr) continue;
        if (out) out[n] = g[w];
        n++;
      }
    }
    if (out) sort_i64(out, n);
    else ptr[k + 1] = ptr[k] + n;
  }
  free(mark);
  free(vptr);
  free(vlist);
  return 0;
}

/* The union of two CSR patterns with sorted distinct columns per row (n rows: ia/ja and ib/jb, int64): called with
 * jc NULL it writes the row pointers ic (n + 1); then, jc sized ic[n], the columns. */
void he_csr_union(int64_t n, const int64_t *ia, const int64_t *ja, const int64_t *ib, const int64_t *jb, int64_t *ic,
                  int64_t *jc) {
  if (!jc) ic[0] = 0;
  for (int64_t r = 0; r < n; r++) {
    int64_t p = ia[r], pe = ia[r + 1], q = ib[r], qe = ib[r + 1], m = 0, *out = jc ? jc + ic[r] : NULL;
    while (p < pe || q < qe) {
      int64_t v;
      if (q >= qe || (p < pe && ja[p] < jb[q])) v = ja[p++];
      else if (p >= pe || jb[q] < ja[p]) v = jb[q++];
      else { v = ja[p++]; q++; }
      if (out) out[m] = v;
      m++;
    }
    if (!jc) ic[r + 1] = ic[r] + m;
  }
}

/* The scalar pattern (3 dofs a vertex) of a vertex pattern (n rows; vptr, vcols int64 global vertex numbers): dof
 * row 3v + a has the columns 3w + b of every w in v's row, in order. ia (3n + 1), ja (9 vptr[n]): PETSc's index type
 * (idx64). */
void he_expand_pattern(int64_t n, const int64_t *vptr, const int64_t *vcols, int idx64, void *ia, void *ja) {
  PW(ia, 0, 0);
  for (int64_t v = 0; v < n; v++) {
    const int64_t d = vptr[v + 1] - vptr[v];
    for (int a = 0; a < 3; a++) {
      const int64_t r = 3 * v + a, start = 9 * vptr[v] + 3 * d * a;
      PW(ia, r + 1, start + 3 * d);
      for (int64_t k = 0; k < d; k++)
        for (int b = 0; b < 3; b++) PW(ja, start + 3 * k + b, 3 * vcols[vptr[v] + k] + b);
    }
  }
}

/* The position of column col in row r of a CSR pattern with sorted columns (ia, ja: PETSc's index type), or -1. */
static int64_t csr_find(const void *ia, const void *ja, int idx64, int64_t r, int64_t col) {
  int64_t lo = PI(ia, r), hi = PI(ia, r + 1);
  while (lo < hi) {
    const int64_t mid = lo + (hi - lo) / 2, c = PI(ja, mid);
    if (c == col) return mid;
    if (c < col) lo = mid + 1; else hi = mid;
  }
  return -1;
}

/* aij.CellMap's loop for one index type T (int32_t, int64_t): see he_cell_map. A vertex's three rows are checked
 * once per cell and vertex (the same length, consecutive), its column's position found by bisection in its first row,
 * and the block's 9 columns read back. */
#define HE_CELL_MAP(NAME, T)                                                                                          \
  static int64_t NAME(int64_t nc, int nn, const idx_t *cells, const int64_t *own, const T *ia, const T *ja,          \
                      int32_t *base, int32_t *rowlen) {                                                               \
    int64_t missing = 0;                                                                                              \
    for (int64_t e = 0; e < nc; e++) {                                                                                \
      const idx_t *c = cells + (int64_t)nn * e;                                                                       \
      int32_t *B = base + (int64_t)nn * nn * e, *L = rowlen + (int64_t)nn * e;                                        \
      int64_t o[HE_MAXN];                                                                                             \
      int interior = 1, bad = 0;                                                                                      \
      for (int a = 0; a < nn; a++) { o[a] = own[c[a]]; interior &= o[a] >= 0; }                                      \
      if (!interior) {                                                                                                \
        for (int k = 0; k < nn * nn; k++) B[k] = -1;                                                                  \
        for (int a = 0; a < nn; a++) L[a] = 0;                                                                        \
        continue;                                                                                                     \
      }                                                                                                               \
      for (int a = 0; a < nn && !bad; a++) {                                                                          \
        const int64_t r = 3 * o[a], r0 = ia[r], len = (int64_t)ia[r + 1] - r0;                                       \
        if ((int64_t)ia[r + 2] - r0 != 2 * len || (int64_t)ia[r + 3] - r0 != 3 * len) { bad = 1; break; }             \
        L[a] = (int32_t)len;                                                                                          \
        for (int b = 0; b < nn; b++) {                                                                                \
          const int64_t col = 3 * o[b];                                                                               \
          int64_t lo = r0, hi = r0 + len;                                                                             \
          while (lo < hi) {                                                                                           \
            const int64_t mid = lo + (hi - lo) / 2;                                                                   \
            if ((int64_t)ja[mid] < col) lo = mid + 1; else hi = mid;                                                  \
          }                                                                                                           \
          if (lo + 2 >= r0 + len) { bad = 1; break; }                                                                 \
          for (int i = 0; i < 3; i++)                                                                                 \
            for (int jj = 0; jj < 3; jj++)                                                                            \
              bad |= (int64_t)ja[lo + i * len + jj] != col + jj;                                                      \
          if (bad) break;                                                                                             \
          B[nn * a + b] = (int32_t)lo;                                                                                \
        }                                                                                                             \
      }                                                                                                               \
      missing += bad;                                                                                                 \
    }                                                                                                                 \
    return missing;                                                                                                   \
  }
HE_CELL_MAP(cell_map_i32, int32_t)
HE_CELL_MAP(cell_map_i64, int64_t)
#undef HE_CELL_MAP

/* aij.CellMap: for each cell whose nodes this rank all owns (own[w] >= 0: the node's index among the owned ones;
 * cells nc x nn, local), where its node pair (a, b)'s 3x3 block starts in the values of the scalar CSR ia/ja (owned
 * rows and columns 3 own + i) — base[nn^2 e + nn a + b] — and the length of node a's rows, rowlen[nn e + a]; the
 * other cells get base -1 and rowlen 0. Every entry of every block is checked: returns the number of cells with an
 * entry missing from the pattern (0: the map is complete). */
int64_t he_cell_map(int64_t nc, int nn, const idx_t *cells, const int64_t *own, const void *ia, const void *ja,
                    int idx64, int32_t *base, int32_t *rowlen) {
  return idx64 ? cell_map_i64(nc, nn, cells, own, ia, ja, base, rowlen)
               : cell_map_i32(nc, nn, cells, own, ia, ja, base, rowlen);
}

/* aij.SBAIJCopy on one rank: of a scalar CSR ia/ja (3 rows a vertex with the same columns, a vertex's 3 columns
 * consecutive; n vertices), per block row v its blocks (v, w) with w >= v — their columns w, where the block's first
 * entry is in the values (p0) and the length of v's rows (L). Called twice: with bcols NULL it writes the block row
 * pointers bptr (n + 1); then, bcols, p0 and L sized bptr[n], the blocks. Returns the number of block rows whose
 * entries are not whole 3x3 blocks (0: the copy can be made). */
int64_t he_upper_blocks(int64_t n, const void *ia, const void *ja, int idx64, int64_t *bptr, int64_t *bcols,
                        int32_t *p0, int32_t *L) {
  int64_t bad = 0;
  if (!bcols) bptr[0] = 0;
  for (int64_t v = 0; v < n; v++) {
    const int64_t r0 = PI(ia, 3 * v), len = PI(ia, 3 * v + 1) - r0;
    int64_t m = 0;
    const int64_t at = bcols ? bptr[v] : 0;
    if (len % 3 == 0)
      for (int64_t k = r0; k < r0 + len; k += 3) {
        const int64_t c = PI(ja, k);
        if (c % 3 || PI(ja, k + 2) != c + 2) { bad++; break; }
        if (c / 3 < v) continue;
        if (bcols) { bcols[at + m] = c / 3; p0[at + m] = (int32_t)k; L[at + m] = (int32_t)len; }
        m++;
      }
    else bad++;
    if (!bcols) bptr[v + 1] = bptr[v] + m;
  }
  return bad;
}

/* sbaij.UpperFill: for each cell whose nodes this rank all owns, the block index in the block CSR si/sj (upper block
 * triangle, owned block rows and columns) of its node pair (a, b) where own[a] <= own[b] — pos[nn^2 e + nn a + b] —
 * and -1 elsewhere (the lower pairs, and every pair of the other cells). Returns the number of pairs missing. */
int64_t he_upper_map(int64_t nc, int nn, const idx_t *cells, const int64_t *own, const void *si, const void *sj,
                     int idx64, int32_t *pos) {
  int64_t missing = 0;
  for (int64_t e = 0; e < nc; e++) {
    const idx_t *c = cells + (int64_t)nn * e;
    int32_t *P = pos + (int64_t)nn * nn * e;
    int interior = 1;
    for (int a = 0; a < nn; a++) interior &= own[c[a]] >= 0;
    for (int a = 0; a < nn; a++)
      for (int b = 0; b < nn; b++) {
        const int64_t oa = own[c[a]], ob = own[c[b]];
        int64_t p = -1;
        if (interior && oa <= ob) {
          p = csr_find(si, sj, idx64, oa, ob);
          missing += p < 0;
        }
        P[nn * a + b] = (int32_t)p;
      }
  }
  return missing;
}
#undef PI
#undef PW
