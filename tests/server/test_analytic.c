/* test_analytic.c — closed-form media (server/analytic.c) against brute-force ray marching
 * and independent closed forms evaluated in long double. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "analytic.h"
#include "oc_err.h"
#include "oc_planet.h"

/* ---- helpers --------------------------------------------------------------------------------- */

/* |a − b| ≤ tol, reporting both values (cmocka 1.1 has no floating-point assert). */
#define assert_near(a, b, tol)                                                                  \
  do {                                                                                          \
    double a_ = (a), b_ = (b), t_ = (tol);                                                      \
    if (!(fabs(a_ - b_) <= t_)) fail_msg("%s = %.17g, expected %.17g +- %.3g", #a, a_, b_, t_); \
  } while (0)

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;
static double rnd(void) { /* xorshift64*, uniform in [0, 1) */
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return (double)((rng_state * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}
static oc_dvec3 rnd_dir(void) {
  for (;;) {
    oc_dvec3 v = oc_dv3(2 * rnd() - 1, 2 * rnd() - 1, 2 * rnd() - 1);
    double l = oc_dlen(v);
    if (l > 0.1 && l <= 1.0) return oc_dscale(v, 1.0 / l);
  }
}

/* Midpoint-rule optical depth over [0, tmax] with step dt: each boundary crossing costs at most
 * σt·dt, so the error is below crossings·σt·dt. */
static double march(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 d, double tmax, double dt) {
  long n = (long)ceil(tmax / dt);
  double h = tmax / (double)n, s = 0.0;
  for (long i = 0; i < n; i++) s += ocs_medium_sigma_t(m, oc_dmad(p, d, ((double)i + 0.5) * h));
  return s * h;
}

/* |p| in long double: the reference for the slab figures below. */
static long double len_l(oc_dvec3 p) {
  return sqrtl((long double)p.x * p.x + (long double)p.y * p.y + (long double)p.z * p.z);
}

static ocs_medium_t one(const ocs_prim_t *p) {
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, p), 0);
  return m;
}

/* ---- chords vs marching ---------------------------------------------------------------------- */

static void check_random_rays(const ocs_medium_t *m, oc_dvec3 around, double spread, double tmax, double dt,
                              double sigma_max, int rays, int crossings) {
  int hits = 0;
  for (int r = 0; r < rays; r++) {
    oc_dvec3 p = oc_dadd(around, oc_dv3(spread * (2 * rnd() - 1), spread * (2 * rnd() - 1), spread * (2 * rnd() - 1)));
    oc_dvec3 d = rnd_dir();
    if (r % 2) { /* aim odd rays at a random point near the centre, so that many do cross */
      oc_dvec3 aim = oc_dadd(around, oc_dscale(rnd_dir(), 0.4 * spread * rnd()));
      d = oc_dnorm(oc_dsub(aim, p));
    }
    double tm = (r % 3 == 0) ? tmax * (0.2 + 0.8 * rnd()) : tmax; /* some segments end inside */
    double exact = ocs_medium_optical_depth(m, p, d, tm);
    double brute = march(m, p, d, tm, dt);
    double tol = crossings * sigma_max * dt + 1e-9;
    if (fabs(exact - brute) > tol)
      fail_msg("ray %d: exact %.12g brute %.12g diff %.3g tol %.3g", r, exact, brute, exact - brute, tol);
    hits += exact > 0.0;
  }
  assert_true(hits >= rays / 4); /* the rays do cross the medium */
}

static void test_chord__sphere_vs_march(void **state) {
  (void)state;
  ocs_prim_t s;
  assert_int_equal(ocs_prim_sphere(&s, (oc_geo_t){45, 10, 3000}, 1500, 0.02), 0);
  ocs_medium_t m = one(&s);
  check_random_rays(&m, s.sphere.c, 2500, 8000, 0.01, 0.02, 24, 2);
}

static void test_chord__box_vs_march(void **state) {
  (void)state;
  ocs_prim_t b;
  assert_int_equal(ocs_prim_box(&b, (oc_geo_t){-20, 130, 500}, 2000, 800, 600, 30, 0.05), 0);
  ocs_medium_t m = one(&b);
  check_random_rays(&m, b.box.c, 1500, 6000, 0.01, 0.05, 24, 2);
}

static void test_chord__slab_vs_march(void **state) {
  (void)state;
  ocs_prim_t sl;
  assert_int_equal(ocs_prim_slab(&sl, 1000, 2500, 0.003), 0);
  ocs_medium_t m = one(&sl);
  oc_dvec3 c = oc_geo_to_xyz((oc_geo_t){10, -60, 1800});
  check_random_rays(&m, c, 2000, 30000, 0.05, 0.003, 24, 4);
}

static void test_medium__overlaps_add(void **state) {
  (void)state;
  ocs_prim_t a, b, box, sl;
  oc_geo_t g = {-33, 151, 2000};
  assert_int_equal(ocs_prim_sphere(&a, g, 1200, 0.01), 0);
  g.alt = 2600;
  assert_int_equal(ocs_prim_sphere(&b, g, 900, 0.03), 0);
  g.alt = 1000;
  assert_int_equal(ocs_prim_box(&box, g, 1500, 1500, 1000, 45, 0.02), 0);
  assert_int_equal(ocs_prim_slab(&sl, 1500, 2200, 0.001), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &a), 0);
  assert_int_equal(ocs_medium_add(&m, &b), 0);
  assert_int_equal(ocs_medium_add(&m, &box), 0);
  assert_int_equal(ocs_medium_add(&m, &sl), 0);
  oc_dvec3 pa = oc_geo_to_xyz((oc_geo_t){-33, 151, 1900}); /* inside all four */
  assert_near(ocs_medium_sigma_t(&m, pa), 0.01 + 0.03 + 0.02 + 0.001, 1e-15);
  oc_dvec3 c = oc_geo_to_xyz((oc_geo_t){-33, 151, 2000});
  check_random_rays(&m, c, 2000, 9000, 0.01, 0.061, 24, 10);
  /* The sum over prims is the sum of the single-prim depths. */
  ocs_medium_t ma = one(&a), mb = one(&b), mx = one(&box), ms = one(&sl);
  for (int r = 0; r < 16; r++) {
    oc_dvec3 p = oc_dadd(c, oc_dscale(rnd_dir(), 3000 * rnd()));
    oc_dvec3 d = rnd_dir();
    double sum = ocs_medium_tau_sun(&ma, p, d) + ocs_medium_tau_sun(&mb, p, d) + ocs_medium_tau_sun(&mx, p, d) +
                 ocs_medium_tau_sun(&ms, p, d);
    assert_near(ocs_medium_tau_sun(&m, p, d), sum, 1e-12 * (1 + sum));
  }
}

