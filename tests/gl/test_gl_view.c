/* test_gl_view.c — the viewer's frame loop (client/gl/gl_view.c), headless: a state is shown only
 * once its bricks are uploaded (a bounded number per frame), the next one blends in over one epoch
 * period from the state shown before (t = 0: the previous image, t = 1: the new one exactly), the
 * resident bytes stay within the budget, reprojection runs through the same loop, and a state over
 * the budget is refused while the shown one stays; with a moving camera over a static field, through
 * epochs of splits and merges, the picture changes little from frame to frame (no popping); in the
 * window a new state keeps a young cloud shadow volume, a one-shot frame rebuilds it, and a rebuild is
 * spread over frames and ends as the one-shot build. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "interp.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54

static void make_state(oc_state_t *st, oc_camera_t cam, uint32_t id_base, uint64_t epoch) {
  sphere_state(st, cam, H, id_base);
  st->epoch = epoch;
}

static void render_direct(const oc_state_t *s, const oc_render_desc_t *d, oc_image_t *img) {
  char why[512];
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, s, why, sizeof why), 0);
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  assert_int_equal(ocv_gl_render_state(ren, &gs, d, img, why, sizeof why), 0);
  ocv_gl_state_free(&gs);
}

static void test_gl_view__epochs(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_camera_pose_t far = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}, near = {{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cf = oc_camera_from_pose(far);
  oc_state_t s1, s2;
  make_state(&s1, cf, 0, 1);
  make_state(&s2, oc_camera_from_pose(near), 1000000, 2);
  oc_render_desc_t d = const_bg_desc(cf, W, H);
  oc_image_t r1, r2, img = {0};
  render_direct(&s1, &d, &r1);
  render_direct(&s2, &d, &r2);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);

  /* a grant of room for both states' bricks and 8 more, records taken off (K = 3) */
  uint32_t nslots = s1.brick_count + s2.brick_count + 8;
  uint64_t budget = (uint64_t)nslots * (OC_SLOT_BYTES + OC_RECORD_BYTES);
  oc_budget_t g = {.budget = budget, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  ocv_gl_view_desc_t vd = {.grant = g, .animated = 1, .epoch_period = 1.0,
                           .upload_per_frame = 32 * OC_SLOT_BYTES};
  ocv_gl_view_t *v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  ocv_gl_view_stats_t st;
  assert_int_equal(ocv_gl_view_frame(v, &d, 0.0, 0, &img, &st, why, sizeof why), 0);
  assert_false(st.shown); /* nothing yet */

  /* epoch 1 arrives: shown after ceil(bricks / 32) frames, then exactly its image */
  assert_int_equal(ocv_gl_view_push(v, &s1, why, sizeof why), 0);
  int frames = 0;
  do {
    assert_int_equal(ocv_gl_view_frame(v, &d, 0.1 * frames, 0, &img, &st, why, sizeof why), 0);
    assert_true(st.uploaded_bytes <= 32 * OC_SLOT_BYTES);
    frames++;
  } while (!st.shown);
  assert_int_equal(frames, (int)((s1.brick_count + 31) / 32));
  assert_int_equal(st.epoch, 1);
  assert_memory_equal(img.px, r1.px, sizeof(float) * 4 * W * H);

  /* epoch 2 arrives at t = 10 s: it blends in from epoch 1 over one period */
  assert_int_equal(ocv_gl_view_push(v, &s2, why, sizeof why), 0);
  double now = 10.0;
  do {
    assert_int_equal(ocv_gl_view_frame(v, &d, now, 0, &img, &st, why, sizeof why), 0);
    assert_true(st.resident_bytes <= budget + (uint64_t)(s1.node_count + s2.node_count) * OC_RECORD_BYTES);
  } while (st.epoch != 2);
  assert_true(st.t == 0.0f);
  double at0 = rmse(&img, &r1), p12 = rmse(&r1, &r2);
  assert_int_equal(ocv_gl_view_frame(v, &d, now + 0.5, 0, &img, &st, why, sizeof why), 0);
  double half1 = rmse(&img, &r1), half2 = rmse(&img, &r2);
  assert_int_equal(ocv_gl_view_frame(v, &d, now + 1.0, 0, &img, &st, why, sizeof why), 0);
  assert_true(st.t == 1.0f);
  assert_memory_equal(img.px, r2.px, sizeof(float) * 4 * W * H);
  printf("view: epoch 1 shown after %d frames; epoch 2 at t=0 vs epoch 1 RMSE %.2f (epochs differ by %.2f), "
         "t=½ %.2f / %.2f\n", frames, at0, p12, half1, half2);
  assert_true(at0 < p12 / 3 && half1 < p12 && half2 < p12);

  /* reprojection through the loop: still camera, 16 frames → the full image */
  for (int f = 0; f < 16; f++) assert_int_equal(ocv_gl_view_frame(v, &d, now + 2.0 + f, 1, &img, &st, why, sizeof why), 0);
  assert_true(st.frame.reprojected > 0);
  assert_memory_equal(img.px, r2.px, sizeof(float) * 4 * W * H);

  /* over the budget: refused, the shown state stays */
  oc_state_t big;
  make_state(&big, oc_camera_from_pose((oc_camera_pose_t){{0.0, -0.03, 3000.0}, 90.0, 0.0, 40.0}), 2000000, 3);
  if (big.brick_count > nslots - s2.brick_count) {
    assert_int_equal(ocv_gl_view_push(v, &big, why, sizeof why), OC_ETOOBIG);
    assert_int_equal(ocv_gl_view_frame(v, &d, now + 30, 0, &img, &st, why, sizeof why), 0);
    assert_int_equal(st.epoch, 2);
  }
  oc_state_free(&big);
  ocv_gl_view_free(v);
  oc_image_free(&r1);
  oc_image_free(&r2);
  oc_image_free(&img);
  oc_state_free(&s1);
  oc_state_free(&s2);
}

