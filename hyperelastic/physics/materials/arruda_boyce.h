/* Arruda and Boyce's eight-chain model (J. Mech. Phys. Solids 41, 1993) with the isochoric/volumetric split:
 * constants (mu_n, lambda_m, w0, kappa), W = mu_n lambda_m^2 (r beta + ln(beta / sinh beta) - w0), r = sqrt(I1_bar / 3)
 * / lambda_m < 1, beta = L^-1(r), L(b) = coth b - 1/b; W' = mu_n lambda_m beta / (2 q), q = sqrt(3 I1_bar), W'' =
 * mu_n / (4 q^2) (1/L'(beta) - 3 lambda_m beta / q) (six divisions a point). The stress and its derivative those of
 * _i1.h. Undefined for J <= 0 and at the locking stretch r >= 1. Numpy reference: arruda_boyce.py (the series'
 * coefficients there). */
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
  const double e = exp(-2 * b), z = 1 / (1 - e), ib = 1 / b, cth = (1 + e) * z, csh2 = 4 * e * z * z;
  *L = cth - ib;
  *dL = ib * ib - csh2;
  *d2L = 2 * (csh2 * cth - ib * ib * ib);
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

/* The start of the iteration below: g(r) = L^-1(r) (1 - r)/r (smooth on [0, 1], g(0) = 3, g(1) = 1) by Chebyshev series
 * on seven pieces of r, fitted to the inverse to round-off by scripts/fit_inverse_langevin.py, which prints this table
 * and the largest relative error of beta on each piece. */
static const double INVLANGEVIN_EDGES[8] = {0.0, 0.25, 0.5, 0.7, 0.8, 0.9, 0.97, 1.0};
static const double INVLANGEVIN_CHEB[7][11] = {
  {2.6598822520489378, -0.32957819320679271, 0.0099339799963028518, -0.00057420064980865943,
   2.9721056158675409e-05, -1.5486186309327873e-06, 9.9526657614723893e-08, -4.5351859861576406e-09,
   3.4664002549909195e-10, -1.353746398339403e-11, 1.205671330628168e-12},
  {2.0629811731186569, -0.27122836298522468, 0.0052247556200740114, -0.00024012247599369528,
   1.8001531845923228e-05, 4.1750983549330857e-07, 1.1437238482873268e-07, 7.3001429153428058e-09,
   6.9380665494690389e-10, 3.7828077018575557e-11, 1.1716080892454801e-12},
  {1.6032804795369437, -0.19060397472112517, 0.0029722011397305573, 0.00012635831218325513,
   2.7641542890420957e-05, 2.0329342583553507e-06, 6.5528212803222488e-08, -1.7448520352482238e-08,
   -4.5780980531065557e-09, -6.9141797943255935e-10, -7.3427108099723237e-11},
  {1.3311507092846819, -0.083252593838662917, 0.0014664615754719145, 6.5714519851792745e-05,
   3.3252429762739941e-07, -4.4030747903068961e-07, -4.2193063185664159e-08, -2.9978461630701801e-10,
   4.0555944368194126e-10, 5.4483432409530749e-11, 2.5747053554880095e-12},
  {1.1783652114853873, -0.069145294741331048, 0.001912597614207291, -1.4776488249103083e-05,
   -7.3185012705330963e-06, 5.4461762141954486e-07, 1.1605907109631244e-07, -1.1721631184884961e-08,
   -3.229632016142722e-09, 1.0551480023625612e-10, 9.480380982139714e-11},
  {1.0702688248534826, -0.040077570744168955, 0.00075036767772700141, -1.4042073901635322e-05,
   2.5860819883608281e-07, -2.6503721223637511e-09, -8.7635041801993143e-10, 3.292395106741225e-10,
   -8.4017667369780626e-11, 1.3057634787146274e-11, 2.5869784848742383e-13},
  {1.0153461651336109, -0.015463020881981874, 0.00011774556450576095, -8.9659182874663934e-07,
   6.8272234922692252e-09, -5.1999217185032485e-11, 3.8281568248366406e-13, -1.2981854889145713e-14,
   -1.1149578623188511e-14, -6.7604854032765231e-15, -7.8127947472010651e-15},
};
/* largest relative error of beta per piece: 4.8e-14, 4.5e-13, 7.1e-12, 8.6e-13, 1.9e-11, 2.0e-12, 5.1e-12 */

HE_INLINE double inverse_langevin_start(double r) {
  int k = 0;
  while (k < 6 && r >= INVLANGEVIN_EDGES[k + 1]) k++;
  const double lo = INVLANGEVIN_EDGES[k], hi = INVLANGEVIN_EDGES[k + 1];
  const double t = (2 * r - lo - hi) * (1 / (hi - lo));      /* (a constant per piece: folded by the compiler) */
  const double *c = INVLANGEVIN_CHEB[k];
  double b1 = 0, b2 = 0;                     /* Clenshaw's recurrence */
  for (int j = 10; j >= 1; j--) {
    const double b0 = 2 * t * b1 - b2 + c[j];
    b2 = b1, b1 = b0;
  }
  return (c[0] + t * b1 - b2) * r / (1 - r);
}

/* beta = L^-1(r), 0 < r < 1: Newton's iteration from inverse_langevin_start (within 2e-11), to a step d below 1e-8 beta
 * (quadratic convergence: the root to round-off; one step), and 1/L' at the root from L'(b) - L''(b) d, to first order
 * in d (the error O(d^2): round-off; no division more). */
HE_INLINE double inverse_langevin(double r, double *idL) {
  double b = inverse_langevin_start(r), L, dL, d2L;
  for (int it = 0; it < 20; it++) {
    langevin(b, &L, &dL, &d2L);
    *idL = 1 / dL;
    const double step = (L - r) * *idL;
    b -= step;
    if (fabs(step) <= 1e-8 * b) {
      *idL *= 1 + d2L * step * *idL;
      break;
    }
  }
  return b;
}

HE_INLINE int arruda_boyce_w(const double *prm, double s, double *w, double *w1, double *w2) {
  const double mun = prm[0], lm = prm[1], w0 = prm[2];
  const double q = sqrt(3 * (s + 3)), r = q / (3 * lm);
  if (!(r < 1)) return 1;
  double idL;
  const double b = inverse_langevin(r, &idL), iq = 1 / q;
  if (w) *w = mun * lm * lm * (r * b + log_b_over_sinh(b) - w0);
  *w1 = 0.5 * mun * lm * b * iq;
  *w2 = 0.25 * mun * iq * iq * (idL - 3 * lm * b * iq);
  return 0;
}

#define arruda_boyce_CELL_TANGENT 1
HE_I1_MATERIAL(arruda_boyce, 3)
