/* redis_client.c — one Redis connection on the libuv loop with deadlines and reconnects
 * (redis_client.h).
 *
 * Ownership of a command: hiredis holds it until it calls on_reply (with the reply, or NULL when
 * the context goes away), and its deadline timer holds it until the timer is closed. Whichever of
 * reply, deadline or loss comes first delivers the callback; the command is freed when both
 * holders have let go, so a reply arriving after its deadline finds it alive and is dropped.
 *
 * The event glue is hiredis' adapters/libuv.h with one fix: 0.14's ignores a poll that reports an
 * error (a write to a peer that died: libuv gives UV_EBADF and stops the poll), so a dead server
 * went unnoticed until deadlines piled up. Here an error status hands the socket to hiredis, whose
 * read or write then fails and disconnects (fixed the same way in later hiredis). */
#include "redis_client.h"

#include <hiredis/hiredis.h>
#include <hiredis/async.h>
#include <stdlib.h>
#include <string.h>

#include "oc_backoff.h"
#include "oc_err.h"
#include "oc_log.h"

typedef struct {
  ocs_redis_t *r;
  ocs_redis_cb cb;
  void *ctx;
  uv_timer_t timer;
  int done;  /* the callback was delivered */
  int refs;  /* hiredis' and the timer's */
} ocs__rcmd_t;

struct ocs_redis_s {
  uv_loop_t *loop;
  redisAsyncContext *ac; /* NULL while down */
  int up, closing, open_handles;
  uint32_t in_row;       /* timeouts since the last reply */
  ocs_redis_opts_t o;
  char host[256];
  oc_backoff_t backoff;
  uv_timer_t retry, connect_deadline;
  ocs_redis_stats_t st;
};

static void ocs__connect(ocs_redis_t *r);

/*-*** Event glue: hiredis' libuv adapter, with errors handed to hiredis ***/

typedef struct {
  redisAsyncContext *ac;
  uv_poll_t poll;
  int events;
} ocs__glue_t;

static void ocs__glue_poll(uv_poll_t *h, int status, int events) {
  ocs__glue_t *g = h->data;
  int ev = status < 0 ? g->events : events; /* an error: let hiredis find it by reading or writing */
  if (g->ac && (ev & UV_READABLE)) redisAsyncHandleRead(g->ac);
  if (g->ac && (ev & UV_WRITABLE)) redisAsyncHandleWrite(g->ac);
}

static void ocs__glue_set(void *priv, int add, int ev) {
  ocs__glue_t *g = priv;
  g->events = add ? g->events | ev : g->events & ~ev;
  if (g->events) uv_poll_start(&g->poll, g->events, ocs__glue_poll);
  else uv_poll_stop(&g->poll);
}
static void ocs__glue_add_read(void *p) { ocs__glue_set(p, 1, UV_READABLE); }
static void ocs__glue_del_read(void *p) { ocs__glue_set(p, 0, UV_READABLE); }
static void ocs__glue_add_write(void *p) { ocs__glue_set(p, 1, UV_WRITABLE); }
static void ocs__glue_del_write(void *p) { ocs__glue_set(p, 0, UV_WRITABLE); }
static void ocs__glue_closed(uv_handle_t *h) { free(h->data); }
static void ocs__glue_cleanup(void *priv) {
  ocs__glue_t *g = priv;
  g->ac = NULL; /* hiredis is freeing the context */
  uv_close((uv_handle_t *)&g->poll, ocs__glue_closed);
}

static int ocs__glue_attach(redisAsyncContext *ac, uv_loop_t *loop) {
  ocs__glue_t *g = calloc(1, sizeof *g);
  if (!g) return -1;
  if (uv_poll_init(loop, &g->poll, ac->c.fd) != 0) {
    free(g);
    return -1;
  }
  g->ac = ac;
  g->poll.data = g;
  ac->ev.data = g;
  ac->ev.addRead = ocs__glue_add_read;
  ac->ev.delRead = ocs__glue_del_read;
  ac->ev.addWrite = ocs__glue_add_write;
  ac->ev.delWrite = ocs__glue_del_write;
  ac->ev.cleanup = ocs__glue_cleanup;
  return 0;
}

