/* sun_depth.c — τ (sun optical depth) for a node's samples: the direct march and the group volume
 * (sun_depth.h has the model; docs/numerics.md the errors). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <xxhash.h> /* XXH3_128bits: a volume's record of the bricks it read */

#include "brick.h" /* ocg_brick_base, ocg_brick_frac, ocg_brick_base_voxel, ocg_trilerp */
#include "oc_err.h"
#include "voxelize.h" /* ocs_brick_sample_pos */
#include "sun_depth.h"

#define OCS__S OC_ROOT_HALF
#define OCS__R_ATMO (OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT)
#define OCS__R_STOP OCS_TAU_PLANET_STOP
/*! Safety cap on steps plus skips of one march: far above any real march (a grazing ray through
 *  the whole atmosphere at the finest level and step factor takes a few hundred thousand). */
#define OCS__MAX_ITER 4000000

/*-*** Desc ***/

typedef struct {
  const ocs_tau_desc_t *u;
  oc_dvec3 sun;
  int filter_levels, min_level, group_levels;
  double step_factor, cone;
} ocs__desc_t;

static int ocs__desc(const ocs_tau_desc_t *d, ocs__desc_t *o) {
  if (!d || !d->sigma || !d->bound) return OC_EINVAL;
  double n = oc_dlen(d->sun_dir);
  if (!isfinite(n) || !(n > 0.0)) return OC_EINVAL;
  o->u = d;
  o->sun = oc_dscale(d->sun_dir, 1.0 / n);
  o->filter_levels = d->filter_levels ? d->filter_levels : OCS_TAU_DEFAULT_FILTER_LEVELS;
  o->min_level = d->min_level ? d->min_level : OCS_TAU_DEFAULT_MIN_LEVEL;
  o->group_levels = d->group_levels ? d->group_levels : OCS_TAU_DEFAULT_GROUP_LEVELS;
  o->step_factor = d->step_factor != 0.0 ? d->step_factor : OCS_TAU_DEFAULT_STEP_FACTOR;
  o->cone = d->cone != 0.0 ? d->cone : OCS_TAU_DEFAULT_CONE;
  if (o->filter_levels < 0 || o->filter_levels > OC_KEY_MAX_LEVEL) return OC_EINVAL;
  if (o->min_level < 0 || o->min_level > OC_KEY_MAX_LEVEL) return OC_EINVAL;
  if (o->group_levels < 0 || o->group_levels > OCS_TAU_MAX_GROUP_LEVELS) return OC_EINVAL;
  if (!(o->step_factor > 0.0 && o->step_factor <= 16.0)) return OC_EINVAL;
  if (!(o->cone >= 0.0 && o->cone <= 1.0)) return OC_EINVAL;
  return 0;
}

/* Voxel (sample spacing, size/7) of a level. */
static double ocs__voxel(int level) { return ldexp(2.0 * OCS__S / 7.0, -level); }

/*-*** Memo: bounds and bricks asked during one call ***/

typedef struct {
  oc_key_t key; /* 0: free slot */
  float smin, smax;
  float asked_min, asked_max; /* the bound as the callback answered it (a volume records it) */
  int32_t brick; /* index into the pool, -1: not fetched */
  float bmax;    /* the fetched samples' maximum */
  int32_t ranged; /* smin/smax narrowed to the samples' range (ocs__brick; the clear-sky proof
                     fetches without narrowing, so the march it may precede is unchanged) */
} ocs__ent_t;

typedef struct {
  uint32_t ix, iy, iz;
  int32_t slot; /* -1: none */
} ocs__cur_t;

/*! Entries per level of the "current node" cache: the 512 rays of a direct march climb through
 *  the same few nodes one after the other, and one entry per level thrashed between them (each
 *  miss made a key and probed the memo). Direct-mapped on the node's coordinates. */
#define OCS__CUR_WAYS 16

/* One call's state: the memo, the march parameters and a per-level "current node" cache. */
typedef struct {
  const ocs__desc_t *d;
  ocs__ent_t *tab;
  uint32_t cap, count; /* cap: power of two */
  float *pool;
  int32_t nbricks, pool_cap;
  double *scr; /* a column's slice positions and running integrals */
  int32_t scr_cap;
  int err;
  int level_m;  /* march level */
  int level_lo; /* coarsest level sampled or bounded */
  double h0;    /* first step, m */
  double cell_k[OC_KEY_MAX_LEVEL + 1], cell_n[OC_KEY_MAX_LEVEL + 1]; /* 2^L / 2S, 2^L */
  double step_up[OC_KEY_MAX_LEVEL + 2]; /* h0·2^(j+1): a step this long samples one level coarser */
  double size[OC_KEY_MAX_LEVEL + 1];   /* oc_key_size(L), once: node_exit asked it per node */
  double voxel[OC_KEY_MAX_LEVEL + 1];  /* ocs__voxel(L), once: not an ldexp at every walk */
  ocs__cur_t cur[OC_KEY_MAX_LEVEL + 1][OCS__CUR_WAYS];
  /* The last node (at a step's level) whose whole ancestry down from level_lo was found non-empty. */
  int chk_level;
  uint32_t chk_ix, chk_iy, chk_iz;
} ocs__ctx_t;

static void ocs__cur_reset(ocs__ctx_t *c) {
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    for (int i = 0; i < OCS__CUR_WAYS; i++) c->cur[l][i].slot = -1;
  c->chk_level = -1;
}

/* The finest level whose σt a node's march reads: L − filter_levels, never coarser than min_level
 * (nor than the node itself, when that is coarser still). */
static int ocs__march_level(const ocs__desc_t *d, int node_level) {
  int m = node_level - d->filter_levels;
  int lo = d->min_level < node_level ? d->min_level : node_level;
  return m < lo ? lo : m;
}

int ocs_tau_march_level(const ocs_tau_desc_t *du, int node_level) {
  ocs__desc_t d;
  if (node_level < 0 || node_level > OC_KEY_MAX_LEVEL || ocs__desc(du, &d) < 0) return -1;
  return ocs__march_level(&d, node_level);
}

static int ocs__ctx_init(ocs__ctx_t *c, const ocs__desc_t *d, int node_level) {
  memset(c, 0, sizeof *c);
  c->d = d;
  c->cap = 256;
  c->tab = calloc(c->cap, sizeof *c->tab);
  if (!c->tab) return OC_ENOMEM;
  int m = ocs__march_level(d, node_level);
  int lo = d->min_level < node_level ? d->min_level : node_level;
  c->level_m = m;
  c->level_lo = lo;
  c->h0 = d->step_factor * ocs__voxel(m);
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    c->cell_n[l] = ldexp(1.0, l);
    c->cell_k[l] = c->cell_n[l] / (2.0 * OCS__S);
    c->step_up[l] = ldexp(c->h0, l + 1);
    c->size[l] = oc_key_size(l);
    c->voxel[l] = ocs__voxel(l);
  }
  c->step_up[OC_KEY_MAX_LEVEL + 1] = INFINITY;
  ocs__cur_reset(c);
  return 0;
}

static void ocs__ctx_free(ocs__ctx_t *c) {
  free(c->tab);
  free(c->pool);
  free(c->scr);
}

static inline uint32_t ocs__hash(oc_key_t k) { return (uint32_t)((k * 0x9E3779B97F4A7C15ull) >> 32); }

static int ocs__grow(ocs__ctx_t *c) {
  uint32_t ncap = c->cap * 2;
  ocs__ent_t *nt = calloc(ncap, sizeof *nt);
  if (!nt) return OC_ENOMEM;
  for (uint32_t i = 0; i < c->cap; i++) {
    if (!c->tab[i].key) continue;
    uint32_t h = ocs__hash(c->tab[i].key) & (ncap - 1);
    while (nt[h].key) h = (h + 1) & (ncap - 1);
    nt[h] = c->tab[i];
  }
  free(c->tab);
  c->tab = nt;
  c->cap = ncap;
  ocs__cur_reset(c); /* slots moved */
  return 0;
}

