/* test_optics.c — numerical checks of shaders/optics.h as C (float; test_optics_double.c includes this
 * file with OCG_REAL_DOUBLE defined and runs the same checks in double).
 *
 * Every tolerance below is stated in units of EPS, the machine epsilon of the precision under test,
 * or derived from a stated error model; the worst errors are printed so docs/numerics.md can quote them.
 * References are computed in long double (x87 80-bit on x86-64) with expm1l/expl.
 *
 * OC_TABLE_OUT=path: also write the integrator comparison table (Markdown) to that file. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include "report.h"

#include <float.h>  /* FLT_EPSILON, DBL_EPSILON */
#include <math.h>   /* expm1l, isfinite */
#include <stdio.h>  /* printf, fopen */
#include <stdlib.h> /* getenv */
#include <string.h> /* strlen */

#include "optics.h" /* the header under test (shaders/ is on oc_common's include path) */
#include "march.h"  /* ocg_cloud_shadow: the cloud's shadow with its diffuse transmission */

#if defined(OCG_REAL_DOUBLE)
#define EPS ((long double)DBL_EPSILON)
#define REAL_MIN ((long double)DBL_MIN)
#define PREC "double"
#else
#define EPS ((long double)FLT_EPSILON)
#define REAL_MIN ((long double)FLT_MIN)
#define PREC "float"
#endif
typedef long double ld;
#define PI_L 3.141592653589793238462643383279502884L

static ld rel_err(ld got, ld want) {
  if (want == 0) return fabsl(got);
  return fabsl(got - want) / fabsl(want);
}

/* ---- Phase functions ------------------------------------------------------------------------------ */

typedef ocg_real (*phase_fn)(ocg_real mu, ocg_real g);

static ocg_real ph_hg(ocg_real mu, ocg_real g) { return ocg_phase_hg(mu, g); }
static ocg_real ph_rayleigh(ocg_real mu, ocg_real g) { (void)g; return ocg_phase_rayleigh(mu); }
static ocg_real ph_cs(ocg_real mu, ocg_real g) { return ocg_phase_cornette_shanks(mu, g); }
static ocg_real ph_draine0(ocg_real mu, ocg_real g) { return ocg_phase_draine(mu, g, OCG_R(0.0)); }
static ocg_real ph_draine_hgd(ocg_real mu, ocg_real g) { return ocg_phase_draine(mu, g, OCG_HGD_ALPHA); }
static ocg_real ph_draine100(ocg_real mu, ocg_real g) { return ocg_phase_draine(mu, g, OCG_R(100.0)); }
/* HG+Draine: the "g" argument is the asymmetry of the sharper (HG) lobe, g_HG * gscale; only g >= 0. */
static ocg_real ph_hgd(ocg_real mu, ocg_real g) {
  return ocg_phase_hg_draine_scaled(mu, (ocg_real)((ld)g / (ld)OCG_HGD_G_HG));
}

/* Integral of p over the sphere, 2 pi \int_{-1}^{1} p(mu) dmu, by composite Simpson in the variable
 * s = ln(1 + g^2 - 2 g mu): the HG factor (1 + g^2 - 2 g mu)^{-3/2} times the Jacobian
 * dmu/ds = -e^s / (2g) becomes e^{-s/2}, smooth over s in [2 ln(1-|g|), 2 ln(1+|g|)] (width 15.2 at
 * g = 0.999), so the forward peak is resolved (about 500 nodes per float cell of mu at the peak). mu is
 * computed in long double and rounded to ocg_real, so in float the result is the integral of what a
 * float renderer evaluates, mu-quantisation included. |g| < 1e-3: Simpson in mu directly. */
static ld sphere_integral(phase_fn p, ld g) {
  const int m = 1 << 16; /* even */
  ld sum = 0;
  if (fabsl(g) < 1e-3L) {
    ld h = 2.0L / m;
    for (int i = 0; i <= m; ++i) {
      ld mu = -1.0L + h * i;
      ld w = (i == 0 || i == m) ? 1 : (i % 2 ? 4 : 2);
      sum += w * (ld)p((ocg_real)mu, (ocg_real)g);
    }
    return 2.0L * PI_L * sum * h / 3.0L;
  }
  ld ag = fabsl(g);
  ld s0 = 2.0L * logl(1.0L - ag), s1 = 2.0L * logl(1.0L + ag);
  ld h = (s1 - s0) / m;
  for (int i = 0; i <= m; ++i) {
    ld s = s0 + h * i;
    ld es = expl(s);
    ld mu = (1.0L + g * g - es) / (2.0L * g);
    if (i == 0) mu = g > 0 ? 1.0L : -1.0L; /* exact ends: the peak */
    if (i == m) mu = g > 0 ? -1.0L : 1.0L;
    mu = fminl(1.0L, fmaxl(-1.0L, mu));
    ld w = (i == 0 || i == m) ? 1 : (i % 2 ? 4 : 2);
    sum += w * (ld)p((ocg_real)mu, (ocg_real)g) * es / (2.0L * ag);
  }
  return 2.0L * PI_L * sum * h / 3.0L;
}

static const double g_grid[] = {-0.999, -0.995, -0.99, -0.95, -0.9, -0.75, -0.5, -0.25, -0.1, -1e-4, 0.0,
                                1e-4,   0.1,    0.25,  0.5,   0.75, 0.9,   0.95, 0.99, 0.995, 0.999};
#define N_G (sizeof g_grid / sizeof g_grid[0])

/* Tolerance on |integral - 1|. double: quadrature error only. float: the mu-quantisation described in
 * sphere_integral grows like ((1-g)^2 / 2^-24)^-2 near |g| = 1, so the bound is per |g| band. */
static ld norm_tol(ld g) {
#if defined(OCG_REAL_DOUBLE)
  (void)g;
  return 1e-9L;
#else
  ld ag = fabsl(g);
  if (ag <= 0.95L) return 3e-7L;
  if (ag <= 0.99L) return 1e-5L;
  return 2e-3L; /* measured 8.9e-4 at |g| = 0.999: the peak is 8 float cells of mu wide */
#endif
}

static void check_normalised(const char *name, phase_fn p, ld gmin, ld gmax, ld *worst_out) {
  ld worst = 0, worst_g = 0;
  for (size_t i = 0; i < N_G; ++i) {
    ld g = g_grid[i];
    if (g < gmin || g > gmax) continue;
    ld integral = sphere_integral(p, g);
    ld err = fabsl(integral - 1.0L);
    if (err > worst) worst = err, worst_g = g;
    if (!(err <= norm_tol(g))) {
      printf("  %s g=%.4Lg: integral %.12Lg, |err| %.3Lg > tol %.3Lg\n", name, g, integral, err, norm_tol(g));
      fail_msg("%s not normalised at g=%.4Lg", name, g);
    }
  }
  printf("  %-28s worst |int - 1| = %.3Le at g = %+.3Lf\n", name, worst, worst_g);
  {
    char what[128];
    snprintf(what, sizeof what, "%s integrates to 1, g in [%.4Lg, %.4Lg] (%s)", name, gmin, gmax, PREC);
    oc_report("phase", what, (double)worst, (double)norm_tol(gmax > -gmin ? gmax : -gmin) * 1.0000001, "");
  }
  if (worst_out) *worst_out = worst;
}

