/* test_budget.c — BUDGET end to end (docs/protocol.md "BUDGET", docs/operations.md "Rebalancing
 * budgets"): a version-3 viewer lowered by the control "budget" op stays within the budget in
 * force at every epoch (the session's own count, and ours: the larger of the budgets in force
 * before and after each state) and its store shrinks; refusals are named (no such session, a
 * control session, a version-1 viewer, below the minimum, above what admission can give); a
 * version-1 viewer is never sent BUDGET nor lowered; admission lowers a greedy version-3 viewer to
 * a fair share when a new viewer needs room, admits the new one smaller at once and raises it
 * once the room is free; each budget op writes an audit line. At most 8 stepped epochs a test. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "net_fixture.h"
#include "test_main.h"

#define MIB (1ull << 20)

/* A viewer that follows the budget in force (the budget event) and checks every state. */
typedef struct {
  ocv_conn_t *c;
  int states;
  uint64_t epoch;
  uint64_t in_force;     /* WELCOME's budget, then each budget event's */
  uint64_t before;       /* in force when the last state began */
  int budget_events;
  uint64_t over;         /* states whose window exceeded the budget in force (ours) */
  uint64_t resident_max_after; /* the largest window once the last budget event came */
  uint32_t session;
  char closed[256];
} bviewer_t;

static void bv_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  bviewer_t *v = ctx;
  (void)resumed;
  v->in_force = v->before = w->budget;
  v->session = w->session;
}

static void bv_budget(void *ctx, const oc_budget_t *g) {
  bviewer_t *v = ctx;
  v->in_force = g->budget;
  v->budget_events++;
  v->resident_max_after = 0;
}

static void bv_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  bviewer_t *v = ctx;
  (void)bricks;
  ocp_viewer_stats_t st;
  ocp_viewer_stats(ocv_conn_session(v->c), &st);
  uint64_t allowed = v->before > v->in_force ? v->before : v->in_force;
  if (st.resident_bytes > allowed) v->over++;
  if (st.resident_bytes > v->resident_max_after) v->resident_max_after = st.resident_bytes;
  v->before = v->in_force;
  v->states++;
  v->epoch = s->epoch;
}

static void bv_closed(void *ctx, uint32_t code, const char *text) {
  bviewer_t *v = ctx;
  snprintf(v->closed, sizeof v->closed, "%u %s", (unsigned)code, text);
}

