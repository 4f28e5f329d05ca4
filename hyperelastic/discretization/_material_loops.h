/* The cell loops of one material, instantiated once per material by the generated he_materials.h:
 *   #include "materials/NAME.h"
 *   #define MATERIAL NAME
 *   #include "_material_loops.h"
 * which defines he_forces_NAME, he_energy_NAME, he_kv_NAME, he_tangent_NAME, he_tangent_diag_NAME, he_fields_NAME and
 * he_forces_dg_NAME (bound by name in kernels.py) from NAME_stress, NAME_prepare, NAME_dstress and NAME_cache; where the
 * header defines NAME_BATCH_J 1, the force, energy and K v loops use NAME_stress_j and NAME_prepare_j
 * (from F, 1/J, ln J); where it defines NAME_CELL_TANGENT 1, the tangent loops take the cell's 12x12
 * block and its diagonal from NAME_cell_tangent and NAME_cell_tangent_diag instead of twelve NAME_dstress.
 * Every loop takes the material's parameter block `prm` (HE_NPARAM doubles: the constants in the order
 * the header reads them, materials/NAME.py's `constants`, zero-padded), restrict-qualified (_kernels.c). Where the
 * header defines NAME_PER_CELL 1, the loops are instantiated a second time with HE_PER_CELL 1 and named
 * he_KIND_NAME_cells: their prm holds a block per cell (nc x HE_NPARAM), which HE_CELL_PARAMS(e) selects at each
 * cell (in the others it is nothing: the same code as before).
 * No include guard: it is meant to be included once per material (the helpers it shares with the other loops
 * are _cells.h's). */
#include "_cells.h"

#if HE_MAT(BATCH_J)
/* A material whose stress takes 1/J and ln J (NAME_BATCH_J; undefined for J <= 0): the force, energy and
 * K v loops go by blocks of HE_BLOCK cells, the block's F and J first (gather_block: the cells from e0,
 * returns how many), then its 1/J and ln J at once (he_jscalars, _kernels.c), then each cell's stress
 * NAME_stress_j or NAME_prepare_j. */
HE_INLINE int HE_FN(gather_block)(int64_t e0, int64_t nc, const idx_t *cells, const double *Dminv,
                                      const double *x, he_jblock *b) {
  int n = nc - e0 < HE_BLOCK ? (int)(nc - e0) : HE_BLOCK;
  for (int q = 0; q < n; q++) {
    gather_F(cells + 4 * (e0 + q), Dminv + 9 * (e0 + q), x, b->F[q]);
    b->J[q] = det3(b->F[q]);
  }
  he_jscalars(b, n);
  return n;
}

/* f += k(x). Returns the number of cells where the material is undefined (their force is skipped). */
int64_t HE_FN(forces)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      const double *restrict prm, double *f) {
  HE_PARAMS(p);
  int64_t bad = 0;
  he_jblock jb;
  for (int64_t e0 = 0; e0 < nc; e0 += HE_BLOCK) {
    int n = HE_FN(gather_block)(e0, nc, cells, Dminv, x, &jb);
    for (int q = 0; q < n; q++) {
      HE_CELL_PARAMS(e0 + q);
      double P[9];
      int64_t e = e0 + q;
      if (!(jb.J[q] > 0)) { bad++; continue; }
      HE_MAT(stress_j)(p, jb.F[q], jb.rJ[q], jb.lnJ[q], P, NULL);
      scatter_force(cells + 4 * e, Dminv + 9 * e, vol[e], P, f);
    }
  }
  return bad;
}

/* Elastic energy sum_e V Psi(F_e), and min/max of J = det F. Returns the number of undefined cells.
 * The sum is compensated (he_kahan_add). */
