/* test_admission.c — the front door of overcast-server: fair budgets (a greedy viewer, connected or
 * vanished, cannot lock the others out), lingering sessions giving their budget back, the
 * lingering caps, per-address connection limits and the handshake rate (a connect storm from one
 * address), and every refusal named in one line, in ERROR and in the server's log. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "net_fixture.h"
#include "test_main.h"

#define MIB (1ull << 20)
#define GREEDY (1ull << 60) /* 2^40 MiB */

/* Closes with a reset (SO_LINGER 0): no GOODBYE, the session lingers for resume. */
static void raw_reset(int fd) {
  struct linger l = {1, 0};
  setsockopt(fd, SOL_SOCKET, SO_LINGER, &l, sizeof l);
  close(fd);
}

/* Waits until the server's stats have `key` = n, asking from 127.0.0.9 (its own handshake
 * bucket) at 4 a second (under the default rate of 10). */
static void wait_stat(int port, const char *key, double n) {
  for (int i = 0; i < 480; i++) {
    int32_t st;
    char *r = control_from("127.0.0.9", port, NULL, "{\"op\":\"stats\"}", &st);
    assert_int_equal(st, 0);
    double got = json_num(r, NULL, key);
    free(r);
    if (got == n) return;
    sleep_us(250000);
  }
  fail_msg("stats never had %s = %g", key, n);
}

static void wait_lingering(int port, int n) { wait_stat(port, "lingering", n); }

/* Waits until the viewer's WELCOME or its refusal has arrived: 0 welcomed, 1 refused. */
static int viewer_admitted(viewer_t *v) {
  char why[512];
  int r = ocv_conn_wait_ready(v->c, 30.0, why, sizeof why);
  if (r < 0) fail_msg("viewer: %s", why);
  if (r == 1) print_message("viewer refused: %s\n", v->closed_text);
  return r;
}

static int file_has(const char *path, const char *text) {
  FILE *f = fopen(path, "r");
  if (!f) return 0;
  char line[2048];
  int found = 0;
  while (!found && fgets(line, sizeof line, f)) found = strstr(line, text) != NULL;
  fclose(f);
  return found;
}

/* A HELLO for 2^40 MiB, then a reset: on default settings it got a fair share, not the total, and
 * right after it three viewers asking 64 MiB are each welcomed with at least 16 MiB. */
static void test_admission__greedy_then_vanish(void **state) {
  (void)state;
  server_t s = sphere_server(NULL);
  int fd = raw_connect(s.port), code;
  uint64_t greedy = raw_hello(fd, GREEDY, &code);
  assert_int_equal(code, OCP_CODE_OK);
  assert_true(greedy == 1ull << 30); /* a quarter of the default 4 GiB */
  raw_reset(fd);
  wait_lingering(s.port, 1);
  viewer_t v[3];
  for (int i = 0; i < 3; i++) {
    viewer_open(&v[i], s.port, 64 * MIB, NULL);
    assert_int_equal(viewer_admitted(&v[i]), 0);
    assert_true(v[i].granted >= 16 * MIB);
  }
  step(s.port, 1);
  for (int i = 0; i < 3; i++) {
    assert_int_equal(viewer_wait(&v[i], 1, 120), 0);
    ocv_conn_close(v[i].c);
  }
  assert_int_equal(stop_server(&s), 0);
}

/* Where the total is short, the lingering greedy session gives its budget back (oldest first),
 * then a viewer gets the largest budget that fits above the minimum, and FULL comes only when not
 * even the minimum fits, named in ERROR and in the log. */
