/* gl_fixture.h — what the GL tests of client/gl share (header-only): one context and renderer per
 * test program (skipped without GL unless OC_GL_REQUIRE=1), the analytic sphere voxelized for a
 * camera, the RMSE of two images on the 0–255 scale after the viewer's tone mapping, and the largest
 * difference of two 8-bit pictures. */
#ifndef OC_TESTS_GL_FIXTURE_H
#define OC_TESTS_GL_FIXTURE_H

#include <string.h> /* memset */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "oc_camera.h"
#include "oc_image.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "ocv_gl.h"

static ocv_gl_context_t *ctx;
static ocv_gl_renderer_t *ren;

static int setup(void **state) {
  (void)state;
  char why[1024];
  ctx = ocv_gl_context_init(why, sizeof why);
  if (!ctx) printf("%s\n", why);
  else if (!(ren = ocv_gl_renderer_create(why, sizeof why))) printf("programs: %s\n", why);
  return 0;
}

static int teardown(void **state) {
  (void)state;
  ocv_gl_renderer_free(ren);
  ocv_gl_context_free(ctx);
  return 0;
}

static inline void require_gl(void) {
  if (ctx && ren) return;
  const char *req = getenv("OC_GL_REQUIRE");
  if (req && req[0] == '1') fail_msg("OC_GL_REQUIRE=1 but no headless OpenGL 4.5 context");
  skip();
}

/* scenes/analytic_sphere.json voxelized for cam at an image height h; brick ids + id_base (so that
 * states made for different cameras never share an id with other content). */
static inline void sphere_state(oc_state_t *st, oc_camera_t cam, int h, uint32_t id_base) {
  char path[1024], why[512];
  const char *root = getenv("OC_SOURCE_DIR");
  snprintf(path, sizeof path, "%s/scenes/analytic_sphere.json", root && *root ? root : ".");
  oc_scene_t sc;
  assert_int_equal(oc_scene_load(&sc, path, why, sizeof why), 0);
  oc_state_init(st);
  ocs_scene_voxelize_desc_t vd = {cam, h, 2.0, 0, 0, 2};
  if (ocs_scene_voxelize(st, &sc, &vd, why, sizeof why) < 0) fail_msg("voxelize: %s", why);
  for (uint32_t i = 0; i < st->node_count; i++)
    if (st->nodes[i].kind == OC_NODE_BRICK) st->nodes[i].brick_id += id_base;
  for (uint32_t b = 0; b < st->brick_count; b++) st->bricks[b].id += id_base;
  oc_scene_free(&sc);
}

/* A w×h view from cam against a constant background (no atmosphere, no planet): the analytic
 * tests' lighting, every other knob at its default. */
static inline oc_render_desc_t const_bg_desc(oc_camera_t cam, int w, int h) {
  oc_render_desc_t d;
  memset(&d, 0, sizeof d);
  d.width = w;
  d.height = h;
  d.camera = cam;
  d.background = OC_BG_CONSTANT;
  d.background_radiance = 0.02f;
  return d;
}

/* RMSE on the 0–255 scale after tone mapping at exposure 10. */
static inline double rmse(const oc_image_t *a, const oc_image_t *b) {
  size_t n = (size_t)a->w * (size_t)a->h * 3;
  uint8_t *ra = malloc(n), *rb = malloc(n);
  assert_non_null(ra);
  assert_non_null(rb);
  oc_image_tonemap(a, 10.0f, ra);
  oc_image_tonemap(b, 10.0f, rb);
  double se = 0.0;
  for (size_t i = 0; i < n; i++) se += ((double)ra[i] - rb[i]) * ((double)ra[i] - rb[i]);
  free(ra);
  free(rb);
  return sqrt(se / (double)n);
}

/* The largest difference between two byte arrays of n bytes (8-bit pictures: in steps). */
static inline int max_step(const uint8_t *a, const uint8_t *b, size_t n) {
  int m = 0;
  for (size_t i = 0; i < n; i++) {
    int d = abs((int)a[i] - (int)b[i]);
    if (d > m) m = d;
  }
  return m;
}

#endif /* OC_TESTS_GL_FIXTURE_H */
