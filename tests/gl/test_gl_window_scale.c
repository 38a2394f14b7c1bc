/* test_gl_window_scale.c — what keeps overcast-view's window alive without a GPU (client/gl/gl_view.c,
 * gl_present.c), headless and without timing anything: the frame times the controller sees are
 * made up (ocv_gl_view_frame_time), so no check depends on the machine's speed.
 *   - the frame-time target: the first frame is traced at the coarsest scale, fast frames refine it,
 *     slow ones coarsen it, and between the two thresholds it holds (no flicker); frames that
 *     switched state or showed nothing are not counted; without a target every frame is full size;
 *   - the picture: a frame traced at half size, upsampled by the present pass, equals the CPU's
 *     bilinear upsampling of the same radiance tone-mapped (to one 8-bit step), and is close to the
 *     full-size picture; at the picture's own size the pass is the plain tone mapping;
 *   - uploads with a target go on while time is left (a state arriving is shown in that frame) and
 *     stop after one step when none is;
 *   - a new state blended in under reprojection continues the picture in its first frame (no 4×4
 *     blocks), and 16 frames later is exactly the new state's picture;
 *   - the HUD names the traced size. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "hud.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_render.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, const_bg_desc, max_step, rmse */

#define W 256
#define H 144 /* the coarsest scale keeping ≥ 32 rows: 1/4 (36 rows) */

static const oc_camera_pose_t pose = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0};

/* A view of the sphere state with a frame-time target (ms) and the given upload step; frames run
 * until the state is shown. */
static ocv_gl_view_t *view_with(const oc_state_t *s, double frame_ms, uint64_t upload, int *frames) {
  char why[512];
  uint32_t nslots = s->brick_count + 8;
  oc_budget_t g = {.budget = (uint64_t)nslots * (OC_SLOT_BYTES + OC_RECORD_BYTES), .slot_bytes = OC_SLOT_BYTES,
                   .record_bytes = OC_RECORD_BYTES, .kept_states = 2};
  ocv_gl_view_desc_t vd = {.grant = g, .frame_ms = frame_ms, .upload_per_frame = upload};
  ocv_gl_view_t *v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  assert_int_equal(ocv_gl_view_push(v, s, why, sizeof why), 0);
  oc_render_desc_t d = const_bg_desc(oc_camera_from_pose(pose), W, H);
  ocv_gl_view_stats_t st;
  *frames = 0;
  do {
    assert_int_equal(ocv_gl_view_frame(v, &d, 0.0, 0, NULL, &st, why, sizeof why), 0);
    (*frames)++;
  } while (!st.shown && *frames < 100000);
  assert_true(st.switched);
  return v;
}

/* One frame at W×H after the controller was told the last one took `ms`; its scale. */
static int frame_after(ocv_gl_view_t *v, double ms, ocv_gl_view_stats_t *st) {
  char why[512];
  ocv_gl_view_frame_time(v, ms);
  oc_render_desc_t d = const_bg_desc(oc_camera_from_pose(pose), W, H);
  assert_int_equal(ocv_gl_view_frame(v, &d, 1.0, 1, NULL, st, why, sizeof why), 0);
  assert_true(st->shown);
  int tw, th;
  ocv_gl_view_trace_size(W, H, st->scale, &tw, &th);
  assert_int_equal(st->trace_w, tw);
  assert_int_equal(st->trace_h, th);
  return st->scale;
}

