/* bench_render.c — `overcast-bench render`: CPU reference renderer throughput (samples/s) per
 * thread count, side by side in one run, and a check that every thread count produced the same
 * image. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"
#include "ocv.h"
#include <math.h>
#ifdef OC_HAVE_GL

#endif

typedef struct {
  const char *scene, *camera, *png;
  int size[2], repeat, gl, ground_map;
  oct_list_t threads;
  double step, time;
} render_opts_t;

/* The render description both renderers get: the scene's (its features and optics) at this view, with
 * o's step factor and ground map. */
static oc_render_desc_t render_desc(const oc_scene_t *sc, oc_camera_t cam, const render_opts_t *o, const oc_atmo_t *atmo) {
  oc_render_desc_t d = oc_scene_render_desc(sc, atmo);
  d.width = o->size[0];
  d.height = o->size[1];
  d.camera = cam;
  d.step_factor = o->step;
  d.shadow_ground_cells = o->ground_map;
  return d;
}

/* The same description with the cloud model before the truth fit (Wrenninge's octaves, a = b = c = ½). */
static oc_render_desc_t oct_render_legacy(oc_render_desc_t d) {
  d.ms_model = OC_MS_MODEL_OCTAVES;
  d.ms_a = d.ms_b = d.ms_c = 0.5f;
  return d;
}

/* The fitted cloud model against the one before the fit, alternated in one run (one thread): the
 * cost of the model alone. */