static void test_admission__lingering_give_back_then_largest_fit(void **state) {
  (void)state;
  server_t s;
  char log[64];
  snprintf(log, sizeof log, "/tmp/oc_admission_%d.log", (int)getpid());
  const char *extra[] = {"--scene", scene_sphere, "--total-budget", "96", "--max-budget", "64", "--linger-budget", "64", NULL};
  start_server_log(&s, extra, log);
  int fd = raw_connect(s.port), code;
  assert_true(raw_hello(fd, GREEDY, &code) == 64 * MIB);
  raw_reset(fd);
  wait_lingering(s.port, 1);
  viewer_t a, b, c;
  viewer_open(&a, s.port, 64 * MIB, NULL); /* 32 MiB free: the lingering 64 MiB go back first */
  assert_int_equal(viewer_admitted(&a), 0);
  assert_true(a.granted == 64 * MIB);
  wait_lingering(s.port, 0);
  viewer_open(&b, s.port, 64 * MIB, NULL); /* the largest that fits */
  assert_int_equal(viewer_admitted(&b), 0);
  assert_true(b.granted == 32 * MIB);
  viewer_open(&c, s.port, 64 * MIB, NULL); /* nothing left */
  assert_int_equal(viewer_admitted(&c), 1);
  assert_int_equal(c.closed_code, OCP_CODE_FULL);
  assert_non_null(strstr(c.closed_text, "bytes of viewer budget left"));
  step(s.port, 1);
  assert_int_equal(viewer_wait(&a, 1, 120), 0);
  assert_int_equal(viewer_wait(&b, 1, 120), 0);
  int32_t st;
  char *r = control(s.port, NULL, "{\"op\":\"stats\"}", &st);
  assert_true(json_num(r, "\"refusals\"", "budget") == 1);
  free(r);
  close_and_stop(&s, a.c, b.c, c.c, NULL);
  assert_true(file_has(log, "lingering session let go: session"));
  assert_true(file_has(log, c.closed_text));
  unlink(log);
}

/* A viewer holding the per-viewer maximum stays connected and keeps acknowledging; a second one
 * is still welcomed with a usable budget (default settings). */
static void test_admission__greedy_connected(void **state) {
  (void)state;
  server_t s = sphere_server(NULL);
  viewer_t g, v;
  viewer_open(&g, s.port, GREEDY, NULL);
  assert_int_equal(viewer_admitted(&g), 0);
  assert_true(g.granted == 1ull << 30);
  step(s.port, 1);
  assert_int_equal(viewer_wait(&g, 1, 120), 0);
  viewer_open(&v, s.port, 64 * MIB, NULL);
  assert_int_equal(viewer_admitted(&v), 0);
  assert_true(v.granted == 64 * MIB);
  for (int e = 2; e <= 3; e++) { /* one epoch at a time: each is acknowledged before the next */
    step(s.port, 1);
    if (viewer_wait(&g, e, 120) != 0) fail_msg("the greedy viewer: closed (%u: %s) after %d states", g.closed_code, g.closed_text, g.states);
    assert_int_equal(viewer_wait(&v, e - 1, 120), 0);
  }
  assert_int_equal(g.closed_code, 0);
  close_and_stop(&s, g.c, v.c, NULL);
}

/* --max-lingering 1: a second vanished viewer makes the first one go; and a session over the
 * lingering budget does not linger at all. */
static void test_admission__lingering_caps(void **state) {
  (void)state;
  server_t s = sphere_server("--max-lingering", "1", "--linger-budget", "16", NULL);
  int code, f1 = raw_connect(s.port), f2 = raw_connect(s.port), f3 = raw_connect(s.port);
  assert_true(raw_hello(f1, 8 * MIB, &code) == 8 * MIB);
  assert_true(raw_hello(f2, 8 * MIB, &code) == 8 * MIB);
  assert_true(raw_hello(f3, 32 * MIB, &code) == 32 * MIB);
  raw_reset(f1);
  wait_lingering(s.port, 1);
  raw_reset(f2); /* the cap of one: f1's session goes */
  raw_reset(f3); /* 32 MiB > the 16 MiB lingering budget: not kept */
  for (int i = 0; i < 480; i++) {
    int32_t st;
    char *r = control_from("127.0.0.9", s.port, NULL, "{\"op\":\"stats\"}", &st);
    double viewers = json_num(r, NULL, "viewers"), lingering = json_num(r, NULL, "lingering");
    double lb = json_num(r, NULL, "lingering_budget");
    free(r);
    if (viewers == 1) {
      assert_true(lingering == 1 && lb == 8.0 * MIB);
      break;
    }
    if (i == 479) fail_msg("still %g viewers", viewers);
    sleep_us(250000);
  }
  assert_int_equal(stop_server(&s), 0);
}

