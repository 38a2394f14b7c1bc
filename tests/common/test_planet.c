/* test_planet.c — geodetic conversion, ENU frames, view angles and camera-relative precision
 * (common/oc_planet.c); the camera and key worked examples of docs/protocol.md ("Conventions"),
 * recomputed with oc_camera_from_pose() and oc_key.h and compared with the numbers as printed there. */
#include <math.h>
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h> /* strtod, getenv, malloc */
#include <string.h> /* strchr, strlen, strstr */

#include <cmocka.h>

#include "test_main.h"
#include "test_util.h"
#include "report.h"

#include "oc_camera.h"
#include "oc_key.h"
#include "oc_planet.h"

#define R OC_PLANET_RADIUS

static double rng_range(double a, double b) { return a + (b - a) * rng_unit(); }
static oc_dvec3 rng_dir(void) {
  for (;;) {
    oc_dvec3 v = oc_dv3(rng_range(-1, 1), rng_range(-1, 1), rng_range(-1, 1));
    double l = oc_dlen(v);
    if (l > 0.1 && l <= 1.0) return oc_dscale(v, 1.0 / l);
  }
}

static double dist(oc_dvec3 a, oc_dvec3 b) { return oc_dlen(oc_dsub(a, b)); }
/* Smallest angle between two longitudes, degrees. */
static double lon_diff(double a, double b) {
  double d = fmod(fabs(a - b), 360.0);
  return d > 180.0 ? 360.0 - d : d;
}

/*-*** Geodetic ***/

static void test_geo__known_points(void **state) {
  (void)state;
  oc_dvec3 p = oc_geo_to_xyz((oc_geo_t){0, 0, 0});
  assert_true(p.x == R && p.y == 0.0 && p.z == 0.0);
  p = oc_geo_to_xyz((oc_geo_t){0, 90, 0});
  assert_true(p.x == 0.0 && p.y == R && p.z == 0.0);
  p = oc_geo_to_xyz((oc_geo_t){0, 180, 1000});
  assert_true(p.x == -(R + 1000) && p.y == 0.0 && p.z == 0.0);
  p = oc_geo_to_xyz((oc_geo_t){90, 37, 0}); /* any longitude at the pole */
  assert_true(p.x == 0.0 && p.y == 0.0 && p.z == R);
  p = oc_geo_to_xyz((oc_geo_t){-90, -120, 5});
  assert_true(p.x == 0.0 && p.y == 0.0 && p.z == -(R + 5));
  oc_geo_t g = oc_xyz_to_geo(oc_dv3(0, 0, R));
  assert_true(g.lat == 90.0 && g.lon == 0.0 && g.alt == 0.0);
  g = oc_xyz_to_geo(oc_dv3(0, 0, -R - 2));
  assert_true(g.lat == -90.0 && g.lon == 0.0 && g.alt == 2.0);
  g = oc_xyz_to_geo(oc_dv3(-R, 0, 0));
  assert_true(g.lat == 0.0 && g.lon == 180.0 && g.alt == 0.0);
  g = oc_xyz_to_geo(oc_dv3(-R, -0.0, 0)); /* -180 is reported as 180: lon in (-180, 180] */
  assert_true(g.lon == 180.0);
  g = oc_xyz_to_geo(oc_dv3(0, -R, 0));
  assert_true(g.lon == -90.0);
  g = oc_xyz_to_geo(oc_dv3(R, R, R));
  assert_true(fabs(g.lon - 45.0) < 1e-13 && fabs(g.lat - atan(1 / sqrt(2.0)) / OC_DEG) < 1e-12);
}

static void test_geo__lon_wrap(void **state) {
  (void)state;
  for (int n = 0; n < 1000; n++) {
    double lat = rng_range(-90, 90), lon = rng_range(-180, 180), alt = rng_range(-1000, 1e5);
    oc_dvec3 a = oc_geo_to_xyz((oc_geo_t){lat, lon, alt});
    oc_dvec3 b = oc_geo_to_xyz((oc_geo_t){lat, lon + 360.0, alt});
    oc_dvec3 c = oc_geo_to_xyz((oc_geo_t){lat, lon - 720.0, alt});
    assert_true(dist(a, b) < 1e-6 && dist(a, c) < 1e-6);
  }
  oc_geo_t g = oc_xyz_to_geo(oc_geo_to_xyz((oc_geo_t){10, 190, 0}));
  assert_true(fabs(g.lon - -170.0) < 1e-11);
  g = oc_xyz_to_geo(oc_geo_to_xyz((oc_geo_t){10, -180, 0}));
  assert_true(g.lon == 180.0);
}

