/* source_analytic.c — homogeneous spheres, boxes and slabs as field sources (closed-form oracles
 * for the whole pipeline). Spheres and boxes are box-filtered with OCS_ANALYTIC_SUB³ (or more)
 * sub-samples per sample; slabs exactly, from the volume of the sample's cube between the shell's
 * two spheres taken as planes across the cube (ocs__slab_fraction); the
 * bound is exact in the sense of ocs_prim_intersects_box (0 outside, σt where the box meets it, and
 * σt as the minimum only when the primitive contains the whole box). */
#include <stdio.h>
#include <math.h>
#include <stdlib.h>

#include "analytic.h"
#include "oc_err.h"
#include "voxelize.h"
#include "ocs_field.h"

/*! Fewest sub-samples per axis of the box filter (4³ = 64 points per sample). */
#ifndef OCS_ANALYTIC_SUB
#define OCS_ANALYTIC_SUB 4
#endif
/*! Sub-samples are added until their spacing is at most the primitive's feature size (radius,
 *  smallest half-size, thickness) / OCS_ANALYTIC_FEATURE_DIV, up to OCS_VOXELIZE_MAX_SUB per axis:
 *  a hard edge met by a coarse voxel needs that many to keep the box average's error small. */
#ifndef OCS_ANALYTIC_FEATURE_DIV
#define OCS_ANALYTIC_FEATURE_DIV 32.0
#endif

typedef struct {
  ocs_source_t base;
  ocs_medium_t medium; /* one primitive */
  double feature;     /* m: the primitive's smallest dimension */
} ocs__analytic_t;

/*! Largest cube a slab is filtered in one piece: across it the shell's spheres bend from a plane by
 *  v²/(8R) ≤ 7.9 m. A coarser voxel is split into n³ such cubes (n ≤ 16), each exact to that. */
#define OCS_SLAB_EXACT_MAX_VOXEL 20000.0

static double ocs__analytic_fn(void *ctx, oc_dvec3 p) { return ocs_medium_sigma_t(ctx, p); }

static double ocs__pos3(double x) { return x > 0.0 ? x * x * x : 0.0; }
static double ocs__pos2(double x) { return x > 0.0 ? x * x : 0.0; }

/* Fraction of an axis-aligned cube whose points u (relative to its centre) have n·u ≤ s, with
 * a, b, c = |n_x|, |n_y|, |n_z| times the cube's edge: the volume under a plane, the classic
 * inclusion-exclusion over the 8 corners, Σ ±max(0, t − corner)³ / (6abc), with lower-dimensional
 * forms when the plane is (nearly) parallel to an axis, where that sum would cancel. */
static double ocs__cube_below(double a, double b, double c, double s) {
  double w = a + b + c, t = s + 0.5 * w;
  if (!(t > 0.0)) return 0.0;
  if (!(t < w)) return 1.0;
  if (t > 0.5 * w) return 1.0 - ocs__cube_below(a, b, c, -s); /* the smaller side: less cancellation */
  if (a < b) { double x = a; a = b; b = x; }
  if (b < c) { double x = b; b = c; c = x; }
  if (a < b) { double x = a; a = b; b = x; }
  double v;
  if (c > 1e-6 * a) {
    v = 0.0;
    for (int i = 0; i < 8; i++) {
      double q = t - ((i & 1) ? a : 0.0) - ((i & 2) ? b : 0.0) - ((i & 4) ? c : 0.0);
      v += ((__builtin_popcount((unsigned)i) & 1) ? -1.0 : 1.0) * ocs__pos3(q);
    }
    v /= 6.0 * a * b * c;
  } else if (b > 1e-6 * a) {
    double u = t - 0.5 * c;
    v = (ocs__pos2(u) - ocs__pos2(u - a) - ocs__pos2(u - b) + ocs__pos2(u - a - b)) / (2.0 * a * b);
  } else {
    v = (t - 0.5 * (b + c)) / a;
  }
  return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v);
}

