/* test_planet_loopback.c — the main job in small: overcast-server on the built-in procedural planet
 * (127.0.0.1, a free port, stepped by command) and a headless overcast-view fetching three epochs
 * over the wire and rendering them with GL at 96×54 from the main job's camera. The picture must be
 * a recognisable cloudy sky:
 *   - the CPU reference renderer draws the same received state (--save-state, then --state) within
 *     RMSE 1 on the 0–255 scale (the GL picture is not garbage that happens to look plausible);
 *   - the top rows are blue sky (blue well above red);
 *   - the lower half is cloud: a good share of near-white pixels, with structure (not one flat
 *     colour), and brighter than the sky above it.
 * Programs from $OC_BIN_DIR (else ../bin beside this test). Without a GL context the test skips,
 * unless OC_GL_REQUIRE=1 (CI: Mesa). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "oc_image.h"
#include "programs.h" /* oc_test_dirs, oc_test_run, oc_test_start */

#define W 96
#define H 54
#define CAMERA "45.5,-4,6000,260,-15,60" /* the main job's camera (scripts/run.sh) */

static char bin[2048], tmp[256];
static uint8_t *gl_rgb, *cpu_rgb;

static int setup(void **state) {
  (void)state;
  oc_test_dirs(bin, sizeof bin, NULL, 0);
  snprintf(tmp, sizeof tmp, "/tmp/oc_test_planet_XXXXXX");
  return mkdtemp(tmp) ? 0 : -1;
}

static int teardown(void **state) {
  (void)state;
  free(gl_rgb);
  free(cpu_rgb);
  char cmd[1024];
  snprintf(cmd, sizeof cmd, "[ -f '%s/server.pid' ] && kill $(cat '%s/server.pid') 2>/dev/null; rm -rf '%s'", tmp, tmp, tmp);
  (void)oc_test_run(cmd);
  return 0;
}

static void load(const char *dir, uint8_t **rgb) {
  char path[512], why[512], cam[256];
  int w = 0, h = 0;
  snprintf(path, sizeof path, "%s/%s/frame_0000.png", tmp, dir);
  if (oc_png_read(path, &w, &h, rgb, "overcast-camera", cam, sizeof cam, why, sizeof why) < 0) fail_msg("%s", why);
  assert_int_equal(w, W);
  assert_int_equal(h, H);
}

static void test_planet__loopback_cloudy_sky(void **state) {
  (void)state;
#if defined(__SANITIZE_ADDRESS__)
  /* The planet's first epochs box-filter the procedural field for τ at every coarse level: about
   * 5 s of CPU in the optimised build, many minutes under ASan. The gcc stage runs this test; the
   * sanitizer stage covers the same server, protocol and renderer code through tests/net (which
   * serves the procedural planet too) and the other GL tests. */
  printf("built with AddressSanitizer: skipped (the gcc stage runs it)\n");
  skip();
#endif
  char cmd[8192], pid[1100], ready[1100];
  snprintf(cmd, sizeof cmd,
           "'%s/overcast-server' --listen 127.0.0.1:0 --epoch-period 0 --threads 2 >'%s/addr' 2>'%s/server.log'", bin,
           tmp, tmp);
  snprintf(pid, sizeof pid, "%s/server.pid", tmp);
  snprintf(ready, sizeof ready, "grep -q 'listening on' '%s/addr'", tmp);
  assert_int_equal(oc_test_start(NULL, cmd, pid, ready, 300), 0);
  snprintf(cmd, sizeof cmd,
           "'%s/overcast-view' --connect $(sed -n 's/^listening on //p' '%s/addr') --step --wait-epochs 3 --budget 4 "
           "--timeout 600 --headless --renderer gl --camera " CAMERA " --size %dx%d --out '%s/gl' --save-state '%s/s.ocst' -q",
           bin, tmp, W, H, tmp, tmp);
  int r = oc_test_run(cmd);
  if (r != 0) {
    const char *req = getenv("OC_GL_REQUIRE");
    snprintf(cmd, sizeof cmd, "cat '%s/server.log'", tmp);
    (void)oc_test_run(cmd);
    if (req && req[0] == '1') fail_msg("overcast-view --connect --renderer gl exited %d", r);
    printf("no GL: skipped\n");
    skip();
  }
  snprintf(cmd, sizeof cmd,
           "'%s/overcast-view' --state '%s/s.ocst' --headless --renderer cpu --camera " CAMERA " --size %dx%d --out '%s/cpu' -q",
           bin, tmp, W, H, tmp);
  assert_int_equal(oc_test_run(cmd), 0);
  load("gl", &gl_rgb);
  load("cpu", &cpu_rgb);
  double rmse = oc_rgb8_rmse(gl_rgb, cpu_rgb, W, H);
  printf("GL vs CPU reference of the received state: RMSE %.3f\n", rmse);
  assert_true(rmse <= 1.0);

  /* sky: the top 15 % of rows */
  double r_sky = 0, b_sky = 0, l_sky = 0;
  int n_sky = 0;
  for (int y = 0; y < H * 15 / 100; y++)
    for (int x = 0; x < W; x++, n_sky++) {
      const uint8_t *p = gl_rgb + 3 * (y * W + x);
      r_sky += p[0];
      b_sky += p[2];
      l_sky += (p[0] + p[1] + p[2]) / 3.0;
    }
  r_sky /= n_sky, b_sky /= n_sky, l_sky /= n_sky;
  /* clouds: the lower half */
  double sum = 0, sum2 = 0;
  int white = 0, n = 0;
  for (int y = H / 2; y < H; y++)
    for (int x = 0; x < W; x++, n++) {
      const uint8_t *p = gl_rgb + 3 * (y * W + x);
      int lo = p[0] < p[1] ? (p[0] < p[2] ? p[0] : p[2]) : (p[1] < p[2] ? p[1] : p[2]);
      int hi = p[0] > p[1] ? (p[0] > p[2] ? p[0] : p[2]) : (p[1] > p[2] ? p[1] : p[2]);
      double l = (p[0] + p[1] + p[2]) / 3.0;
      sum += l;
      sum2 += l * l;
      if (lo > 150 && hi - lo < 50) white++;
    }
  double mean = sum / n, sd = sqrt(fmax(0.0, sum2 / n - mean * mean));
  printf("sky: mean R %.0f, B %.0f; lower half: mean %.0f, sd %.1f, %.0f %% near-white\n", r_sky, b_sky, mean, sd,
         100.0 * white / n);
  assert_true(b_sky > r_sky + 30.0);   /* blue sky */
  assert_true(white > n / 10);         /* clouds */
  assert_true(sd > 4.0);               /* with structure */
  assert_true(mean > l_sky);           /* brighter than the sky above */
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_planet__loopback_cloudy_sky)};
  return cmocka_run_group_tests_name("planet_loopback", tests, setup, teardown);
}
