/* Arruda and Boyce's eight-chain model (J. Mech. Phys. Solids 41, 1993) with the isochoric/volumetric split:
 * constants (mu_n, lambda_m, w0, kappa), W = mu_n lambda_m^2 (r beta + ln(beta / sinh beta) - w0), r = sqrt(I1_bar / 3)
 * / lambda_m < 1, beta = L^-1(r), L(b) = coth b - 1/b; W' = mu_n lambda_m beta / (2 q), q = sqrt(3 I1_bar), W'' =
 * mu_n / (4 q^2) (1/L'(beta) - 3 lambda_m beta / q). The stress and its derivative those of _i1.h. Undefined for
 * J <= 0 and at the locking stretch r >= 1. Numpy reference: arruda_boyce.py (the series' coefficients there). */
#include "_i1.h"

/* L(b), L'(b) and ln(b / sinh b), b > 0: their series below 0.3, where the closed forms lose digits. */
HE_INLINE void langevin(double b, double *L, double *dL, double *lnb) {
  static const double c[8] = {1.0 / 3, -1.0 / 45, 2.0 / 945, -1.0 / 4725, 2.0 / 93555, -1382.0 / 638512875,
                              4.0 / 18243225, -3617.0 / 162820783125};
  if (b < 0.3) {
    const double x2 = b * b;
    double l = 0, d = 0, g = 0;
    for (int n = 7; n >= 0; n--) {
      l = l * x2 + c[n];
      d = d * x2 + c[n] * (2 * n + 1);
      g = g * x2 + c[n] / (2 * n + 2);
    }
    *L = b * l;
    *dL = d;
    *lnb = -x2 * g;
    return;
  }
  const double sh = sinh(b);
  *L = 1 / tanh(b) - 1 / b;
  *dL = 1 / (b * b) - 1 / (sh * sh);
  *lnb = log(2 * b) - b - log1p(-exp(-2 * b));
}

/* beta = L^-1(r), 0 < r < 1: Newton's iteration from Cohen's Pade approximation r (3 - r^2) / (1 - r^2) (Rheol. Acta
 * 30, 1991), to a step below 1e-8 beta (converging quadratically, the next would be below round-off: 1-4 steps);
 * L, L' and ln(beta / sinh beta) at the root. */
HE_INLINE double inverse_langevin(double r, double *L, double *dL, double *lnb) {
  double b = r * (3 - r * r) / (1 - r * r);
  for (int it = 0; it < 20; it++) {
    langevin(b, L, dL, lnb);
    const double step = (*L - r) / *dL;
    b -= step;
    if (fabs(step) <= 1e-8 * b) break;
  }
  langevin(b, L, dL, lnb);
  return b;
}

HE_INLINE int arruda_boyce_w(const double *prm, double s, double *w, double *w1, double *w2) {
  const double mun = prm[0], lm = prm[1], w0 = prm[2];
  const double q = sqrt(3 * (s + 3)), r = q / (3 * lm);
  if (!(r < 1)) return 1;
  double L, dL, lnb;
  const double b = inverse_langevin(r, &L, &dL, &lnb);
  *w = mun * lm * lm * (r * b + lnb - w0);
  *w1 = mun * lm * b / (2 * q);
  *w2 = mun / (4 * q * q) * (1 / dL - 3 * lm * b / q);
  return 0;
}

HE_I1_MATERIAL(arruda_boyce, 3)