/* The slot of key with its bound known (asking the callback the first time); -1 on error. */
static int32_t ocs__lookup(ocs__ctx_t *c, oc_key_t key) {
  if ((c->count + 1) * 2 > c->cap && ocs__grow(c) < 0) {
    c->err = OC_ENOMEM;
    return -1;
  }
  uint32_t h = ocs__hash(key) & (c->cap - 1);
  while (c->tab[h].key) {
    if (c->tab[h].key == key) return (int32_t)h;
    h = (h + 1) & (c->cap - 1);
  }
  float mn = 0.0f, mx = 0.0f;
  c->d->u->bound(c->d->u->ctx, key, &mn, &mx);
  c->tab[h].asked_min = mn, c->tab[h].asked_max = mx;
  /* Anything not provably [0, 0] or [v, v] (NaN included) is "varies": the brick is fetched. */
  if (!(mx >= 0.0f) || isnan(mn)) mn = 0.0f, mx = INFINITY;
  if (!(mn >= 0.0f)) mn = 0.0f;
  if (!(mx <= OC_VALUE_MAX)) mx = mn == mx ? OC_VALUE_MAX : INFINITY; /* a uniform +Inf is sanitised */
  if (mn > OC_VALUE_MAX) mn = OC_VALUE_MAX;
  c->tab[h].key = key;
  c->tab[h].smin = mn;
  c->tab[h].smax = mx;
  c->tab[h].brick = -1;
  c->tab[h].ranged = 0;
  c->count++;
  return (int32_t)h;
}

/* The brick of a slot (fetched the first time, e->bmax set), without narrowing the slot's range;
 * NULL on error. */
static const float *ocs__fetch(ocs__ctx_t *c, int32_t slot) {
  ocs__ent_t *e = &c->tab[slot];
  if (e->brick < 0) {
    if (c->nbricks == c->pool_cap) {
      int32_t ncap = c->pool_cap ? c->pool_cap * 2 : 16;
      float *np = realloc(c->pool, (size_t)ncap * OC_BRICK_VOXELS * sizeof(float));
      if (!np) {
        c->err = OC_ENOMEM;
        return NULL;
      }
      c->pool = np;
      c->pool_cap = ncap;
    }
    float *b = c->pool + (size_t)c->nbricks * OC_BRICK_VOXELS;
    int r = c->d->u->sigma(c->d->u->ctx, e->key, b);
    if (r < 0) {
      c->err = r;
      return NULL;
    }
    oc_sanitize(b, OC_BRICK_VOXELS, NULL);
    e->brick = c->nbricks++;
    float mx = b[0];
    for (int i = 1; i < OC_BRICK_VOXELS; i++) mx = b[i] > mx ? b[i] : mx;
    e->bmax = mx;
  }
  return c->pool + (size_t)e->brick * OC_BRICK_VOXELS;
}

/* The brick of a slot (fetched the first time), its range narrowed; NULL on error. */
static const float *ocs__brick(ocs__ctx_t *c, int32_t slot) {
  const float *b = ocs__fetch(c, slot);
  ocs__ent_t *e = &c->tab[slot];
  if (b && !e->ranged) {
    /* The samples' own range is exact where the bound was only conservative: an all-zero brick is
     * skipped from now on, a uniform one read without interpolation. */
    float mn = b[0], mx = b[0];
    for (int i = 1; i < OC_BRICK_VOXELS; i++) {
      mn = b[i] < mn ? b[i] : mn;
      mx = b[i] > mx ? b[i] : mx;
    }
    e->smin = mn, e->smax = mx;
    e->ranged = 1;
    c->chk_level = -1;
  }
  return b;
}

/* The slot of node (ix, iy, iz) of `level` through the per-level "current node" cache; -1 on error. */
static int32_t ocs__slot(ocs__ctx_t *c, int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  uint32_t way = (ix ^ iy * 3u ^ iz * 5u) & (OCS__CUR_WAYS - 1);
  ocs__cur_t *cu = &c->cur[level][way];
  if (cu->slot >= 0 && cu->ix == ix && cu->iy == iy && cu->iz == iz) return cu->slot;
  int32_t slot = ocs__lookup(c, oc_key_make(level, ix, iy, iz));
  if (slot < 0) return -1; /* a grow reset the cache (slots moved); cu is still this entry */
  cu->ix = ix, cu->iy = iy, cu->iz = iz, cu->slot = slot;
  return slot;
}

/* The coarsest level l in level_lo..level whose node holding node (ix, iy, iz) of `level` has the
 * bound [0, 0] (every sample of a node at l or finer inside it is then 0, and so is the
 * reconstruction); -1 when there is none; -2 on error. A walk's next node shares most of its
 * ancestors with the last one checked, so only the levels below where their chains meet are asked. */
static int ocs__empty_level(ocs__ctx_t *c, int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  int l0 = c->level_lo;
  if (c->chk_level == level) { /* the ancestors shared with the last node whose chain was non-empty are */
    uint32_t x = (ix ^ c->chk_ix) | (iy ^ c->chk_iy) | (iz ^ c->chk_iz);
    if (!x) return -1;
    int shared = level - (32 - __builtin_clz(x)); /* the finest level where the two chains meet */
    l0 = shared + 1 > l0 ? shared + 1 : l0;
  }
  for (int l = l0; l <= level; l++) {
    int sh = level - l;
    int32_t slot = ocs__slot(c, l, ix >> sh, iy >> sh, iz >> sh);
    if (slot < 0) return -2;
    if (!(c->tab[slot].smax > 0.0f)) return l;
  }
  c->chk_level = level, c->chk_ix = ix, c->chk_iy = iy, c->chk_iz = iz;
  return -1;
}

/*-*** Ray geometry ***/

/* Intersections t1 ≤ t2 of p + t·d (d unit) with the sphere |x| = r about the planet centre;
 * 0 when the ray misses it. The half chord from the perpendicular distance (no b² − c). */
static int ocs__sphere(oc_dvec3 p, oc_dvec3 d, double r, double *t1, double *t2) {
  double b = oc_ddot(p, d);
  oc_dvec3 perp = oc_dmad(p, d, -b);
  double q = oc_dlen(perp);
  if (!(q < r)) return 0;
  double h = sqrt((r - q) * (r + q));
  *t1 = -b - h;
  *t2 = -b + h;
  return 1;
}

/* The part [t0, t1] of the ray from p toward the sun that τ integrates (sun_depth.h: the cuts);
 * 0 when it is empty. */
static int ocs__clip(oc_dvec3 p, oc_dvec3 d, double *t0, double *t1) {
  double a1, a2, i1, i2;
  if (oc_ddot(p, p) < OCS__R_STOP * OCS__R_STOP) return 0;
  if (!ocs__sphere(p, d, OCS__R_ATMO, &a1, &a2)) return 0;
  double lo = a1 > 0.0 ? a1 : 0.0, hi = a2;
  if (ocs__sphere(p, d, OCS__R_STOP, &i1, &i2) && i1 >= 0.0 && i1 < hi) hi = i1;
  double pv[3] = {p.x, p.y, p.z}, dv[3] = {d.x, d.y, d.z};
  for (int a = 0; a < 3; a++) { /* the root cube (the atmosphere sphere is inscribed: rounding only) */
    if (dv[a] > 0.0) hi = fmin(hi, (OCS__S - pv[a]) / dv[a]);
    else if (dv[a] < 0.0) hi = fmin(hi, (-OCS__S - pv[a]) / dv[a]);
  }
  if (!(hi > lo)) return 0;
  *t0 = lo;
  *t1 = hi;
  return 1;
}