int64_t HE_FN(energy)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      const double *restrict prm, double *out /* [energy, Jmin, Jmax] */) {
  HE_PARAMS(p);
  int64_t bad = 0;
  double W = 0, comp = 0, jmin = INFINITY, jmax = -INFINITY;
  he_jblock jb;
  for (int64_t e0 = 0; e0 < nc; e0 += HE_BLOCK) {
    int n = HE_FN(gather_block)(e0, nc, cells, Dminv, x, &jb);
    for (int q = 0; q < n; q++) {
      HE_CELL_PARAMS(e0 + q);
      double P[9], psi, J = jb.J[q];
      he_jrange(J, &jmin, &jmax);
      if (!(J > 0)) { bad++; continue; }
      HE_MAT(stress_j)(p, jb.F[q], jb.rJ[q], jb.lnJ[q], P, &psi);
      he_kahan_add(&W, &comp, vol[e0 + q] * psi);
    }
  }
  out[0] = W; out[1] = jmin; out[2] = jmax;
  return bad;
}
#else
/* Cell by cell (by blocks, St.VK's loop is ~10% slower: it has no division or logarithm to batch). */
/* f += k(x). Returns the number of cells where the material is undefined (their force is skipped). */
int64_t HE_FN(forces)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      const double *restrict prm, double *f) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + 4 * e;
    double F[9], P[9];
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(stress)(p, F, P, NULL)) { bad++; continue; }
    scatter_force(c, Dminv + 9 * e, vol[e], P, f);
  }
  return bad;
}

/* Elastic energy sum_e V Psi(F_e), and min/max of J = det F. Returns the number of undefined cells.
 * The sum is compensated (he_kahan_add). */
int64_t HE_FN(energy)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      const double *restrict prm, double *out /* [energy, Jmin, Jmax] */) {
  HE_PARAMS(p);
  int64_t bad = 0;
  double W = 0, comp = 0, jmin = INFINITY, jmax = -INFINITY;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double F[9], P[9], psi;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    he_jrange(det3(F), &jmin, &jmax);
    if (HE_MAT(stress)(p, F, P, &psi)) { bad++; continue; }
    he_kahan_add(&W, &comp, vol[e] * psi);
  }
  out[0] = W; out[1] = jmin; out[2] = jmax;
  return bad;
}
#endif

#if HE_MAT(BATCH_J)
/* y += K(x) v without assembling, by blocks of cells (NAME_prepare_j from the block's 1/J, ln J). */
int64_t HE_FN(kv)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                  const double *restrict prm, const double *v, double *y) {
  HE_PARAMS(p);
  int64_t bad = 0;
  he_jblock jb;
  for (int64_t e0 = 0; e0 < nc; e0 += HE_BLOCK) {
    int n = HE_FN(gather_block)(e0, nc, cells, Dminv, x, &jb);
    for (int q = 0; q < n; q++) {
      HE_CELL_PARAMS(e0 + q);
      int64_t e = e0 + q;
      const idx_t *c = cells + 4 * e;
      double dF[9], dP[9];
      HE_MAT(cache) d;
      if (!(jb.J[q] > 0)) { bad++; continue; }
      HE_MAT(prepare_j)(p, jb.F[q], jb.rJ[q], jb.lnJ[q], &d);
      gather_F(c, Dminv + 9 * e, v, dF);
      HE_MAT(dstress)(p, &d, dF, dP);
      scatter_force(c, Dminv + 9 * e, vol[e], dP, y);
    }
  }
  return bad;
}
#else
/* y += K(x) v, cell by cell, without assembling. */
int64_t HE_FN(kv)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                  const double *restrict prm, const double *v, double *y) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + 4 * e;
    double F[9], dF[9], dP[9];
    HE_MAT(cache) d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(p, F, &d)) { bad++; continue; }
    gather_F(c, Dminv + 9 * e, v, dF);
    HE_MAT(dstress)(p, &d, dF, dP);
    scatter_force(c, Dminv + 9 * e, vol[e], dP, y);
  }
  return bad;
}
#endif

/* Column (b,k) of the cell tangent: K[(a,i),(b,k)] = V sum_j dP(e_k (x) G_b)_ij G_a,j */
HE_INLINE void HE_FN(tangent_column)(const double *p, const HE_MAT(cache) *d, double G[4][3], double V,
                                         int b, int k, double col[12]) {
  double dF[9] = {0}, dP[9];
  dF[3 * k + 0] = G[b][0];
  dF[3 * k + 1] = G[b][1];
  dF[3 * k + 2] = G[b][2];
  HE_MAT(dstress)(p, d, dF, dP);
  for (int a = 0; a < 4; a++)
    for (int i = 0; i < 3; i++)
      col[3 * a + i] = V * (dP[3 * i] * G[a][0] + dP[3 * i + 1] * G[a][1] + dP[3 * i + 2] * G[a][2]);
}

/* Cell tangents, 144 values per cell, row-major over local dofs (3a+i, 3b+k); written, or added to
 * vals when accumulate != 0. */
