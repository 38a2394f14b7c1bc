/* test_gl_render.c — the GL compute renderer (client/gl) against the CPU reference renderer.
 *
 * The same state is rendered by oc_render_state() and ocv_gl_render_state() and both images are
 * tone-mapped alike (oc_image_tonemap); the RMSE and the largest channel difference on the 0–255
 * scale are printed and bounded:
 *   1. constant_background: scenes/analytic_sphere.json voxelized locally, seen from its camera,
 *      no atmosphere and no planet (OC_BG_CONSTANT);
 *   2. atmosphere: the same state with atmosphere, planet and sun disc;
 *   3. camera_inside: the camera inside the sphere near its edge, looking out;
 *   4. low_sun: the sun 3° above the horizon (τ baked for it);
 *   5. jitter, space, ground, one metre from the cloud, the sphere's shadow in the air and on the
 *      ground (cloud_shadow): likewise;
 *   6. step_factor_sensitivity: the bound is tight — a 10 % change of the GLSL step factor breaks it;
 *   7. errors_name_file_and_line: a broken kernel's compile error names shaders/FILE:LINE.
 * Bounds (1–6): RMSE ≤ CMP_RMSE = 0.25 and no channel off by more than CMP_MAX = 8; measured on
 * llvmpipe (Mesa 22.3): RMSE 0.000–0.025, largest difference 1 — about 10× margin for rounding
 * differences between Mesa/LLVM versions, while a 10 % step-factor change gives ≥ 0.67 (test 6).
 * A test that passes on a black or uniform image proves nothing, so each image must also have a
 * spread of values. With $OC_TEST_OUT set, both renders are written there as PNGs.
 * Images are 160×90 (test 6: 96×54), LP_NUM_THREADS=2 (design.md, CI). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h> /* unlink, rmdir */

#include "oc_atmo.h"
#include "oc_camera.h"
#include "oc_err.h" /* OC_EINVAL */
#include "oc_image.h"
#include "oc_key.h"
#include "oc_planet.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "ocv_gl.h"

#define W 160
#define H 90
#define EXPOSURE 10.0f
#define CMP_RMSE 0.25 /* see the top of the file */
#define CMP_MAX 8

typedef struct {
  ocv_gl_context_t *ctx;
  ocv_gl_renderer_t *r;
  oc_atmo_t *atmo;
} fixture_t;

static fixture_t fx;

static int setup(void **state) {
  (void)state;
  char why[1024] = "";
  fx.ctx = ocv_gl_context_init(why, sizeof why);
  if (!fx.ctx) {
    printf("%s\n", why);
    return 0; /* each test skips or fails (OC_GL_REQUIRE=1) */
  }
  char info[512];
  ocv_gl_context_describe(fx.ctx, info, sizeof info);
  printf("GL: %s\n", info);
  fx.r = ocv_gl_renderer_create(why, sizeof why);
  if (!fx.r) printf("raymarch program: %s\n", why);
  ocg_atmosphere ap;
  oc_atmo_params_default(&ap);
  fx.atmo = oc_atmo_create(&ap, 2);
  return 0;
}

static int teardown(void **state) {
  (void)state;
  oc_atmo_free(fx.atmo);
  ocv_gl_renderer_free(fx.r);
  ocv_gl_context_free(fx.ctx);
  return 0;
}

static void require_gl(void) {
  if (fx.ctx) {
    assert_non_null(fx.r); /* the kernel must compile wherever a context exists */
    return;
  }
  const char *req = getenv("OC_GL_REQUIRE");
  if (req && req[0] == '1') fail_msg("OC_GL_REQUIRE=1 but no headless OpenGL 4.5 context");
  skip();
}

/* require_gl(), and the atmosphere tables the fixture made. */
static void require_atmo(void) {
  require_gl();
  assert_non_null(fx.atmo);
}