static void test_phase__normalised_over_sphere(void **state) {
  (void)state;
  printf("[" PREC "] phase normalisation, g in [-0.999, 0.999] (%zu values), Simpson in ln(1+g^2-2g mu):\n", N_G);
  check_normalised("HG", ph_hg, -1, 1, NULL);
  check_normalised("Rayleigh", ph_rayleigh, 0, 0, NULL);
  check_normalised("Cornette-Shanks", ph_cs, -1, 1, NULL);
  check_normalised("Draine alpha=0", ph_draine0, -1, 1, NULL);
  check_normalised("Draine alpha=21.9955", ph_draine_hgd, -1, 1, NULL);
  check_normalised("Draine alpha=100", ph_draine100, -1, 1, NULL);
  /* HG+Draine at gscale = g / g_HG for every grid g in [0, g_HG]: the octave lobes c^i. */
  check_normalised("HG+Draine (scaled)", ph_hgd, 0, (ld)OCG_HGD_G_HG, NULL);
  /* The d = 10 µm lobe itself (gscale 1). */
  ld one = sphere_integral(ph_hgd, (ld)OCG_HGD_G_HG);
  printf("  %-28s |int - 1| = %.3Le (gscale 1)\n", "HG+Draine d=10um", fabsl(one - 1.0L));
  assert_true(fabsl(one - 1.0L) <= norm_tol(0.99L));
}

static void test_phase__finite_at_poles_and_outside_domain(void **state) {
  (void)state;
  const ocg_real mus[] = {OCG_R(-1.0), OCG_R(1.0), OCG_R(-1.0000001), OCG_R(1.0000001), OCG_R(-2.0), OCG_R(2.0),
                          OCG_R(0.0)};
  for (size_t i = 0; i < N_G; ++i) {
    ocg_real g = (ocg_real)g_grid[i];
    for (size_t j = 0; j < sizeof mus / sizeof mus[0]; ++j) {
      ocg_real mu = mus[j];
      ocg_real v[] = {ocg_phase_hg(mu, g), ocg_phase_cornette_shanks(mu, g), ocg_phase_draine(mu, g, OCG_HGD_ALPHA),
                      ocg_phase_rayleigh(mu), ocg_phase_hg_draine(mu),
                      ocg_phase_hg_draine_scaled(mu, (ocg_real)fabs(g_grid[i]))};
      for (size_t k = 0; k < sizeof v / sizeof v[0]; ++k) {
        if (!(isfinite(v[k]) && v[k] > 0)) fail_msg("phase %zu not finite/positive at mu=%g g=%g", k, (double)mu, (double)g);
      }
    }
    /* Clamping: outside [-1, 1] equals the pole. */
    assert_true(ocg_phase_hg(OCG_R(1.5), g) == ocg_phase_hg(OCG_R(1.0), g));
    assert_true(ocg_phase_hg(OCG_R(-1.5), g) == ocg_phase_hg(OCG_R(-1.0), g));
  }
  /* Closed forms at the poles: HG(1, g) = (1+g)/(4 pi (1-g)^2). */
  for (size_t i = 0; i < N_G; ++i) {
    ld g = (ld)(ocg_real)g_grid[i];
    ld want = (1 + g) / (4 * PI_L * (1 - g) * (1 - g));
    assert_true(rel_err((ld)ocg_phase_hg(OCG_R(1.0), (ocg_real)g), want) <= 8 * EPS);
    want = (1 - g) / (4 * PI_L * (1 + g) * (1 + g));
    assert_true(rel_err((ld)ocg_phase_hg(OCG_R(-1.0), (ocg_real)g), want) <= 8 * EPS);
  }
  printf("[" PREC "] HG+Draine: p(1) = %.6g, p(0) = %.6g, p(-1) = %.6g sr^-1\n", (double)ocg_phase_hg_draine(OCG_R(1.0)),
         (double)ocg_phase_hg_draine(OCG_R(0.0)), (double)ocg_phase_hg_draine(OCG_R(-1.0)));
}

static void test_phase__special_cases_agree(void **state) {
  (void)state;
  assert_true(rel_err((ld)ocg_phase_hg(OCG_R(0.3), OCG_R(0.0)), 1.0L / (4 * PI_L)) <= 2 * EPS);
  assert_true(rel_err((ld)ocg_phase_rayleigh(OCG_R(0.0)), 3.0L / (16 * PI_L)) <= 2 * EPS);
  assert_true(rel_err((ld)ocg_phase_rayleigh(OCG_R(1.0)), 6.0L / (16 * PI_L)) <= 2 * EPS);
  for (int i = -10; i <= 10; ++i) {
    ocg_real mu = (ocg_real)(i / 10.0);
    for (size_t k = 0; k < N_G; ++k) {
      ocg_real g = (ocg_real)g_grid[k];
      /* Draine(alpha = 0) is HG; Draine(alpha = 1) is Cornette-Shanks. */
      assert_true(rel_err((ld)ocg_phase_draine(mu, g, OCG_R(0.0)), (ld)ocg_phase_hg(mu, g)) <= 2 * EPS);
      assert_true(rel_err((ld)ocg_phase_draine(mu, g, OCG_R(1.0)), (ld)ocg_phase_cornette_shanks(mu, g)) <= 8 * EPS);
      /* Against a long double evaluation of the textbook forms. */
      /* q without cancellation: the long double textbook 1 + g^2 - 2 g mu loses 20 bits at g = 0.999. */
      ld G = (ld)g, M = (ld)mu, q = G >= 0 ? (1 - G) * (1 - G) + 2 * G * (1 - M) : (1 + G) * (1 + G) - 2 * G * (1 + M);
      ld hg = (1 - G * G) / (4 * PI_L * powl(q, 1.5L));
      ld cs = 3 * (1 - G * G) * (1 + M * M) / (8 * PI_L * (2 + G * G) * powl(q, 1.5L));
      assert_true(rel_err((ld)ocg_phase_hg(mu, g), hg) <= 8 * EPS);
      assert_true(rel_err((ld)ocg_phase_cornette_shanks(mu, g), cs) <= 16 * EPS);
    }
  }
}

static void test_phase__hgd_constants_match_formulas(void **state) {
  (void)state;
  const ld d = 10.0L;
  ld g_hg = expl(-0.0990567L / (d - 1.67154L));
  ld g_d = expl(-2.20679L / (d + 3.91029L) - 0.428934L);
  ld alpha = expl(3.62489L - 8.29288L / (d + 5.52825L));
  ld w = expl(-0.599085L / (d - 0.641583L) - 0.664888L);
  printf("[" PREC "] HG+D d=10um: g_hg %.6Lf g_d %.6Lf alpha %.5Lf w %.6Lf\n", g_hg, g_d, alpha, w);
  assert_true(rel_err((ld)OCG_HGD_G_HG, g_hg) <= fmaxl(EPS, 1e-14L));
  assert_true(rel_err((ld)OCG_HGD_G_D, g_d) <= fmaxl(EPS, 1e-14L));
  assert_true(rel_err((ld)OCG_HGD_ALPHA, alpha) <= fmaxl(EPS, 1e-14L));
  assert_true(rel_err((ld)OCG_HGD_W, w) <= fmaxl(EPS, 1e-14L));
  /* design.md rounds them to 5 digits. */
  assert_true(fabsl(g_hg - 0.98818L) < 1e-5L && fabsl(g_d - 0.55567L) < 1e-5L);
  assert_true(fabsl(alpha - 21.9955L) < 1e-4L && fabsl(w - 0.48244L) < 1e-5L);
}

/* ---- Segment weight --------------------------------------------------------------------------------- */

