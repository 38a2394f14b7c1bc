/* test_atmo.c — the clear-sky atmosphere (shaders/atmosphere.h, common/oc_atmo.c): table look-ups
 * against independent double-precision integrals and closed forms, the float geometry at planet
 * scale, the sun softening, the sky tables' magnitudes and consistency, thread independence, and
 * parameter validation. The measured errors are printed (docs/numerics.md quotes them). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "report.h"

#include "atmosphere.h"
#include "oc_atmo.h"
#include "oc_atmo_internal.h" /* oc__atmo_eval: the tables' integrals without the tables */
#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"

#define PI 3.14159265358979323846

/* |a − b| ≤ tol, reporting both values (cmocka 1.1 has no floating-point assert). */
#define assert_near(a, b, tol)                                                                  \
  do {                                                                                          \
    double a_ = (a), b_ = (b), t_ = (tol);                                                      \
    if (!(fabs(a_ - b_) <= t_)) fail_msg("%s = %.17g, expected %.17g +- %.3g", #a, a_, b_, t_); \
  } while (0)

static double ch(ocg_vec3 v, int c) { return c == 0 ? v.x : c == 1 ? v.y : v.z; }

/* μs at the centre of column i of an (r, μs) table of width w (the inverse of ocg_atmo_mus_to_unit,
 * in double). */
static double mus_of_unit(double x) {
  double k = OCG_ATMO_MUS_K, y = 2.0 * x - 1.0;
  return k * y / (1.0 + k - fabs(y));
}
static double mus_centre(int i, int w) { return mus_of_unit((double)i / (w - 1)); }

/* ---- An independent double-precision model of the medium (not the shared header) -------------------- */

typedef struct {
  double b, t, bR[3], HR, bMs, bMe, HM, bO[3], oc, ow;
} ref_atm_t;

static ref_atm_t ref_of(const ocg_atmosphere *p) {
  ref_atm_t m = {p->bottom_radius, p->top_radius, {p->rayleigh_scattering.x, p->rayleigh_scattering.y, p->rayleigh_scattering.z},
                 p->rayleigh_scale_height, p->mie_scattering, p->mie_extinction, p->mie_scale_height,
                 {p->ozone_absorption.x, p->ozone_absorption.y, p->ozone_absorption.z}, p->ozone_center, p->ozone_half_width};
  return m;
}

static double ref_sigma_t(const ref_atm_t *m, double h, int c) {
  double o = 1.0 - fabs(h - m->oc) / m->ow;
  return m->bR[c] * exp(-h / m->HR) + m->bMe * exp(-h / m->HM) + m->bO[c] * (o > 0.0 ? o : 0.0);
}

/* Distance to the top sphere along (r, μ), long double. */
static double ref_dist_top(const ref_atm_t *m, double r, double mu) {
  long double R = r, M = mu, T = m->t;
  long double disc = R * R * (M * M - 1.0L) + T * T;
  return (double)(-R * M + sqrtl(disc > 0 ? disc : 0));
}

/* Optical depth to the top by composite Simpson with n intervals (n even). */
static void ref_tau(const ref_atm_t *m, double r, double mu, int n, double tau[3]) {
  double d = ref_dist_top(m, r, mu), hstep = d / n;
  for (int c = 0; c < 3; c++) tau[c] = 0.0;
  for (int i = 0; i <= n; i++) {
    double s = i * hstep;
    double rs = sqrt(s * s + 2.0 * r * mu * s + r * r);
    double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    for (int c = 0; c < 3; c++) tau[c] += w * ref_sigma_t(m, rs - m->b, c);
  }
  for (int c = 0; c < 3; c++) tau[c] *= hstep / 3.0;
}

/* ---- Fixtures ------------------------------------------------------------------------------------------ */

typedef struct {
  ocg_atmosphere p;
  oc_atmo_t *a; /* default parameters, 2 threads */
} fix_t;

static int setup(void **state) {
  static fix_t f;
  oc_atmo_params_default(&f.p);
  f.a = oc_atmo_create(&f.p, 2);
  if (!f.a) return -1;
  *state = &f;
  return 0;
}

static int teardown(void **state) {
  fix_t *f = *state;
  oc_atmo_free(f->a);
  return 0;
}

/* ---- Parameters and layout ---------------------------------------------------------------------------- */

static void test_atmo__params_default(void **state) {
  (void)state;
  ocg_atmosphere p;
  oc_atmo_params_default(&p);
  assert_true(p.bottom_radius == (float)OC_PLANET_RADIUS);
  assert_true(p.top_radius == (float)(OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT));
  assert_true(p.rayleigh_scattering.x == 5.802e-6f && p.rayleigh_scattering.y == 13.558e-6f && p.rayleigh_scattering.z == 33.1e-6f);
  assert_true(p.mie_scattering == 3.996e-6f && p.mie_extinction == 4.44e-6f && p.mie_g == 0.8f);
  assert_true(p.ozone_center == 25000.0f && p.ozone_half_width == 15000.0f);
  /* The layout is GLSL std140 (the struct can be copied into a uniform block). */
  assert_int_equal(sizeof(ocg_atmosphere), 96);
  assert_int_equal(offsetof(ocg_atmosphere, rayleigh_scattering), 0);
  assert_int_equal(offsetof(ocg_atmosphere, rayleigh_scale_height), 12);
  assert_int_equal(offsetof(ocg_atmosphere, ozone_absorption), 16);
  assert_int_equal(offsetof(ocg_atmosphere, ground_albedo), 32);
  assert_int_equal(offsetof(ocg_atmosphere, solar_irradiance), 48);
  assert_int_equal(offsetof(ocg_atmosphere, bottom_radius), 64);
  assert_int_equal(offsetof(ocg_atmosphere, mie_scale_height), 80);
}

/* Creates with stderr captured; returns the handle and the log text. */
static oc_atmo_t *create_captured(const ocg_atmosphere *p, char *log, size_t n) {
  fflush(stderr);
  int saved = dup(2);
  FILE *tf = tmpfile();
  assert_non_null(tf);
  dup2(fileno(tf), 2);
  oc_atmo_t *a = oc_atmo_create(p, 1);
  fflush(stderr);
  dup2(saved, 2);
  close(saved);
  rewind(tf);
  size_t k = fread(log, 1, n - 1, tf);
  log[k] = '\0';
  fclose(tf);
  return a;
}

static void test_atmo__bad_params_rejected(void **state) {
  fix_t *f = *state;
  char log[512], want[96];
  struct {
    const char *field;
    ocg_atmosphere q;
  } cases[24];
  int n = 0;
#define BAD(name, stmt)    \
  do {                     \
    cases[n].field = name; \
    cases[n].q = f->p;     \
    ocg_atmosphere *q = &cases[n].q; \
    stmt;                  \
    n++;                   \
  } while (0)
  BAD("bottom_radius", q->bottom_radius = -1.0f);
  BAD("bottom_radius", q->bottom_radius = NAN);
  BAD("top_radius", q->top_radius = q->bottom_radius);
  BAD("top_radius", q->top_radius = INFINITY);
  BAD("rayleigh_scattering", q->rayleigh_scattering.y = -1e-6f);
  BAD("rayleigh_scale_height", q->rayleigh_scale_height = 0.0f);
  BAD("mie_scattering", q->mie_scattering = INFINITY);
  BAD("mie_extinction", q->mie_extinction = 0.5f * q->mie_scattering);
  BAD("mie_scale_height", q->mie_scale_height = -5.0f);
  BAD("mie_g", q->mie_g = 1.0f);
  BAD("mie_g", q->mie_g = NAN);
  BAD("ozone_absorption", q->ozone_absorption.z = NAN);
  BAD("ozone_center", q->ozone_center = INFINITY);
  BAD("ozone_half_width", q->ozone_half_width = 0.0f);
  BAD("ground_albedo", q->ground_albedo.x = 1.5f);
  BAD("sun_angular_radius", q->sun_angular_radius = 0.0f);
  BAD("solar_irradiance", q->solar_irradiance.x = -1.0f);
#undef BAD
  for (int i = 0; i < n; i++) {
    oc_atmo_t *a = create_captured(&cases[i].q, log, sizeof log);
    if (a) {
      oc_atmo_free(a);
      fail_msg("case %d (%s) was accepted", i, cases[i].field);
    }
    snprintf(want, sizeof want, "bad parameter %s (", cases[i].field);
    if (!strstr(log, want)) fail_msg("case %d: log \"%s\" does not name %s", i, log, cases[i].field);
  }
  assert_null(create_captured(NULL, log, sizeof log));
  assert_non_null(strstr(log, "bad parameter params"));
  oc_atmo_free(NULL);
}

static void test_atmo__table_accessor(void **state) {
  fix_t *f = *state;
  int w, h;
  const float *px;
  static const int size[4][2] = {{OCG_ATMO_TRANSMITTANCE_W, OCG_ATMO_TRANSMITTANCE_H},
                                 {OCG_ATMO_MULTISCATTER_W, OCG_ATMO_MULTISCATTER_H},
                                 {OCG_ATMO_IRRADIANCE_W, OCG_ATMO_IRRADIANCE_H},
                                 {OCG_ATMO_IRRADIANCE_W, OCG_ATMO_IRRADIANCE_H}};
  assert_int_equal(OCG_ATMO_TRANSMITTANCE_W, 256);
  assert_int_equal(OCG_ATMO_TRANSMITTANCE_H, 64);
  assert_int_equal(OCG_ATMO_MULTISCATTER_W, 32);
  assert_int_equal(OCG_ATMO_MULTISCATTER_H, 32);
  for (int k = 0; k < OC_ATMO_TABLE_COUNT; k++) {
    assert_int_equal(oc_atmo_table(f->a, k, &w, &h, &px), 0);
    assert_int_equal(w, size[k][0]);
    assert_int_equal(h, size[k][1]);
    for (int i = 0; i < w * h * 4; i++) {
      if (!isfinite(px[i]) || px[i] < 0.0f) fail_msg("table %d texel %d channel %d = %g", k, i / 4, i % 4, px[i]);
      if (i % 4 == 3) assert_true(px[i] == 1.0f);
    }
  }
  assert_int_equal(oc_atmo_table(f->a, OC_ATMO_TABLE_COUNT, &w, &h, &px), OC_EINVAL);
  assert_int_equal(oc_atmo_table(f->a, -1, &w, &h, &px), OC_EINVAL);
  assert_int_equal(oc_atmo_table(NULL, 0, &w, &h, &px), OC_EINVAL);
  assert_int_equal(oc_atmo_table(f->a, 0, NULL, &h, &px), OC_EINVAL);
  assert_true(oc_atmo_params(f->a)->mie_g == f->p.mie_g);
}

/* ---- Shared header: float geometry at planet scale, phase functions ----------------------------------- */

static void test_atmo__float_geometry_planet_scale(void **state) {
  fix_t *f = *state;
  ref_atm_t m = ref_of(&f->p);
  /* Grazing and steep rays near the ground and near the top, in float, against long double. */
  const double hs[] = {0.0, 1.0, 100.0, 2000.0, 50000.0, 99999.0, 100000.0};
  const double mus[] = {-1.0, -0.3, -0.02, -0.004, -0.0005, 0.0, 0.0005, 0.01, 0.5, 1.0};
  double worst_top = 0.0, worst_bot = 0.0;
  for (size_t i = 0; i < sizeof hs / sizeof hs[0]; i++)
    for (size_t j = 0; j < sizeof mus / sizeof mus[0]; j++) {
      float r = (float)(m.b + hs[i]), mu = (float)mus[j];
      long double R = r, M = mu, B = m.b, T = m.t;
      long double dt = -R * M + sqrtl(R * R * (M * M - 1) + T * T);
      long double db_disc = R * R * (M * M - 1) + B * B;
      float got_t = ocg_atmo_dist_top(f->p, r, mu);
      double e = fabs(got_t - (double)dt) / fmax((double)dt, 1.0);
      if (e > worst_top) worst_top = e;
      int hits = M < 0 && db_disc >= 0;
      assert_int_equal(ocg_atmo_ray_hits_ground(f->p, r, mu), hits);
      if (hits) {
        long double db = -R * M - sqrtl(db_disc);
        float got_b = ocg_atmo_dist_bottom(f->p, r, mu);
        double eb = fabs(got_b - (double)db) / fmax((double)db, 1.0);
        if (eb > worst_bot) worst_bot = eb;
      }
    }
  print_message("float ray-sphere distances vs long double: worst relative error top %.2e, ground %.2e\n", worst_top,
                worst_bot);
  oc_report("atmosphere", "float ray-sphere distance to the ground vs long double", worst_bot, 2e-6, "rel");
  assert_true(worst_top < 2e-6);
  assert_true(worst_bot < 2e-6);
  /* Bruneton's form −rμ − √(r²(μ²−1) + b²) in float, for comparison: 1 m up, 0.06° below. */
  float r = (float)(m.b + 1.0), mu = -0.001f;
  float naive = -r * mu - sqrtf(fmaxf(r * r * (mu * mu - 1.0f) + (float)m.b * (float)m.b, 0.0f));
  long double R = r, M = mu, B = m.b;
  double exact = (double)(-R * M - sqrtl(R * R * (M * M - 1) + B * B));
  print_message("grazing ray 1 m above ground, mu=-1e-3: exact %.4f m, shared header %.4f m, naive float %.4f m\n", exact,
                (double)ocg_atmo_dist_bottom(f->p, r, mu), (double)naive);
}

static void test_atmo__phase_functions_normalised(void **state) {
  (void)state;
  const float gs[] = {0.0f, 0.5f, 0.8f, -0.3f};
  for (int k = 0; k < 4; k++) {
    double s = 0.0, sr = 0.0;
    const int n = 200000;
    for (int i = 0; i < n; i++) {
      float nu = (float)(-1.0 + (i + 0.5) * 2.0 / n);
      s += ocg_phase_cornette_shanks(nu, gs[k]) * 2.0 * PI * 2.0 / n;
      sr += ocg_phase_rayleigh(nu) * 2.0 * PI * 2.0 / n;
    }
    assert_near(s, 1.0, 1e-4);
    assert_near(sr, 1.0, 1e-5);
  }
  /* Cornette–Shanks against design.md's formula at one point. */
  double g = 0.8, mu = 0.3, want = 3 * (1 - g * g) * (1 + mu * mu) / (8 * PI * (2 + g * g) * pow(1 + g * g - 2 * g * mu, 1.5));
  assert_near(ocg_phase_cornette_shanks(0.3f, 0.8f), want, 1e-6 * want);
}

static void test_atmo__mappings_round_trip(void **state) {
  fix_t *f = *state;
  /* Texel centres of the edges land on the domain's ends. */
  ocg_vec2 uv = ocg_atmo_transmittance_uv(f->p, f->p.bottom_radius, 1.0f);
  assert_near(uv.x, 0.5 / OCG_ATMO_TRANSMITTANCE_W, 1e-7);
  assert_near(uv.y, 0.5 / OCG_ATMO_TRANSMITTANCE_H, 1e-7);
  uv = ocg_atmo_transmittance_uv(f->p, f->p.bottom_radius, 0.0f); /* the horizon from the ground */
  assert_near(uv.x, 1.0 - 0.5 / OCG_ATMO_TRANSMITTANCE_W, 1e-6);
  uv = ocg_atmo_transmittance_uv(f->p, f->p.top_radius, 1.0f);
  assert_near(uv.y, 1.0 - 0.5 / OCG_ATMO_TRANSMITTANCE_H, 1e-7);
  for (int i = 0; i <= 10; i++)
    for (int j = 0; j <= 10; j++) {
      ocg_vec2 in = ocg_v2(0.05f + 0.09f * i, 0.05f + 0.09f * j);
      ocg_vec2 rm = ocg_atmo_transmittance_rmu(f->p, in);
      ocg_vec2 back = ocg_atmo_transmittance_uv(f->p, rm.x, rm.y);
      assert_near(back.x, in.x, 2e-3); /* float: r near the ground carries ~0.5 m */
      assert_near(back.y, in.y, 1e-4);
      ocg_vec2 rs = ocg_atmo_rmus_from_uv(f->p, in, 64.0f, 16.0f);
      ocg_vec2 back2 = ocg_atmo_rmus_uv(f->p, rs.x, rs.y, 64.0f, 16.0f);
      assert_near(back2.x, in.x, 1e-6);
      assert_near(back2.y, in.y, 1e-4);
    }
}

/* ---- Transmittance -------------------------------------------------------------------------------------- */

static void test_atmo__zenith_transmittance_analytic(void **state) {
  fix_t *f = *state;
  ref_atm_t m = ref_of(&f->p);
  double H = m.t - m.b;
  for (int c = 0; c < 3; c++) {
    double tau = m.bR[c] * m.HR * (1.0 - exp(-H / m.HR)) + m.bMe * m.HM * (1.0 - exp(-H / m.HM)) + m.bO[c] * m.ow;
    double got = ch(oc_atmo_transmittance(f->a, m.b, 1.0), c);
    print_message("zenith T at the ground, channel %d: table %.8f, exact %.8f (rel %.1e)\n", c, got, exp(-tau),
                  fabs(got / exp(-tau) - 1));
    assert_near(got, exp(-tau), 2e-6 * exp(-tau));
  }
  /* Rayleigh alone: exp(−β H (1 − e^(−100 km/H))), the brief's closed form. */
  ocg_atmosphere q = f->p;
  q.mie_scattering = q.mie_extinction = 0.0f;
  q.ozone_absorption = ocg_v3s(0.0f);
  oc_atmo_t *a = oc_atmo_create(&q, 2);
  assert_non_null(a);
  for (int c = 0; c < 3; c++) {
    double want = exp(-m.bR[c] * m.HR * (1.0 - exp(-H / m.HR)));
    assert_near(ch(oc_atmo_transmittance(a, m.b, 1.0), c), want, 2e-6 * want);
  }
  oc_atmo_free(a);
}

static void test_atmo__transmittance_vs_integration(void **state) {
  fix_t *f = *state;
  ref_atm_t m = ref_of(&f->p);
  const double hs[] = {0.0, 300.0, 1500.0, 5000.0, 12000.0, 33000.0, 70000.0, 99000.0};
  /* Worst errors by regime: relative where T > 0.1 (the visible range), relative where
   * 1e-3 < T ≤ 0.1 (low sun, grazing), absolute everywhere. */
  double rel_hi = 0.0, rel_lo = 0.0, worst_abs = 0.0, at_h = 0.0, at_mu = 0.0, quad = 0.0;
  int samples = 0;
  for (size_t i = 0; i < sizeof hs / sizeof hs[0]; i++) {
    double r = m.b + hs[i];
    double mu_h = -sqrt((r - m.b) * (r + m.b)) / r;
    /* Zenith to the horizon: a fixed set plus cosines just above the horizon (grazing rays; exactly
     * at the horizon the ray touches the ground, which counts as meeting it). */
    double mus[24];
    int n = 0;
    const double fixed[] = {1.0, 0.9, 0.71, 0.5, 0.33, 0.2, 0.13, 0.07, 0.03, 0.011, 0.004};
    for (size_t k = 0; k < sizeof fixed / sizeof fixed[0]; k++)
      if (fixed[k] > mu_h) mus[n++] = fixed[k];
    const double above[] = {1e-5, 1e-4, 1e-3, 3e-3, 1e-2, 2e-2, 5e-2};
    for (size_t k = 0; k < sizeof above / sizeof above[0]; k++) mus[n++] = mu_h + above[k];
    for (int k = 0; k < n; k++) {
      double tau[3];
      ref_tau(&m, r, mus[k], 40000, tau);
      ocg_vec3 got = oc_atmo_transmittance(f->a, r, mus[k]);
      double direct[3];
      oc__atmo_eval(f->a, OC_ATMO_TABLE_TRANSMITTANCE, r, mus[k], direct);
      for (int c = 0; c < 3; c++) {
        double want = exp(-tau[c]), g = ch(got, c);
        double eq = fabs(direct[c] - want) / want;
        if (eq > quad) quad = eq;
        if (!(g >= 0.0 && g <= 1.0)) fail_msg("T(%g m, %g) = %g", hs[i], mus[k], g);
        double ea = fabs(g - want), er = ea / want;
        samples++;
        if (ea > worst_abs) worst_abs = ea;
        if (want > 0.1 && er > rel_hi) {
          rel_hi = er;
          at_h = hs[i];
          at_mu = mus[k];
        }
        if (want > 1e-3 && want <= 0.1 && er > rel_lo) rel_lo = er;
      }
    }
  }
  print_message("transmittance table vs Simpson (40000 steps), %d samples: worst relative error %.2e where T > 0.1 "
                "(h %.0f m, mu %.4f), %.2e where 1e-3 < T <= 0.1; worst absolute %.2e\n",
                samples, rel_hi, at_h, at_mu, rel_lo, worst_abs);
  print_message("transmittance quadrature alone (no table) vs Simpson: worst relative error %.2e\n", quad);
  oc_report("atmosphere", "transmittance table vs 40 000-step Simpson, T > 0.1 (incl. grazing)", rel_hi, 5e-3, "rel");
  oc_report("atmosphere", "transmittance table, 1e-3 < T ≤ 0.1", rel_lo, 3e-2, "rel");
  assert_true(quad < 1e-6);
  assert_true(rel_hi < 5e-3);
  assert_true(rel_lo < 3e-2);
  assert_true(worst_abs < 5e-3);
  /* Exactly at the horizon the ray touches the ground: 0. */
  double r = m.b + 300.0, mu_h = -sqrt(300.0 * (r + m.b)) / r;
  if (ocg_atmo_ray_hits_ground(f->p, (float)r, (float)mu_h)) assert_true(oc_atmo_transmittance(f->a, r, mu_h).x == 0.0f);
}

static void test_atmo__transmittance_range_and_monotone(void **state) {
  fix_t *f = *state;
  const double b = f->p.bottom_radius;
  const double hs[] = {0.0, 10.0, 800.0, 6000.0, 20000.0, 60000.0, 99990.0, 100000.0};
  for (size_t i = 0; i < sizeof hs / sizeof hs[0]; i++) {
    double r = b + hs[i], mu_h = -sqrt(hs[i] * (r + b)) / r;
    double prev[3] = {0.0, 0.0, 0.0};
    for (int k = 0; k <= 4000; k++) {
      double mu = -1.0 + k * (2.0 / 4000);
      ocg_vec3 T = oc_atmo_transmittance(f->a, r, mu);
      for (int c = 0; c < 3; c++) {
        double v = ch(T, c);
        if (!(v >= 0.0 && v <= 1.0)) fail_msg("T(%g, %g) = %g", hs[i], mu, v);
        if (v < prev[c]) fail_msg("T not monotone in mu at h %g mu %g: %g < %g", hs[i], mu, v, prev[c]);
        if (mu < mu_h - 1e-6 && v != 0.0) fail_msg("T(%g, %g) = %g below the horizon", hs[i], mu, v);
        prev[c] = v;
      }
    }
  }
  /* Outside the atmosphere: upward rays see nothing, limb rays equal the entry point's. */
  double t = f->p.top_radius, r = t + 3e5;
  ocg_vec3 up = oc_atmo_transmittance(f->a, r, 0.2);
  assert_true(up.x == 1.0f && up.y == 1.0f && up.z == 1.0f);
  double mu = -0.5, d = -r * mu - sqrt(r * r * (mu * mu - 1) + t * t), mu_in = (r * mu + d) / t;
  assert_near(oc_atmo_transmittance(f->a, r, mu).y, oc_atmo_transmittance(f->a, t, mu_in).y, 1e-6);
  ocg_vec3 z = oc_atmo_transmittance(f->a, NAN, 0.5);
  assert_true(z.x == 0.0f && z.y == 0.0f && z.z == 0.0f);
}

static void test_atmo__sun_transmittance_softened(void **state) {
  fix_t *f = *state;
  const double b = f->p.bottom_radius, alpha = f->p.sun_angular_radius;
  const double hs[] = {0.0, 2000.0, 50000.0, 100000.0};
  for (size_t i = 0; i < sizeof hs / sizeof hs[0]; i++) {
    double r = b + hs[i], sin_h = b / r, cos_h = -sqrt(hs[i] * (r + b)) / r;
    /* Exactly zero once the disc is below the horizon, and well below it. */
    const double below[] = {-1.0, -0.7, cos_h - 0.05, cos_h - 1.01 * alpha * sin_h};
    for (int k = 0; k < 4; k++) {
      ocg_vec3 T = oc_atmo_sun_transmittance(f->a, r, below[k]);
      if (T.x != 0.0f || T.y != 0.0f || T.z != 0.0f) fail_msg("sun T at h %g mu_s %g = %g", hs[i], below[k], T.x);
    }
    /* Fully above: the plain transmittance. */
    const double above[] = {1.0, 0.5, cos_h + 0.1};
    for (int k = 0; k < 3; k++) {
      ocg_vec3 S = oc_atmo_sun_transmittance(f->a, r, above[k]), T = oc_atmo_transmittance(f->a, r, above[k]);
      assert_true(isfinite(S.x) && S.x == T.x && S.y == T.y && S.z == T.z);
    }
    /* Across the disc: the smoothstep, monotone from 0 to T(horizon). */
    double prev = 0.0;
    for (int k = 0; k <= 40; k++) {
      double mus = cos_h + (-1.0 + k / 20.0) * alpha * sin_h;
      double v = oc_atmo_sun_transmittance(f->a, r, mus).x;
      if (v < prev) fail_msg("sun T not monotone across the horizon at h %g", hs[i]);
      prev = v;
    }
    double half = oc_atmo_sun_transmittance(f->a, r, cos_h).x;
    double full = oc_atmo_sun_transmittance(f->a, r, cos_h + alpha * sin_h).x;
    assert_true(half > 0.0 && full > half);
    assert_near(half, 0.5 * oc_atmo_transmittance(f->a, r, cos_h + 1e-7).x, 2e-3 * full + 1e-7);
  }
  /* From space, the planet's shadow still applies; facing the sun, nothing absorbs. */
  double r = f->p.top_radius + 2e6;
  assert_true(oc_atmo_sun_transmittance(f->a, r, -0.999).x == 0.0f);
  assert_true(oc_atmo_sun_transmittance(f->a, r, 0.3).x == 1.0f);
}

/* ---- Sky tables ----------------------------------------------------------------------------------------- */

static void test_atmo__multiscatter_finite_positive(void **state) {
  fix_t *f = *state;
  const double b = f->p.bottom_radius;
  for (int i = 0; i <= 50; i++)
    for (int j = 0; j <= 50; j++) {
      double r = b + 100000.0 * j / 50, mus = -1.0 + 2.0 * i / 50;
      ocg_vec3 p = oc_atmo_multiscatter(f->a, r, mus);
      for (int c = 0; c < 3; c++) {
        double v = ch(p, c);
        if (!(isfinite(v) && v >= 0.0)) fail_msg("psi(%g, %g) = %g", r - b, mus, v);
        if (mus >= -0.1 && !(v > 0.0)) fail_msg("psi(%g, %g) = %g, expected > 0", r - b, mus, v);
      }
    }
  ocg_vec3 noon = oc_atmo_multiscatter(f->a, b, 1.0);
  print_message("psi_ms at the ground, sun at zenith: %.4e %.4e %.4e /sr\n", noon.x, noon.y, noon.z);
  assert_true(noon.x > 5e-3 && noon.z < 0.1 && noon.x < noon.y && noon.y < noon.z);
  ocg_vec3 inf = oc_atmo_multiscatter(f->a, b, NAN);
  assert_true(inf.x == 0.0f);
}

static void test_atmo__irradiance_noon_and_night(void **state) {
  fix_t *f = *state;
  ref_atm_t m = ref_of(&f->p);
  double H = m.t - m.b;
  ocg_vec3 E = oc_atmo_sky_irradiance(f->a, m.b, 1.0);
  /* Thin-atmosphere single scattering with the sun at the zenith: half of the Rayleigh optical depth
   * goes down, and ~0.9 of the Mie (Cornette–Shanks g = 0.8 sends 0.92 of its energy forward). */
  for (int c = 0; c < 3; c++) {
    double tauR = m.bR[c] * m.HR * (1.0 - exp(-H / m.HR)), tauM = m.bMs * m.HM;
    double est = 0.5 * tauR + 0.9 * tauM, got = ch(E, c);
    print_message("sky irradiance at noon, channel %d: %.4e (thin single-scattering estimate %.4e, ratio %.3f)\n", c, got,
                  est, got / est);
    assert_true(got > 0.8 * est && got < 1.25 * est);
  }
  assert_true(E.x < E.y && E.y < E.z); /* the sky is blue */
  /* Night: 30° below the horizon nothing above the observer is lit. */
  ocg_vec3 n = oc_atmo_sky_irradiance(f->a, m.b, -0.5), nf = oc_atmo_sky_fluence(f->a, m.b, -0.5);
  ocg_vec3 dusk = oc_atmo_sky_irradiance(f->a, m.b, -0.2);
  print_message("sky irradiance at mu_s -0.2: %.2e, at -0.5: %.2e; fluence at -0.5: %.2e\n", dusk.z, n.z, nf.z);
  for (int c = 0; c < 3; c++) {
    assert_true(ch(n, c) >= 0.0 && ch(n, c) < 1e-9);
    assert_true(ch(nf, c) >= 0.0 && ch(nf, c) < 1e-9);
    assert_true(ch(dusk, c) < 1e-4 * ch(E, c) * 10.0);
  }
  /* Monotone in the sun's height at the ground (a brighter sky with a higher sun). */
  double prev = 0.0;
  for (int k = 0; k <= 200; k++) {
    double v = oc_atmo_sky_irradiance(f->a, m.b, -1.0 + k / 100.0).z;
    assert_true(v >= prev);
    prev = v;
  }
}

/* At texel centres of the ground row, the fluence table's lower hemisphere is the lit ground seen
 * from the ground, 2π · (a/π)(T_sun μs⁺ + E), so fluence − that is the upper hemisphere's fluence,
 * which lies between E (all light from the zenith) and well under 4E (a bright horizon). */
static void test_atmo__fluence_consistent_with_irradiance(void **state) {
  fix_t *f = *state;
  const double b = f->p.bottom_radius;
  double lo = 1e30, hi = 0.0;
  for (int i = 0; i < OCG_ATMO_IRRADIANCE_W; i++) {
    double mus = mus_centre(i, OCG_ATMO_IRRADIANCE_W);
    if (mus < 0.05) continue;
    ocg_vec3 F = oc_atmo_sky_fluence(f->a, b, mus), E = oc_atmo_sky_irradiance(f->a, b, mus);
    ocg_vec3 T = oc_atmo_sun_transmittance(f->a, b, mus), alb = f->p.ground_albedo;
    for (int c = 0; c < 3; c++) {
      double ground = 2.0 * ch(alb, c) * (ch(T, c) * mus + ch(E, c));
      double up = ch(F, c) - ground, ratio = up / ch(E, c);
      if (ratio < lo) lo = ratio;
      if (ratio > hi) hi = ratio;
    }
  }
  print_message("upper-hemisphere fluence / irradiance at the ground (sun above 3 deg): %.3f .. %.3f\n", lo, hi);
  assert_true(lo > 1.0 && hi < 8.0);
  /* Sun near the zenith: 2 for an isotropic sky, a little more for a sky brighter at the horizon. */
  double mus = mus_centre(OCG_ATMO_IRRADIANCE_W - 1, OCG_ATMO_IRRADIANCE_W);
  ocg_vec3 F = oc_atmo_sky_fluence(f->a, b, mus), E = oc_atmo_sky_irradiance(f->a, b, mus);
  ocg_vec3 T = oc_atmo_sun_transmittance(f->a, b, mus);
  for (int c = 0; c < 3; c++) {
    double up = ch(F, c) - 2.0 * ch(f->p.ground_albedo, c) * (ch(T, c) * mus + ch(E, c));
    assert_true(up / ch(E, c) > 2.0 && up / ch(E, c) < 3.0);
  }
  /* At altitude the fluence grows toward the horizon-lit shell; it stays finite and ≥ 0 everywhere. */
  for (int j = 0; j <= 20; j++)
    for (int i = 0; i <= 40; i++) {
      ocg_vec3 F = oc_atmo_sky_fluence(f->a, b + 5000.0 * j, -1.0 + i / 20.0);
      assert_true(isfinite(F.x) && F.x >= 0.0 && isfinite(F.z) && F.z >= 0.0);
    }
}

/* Look-ups reproduce GL_LINEAR + CLAMP_TO_EDGE on the raw table: the texel value at a texel centre,
 * the mean of two at the midpoint, the edge texel beyond the edge. */
static void test_atmo__lookup_is_gl_bilinear(void **state) {
  fix_t *f = *state;
  int w, h;
  const float *px;
  assert_int_equal(oc_atmo_table(f->a, OC_ATMO_TABLE_IRRADIANCE, &w, &h, &px), 0);
  const double b = f->p.bottom_radius, t = f->p.top_radius, H = sqrt((t - b) * (t + b));
  for (int j = 0; j < h; j++)
    for (int i = 0; i + 1 < w; i++) {
      double xr = (double)j / (h - 1), rho = H * xr, r = sqrt(rho * rho + b * b);
      double mus0 = mus_centre(i, w), musm = mus_of_unit((i + 0.5) / (w - 1)); /* half-way in u */
      const float *a0 = px + 4 * (j * w + i), *a1 = a0 + 4;
      double v0 = oc_atmo_sky_irradiance(f->a, r, mus0).z, vm = oc_atmo_sky_irradiance(f->a, r, musm).z;
      assert_near(v0, a0[2], 1e-5 * a0[2] + 1e-12);
      assert_near(vm, 0.5 * (a0[2] + a1[2]), 1e-5 * a0[2] + 1e-12);
    }
  /* r beyond the top clamps to the top row. */
  assert_true(oc_atmo_sky_irradiance(f->a, t + 5e4, 0.3).y == oc_atmo_sky_irradiance(f->a, t, 0.3).y);
}

/* The (r, μs) tables against their integrals evaluated directly at random points: the interpolation
 * error of 32×32 and 64×32 texels with the ρ/H rows and the rational μs columns. */
static void test_atmo__rmus_tables_interpolation(void **state) {
  fix_t *f = *state;
  static const char *name[] = {"", "multiscatter", "irradiance", "fluence"};
  uint64_t s = 0x243f6a8885a308d3ull;
  for (int which = 1; which < OC_ATMO_TABLE_COUNT; which++) {
    int w, h;
    const float *px;
    oc_atmo_table(f->a, which, &w, &h, &px);
    double vmax[3] = {0.0, 0.0, 0.0};
    for (int i = 0; i < w * h; i++)
      for (int c = 0; c < 3; c++) vmax[c] = fmax(vmax[c], px[4 * i + c]);
    double rel = 0.0, rel_cloud = 0.0, absmax = 0.0, at_h = 0.0, at_mus = 0.0;
    for (int k = 0; k < 160; k++) {
      s = s * 6364136223846793005ull + 1442695040888963407ull;
      double u1 = (double)(s >> 11) / 9007199254740992.0;
      s = s * 6364136223846793005ull + 1442695040888963407ull;
      double u2 = (double)(s >> 11) / 9007199254740992.0;
      /* Half the samples at cloud altitudes (0–15 km). */
      double hgt = (k % 2 ? 15000.0 : 100000.0) * u1, mus = -1.0 + 2.0 * u2, r = f->p.bottom_radius + hgt;
      ocg_vec3 got = which == 1 ? oc_atmo_multiscatter(f->a, r, mus)
                     : which == 2 ? oc_atmo_sky_irradiance(f->a, r, mus)
                                  : oc_atmo_sky_fluence(f->a, r, mus);
      double want[3];
      oc__atmo_eval(f->a, which, r, mus, want);
      for (int c = 0; c < 3; c++) {
        double e = fabs(ch(got, c) - want[c]);
        absmax = fmax(absmax, e / vmax[c]);
        if (want[c] > 0.01 * vmax[c]) {
          double er = e / want[c];
          if (er > rel) {
            rel = er;
            at_h = hgt;
            at_mus = mus;
          }
          if (hgt < 15000.0 && mus > 0.1) rel_cloud = fmax(rel_cloud, er);
        }
      }
    }
    print_message("%s table vs direct quadrature, 160 random points: worst relative error %.2e (h %.0f m, mu_s %.3f) "
                  "where the value > 1%% of the table max, %.2e below 15 km with the sun above 6 deg; worst absolute "
                  "%.2e of the max\n",
                  name[which], rel, at_h, at_mus, rel_cloud, absmax);
    {
      char what[128];
      snprintf(what, sizeof what, "%s table vs direct quadrature, below 15 km, sun above 6°", name[which]);
      oc_report("atmosphere", what, rel_cloud, 0.02, "rel");
    }
    assert_true(absmax < 0.015);
    assert_true(rel_cloud < 0.02);
    assert_true(rel < 0.1);
  }
}

static void test_atmo__threads_identical(void **state) {
  fix_t *f = *state;
  oc_atmo_t *one = oc_atmo_create(&f->p, 1), *three = oc_atmo_create(&f->p, 3);
  assert_non_null(one);
  assert_non_null(three);
  for (int k = 0; k < OC_ATMO_TABLE_COUNT; k++) {
    int w1, h1, w2, h2, w3, h3;
    const float *p1, *p2, *p3;
    oc_atmo_table(one, k, &w1, &h1, &p1);
    oc_atmo_table(f->a, k, &w2, &h2, &p2); /* 2 threads */
    oc_atmo_table(three, k, &w3, &h3, &p3);
    assert_int_equal(memcmp(p1, p2, sizeof(float) * 4 * w1 * h1), 0);
    assert_int_equal(memcmp(p1, p3, sizeof(float) * 4 * w1 * h1), 0);
  }
  oc_atmo_free(one);
  oc_atmo_free(three);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_atmo__params_default),
      cmocka_unit_test(test_atmo__bad_params_rejected),
      cmocka_unit_test(test_atmo__table_accessor),
      cmocka_unit_test(test_atmo__float_geometry_planet_scale),
      cmocka_unit_test(test_atmo__phase_functions_normalised),
      cmocka_unit_test(test_atmo__mappings_round_trip),
      cmocka_unit_test(test_atmo__zenith_transmittance_analytic),
      cmocka_unit_test(test_atmo__transmittance_vs_integration),
      cmocka_unit_test(test_atmo__transmittance_range_and_monotone),
      cmocka_unit_test(test_atmo__sun_transmittance_softened),
      cmocka_unit_test(test_atmo__multiscatter_finite_positive),
      cmocka_unit_test(test_atmo__irradiance_noon_and_night),
      cmocka_unit_test(test_atmo__fluence_consistent_with_irradiance),
      cmocka_unit_test(test_atmo__lookup_is_gl_bilinear),
      cmocka_unit_test(test_atmo__rmus_tables_interpolation),
      cmocka_unit_test(test_atmo__threads_identical),
  };
  return cmocka_run_group_tests_name("atmo", tests, setup, teardown);
}
