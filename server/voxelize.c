#include "voxelize.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "oc_brick.h"
#include "oc_err.h"
#include "oc_planet.h"

/* ---- Sample positions ------------------------------------------------------------------------ */

/* Spacing of the sample lattice of a level: (2S/7)·2^−level. ldexp is exact, so the lattices of
 * all levels are nested: sample g of level L sits exactly where sample 2g of level L+1 does. */
static inline double oc__spacing(int level) { return ldexp(2.0 * OC_ROOT_HALF / 7.0, -level); }

oc_dvec3 ocs_brick_sample_pos(oc_key_t key, int i, int j, int k) {
  int level = oc_key_level(key);
  uint32_t ix, iy, iz;
  oc_key_coords(key, &ix, &iy, &iz);
  double u = oc__spacing(level);
  return oc_dv3(-OC_ROOT_HALF + (double)(7 * (int64_t)ix + i) * u, -OC_ROOT_HALF + (double)(7 * (int64_t)iy + j) * u,
                -OC_ROOT_HALF + (double)(7 * (int64_t)iz + k) * u);
}

/* Sub-sample coordinates: every one is −S + (g + f)·u with g the integer lattice index of the
 * sample and f the sub-sample offset; both are the same whichever node computes them. */
static int oc__sub_positions(oc_key_t key, int sub, double pos[3][8][OCS_VOXELIZE_MAX_SUB]) {
  if (sub < 1) sub = 1;
  if (sub > OCS_VOXELIZE_MAX_SUB) sub = OCS_VOXELIZE_MAX_SUB;
  uint32_t ic[3];
  oc_key_coords(key, &ic[0], &ic[1], &ic[2]);
  double u = oc__spacing(oc_key_level(key));
  for (int a = 0; a < 3; a++)
    for (int i = 0; i < 8; i++) {
      double g = (double)(7 * (int64_t)ic[a] + i);
      for (int m = 0; m < sub; m++) pos[a][i][m] = -OC_ROOT_HALF + (g + (((double)m + 0.5) / (double)sub - 0.5)) * u;
    }
  return sub;
}

/* The mean of fn over sample (i, j, k)'s sub³ sub-samples, in a fixed order. */
static double oc__box_mean(double (*fn)(void *ctx, oc_dvec3 p), void *ctx, int sub,
                           const double pos[3][8][OCS_VOXELIZE_MAX_SUB], int i, int j, int k) {
  double sum = 0.0;
  for (int mz = 0; mz < sub; mz++)
    for (int my = 0; my < sub; my++)
      for (int mx = 0; mx < sub; mx++) sum += fn(ctx, oc_dv3(pos[0][i][mx], pos[1][j][my], pos[2][k][mz]));
  return sub == 1 ? sum : sum * (1.0 / ((double)sub * sub * sub));
}

/* ocs_brick_sample() : the positions are the same from either node and the order of the sub-samples
 * is fixed, so shared face samples agree bit for bit. */
void ocs_brick_sample(oc_key_t key, double (*fn)(void *ctx, oc_dvec3 p), void *ctx, int sub, float out[512]) {
  double pos[3][8][OCS_VOXELIZE_MAX_SUB];
  sub = oc__sub_positions(key, sub, pos);
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) out[i + 8 * j + 64 * k] = (float)oc__box_mean(fn, ctx, sub, pos, i, j, k);
}

/* The box filter of a smooth field (τ): where the mean of the 8 corner sub-samples matches the value
 * at the sample within 1e-3 (relative; absolute below 1e-2) the field is taken as trilinear over the
 * box, whose lattice mean is exactly that corner mean; elsewhere (a face inside the box) every
 * sub-sample is averaged. 9 evaluations instead of sub³ almost everywhere; the test reads only
 * positions either node computes alike, so shared face samples still agree bit for bit. */
static void oc__brick_sample_smooth(oc_key_t key, double (*fn)(void *ctx, oc_dvec3 p), void *ctx, int sub,
                                    float out[512]) {
  if (sub <= 1) {
    ocs_brick_sample(key, fn, ctx, sub, out);
    return;
  }
  double pos[3][8][OCS_VOXELIZE_MAX_SUB];
  sub = oc__sub_positions(key, sub, pos);
  int e = sub - 1;
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) {
        double q = 0.0;
        for (int c = 0; c < 8; c++)
          q += fn(ctx, oc_dv3(pos[0][i][c & 1 ? e : 0], pos[1][j][c & 2 ? e : 0], pos[2][k][c & 4 ? e : 0]));
        q *= 0.125;
        double centre = fn(ctx, ocs_brick_sample_pos(key, i, j, k));
        int smooth = fabs(centre - q) <= 1e-3 * fmax(fabs(q), 1e-2);
        out[i + 8 * j + 64 * k] = (float)(smooth ? q : oc__box_mean(fn, ctx, sub, pos, i, j, k));
      }
}

