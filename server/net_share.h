/* net_share.h — the network server's side of sharing bricks between front-ends through Redis
 * (net_share.c). Not a public interface: net_server.c opens and closes it, net_epoch.c looks the
 * queue up before production and stores what production made, net_control.c tells it of a
 * reloaded world, net_stats.c reports it. */
#ifndef OC_SERVER_NET_SHARE_H
#define OC_SERVER_NET_SHARE_H

#include <stddef.h>
#include <stdint.h>

#include "control_stream.h"
#include "oc_scene.h"

typedef struct ocs_server_s ocs_server_t;
typedef struct ocs_share_s ocs_share_t;

typedef struct {
  int enabled, up;          /* --redis given; connected now */
  uint64_t lookups;         /* productions that waited for a lookup */
  uint64_t looked_up;       /* bricks asked for */
  uint64_t hits, taken;     /* found in Redis; of those, offered and taken into the cache */
  uint64_t leased, busy;    /* made here under a lease; another front-end's lease: held back */
  uint64_t held;            /* held back in the world */
  uint64_t unavailable;     /* Redis down or slow: made here */
  uint64_t rejected;        /* values that failed their checks (made again) */
  uint64_t refused;         /* values whose content the world refused */
  uint64_t skipped;         /* productions with Redis down: no lookup */
  uint64_t cut_short;       /* lookups whose deadline came before every answer */
  uint64_t stored, not_stored, store_failures;
  uint64_t released;        /* leases given back: production did not reach their bricks */
  uint64_t answered;        /* lookups answered (any outcome) */
  uint64_t answer_us;       /* summed over those: from the lookup's start to the answer */
  uint64_t wait_us;         /* summed over productions: how long each waited for its lookup */
  ocs_ctl_stats_t control;  /* the control history (control_stream.h) */
} ocs_share_stats_t;

/*! ocs_share_open() : with desc.redis_host, connects (asynchronously: a Redis not up yet only
 *  means local production until it is) and opens the control history (control_stream.h), which
 *  then starts the epochs (ocs_epoch_start_timer()) once it is read. Bricks are shared on the
 *  clock only: a stepped server shares its control history. @return 0 or a negative OC_E* with why. */
int ocs_share_open(ocs_server_t *srv, char *why, size_t why_len);
/*! ocs_share_close() : drops the connection; a production waiting for a lookup starts now. */
void ocs_share_close(ocs_server_t *srv);
/*! ocs_share_lookup() : looks the queue's best bricks up. @return 1 when go(srv) will be called
 *  once the answers are in or the deadline passes; 0 (no sharing, Redis down, nothing queued):
 *  go now. */
int ocs_share_lookup(ocs_server_t *srv, void (*go)(ocs_server_t *srv));
/*! ocs_share_store_made() : stores what production made here (after ocs_world_produce_end()). */
void ocs_share_store_made(ocs_server_t *srv);
/*! ocs_share_world_changed() : a reload replaced the world: answers about the old one are dropped. */
void ocs_share_world_changed(ocs_server_t *srv);
/*! ocs_share_content_id() : the content id a world of `scene` gets (0 without --redis). */
int ocs_share_content_id(const ocs_server_t *srv, const oc_scene_t *scene, uint64_t *out, char *why, size_t why_len);
void ocs_share_stats(const ocs_server_t *srv, ocs_share_stats_t *out);
/*! ocs_share_control() : the shared control history, or NULL (no --redis: changes apply here). */
ocs_ctl_t *ocs_share_control(const ocs_server_t *srv);
/*! ocs_share_idle() : the world is idle between epochs: the control entries due are applied. */
void ocs_share_idle(ocs_server_t *srv);

#endif /* OC_SERVER_NET_SHARE_H */