/* ---- grazing rays ---------------------------------------------------------------------------- */

static void test_chord__sphere_grazing(void **state) {
  (void)state;
  const double r = 1500;
  ocs_prim_t s;
  assert_int_equal(ocs_prim_sphere(&s, (oc_geo_t){37, -122, 4000}, r, 1.0), 0);
  oc_enu_t enu = oc_enu_at(s.sphere.c);
  oc_dvec3 d = enu.east, n = enu.north;
  const double deltas[] = {100.0, 1.0, 1e-3, 1e-6};
  for (size_t i = 0; i < sizeof deltas / sizeof deltas[0]; i++) {
    double dl = deltas[i];
    oc_dvec3 p = oc_dmad(oc_dmad(s.sphere.c, n, r - dl), d, -5000.0);
    long double h = sqrtl((long double)dl * (2.0L * r - dl));
    double expect = (double)(2.0L * h);
    /* The origin itself is known to ~ulp(6.4e6 m) = 1e-9 m per coordinate, so the closest
     * approach is uncertain by ~2e-9 m and the half chord by r·2e-9/h. */
    double tol = 4.0 * r * 2e-9 / (double)h + 1e-12 * expect;
    double got = ocs_prim_chord(&s, p, d, INFINITY);
    if (fabs(got - expect) > tol) fail_msg("delta %g: chord %.15g expected %.15g tol %.3g", dl, got, expect, tol);
  }
  /* Clearly outside: nothing. */
  oc_dvec3 p = oc_dmad(oc_dmad(s.sphere.c, n, r + 1e-3), d, -5000.0);
  assert_true(ocs_prim_chord(&s, p, d, INFINITY) == 0.0);
  /* Axis-aligned geometry at planet scale, where every coordinate is exact: a tight check. */
  ocs_prim_t t = s;
  t.sphere.c = oc_dv3(6372000.0, 0.0, 0.0);
  for (double dl = 1.0; dl >= 1e-6; dl *= 1e-2) {
    double y = r - dl; /* the closest approach actually represented */
    oc_dvec3 q = oc_dv3(6372000.0, y, -7000.0);
    long double ly = y;
    double expect = (double)(2.0L * sqrtl(((long double)r - ly) * ((long double)r + ly)));
    assert_near(ocs_prim_chord(&t, q, oc_dv3(0, 0, 1), INFINITY), expect, 1e-14 * expect);
  }
}