static void test_gl_window_scale__controller(void **state) {
  (void)state;
  require_gl();
  oc_state_t s;
  sphere_state(&s, oc_camera_from_pose(pose), H, 0);
  int frames;
  ocv_gl_view_t *v = view_with(&s, 100.0, 0, &frames);
  ocv_gl_view_stats_t st;
  /* the switch frame is not counted: a slow report now changes nothing */
  assert_int_equal(ocv_gl_view_scale(v, H), 4);
  assert_int_equal(frame_after(v, 5000.0, &st), 4);
  assert_int_equal(st.trace_w, 64);
  assert_int_equal(st.trace_h, 36);
  /* fast frames (1 ms): after three in a row, as fine as fits (1 ms × 16 ≤ 60 % of 100 ms) */
  assert_int_equal(frame_after(v, 1.0, &st), 4);
  assert_int_equal(frame_after(v, 1.0, &st), 4);
  assert_int_equal(frame_after(v, 1.0, &st), 1);
  assert_int_equal(st.trace_w, W);
  /* one slow frame (250 ms) is a hiccup; two in a row coarsen as far as brings it under 70 ms */
  assert_int_equal(frame_after(v, 250.0, &st), 1);
  assert_int_equal(frame_after(v, 250.0, &st), 2);
  assert_int_equal(st.trace_w, 128);
  /* between the thresholds it holds: 20 ms would be 80 ms at full size, over 60 % of the target */
  for (int i = 0; i < 10; i++) assert_int_equal(frame_after(v, 20.0 * 4.0, &st), 2);
  for (int i = 0; i < 10; i++) assert_int_equal(frame_after(v, 120.0, &st), 2); /* ≤ 1.25 × 100 */
  /* a very slow frame (> 3× the target) coarsens at once, never past the coarsest allowed (1/4) */
  assert_int_equal(frame_after(v, 10000.0, &st), 4);
  assert_int_equal(frame_after(v, 10000.0, &st), 4);
  assert_int_equal(ocv_gl_view_scale(v, 1080), 4); /* (1/8 allowed at 1080 rows, not reached yet) */
  ocv_gl_view_free(v);

  /* a tall view starts at 1/8 (the first frame of 1280×720 on llvmpipe: 160×90) */
  ocv_gl_view_desc_t vd = {.grant = {.budget = 64u << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES,
                                     .kept_states = 2},
                           .frame_ms = 100.0};
  char why[512];
  v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  assert_int_equal(ocv_gl_view_scale(v, 720), 8);
  assert_int_equal(ocv_gl_view_scale(v, 90), 2); /* 45 rows: 1/4 would leave 22 */
  int tw, th;
  ocv_gl_view_trace_size(1280, 720, 8, &tw, &th);
  assert_true(tw == 160 && th == 90);
  ocv_gl_view_free(v);
  /* a bad target is refused, naming it */
  vd.frame_ms = -1.0;
  assert_null(ocv_gl_view_create(ren, &vd, why, sizeof why));
  assert_non_null(strstr(why, "frame-time target"));

  /* no target (headless PNGs): every frame at full size, whatever is reported */
  v = view_with(&s, 0.0, 0, &frames);
  assert_int_equal(ocv_gl_view_scale(v, H), 1);
  for (int i = 0; i < 4; i++) assert_int_equal(frame_after(v, 1e6, &st), 1);
  assert_int_equal(st.trace_w, W);
  ocv_gl_view_free(v);
  oc_state_free(&s);
}

/* CPU bilinear upsampling of a rw×rh image to w×h, texel centres aligned, edges clamped. */
static void upsample_cpu(const oc_image_t *src, oc_image_t *dst) {
  for (int y = 0; y < dst->h; y++)
    for (int x = 0; x < dst->w; x++) {
      float u = ((float)x + 0.5f) * (float)src->w / (float)dst->w - 0.5f;
      float t = ((float)y + 0.5f) * (float)src->h / (float)dst->h - 0.5f;
      int x0 = (int)floorf(u), y0 = (int)floorf(t);
      float fx = u - (float)x0, fy = t - (float)y0;
      for (int c = 0; c < 4; c++) {
        float q[4];
        for (int k = 0; k < 4; k++) {
          int xx = x0 + (k & 1), yy = y0 + (k >> 1);
          xx = xx < 0 ? 0 : xx >= src->w ? src->w - 1 : xx;
          yy = yy < 0 ? 0 : yy >= src->h ? src->h - 1 : yy;
          q[k] = src->px[((size_t)yy * (size_t)src->w + (size_t)xx) * 4 + (size_t)c];
        }
        float a = q[0] + (q[1] - q[0]) * fx, b = q[2] + (q[3] - q[2]) * fx;
        dst->px[((size_t)y * (size_t)dst->w + (size_t)x) * 4 + (size_t)c] = a + (b - a) * fy;
      }
    }
}