static const double sigma_list[] = {0.0, 1e-12, 1e-6, 1e-3, 1.0, 1e3, 1e9};
#define N_SIGMA (sizeof sigma_list / sizeof sigma_list[0])

static ld ref_weight(ocg_real s, ocg_real d) {
  ld S = (ld)s, D = (ld)d;
  if (S == 0) return D;
  return -expm1l(-S * D) / S;
}

/* What the header would compute without the small-x series: (1 - e^{-x}) / sigma_t. */
static ocg_real naive_weight(ocg_real s, ocg_real d) { return (OCG_R(1.0) - ocg_exp(-s * d)) / s; }

/* Relative error bound of ocg_segment_weight in EPS: x = s d rounds (<= 0.5), the series or exp and
 * subtraction (<= 1.5), the final multiply/divide (<= 0.5), glibc exp within 1 ulp. */
#define W_TOL_EPS 3.0L

static void test_segment_weight__matches_expm1_reference(void **state) {
  (void)state;
  ld worst = 0;
  double worst_s = 0, worst_d = 0;
  /* The grid of the brief: sigma_t list x d = 1e-6 .. 1e7 (each decade and its half-decade). */
  for (size_t i = 0; i < N_SIGMA; ++i) {
    for (int e = -12; e <= 14; ++e) {
      ocg_real s = (ocg_real)sigma_list[i], d = (ocg_real)pow(10.0, e / 2.0);
      ocg_real w = ocg_segment_weight(s, d);
      ld err = rel_err((ld)w, ref_weight(s, d)) / EPS;
      assert_true(isfinite(w) && w >= 0);
      if (err > worst) worst = err, worst_s = (double)s, worst_d = (double)d;
      if (!(err <= W_TOL_EPS)) fail_msg("w(%g, %g) = %.9g, ref %.12Lg, err %.2Lf EPS", (double)s, (double)d, (double)w, ref_weight(s, d), err);
    }
  }
  /* Dense sweep of x = sigma_t d across the series threshold and beyond (sigma_t = 1 and 7.3). */
  for (int k = 0; k <= 20000; ++k) {
    ld x = powl(10.0L, -20.0L + 22.0L * k / 20000.0L);
    for (int j = 0; j < 2; ++j) {
      ocg_real s = j ? OCG_R(7.3) : OCG_R(1.0);
      ocg_real d = (ocg_real)(x / (ld)s);
      ld err = rel_err((ld)ocg_segment_weight(s, d), ref_weight(s, d)) / EPS;
      if (err > worst) worst = err, worst_s = (double)s, worst_d = (double)d;
      if (!(err <= W_TOL_EPS)) fail_msg("w(%g, %g) err %.2Lf EPS", (double)s, (double)d, err);
    }
  }
  printf("[" PREC "] segment weight: worst relative error %.3Lf EPS (sigma_t %g, d %g); tolerance %.1Lf EPS\n", worst,
         worst_s, worst_d, W_TOL_EPS);
  oc_report("integrator", "segment weight (1-e^-σd)/σ, σ 0..1e9, d 1e-6..1e7 m (" PREC ")", (double)worst, (double)W_TOL_EPS, "ulp");
  /* Vector form agrees per channel. */
  ocg_vec3 w3 = ocg_segment_weight3(ocg_v3(OCG_R(0.0), OCG_R(1e-12), OCG_R(1e9)), OCG_R(2.0));
  assert_true(w3.x == ocg_segment_weight(OCG_R(0.0), OCG_R(2.0)));
  assert_true(w3.y == ocg_segment_weight(OCG_R(1e-12), OCG_R(2.0)));
  assert_true(w3.z == ocg_segment_weight(OCG_R(1e9), OCG_R(2.0)));
}

/* Fails if the small-sigma_t series guard is removed from ocg_segment_weight (the naive quotient is
 * printed next to it to show why). */
static void test_segment_weight__series_guard_needed(void **state) {
  (void)state;
  struct { ocg_real s, d; } c[] = {{OCG_R(1e-12), OCG_R(1e-6)}, {OCG_R(1e-6), OCG_R(1e-3)}, {OCG_R(1e-4), OCG_R(1.0)},
                                   {OCG_R(1e-3), OCG_R(0.1)}};
  for (size_t i = 0; i < sizeof c / sizeof c[0]; ++i) {
    ocg_real w = ocg_segment_weight(c[i].s, c[i].d), nv = naive_weight(c[i].s, c[i].d);
    ld ref = ref_weight(c[i].s, c[i].d);
    printf("[" PREC "] sigma_t %g d %g: ref %.10Lg  guarded %.10g (%.2Lf EPS)  naive %.10g (rel err %.2Lg)\n",
           (double)c[i].s, (double)c[i].d, ref, (double)w, rel_err((ld)w, ref) / EPS, (double)nv, rel_err((ld)nv, ref));
    assert_true(rel_err((ld)w, ref) <= W_TOL_EPS * EPS);
    if (i == 0) {
      oc_report("integrator", "σt 1e-12, d 1e-6 m with the series guard (" PREC ")", (double)(rel_err((ld)w, ref) / EPS), (double)W_TOL_EPS, "ulp");
      oc_report_above("integrator", "same without the guard, naive (1-e^-σd)/σ: fails (" PREC ")", (double)rel_err((ld)nv, ref), 0.99, "rel");
    }
  }
  /* The naive form is 0 here in both precisions (e^{-1e-18} rounds to 1). */
  assert_true(naive_weight(OCG_R(1e-12), OCG_R(1e-6)) == OCG_R(0.0));
  /* sigma_t = 0: exactly d (the naive form would be 0/0). */
  assert_true(ocg_segment_weight(OCG_R(0.0), OCG_R(123.5)) == OCG_R(123.5));
  assert_true(isnan(naive_weight(OCG_R(0.0), OCG_R(1.0))));
  /* Huge sigma_t d: 1 / sigma_t. */
  assert_true(rel_err((ld)ocg_segment_weight(OCG_R(1e9), OCG_R(1e7)), 1e-9L) <= 2 * EPS);
  assert_true(ocg_transmittance(OCG_R(1e9), OCG_R(1e7)) == OCG_R(0.0));
  assert_true(ocg_transmittance(OCG_R(0.0), OCG_R(1e7)) == OCG_R(1.0));
}

/* ---- Segment integrator over N equal steps --------------------------------------------------------- */

/* March N equal steps of a homogeneous medium with sigma_s = sigma_t, S = 1 (design.md: add
 * T sigma_s S w, then T *= e^{-sigma_t d}). Returns S_N and T_N; fails on T outside [0, 1] or increasing. */
static void march_hillaire(ocg_real s, ocg_real d, long n, ocg_real *sum, ocg_real *t_out) {
  ocg_real t = OCG_R(1.0), acc = OCG_R(0.0);
  ocg_real w = ocg_segment_weight(s, d), tr = ocg_transmittance(s, d);
  for (long k = 0; k < n; ++k) {
    acc += t * s * w;
    ocg_real tn = t * tr;
    if (!(tn >= OCG_R(0.0) && tn <= t && t <= OCG_R(1.0))) fail_msg("T not in [0,1] or increasing at step %ld", k);
    t = tn;
  }
  *sum = acc;
  *t_out = t;
}

/* The same with optical depth accumulated and T = e^{-tau} (one exp per step either way). */
static void march_tau(ocg_real s, ocg_real d, long n, ocg_real *sum, ocg_real *t_out) {
  ocg_real tau = OCG_R(0.0), acc = OCG_R(0.0), x = s * d;
  ocg_real a = s * ocg_segment_weight(s, d);
  for (long k = 0; k < n; ++k) {
    acc += ocg_exp(-tau) * a;
    tau += x;
  }
  *sum = acc;
  *t_out = ocg_exp(-tau);
}

