#include "analytic.h"

#include <math.h>
#include <string.h>

#include "oc_err.h"

/* ---- Construction ---------------------------------------------------------------------------- */

static int oc__finite_geo(oc_geo_t g) { return isfinite(g.lat) && isfinite(g.lon) && isfinite(g.alt); }
static int oc__sigma_ok(double s) { return isfinite(s) && s >= 0.0; }

int ocs_prim_sphere(ocs_prim_t *out, oc_geo_t centre, double radius, double sigma_t) {
  OC_RETURN_IF(!out || !oc__finite_geo(centre) || !isfinite(radius) || !(radius > 0.0) || !oc__sigma_ok(sigma_t),
               OC_EINVAL);
  memset(out, 0, sizeof *out);
  out->kind = OCS_PRIM_SPHERE;
  out->sigma_t = sigma_t;
  out->sphere.centre = centre;
  out->sphere.radius = radius;
  out->sphere.c = oc_geo_to_xyz(centre);
  return 0;
}

int ocs_prim_box(ocs_prim_t *out, oc_geo_t base, double size_e, double size_n, double size_u, double heading_deg,
                double sigma_t) {
  OC_RETURN_IF(!out || !oc__finite_geo(base) || !isfinite(heading_deg) || !oc__sigma_ok(sigma_t), OC_EINVAL);
  OC_RETURN_IF(!isfinite(size_e) || !isfinite(size_n) || !isfinite(size_u), OC_EINVAL);
  OC_RETURN_IF(!(size_e > 0.0) || !(size_n > 0.0) || !(size_u > 0.0), OC_EINVAL);
  memset(out, 0, sizeof *out);
  out->kind = OCS_PRIM_BOX;
  out->sigma_t = sigma_t;
  out->box.base = base;
  out->box.size[0] = size_e;
  out->box.size[1] = size_n;
  out->box.size[2] = size_u;
  out->box.heading = heading_deg;
  oc_dvec3 b = oc_geo_to_xyz(base);
  oc_enu_t enu = oc_enu_at(b);
  /* Heading h clockwise from north: the box's north edge points along cos h·north + sin h·east,
   * its east edge along cos h·east − sin h·north (a rotation about up, so still right-handed). */
  double ch = cos(heading_deg * OC_DEG), sh = sin(heading_deg * OC_DEG);
  out->box.axis[0] = oc_dnorm(oc_dsub(oc_dscale(enu.east, ch), oc_dscale(enu.north, sh)));
  out->box.axis[1] = oc_dnorm(oc_dadd(oc_dscale(enu.north, ch), oc_dscale(enu.east, sh)));
  out->box.axis[2] = enu.up;
  for (int k = 0; k < 3; k++) out->box.half[k] = 0.5 * out->box.size[k];
  out->box.c = oc_dmad(b, enu.up, out->box.half[2]);
  return 0;
}

int ocs_prim_slab(ocs_prim_t *out, double base_alt, double top_alt, double sigma_t) {
  OC_RETURN_IF(!out || !isfinite(base_alt) || !isfinite(top_alt) || !oc__sigma_ok(sigma_t), OC_EINVAL);
  OC_RETURN_IF(!(top_alt > base_alt) || base_alt < -OC_PLANET_RADIUS, OC_EINVAL);
  memset(out, 0, sizeof *out);
  out->kind = OCS_PRIM_SLAB;
  out->sigma_t = sigma_t;
  out->slab.base = base_alt;
  out->slab.top = top_alt;
  out->slab.r_in = OC_PLANET_RADIUS + base_alt;
  out->slab.r_out = OC_PLANET_RADIUS + top_alt;
  return 0;
}

/* ---- Point queries --------------------------------------------------------------------------- */

/* Box-frame coordinates of a planet-frame offset from the box centre. */
static inline void oc__box_local(const ocs_prim_t *pr, oc_dvec3 o, double l[3]) {
  for (int k = 0; k < 3; k++) l[k] = oc_ddot(o, pr->box.axis[k]);
}

