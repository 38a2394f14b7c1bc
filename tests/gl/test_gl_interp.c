/* test_gl_interp.c — interpolation between states on the GPU (client/interp.h → client/gl/gl_interp.c
 * → the kernel's mix(previous, newest, t)): at t = 1 the newest state exactly; at t = 0 the previous
 * state (exactly where bricks were refreshed in place, closely where the tree was re-planned, since
 * a split parent is resampled and merged descendants are kept one level finer than the merged leaf,
 * not at their own depth); in between, in between; halfway, the CPU reference renderer's image of
 * the interpolated state, materialised on the CPU (refreshed in place, split, merged: a merged leaf
 * as its 8 children); a static scene's refreshed brick snaps (only splits and merges cross-fade). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "brick.h" /* ocg_*: N's reconstruction at a merged leaf's child lattices */
#include "interp.h"
#include "oc_camera.h"
#include "oc_key.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54

static void make_state(oc_state_t *st, oc_camera_t cam, uint32_t id_base) { sphere_state(st, cam, H, id_base); }

static oc_render_desc_t view_desc(oc_camera_t cam) {
  oc_render_desc_t d = const_bg_desc(cam, W, H);
  d.threads = 2;
  return d;
}

static void render(const oc_state_t *s, oc_camera_t cam, const ocv_gl_prev_t *gp, float t, oc_image_t *img) {
  char why[512];
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, s, why, sizeof why), 0);
  oc_render_desc_t d = view_desc(cam);
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  ocv_gl_renderer_set_prev(ren, gp, t);
  if (ocv_gl_render_state(ren, &gs, &d, img, why, sizeof why) < 0) fail_msg("render: %s", why);
  ocv_gl_renderer_set_prev(ren, NULL, 1.0f);
  ocv_gl_state_free(&gs);
}

/* P seen from far, N re-planned from nearer (other leaves, other bricks), both from the same view. */
static void blend_case(const char *name, oc_state_t *P, oc_state_t *N, oc_camera_t view, int animated, double max_t0) {
  char why[512];
  ocv_interp_t ip;
  ocv_interp_init(&ip);
  assert_int_equal(ocv_interp_build(&ip, P, N), 0);
  ocv_interp_stats_t is;
  ocv_interp_stats(&ip, &is);
  ocv_gl_prev_t gp;
  if (ocv_gl_prev_upload(&gp, &ip, animated, why, sizeof why) < 0) fail_msg("%s", why);
  oc_image_t ip_, in_, i0, i1, ih;
  render(P, view, NULL, 1.0f, &ip_);
  render(N, view, NULL, 1.0f, &in_);
  render(N, view, &gp, 0.0f, &i0);
  render(N, view, &gp, 1.0f, &i1);
  render(N, view, &gp, 0.5f, &ih);
  double pn = rmse(&ip_, &in_), t0p = rmse(&i0, &ip_), hp = rmse(&ih, &ip_), hn = rmse(&ih, &in_);
  printf("%s: same %u own %u parent %u children %u | RMSE P–N %.2f, t=0 vs P %.2f, t=½ vs P %.2f vs N %.2f\n", name,
         is.count[OCV_INTERP_SAME], is.count[OCV_INTERP_OWN], is.count[OCV_INTERP_PARENT], is.count[OCV_INTERP_CHILDREN],
         pn, t0p, hp, hn);
  assert_memory_equal(i1.px, in_.px, sizeof(float) * 4 * W * H); /* t = 1: the newest state */
  assert_true(pn > 1.0);                                        /* the two states do differ */
  assert_true(t0p <= max_t0);                                   /* t = 0: the previous state */
  assert_true(hp < pn && hn < pn);                              /* t = ½: in between */
  oc_image_free(&ip_);
  oc_image_free(&in_);
  oc_image_free(&i0);
  oc_image_free(&i1);
  oc_image_free(&ih);
  ocv_gl_prev_free(&gp);
  ocv_interp_free(&ip);
}

/* N's reconstruction (brick.h, as common/oc_render.c) at leaf-local u; cur holds N's decoded
 * samples (or its constant value everywhere). */