static void test_segment__telescopes_to_one_minus_exp(void **state) {
  (void)state;
  static const long n_list[] = {1, 3, 10, 32, 100, 316, 1000, 3162, 10000, 31623, 100000, 316228, 1000000};
  const int n_n = (int)(sizeof n_list / sizeof n_list[0]);
  printf("[" PREC "] N equal steps, sigma_s = sigma_t, S = 1: worst |S_N - (1 - e^-tau)| / (EPS max(ref, EPS)) over\n"
         "         sigma_t in {0,1e-12,1e-6,1e-3,1,1e3,1e9} x d in 1e-6..1e7; bound (3N+8)\n");
  printf("| N | T *= exp(-x) (design) | T = exp(-tau) | worst case at |\n|---:|---:|---:|---|\n");
  for (int in = 0; in < n_n; ++in) {
    long n = n_list[in];
    ld worst_a = 0, worst_b = 0;
    char where[96] = "";
    for (size_t i = 0; i < N_SIGMA; ++i) {
      for (int e = -6; e <= 7; ++e) {
        ocg_real s = (ocg_real)sigma_list[i], d = (ocg_real)pow(10.0, e);
        ocg_real sum, t;
        march_hillaire(s, d, n, &sum, &t);
        ld tau = (ld)s * (ld)d * (ld)n;
        ld ref_s = -expm1l(-tau), ref_t = expl(-tau);
        /* Error model: each exp, multiply and add within 1 ulp (3N + 8 for the sum of N positive terms, 2N + 2
         * for the product); x = sigma_t d rounded once (relative EPS/2) shifts T_N by tau EPS/2 relatively
         * and S_N by tau e^{-tau} EPS/2 absolutely; subnormal T adds an absolute REAL_MIN per step. */
        ld tol_s = (3.0L * n + 8.0L) * EPS * ref_s + 0.5L * EPS * tau * ref_t + 4.0L * n * REAL_MIN;
        ld tol_t = (2.0L * n + 2.0L + 0.5L * tau) * EPS * ref_t + 4.0L * n * REAL_MIN;
        ld es = fabsl((ld)sum - ref_s), et = fabsl((ld)t - ref_t);
        if (!(es <= tol_s)) fail_msg("N=%ld s=%g d=%g: S=%.9g ref %.12Lg (tol %.3Lg)", n, (double)s, (double)d, (double)sum, ref_s, tol_s);
        if (!(et <= tol_t)) fail_msg("N=%ld s=%g d=%g: T=%.9g ref %.12Lg (tol %.3Lg)", n, (double)s, (double)d, (double)t, ref_t, tol_t);
        /* Conservation: in-scattered plus transmitted is 1 (within the same rounding model). */
        if (!(fabsl((ld)sum + (ld)t - 1.0L) <= tol_s + tol_t + 2 * EPS)) fail_msg("S+T != 1 at N=%ld", n);
        ld ra = es / (EPS * fmaxl(ref_s, EPS));
        if (ra > worst_a) {
          worst_a = ra;
          snprintf(where, sizeof where, "sigma_t %g, d %g", (double)s, (double)d);
        }
        march_tau(s, d, n, &sum, &t);
        ld rb = fabsl((ld)sum - ref_s) / (EPS * fmaxl(ref_s, EPS));
        if (rb > worst_b) worst_b = rb;
      }
    }
    printf("| %ld | %.3Lg | %.3Lg | %s |\n", n, worst_a, worst_b, where);
  }
}

/* ---- Integration rules side by side ------------------------------------------------------------------ */

enum { RULE_HILLAIRE, RULE_LEFT, RULE_PALENIK, RULE_SIMPSON, RULE_COUNT };
static const char *const rule_name[RULE_COUNT] = {"Hillaire (energy-conserving)", "left Riemann",
                                                  "Páleník Alg. 1 (T first)", "Páleník Simpson (eq. 4.6/4.11)"};

/* Homogeneous medium of total optical depth tau split into n steps, sigma_s = sigma_t = 1, S = 1. */
static ld integrate_rule(int rule, ld tau, long n) {
  ocg_real s = OCG_R(1.0), d = (ocg_real)(tau / n), x = s * d;
  ocg_real t = OCG_R(1.0), acc = OCG_R(0.0), ext = ocg_exp(-x);
  switch (rule) {
  case RULE_HILLAIRE: /* add T sigma_s S w, then T *= e^{-x} */
    for (long k = 0; k < n; ++k) acc += t * s * ocg_segment_weight(s, d), t *= ext;
    break;
  case RULE_LEFT: /* add S sigma_s d T, then T *= e^{-x} */
    for (long k = 0; k < n; ++k) acc += s * d * t, t *= ext;
    break;
  case RULE_PALENIK: /* Páleník 2016, Algorithm 1: T *= ext first, then col = sigma p den I T dx */
    for (long k = 0; k < n; ++k) t *= ext, acc += s * t * d;
    break;
  case RULE_SIMPSON: /* Páleník eq. 4.10/4.11: trapezoid E_n, Simpson weights 1,4,2,...,4,1 (h/3) on N+1 samples */
    if (n % 2) return NAN;
    for (long k = 0; k <= n; ++k) {
      ocg_real zeta = (k == 0 || k == n) ? OCG_R(1.0) : (k % 2 ? OCG_R(4.0) : OCG_R(2.0));
      acc += zeta * s * t * d * OCG_R(0.333333333333333333);
      t *= ext; /* E_{k+1} = E_k exp(-sigma dx (rho_k + rho_{k+1}) / 2), rho constant */
    }
    break;
  }
  return (ld)acc;
}

static void test_integrators__error_against_step_count(void **state) {
  (void)state;
  static const double taus[] = {0.1, 1.0, 10.0};
  char buf[8192];
  size_t len = 0;
  len += (size_t)snprintf(buf + len, sizeof buf - len,
                          "Absolute error of the in-scattered radiance against the exact 1 - e^{-tau} (homogeneous "
                          "medium, sigma_s = sigma_t, S = 1, N equal steps, %s). Simpson uses N + 1 samples.\n\n"
                          "| tau | N | %s | %s | %s | %s |\n|---:|---:|---:|---:|---:|---:|\n",
                          PREC, rule_name[0], rule_name[1], rule_name[2], rule_name[3]);
  for (size_t it = 0; it < 3; ++it) {
    ld tau = taus[it], ref = -expm1l(-tau);
    ld prev[RULE_COUNT] = {0};
    for (long n = 1; n <= 1024; n *= 2) {
      ld err[RULE_COUNT];
      for (int r = 0; r < RULE_COUNT; ++r) err[r] = integrate_rule(r, tau, n) - ref;
      len += (size_t)snprintf(buf + len, sizeof buf - len, "| %g | %ld | %.2Le | %.2Le | %.2Le | ", (double)tau, n,
                              fabsl(err[0]), fabsl(err[1]), fabsl(err[2]));
      len += (size_t)(isnan(err[3]) ? snprintf(buf + len, sizeof buf - len, "— |\n")
                                    : snprintf(buf + len, sizeof buf - len, "%.2Le |\n", fabsl(err[3])));
      /* Hillaire: rounding only. */
      assert_true(fabsl(err[0]) <= (3.0L * n + 8.0L) * EPS);
      /* Left Riemann overestimates, Alg. 1 underestimates; both worse than Hillaire. */
      assert_true(err[1] > 0 && err[2] < 0);
      assert_true(fabsl(err[0]) < fabsl(err[1]) && fabsl(err[0]) < fabsl(err[2]));
      /* First order: the error halves when N doubles (where rounding does not dominate). */
      if (tau / n <= 0.1L && fabsl(err[2]) > 1e4L * EPS) {
        assert_true(prev[1] / fabsl(err[1]) > 1.8L && prev[1] / fabsl(err[1]) < 2.2L);
        assert_true(prev[2] / fabsl(err[2]) > 1.8L && prev[2] / fabsl(err[2]) < 2.2L);
      }
      prev[1] = fabsl(err[1]);
      prev[2] = fabsl(err[2]);
    }
  }
  assert_true(len < sizeof buf - 1);
  fputs(buf, stdout);
  const char *path = getenv("OC_TABLE_OUT");
  if (path && *path) {
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    assert_true(fwrite(buf, 1, len, f) == len);
    assert_int_equal(fclose(f), 0);
    printf("(table written to %s)\n", path);
  }
}

