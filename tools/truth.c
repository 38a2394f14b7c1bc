/* truth.c — stored truth images read back and scored (truth.h). */
#include "truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocs.h"
#include "optics.h" /* ocg_aces_fit, ocg_srgb_encode: the tone map of oc_image_tonemap */

double oct_truth_source_length(const oc_source_t *src) {
  switch (src->type) {
    case OC_SOURCE_SPHERE: return 2.0 * src->sphere.radius;
    case OC_SOURCE_BOX: return src->box.size[2];
    case OC_SOURCE_SLAB: return src->slab.top - src->slab.base;
    default: return 0.0;
  }
}

double *oct_truth_source_sigma(oc_source_t *src) {
  switch (src->type) {
    case OC_SOURCE_SPHERE: return &src->sphere.sigma_t;
    case OC_SOURCE_BOX: return &src->box.sigma_t;
    case OC_SOURCE_SLAB: return &src->slab.sigma_t;
    default: return NULL;
  }
}

int oct_truth_scale(oc_scene_t *sc, double tau) {
  double len = 0.0, *first = NULL;
  for (int i = 0; i < sc->nsources && !first; i++)
    if ((len = oct_truth_source_length(&sc->sources[i])) > 0.0) first = oct_truth_source_sigma(&sc->sources[i]);
  if (!first || !(*first > 0.0)) return -1;
  double f = tau / (*first * len); /* every source scaled alike, as the bench does */
  for (int i = 0; i < sc->nsources; i++) {
    double *s = oct_truth_source_sigma(&sc->sources[i]);
    if (s) *s *= f;
  }
  return 0;
}

void oct_truth_case_free(oct_truth_case_t *c) {
  free(c->L);
  free(c->se);
  memset(c, 0, sizeof *c);
}

static int oc__truth_bad(FILE *f, oct_truth_case_t *c, char *why, size_t why_len, const char *path, const char *what) {
  snprintf(why, why_len, "%s: %s", path, what);
  if (f) fclose(f);
  oct_truth_case_free(c);
  return OC_EINVAL;
}

/* "key value" lines up to "pixels", then w·h "radiance se" lines. */
int oct_truth_case_load(oct_truth_case_t *c, const char *path, char *why, size_t why_len) {
  memset(c, 0, sizeof *c);
  FILE *f = fopen(path, "r");
  if (!f) return oc__truth_bad(NULL, c, why, why_len, path, "cannot open");
  char line[1024];
  int have = 0;
  while (fgets(line, sizeof line, f)) {
    line[strcspn(line, "\r\n")] = '\0';
    if (line[0] == '#' || line[0] == '\0') continue;
    if (strcmp(line, "pixels") == 0) {
      have = 1;
      break;
    }
    if (sscanf(line, "scene %511s", c->scene) == 1 || sscanf(line, "camera %159s", c->camera) == 1 ||
        sscanf(line, "tau %lf", &c->tau) == 1 || sscanf(line, "size %d %d", &c->w, &c->h) == 2 ||
        sscanf(line, "paths %ld", &c->paths) == 1 || sscanf(line, "albedo %lf", &c->albedo) == 1 ||
        sscanf(line, "background %lf", &c->background) == 1 || sscanf(line, "mean %lf %lf", &c->mean, &c->mean_se) == 2 ||
        sscanf(line, "env %lf %lf", &c->env, &c->env_se) == 2 || sscanf(line, "air_sigma %lf", &c->air_sigma) == 1 ||
        sscanf(line, "air_top %lf", &c->air_top) == 1 ||
        strncmp(line, "seed ", 5) == 0)
      continue;
    return oc__truth_bad(f, c, why, why_len, path, "unknown line");
  }
  if (!have || !c->scene[0] || !(c->tau > 0.0) || c->w <= 0 || c->h <= 0 || c->w > 4096 || c->h > 4096 ||
      !(c->albedo >= 0.0 && c->albedo <= 1.0))
    return oc__truth_bad(f, c, why, why_len, path, "missing or invalid parameters");
  if (!(c->air_sigma >= 0.0 && c->air_sigma <= OC_RENDER_MAX_AIR_SIGMA))
    return oc__truth_bad(f, c, why, why_len, path, "air_sigma: outside [0, 1e-3] m⁻¹");
  if (c->air_sigma > 0.0 && !(c->air_top >= 100.0 && c->air_top <= OC_ATMOSPHERE_HEIGHT))
    return oc__truth_bad(f, c, why, why_len, path, "air_top: outside [100, 1e5] m");
  size_t n = (size_t)c->w * (size_t)c->h;
  c->L = malloc(n * sizeof *c->L);
  c->se = malloc(n * sizeof *c->se);
  if (!c->L || !c->se) return oc__truth_bad(f, c, why, why_len, path, "out of memory");
  for (size_t i = 0; i < n; i++)
    if (fscanf(f, "%lf %lf", &c->L[i], &c->se[i]) != 2 || !isfinite(c->L[i]) || !(c->se[i] >= 0.0))
      return oc__truth_bad(f, c, why, why_len, path, "short or invalid pixel data");
  fclose(f);
  return 0;
}

