/* net_share.c — bricks shared with the other front-ends of one world through Redis (brick_remote.h;
 * world.h, "Sharing bricks"; docs/scale-out.md).
 *
 * Before production (clocked epochs), the queue's best bricks are looked up in Redis, pipelined on
 * this connection: a brick another front-end made is offered to the world's cache, one another is
 * making right now (its lease) is held back until the next tick, one nobody has is leased and made
 * here. Production starts when every answer is in, or at a short deadline, whichever comes first;
 * answers after that still count (offers and holds are safe while production runs). After
 * production, what was made here is stored for the others. Whenever Redis is down or slow the
 * lookup is skipped or cut short and everything is made locally: no tick ever waits for Redis
 * longer than the deadline.
 *
 * The same --redis also holds the world's control history (control_stream.h), in clocked and in
 * stepped mode; bricks are shared on the clock only (a stepped world makes everything it plans). */
#include "net_share.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "brick_remote.h"
#include "control_stream.h"
#include "net_internal.h"
#include "oc_bytes.h" /* oc_grow */
#include "oc_err.h"
#include "oc_log.h"
#include "redis_client.h"
#include "scene_digest.h"

/* The queue's best bricks looked up per production: beyond this many, production will not reach
 * them before the next tick anyway (a few thousand bricks per second per front-end). */
#define OCS_SHARE_LOOKUP_MAX 4096
/* A stored brick lives this long in Redis unless maxmemory evicts it first (docs/scale-out.md). */
#define OCS_SHARE_TTL_S 3600u

/* A brick this front-end leased at the last lookup: given back if production did not make it. */
typedef struct {
  oc_key_t key;
  uint64_t stamp;
} ocs__leased_t;

struct ocs_share_s {
  ocs_server_t *srv;
  ocs_redis_t *redis;
  ocs_remote_t *tier;   /* NULL: stepped, bricks not shared */
  ocs_ctl_t *ctl;       /* the control history */
  uint64_t gen;          /* the world's generation: answers about an older world are dropped */
  int inflight;          /* fetches of this lookup not answered yet */
  int waiting;           /* production waits for this lookup */
  uint64_t started_ns;   /* uv_hrtime() at this lookup's start: what it adds, in the stats */
  void (*go)(ocs_server_t *srv);
  uv_timer_t deadline;
  int closing;
  ocs__leased_t *leased; /* this lookup's leases */
  size_t nleased, leased_cap;
  ocs_share_stats_t st;
  uint8_t buf[OCS_SHARE_MAX_BYTES];
};

typedef struct {
  ocs_share_t *sh;
  uint64_t gen;
  oc_key_t key;
  uint64_t stamp;
} ocs__lookup_t;

static void ocs__lookup_end(ocs_share_t *sh) {
  if (!sh->waiting) return;
  sh->waiting = 0;
  sh->st.wait_us += (uv_hrtime() - sh->started_ns) / 1000u;
  uv_timer_stop(&sh->deadline);
  sh->go(sh->srv);
}

static void ocs__on_deadline(uv_timer_t *t) {
  ocs_share_t *sh = t->data;
  if (sh->waiting) sh->st.cut_short++;
  ocs__lookup_end(sh);
}

static void ocs__on_found(void *ctx, int outcome, const uint8_t *content, size_t n) {
  ocs__lookup_t *l = ctx;
  ocs_share_t *sh = l->sh;
  sh->st.answered++;
  sh->st.answer_us += (uv_hrtime() - sh->started_ns) / 1000u;
  if (!sh->closing && l->gen == sh->gen) {
    ocs_world_t *w = sh->srv->world;
    if (outcome == OCS_REMOTE_HIT) {
      int r = ocs_world_offer(w, l->key, l->stamp, content, n);
      if (r == 1) sh->st.taken++;
      else if (r < 0) sh->st.refused++;
    } else if (outcome == OCS_REMOTE_BUSY) {
      ocs_world_hold_back(w, l->key, l->stamp);
      sh->st.held++;
    } else if (outcome == OCS_REMOTE_LEASED) {
      ocs__leased_t *a = oc_grow(sh->leased, &sh->leased_cap, sh->nleased, sizeof *a, 256);
      if (a) sh->leased = a;
      if (sh->nleased < sh->leased_cap) sh->leased[sh->nleased++] = (ocs__leased_t){l->key, l->stamp};
    }
  }
  free(l);
  if (--sh->inflight == 0) ocs__lookup_end(sh);
}

