/* test_cluster.c — front-ends sharing one brick store (overcast-server --redis; docs/scale-out.md):
 * two servers of one scene and a real redis-server on loopback. A viewer of the second front-end
 * gets, verified, what the first one made, and the second makes almost none of it; while Redis is
 * gone both serve from their own production, every state verified; when it is back, sharing
 * resumes. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "net_fixture.h"
#include "server/redis_fixture.h"

static double stat_of(int port, const char *key) {
  int32_t status;
  char *r = control(port, NULL, "{\"op\":\"stats\"}", &status);
  assert_int_equal(status, 0);
  double v = json_num(r, NULL, key);
  free(r);
  return v;
}

static double share_of(int port, const char *key) {
  int32_t status;
  char *r = control(port, NULL, "{\"op\":\"stats\"}", &status);
  assert_int_equal(status, 0);
  if (!strstr(r, "\"share\"")) fail_msg("no share in the stats of port %d: %.300s", port, r);
  double v = json_num(r, "\"share\"", key);
  free(r);
  return v;
}

/* 1 while the front-end's Redis connection is up (a JSON boolean). */
static int redis_up(int port) {
  int32_t status;
  char *r = control(port, NULL, "{\"op\":\"stats\"}", &status);
  if (status != 0) fail_msg("stats of port %d: %s", port, r);
  const char *p = strstr(r, "\"redis_up\":");
  if (p) p += strlen("\"redis_up\":");
  while (p && (*p == ' ' || *p == '\t')) p++;
  int up = p && strncmp(p, "true", 4) == 0;
  free(r);
  return up;
}

/* What a failed assertion leaves running is stopped here, or ctest would wait on their pipes. */
static pid_t children[3];
static int teardown(void **state) {
  (void)state;
  for (int i = 0; i < 3; i++)
    if (children[i] > 0) {
      kill(children[i], SIGCONT);
      kill(children[i], SIGKILL);
      waitpid(children[i], NULL, 0);
      children[i] = 0;
    }
  return 0;
}

static void sun(int port, int lat, int lon) {
  char req[96];
  snprintf(req, sizeof req, "{\"op\":\"sun\",\"lat\":%d,\"lon\":%d}", lat, lon);
  int32_t status;
  free(control(port, NULL, req, &status));
  assert_int_equal(status, 0);
}

/* A viewer of the sphere's camera on `port`, each state verified by the client, until its tree
 * is whole: nothing queued and nothing made or taken from Redis for five states running. What it
 * holds then does not depend on the machine's speed. */
static void view(int port, uint64_t budget) {
  viewer_t v;
  viewer_open(&v, port, budget, NULL);
  int settled = 0;
  double last = -1;
  while (settled < 5) {
    assert_int_equal(viewer_wait(&v, v.states + 1, 120.0), 0);
    double now = stat_of(port, "bricks_produced") + share_of(port, "taken");
    settled = now == last && stat_of(port, "queue") == 0 ? settled + 1 : 0;
    last = now;
    assert_true(v.states < 1000);
  }
  ocv_conn_close(v.c);
}

static void start_front_end(server_t *s, int redis_port, const char *log) {
  char addr[64];
  snprintf(addr, sizeof addr, "127.0.0.1:%d", redis_port);
  /* the lookup waits for every answer (a generous deadline), so what is shared does not depend on
   * the machine's speed; the epochs are on the clock, as sharing needs */
  const char *extra[] = {"--scene", scene_sphere, "--epoch-period", "0.25", "--redis", addr, "--redis-deadline", "30000",
                         "--handshake-rate", "1000", NULL}; /* the test polls stats */
  start_server_log(s, extra, log);
}

static void test_cluster__made_once_then_without_redis(void **state) {
  (void)state;
  redis_proc_t r;
  assert_int_equal(redis_start(&r, 0), 0);
  server_t a, b;
  children[0] = r.pid;
  start_front_end(&a, r.port, getenv("OC_CLUSTER_LOG_A"));
  children[1] = a.pid;
  start_front_end(&b, r.port, getenv("OC_CLUSTER_LOG_B"));
  children[2] = b.pid;
  for (int i = 0; i < 200 && !(redis_up(a.port) && redis_up(b.port)); i++) redis_sleep_ms(100);
  view(a.port, 4u << 20);
  double made_a = stat_of(a.port, "bricks_produced");
  view(b.port, 4u << 20);
  double made_b = stat_of(b.port, "bricks_produced"), taken_b = share_of(b.port, "taken");
  print_message("front-end A made %.0f bricks; B made %.0f and took %.0f from Redis\n", made_a, made_b, taken_b);
  assert_true(made_a > 100);
  assert_true(taken_b >= 0.9 * made_a);
  assert_true(made_b <= 0.02 * made_a);
  /* Redis gone: a sun that moved on B alone is made there, every state verified, no lookup tried */
  int port = r.port;
  kill(r.pid, SIGKILL);
  waitpid(r.pid, NULL, 0);
  r.pid = children[0] = 0;
  for (int i = 0; i < 200 && redis_up(b.port); i++) redis_sleep_ms(100);
  sun(b.port, 10, 30);
  double before = stat_of(b.port, "bricks_produced");
  view(b.port, 4u << 20);
  assert_true(stat_of(b.port, "bricks_produced") > before + 100);
  assert_true(share_of(b.port, "skipped") > 0);
  /* Redis back on its port: the front-ends reconnect and share again, under a sun both agree on */
  assert_int_equal(redis_start(&r, port), 0);
  children[0] = r.pid;
  for (int i = 0; i < 400 && !(redis_up(a.port) && redis_up(b.port)); i++) redis_sleep_ms(100);
  assert_true(redis_up(a.port) && redis_up(b.port));
  sun(a.port, -20, 50);
  sun(b.port, -20, 50);
  double taken_before = share_of(b.port, "taken"), made_before = stat_of(b.port, "bricks_produced");
  view(a.port, 4u << 20);
  view(b.port, 4u << 20);
  double taken = share_of(b.port, "taken") - taken_before, made = stat_of(b.port, "bricks_produced") - made_before;
  print_message("after Redis came back: B took %.0f bricks and made %.0f\n", taken, made);
  assert_true(taken > 100 && made <= 0.02 * taken);
  children[1] = children[2] = 0;
  assert_int_equal(stop_server(&a), 0);
  assert_int_equal(stop_server(&b), 0);
  children[0] = 0;
  redis_stop(&r);
}

int main(void) {
  signal(SIGPIPE, SIG_IGN);
  const char *src = getenv("OC_SOURCE_DIR");
  snprintf(scene_sphere, sizeof scene_sphere, "%s/scenes/analytic_sphere.json", src ? src : ".");
  const struct CMUnitTest tests[] = {cmocka_unit_test_teardown(test_cluster__made_once_then_without_redis, teardown)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