/* The analytic sphere scene, optionally with another camera pose or sun, voxelized for that view. */
static void make_scene(oc_scene_t *sc, oc_state_t *st, oc_camera_t *cam, const oc_scene_camera_t *pose_over,
                       const oc_dvec3 *sun_over) {
  char path[1024], why[512];
  const char *root = getenv("OC_SOURCE_DIR");
  snprintf(path, sizeof path, "%s/scenes/analytic_sphere.json", root && *root ? root : ".");
  assert_int_equal(oc_scene_load(sc, path, why, sizeof why), 0);
  if (pose_over) sc->camera = *pose_over;
  if (sun_over) sc->sun_dir = *sun_over;
  oc_camera_pose_t pose = {sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  *cam = oc_camera_from_pose(pose);
  oc_state_init(st);
  ocs_scene_voxelize_desc_t vd = {*cam, H, 2.0, 0, 0, 2};
  if (ocs_scene_voxelize(st, sc, &vd, why, sizeof why) < 0) fail_msg("voxelize: %s", why);
}

/* Mean and standard deviation of the 8-bit image (all channels). */
static void spread(const uint8_t *rgb, double *mean, double *sd) {
  double s = 0.0, s2 = 0.0;
  for (int i = 0; i < W * H * 3; i++) {
    s += rgb[i];
    s2 += (double)rgb[i] * rgb[i];
  }
  *mean = s / (W * H * 3);
  *sd = sqrt(fmax(s2 / (W * H * 3) - *mean * *mean, 0.0));
}

static void save_png(const char *name, const char *which, const uint8_t *rgb) {
  const char *dir = getenv("OC_TEST_OUT");
  if (!dir || !*dir) return;
  char path[1024], why[512];
  snprintf(path, sizeof path, "%s/gl_render_%s_%s.png", dir, name, which);
  if (oc_png_write(path, W, H, rgb, NULL, 0, why, sizeof why) < 0) printf("warning: %s\n", why);
}

/* Renders st both ways, prints and checks RMSE and max error, and that the image has content. */
static void compare(const char *name, const oc_state_t *st, const oc_render_desc_t *d, double max_rmse, int max_err) {
  oc_image_t cpu = {0}, gpu = {0};
  assert_int_equal(oc_image_alloc(&cpu, W, H), 0);
  assert_int_equal(oc_image_alloc(&gpu, W, H), 0);
  oc_render_stats_t stats;
  assert_int_equal(oc_render_state(st, d, &cpu, &stats), 0);
  assert_int_equal(stats.nonfinite, 0);

  char why[1024] = "";
  ocv_gl_state_t gs;
  int rc = ocv_gl_state_upload(&gs, st, why, sizeof why);
  if (rc) fail_msg("upload: %s", why);
  rc = ocv_gl_render_state(fx.r, &gs, d, &gpu, why, sizeof why);
  if (rc) fail_msg("render: %s", why);

  uint8_t *a = malloc(W * H * 3), *b = malloc(W * H * 3);
  assert_non_null(a);
  assert_non_null(b);
  assert_int_equal(oc_image_tonemap(&cpu, EXPOSURE, a), 0);
  assert_int_equal(oc_image_tonemap(&gpu, EXPOSURE, b), 0); /* no non-finite pixel */
  double rmse = oc_rgb8_rmse(a, b, W, H);
  int worst = 0, wi = 0;
  for (int i = 0; i < W * H * 3; i++) {
    int e = abs((int)a[i] - (int)b[i]);
    if (e > worst) {
      worst = e;
      wi = i;
    }
  }
  double lin = 0.0, peak = 0.0; /* linear radiance: largest difference relative to the image's peak */
  for (int i = 0; i < W * H * 4; i++)
    if (i % 4 != 3) peak = fmax(peak, fabs(cpu.px[i]));
  for (int i = 0; i < W * H * 4; i++)
    if (i % 4 != 3) lin = fmax(lin, fabs(cpu.px[i] - gpu.px[i]) / fmax(peak, 1e-30));
  double mean, sd, gmean, gsd;
  spread(a, &mean, &sd);
  spread(b, &gmean, &gsd);
  printf("%-20s %u leaves, %u bricks, %u inner, GPU %.2f MiB | RMSE %.3f, max %d at (%d, %d), linear %.1e of peak | CPU mean %.1f sd %.1f, "
         "GPU mean %.1f sd %.1f | %llu samples\n",
         name, st->node_count, st->brick_count, gs.inner_count, gs.resident_bytes / 1048576.0, rmse, worst, wi / 3 % W,
         wi / 3 / W, lin, mean, sd, gmean, gsd, (unsigned long long)stats.samples);
  save_png(name, "cpu", a);
  save_png(name, "gpu", b);

  /* The CPU image is neither black nor uniform, nor the GPU's. sd > 2, not 5: the multiple-scattering
   * model fitted to the truth lights the dense sphere that fills the view 1 m from its surface
   * nearly evenly (one_metre: sd 2.9 of 0–255 at mean 232). */
  assert_true(mean > 10.0 && sd > 2.0);
  assert_true(gmean > 10.0 && gsd > 2.0);
  assert_true(rmse <= max_rmse);
  assert_true(worst <= max_err);
  ocv_gl_state_free(&gs);
  free(a);
  free(b);
  oc_image_free(&cpu);
  oc_image_free(&gpu);
}

static oc_render_desc_t base_desc(const oc_scene_t *sc, oc_camera_t cam) {
  oc_render_desc_t d;
  memset(&d, 0, sizeof d);
  d.width = W;
  d.height = H;
  d.camera = cam;
  d.ms_octaves = sc->optics.ms_octaves;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)sc->optics.albedo;
  d.threads = 2;
  d.atmo = fx.atmo;
  return d;
}

