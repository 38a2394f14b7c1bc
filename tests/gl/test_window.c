/* test_window.c — overcast-view --window driven like a user: in a virtual X server (Xvfb), keys
 * sent with xdotool. Skipped (not failed) where Xvfb or xdotool is missing, which CI is: neither is
 * a project dependency. Run where they are, it checks that:
 *   - the window renders, and a screenshot (P) equals the headless frame of the camera stored in it
 *     (the picture is tone-mapped on the GPU in the window, on the CPU headless), every pixel traced
 *     at full size (--frame-ms 0, and R turning the default reprojection off);
 *   - W flies forward (the next screenshot's camera moved) and --record saved the flight;
 *   - V changes the picture (the LOD view), and after cycling back, = (exposure up) brightens it;
 *   - a resized window renders at its new size;
 *   - dragging with the left mouse button turns the view;
 *   - Esc quits with status 0.
 * Programs from $OC_BIN_DIR (else ../bin beside this test), scenes from $OC_SOURCE_DIR. */
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

#include "oc_camera.h"
#include "oc_image.h"
#include "programs.h" /* oc_test_dirs, oc_test_run, oc_test_start */

static char bin[2048], src[2048], tmp[256];

typedef struct {
  int w, h;
  uint8_t *rgb;
  char camera[256];
} png_t;

static png_t shot[6], head;

static int setup(void **state) {
  (void)state;
  oc_test_dirs(bin, sizeof bin, src, sizeof src);
  snprintf(tmp, sizeof tmp, "/tmp/oc_test_window_XXXXXX");
  return mkdtemp(tmp) ? 0 : -1;
}

static int teardown(void **state) {
  (void)state;
  for (int i = 0; i < 6; i++) free(shot[i].rgb);
  free(head.rgb);
  char cmd[1024];
  snprintf(cmd, sizeof cmd, "[ -f '%s/xvfb.pid' ] && kill $(cat '%s/xvfb.pid') 2>/dev/null; rm -rf '%s'", tmp, tmp, tmp);
  (void)oc_test_run(cmd);
  return 0;
}

static void load(const char *path, png_t *p) {
  char why[512];
  p->camera[0] = '\0';
  if (oc_png_read(path, &p->w, &p->h, &p->rgb, "overcast-camera", p->camera, sizeof p->camera, why, sizeof why) < 0)
    fail_msg("%s", why);
}

static double mean(const png_t *p) {
  double s = 0;
  size_t n = (size_t)p->w * (size_t)p->h * 3;
  for (size_t i = 0; i < n; i++) s += p->rgb[i];
  return s / (double)n;
}

