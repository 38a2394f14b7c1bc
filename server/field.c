/* field.c — the field: the scene's sources summed, behind ocs_field.h. */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "ocs_field.h"
#include "seqcache.h"

struct ocs_field_s {
  int count;
  int cache_on;
  int exact; /* sample with each source's sample_exact where it has one */
  ocs_source_t *src[OC_SCENE_MAX_SOURCES];
  ocs_seqcache_t *bc[OC_SCENE_MAX_SOURCES]; /* the bound cache; NULL: the source is not cached */
  atomic_ullong sampled, bounds, hits, misses;
};

/*-*** The bound cache (ocs_field.h): one seqcache per cacheable source, lo|hi in one word ***/

static int ocs__bcache_get(const ocs_seqcache_t *c, oc_key_t key, uint64_t step, float *lo, float *hi) {
  uint64_t v;
  if (!ocs_seqcache_get(c, key, step, &v)) return 0;
  uint32_t a = (uint32_t)(v >> 32), b = (uint32_t)v;
  memcpy(lo, &a, sizeof a);
  memcpy(hi, &b, sizeof b);
  return 1;
}

static void ocs__bcache_put(ocs_seqcache_t *c, oc_key_t key, uint64_t step, float lo, float hi) {
  uint32_t a, b;
  memcpy(&a, &lo, sizeof a);
  memcpy(&b, &hi, sizeof b);
  uint64_t v = ((uint64_t)a << 32) | b;
  ocs_seqcache_put(c, key, step, &v);
}

/* Empties every table (callers serialise against bound()). */
static void ocs__bcache_clear(ocs_field_t *f) {
  for (int i = 0; i < f->count; i++) ocs_seqcache_clear(f->bc[i]);
}

/*-*** The field ***/

int ocs_field_create(ocs_field_t **out, const oc_scene_t *sc, char *why, size_t why_len) {
  *out = NULL;
  ocs_field_t *f = calloc(1, sizeof *f);
  if (!f) return OC_ENOMEM;
  atomic_init(&f->sampled, 0);
  atomic_init(&f->bounds, 0);
  atomic_init(&f->hits, 0);
  atomic_init(&f->misses, 0);
  const char *env = getenv("OCS_FIELD_BOUND_CACHE"); /* "0": bypassed, for before/after benches */
  f->cache_on = !(env && strcmp(env, "0") == 0);
  env = getenv("OCS_FIELD_EXACT"); /* "1": the exact box filters, for before/after benches */
  f->exact = env && strcmp(env, "1") == 0;
  for (int i = 0; i < sc->nsources; i++) {
    const oc_source_t *d = &sc->sources[i];
    char sub[512] = "";
    int r;
    switch (d->type) {
      case OC_SOURCE_SPHERE:
      case OC_SOURCE_BOX:
      case OC_SOURCE_SLAB: r = ocs_source_analytic_create(&f->src[i], d, sub, sizeof sub); break;
      case OC_SOURCE_PROCEDURAL: r = ocs_source_procedural_create(&f->src[i], d, sc->seed, sub, sizeof sub); break;
      case OC_SOURCE_VDB: r = ocs_source_vdb_create(&f->src[i], d, sub, sizeof sub); break;
      default: r = OC_EINVAL; snprintf(sub, sizeof sub, "unknown source type %d", (int)d->type); break;
    }
    if (r < 0) {
      if (why) snprintf(why, why_len, "sources[%d] (%s): %s", i, oc_scene_source_type_name(d->type), sub[0] ? sub : oc_strerror(r));
      ocs_field_free(f);
      return r;
    }
    f->count = i + 1;
    if (f->src[i]->vt->bound_by_step) {
      f->bc[i] = ocs_seqcache_new(OCS_FIELD_BOUND_CACHE_SLOTS, 1);
      if (!f->bc[i]) {
        ocs_field_free(f);
        return OC_ENOMEM;
      }
    }
    /* The scene decides: with animation off, sources freeze at t = 0 (2 kept states). */
    if (!oc_scene_has(sc, OC_FEATURE_ANIMATION)) f->src[i]->animated = 0;
  }
  *out = f;
  return 0;
}

void ocs_field_free(ocs_field_t *f) {
  if (!f) return;
  for (int i = 0; i < f->count; i++)
    if (f->src[i]) f->src[i]->vt->destroy(f->src[i]);
  for (int i = 0; i < f->count; i++) ocs_seqcache_free(f->bc[i]);
  free(f);
}

int ocs_field_animated(const ocs_field_t *f) {
  for (int i = 0; i < f->count; i++)
    if (f->src[i]->animated) return 1;
  return 0;
}

/* One source's step for node key's own content (its node_step, else its level's time step). */
static uint64_t ocs__node_step_of(const ocs_source_t *s, oc_key_t key, int level, double t) {
  return s->vt->node_step ? s->vt->node_step(s, key, t) : s->vt->time_step(s, level, t);
}

/* One source's bound of node key's footprint [lo, hi]. */
static void ocs__source_bound(const ocs_source_t *s, oc_key_t key, oc_dvec3 lo, oc_dvec3 hi, double t, float *a, float *b) {
  if (s->vt->node_bound && oc_key_valid(key))
    s->vt->node_bound(s, key, t, a, b);
  else
    s->vt->bound(s, lo, hi, t, a, b);
}

