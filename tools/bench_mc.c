/* bench_mc.c — the Monte Carlo transport kernel of `overcast-bench truth` (see bench_mc.h).
 *
 * Positions, distances, throughput and sums are double. σt is the CPU reference renderer's own
 * reconstruction (float, shaders/brick.h; bit-identical to oc_render_sample_state(), which
 * oct_mc_check_reconstruction() proves on each state) and phase values come from shaders/optics.h
 * (float, the renderer's functions): both are inputs to the estimator, not part of its error. */
#include "bench_mc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "brick.h" /* ocg_code_decode, ocg_brick_voxel: a brick's majorant */
#include "oc.h"
#include "optics.h"    /* ocg_phase_hg, ocg_phase_hg_draine, OCG_HGD_* */

/* Locating a leaf looks this far ahead along the ray, as the renderer does (OC__LOCATE_EPS in
 * common/oc_render.c), so a point on a shared face is found in the leaf being entered. */
#define OCT_MC_LOCATE_EPS 1e-4
/* Majorants get this relative margin: a decoded code can exceed its range's hi by an ulp or two
 * of float, and trilinear interpolation by another. Larger majorants cost time, never accuracy. */
#define OCT_MC_MAJORANT_MARGIN 1e-5
/* Next-event transmittance stops accumulating past this optical depth: e^-100 ≈ 4e-44, far below
 * any radiance the comparison can resolve, and deep shadow rays would otherwise cross the cloud. */
#define OCT_MC_TAU_CUTOFF 100.0
/* Russian roulette below this throughput (reached with albedo < 1, or through sun-lobe weights). */
#define OCT_MC_RR_THRESHOLD 0.1
#define OCT_MC_INV_4PI 0.0795774715459476679 /* 1/(4π): the thin air's isotropic phase function */

static const oct_mc_phase_t oct__isotropic = {OCT_MC_PHASE_HG, 0.0};

/* ---- Random numbers: splitmix64 seeding xoshiro256** (Blackman & Vigna 2018) ---------------------- */

static uint64_t oct__splitmix64(uint64_t *x) {
  uint64_t z = (*x += 0x9e3779b97f4a7c15u);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
  return z ^ (z >> 31);
}

static uint64_t oct__rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void oct_mc_rng_seed(oct_mc_rng_t *r, uint64_t seed, uint64_t stream) {
  /* Hash the seed first so that (seed, stream) and (seed + 1, stream - γ) cannot start splitmix64
   * at overlapping points of its counter sequence. */
  uint64_t h = seed;
  uint64_t x = oct__splitmix64(&h) ^ stream;
  for (int i = 0; i < 4; i++) r->s[i] = oct__splitmix64(&x);
}

double oct_mc_uniform(oct_mc_rng_t *r) {
  uint64_t *s = r->s;
  uint64_t out = oct__rotl(s[1] * 5u, 7) * 9u;
  uint64_t t = s[1] << 17;
  s[2] ^= s[0];
  s[3] ^= s[1];
  s[1] ^= s[2];
  s[0] ^= s[3];
  s[2] ^= t;
  s[3] = oct__rotl(s[3], 45);
  return (double)(out >> 11) * 0x1.0p-53;
}

void oct_mc_mean_se(double s1, double s2, double n, double *mean, double *se) {
  *mean = s1 / n;
  double var = n > 1.0 ? (s2 - s1 * s1 / n) / (n - 1.0) : 0.0;
  *se = sqrt(fmax(var, 0.0) / n);
}

/* ---- Phase functions ------------------------------------------------------------------------------- */

double oct_mc_phase_eval(const oct_mc_phase_t *ph, double mu) {
  if (ph->kind == OCT_MC_PHASE_HG) return ocg_phase_hg((float)mu, (float)ph->g);
  return ocg_phase_hg_draine((float)mu);
}

/* HG by inversion of its CDF (in the form that maps ξ = 0 to mu = -1 and ξ = 1 to mu = 1 without
 * cancellation in the forward peak); isotropic for |g| < 1e-6. */
static double oct__sample_hg(double g, double xi) {
  if (fabs(g) < 1e-6) return 1.0 - 2.0 * xi;
  double s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
  double mu = (1.0 + g * g - s * s) / (2.0 * g);
  return fmin(1.0, fmax(-1.0, mu));
}