/* ---- No popping: a moving camera over a static field ------------------------------------------------
 *
 * The camera flies north past the sphere (5.5 km west of its centre, lat −0.025° → +0.025°,
 * looking east) through PATH_E epochs of one period each; epoch k's state is planned for the camera
 * where it is when the state arrives (sphere_state: refined by distance), so the leaves ahead split
 * and those left behind merge. PATH_F frames per period, at times spread evenly over it, the camera
 * moving smoothly in between. The camera's own motion changes consecutive frames by far more than
 * any pop (RMSE ~12 here: the silhouette moves about 2 px per frame), so the frame-to-frame change of
 * the picture is measured with the camera held: at each frame time the view is rendered also from
 * the previous frame's camera, and the jump is the RMSE between that and the previous frame — the
 * change over one frame interval that is not camera motion. With interpolation (epoch_period 1 s,
 * static scene: splits and merges cross-fade) it must stay below SMOOTH_BOUND; with interpolation
 * off (epoch_period 0: each state snaps in when complete) the largest jump, at an epoch boundary,
 * must be at least SMOOTH_RATIO times the interpolated one — the negative control. Frames are
 * 64×36, rendered from states planned for 54 rows.
 *
 * Merges: a merged leaf's previous value is kept at its children's resolution (client/interp.h,
 * CHILDREN: 8 sub-bricks, stepped octant by octant while it blends), so the cross-fade starts from
 * the picture the children showed and the coarse content fades in over the period. (With the
 * previous value point-sampled on the merged leaf's own coarse lattice, as before, the children's
 * finer detail vanished at t = 0: boundary jumps of 0.9–3.5 at epochs that merge leaves, which needed
 * a looser bound of their own.) The boundary frames of merging epochs are still reported apart.
 * Measured on llvmpipe: boundaries with merges ≤ 1.38 (previously 3.53), split boundaries and
 * in-epoch jumps ≤ 1.49 (the largest now the first frame after a merge boundary: mixing σt linearly
 * from the children's field, which is empty where the coarse leaf smears density, changes the
 * picture fastest at small t), snapping 4.91. */
#define PATH_E 7
#define PATH_W 64 /* rendered smaller than planned for (H = 54): cheaper */
#define PATH_H 36
#define PATH_F 8
#define SMOOTH_BOUND 2.0 /* measured 1.51 (2.05 before the sun path's share, 2026-12-08; 1.49 before H(D)); snapping 4.88 */
#define SMOOTH_RATIO 2.5