static void ocs__cmd_release(ocs__rcmd_t *c) {
  if (--c->refs == 0) free(c);
}
static void ocs__cmd_closed(uv_handle_t *h) { ocs__cmd_release(h->data); }

/* Delivers a command's outcome once and lets its timer go. */
static void ocs__deliver(ocs__rcmd_t *c, int status, const redisReply *reply) {
  c->done = 1;
  uv_timer_stop(&c->timer);
  c->cb(c->ctx, status, reply);
  uv_close((uv_handle_t *)&c->timer, ocs__cmd_closed);
}

static void ocs__set_state(ocs_redis_t *r, int up) {
  if (r->up == up) return;
  r->up = up;
  if (up) r->st.connects++;
  else r->st.downs++;
  oc_log(up ? OC_LOG_INFO : OC_LOG_WARN, "redis %s:%d %s", r->host, r->o.port, up ? "up" : "down");
  if (r->o.on_state && !r->closing) r->o.on_state(r->o.state_ctx, up);
}

static void ocs__on_retry(uv_timer_t *t) { ocs__connect(t->data); }

static void ocs__schedule_retry(ocs_redis_t *r) {
  if (r->closing) return;
  uv_timer_start(&r->retry, ocs__on_retry, oc_backoff_next(&r->backoff), 0);
}

/* Drops the context now: hiredis runs the pending callbacks with NULL (DOWN), then, if it was
 * connected, on_disconnect. */
static void ocs__drop(ocs_redis_t *r) {
  redisAsyncContext *ac = r->ac;
  if (!ac) return;
  int was_connected = (ac->c.flags & REDIS_CONNECTED) != 0;
  redisAsyncFree(ac);
  if (!was_connected) { /* no on_disconnect comes: a connect that never finished */
    r->ac = NULL;
    ocs__schedule_retry(r);
  }
}

static void ocs__on_reply(redisAsyncContext *ac, void *reply, void *priv) {
  ocs__rcmd_t *c = priv;
  ocs_redis_t *r = ac->data;
  if (!c->done) {
    if (reply) {
      r->st.replies++;
      r->in_row = 0;
    } else {
      r->st.dropped++;
    }
    ocs__deliver(c, reply ? OCS_REDIS_OK : OCS_REDIS_DOWN, reply);
  }
  ocs__cmd_release(c);
}

static void ocs__on_timeout(uv_timer_t *t) {
  ocs__rcmd_t *c = t->data;
  if (c->done) return;
  ocs_redis_t *r = c->r; /* alive: an undelivered command means its context is */
  r->st.timeouts++;
  r->in_row++;
  ocs__deliver(c, OCS_REDIS_TIMEOUT, NULL);
  if (!r->closing && r->up && r->in_row >= r->o.stuck_after) {
    oc_log(OC_LOG_WARN, "redis %s:%d: %u commands in a row past their deadline: dropping the connection",
           r->host, r->o.port, r->in_row);
    r->st.stuck++;
    ocs__drop(r);
  }
}

static void ocs__on_connect(const redisAsyncContext *ac, int status) {
  ocs_redis_t *r = ac->data;
  uv_timer_stop(&r->connect_deadline);
  if (status != REDIS_OK) { /* hiredis frees the context after this */
    oc_log(OC_LOG_DEBUG, "redis %s:%d: connect failed: %s", r->host, r->o.port, ac->errstr);
    r->ac = NULL;
    ocs__schedule_retry(r);
    return;
  }
  r->in_row = 0;
  oc_backoff_init(&r->backoff, r->o.retry_ms, r->o.seed + r->st.connects);
  ocs__set_state(r, 1);
}

static void ocs__on_disconnect(const redisAsyncContext *ac, int status) {
  ocs_redis_t *r = ac->data;
  (void)status;
  r->ac = NULL;
  ocs__set_state(r, 0);
  ocs__schedule_retry(r);
}