static void test_geo__round_trip(void **state) {
  (void)state;
  static const double alts[] = {-1000, 0, 1, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8};
  static const double lats[] = {-90, -89.999999, -45, 0, 30, 89.9999999, 90};
  static const double lons[] = {-180, -179.9999999, -90, 0, 45, 179.9999999, 180};
  double worst_pos = 0, worst_ang = 0;
  for (int n = 0; n < 20000; n++) {
    oc_geo_t g;
    if (n < 9 * 7 * 7) {
      g = (oc_geo_t){lats[n / 9 % 7], lons[n / 63], alts[n % 9]};
    } else {
      g.lat = rng_range(-90, 90);
      g.lon = rng_range(-180, 180);
      g.alt = rng_range(-1000, 1e8 * rng_unit() * rng_unit());
    }
    oc_dvec3 p = oc_geo_to_xyz(g);
    oc_geo_t h = oc_xyz_to_geo(p);
    double r = R + g.alt;
    /* Altitude to a few ulps of the radius (three roundings in x, y, z and two in hypot), angles
     * to ~1e-14 rad of arc. */
    assert_true(fabs(h.alt - g.alt) <= 1e-15 * r + 1e-9);
    assert_true(fabs(h.lat - g.lat) <= 1e-12);
    assert_true(h.lon > -180.0 && h.lon <= 180.0);
    assert_true(h.lat >= -90.0 && h.lat <= 90.0);
    if (fabs(g.lat) != 90.0) {
      double d = lon_diff(h.lon, g.lon) * cos(g.lat * OC_DEG);
      if (d > worst_ang) worst_ang = d;
      assert_true(d <= 1e-12);
    } else {
      assert_true(h.lon == 0.0); /* pole convention */
    }
    /* And back: the same point. */
    double e = dist(oc_geo_to_xyz(h), p);
    if (e / r > worst_pos) worst_pos = e / r;
    assert_true(e <= 1e-15 * r * 8);
  }
  /* Cartesian first: random points from near the centre to 1e8 m. */
  for (int n = 0; n < 20000; n++) {
    oc_dvec3 p = oc_dscale(rng_dir(), rng_range(R - 1000, R + 1e8 * rng_unit()));
    double e = dist(oc_geo_to_xyz(oc_xyz_to_geo(p)), p);
    assert_true(e <= 8e-16 * oc_dlen(p));
  }
  print_message("geo round trip: worst position error %.3g x radius, worst lon error %.3g deg of arc\n",
                worst_pos, worst_ang);
}

/*-*** ENU and view angles ***/

static void check_enu(oc_enu_t f, oc_dvec3 p) {
  const double eps = 1e-14;
  assert_true(fabs(oc_dlen(f.east) - 1) < eps && fabs(oc_dlen(f.north) - 1) < eps && fabs(oc_dlen(f.up) - 1) < eps);
  assert_true(fabs(oc_ddot(f.east, f.north)) < eps && fabs(oc_ddot(f.east, f.up)) < eps &&
              fabs(oc_ddot(f.north, f.up)) < eps);
  /* Right-handed: east × north = up. */
  assert_true(dist(oc_dcross(f.east, f.north), f.up) < eps);
  /* Up is radial, east horizontal (no z), north points toward +Z unless at a pole. */
  assert_true(dist(f.up, oc_dnorm(p)) < eps);
  assert_true(f.east.z == 0.0);
  assert_true(f.north.z >= 0.0);
}