/* ---- Refinement ------------------------------------------------------------------------------ */

/* The description with its defaults filled in (oc__resolve). */
typedef ocs_voxelize_desc_t oc__vox_t;

static int oc__wants_split(const oc__vox_t *v, oc_key_t key, int level) {
  if (level < v->min_level) return 1;
  if (level >= v->max_level) return 0;
  if (v->aabb_count == 0 && !v->refine) return 0;
  if (v->aabb_count > 0) {
    oc_dvec3 o;
    double size;
    oc_key_bounds(key, &o, &size);
    double g = v->margin + size / 14.0;
    oc_dvec3 lo = oc_dv3(o.x - g, o.y - g, o.z - g), hi = oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g);
    int any = 0;
    for (int i = 0; i < v->aabb_count && !any; i++) {
      const ocs_aabb_t *b = &v->aabbs[i];
      any = lo.x <= b->hi.x && hi.x >= b->lo.x && lo.y <= b->hi.y && hi.y >= b->lo.y && lo.z <= b->hi.z &&
            hi.z >= b->lo.z;
    }
    if (!any) return 0;
  }
  if (v->refine) return v->refine(v->refine_ctx, key) != 0;
  return 1;
}

typedef struct {
  oc_key_t *k;
  uint32_t n;
} oc__keys_t;

/* Depth-first walk shared by both passes: counting (keys == NULL) stops with OC_ETOOBIG as soon as
 * the leaves pass max_nodes, with no allocation; placing writes each leaf at the next slot of its
 * level. At one level, depth-first visits nodes in ascending Morton order, and every key of level L
 * is below every key of level L+1, so "levels in ascending order, each in visiting order" is the
 * canonical ascending key order without sorting. Recursion depth ≤ 22. */
typedef struct {
  const oc__vox_t *v;
  uint64_t count[OC_KEY_MAX_LEVEL + 1];
  uint64_t total;
  oc_key_t *keys;                       /* NULL while counting */
  uint64_t slot[OC_KEY_MAX_LEVEL + 1];  /* placing: next index per level */
  uint64_t end[OC_KEY_MAX_LEVEL + 1];   /* placing: end of each level's run */
} oc__walk_t;

static int oc__walk(oc__walk_t *w, oc_key_t key, int level) {
  if (level < OC_KEY_MAX_LEVEL && oc__wants_split(w->v, key, level)) {
    for (int c = 0; c < 8; c++) OC_TRY(oc__walk(w, (key << 3) | (oc_key_t)c, level + 1));
    return 0;
  }
  if (!w->keys) {
    if (++w->total > w->v->max_nodes) return OC_ETOOBIG;
    w->count[level]++;
    return 0;
  }
  /* A refinement callback that changed its answer between the passes. */
  if (w->slot[level] >= w->end[level]) return OC_EINVAL;
  w->keys[w->slot[level]++] = key;
  return 0;
}

/* oc__build_leaves() : the leaves in ascending key order, or OC_ETOOBIG before allocating anything
 * when there would be more than max_nodes of them. The refinement predicate is asked twice per
 * node (it must be deterministic); it is cheap next to sampling a brick. */
static int oc__build_leaves(const oc__vox_t *v, oc__keys_t *leaves) {
  oc__walk_t *w = calloc(1, sizeof *w);
  if (!w) return OC_ENOMEM;
  w->v = v;
  int rc = oc__walk(w, OC_KEY_ROOT, 0);
  if (rc == 0) {
    leaves->k = malloc((size_t)w->total * sizeof *leaves->k);
    if (!leaves->k) rc = OC_ENOMEM;
  }
  if (rc == 0) {
    uint64_t at = 0;
    for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
      w->slot[l] = at;
      at += w->count[l];
      w->end[l] = at;
    }
    w->keys = leaves->k;
    rc = oc__walk(w, OC_KEY_ROOT, 0);
    for (int l = 0; rc == 0 && l <= OC_KEY_MAX_LEVEL; l++)
      if (w->slot[l] != w->end[l]) rc = OC_EINVAL;
  }
  if (rc == 0)
    leaves->n = (uint32_t)w->total;
  else {
    free(leaves->k);
    leaves->k = NULL;
  }
  free(w);
  return rc;
}

