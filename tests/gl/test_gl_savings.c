/* test_gl_savings.c — what the GL renderer leaves out changes no pixel:
 *   - the octree map (client/gl/gl_state.c, Pettersson's 64³ map): a state deep enough gets a map
 *     whose level is within OCV_GL_MAP_MAX_LEVEL and its deepest leaf, its words stay within the
 *     tree and records' own size, and an image rendered with the map is bit-identical to one
 *     descending every lookup from the root (a wrong map entry would pick another leaf);
 *   - shader variants (client/gl/gl_render.c): the kernel compiled without the features a frame does
 *     not use (here: no atmosphere; a debug view) renders what the generic kernel renders, bit for
 *     bit (a variant constant of the wrong value would drop or add a term). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "test_main.h"
#include "oc_camera.h"
#include "oc_image.h"
#include "oc_key.h"
#include "oc_render.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state */

#define W 96
#define H 54

static void test_gl_savings__same_image(void **state) {
  (void)state;
  require_gl();
  char why[512];
  static const oc_camera_pose_t poses[] = {
      {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0},   /* the scene's camera */
      {{0.0, -0.02, 3000.0}, 90.0, 10.0, 60.0},  /* inside the sphere: deeper leaves */
  };
  for (int v = 0; v < 2; v++) {
    oc_camera_t cam = oc_camera_from_pose(poses[v]);
    oc_state_t st;
    sphere_state(&st, cam, H, 0);
    int deepest = 0;
    for (uint32_t i = 0; i < st.node_count; i++)
      if (oc_key_level(st.nodes[i].key) > deepest) deepest = oc_key_level(st.nodes[i].key);
    ocv_gl_state_t gs;
    assert_int_equal(ocv_gl_state_upload(&gs, &st, why, sizeof why), 0);
    uint64_t map_bytes = gs.map_level ? 4ull << (3 * gs.map_level) : 0;
    printf("view %d: %u leaves, %u inner, deepest level %d: map level %d (%llu KiB)\n", v, gs.leaf_count, gs.inner_count,
           deepest, gs.map_level, (unsigned long long)(map_bytes >> 10));
    assert_true(gs.map_level >= 1 && gs.map_level <= OCV_GL_MAP_MAX_LEVEL && gs.map_level <= deepest);
    assert_true(map_bytes <= 4 * (1 + 8ull * gs.inner_count) + (uint64_t)gs.leaf_count * OC_RECORD_BYTES);
    oc_render_desc_t d = const_bg_desc(cam, W, H);
    oc_image_t a = {0}, b = {0};
    assert_int_equal(oc_image_alloc(&a, W, H), 0);
    assert_int_equal(oc_image_alloc(&b, W, H), 0);
    assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &a, why, sizeof why), 0);
    ocv_gl_renderer_set_map(ren, 0);
    assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &b, why, sizeof why), 0);
    ocv_gl_renderer_set_map(ren, 1);
    assert_memory_equal(a.px, b.px, sizeof(float) * 4 * W * H);
    for (int debug = 0; debug <= OC_DEBUG_LOD; debug += OC_DEBUG_LOD) {
      d.debug_view = debug;
      assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &a, why, sizeof why), 0);
      ocv_gl_renderer_set_variants(ren, 0);
      assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &b, why, sizeof why), 0);
      ocv_gl_renderer_set_variants(ren, 1);
      assert_memory_equal(a.px, b.px, sizeof(float) * 4 * W * H);
    }
    oc_image_free(&a);
    oc_image_free(&b);
    ocv_gl_state_free(&gs);
    oc_state_free(&st);
  }
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_savings__same_image))