/* ---- Multiple-scattering octaves, beer-powder --------------------------------------------------------- */

static void test_ms_octaves__sum_and_limits(void **state) {
  (void)state;
  const ocg_real a = OCG_R(0.5), b = OCG_R(0.5), c = OCG_R(0.5);
  for (int im = -4; im <= 4; ++im) {
    ocg_real mu = (ocg_real)(im / 4.0);
    ocg_real p0 = ocg_phase_hg_draine(mu);
    assert_true(ocg_ms_octaves(OCG_R(1.0), mu, a, b, c, 0) == OCG_R(0.0));
    /* Octave 0 is single scattering. */
    assert_true(rel_err((ld)ocg_ms_octaves(OCG_R(2.0), mu, a, b, c, 1), (ld)(ocg_exp(OCG_R(-2.0)) * p0)) <= 2 * EPS);
    /* a = b = c = 1: n copies of single scattering. */
    assert_true(rel_err((ld)ocg_ms_octaves(OCG_R(0.7), mu, OCG_R(1.0), OCG_R(1.0), OCG_R(1.0), 8),
                        8.0L * (ld)(ocg_exp(OCG_R(-0.7)) * p0)) <= 16 * EPS);
    ocg_real prev_tau = OCG_R(1e30);
    for (int it = 0; it <= 60; ++it) {
      ocg_real tau = it == 0 ? OCG_R(0.0) : (ocg_real)pow(10.0, -6.0 + it * 0.15); /* 0, 1e-6 .. 1e3 */
      ocg_real prev_n = OCG_R(0.0);
      for (int n = 1; n <= 12; ++n) {
        ocg_real v = ocg_ms_octaves(tau, mu, a, b, c, n);
        assert_true(isfinite(v) && v >= 0);
        assert_true(v >= prev_n); /* adding an octave never removes light */
        prev_n = v;
      }
      ocg_real v8 = ocg_ms_octaves(tau, mu, a, b, c, 8);
      assert_true(v8 <= prev_tau); /* deeper in the cloud is darker */
      prev_tau = v8;
    }
  }
  /* Deep inside a cloud the higher octaves carry the light (why tau, not T, is stored). */
  ocg_real deep1 = ocg_ms_octaves(OCG_R(40.0), OCG_R(0.0), a, b, c, 1), deep8 = ocg_ms_octaves(OCG_R(40.0), OCG_R(0.0), a, b, c, 8);
  printf("[" PREC "] octaves at tau 40, mu 0: 1 octave %.3g, 8 octaves %.3g\n", (double)deep1, (double)deep8);
  assert_true(deep8 > 1e6 * deep1);
}

/* The cloud's shadow: e^{-τ} exactly for a pure absorber and for the legacy model; at ω = 1 the closed
 * form max(1/(1 + a_s τ), e^{-τ}); in [e^{-τ}, 1], 1 at τ = 0, never rising with τ or with absorption,
 * finite at absurd τ. */
static void test_cloud_shadow__limits(void **state) {
  (void)state;
  ocg_cloud_model cm;
  memset(&cm, 0, sizeof cm);
  const ocg_real ws[] = {OCG_R(0.0), OCG_R(0.5), OCG_R(0.9), OCG_R(0.99), OCG_R(1.0)};
  ocg_real prev_w[61];
  for (size_t iw = 0; iw < sizeof ws / sizeof ws[0]; ++iw) {
    cm.albedo = ws[iw];
    ocg_real prev = OCG_R(2.0);
    for (int it = 0; it <= 60; ++it) {
      ocg_real tau = it == 0 ? OCG_R(0.0) : (ocg_real)pow(10.0, -6.0 + it * 0.15); /* 0, 1e-6 .. 1e3 */
      ld direct = (ld)ocg_exp(-tau), v = (ld)ocg_cloud_shadow(cm, tau); /* S adds a term ≥ 0 to this */
      assert_true(isfinite((double)v) && v >= direct * (1 - 4 * EPS) && v <= 1 + 4 * EPS);
      assert_true(v <= (ld)prev * (1 + 4 * EPS)); /* deeper is darker */
      if (iw > 0) assert_true(v >= (ld)prev_w[it] * (1 - 4 * EPS)); /* more albedo, more light */
      if (ws[iw] == OCG_R(0.0)) assert_true(rel_err(v, direct) <= 4 * EPS);
      if (ws[iw] == OCG_R(1.0)) {
        ld td = 1.0L / (1.0L + (ld)OCG_SHADOW_DIFFUSE_A * (ld)tau); /* the diffusion law, or the beam */
        assert_true(fabsl(v - (td > direct ? td : direct)) <= 16 * EPS);
      }
      prev = (ocg_real)v;
      prev_w[it] = (ocg_real)v;
    }
    assert_true(ocg_cloud_shadow(cm, OCG_R(0.0)) == OCG_R(1.0));
    ocg_real huge = ocg_cloud_shadow(cm, OCG_R(1e30));
    assert_true(isfinite(huge) && huge >= OCG_R(0.0) && huge < OCG_R(1e-20));
  }
  cm.albedo = OCG_R(1.0);
  cm.legacy = 1;
  assert_true(rel_err((ld)ocg_cloud_shadow(cm, OCG_R(3.0)), expl(-3.0L)) <= 4 * EPS);
  cm.legacy = 0;
  ocg_real s1 = ocg_cloud_shadow(cm, OCG_R(10.0));
  cm.albedo = OCG_R(0.9);
  printf("[" PREC "] cloud shadow at tau 10: e^-tau %.3g, albedo 0.9 %.3g, albedo 1 %.3g\n", exp(-10.0),
         (double)ocg_cloud_shadow(cm, OCG_R(10.0)), (double)s1);
}

/* Absorption along the sun's path (march.h ocg_ms_sun_absorption): the octaves and the diffuse part are
 * exactly those without it times e^{−s(1−ω)τ}, against expl; nothing at ω = 1 or τ = 0; finite and 0 at
 * absurd τ. */
