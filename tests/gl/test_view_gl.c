/* test_view_gl.c — overcast-view end to end with both renderers.
 *
 * overcast-server plans a state of scenes/analytic_sphere.json offline (--save-state, a tiny
 * budget); overcast-view renders it headless at 160×90 from the scene's camera twice, with
 * --renderer cpu and --renderer gl. Both PNGs are read back: the RMSE between them on the 0–255
 * scale must be ≤ 1, the image must not be black or uniform, and each PNG must carry the camera it
 * was rendered with (the text chunk --camera-from reads), which restores the same frame.
 *
 * Programs from $OC_BIN_DIR (else ../bin next to this test's folder), scenes from $OC_SOURCE_DIR.
 * Without a GL context the gl run fails and the test skips, unless OC_GL_REQUIRE=1 (CI: Mesa). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h> /* readlink */

#include "oc_camera.h"
#include "oc_image.h"
#include "programs.h" /* oc_test_dirs, oc_test_run */

#define SIZE "160x90"
#define CAMERA "0,-0.09,3000,90,0,40" /* scenes/analytic_sphere.json's camera */

static char bin[2048], src[2048], tmp[256];

static int setup(void **state) {
  (void)state;
  oc_test_dirs(bin, sizeof bin, src, sizeof src);
  snprintf(tmp, sizeof tmp, "/tmp/oc_test_view_gl_XXXXXX");
  if (!mkdtemp(tmp)) return -1;
  char cmd[8192];
  snprintf(cmd, sizeof cmd,
           "'%s/overcast-server' --scene '%s/scenes/analytic_sphere.json' --save-state '%s/p.ocst' --epochs 3 "
           "--budget 4 --viewport 160x90 -q >/dev/null",
           bin, src, tmp);
  return oc_test_run(cmd) == 0 ? 0 : -1;
}

typedef struct {
  int w, h;
  uint8_t *rgb;
  char camera[256];
} png_t;

static png_t c, g, g2; /* freed in teardown, also after a failed assertion */

static int teardown(void **state) {
  (void)state;
  free(c.rgb);
  free(g.rgb);
  free(g2.rgb);
  char cmd[512];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
  return oc_test_run(cmd) == 0 ? 0 : -1;
}

static int view(const char *renderer, const char *camera_opt, const char *out) {
  char cmd[8192];
  snprintf(cmd, sizeof cmd,
           "cd '%s' && '%s/overcast-view' --headless --renderer %s --state '%s/p.ocst' %s --size " SIZE
           " --out '%s/%s' -q >/dev/null",
           src, bin, renderer, tmp, camera_opt, tmp, out);
  return oc_test_run(cmd);
}

static void load(const char *out, png_t *p) {
  char path[512], why[512];
  snprintf(path, sizeof path, "%s/%s/frame_0000.png", tmp, out);
  p->camera[0] = '\0';
  int r = oc_png_read(path, &p->w, &p->h, &p->rgb, "overcast-camera", p->camera, sizeof p->camera, why, sizeof why);
  if (r < 0) fail_msg("%s", why);
  assert_int_equal(p->w, 160);
  assert_int_equal(p->h, 90);
}

/* Not black, not uniform: a spread of values, and a bright cloud against the sky. */
static void assert_has_content(const png_t *p) {
  double sum = 0, sum2 = 0;
  int lo = 255, hi = 0;
  size_t n = (size_t)p->w * (size_t)p->h * 3;
  for (size_t i = 0; i < n; i++) {
    sum += p->rgb[i];
    sum2 += (double)p->rgb[i] * p->rgb[i];
    if (p->rgb[i] < lo) lo = p->rgb[i];
    if (p->rgb[i] > hi) hi = p->rgb[i];
  }
  double mean = sum / (double)n, sd = sqrt(fmax(0.0, sum2 / (double)n - mean * mean));
  printf("mean %.1f, sd %.1f, range %d..%d\n", mean, sd, lo, hi);
  assert_true(mean > 20.0);
  assert_true(sd > 10.0);
  assert_true(hi - lo > 64);
}

static void test_view_gl__cpu_and_gl_agree(void **state) {
  (void)state;
  assert_int_equal(view("cpu", "--camera " CAMERA, "cpu"), 0);
  int r = view("gl", "--camera " CAMERA, "gl");
  if (r != 0) {
    const char *req = getenv("OC_GL_REQUIRE");
    if (req && req[0] == '1') fail_msg("OC_GL_REQUIRE=1 but overcast-view --renderer gl exited %d", r);
    printf("no GL: skipped\n");
    skip();
  }
  load("cpu", &c);
  load("gl", &g);
  assert_has_content(&c);
  assert_has_content(&g);
  double rmse = oc_rgb8_rmse(c.rgb, g.rgb, 160, 90);
  printf("cpu vs gl: RMSE %.4f on 0-255\n", rmse);
  assert_true(rmse <= 1.0);

  /* The camera chunk holds the view, in oc_camera_format()'s exact form. */
  oc_camera_pose_t want, got;
  char why[256], text[256];
  assert_int_equal(oc_camera_parse(CAMERA, &want, why, sizeof why), 0);
  oc_camera_format(want, text, sizeof text);
  assert_string_equal(g.camera, text);
  assert_int_equal(oc_camera_parse(g.camera, &got, why, sizeof why), 0);

  /* --camera-from the gl frame restores the same view: the same frame, bit for bit. */
  char opt[512];
  snprintf(opt, sizeof opt, "--camera-from '%s/gl/frame_0000.png'", tmp);
  assert_int_equal(view("gl", opt, "gl2"), 0);
  load("gl2", &g2);
  assert_memory_equal(g.rgb, g2.rgb, (size_t)160 * 90 * 3);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_view_gl__cpu_and_gl_agree),
  };
  return cmocka_run_group_tests_name("view_gl", tests, setup, teardown);
}
