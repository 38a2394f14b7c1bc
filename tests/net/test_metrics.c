/* test_metrics.c — overcast-server's /metrics end to end (server/net_metrics.c): the real binary on
 * 127.0.0.1 with --metrics-listen 127.0.0.1:0, scraped with curl and checked with promtool (both
 * required: CI installs them, scripts/install-deps.sh too); the figures agree with the control
 * "stats" and "sessions" replies taken around the scrape; a scrape waits while the world is busy
 * and is not left hanging by a shutdown; tokens guard it; clocked ticks fill the lateness histogram. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <cjson/cJSON.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "net_fixture.h"

static char tmpdir[256];

/*-*** Tools: curl and promtool ***/

static void require_tool(const char *tool) {
  char cmd[160];
  snprintf(cmd, sizeof cmd, "command -v %s >/dev/null 2>&1", tool);
  if (system(cmd) != 0)
    fail_msg("%s is not installed: this test needs it (bash scripts/install-deps.sh installs it; CI does)", tool);
}

/* curl's argv for GET http://127.0.0.1:port/path (auth: a bearer token or NULL), the body into
 * `body`, the status code on stdout. */
static void curl_argv(const char **argv, char *url, size_t url_cap, char *hdr, size_t hdr_cap, int port, const char *path,
                      const char *auth, const char *body) {
  snprintf(url, url_cap, "http://127.0.0.1:%d%s", port, path);
  int n = 0;
  argv[n++] = "curl";
  argv[n++] = "-s";
  argv[n++] = "--max-time";
  argv[n++] = "600";
  argv[n++] = "-o";
  argv[n++] = body;
  argv[n++] = "-w";
  argv[n++] = "%{http_code}";
  if (auth) {
    snprintf(hdr, hdr_cap, "Authorization: Bearer %s", auth);
    argv[n++] = "-H";
    argv[n++] = hdr;
  }
  argv[n++] = url;
  argv[n] = NULL;
}

/* Starts curl in the background, its status code into code_path. */
static pid_t scrape_start(int port, const char *path, const char *auth, const char *body, const char *code_path) {
  const char *argv[16];
  char url[128], hdr[400];
  curl_argv(argv, url, sizeof url, hdr, sizeof hdr, port, path, auth, body);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    FILE *f = freopen(code_path, "w", stdout);
    if (!f) _exit(126);
    execvp("curl", (char *const *)argv);
    _exit(127);
  }
  return pid;
}

/* The HTTP status of a scrape that ended (0: none, e.g. the connection closed). */
static int scrape_status(pid_t pid, const char *code_path) {
  int st;
  assert_int_equal(waitpid(pid, &st, 0), pid);
  char *code = read_file(code_path);
  int c = atoi(code);
  free(code);
  return c;
}

/* GET /path; @return the body (malloc'd) and the status in *status. */
static char *scrape(int port, const char *path, const char *auth, int *status) {
  char body[300], code[300];
  snprintf(body, sizeof body, "%s/body", tmpdir);
  snprintf(code, sizeof code, "%s/code", tmpdir);
  unlink(body);
  *status = scrape_status(scrape_start(port, path, auth, body, code), code);
  return read_file(body);
}

/* `promtool check metrics` on the text: it must exit 0 and print nothing. */
static void promtool_clean(const char *text) {
  char in[300], out[300], cmd[800];
  snprintf(in, sizeof in, "%s/scrape.txt", tmpdir);
  snprintf(out, sizeof out, "%s/promtool.txt", tmpdir);
  write_file(in, text);
  snprintf(cmd, sizeof cmd, "promtool check metrics <'%s' >'%s' 2>&1", in, out);
  int rc = system(cmd);
  char *said = read_file(out);
  if (rc != 0 || said[0]) fail_msg("promtool check metrics: status %d: %s", rc, said);
  free(said);
}

/*-*** Reading the figures ***/

/* The value of the sample whose name and labels are exactly `sample` ("name" or "name{k=\"v\"}"). */
static double metric(const char *text, const char *sample) {
  size_t n = strlen(sample);
  for (const char *p = text; p && *p; p = strchr(p, '\n'), p = p ? p + 1 : NULL)
    if (!strncmp(p, sample, n) && p[n] == ' ') return strtod(p + n + 1, NULL);
  fail_msg("no sample %s in the scrape", sample);
  return NAN;
}