int ocs_share_open(ocs_server_t *srv, char *why, size_t why_len) {
  const ocs_server_desc_t *d = &srv->desc;
  if (!d->redis_host) return 0;
  ocs_share_t *sh = calloc(1, sizeof *sh);
  if (!sh) return OC_ENOMEM;
  sh->srv = srv;
  uint64_t id = (uint64_t)getpid() << 32 ^ (uint64_t)time(NULL);
  ocs_redis_opts_t ro = {.host = d->redis_host, .port = d->redis_port, .seed = id};
  ocs_remote_opts_t to = {.deadline_ms = d->redis_deadline_ms > 0 ? (uint32_t)d->redis_deadline_ms : 200, .value_ttl_s = OCS_SHARE_TTL_S,
                          .frontend_id = id};
  int r = 0;
  if (srv->period > 0 && ((r = ocs_redis_open(&sh->redis, &srv->loop, &ro)) < 0 ||
                          (r = ocs_remote_create(&sh->tier, sh->redis, &to)) < 0)) {
    ocs_redis_close(sh->redis);
    free(sh);
    return oc_errorf(r, why, why_len, "--redis %s:%d: %s", d->redis_host, d->redis_port, oc_strerror(r));
  }
  if ((r = ocs_ctl_open(&sh->ctl, srv, id, why, why_len)) < 0) {
    ocs_redis_close(sh->redis);
    ocs_remote_free(sh->tier);
    free(sh);
    return r;
  }
  uv_timer_init(&srv->loop, &sh->deadline);
  sh->deadline.data = sh;
  srv->share = sh;
  if (sh->tier)
    oc_log_info("sharing bricks through redis %s:%d (content id %016llx)", d->redis_host, d->redis_port,
                (unsigned long long)d->world.content_id);
  oc_log_info("control history in redis %s:%d, stream %s", d->redis_host, d->redis_port, OCS_CTL_STREAM);
  return 0;
}

static void ocs__share_closed(uv_handle_t *h) {
  ocs_share_t *sh = h->data;
  ocs_remote_free(sh->tier);
  free(sh->leased);
  free(sh);
}

void ocs_share_close(ocs_server_t *srv) {
  ocs_share_t *sh = srv->share;
  if (!sh || sh->closing) return;
  ocs__lookup_end(sh); /* production must run and end for the server to stop */
  sh->closing = 1;
  ocs_ctl_close(sh->ctl);
  ocs_redis_close(sh->redis); /* fetches in flight are answered now, and dropped */
  srv->share = NULL;
  uv_close((uv_handle_t *)&sh->deadline, ocs__share_closed);
}