int oct_truth_case_state(const oct_truth_case_t *c, const char *root, oc_scene_t *sc, oc_camera_t *cam, oc_state_t *st,
                        char *why, size_t why_len) {
  char path[1100];
  snprintf(path, sizeof path, "%s%s%s", root ? root : "", root ? "/" : "", c->scene);
  int rc = oc_scene_load(sc, path, why, why_len);
  if (rc < 0) return rc;
  if (oct_truth_scale(sc, c->tau) < 0) {
    snprintf(why, why_len, "%s: the first source has no extinction to scale", path);
    oc_scene_free(sc);
    return OC_EINVAL;
  }
  sc->optics.albedo = c->albedo;
  oc_camera_pose_t pose = {sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  if (c->camera[0] && (rc = oc_camera_parse(c->camera, &pose, why, why_len)) < 0) {
    oc_scene_free(sc);
    return rc;
  }
  *cam = oc_camera_from_pose(pose);
  oc_state_init(st);
  ocs_scene_voxelize_desc_t vd = {*cam, c->h, 2.0, 16, 0, 1};
  if ((rc = ocs_scene_voxelize(st, sc, &vd, why, why_len)) < 0) {
    oc_state_free(st);
    oc_scene_free(sc);
  }
  return rc < 0 ? rc : 0;
}

oc_render_desc_t oct_truth_case_desc(const oct_truth_case_t *c, const oc_scene_t *sc, oc_camera_t cam) {
  oc_render_desc_t d = {0};
  d.width = c->w;
  d.height = c->h;
  d.camera = cam;
  d.step_factor = 0.25;
  d.ms_octaves = sc->optics.ms_octaves;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)c->albedo;
  d.albedo_zero = c->albedo == 0.0;
  oct_truth_light(&d, c->background);
  d.air_sigma = (float)c->air_sigma;
  d.air_top = c->air_top;
  d.threads = 1;
  return d;
}

void oct_truth_light(oc_render_desc_t *d, double background) {
  d->background = OC_BG_CONSTANT;
  d->background_radiance = (float)background;
  d->flags = OC_RF_NO_ATMOSPHERE;
  d->atmo = NULL;
  d->sun_irradiance = 0.0f; /* the default, 1 */
}

/* One grey value through the benches' tone map (exposure 10, ACES fit, sRGB), 0–255, unrounded. */
static double oc__tone(double v) {
  return 255.0 * ocg_srgb_encode(ocg_aces_fit(ocg_v3s((float)v * OCT_TRUTH_EXPOSURE)).x);
}

int oct_truth_score(const oct_truth_case_t *c, const oc_image_t *img, oct_truth_score_t *s) {
  size_t n = (size_t)c->w * (size_t)c->h;
  oc_image_t t = {0};
  uint8_t *a = malloc(3 * n), *b = malloc(3 * n);
  if (!a || !b || oc_image_alloc(&t, c->w, c->h) < 0) {
    free(a);
    free(b);
    return OC_ENOMEM;
  }
  double sum = 0.0, noise2 = 0.0;
  for (size_t i = 0; i < n; i++) {
    sum += img->px[4 * i];
    t.px[4 * i] = t.px[4 * i + 1] = t.px[4 * i + 2] = (float)c->L[i];
    t.px[4 * i + 3] = 1.0f;
    double dn = oc__tone(c->L[i] + c->se[i]) - oc__tone(fmax(c->L[i] - c->se[i], 0.0)); /* ≈ 2·SE·slope */
    noise2 += 2.0 * (0.5 * dn) * (0.5 * dn); /* two seeds differ by √2·SE */
  }
  oc_image_tonemap(&t, OCT_TRUTH_EXPOSURE, a);
  oc_image_tonemap(img, OCT_TRUTH_EXPOSURE, b);
  s->mean = sum / (double)n;
  s->rel = c->mean > 0.0 ? (s->mean - c->mean) / c->mean : 0.0;
  s->rel_se = c->mean > 0.0 ? c->mean_se / c->mean : 0.0;
  s->rmse8 = oc_rgb8_rmse(a, b, c->w, c->h);
  s->noise8 = sqrt(noise2 / (double)n);
  oc_image_free(&t);
  free(a);
  free(b);
  return 0;
}

int oct_truth_ambient(const oct_truth_case_t *c, const oc_state_t *st, oc_render_desc_t d, double *mean) {
  oc_image_t img = {0};
  int rc = oc_image_alloc(&img, c->w, c->h);
  if (rc < 0) return rc;
  d.background_radiance = 1.0f;
  d.sun_irradiance = 1e-30f; /* 0 would mean the default, 1 */
  d.flags &= ~(uint32_t)OC_RF_NO_AMBIENT;
  rc = oc_render_state(st, &d, &img, NULL);
  double sum = 0.0;
  for (size_t i = 0; i < (size_t)c->w * (size_t)c->h; i++) sum += img.px[4 * i];
  *mean = sum / ((double)c->w * (double)c->h);
  oc_image_free(&img);
  return rc < 0 ? rc : 0;
}