static float leaf_eval(const float cur[OC_BRICK_VOXELS], ocg_vec3 u) {
  ocg_vec3 base = ocg_brick_base(u), f = ocg_brick_frac(u, base);
  ocg_uint b0 = ocg_brick_base_voxel(base);
  float v[8];
  for (ocg_uint q = 0; q < 8u; q++) v[q] = cur[b0 + ocg_brick_voxel(q & 1u, (q >> 1) & 1u, q >> 2)];
  return ocg_trilerp(ocg_v4(v[0], v[1], v[2], v[3]), ocg_v4(v[4], v[5], v[6], v[7]), f);
}

/* Adds leaf `key` with samples mix(prev, cur, w) per channel (GLSL mix(a, b, w)), re-encoded by
 * oc_brick_encode (empty, uniform or a brick with a new sequential id). */
static void add_mixed(oc_state_t *out, oc_key_t key, const float *prev[OC_CHANNELS], const float prev_value[OC_CHANNELS],
                      float cur[OC_CHANNELS][OC_BRICK_VOXELS], float w, uint32_t *next_id) {
  float mixed[OC_CHANNELS][OC_BRICK_VOXELS];
  for (int c = 0; c < OC_CHANNELS; c++)
    for (int v = 0; v < OC_BRICK_VOXELS; v++) {
      float a = w < 1.0f ? (prev[c] ? prev[c][v] : prev_value[c]) : cur[c][v];
      mixed[c][v] = a * (1.0f - w) + cur[c][v] * w;
    }
  oc_node_t m;
  memset(&m, 0, sizeof m);
  m.key = key;
  oc_brick_codes_t codes;
  m.kind = (uint8_t)oc_brick_encode(mixed[OC_CH_SIGMA], mixed[OC_CH_TAU], &codes, m.range);
  if (m.kind == OC_NODE_BRICK) {
    m.brick_id = (*next_id)++;
    assert_int_equal(oc_state_add_brick(out, m.brick_id, &codes), 0);
  }
  assert_int_equal(oc_state_add_node(out, &m), 0);
}

/* The state the kernel shows at blend parameter t, materialised on the CPU: every leaf of N keeps
 * its key, except a merged leaf with a fine previous value (client/interp.h, CHILDREN), which
 * becomes its 8 children: the kernel blends it at the children's resolution (sub-brick c in octant
 * c) and steps it octant by octant, as the children were, so the interpolated state keeps P's finer
 * topology there (one level finer) until t = 1. Samples are mix(previous, newest, w) per channel
 * with w the weight of the leaf's source (the kernel mixes the two trilinear reconstructions, and
 * trilinear reconstruction is linear in the samples, so mixing the samples gives the same field;
 * for a child, N's reconstruction is taken at the child's lattice, where it is again exactly
 * trilinear between samples: every child cell lies inside one of N's cells). Leaves with w = 1 are
 * N's own. */