int64_t HE_FN(tangent)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                       const double *restrict prm, double *vals, int accumulate) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double F[9], G[4][3], col[12];
    HE_MAT(cache) d;
    double *K = vals + 144 * e;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(p, F, &d)) {
      for (int k = 0; k < 144; k++) K[k] = NAN;
      bad++;
      continue;
    }
    gradN(Dminv + 9 * e, G);
#if HE_MAT(CELL_TANGENT)
    (void)col;
    HE_MAT(cell_tangent)(p, &d, G, vol[e], K, accumulate);
#else
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        HE_FN(tangent_column)(p, &d, G, vol[e], b, k, col);
        if (accumulate)
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] += col[r];
        else
          for (int r = 0; r < 12; r++) K[12 * r + 3 * b + k] = col[r];
      }
#endif
  }
  return bad;
}

/* diag += diagonal of K(x) */
int64_t HE_FN(tangent_diag)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol,
                            const double *x, const double *restrict prm, double *diag) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + 4 * e;
    double F[9], G[4][3], col[12];
    HE_MAT(cache) d;
    gather_F(c, Dminv + 9 * e, x, F);
    if (HE_MAT(prepare)(p, F, &d)) { bad++; continue; }
    gradN(Dminv + 9 * e, G);
#if HE_MAT(CELL_TANGENT)
    HE_MAT(cell_tangent_diag)(p, &d, G, vol[e], col);
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) diag[3 * (int64_t)c[b] + k] += col[3 * b + k];
#else
    for (int b = 0; b < 4; b++)
      for (int k = 0; k < 3; k++) {
        HE_FN(tangent_column)(p, &d, G, vol[e], b, k, col);
        diag[3 * (int64_t)c[b] + k] += col[3 * b + k];
      }
#endif
  }
  return bad;
}

/* The energy-momentum (discrete-gradient) first Piola stress at a point of the midpoint step from Fn to
 * F1 = 2 F - Fn, F the midpoint (kernels.py, CellKernels.forces_discrete_gradient, has the formulas and
 * references): P = F S_alg, S_alg = S(C_bar) + (dW - S(C_bar) : dE) dE / (dE : dE). S(C_bar) = Ft^-1 P(Ft) for
 * any Ft with Ft^T Ft = C_bar and det Ft of the sign of det F (objective materials): from the Cholesky
 * factor C_bar = L L^T, Ft = L^T, its last row negated where det F < 0. Returns 1 where the material is
 * undefined at Fn or F1 (P not set). */
HE_INLINE int HE_FN(point_dg)(const double *p, const double *F, const double *Fn, double *P) {
  double F1[9], Cn[9], C1[9], Cb[9], dE[9], psin, psi1;
  for (int k = 0; k < 9; k++) F1[k] = 2 * F[k] - Fn[k];
  if (HE_MAT(stress)(p, Fn, P, &psin) || HE_MAT(stress)(p, F1, P, &psi1)) return 1;
  mtm(Fn, Fn, Cn);
  mtm(F1, F1, C1);
  for (int k = 0; k < 9; k++) { Cb[k] = 0.5 * (Cn[k] + C1[k]); dE[k] = 0.5 * (C1[k] - Cn[k]); }
  /* Cholesky C_bar = L L^T; Ft = L^T (upper triangular, row-major) */
  double l00 = Cb[0] > 0 ? sqrt(Cb[0]) : 0;
  if (!(l00 > 0)) return 1;
  double l10 = Cb[3] / l00, l20 = Cb[6] / l00;
  double d11 = Cb[4] - l10 * l10;
  if (!(d11 > 0)) return 1;
  double l11 = sqrt(d11), l21 = (Cb[7] - l20 * l10) / l11;
  double d22 = Cb[8] - l20 * l20 - l21 * l21;
  if (!(d22 > 0)) return 1;
  /* with the midpoint's orientation: Ft = diag(1, 1, -1) L^T where det F < 0 (materials defined when
   * inverted depend on the sign of J, which C does not carry) */
  double l22 = det3(F) < 0 ? -sqrt(d22) : sqrt(d22);
  double Ft[9] = {l00, l10, l20, 0, l11, l21, 0, 0, l22}, Pt[9], cof[9], S[9];
  if (HE_MAT(stress)(p, Ft, Pt, NULL)) return 1;
  cof_mixed(Ft, Ft, cof);                      /* Ft^-1 = cof^T / det */
  double idet = 1.0 / (l00 * l11 * l22);
  mtm(cof, Pt, S);
  double sde = 0, nn = 0;
  for (int i = 0; i < 3; i++)
    for (int j = i; j < 3; j++) {
      double s = 0.5 * idet * (S[3 * i + j] + S[3 * j + i]);
      S[3 * i + j] = S[3 * j + i] = s;
    }
  for (int k = 0; k < 9; k++) { sde += S[k] * dE[k]; nn += dE[k] * dE[k]; }
  if (nn > 1e-12) { /* |dE| > 1e-6: below it the correction, O(|dE|^2), is under the rounding of dW */
    double w = (psi1 - psin - sde) / nn;
    for (int k = 0; k < 9; k++) S[k] += w * dE[k];
  }
  mm(F, S, P);
  return 0;
}