/*-*** Exact integration of the reconstruction ***/

/* Trilinear interpolation of a cell's corners k[i + 2j + 4l] at fractions (fx, fy, fz). */
static inline double ocs__tri(const double k[8], double fx, double fy, double fz) {
  double a = k[0] + (k[1] - k[0]) * fx, b = k[2] + (k[3] - k[2]) * fx;
  double e = k[4] + (k[5] - k[4]) * fx, g = k[6] + (k[7] - k[6]) * fx;
  double y0 = a + (b - a) * fy, y1 = e + (g - e) * fy;
  return y0 + (y1 - y0) * fz;
}

/* Running integrals to record during a walk: out[i] = base + ∫ from the walk's start to cp[i], for
 * the ascending checkpoints cp[*i ..] that the walk passes. */
typedef struct {
  const double *cp;
  double *out;
  int n, i;
  double base;
} ocs__cps_t;

/* Records the checkpoints up to `upto` (inclusive) on a piece where σt is the constant `val` from
 * t (where the integral so far is sum). */
static void ocs__cps_const(ocs__cps_t *q, double upto, double t, double sum, double val) {
  if (!q) return;
  for (; q->i < q->n && q->cp[q->i] <= upto; q->i++) {
    double x = q->cp[q->i] > t ? q->cp[q->i] : t;
    q->out[q->i] = q->base + sum + val * (x - t);
  }
}

/* Distance along the ray p + t·dir (pv = p + S per axis, idv = 1/dir or 0) to where it leaves the
 * node (ix, iy, iz) of `level`. */
static double ocs__node_exit(const double pv[3], const int sg[3], const double idv[3], double size, const uint32_t n[3]) {
  double t = INFINITY;
  for (int a = 0; a < 3; a++) {
    double f = sg[a] > 0 ? ((double)n[a] + 1.0) * size : (double)n[a] * size;
    double x = (f - pv[a]) * idv[a];
    if (sg[a] != 0 && x < t) t = x; /* fmin's result (x is never NaN): a ternary, not a libm call */
  }
  return t;
}

/* ∫ σt over p + t·sun, t ∈ [ta, tb], with σt reconstructed from the bricks of `level`, EXACTLY up to
 * rounding: a 3D DDA walks the ray cell by cell through the level's sample lattice (cells of edge
 * v = size/7, 7³ per node, never straddling two nodes), and on each cell segment the trilinear
 * interpolant is a cubic in t, which Simpson's rule integrates exactly (both ends and the middle;
 * the end is the next cell's start inside a brick). Nodes inside an empty node of level_lo..level
 * are jumped over, a uniform node [v, v] adds v·length. Checkpoints (may be NULL) are recorded on
 * the way: a checkpoint inside a cell splits its segment, each part again exact. The ray must lie
 * in the root cube over [ta, tb] (ocs__clip). */
static double ocs__walk(ocs__ctx_t *c, oc_dvec3 p, double ta, double tb, int level, ocs__cps_t *q) {
  const oc_dvec3 s = c->d->sun;
  const double pv[3] = {p.x + OCS__S, p.y + OCS__S, p.z + OCS__S}, dv[3] = {s.x, s.y, s.z};
  const double v = c->voxel[level], inv = 1.0 / v, eta = 1e-6 * v;
  const int64_t ncell = (int64_t)7 << level;
  int sg[3];
  double idv[3];
  for (int a = 0; a < 3; a++) {
    sg[a] = dv[a] > 0.0 ? 1 : dv[a] < 0.0 ? -1 : 0;
    idv[a] = sg[a] ? 1.0 / dv[a] : 0.0;
  }
  double sum = 0.0, t = ta;
  int64_t g[3] = {0, 0, 0};
  int have = 0; /* g holds the cell at t */
  for (long it = 0; t < tb && !c->err && it < OCS__MAX_ITER; it++) {
    if (!have) { /* locate the cell just past t */
      double half = 0.5 * (tb - t), tl = t + (half < eta ? half : eta);
      for (int a = 0; a < 3; a++) {
        double u = floor((pv[a] + tl * dv[a]) * inv);
        g[a] = u < 0.0 ? 0 : u >= (double)ncell ? ncell - 1 : (int64_t)u;
      }
      have = 1;
    }
    uint32_t n[3] = {(uint32_t)(g[0] / 7), (uint32_t)(g[1] / 7), (uint32_t)(g[2] / 7)};
    int le = ocs__empty_level(c, level, n[0], n[1], n[2]);
    if (le == -2) break;
    if (le >= 0) { /* jump over the coarsest empty node */
      int sh = level - le;
      uint32_t ne[3] = {n[0] >> sh, n[1] >> sh, n[2] >> sh};
      double te = ocs__node_exit(pv, sg, idv, c->size[le], ne);
      if (!(te > t)) te = t + eta; /* rounding: never stall */
      if (te > tb) te = tb;
      ocs__cps_const(q, te, t, sum, 0.0);
      t = te, have = 0;
      continue;
    }
    int32_t slot = ocs__slot(c, level, n[0], n[1], n[2]);
    if (slot < 0) break;
    const ocs__ent_t *e = &c->tab[slot];
    if (e->smin == e->smax) { /* uniform: v·length */
      double te = ocs__node_exit(pv, sg, idv, c->size[level], n), val = e->smin;
      if (!(te > t)) te = t + eta;
      if (te > tb) te = tb;
      ocs__cps_const(q, te, t, sum, val);
      sum += val * (te - t);
      t = te, have = 0;
      continue;
    }
    const float *b = ocs__brick(c, slot);
    if (!b) break;
    if (c->tab[slot].smin == c->tab[slot].smax) continue; /* the brick itself is uniform or zero */
    /* cell by cell through this node */
    int64_t lo[3] = {7 * (int64_t)n[0], 7 * (int64_t)n[1], 7 * (int64_t)n[2]};
    double k[8], o[3], fa = 0.0;
    int first = 1;
    for (;;) {
      int bi = (int)(g[0] - lo[0]) + 8 * (int)(g[1] - lo[1]) + 64 * (int)(g[2] - lo[2]);
      k[0] = b[bi], k[1] = b[bi + 1], k[2] = b[bi + 8], k[3] = b[bi + 9];
      k[4] = b[bi + 64], k[5] = b[bi + 65], k[6] = b[bi + 72], k[7] = b[bi + 73];
      for (int a = 0; a < 3; a++) o[a] = (double)g[a] * v - pv[a];
      /* a cell whose corners are all 0 (σt ≥ 0: their sum is 0) interpolates to exactly +0.0, the
       * value ocs__tri would return, so it is not evaluated: clear cells of a cloudy brick are many */
      int zero = k[0] + k[1] + k[2] + k[3] + k[4] + k[5] + k[6] + k[7] == 0.0;
#define OCS__F(tt) \
  (zero ? 0.0 : ocs__tri(k, ((tt) * dv[0] - o[0]) * inv, ((tt) * dv[1] - o[1]) * inv, ((tt) * dv[2] - o[2]) * inv))
      if (first) fa = OCS__F(t), first = 0;
      double tc = tb;
      int am = -1;
      for (int a = 0; a < 3; a++) {
        if (!sg[a]) continue;
        double tn = ((double)(g[a] + (sg[a] > 0)) * v - pv[a]) * idv[a];
        if (tn < tc) tc = tn, am = a;
      }
      if (q) /* checkpoints inside this cell split its segment */
        for (; q->i < q->n && q->cp[q->i] <= tc; q->i++) {
          double x = q->cp[q->i];
          if (x > t) {
            double fx = OCS__F(x);
            sum += (x - t) * (1.0 / 6.0) * (fa + 4.0 * OCS__F(0.5 * (t + x)) + fx);
            t = x, fa = fx;
          }
          q->out[q->i] = q->base + sum;
        }
      if (tc > t) {
        double fb = OCS__F(tc);
        sum += (tc - t) * (1.0 / 6.0) * (fa + 4.0 * OCS__F(0.5 * (t + tc)) + fb);
        t = tc, fa = fb;
      }
#undef OCS__F
      if (am < 0 || !(t < tb)) break; /* the end */
      g[am] += sg[am];
      if (g[am] < 0 || g[am] >= ncell) { /* out of the root cube (rounding at its face) */
        t = tb;
        break;
      }
      if (g[am] < lo[am] || g[am] >= lo[am] + 7) break; /* into the next node */
      if (++it >= OCS__MAX_ITER) break;
    }
  }
  ocs__cps_const(q, tb, t, sum, 0.0);
  return sum;
}

