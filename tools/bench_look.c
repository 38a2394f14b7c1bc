/* bench_look.c — `overcast-bench look`: is a view worth opening? The state the server core plans
 * for a viewer at the camera (procedural and VDB scenes; analytic ones voxelized with exact τ),
 * rendered by the CPU reference, measured the way issue 21 judges the main job's first frame:
 *   - cloud pixels: those the cloud covers at least half (cloud transmittance Tc ≤ 0.5), as a
 *     share of the frame (goal ≥ 15 %);
 *   - lit against dark cloud: the mean linear luminance of the brightest fifth of the cloud
 *     pixels over that of the darkest fifth (goal ≥ 2): sunlit tops against shaded bases and
 *     sides. A flat, evenly lit cloud deck scores about 1;
 *   - the ground: the mean colour of the pixels that see neither cloud nor sky (the ground and its
 *     cloud shadows), so that "reads as land" is a number too.
 * Several cameras may be given (`;`-separated), one row each. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"

typedef struct {
  const char *scene, *camera, *png, *sun;
  int size[2], epochs, budget, ground_map;
  double time, exposure, min_cloud, min_ratio;
} look_opts_t;

static const oc_cli_opt_t look_opts[] = {
    OCT_OPT_SCENE(look_opts_t),
    {.name = "camera", .type = OC_CLI_STRING, .offset = offsetof(look_opts_t, camera),
     .arg = "LAT,LON,ALT,HEADING,PITCH,FOV[;...]", .def_note = "the scene's camera",
     .help = "the viewer's camera; several separated by ';' give a row each"},
    OCT_SIZE(look_opts_t, size, "size", "320x180", "image size"),
    OCT_OPT_EPOCHS(look_opts_t, "10", "epochs the server core plans before the frame"),
    OCT_OPT_BUDGET(look_opts_t, "64", "the viewer's"),
    OCT_OPT_TIME(look_opts_t),
    OCT_DBL(look_opts_t, exposure, "exposure", "X", 1e-3, 1e3, "10", "exposure of --png (the viewer's default)"),
    OCT_DBL(look_opts_t, min_cloud, "min-cloud", "PCT", 0, 100, "15", "cloud pixels, % of the frame, to pass"),
    OCT_DBL(look_opts_t, min_ratio, "min-ratio", "X", 0, 1e6, "2", "lit / dark cloud luminance to pass"),
    OCT_STR(look_opts_t, sun, "sun", "HEADING,ELEVATION",
            "the sun as seen from each camera, degrees (default: the scene's sun; its direction is the planet's, "
            "so it moves with the camera)"),
    OCT_STR(look_opts_t, png, "png", "PREFIX", "also write each camera's image as PREFIX<i>.png"),
    OCT_OPT_GROUND_MAP(look_opts_t),
    OCT_OPTS_END};

OCT_SPEC(look,
         "A view's look, measured: cloud pixels, lit against dark cloud luminance, the ground's colour\n"
         "(the state the server core plans at the camera, CPU reference). Exit status 1 when a camera\n"
         "misses --min-cloud or --min-ratio.",
         look_opts);

typedef struct {
  double cloud_pct, ratio, lit, dark;
  double ground[3], ground_pct;
} look_t;

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static double luminance(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

/* The figures of one rendered frame; `sky` holds the same view without clouds or ground (a state
 * with no nodes): a pixel whose radiance differs from the sky by less than 2 % is sky. */