/* The analytic sphere scene voxelized for its camera (make_scene()), freed by view_close(). */
typedef struct {
  oc_scene_t sc;
  oc_state_t st;
  oc_camera_t cam;
} view_t;

/* make_scene() into v, once require_gl() lets the test go on. @return the base description of a
 * render of it (base_desc()). */
static oc_render_desc_t view_open(view_t *v, const oc_scene_camera_t *pose_over, const oc_dvec3 *sun_over) {
  require_gl();
  make_scene(&v->sc, &v->st, &v->cam, pose_over, sun_over);
  return base_desc(&v->sc, v->cam);
}

/* The constant background of the comparisons without atmosphere (radiance 0.02). */
static void constant_background(oc_render_desc_t *d) {
  d->background = OC_BG_CONSTANT;
  d->background_radiance = 0.02f;
}

/* view_open() with the scene's camera and sun, before the constant background. */
static oc_render_desc_t constant_view(view_t *v) {
  oc_render_desc_t d = view_open(v, NULL, NULL);
  constant_background(&d);
  return d;
}

static void view_close(view_t *v) {
  oc_state_free(&v->st);
  oc_scene_free(&v->sc);
}

/* compare() of the scene seen with that camera and sun (NULL: the scene's), against the CPU. */
static void compare_view(const char *name, const oc_scene_camera_t *pose_over, const oc_dvec3 *sun_over) {
  view_t vw;
  oc_render_desc_t d = view_open(&vw, pose_over, sun_over);
  compare(name, &vw.st, &d, CMP_RMSE, CMP_MAX);
  view_close(&vw);
}

static void test_gl_render__constant_background(void **state) {
  (void)state;
  view_t vw;
  oc_render_desc_t d = constant_view(&vw);
  compare("constant_background", &vw.st, &d, CMP_RMSE, CMP_MAX);
  d.albedo = 0.9f; /* the occluded ambient's far side, marched past the chord's cap (τ 200 across) */
  compare("absorbing_under_uniform_sky", &vw.st, &d, CMP_RMSE, CMP_MAX);
  view_close(&vw);
}

/* The model before the truth fit matches the CPU as the fitted one does; optics outside their domain
 * are refused by name, never drawn as NaN. */
static void test_gl_render__cloud_model(void **state) {
  (void)state;
  view_t vw;
  oc_render_desc_t d = view_open(&vw, NULL, NULL);
  d.ms_model = OC_MS_MODEL_OCTAVES;
  d.ms_a = d.ms_b = d.ms_c = 0.5f;
  compare("octaves_before_fit", &vw.st, &d, CMP_RMSE, CMP_MAX);
  ocv_gl_state_t gs;
  char why[1024] = "";
  if (ocv_gl_state_upload(&gs, &vw.st, why, sizeof why)) fail_msg("upload: %s", why);
  oc_image_t img = {0};
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  oc_render_desc_t bad = base_desc(&vw.sc, vw.cam);
  bad.ms_b = NAN;
  assert_int_equal(ocv_gl_render_state(fx.r, &gs, &bad, &img, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "ms_b"));
  bad = base_desc(&vw.sc, vw.cam);
  bad.albedo = 1.5f;
  assert_int_equal(ocv_gl_render_state(fx.r, &gs, &bad, &img, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "albedo"));
  bad = base_desc(&vw.sc, vw.cam); /* drawn by the CPU reference only: refused, never silently left out */
  bad.air_sigma = 1e-5f;
  assert_int_equal(ocv_gl_render_state(fx.r, &gs, &bad, &img, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "air_sigma"));
  oc_image_free(&img);
  ocv_gl_state_free(&gs);
  view_close(&vw);
}

