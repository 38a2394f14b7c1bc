/* test_cluster.c — front-ends sharing one brick store (overcast-server --redis; docs/scale-out.md):
 * two servers of one scene and a real redis-server on loopback. A viewer of the second front-end
 * gets, verified, what the first one made, and the second makes almost none of it; while Redis is
 * gone both serve from their own production, every state verified; when it is back, sharing
 * resumes. Then scripts/cluster.sh's cluster (redis-server, two front-ends, HAProxy with PROXY v2):
 * a viewer whose front-end dies reconnects through HAProxy to the other one. */
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

/* A Redis that stops answering (SIGSTOP: it still accepts connections) costs a front-end with the
 * default deadline (200 ms, a tenth of the period) nothing but that: production starts at the
 * deadline, or without a lookup once the connection is judged stuck; the viewer's states go on. */
static void test_cluster__redis_stopped(void **state) {
  (void)state;
  redis_proc_t r;
  assert_int_equal(redis_start(&r, 0), 0);
  children[0] = r.pid;
  char addr[64];
  snprintf(addr, sizeof addr, "127.0.0.1:%d", r.port);
  const char *extra[] = {"--scene", scene_sphere, "--epoch-period", "0.25", "--redis", addr, "--handshake-rate", "1000", NULL};
  server_t a;
  start_server(&a, extra);
  children[1] = a.pid;
  for (int i = 0; i < 200 && !redis_up(a.port); i++) redis_sleep_ms(100);
  viewer_t v;
  viewer_open(&v, a.port, 4u << 20, NULL);
  assert_int_equal(viewer_wait(&v, 2, 120.0), 0);
  kill(r.pid, SIGSTOP);
  double made = stat_of(a.port, "bricks_produced");
  assert_int_equal(viewer_wait(&v, v.states + 8, 120.0), 0); /* states go on, each verified */
  assert_true(stat_of(a.port, "bricks_produced") > made);
  assert_true(share_of(a.port, "cut_short") + share_of(a.port, "skipped") > 0);
  kill(r.pid, SIGCONT);
  for (int i = 0; i < 300 && !redis_up(a.port); i++) redis_sleep_ms(100);
  assert_true(redis_up(a.port));
  ocv_conn_close(v.c);
  children[1] = 0;
  assert_int_equal(stop_server(&a), 0);
  children[0] = 0;
  redis_stop(&r);
}

/*-*** scripts/cluster.sh: redis-server, front-ends and HAProxy ***/

static char cluster_dir[64];

static void cluster(const char *cmd, const char *args) {
  char line[8192];
  snprintf(line, sizeof line, "bash %s/scripts/cluster.sh %s --dir %s --bin %s %s >> %s/cluster.txt 2>&1",
           getenv("OC_SOURCE_DIR"), cmd, cluster_dir, getenv("OC_BIN_DIR"), args, cluster_dir);
  if (system(line) != 0) fail_msg("%s failed: see %s/cluster.txt", line, cluster_dir);
}

static int cluster_teardown(void **state) {
  (void)state;
  if (cluster_dir[0]) cluster("stop", "");
  return 0;
}

/* The port and process id of front-end i (1-based), from the files cluster.sh writes. */
static void front_end(int i, int *port, pid_t *pid) {
  char path[128], name[16], want[16];
  snprintf(want, sizeof want, "front%d", i);
  long v;
  *port = 0;
  *pid = 0;
  snprintf(path, sizeof path, "%s/ports", cluster_dir);
  FILE *f = fopen(path, "r");
  assert_non_null(f);
  while (fscanf(f, "%15s %ld", name, &v) == 2)
    if (!strcmp(name, want)) *port = (int)v;
  fclose(f);
  snprintf(path, sizeof path, "%s/pids", cluster_dir);
  assert_non_null(f = fopen(path, "r"));
  while (fscanf(f, "%15s %ld", name, &v) == 2)
    if (!strcmp(name, want)) *pid = (pid_t)v;
  fclose(f);
  assert_true(*port > 0 && *pid > 0);
}

/* Viewer sessions a front-end serves now. */
static int viewers_on(int port) {
  int32_t status;
  char *r = control(port, NULL, "{\"op\":\"sessions\"}", &status);
  assert_int_equal(status, 0);
  int n = 0;
  for (const char *p = r; (p = strstr(p, "\"viewer\"")) != NULL; p++) n++;
  free(r);
  return n;
}

/* A viewer behind HAProxy whose front-end dies reconnects through HAProxy, lands on the other
 * front-end as a new session (sessions live in one process: docs/scale-out.md) and goes on
 * receiving states, each verified. */
static void test_cluster__failover_behind_haproxy(void **state) {
  (void)state;
  snprintf(cluster_dir, sizeof cluster_dir, "/tmp/oc_cluster_XXXXXX");
  assert_non_null(mkdtemp(cluster_dir));
  char args[4200];
  int hport = redis_free_port();
  snprintf(args, sizeof args, "-n 2 --port %d -- --scene %s --epoch-period 0.25 --threads 1 --handshake-rate 1000", hport,
           scene_sphere);
  cluster("start", args);
  viewer_t v;
  viewer_open(&v, hport, 4u << 20, NULL);
  assert_int_equal(viewer_wait(&v, 4, 120.0), 0);
  int p1, p2;
  pid_t k1, k2;
  front_end(1, &p1, &k1);
  front_end(2, &p2, &k2);
  int on1 = viewers_on(p1), on2 = viewers_on(p2);
  assert_int_equal(on1 + on2, 1);
  int survivor = on1 ? p2 : p1;
  kill(on1 ? k1 : k2, SIGKILL); /* its front-end dies */
  char why[512];
  int r = 0;
  for (int i = 0; i < 200 && r == 0; i++) r = ocv_conn_poll(v.c, 0.05, why, sizeof why);
  assert_true(r != 0); /* the viewer saw it */
  int states = v.states;
  r = -1;
  for (int i = 0; i < 20 && r != 0; i++) { /* HAProxy's health check marks it down within a second or two */
    r = ocv_conn_reconnect(v.c, 5.0, why, sizeof why);
    if (r != 0) redis_sleep_ms(250);
  }
  assert_int_equal(r, 0);
  ocp_camera_t cam = sphere_camera(160, 90);
  assert_int_equal(ocv_conn_camera(v.c, &cam), 0);
  assert_int_equal(viewer_wait(&v, states + 4, 120.0), 0);
  assert_int_equal(v.welcomes, 2);
  assert_int_equal(v.resumed, 0); /* a new session on the other front-end */
  assert_int_equal(viewers_on(survivor), 1);
  ocv_conn_close(v.c);
  cluster("stop", "");
  cluster_dir[0] = 0;
}

int main(void) {
  signal(SIGPIPE, SIG_IGN);
  const char *src = getenv("OC_SOURCE_DIR");
  snprintf(scene_sphere, sizeof scene_sphere, "%s/scenes/analytic_sphere.json", src ? src : ".");
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cluster__made_once_then_without_redis, teardown),
      cmocka_unit_test_teardown(test_cluster__redis_stopped, teardown),
      cmocka_unit_test_teardown(test_cluster__failover_behind_haproxy, cluster_teardown),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