/* Draine: HG(g_D) × (1 + α mu²) up to normalisation, so sampling HG(g_D) and accepting with
 * probability (1 + α mu²)/(1 + α) draws it exactly (acceptance ≈ 0.56 for the cloud fit). */
static double oct__sample_draine(double g, double alpha, oct_mc_rng_t *r) {
  for (;;) {
    double mu = oct__sample_hg(g, oct_mc_uniform(r));
    if (oct_mc_uniform(r) * (1.0 + alpha) <= 1.0 + alpha * mu * mu) return mu;
  }
}

double oct_mc_phase_sample_mu(const oct_mc_phase_t *ph, oct_mc_rng_t *r) {
  if (ph->kind == OCT_MC_PHASE_HG) return oct__sample_hg(ph->g, oct_mc_uniform(r));
  /* The mixture (1 - w)·HG(g_HG) + w·Draine(g_D, α) of ocg_phase_hg_draine: pick a lobe with its
   * weight, then sample that lobe exactly (the float constants the renderer evaluates). */
  if (oct_mc_uniform(r) < (double)OCG_HGD_W) return oct__sample_draine((double)OCG_HGD_G_D, (double)OCG_HGD_ALPHA, r);
  return oct__sample_hg((double)OCG_HGD_G_HG, oct_mc_uniform(r));
}

/* An orthonormal basis around unit n without a branch on a special axis (Duff et al. 2017). */
static void oct__basis(oc_dvec3 n, oc_dvec3 *b1, oc_dvec3 *b2) {
  double sign = copysign(1.0, n.z);
  double a = -1.0 / (sign + n.z);
  double b = n.x * n.y * a;
  *b1 = oc_dv3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
  *b2 = oc_dv3(b, sign + n.y * n.y * a, -n.y);
}

oc_dvec3 oct_mc_phase_sample(const oct_mc_phase_t *ph, oc_dvec3 d, oct_mc_rng_t *r) {
  double mu = oct_mc_phase_sample_mu(ph, r);
  double phi = 6.283185307179586477 * oct_mc_uniform(r);
  double sin_t = sqrt(fmax(0.0, 1.0 - mu * mu));
  oc_dvec3 b1, b2;
  oct__basis(d, &b1, &b2);
  oc_dvec3 w = oc_dadd(oc_dscale(d, mu), oc_dadd(oc_dscale(b1, sin_t * cos(phi)), oc_dscale(b2, sin_t * sin(phi))));
  return oc_dnorm(w); /* renormalised so that thousands of bounces never drift off the unit sphere */
}

/* ---- The state: a leaf index and the reconstruction -------------------------------------------------------
 * oc_state_find_leaf() tries the level-21 key and each ancestor in turn, a binary search per level;
 * the kernel looks leaves up millions of times, so it builds its own index once. Leaves partition
 * the root cube, and a leaf of level L covers one contiguous range of level-21 Morton codes,
 * [m·8^(21−L), (m+1)·8^(21−L)); sorted by range start, the leaf holding a point is found by one
 * binary search, and it is the leaf oc_state_find_leaf() finds for that point's key. */

struct oct_mc_index {
  uint64_t *start; /* range start, ascending */
  uint64_t *end;   /* one past the range's last code */
  uint32_t *node;  /* index into state->nodes */
  uint32_t count;
};

typedef struct {
  const oc_node_t *n;  /* NULL: no leaf */
  const oc_brick_t *b; /* the payload of a brick leaf (NULL if missing: read as range.lo) */
  oc_dvec3 origin;
  double size;
} oct__leaf_t;

static int oct__cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