/* ---- Sampling workers ------------------------------------------------------------------------ */

/*! Leaves per work item: small enough to balance, large enough to keep the atomics cold. */
#ifndef OCS_VOXELIZE_CHUNK
#define OCS_VOXELIZE_CHUNK 16
#endif

typedef struct {
  oc_brick_codes_t *codes; /* the chunk's bricks, in leaf order */
  uint32_t count, cap;
  oc_sanitize_stats_t san;
} oc__chunk_t;

typedef struct {
  const oc__vox_t *v;
  const oc_key_t *leaves;
  uint32_t n;
  oc_node_t *nodes;
  oc__chunk_t *chunks;
  uint32_t nchunks;
  atomic_uint next_chunk;
  atomic_uint bricks;
  atomic_int err;
} oc__job_t;

static void oc__san_add(oc_sanitize_stats_t *a, const oc_sanitize_stats_t *b) {
  a->nan += b->nan;
  a->inf += b->inf;
  a->negative += b->negative;
}

static void *oc__worker(void *arg) {
  oc__job_t *job = arg;
  const oc__vox_t *v = job->v;
  float sigma[OC_BRICK_VOXELS], tau[OC_BRICK_VOXELS];
  oc_brick_codes_t codes;
  for (;;) {
    if (atomic_load(&job->err)) break;
    uint32_t c = atomic_fetch_add(&job->next_chunk, 1u);
    if (c >= job->nchunks) break;
    oc__chunk_t *ch = &job->chunks[c];
    uint32_t end = (c + 1) * OCS_VOXELIZE_CHUNK < job->n ? (c + 1) * OCS_VOXELIZE_CHUNK : job->n;
    for (uint32_t li = c * OCS_VOXELIZE_CHUNK; li < end; li++) {
      oc_key_t key = job->leaves[li];
      ocs_brick_sample(key, v->sigma, v->ctx, v->sub_sigma, sigma);
      if (v->tau)
        oc__brick_sample_smooth(key, v->tau, v->ctx, v->sub_tau, tau);
      else
        memset(tau, 0, sizeof tau);
      oc_sanitize_stats_t s1 = {0}, s2 = {0};
      oc_sanitize(sigma, OC_BRICK_VOXELS, &s1);
      oc_sanitize(tau, OC_BRICK_VOXELS, &s2);
      oc__san_add(&ch->san, &s1);
      oc__san_add(&ch->san, &s2);
      oc_node_t *nd = &job->nodes[li];
      memset(nd, 0, sizeof *nd);
      nd->key = key;
      nd->kind = (uint8_t)oc_brick_encode(sigma, tau, &codes, nd->range);
      if (nd->kind == OC_NODE_BRICK) {
        if (atomic_fetch_add(&job->bricks, 1u) + 1u > OC_STATE_MAX_BRICKS) {
          atomic_store(&job->err, OC_ETOOBIG);
          return NULL;
        }
        if (ch->count == ch->cap) {
          uint32_t cap = ch->cap ? ch->cap * 2 : 4;
          oc_brick_codes_t *nc = realloc(ch->codes, (size_t)cap * sizeof *nc);
          if (!nc) {
            atomic_store(&job->err, OC_ENOMEM);
            return NULL;
          }
          ch->codes = nc;
          ch->cap = cap;
        }
        ch->codes[ch->count++] = codes;
      }
    }
  }
  return NULL;
}

static int oc__sample_all(oc__job_t *job, int threads) {
  pthread_t tid[OCS_VOXELIZE_MAX_THREADS];
  int started = 0;
  for (int t = 1; t < threads; t++) {
    if (pthread_create(&tid[started], NULL, oc__worker, job) != 0) break; /* fewer threads, same bytes */
    started++;
  }
  oc__worker(job);
  for (int t = 0; t < started; t++) pthread_join(tid[t], NULL);
  return atomic_load(&job->err);
}

/* ---- The builder ----------------------------------------------------------------------------- */