int ocs_share_lookup(ocs_server_t *srv, void (*go)(ocs_server_t *srv)) {
  ocs_share_t *sh = srv->share;
  if (!sh || !sh->tier || sh->waiting) return 0;
  ocs_world_hold_clear(srv->world); /* each tick looks again */
  if (!ocs_redis_up(sh->redis)) {
    sh->st.skipped++;
    return 0;
  }
  oc_key_t key;
  uint64_t stamp;
  sh->nleased = 0;
  sh->started_ns = uv_hrtime();
  /* production takes the whole queue: what is not looked up would be made here unasked. A lease of
   * a brick production then does not reach keeps the others off it until production ends and
   * gives it back (ocs_share_store_made): one tick at most. */
  for (size_t i = 0; i < OCS_SHARE_LOOKUP_MAX && ocs_world_queue_item(srv->world, i, &key, &stamp) == 0; i++) {
    ocs__lookup_t *l = malloc(sizeof *l);
    if (!l) break;
    *l = (ocs__lookup_t){sh, sh->gen, key, stamp};
    ocs_bkey_t id = ocs_world_brick_id(srv->world, key, stamp);
    if (ocs_remote_fetch(sh->tier, &id, ocs__on_found, l) < 0) {
      free(l);
      break; /* down: the rest is made here */
    }
    sh->inflight++;
    sh->st.looked_up++;
  }
  if (!sh->inflight) return 0;
  sh->go = go;
  sh->waiting = 1;
  sh->st.lookups++;
  /* what production waits for: the deadline given, or by default 200 ms and a tenth of the period */
  double ms = srv->desc.redis_deadline_ms > 0 ? srv->desc.redis_deadline_ms : 100.0 * srv->period;
  if (!(srv->desc.redis_deadline_ms > 0) && ms > 200) ms = 200;
  uv_timer_start(&sh->deadline, ocs__on_deadline, (uint64_t)(ms > 1 ? ms : 1), 0);
  return 1;
}

void ocs_share_store_made(ocs_server_t *srv) {
  ocs_share_t *sh = srv->share;
  if (!sh || !sh->tier) return;
  oc_key_t keys[256];
  uint64_t stamps[256];
  size_t n;
  while ((n = ocs_world_made_take(srv->world, keys, stamps, 256)) > 0)
    for (size_t i = 0; i < n; i++) {
      size_t len = ocs_world_export(srv->world, keys[i], stamps[i], sh->buf, sizeof sh->buf);
      ocs_bkey_t id = ocs_world_brick_id(srv->world, keys[i], stamps[i]);
      if (len && ocs_remote_store(sh->tier, &id, sh->buf, len) == 0) sh->st.stored++;
      else sh->st.not_stored++;
    }
  /* leases of bricks production did not reach go back (a made one's went with its store) */
  for (size_t i = 0; i < sh->nleased; i++)
    if (!ocs_world_export(srv->world, sh->leased[i].key, sh->leased[i].stamp, sh->buf, sizeof sh->buf)) {
      ocs_bkey_t id = ocs_world_brick_id(srv->world, sh->leased[i].key, sh->leased[i].stamp);
      if (ocs_remote_release(sh->tier, &id) == 0) sh->st.released++;
    }
  sh->nleased = 0;
}

void ocs_share_world_changed(ocs_server_t *srv) {
  if (srv->share) srv->share->gen++;
}

int ocs_share_content_id(const ocs_server_t *srv, const oc_scene_t *scene, uint64_t *out, char *why, size_t why_len) {
  *out = 0;
  if (!srv->desc.redis_host || !(srv->period > 0)) return 0; /* bricks are shared on the clock only */
  return ocs_scene_digest(srv->scene_path, scene, out, why, why_len);
}

void ocs_share_stats(const ocs_server_t *srv, ocs_share_stats_t *out) {
  memset(out, 0, sizeof *out);
  const ocs_share_t *sh = srv->share;
  if (!sh) return;
  *out = sh->st;
  out->enabled = 1;
  ocs_ctl_stats(sh->ctl, &out->control);
  out->up = sh->tier ? ocs_redis_up(sh->redis) : out->control.up;
  if (!sh->tier) return;
  ocs_remote_stats_t rs;
  ocs_remote_stats(sh->tier, &rs);
  out->hits = rs.hits;
  out->leased = rs.leased;
  out->busy = rs.busy;
  out->unavailable = rs.unavailable;
  out->rejected = rs.rejected;
  out->store_failures = rs.store_failures;
}

ocs_ctl_t *ocs_share_control(const ocs_server_t *srv) { return srv->share && !srv->share->closing ? srv->share->ctl : NULL; }

void ocs_share_idle(ocs_server_t *srv) { ocs_ctl_idle(ocs_share_control(srv)); }