static void test_enu__orthonormal_right_handed(void **state) {
  (void)state;
  for (int n = 0; n < 20000; n++) {
    oc_dvec3 p = oc_dscale(rng_dir(), rng_range(1.0, 1e8));
    check_enu(oc_enu_at(p), p);
  }
  /* Known frames: lat 0 lon 0 is (E, N, U) = (+Y, +Z, +X); lat 0 lon 90 is (-X, +Z, +Y). */
  oc_enu_t f = oc_enu_at(oc_geo_to_xyz((oc_geo_t){0, 0, 0}));
  assert_true(dist(f.east, oc_dv3(0, 1, 0)) == 0 && dist(f.north, oc_dv3(0, 0, 1)) == 0 && dist(f.up, oc_dv3(1, 0, 0)) == 0);
  f = oc_enu_at(oc_geo_to_xyz((oc_geo_t){0, 90, 0}));
  assert_true(dist(f.east, oc_dv3(-1, 0, 0)) == 0 && dist(f.north, oc_dv3(0, 0, 1)) == 0);
  /* Poles: east +Y; north -X at the north pole, +X at the south pole (the limit along lon 0). */
  f = oc_enu_at(oc_dv3(0, 0, R));
  check_enu(f, oc_dv3(0, 0, R));
  assert_true(dist(f.east, oc_dv3(0, 1, 0)) == 0 && dist(f.north, oc_dv3(-1, 0, 0)) == 0);
  f = oc_enu_at(oc_dv3(0, 0, -R));
  assert_true(dist(f.east, oc_dv3(0, 1, 0)) == 0 && dist(f.north, oc_dv3(1, 0, 0)) == 0 && dist(f.up, oc_dv3(0, 0, -1)) == 0);
  assert_true(dist(oc_dcross(f.east, f.north), f.up) == 0);
  /* Continuous approaching the pole along lon 0, and finite for a tiny offset off the axis. */
  oc_enu_t near = oc_enu_at(oc_geo_to_xyz((oc_geo_t){89.9999999, 0, 0}));
  assert_true(dist(near.north, oc_dv3(-1, 0, 0)) < 1e-8 && dist(near.east, oc_dv3(0, 1, 0)) < 1e-8);
  f = oc_enu_at(oc_dv3(1e-300, 0, R));
  check_enu(f, oc_dv3(1e-300, 0, R));
}

static void test_view__known_directions(void **state) {
  (void)state;
  oc_enu_t f = oc_enu_at(oc_geo_to_xyz((oc_geo_t){0, 0, 0}));
  /* Heading 0, pitch 0 at the equator points north, +Z; heading 90 points east, +Y. */
  oc_dvec3 d = oc_heading_pitch_dir(f, 0, 0);
  assert_true(d.x == 0.0 && d.y == 0.0 && d.z == 1.0);
  d = oc_heading_pitch_dir(f, 90, 0);
  assert_true(d.x == 0.0 && d.y == 1.0 && d.z == 0.0);
  assert_true(dist(d, f.east) == 0.0);
  d = oc_heading_pitch_dir(f, 180, 0);
  assert_true(d.z == -1.0);
  d = oc_heading_pitch_dir(f, 270, 0);
  assert_true(d.y == -1.0);
  d = oc_heading_pitch_dir(f, -90, 0);
  assert_true(d.y == -1.0);
  d = oc_heading_pitch_dir(f, 123, 90); /* straight up: the heading does not matter */
  assert_true(dist(d, f.up) < 1e-16);
  d = oc_heading_pitch_dir(f, 0, -90);
  assert_true(d.x == -1.0);
  d = oc_heading_pitch_dir(f, 45, 0);
  assert_true(fabs(d.y - sqrt(0.5)) < 3e-16 && fabs(d.z - sqrt(0.5)) < 3e-16);
  /* Elsewhere: heading 90 is the frame's east, pitch up tilts toward the frame's up. */
  oc_dvec3 p = oc_geo_to_xyz((oc_geo_t){48.85, 2.35, 300});
  f = oc_enu_at(p);
  assert_true(dist(oc_heading_pitch_dir(f, 90, 0), f.east) < 1e-16);
  assert_true(dist(oc_heading_pitch_dir(f, 0, 0), f.north) < 1e-16);
  d = oc_heading_pitch_dir(f, 0, 30);
  assert_true(fabs(oc_ddot(d, f.up) - 0.5) < 1e-15);
  /* Clockwise from north: heading 90 is to the right of heading 0 seen from above. */
  assert_true(oc_ddot(oc_dcross(oc_heading_pitch_dir(f, 0, 0), oc_heading_pitch_dir(f, 90, 0)), f.up) < 0);
}

