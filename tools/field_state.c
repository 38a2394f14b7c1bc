#include "field_state.h"

#include <math.h>
#include <stdio.h>

#include "oc_err.h"
#include "oc_scene_voxelize.h" /* oc_lod_pixels */
#include "oc_voxelize.h"

typedef struct {
  const oct_field_state_desc_t *d;
  double k; /* pixels per radian-ish: viewport_height / (2 tan(fov/2)) */
  double pixels;
} oct__ctx_t;

static double oct__sigma(void *ctx, oc_dvec3 p) {
  const oct__ctx_t *c = ctx;
  return ocs_field_point(c->d->field, p, c->d->time);
}

/* τ: the field's σt integrated toward the sun with midpoint steps. */
static double oct__tau(void *ctx, oc_dvec3 p) {
  const oct__ctx_t *c = ctx;
  const oct_field_state_desc_t *d = c->d;
  double tau = 0.0;
  int n = (int)ceil(d->tau_length / d->tau_step);
  for (int i = 0; i < n; i++) tau += ocs_field_point(d->field, oc_dmad(p, d->sun_dir, (i + 0.5) * d->tau_step), d->time);
  return tau * d->tau_step;
}

static int oct__refine(void *ctx, oc_key_t key) {
  const oct__ctx_t *c = ctx;
  if (oc_lod_pixels(key, c->d->camera.pos, c->k) <= c->pixels) return 0;
  float lo, hi;
  ocs_field_bound(c->d->field, key, c->d->time, &lo, &hi);
  return hi > 0.0f && lo != hi; /* empty and uniform nodes are never split */
}

int oct_field_state(oc_state_t *out, const oct_field_state_desc_t *d0, char *why, size_t why_len) {
  oct_field_state_desc_t d = *d0;
  if (d.viewport_height <= 0) d.viewport_height = 360;
  if (d.pixels <= 0.0) d.pixels = 2.0;
  if (d.max_level <= 0) d.max_level = 16;
  if (d.tau_step <= 0.0) d.tau_step = 250.0;
  if (d.tau_length <= 0.0) d.tau_length = 20000.0;
  oct__ctx_t c = {&d, d.viewport_height / (2.0 * tan(0.5 * d.camera.vfov_deg * OC_DEG)), d.pixels};
  oc_voxelize_desc_t vd = {0};
  vd.sigma = oct__sigma;
  vd.tau = d.shadows ? oct__tau : NULL;
  vd.ctx = &c;
  vd.min_level = 2;
  vd.max_level = d.max_level;
  vd.refine = oct__refine;
  vd.refine_ctx = &c;
  vd.sub_sigma = 2;
  vd.time = d.time;
  vd.sun_dir = d.sun_dir;
  vd.threads = d.threads > 0 ? d.threads : 1;
  vd.max_nodes = 400000;
  int r = oc_voxelize(out, &vd);
  if (r < 0 && why) snprintf(why, why_len, "building a state from the field: %s", oc_strerror(r));
  return r;
}