static void test_gl_render__atmosphere(void **state) {
  (void)state;
  require_atmo();
  compare_view("atmosphere", NULL, NULL);
}

static void test_gl_render__camera_inside(void **state) {
  (void)state;
  require_atmo();
  /* 1950 m east of the centre of the 2000 m sphere (lat 0, lon 0, alt 3 km), looking east and up. */
  oc_scene_camera_t pose = {{0.0, 1950.0 / (OC_PLANET_RADIUS + 3000.0) / OC_DEG, 3000.0}, 90.0, 10.0, 60.0};
  compare_view("camera_inside", &pose, NULL);
}

static void test_gl_render__low_sun(void **state) {
  (void)state;
  require_atmo();
  /* At (0°N, 0°E) up is +X, east +Y, north +Z: the sun 3° above the north-eastern horizon. */
  double el = 3.0 * OC_DEG;
  oc_dvec3 sun = oc_dnorm(oc_dv3(sin(el), cos(el) * sqrt(0.5), cos(el) * sqrt(0.5)));
  compare_view("low_sun", NULL, &sun);
}

/* The sphere's shadow in the air and on the ground, which lie in empty leaves (the cloud shadow volume,
 * shaders/shadow.h): the sun 20° up in the east, the camera 17 km west of the sphere looking east and
 * down at its shadow. The leaves without cloud are made empty, as the planner sends them (the local
 * voxelizer gives them τ). The shadow volume changes the CPU image here (RMSE > 1 against it switched
 * off), and the GPU's is the CPU's within the usual bounds. */
static void test_gl_render__cloud_shadow(void **state) {
  (void)state;
  require_atmo();
  double el = 20.0 * OC_DEG;
  oc_dvec3 sun = oc_dv3(sin(el), cos(el), 0.0);
  oc_scene_camera_t pose = {{0.0, -0.15, 3000.0}, 90.0, -12.0, 40.0};
  view_t vw;
  oc_render_desc_t d = view_open(&vw, &pose, &sun);
  for (uint32_t i = 0; i < vw.st.node_count; i++)
    if (!(vw.st.nodes[i].range[OC_CH_SIGMA].hi > 0.0f)) {
      memset(&vw.st.nodes[i].range, 0, sizeof vw.st.nodes[i].range);
      vw.st.nodes[i].kind = OC_NODE_EMPTY;
    }
  compare("cloud_shadow", &vw.st, &d, CMP_RMSE, CMP_MAX);
  oc_image_t on = {0}, off = {0};
  assert_int_equal(oc_image_alloc(&on, W, H), 0);
  assert_int_equal(oc_image_alloc(&off, W, H), 0);
  assert_int_equal(oc_render_state(&vw.st, &d, &on, NULL), 0);
  d.flags |= OC_RF_NO_CLOUD_SHADOW;
  assert_int_equal(oc_render_state(&vw.st, &d, &off, NULL), 0);
  uint8_t *a = malloc(W * H * 3), *b = malloc(W * H * 3);
  assert_non_null(a);
  assert_non_null(b);
  assert_int_equal(oc_image_tonemap(&on, EXPOSURE, a), 0);
  assert_int_equal(oc_image_tonemap(&off, EXPOSURE, b), 0);
  double rmse = oc_rgb8_rmse(a, b, W, H);
  printf("cloud_shadow: CPU with the shadow volume against without: RMSE %.2f\n", rmse);
  assert_true(rmse > 1.0);
  free(a);
  free(b);
  oc_image_free(&on);
  oc_image_free(&off);
  view_close(&vw);
}

