/* Arruda and Boyce's eight-chain model (J. Mech. Phys. Solids 41, 1993) with the isochoric/volumetric split:
 * constants (mu_n, lambda_m, w0, kappa), W = mu_n lambda_m^2 (r beta + ln(beta / sinh beta) - w0), r = sqrt(I1_bar / 3)
 * / lambda_m < 1, beta = L^-1(r), L(b) = coth b - 1/b; W' = mu_n lambda_m beta / (2 q), q = sqrt(3 I1_bar), W'' =
 * mu_n / (4 q^2) (1/L'(beta) - 3 lambda_m beta / q). The stress and its derivative those of _i1.h. Undefined for
 * J <= 0 and at the locking stretch r >= 1. Numpy reference: arruda_boyce.py (the series' coefficients there). */
#include "_i1.h"

static const double LANGEVIN_SERIES[8] = {1.0 / 3, -1.0 / 45, 2.0 / 945, -1.0 / 4725, 2.0 / 93555, -1382.0 / 638512875,
                                          4.0 / 18243225, -3617.0 / 162820783125};

/* L(b), L'(b) and L''(b), b > 0: their series below 0.3, where the closed forms lose digits; above, with e =
 * exp(-2b) and z = 1/(1 - e), coth b = (1 + e) z, 1/sinh^2 b = 4 e z^2 (one exponential). */
HE_INLINE void langevin(double b, double *L, double *dL, double *d2L) {
  if (b < 0.3) {
    const double x2 = b * b;
    double l = 0, d = 0, d2 = 0;
    for (int n = 7; n >= 0; n--) {
      l = l * x2 + LANGEVIN_SERIES[n];
      d = d * x2 + LANGEVIN_SERIES[n] * (2 * n + 1);
      d2 = d2 * x2 + LANGEVIN_SERIES[n] * (2 * n + 1) * (2 * n);
    }
    *L = b * l;
    *dL = d;
    *d2L = d2 / b;
    return;
  }
  const double e = exp(-2 * b), z = 1 / (1 - e), cth = (1 + e) * z, csh2 = 4 * e * z * z;
  *L = cth - 1 / b;
  *dL = 1 / (b * b) - csh2;
  *d2L = 2 * csh2 * cth - 2 / (b * b * b);
}

/* ln(b / sinh b): its series below 0.3 (sum_n C_n b^(2n) / (2n), the integral of L's), else ln(2b) - b -
 * ln(1 - exp(-2b)). */
HE_INLINE double log_b_over_sinh(double b) {
  if (b < 0.3) {
    const double x2 = b * b;
    double g = 0;
    for (int n = 7; n >= 0; n--) g = g * x2 + LANGEVIN_SERIES[n] / (2 * n + 2);
    return -x2 * g;
  }
  return log(2 * b) - b - log1p(-exp(-2 * b));
}

/* beta = L^-1(r), 0 < r < 1: Newton's iteration from Cohen's Pade approximation r (3 - r^2) / (1 - r^2) (Rheol. Acta
 * 30, 1991), to a step d below 1e-8 beta (converging quadratically: the root to round-off; 1-4 steps), and L' at the
 * root as L'(b) - L''(b) d (its error O(d^2): round-off). */
HE_INLINE double inverse_langevin(double r, double *dL) {
  double b = r * (3 - r * r) / (1 - r * r), L, d2L;
  for (int it = 0; it < 20; it++) {
    langevin(b, &L, dL, &d2L);
    const double step = (L - r) / *dL;
    b -= step;
    if (fabs(step) <= 1e-8 * b) {
      *dL -= d2L * step;
      break;
    }
  }
  return b;
}

HE_INLINE int arruda_boyce_w(const double *prm, double s, double *w, double *w1, double *w2) {
  const double mun = prm[0], lm = prm[1], w0 = prm[2];
  const double q = sqrt(3 * (s + 3)), r = q / (3 * lm);
  if (!(r < 1)) return 1;
  double dL;
  const double b = inverse_langevin(r, &dL);
  if (w) *w = mun * lm * lm * (r * b + log_b_over_sinh(b) - w0);
  *w1 = mun * lm * b / (2 * q);
  *w2 = mun / (4 * q * q) * (1 / dL - 3 * lm * b / q);
  return 0;
}

#define arruda_boyce_CELL_TANGENT 1
HE_I1_MATERIAL(arruda_boyce, 3)