static void interpolated_state(oc_state_t *out, const oc_state_t *N, const ocv_interp_t *ip, int animated, float t) {
  oc_state_init(out);
  out->epoch = N->epoch;
  out->time = N->time;
  out->sun_dir = N->sun_dir;
  uint32_t next_id = 1;
  for (uint32_t i = 0; i < N->node_count; i++) {
    const oc_node_t *n = &N->nodes[i];
    const ocv_interp_prev_t *p = &ip->prev[i];
    /* the Conventions' weights, written out rather than taken from ocv_interp_weight(): t where
     * the leaf changed (OWN only when animated; PARENT, CHILDREN always), else N's own value */
    int blends = p->source == OCV_INTERP_PARENT || p->source == OCV_INTERP_CHILDREN ||
                 (animated && p->source == OCV_INTERP_OWN);
    float w = blends ? t : 1.0f;
    float cur[OC_CHANNELS][OC_BRICK_VOXELS];
    if (n->kind == OC_NODE_BRICK) {
      const oc_brick_t *b = oc_state_find_brick(N, n->brick_id);
      assert_non_null(b);
      oc_brick_decode(&b->codes, n->range, cur[OC_CH_SIGMA], cur[OC_CH_TAU]);
    } else {
      for (int c = 0; c < OC_CHANNELS; c++)
        for (int v = 0; v < OC_BRICK_VOXELS; v++) cur[c][v] = n->kind == OC_NODE_UNIFORM ? n->range[c].lo : 0.0f;
    }
    if (w < 1.0f && p->fine) {
      assert_int_equal(p->source, OCV_INTERP_CHILDREN);
      assert_null(ocv_interp_samples(ip, i, OC_CH_SIGMA));
      for (int sub = 0; sub < 8; sub++) {
        float fc[OC_CHANNELS][OC_BRICK_VOXELS];
        for (int v = 0; v < OC_BRICK_VOXELS; v++) {
          int x = v & 7, y = (v >> 3) & 7, z = v >> 6; /* u = (c_axis + i/7)/2, rounded once */
          ocg_vec3 u = ocg_v3((float)((7.0 * (sub & 1) + x) / 14.0), (float)((7.0 * ((sub >> 1) & 1) + y) / 14.0),
                              (float)((7.0 * (sub >> 2) + z) / 14.0));
          for (int c = 0; c < OC_CHANNELS; c++) fc[c][v] = leaf_eval(cur[c], u);
        }
        const float *prev[OC_CHANNELS] = {ocv_interp_sub_samples(ip, i, sub, OC_CH_SIGMA),
                                          ocv_interp_sub_samples(ip, i, sub, OC_CH_TAU)};
        assert_non_null(prev[0]);
        assert_non_null(prev[1]);
        add_mixed(out, oc_key_child(n->key, sub), prev, p->value, fc, w, &next_id);
      }
      continue;
    }
    const float *prev[OC_CHANNELS] = {NULL, NULL};
    if (w < 1.0f)
      for (int c = 0; c < OC_CHANNELS; c++) prev[c] = ocv_interp_samples(ip, i, c);
    add_mixed(out, n->key, prev, p->value, cur, w, &next_id);
  }
  oc_state_canonicalize(out);
  char why[256];
  if (oc_state_validate(out, why, sizeof why) < 0) fail_msg("interpolated state: %s", why);
}

static void cpu_render(const oc_state_t *s, oc_camera_t cam, oc_image_t *img) {
  oc_render_desc_t d = view_desc(cam);
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  oc_render_stats_t st;
  assert_int_equal(oc_render_state(s, &d, img, &st), 0);
  assert_int_equal(st.nonfinite, 0);
}

/* Halfway through an epoch the GL image (N with P's previous values, t = ½) matches the CPU
 * reference renderer of the interpolated state within HALF_BOUND — GL vs CPU of one state differs
 * by ~0.01 and the re-encoding by at most oc_code_rel_error_bound (~1e-4 relative), so any real
 * error in the previous values (a wrong pool entry, a parent resampled at the wrong offset, the
 * wrong weight) or in the kernel's mix shows. Negative controls: the CPU render of N alone and of
 * P alone are farther than 4·HALF_BOUND, and that of the state interpolated at t = 0.4 instead of
 * ½ farther than 2·HALF_BOUND (a blend parameter off by 0.1 breaks the bound too). Measured on
 * llvmpipe: 0.000–0.011; controls ≥ 0.78 (t = 0.4), ≥ 3.0 (N, P). Without the kernel stepping a
 * blending merged leaf octant by octant (as its children were stepped) the merge case is 0.75. */
#define HALF_BOUND 0.25