static int bench_models(const char *prog, const oc_state_t *st, oc_render_desc_t d, long repeat) {
  oc_image_t img = {0};
  if (oc_image_alloc(&img, d.width, d.height) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  oc_render_desc_t dd[2] = {d, oct_render_legacy(d)};
  double best[2] = {1e30, 1e30};
  uint64_t samples[2] = {0, 0};
  dd[0].threads = dd[1].threads = 1;
  for (long r = 0; r < repeat; r++)
    for (int k = 0; k < 2; k++) {
      oc_render_stats_t rs;
      double t0 = oct_now();
      if (oc_render_state(st, &dd[k], &img, &rs) < 0) {
        oc_image_free(&img);
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed");
      }
      best[k] = fmin(best[k], oct_now() - t0);
      samples[k] = rs.samples;
    }
  oc_image_free(&img);
  printf("\n# Cloud model cost (1 thread, alternated, best of %ld)\n\n| model | s | samples | vs before the fit |\n"
         "|---|---:|---:|---:|\n| fitted (march.h) | %.4f | %llu | %.3f |\n| octaves before the fit | %.4f | %llu | 1 |\n",
         repeat, best[0], (unsigned long long)samples[0], best[0] / best[1], best[1], (unsigned long long)samples[1]);
  return OC_EXIT_OK;
}

#ifdef OC_HAVE_GL
/* The GL compute renderer on the same state (upload once, best of `repeat` renders including the
 * read-back), its time against one CPU thread and its RMSE (0–255, after tone mapping) against the
 * CPU image. */
static int bench_gl(const oc_state_t *st, const oc_scene_t *sc, oc_camera_t cam, const render_opts_t *o,
                    const oc_atmo_t *atmo, const oc_image_t *ref, double cpu1) {
  const int w = o->size[0], h = o->size[1];
  const long repeat = o->repeat;
  const char *prog = "overcast-bench";
  char why[1024], info[512];
  ocv_gl_context_t *ctx = ocv_gl_context_init(why, sizeof why);
  if (!ctx) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--gl: %s", why);
  ocv_gl_context_describe(ctx, info, sizeof info);
  ocv_gl_renderer_t *r = ocv_gl_renderer_create(why, sizeof why);
  ocv_gl_state_t gs;
  memset(&gs, 0, sizeof gs);
  int rc = OC_EXIT_OK;
  double tu = oct_now();
  if (!r || ocv_gl_state_upload(&gs, st, why, sizeof why) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--gl: %s", why);
    goto out;
  }
  tu = oct_now() - tu;
  oc_render_desc_t d = render_desc(sc, cam, o, atmo);
  oc_image_t img = {0}, other = {0};
  if (oc_image_alloc(&img, w, h) < 0 || oc_image_alloc(&other, w, h) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    goto out;
  }
  /* the full renderer, then each saving switched off alone (the octree map; the shader variant
   * without the features this frame does not use), alternated in one run so all see the same
   * machine load; every configuration renders the same image */
  /* the last row renders with a renderer of its own whose cloud shadow pass reruns every time: the sun
   * nudged by an ulp, alternately, so the state's volume counts (the other rows keep theirs) */
  static const struct {
    int map, variants, legacy, pass;
    const char *label;
  } cf[] = {{1, 1, 0, 0, "gl"},
            {0, 1, 0, 0, "gl, no octree map"},
            {1, 0, 0, 0, "gl, generic kernel (no variant)"},
            {1, 1, 1, 0, "gl, the octaves before the truth fit"},
            {1, 1, 0, 1, "gl, with its cloud shadow pass (a new sun every render)"}};
  enum { NCF = sizeof cf / sizeof cf[0] };
  double best[NCF] = {1e30, 1e30, 1e30, 1e30, 1e30};
  oc_render_desc_t dl = oct_render_legacy(d);
  ocv_gl_renderer_t *rp = ocv_gl_renderer_create(why, sizeof why);
  if (!rp) rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--gl: %s", why);
  const oc_dvec3 sun = gs.sun_dir;
  for (long i = 0; i <= repeat && rc == OC_EXIT_OK; i++) /* the first round compiles and uploads: not counted */
    for (int c = 0; c < NCF && rc == OC_EXIT_OK; c++) {
      ocv_gl_renderer_t *rr = cf[c].pass ? rp : r;
      ocv_gl_renderer_set_map(rr, cf[c].map);
      ocv_gl_renderer_set_variants(rr, cf[c].variants);
      gs.sun_dir = sun;
      if (cf[c].pass) gs.sun_dir.x = nextafter(sun.x, (i & 1) ? INFINITY : -INFINITY);
      double t0 = oct_now();
      if (ocv_gl_render_state(rr, &gs, cf[c].legacy ? &dl : &d, cf[c].legacy || cf[c].pass ? &other : &img, why, sizeof why) < 0)
        rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--gl: %s", why);
      double t = oct_now() - t0;
      if (i > 0 && t < best[c]) best[c] = t;
    }
  gs.sun_dir = sun;
  ocv_gl_renderer_free(rp);
  ocv_gl_renderer_set_map(r, 1);
  ocv_gl_renderer_set_variants(r, 1);
  if (rc == OC_EXIT_OK) {
    size_t n = (size_t)w * (size_t)h * 3;
    uint8_t *a = malloc(n), *b = malloc(n);
    double se = 0.0;
    if (a && b) {
      oc_image_tonemap(ref, 10.0f, a);
      oc_image_tonemap(&img, 10.0f, b);
      for (size_t i = 0; i < n; i++) se += ((double)a[i] - b[i]) * ((double)a[i] - b[i]);
    }
    printf("\n# GL compute renderer (%s), state upload %.3f s, octree map level %d (%d descent steps saved), %s\n\n",
           info, tu, gs.map_level, gs.map_level, atmo ? "atmosphere" : "no atmosphere");
    printf("| renderer | best of %ld (s) | M rays/s | vs 1 CPU thread | vs gl | RMSE vs CPU (0–255) |\n"
           "|---|---:|---:|---:|---:|---:|\n", repeat);
    for (int c = 0; c < NCF; c++) {
      printf("| %s | %.3f | %.3f | %.2f | %.3f | ", cf[c].label, best[c], (double)w * h / best[c] * 1e-6, cpu1 / best[c],
             best[c] / best[0]);
      if (c == 0) printf("%.3f |\n", sqrt(se / (double)n));
      else printf(cf[c].legacy ? "(the other model) |\n" : cf[c].pass ? "(the sun an ulp apart) |\n" : "(same image) |\n");
    }
    free(a);
    free(b);
  }
  oc_image_free(&img);
  oc_image_free(&other);
out:
  ocv_gl_state_free(&gs);
  ocv_gl_renderer_free(r);
  ocv_gl_context_free(ctx);
  return rc;
}
#endif

/* --gl: a flag that builds without GL refuse. */
static int opt_gl(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  (void)text;
#ifdef OC_HAVE_GL
  (void)prog;
  *(int *)oc_cli_field(o, base) = 1;
  return 0;
#else
  (void)base;
  return oc_cli_fail(prog, -1, "--%s: this build has no GL renderer", o->name);
#endif
}

static const oc_cli_opt_t render_opts[] = {
    {.name = "scene", .type = OC_CLI_STRING, .offset = offsetof(render_opts_t, scene), .arg = "FILE",
     .def = "scenes/analytic_sphere.json",
     .help = "scene; with procedural or vdb sources, the state the server core plans for a viewer at this camera "
             "(8 epochs, 64 MiB)"},
    OCT_OPT_CAMERA(render_opts_t),
    OCT_SIZE(render_opts_t, size, "size", "320x180", "image size"),
    OCT_LIST(render_opts_t, threads, "threads", 1, 256, "1,2", "comma-separated thread counts"),
    OCT_INT(render_opts_t, repeat, "repeat", "N", 1, 1000, "3", "renders per thread count; the fastest counts"),
    OCT_DBL(render_opts_t, step, "step-factor", "X", 1e-3, 1e3, "0.5", "step × voxel spacing"),
    OCT_OPT_TIME(render_opts_t),
    OCT_STR(render_opts_t, png, "png", "FILE", "also write the first thread count's image"),
    OCT_OPT_GROUND_MAP(render_opts_t),
    {.name = "gl", .type = OC_CLI_CUSTOM, .parse = opt_gl, .offset = offsetof(render_opts_t, gl),
     .help = "also time the GL compute renderer (headless EGL) on the same state and give its RMSE against the "
             "CPU image"},
    OCT_OPTS_END};

OCT_SPEC(render,
         "CPU reference renderer throughput per thread count.",
         render_opts);

/* The state to render: analytic scenes voxelized with exact τ; others as the server core plans
 * them for a viewer at this camera. */
static int render_state(const char *prog, const render_opts_t *o, const oc_scene_t *sc, oc_camera_pose_t pose,
                        oc_state_t *st) {
  char why[512];
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_medium_t medium;
  if (ocs_scene_medium(sc, &medium, NULL, 0) == 0) { /* analytic: exact τ */
    ocs_scene_voxelize_desc_t vd = {cam, o->size[1], 2.0, 16, 0, 2};
    if (ocs_scene_voxelize(st, sc, &vd, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s: %s", o->scene, why);
    return 0;
  }
  ocs_world_desc_t wd = {.threads = 2, .time = o->time};
  ocs_world_t *world = NULL;
  if (ocs_world_create(&world, sc, &wd, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s: %s", o->scene, why);
  ocs_plan_desc_t pd = {.budget = 64u << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES,
                        .max_depth = 21, .split_fraction = 0.5};
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, o->size[0], o->size[1]};
  int r = ocs_world_plan_offline(world, &pd, &view, 8, st, why, sizeof why);
  ocs_world_free(world);
  if (r < 0) return oc_cli_fail(prog, -1, "%s: %s", o->scene, why);
  return 0;
}

/* --png: the image tone-mapped, the camera in its text chunk. */
static int render_png(const char *prog, const char *path, oc_camera_pose_t pose, const oc_image_t *img) {
  char why[512], cam_text[256];
  uint8_t *rgb = malloc((size_t)img->w * (size_t)img->h * 3);
  if (!rgb) return oc_cli_fail(prog, -1, "out of memory");
  oc_camera_format(pose, cam_text, sizeof cam_text);
  oc_png_text_t text[1] = {{"overcast-camera", cam_text}};
  oc_image_tonemap(img, 10.0f, rgb);
  int r = oc_png_write(path, img->w, img->h, rgb, text, 1, why, sizeof why);
  free(rgb);
  if (r < 0) return oc_cli_fail(prog, -1, "%s", why);
  return 0;
}

int oct_bench_render(const char *prog, int argc, char **argv) {
  render_opts_t o = {0};
  static oc_scene_t sc;
  oc_camera_pose_t pose;
  int rc = oct_begin(&oct_bench_render_spec, argc, argv, &o, &o.scene, &o.camera, &sc, &pose);
  if (rc != OCT_GO) return rc;
  const int w = o.size[0], h = o.size[1];
  const long repeat = o.repeat;
  const double step = o.step;
  oc_camera_t cam = oc_camera_from_pose(pose);
  oc_state_t st;
  oc_state_init(&st);
  if (render_state(prog, &o, &sc, pose, &st)) return OC_EXIT_RUNTIME;
  double ta = oct_now();
  oc_atmo_t *atmo = NULL; /* none when the scene has no atmosphere */
  if (oc_scene_atmo(&sc, 2, &atmo) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
  ta = oct_now() - ta;

  printf("# CPU reference renderer: %s, %dx%d, step factor %g, state %u nodes / %u bricks, atmosphere tables %.3f s\n\n",
         o.scene, w, h, step, st.node_count, st.brick_count, ta);
  printf("| threads | best of %ld (s) | samples | M samples/s | M rays/s | speed-up | image |\n", repeat);
  printf("|---:|---:|---:|---:|---:|---:|---|\n");
  oc_image_t ref = {0}, img = {0};
  double base = 0.0;
  for (int i = 0; i < o.threads.n; i++) {
    long threads = o.threads.v[i];
    oc_render_desc_t d = render_desc(&sc, cam, &o, atmo);
    d.threads = (int)threads;
    if (oc_image_alloc(&img, w, h) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    double best = 1e30;
    oc_render_stats_t rs = {0};
    for (long r = 0; r < repeat; r++) {
      fprintf(stderr, "\r%s: render: %ld threads, run %ld/%ld ", prog, threads, r + 1, repeat);
      double t0 = oct_now();
      if (oc_render_state(&st, &d, &img, &rs) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed");
      double t = oct_now() - t0;
      if (t < best) best = t;
    }
    fprintf(stderr, "\r\033[K");
    const char *same = "reference";
    if (i == 0) {
      base = best;
      ref = img;
      img.px = NULL;
      if (o.png && render_png(prog, o.png, pose, &ref)) return OC_EXIT_RUNTIME;
    } else {
      same = memcmp(ref.px, img.px, sizeof(float) * 4 * (size_t)w * (size_t)h) == 0 ? "identical" : "DIFFERS";
      if (same[0] == 'D') rc = OC_EXIT_RUNTIME;
      oc_image_free(&img);
    }
    printf("| %ld | %.3f | %llu | %.2f | %.3f | %.2f | %s |\n", threads, best, (unsigned long long)rs.samples,
           rs.samples / best * 1e-6, (double)w * h / best * 1e-6, base / best, same);
  }
  if (rc == OCT_GO) rc = bench_models(prog, &st, render_desc(&sc, cam, &o, atmo), repeat);
#ifdef OC_HAVE_GL
  if (o.gl && rc == OC_EXIT_OK) rc = bench_gl(&st, &sc, cam, &o, atmo, &ref, base);
#endif
  oc_image_free(&ref);
  oc_atmo_free(atmo);
  oc_state_free(&st);
  oc_scene_free(&sc);
  if (rc) fprintf(stderr, "%s: images differ between thread counts\n", prog);
  return rc;
}