static int look_measure(const oc_image_t *img, const oc_image_t *sky, look_t *out) {
  size_t n = (size_t)img->w * (size_t)img->h, nc = 0, ng = 0;
  double *lum = malloc(sizeof *lum * (n ? n : 1));
  if (!lum) return -1;
  memset(out, 0, sizeof *out);
  for (size_t i = 0; i < n; i++) {
    const float *p = img->px + 4 * i, *s = sky->px + 4 * i;
    if (p[3] <= 0.5f) {
      lum[nc++] = luminance(p);
    } else if (fabs(luminance(p) - luminance(s)) > 0.02 * luminance(s)) {
      for (int c = 0; c < 3; c++) out->ground[c] += p[c];
      ng++;
    }
  }
  out->cloud_pct = 100.0 * (double)nc / (double)n;
  out->ground_pct = 100.0 * (double)ng / (double)n;
  for (int c = 0; c < 3 && ng; c++) out->ground[c] /= (double)ng;
  if (nc >= 5) {
    qsort(lum, nc, sizeof *lum, cmp_double);
    size_t k = nc / 5;
    for (size_t i = 0; i < k; i++) {
      out->dark += lum[i];
      out->lit += lum[nc - 1 - i];
    }
    out->dark /= (double)k;
    out->lit /= (double)k;
    out->ratio = out->dark > 0.0 ? out->lit / out->dark : INFINITY;
  }
  free(lum);
  return 0;
}