int oct_mc_medium_state(oct_mc_medium_t *m, const oc_state_t *s) {
  memset(m, 0, sizeof *m);
  m->kind = OCT_MC_MEDIUM_STATE;
  m->state = s;
  struct oct_mc_index *ix = calloc(1, sizeof *ix);
  uint64_t *pairs = calloc(2 * (size_t)s->node_count + 1, sizeof *pairs);
  if (ix) {
    ix->start = calloc((size_t)s->node_count + 1, sizeof *ix->start);
    ix->end = calloc((size_t)s->node_count + 1, sizeof *ix->end);
    ix->node = calloc((size_t)s->node_count + 1, sizeof *ix->node);
  }
  if (!ix || !pairs || !ix->start || !ix->end || !ix->node) {
    if (ix) {
      free(ix->start);
      free(ix->end);
      free(ix->node);
    }
    free(ix);
    free(pairs);
    return -1;
  }
  for (uint32_t i = 0; i < s->node_count; i++) { /* (start, node) pairs, sorted by start */
    int L = oc_key_level(s->nodes[i].key);
    uint64_t morton = s->nodes[i].key & ((UINT64_C(1) << (3 * L)) - 1u);
    pairs[2 * i] = morton << (3 * (OC_KEY_MAX_LEVEL - L));
    pairs[2 * i + 1] = i;
  }
  qsort(pairs, s->node_count, 2 * sizeof *pairs, oct__cmp_u64);
  for (uint32_t i = 0; i < s->node_count; i++) {
    uint32_t node = (uint32_t)pairs[2 * i + 1];
    int L = oc_key_level(s->nodes[node].key);
    ix->start[i] = pairs[2 * i];
    ix->end[i] = pairs[2 * i] + (UINT64_C(1) << (3 * (OC_KEY_MAX_LEVEL - L)));
    ix->node[i] = node;
  }
  ix->count = s->node_count;
  free(pairs);
  m->index = ix;
  return 0;
}

void oct_mc_medium_free(oct_mc_medium_t *m) {
  if (m->index) {
    free(m->index->start);
    free(m->index->end);
    free(m->index->node);
    free(m->index);
  }
  m->index = NULL;
}

/* The leaf holding q. @return 0, -1 outside the root cube, -2 inside it but in no leaf. */
static int oct__locate(const oct_mc_medium_t *m, oc_dvec3 q, oct__leaf_t *lf) {
  memset(lf, 0, sizeof *lf);
  oc_key_t k = oc_key_from_point(OC_KEY_MAX_LEVEL, q);
  if (k == OC_KEY_INVALID) return -1;
  const struct oct_mc_index *ix = m->index;
  uint64_t code = k & ((UINT64_C(1) << (3 * OC_KEY_MAX_LEVEL)) - 1u); /* drop the sentinel */
  uint32_t a = 0, b = ix->count;                                        /* last start ≤ code */
  while (a < b) {
    uint32_t mid = a + (b - a) / 2;
    if (ix->start[mid] <= code) a = mid + 1;
    else b = mid;
  }
  if (a == 0 || code >= ix->end[a - 1]) return -2;
  lf->n = &m->state->nodes[ix->node[a - 1]];
  lf->b = lf->n->kind == OC_NODE_BRICK ? oc_state_find_brick(m->state, lf->n->brick_id) : NULL;
  oc_key_bounds(lf->n->key, &lf->origin, &lf->size);
  return 0;
}

/* σt of a leaf at p: oc_render_sample_leaf(), the renderer's reconstruction (shaders/brick.h);
 * oct_mc_check_reconstruction() compares the leaves oct__locate() finds with oc_render_sample_state()'s,
 * bit for bit, before every truth run. */
static float oct__leaf_sigma(const oct__leaf_t *lf, oc_dvec3 p) {
  return oc_render_sample_leaf(lf->n, lf->b, lf->origin, lf->size, OC_CH_SIGMA, p);
}

long oct_mc_check_reconstruction(const oct_mc_medium_t *m, uint64_t seed, long n, long *tested) {
  const oc_state_t *s = m->state;
  long bad = 0;
  *tested = 0;
  if (!s->node_count) return 0;
  oct_mc_rng_t r;
  oct_mc_rng_seed(&r, seed, UINT64_C(0xC0FFEE));
  for (long i = 0; i < n; i++) {
    /* A random non-empty leaf, a random point in it; every 4th point on a face, where ties go
     * to the upper neighbour. */
    const oc_node_t *nd = &s->nodes[(uint32_t)(oct_mc_uniform(&r) * s->node_count)];
    if (nd->kind == OC_NODE_EMPTY) continue;
    oc_dvec3 origin;
    double size;
    oc_key_bounds(nd->key, &origin, &size);
    double u[3] = {oct_mc_uniform(&r), oct_mc_uniform(&r), oct_mc_uniform(&r)};
    if ((i & 3) == 0) u[i % 3] = floor(u[i % 3] * 7.0 + 0.5) / 7.0;
    oc_dvec3 p = oc_dv3(origin.x + u[0] * size, origin.y + u[1] * size, origin.z + u[2] * size);
    oct__leaf_t lf;
    float mine = oct__locate(m, p, &lf) == 0 ? oct__leaf_sigma(&lf, p) : 0.0f, ref, tau;
    oc_render_sample_state(s, p, &ref, &tau);
    if (memcmp(&mine, &ref, sizeof mine) != 0) bad++;
    (*tested)++;
  }
  return bad;
}