static void half_matches_cpu(const char *name, const oc_state_t *P, const oc_state_t *N, oc_camera_t view,
                             int animated) {
  char why[512];
  ocv_interp_t ip;
  ocv_interp_init(&ip);
  assert_int_equal(ocv_interp_build(&ip, P, N), 0);
  ocv_gl_prev_t gp;
  if (ocv_gl_prev_upload(&gp, &ip, animated, why, sizeof why) < 0) fail_msg("%s", why);
  oc_state_t M, M4;
  interpolated_state(&M, N, &ip, animated, 0.5f);
  interpolated_state(&M4, N, &ip, animated, 0.4f);
  oc_image_t gl, cm, c4, cn, cp;
  render(N, view, &gp, 0.5f, &gl);
  cpu_render(&M, view, &cm);
  cpu_render(&M4, view, &c4);
  cpu_render(N, view, &cn);
  cpu_render(P, view, &cp);
  double e = rmse(&gl, &cm), e4 = rmse(&gl, &c4), en = rmse(&gl, &cn), ep = rmse(&gl, &cp);
  ocv_interp_stats_t is;
  ocv_interp_stats(&ip, &is);
  printf("%s, t=½ (own %u parent %u children %u; interpolated state: %u leaves, %u bricks): GL vs CPU of the "
         "interpolated state RMSE %.3f (bound %.2f); controls: CPU at t=0.4 %.3f, N %.3f, P %.3f\n",
         name, is.count[OCV_INTERP_OWN], is.count[OCV_INTERP_PARENT], is.count[OCV_INTERP_CHILDREN], M.node_count,
         M.brick_count, e, HALF_BOUND, e4, en, ep);
  assert_true(e <= HALF_BOUND);
  assert_true(e4 > 2 * HALF_BOUND);
  assert_true(en > 4 * HALF_BOUND);
  assert_true(ep > 4 * HALF_BOUND);
  oc_image_free(&gl);
  oc_image_free(&cm);
  oc_image_free(&c4);
  oc_image_free(&cn);
  oc_image_free(&cp);
  oc_state_free(&M);
  oc_state_free(&M4);
  ocv_gl_prev_free(&gp);
  ocv_interp_free(&ip);
}

static void test_gl_interp__refresh_and_replan(void **state) {
  (void)state;
  require_gl();
  oc_camera_pose_t far = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}, near = {{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cf = oc_camera_from_pose(far), cn = oc_camera_from_pose(near);
  oc_state_t P, N, R;
  make_state(&P, cf, 0);
  /* a refresh in place: every brick of P with new content under a new id (OWN) */
  oc_state_init(&R);
  assert_int_equal(oc_state_copy(&R, &P), 0);
  for (uint32_t i = 0; i < R.node_count; i++)
    if (R.nodes[i].kind == OC_NODE_BRICK) R.nodes[i].brick_id += 500000;
  for (uint32_t b = 0; b < R.brick_count; b++) {
    R.bricks[b].id += 500000;
    for (int v = 0; v < 512; v++) R.bricks[b].codes.code[0][v] = (uint16_t)(R.bricks[b].codes.code[0][v] ? 65535 - (v & 255) : 0);
  }
  blend_case("refresh", &P, &R, cf, 1, 0.5);
  half_matches_cpu("refresh", &P, &R, cf, 1);
  { /* a static scene has no time interpolation: a brick refreshed in place snaps to the newest */
    char why[512];
    ocv_interp_t ip;
    ocv_interp_init(&ip);
    assert_int_equal(ocv_interp_build(&ip, &P, &R), 0);
    ocv_gl_prev_t gp;
    assert_int_equal(ocv_gl_prev_upload(&gp, &ip, 0, why, sizeof why), 0);
    oc_image_t a, b;
    render(&R, cf, &gp, 0.0f, &a);
    render(&R, cf, NULL, 1.0f, &b);
    assert_memory_equal(a.px, b.px, sizeof(float) * 4 * W * H);
    oc_image_free(&a);
    oc_image_free(&b);
    ocv_gl_prev_free(&gp);
    ocv_interp_free(&ip);
  }
  /* re-planned for a nearer camera: splits and merges, seen from the far camera */
  make_state(&N, cn, 1000000);
  blend_case("replan", &P, &N, cf, 1, 3.0);
  half_matches_cpu("replan", &P, &N, cf, 1); /* splits: PARENT */
  /* merges (the other way): t = 0 is P's picture up to the detail of descendants two or more levels
   * below a merged leaf (kept one level finer); measured 2.84 of 9.97, 8.57 with previous values on
   * the merged leaf's own lattice */
  blend_case("merge", &N, &P, cf, 1, 4.0);
  half_matches_cpu("merge", &N, &P, cf, 1);  /* the other way: CHILDREN */
  oc_state_free(&P);
  oc_state_free(&N);
  oc_state_free(&R);
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_interp__refresh_and_replan))