/* A slab's exact box average at one sample (cube of edge v centred at p). */
static double ocs__slab_fraction(const ocs_prim_t *pr, oc_dvec3 p, double v) {
  double r = oc_dlen(p);
  if (!(r > 0.0)) return 0.0;
  oc_dvec3 n = oc_dscale(p, 1.0 / r);
  double a = fabs(n.x) * v, b = fabs(n.y) * v, c = fabs(n.z) * v;
  return ocs__cube_below(a, b, c, pr->slab.r_out - r) - ocs__cube_below(a, b, c, pr->slab.r_in - r);
}

/*! Margin beyond which a slab's sample cube is wholly in or out of the shell without splitting it:
 *  far above the planes' bend across a piece (≤ 7.9 m), so each piece would give exactly 0 or 1. */
#define OCS_SLAB_CLEAR_MARGIN 1000.0

/* A coarse slab sample cube (centre c, edge v) whose every point is more than the margin from both
 * spheres: 1 inside the shell, 0 outside; -1 when it must be split. */
static int ocs__slab_cube_clear(const ocs_prim_t *pr, oc_dvec3 c, double v) {
  double h = 0.5 * v, near2 = 0.0, far2 = 0.0, cc[3] = {c.x, c.y, c.z};
  for (int k = 0; k < 3; k++) {
    double lo = cc[k] - h, hi = cc[k] + h, n = lo > 0.0 ? lo : hi < 0.0 ? -hi : 0.0, f = fmax(fabs(lo), fabs(hi));
    near2 += n * n;
    far2 += f * f;
  }
  double near = sqrt(near2), far = sqrt(far2), m = OCS_SLAB_CLEAR_MARGIN;
  if (far < pr->slab.r_in - m || near > pr->slab.r_out + m) return 0;
  if (near > pr->slab.r_in + m && far < pr->slab.r_out - m) return 1;
  return -1;
}

/* The box lies inside a sphere or box when its 8 corners do (both are convex). The slab's shell is
 * not convex: the box is inside it when its closest point to the planet centre is beyond r_in and
 * its farthest corner within r_out. */
static int ocs__box_inside(const ocs_prim_t *p, oc_dvec3 lo, oc_dvec3 hi) {
  if (p->kind == OCS_PRIM_SLAB) {
    oc_dvec3 q = oc_dv3(fmax(lo.x, fmin(0.0, hi.x)), fmax(lo.y, fmin(0.0, hi.y)), fmax(lo.z, fmin(0.0, hi.z)));
    double far = 0.0;
    for (int c = 0; c < 8; c++)
      far = fmax(far, oc_dlen(oc_dv3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z)));
    return oc_dlen(q) >= p->slab.r_in && far <= p->slab.r_out;
  }
  for (int c = 0; c < 8; c++) {
    oc_dvec3 q = oc_dv3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
    if (ocs_prim_sigma_t(p, q) <= 0.0) return 0;
  }
  return 1;
}

static void ocs__analytic_bound(const ocs_source_t *s, oc_dvec3 lo, oc_dvec3 hi, double t, float *smin, float *smax) {
  (void)t;
  const ocs_prim_t *p = &((const ocs__analytic_t *)s)->medium.prims[0];
  int meets = ocs_prim_intersects_box(p, lo, hi);
  *smax = meets ? (float)p->sigma_t : 0.0f;
  *smin = meets && ocs__box_inside(p, lo, hi) ? (float)p->sigma_t : 0.0f;
}