static oc_camera_t path_camera(double now) { /* now in [0, PATH_E) s */
  double s = now / PATH_E;
  return oc_camera_from_pose((oc_camera_pose_t){{-0.025 + 0.05 * s, -0.05, 3000.0}, 90.0, 0.0, 40.0});
}

typedef struct {
  double max_smooth;   /**< largest held-camera jump outside merge boundaries (reported apart) */
  double max_merge;    /**< largest at the boundary of an epoch whose transition merged leaves */
  double max_all;      /**< largest of all */
  double max_raw;      /**< largest RMSE between consecutive frames as shown (camera motion included) */
  int at;              /**< frame of max_all */
} path_jumps_t;

static void fly(const oc_state_t *states, const int *merges, double period, path_jumps_t *out) {
  char why[512];
  uint32_t most = 0;
  for (int k = 0; k < PATH_E; k++) most = states[k].brick_count > most ? states[k].brick_count : most;
  oc_budget_t g = {.budget = (uint64_t)(3 * most + 8) * (OC_SLOT_BYTES + OC_RECORD_BYTES),
                   .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 2};
  ocv_gl_view_desc_t vd = {.grant = g, .animated = 0, .epoch_period = period};
  ocv_gl_view_t *v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  oc_render_desc_t d;
  memset(&d, 0, sizeof d);
  d.width = PATH_W;
  d.height = PATH_H;
  d.background = OC_BG_CONSTANT;
  d.background_radiance = 0.02f;
  d.flags = OC_RF_NO_AMBIENT; /* the sun alone, as when SMOOTH_BOUND was measured: the uniform sky
                                 lifts every cloud pixel alike and makes pops smaller in 0–255 */
  oc_image_t last = {0}, cur = {0}, held = {0};
  assert_int_equal(oc_image_alloc(&last, PATH_W, PATH_H), 0);
  assert_int_equal(oc_image_alloc(&cur, PATH_W, PATH_H), 0);
  assert_int_equal(oc_image_alloc(&held, PATH_W, PATH_H), 0);
  memset(out, 0, sizeof *out);
  oc_camera_t last_cam = path_camera(0.0);
  ocv_gl_view_stats_t st;
  for (int k = 0; k < PATH_E; k++) {
    assert_int_equal(ocv_gl_view_push(v, &states[k], why, sizeof why), 0); /* all uploaded at the next frame */
    for (int j = 0; j < PATH_F; j++) {
      double now = k + (double)j / PATH_F;
      /* the previous frame's camera, now (snapping changes nothing within an epoch: boundaries only) */
      int measure = k + j > 0 && (period > 0.0 || j == 0);
      if (measure) {
        d.camera = last_cam;
        assert_int_equal(ocv_gl_view_frame(v, &d, now, 0, &held, &st, why, sizeof why), 0);
      }
      d.camera = path_camera(now);
      assert_int_equal(ocv_gl_view_frame(v, &d, now, 0, &cur, &st, why, sizeof why), 0);
      assert_true(st.shown);
      assert_int_equal(st.epoch, (uint64_t)k + 1);
      if (k + j > 0) out->max_raw = fmax(out->max_raw, rmse(&cur, &last));
      if (measure) {
        double jump = rmse(&held, &last);
        if (j == 0 && merges[k]) out->max_merge = fmax(out->max_merge, jump);
        else out->max_smooth = fmax(out->max_smooth, jump);
        if (jump > out->max_all) {
          out->max_all = jump;
          out->at = k * PATH_F + j;
        }
      }
      last_cam = d.camera;
      oc_image_t tmp = last;
      last = cur;
      cur = tmp;
    }
  }
  oc_image_free(&last);
  oc_image_free(&cur);
  oc_image_free(&held);
  ocv_gl_view_free(v);
}