/* The bound is tight: the GLSL image matches the CPU reference within STEP_BOUND at the same step
 * factor, and rendering the GLSL side with the step factor changed by 10 % (either way) breaks
 * that bound — so a kernel that stepped differently from oc__trace (another step length, another
 * sample position inside the segment, a segment dropped or doubled at node faces) would fail here.
 * The sphere (constant σt, τ from the sun) seen from the scene's camera, no jitter, the default
 * step factor 0.5 and a constant background: along a ray σt changes at the sphere's edge (a ramp
 * across one voxel of the trilinear reconstruction) and τ varies everywhere, so the segment
 * integral is not exact and the step length shows (measured on llvmpipe: 0.011 at the same step,
 * 1.03 at ×1.1 and 0.80 at ×0.9, 0–255 scale). A second view with atmosphere at step factor 1.0,
 * where air segments interleave with cloud segments (0.021; 1.08 and 0.67). 96×54 to stay cheap. */
#define STEP_W 96
#define STEP_H 54
#define STEP_BOUND CMP_RMSE /* the bound every view above is held to */

static void render_small(const oc_state_t *st, const oc_render_desc_t *d, int gl, uint8_t *rgb) {
  oc_image_t img = {0};
  assert_int_equal(oc_image_alloc(&img, d->width, d->height), 0);
  if (gl) {
    char why[1024] = "";
    ocv_gl_state_t gs;
    if (ocv_gl_state_upload(&gs, st, why, sizeof why)) fail_msg("upload: %s", why);
    if (ocv_gl_render_state(fx.r, &gs, d, &img, why, sizeof why)) fail_msg("render: %s", why);
    ocv_gl_state_free(&gs);
  } else {
    assert_int_equal(oc_render_state(st, d, &img, NULL), 0);
  }
  assert_int_equal(oc_image_tonemap(&img, EXPOSURE, rgb), 0);
  oc_image_free(&img);
}

static void test_gl_render__step_factor_sensitivity(void **state) {
  (void)state;
  require_atmo();
  static const struct {
    const char *name;
    int atmosphere;
    double step;
  } views[] = {{"constant_background", 0, 0.5}, {"atmosphere", 1, 1.0}};
  uint8_t *cpu = malloc(STEP_W * STEP_H * 3), *gpu = malloc(STEP_W * STEP_H * 3);
  assert_non_null(cpu);
  assert_non_null(gpu);
  for (int v = 0; v < 2; v++) {
    view_t vw;
    oc_render_desc_t d = view_open(&vw, NULL, NULL);
    d.width = STEP_W;
    d.height = STEP_H;
    if (!views[v].atmosphere) {
      constant_background(&d);
    }
    d.step_factor = views[v].step;
    render_small(&vw.st, &d, 0, cpu);
    render_small(&vw.st, &d, 1, gpu);
    double same = oc_rgb8_rmse(cpu, gpu, STEP_W, STEP_H);
    d.step_factor = views[v].step * 1.1;
    render_small(&vw.st, &d, 1, gpu);
    double longer = oc_rgb8_rmse(cpu, gpu, STEP_W, STEP_H);
    d.step_factor = views[v].step * 0.9;
    render_small(&vw.st, &d, 1, gpu);
    double shorter = oc_rgb8_rmse(cpu, gpu, STEP_W, STEP_H);
    printf("step factor %.1f, %-19s GLSL vs CPU RMSE %.3f (bound %.2f); GLSL at ×1.1 %.3f, at ×0.9 %.3f\n",
           views[v].step, views[v].name, same, STEP_BOUND, longer, shorter);
    assert_true(same <= STEP_BOUND);   /* the same step factor: within the bound */
    assert_true(longer > STEP_BOUND);  /* negative controls: a 10 % change breaks it */
    assert_true(shorter > STEP_BOUND);
    view_close(&vw);
  }
  free(cpu);
  free(gpu);
}

/* Extreme places: from space (1000 km up, the whole limb in view), from the ground (2 m up,
 * looking at the cloud from below), and 1 m from the cloud's surface. */
