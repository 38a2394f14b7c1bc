/* brick_remote.c — bricks shared through Redis, with leases (brick_remote.h). */
#include "brick_remote.h"

#include <hiredis/hiredis.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "oc_log.h"

struct ocs_remote_s {
  ocs_redis_t *redis;
  ocs_remote_opts_t o;
  ocs_remote_stats_t st;
};

/* One fetch in flight: GET, then on a nil reply SET NX PX. */
typedef struct {
  ocs_remote_t *t;
  ocs_bkey_t key;
  ocs_remote_cb cb;
  void *ctx;
} ocs__fetch_t;

static void ocs__fetch_done(ocs__fetch_t *f, int outcome, const uint8_t *content, size_t n) {
  ocs_remote_stats_t *st = &f->t->st;
  if (outcome == OCS_REMOTE_HIT) st->hits++;
  else if (outcome == OCS_REMOTE_LEASED) st->leased++;
  else if (outcome == OCS_REMOTE_BUSY) st->busy++;
  else st->unavailable++;
  f->cb(f->ctx, outcome, content, n);
  free(f);
}

/* SET NX GET answers with the lease's holder before the call: nil (it was free, now ours), this
 * front-end (ours already: looked up again at a later tick) or another (busy). */
static void ocs__on_lease(void *ctx, int status, const redisReply *r) {
  ocs__fetch_t *f = ctx;
  char id[24];
  snprintf(id, sizeof id, "%016" PRIx64, f->t->o.frontend_id);
  if (status != OCS_REDIS_OK || !r || (r->type != REDIS_REPLY_NIL && r->type != REDIS_REPLY_STRING))
    ocs__fetch_done(f, OCS_REMOTE_UNAVAILABLE, NULL, 0);
  else if (r->type == REDIS_REPLY_NIL || (r->len == strlen(id) && !memcmp(r->str, id, r->len)))
    ocs__fetch_done(f, OCS_REMOTE_LEASED, NULL, 0);
  else
    ocs__fetch_done(f, OCS_REMOTE_BUSY, NULL, 0);
}

static int ocs__lease(ocs__fetch_t *f) {
  char name[OCS_BKEY_TEXT], id[24], ms[16];
  ocs_bkey_text(&f->key, "oc:l:", name);
  snprintf(id, sizeof id, "%016" PRIx64, f->t->o.frontend_id);
  snprintf(ms, sizeof ms, "%u", f->t->o.lease_ms);
  const char *argv[] = {"SET", name, id, "NX", "PX", ms, "GET"}; /* NX with GET: Redis ≥ 7.0 */
  size_t lens[7];
  for (int i = 0; i < 7; i++) lens[i] = strlen(argv[i]);
  return ocs_redis_command(f->t->redis, f->t->o.deadline_ms, ocs__on_lease, f, 7, argv, lens);
}

static void ocs__on_get(void *ctx, int status, const redisReply *r) {
  ocs__fetch_t *f = ctx;
  if (status != OCS_REDIS_OK || !r || (r->type != REDIS_REPLY_STRING && r->type != REDIS_REPLY_NIL)) {
    ocs__fetch_done(f, OCS_REMOTE_UNAVAILABLE, NULL, 0);
    return;
  }
  if (r->type == REDIS_REPLY_STRING) {
    const uint8_t *content;
    size_t n;
    int e = ocs_bval_unpack(&f->key, (const uint8_t *)r->str, r->len, &content, &n);
    if (e == 0) {
      ocs__fetch_done(f, OCS_REMOTE_HIT, content, n);
      return;
    }
    f->t->st.rejected++; /* produced again, and the store overwrites it */
    oc_log(OC_LOG_WARN, "redis brick value rejected (%s): making it again", oc_strerror(e));
  }
  if (ocs__lease(f) < 0) ocs__fetch_done(f, OCS_REMOTE_UNAVAILABLE, NULL, 0);
}