/* ∫ σt over p + t·sun, t ∈ [t0, t1], through the cone's levels: the level sampled at distance t is
 * the one the step Δ(t) = max(h0, cone·(t + t_ref)) selects (level_m − j where Δ ≥ h0·2^(j+1),
 * not coarser than level_lo), so the ray is cut where cone·(t + t_ref) = h0·2^(j+1) and each piece
 * is integrated exactly at its level (ocs__walk). */
static double ocs__march(ocs__ctx_t *c, oc_dvec3 p, double t0, double t1, double t_ref) {
  int jmax = c->level_m - c->level_lo, j = 0;
  double cone = c->d->cone, tau = 0.0, t = t0;
  while (j < jmax && t0 >= c->step_up[j] / cone - t_ref) j++;
  while (t < t1 && !c->err) {
    double te = t1;
    if (j < jmax) {
      double tj = c->step_up[j] / cone - t_ref;
      if (tj < te) te = tj;
    }
    if (te > t) {
      tau += ocs__walk(c, p, t, te, c->level_m - j, NULL);
      t = te;
    }
    if (j >= jmax) break;
    j++;
  }
  return tau;
}

/* τ at p: the clipped ray, marched. */
static double ocs__tau_point(ocs__ctx_t *c, oc_dvec3 p, double t_ref) {
  double t0, t1;
  if (!ocs__clip(p, c->d->sun, &t0, &t1)) return 0.0;
  return ocs__march(c, p, t0, t1, t_ref);
}

static float ocs__to_float(double tau) {
  if (!(tau > 0.0)) return 0.0f;
  return tau < 3.0e38 ? (float)tau : 3.0e38f;
}

/*-*** Clear sky: a node's sun column proven empty by the bounds (ocs_tau_direct(), note 1) ***/

/*! Most nodes one proof may visit before giving up (and marching): a column through clear air
 *  visits tens; one through a cloud fails long before this. */
#define OCS__CLEAR_BUDGET 4096
/*! Spatial margin (m) around every node tested: far above the rounding of the walk's positions
 *  (a few ulps of 6.5e6 m, about 1e-9 m each). */
#define OCS__CLEAR_EPS 0.05

typedef struct {
  double c[3], h;  /* the node box's centre and half edge (+ margin) */
  double id[3];    /* 1/sun per axis, 0 where the sun's component is 0 */
  int sg[3];
  int maxl;        /* the finest level that may prove this piece */
  long budget;
} ocs__sweep_t;

/* Whether the segment c + t·sun, t ∈ [ta, tb], meets the box [lo − h, hi + h] (the node grown by
 * the swept box's half edge: the swept box meets the node iff its centre's segment meets that). */
static int ocs__seg_meets(const ocs__sweep_t *w, double ta, double tb, const double lo[3], const double hi[3]) {
  for (int a = 0; a < 3; a++) {
    double l = lo[a] - w->h, u = hi[a] + w->h;
    if (!w->sg[a]) {
      if (w->c[a] < l || w->c[a] > u) return 0;
      continue;
    }
    double t1 = (l - w->c[a]) * w->id[a], t2 = (u - w->c[a]) * w->id[a];
    if (t1 > t2) {
      double x = t1;
      t1 = t2, t2 = x;
    }
    ta = t1 > ta ? t1 : ta;
    tb = t2 < tb ? t2 : tb;
    if (ta > tb) return 0;
  }
  return 1;
}

/* Whether every point of the swept box over [ta, tb] inside node (level; ix, iy, iz) lies in a
 * node of level level_lo .. maxl whose bound is [0, 0] (the test ocs__empty_level() makes), or in
 * a node of level maxl whose samples are all 0. */
static int ocs__clear_node(ocs__ctx_t *c, ocs__sweep_t *w, int level, uint32_t ix, uint32_t iy, uint32_t iz, double ta, double tb) {
  if (--w->budget < 0) return 0;
  double size = oc_key_size(level);
  double lo[3] = {-OCS__S + (double)ix * size, -OCS__S + (double)iy * size, -OCS__S + (double)iz * size};
  double hi[3] = {lo[0] + size, lo[1] + size, lo[2] + size};
  if (!ocs__seg_meets(w, ta, tb, lo, hi)) return 1;
  if (level >= c->level_lo) {
    int32_t slot = ocs__slot(c, level, ix, iy, iz);
    if (slot < 0) return 0;
    if (!(c->tab[slot].smax > 0.0f)) return 1;
    if (level >= w->maxl) { /* the level walked here: its samples decide, as they do in the walk */
      const float *b = ocs__fetch(c, slot);
      return b && !(c->tab[slot].bmax > 0.0f);
    }
  }
  for (int q = 0; q < 8; q++)
    if (!ocs__clear_node(c, w, level + 1, 2 * ix + (q & 1), 2 * iy + (q >> 1 & 1), 2 * iz + (q >> 2), ta, tb)) return 0;
  return 1;
}

/* Whether the direct march of `key` provably gives τ = 0 at all 512 samples: the swept box is cut
 * where the cone changes level (as ocs__march cuts each ray, t_ref = 0, at the same doubles), and
 * each piece is covered by nodes the walk of that piece would find empty: a bound [0, 0] at a level
 * from level_lo to the one walked there, or, at the level walked, samples all 0 (the walk fetches
 * that brick and then jumps it; the proof fetches it without narrowing the memo's range, so a
 * march after a failed proof runs exactly as without it). */
static int ocs__column_clear(ocs__ctx_t *c, oc_key_t key) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  const oc_dvec3 s = c->d->sun;
  ocs__sweep_t w;
  w.h = 0.5 * size + OCS__CLEAR_EPS;
  w.c[0] = o.x + 0.5 * size, w.c[1] = o.y + 0.5 * size, w.c[2] = o.z + 0.5 * size;
  const double dv[3] = {s.x, s.y, s.z};
  for (int a = 0; a < 3; a++) {
    w.sg[a] = dv[a] > 0.0 ? 1 : dv[a] < 0.0 ? -1 : 0;
    w.id[a] = w.sg[a] ? 1.0 / dv[a] : 0.0;
  }
  w.budget = OCS__CLEAR_BUDGET;
  /* Where any sample's ray may leave the atmosphere sphere (clip's t1 ≤ that exit): for p in the
   * box, exit = −b + sqrt(Ra² − |p|² + b²), b = p·sun, bounded with max(−b) and max(b²) over the
   * corners (b is linear) and min |p|² over the box. */
  double nb = -INFINITY, b2 = 0.0, p2 = 0.0;
  for (int q = 0; q < 8; q++) {
    double b = (o.x + (q & 1) * size) * s.x + (o.y + (q >> 1 & 1) * size) * s.y + (o.z + (q >> 2) * size) * s.z;
    nb = fmax(nb, -b), b2 = fmax(b2, b * b);
  }
  const double pv[3] = {o.x, o.y, o.z};
  for (int a = 0; a < 3; a++) {
    double x = pv[a] > 0.0 ? pv[a] : pv[a] + size < 0.0 ? pv[a] + size : 0.0;
    p2 += x * x;
  }
  double t_hi = nb + sqrt(fmax(0.0, OCS__R_ATMO * OCS__R_ATMO - p2 + b2));
  t_hi = t_hi * (1.0 + 1e-9) + 1.0;
  if (!(t_hi > 0.0)) return 1; /* no ray meets the atmosphere ahead */
  int jmax = c->level_m - c->level_lo;
  double ta = 0.0;
  for (int j = 0; j <= jmax && ta < t_hi; j++) {
    double tb = j < jmax ? c->step_up[j] / c->d->cone : t_hi;
    if (tb > t_hi) tb = t_hi;
    if (tb > ta) {
      w.maxl = c->level_m - j;
      if (!ocs__clear_node(c, &w, 0, 0, 0, 0, ta, tb)) return 0;
    }
    ta = tb > ta ? tb : ta;
  }
  return 1;
}