static void test_chord__slab_grazing(void **state) {
  (void)state;
  ocs_prim_t sl;
  const double base = 1000, top = 2500;
  assert_int_equal(ocs_prim_slab(&sl, base, top, 1.0), 0);
  long double ri = OC_PLANET_RADIUS + base, ro = OC_PLANET_RADIUS + top;
  /* Horizontal rays in the x = rp plane along +y, from y = -L (outside the slab): every
   * coordinate is exact, so this checks the algorithm itself near both tangencies. */
  const double rps[] = {OC_PLANET_RADIUS + top - 1.0, OC_PLANET_RADIUS + top - 1e-4, OC_PLANET_RADIUS + base + 1e-3,
                        OC_PLANET_RADIUS + base - 1e-3, OC_PLANET_RADIUS + base - 10.0, OC_PLANET_RADIUS + top + 1e-3};
  for (size_t i = 0; i < sizeof rps / sizeof rps[0]; i++) {
    double rp = rps[i];
    long double lrp = rp;
    long double ho = lrp < ro ? sqrtl((ro - lrp) * (ro + lrp)) : 0.0L;
    long double hi = lrp < ri ? sqrtl((ri - lrp) * (ri + lrp)) : 0.0L;
    double expect = (double)(2.0L * (ho - hi));
    oc_dvec3 p = oc_dv3(rp, -400000.0, 0.0);
    double got = ocs_prim_chord(&sl, p, oc_dv3(0, 1, 0), INFINITY);
    /* ulp-level errors in |perp| (1e-9 m) move h by r·1e-9/h. */
    double tol = 1e-9 * (double)ro / (hi > 0 ? (double)hi : (double)ho) + 1e-12 * expect + 1e-12;
    if (fabs(got - expect) > tol)
      fail_msg("rp-R %g: chord %.15g expected %.15g tol %.3g", rp - OC_PLANET_RADIUS, got, expect, tol);
  }
  /* A camera above the slab looking at the horizon: the chord is continuous through the inner
   * tangency (no 0/0, no jump), with a generic (non axis-aligned) direction. */
  oc_dvec3 up = oc_dnorm(oc_dv3(0.3, -0.5, 0.8));
  oc_dvec3 side = oc_dnorm(oc_dcross(up, oc_dv3(0, 0, 1)));
  double prev = -1;
  for (int k = -4; k <= 4; k++) {
    double rp = OC_PLANET_RADIUS + base + k * 1e-3;
    oc_dvec3 p = oc_dmad(oc_dscale(up, rp), side, -300000.0);
    double got = ocs_prim_chord(&sl, p, side, INFINITY);
    long double lrp = rp;
    long double ho = sqrtl((ro - lrp) * (ro + lrp)), hi = lrp < ri ? sqrtl((ri - lrp) * (ri + lrp)) : 0.0L;
    double expect = (double)(2.0L * (ho - hi));
    /* The origin's rounding (~2e-9 m across the ray) moves an inner half chord h by at most
     * √(2·r·2e-9) ≈ 0.16 m at exact tangency, and by r·2e-9/h away from it. */
    double tol = 2.0 * sqrt(2.0 * (double)ri * 4e-9);
    if (fabs(got - expect) > tol) fail_msg("k %d: chord %.12g expected %.12g", k, got, expect);
    /* No jump across the tangency: neighbours 1 mm apart differ by at most ~2·√(2r·1mm) = 0.23 m. */
    if (prev >= 0) assert_true(fabs(got - prev) <= 2.0 * sqrt(2.0 * (double)ri * 1e-3) + tol);
    prev = got;
  }
}