static void test_ms_sun_absorption__closed_form(void **state) {
  (void)state;
  ocg_cloud_model cm;
  memset(&cm, 0, sizeof cm);
  cm.ms_a = OCG_R(0.5), cm.ms_b = OCG_R(0.5), cm.ms_c = OCG_R(0.9), cm.ms_n = 4;
  cm.albedo_power = OCG_MS_ALBEDO_POWER, cm.diffuse_b = OCG_MS_DIFFUSE_B, cm.diffuse_a = OCG_MS_DIFFUSE_A;
  const ocg_real ws[] = {OCG_R(0.5), OCG_R(0.9), OCG_R(0.99), OCG_R(1.0)}, taus[] = {OCG_R(0.0), OCG_R(1.0), OCG_R(20.0)};
  const ocg_vec3 e = ocg_v3s(OCG_R(1.0));
  for (size_t iw = 0; iw < sizeof ws / sizeof ws[0]; ++iw)
    for (size_t it = 0; it < sizeof taus / sizeof taus[0]; ++it) {
      cm.albedo = ws[iw];
      cm.sun_abs = OCG_R(0.0);
      ld ms0 = (ld)ocg_cloud_source_ms(cm, OCG_R(0.01), taus[it], OCG_R(0.3), e).x;
      ld msd0 = (ld)ocg_cloud_source_msd(cm, OCG_R(0.01), taus[it], e).x;
      cm.sun_abs = OCG_MS_SUN_ABS;
      ld f = expl(-(ld)OCG_MS_SUN_ABS * (1.0L - (ld)ws[iw]) * (ld)taus[it]);
      assert_true(rel_err((ld)ocg_cloud_source_ms(cm, OCG_R(0.01), taus[it], OCG_R(0.3), e).x, ms0 * f) <= 16 * EPS);
      assert_true(rel_err((ld)ocg_cloud_source_msd(cm, OCG_R(0.01), taus[it], e).x, msd0 * f) <= 16 * EPS);
      if (ws[iw] == OCG_R(1.0) || taus[it] == OCG_R(0.0)) assert_true(ocg_ms_sun_absorption(cm, taus[it]) == OCG_R(1.0));
    }
  cm.albedo = OCG_R(0.9);
  ocg_real huge = ocg_ms_sun_absorption(cm, OCG_R(1e30));
  assert_true(isfinite(huge) && huge == OCG_R(0.0));
}

/* The sun path's share (march.h ocg_ms_split): S = γτ/(γτ + D½·e^{−β max(μ, 0)}) of the octaves and the
 * diffuse part joins the sample's source, the rest stays deferred, so nothing is lost or made; nothing
 * moves at γ = 0 or τ = 0; S grows toward the sun (μ > 0) and with τ, and tends to 1 at absurd τ. */
static void test_ms_split__share_conserves(void **state) {
  (void)state;
  ocg_cloud_model cm;
  memset(&cm, 0, sizeof cm);
  cm.chord_half = OCG_MS_CHORD_HALF, cm.ms_forward = OCG_MS_FORWARD, cm.sun_share = OCG_R(0.25);
  const ocg_real taus[] = {OCG_R(0.0), OCG_R(0.5), OCG_R(5.0), OCG_R(50.0)}, mus[] = {OCG_R(-1.0), OCG_R(0.0), OCG_R(0.9)};
  for (size_t it = 0; it < sizeof taus / sizeof taus[0]; ++it)
    for (size_t im = 0; im < sizeof mus / sizeof mus[0]; ++im) {
      ocg_vec3 j = ocg_v3(OCG_R(1.0), OCG_R(2.0), OCG_R(3.0)), jms = ocg_v3s(OCG_R(0.5)), jmsd = ocg_v3s(OCG_R(0.25));
      ocg_ms_split(cm, taus[it], mus[im], &j, &jms, &jmsd);
      ld gt = 0.25L * (ld)taus[it], dh = (ld)OCG_MS_CHORD_HALF * expl(-(ld)OCG_MS_FORWARD * fmaxl((ld)mus[im], 0.0L));
      ld sh = gt / (gt + dh);
      assert_true(fabsl((ld)j.x - (1.0L + 0.75L * sh)) <= 16 * EPS && fabsl((ld)j.z - (3.0L + 0.75L * sh)) <= 16 * EPS);
      assert_true(fabsl((ld)jms.y - 0.5L * (1.0L - sh)) <= 16 * EPS && fabsl((ld)jmsd.y - 0.25L * (1.0L - sh)) <= 16 * EPS);
      assert_true(fabsl((ld)(j.y + jms.y + jmsd.y) - 2.75L) <= 16 * EPS); /* nothing lost or made */
      if (taus[it] == OCG_R(0.0)) assert_true(j.x == OCG_R(1.0) && jms.x == OCG_R(0.5));
    }
  ocg_vec3 a = ocg_v3s(OCG_R(0.0)), b = ocg_v3s(OCG_R(1.0)), c = ocg_v3s(OCG_R(0.0));
  ocg_ms_split(cm, OCG_R(5.0), OCG_R(-0.5), &a, &b, &c);
  ocg_vec3 a2 = ocg_v3s(OCG_R(0.0)), b2 = ocg_v3s(OCG_R(1.0)), c2 = ocg_v3s(OCG_R(0.0));
  ocg_ms_split(cm, OCG_R(5.0), OCG_R(0.8), &a2, &b2, &c2);
  assert_true(a2.x > a.x); /* toward the sun the share is larger */
  ocg_vec3 h = ocg_v3s(OCG_R(0.0)), hm = ocg_v3s(OCG_R(1.0)), hd = ocg_v3s(OCG_R(0.0));
  ocg_ms_split(cm, OCG_R(1e30), OCG_R(0.0), &h, &hm, &hd);
  assert_true(isfinite(h.x) && h.x >= OCG_R(0.999) && hm.x <= OCG_R(1e-3));
  cm.sun_share = OCG_R(0.0);
  ocg_vec3 z = ocg_v3s(OCG_R(1.0)), zm = ocg_v3s(OCG_R(1.0)), zd = ocg_v3s(OCG_R(1.0));
  ocg_ms_split(cm, OCG_R(5.0), OCG_R(0.5), &z, &zm, &zd);
  assert_true(z.x == OCG_R(1.0) && zm.x == OCG_R(1.0) && zd.x == OCG_R(1.0));
}

/* The chord past the early exit (march.h ocg_march_chord): a run in the sun alone stops at the cap
 * with the depth the chord factor reads; a run with far-side sky light goes on past it until that light
 * has fallen by e^{-OCG_AMBIENT_FAR_DEPTH}, its decay exactly e^{-kappa_f d}, and the chord factor
 * still reads the depth at the cap. */
static void test_march_chord__far_side_past_the_cap(void **state) {
  (void)state;
  ocg_cloud_model cm;
  memset(&cm, 0, sizeof cm);
  cm.albedo = OCG_R(0.9);
  ocg_real kf = ocg_ambient_far_kappa(cm), d = OCG_R(1.0); /* σ·d = 1 per step */
  assert_true(rel_err((ld)kf, (ld)OCG_AMBIENT_FAR_B * 0.1L) <= 8 * EPS);
  for (int sky = 0; sky < 2; ++sky) {
    ocg_march m = ocg_march_begin(OCG_R(0.0));
    m.tau_run = OCG_R(7.0);
    m.len_run = OCG_R(7.0);
    m.L_far = ocg_v3s(sky ? OCG_R(1.0) : OCG_R(0.0));
    int steps = 0;
    while (ocg_march_chord(&m, cm, OCG_R(1.0), kf, d) && steps < 100000) steps++;
    steps++; /* the step that said stop was taken too */
    assert_true(m.tau_run >= OCG_MS_CHORD_MAX && m.tau_run < OCG_MS_CHORD_MAX + OCG_R(1.0));
    if (!sky) {
      assert_true(m.d_far == OCG_R(0.0));
      continue;
    }
    assert_true(kf * m.d_far >= OCG_AMBIENT_FAR_DEPTH && kf * (m.d_far - d) < OCG_AMBIENT_FAR_DEPTH);
    ld want = expl(-(ld)kf * (ld)(m.tau_run + m.d_far - OCG_R(7.0)));
    assert_true(rel_err((ld)m.L_far.x, want) <= (ld)steps * 8 * EPS);
    printf("[" PREC "] far side past the cap at albedo 0.9: %d chord steps, D %.1f + %.1f\n", steps, (double)m.tau_run,
           (double)m.d_far);
  }
  cm.albedo = OCG_R(1.0); /* no absorption: nothing to decay, and no far-side light to march for */
  assert_true(ocg_ambient_far_kappa(cm) == OCG_R(0.0));
  assert_true(ocg_ambient_face(cm) == OCG_R(1.0));
}