static void test_view__heading_pitch_round_trip(void **state) {
  (void)state;
  for (int n = 0; n < 20000; n++) {
    oc_dvec3 p = oc_dscale(rng_dir(), rng_range(R - 1000, R + 1e8));
    if (n == 0) p = oc_dv3(0, 0, R);
    if (n == 1) p = oc_dv3(0, 0, -R);
    oc_enu_t f = oc_enu_at(p);
    double h = rng_range(0, 360), t = rng_range(-89.9, 89.9);
    oc_dvec3 d = oc_heading_pitch_dir(f, h, t);
    assert_true(fabs(oc_dlen(d) - 1.0) < 1e-15);
    double h2, t2;
    oc_dir_heading_pitch(f, d, &h2, &t2);
    assert_true(h2 >= 0.0 && h2 < 360.0);
    assert_true(lon_diff(h, h2) < 1e-10);
    assert_true(fabs(t - t2) < 1e-12);
    /* Scale does not matter. */
    oc_dir_heading_pitch(f, oc_dscale(d, 1234.5), &h2, &t2);
    assert_true(lon_diff(h, h2) < 1e-10 && fabs(t - t2) < 1e-12);
  }
  oc_enu_t f = oc_enu_at(oc_dv3(R, 0, 0));
  double h, t;
  oc_dir_heading_pitch(f, f.up, &h, &t);
  assert_true(t == 90.0 && h == 0.0); /* undefined heading comes back as 0 */
  oc_dir_heading_pitch(f, oc_dscale(f.east, -1.0), &h, &t);
  assert_true(h == 270.0 && t == 0.0);
  oc_dir_heading_pitch(f, oc_dscale(f.north, -1.0), &h, &t);
  assert_true(h == 180.0);
  oc_dir_heading_pitch(f, oc_dv3(0, -1e-300, 1), &h, &t); /* a hair west of north: not 360 */
  assert_true(h >= 0.0 && h < 360.0);
}

/*-*** Camera-relative positions ***/

typedef struct {
  double point, node, naive, node_dist; /**< max errors (m); farthest node origin tested (m) */
} errs_t;

static void errs_merge(errs_t *a, errs_t b) {
  a->point = fmax(a->point, b.point);
  a->node = fmax(a->node, b.node);
  a->naive = fmax(a->naive, b.naive);
  a->node_dist = fmax(a->node_dist, b.node_dist);
}

/* Largest per-axis error of a float relative position against the double answer. */
static double axis_err(const float out[3], oc_dvec3 want) {
  double e = fabs((double)out[0] - want.x);
  e = fmax(e, fabs((double)out[1] - want.y));
  return fmax(e, fabs((double)out[2] - want.z));
}

static double naive_err(oc_dvec3 p, oc_dvec3 cam) {
  float out[3] = {(float)p.x - (float)cam.x, (float)p.y - (float)cam.y, (float)p.z - (float)cam.z};
  return axis_err(out, oc_dsub(p, cam));
}

/* A camera plus points 1..1000 m from it, through oc_camrel_point(), and when `nodes` is set the
 * level-16..21 node around each point through oc_camrel_node() (origins up to ~1.2 km away). */
static errs_t camrel_errors(oc_dvec3 cam, int count, bool nodes) {
  errs_t w = {0, 0, 0, 0};
  oc_camrel_t c = oc_camrel_make(cam);
  for (int a = 0; a < 3; a++) assert_true(c.frac[a] >= 0.0f && c.frac[a] < 1.0f);
  double cc[3] = {cam.x, cam.y, cam.z};
  for (int a = 0; a < 3; a++) {
    double back = -OC_ROOT_HALF + ((double)c.cell[a] + (double)c.frac[a]) * OC_CELL21_SIZE;
    assert_true(fabs(back - cc[a]) < 1e-6);
  }
  for (int n = 0; n < count; n++) {
    oc_dvec3 p = oc_dmad(cam, rng_dir(), 1.0 + 999.0 * rng_unit());
    float out[3];
    oc_camrel_point(&c, p, out);
    w.point = fmax(w.point, axis_err(out, oc_dsub(p, cam)));
    w.naive = fmax(w.naive, naive_err(p, cam));
    if (!nodes) continue;
    int level = 16 + (int)(rng_u64() % 6);
    oc_key_t k = oc_key_from_point(level, p);
    assert_true(oc_key_valid(k));
    oc_dvec3 o;
    oc_key_bounds(k, &o, NULL);
    oc_camrel_node(&c, k, out);
    w.node = fmax(w.node, axis_err(out, oc_dsub(o, cam)));
    w.naive = fmax(w.naive, naive_err(o, cam));
    w.node_dist = fmax(w.node_dist, dist(o, cam));
  }
  return w;
}