static void test_gl_render__space_and_ground(void **state) {
  (void)state;
  require_atmo();
  static const struct {
    const char *name;
    oc_scene_camera_t pose;
  } views[] = {
      {"space", {{0.0, -12.0, 1.0e6}, 90.0, -60.0, 60.0}},
      {"ground", {{0.0, -0.03, 2.0}, 90.0, 20.0, 60.0}},
      /* 1 m from the sphere's surface, 6 374 km from the planet's centre: no banding or jitter from
       * float positions (they are camera-relative integer cells) */
      {"one_metre", {{0.0, -2001.0 / (OC_PLANET_RADIUS + 3000.0) * 180.0 / 3.14159265358979323846, 3000.0}, 90.0, 0.0, 60.0}},
  };
  for (int i = 0; i < 3; i++) {
    compare_view(views[i].name, &views[i].pose, NULL);
  }
}

/* Per-pixel jitter of the ray start (shaders/sampling.h): the same hash of pixel and frame on both
 * sides, so jittered frames agree too, and two frames differ from each other. */
static void test_gl_render__jitter(void **state) {
  (void)state;
  view_t vw;
  oc_render_desc_t d = constant_view(&vw);
  d.flags = OC_RF_JITTER;
  d.frame = 7;
  compare("jitter", &vw.st, &d, CMP_RMSE, CMP_MAX);
  oc_image_t a = {0}, b = {0};
  assert_int_equal(oc_image_alloc(&a, W, H), 0);
  assert_int_equal(oc_image_alloc(&b, W, H), 0);
  assert_int_equal(oc_render_state(&vw.st, &d, &a, NULL), 0);
  d.frame = 8;
  assert_int_equal(oc_render_state(&vw.st, &d, &b, NULL), 0);
  assert_memory_not_equal(a.px, b.px, sizeof(float) * 4 * W * H);
  oc_image_free(&a);
  oc_image_free(&b);
  view_close(&vw);
}

/* Debug views: a pixel that differs from the normal image shows a LOD colour of a level present in
 * the state, a grey 0.3·exp(−τ) in [0, 0.3], or the edge colour; most cloudy pixels change in the LOD
 * and τ views, a few (the edges) in the bounds view. */
static void test_gl_render__debug_views(void **state) {
  (void)state;
  view_t vw;
  oc_render_desc_t d = constant_view(&vw);
  char why[512];
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, &vw.st, why, sizeof why), 0);
  oc_image_t normal = {0}, v = {0};
  assert_int_equal(oc_image_alloc(&normal, W, H), 0);
  assert_int_equal(oc_image_alloc(&v, W, H), 0);
  assert_int_equal(ocv_gl_render_state(fx.r, &gs, &d, &normal, why, sizeof why), 0);
  int levels[22] = {0};
  for (uint32_t i = 0; i < vw.st.node_count; i++)
    if (vw.st.nodes[i].range[0].hi > 0) levels[oc_key_level(vw.st.nodes[i].key)] = 1;
  for (int view = OC_DEBUG_LOD; view <= OC_DEBUG_BOUNDS; view++) {
    d.debug_view = view;
    assert_int_equal(ocv_gl_render_state(fx.r, &gs, &d, &v, why, sizeof why), 0);
    int cloud = 0, changed = 0, ok = 1;
    for (int i = 0; i < W * H; i++) {
      const float *a = &normal.px[4 * i], *b = &v.px[4 * i];
      int differs = memcmp(a, b, 4 * sizeof(float)) != 0;
      cloud += a[3] < 1.0f;
      changed += differs;
      if (view == OC_DEBUG_BOUNDS && differs && !(b[0] == 0.3f && b[1] == 0.15f && b[2] == 0.0f)) ok = 0;
      if (view == OC_DEBUG_TAU && differs && !(b[0] >= 0 && b[0] <= 0.3f && b[0] == b[1] && b[1] == b[2])) ok = 0;
      if (view == OC_DEBUG_LOD && differs) {
        int hit = 0;
        for (int l = 0; l <= 21; l++) {
          float h = (float)l / 21.0f, e = 2e-6f;
          float c[3] = {0.3f * fminf(fmaxf(2 * h - 0.5f, 0), 1), 0.3f * fminf(fmaxf(1 - fabsf(2 * h - 1), 0), 1),
                        0.3f * fminf(fmaxf(1.5f - 2 * h, 0), 1)};
          if (levels[l] && fabsf(b[0] - c[0]) < e && fabsf(b[1] - c[1]) < e && fabsf(b[2] - c[2]) < e) hit = 1;
        }
        if (!hit) ok = 0;
      }
    }
    printf("debug view %d: %d cloudy pixels, %d changed\n", view, cloud, changed);
    uint8_t rgb[W * H * 3];
    oc_image_tonemap(&v, EXPOSURE, rgb);
    save_png("debug", view == OC_DEBUG_LOD ? "lod" : view == OC_DEBUG_TAU ? "tau" : "bounds", rgb);
    assert_true(ok);
    assert_true(cloud > 100);
    if (view == OC_DEBUG_BOUNDS) assert_true(changed > 0 && changed < cloud / 2);
    else assert_true(changed > cloud / 2);
  }
  oc_image_free(&normal);
  oc_image_free(&v);
  ocv_gl_state_free(&gs);
  view_close(&vw);
}