double ocs_prim_sigma_t(const ocs_prim_t *pr, oc_dvec3 p) {
  switch (pr->kind) {
  case OCS_PRIM_SPHERE: {
    oc_dvec3 o = oc_dsub(p, pr->sphere.c);
    return oc_ddot(o, o) <= pr->sphere.radius * pr->sphere.radius ? pr->sigma_t : 0.0;
  }
  case OCS_PRIM_BOX: {
    double l[3];
    oc__box_local(pr, oc_dsub(p, pr->box.c), l);
    for (int k = 0; k < 3; k++)
      if (!(fabs(l[k]) <= pr->box.half[k])) return 0.0;
    return pr->sigma_t;
  }
  case OCS_PRIM_SLAB: {
    double r = oc_dlen(p);
    return (r >= pr->slab.r_in && r <= pr->slab.r_out) ? pr->sigma_t : 0.0;
  }
  default:
    return 0.0;
  }
}

/* ---- Chords ---------------------------------------------------------------------------------- */

/* oc__ball_chord() : length of {t in [0, tmax] : |o + t·d| < r}, d unit, o relative to the centre.
 * perp = o − (o·d)d is the offset of the closest approach; the half chord h = √(r² − |perp|²) is
 * formed as √((r − |perp|)(r + |perp|)). The roots −b ± h are taken as q = −b − sign(b)·h and c/q
 * with c = |o|² − r² = (|o| − r)(|o| + r), so neither root subtracts nearly equal numbers (the
 * classic "stable quadratic" of Numerical Recipes §5.6; Haines et al., Ray Tracing Gems ch. 7). */
static double oc__ball_chord(oc_dvec3 o, oc_dvec3 d, double r, double tmax) {
  if (!(r > 0.0)) return 0.0;
  double b = oc_ddot(o, d);
  oc_dvec3 perp = oc_dmad(o, d, -b);
  double pl = oc_dlen(perp);
  if (!(pl < r)) return 0.0; /* misses or is tangent: a set of measure zero */
  double h = sqrt((r - pl) * (r + pl));
  double ol = oc_dlen(o);
  double c = (ol - r) * (ol + r);
  double q = -b - copysign(h, b); /* |q| ≥ h > 0 */
  double ta = q, tb = c / q;
  double t0 = ta < tb ? ta : tb, t1 = ta < tb ? tb : ta;
  if (!(t1 > 0.0) || !(t0 < tmax)) return 0.0;
  if (t0 >= 0.0 && t1 <= tmax) return 2.0 * h; /* the whole chord */
  double lo = t0 > 0.0 ? t0 : 0.0, hi = t1 < tmax ? t1 : tmax;
  return hi > lo ? hi - lo : 0.0;
}

/* oc__box_chord() : the slab method in the box frame; o is the origin relative to the box centre. */
static double oc__box_chord(const ocs_prim_t *pr, oc_dvec3 o, oc_dvec3 d, double tmax) {
  double lo[3], ld[3];
  oc__box_local(pr, o, lo);
  oc__box_local(pr, d, ld);
  double tn = 0.0, tf = tmax;
  for (int k = 0; k < 3; k++) {
    double hk = pr->box.half[k];
    if (ld[k] == 0.0) { /* parallel to this pair of faces: inside or never */
      if (!(fabs(lo[k]) <= hk)) return 0.0;
      continue;
    }
    double ta = (-hk - lo[k]) / ld[k], tb = (hk - lo[k]) / ld[k];
    double t0 = ta < tb ? ta : tb, t1 = ta < tb ? tb : ta;
    if (t0 > tn) tn = t0;
    if (t1 < tf) tf = t1;
    if (!(tf > tn)) return 0.0;
  }
  return tf - tn;
}

double ocs_prim_chord(const ocs_prim_t *pr, oc_dvec3 p, oc_dvec3 d, double tmax) {
  if (!(tmax > 0.0)) return 0.0;
  double dl = oc_dlen(d);
  if (!(dl > 0.0) || !isfinite(dl)) return 0.0;
  d = oc_dscale(d, 1.0 / dl);
  switch (pr->kind) {
  case OCS_PRIM_SPHERE:
    return oc__ball_chord(oc_dsub(p, pr->sphere.c), d, pr->sphere.radius, tmax);
  case OCS_PRIM_BOX:
    return oc__box_chord(pr, oc_dsub(p, pr->box.c), d, tmax);
  case OCS_PRIM_SLAB: {
    /* The inner ball lies inside the outer one, so the shell's part of [0, tmax] is the outer
     * ball's part minus the inner ball's part. This covers origins inside the inner ball, inside
     * the shell and outside, and rays that graze either sphere. */
    double l = oc__ball_chord(p, d, pr->slab.r_out, tmax) - oc__ball_chord(p, d, pr->slab.r_in, tmax);
    return l > 0.0 ? l : 0.0;
  }
  default:
    return 0.0;
  }
}

