/* test_audit.c — overcast-server --audit-log end to end (server/net_audit.c): every control change
 * (weather, time, pause, resume, sun, step, reload, disconnect), accepted or refused, appends one
 * line that cJSON parses back, with the UTC time, the peer and session, the op, its arguments and
 * the outcome; read-only requests (stats, sessions) and requests with no valid op write nothing;
 * the file is appended to, never truncated. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <cjson/cJSON.h>
#include <ctype.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "net_fixture.h"

/* "2025-01-31T23:59:59.123Z" */
static int is_iso8601_utc(const char *t) {
  static const char shape[] = "dddd-dd-ddTdd:dd:dd.dddZ";
  if (strlen(t) != sizeof shape - 1) return 0;
  for (size_t i = 0; shape[i]; i++)
    if (shape[i] == 'd' ? !isdigit((unsigned char)t[i]) : t[i] != shape[i]) return 0;
  return 1;
}

typedef struct {
  const char *json, *op;
  int ok;                 /* the outcome the line must record */
  const char *arg, *value; /* an argument the line must carry (a string value), or NULL */
} request_t;

static void test_audit__one_line_per_change(void **state) {
  (void)state;
  char path[128];
  snprintf(path, sizeof path, "/tmp/oc_audit_%d.log", (int)getpid());
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs("{\"earlier\":true}\n", f); /* a line of an earlier run: appended to, never truncated */
  fclose(f);
  server_t s;
  const char *extra[] = {"--audit-log", path, NULL}; /* the procedural planet: weather applies */
  start_server(&s, extra);
  viewer_t v;
  char why[512];
  viewer_open(&v, s.port, 4u << 20, NULL);
  assert_int_equal(ocv_conn_wait_ready(v.c, 30, why, sizeof why), 0);
  char kick[64];
  snprintf(kick, sizeof kick, "{\"op\":\"disconnect\",\"session\":%u}", ocp_viewer_welcome(ocv_conn_session(v.c))->session);
  const request_t req[] = {
      {"{\"op\":\"weather\",\"preset\":\"storm\",\"seconds\":60}", "weather", 1, "preset", "storm"},
      {"{\"op\":\"weather\",\"preset\":\"hail\"}", "weather", 0, "preset", "hail"},
      {"{\"op\":\"stats\"}", NULL, 1, NULL, NULL},
      {"{\"op\":\"time\",\"set\":3600,\"scale\":2}", "time", 1, NULL, NULL},
      {"{\"op\":\"pause\"}", "pause", 1, NULL, NULL},
      {"{\"op\":\"resume\"}", "resume", 1, NULL, NULL},
      {"{\"op\":\"sun\",\"lat\":10,\"lon\":20}", "sun", 1, NULL, NULL},
      {"{\"op\":\"sun\",\"dir\":[0,0,0]}", "sun", 0, NULL, NULL},
      {"{\"op\":\"sessions\"}", NULL, 1, NULL, NULL},
      {"{\"op\":\"step\",\"epochs\":1}", "step", 1, NULL, NULL},
      {"{\"op\":\"fly\"}", NULL, 0, NULL, NULL},
      {"{\"op\":\"disconnect\",\"session\":999}", "disconnect", 0, NULL, NULL},
      {kick, "disconnect", 1, NULL, NULL},
      {"{\"op\":\"reload\"}", "reload", 1, NULL, NULL},
  };
  const size_t nreq = sizeof req / sizeof req[0];
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL};
  ocv_conn_t *ctl = NULL;
  if (ocv_conn_open(&ctl, "127.0.0.1", s.port, &cd, NULL, 5.0, why, sizeof why) < 0) fail_msg("control: %s", why);
  assert_int_equal(ocv_conn_wait_ready(ctl, 5.0, why, sizeof why), 0);
  uint32_t session = ocp_viewer_welcome(ocv_conn_session(ctl))->session;
  for (size_t i = 0; i < nreq; i++) {
    char *reply = NULL;
    int32_t st = -1;
    if (ocv_control_request(ctl, req[i].json, 300.0, &reply, &st, why, sizeof why) < 0) fail_msg("%s: %s", req[i].json, why);
    if ((st == 0) != req[i].ok) fail_msg("%s: status %d: %s", req[i].json, (int)st, reply);
    free(reply);
  }
  ocv_conn_close(ctl);
  ocv_conn_close(v.c);
  assert_int_equal(stop_server(&s), 0);

  f = fopen(path, "r");
  assert_non_null(f);
  char line[4096];
  assert_non_null(fgets(line, sizeof line, f));
  assert_string_equal(line, "{\"earlier\":true}\n");
  for (size_t i = 0; i < nreq; i++) {
    if (!req[i].op) continue; /* read-only, or no op: not logged */
    if (!fgets(line, sizeof line, f)) fail_msg("no line for %s", req[i].json);
    cJSON *e = cJSON_Parse(line);
    if (!cJSON_IsObject(e)) fail_msg("not a JSON object: %s", line);
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(e, "time"), *peer = cJSON_GetObjectItemCaseSensitive(e, "peer"),
                *sid = cJSON_GetObjectItemCaseSensitive(e, "session"), *op = cJSON_GetObjectItemCaseSensitive(e, "op"),
                *args = cJSON_GetObjectItemCaseSensitive(e, "args"), *ok = cJSON_GetObjectItemCaseSensitive(e, "ok"),
                *err = cJSON_GetObjectItemCaseSensitive(e, "error");
    if (!cJSON_IsString(t) || !is_iso8601_utc(t->valuestring)) fail_msg("time: %s", line);
    if (!cJSON_IsString(peer) || strncmp(peer->valuestring, "127.0.0.1:", 10) != 0) fail_msg("peer: %s", line);
    if (!cJSON_IsNumber(sid) || sid->valuedouble != (double)session) fail_msg("session (want %u): %s", session, line);
    if (!cJSON_IsString(op) || strcmp(op->valuestring, req[i].op) != 0) fail_msg("op (want %s): %s", req[i].op, line);
    if (!cJSON_IsObject(args) || cJSON_GetObjectItemCaseSensitive(args, "op")) fail_msg("args: %s", line);
    /* the arguments are the request's other members, as given */
    cJSON *asked = cJSON_Parse(req[i].json);
    cJSON_DeleteItemFromObjectCaseSensitive(asked, "op");
    if (!cJSON_Compare(asked, args, 1)) fail_msg("args are not the request's (%s): %s", req[i].json, line);
    cJSON_Delete(asked);
    if (req[i].arg) {
      const cJSON *a = cJSON_GetObjectItemCaseSensitive(args, req[i].arg);
      assert_true(cJSON_IsString(a) && !strcmp(a->valuestring, req[i].value));
    }
    if (!(cJSON_IsBool(ok) && cJSON_IsTrue(ok) == req[i].ok)) fail_msg("ok (want %d): %s", req[i].ok, line);
    if (req[i].ok ? err != NULL : !(cJSON_IsString(err) && err->valuestring[0])) fail_msg("error: %s", line);
    cJSON_Delete(e);
  }
  if (fgets(line, sizeof line, f)) fail_msg("a line too many: %s", line);
  fclose(f);
  unlink(path);
}

int main(void) {
  (void)scene_sphere; /* the fixture's; this test serves the procedural planet, whose weather changes */
  signal(SIGPIPE, SIG_IGN);
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_audit__one_line_per_change, net_teardown),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
