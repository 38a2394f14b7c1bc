/* redis_client.h — one Redis connection on the libuv loop, with what hiredis 0.14 lacks.
 *
 * hiredis 0.14's async API (its libuv adapter) has no timeouts and its context belongs to the loop
 * thread. This module adds:
 *   - a deadline on every command (a uv_timer): the callback comes exactly once, with the reply,
 *     with OCS_REDIS_TIMEOUT when the deadline passes first (a late reply is dropped), or with
 *     OCS_REDIS_DOWN when the connection is lost;
 *   - a connection judged stuck after `stuck_after` timeouts in a row (a stopped or overloaded
 *     Redis still accepts TCP connections), which is then dropped;
 *   - reconnects with exponential backoff and jitter (oc_backoff), and a deadline on connecting.
 * While the connection is not up, ocs_redis_command() refuses at once (OC_EIO), so callers fall
 * back to their local path without waiting: nothing ever blocks on Redis.
 *
 * Every function runs on the loop's thread. */
#ifndef OC_SERVER_REDIS_CLIENT_H
#define OC_SERVER_REDIS_CLIENT_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

struct redisReply;
typedef struct ocs_redis_s ocs_redis_t;

/* A command's outcome, given to its callback. */
enum { OCS_REDIS_OK = 0, OCS_REDIS_TIMEOUT = 1, OCS_REDIS_DOWN = 2 };

/*! A command's callback: status OCS_REDIS_OK with the reply (valid only during the call; it may be
 *  an error reply), or TIMEOUT / DOWN with reply NULL. */
typedef void (*ocs_redis_cb)(void *ctx, int status, const struct redisReply *reply);

typedef struct {
  const char *host;           /* an address hiredis resolves, e.g. "127.0.0.1" */
  int port;
  uint32_t connect_ms;        /* deadline of a connection attempt (default 1000) */
  uint32_t stuck_after;       /* timeouts in a row that drop the connection (default 3) */
  uint32_t retry_ms;          /* the first reconnect delay; backoff doubles it (default 250) */
  uint64_t seed;              /* the backoff's jitter */
  /* called on the loop when the connection comes up (1) or goes down (0); may be NULL */
  void (*on_state)(void *ctx, int up);
  void *state_ctx;
} ocs_redis_opts_t;

typedef struct {
  uint64_t commands;    /* accepted by ocs_redis_command() */
  uint64_t replies;     /* answered in time */
  uint64_t timeouts;    /* deadline passed first */
  uint64_t dropped;     /* connection lost while waiting */
  uint64_t refused;     /* ocs_redis_command() while down */
  uint64_t connects;    /* connections that came up */
  uint64_t downs;       /* connections lost, stuck ones included */
  uint64_t stuck;       /* connections dropped for timeouts in a row */
} ocs_redis_stats_t;

/*! ocs_redis_open() : starts connecting (asynchronously) and keeps reconnecting until closed.
 *  @return 0, OC_EINVAL (no host, port outside 1 … 65535) or OC_ENOMEM. */
int ocs_redis_open(ocs_redis_t **out, uv_loop_t *loop, const ocs_redis_opts_t *o);
/*! ocs_redis_close() : drops the connection (pending commands get OCS_REDIS_DOWN, now) and frees
 *  everything once the loop has closed its handles. NULL is accepted. */
void ocs_redis_close(ocs_redis_t *r);
/*! ocs_redis_up() : 1 while connected and not judged stuck. */
int ocs_redis_up(const ocs_redis_t *r);
/*! ocs_redis_command() : sends argv (binary-safe) with a deadline in ms (≥ 1).
 *  @return 0: cb will be called exactly once, never from inside this call. OC_EIO: not connected,
 *  cb will never be called. OC_EINVAL, OC_ENOMEM likewise. */
int ocs_redis_command(ocs_redis_t *r, uint32_t deadline_ms, ocs_redis_cb cb, void *ctx, int argc,
                      const char **argv, const size_t *lens);
/*! ocs_redis_stats() : the counters so far. */
void ocs_redis_stats(const ocs_redis_t *r, ocs_redis_stats_t *out);

#endif /* OC_SERVER_REDIS_CLIENT_H */