static void test_gl_view__no_popping(void **state) {
  (void)state;
  require_gl();
  oc_state_t states[PATH_E];
  int merges[PATH_E] = {0};
  uint32_t split_leaves = 0, merged_leaves = 0;
  for (int k = 0; k < PATH_E; k++) {
    make_state(&states[k], path_camera(k), 1000000u * (uint32_t)k, (uint64_t)k + 1);
    if (k == 0) continue;
    ocv_interp_t ip;
    ocv_interp_init(&ip);
    assert_int_equal(ocv_interp_build(&ip, &states[k - 1], &states[k]), 0);
    ocv_interp_stats_t is;
    ocv_interp_stats(&ip, &is);
    split_leaves += is.count[OCV_INTERP_PARENT];
    merged_leaves += is.count[OCV_INTERP_CHILDREN];
    merges[k] = is.count[OCV_INTERP_CHILDREN] > 0;
    ocv_interp_free(&ip);
  }
  path_jumps_t lerp, snap;
  fly(states, merges, 1.0, &lerp);
  fly(states, merges, 0.0, &snap);
  printf("no popping: %d epochs, %d frames each; %u leaves from splits, %u merged leaves | held-camera jump, "
         "interpolated: max %.3f (frame %d; merge boundaries %.3f, elsewhere %.3f), snapping: max %.3f (frame %d) | "
         "as shown (camera motion included): %.2f / %.2f\n",
         PATH_E, PATH_F, split_leaves, merged_leaves, lerp.max_all, lerp.at, lerp.max_merge, lerp.max_smooth,
         snap.max_all, snap.at, lerp.max_raw, snap.max_raw);
  assert_true(split_leaves >= 100 && merged_leaves >= 10); /* many splits (8 leaves each) and merges */
  assert_true(lerp.max_all <= SMOOTH_BOUND);                /* merge boundaries included */
  assert_true(snap.max_all >= SMOOTH_RATIO * lerp.max_all); /* the control: snapping pops */
  assert_true(snap.max_all >= 2.0 * SMOOTH_BOUND);          /* and the bound itself tells them apart */
  for (int k = 0; k < PATH_E; k++) oc_state_free(&states[k]);
}

/* The camera of the shadow tests, and a view from it over a planet without an atmosphere (a shadow
 * volume, no tables). */
static const oc_camera_pose_t SHADOW_POSE = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0};
static oc_render_desc_t planet_desc(oc_camera_t cam) {
  oc_render_desc_t d = const_bg_desc(cam, W, H);
  d.background = OC_BG_DEFAULT;
  d.flags |= OC_RF_NO_ATMOSPHERE;
  d.shadow_cells = 16;
  d.shadow_levels = 4;
  d.shadow_ground_cells = 32;
  return d;
}

/* Shadow passes the view runs for three states arriving at times at[] (s), each shown before the next:
 * with a frame-time target (window) or without (one-shot), the camera held, over a planet; *most: the
 * most texels the passes wrote in one frame after the first state's. */