/* The clear-sky proof of ocs_tau_direct() (note 1), counted: 1 when τ is all 0 and need not be
 * marched (tau zeroed), else 0 and c ready for the march (what the proof fetched stays memoised). */
static int ocs__proven_clear(ocs__ctx_t *c, const ocs_tau_desc_t *du, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  if (du->stats) atomic_fetch_add_explicit(&du->stats->direct, 1, memory_order_relaxed);
  int clear = ocs__column_clear(c, key);
  c->err = 0; /* a failed proof (out of memory in its memo) leaves the march to find out */
  if (!clear) return 0;
  if (du->stats) atomic_fetch_add_explicit(&du->stats->clear_proven, 1, memory_order_relaxed);
  if (du->march_clear) {
    if (du->stats) atomic_fetch_add_explicit(&du->stats->clear_marched, 1, memory_order_relaxed);
    return 0;
  }
  memset(tau, 0, sizeof(float) * OC_BRICK_VOXELS);
  return 1;
}

int ocs_tau_direct(const ocs_tau_desc_t *du, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  ocs__desc_t d;
  if (!tau || !oc_key_valid(key)) return OC_EINVAL;
  OC_TRY(ocs__desc(du, &d));
  ocs__ctx_t c;
  OC_TRY(ocs__ctx_init(&c, &d, oc_key_level(key)));
  if (ocs__proven_clear(&c, du, key, tau)) {
    ocs__ctx_free(&c);
    return 0;
  }
  for (int k = 0; k < 8 && !c.err; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) tau[i + 8 * j + 64 * k] = ocs__to_float(ocs__tau_point(&c, ocs_brick_sample_pos(key, i, j, k), 0.0));
  int err = c.err;
  ocs__ctx_free(&c);
  if (err) memset(tau, 0, sizeof(float) * OC_BRICK_VOXELS);
  return err;
}

/*-*** The group volume ***/

#define OCS__VOL_MAGIC 0x5441554fu /* "OUAT" */
#define OCS__VOL_VERSION 2u

/* The block: this header, the coverage bitmap (one bit per descendant, x fastest), the column
 * table (na × nb, a fastest), the floats, then the inputs (n_bounds ocs__in_bound_t, n_bricks
 * ocs__in_brick_t); each part starts on a 16-byte boundary. */
typedef struct {
  uint32_t magic, version;
  oc_key_t group;
  int32_t level, nd;  /* nodes' level; descendants per axis (2^(level − level(group))) */
  int32_t na, nb;     /* columns along e1, e2 */
  uint64_t nfloats, bytes;
  uint64_t off_cov, off_cols, off_vals; /* byte offsets of the parts */
  double o[3], e1[3], e2[3], s[3]; /* grid origin (group centre) and the sun frame */
  double a_lo, b_lo, c_lo, da, dc; /* column (ia, ib) at a_lo + ia·da, b_lo + ib·da; slice k at c_lo + k·dc */
  /* what else the bits depend on: the desc's parameters (the sun is s) */
  int32_t filter_levels, min_level, group_levels, flags; /* flags: OCS__VOL_COVER_ALL | OCS__VOL_GROUND */
  double step_factor, cone;
  uint64_t off_inp;
  uint32_t n_bounds, n_bricks;
} ocs__vol_t;
#define OCS__VOL_COVER_ALL 1
#define OCS__VOL_GROUND 2

/* A volume's inputs: every answer its callbacks gave. The build is a deterministic function of
 * them (each key is asked at most once, and what is asked next depends only on earlier answers),
 * so the same answers make the same volume, bit for bit (ocs_tau_volume_unchanged). */
typedef struct {
  oc_key_t key;
  float smin, smax; /* as bound() answered */
} ocs__in_bound_t;
typedef struct {
  oc_key_t key;
  uint64_t lo, hi; /* XXH3-128 of the brick sigma() gave, sanitised */
} ocs__in_brick_t;

typedef struct {
  int32_t k0, n; /* slices k0 .. k0 + n − 1 */
  uint32_t off;  /* first float */
} ocs__col_t;

/* Grid coordinates (column a, column b, slice) of the 512 samples of node (kx, ky, kz) at the
 * volume's level, f[v][3] with v = i + 8j + 64k: sample 0 projected, then affine steps along i, j,
 * k (samples lie on a lattice). The build marks what each sample needs with exactly the
 * operations the lookup uses, so a lookup always finds the slices it reads. */
static void ocs__grid_of(const ocs__vol_t *v, uint32_t kx, uint32_t ky, uint32_t kz, double f[512][3]) {
  double u = ocs__voxel(v->level);
  double rel[3] = {-OCS__S + (double)(7 * (int64_t)kx) * u - v->o[0], -OCS__S + (double)(7 * (int64_t)ky) * u - v->o[1],
                   -OCS__S + (double)(7 * (int64_t)kz) * u - v->o[2]};
  const double *ax[3] = {v->e1, v->e2, v->s};
  double lo[3] = {v->a_lo, v->b_lo, v->c_lo}, sp[3] = {v->da, v->da, v->dc}, f0[3], st[3][3];
  for (int a = 0; a < 3; a++) {
    f0[a] = (rel[0] * ax[a][0] + rel[1] * ax[a][1] + rel[2] * ax[a][2] - lo[a]) / sp[a];
    for (int d = 0; d < 3; d++) st[d][a] = u * ax[a][d] / sp[a]; /* one sample along axis d */
  }
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++)
        for (int a = 0; a < 3; a++) f[i + 8 * j + 64 * k][a] = f0[a] + i * st[0][a] + j * st[1][a] + k * st[2][a];
}

static oc_key_t ocs__group(const ocs__desc_t *d, oc_key_t key) {
  int l = oc_key_level(key) - d->group_levels;
  return oc_key_ancestor(key, l > 0 ? l : 0);
}

oc_key_t ocs_tau_group_of(const ocs_tau_desc_t *du, oc_key_t key) {
  ocs__desc_t d;
  if (!oc_key_valid(key) || ocs__desc(du, &d) < 0) return OC_KEY_INVALID;
  return ocs__group(&d, key);
}

/* The part [lo, hi] of the line q0 + c·s inside the root cube; 0 when it misses it. */
static int ocs__line_root(oc_dvec3 q0, oc_dvec3 s, double *lo, double *hi) {
  double pv[3] = {q0.x, q0.y, q0.z}, dv[3] = {s.x, s.y, s.z}, a = -INFINITY, b = INFINITY;
  for (int k = 0; k < 3; k++) {
    if (dv[k] == 0.0) {
      if (!(pv[k] >= -OCS__S && pv[k] <= OCS__S)) return 0;
      continue;
    }
    double u = (-OCS__S - pv[k]) / dv[k], w = (OCS__S - pv[k]) / dv[k];
    a = fmax(a, fmin(u, w)), b = fmin(b, fmax(u, w));
  }
  *lo = a, *hi = b;
  return b > a;
}