static void test_gl_window_scale__upsampled_picture(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_state_t s;
  sphere_state(&s, oc_camera_from_pose(pose), H, 0);
  int frames;
  ocv_gl_view_t *v = view_with(&s, 100.0, 0, &frames);
  ocv_gl_view_stats_t st;
  for (int i = 0; i < 4; i++) frame_after(v, 1.0, &st); /* to full size (the first report, after the switch, is not counted) */
  assert_int_equal(frame_after(v, 250.0, &st), 1);
  frame_after(v, 250.0, &st); /* → 1/2 */
  assert_int_equal(ocv_gl_view_scale(v, H), 2);
  oc_render_desc_t d = const_bg_desc(oc_camera_from_pose(pose), W, H);
  oc_image_t half = {0}, up = {0}, full = {0}, wrong = {0};
  assert_int_equal(oc_image_alloc(&half, W / 2, H / 2), 0);
  assert_int_equal(oc_image_alloc(&up, W, H), 0);
  assert_int_equal(oc_image_alloc(&full, W, H), 0);
  /* an image of the picture's size while the frame is traced at half: refused, saying both */
  assert_int_equal(oc_image_alloc(&wrong, W, H), 0);
  assert_int_equal(ocv_gl_view_frame(v, &d, 2.0, 0, &wrong, &st, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "128x72"));
  assert_int_equal(ocv_gl_view_frame(v, &d, 2.0, 0, &half, &st, why, sizeof why), 0);
  assert_int_equal(st.trace_w, W / 2);

  ocv_gl_present_t *p = ocv_gl_present_create(why, sizeof why);
  if (!p) fail_msg("%s", why);
  size_t n = (size_t)W * H * 3;
  uint8_t *gpu = malloc(n), *cpu = malloc(n), *ref = malloc(n);
  assert_true(gpu && cpu && ref);
  assert_true(ocv_gl_present_upsample(p, ocv_gl_view_output(v), W / 2, H / 2, W, H, 10.0f, NULL, 0, 0, why, sizeof why));
  assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
  upsample_cpu(&half, &up);
  assert_int_equal(oc_image_tonemap(&up, 10.0f, cpu), 0);
  int steps = max_step(gpu, cpu, n);
  /* the same view at full size, rendered directly */
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, &s, why, sizeof why), 0);
  assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &full, why, sizeof why), 0);
  assert_int_equal(oc_image_tonemap(&full, 10.0f, ref), 0);
  double e_full = oc_rgb8_rmse(gpu, ref, W, H);
  /* a picture one traced pixel off would be further from it than the upsampled one is */
  double e_shift = oc_rgb8_rmse(gpu + 3 * 2, ref, W, H - 1); /* 2 picture pixels to the left */
  printf("half size upsampled: GPU vs CPU bilinear at most %d steps; vs the full-size picture RMSE %.2f "
         "(shifted by 2 px: %.2f)\n", steps, e_full, e_shift);
  assert_true(steps <= 1);
  assert_true(e_full < 6.0 && e_full < e_shift);

  /* at the picture's own size the pass is the plain tone mapping, exactly */
  assert_true(ocv_gl_present_upsample(p, ocv_gl_renderer_output(ren), W, H, W, H, 10.0f, NULL, 0, 0, why, sizeof why));
  assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
  assert_true(max_step(gpu, ref, n) <= 1);
  /* a source larger than the picture is refused */
  assert_int_equal(ocv_gl_present_upsample(p, ocv_gl_renderer_output(ren), W, H, W / 2, H / 2, 10.0f, NULL, 0, 0, why,
                                           sizeof why), 0u);
  assert_non_null(strstr(why, "radiance buffer of"));

  ocv_gl_state_free(&gs);
  ocv_gl_present_free(p);
  free(gpu);
  free(cpu);
  free(ref);
  oc_image_free(&half);
  oc_image_free(&up);
  oc_image_free(&full);
  oc_image_free(&wrong);
  ocv_gl_view_free(v);
  oc_state_free(&s);
}

static void test_gl_window_scale__uploads(void **state) {
  (void)state;
  require_gl();
  oc_state_t s;
  sphere_state(&s, oc_camera_from_pose(pose), H, 0);
  assert_true(s.brick_count > 4);
  /* time enough (a 10⁶ ms target): the state arriving is uploaded and shown in the same frame */
  int frames;
  ocv_gl_view_t *v = view_with(&s, 1e6, 16 * OC_SLOT_BYTES, &frames);
  assert_int_equal(frames, 1);
  ocv_gl_view_free(v);
  /* no time at all (10⁻⁶ ms): one step of a sixteenth of upload_per_frame (one brick) a frame */
  v = view_with(&s, 1e-6, 16 * OC_SLOT_BYTES, &frames);
  printf("uploads: %u bricks in 1 frame with time, %d frames without\n", s.brick_count, frames);
  assert_int_equal(frames, (int)s.brick_count);
  ocv_gl_view_free(v);
  oc_state_free(&s);
}

/* Reprojected frames of the view at times t0, t0 + dt, ... until epoch `epoch` is shown, then `more`
 * frames; the last into img. */
static void reprojected(ocv_gl_view_t *v, const oc_render_desc_t *d, double t0, double dt, uint64_t epoch, int more,
                        oc_image_t *img) {
  char why[512];
  ocv_gl_view_stats_t st;
  int n = 0;
  do assert_int_equal(ocv_gl_view_frame(v, d, t0 + dt * n++, 1, img, &st, why, sizeof why), 0);
  while (st.epoch != epoch);
  for (int f = 0; f < more; f++) assert_int_equal(ocv_gl_view_frame(v, d, t0 + dt * n++, 1, img, &st, why, sizeof why), 0);
}

