/* oc_planet.c — geodetic coordinates, local ENU frames, view angles and camera-relative
 * positions (oc_planet.h).
 *
 * Angles are reduced in degrees before any trigonometry (as GeographicLib's sincosd/atan2d), so
 * the cardinal angles are exact: lat ±90 gives x = y = 0, lon 180 gives y = 0, heading 90 is
 * exactly east. */
#include "oc_planet.h"

#include <math.h> /* remquo, sin, cos, atan2, hypot, floor, isfinite, copysign */

/*-*** Angles in degrees ***/

/* sin and cos of an angle in degrees, exact at multiples of 90: remquo reduces to [-45, 45]
 * without rounding, and the quadrant is applied by swapping and negating. */
static void oc__sincosd(double deg, double *s_out, double *c_out) {
  int q = 0;
  double r = remquo(deg, 90.0, &q) * OC_DEG;
  double s = sin(r), c = cos(r);
  switch ((unsigned)q & 3u) {
    case 0u: *s_out = s; *c_out = c; break;
    case 1u: *s_out = c; *c_out = -s; break;
    case 2u: *s_out = -s; *c_out = -c; break;
    default: *s_out = -c; *c_out = s; break;
  }
  *c_out += 0.0; /* -0 → +0, so cos of a right angle never carries a sign into a product */
}

/* atan2(y, x) in degrees in [-180, 180], exact on the axes and diagonals: the arguments are
 * swapped and reflected so that atan2 itself only sees [-45°, 45°]. */
static double oc__atan2d(double y, double x) {
  int q = 0;
  if (fabs(y) > fabs(x)) {
    double t = x;
    x = y;
    y = t;
    q = 2;
  }
  if (signbit(x)) {
    x = -x;
    q++;
  }
  double a = atan2(y, x) / OC_DEG;
  switch (q) {
    case 1: return copysign(180.0, y) - a;
    case 2: return 90.0 - a;
    case 3: return -90.0 + a;
    default: return a;
  }
}

/*-*** Geodetic ***/

oc_dvec3 oc_geo_to_xyz(oc_geo_t g) {
  double slat, clat, slon, clon;
  oc__sincosd(g.lat, &slat, &clat);
  oc__sincosd(g.lon, &slon, &clon);
  double r = OC_PLANET_RADIUS + g.alt;
  return oc_dv3(r * clat * clon, r * clat * slon, r * slat);
}

oc_geo_t oc_xyz_to_geo(oc_dvec3 p) {
  double h = hypot(p.x, p.y);
  oc_geo_t g;
  g.lat = oc__atan2d(p.z, h);
  /* On the axis the poles report lon 0, the limit oc_enu_at() uses (tested explicitly: signed
   * zeros would make atan2 say ±180). */
  g.lon = h > 0.0 ? oc__atan2d(p.y, p.x) : 0.0;
  if (g.lon <= -180.0) g.lon += 360.0; /* (-180, 180] */
  g.alt = hypot(h, p.z) - OC_PLANET_RADIUS;
  return g;
}

/*-*** Local frames and view angles ***/

oc_enu_t oc_enu_at(oc_dvec3 p) {
  oc_enu_t f;
  double h = hypot(p.x, p.y), r = hypot(h, p.z);
  f.up = r > 0.0 ? oc_dv3(p.x / r, p.y / r, p.z / r) : oc_dv3(0.0, 0.0, 1.0);
  /* East is Z × up, horizontal. Dividing by h (not multiplying by 1/h) stays finite for tiny h;
   * on the axis itself it is +Y, the limit along lon 0, which makes north -X at the north pole
   * and +X at the south pole. */
  f.east = h > 0.0 ? oc_dv3(-p.y / h, p.x / h, 0.0) : oc_dv3(0.0, 1.0, 0.0);
  f.north = oc_dcross(f.up, f.east);
  return f;
}

oc_dvec3 oc_heading_pitch_dir(oc_enu_t enu, double heading_deg, double pitch_deg) {
  double sh, ch, sp, cp;
  oc__sincosd(heading_deg, &sh, &ch);
  oc__sincosd(pitch_deg, &sp, &cp);
  oc_dvec3 d = oc_dscale(enu.east, cp * sh);
  d = oc_dmad(d, enu.north, cp * ch);
  return oc_dmad(d, enu.up, sp);
}

void oc_dir_heading_pitch(oc_enu_t enu, oc_dvec3 dir, double *heading_deg, double *pitch_deg) {
  double e = oc_ddot(dir, enu.east), n = oc_ddot(dir, enu.north), u = oc_ddot(dir, enu.up);
  double pitch = oc__atan2d(u, hypot(e, n));
  /* Straight up or down the heading is undefined; it comes out as 0. */
  double heading = oc__atan2d(e, n);
  if (heading < 0.0) heading += 360.0;
  if (heading >= 360.0) heading = 0.0; /* a tiny negative angle + 360 can round to 360 */
  if (heading_deg) *heading_deg = heading;
  if (pitch_deg) *pitch_deg = pitch;
}