/* The state the server core plans for a viewer at this camera (analytic scenes: voxelized). */
static int look_state(const char *prog, const look_opts_t *o, const oc_scene_t *sc, oc_camera_pose_t pose,
                      oc_state_t *st) {
  char why[512];
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_medium_t medium;
  if (ocs_scene_medium(sc, &medium, NULL, 0) == 0) {
    ocs_scene_voxelize_desc_t vd = {cam, o->size[1], 2.0, 16, 0, 2};
    if (ocs_scene_voxelize(st, sc, &vd, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s", why);
    return 0;
  }
  ocs_world_desc_t wd = {.threads = 2, .time = o->time};
  ocs_world_t *world = NULL;
  if (ocs_world_create(&world, sc, &wd, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s", why);
  ocs_plan_desc_t pd = {.budget = (uint64_t)o->budget << 20, .slot_bytes = OC_SLOT_BYTES,
                        .record_bytes = OC_RECORD_BYTES, .max_depth = 21, .split_fraction = 0.5};
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, o->size[0], o->size[1]};
  int r = ocs_world_plan_offline(world, &pd, &view, o->epochs, st, why, sizeof why);
  ocs_world_free(world);
  return r < 0 ? oc_cli_fail(prog, -1, "%s", why) : 0;
}

static int look_png(const char *prog, const char *prefix, int i, oc_camera_pose_t pose, const oc_image_t *img,
                    double exposure) {
  char path[1024], why[512], cam_text[256];
  snprintf(path, sizeof path, "%s%d.png", prefix, i);
  uint8_t *rgb = malloc((size_t)img->w * (size_t)img->h * 3);
  if (!rgb) return oc_cli_fail(prog, -1, "out of memory");
  oc_camera_format(pose, cam_text, sizeof cam_text);
  oc_png_text_t text[1] = {{"overcast-camera", cam_text}};
  oc_image_tonemap(img, (float)exposure, rgb);
  int r = oc_png_write(path, img->w, img->h, rgb, text, 1, why, sizeof why);
  free(rgb);
  if (r < 0) return oc_cli_fail(prog, -1, "%s", why);
  fprintf(stderr, "%s: wrote %s\n", prog, path);
  return 0;
}

/* One camera: plan, render with and without the state, measure, print a row. 1: below a goal. */
static int look_camera(const char *prog, const look_opts_t *o, const oc_scene_t *sc, const oc_atmo_t *atmo,
                       oc_camera_pose_t pose, const char *label, int i) {
  oc_state_t st, none;
  oc_state_init(&st);
  oc_state_init(&none);
  oc_image_t img = {0}, sky = {0};
  int rc = -1;
  if (look_state(prog, o, sc, pose, &st)) goto out;
  none.epoch = st.epoch;
  none.time = st.time;
  none.sun_dir = st.sun_dir;
  oc_render_desc_t d = oc_scene_render_desc(sc, atmo);
  d.width = o->size[0];
  d.height = o->size[1];
  d.camera = oc_camera_from_pose(pose);
  d.threads = 2;
  d.shadow_ground_cells = o->ground_map;
  oc_render_stats_t rs;
  look_t lk;
  if (oc_image_alloc(&img, d.width, d.height) < 0 || oc_image_alloc(&sky, d.width, d.height) < 0 ||
      oc_render_state(&st, &d, &img, &rs) < 0 || oc_render_state(&none, &d, &sky, &rs) < 0 ||
      look_measure(&img, &sky, &lk) < 0) {
    oc_cli_fail(prog, -1, "render failed");
    goto out;
  }
  if (o->png && look_png(prog, o->png, i, pose, &img, o->exposure)) goto out;
  int ok = lk.cloud_pct >= o->min_cloud && lk.ratio >= o->min_ratio;
  printf("| %s | %u | %.1f | %.2f | %.3g / %.3g | %.1f | %.3f %.3f %.3f | %s |\n", label, st.brick_count,
         lk.cloud_pct, lk.ratio, lk.lit, lk.dark, lk.ground_pct, lk.ground[0], lk.ground[1], lk.ground[2],
         ok ? "yes" : "NO");
  rc = ok ? 0 : 1;
out:
  oc_image_free(&img);
  oc_image_free(&sky);
  oc_state_free(&st);
  oc_state_free(&none);
  return rc;
}

int oct_bench_look(const char *prog, int argc, char **argv) {
  look_opts_t o = {0};
  static oc_scene_t sc;
  int rc = oct_begin(&oct_bench_look_spec, argc, argv, &o, &o.scene, NULL, &sc, NULL);
  if (rc != OCT_GO) return rc;
  oc_atmo_t *atmo = NULL;
  if (oc_scene_atmo(&sc, 2, &atmo) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
  }
  double sun[2];
  char end;
  if (o.sun && (sscanf(o.sun, "%lf,%lf%c", &sun[0], &sun[1], &end) != 2 || !isfinite(sun[0]) ||
                fabs(sun[1]) > 90.0)) {
    oc_atmo_free(atmo);
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--sun: \"%s\" is not HEADING,ELEVATION in degrees (elevation in [-90, 90])",
                       o.sun);
  }
  printf("# %s, %dx%d, %d epochs, %d MiB; goals: cloud ≥ %g %%, lit / dark ≥ %g\n\n", o.scene ? o.scene : "planet",
         o.size[0], o.size[1], o.epochs, o.budget, o.min_cloud, o.min_ratio);
  printf("| camera | bricks | cloud pixels %% | lit / dark | lit, dark luminance | ground pixels %% | ground RGB "
         "radiance | goals met |\n|---|---:|---:|---:|---:|---:|---|---|\n");
  /* the cameras in --camera, or the scene's once */
  int missed = 0;
  char *list = o.camera ? strdup(o.camera) : NULL, *save = NULL;
  rc = o.camera && !list ? OC_EXIT_RUNTIME : OC_EXIT_OK;
  char *c = list ? strtok_r(list, ";", &save) : NULL;
  for (int i = 0; rc == OC_EXIT_OK && (i == 0 || c); i++, c = c ? strtok_r(NULL, ";", &save) : NULL) {
    char why[512];
    oc_camera_pose_t pose = {sc.camera.pos, sc.camera.heading, sc.camera.pitch, sc.camera.fov};
    if (c && oc_camera_parse(c, &pose, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
      break;
    }
    if (o.sun) sc.sun_dir = oc_heading_pitch_dir(oc_enu_at(oc_geo_to_xyz(pose.geo)), sun[0], sun[1]);
    int r = look_camera(prog, &o, &sc, atmo, pose, c ? c : "the scene's", i);
    if (r < 0) rc = OC_EXIT_RUNTIME;
    missed |= r > 0;
  }
  free(list);
  if (rc == OC_EXIT_OK && missed) rc = 1;
  oc_atmo_free(atmo);
  oc_scene_free(&sc);
  return rc;
}
