/* The cell loops of one material on elements with quadrature (P2 tetrahedra, and P1 through the same path
 * for the tests), instantiated once per material header right after _material_loops.h by the generated
 * he_materials.h, with the same MATERIAL: he_eforces_NAME, he_eenergy_NAME, he_ekv_NAME, he_etangent_NAME,
 * he_etangent_diag_NAME and he_eforces_dg_NAME (bound in kernels.py, ElementKernels).
 *
 * Arguments: nc cells of nn nodes (cells: nc x nn local node indices), nq quadrature points with the
 * reference gradients dN (nq x nn x 3) and per (cell, point) `geo` (nc x nq x 10: J^-1 row-major, then the
 * weight |det J| w_q, J = dX/dxi). At a point, grad N_a = J^-T dN_a and F = sum_a x_a (x) grad N_a; the
 * element force is sum_q w_q P(F_q) grad N_a(q), the energy sum_q w_q psi(F_q), the tangent the
 * derivative of the force: the material's moduli dP/dF at each point (9 dstress calls, the same header as
 * the P1 loops) contracted with the gradients on both sides. A cell where the material is undefined at any
 * point is skipped and counted. */
#define HE_EFN(kind) HE_CAT(HE_CAT(he_e, kind), HE_CAT(_, HE_CAT(MATERIAL, HE_SUFFIX)))

#include "_cells.h"

/* The material's moduli at a point, times the weight w: A[3i+j][3k+l] = w dP_ij / dF_kl, one directional
 * derivative per unit dF = e_k (x) e_l (9 per point, where the tangent's columns e_k (x) G_b would take 3 nn). */
HE_INLINE void HE_EFN(moduli)(const double *p, const HE_MAT(cache) *d, double w, double A[9][9]) {
  for (int kl = 0; kl < 9; kl++) {
    double dF[9] = {0}, dP[9];
    dF[kl] = 1;
    HE_MAT(dstress)(p, d, dF, dP);
    for (int ij = 0; ij < 9; ij++) A[ij][kl] = w * dP[ij];
  }
}

/* f += k(x). Returns the number of cells where the material is undefined (their force is skipped). */
int64_t HE_EFN(forces)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                       const double *x, const double *restrict prm, double *f) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], fe[HE_MAXN][3] = {{0}};
    int undefined = 0;
    e_gather(c, nn, x, xe);
    for (int q = 0; q < nq && !undefined; q++) {
      double G[HE_MAXN][3], F[9], P[9];
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      undefined = HE_MAT(stress)(p, F, P, NULL);
      if (!undefined) e_add_force(P, G, nn, g[9], fe);
    }
    if (undefined) { bad++; continue; }
    e_scatter(c, nn, fe, f);
  }
  return bad;
}

/* Elastic energy sum_e sum_q w psi(F_q) (Kahan-compensated, as the P1 loop), min/max of det F over the
 * points. Returns the number of cells where the material is undefined (their energy is left out). */
int64_t HE_EFN(energy)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                       const double *x, const double *restrict prm, double *out /* [energy, Jmin, Jmax] */) {
  HE_PARAMS(p);
  int64_t bad = 0;
  double W = 0, comp = 0, jmin = INFINITY, jmax = -INFINITY;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double xe[HE_MAXN][3], cell = 0;
    int undefined = 0;
    e_gather(cells + (int64_t)nn * e, nn, x, xe);
    for (int q = 0; q < nq; q++) {
      double G[HE_MAXN][3], F[9], P[9], psi;
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      he_jrange(det3(F), &jmin, &jmax);
      if (HE_MAT(stress)(p, F, P, &psi)) undefined = 1;
      else cell += g[9] * psi;
    }
    if (undefined) { bad++; continue; }
    he_kahan_add(&W, &comp, cell);
  }
  out[0] = W; out[1] = jmin; out[2] = jmax;
  return bad;
}

/* y += K(x) v without assembling. */
int64_t HE_EFN(kv)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                   const double *x, const double *restrict prm, const double *v, double *y) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], ve[HE_MAXN][3], ye[HE_MAXN][3] = {{0}};
    int undefined = 0;
    e_gather(c, nn, x, xe);
    e_gather(c, nn, v, ve);
    for (int q = 0; q < nq && !undefined; q++) {
      double G[HE_MAXN][3], F[9], dF[9], dP[9];
      HE_MAT(cache) d;
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      undefined = HE_MAT(prepare)(p, F, &d);
      if (undefined) break;
      e_deformation(ve, G, nn, dF);
      HE_MAT(dstress)(p, &d, dF, dP);
      e_add_force(dP, G, nn, g[9], ye);
    }
    if (undefined) { bad++; continue; }
    e_scatter(c, nn, ye, y);
  }
  return bad;
}

/* Cell tangents, (3 nn)^2 values per cell, row-major over dofs (3a+i, 3b+k): K_ai,bk = sum over the points of
 * sum_jl G_a,j A_ijkl G_b,l (A = w dP/dF, HE_EFN(moduli)). A hyperelastic tangent is symmetric (A_ijkl = A_klij):
 * the blocks b >= a are summed and mirrored. Written, or added to vals when accumulate != 0. A cell where the
 * material is undefined gets NaN. */
