/* test_camera_path.c — recorded camera paths (client/camera_path.c): exact round trip through the
 * file, interpolation (longitude and heading the short way round), clamping, and errors that name
 * the file and line. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "test_main.h"
#include "camera_path.h"
#include "oc_err.h"

static oc_camera_pose_t pose(double lat, double lon, double alt, double h, double p, double f) {
  return (oc_camera_pose_t){{lat, lon, alt}, h, p, f};
}

static void test_camera_path__sample_and_round_trip(void **state) {
  (void)state;
  ocv_path_t p, q;
  ocv_path_init(&p);
  assert_int_equal(ocv_path_add(&p, 0.0, pose(45, 179, 2000, 350, -5, 60)), 0);
  assert_int_equal(ocv_path_add(&p, 2.0, pose(47, -179, 4000, 10, 5, 40)), 0);
  assert_int_equal(ocv_path_add(&p, 2.0, pose(0, 0, 0, 0, 0, 60)), OC_EINVAL); /* not after */
  oc_camera_pose_t o;
  assert_int_equal(ocv_path_sample(&p, 1.0, &o), 0);
  assert_true(fabs(o.geo.lat - 46) < 1e-12 && fabs(o.geo.alt - 3000) < 1e-9);
  assert_true(fabs(fabs(o.geo.lon) - 180) < 1e-9); /* across the date line, not through 0° */
  assert_true(fabs(o.heading - 360) < 1e-9 || fabs(o.heading) < 1e-9); /* across north */
  assert_true(fabs(o.pitch) < 1e-12 && fabs(o.fov - 50) < 1e-12);
  assert_int_equal(ocv_path_sample(&p, -5, &o), 0);
  assert_true(o.geo.lat == 45);
  assert_int_equal(ocv_path_sample(&p, 99, &o), 0);
  assert_true(o.geo.lat == 47);
  char file[] = "/tmp/oc_path_XXXXXX", why[256];
  int fd = mkstemp(file);
  assert_true(fd >= 0);
  close(fd);
  assert_int_equal(ocv_path_save(&p, file, why, sizeof why), 0);
  ocv_path_init(&q);
  assert_int_equal(ocv_path_load(&q, file, why, sizeof why), 0);
  assert_int_equal(q.count, 2);
  assert_memory_equal(q.t, p.t, 2 * sizeof *p.t);
  assert_memory_equal(q.pose, p.pose, 2 * sizeof *p.pose);
  assert_true(ocv_path_duration(&q) == 2.0);
  ocv_path_free(&q);
  ocv_path_free(&p);
  remove(file);
}

static void expect_load_error(const char *text, const char *msg) {
  char file[] = "/tmp/oc_path_XXXXXX", why[256] = "";
  int fd = mkstemp(file);
  assert_true(fd >= 0);
  assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
  close(fd);
  ocv_path_t p;
  ocv_path_init(&p);
  assert_true(ocv_path_load(&p, file, why, sizeof why) < 0);
  if (!strstr(why, msg) || !strstr(why, file)) fail_msg("\"%s\": got \"%s\", want \"%s\"", text, why, msg);
  assert_int_equal(p.count, 0);
  remove(file);
}

static void test_camera_path__errors(void **state) {
  (void)state;
  expect_load_error("", "no camera keys");
  expect_load_error("# only a comment\n\n", "no camera keys");
  expect_load_error("0 45,0,2000,0,0,60\nx 45,0,2000,0,0,60\n", ":2: expected a time");
  expect_load_error("1 45,0,2000,0,0,60\n0.5 45,0,2000,0,0,60\n", ":2: time 0.5 is not after");
  expect_load_error("0 45,0\n", ":1:");
  ocv_path_t p;
  char why[256];
  ocv_path_init(&p);
  assert_int_equal(ocv_path_load(&p, "/nonexistent/path.txt", why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, "/nonexistent/path.txt: cannot open"));
  oc_camera_pose_t o;
  assert_int_equal(ocv_path_sample(&p, 0, &o), OC_EINVAL);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_camera_path__sample_and_round_trip),
             cmocka_unit_test(test_camera_path__errors))
