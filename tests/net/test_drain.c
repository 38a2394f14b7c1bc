/* test_drain.c — drains and reconnects (server/net_server.c ocs_server_drain(), net_house.c;
 * docs/operations.md, "Drains"): `drain` tells a viewer GOODBYE RECONNECT with a delay, refuses a
 * new viewer with the reason "draining", and the server exits 0 once the viewer left; a viewer
 * that never leaves is closed at --drain-timeout and the server still exits 0; a second SIGTERM
 * stops at once; a viewer told to reconnect comes back, with backoff, to a new server on the same
 * port and verifies its states there. Waits are for messages, log lines and exits, never sleeps. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "oc_backoff.h"

#include "net_fixture.h"
#include "test_main.h"

/* Polls a viewer until the server closed it (at most 60 s); its close code. */
static uint32_t wait_closed(viewer_t *v) {
  char why[512];
  for (int i = 0; i < 600 && !v->closed_code; i++)
    if (ocv_conn_poll(v->c, 0.1, why, sizeof why) != 0) break;
  return v->closed_code;
}

/* Steps until the viewer holds n states: a step that ran before its camera reached the server
 * brings it nothing, so one more is asked (no sleep to guess when the camera is there). */
static void step_until(int port, viewer_t *v, int n) {
  char why[512];
  assert_int_equal(ocv_conn_wait_ready(v->c, 60, why, sizeof why), 0);
  assert_int_equal(ocv_conn_flush(v->c, 5, why, sizeof why), 0);
  for (int i = 0; i < 30 && v->states < n; i++) {
    step(port, 1);
    int r = viewer_wait(v, v->states + 1, 10);
    assert_true(r == 0 || r == OC_EIO); /* OC_EIO: not within 10 s; another step */
  }
  assert_true(v->states >= n);
}

static void log_path(char *out, size_t cap, const char *what) {
  snprintf(out, cap, "/tmp/oc_net_drain_%s_%d.log", what, (int)getpid());
}

static void test_drain__ctl_drain(void **state) {
  (void)state;
  char log[256], audit[256];
  log_path(log, sizeof log, "ctl");
  log_path(audit, sizeof audit, "audit");
  const char *extra[] = {"--scene", scene_sphere, "--audit-log", audit, NULL};
  server_t s;
  start_server_log(&s, extra, log);
  viewer_t a, b;
  viewer_open(&a, s.port, 4u << 20, NULL);
  step_until(s.port, &a, 1);

  int32_t st;
  char *r = control(s.port, NULL, "{\"op\":\"drain\"}", &st);
  assert_int_equal(st, 0);
  assert_true(json_num(r, NULL, "viewers") == 1);
  free(r);
  /* a new viewer is refused while the first has not left: GOODBYE RECONNECT, reason draining */
  char why[512];
  viewer_open(&b, s.port, 4u << 20, NULL);
  assert_int_equal(ocv_conn_wait_ready(b.c, 60, why, sizeof why), 1);
  assert_int_equal(b.closed_code, OCP_CODE_RECONNECT);
  assert_non_null(strstr(b.closed_text, "draining"));
  ocv_conn_close(b.c);
  r = control(s.port, NULL, "{\"op\":\"stats\"}", &st); /* control clients still welcome */
  assert_int_equal(st, 0);
  assert_true(json_num(r, "\"refusals\"", "draining") == 1);
  free(r);

  assert_int_equal(wait_closed(&a), OCP_CODE_RECONNECT);
  assert_int_equal(ocp_reconnect_delay_ms(a.closed_text), 1000);
  ocv_conn_close(a.c);
  assert_int_equal(wait_exit(&s), 0);
  wait_log(log, "drained: every viewer has left", 1);
  char *t = read_file(audit);
  assert_non_null(strstr(t, "\"op\":\"drain\""));
  free(t);
  unlink(log);
  unlink(audit);
}

/* A server draining (SIGTERM sent) with --drain-timeout `timeout`, logging to d->log, and a raw
 * viewer welcomed there before that never reads nor leaves (socket d->fd). */
typedef struct {
  server_t s;
  char log[256];
  int fd;
} drained_t;