/* Runs across gaps (march.h ocg_march_run): a march through cloud A (depth da over 400 m), a gap of
 * length g whose extinction is gap_sig, and cloud B (depth db over lb m), its multiply scattered light
 * alone (a source σ per metre). Returns L.x. */
static ld march_clouds(ocg_cloud_model cm, ocg_real da, ocg_real g, ocg_real gap_sig, ocg_real db, ocg_real lb) {
  ocg_march m = ocg_march_begin(OCG_R(-0.5));
  const ocg_real d = OCG_R(10.0), sa = da / OCG_R(400.0), sb = db / lb;
  const ocg_vec3 zero = ocg_v3s(OCG_R(0.0));
  for (int part = 0; part < 3; ++part) {
    ocg_real len = part == 0 ? OCG_R(400.0) : part == 1 ? g : lb, sig = part == 0 ? sa : part == 1 ? gap_sig : sb;
    int n = (int)ceil((double)(len / d));
    for (int i = 0; i < n; ++i) {
      ocg_real seg = i + 1 < n ? d : len - d * (ocg_real)(n - 1);
      ocg_march_run(&m, cm, sig, seg);
      ocg_march_segment(&m, ocg_v3s(sig), sig, zero, ocg_v3s(sig), zero, zero, OCG_R(0.0), seg);
    }
  }
  ocg_march_end_run(&m, cm);
  return (ld)m.L.x;
}

/* A gap of exact zeros and one of a trace of cloud give the same light (before, the first ended the run:
 * the light drew the zero set's cubes); the light is continuous as the gap closes, as B thins to nothing,
 * and in the gap's length; a long gap is two runs exactly. */
static void test_march_run__gaps_are_continuous(void **state) {
  (void)state;
  ocg_cloud_model cm;
  memset(&cm, 0, sizeof cm);
  cm.albedo = OCG_R(1.0);
  cm.ms_n = 4;
  cm.chord_half = OCG_MS_CHORD_HALF;
  cm.ms_forward = OCG_MS_FORWARD;
  ld joined = march_clouds(cm, OCG_R(3.0), OCG_R(0.0), OCG_R(0.0), OCG_R(20.0), OCG_R(400.0));
  for (int i = 0; i < 3; ++i) { /* gaps of 30, 120, 400 m */
    ocg_real g = i == 0 ? OCG_R(30.0) : i == 1 ? OCG_R(120.0) : OCG_R(400.0);
    ld zero = march_clouds(cm, OCG_R(3.0), g, OCG_R(0.0), OCG_R(20.0), OCG_R(400.0));
    ld trace = march_clouds(cm, OCG_R(3.0), g, OCG_R(1e-7), OCG_R(20.0), OCG_R(400.0));
    assert_true(rel_err(trace, zero) <= 1e-4L + 64 * EPS);
    assert_true(zero < joined);
    printf("[" PREC "] a %.0f m gap: zeros %.4Lg, a trace of cloud %.4Lg, no gap %.4Lg\n", (double)g, zero, trace, joined);
  }
  ld closed = march_clouds(cm, OCG_R(3.0), OCG_R(1e-3), OCG_R(0.0), OCG_R(20.0), OCG_R(400.0));
  assert_true(rel_err(closed, joined) <= 1e-4L + 64 * EPS);
  /* B as thick as A but shrinking to nothing after the gap: the light tends to A's alone within the
   * bound of march.h (OCG_RUN_JUMP of the run's multiply scattered light, at any coupling) */
  ld worst_b = 0;
  for (int i = 1; i <= 40; ++i) {
    ocg_real g = OCG_R(25.0) * (ocg_real)i;
    ld a_alone = march_clouds(cm, OCG_R(3.0), g, OCG_R(0.0), OCG_R(0.0), OCG_R(1.0));
    ld b_short = march_clouds(cm, OCG_R(3.0), g, OCG_R(0.0), OCG_R(3.0) / OCG_R(400.0) * OCG_R(0.01), OCG_R(0.01));
    worst_b = rel_err(b_short, a_alone) > worst_b ? rel_err(b_short, a_alone) : worst_b;
  }
  assert_true(worst_b <= (ld)OCG_RUN_JUMP);
  /* the light as the gap widens: no step larger than the largest rate allows */
  ld prev = joined, worst = 0;
  for (int i = 1; i <= 200; ++i) {
    ld v = march_clouds(cm, OCG_R(3.0), OCG_R(10.0) * (ocg_real)i, OCG_R(0.0), OCG_R(20.0), OCG_R(400.0));
    worst = fabsl(v - prev) / joined > worst ? fabsl(v - prev) / joined : worst;
    prev = v;
  }
  assert_true(worst <= 0.03L); /* 10 m of 400: k moves 2.5 %; an end at the gap moved 70 % */
  /* a gap of OCG_RUN_GAP_END run lengths or more: A and B are two runs, exactly as each alone */
  ld apart = march_clouds(cm, OCG_R(3.0), OCG_R(1700.0), OCG_R(0.0), OCG_R(20.0), OCG_R(400.0));
  ld a_only = march_clouds(cm, OCG_R(3.0), OCG_R(1700.0), OCG_R(0.0), OCG_R(0.0), OCG_R(1.0));
  ld b_only = march_clouds(cm, OCG_R(0.0), OCG_R(1700.0), OCG_R(0.0), OCG_R(20.0), OCG_R(400.0)) * expl(-3.0L);
  /* (b_only: B seen through A) */
  assert_true(rel_err(apart, a_only + b_only) <= 256 * EPS);
  printf("[" PREC "] widening gap: largest step %.4Lg of the joined light; B shrunk to nothing: %.4Lg; apart %.5Lg = "
         "%.5Lg + %.5Lg\n", worst, worst_b, apart, a_only, b_only);
}

static void test_beer_powder__finite_and_bounded(void **state) {
  (void)state;
  ld peak = 2.0L / (3.0L * sqrtl(3.0L)); /* at tau = ln(3)/2 */
  ocg_real taus[] = {OCG_R(0.0), OCG_R(1e-30), OCG_R(1e-12), OCG_R(1e-6), OCG_R(0.1), OCG_R(0.5493061443340549),
                     OCG_R(1.0), OCG_R(10.0), OCG_R(100.0), OCG_R(1e30), OCG_R(-1.0)};
  for (size_t i = 0; i < sizeof taus / sizeof taus[0]; ++i) {
    ocg_real v = ocg_beer_powder(taus[i]);
    assert_true(isfinite(v) && v >= 0 && (ld)v <= peak * (1 + 4 * EPS));
  }
  assert_true(ocg_beer_powder(OCG_R(0.0)) == OCG_R(0.0));
  assert_true(rel_err((ld)ocg_beer_powder(OCG_R(0.5493061443340549)), peak) <= 4 * EPS);
  /* Small tau: 2 tau (1 - 2 tau), no cancellation. */
  assert_true(rel_err((ld)ocg_beer_powder(OCG_R(1e-12)), expl(-(ld)OCG_R(1e-12)) * -expm1l(-2 * (ld)OCG_R(1e-12))) <= 4 * EPS);
  assert_true(rel_err((ld)ocg_beer_powder(OCG_R(1e-3)), expl(-1e-3L) * -expm1l(-2e-3L)) <= 4 * EPS);
}