/* ---- origins inside -------------------------------------------------------------------------- */

static void test_tau__inside_sphere(void **state) {
  (void)state;
  ocs_prim_t s;
  assert_int_equal(ocs_prim_sphere(&s, (oc_geo_t){-10, 45, 5000}, 2000, 0.04), 0);
  ocs_medium_t m = one(&s);
  for (int r = 0; r < 32; r++) {
    oc_dvec3 off = oc_dscale(rnd_dir(), 1999.0 * rnd());
    oc_dvec3 d = rnd_dir();
    long double b = (long double)off.x * d.x + (long double)off.y * d.y + (long double)off.z * d.z;
    long double c =
        (long double)off.x * off.x + (long double)off.y * off.y + (long double)off.z * off.z - 2000.0L * 2000.0L;
    double expect = (double)(0.04L * (-b + sqrtl(b * b - c)));
    double got = ocs_medium_tau_sun(&m, oc_dadd(s.sphere.c, off), d);
    /* p = c + off rounds to ~1e-9 m, which moves the exit by up to ~(1 + |b|/h)·1e-9 m. */
    assert_near(got, expect, 1e-10 * expect + 2e-9);
    /* A finite segment that ends inside: σt·tmax. */
    assert_near(ocs_medium_optical_depth(&m, oc_dadd(s.sphere.c, off), d, 1e-3), 0.04 * 1e-3, 1e-15);
  }
}

/* A medium of one slab (base..top m above the ground, σt sig) and a point in it or below it, with
 * the point's local frame and its distance from the planet's centre. */
typedef struct {
  ocs_prim_t prim;
  ocs_medium_t m;
  oc_dvec3 p;
  oc_enu_t enu;
  long double r;
} slab_probe_t;

static void slab_probe(slab_probe_t *s, double base, double top, double sig, oc_geo_t at) {
  assert_int_equal(ocs_prim_slab(&s->prim, base, top, sig), 0);
  s->m = one(&s->prim);
  s->p = oc_geo_to_xyz(at);
  s->enu = oc_enu_at(s->p);
  s->r = len_l(s->p);
}

static void test_tau__inside_slab(void **state) {
  (void)state;
  const double base = 1000, top = 2500, sig = 0.002, h = 1500;
  slab_probe_t s;
  slab_probe(&s, base, top, sig, (oc_geo_t){52, 4, h});
  long double ro = OC_PLANET_RADIUS + top;
  /* Up: σt (top − h). */
  assert_near(ocs_medium_tau_sun(&s.m, s.p, s.enu.up), sig * (top - h), 1e-12);
  /* Horizontal: σt √(r_out² − r²) (the inner sphere is missed). */
  double horiz = (double)(sig * sqrtl((ro - s.r) * (ro + s.r)));
  assert_near(ocs_medium_tau_sun(&s.m, s.p, s.enu.east), horiz, 1e-9 * horiz);
  /* Down: through the ground and the planet, out through the slab on the far side: no planet
   * shadow in τ (Conventions). Straight down: (h − base) + (top − base). */
  assert_near(ocs_medium_tau_sun(&s.m, s.p, oc_dscale(s.enu.up, -1)), sig * ((h - base) + (top - base)), 1e-9);
}

/* ---- τ toward the sun below a slab ----------------------------------------------------------- */