/* ---- Bounds ---------------------------------------------------------------------------------- */

void ocs_prim_bounds(const ocs_prim_t *pr, oc_dvec3 *lo, oc_dvec3 *hi) {
  switch (pr->kind) {
  case OCS_PRIM_SPHERE: {
    double r = pr->sphere.radius;
    *lo = oc_dsub(pr->sphere.c, oc_dv3(r, r, r));
    *hi = oc_dadd(pr->sphere.c, oc_dv3(r, r, r));
    return;
  }
  case OCS_PRIM_BOX: {
    double e[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) {
      oc_dvec3 a = pr->box.axis[k];
      double h = pr->box.half[k];
      e[0] += fabs(a.x) * h;
      e[1] += fabs(a.y) * h;
      e[2] += fabs(a.z) * h;
    }
    *lo = oc_dsub(pr->box.c, oc_dv3(e[0], e[1], e[2]));
    *hi = oc_dadd(pr->box.c, oc_dv3(e[0], e[1], e[2]));
    return;
  }
  case OCS_PRIM_SLAB: {
    double r = pr->slab.r_out;
    *lo = oc_dv3(-r, -r, -r);
    *hi = oc_dv3(r, r, r);
    return;
  }
  default:
    *lo = oc_dv3(0, 0, 0);
    *hi = oc_dv3(0, 0, 0);
    return;
  }
}

static inline double oc__clampd(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* Separating-axis test of an oriented box against an axis-aligned one (Ericson, Real-Time
 * Collision Detection §4.4.1): 3 + 3 face axes and 9 edge-cross axes; EPS keeps near-parallel
 * edge pairs (whose cross product vanishes) from separating boxes that meet. */
static int oc__obb_meets_aabb(const ocs_prim_t *pr, oc_dvec3 lo, oc_dvec3 hi) {
  const double EPS = 1e-12;
  double a[3] = {0.5 * (hi.x - lo.x), 0.5 * (hi.y - lo.y), 0.5 * (hi.z - lo.z)};
  oc_dvec3 ac = oc_dv3(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.5 * (lo.z + hi.z));
  oc_dvec3 tv = oc_dsub(pr->box.c, ac);
  double t[3] = {tv.x, tv.y, tv.z};
  const double *b = pr->box.half;
  double R[3][3], AR[3][3];
  for (int j = 0; j < 3; j++) {
    oc_dvec3 u = pr->box.axis[j];
    R[0][j] = u.x;
    R[1][j] = u.y;
    R[2][j] = u.z;
  }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) AR[i][j] = fabs(R[i][j]) + EPS;
  double scale = a[0] + a[1] + a[2] + b[0] + b[1] + b[2];
  double slack = EPS * scale; /* absolute slack matching the relative EPS */
  for (int i = 0; i < 3; i++) {
    double rb = b[0] * AR[i][0] + b[1] * AR[i][1] + b[2] * AR[i][2];
    if (fabs(t[i]) > a[i] + rb + slack) return 0;
  }
  for (int j = 0; j < 3; j++) {
    double ra = a[0] * AR[0][j] + a[1] * AR[1][j] + a[2] * AR[2][j];
    double tj = t[0] * R[0][j] + t[1] * R[1][j] + t[2] * R[2][j];
    if (fabs(tj) > ra + b[j] + slack) return 0;
  }
  for (int i = 0; i < 3; i++) {
    int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; j++) {
      int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      double ra = a[i1] * AR[i2][j] + a[i2] * AR[i1][j];
      double rb = b[j1] * AR[i][j2] + b[j2] * AR[i][j1];
      if (fabs(t[i2] * R[i1][j] - t[i1] * R[i2][j]) > ra + rb + slack) return 0;
    }
  }
  return 1;
}