/*-*** Camera-relative positions ***/

/* Level-21 cells are exact in float too: OC_CELL21_SIZE = 808875·2^-17, 20 significant bits. */
#define OC__CELL21_F ((float)OC_CELL21_SIZE)

/* Beyond this a cell index is meaningless (2^60 cells ≈ 7e18 m); clamping there keeps the int64
 * conversion and the difference of two cells defined for absurd or non-finite input. */
#define OC__CELL_LIMIT 1152921504606846976.0 /* 2^60 */

/* Splits one coordinate into its level-21 cell and the fraction in [0, 1). (c + S)/cell21 has
 * an absolute error of a few 1e-10 cells at 1e7 m, far below anything a float can carry. */
static int64_t oc__split(double c, double *frac) {
  double t = (c + OC_ROOT_HALF) / OC_CELL21_SIZE;
  if (!(t > -OC__CELL_LIMIT)) t = isnan(t) ? 0.0 : -OC__CELL_LIMIT;
  if (t > OC__CELL_LIMIT) t = OC__CELL_LIMIT;
  double f = floor(t);
  *frac = t - f;
  if (*frac >= 1.0) { /* t a hair below an integer: t - f rounded up to 1 */
    f += 1.0;
    *frac = 0.0;
  }
  return (int64_t)f;
}

oc_camrel_t oc_camrel_make(oc_dvec3 cam) {
  oc_camrel_t c;
  double p[3] = {cam.x, cam.y, cam.z};
  for (int a = 0; a < 3; a++) {
    double f;
    c.cell[a] = oc__split(p[a], &f);
    c.frac[a] = (float)f;
    /* A fraction just below 1 can round up to 1.0f: carry it into the cell. */
    if (c.frac[a] >= 1.0f) {
      c.cell[a] += 1;
      c.frac[a] = 0.0f;
    }
  }
  return c;
}

/* The GPU's formula, in float: the integer difference is exact in float below 2^24 cells
 * (1.0e8 m), both products and the difference each round once, so the error is about one ulp
 * of the result (3e-5 m at 500 m) instead of one ulp of the absolute position (0.5 m). */
static float oc__rel(int64_t dcell, float frac_delta) {
  return (float)dcell * OC__CELL21_F + frac_delta * OC__CELL21_F;
}

void oc_camrel_node(const oc_camrel_t *c, oc_key_t key, float out[3]) {
  int level = oc_key_level(key);
  if (!c || !out || level < 0) {
    if (out) out[0] = out[1] = out[2] = NAN;
    return;
  }
  uint32_t i[3];
  oc_key_coords(key, &i[0], &i[1], &i[2]);
  int shift = OC_KEY_MAX_LEVEL - level; /* the node origin is level-21 cell i·2^shift, frac 0 */
  for (int a = 0; a < 3; a++) out[a] = oc__rel(((int64_t)i[a] << shift) - c->cell[a], -c->frac[a]);
}

void oc_camrel_point(const oc_camrel_t *c, oc_dvec3 p, float out[3]) {
  if (!c || !out) {
    if (out) out[0] = out[1] = out[2] = NAN;
    return;
  }
  double pc[3] = {p.x, p.y, p.z};
  for (int a = 0; a < 3; a++) {
    double f;
    int64_t cell = oc__split(pc[a], &f);
    /* Both fractions are in [0, 1): their difference is small, so float keeps ~1e-7 m of it. */
    out[a] = oc__rel(cell - c->cell[a], (float)(f - (double)c->frac[a]));
  }
}

void oc_key_radius_range(oc_key_t key, double *rmin, double *rmax) {
  oc_dvec3 o;
  double s, n2 = 0.0, f2 = 0.0;
  oc_key_bounds(key, &o, &s);
  const double lo[3] = {o.x, o.y, o.z};
  for (int a = 0; a < 3; a++) {
    double l = lo[a], h = lo[a] + s, n = l > 0 ? l : (h < 0 ? h : 0), f = fmax(fabs(l), fabs(h));
    n2 += n * n;
    f2 += f * f;
  }
  *rmin = sqrt(n2);
  *rmax = sqrt(f2);
}

int oc_key_meets_ground(oc_key_t key) {
  double rmin, rmax;
  oc_key_radius_range(key, &rmin, &rmax);
  return rmin <= OC_PLANET_RADIUS && rmax >= OC_PLANET_RADIUS;
}