static void test_tau__slab_sun_angles(void **state) {
  (void)state;
  const double base = 2000, top = 3000, sig = 0.01;
  slab_probe_t s;
  slab_probe(&s, base, top, sig, (oc_geo_t){-5, 100, 300});
  oc_dvec3 p = s.p;
  long double rp = s.r;
  const double zenith[3] = {0.0, 60.0, 85.0};
  for (int i = 0; i < 3; i++) {
    double th = zenith[i] * OC_DEG, mu = cos(th);
    oc_dvec3 sun = oc_dadd(oc_dscale(s.enu.up, mu), oc_dscale(s.enu.east, sin(th)));
    /* Distance along the sun ray to radius r: √(r² − rp²(1 − μ²)) − rp μ. */
    long double lmu = (long double)oc_ddot(oc_dnorm(p), oc_dnorm(sun));
    long double s2 = 1.0L - lmu * lmu;
    long double ro = OC_PLANET_RADIUS + top, ri = OC_PLANET_RADIUS + base;
    long double to = sqrtl(ro * ro - rp * rp * s2) - rp * lmu, ti = sqrtl(ri * ri - rp * rp * s2) - rp * lmu;
    double exact = (double)(sig * (to - ti));
    double flat = sig * (top - base) / mu;
    double got = ocs_medium_tau_sun(&s.m, p, sun);
    assert_near(got, exact, 1e-9 * exact);
    if (i == 0) assert_near(got, flat, 1e-9);
    if (i == 1) assert_near(got, flat, 2e-3 * flat); /* curvature: ~tan²θ·z/R = 1.2e-3 */
    if (i == 2) assert_true(got < flat && got > 0.9 * flat);
    print_message("slab tau: zenith %4.1f  exact %.9f  flat (top-base)/mu %.9f\n", zenith[i], got, flat);
    /* From inside the slab: (top − z)/μ type, exact spherical form. */
    oc_dvec3 q = oc_geo_to_xyz((oc_geo_t){-5, 100, 2400});
    long double rq = len_l(q);
    long double tq = sqrtl(ro * ro - rq * rq * s2) - rq * lmu;
    double gq = ocs_medium_tau_sun(&s.m, q, sun);
    assert_near(gq, (double)(sig * tq), 1e-9 * gq);
    if (i == 0) assert_near(gq, sig * (top - 2400), 1e-9);
  }
}

/* ---- the box and its heading ----------------------------------------------------------------- */

static void test_box__heading(void **state) {
  (void)state;
  oc_geo_t g = {30, 20, 1000};
  ocs_prim_t b;
  assert_int_equal(ocs_prim_box(&b, g, 2000, 500, 300, 30, 0.1), 0);
  ocs_medium_t m = one(&b);
  oc_enu_t enu = oc_enu_at(oc_geo_to_xyz(g));
  double c30 = cos(30 * OC_DEG), s30 = sin(30 * OC_DEG);
  oc_dvec3 bn = oc_dadd(oc_dscale(enu.north, c30), oc_dscale(enu.east, s30)); /* heading 30 */
  oc_dvec3 be = oc_dsub(oc_dscale(enu.east, c30), oc_dscale(enu.north, s30));
  assert_true(oc_dlen(oc_dsub(b.box.axis[1], bn)) < 1e-12);
  assert_true(oc_dlen(oc_dsub(b.box.axis[0], be)) < 1e-12);
  /* The centre is half the height above the base. */
  assert_true(oc_dlen(oc_dsub(b.box.c, oc_geo_to_xyz((oc_geo_t){30, 20, 1150}))) < 1e-6);
  /* Chords through the centre (σt = 0.1): along the box axes, and along true north/east. */
  struct { oc_dvec3 d; double len; } cases[] = {
      {bn, 500.0}, {be, 2000.0}, {enu.up, 300.0},
      {enu.north, 2.0 * 250.0 / c30}, /* 30° off the box's north axis: leaves through the long faces */
      {enu.east, 2.0 * 250.0 / s30},  /* 60° off it: through the same faces, 1000 m */
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    oc_dvec3 p = oc_dmad(b.box.c, cases[i].d, -3000.0);
    assert_near(ocs_medium_tau_sun(&m, p, cases[i].d), 0.1 * cases[i].len, 1e-9);
  }
  /* Point tests along true north from the centre: local n = t cos30, e = −t sin30. */
  assert_true(ocs_medium_sigma_t(&m, oc_dmad(b.box.c, enu.north, 280)) == 0.1);
  assert_true(ocs_medium_sigma_t(&m, oc_dmad(b.box.c, enu.north, 300)) == 0.0);
  assert_true(ocs_medium_sigma_t(&m, oc_dmad(b.box.c, enu.east, 490)) == 0.1);
  assert_true(ocs_medium_sigma_t(&m, oc_dmad(b.box.c, enu.east, 510)) == 0.0);
  /* Heading 90: the north edge points east. */
  ocs_prim_t b90;
  assert_int_equal(ocs_prim_box(&b90, g, 2000, 500, 300, 90, 0.1), 0);
  assert_true(oc_dlen(oc_dsub(b90.box.axis[1], enu.east)) < 1e-12);
  assert_true(oc_dlen(oc_dsub(b90.box.axis[0], oc_dscale(enu.north, -1))) < 1e-12);
  ocs_medium_t m90 = one(&b90);
  assert_near(ocs_medium_tau_sun(&m90, oc_dmad(b90.box.c, enu.east, -3000), enu.east), 0.1 * 500, 1e-9);
  assert_near(ocs_medium_tau_sun(&m90, oc_dmad(b90.box.c, enu.north, -3000), enu.north), 0.1 * 2000, 1e-9);
  /* A ray parallel to a face pair, inside and outside that slab. */
  assert_near(ocs_medium_tau_sun(&m, oc_dmad(oc_dmad(b.box.c, bn, 200), be, -5000), be), 0.1 * 2000, 1e-9);
  assert_true(ocs_medium_tau_sun(&m, oc_dmad(oc_dmad(b.box.c, bn, 260), be, -5000), be) == 0.0);
}

