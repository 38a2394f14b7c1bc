/* test_brick_remote.c — bricks shared through a real redis-server (server/brick_remote.h): two
 * front-ends on one loop, production once through the lease, a damaged value made again, a lease
 * that outlives a dead producer only by its time, and a Redis that is gone. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <hiredis/hiredis.h>
#include <string.h>
#include <uv.h>

#include "brick_remote.h"
#include "oc_err.h"
#include "server/redis_loop_fixture.h"

typedef struct {
  int calls, outcome;
  uint8_t content[64];
  size_t n;
} got_t;

static void on_got(void *ctx, int outcome, const uint8_t *content, size_t n) {
  got_t *g = ctx;
  g->calls++;
  g->outcome = outcome;
  g->n = n < sizeof g->content ? n : sizeof g->content;
  if (content) memcpy(g->content, content, g->n);
}

typedef struct {
  uv_loop_t *loop;
  ocs_redis_t *redis;
  ocs_remote_t *tier;
  int up;
} frontend_t;

static void on_state(void *ctx, int up) { ((frontend_t *)ctx)->up = up; }

/* A front-end on the fixture's Redis and loop, connected. */
static void frontend_open(redis_loop_t *fx, frontend_t *f, uint64_t id, uint32_t lease_ms) {
  memset(f, 0, sizeof *f);
  f->loop = &fx->loop;
  ocs_redis_opts_t o = {
      .host = "127.0.0.1", .port = fx->redis.port, .retry_ms = 50, .on_state = on_state, .state_ctx = f};
  assert_int_equal(ocs_redis_open(&f->redis, f->loop, &o), 0);
  assert_true(redis_run_until(f->loop, &f->up));
  ocs_remote_opts_t r = {.deadline_ms = 10000, .lease_ms = lease_ms, .frontend_id = id};
  assert_int_equal(ocs_remote_create(&f->tier, f->redis, &r), 0);
}

/* Two front-ends, a (id 0xa) and b (id 0xb), that share one Redis. */
static void frontend_open_pair(redis_loop_t *fx, frontend_t *a, frontend_t *b, uint32_t lease_ms) {
  frontend_open(fx, a, 0xa, lease_ms);
  frontend_open(fx, b, 0xb, lease_ms);
}

static void frontend_close(frontend_t *f) {
  ocs_redis_close(f->redis);
  ocs_remote_free(f->tier);
}

static int fetch(frontend_t *f, const ocs_bkey_t *k, got_t *g) {
  memset(g, 0, sizeof *g);
  int r = ocs_remote_fetch(f->tier, k, on_got, g);
  if (r < 0) return r;
  assert_true(redis_run_until(f->loop, &g->calls));
  return g->outcome;
}

static void on_raw_set(void *ctx, int status, const struct redisReply *r) {
  (void)status;
  (void)r;
  *(int *)ctx = 1;
}

/* Writes raw bytes under a brick's name, as a damaged or foreign value would be. */
static void put_raw(frontend_t *f, const ocs_bkey_t *k, const char *bytes, size_t n) {
  char name[OCS_BKEY_TEXT];
  ocs_bkey_text(k, "oc:b:", name);
  const char *argv[] = {"SET", name, bytes};
  size_t lens[] = {3, strlen(name), n};
  int done = 0;
  assert_int_equal(ocs_redis_command(f->redis, 10000, on_raw_set, &done, 3, argv, lens), 0);
  assert_true(redis_run_until(f->loop, &done));
}