/* One control request's reply member `key` (a cJSON tree, to cJSON_Delete()). */
static cJSON *control_json(int port, const char *token, const char *json, const char *key) {
  int32_t st;
  char *r = control(port, token, json, &st);
  if (st != 0) fail_msg("%s: status %d: %s", json, (int)st, r ? r : "?");
  cJSON *j = cJSON_Parse(r);
  free(r);
  assert_non_null(j);
  cJSON *m = cJSON_DetachItemFromObjectCaseSensitive(j, key);
  cJSON_Delete(j);
  assert_non_null(m);
  return m;
}

static double jnum(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!cJSON_IsNumber(v)) fail_msg("no number \"%s\" in the reply", key);
  return v->valuedouble;
}

/* The session `id`'s object in a "sessions" array. */
static const cJSON *session_of(const cJSON *sessions, double id) {
  const cJSON *t;
  cJSON_ArrayForEach(t, sessions) if (jnum(t, "id") == id) return t;
  fail_msg("no session %.0f", id);
  return NULL;
}

/* The second line overcast-server prints: "metrics on 127.0.0.1:PORT". */
static int metrics_port(server_t *s) {
  char line[256] = "";
  assert_non_null(fgets(line, sizeof line, s->out));
  assert_non_null(strstr(line, "metrics on 127.0.0.1:"));
  int port = atoi(strrchr(line, ':') + 1);
  assert_true(port > 0);
  return port;
}

/* overcast-server with `extra` and --metrics-listen 127.0.0.1:0 (log: as start_server_log()), once
 * curl and promtool are known to be there. @return the metrics port. */
static int start_with_metrics(server_t *s, const char *const *extra, const char *log) {
  require_tool("curl");
  require_tool("promtool");
  const char *argv[24];
  int n = 0;
  for (; extra[n]; n++) argv[n] = extra[n];
  argv[n++] = "--metrics-listen";
  argv[n++] = "127.0.0.1:0";
  argv[n] = NULL;
  start_server_log(s, argv, log);
  return metrics_port(s);
}

static void touch(const char *path) {
  FILE *g = fopen(path, "w");
  assert_non_null(g);
  fclose(g);
}

/*-*** Tests ***/

/* promtool finds the scrape clean, and its figures are those of the stats and sessions replies
 * taken just before and after (equal where nothing moved; between them where a counter moved). */