static void test_camrel__precision(void **state) {
  (void)state;
  static const double radii[2] = {R, 1e7};
  errs_t all = {0, 0, 0, 0};
  for (int ri = 0; ri < 2; ri++) {
    errs_t r = {0, 0, 0, 0};
    for (int m = 0; m < 200; m++) {
      oc_dvec3 cam = oc_dscale(rng_dir(), radii[ri]);
      /* Nodes exist only inside the root cube; a 1e7 m camera is often outside it. */
      bool inside = fabs(cam.x) < OC_ROOT_HALF - 2000 && fabs(cam.y) < OC_ROOT_HALF - 2000 &&
                    fabs(cam.z) < OC_ROOT_HALF - 2000;
      errs_merge(&r, camrel_errors(cam, 200, inside));
    }
    /* On an axis (outside the cube at 1e7 m), and near the diagonal (inside it). */
    errs_merge(&r, camrel_errors(oc_dv3(radii[ri], 0, 0), 2000, ri == 0));
    errs_merge(&r, camrel_errors(oc_dscale(oc_dnorm(oc_dv3(1, 0.97, 1.03)), radii[ri]), 2000, true));
    print_message("camera %.4g m from the centre, points 1..1000 m away: max per-axis error "
                  "oc_camrel_point %.3g m, oc_camrel_node %.3g m (origins up to %.0f m away), "
                  "naive (float)p - (float)cam %.3g m\n",
                  radii[ri], r.point, r.node, r.node_dist, r.naive);
    errs_merge(&all, r);
  }
  oc_report("frames", "camera-relative position 1..1000 m from a camera 1e7 m out (oc_camrel)", fmax(all.point, all.node), 1e-3, "m");
  oc_report_above("frames", "same with absolute floats (float)p - (float)cam: fails", all.naive, 0.1, "m");
  assert_true(all.point < 1e-3 && all.node < 1e-3);
  assert_true(all.naive > 0.1);
}

static void test_camrel__node_exact_offsets(void **state) {
  (void)state;
  /* A camera exactly on a level-21 corner: node offsets are whole multiples of the cell. */
  oc_key_t k = oc_key_make(21, 1000000, 1500000, 2000000);
  oc_dvec3 o;
  oc_key_bounds(k, &o, NULL);
  oc_camrel_t c = oc_camrel_make(o);
  assert_true(c.frac[0] == 0.0f && c.frac[1] == 0.0f && c.frac[2] == 0.0f);
  float out[3];
  oc_camrel_node(&c, k, out);
  assert_true(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);
  oc_camrel_node(&c, oc_key_neighbor(k, 3, -2, 0), out);
  assert_true(out[0] == (float)(3 * OC_CELL21_SIZE) && out[1] == (float)(-2 * OC_CELL21_SIZE) && out[2] == 0.0f);
  /* A coarse node: its origin is the level-21 cell i·2^(21-L). */
  oc_key_t a = oc_key_ancestor(k, 10);
  oc_dvec3 ao;
  oc_key_bounds(a, &ao, NULL);
  oc_camrel_node(&c, a, out);
  assert_true(fabs(out[0] - (ao.x - o.x)) <= 1e-7 * fabs(ao.x - o.x) + 1e-6);
  /* Far nodes keep float's relative precision. */
  oc_camrel_node(&c, OC_KEY_ROOT, out);
  assert_true(fabs(out[0] - (-OC_ROOT_HALF - o.x)) <= 1e-7 * fabs(-OC_ROOT_HALF - o.x));
  /* Invalid input. */
  oc_camrel_node(&c, 2, out);
  assert_true(isnan(out[0]) && isnan(out[1]) && isnan(out[2]));
  oc_camrel_node(NULL, k, out);
  assert_true(isnan(out[0]));
  oc_camrel_point(NULL, o, out);
  assert_true(isnan(out[0]));
}