int ocs_remote_create(ocs_remote_t **out, ocs_redis_t *redis, const ocs_remote_opts_t *o) {
  if (!out || !redis) return OC_EINVAL;
  ocs_remote_t *t = calloc(1, sizeof *t);
  if (!t) return OC_ENOMEM;
  t->redis = redis;
  if (o) t->o = *o;
  if (!t->o.deadline_ms) t->o.deadline_ms = 200;
  if (!t->o.lease_ms) t->o.lease_ms = 10000;
  *out = t;
  return 0;
}

void ocs_remote_free(ocs_remote_t *t) { free(t); }

int ocs_remote_fetch(ocs_remote_t *t, const ocs_bkey_t *key, ocs_remote_cb cb, void *ctx) {
  if (!t || !key || !cb) return OC_EINVAL;
  t->st.fetches++;
  ocs__fetch_t *f = malloc(sizeof *f);
  if (!f) return OC_ENOMEM;
  *f = (ocs__fetch_t){t, *key, cb, ctx};
  char name[OCS_BKEY_TEXT];
  ocs_bkey_text(key, "oc:b:", name);
  const char *argv[] = {"GET", name};
  size_t lens[] = {3, strlen(name)};
  int r = ocs_redis_command(t->redis, t->o.deadline_ms, ocs__on_get, f, 2, argv, lens);
  if (r < 0) {
    free(f);
    t->st.unavailable++;
  }
  return r;
}

static void ocs__on_stored(void *ctx, int status, const redisReply *r) {
  ocs_remote_t *t = ctx;
  if (status != OCS_REDIS_OK || !r || r->type == REDIS_REPLY_ERROR) t->st.store_failures++;
}

int ocs_remote_store(ocs_remote_t *t, const ocs_bkey_t *key, const void *content, size_t n) {
  if (!t || !key || (n && !content)) return OC_EINVAL;
  if (n > OCS_BVAL_MAX_CONTENT) return OC_ETOOBIG;
  size_t len = ocs_bval_size(n);
  uint8_t *v = malloc(len);
  if (!v) return OC_ENOMEM;
  ocs_bval_pack(key, content, n, v, len);
  char name[OCS_BKEY_TEXT], lease[OCS_BKEY_TEXT], ttl[16];
  ocs_bkey_text(key, "oc:b:", name);
  ocs_bkey_text(key, "oc:l:", lease);
  snprintf(ttl, sizeof ttl, "%u", t->o.value_ttl_s);
  const char *set[] = {"SET", name, (const char *)v, "EX", ttl};
  size_t set_lens[] = {3, strlen(name), len, 2, strlen(ttl)};
  /* hiredis copies the arguments into its output buffer: v is free to go after the call */
  int r = ocs_redis_command(t->redis, t->o.deadline_ms, ocs__on_stored, t, t->o.value_ttl_s ? 5 : 3, set, set_lens);
  free(v);
  if (r < 0) {
    t->st.store_failures++;
    return r;
  }
  t->st.stores++;
  ocs_remote_release(t, key);
  return 0;
}

/* Deletes a lease only if this front-end holds it: one that expired may be another's now. */
static const char ocs__release_lua[] =
    "if redis.call('get', KEYS[1]) == ARGV[1] then return redis.call('del', KEYS[1]) end return 0";

int ocs_remote_release(ocs_remote_t *t, const ocs_bkey_t *key) {
  if (!t || !key) return OC_EINVAL;
  char lease[OCS_BKEY_TEXT], id[24];
  ocs_bkey_text(key, "oc:l:", lease);
  snprintf(id, sizeof id, "%016" PRIx64, t->o.frontend_id);
  const char *argv[] = {"EVAL", ocs__release_lua, "1", lease, id};
  size_t lens[5];
  for (int i = 0; i < 5; i++) lens[i] = strlen(argv[i]);
  int r = ocs_redis_command(t->redis, t->o.deadline_ms, ocs__on_stored, t, 5, argv, lens);
  if (r < 0) t->st.store_failures++;
  else t->st.releases++;
  return r;
}

void ocs_remote_stats(const ocs_remote_t *t, ocs_remote_stats_t *out) {
  if (t) *out = t->st;
  else memset(out, 0, sizeof *out);
}