/* ---- Spans: intervals along a ray with one majorant ----------------------------------------------------- */

typedef struct {
  double t_end;      /**< the span is [t, t_end) */
  double maj;        /**< majorant of σt on it (0: nothing to collide with) */
  int escape;        /**< the ray has left the medium at t */
  int constant;      /**< σt is the constant `value` on the span (uniform leaf, a brick leaf whose
                          payload is missing, or the slab) */
  double value;
  oct__leaf_t leaf;  /**< state: the leaf the span lies in (σt is evaluated in it) */
} oct__span_t;

/* Ray–AABB interval; false when missed. */
static int oct__ray_box(oc_dvec3 o, oc_dvec3 d, double lo, double hi, double *t0, double *t1) {
  double a = -INFINITY, b = INFINITY;
  const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
  for (int i = 0; i < 3; i++) {
    if (dd[i] == 0.0) {
      if (oo[i] < lo || oo[i] > hi) return 0;
      continue;
    }
    double ta = (lo - oo[i]) / dd[i], tb = (hi - oo[i]) / dd[i];
    a = fmax(a, fmin(ta, tb));
    b = fmin(b, fmax(ta, tb));
  }
  if (a > b) return 0;
  *t0 = a;
  *t1 = b;
  return 1;
}

/* Distance from p along d to the exit of the box [origin, origin + size]. */
static double oct__box_exit(oc_dvec3 origin, double size, oc_dvec3 p, oc_dvec3 d) {
  const double pp[3] = {p.x, p.y, p.z}, dd[3] = {d.x, d.y, d.z}, o[3] = {origin.x, origin.y, origin.z};
  double t = INFINITY;
  for (int i = 0; i < 3; i++) {
    if (dd[i] > 0.0) t = fmin(t, (o[i] + size - pp[i]) / dd[i]);
    else if (dd[i] < 0.0) t = fmin(t, (o[i] - pp[i]) / dd[i]);
  }
  return t;
}

/* The sample cell of a brick leaf holding q and the part of the ray inside it. Its majorant is the
 * largest of its eight decoded corners: the reconstruction is their trilinear interpolation, a
 * convex combination, so it never exceeds them. A whole-leaf majorant (range.hi) would do, but
 * coarse leaves that a thin cloud crosses (the box-filtered far side of a slab) are mostly far
 * below their hi, and delta tracking would spend hundreds of null collisions in each. */
static void oct__cell_span(const oct__leaf_t *lf, oc_dvec3 p, oc_dvec3 q, oc_dvec3 d, double t, oct__span_t *sp) {
  float lo = lf->n->range[OC_CH_SIGMA].lo, hi = lf->n->range[OC_CH_SIGMA].hi;
  double cs = lf->size / 7.0;
  const double qq[3] = {q.x, q.y, q.z}, oo[3] = {lf->origin.x, lf->origin.y, lf->origin.z};
  unsigned base[3];
  for (int i = 0; i < 3; i++) base[i] = (unsigned)fmin(6.0, fmax(0.0, floor((qq[i] - oo[i]) / cs)));
  oc_dvec3 corner = oc_dv3(oo[0] + base[0] * cs, oo[1] + base[1] * cs, oo[2] + base[2] * cs);
  sp->t_end = t + fmax(oct__box_exit(corner, cs, p, d), OCT_MC_LOCATE_EPS);
  if (!(hi > 0.0f)) return; /* an all-zero channel */
  const uint16_t *code = lf->b->codes.code[OC_CH_SIGMA];
  float m = 0.0f;
  for (unsigned k = 0; k < 8; k++) {
    unsigned v = ocg_brick_voxel(base[0] + (k & 1u), base[1] + ((k >> 1) & 1u), base[2] + (k >> 2));
    m = fmaxf(m, ocg_code_decode(code[v], lo, hi));
  }
  sp->maj = (double)m * (1.0 + OCT_MC_MAJORANT_MARGIN);
}