static double oc__now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int oc__resolve(const ocs_voxelize_desc_t *d, oc__vox_t *v, oc_dvec3 *sun) {
  OC_RETURN_IF(!d->sigma, OC_EINVAL);
  OC_RETURN_IF(d->min_level < 0 || d->min_level > OC_KEY_MAX_LEVEL, OC_EINVAL);
  int max_level = d->max_level == 0 ? d->min_level : d->max_level;
  OC_RETURN_IF(max_level < d->min_level || max_level > OC_KEY_MAX_LEVEL, OC_EINVAL);
  OC_RETURN_IF(d->aabb_count < 0 || (d->aabb_count > 0 && !d->aabbs), OC_EINVAL);
  for (int i = 0; i < d->aabb_count; i++) {
    const ocs_aabb_t *b = &d->aabbs[i];
    OC_RETURN_IF(!isfinite(b->lo.x) || !isfinite(b->lo.y) || !isfinite(b->lo.z) || !isfinite(b->hi.x) ||
                     !isfinite(b->hi.y) || !isfinite(b->hi.z),
                 OC_EINVAL);
    OC_RETURN_IF(b->lo.x > b->hi.x || b->lo.y > b->hi.y || b->lo.z > b->hi.z, OC_EINVAL);
  }
  OC_RETURN_IF(!isfinite(d->margin) || d->margin < 0.0, OC_EINVAL);
  OC_RETURN_IF(d->sub_sigma < 0 || d->sub_sigma > OCS_VOXELIZE_MAX_SUB, OC_EINVAL);
  OC_RETURN_IF(d->sub_tau < 0 || d->sub_tau > OCS_VOXELIZE_MAX_SUB, OC_EINVAL);
  OC_RETURN_IF(d->threads < 0 || d->threads > OCS_VOXELIZE_MAX_THREADS, OC_EINVAL);
  OC_RETURN_IF(!isfinite(d->time), OC_EINVAL);
  double sl = oc_dlen(d->sun_dir);
  OC_RETURN_IF(!isfinite(sl) || !(sl > 0.0), OC_EINVAL);
  *sun = fabs(sl - 1.0) <= 1e-12 ? d->sun_dir : oc_dscale(d->sun_dir, 1.0 / sl);

  *v = *d;
  v->max_level = max_level;
  if (!v->refine_ctx) v->refine_ctx = d->ctx;
  if (!v->sub_sigma) v->sub_sigma = 4;
  if (!v->sub_tau) v->sub_tau = 1;
  if (!v->threads) v->threads = 1;
  if (v->max_nodes == 0 || v->max_nodes > OC_STATE_MAX_NODES) v->max_nodes = OC_STATE_MAX_NODES;
  return 0;
}

int ocs_voxelize(oc_state_t *out, const ocs_voxelize_desc_t *d) {
  OC_RETURN_IF(!out || !d, OC_EINVAL);
  double t0 = oc__now();
  oc__vox_t v;
  oc_dvec3 sun;
  int rc = oc__resolve(d, &v, &sun);
  if (rc < 0) {
    oc_state_free(out);
    oc_state_init(out);
    return rc;
  }

  oc__keys_t leaves = {0};
  oc__job_t job;
  memset(&job, 0, sizeof job);
  oc_state_t s;
  oc_state_init(&s);
  rc = oc__build_leaves(&v, &leaves);
  if (rc < 0) goto done;

  job.v = &v;
  job.leaves = leaves.k;
  job.n = leaves.n;
  job.nchunks = (leaves.n + OCS_VOXELIZE_CHUNK - 1) / OCS_VOXELIZE_CHUNK;
  job.nodes = malloc((size_t)leaves.n * sizeof *job.nodes);
  job.chunks = calloc(job.nchunks, sizeof *job.chunks);
  atomic_init(&job.next_chunk, 0u);
  atomic_init(&job.bricks, 0u);
  atomic_init(&job.err, 0);
  if (!job.nodes || !job.chunks) {
    rc = OC_ENOMEM;
    goto done;
  }
  rc = oc__sample_all(&job, v.threads);
  if (rc < 0) goto done;

  /* Assemble in leaf (= key) order; brick ids ascend with it. */
  uint32_t nbricks = atomic_load(&job.bricks);
  uint32_t first = d->first_brick_id ? d->first_brick_id : 1u;
  if (nbricks > 0 && (uint64_t)first + nbricks - 1 > UINT32_MAX) {
    rc = OC_ERANGE;
    goto done;
  }
  /* Exact reservations (oc_state_free releases with free()), so the appends below never grow. */
  s.nodes = malloc((size_t)job.n * sizeof *s.nodes);
  s.bricks = nbricks ? malloc((size_t)nbricks * sizeof *s.bricks) : NULL;
  if ((job.n && !s.nodes) || (nbricks && !s.bricks)) {
    rc = OC_ENOMEM;
    goto done;
  }
  s.node_cap = job.n;
  s.brick_cap = nbricks;
  s.epoch = d->epoch;
  s.time = d->time;
  s.sun_dir = sun;
  uint32_t id = first;
  oc_sanitize_stats_t san = {0};
  for (uint32_t c = 0; c < job.nchunks && rc == 0; c++) {
    oc__chunk_t *ch = &job.chunks[c];
    uint32_t end = (c + 1) * OCS_VOXELIZE_CHUNK < job.n ? (c + 1) * OCS_VOXELIZE_CHUNK : job.n;
    uint32_t bi = 0;
    for (uint32_t li = c * OCS_VOXELIZE_CHUNK; li < end && rc == 0; li++) {
      oc_node_t *nd = &job.nodes[li];
      if (nd->kind == OC_NODE_BRICK) {
        nd->brick_id = id;
        rc = oc_state_add_brick(&s, id, &ch->codes[bi++]);
        id++;
      }
      if (rc == 0) rc = oc_state_add_node(&s, nd);
    }
    oc__san_add(&san, &ch->san);
    free(ch->codes); /* release as we go: the payload is held twice only one chunk at a time */
    ch->codes = NULL;
  }
  if (rc < 0) goto done;
  oc_state_canonicalize(&s);
  if (oc_state_validate(&s, NULL, 0) != 0) {
    rc = OC_ECORRUPT;
    goto done;
  }

  if (d->stats) {
    ocs_voxelize_stats_t *st = d->stats;
    memset(st, 0, sizeof *st);
    st->leaves = s.node_count;
    st->bricks = s.brick_count;
    for (uint32_t i = 0; i < s.node_count; i++) {
      const oc_node_t *nd = &s.nodes[i];
      st->empty += nd->kind == OC_NODE_EMPTY;
      st->uniform += nd->kind == OC_NODE_UNIFORM;
      int l = oc_key_level(nd->key);
      if (l >= 0 && l <= OC_KEY_MAX_LEVEL) st->per_level[l]++;
    }
    st->sanitize = san;
  }

done:
  if (job.chunks)
    for (uint32_t c = 0; c < job.nchunks; c++) free(job.chunks[c].codes);
  free(job.chunks);
  free(job.nodes);
  free(leaves.k);
  oc_state_free(out);
  if (rc < 0) {
    oc_state_free(&s);
    oc_state_init(out);
  } else {
    *out = s;
    if (d->stats) d->stats->seconds = oc__now() - t0;
  }
  return rc;
}