static void test_camrel__far_and_outside(void **state) {
  (void)state;
  /* Outside the root cube the cells run negative or past 2^21: int64, no wrap. */
  oc_dvec3 cam = oc_dv3(-1e7, 3e7, -1e8);
  oc_camrel_t c = oc_camrel_make(cam);
  assert_true(c.cell[0] < 0 && c.cell[1] > (1 << 21) && c.cell[2] < 0);
  float out[3];
  oc_dvec3 p = oc_dadd(cam, oc_dv3(0.25, -0.5, 10.0));
  oc_camrel_point(&c, p, out);
  assert_true(fabs(out[0] - 0.25) < 1e-4 && fabs(out[1] + 0.5) < 1e-4 && fabs(out[2] - 10.0) < 1e-4);
  /* The planet centre seen from there: relative precision of a float. */
  oc_camrel_point(&c, oc_dv3(0, 0, 0), out);
  assert_true(fabs(out[2] - 1e8) <= 1e8 * 1.2e-7);
  /* Non-finite input stays defined (no undefined int conversion under UBSan). */
  c = oc_camrel_make(oc_dv3(NAN, INFINITY, -INFINITY));
  (void)c;
  /* A value a hair below a cell boundary never yields frac == 1. */
  for (int n = 0; n < 1000; n++) {
    double x = -OC_ROOT_HALF + (double)(rng_u64() % 4000000) * OC_CELL21_SIZE - 2000000.0 * OC_CELL21_SIZE;
    c = oc_camrel_make(oc_dv3(nextafter(x, -INFINITY), x, nextafter(x, INFINITY)));
    for (int a = 0; a < 3; a++) assert_true(c.frac[a] >= 0.0f && c.frac[a] < 1.0f);
  }
}

/*-*** The worked examples of docs/protocol.md ("Conventions") ***/

/* docs/protocol.md, read once when OC_SOURCE_DIR is set (ctest sets it): every number below must
 * appear there as written, so the page and this test cannot part silently. NULL when run by hand
 * without it (the numbers are still checked against the code). */
static char *g_doc;

static char *read_doc(void) {
  const char *src = getenv("OC_SOURCE_DIR");
  if (!src) return NULL;
  char path[1024];
  snprintf(path, sizeof path, "%s/docs/protocol.md", src);
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  char *buf = malloc(1u << 20);
  assert_non_null(buf);
  size_t n = fread(buf, 1, (1u << 20) - 1, f);
  fclose(f);
  buf[n] = '\0';
  return buf;
}

/* `got` equals the decimal `text` to its printed precision: within half a unit of its last
 * digit (and a hair more for the rounding of the comparison itself). */
static void assert_printed(double got, const char *text) {
  const char *dot = strchr(text, '.');
  int decimals = dot ? (int)strlen(dot + 1) : 0;
  double want = strtod(text, NULL), tol = 0.5 * pow(10.0, -decimals) * (1.0 + 1e-9);
  if (!(fabs(got - want) <= tol)) fail_msg("computed %.17g, the doc says %s", got, text);
}

/* A vector as the doc prints it, "(x, y, z)": each component to its precision, and the text on
 * the page. */
static void assert_vec(oc_dvec3 got, const char *x, const char *y, const char *z) {
  assert_printed(got.x, x);
  assert_printed(got.y, y);
  assert_printed(got.z, z);
  char line[160];
  snprintf(line, sizeof line, "(%s, %s, %s)", x, y, z);
  if (g_doc && !strstr(g_doc, line)) fail_msg("docs/protocol.md no longer shows %s", line);
}

static void assert_doc_has(const char *text) {
  if (g_doc && !strstr(g_doc, text)) fail_msg("docs/protocol.md no longer shows \"%s\"", text);
}