/* The span of the state at o + t·d: the leaf there, or with `cells` the sample cell of a brick leaf
 * (delta tracking wants tight majorants; the exact optical depth integrates a whole leaf at once).
 * The leaf is located a little ahead (OCT_MC_LOCATE_EPS) as the renderer does. Outside the root
 * cube there is nothing: empty space up to the cube when the ray still enters it, an escape
 * otherwise. */
static void oct__state_span(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d, double t, int cells, oct__span_t *sp) {
  const double S = OC_ROOT_HALF;
  oc_dvec3 p = oc_dmad(o, d, t), q = oc_dmad(o, d, t + OCT_MC_LOCATE_EPS);
  double a0, a1;
  memset(sp, 0, sizeof *sp);
  int where = oct__locate(m, q, &sp->leaf);
  if (where == -1) {
    if (oct__ray_box(p, d, -S, S, &a0, &a1) && a0 > 0.0) sp->t_end = t + a0;
    else sp->escape = 1;
    return;
  }
  if (where == -2) { /* no leaf holds the point: empty to the root cube's exit, as the renderer treats it */
    sp->t_end = t + (oct__ray_box(p, d, -S, S, &a0, &a1) ? fmax(a1, OCT_MC_LOCATE_EPS) : OCT_MC_LOCATE_EPS);
    return;
  }
  const oc_node_t *n = sp->leaf.n;
  oc_range_t r = n->range[OC_CH_SIGMA];
  if (n->kind == OC_NODE_BRICK && sp->leaf.b && cells) {
    oct__cell_span(&sp->leaf, p, q, d, t, sp);
    return;
  }
  sp->t_end = t + fmax(oct__box_exit(sp->leaf.origin, sp->leaf.size, p, d), OCT_MC_LOCATE_EPS);
  if (n->kind == OC_NODE_UNIFORM || (n->kind == OC_NODE_BRICK && !sp->leaf.b)) {
    sp->constant = 1; /* the renderer reads range.lo (a missing payload too) */
    sp->value = sp->maj = fmax((double)r.lo, 0.0);
  } else if (n->kind == OC_NODE_BRICK && r.hi > 0.0f) {
    sp->maj = fmax((double)r.lo, (double)r.hi) * (1.0 + OCT_MC_MAJORANT_MARGIN);
  }
}

/* The slab 0 ≤ z ≤ tau along the ray: one span with majorant 1 inside it, empty before it. */
static void oct__slab_span(double tau, oc_dvec3 o, oc_dvec3 d, double t, oct__span_t *sp) {
  memset(sp, 0, sizeof *sp);
  sp->constant = 1;
  sp->value = 1.0;
  if (d.z == 0.0) {
    sp->escape = !(o.z >= 0.0 && o.z <= tau);
    sp->t_end = INFINITY;
    sp->maj = 1.0;
    return;
  }
  double ta = (0.0 - o.z) / d.z, tb = (tau - o.z) / d.z;
  double lo = fmin(ta, tb), hi = fmax(ta, tb);
  if (t < lo) sp->t_end = lo;
  else if (t < hi) {
    sp->t_end = hi;
    sp->maj = 1.0;
  } else sp->escape = 1;
}

/* ---- Exact optical depth ------------------------------------------------------------------------------ */

/* ∫σt over [ta, tb] inside one brick leaf. The reconstruction is trilinear in each of the leaf's
 * 7³ sample cells, so along a line it is a polynomial of degree 3 between cell-boundary crossings;
 * two-point Gauss–Legendre is exact for degree 3, and its nodes are interior to each piece, so
 * every sample falls in the piece's own cell. */