/* ---- Analytic media -------------------------------------------------------------------------- */

double ocs_medium_sigma_cb(void *ctx, oc_dvec3 p) {
  const ocs_medium_ctx_t *c = ctx;
  return ocs_medium_sigma_t(c->medium, p);
}

double ocs_medium_tau_cb(void *ctx, oc_dvec3 p) {
  const ocs_medium_ctx_t *c = ctx;
  return ocs_medium_tau_sun(c->medium, p, c->sun_dir);
}

int ocs_medium_refine_cb(void *ctx, oc_key_t key) {
  const ocs_medium_ctx_t *c = ctx;
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = c->margin + size / 14.0;
  oc_dvec3 lo = oc_dv3(o.x - g, o.y - g, o.z - g), hi = oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g);
  const ocs_medium_t *m = c->medium;
  int n = m->count < 0 ? 0 : (m->count > OCS_MEDIUM_MAX_PRIMS ? OCS_MEDIUM_MAX_PRIMS : m->count);
  for (int i = 0; i < n; i++) {
    const ocs_prim_t *pr = &m->prims[i];
    if (pr->kind != OCS_PRIM_NONE && pr->sigma_t > 0.0 && ocs_prim_intersects_box(pr, lo, hi)) return 1;
  }
  return 0;
}

int ocs_voxelize_medium(oc_state_t *out, const ocs_medium_t *m, int max_level, int sub, oc_dvec3 sun_dir, int threads) {
  OC_RETURN_IF(!out || !m, OC_EINVAL);
  ocs_medium_ctx_t ctx = {m, sun_dir, 0.0};
  double sl = oc_dlen(sun_dir);
  if (isfinite(sl) && sl > 0.0) ctx.sun_dir = oc_dscale(sun_dir, 1.0 / sl);
  ocs_voxelize_desc_t d = {0};
  d.sigma = ocs_medium_sigma_cb;
  d.tau = ocs_medium_tau_cb;
  d.ctx = &ctx;
  d.min_level = 0;
  d.max_level = max_level;
  d.refine = ocs_medium_refine_cb;
  d.sub_sigma = sub;
  d.sun_dir = sun_dir;
  d.threads = threads;
  return ocs_voxelize(out, &d);
}