/* One column: τ at slices k0 .. k0 + n − 1 (c_k = c_lo + k·dc). The top is a march toward the sun
 * (cone distances counted from the middle of the column's run). Below it the column is integrated
 * exactly at the march level (ocs__walk) from the lowest slice up to the top, recording the running
 * integral J at every slice, with σt counted only inside the atmosphere sphere and the root cube
 * and outside the stop sphere: a slice's τ is then τ(top) + J(top) − J(c_k), the same cut as a
 * march from that point (sun_depth.h): a slice inside the stop sphere has τ = 0, one below it
 * integrates only up to where its ray enters it (J(entry) − J(c_k)). */
static void ocs__column(ocs__ctx_t *c, const ocs__vol_t *v, oc_dvec3 q0, int32_t k0, int32_t n, float *out) {
  oc_dvec3 s = c->d->sun;
  double ctop = v->c_lo + (k0 + n - 1) * v->dc;
  double cmid = v->c_lo + (k0 + 0.5 * (n - 1)) * v->dc;
  double top = ocs__tau_point(c, oc_dmad(q0, s, ctop), ctop - cmid);
  out[n - 1] = ocs__to_float(top);
  if (n < 2 || c->err) return;
  if (c->scr_cap < 2 * n) {
    double *ns = realloc(c->scr, 2 * (size_t)n * sizeof *ns);
    if (!ns) {
      c->err = OC_ENOMEM;
      return;
    }
    c->scr = ns, c->scr_cap = 2 * n;
  }
  double *cp = c->scr, *J = c->scr + n;
  for (int32_t i = 0; i < n; i++) cp[i] = v->c_lo + (k0 + i) * v->dc, J[i] = 0.0;
  double ci1 = INFINITY, ci2 = -INFINITY, a1, a2, r1, r2, ji1 = 0.0;
  int stop = ocs__sphere(q0, s, OCS__R_STOP, &ci1, &ci2);
  ocs__cps_t q = {cp, J, n, 0, 0.0};
  if (ocs__sphere(q0, s, OCS__R_ATMO, &a1, &a2) && ocs__line_root(q0, s, &r1, &r2)) {
    double lo = fmax(cp[0], fmax(a1, r1)), hi = fmin(ctop, fmin(a2, r2));
    /* the pieces where σt counts: [lo, hi] without the stop sphere's (ci1, ci2) */
    double pa[2] = {lo, stop ? fmax(lo, ci2) : hi}, pb[2] = {stop ? fmin(hi, ci1) : hi, hi};
    for (int k = 0; k < 2 && !c->err; k++) {
      if (pb[k] > pa[k]) {
        ocs__cps_const(&q, pa[k], pa[k], 0.0, 0.0); /* J is constant before the piece */
        q.base += ocs__walk(c, q0, pa[k], pb[k], c->level_m, &q);
      }
      if (k == 0) ji1 = q.base; /* J where the ray enters the stop sphere */
      if (!stop) break;
    }
  }
  ocs__cps_const(&q, INFINITY, 0.0, 0.0, 0.0);
  for (int32_t i = n - 2; i >= 0; i--) {
    double ck = cp[i], tau;
    if (ck >= ci1 && ck <= ci2) tau = 0.0;                /* the sample point is inside the stop sphere */
    else if (ck < ci1 && ctop >= ci1) tau = ji1 - J[i]; /* its ray is cut where it enters it */
    else tau = top + (J[n - 1] - J[i]);
    out[i] = ocs__to_float(tau);
  }
}

static size_t ocs__align16(size_t x) { return (x + 15) & ~(size_t)15; }

/* Whether node (ix, iy, iz) of `level` may hold σt, judged from the march level's samples (its
 * ancestor A at level m): the sample cubes of a level (edge size/7 around each sample) tile space,
 * so when every sample of A whose cube overlaps the node's footprint (the node grown by half its
 * voxel) is 0, σt is 0 over the whole footprint and so are all the node's samples (exactly for an
 * exact box filter; a source that estimates box averages from sub-samples may, rarely, see a
 * thin wisp at the finer level only: ocs_tau_volume_lookup() then says OC_ENOENT and the caller
 * uses ocs_tau_direct()). The bricks asked for are those the columns march through anyway.
 * @return 1, 0, or a negative OC_E*. */
static int ocs__covered(ocs__ctx_t *c, int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  int m = c->level_m, fe = level - m;
  uint32_t ax = ix >> fe, ay = iy >> fe, az = iz >> fe;
  int32_t slot = ocs__lookup(c, oc_key_make(m, ax, ay, az));
  if (slot < 0) return c->err;
  if (!(c->tab[slot].smax > 0.0f)) return 0;
  if (c->tab[slot].smin > 0.0f) return 1;
  const float *b = ocs__brick(c, slot);
  if (!b) return c->err;
  if (!(c->tab[slot].smax > 0.0f)) return 0; /* the brick itself is all zero */
  /* per axis, the local samples j of A whose cube [j − ½, j + ½] (level-m voxels) overlaps the
   * footprint [(7i − ½)/2^fe, (7i + 7½)/2^fe] − 7·a (open overlap; exact in binary) */
  uint32_t in[3] = {ix, iy, iz}, an[3] = {ax, ay, az};
  int lo[3], hi[3];
  for (int k = 0; k < 3; k++) {
    double u0 = ldexp(7.0 * in[k] - 0.5, -fe) - 7.0 * an[k], u1 = ldexp(7.0 * in[k] + 7.5, -fe) - 7.0 * an[k];
    lo[k] = (int)floor(u0 - 0.5) + 1;
    hi[k] = (int)ceil(u1 + 0.5) - 1;
    lo[k] = lo[k] < 0 ? 0 : lo[k];
    hi[k] = hi[k] > 7 ? 7 : hi[k];
  }
  for (int k = lo[2]; k <= hi[2]; k++)
    for (int j = lo[1]; j <= hi[1]; j++)
      for (int i = lo[0]; i <= hi[0]; i++)
        if (b[i + 8 * j + 64 * k] > 0.0f) return 1;
  return 0;
}

/* The desc's parameters a volume's bits depend on (besides the sun and the callbacks' answers). */
static void ocs__vol_params(ocs__vol_t *v, const ocs__desc_t *d) {
  v->filter_levels = d->filter_levels, v->min_level = d->min_level, v->group_levels = d->group_levels;
  v->flags = (d->u->cover_all ? OCS__VOL_COVER_ALL : 0) | (d->u->ground ? OCS__VOL_GROUND : 0);
  v->step_factor = d->step_factor, v->cone = d->cone;
}

/* Appends the memo's answers to the block (*blk, *total grow): every bound asked, and the hash of
 * every brick fetched. @return 0 or OC_ENOMEM (*blk unchanged). */
static int ocs__record_inputs(const ocs__ctx_t *c, unsigned char **blk, size_t *total) {
  size_t off = ocs__align16(*total);
  size_t n = off + c->count * sizeof(ocs__in_bound_t) + (size_t)c->nbricks * sizeof(ocs__in_brick_t);
  unsigned char *nb = realloc(*blk, n);
  if (!nb) return OC_ENOMEM;
  memset(nb + *total, 0, off - *total);
  ocs__vol_t *v = (ocs__vol_t *)nb;
  ocs__in_bound_t *ib = (ocs__in_bound_t *)(nb + off);
  ocs__in_brick_t *ik = (ocs__in_brick_t *)(ib + c->count);
  uint32_t nbound = 0, nbrick = 0;
  for (uint32_t i = 0; i < c->cap; i++) {
    const ocs__ent_t *e = &c->tab[i];
    if (!e->key) continue;
    ib[nbound++] = (ocs__in_bound_t){e->key, e->asked_min, e->asked_max};
    if (e->brick < 0) continue;
    XXH128_hash_t h = XXH3_128bits(c->pool + (size_t)e->brick * OC_BRICK_VOXELS, OC_BRICK_VOXELS * sizeof(float));
    ik[nbrick++] = (ocs__in_brick_t){e->key, h.low64, h.high64};
  }
  v->off_inp = off, v->n_bounds = nbound, v->n_bricks = nbrick;
  v->bytes = n;
  *blk = nb;
  *total = n;
  return 0;
}