/* ---- Water content, tone mapping --------------------------------------------------------------------- */

static void test_markl__water_content_to_extinction(void **state) {
  (void)state;
  ld liq = (ld)ocg_sigma_t_liquid(OCG_R(1e-3), OCG_RHO_AIR);
  ld ice = (ld)ocg_sigma_t_ice(OCG_R(1e-3), OCG_RHO_AIR);
  printf("[" PREC "] Märkl: LWC 1e-3 -> %.9Lg m^-1, IWC 1e-3 -> %.9Lg m^-1\n", liq, ice);
  assert_true(rel_err(liq, 0.18375L) <= 4 * EPS);
  assert_true(rel_err(ice, 4.0L * sqrtl(3.0L) / 3.0L * 1e-3L * 1.225L / (917.0L * 25e-6L)) <= 4 * EPS);
  assert_true(ocg_sigma_t_liquid(OCG_R(0.0), OCG_R(1.0)) == OCG_R(0.0));
  /* Linear in both arguments. */
  assert_true(rel_err((ld)ocg_sigma_t_liquid(OCG_R(2e-3), OCG_R(0.6125)), 0.18375L) <= 4 * EPS);
}

static void test_aces__monotone_and_in_unit_range(void **state) {
  (void)state;
  /* Grey axis and a few hues, exposure 0 .. 1e4: every channel non-decreasing, in [0, 1]. */
  const ocg_vec3 hues[] = {ocg_v3(OCG_R(1.0), OCG_R(1.0), OCG_R(1.0)), ocg_v3(OCG_R(1.0), OCG_R(0.8), OCG_R(0.6)),
                           ocg_v3(OCG_R(0.5), OCG_R(0.7), OCG_R(1.0)), ocg_v3(OCG_R(0.9), OCG_R(0.95), OCG_R(1.0))};
  for (size_t h = 0; h < sizeof hues / sizeof hues[0]; ++h) {
    ocg_vec3 prev = ocg_v3s(OCG_R(0.0));
    for (int i = 0; i <= 4000; ++i) {
      ocg_real k = i == 0 ? OCG_R(0.0) : (ocg_real)pow(10.0, -5.0 + 9.0 * i / 4000.0);
      ocg_vec3 o = ocg_aces_fit(ocg_scale3(hues[h], k));
      assert_true(o.x >= 0 && o.x <= 1 && o.y >= 0 && o.y <= 1 && o.z >= 0 && o.z <= 1);
      if (!(o.x >= prev.x && o.y >= prev.y && o.z >= prev.z))
        fail_msg("ACES not monotone: hue %zu k %g", h, (double)k);
      prev = o;
    }
    assert_true(prev.x == OCG_R(1.0) && prev.y == OCG_R(1.0) && prev.z == OCG_R(1.0));
  }
  ocg_vec3 z = ocg_aces_fit(ocg_v3s(OCG_R(0.0)));
  assert_true(z.x == 0 && z.y == 0 && z.z == 0);
  /* The rational fit itself is monotone for v >= 0. */
  ocg_real prev = ocg_aces_rrt_odt_fit(OCG_R(0.0));
  for (int i = 1; i <= 10000; ++i) {
    ocg_real v = ocg_aces_rrt_odt_fit((ocg_real)(i * 0.01));
    assert_true(v >= prev);
    prev = v;
  }
  ocg_vec3 g18 = ocg_aces_fit(ocg_v3s(OCG_R(0.18)));
  printf("[" PREC "] ACES fit: 0.18 grey -> %.6f %.6f %.6f; 1.0 -> %.6f\n", (double)g18.x, (double)g18.y, (double)g18.z,
         (double)ocg_aces_fit(ocg_v3s(OCG_R(1.0))).x);
}

static void test_srgb__known_points(void **state) {
  (void)state;
  assert_true(ocg_srgb_encode(OCG_R(0.0)) == OCG_R(0.0));
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(1.0)), 1.0L) <= 2 * EPS);
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(0.0031308)), 0.040449936L) <= 2 * EPS);
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(0.18)), 0.46135612950044164L) <= 4 * EPS);
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(0.5)), 0.7353569830524495L) <= 4 * EPS);
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(0.001)), 0.01292L) <= 2 * EPS);
  /* Clamped outside [0, 1]; NaN maps to 0 (C). */
  assert_true(ocg_srgb_encode(OCG_R(-1.0)) == OCG_R(0.0));
  assert_true(rel_err((ld)ocg_srgb_encode(OCG_R(7.0)), 1.0L) <= 2 * EPS);
  assert_true(ocg_srgb_encode((ocg_real)NAN) == OCG_R(0.0));
  /* Continuous at the knee (the two branches meet within 1e-7 relative) and monotone. */
  ld lo = 12.92L * 0.0031308L, hi = 1.055L * powl(0.0031308L, 1.0L / 2.4L) - 0.055L;
  assert_true(fabsl(lo - hi) / lo < 1e-6L);
  ocg_real prev = OCG_R(0.0);
  for (int i = 1; i <= 100000; ++i) {
    ocg_real v = ocg_srgb_encode((ocg_real)(i * 1e-5));
    assert_true(v >= prev);
    prev = v;
  }
  ocg_vec3 e3 = ocg_srgb_encode3(ocg_v3(OCG_R(0.0), OCG_R(0.18), OCG_R(1.0)));
  assert_true(e3.x == ocg_srgb_encode(OCG_R(0.0)) && e3.y == ocg_srgb_encode(OCG_R(0.18)) && e3.z == ocg_srgb_encode(OCG_R(1.0)));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_phase__normalised_over_sphere),
      cmocka_unit_test(test_phase__finite_at_poles_and_outside_domain),
      cmocka_unit_test(test_phase__special_cases_agree),
      cmocka_unit_test(test_phase__hgd_constants_match_formulas),
      cmocka_unit_test(test_segment_weight__matches_expm1_reference),
      cmocka_unit_test(test_segment_weight__series_guard_needed),
      cmocka_unit_test(test_segment__telescopes_to_one_minus_exp),
      cmocka_unit_test(test_integrators__error_against_step_count),
      cmocka_unit_test(test_ms_octaves__sum_and_limits),
      cmocka_unit_test(test_cloud_shadow__limits),
      cmocka_unit_test(test_ms_sun_absorption__closed_form),
      cmocka_unit_test(test_ms_split__share_conserves),
      cmocka_unit_test(test_march_chord__far_side_past_the_cap),
      cmocka_unit_test(test_march_run__gaps_are_continuous),
      cmocka_unit_test(test_beer_powder__finite_and_bounded),
      cmocka_unit_test(test_markl__water_content_to_extinction),
      cmocka_unit_test(test_aces__monotone_and_in_unit_range),
      cmocka_unit_test(test_srgb__known_points),
  };
  return cmocka_run_group_tests_name("optics_" PREC, tests, NULL, NULL);
}
