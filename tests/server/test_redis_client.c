/* test_redis_client.c — server/redis_client.c against a real redis-server on loopback: commands
 * and binary values, deadlines on a stopped server, a stuck connection dropped and re-made, a
 * killed server's pending commands and its restart, and close with commands in flight. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <hiredis/hiredis.h>
#include <string.h>
#include <uv.h>

#include "oc_err.h"
#include "redis_client.h"
#include "server/redis_fixture.h"

typedef struct {
  int calls, status, type;
  char str[64];
  size_t len;
} reply_t;

static void on_reply(void *ctx, int status, const redisReply *r) {
  reply_t *o = ctx;
  o->calls++;
  o->status = status;
  o->type = r ? r->type : -1;
  o->len = 0;
  if (r && (r->type == REDIS_REPLY_STRING || r->type == REDIS_REPLY_STATUS || r->type == REDIS_REPLY_ERROR)) {
    o->len = r->len < sizeof o->str ? r->len : sizeof o->str;
    memcpy(o->str, r->str, o->len);
  }
}

/* Runs the loop until *flag becomes non-zero or about 20 s of loop time pass (a guard against
 * hangs, not a speed limit). */
static int run_until(uv_loop_t *loop, const int *flag) {
  for (int i = 0; i < 2000 && !*flag; i++) {
    uv_run(loop, UV_RUN_NOWAIT);
    if (!*flag) redis_sleep_ms(10);
  }
  return *flag;
}

typedef struct {
  int ups, downs;
  int up;
} state_t;
static void on_state(void *ctx, int up) {
  state_t *s = ctx;
  s->up = up;
  if (up) s->ups++;
  else s->downs++;
}

static int cmd(ocs_redis_t *r, uint32_t ms, reply_t *out, int argc, const char **argv) {
  size_t lens[8];
  for (int i = 0; i < argc; i++) lens[i] = strlen(argv[i]);
  memset(out, 0, sizeof *out);
  return ocs_redis_command(r, ms, on_reply, out, argc, argv, lens);
}

static void open_client(uv_loop_t *loop, ocs_redis_t **r, state_t *s, int port) {
  ocs_redis_opts_t o = {.host = "127.0.0.1", .port = port, .connect_ms = 2000, .stuck_after = 2, .retry_ms = 50,
                        .seed = 7, .on_state = on_state, .state_ctx = s};
  assert_int_equal(ocs_redis_open(r, loop, &o), 0);
  assert_true(run_until(loop, &s->up));
}

static void close_client(uv_loop_t *loop, ocs_redis_t *r) {
  ocs_redis_close(r);
  uv_run(loop, UV_RUN_DEFAULT); /* closes every handle: nothing may be left running */
  assert_int_equal(uv_loop_close(loop), 0);
}