static void bv_open(bviewer_t *v, int port, uint64_t budget, int max_version) {
  memset(v, 0, sizeof *v);
  ocp_viewer_desc_t d = {.role = OCP_ROLE_VIEWER, .budget = budget, .max_depth = 21, .width = 160, .height = 90,
                         .caps = OCP_CAP_DICT, .lean = 1, .max_version = (uint16_t)max_version};
  ocp_viewer_events_t ev = {.ctx = v, .welcome = bv_welcome, .state = bv_state, .closed = bv_closed, .budget = bv_budget};
  char why[512];
  if (ocv_conn_create(&v->c, "127.0.0.1", port, &d, &ev, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  if (ocv_conn_reconnect(v->c, 5.0, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  ocp_camera_t cam = sphere_camera(160, 90);
  assert_int_equal(ocv_conn_camera(v->c, &cam), 0);
  int r = ocv_conn_wait_ready(v->c, 30.0, why, sizeof why);
  if (r != 0) fail_msg("viewer not welcomed: %s %s", why, v->closed);
}

/* Steps one epoch and waits for each viewer's state of it. */
static void step_all(int port, bviewer_t *const *v, int n) {
  step(port, 1);
  for (int i = 0; i < n; i++) {
    char why[512];
    int want = v[i]->states + 1;
    for (int k = 0; k < 400 && v[i]->states < want; k++) {
      int r = ocv_conn_poll(v[i]->c, 0.05, why, sizeof why);
      if (r != 0) fail_msg("viewer %d: %s (%s)", i, why, v[i]->closed);
    }
    if (v[i]->states < want) fail_msg("viewer %d: no state after a step", i);
  }
}

static char *budget_op(int port, uint32_t session, uint64_t bytes, int32_t *st) {
  char json[160];
  snprintf(json, sizeof json, "{\"op\":\"budget\",\"session\":%u,\"bytes\":%llu}", (unsigned)session, (unsigned long long)bytes);
  return control(port, NULL, json, st);
}

static void expect_refused(int port, uint32_t session, uint64_t bytes, const char *text) {
  int32_t st;
  char *r = budget_op(port, session, bytes, &st);
  if (st != OCP_CODE_REQUEST || !strstr(r, text)) fail_msg("budget %u %llu: status %d, %s (wanted \"%s\")", (unsigned)session,
                                                          (unsigned long long)bytes, (int)st, r, text);
  free(r);
}

static double granted_bytes(int port) {
  int32_t st;
  char *r = control(port, NULL, "{\"op\":\"stats\"}", &st);
  assert_int_equal(st, 0);
  double g = json_num(r, NULL, "granted_bytes");
  free(r);
  return g;
}

/* A version-3 viewer at 8 MiB lowered by hand below what it holds: every window within the budget
 * in force, the store (budget event) shrinks once the old states left, the reservation follows. */
static void test_budget__lowered_by_ctl(void **state) {
  (void)state;
  char audit[] = "/tmp/oc_budget_audit_XXXXXX";
  int afd = mkstemp(audit);
  assert_true(afd >= 0);
  close(afd);
  server_t s = sphere_server("--audit-log", audit, NULL);
  bviewer_t v;
  bv_open(&v, s.port, 8 * MIB, 0);
  assert_int_equal(v.in_force, 8 * MIB);
  bviewer_t *all[] = {&v};
  for (int i = 0; i < 3; i++) step_all(s.port, all, 1);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(ocv_conn_session(v.c), &st);
  uint64_t low = st.resident_bytes / 2; /* below what it holds: the tree must shrink */
  uint64_t mn = oc_budget_min(&ocp_viewer_welcome(ocv_conn_session(v.c))->grant);
  if (low < mn) low = mn;
  print_message("resident %llu bytes at 8 MiB; lowered to %llu\n", (unsigned long long)st.resident_bytes, (unsigned long long)low);
  assert_true(low < st.resident_bytes);
  int32_t code;
  char *r = budget_op(s.port, v.session, low, &code);
  assert_int_equal(code, 0);
  assert_non_null(strstr(r, "\"was\":8388608"));
  free(r);
  for (int i = 0; i < 5; i++) step_all(s.port, all, 1);
  ocp_viewer_stats(ocv_conn_session(v.c), &st);
  print_message("after 5 epochs: in force %llu, %d budget events, resident %llu, over %llu (session: %llu)\n",
                (unsigned long long)v.in_force, v.budget_events, (unsigned long long)st.resident_bytes,
                (unsigned long long)v.over, (unsigned long long)st.over_budget);
  assert_int_equal(v.in_force, low);      /* the store shrank to it */
  assert_int_equal(v.budget_events, 1);
  assert_int_equal(st.budgets, 1);        /* one BUDGET */
  assert_int_equal(v.over, 0);
  assert_int_equal(st.over_budget, 0);
  assert_true(st.resident_bytes <= low);
  assert_true(v.resident_max_after <= low);
  assert_true(granted_bytes(s.port) == (double)low); /* the old budget is no longer reserved */
  /* refusals, each named */
  expect_refused(s.port, 999, 4 * MIB, "no session 999");
  expect_refused(s.port, v.session, 1, "below the minimum");
  expect_refused(s.port, v.session, 1ull << 40, "above the per-viewer maximum");
  close_and_stop(&s, v.c, NULL);
  char *log = read_file(audit);
  assert_non_null(log);
  assert_non_null(strstr(log, "\"op\":\"budget\""));
  assert_non_null(strstr(log, "\"ok\":true"));
  assert_non_null(strstr(log, "below the minimum")); /* refusals are audited too */
  free(log);
  unlink(audit);
}

/* A server sharing 8 MiB (8 at most a viewer) and a first viewer (max_version as for bv_open)
 * granted the 6 it asks. */
static void start_greedy(server_t *s, bviewer_t *g, int max_version) {
  const char *extra[] = {"--scene", scene_sphere, "--total-budget", "8", "--max-budget", "8", NULL};
  start_server(s, extra);
  bv_open(g, s->port, 6 * MIB, max_version);
  assert_int_equal(g->in_force, 6 * MIB);
}

/* A version-1 viewer: the op is refused by name, admission never lowers it, it never gets BUDGET;
 * the version-3 newcomer gets what is left. Then a control session is refused. */
static void test_budget__v1_fixed(void **state) {
  (void)state;
  server_t s;
  bviewer_t a, b;
  start_greedy(&s, &a, 1);
  assert_int_equal(ocp_viewer_welcome(ocv_conn_session(a.c))->version, 1);
  expect_refused(s.port, a.session, 2 * MIB, "this viewer speaks protocol version 1: BUDGET needs 3");
  bv_open(&b, s.port, 4 * MIB, 0); /* needs room: only version-3 viewers would be lowered */
  assert_int_equal(b.in_force, 2 * MIB);
  bviewer_t *all[] = {&a, &b};
  for (int i = 0; i < 4; i++) step_all(s.port, all, 2);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(ocv_conn_session(a.c), &st);
  assert_int_equal(st.budgets, 0);
  assert_int_equal(a.budget_events, 0);
  assert_int_equal(a.in_force, 6 * MIB);
  assert_int_equal(b.in_force, 2 * MIB); /* nothing was freed */
  assert_true(granted_bytes(s.port) == 8.0 * MIB);
  int replied = 0;
  ocv_conn_t *ctl = control_open(s.port, &replied);
  uint32_t cid = ocp_viewer_welcome(ocv_conn_session(ctl))->session;
  char text[64];
  snprintf(text, sizeof text, "session %u is a control session", (unsigned)cid);
  expect_refused(s.port, cid, 2 * MIB, text);
  close_and_stop(&s, ctl, a.c, b.c, NULL);
}

/* Admission: a greedy version-3 viewer (6 of 8 MiB) is lowered to a fair share (2 MiB) when a new
 * viewer asks 4; the newcomer is admitted with the 2 left at once and raised to 4 once the greedy
 * one's old states have left its window; every window of both stays within its budget in force. */
static void test_budget__admission_lowers_greedy(void **state) {
  (void)state;
  server_t s;
  bviewer_t g, n;
  start_greedy(&s, &g, 0);
  bviewer_t *one[] = {&g};
  for (int i = 0; i < 3; i++) step_all(s.port, one, 1);
  bv_open(&n, s.port, 4 * MIB, 0);
  assert_int_equal(n.in_force, 2 * MIB); /* what was left, at once */
  bviewer_t *both[] = {&g, &n};
  for (int i = 0; i < 5; i++) step_all(s.port, both, 2);
  print_message("greedy: in force %llu (%d events, over %llu); newcomer: in force %llu (%d events, over %llu)\n",
                (unsigned long long)g.in_force, g.budget_events, (unsigned long long)g.over, (unsigned long long)n.in_force,
                n.budget_events, (unsigned long long)n.over);
  assert_int_equal(g.in_force, 2 * MIB);
  assert_int_equal(n.in_force, 4 * MIB);
  assert_int_equal(g.over, 0);
  assert_int_equal(n.over, 0);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(ocv_conn_session(g.c), &st);
  assert_int_equal(st.over_budget, 0);
  ocp_viewer_stats(ocv_conn_session(n.c), &st);
  assert_int_equal(st.over_budget, 0);
  assert_true(granted_bytes(s.port) == 6.0 * MIB);
  int32_t code;
  char *r = control(s.port, NULL, "{\"op\":\"stats\"}", &code);
  assert_int_equal(code, 0);
  assert_true(json_num(r, NULL, "budget_lowerings") == 1.0);
  free(r);
  close_and_stop(&s, g.c, n.c, NULL);
}

OC_TEST_MAIN(net_setup, NULL,
             cmocka_unit_test_teardown(test_budget__lowered_by_ctl, net_teardown),
             cmocka_unit_test_teardown(test_budget__v1_fixed, net_teardown),
             cmocka_unit_test_teardown(test_budget__admission_lowers_greedy, net_teardown))
