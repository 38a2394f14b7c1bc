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
#include "server/redis_loop_fixture.h"

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

/* Each test gets a redis-server, a loop and a client that is up. The teardown closes the client
 * (unless the test did) and then the loop: nothing may be left running. */
typedef struct {
  redis_loop_t base;
  ocs_redis_t *r;
  state_t s;
} fixture_t;

static int setup(void **state) {
  static fixture_t fx;
  memset(&fx, 0, sizeof fx);
  *state = &fx;
  if (redis_loop_open(&fx.base) != 0) return -1;
  ocs_redis_opts_t o = {.host = "127.0.0.1", .port = fx.base.redis.port, .connect_ms = 2000, .stuck_after = 2,
                        .retry_ms = 50, .seed = 7, .on_state = on_state, .state_ctx = &fx.s};
  if (ocs_redis_open(&fx.r, &fx.base.loop, &o) != 0 || !redis_run_until(&fx.base.loop, &fx.s.up)) {
    if (fx.r) ocs_redis_close(fx.r);
    fx.r = NULL;
    redis_loop_close(&fx.base);
    return -1;
  }
  return 0;
}

static int teardown(void **state) {
  fixture_t *fx = *state;
  if (fx->r) ocs_redis_close(fx->r);
  return redis_loop_close(&fx->base);
}

static const char *get[] = {"GET", "k"};

static void test_redis__commands_and_binary_values(void **state) {
  fixture_t *fx = *state;
  ocs_redis_t *r = fx->r;
  const char bin[] = {'a', 0, 'b', (char)0xff};
  const char *set[] = {"SET", "k", bin};
  size_t lens[] = {3, 1, sizeof bin};
  reply_t a = {0}, b = {0};
  assert_int_equal(ocs_redis_command(r, 10000, on_reply, &a, 3, set, lens), 0);
  assert_int_equal(a.calls, 0); /* never from inside the call */
  assert_int_equal(cmd(r, 10000, &b, 2, get), 0);
  assert_true(redis_run_until(&fx->base.loop, &b.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  assert_int_equal(b.status, OCS_REDIS_OK);
  assert_int_equal(b.type, REDIS_REPLY_STRING);
  assert_int_equal(b.len, sizeof bin);
  assert_memory_equal(b.str, bin, sizeof bin);
  /* an error reply is a reply */
  const char *bad[] = {"NOSUCHCOMMAND"};
  assert_int_equal(cmd(r, 10000, &a, 1, bad), 0);
  assert_true(redis_run_until(&fx->base.loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
  assert_int_equal(a.type, REDIS_REPLY_ERROR);
  assert_int_equal(ocs_redis_command(r, 0, on_reply, &a, 1, bad, lens), OC_EINVAL);
}

/* A stopped server still accepts connections: only deadlines notice. */
static void test_redis__deadlines_and_a_stuck_connection(void **state) {
  fixture_t *fx = *state;
  ocs_redis_t *r = fx->r;
  uv_loop_t *loop = &fx->base.loop;
  kill(fx->base.redis.pid, SIGSTOP);
  reply_t a, b;
  assert_int_equal(cmd(r, 100, &a, 2, get), 0);
  assert_true(redis_run_until(loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_TIMEOUT);
  assert_true(ocs_redis_up(r)); /* one timeout is not yet stuck */
  assert_int_equal(cmd(r, 100, &b, 2, get), 0);
  assert_true(redis_run_until(loop, &b.calls));
  assert_int_equal(b.status, OCS_REDIS_TIMEOUT);
  assert_int_equal(a.calls, 1); /* exactly once, the late reply never comes through */
  ocs_redis_stats_t st;
  ocs_redis_stats(r, &st);
  assert_int_equal(st.stuck, 1);
  assert_int_equal(fx->s.downs, 1);
  assert_int_equal(cmd(r, 100, &a, 2, get), OC_EIO); /* refused at once while down */
  kill(fx->base.redis.pid, SIGCONT);
  fx->s.up = 0;
  assert_true(redis_run_until(loop, &fx->s.up)); /* reconnected */
  assert_int_equal(cmd(r, 10000, &a, 2, get), 0);
  assert_true(redis_run_until(loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
}

static void test_redis__server_killed_and_restarted(void **state) {
  fixture_t *fx = *state;
  ocs_redis_t *r = fx->r;
  uv_loop_t *loop = &fx->base.loop;
  int port = fx->base.redis.port;
  kill(fx->base.redis.pid, SIGSTOP);
  reply_t a;
  assert_int_equal(cmd(r, 60000, &a, 2, get), 0); /* pending when the server dies */
  redis_kill(&fx->base.redis);
  assert_true(redis_run_until(loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_DOWN);
  assert_int_equal(fx->s.up, 0);
  /* reconnect attempts fail quietly until a server is back on the port */
  for (int i = 0; i < 20; i++) {
    uv_run(loop, UV_RUN_NOWAIT);
    redis_sleep_ms(10);
  }
  assert_int_equal(redis_start(&fx->base.redis, port), 0);
  assert_true(redis_run_until(loop, &fx->s.up));
  assert_int_equal(fx->s.ups, 2);
  assert_int_equal(cmd(r, 10000, &a, 2, get), 0);
  assert_true(redis_run_until(loop, &a.calls));
  assert_int_equal(a.status, OCS_REDIS_OK);
}

static void test_redis__close_with_commands_in_flight(void **state) {
  fixture_t *fx = *state;
  kill(fx->base.redis.pid, SIGSTOP);
  reply_t a[3];
  for (int i = 0; i < 3; i++) assert_int_equal(cmd(fx->r, 60000, &a[i], 2, get), 0);
  ocs_redis_close(fx->r);
  fx->r = NULL;
  for (int i = 0; i < 3; i++) {
    assert_int_equal(a[i].calls, 1);
    assert_int_equal(a[i].status, OCS_REDIS_DOWN);
  }
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
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_setup_teardown(test_redis__commands_and_binary_values, setup, teardown),
      cmocka_unit_test_setup_teardown(test_redis__deadlines_and_a_stuck_connection, setup, teardown),
      cmocka_unit_test_setup_teardown(test_redis__server_killed_and_restarted, setup, teardown),
      cmocka_unit_test_setup_teardown(test_redis__close_with_commands_in_flight, setup, teardown),
      cmocka_unit_test(test_redis__bad_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
