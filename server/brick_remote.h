/* brick_remote.h — the shared tier of the brick store: bricks in Redis, shared by every
 * front-end of one world (docs/architecture.md, "Beyond one machine").
 *
 * Production happens once across the cluster: a front-end that misses locally asks here. A hit
 * hands back content another front-end made. On a miss it takes the brick's lease (SET NX PX): the
 * winner produces and stores the brick, the others requeue it and look again later. Whenever Redis
 * is down, slow or answers nonsense, the answer is OCS_REMOTE_UNAVAILABLE and the caller produces
 * locally: a viewer never waits on Redis.
 *
 * Names in Redis: "oc:b:<key>" holds a value packed by brick_value.h; "oc:l:<key>" a lease, whose
 * value is the front-end's id and which expires by itself (PX), so a front-end that dies while
 * producing only delays the others by the lease time. A front-end that looks a brick up again
 * while it holds the lease gets it again (SET NX GET, Redis ≥ 7.0); one that did not make a leased
 * brick gives the lease back (compare and delete, a two-line Lua script).
 *
 * Every function runs on the loop's thread (redis_client.h). */
#ifndef OC_SERVER_BRICK_REMOTE_H
#define OC_SERVER_BRICK_REMOTE_H

#include <stddef.h>
#include <stdint.h>

#include "brick_value.h"
#include "redis_client.h"

/* What a fetch found. */
enum {
  OCS_REMOTE_HIT = 0,          /* content is the brick, as stored */
  OCS_REMOTE_LEASED = 1,       /* nobody has it: this front-end holds the lease, produce and store it */
  OCS_REMOTE_BUSY = 2,         /* another front-end holds the lease: requeue, look again later */
  OCS_REMOTE_UNAVAILABLE = 3,  /* Redis down, slow or wrong: produce locally */
};

typedef struct {
  uint32_t deadline_ms;  /* each Redis command's deadline (default 200) */
  uint32_t lease_ms;     /* a lease's lifetime: longer than the dearest brick takes (default 10000) */
  uint32_t value_ttl_s;  /* a stored brick's lifetime in Redis; 0: none, Redis' maxmemory policy evicts */
  uint64_t frontend_id;  /* written into leases, for operators reading them */
} ocs_remote_opts_t;

typedef struct {
  uint64_t fetches, hits, leased, busy, unavailable;
  uint64_t rejected;  /* values that failed a check (brick_value.h): discarded, produced again */
  uint64_t stores, store_failures, releases;
} ocs_remote_stats_t;

typedef struct ocs_remote_s ocs_remote_t;

/*! A fetch's outcome; content/n only with OCS_REMOTE_HIT, valid during the call. */
typedef void (*ocs_remote_cb)(void *ctx, int outcome, const uint8_t *content, size_t n);

/*! ocs_remote_create() : the tier over an open connection (not owned). @return 0, OC_EINVAL, OC_ENOMEM. */
int ocs_remote_create(ocs_remote_t **out, ocs_redis_t *redis, const ocs_remote_opts_t *o);
/*! ocs_remote_free() : call after the connection is closed (its callbacks have run). NULL is accepted. */
void ocs_remote_free(ocs_remote_t *t);
/*! ocs_remote_fetch() : looks `key` up and, when absent, tries to take its lease.
 *  @return 0: cb will be called exactly once, on the loop, never from inside this call. OC_EIO:
 *  Redis is down (counted as unavailable: produce locally), OC_EINVAL, OC_ENOMEM: cb never will. */
int ocs_remote_fetch(ocs_remote_t *t, const ocs_bkey_t *key, ocs_remote_cb cb, void *ctx);
/*! ocs_remote_store() : stores a brick this front-end made (under its lease or not) and releases
 *  the lease. Fire and forget: a failure is counted, the brick is simply made again elsewhere.
 *  @return 0, OC_EIO (down), OC_ETOOBIG, OC_ENOMEM. */
int ocs_remote_store(ocs_remote_t *t, const ocs_bkey_t *key, const void *content, size_t n);
/*! ocs_remote_release() : gives a lease this front-end holds back (it did not make the brick after
 *  all), so that another may make it at once instead of after the lease's time. Fire and forget.
 *  @return 0, OC_EIO (down), OC_EINVAL. */
int ocs_remote_release(ocs_remote_t *t, const ocs_bkey_t *key);
/*! ocs_remote_stats() : the counters so far. */
void ocs_remote_stats(const ocs_remote_t *t, ocs_remote_stats_t *out);

#endif /* OC_SERVER_BRICK_REMOTE_H */