int ocs_tau_volume_build(const ocs_tau_desc_t *du, oc_key_t group, int level, void **vol, size_t *bytes) {
  ocs__desc_t d;
  if (!vol || !bytes) return OC_EINVAL;
  *vol = NULL;
  *bytes = 0;
  OC_TRY(ocs__desc(du, &d));
  int gl = oc_key_level(group);
  if (gl < 0 || level < gl || level > OC_KEY_MAX_LEVEL || level - gl > OCS_TAU_MAX_GROUP_LEVELS) return OC_EINVAL;

  /* The sun frame: s, and e1 ⊥ s from the axis least aligned with it, e2 = s × e1. */
  oc_dvec3 s = d.sun;
  double as[3] = {fabs(s.x), fabs(s.y), fabs(s.z)};
  int ax = as[0] < as[1] ? (as[0] < as[2] ? 0 : 2) : (as[1] < as[2] ? 1 : 2);
  oc_dvec3 axis = oc_dv3(ax == 0, ax == 1, ax == 2);
  oc_dvec3 e1 = oc_dnorm(oc_dmad(axis, s, -oc_ddot(axis, s))), e2 = oc_dcross(s, e1);
  double k1 = fabs(e1.x) + fabs(e1.y) + fabs(e1.z), k2 = fabs(e2.x) + fabs(e2.y) + fabs(e2.z);
  double ks = as[0] + as[1] + as[2];

  oc_dvec3 go;
  double gsize;
  oc_key_bounds(group, &go, &gsize);
  uint32_t gx, gy, gz;
  oc_key_coords(group, &gx, &gy, &gz);
  int32_t nd = 1 << (level - gl);
  double vox = ocs__voxel(level);
  /* The grid spans the group's cube (every sample lies in its closed box) with a column and two
   * slices to spare on every side; the volume's header doubles as the projection's parameters. */
  ocs__vol_t hv;
  memset(&hv, 0, sizeof hv);
  hv.da = OCS_TAU_COLUMN_SPACING * vox, hv.dc = OCS_TAU_SLICE_SPACING * vox;
  double gh = 0.5 * gsize * (1.0 + 1e-9) + 1e-6;
  double ea = gh * k1, eb = gh * k2, ec = gh * ks;
  int32_t na = (int32_t)ceil(2.0 * ea / hv.da) + 3, nb = (int32_t)ceil(2.0 * eb / hv.da) + 3;
  int32_t nc = (int32_t)ceil((2.0 * ec + 4.0 * hv.dc) / hv.dc) + 2;
  hv.level = level, hv.nd = nd, hv.na = na, hv.nb = nb;
  hv.o[0] = go.x + 0.5 * gsize, hv.o[1] = go.y + 0.5 * gsize, hv.o[2] = go.z + 0.5 * gsize;
  hv.e1[0] = e1.x, hv.e1[1] = e1.y, hv.e1[2] = e1.z;
  hv.e2[0] = e2.x, hv.e2[1] = e2.y, hv.e2[2] = e2.z;
  hv.s[0] = s.x, hv.s[1] = s.y, hv.s[2] = s.z;
  hv.a_lo = -ea - hv.da, hv.b_lo = -eb - hv.da, hv.c_lo = -ec - 2.0 * hv.dc;
  ocs__vol_params(&hv, &d);

  ocs__ctx_t c;
  OC_TRY(ocs__ctx_init(&c, &d, level));
  size_t ncol = (size_t)na * (size_t)nb, ndesc = (size_t)nd * nd * nd;
  size_t off_cov = ocs__align16(sizeof(ocs__vol_t)), off_cols = off_cov + ocs__align16((ndesc + 7) / 8);
  size_t off_vals = off_cols + ocs__align16(ncol * sizeof(ocs__col_t));
  unsigned char *cov = calloc(1, (ndesc + 7) / 8);
  int32_t *krange = malloc(2 * ncol * sizeof(int32_t));
  ocs__col_t *cols = malloc(ncol * sizeof *cols);
  double(*f)[3] = malloc(sizeof(double[OC_BRICK_VOXELS][3])); /* one node's grid coordinates */
  int r = 0;
  if (!cov || !krange || !cols || !f) {
    r = OC_ENOMEM;
    goto out;
  }

  /* Pass 1: coverage (descendants the march level's σt says may hold σt, ocs__covered()) and the
   * slices each column must hold: for every sample of a covered descendant, slices ⌊c⌋ and ⌊c⌋ + 1
   * of the four columns around its sun ray. */
  for (size_t i = 0; i < ncol; i++) krange[2 * i] = INT32_MAX, krange[2 * i + 1] = -1;
  for (size_t q = 0; q < ndesc; q++) {
    uint32_t qx = (uint32_t)(q % (size_t)nd), qy = (uint32_t)(q / (size_t)nd % (size_t)nd), qz = (uint32_t)(q / ((size_t)nd * nd));
    uint32_t kx = gx * (uint32_t)nd + qx, ky = gy * (uint32_t)nd + qy, kz = gz * (uint32_t)nd + qz;
    int cv = du->cover_all ? 1 : ocs__covered(&c, level, kx, ky, kz);
    if (cv < 0) {
      r = cv;
      goto out;
    }
    if (!cv && du->ground && du->ground(du->ctx, oc_key_make(level, kx, ky, kz))) {
      float zero[OC_BRICK_VOXELS]; /* the proof writes the τ it proves (0), not needed here */
      cv = !ocs__proven_clear(&c, du, oc_key_make(level, kx, ky, kz), zero);
      if (cv && du->stats) atomic_fetch_add_explicit(&du->stats->columns, 1, memory_order_relaxed);
    }
    if (!cv) continue;
    cov[q / 8] |= (unsigned char)(1u << (q % 8));
    ocs__grid_of(&hv, kx, ky, kz, f);
    for (int vi = 0; vi < OC_BRICK_VOXELS; vi++) {
      /* the margins keep every coordinate ≥ 1: truncation is floor */
      if (!(f[vi][0] >= 0.0 && f[vi][0] < na - 1 && f[vi][1] >= 0.0 && f[vi][1] < nb - 1 && f[vi][2] >= 0.0 &&
            f[vi][2] < nc - 1)) {
        r = OC_ECORRUPT; /* the margins make this impossible */
        goto out;
      }
      int32_t ia = (int32_t)f[vi][0], ib = (int32_t)f[vi][1], kc = (int32_t)f[vi][2];
      int32_t *kr = &krange[2 * ((size_t)ib * (size_t)na + (size_t)ia)];
      for (int m = 0; m < 4; m++) {
        int32_t *km = kr + 2 * ((m & 1) + (m >> 1) * na);
        km[0] = kc < km[0] ? kc : km[0];
        km[1] = kc + 1 > km[1] ? kc + 1 : km[1];
      }
    }
  }
  uint64_t nfloats = 0;
  for (size_t i = 0; i < ncol; i++) {
    cols[i].k0 = 0, cols[i].n = 0, cols[i].off = (uint32_t)nfloats;
    if (krange[2 * i + 1] < 0) continue;
    cols[i].k0 = krange[2 * i], cols[i].n = krange[2 * i + 1] - krange[2 * i] + 1;
    nfloats += (uint64_t)cols[i].n;
  }

  size_t total = off_vals + (size_t)nfloats * sizeof(float);
  unsigned char *blk = malloc(total);
  if (!blk) {
    r = OC_ENOMEM;
    goto out;
  }
  ocs__vol_t *v = (ocs__vol_t *)blk;
  memset(blk, 0, off_vals);
  *v = hv;
  v->magic = OCS__VOL_MAGIC, v->version = OCS__VOL_VERSION;
  v->group = group;
  v->nfloats = nfloats, v->bytes = total;
  v->off_cov = off_cov, v->off_cols = off_cols, v->off_vals = off_vals;
  memcpy(blk + off_cov, cov, (ndesc + 7) / 8);
  memcpy(blk + off_cols, cols, ncol * sizeof *cols);
  float *val = (float *)(blk + off_vals);

  /* Pass 2: march every column once. */
  oc_dvec3 o = oc_dv3(hv.o[0], hv.o[1], hv.o[2]);
  for (size_t i = 0; i < ncol && !c.err; i++) {
    if (!cols[i].n) continue;
    double a = hv.a_lo + (double)(i % (size_t)na) * hv.da, b = hv.b_lo + (double)(i / (size_t)na) * hv.da;
    oc_dvec3 q0 = oc_dadd(o, oc_dadd(oc_dscale(e1, a), oc_dscale(e2, b)));
    ocs__column(&c, v, q0, cols[i].k0, cols[i].n, val + cols[i].off);
  }
  r = c.err ? c.err : ocs__record_inputs(&c, &blk, &total);
  if (r < 0) {
    free(blk);
    goto out;
  }
  *vol = blk;
  *bytes = total;
out:
  ocs__ctx_free(&c);
  free(cov);
  free(krange);
  free(cols);
  free(f);
  return r;
}