/* f += the energy-momentum force of the midpoint step from xn to x1 = 2 x - xn, x the midpoint (point_dg).
 * Returns the number of cells where the material is undefined at xn or x1 (their force is skipped). */
int64_t HE_FN(forces_dg)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                         const double *restrict prm, const double *xn, double *f) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + 4 * e;
    double F[9], Fn[9], P[9];
    gather_F(c, Dminv + 9 * e, x, F);
    gather_F(c, Dminv + 9 * e, xn, Fn);
    if (HE_FN(point_dg)(p, F, Fn, P)) { bad++; continue; }
    scatter_force(c, Dminv + 9 * e, vol[e], P, f);
  }
  return bad;
}


/* The second Piola-Kirchhoff stress S = F^-1 P(F) of each cell (nc x 9; NaN where the material is undefined): the
 * viscoelastic effect's S_iso with the isochoric constants. Returns the number of undefined cells. */
int64_t HE_FN(pk2)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                   const double *restrict prm, double *S) {
  HE_PARAMS(p);
  int64_t bad = 0;
  (void)vol;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double F[9], P[9];
    int undefined;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    undefined = HE_MAT(stress)(p, F, P, NULL);
    bad += undefined != 0;
    pk2_of(F, P, undefined, S + 9 * e);
  }
  return bad;
}


/* The output's cell fields (output/fields.py), 15 numbers a cell: J = det F, Psi, the von Mises stress
 * sqrt(3/2 s:s) of the Cauchy stress sigma = P F^T / J (s its deviator), sigma and the Green-Lagrange strain
 * E = (F^T F - I)/2 as Tensor6 (xx, xy, xz, yy, yz, zz). Psi, von Mises and sigma are NaN where the material is
 * undefined or they are not finite. Returns the number of such cells. */
int64_t HE_FN(fields)(int64_t nc, const idx_t *cells, const double *Dminv, const double *vol, const double *x,
                      const double *restrict prm, double *out) {
  static const int T6[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
  HE_PARAMS(p);
  int64_t bad = 0;
  (void)vol;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double F[9], P[9], sig[9], psi = 0, *o = out + 15 * e;
    gather_F(cells + 4 * e, Dminv + 9 * e, x, F);
    double J = det3(F);
    o[0] = J;
    for (int k = 0; k < 6; k++) {
      int i = T6[k][0], j = T6[k][1];
      o[9 + k] = 0.5 * (F[i] * F[j] + F[3 + i] * F[3 + j] + F[6 + i] * F[6 + j] - (i == j ? 1.0 : 0.0));
    }
    int ok = HE_MAT(stress)(p, F, P, &psi) == 0 && isfinite(psi);
    double ss = 0, tr = 0;
    for (int i = 0; ok && i < 3; i++)
      for (int j = 0; j < 3; j++) {
        sig[3 * i + j] = (P[3 * i] * F[3 * j] + P[3 * i + 1] * F[3 * j + 1] + P[3 * i + 2] * F[3 * j + 2]) / J;
        ok = ok && isfinite(sig[3 * i + j]);
      }
    if (!ok) {
      bad++;
      o[1] = o[2] = NAN;
      for (int k = 0; k < 6; k++) o[3 + k] = NAN;
      continue;
    }
    tr = (sig[0] + sig[4] + sig[8]) / 3.0;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) {
        double s = sig[3 * i + j] - (i == j ? tr : 0.0);
        ss += s * s;
      }
    o[1] = psi;
    o[2] = sqrt(1.5 * ss);
    for (int k = 0; k < 6; k++) o[3 + k] = sig[3 * T6[k][0] + T6[k][1]];
  }
  return bad;
}