static double oct__brick_integral(const oct__leaf_t *lf, oc_dvec3 o, oc_dvec3 d, double ta, double tb) {
  double cuts[2 + 3 * 6];
  int n = 0;
  cuts[n++] = ta;
  const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
  const double org[3] = {lf->origin.x, lf->origin.y, lf->origin.z};
  for (int ax = 0; ax < 3; ax++) {
    if (dd[ax] == 0.0) continue;
    for (int c = 1; c < 7; c++) { /* interior cell faces at origin + c·size/7 */
      double tc = (org[ax] + c * (lf->size / 7.0) - oo[ax]) / dd[ax];
      if (tc > ta && tc < tb) cuts[n++] = tc;
    }
  }
  cuts[n++] = tb;
  for (int i = 2; i < n - 1; i++) /* insertion sort of the crossings (at most 18) */
    for (int j = i; j > 1 && cuts[j] < cuts[j - 1]; j--) {
      double x = cuts[j];
      cuts[j] = cuts[j - 1];
      cuts[j - 1] = x;
    }
  const double node = 0.5773502691896257645; /* 1/√3 */
  double sum = 0.0;
  for (int i = 0; i + 1 < n; i++) {
    double h = 0.5 * (cuts[i + 1] - cuts[i]), mid = 0.5 * (cuts[i + 1] + cuts[i]);
    if (!(h > 0.0)) continue;
    float s0 = oct__leaf_sigma(lf, oc_dmad(o, d, mid - h * node));
    float s1 = oct__leaf_sigma(lf, oc_dmad(o, d, mid + h * node));
    sum += h * ((double)s0 + (double)s1);
  }
  return sum;
}

static double oct__slab_optical_depth(double tau, oc_dvec3 o, oc_dvec3 d) {
  if (o.z < 0.0 || o.z > tau) return 0.0; /* only called from inside (next-event estimation) */
  if (d.z > 0.0) return (tau - o.z) / d.z;
  if (d.z < 0.0) return o.z / -d.z;
  return INFINITY;
}

/* The thin air along o + t·d: [*a0, *a1] and the ground at *tg (oc_render_air_shell); 0 without air. */
static int oct__air(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d, double *a0, double *a1, double *tg) {
  *tg = INFINITY;
  return m->kind == OCT_MC_MEDIUM_STATE && m->air_sigma > 0.0 && oc_render_air_shell(o, d, m->air_top, a0, a1, tg);
}

double oct_mc_optical_depth(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d) {
  if (m->kind == OCT_MC_MEDIUM_SLAB) return oct__slab_optical_depth(m->slab_tau, o, d);
  double a0, a1, tg;
  double tau = oct__air(m, o, d, &a0, &a1, &tg) ? m->air_sigma * (a1 - a0) : 0.0, t = 0.0;
  oct__span_t sp;
  for (;;) {
    oct__state_span(m, o, d, t, 0, &sp);
    if (sp.escape || tau > OCT_MC_TAU_CUTOFF) return tau;
    if (sp.maj > 0.0) tau += sp.constant ? sp.value * (sp.t_end - t) : oct__brick_integral(&sp.leaf, o, d, t, sp.t_end);
    t = sp.t_end;
  }
}

/* ---- Delta tracking ------------------------------------------------------------------------------------ */

/* Delta tracking through the cloud up to t_max: 1 with *t at a real collision before it, else 0. */
static int oct__cloud_flight(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d, double t_max, oct_mc_rng_t *r, double *t,
                             oct_mc_stats_t *st) {
  double tt = 0.0;
  oct__span_t sp;
  for (;;) {
    if (m->kind == OCT_MC_MEDIUM_SLAB) oct__slab_span(m->slab_tau, o, d, tt, &sp);
    else oct__state_span(m, o, d, tt, 1, &sp);
    if (sp.escape || tt >= t_max) return 0;
    sp.t_end = fmin(sp.t_end, t_max);
    if (!(sp.maj > 0.0)) { /* nothing to hit: skip the whole span */
      tt = sp.t_end;
      continue;
    }
    /* Tentative collisions at rate maj; each is real with probability σt/maj. Free paths are
     * memoryless, so a flight that overshoots the span simply restarts at its end. */
    for (;;) {
      tt += -log1p(-oct_mc_uniform(r)) / sp.maj;
      if (tt >= sp.t_end) {
        tt = sp.t_end;
        break;
      }
      double sig = sp.constant ? sp.value : (double)oct__leaf_sigma(&sp.leaf, oc_dmad(o, d, tt));
      if (sig > sp.maj) st->majorant_violations++;
      if (oct_mc_uniform(r) * sp.maj < sig) {
        *t = tt;
        return 1;
      }
      st->null_collisions++;
    }
  }
}

int oct_mc_flight(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d, oct_mc_rng_t *r, double *t, oct_mc_stats_t *st) {
  double a0, a1, tg, t_air = INFINITY;
  if (oct__air(m, o, d, &a0, &a1, &tg)) { /* homogeneous: the free path in closed form */
    double s = a0 - log1p(-oct_mc_uniform(r)) / m->air_sigma;
    if (s < a1) t_air = s;
  }
  if (oct__cloud_flight(m, o, d, fmin(t_air, tg), r, t, st)) return 1;
  if (t_air < tg) {
    *t = t_air;
    return 2;
  }
  return 0;
}