/* ---- bounds and box tests -------------------------------------------------------------------- */

static void check_bounds(const ocs_prim_t *pr, oc_dvec3 around, double spread) {
  oc_dvec3 lo, hi;
  ocs_prim_bounds(pr, &lo, &hi);
  int inside = 0;
  for (int i = 0; i < 20000; i++) {
    oc_dvec3 p = oc_dadd(around, oc_dv3(spread * (2 * rnd() - 1), spread * (2 * rnd() - 1), spread * (2 * rnd() - 1)));
    /* A small axis-aligned box around p. */
    double e = spread * 0.02 * rnd();
    oc_dvec3 blo = oc_dsub(p, oc_dv3(e, e, e)), bhi = oc_dadd(p, oc_dv3(e, e, e));
    int meets = ocs_prim_intersects_box(pr, blo, bhi);
    if (ocs_prim_sigma_t(pr, p) > 0) {
      inside++;
      assert_true(p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z);
      assert_true(meets); /* never false for a box that contains a point of the primitive */
    }
    /* A box whose every corner and centre is outside and far from the primitive must not meet it
     * (checked only when the box is outside the prim's AABB, where the answer is sure). */
    if (bhi.x < lo.x || bhi.y < lo.y || bhi.z < lo.z || blo.x > hi.x || blo.y > hi.y || blo.z > hi.z)
      assert_false(meets);
  }
  assert_true(inside > 100);
}

static void test_prim__bounds_and_box_test(void **state) {
  (void)state;
  ocs_prim_t s, b, sl;
  assert_int_equal(ocs_prim_sphere(&s, (oc_geo_t){60, -30, 2000}, 1000, 0.01), 0);
  assert_int_equal(ocs_prim_box(&b, (oc_geo_t){60, -30, 0}, 1500, 400, 700, 73, 0.01), 0);
  assert_int_equal(ocs_prim_slab(&sl, 1000, 2000, 0.01), 0);
  check_bounds(&s, s.sphere.c, 1500);
  check_bounds(&b, b.box.c, 1200);
  check_bounds(&sl, oc_geo_to_xyz((oc_geo_t){60, -30, 1500}), 1500);
  /* Exact answers for the oriented box: a point just outside a face, a box straddling an edge. */
  double e = 1.0;
  oc_dvec3 out = oc_dmad(b.box.c, b.box.axis[0], 750 + 5);
  assert_false(ocs_prim_intersects_box(&b, oc_dsub(out, oc_dv3(e, e, e)), oc_dadd(out, oc_dv3(e, e, e))));
  oc_dvec3 in = oc_dmad(b.box.c, b.box.axis[0], 750 - 0.5);
  assert_true(ocs_prim_intersects_box(&b, oc_dsub(in, oc_dv3(e, e, e)), oc_dadd(in, oc_dv3(e, e, e))));
  /* Slab: a box inside the inner sphere (under the ground), and one in space. */
  oc_dvec3 deep = oc_geo_to_xyz((oc_geo_t){0, 0, -100000});
  assert_false(ocs_prim_intersects_box(&sl, oc_dsub(deep, oc_dv3(10, 10, 10)), oc_dadd(deep, oc_dv3(10, 10, 10))));
  oc_dvec3 high = oc_geo_to_xyz((oc_geo_t){0, 0, 50000});
  assert_false(ocs_prim_intersects_box(&sl, oc_dsub(high, oc_dv3(10, 10, 10)), oc_dadd(high, oc_dv3(10, 10, 10))));
  /* The whole root cube meets it. */
  double S = OC_ROOT_HALF;
  assert_true(ocs_prim_intersects_box(&sl, oc_dv3(-S, -S, -S), oc_dv3(S, S, S)));
  ocs_medium_t m;
  ocs_medium_init(&m);
  oc_dvec3 lo, hi;
  assert_int_equal(ocs_medium_bounds(&m, &lo, &hi), OC_ENOENT);
  assert_int_equal(ocs_medium_add(&m, &s), 0);
  assert_int_equal(ocs_medium_add(&m, &b), 0);
  assert_int_equal(ocs_medium_bounds(&m, &lo, &hi), 0);
  oc_dvec3 slo, shi;
  ocs_prim_bounds(&s, &slo, &shi);
  assert_true(lo.x <= slo.x && hi.z >= shi.z);
}