/* 500 connections from 127.0.0.1 that never say HELLO: those past the per-address limit are
 * refused at once, naming it, and a viewer from 127.0.0.2 is still welcomed and served. */
static void test_admission__connect_storm(void **state) {
  (void)state;
  server_t s = sphere_server(NULL);
  enum { STORM = 500 };
  static int fds[STORM];
  for (int i = 0; i < STORM; i++) fds[i] = raw_connect_from(1, s.port);
  char text[1100];
  assert_int_equal(raw_read_close_code(fds[STORM - 1], 30, text, sizeof text), OCP_CODE_FULL);
  assert_non_null(strstr(text, "too many connections from 127.0.0.1"));
  viewer_t v;
  viewer_open_from(&v, "127.0.0.2", s.port, 16 * MIB, NULL, 0);
  assert_int_equal(viewer_admitted(&v), 0);
  int32_t st;
  char *r = control_from("127.0.0.2", s.port, NULL, "{\"op\":\"step\",\"epochs\":1}", &st);
  assert_int_equal(st, 0);
  free(r);
  assert_int_equal(viewer_wait(&v, 1, 120), 0);
  r = control_from("127.0.0.2", s.port, NULL, "{\"op\":\"stats\"}", &st);
  assert_true(json_num(r, "\"refusals\"", "per_address") >= STORM - 32 - 1);
  free(r);
  for (int i = 0; i < STORM - 1; i++) close(fds[i]);
  close_and_stop(&s, v.c, NULL);
}

/* The handshake rate: a bucket of --max-per-address handshakes refilled at --handshake-rate per
 * second; quick reconnects past it are refused, naming the rate, and other addresses are not. */
static void test_admission__handshake_rate(void **state) {
  (void)state;
  server_t s = sphere_server("--max-per-address", "4", "--handshake-rate", "0.1", NULL);
  int code;
  for (int i = 0; i < 4; i++) { /* within the bucket (a refill takes 10 s) */
    int fd = raw_connect_from(3, s.port);
    raw_hello(fd, 4 * MIB, &code);
    assert_int_equal(code, OCP_CODE_OK);
    close(fd);
  }
  wait_stat(s.port, "admitted", 1); /* the four are closed (the one counted is the stats request) */
  char text[1100];
  assert_int_equal(raw_read_close_code(raw_connect_from(3, s.port), 30, text, sizeof text), OCP_CODE_FULL);
  assert_non_null(strstr(text, "too many new connections from 127.0.0.3"));
  int fd = raw_connect_from(4, s.port); /* another address has its own bucket */
  raw_hello(fd, 4 * MIB, &code);
  assert_int_equal(code, OCP_CODE_OK);
  close(fd);
  assert_int_equal(stop_server(&s), 0);
}

OC_TEST_MAIN(net_setup, NULL,
             cmocka_unit_test_teardown(test_admission__greedy_then_vanish, net_teardown),
             cmocka_unit_test_teardown(test_admission__lingering_give_back_then_largest_fit, net_teardown),
             cmocka_unit_test_teardown(test_admission__greedy_connected, net_teardown),
             cmocka_unit_test_teardown(test_admission__lingering_caps, net_teardown),
             cmocka_unit_test_teardown(test_admission__connect_storm, net_teardown),
             cmocka_unit_test_teardown(test_admission__handshake_rate, net_teardown))