static void ocs__on_connect_deadline(uv_timer_t *t) {
  ocs_redis_t *r = t->data;
  if (!r->ac || r->up) return;
  oc_log(OC_LOG_DEBUG, "redis %s:%d: no connection within %u ms", r->host, r->o.port, r->o.connect_ms);
  ocs__drop(r);
}

static void ocs__connect(ocs_redis_t *r) {
  if (r->closing || r->ac) return;
  redisAsyncContext *ac = redisAsyncConnect(r->host, r->o.port);
  if (!ac || ac->err || ocs__glue_attach(ac, r->loop) != 0) {
    if (ac) {
      oc_log(OC_LOG_DEBUG, "redis %s:%d: %s", r->host, r->o.port, ac->err ? ac->errstr : "cannot watch the socket");
      redisAsyncFree(ac);
    }
    ocs__schedule_retry(r);
    return;
  }
  ac->data = r;
  redisAsyncSetConnectCallback(ac, ocs__on_connect);
  redisAsyncSetDisconnectCallback(ac, ocs__on_disconnect);
  r->ac = ac;
  uv_timer_start(&r->connect_deadline, ocs__on_connect_deadline, r->o.connect_ms, 0);
}

int ocs_redis_open(ocs_redis_t **out, uv_loop_t *loop, const ocs_redis_opts_t *o) {
  if (!out || !loop || !o || !o->host || !*o->host || strlen(o->host) >= 256 || o->port < 1 || o->port > 65535)
    return OC_EINVAL;
  ocs_redis_t *r = calloc(1, sizeof *r);
  if (!r) return OC_ENOMEM;
  r->loop = loop;
  r->o = *o;
  strcpy(r->host, o->host);
  r->o.host = r->host;
  if (!r->o.connect_ms) r->o.connect_ms = 1000;
  if (!r->o.stuck_after) r->o.stuck_after = 3;
  if (!r->o.retry_ms) r->o.retry_ms = 250;
  oc_backoff_init(&r->backoff, r->o.retry_ms, r->o.seed);
  uv_timer_init(loop, &r->retry);
  uv_timer_init(loop, &r->connect_deadline);
  r->retry.data = r->connect_deadline.data = r;
  r->open_handles = 2;
  ocs__connect(r);
  *out = r;
  return 0;
}

static void ocs__handle_closed(uv_handle_t *h) {
  ocs_redis_t *r = h->data;
  if (--r->open_handles == 0) free(r);
}

void ocs_redis_close(ocs_redis_t *r) {
  if (!r || r->closing) return;
  r->closing = 1;
  uv_timer_stop(&r->retry);
  uv_timer_stop(&r->connect_deadline);
  ocs__drop(r);
  uv_close((uv_handle_t *)&r->retry, ocs__handle_closed);
  uv_close((uv_handle_t *)&r->connect_deadline, ocs__handle_closed);
}

int ocs_redis_up(const ocs_redis_t *r) { return r && r->up && !r->closing; }

int ocs_redis_command(ocs_redis_t *r, uint32_t deadline_ms, ocs_redis_cb cb, void *ctx, int argc,
                      const char **argv, const size_t *lens) {
  if (!r || !cb || argc < 1 || !argv || !lens || deadline_ms < 1) return OC_EINVAL;
  if (!ocs_redis_up(r) || !r->ac) {
    r->st.refused++;
    return OC_EIO;
  }
  ocs__rcmd_t *c = calloc(1, sizeof *c);
  if (!c) return OC_ENOMEM;
  *c = (ocs__rcmd_t){.r = r, .cb = cb, .ctx = ctx, .refs = 2};
  if (redisAsyncCommandArgv(r->ac, ocs__on_reply, c, argc, argv, lens) != REDIS_OK) {
    free(c);
    r->st.refused++;
    return OC_EIO;
  }
  uv_timer_init(r->loop, &c->timer);
  c->timer.data = c;
  uv_timer_start(&c->timer, ocs__on_timeout, deadline_ms, 0);
  r->st.commands++;
  return 0;
}

void ocs_redis_stats(const ocs_redis_t *r, ocs_redis_stats_t *out) {
  if (r) *out = r->st;
  else memset(out, 0, sizeof *out);
}