/* A kernel error names the kernel file and line; a missing shader folder says where it looked. */
static void test_gl_render__errors_name_file_and_line(void **state) {
  (void)state;
  require_gl();
  char dir[] = "/tmp/oc_gl_render_XXXXXX", path[1200], src[1200], why[2048] = "";
  assert_non_null(mkdtemp(dir));
  static const char *const headers[] = {"oc_port.h", "sampling.h",   "optics.h", "brick.h",
                                        "shadow.h",  "atmosphere.h", "march.h"};
  for (int i = 0; i < 7; i++) { /* the real headers, then a broken kernel */
    snprintf(src, sizeof src, "%s/%s", ocv_gl_shader_dir(), headers[i]);
    snprintf(path, sizeof path, "%s/%s", dir, headers[i]);
    FILE *in = fopen(src, "rb"), *out = fopen(path, "wb");
    assert_non_null(in);
    assert_non_null(out);
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, in)) > 0) assert_int_equal(fwrite(buf, 1, n, out), n);
    fclose(in);
    fclose(out);
  }
  snprintf(path, sizeof path, "%s/raymarch.comp.glsl", dir);
  FILE *k = fopen(path, "wb");
  assert_non_null(k);
  fputs("layout(local_size_x = 1) in;\nvoid main() {\n  float x = undefined_name;\n}\n", k);
  fclose(k);
  const char *old = getenv("OC_SHADER_DIR");
  char *saved = old ? strdup(old) : NULL;
  setenv("OC_SHADER_DIR", dir, 1);
  ocv_gl_renderer_t *r = ocv_gl_renderer_create(why, sizeof why);
  assert_null(r);
  printf("broken kernel: %s", why);
  /* Mesa names the column ("…:3(12)"), NVIDIA does not ("…:3 : error"): the line is what must match. */
  const char *at = strstr(why, "shaders/raymarch.comp.glsl:3");
  assert_non_null(at);
  assert_true(at[strlen("shaders/raymarch.comp.glsl:3")] == '(' || at[strlen("shaders/raymarch.comp.glsl:3")] == ' ');
  setenv("OC_SHADER_DIR", "/nonexistent-oc-shaders", 1);
  assert_null(ocv_gl_renderer_create(why, sizeof why));
  printf("missing folder: %s\n", why);
  assert_non_null(strstr(why, "cannot read /nonexistent-oc-shaders/oc_port.h"));
  if (saved) setenv("OC_SHADER_DIR", saved, 1);
  else unsetenv("OC_SHADER_DIR");
  free(saved);
  for (int i = 0; i < 5; i++) {
    snprintf(path, sizeof path, "%s/%s", dir, headers[i]);
    unlink(path);
  }
  snprintf(path, sizeof path, "%s/raymarch.comp.glsl", dir);
  unlink(path);
  rmdir(dir);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_gl_render__constant_background),
      cmocka_unit_test(test_gl_render__atmosphere),
      cmocka_unit_test(test_gl_render__cloud_model),
      cmocka_unit_test(test_gl_render__camera_inside),
      cmocka_unit_test(test_gl_render__low_sun),
      cmocka_unit_test(test_gl_render__cloud_shadow),
      cmocka_unit_test(test_gl_render__jitter),
      cmocka_unit_test(test_gl_render__step_factor_sensitivity),
      cmocka_unit_test(test_gl_render__space_and_ground),
      cmocka_unit_test(test_gl_render__debug_views),
      cmocka_unit_test(test_gl_render__errors_name_file_and_line),
  };
  return cmocka_run_group_tests_name("gl_render", tests, setup, teardown);
}