static void test_metrics__promtool_and_stats(void **state) {
  (void)state;
  server_t s;
  const char *extra[] = {"--scene", scene_sphere, "--max-viewers", "1", NULL};
  int mport = start_with_metrics(&s, extra, NULL);
  viewer_t a, b;
  char why[256];
  viewer_open(&a, s.port, 8u << 20, NULL);
  assert_int_equal(ocv_conn_wait_ready(a.c, 30, why, sizeof why), 0);
  for (int i = 1; i <= 2; i++) { /* one at a time: a step while a state is unacknowledged skips the viewer */
    step(s.port, 1);
    assert_int_equal(viewer_wait(&a, i, 120), 0);
  }
  viewer_open(&b, s.port, 8u << 20, NULL); /* the viewer limit: refused, counted under "viewers" */
  assert_int_equal(ocv_conn_wait_ready(b.c, 30, why, sizeof why), 1);
  assert_int_equal(b.closed_code, OCP_CODE_FULL);
  ocv_conn_close(b.c);
  double id = (double)ocp_viewer_welcome(ocv_conn_session(a.c))->session;

  cJSON *w1 = control_json(s.port, NULL, "{\"op\":\"stats\"}", "world");
  cJSON *s1 = control_json(s.port, NULL, "{\"op\":\"sessions\"}", "sessions");
  int status;
  char *text = scrape(mport, "/metrics", NULL, &status);
  cJSON *w2 = control_json(s.port, NULL, "{\"op\":\"stats\"}", "world");
  cJSON *s2 = control_json(s.port, NULL, "{\"op\":\"sessions\"}", "sessions");
  assert_int_equal(status, 200);
  promtool_clean(text);

  static const struct {
    const char *sample, *key;
  } same[] = {
      {"overcast_ticks_total", "ticks"},
      {"overcast_ticks_late_total", "late_ticks"},
      {"overcast_epoch", "epoch"},
      {"overcast_production_queue_bricks", "queue"},
      {"overcast_bricks_produced_total", "bricks_produced"},
      {"overcast_brick_requests_total", "brick_requests"},
      {"overcast_brick_cache_hits_total", "cache_hits"},
      {"overcast_brick_cache_misses_total", "cache_misses"},
      {"overcast_brick_cache_bytes", "cache_bytes"},
      {"overcast_brick_production_errors_total", "produce_errors"},
      {"overcast_viewers", "viewers"},
      {"overcast_budget_granted_bytes", "granted_bytes"},
      {"overcast_budget_lingering_bytes", "lingering_budget"},
      {"overcast_held_state_bytes", "held_bytes"},
      {"overcast_resumes_total", "resumes"},
  };
  for (size_t i = 0; i < sizeof same / sizeof same[0]; i++) {
    double m = metric(text, same[i].sample), a1 = jnum(w1, same[i].key), a2 = jnum(w2, same[i].key);
    if (!(m == a1 && a1 == a2)) fail_msg("%s = %.17g, stats %s: %.17g then %.17g", same[i].sample, m, same[i].key, a1, a2);
  }
  assert_true(metric(text, "overcast_ticks_total") == 2);
  assert_true(metric(text, "overcast_bricks_produced_total") > 0);
  const cJSON *lim = cJSON_GetObjectItemCaseSensitive(w1, "limits");
  assert_true(metric(text, "overcast_budget_total_bytes") == jnum(lim, "total_budget"));
  assert_true(metric(text, "overcast_budget_max_viewer_bytes") == jnum(lim, "max_budget"));
  const cJSON *bs = cJSON_GetObjectItemCaseSensitive(w1, "brick_seconds");
  assert_true(metric(text, "overcast_brick_production_seconds_count") == jnum(bs, "count"));
  assert_true(metric(text, "overcast_brick_production_seconds_bucket{le=\"+Inf\"}") == jnum(bs, "count"));
  /* counters that the control connections themselves move: between the two replies */
  static const char *moving[][2] = {{"overcast_connections_accepted_total", "accepted"},
                                    {"overcast_connections_closed_errors_total", "closed_errors"}};
  for (size_t i = 0; i < 2; i++) {
    double m = metric(text, moving[i][0]);
    if (!(jnum(w1, moving[i][1]) <= m && m <= jnum(w2, moving[i][1])))
      fail_msg("%s = %.0f, not within the stats replies around it", moving[i][0], m);
  }
  /* refusals by reason, every one the stats reply lists */
  const cJSON *r1 = cJSON_GetObjectItemCaseSensitive(w1, "refusals"), *r2 = cJSON_GetObjectItemCaseSensitive(w2, "refusals"), *r;
  int reasons = 0;
  cJSON_ArrayForEach(r, r1) {
    char sample[128];
    snprintf(sample, sizeof sample, "overcast_refusals_total{reason=\"%s\"}", r->string);
    double m = metric(text, sample);
    assert_true(r->valuedouble <= m && m <= jnum(r2, r->string));
    reasons++;
  }
  assert_int_equal(reasons, 10); /* OCS_REFUSALS: connections ... shutdown, proxy, draining */
  assert_true(metric(text, "overcast_refusals_total{reason=\"viewers\"}") == 1);
  /* sessions by state: the viewer is ready; none lingers, as the stats reply says */
  assert_true(metric(text, "overcast_sessions{state=\"ready\"}") >= 1);
  assert_true(metric(text, "overcast_sessions{state=\"lingering\"}") == jnum(w1, "lingering"));
  /* the viewer's own figures, as the sessions reply has them */
  char sample[128];
  const cJSON *v1 = session_of(s1, id), *v2 = session_of(s2, id);
  snprintf(sample, sizeof sample, "overcast_viewer_sent_bytes_total{session=\"%.0f\"}", id);
  double sent = metric(text, sample);
  assert_true(jnum(v1, "bytes_out") <= sent && sent <= jnum(v2, "bytes_out") && sent > 0);
  snprintf(sample, sizeof sample, "overcast_viewer_epochs_total{session=\"%.0f\"}", id);
  assert_true(metric(text, sample) == jnum(v1, "epochs") && jnum(v1, "epochs") == 2);
  snprintf(sample, sizeof sample, "overcast_viewer_budget_bytes{session=\"%.0f\"}", id);
  assert_true(metric(text, sample) == jnum(v1, "budget") && metric(text, sample) == (double)a.granted);
  snprintf(sample, sizeof sample, "overcast_viewer_resident_bytes{session=\"%.0f\"}", id);
  assert_true(metric(text, sample) == jnum(v1, "resident"));
  /* the HUD's figures (client/view_main.c): the grant, what the kept states hold, the bytes in */
  ocp_viewer_stats_t hud;
  ocp_viewer_stats(ocv_conn_session(a.c), &hud);
  assert_true(metric(text, sample) == (double)hud.resident_bytes);
  snprintf(sample, sizeof sample, "overcast_viewer_sent_bytes_total{session=\"%.0f\"}", id);
  double hud_sent = metric(text, sample); /* the same bytes; a keepalive may be on the way */
  if (!((double)hud.bytes_in <= hud_sent && hud_sent - (double)hud.bytes_in < 64))
    fail_msg("the HUD counts %.0f bytes in, the metrics %.0f out", (double)hud.bytes_in, hud_sent);
  assert_true(metric(text, "process_resident_memory_bytes") > 0);
  free(text);
  cJSON_Delete(w1), cJSON_Delete(w2), cJSON_Delete(s1), cJSON_Delete(s2);

  text = scrape(mport, "/", NULL, &status); /* only /metrics is served */
  assert_int_equal(status, 404);
  free(text);
  ocv_conn_close(a.c);
  assert_int_equal(stop_server(&s), 0);
}