static void drain_raw(drained_t *d, const char *name, const char *timeout) {
  log_path(d->log, sizeof d->log, name);
  const char *extra[] = {"--scene", scene_sphere, "--drain-timeout", timeout, NULL};
  start_server_log(&d->s, extra, d->log);
  int code;
  d->fd = raw_connect(d->s.port);
  assert_true(raw_hello(d->fd, 4u << 20, &code) > 0);
  kill(d->s.pid, SIGTERM);
}

/* The server has exited: its log names `last`; the socket and the log go. */
static void drained_end(drained_t *d, const char *last) {
  wait_log(d->log, last, 1);
  close(d->fd);
  unlink(d->log);
}

/* A viewer that never leaves: the drain's deadline closes it. */
static void test_drain__timeout(void **state) {
  (void)state;
  drained_t d;
  drain_raw(&d, "timeout", "1");
  assert_int_equal(wait_exit(&d.s), 0);
  drained_end(&d, "drain timeout: closing 1 viewer(s)");
}

/* A second SIGTERM during a drain stops at once (the drain timeout would be 10 minutes). */
static void test_drain__second_sigterm(void **state) {
  (void)state;
  drained_t d;
  drain_raw(&d, "twice", "600");
  wait_log(d.log, "SIGTERM: draining", 1);
  kill(d.s.pid, SIGTERM);
  assert_int_equal(wait_exit(&d.s), 0);
  drained_end(&d, "SIGTERM: shutting down");
}

/* Told to reconnect, the viewer waits its backoff and comes back to a new server on the same
 * port (no session to resume there: a new one), and verifies its states; nothing is left. */
static void test_drain__reconnect_to_restarted(void **state) {
  (void)state;
  char log[256];
  log_path(log, sizeof log, "restart");
  const char *extra[] = {"--scene", scene_sphere, NULL};
  server_t s;
  start_server(&s, extra);
  viewer_t v;
  viewer_open(&v, s.port, 4u << 20, NULL);
  step_until(s.port, &v, 2);
  kill(s.pid, SIGTERM);
  assert_int_equal(wait_closed(&v), OCP_CODE_RECONNECT);
  assert_int_equal(wait_exit(&s), 0); /* it left: the drain is over */

  char listen[64];
  snprintf(listen, sizeof listen, "127.0.0.1:%d", s.port);
  const char *again[] = {"--scene", scene_sphere, "--listen", listen, NULL};
  server_t s2;
  start_server_log(&s2, again, log);
  assert_int_equal(s2.port, s.port);
  oc_backoff_t bo;
  oc_backoff_init(&bo, ocp_reconnect_delay_ms(v.closed_text), 7);
  char why[512];
  int ok = 0;
  for (int attempt = 0; attempt < 8 && !ok; attempt++) {
    sleep_us(1000L * oc_backoff_next(&bo)); /* the backoff under test, not a synchronisation */
    v.closed_code = 0;
    ok = ocv_conn_reconnect(v.c, 5.0, why, sizeof why) == 0 && ocv_conn_wait_ready(v.c, 60, why, sizeof why) == 0;
  }
  assert_true(ok);
  assert_int_equal(v.resumed, 0); /* the old session died with the old server */
  ocp_camera_t cam = sphere_camera(160, 90);
  assert_int_equal(ocv_conn_camera(v.c, &cam), 0);
  step_until(s2.port, &v, v.states + 2); /* each state's checksum verified */
  ocv_conn_close(v.c);
  assert_int_equal(stop_server(&s2), 0);
  wait_log(log, "drained: every viewer has left", 1);
  unlink(log);
}

/* The viewer's network thread (overcast-view's): one line per attempt. */
typedef struct {
  pthread_mutex_t mu;
  int lines;
  char last[512];
} net_log_t;

static void net_log(void *ctx, const char *line) {
  net_log_t *l = ctx;
  pthread_mutex_lock(&l->mu);
  l->lines++;
  snprintf(l->last, sizeof l->last, "%s", line);
  pthread_mutex_unlock(&l->mu);
}

static ocv_net_status_t net_status(ocv_net_t *n) {
  ocv_net_status_t st;
  ocv_net_status(n, &st);
  return st;
}