int ocs_tau_volume_lookup(const void *vol, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  const ocs__vol_t *v = vol;
  if (!v || !tau || v->magic != OCS__VOL_MAGIC || v->version != OCS__VOL_VERSION) return OC_EINVAL;
  int gl = oc_key_level(v->group);
  if (oc_key_level(key) != v->level || oc_key_ancestor(key, gl) != v->group) return OC_EINVAL;
  const unsigned char *blk = vol;
  uint32_t kx, ky, kz, gx, gy, gz;
  oc_key_coords(key, &kx, &ky, &kz);
  oc_key_coords(v->group, &gx, &gy, &gz);
  size_t q = (size_t)(kx - gx * (uint32_t)v->nd) + (size_t)v->nd * ((ky - gy * (uint32_t)v->nd) + (size_t)v->nd * (kz - gz * (uint32_t)v->nd));
  if (!(blk[v->off_cov + q / 8] >> (q % 8) & 1u)) return OC_ENOENT;
  const ocs__col_t *cols = (const ocs__col_t *)(blk + v->off_cols);
  const float *val = (const float *)(blk + v->off_vals);
  double f[OC_BRICK_VOXELS][3];
  ocs__grid_of(v, kx, ky, kz, f);
  for (int vi = 0; vi < OC_BRICK_VOXELS; vi++) {
    if (!(f[vi][0] >= 0.0 && f[vi][0] < v->na - 1 && f[vi][1] >= 0.0 && f[vi][1] < v->nb - 1 && f[vi][2] >= 0.0))
      return OC_ECORRUPT;
    int32_t ia = (int32_t)f[vi][0], ib = (int32_t)f[vi][1], kc = (int32_t)f[vi][2]; /* floor: ≥ 0 */
    double wa = f[vi][0] - ia, wb = f[vi][1] - ib, wc = f[vi][2] - kc;
    const ocs__col_t *c00 = &cols[(size_t)ib * (size_t)v->na + (size_t)ia];
    const ocs__col_t *qc[4] = {c00, c00 + 1, c00 + v->na, c00 + v->na + 1};
    double t[4];
    for (int m = 0; m < 4; m++) {
      if (kc < qc[m]->k0 || kc + 1 > qc[m]->k0 + qc[m]->n - 1) return OC_ECORRUPT; /* the build marked these */
      const float *cv = val + qc[m]->off + (uint32_t)(kc - qc[m]->k0);
      t[m] = cv[0] + (cv[1] - (double)cv[0]) * wc;
    }
    double x0 = t[0] + (t[1] - t[0]) * wa, x1 = t[2] + (t[3] - t[2]) * wa;
    tau[vi] = ocs__to_float(x0 + (x1 - x0) * wb);
  }
  return 0;
}

/* Whether a volume was built with d's parameters and sun (compared bit for bit). */
static int ocs__same_params(const ocs__vol_t *v, const ocs__desc_t *d) {
  ocs__vol_t w;
  ocs__vol_params(&w, d);
  return w.filter_levels == v->filter_levels && w.min_level == v->min_level && w.group_levels == v->group_levels &&
         w.flags == v->flags && w.step_factor == v->step_factor && w.cone == v->cone && d->sun.x == v->s[0] &&
         d->sun.y == v->s[1] && d->sun.z == v->s[2];
}

int ocs_tau_volume_unchanged(const ocs_tau_desc_t *du, const void *vol) {
  ocs__desc_t d;
  OC_TRY(ocs__desc(du, &d));
  const ocs__vol_t *v = vol;
  if (!v || v->magic != OCS__VOL_MAGIC || v->version != OCS__VOL_VERSION) return OC_EINVAL;
  if (!ocs__same_params(v, &d)) return 0;
  const ocs__in_bound_t *ib = (const ocs__in_bound_t *)((const unsigned char *)vol + v->off_inp);
  for (uint32_t i = 0; i < v->n_bounds; i++) { /* the bounds first: most are cached, and cheap */
    float mn = 0.0f, mx = 0.0f;
    du->bound(du->ctx, ib[i].key, &mn, &mx);
    if (memcmp(&mn, &ib[i].smin, sizeof mn) || memcmp(&mx, &ib[i].smax, sizeof mx)) return 0;
  }
  const ocs__in_brick_t *ik = (const ocs__in_brick_t *)(ib + v->n_bounds);
  float b[OC_BRICK_VOXELS];
  for (uint32_t i = 0; i < v->n_bricks; i++) {
    OC_TRY(du->sigma(du->ctx, ik[i].key, b));
    oc_sanitize(b, OC_BRICK_VOXELS, NULL);
    XXH128_hash_t h = XXH3_128bits(b, sizeof b);
    if (h.low64 != ik[i].lo || h.high64 != ik[i].hi) return 0;
  }
  return 1;
}

int ocs_tau_columns(const ocs_tau_desc_t *du, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  ocs__desc_t d;
  if (!tau || !oc_key_valid(key)) return OC_EINVAL;
  OC_TRY(ocs__desc(du, &d));
  ocs__ctx_t c;
  OC_TRY(ocs__ctx_init(&c, &d, oc_key_level(key)));
  int clear = ocs__proven_clear(&c, du, key, tau);
  ocs__ctx_free(&c);
  if (clear) return 0;
  if (du->stats) atomic_fetch_add_explicit(&du->stats->columns, 1, memory_order_relaxed);
  ocs_tau_desc_t all = *du;
  all.cover_all = 1;
  void *vol = NULL;
  size_t bytes = 0;
  OC_TRY(ocs_tau_volume_build(&all, key, oc_key_level(key), &vol, &bytes));
  int r = ocs_tau_volume_lookup(vol, key, tau);
  free(vol);
  return r;
}

int ocs_tau_node(const ocs_tau_desc_t *du, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  ocs__desc_t d;
  if (!tau || !oc_key_valid(key)) return OC_EINVAL;
  OC_TRY(ocs__desc(du, &d));
  void *vol = NULL;
  size_t bytes = 0;
  OC_TRY(ocs_tau_volume_build(du, ocs__group(&d, key), oc_key_level(key), &vol, &bytes));
  int r = ocs_tau_volume_lookup(vol, key, tau);
  free(vol);
  return r == OC_ENOENT ? ocs_tau_direct(du, key, tau) : r; /* σt bound [0, 0]: not in the volume */
}
