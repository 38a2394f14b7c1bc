/* bench_util.c — what the overcast-bench subcommands share (bench_util.h). */
#include "bench_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "oc.h"

double oct_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int oct__cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

double oct_median(double *v, int n) {
  qsort(v, (size_t)n, sizeof *v, oct__cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int oct_parse_list(const char *p, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n) {
  char buf[256];
  *n = 0;
  snprintf(buf, sizeof buf, "%s", text);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    if (*n == cap) {
      oc_cli_fail(p, 0, "%s: at most %d entries", opt, cap);
      return -1;
    }
    if (oc_cli_int(p, opt, tok, lo, hi, &out[(*n)++])) return -1;
  }
  if (*n == 0) {
    oc_cli_fail(p, 0, "%s: empty list", opt);
    return -1;
  }
  return 0;
}

int oct_load_scene(const char *p, const char *path, oc_scene_t *sc) {
  char why[1024];
  if (!path) {
    oc_scene_default(sc);
    return 0;
  }
  if (oc_scene_load(sc, path, why, sizeof why) < 0) {
    oc_cli_fail(p, 0, "%s", why);
    return -1;
  }
  return 0;
}

/*-*** Option parsers ***/

int oct_opt_list(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  oct_list_t *l = oc_cli_field(o, base);
  char opt[80];
  long span = (long)o->hi - (long)o->lo + 1;
  snprintf(opt, sizeof opt, "--%s", o->name);
  return oct_parse_list(p, opt, text, (long)o->lo, (long)o->hi, l->v, span < OCT_LIST_MAX ? (int)span : OCT_LIST_MAX,
                        &l->n);
}

int oct_opt_doubles(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  oct_dlist_t *l = oc_cli_field(o, base);
  char buf[512], opt[80];
  snprintf(buf, sizeof buf, "%s", text);
  snprintf(opt, sizeof opt, "--%s", o->name);
  l->n = 0;
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (l->n == OCT_LIST_MAX) return oc_cli_fail(p, -1, "%s: at most %d entries", opt, OCT_LIST_MAX);
    if (oc_cli_double(p, opt, tok, o->lo, o->hi, &l->v[l->n++])) return -1;
  }
  if (l->n == 0) return oc_cli_fail(p, -1, "%s: empty list", opt);
  return 0;
}

int oct_opt_at(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  oct_at_t *at = oc_cli_field(o, base);
  if (sscanf(text, "%lf,%lf", &at->lat, &at->lon) != 2 ||
      !(at->lat >= -90 && at->lat <= 90 && at->lon >= -360 && at->lon <= 360)) {
    oc_cli_fail(p, 0, "--%s: expected LAT,LON in degrees, got \"%s\"", o->name, text);
    return -1;
  }
  at->given = 1;
  return 0;
}

int oct_opt_size(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  int *wh = oc_cli_field(o, base);
  char opt[80];
  snprintf(opt, sizeof opt, "--%s", o->name);
  return oc_cli_size(p, opt, text, &wh[0], &wh[1]);
}

int oct_opt_ground_map(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  int *n = oc_cli_field(o, base);
  char opt[80];
  long v;
  snprintf(opt, sizeof opt, "--%s", o->name);
  if (oc_cli_int(p, opt, text, -1, OC_RENDER_SHADOW_GROUND_CELLS_MAX, &v) < 0) return -1;
  if (v != -1 && v < OC_RENDER_SHADOW_GROUND_CELLS_MIN) { /* 0 would mean the renderer's default */
    oc_cli_fail(p, 0, "%s: %ld is neither -1 nor in [%d, %d]", opt, v, OC_RENDER_SHADOW_GROUND_CELLS_MIN,
                OC_RENDER_SHADOW_GROUND_CELLS_MAX);
    return -1;
  }
  *n = (int)v;
  return 0;
}

int oct_opt_renderer(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  int *gl = oc_cli_field(o, base);
  if (strcmp(text, "cpu") && strcmp(text, "gl")) {
    oc_cli_fail(p, 0, "--%s: expected cpu or gl, got \"%s\"", o->name, text);
    return -1;
  }
  *gl = !strcmp(text, "gl");
#ifndef OC_HAVE_GL
  if (*gl) {
    oc_cli_fail(p, 0, "--%s gl: this build has no GL renderer (libepoxy was not found)", o->name);
    return -1;
  }
#endif
  return 0;
}

/*-*** The preamble ***/