/* A scrape while a step runs waits for it (the figures are read only while the world is free):
 * held by --step-gate, it gets nothing until the test releases the step, then the step's figures.
 * A scrape still waiting when the server stops is answered or closed, not left hanging. */
static void test_metrics__waits_for_the_world(void **state) {
  (void)state;
  char gate[300], body[300], code[300], log[300];
  snprintf(log, sizeof log, "%s/server.log", tmpdir);
  snprintf(gate, sizeof gate, "%s/gate", tmpdir);
  snprintf(body, sizeof body, "%s/held_body", tmpdir);
  snprintf(code, sizeof code, "%s/held_code", tmpdir);
  unlink(gate);
  server_t s;
  const char *extra[] = {"--scene", scene_sphere, "--step-gate", gate, NULL};
  int mport = start_with_metrics(&s, extra, log);
  char why[512];
  int replied = 0;
  ocv_conn_t *ctl = control_open(s.port, &replied);
  assert_int_equal(ocv_conn_control(ctl, 1, "{\"op\":\"step\",\"epochs\":1}"), 0); /* held by the gate */
  assert_int_equal(ocv_conn_flush(ctl, 5.0, why, sizeof why), 0);
  wait_log(log, "): step", 1); /* the request was handled: the step has begun */
  pid_t curl = scrape_start(mport, "/metrics", NULL, body, code);
  for (int i = 0; i < 20; i++) { /* 2 s of the test's clock: the held step cannot end, nor the scrape */
    assert_int_equal(ocv_conn_poll(ctl, 0.1, why, sizeof why), 0);
    assert_int_equal(waitpid(curl, NULL, WNOHANG), 0);
  }
  assert_int_equal(replied, 0);
  touch(gate); /* released */
  assert_int_equal(scrape_status(curl, code), 200);
  char *text = read_file(body);
  promtool_clean(text);
  assert_true(metric(text, "overcast_ticks_total") == 1); /* read after the step, not during it */
  free(text);
  while (!replied) assert_int_equal(ocv_conn_poll(ctl, 0.1, why, sizeof why), 0);

  unlink(gate); /* the next step is held again, and the server stops under a waiting scrape */
  replied = 0;
  assert_int_equal(ocv_conn_control(ctl, 2, "{\"op\":\"step\",\"epochs\":1}"), 0);
  assert_int_equal(ocv_conn_flush(ctl, 5.0, why, sizeof why), 0);
  wait_log(log, "): step", 2);
  curl = scrape_start(mport, "/metrics", NULL, body, code);
  sleep_us(500000); /* most likely waiting by now; if not yet connected, refused: either way it ends */
  kill(s.pid, SIGTERM);
  int st = scrape_status(curl, code); /* before the step ends: stopping answers it, or closes it */
  assert_true(st == 503 || st == 0);
  touch(gate);
  ocv_conn_close(ctl);
  assert_int_equal(wait_exit(&s), 0); /* stopping already: a second SIGTERM would kill it */
  unlink(gate);
}