static void test_redis__commands_and_binary_values(void **state) {
  (void)state;
  redis_proc_t p;
  assert_int_equal(redis_start(&p, 0), 0);
  uv_loop_t loop;
  uv_loop_init(&loop);
  ocs_redis_t *r;
  state_t s = {0};
  open_client(&loop, &r, &s, p.port);
  const char bin[] = {'a', 0, 'b', (char)0xff};
  const char *set[] = {"SET", "k", bin};
  size_t lens[] = {3, 1, sizeof bin};
  reply_t a = {0}, b = {0};
  assert_int_equal(ocs_redis_command(r, 10000, on_reply, &a, 3, set, lens), 0);
  assert_int_equal(a.calls, 0); /* never from inside the call */
  const char *get[] = {"GET", "k"};
  assert_int_equal(cmd(r, 10000, &b, 2, get), 0);
  assert_true(run_until(&loop, &b.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  assert_int_equal(b.status, OCS_REDIS_OK);
  assert_int_equal(b.type, REDIS_REPLY_STRING);
  assert_int_equal(b.len, sizeof bin);
  assert_memory_equal(b.str, bin, sizeof bin);
  /* an error reply is a reply */
  const char *bad[] = {"NOSUCHCOMMAND"};
  assert_int_equal(cmd(r, 10000, &a, 1, bad), 0);
  assert_true(run_until(&loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  assert_int_equal(a.type, REDIS_REPLY_ERROR);
  assert_int_equal(ocs_redis_command(r, 0, on_reply, &a, 1, bad, lens), OC_EINVAL);
  close_client(&loop, r);
  redis_stop(&p);
}

/* A stopped server still accepts connections: only deadlines notice. */
static void test_redis__deadlines_and_a_stuck_connection(void **state) {
  (void)state;
  redis_proc_t p;
  assert_int_equal(redis_start(&p, 0), 0);
  uv_loop_t loop;
  uv_loop_init(&loop);
  ocs_redis_t *r;
  state_t s = {0};
  open_client(&loop, &r, &s, p.port);
  kill(p.pid, SIGSTOP);
  const char *get[] = {"GET", "k"};
  reply_t a, b;
  assert_int_equal(cmd(r, 100, &a, 2, get), 0);
  assert_true(run_until(&loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_TIMEOUT);
  assert_true(ocs_redis_up(r)); /* one timeout is not yet stuck */
  assert_int_equal(cmd(r, 100, &b, 2, get), 0);
  assert_true(run_until(&loop, &b.calls));
  assert_int_equal(b.status, OCS_REDIS_TIMEOUT);
  assert_int_equal(a.calls, 1); /* exactly once, the late reply never comes through */
  ocs_redis_stats_t st;
  ocs_redis_stats(r, &st);
  assert_int_equal(st.stuck, 1);
  assert_int_equal(s.downs, 1);
  assert_int_equal(cmd(r, 100, &a, 2, get), OC_EIO); /* refused at once while down */
  kill(p.pid, SIGCONT);
  s.up = 0;
  assert_true(run_until(&loop, &s.up)); /* reconnected */
  assert_int_equal(cmd(r, 10000, &a, 2, get), 0);
  assert_true(run_until(&loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  close_client(&loop, r);
  redis_stop(&p);
}

static void test_redis__server_killed_and_restarted(void **state) {
  (void)state;
  redis_proc_t p;
  assert_int_equal(redis_start(&p, 0), 0);
  int port = p.port;
  uv_loop_t loop;
  uv_loop_init(&loop);
  ocs_redis_t *r;
  state_t s = {0};
  open_client(&loop, &r, &s, port);
  kill(p.pid, SIGSTOP);
  const char *get[] = {"GET", "k"};
  reply_t a;
  assert_int_equal(cmd(r, 60000, &a, 2, get), 0); /* pending when the server dies */
  kill(p.pid, SIGKILL);
  waitpid(p.pid, NULL, 0);
  p.pid = 0;
  assert_true(run_until(&loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_DOWN);
  assert_int_equal(s.up, 0);
  /* reconnect attempts fail quietly until a server is back on the port */
  for (int i = 0; i < 20; i++) {
    uv_run(&loop, UV_RUN_NOWAIT);
    redis_sleep_ms(10);
  }
  assert_int_equal(redis_start(&p, port), 0);
  assert_true(run_until(&loop, &s.up));
  assert_int_equal(s.ups, 2);
  assert_int_equal(cmd(r, 10000, &a, 2, get), 0);
  assert_true(run_until(&loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  close_client(&loop, r);
  redis_stop(&p);
}

static void test_redis__close_with_commands_in_flight(void **state) {
  (void)state;
  redis_proc_t p;
  assert_int_equal(redis_start(&p, 0), 0);
  uv_loop_t loop;
  uv_loop_init(&loop);
  ocs_redis_t *r;
  state_t s = {0};
  open_client(&loop, &r, &s, p.port);
  kill(p.pid, SIGSTOP);
  const char *get[] = {"GET", "k"};
  reply_t a[3];
  for (int i = 0; i < 3; i++) assert_int_equal(cmd(r, 60000, &a[i], 2, get), 0);
  ocs_redis_close(r);
  for (int i = 0; i < 3; i++) {
    assert_int_equal(a[i].calls, 1);
    assert_int_equal(a[i].status, OCS_REDIS_DOWN);
  }
  uv_run(&loop, UV_RUN_DEFAULT);
  assert_int_equal(uv_loop_close(&loop), 0);
  redis_stop(&p);
}

static void test_redis__bad_options(void **state) {
  (void)state;
  uv_loop_t loop;
  uv_loop_init(&loop);
  ocs_redis_t *r = NULL;
  ocs_redis_opts_t o = {.host = "127.0.0.1", .port = 0};
  assert_int_equal(ocs_redis_open(&r, &loop, &o), OC_EINVAL);
  o.port = 70000;
  assert_int_equal(ocs_redis_open(&r, &loop, &o), OC_EINVAL);
  o.port = 6379;
  o.host = "";
  assert_int_equal(ocs_redis_open(&r, &loop, &o), OC_EINVAL);
  assert_int_equal(uv_loop_close(&loop), 0);
}

int main(void) {
  signal(SIGPIPE, SIG_IGN);
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_redis__commands_and_binary_values),
      cmocka_unit_test(test_redis__deadlines_and_a_stuck_connection),
      cmocka_unit_test(test_redis__server_killed_and_restarted),
      cmocka_unit_test(test_redis__close_with_commands_in_flight),
      cmocka_unit_test(test_redis__bad_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