int ocs_prim_intersects_box(const ocs_prim_t *pr, oc_dvec3 lo, oc_dvec3 hi) {
  switch (pr->kind) {
  case OCS_PRIM_SPHERE: {
    oc_dvec3 c = pr->sphere.c;
    /* The closest point of the box to the centre, as an offset from the centre. */
    oc_dvec3 q = oc_dv3(oc__clampd(c.x, lo.x, hi.x) - c.x, oc__clampd(c.y, lo.y, hi.y) - c.y,
                        oc__clampd(c.z, lo.z, hi.z) - c.z);
    return oc_ddot(q, q) <= pr->sphere.radius * pr->sphere.radius;
  }
  case OCS_PRIM_BOX:
    return oc__obb_meets_aabb(pr, lo, hi);
  case OCS_PRIM_SLAB: {
    /* Nearest and farthest points of the box from the planet centre. */
    oc_dvec3 n = oc_dv3(oc__clampd(0.0, lo.x, hi.x), oc__clampd(0.0, lo.y, hi.y), oc__clampd(0.0, lo.z, hi.z));
    oc_dvec3 f = oc_dv3(fmax(fabs(lo.x), fabs(hi.x)), fmax(fabs(lo.y), fabs(hi.y)), fmax(fabs(lo.z), fabs(hi.z)));
    return oc_dlen(n) <= pr->slab.r_out && oc_dlen(f) >= pr->slab.r_in;
  }
  default:
    return 0;
  }
}

/* ---- Media ----------------------------------------------------------------------------------- */

void ocs_medium_init(ocs_medium_t *m) { memset(m, 0, sizeof *m); }

int ocs_medium_add(ocs_medium_t *m, const ocs_prim_t *pr) {
  OC_RETURN_IF(!m || !pr, OC_EINVAL);
  OC_RETURN_IF(pr->kind != OCS_PRIM_SPHERE && pr->kind != OCS_PRIM_BOX && pr->kind != OCS_PRIM_SLAB, OC_EINVAL);
  OC_RETURN_IF(m->count < 0 || m->count >= OCS_MEDIUM_MAX_PRIMS, OC_ENOBUFS);
  m->prims[m->count++] = *pr;
  return 0;
}

static inline int oc__count(const ocs_medium_t *m) {
  return m->count < 0 ? 0 : (m->count > OCS_MEDIUM_MAX_PRIMS ? OCS_MEDIUM_MAX_PRIMS : m->count);
}

double ocs_medium_sigma_t(const ocs_medium_t *m, oc_dvec3 p) {
  double s = 0.0;
  int n = oc__count(m);
  for (int i = 0; i < n; i++) s += ocs_prim_sigma_t(&m->prims[i], p);
  return s;
}

double ocs_medium_optical_depth(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 dir, double tmax) {
  double tau = 0.0;
  int n = oc__count(m);
  for (int i = 0; i < n; i++) {
    const ocs_prim_t *pr = &m->prims[i];
    if (pr->sigma_t == 0.0) continue;
    tau += pr->sigma_t * ocs_prim_chord(pr, p, dir, tmax);
  }
  return tau;
}

double ocs_medium_tau_sun(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 sun_dir) {
  return ocs_medium_optical_depth(m, p, sun_dir, INFINITY);
}

int ocs_medium_bounds(const ocs_medium_t *m, oc_dvec3 *lo, oc_dvec3 *hi) {
  int n = oc__count(m), any = 0;
  oc_dvec3 l = {0, 0, 0}, h = {0, 0, 0};
  for (int i = 0; i < n; i++) {
    if (m->prims[i].kind == OCS_PRIM_NONE) continue;
    oc_dvec3 a, b;
    ocs_prim_bounds(&m->prims[i], &a, &b);
    if (!any) {
      l = a;
      h = b;
      any = 1;
    } else {
      l = oc_dv3(fmin(l.x, a.x), fmin(l.y, a.y), fmin(l.z, a.z));
      h = oc_dv3(fmax(h.x, b.x), fmax(h.y, b.y), fmax(h.z, b.z));
    }
  }
  if (!any) return OC_ENOENT;
  *lo = l;
  *hi = h;
  return 0;
}
