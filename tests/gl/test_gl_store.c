/* test_gl_store.c — the viewer's kept states on the GPU (client/gl/gl_store.c): uploads bounded per
 * call, bricks shared between states uploaded once, slots freed when the oldest state is dropped,
 * resident bytes by the Conventions' measure within the atlas, and the image of a stored state
 * identical to the one-shot upload's (slot placement must not change a value). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "oc_atmo.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54

/* The analytic sphere voxelized for a camera at longitude lon; brick ids shifted by id_base. */
static void make_state(oc_state_t *st, oc_camera_t *cam, double lon, uint32_t id_base) {
  oc_camera_pose_t pose = {{0.0, lon, 3000.0}, 90.0, 0.0, 40.0};
  *cam = oc_camera_from_pose(pose);
  sphere_state(st, *cam, H, id_base);
  assert_true(st->brick_count > 40);
}

/* A copy of s in which `n` bricks got new content under new ids (a refreshed epoch). */
static void refresh(oc_state_t *dst, const oc_state_t *s, uint32_t n) {
  oc_state_init(dst);
  assert_int_equal(oc_state_copy(dst, s), 0);
  uint32_t next = s->bricks[s->brick_count - 1].id + 1, done = 0;
  oc_node_t *nodes[64];
  oc_brick_t *bricks[64];
  assert_true(n <= 64);
  for (uint32_t i = 0; i < dst->node_count && done < n; i++) /* look up first: ids change below */
    if (dst->nodes[i].kind == OC_NODE_BRICK) {
      nodes[done] = &dst->nodes[i];
      bricks[done++] = (oc_brick_t *)oc_state_find_brick(dst, dst->nodes[i].brick_id);
    }
  for (uint32_t k = 0; k < done; k++) {
    bricks[k]->id = nodes[k]->brick_id = next++;
    for (int v = 0; v < 512; v++)
      if (bricks[k]->codes.code[0][v] > 1 && bricks[k]->codes.code[0][v] < 65535) bricks[k]->codes.code[0][v]++;
  }
  oc_state_canonicalize(dst);
  char why[256];
  if (oc_state_validate(dst, why, sizeof why)) fail_msg("refresh: %s", why);
}

static void render(const ocv_gl_state_t *gs, oc_camera_t cam, oc_image_t *img) {
  oc_render_desc_t d = const_bg_desc(cam, W, H);
  char why[512];
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  if (ocv_gl_render_state(ren, gs, &d, img, why, sizeof why) < 0) fail_msg("render: %s", why);
}

/* The stored state renders exactly like a one-shot upload of the same state. */
static void expect_same_image(const ocv_gl_state_t *stored, const oc_state_t *s, oc_camera_t cam) {
  ocv_gl_state_t one;
  char why[512];
  assert_int_equal(ocv_gl_state_upload(&one, s, why, sizeof why), 0);
  oc_image_t a = {0}, b = {0};
  render(stored, cam, &a);
  render(&one, cam, &b);
  double lo = 1e30, hi = -1e30;
  for (int i = 0; i < W * H * 4; i++) {
    lo = a.px[i] < lo ? a.px[i] : lo;
    hi = a.px[i] > hi ? a.px[i] : hi;
  }
  assert_true(hi > lo); /* not a uniform image */
  assert_memory_equal(a.px, b.px, sizeof(float) * 4 * W * H);
  oc_image_free(&a);
  oc_image_free(&b);
  ocv_gl_state_free(&one);
}

static uint32_t distinct_bricks(const oc_state_t *a, const oc_state_t *b) {
  uint32_t n = a->brick_count;
  for (uint32_t i = 0; i < b->brick_count; i++) n += oc_state_find_brick(a, b->bricks[i].id) == NULL;
  return n;
}

