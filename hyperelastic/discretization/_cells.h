/* What the cell loops share (_kernels.c, _material_loops.h, _element_loops.h): the index type, a linear
 * tetrahedron's F and force, the blocks of cells whose 1/J and ln J are taken at once, the parameter block,
 * the macros naming a material's loops, and a quadrature point's gradients, F and force (elements with
 * quadrature). Included by each of them; defines nothing that depends on a material. */
#ifndef HE_CELLS_H
#define HE_CELLS_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "materials/_tensor.h"

typedef int32_t idx_t;

HE_INLINE void gather_F(const idx_t *c, const double *Dminv, const double *x, double *F) {
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
HE_INLINE void scatter_force(const idx_t *c, const double *Dminv, double V, const double *P, double *f) {
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

/* grad N_b for b = 0..3 from Dminv */
HE_INLINE void gradN(const double *Dminv, double G[4][3]) {
  for (int j = 0; j < 3; j++) {
    G[1][j] = Dminv[j];
    G[2][j] = Dminv[3 + j];
    G[3][j] = Dminv[6 + j];
    G[0][j] = -(G[1][j] + G[2][j] + G[3][j]);
  }
}

/* Cells in blocks of HE_BLOCK: the force, energy and K v loops take J = det F of a whole block first,
 * then 1/J and ln J of the block at once (he_jscalars), for materials whose stress needs them
 * (NAME_BATCH_J).
 * Cell by cell, the division and the logarithm wait on J and on each other: ~30% of a Neo-Hookean
 * force; over a block they are vector operations. The logarithm is glibc's vector one (libmvec, named
 * by the x86-64 vector function ABI: _ZGVeN8v_log for 8 lanes of AVX-512, _ZGVdN4v_log for 4 of AVX2)
 * where setup.py found libmvec (HE_MVEC), else log(). Each lane's result is that lane's alone, so a
 * cell's ln J does not depend on its place in a block (or on the partition). */
#define HE_BLOCK 32
typedef struct {
  double F[HE_BLOCK][9], J[HE_BLOCK], rJ[HE_BLOCK], lnJ[HE_BLOCK];
} he_jblock;

#if defined(HE_MVEC) && (defined(__AVX512F__) || defined(__AVX2__))
#include <immintrin.h>
#if defined(__AVX512F__)
__m512d _ZGVeN8v_log(__m512d);
HE_INLINE void he_log_block(const double *s, double *out) {
  for (int q = 0; q < HE_BLOCK; q += 8) _mm512_storeu_pd(out + q, _ZGVeN8v_log(_mm512_loadu_pd(s + q)));
}
#else
__m256d _ZGVdN4v_log(__m256d);
HE_INLINE void he_log_block(const double *s, double *out) {
  for (int q = 0; q < HE_BLOCK; q += 4) _mm256_storeu_pd(out + q, _ZGVdN4v_log(_mm256_loadu_pd(s + q)));
}
#endif
#else
HE_INLINE void he_log_block(const double *s, double *out) {
  for (int q = 0; q < HE_BLOCK; q++) out[q] = log(s[q]);
}
#endif

/* b->rJ, b->lnJ = 1/J, ln J of the first n cells' b->J where J > 0, NaN elsewhere (no division by zero
 * nor log of a non-positive number is evaluated: runs under -fp_trap stay clean). */
HE_INLINE void he_jscalars(he_jblock *b, int n) {
  double s[HE_BLOCK];
  for (int q = 0; q < HE_BLOCK; q++) s[q] = (q < n && b->J[q] > 0) ? b->J[q] : 1.0;
  for (int q = 0; q < HE_BLOCK; q++) b->rJ[q] = 1.0 / s[q];
  he_log_block(s, b->lnJ);
  for (int q = 0; q < n; q++)
    if (!(b->J[q] > 0)) b->rJ[q] = b->lnJ[q] = NAN;
}

/* W += t, compensated (Kahan): the energy line search compares energies that differ by far less than the energy
 * itself near convergence, so the sum's rounding error must stay at one ulp, not one per cell. */
HE_INLINE void he_kahan_add(double *W, double *comp, double t) {
  double term = t - *comp, sum = *W + term;
  *comp = (sum - *W) - term;
  *W = sum;
}

/* The range [jmin, jmax] of det F so far, with J. */
HE_INLINE void he_jrange(double J, double *jmin, double *jmax) {
  *jmin = J < *jmin ? J : *jmin;
  *jmax = J > *jmax ? J : *jmax;
}

/* A material's parameter block: at most HE_NPARAM constants (kernels.py pads it with zeros). The loops take
 * it as `const double *restrict prm` (_material_loops.h): it aliases no output array, so the constants stay
 * in registers (without restrict, linear's K v ran ~3% slower; a local copy of the block, 2%). */
#define HE_NPARAM 12
#define HE_PARAMS(p) const double *p = prm
/* Loops instantiated with HE_PER_CELL 1 (a material whose constants vary from cell to cell: NAME_PER_CELL) take a
 * block per cell, prm + HE_NPARAM e at cell e, and carry the suffix _cells; with HE_PER_CELL 0 both are nothing. */
#define HE_CELL_PARAMS(e) HE_CAT(HE_CELL_PARAMS_, HE_PER_CELL)(e)
#define HE_CELL_PARAMS_0(e)
#define HE_CELL_PARAMS_1(e) (p = prm + (int64_t)HE_NPARAM * (e))
#define HE_SUFFIX HE_CAT(HE_SUFFIX_, HE_PER_CELL)
#define HE_SUFFIX_0
#define HE_SUFFIX_1 _cells

/* A material's loops are named he_KIND_NAME (MATERIAL is defined per instantiation by he_materials.h). */
#define HE_CAT_(a, b) a##b
#define HE_CAT(a, b) HE_CAT_(a, b)
#define HE_FN(kind) HE_CAT(HE_CAT(he_, kind), HE_CAT(_, HE_CAT(MATERIAL, HE_SUFFIX)))
#define HE_MAT(fn) HE_CAT(MATERIAL, HE_CAT(_, fn))

/* Elements with quadrature: at most HE_MAXN nodes per cell. */
#define HE_MAXN 10

/* grad N_a (physical) of the nn nodes at a point: G[a][j] = sum_m Jinv[m][j] dN[a][m] */
HE_INLINE void e_grads(const double *g, const double *dN, int nn, double G[HE_MAXN][3]) {
  for (int a = 0; a < nn; a++)
    for (int j = 0; j < 3; j++)
      G[a][j] = g[j] * dN[3 * a] + g[3 + j] * dN[3 * a + 1] + g[6 + j] * dN[3 * a + 2];
}

HE_INLINE void e_gather(const idx_t *c, int nn, const double *x, double xe[HE_MAXN][3]) {
  for (int a = 0; a < nn; a++)
    for (int i = 0; i < 3; i++) xe[a][i] = x[3 * (int64_t)c[a] + i];
}

/* F = sum_a xe_a (x) G_a */
HE_INLINE void e_deformation(double xe[HE_MAXN][3], double G[HE_MAXN][3], int nn, double *F) {
  for (int k = 0; k < 9; k++) F[k] = 0;
  for (int a = 0; a < nn; a++)
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) F[3 * i + j] += xe[a][i] * G[a][j];
}

/* fe_a += w P G_a */
HE_INLINE void e_add_force(const double *P, double G[HE_MAXN][3], int nn, double w, double fe[HE_MAXN][3]) {
  for (int a = 0; a < nn; a++)
    for (int i = 0; i < 3; i++)
      fe[a][i] += w * (P[3 * i] * G[a][0] + P[3 * i + 1] * G[a][1] + P[3 * i + 2] * G[a][2]);
}

/* At point q of cell e of an element with quadrature: its row of `geo` (J^-1 row-major, then the weight |det J| w_q),
 * the physical gradients G of the nn nodes and F of the cell's positions xe. */
HE_INLINE const double *e_point(const double *geo, const double *dN, int64_t e, int q, int nn, int nq,
                                double xe[HE_MAXN][3], double G[HE_MAXN][3], double *F) {
  const double *g = geo + 10 * ((int64_t)nq * e + q);
  e_grads(g, dN + 3 * nn * q, nn, G);
  e_deformation(xe, G, nn, F);
  return g;
}

HE_INLINE void e_scatter(const idx_t *c, int nn, double fe[HE_MAXN][3], double *f) {
  for (int a = 0; a < nn; a++)
    for (int i = 0; i < 3; i++) f[3 * (int64_t)c[a] + i] += fe[a][i];
}

/* T[a][i][3k+l] = sum_j G_a,j A[3i+j][3k+l]: the moduli contracted with one node's gradient. */
HE_INLINE void e_contract_left(double A[9][9], double G[HE_MAXN][3], int nn, double T[HE_MAXN][3][9]) {
  for (int a = 0; a < nn; a++)
    for (int i = 0; i < 3; i++)
      for (int kl = 0; kl < 9; kl++)
        T[a][i][kl] = G[a][0] * A[3 * i][kl] + G[a][1] * A[3 * i + 1][kl] + G[a][2] * A[3 * i + 2][kl];
}

#endif