/* Steps until the thread has published n states (each verified by its checksum in the session). */
static void net_step_until(int port, ocv_net_t *n, uint64_t states) {
  for (int i = 0; i < 60 && net_status(n).states < states; i++) {
    if (net_status(n).connected) step(port, 1);
    sleep_us(100000); /* polling the thread's status, not a synchronisation */
  }
  assert_true(net_status(n).states >= states);
}

/* overcast-view's network thread (seed, retry_attempts: 0 for its default; logging to lg) with
 * `states` verified states from a server that was then drained (SIGTERM) and has exited 0. */
static ocv_net_t *net_thread_drained(server_t *s, net_log_t *lg, uint64_t seed, uint32_t retry_attempts, uint64_t states) {
  const char *extra[] = {"--scene", scene_sphere, NULL};
  start_server(s, extra);
  ocv_net_desc_t d = {.port = s->port, .seed = seed, .retry_attempts = retry_attempts, .on_log = net_log, .ctx = lg,
                      .viewer = {.role = OCP_ROLE_VIEWER, .budget = 4u << 20, .slot_bytes = 2048, .record_bytes = 32,
                                 .max_depth = 21, .width = 160, .height = 90}};
  ocv_net_t *n = NULL;
  assert_int_equal(ocv_net_start(&n, &d), 0);
  ocp_camera_t cam = sphere_camera(160, 90);
  assert_int_equal(ocv_net_set_camera(n, &cam), 0);
  net_step_until(s->port, n, states);
  kill(s->pid, SIGTERM);
  assert_int_equal(wait_exit(s), 0);
  return n;
}

/* overcast-view's network thread across a drain and a restart on the same port: told to
 * reconnect, it waits (one line per attempt), finds the new server and keeps receiving verified
 * states; the draining server exits 0 because it left. */
static void test_drain__net_thread_follows_restart(void **state) {
  (void)state;
  server_t s;
  net_log_t lg = {.mu = PTHREAD_MUTEX_INITIALIZER};
  ocv_net_t *n = net_thread_drained(&s, &lg, 3, 0, 2); /* the thread left: the drain is over */
  char listen[64];
  snprintf(listen, sizeof listen, "127.0.0.1:%d", s.port);
  const char *again[] = {"--scene", scene_sphere, "--listen", listen, NULL};
  server_t s2;
  start_server(&s2, again);
  uint64_t before = net_status(n).states;
  net_step_until(s2.port, n, before + 2);
  ocv_net_status_t st = net_status(n);
  assert_false(st.gave_up);
  assert_true(st.welcomes >= 2);
  assert_int_equal(st.viewer.over_budget, 0); /* and each state matched its checksum, or it would have closed */
  pthread_mutex_lock(&lg.mu);
  assert_true(lg.lines >= 1);
  pthread_mutex_unlock(&lg.mu);
  ocv_net_stop(n);
  assert_int_equal(stop_server(&s2), 0);
}

/* No server comes back: the thread gives up after its attempts with one clear line, and stops. */
static void test_drain__net_thread_gives_up(void **state) {
  (void)state;
  server_t s;
  net_log_t lg = {.mu = PTHREAD_MUTEX_INITIALIZER};
  ocv_net_t *n = net_thread_drained(&s, &lg, 5, 2, 1);
  for (int i = 0; i < 600 && !net_status(n).gave_up; i++) sleep_us(100000);
  ocv_net_status_t st = net_status(n);
  assert_true(st.gave_up);
  assert_non_null(strstr(st.error, "gave up after 2 reconnect attempts"));
  pthread_mutex_lock(&lg.mu);
  assert_int_equal(lg.lines, 3); /* attempt 1 of 2, attempt 2 of 2, gave up */
  assert_non_null(strstr(lg.last, "gave up"));
  pthread_mutex_unlock(&lg.mu);
  ocv_net_stop(n);
}

OC_TEST_MAIN(net_setup, NULL,
             cmocka_unit_test_teardown(test_drain__ctl_drain, net_teardown),
             cmocka_unit_test_teardown(test_drain__timeout, net_teardown),
             cmocka_unit_test_teardown(test_drain__second_sigterm, net_teardown),
             cmocka_unit_test_teardown(test_drain__reconnect_to_restarted, net_teardown),
             cmocka_unit_test_teardown(test_drain__net_thread_follows_restart, net_teardown),
             cmocka_unit_test_teardown(test_drain__net_thread_gives_up, net_teardown))
