/* redis_loop_fixture.h — a redis-server and a libuv loop for one test (header-only, after
 * cmocka.h). redis_loop_open() starts both; redis_loop_close() runs the loop until every
 * handle has closed, checks that nothing was left on it and stops the server. The cmocka
 * setup/teardown pair redis_loop_setup/redis_loop_teardown hands the test a redis_loop_t. */
#ifndef OC_TESTS_REDIS_LOOP_FIXTURE_H
#define OC_TESTS_REDIS_LOOP_FIXTURE_H

#include <string.h>
#include <uv.h>

#include "server/redis_fixture.h"

typedef struct {
  redis_proc_t redis;
  uv_loop_t loop;
} redis_loop_t;

/* Runs the loop until *flag becomes non-zero or about 20 s of loop time pass (a guard against
 * hangs, not a speed limit). */
static inline int redis_run_until(uv_loop_t *loop, const int *flag) {
  for (int i = 0; i < 2000 && !*flag; i++) {
    uv_run(loop, UV_RUN_NOWAIT);
    if (!*flag) redis_sleep_ms(10);
  }
  return *flag;
}

/* Also ignores SIGPIPE: the tests kill servers that the code under test is writing to. */
static inline int redis_loop_open(redis_loop_t *fx) {
  signal(SIGPIPE, SIG_IGN);
  memset(fx, 0, sizeof *fx);
  if (redis_start(&fx->redis, 0) != 0) return -1;
  if (uv_loop_init(&fx->loop) != 0) {
    redis_stop(&fx->redis);
    return -1;
  }
  return 0;
}

/* 0 when the loop closes: every handle the test opened has been closed by the code under test.
 * Waits about 20 s at most, so that a test that failed with handles open does not hang. */
static inline int redis_loop_close(redis_loop_t *fx) {
  for (int i = 0; i < 2000 && uv_run(&fx->loop, UV_RUN_NOWAIT); i++) redis_sleep_ms(10);
  int r = uv_loop_close(&fx->loop);
  if (r != 0) fprintf(stderr, "redis_loop_close: handles left open on the loop (%s)\n", uv_strerror(r));
  redis_stop(&fx->redis);
  return r == 0 ? 0 : -1;
}

static inline int redis_loop_setup(void **state) {
  static redis_loop_t fx;
  *state = &fx;
  return redis_loop_open(&fx);
}

static inline int redis_loop_teardown(void **state) { return redis_loop_close(*state); }

#endif /* OC_TESTS_REDIS_LOOP_FIXTURE_H */