static void test_window__keys_screenshots_record(void **state) {
  (void)state;
  if (oc_test_run("command -v Xvfb >/dev/null && command -v xdotool >/dev/null") != 0) {
    printf("Xvfb or xdotool not installed: skipped\n");
    skip();
  }
  char cmd[16384];
  /* Xvfb picks a free display and writes its number; the viewer renders at 160×90. */
  char pid[1100], ready[1100];
  snprintf(cmd, sizeof cmd, "Xvfb -displayfd 3 -screen 0 320x240x24 -nolisten tcp 3>'%s/display' 2>'%s/xvfb.log'", tmp,
           tmp);
  snprintf(pid, sizeof pid, "%s/xvfb.pid", tmp);
  snprintf(ready, sizeof ready, "[ -s '%s/display' ]", tmp);
  assert_int_equal(oc_test_start(tmp, cmd, pid, ready, 50), 0);
#if defined(__SANITIZE_ADDRESS__)
  /* Mesa's GLX driver, unloaded by glfwTerminate() before LeakSanitizer runs, leaks a few blocks
   * that cannot be symbolised (so tests/lsan.supp cannot name them); the viewer's own code is
   * leak-checked headless by the other tests. */
  const char *asan_env = "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 ";
#else
  const char *asan_env = "";
#endif
  /* One script: start the viewer, wait until it has drawn (the title shows the frame time), press
   * the keys a user would, and give back the viewer's exit status. */
  snprintf(cmd, sizeof cmd,
           "export DISPLAY=:$(cat '%s/display'); cd '%s'; "
           "%s'%s/overcast-view' --window --scene scenes/analytic_sphere.json --size 160x90 --frame-ms 0 --out '%s/out' "
           "--record '%s/flight.txt' > '%s/view.log' 2>&1 & pid=$!; "
           "w=''; for i in $(seq 300); do w=$(xdotool search --name 'overcast-view' 2>/dev/null | head -1); "
           "[ -n \"$w\" ] && xdotool getwindowname $w | grep -q ' ms ' && break; sleep 0.1; done; "
           "[ -n \"$w\" ] || { kill $pid; exit 90; }; "
           "k() { xdotool key --window $w \"$@\"; sleep 0.7; }; "
           "k r; k h; k p; "                       /* 0: every pixel traced (R: reprojection off), no HUD */
           "xdotool keydown --window $w w; sleep 1; xdotool keyup --window $w w; sleep 0.5; k p; " /* 1: flown */
           "k v; k p; "                                                    /* 2: LOD view */
           "k v; k v; k v; k equal; k equal; k equal; k p; "              /* 3: normal, brighter */
           "xdotool windowsize --sync $w 200 100; sleep 1; k p; "         /* 4: resized */
           "xdotool mousemove --window $w 100 50 mousedown 1; sleep 0.3; "  /* mouse look: drag 60 px right */
           "for i in 1 2 3 4 5 6; do xdotool mousemove_relative 10 0; sleep 0.1; done; "
           "xdotool mouseup 1; sleep 0.7; k p; "                              /* 5: looked right */
           "k Escape; wait $pid",
           tmp, src, asan_env, bin, tmp, tmp, tmp);
  int rc = oc_test_run(cmd);
  snprintf(cmd, sizeof cmd, "cat '%s/view.log'; ls '%s/out'; cat '%s/flight.txt' | head -5", tmp, tmp, tmp);
  (void)oc_test_run(cmd);
  assert_int_equal(rc, 0);

  char path[512];
  for (int i = 0; i < 6; i++) {
    snprintf(path, sizeof path, "%s/out/screenshot_%04d.png", tmp, i);
    load(path, &shot[i]);
    printf("screenshot %d: %dx%d, camera %s, mean %.1f\n", i, shot[i].w, shot[i].h, shot[i].camera, mean(&shot[i]));
  }
  /* the window's picture is the headless picture of the same camera */
  snprintf(cmd, sizeof cmd,
           "cd '%s' && '%s/overcast-view' --headless --scene scenes/analytic_sphere.json --size 160x90 "
           "--camera-from '%s/out/screenshot_0000.png' --out '%s/head' -q",
           src, bin, tmp, tmp);
  assert_int_equal(oc_test_run(cmd), 0);
  snprintf(path, sizeof path, "%s/head/frame_0000.png", tmp);
  load(path, &head);
  assert_int_equal(shot[0].w, 160);
  assert_int_equal(shot[0].h, 90);
  double d0 = oc_rgb8_rmse(shot[0].rgb, head.rgb, 160, 90);
  printf("window vs headless (same camera): RMSE %.3f\n", d0);
  assert_true(d0 <= 0.5);
  assert_true(mean(&shot[0]) > 20.0);

  /* W flew forward: a new camera, and the flight was recorded */
  oc_camera_pose_t p0, p1;
  char why[256];
  assert_int_equal(oc_camera_parse(shot[0].camera, &p0, why, sizeof why), 0);
  assert_int_equal(oc_camera_parse(shot[1].camera, &p1, why, sizeof why), 0);
  oc_camera_t c0 = oc_camera_from_pose(p0), c1 = oc_camera_from_pose(p1);
  double moved = oc_dlen(oc_dsub(c1.pos, c0.pos));
  printf("flew %.1f m\n", moved);
  assert_true(moved > 100.0); /* speed = altitude (3 km) per second, for about a second */
  snprintf(cmd, sizeof cmd, "[ $(grep -c . '%s/flight.txt') -ge 3 ]", tmp);
  assert_int_equal(oc_test_run(cmd), 0);

  /* V: the LOD view differs; cycled back and three exposure steps up: brighter than before */
  double dv = oc_rgb8_rmse(shot[1].rgb, shot[2].rgb, 160, 90);
  printf("LOD view vs normal: RMSE %.1f; exposure ×1.95: mean %.1f → %.1f\n", dv, mean(&shot[1]), mean(&shot[3]));
  assert_true(dv > 5.0);
  assert_true(mean(&shot[3]) > mean(&shot[1]) + 5.0);

  /* resized: the picture follows the framebuffer */
  assert_int_equal(shot[4].w, 200);
  assert_int_equal(shot[4].h, 100);
  assert_true(mean(&shot[4]) > 20.0);

  /* dragging with the left button turned the view to the right (heading up), level as before */
  oc_camera_pose_t p5;
  assert_int_equal(oc_camera_parse(shot[5].camera, &p5, why, sizeof why), 0);
  printf("mouse look: heading %.2f → %.2f, pitch %.2f → %.2f\n", p1.heading, p5.heading, p1.pitch, p5.pitch);
  assert_true(p5.heading > p1.heading + 1.0 && p5.heading < p1.heading + 30.0);
  assert_true(fabs(p5.pitch - p1.pitch) < 0.5);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_window__keys_screenshots_record)};
  return cmocka_run_group_tests_name("window", tests, setup, teardown);
}