static uint64_t shadow_passes(double frame_ms, const double at[3], uint64_t *most) {
  char why[512];
  oc_camera_t cam = oc_camera_from_pose(SHADOW_POSE);
  oc_state_t s[3];
  uint32_t bricks = 0;
  for (int k = 0; k < 3; k++) {
    make_state(&s[k], cam, 1000000u * (uint32_t)k, (uint64_t)k + 1);
    bricks += s[k].brick_count;
  }
  oc_render_desc_t d = planet_desc(cam);
  uint64_t budget = (uint64_t)(bricks + 8) * (OC_SLOT_BYTES + OC_RECORD_BYTES);
  oc_budget_t g = {.budget = budget, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  ocv_gl_view_desc_t vd = {.grant = g, .animated = 1, .epoch_period = 1.0, .frame_ms = frame_ms,
                           .upload_per_frame = (uint64_t)(bricks + 8) * OC_SLOT_BYTES};
  ocv_gl_renderer_t *r = ocv_gl_renderer_create(why, sizeof why); /* no volume yet */
  ocv_gl_view_t *v = r ? ocv_gl_view_create(r, &vd, why, sizeof why) : NULL;
  if (!v) fail_msg("%s", why);
  const double base = 1000.0;
  ocv_gl_view_stats_t st;
  *most = 0;
  for (int k = 0; k < 3; k++) {
    assert_int_equal(ocv_gl_view_push(v, &s[k], why, sizeof why), 0);
    for (int frames = 0; frames < 100; frames++) {
      uint64_t t0 = ocv_gl_renderer_shadow_texels(r);
      int shown = st.epoch == (uint64_t)k + 1; /* then one more frame: blended in */
      double now = base + at[k] + (shown ? 0.5 : 0.01 * frames);
      if (ocv_gl_view_frame(v, &d, now, 0, NULL, &st, why, sizeof why)) fail_msg("%s", why);
      uint64_t dt = ocv_gl_renderer_shadow_texels(r) - t0;
      if (k > 0 && dt > *most) *most = dt;
      if (shown) break;
      assert_true(frames < 98);
    }
  }
  uint64_t n = ocv_gl_renderer_shadow_passes(r);
  ocv_gl_view_free(v);
  ocv_gl_renderer_free(r);
  for (int k = 0; k < 3; k++) oc_state_free(&s[k]);
  return n;
}

/* In the window (a frame-time target) a new state keeps a shadow volume younger than
 * OCV_GL_SHADOW_MAX_AGE_S: one pass for three states a second apart, a second pass once the volume is
 * older, spread over frames (a frame writes at most an eighth of its texels and a row of work groups);
 * without a target (one-shot) every new state reruns it whole. The made-up times need no clock. */
static void test_gl_view__shadow_age(void **state) {
  (void)state;
  require_gl();
  const double close[3] = {0.0, 1.0, 2.0}, late[3] = {0.0, 1.0, 1.0 + OCV_GL_SHADOW_MAX_AGE_S};
  uint64_t most_w, most_a, most_o;
  uint64_t window = shadow_passes(100.0, close, &most_w), aged = shadow_passes(100.0, late, &most_a);
  uint64_t oneshot = shadow_passes(0.0, close, &most_o);
  printf("shadow age: passes for 3 states, window %llu (the third after %.0f s: %llu), one-shot %llu; most texels "
         "written in one frame after the first state's: window %llu, aged %llu, one-shot %llu (a whole volume)\n",
         (unsigned long long)window, OCV_GL_SHADOW_MAX_AGE_S, (unsigned long long)aged, (unsigned long long)oneshot,
         (unsigned long long)most_w, (unsigned long long)most_a, (unsigned long long)most_o);
  assert_int_equal(window, 1);
  assert_int_equal(aged, 2);
  assert_int_equal(oneshot, 3);
  assert_true(most_w == 0 && most_a > 0);
  assert_true(most_a * OCV_GL_SHADOW_SLICES <= most_o + most_o / 8); /* the slices are even to a group row */
}

/* The shadow volume of a render: its texels (*n of them), malloc'd. */
static float *shadow_texels(const ocv_gl_renderer_t *r, size_t *n) {
  *n = ocv_gl_renderer_shadow_read(r, NULL, 0);
  assert_true(*n > 0);
  float *v = malloc(*n * sizeof *v);
  assert_non_null(v);
  assert_int_equal(ocv_gl_renderer_shadow_read(r, v, *n), *n);
  return v;
}

/* The window's settings (ocv_gl_view_frame's with a frame-time target) at time now, or the one-shot's. */
static void window_mode(ocv_gl_renderer_t *r, int on, double now) {
  ocv_gl_renderer_set_shadow_age(r, on ? OCV_GL_SHADOW_MAX_AGE_S : 0.0, now);
  ocv_gl_renderer_set_shadow_slices(r, on ? OCV_GL_SHADOW_SLICES : 1);
}

/* In the window a rebuilt shadow volume is built over OCV_GL_SHADOW_SLICES frames, a slice per frame,
 * while the old one is read; from the frame of its last slice on it is read, and it equals the one-shot
 * build of the same state and camera texel for texel: a one-shot render then gives the same image. */
static void test_gl_view__shadow_slices(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_camera_t cam = oc_camera_from_pose(SHADOW_POSE);
  oc_state_t s1, s2; /* the second with other leaves and the sun turned: another volume */
  make_state(&s1, cam, 0, 1);
  make_state(&s2, oc_camera_from_pose((oc_camera_pose_t){{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0}), 1000000, 2);
  oc_dvec3 sun = s2.sun_dir;
  s2.sun_dir = oc_dnorm((oc_dvec3){sun.x + 0.2, sun.y - 0.2, sun.z});
  ocv_gl_state_t g1, g2;
  assert_int_equal(ocv_gl_state_upload(&g1, &s1, why, sizeof why), 0);
  assert_int_equal(ocv_gl_state_upload(&g2, &s2, why, sizeof why), 0);
  oc_render_desc_t d = planet_desc(cam);
  oc_image_t ref, img, old;
  assert_int_equal(oc_image_alloc(&ref, W, H), 0);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  assert_int_equal(oc_image_alloc(&old, W, H), 0);

  /* the one-shot references: a renderer of its own builds each volume whole; the window's its own too */
  ocv_gl_renderer_t *one = ocv_gl_renderer_create(why, sizeof why), *win = ocv_gl_renderer_create(why, sizeof why);
  if (!one || !win) fail_msg("%s", why);
  size_t n, n2;
  assert_int_equal(ocv_gl_render_state(one, &g1, &d, NULL, why, sizeof why), 0);
  float *v1 = shadow_texels(one, &n);
  assert_int_equal(ocv_gl_render_state(one, &g2, &d, &ref, why, sizeof why), 0);
  float *v2 = shadow_texels(one, &n2), *got = malloc(n * sizeof *got);
  assert_true(n2 == n && got && memcmp(v1, v2, n * sizeof *v1) != 0);

  /* the window: the first volume whole (none before), the next one, 10 s later, in slices */
  const double base = 100.0;
  window_mode(win, 1, base);
  assert_int_equal(ocv_gl_render_state(win, &g1, &d, NULL, why, sizeof why), 0);
  int frames = 0, sliced = 0;
  uint64_t most = 0, sum = 0;
  for (;; frames++) {
    assert_true(frames < 4 * OCV_GL_SHADOW_SLICES);
    window_mode(win, 1, base + 10.0 + 0.1 * frames);
    uint64_t t0 = ocv_gl_renderer_shadow_texels(win);
    assert_int_equal(ocv_gl_render_state(win, &g2, &d, &img, why, sizeof why), 0);
    uint64_t dt = ocv_gl_renderer_shadow_texels(win) - t0;
    sliced += dt > 0;
    sum += dt;
    most = dt > most ? dt : most;
    assert_int_equal(ocv_gl_renderer_shadow_read(win, got, n), n);
    if (!memcmp(got, v2, n * sizeof *got)) break;
    assert_memory_equal(got, v1, n * sizeof *got); /* the old volume until the last slice */
    memcpy(old.px, img.px, sizeof(float) * 4 * W * H);
  }
  /* the one-shot render keeps the complete volume (same state and camera) and equals the reference */
  window_mode(win, 0, base + 20.0);
  uint64_t t0 = ocv_gl_renderer_shadow_texels(win);
  assert_int_equal(ocv_gl_render_state(win, &g2, &d, &img, why, sizeof why), 0);
  double before = rmse(&old, &ref);
  printf("shadow slices: a %zu-texel volume rebuilt in %d frames (%d with a slice), at most %llu texels (1/%.1f) a "
         "frame, %llu in all; the frame before its last slice vs the one-shot image RMSE %.3f, after 0\n", n,
         frames + 1, sliced, (unsigned long long)most, (double)n / (double)most, (unsigned long long)sum, before);
  assert_int_equal(ocv_gl_renderer_shadow_texels(win), t0);
  assert_memory_equal(img.px, ref.px, sizeof(float) * 4 * W * H);
  assert_int_equal(frames + 1, OCV_GL_SHADOW_SLICES);
  assert_int_equal(sliced, OCV_GL_SHADOW_SLICES);
  assert_true(sum == n && most * OCV_GL_SHADOW_SLICES <= n + n / 8);
  assert_true(before > 0.0); /* the old volume's shadows show */
  free(v1);
  free(v2);
  free(got);
  ocv_gl_renderer_free(one);
  ocv_gl_renderer_free(win);
  oc_image_free(&ref);
  oc_image_free(&img);
  oc_image_free(&old);
  ocv_gl_state_free(&g1);
  ocv_gl_state_free(&g2);
  oc_state_free(&s1);
  oc_state_free(&s2);
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_view__epochs),
             cmocka_unit_test(test_gl_view__shadow_age),
             cmocka_unit_test(test_gl_view__shadow_slices),
             cmocka_unit_test(test_gl_view__no_popping))