int64_t HE_EFN(tangent)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                        const double *x, const double *restrict prm, double *vals, int accumulate) {
  HE_PARAMS(p);
  const int n3 = 3 * nn;
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double xe[HE_MAXN][3], Ke[3 * HE_MAXN * 3 * HE_MAXN];
    double *K = vals + (int64_t)n3 * n3 * e;
    int undefined = 0;
    for (int r = 0; r < n3 * n3; r++) Ke[r] = 0;
    e_gather(cells + (int64_t)nn * e, nn, x, xe);
    for (int q = 0; q < nq && !undefined; q++) {
      double G[HE_MAXN][3], F[9], A[9][9], T[HE_MAXN][3][9];
      HE_MAT(cache) d;
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      undefined = HE_MAT(prepare)(p, F, &d);
      if (undefined) break;
      HE_EFN(moduli)(p, &d, g[9], A);
      e_contract_left(A, G, nn, T);
      for (int a = 0; a < nn; a++)
        for (int b = a; b < nn; b++)
          for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
              Ke[n3 * (3 * a + i) + 3 * b + k] +=
                  T[a][i][3 * k] * G[b][0] + T[a][i][3 * k + 1] * G[b][1] + T[a][i][3 * k + 2] * G[b][2];
    }
    if (undefined) {
      for (int r = 0; r < n3 * n3; r++) K[r] = NAN;
      bad++;
      continue;
    }
    for (int r = 0; r < n3; r++)
      for (int c = 0; c < 3 * (r / 3); c++) Ke[n3 * r + c] = Ke[n3 * c + r];
    if (accumulate)
      for (int r = 0; r < n3 * n3; r++) K[r] += Ke[r];
    else
      for (int r = 0; r < n3 * n3; r++) K[r] = Ke[r];
  }
  return bad;
}

/* diag += diagonal of K(x) */
int64_t HE_EFN(tangent_diag)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                             const double *x, const double *restrict prm, double *diag) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], de[HE_MAXN][3] = {{0}};
    int undefined = 0;
    e_gather(c, nn, x, xe);
    for (int q = 0; q < nq && !undefined; q++) {
      double G[HE_MAXN][3], F[9];
      HE_MAT(cache) d;
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      undefined = HE_MAT(prepare)(p, F, &d);
      if (undefined) break;
      double A[9][9];
      HE_EFN(moduli)(p, &d, g[9], A);
      for (int b = 0; b < nn; b++)
        for (int k = 0; k < 3; k++)
          for (int j = 0; j < 3; j++)
            de[b][k] += G[b][j] * (A[3 * k + j][3 * k] * G[b][0] + A[3 * k + j][3 * k + 1] * G[b][1] +
                                   A[3 * k + j][3 * k + 2] * G[b][2]);
    }
    if (undefined) { bad++; continue; }
    e_scatter(c, nn, de, diag);
  }
  return bad;
}

/* f += the energy-momentum (discrete-gradient) force of the midpoint step from xn to x1 = 2 x - xn, point by
 * point: at each quadrature point F is linear in the positions, so the P1 construction (_material_loops.h,
 * forces_dg) applies to F_q(xn), F_q(x1) and the force's work over the step is sum_q w (psi(F1_q) -
 * psi(Fn_q)) exactly. Returns the number of cells where the material is undefined at xn or x1. */
int64_t HE_EFN(forces_dg)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                          const double *x, const double *restrict prm, const double *xn, double *f) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    const idx_t *c = cells + (int64_t)nn * e;
    double xe[HE_MAXN][3], xne[HE_MAXN][3], fe[HE_MAXN][3] = {{0}};
    int undefined = 0;
    e_gather(c, nn, x, xe);
    e_gather(c, nn, xn, xne);
    for (int q = 0; q < nq && !undefined; q++) {
      double G[HE_MAXN][3], F[9], Fn[9], P[9];
      const double *g = e_point(geo, dN, e, q, nn, nq, xe, G, F);
      e_deformation(xne, G, nn, Fn);
      undefined = HE_FN(point_dg)(p, F, Fn, P);
      if (!undefined) e_add_force(P, G, nn, g[9], fe);
    }
    if (undefined) { bad++; continue; }
    e_scatter(c, nn, fe, f);
  }
  return bad;
}

/* S = F^-1 P(F) at each point of the stiffness rule (nc x nq x 9; NaN where the material is undefined).
 * Returns the number of points where it is. */
int64_t HE_EFN(pk2)(int64_t nc, int nn, int nq, const idx_t *cells, const double *dN, const double *geo,
                    const double *x, const double *restrict prm, double *S) {
  HE_PARAMS(p);
  int64_t bad = 0;
  for (int64_t e = 0; e < nc; e++) {
    HE_CELL_PARAMS(e);
    double xe[HE_MAXN][3];
    e_gather(cells + (int64_t)nn * e, nn, x, xe);
    for (int q = 0; q < nq; q++) {
      double G[HE_MAXN][3], F[9], P[9];
      int undefined;
      e_point(geo, dN, e, q, nn, nq, xe, G, F);
      undefined = HE_MAT(stress)(p, F, P, NULL);
      bad += undefined != 0;
      pk2_of(F, P, undefined, S + 9 * ((int64_t)nq * e + q));
    }
  }
  return bad;
}

#undef HE_EFN