/* ---- argument checks ------------------------------------------------------------------------- */

static void test_prim__invalid(void **state) {
  (void)state;
  ocs_prim_t p;
  oc_geo_t g = {0, 0, 1000};
  assert_int_equal(ocs_prim_sphere(&p, g, 0, 1), OC_EINVAL);
  assert_int_equal(ocs_prim_sphere(&p, g, 10, -1), OC_EINVAL);
  assert_int_equal(ocs_prim_sphere(&p, g, 10, NAN), OC_EINVAL);
  g.lat = INFINITY;
  assert_int_equal(ocs_prim_sphere(&p, g, 10, 1), OC_EINVAL);
  g.lat = 0;
  assert_int_equal(ocs_prim_box(&p, g, 10, 0, 10, 0, 1), OC_EINVAL);
  assert_int_equal(ocs_prim_box(&p, g, 10, 10, 10, NAN, 1), OC_EINVAL);
  assert_int_equal(ocs_prim_slab(&p, 2000, 2000, 1), OC_EINVAL);
  assert_int_equal(ocs_prim_slab(&p, -7e6, 2000, 1), OC_EINVAL);
  assert_int_equal(ocs_prim_slab(&p, 0, 2000, INFINITY), OC_EINVAL);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_prim_sphere(&p, g, 10, 1), 0);
  for (int i = 0; i < OCS_MEDIUM_MAX_PRIMS; i++) assert_int_equal(ocs_medium_add(&m, &p), 0);
  assert_int_equal(ocs_medium_add(&m, &p), OC_ENOBUFS);
  ocs_prim_t none = {0};
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &none), OC_EINVAL);
  /* Degenerate queries. */
  ocs_medium_add(&m, &p);
  assert_true(ocs_medium_optical_depth(&m, p.sphere.c, oc_dv3(0, 0, 0), 100) == 0.0);
  assert_true(ocs_medium_optical_depth(&m, p.sphere.c, oc_dv3(1, 0, 0), 0) == 0.0);
  assert_true(ocs_medium_optical_depth(&m, p.sphere.c, oc_dv3(1, 0, 0), -5) == 0.0);
  /* A non-unit direction is normalised. */
  assert_near(ocs_medium_optical_depth(&m, p.sphere.c, oc_dv3(3, 0, 0), 5), 5.0, 1e-12);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_chord__sphere_vs_march),  cmocka_unit_test(test_chord__box_vs_march),
      cmocka_unit_test(test_chord__slab_vs_march),    cmocka_unit_test(test_medium__overlaps_add),
      cmocka_unit_test(test_chord__sphere_grazing),   cmocka_unit_test(test_chord__slab_grazing),
      cmocka_unit_test(test_tau__inside_sphere),      cmocka_unit_test(test_tau__inside_slab),
      cmocka_unit_test(test_tau__slab_sun_angles),    cmocka_unit_test(test_box__heading),
      cmocka_unit_test(test_prim__bounds_and_box_test), cmocka_unit_test(test_prim__invalid),
  };
  return cmocka_run_group_tests_name("analytic", tests, NULL, NULL);
}