static void test_gl_store__epochs(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_state_t s1, s2, s3;
  oc_camera_t cam, cam3;
  make_state(&s1, &cam, -0.09, 0);
  refresh(&s2, &s1, 10);
  make_state(&s3, &cam3, -0.08, 1000000);
  uint32_t slots = distinct_bricks(&s1, &s2) + s3.brick_count; /* room for two kept and one staged */
  /* a grant of exactly that many bricks once the records are taken off (K = 3: 2 kept, 1 staged) */
  oc_budget_t g = {.budget = (uint64_t)slots * (OC_SLOT_BYTES + OC_RECORD_BYTES) + OC_RECORD_BYTES,
                   .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  ocv_gl_store_t *st = ocv_gl_store_create(&g, why, sizeof why);
  if (!st) fail_msg("%s", why);
  ocv_gl_store_stats_t ss;
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.capacity, slots);

  /* 1. the first state arrives in bounded pieces: 16 bricks a call */
  assert_int_equal(ocv_gl_store_stage(st, &s1, why, sizeof why), 0);
  int calls = 0, r;
  while ((r = ocv_gl_store_pump(st, 16 * OC_SLOT_BYTES, why, sizeof why)) == 0) {
    calls++;
    assert_null(ocv_gl_store_state(st, 0)); /* nothing to render until it is complete */
  }
  assert_int_equal(r, 1);
  assert_int_equal(calls + 1, (int)((s1.brick_count + 15) / 16));
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.uploaded_bricks, s1.brick_count);
  assert_int_equal(ss.used, s1.brick_count);
  expect_same_image(ocv_gl_store_state(st, 0), &s1, cam);

  /* 2. a refresh uploads only its 10 new bricks; both states are kept */
  assert_int_equal(ocv_gl_store_stage(st, &s2, why, sizeof why), 0);
  assert_int_equal(ocv_gl_store_pump(st, UINT64_MAX, why, sizeof why), 1);
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.uploaded_bricks, s1.brick_count + 10);
  assert_int_equal(ss.ready, 2);
  const oc_state_t *both[2] = {&s2, &s1};
  assert_int_equal(ss.resident_bytes, oc_resident_bytes(both, 2, OC_SLOT_BYTES, OC_RECORD_BYTES));
  expect_same_image(ocv_gl_store_state(st, 0), &s2, cam);
  expect_same_image(ocv_gl_store_state(st, 1), &s1, cam);

  /* 3. a new view: s1 is dropped, the bricks only it held free their slots */
  assert_int_equal(ocv_gl_store_stage(st, &s3, why, sizeof why), 0);
  assert_int_equal(ocv_gl_store_pump(st, UINT64_MAX, why, sizeof why), 1);
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.used, s2.brick_count + s3.brick_count);
  const oc_state_t *kept[2] = {&s3, &s2};
  assert_int_equal(ss.resident_bytes, oc_resident_bytes(kept, 2, OC_SLOT_BYTES, OC_RECORD_BYTES));
  assert_true(ss.resident_bytes <= (uint64_t)slots * OC_SLOT_BYTES + (uint64_t)(s2.node_count + s3.node_count) * OC_RECORD_BYTES);
  expect_same_image(ocv_gl_store_state(st, 0), &s3, cam3);
  printf("store: %u slots, %u used, %llu bricks uploaded for 3 states of %u, %u, %u bricks\n", ss.capacity, ss.used,
         (unsigned long long)ss.uploaded_bricks, s1.brick_count, s2.brick_count, s3.brick_count);

  /* 4. a state that cannot fit beside the kept ones is refused, and nothing leaks: the slots are
   *    as before, and a state that fits is still taken */
  oc_state_t s4;
  oc_camera_t cam4;
  make_state(&s4, &cam4, -0.07, 2000000);
  uint32_t used = ss.used;
  int rc = ocv_gl_store_stage(st, &s4, why, sizeof why);
  if (s4.brick_count > slots - used) {
    assert_int_equal(rc, OC_ETOOBIG);
    assert_non_null(strstr(why, "brick slots"));
    ocv_gl_store_stats(st, &ss);
    assert_int_equal(ss.used, used);
  }
  /* a stage replaced before it completes releases its bricks */
  oc_state_t s5;
  refresh(&s5, &s3, 5);
  assert_int_equal(ocv_gl_store_stage(st, &s5, why, sizeof why), 0);
  assert_int_equal(ocv_gl_store_pump(st, OC_SLOT_BYTES, why, sizeof why), 0);
  assert_int_equal(ocv_gl_store_stage(st, &s5, why, sizeof why), 0); /* staged again from scratch */
  assert_int_equal(ocv_gl_store_pump(st, UINT64_MAX, why, sizeof why), 1);
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.used, distinct_bricks(&s5, &s3));
  expect_same_image(ocv_gl_store_state(st, 0), &s5, cam3);

  ocv_gl_store_free(st);
  oc_state_free(&s1);
  oc_state_free(&s2);
  oc_state_free(&s3);
  oc_state_free(&s4);
  oc_state_free(&s5);
}