int oct_scene_camera(const char *prog, const char *path, const char *camera, oc_scene_t *sc, oc_camera_pose_t *pose) {
  if (oct_load_scene(prog, path, sc)) return OC_EXIT_RUNTIME;
  if (!pose) return OCT_GO;
  char why[512];
  *pose = (oc_camera_pose_t){sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  if (camera && oc_camera_parse(camera, pose, why, sizeof why) < 0) {
    oc_scene_free(sc);
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
  }
  return OCT_GO;
}

int oct_begin(const oc_cli_spec_t *spec, int argc, char **argv, void *opts, const char *const *scene,
              const char *const *camera, oc_scene_t *sc, oc_camera_pose_t *pose) {
  int r = oc_cli_parse(spec, argc, argv, opts, NULL, NULL);
  if (r) return r > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  if (!sc) return OCT_GO;
  return oct_scene_camera(spec->prog, scene ? *scene : NULL, camera ? *camera : NULL, sc, pose);
}

/*-*** A single-threaded brick cache in front of the field ***/

static oct_fcache_ent_t *fcache_find(oct_fcache_t *c, oc_key_t key) {
  if ((c->n + 1) * 2 > c->cap) {
    size_t ncap = c->cap ? c->cap * 2 : 4096;
    oct_fcache_ent_t *nt = calloc(ncap, sizeof *nt);
    if (!nt) return NULL;
    for (size_t i = 0; i < c->cap; i++) {
      if (!c->tab[i].key) continue;
      size_t h = (size_t)((c->tab[i].key * 0x9E3779B97F4A7C15ull) >> 24) & (ncap - 1);
      while (nt[h].key) h = (h + 1) & (ncap - 1);
      nt[h] = c->tab[i];
    }
    free(c->tab);
    c->tab = nt;
    c->cap = ncap;
  }
  size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 24) & (c->cap - 1);
  while (c->tab[h].key && c->tab[h].key != key) h = (h + 1) & (c->cap - 1);
  if (!c->tab[h].key) {
    c->tab[h].key = key;
    c->n++;
  }
  return &c->tab[h];
}

int oct_fcache_sigma(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]) {
  oct_fcache_t *c = ctx;
  c->sigma_calls++;
  oct_fcache_ent_t *e = fcache_find(c, key);
  if (!e) return OC_ENOMEM;
  if (!e->brick) {
    float *np = oc_grow(c->pool, &c->pool_cap, c->nb, OC_BRICK_VOXELS * sizeof(float), 256);
    if (!np) return OC_ENOMEM;
    c->pool = np;
    float *b = c->pool + c->nb * OC_BRICK_VOXELS;
    OC_TRY(ocs_field_sample(c->f, key, c->t, b));
    oc_sanitize(b, OC_BRICK_VOXELS, NULL);
    e->brick = (int)(++c->nb);
    c->sigma_fetches++;
  }
  memcpy(out, c->pool + (size_t)(e->brick - 1) * OC_BRICK_VOXELS, sizeof(float) * OC_BRICK_VOXELS);
  return 0;
}

void oct_fcache_bound(void *ctx, oc_key_t key, float *lo, float *hi) {
  oct_fcache_t *c = ctx;
  c->bound_calls++;
  oct_fcache_ent_t *e = fcache_find(c, key);
  if (!e) { /* out of memory: say "anything" (the sample will fail the same way) */
    *lo = 0.0f, *hi = INFINITY;
    return;
  }
  if (!e->has_bound) {
    ocs_field_bound(c->f, key, c->t, &e->lo, &e->hi);
    e->has_bound = 1;
    c->bound_fetches++;
  }
  *lo = e->lo, *hi = e->hi;
}

void oct_fcache_free(oct_fcache_t *c) {
  free(c->tab);
  free(c->pool);
  c->tab = NULL, c->pool = NULL;
  c->cap = c->n = c->nb = c->pool_cap = 0;
}

/*-*** Issue 17's anchor ***/

double oct_anchor_seconds(const oc_key_t *keys, long n, double *sink) {
  const oc_fbm_t fb = {.octaves = 6, .lacunarity = 2.0, .gain = 0.5, .seed = 17};
  double acc = 0.0, t0 = oct_now();
  for (long q = 0; q < n; q++)
    for (int k = 0; k < 8; k++)
      for (int j = 0; j < 8; j++)
        for (int i = 0; i < 8; i++) {
          oc_dvec3 p = ocs_brick_sample_pos(keys[q], i, j, k);
          acc += oc_fbm3(p.x * 1e-3, p.y * 1e-3, p.z * 1e-3, &fb);
        }
  *sink += acc;
  return oct_now() - t0;
}
