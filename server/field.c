/* field.c — the field: the scene's sources summed, behind ocs_field.h. */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "ocs_field.h"

struct ocs_field_s {
  int count;
  ocs_source_t *src[OC_SCENE_MAX_SOURCES];
  atomic_ullong sampled, bounds;
};

int ocs_field_create(ocs_field_t **out, const oc_scene_t *sc, char *why, size_t why_len) {
  *out = NULL;
  ocs_field_t *f = calloc(1, sizeof *f);
  if (!f) return OC_ENOMEM;
  atomic_init(&f->sampled, 0);
  atomic_init(&f->bounds, 0);
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
  free(f);
}

int ocs_field_animated(const ocs_field_t *f) {
  for (int i = 0; i < f->count; i++)
    if (f->src[i]->animated) return 1;
  return 0;
}

/* The sample footprint reaches size/14 beyond the node on every side (box filter of edge size/7). */
void ocs_field_bound(const ocs_field_t *f, oc_key_t key, double t, float *smin, float *smax) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = size / 14.0;
  oc_dvec3 lo = oc_dv3(o.x - g, o.y - g, o.z - g), hi = oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g);
  float mn = 0.0f, mx = 0.0f;
  for (int i = 0; i < f->count; i++) {
    float a, b;
    f->src[i]->vt->bound(f->src[i], lo, hi, t, &a, &b);
    mn += a;
    mx += b;
  }
  atomic_fetch_add_explicit(&((ocs_field_t *)f)->bounds, 1, memory_order_relaxed);
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
  for (int i = 0; i < f->count; i++) OC_TRY(f->src[i]->vt->sample(f->src[i], key, t, out));
  atomic_fetch_add_explicit(&((ocs_field_t *)f)->sampled, 1, memory_order_relaxed);
  return 0;
}

/* A node must be refreshed when any source's step changes: combine the steps injectively enough
 * for a cache key (a change in any source changes the mix). */
uint64_t ocs_field_time_step(const ocs_field_t *f, int level, double t) {
  uint64_t h = 0;
  for (int i = 0; i < f->count; i++) {
    uint64_t s = f->src[i]->vt->time_step(f->src[i], level, t);
    h = (h ^ s) * 0x100000001b3ull + (uint64_t)i;
  }
  return h;
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
      OC_TRY(f->src[i]->vt->set_weather(f->src[i], preset, t0, seconds));
      n++;
    }
  return n ? 0 : OC_EINVAL;
}

void ocs_field_stats(const ocs_field_t *f, ocs_field_stats_t *out) {
  out->sampled_bricks = atomic_load(&((ocs_field_t *)f)->sampled);
  out->bound_calls = atomic_load(&((ocs_field_t *)f)->bounds);
}