/* States that arrive faster than one uploads (a slow window takes the newest each frame): a replaced
 * stage keeps the uploaded bricks it shares with the new state, so the upload still completes.
 * Before, each stage started again from nothing and, past one call's bytes, never completed. */
static void test_gl_store__restaged_every_call_completes(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_state_t s1, s2;
  oc_camera_t cam;
  make_state(&s1, &cam, -0.09, 0);
  refresh(&s2, &s1, 10);
  assert_true(s1.brick_count > 64);
  uint32_t slots = distinct_bricks(&s1, &s2) + s1.brick_count;
  oc_budget_t g = {.budget = (uint64_t)slots * (OC_SLOT_BYTES + OC_RECORD_BYTES) + OC_RECORD_BYTES,
                   .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  ocv_gl_store_t *st = ocv_gl_store_create(&g, why, sizeof why);
  if (!st) fail_msg("%s", why);
  const oc_state_t *arriving[2] = {&s1, &s2};
  int calls = 0, r = 0;
  while (r == 0 && calls < (int)s1.brick_count) {
    assert_int_equal(ocv_gl_store_stage(st, arriving[calls & 1], why, sizeof why), 0);
    r = ocv_gl_store_pump(st, 32 * OC_SLOT_BYTES, why, sizeof why);
    calls++;
  }
  printf("store: a state of %u bricks, restaged every call, complete after %d calls of 32 bricks\n", s1.brick_count,
         calls);
  assert_int_equal(r, 1);
  expect_same_image(ocv_gl_store_state(st, 0), arriving[(calls - 1) & 1], cam);
  ocv_gl_store_free(st);
  oc_state_free(&s1);
  oc_state_free(&s2);
}

/* The atlas follows the grant, not the budget alone: other slot and record bytes, another K, give
 * another number of slots (oc_budget_slots()), resident bytes are counted in the granted sizes,
 * and a grant too small for a window is refused by name. */
static void test_gl_store__sized_from_the_grant(void **state) {
  (void)state;
  char why[512];
  oc_budget_t g = {.budget = 1u << 20, .slot_bytes = 4096, .record_bytes = 64, .kept_states = 2};
  ocv_gl_store_t *st = ocv_gl_store_create(&g, why, sizeof why);
  if (!st) fail_msg("%s", why);
  ocv_gl_store_stats_t ss;
  ocv_gl_store_stats(st, &ss);
  assert_int_equal(ss.capacity, (1u << 20) / (4096 + 64)); /* 252, not 1 MiB / 2048 = 512 */
  assert_int_equal(ss.capacity, oc_budget_slots(&g));
  oc_state_t s1;
  oc_camera_t cam;
  make_state(&s1, &cam, -0.09, 0);
  if (s1.brick_count <= ss.capacity) {
    assert_int_equal(ocv_gl_store_stage(st, &s1, why, sizeof why), 0);
    assert_int_equal(ocv_gl_store_pump(st, UINT64_MAX, why, sizeof why), 1);
    ocv_gl_store_stats(st, &ss);
    const oc_state_t *one[1] = {&s1};
    assert_int_equal(ss.resident_bytes, oc_resident_bytes(one, 1, 4096, 64));
  }
  ocv_gl_store_free(st);
  oc_state_free(&s1);
  oc_budget_t tiny = {.budget = 100, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  assert_null(ocv_gl_store_create(&tiny, why, sizeof why));
  assert_non_null(strstr(why, "holds no window of 3 states"));
  oc_budget_t k4 = {.budget = 1u << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 4};
  assert_null(ocv_gl_store_create(&k4, why, sizeof why));
  assert_non_null(strstr(why, "kept states must be 2 or 3"));
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_store__epochs),
             cmocka_unit_test(test_gl_store__restaged_every_call_completes),
             cmocka_unit_test(test_gl_store__sized_from_the_grant))