/* The sample footprint reaches size/14 beyond the node on every side (box filter of edge size/7). */
void ocs_field_bound(const ocs_field_t *f, oc_key_t key, double t, float *smin, float *smax) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = size / 14.0;
  oc_dvec3 lo = oc_dv3(o.x - g, o.y - g, o.z - g), hi = oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g);
  float mn = 0.0f, mx = 0.0f;
  int cache = f->cache_on && oc_key_valid(key), level = oc_key_level(key);
  uint64_t hits = 0, misses = 0;
  for (int i = 0; i < f->count; i++) {
    const ocs_source_t *s = f->src[i];
    float a, b;
    if (cache && f->bc[i]) {
      uint64_t step = ocs__node_step_of(s, key, level, t);
      if (ocs__bcache_get(f->bc[i], key, step, &a, &b)) {
        hits++;
      } else {
        ocs__source_bound(s, key, lo, hi, t, &a, &b);
        ocs__bcache_put(f->bc[i], key, step, a, b);
        misses++;
      }
    } else {
      ocs__source_bound(s, key, lo, hi, t, &a, &b);
    }
    mn += a;
    mx += b;
  }
  ocs_field_t *fm = (ocs_field_t *)f;
  atomic_fetch_add_explicit(&fm->bounds, 1, memory_order_relaxed);
  if (hits) atomic_fetch_add_explicit(&fm->hits, hits, memory_order_relaxed);
  if (misses) atomic_fetch_add_explicit(&fm->misses, misses, memory_order_relaxed);
  if (f->count > 1 && mn != mx) { /* float sums may round inward: widen by one ulp to stay conservative */
    mn = mn > 0.0f ? nextafterf(mn, 0.0f) : mn;
    mx = nextafterf(mx, INFINITY);
  }
  *smin = mn;
  *smax = mx;
}

int ocs_field_sample(const ocs_field_t *f, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) {
  if (!oc_key_valid(key)) return OC_EINVAL;
  memset(out, 0, sizeof(float) * OC_BRICK_VOXELS);
  for (int i = 0; i < f->count; i++) {
    const ocs_source_vtbl_t *vt = f->src[i]->vt;
    OC_TRY((f->exact && vt->sample_exact ? vt->sample_exact : vt->sample)(f->src[i], key, t, out));
  }
  atomic_fetch_add_explicit(&((ocs_field_t *)f)->sampled, 1, memory_order_relaxed);
  return 0;
}

/* A node must be refreshed when any source's step changes: combine the steps injectively enough
 * for a cache key (a change in any source changes the mix). */
static uint64_t ocs__step_mix(uint64_t h, uint64_t step, int i) { return (h ^ step) * 0x100000001b3ull + (uint64_t)i; }

uint64_t ocs_field_time_step(const ocs_field_t *f, int level, double t) {
  uint64_t h = 0;
  for (int i = 0; i < f->count; i++) h = ocs__step_mix(h, f->src[i]->vt->time_step(f->src[i], level, t), i);
  return h;
}

uint64_t ocs_field_node_step(const ocs_field_t *f, oc_key_t key, double t) {
  uint64_t h = 0;
  int level = oc_key_level(key);
  for (int i = 0; i < f->count; i++) h = ocs__step_mix(h, ocs__node_step_of(f->src[i], key, level, t), i);
  return h;
}

int ocs_field_step_before(const ocs_field_t *f, oc_key_t key, double t, double *t0) {
  if (!f || !t0 || !oc_key_valid(key)) return 0;
  for (int i = 0; i < f->count; i++)
    if (f->src[i]->vt->step_before && f->src[i]->vt->step_before(f->src[i], key, t, t0)) return 1;
  return 0;
}

int ocs_field_same_samples(const ocs_field_t *f, oc_key_t key, double t0, double t1) {
  int level = oc_key_level(key);
  if (!f || level < 0) return 0;
  for (int i = 0; i < f->count; i++) {
    const ocs_source_t *s = f->src[i];
    if (ocs__node_step_of(s, key, level, t0) == ocs__node_step_of(s, key, level, t1)) continue;
    if (!s->vt->same_samples || !s->vt->same_samples(s, key, t0, t1)) return 0;
  }
  return 1;
}

double ocs_field_point(const ocs_field_t *f, oc_dvec3 p, double t) {
  double v = 0.0;
  for (int i = 0; i < f->count; i++)
    if (f->src[i]->vt->point) v += f->src[i]->vt->point(f->src[i], p, t);
  return v;
}

int ocs_field_set_weather(ocs_field_t *f, oc_preset_t preset, double t0, double seconds) {
  int n = 0;
  for (int i = 0; i < f->count; i++)
    if (f->src[i]->vt->set_weather) {
      int r = f->src[i]->vt->set_weather(f->src[i], preset, t0, seconds);
      if (r == 0) n++;
      ocs__bcache_clear(f); /* even after a failure: a source may have changed before it failed */
      OC_TRY(r);
    }
  return n ? 0 : OC_EINVAL;
}

void ocs_field_stats(const ocs_field_t *f, ocs_field_stats_t *out) {
  out->sampled_bricks = atomic_load(&((ocs_field_t *)f)->sampled);
  out->bound_calls = atomic_load(&((ocs_field_t *)f)->bounds);
  out->bound_hits = atomic_load(&((ocs_field_t *)f)->hits);
  out->bound_misses = atomic_load(&((ocs_field_t *)f)->misses);
}

void ocs_field_set_bound_cache(ocs_field_t *f, int on) {
  if (!f) return;
  ocs__bcache_clear(f);
  f->cache_on = on != 0;
}

void ocs_field_set_exact(ocs_field_t *f, int on) {
  if (f) f->exact = on != 0;
}