static void test_remote__produced_once_shared_by_all(void **state) {
  frontend_t a, b;
  frontend_open_pair(*state, &a, &b, 60000);
  ocs_bkey_in_t in = {.scene = 11, .weather = 12, .sun = 13, .stamp = 14, .node = 15, .channel = 1};
  ocs_bkey_t k = ocs_bkey_make(&in);
  got_t g;
  assert_int_equal(fetch(&a, &k, &g), OCS_REMOTE_LEASED); /* a produces */
  assert_int_equal(fetch(&b, &k, &g), OCS_REMOTE_BUSY);   /* b requeues */
  assert_int_equal(fetch(&a, &k, &g), OCS_REMOTE_LEASED); /* a, looking again, still holds it */
  const char brick[] = "sixty-four bytes of brick codes, say";
  assert_int_equal(ocs_remote_store(a.tier, &k, brick, sizeof brick), 0);
  assert_int_equal(fetch(&b, &k, &g), OCS_REMOTE_HIT); /* replies come in order: stored first */
  assert_int_equal(g.n, sizeof brick);
  assert_memory_equal(g.content, brick, sizeof brick);
  /* another channel of the same node is another brick */
  in.channel = 2;
  ocs_bkey_t k2 = ocs_bkey_make(&in);
  assert_int_equal(fetch(&b, &k2, &g), OCS_REMOTE_LEASED);
  /* a damaged value is discarded and made again under a lease */
  in.channel = 3;
  ocs_bkey_t k3 = ocs_bkey_make(&in);
  uint8_t v[256];
  size_t len = ocs_bval_pack(&k3, brick, sizeof brick, v, sizeof v);
  v[40] ^= 4;
  put_raw(&a, &k3, (const char *)v, len);
  assert_int_equal(fetch(&a, &k3, &g), OCS_REMOTE_LEASED);
  /* a value stored under another brick's name is not that brick */
  in.channel = 4;
  ocs_bkey_t k4 = ocs_bkey_make(&in);
  v[40] ^= 4;
  put_raw(&a, &k4, (const char *)v, len);
  assert_int_equal(fetch(&b, &k4, &g), OCS_REMOTE_LEASED);
  /* a lease given back is free at once; b's release of a's lease changes nothing */
  in.channel = 5;
  ocs_bkey_t k5 = ocs_bkey_make(&in);
  assert_int_equal(fetch(&a, &k5, &g), OCS_REMOTE_LEASED);
  assert_int_equal(ocs_remote_release(b.tier, &k5), 0);
  assert_int_equal(fetch(&b, &k5, &g), OCS_REMOTE_BUSY);
  assert_int_equal(ocs_remote_release(a.tier, &k5), 0);
  assert_int_equal(fetch(&b, &k5, &g), OCS_REMOTE_LEASED);
  ocs_remote_stats_t st;
  ocs_remote_stats(a.tier, &st);
  assert_int_equal(st.rejected, 1);
  assert_int_equal(st.stores, 1);
  ocs_remote_stats(b.tier, &st);
  assert_int_equal(st.rejected, 1);
  assert_int_equal(st.hits, 1);
  assert_int_equal(st.busy, 2);
  frontend_close(&a);
  frontend_close(&b);
}

/* A producer that dies holding the lease delays the others by the lease's time, no more. */
static void test_remote__lease_expires(void **state) {
  frontend_t a, b;
  frontend_open_pair(*state, &a, &b, 200);
  ocs_bkey_in_t in = {.node = 99, .channel = 1};
  ocs_bkey_t k = ocs_bkey_make(&in);
  got_t g;
  assert_int_equal(fetch(&a, &k, &g), OCS_REMOTE_LEASED);
  frontend_close(&a); /* a dies without storing */
  redis_sleep_ms(400);  /* twice the lease: Redis expires it on its own clock */
  assert_int_equal(fetch(&b, &k, &g), OCS_REMOTE_LEASED);
  frontend_close(&b);
}

/* Redis gone: the answer is at once "produce locally", or unavailable for a fetch in flight. */
static void test_remote__redis_gone(void **state) {
  redis_loop_t *fx = *state;
  frontend_t a;
  frontend_open(fx, &a, 0xa, 60000);
  ocs_bkey_in_t in = {.node = 7, .channel = 1};
  ocs_bkey_t k = ocs_bkey_make(&in);
  kill(fx->redis.pid, SIGSTOP);
  got_t g = {0};
  assert_int_equal(ocs_remote_fetch(a.tier, &k, on_got, &g), 0);
  redis_kill(&fx->redis); /* dies with the fetch in flight, unanswered */
  assert_true(redis_run_until(a.loop, &g.calls));
  assert_int_equal(g.outcome, OCS_REMOTE_UNAVAILABLE);
  assert_false(a.up);
  assert_int_equal(ocs_remote_fetch(a.tier, &k, on_got, &g), OC_EIO);
  assert_int_equal(ocs_remote_store(a.tier, &k, "x", 1), OC_EIO);
  ocs_remote_stats_t st;
  ocs_remote_stats(a.tier, &st);
  assert_int_equal(st.unavailable, 2);
  assert_int_equal(st.store_failures, 1);
  frontend_close(&a);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_setup_teardown(test_remote__produced_once_shared_by_all, redis_loop_setup, redis_loop_teardown),
      cmocka_unit_test_setup_teardown(test_remote__lease_expires, redis_loop_setup, redis_loop_teardown),
      cmocka_unit_test_setup_teardown(test_remote__redis_gone, redis_loop_setup, redis_loop_teardown),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