/* A new state blended in under reprojection: its first frame continues the picture (the history,
 * clamped to what is traced now), where it was 4×4 blocks filled from one traced pixel each. */
static void test_gl_window_scale__new_state_continues(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_camera_pose_t near = {{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0};
  oc_state_t s1, s2;
  sphere_state(&s1, oc_camera_from_pose(pose), H, 0);
  sphere_state(&s2, oc_camera_from_pose(near), H, 1000000);
  s1.epoch = 1;
  s2.epoch = 2;
  oc_render_desc_t d = const_bg_desc(oc_camera_from_pose(pose), W, H);
  oc_image_t r1 = {0}, r2 = {0}, img = {0};
  assert_int_equal(oc_image_alloc(&r1, W, H), 0);
  assert_int_equal(oc_image_alloc(&r2, W, H), 0);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  ocv_gl_state_t g1, g2;
  assert_int_equal(ocv_gl_state_upload(&g1, &s1, why, sizeof why), 0);
  assert_int_equal(ocv_gl_state_upload(&g2, &s2, why, sizeof why), 0);
  assert_int_equal(ocv_gl_render_state(ren, &g1, &d, &r1, why, sizeof why), 0);
  assert_int_equal(ocv_gl_render_state(ren, &g2, &d, &r2, why, sizeof why), 0);
  ocv_gl_state_free(&g1);
  ocv_gl_state_free(&g2);

  uint32_t nslots = s1.brick_count + s2.brick_count + 8;
  oc_budget_t g = {.budget = (uint64_t)nslots * (OC_SLOT_BYTES + OC_RECORD_BYTES), .slot_bytes = OC_SLOT_BYTES,
                   .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  ocv_gl_view_desc_t vd = {.grant = g, .animated = 1, .epoch_period = 1.0};
  ocv_gl_view_t *v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  assert_int_equal(ocv_gl_view_push(v, &s1, why, sizeof why), 0);
  reprojected(v, &d, 0.0, 0.1, 1, 16, &img); /* a still camera: 16 frames trace every pixel */
  assert_memory_equal(img.px, r1.px, sizeof(float) * 4 * W * H);
  /* epoch 2 at t = 10 s: its first frame (blend t = 0) */
  assert_int_equal(ocv_gl_view_push(v, &s2, why, sizeof why), 0);
  reprojected(v, &d, 10.0, 0.0, 2, 0, &img);
  double first = rmse(&img, &r1), p12 = rmse(&r1, &r2);
  /* past the blend, 16 frames: every position traced again, nothing clamped any more */
  reprojected(v, &d, 11.5, 0.1, 2, 16, &img);
  double last = rmse(&img, &r2);
  printf("new state under reprojection: first frame vs the picture before RMSE %.2f (the states differ by %.2f); "
         "16 frames later vs the new state %.3f\n", first, p12, last);
  assert_true(first < p12 / 3);
  assert_memory_equal(img.px, r2.px, sizeof(float) * 4 * W * H);

  ocv_gl_view_free(v);
  for (oc_image_t *im[] = {&r1, &r2, &img}, **i = im; i < im + 3; i++) oc_image_free(*i);
  oc_state_free(&s1);
  oc_state_free(&s2);
}

static void test_gl_window_scale__hud(void **state) {
  (void)state;
  ocv_hud_stats_t hs = {.frame_ms = 95.0, .trace_ms = -1, .reproject_ms = -1, .renderer = "gl",
                        .trace_w = 320, .trace_h = 180, .trace_scale = 4};
  char text[512];
  ocv_hud_format(&hs, text, sizeof text);
  assert_non_null(strstr(text, "trace 320x180 (1/4)"));
  hs.trace_w = 1280;
  hs.trace_h = 720;
  hs.trace_scale = 1;
  ocv_hud_format(&hs, text, sizeof text);
  assert_non_null(strstr(text, "trace 1280x720 (full)"));
  hs.trace_w = 0; /* headless frames: no traced size shown */
  ocv_hud_format(&hs, text, sizeof text);
  assert_null(strstr(text, "trace "));
}

OC_TEST_MAIN(setup, teardown, cmocka_unit_test(test_gl_window_scale__controller),
             cmocka_unit_test(test_gl_window_scale__upsampled_picture), cmocka_unit_test(test_gl_window_scale__uploads),
             cmocka_unit_test(test_gl_window_scale__new_state_continues), cmocka_unit_test(test_gl_window_scale__hud))