static void test_doc__camera_examples(void **state) {
  (void)state;
  g_doc = read_doc();
  /* lat 46.5, lon 8, alt 2000 m, heading 30, pitch 10, fov 60 */
  assert_doc_has("lat 46.5, lon 8.0, alt 2000 m, heading 30, pitch 10, fov 60");
  oc_camera_t c = oc_camera_from_pose((oc_camera_pose_t){{46.5, 8.0, 2000.0}, 30.0, 10.0, 60.0});
  oc_enu_t f = oc_enu_at(c.pos);
  assert_vec(c.pos, "4344190.860", "610536.210", "4622810.866");
  assert_vec(f.east, "-0.139173101", "0.990268069", "0");
  assert_vec(f.north, "-0.718315077", "-0.100952601", "0.688354576");
  assert_vec(f.up, "0.681655556", "0.0958004409", "0.725374371");
  assert_vec(c.forward, "-0.562789455", "0.418148112", "0.713035894");
  assert_vec(c.right, "0.238630098", "0.908073604", "-0.344177288");
  assert_vec(c.up, "0.791406157", "0.0235475231", "0.610836974");
  assert_true(c.vfov_deg == 60.0);
  /* The closed forms the doc gives agree with the cross products the code takes. */
  double sh = sin(30 * OC_DEG), ch = cos(30 * OC_DEG), sp = sin(10 * OC_DEG), cp = cos(10 * OC_DEG);
  oc_dvec3 fw = oc_dmad(oc_dmad(oc_dscale(f.east, cp * sh), f.north, cp * ch), f.up, sp);
  oc_dvec3 rt = oc_dmad(oc_dscale(f.east, ch), f.north, -sh);
  oc_dvec3 up = oc_dmad(oc_dmad(oc_dscale(f.east, -sp * sh), f.north, -sp * ch), f.up, cp);
  assert_true(dist(fw, c.forward) < 1e-15 && dist(rt, c.right) < 1e-15 && dist(up, c.up) < 1e-15);
  /* The default camera of scenes/planet.json (and the built-in planet): 45, 0, 2000, 260, -5, 60. */
  assert_doc_has("lat 45, lon 0, alt 2000 m, heading 260, pitch -5, fov 60");
  c = oc_camera_from_pose((oc_camera_pose_t){{45.0, 0.0, 2000.0}, 260.0, -5.0, 60.0});
  assert_vec(c.pos, "4506391.517", "0.000", "4506391.517");
  assert_vec(c.forward, "0.0606921426", "-0.981060262", "-0.183948976");
  assert_vec(c.up, "0.715117689", "-0.0858316512", "0.693714364");
  /* Straight up the heading is lost: right = forward × north, the camera's up is local north. */
  c = oc_camera_from_pose((oc_camera_pose_t){{46.5, 8.0, 2000.0}, 30.0, 90.0, 60.0});
  assert_true(dist(c.forward, f.up) < 1e-15 && dist(c.up, f.north) < 1e-15);
  assert_true(dist(c.right, oc_dscale(f.east, -1.0)) < 1e-15);
  free(g_doc);
  g_doc = NULL;
}

static void test_doc__key_examples(void **state) {
  (void)state;
  g_doc = read_doc();
  /* Level 2, cell (1, 2, 3): sentinel 1 << 6, then the (z y x) bit triples 101 (bit 0 of each)
   * and 110 (bit 1 of each). */
  assert_true(oc_key_make(2, 1, 2, 3) == 0x75);
  assert_doc_has("0x75");
  assert_true(oc_key_parent(0x75) == 0xE && oc_key_child(0xE, 5) == 0x75);
  /* The level-10 node holding the first camera's eye. */
  oc_dvec3 eye = oc_geo_to_xyz((oc_geo_t){46.5, 8.0, 2000.0});
  oc_key_t k = oc_key_from_point(10, eye);
  assert_true(k == 0x7D17394Dull);
  assert_doc_has("0x7d17394d");
  uint32_t ix, iy, iz;
  oc_key_coords(k, &ix, &iy, &iz);
  assert_true(ix == 855 && iy == 560 && iz == 877);
  assert_doc_has("(855, 560, 877)");
  oc_dvec3 o;
  double s;
  oc_key_bounds(k, &o, &s);
  assert_true(s == 12638.671875 && o.x == 4335064.453125 && o.y == 606656.25 && o.z == 4613115.234375);
  assert_doc_has("12638.671875");
  assert_doc_has("(4335064.453125, 606656.25, 4613115.234375)");
  assert_true(OC_ROOT_HALF == 6471000.0 && OC_PLANET_RADIUS == 6371000.0);
  free(g_doc);
  g_doc = NULL;
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_geo__known_points),
             cmocka_unit_test(test_geo__lon_wrap),
             cmocka_unit_test(test_geo__round_trip),
             cmocka_unit_test(test_enu__orthonormal_right_handed),
             cmocka_unit_test(test_view__known_directions),
             cmocka_unit_test(test_view__heading_pitch_round_trip),
             cmocka_unit_test(test_camrel__precision),
             cmocka_unit_test(test_camrel__node_exact_offsets),
             cmocka_unit_test(test_camrel__far_and_outside),
             cmocka_unit_test(test_doc__camera_examples),
             cmocka_unit_test(test_doc__key_examples))