/* With tokens, a scrape presents the control token (the viewer token is not enough). */
static void test_metrics__token(void **state) {
  (void)state;
  server_t s;
  const char *extra[] = {"--scene", scene_sphere, "--token", "viewer-secret", "--control-token", "control-secret", NULL};
  int mport = start_with_metrics(&s, extra, NULL);
  static const struct {
    const char *auth;
    int want;
  } cases[] = {{NULL, 401}, {"viewer-secret", 401}, {"control-secre", 401}, {"control-secret", 200}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    int status;
    char *text = scrape(mport, "/metrics", cases[i].auth, &status);
    if (status != cases[i].want) fail_msg("Bearer %s: HTTP %d, want %d", cases[i].auth ? cases[i].auth : "(none)", status, cases[i].want);
    if (status == 200) promtool_clean(text);
    free(text);
  }
  assert_int_equal(stop_server(&s), 0);
}

/* Clocked ticks: each one's lateness is counted (once per tick that sent states), and the stats
 * reply's count is never ahead of the scrape that follows it. */
static void test_metrics__clocked_lateness(void **state) {
  (void)state;
  server_t s;
  const char *extra[] = {"--scene", scene_sphere, "--epoch-period", "0.5", NULL};
  int mport = start_with_metrics(&s, extra, NULL);
  viewer_t a;
  char why[256];
  viewer_open(&a, s.port, 4u << 20, NULL);
  assert_int_equal(ocv_conn_wait_ready(a.c, 30, why, sizeof why), 0);
  assert_int_equal(viewer_wait(&a, 2, 300), 0);
  cJSON *w = control_json(s.port, NULL, "{\"op\":\"stats\"}", "world");
  int status;
  char *text = scrape(mport, "/metrics", NULL, &status);
  assert_int_equal(status, 200);
  promtool_clean(text);
  double n = metric(text, "overcast_tick_lateness_seconds_count");
  assert_true(n >= 2); /* the viewer got two states: two ticks sent them */
  assert_true(n <= metric(text, "overcast_ticks_total"));
  assert_true(metric(text, "overcast_tick_lateness_seconds_bucket{le=\"+Inf\"}") == n);
  assert_true(metric(text, "overcast_tick_lateness_seconds_sum") >= 0);
  assert_true(jnum(cJSON_GetObjectItemCaseSensitive(w, "tick_lateness"), "count") <= n);
  free(text);
  cJSON_Delete(w);
  ocv_conn_close(a.c);
  assert_int_equal(stop_server(&s), 0);
}

int main(void) {
  const char *src = getenv("OC_SOURCE_DIR");
  snprintf(scene_sphere, sizeof scene_sphere, "%s/scenes/analytic_sphere.json", src ? src : ".");
  snprintf(tmpdir, sizeof tmpdir, "/tmp/oc_metrics_XXXXXX");
  if (!mkdtemp(tmpdir)) return 1;
  signal(SIGPIPE, SIG_IGN);
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_metrics__promtool_and_stats, net_teardown),
      cmocka_unit_test_teardown(test_metrics__waits_for_the_world, net_teardown),
      cmocka_unit_test_teardown(test_metrics__token, net_teardown),
      cmocka_unit_test_teardown(test_metrics__clocked_lateness, net_teardown),
  };
  int r = cmocka_run_group_tests(tests, NULL, NULL);
  char cmd[300];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
  return r;
}