static int ocs__analytic_sample(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) {
  (void)t;
  const ocs__analytic_t *a = (const ocs__analytic_t *)s;
  oc_dvec3 o;
  double size;
  float smin, smax, tmp[OC_BRICK_VOXELS];
  oc_key_bounds(key, &o, &size);
  double g = size / 14.0;
  ocs__analytic_bound(s, oc_dv3(o.x - g, o.y - g, o.z - g), oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g), t,
                      &smin, &smax);
  if (smax == 0.0f) return 0; /* nothing to add */
  if (smin == smax) {
    for (int i = 0; i < OC_BRICK_VOXELS; i++) out[i] += smax;
    return 0;
  }
  const ocs_prim_t *pr = &a->medium.prims[0];
  double spacing = a->feature / OCS_ANALYTIC_FEATURE_DIV, voxel = size / 7.0;
  if (pr->kind == OCS_PRIM_SLAB) {
    int n = (int)ceil(voxel / OCS_SLAB_EXACT_MAX_VOXEL);
    n = n < 1 ? 1 : (n > OCS_VOXELIZE_MAX_SUB ? OCS_VOXELIZE_MAX_SUB : n);
    double e = voxel / n;
    for (int i = 0; i < OC_BRICK_VOXELS; i++) {
      oc_dvec3 c = ocs_brick_sample_pos(key, i & 7, (i >> 3) & 7, i >> 6);
      int clear = n > 1 ? ocs__slab_cube_clear(pr, c, voxel) : -1; /* the same 0 or 1, without n³ pieces */
      if (clear >= 0) {
        out[i] += clear ? (float)pr->sigma_t : 0.0f;
        continue;
      }
      double f = 0.0;
      for (int m = 0; m < n * n * n; m++) {
        oc_dvec3 q = oc_dv3(c.x + ((m % n) + 0.5 - 0.5 * n) * e, c.y + (((m / n) % n) + 0.5 - 0.5 * n) * e,
                            c.z + ((m / (n * n)) + 0.5 - 0.5 * n) * e);
        f += ocs__slab_fraction(pr, q, e);
      }
      out[i] += (float)(pr->sigma_t * f / (double)(n * n * n));
    }
    return 0;
  }
  int sub = (int)ceil(voxel / spacing);
  sub = sub < OCS_ANALYTIC_SUB ? OCS_ANALYTIC_SUB : sub > OCS_VOXELIZE_MAX_SUB ? OCS_VOXELIZE_MAX_SUB : sub;
  ocs_brick_sample(key, ocs__analytic_fn, (void *)&a->medium, sub, tmp);
  for (int i = 0; i < OC_BRICK_VOXELS; i++) out[i] += tmp[i];
  return 0;
}

static uint64_t ocs__analytic_step(const ocs_source_t *s, int level, double t) {
  (void)s, (void)level, (void)t;
  return 0; /* static: never regenerated */
}

static double ocs__analytic_point(const ocs_source_t *s, oc_dvec3 p, double t) {
  (void)t;
  return ocs_medium_sigma_t(&((const ocs__analytic_t *)s)->medium, p);
}

static void ocs__analytic_destroy(ocs_source_t *s) { free(s); }

static const ocs_source_vtbl_t ocs__analytic_vt = {.name = "analytic",
                                                   .bound = ocs__analytic_bound,
                                                   .sample = ocs__analytic_sample,
                                                   .time_step = ocs__analytic_step,
                                                   .point = ocs__analytic_point,
                                                   .destroy = ocs__analytic_destroy,
                                                   .bound_by_step = 0 /* bound() is cheap: not cached */};

int ocs_source_analytic_create(ocs_source_t **out, const oc_source_t *d, char *why, size_t why_len) {
  *out = NULL;
  ocs__analytic_t *a = calloc(1, sizeof *a);
  if (!a) return OC_ENOMEM;
  ocs_prim_t p;
  int r;
  switch (d->type) {
    case OC_SOURCE_SPHERE: r = ocs_prim_sphere(&p, d->sphere.centre, d->sphere.radius, d->sphere.sigma_t); break;
    case OC_SOURCE_BOX:
      r = ocs_prim_box(&p, d->box.base, d->box.size[0], d->box.size[1], d->box.size[2], d->box.heading, d->box.sigma_t);
      break;
    case OC_SOURCE_SLAB: r = ocs_prim_slab(&p, d->slab.base, d->slab.top, d->slab.sigma_t); break;
    default: r = OC_EINVAL; break;
  }
  ocs_medium_init(&a->medium);
  if (r == 0) r = ocs_medium_add(&a->medium, &p);
  if (r < 0) {
    if (why) snprintf(why, why_len, "invalid analytic primitive: %s", oc_strerror(r));
    free(a);
    return r;
  }
  a->feature = p.kind == OCS_PRIM_SPHERE ? p.sphere.radius
               : p.kind == OCS_PRIM_BOX    ? fmin(p.box.half[0], fmin(p.box.half[1], p.box.half[2]))
                                          : p.slab.r_out - p.slab.r_in;
  a->base.vt = &ocs__analytic_vt;
  a->base.animated = 0;
  *out = &a->base;
  return 0;
}