/* ---- Paths -------------------------------------------------------------------------------------------------- */

/* The next direction of a path at direction d. Plain phase sampling has pdf = phase, weight 1.
 * With sun_lobe ε > 0 the direction comes from the mixture q = (1 − ε)·p(d·ω) + ε·p(ω·sun): the
 * second lobe is the in-cloud aureole (sunlight scattered by small angles), which next-event
 * estimation alone finds only when a path happens to point into the 2°-wide forward peak around
 * the sun, and then with a weight of up to 586 sr⁻¹: rare, huge samples (fireflies) whose
 * variance dominates. The throughput takes p(d·ω)/q: unbiased; sun-lobe directions now come
 * often with the small weight they deserve. The price is that phase-sampled directions weigh up to
 * 1/(1 − ε), so a long path that never draws the sun lobe grows its weight geometrically; a small
 * ε keeps that growth slow (ε = 0.02: ×1.8 after 30 bounces). Measured (docs/numerics.md, "Monte
 * Carlo ground truth"): ε = 0.02 is 2–6× more efficient than ε = 0 on the sphere and slab scenes;
 * ε = 0.1 does better on the sphere but lets the weights of the slab's 30-bounce paths explode. */
static oc_dvec3 oct__next_direction(const oct_mc_params_t *p, oc_dvec3 d, oct_mc_rng_t *r, double *beta) {
  if (!(p->sun_lobe > 0.0)) return oct_mc_phase_sample(&p->phase, d, r);
  oc_dvec3 w = oct_mc_uniform(r) < p->sun_lobe ? oct_mc_phase_sample(&p->phase, p->sun, r) : oct_mc_phase_sample(&p->phase, d, r);
  double pa = oct_mc_phase_eval(&p->phase, oc_ddot(d, w)), pb = oct_mc_phase_eval(&p->phase, oc_ddot(w, p->sun));
  *beta *= pa / ((1.0 - p->sun_lobe) * pa + p->sun_lobe * pb);
  return w;
}

void oct_mc_trace(const oct_mc_medium_t *m, const oct_mc_params_t *p, oc_dvec3 o, oc_dvec3 d, oct_mc_rng_t *r,
                  oct_mc_path_t *out, oct_mc_stats_t *st) {
  memset(out, 0, sizeof *out);
  double beta = 1.0;
  st->paths++;
  for (long b = 0;; b++) {
    double t;
    int hit = oct_mc_flight(m, o, d, r, &t, st);
    if (b == 0) out->first_escaped = !hit;
    if (!hit) { /* left the medium: the caller weighs the background it sees along d */
      out->escape_weight = beta;
      out->escape_dir = d;
      return;
    }
    if (b >= p->max_bounces) {
      st->truncated++;
      return;
    }
    st->real_collisions++;
    out->bounces = b + 1;
    o = oc_dmad(o, d, t);
    int air = hit == 2; /* the thin air: albedo 1, isotropic (oct_mc_medium_t) */
    if (!air) beta *= p->albedo;
    if (!(beta > 0.0)) return;
    if (p->sun_irradiance > 0.0) {
      /* Next-event estimation of the delta sun: light travelling along -sun scattered into -d, so
       * mu = cos(angle between the propagation directions) = dot(d, sun), as the renderer's mu. */
      double tau = oct_mc_optical_depth(m, o, p->sun);
      st->nee_rays++;
      double ph = air ? OCT_MC_INV_4PI : oct_mc_phase_eval(&p->phase, oc_ddot(d, p->sun));
      double l = beta * p->sun_irradiance * ph * exp(-tau);
      out->sun += l;
      if (air) out->sun_air += l;
      if (b == 0) out->sun_single = l;
    }
    d = air ? oct_mc_phase_sample(&oct__isotropic, d, r) : oct__next_direction(p, d, r, &beta);
    if (beta < OCT_MC_RR_THRESHOLD) {
      if (oct_mc_uniform(r) * OCT_MC_RR_THRESHOLD >= beta) return;
      beta = OCT_MC_RR_THRESHOLD;
    }
  }
}
