/* control_stream.h — the control history of a world served by several front-ends, in a Redis
 * Stream (docs/scale-out.md, "Control: the history in a Redis Stream"; world_clock.h).
 *
 * With --redis, a control request that changes the world (weather, time, pause, resume, sun, and in
 * stepped mode step) is not applied where it arrives: it is appended (XADD) to the stream
 * OCS_CTL_STREAM, and every front-end, the receiver included, applies the entries it reads (XREAD
 * BLOCK) in the stream's order, each at the same epoch:
 *   - clocked: entry i takes effect at epoch E_i = max(its "epoch" field, E_{i-1}); the receiver
 *     asks for an epoch at least 2 ticks ahead (ocs_ctl_epoch_ahead()), far enough that every
 *     front-end has read it before it builds that epoch. A clock change is an entry of the world
 *     clock's history at instant E_i·P; a weather change starts at the world time of that instant;
 *     a sun move is applied between ticks E_i − 1 and E_i.
 *   - stepped: a step entry steps its epochs on every front-end; a change takes effect from the
 *     epoch after the steps before it in the stream.
 * The first entry, id 0-1 (an XADD with that id succeeds only on an empty stream), is the clock's
 * origin: a front-end that starts later takes it, then applies the whole stream, before its first
 * epoch. While the stream's Redis is unreachable, changes are refused: never applied on one
 * front-end only.
 *
 * Two connections of its own (redis_client.h): a blocking XREAD occupies its connection for up to
 * OCS_CTL_BLOCK_MS, so reads have one and appends the other (bricks keep theirs, net_share.c).
 * Everything runs on the loop thread; the world is changed only while it is idle (ocs_ctl_idle()). */
#ifndef OC_SERVER_CONTROL_STREAM_H
#define OC_SERVER_CONTROL_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "oc_math.h"

typedef struct ocs_server_s ocs_server_t;
typedef struct ocs_world_s ocs_world_t;
typedef struct ocs_session_s ocs_session_t;
typedef struct ocs_ctl_s ocs_ctl_t;
struct cJSON;

#define OCS_CTL_STREAM "oc:ctl"  /* the stream's key: one world per Redis */
#define OCS_CTL_VERSION 1        /* the entries' "v"; a newer one is skipped */
#define OCS_CTL_BLOCK_MS 1000u   /* XREAD BLOCK */
#define OCS_CTL_CATCHUP_S 10.0   /* the first epoch waits at most this long for the history */

/* A change of the world, as a control request asks it and as a stream entry carries it. */
typedef enum {
  OCS_CHG_ORIGIN = 0, /* the clock's first entry: world time `time` at instant `utc` */
  OCS_CHG_WEATHER,    /* `preset` over `seconds` */
  OCS_CHG_TIME,       /* world time `set` and/or `scale` (NAN: not given) */
  OCS_CHG_PAUSE,
  OCS_CHG_RESUME,
  OCS_CHG_SUN,        /* unit vector `sun` */
  OCS_CHG_STEP,       /* `epochs` more epochs (stepped mode) */
  OCS_CHG_COUNT
} ocs_chg_op_t;

typedef struct {
  ocs_chg_op_t op;
  int preset;
  double seconds;
  double set, scale;
  oc_dvec3 sun;
  uint32_t epochs;
  double utc, time;
} ocs_change_t;

/*! ocs_change_name() : "origin", "weather", ... (the entries' "op"), or NULL. */
const char *ocs_change_name(int op);
/*! ocs_change_apply() : a change (not a step) to the world, at instant utc. @return 0 or OC_E*. */
int ocs_change_apply(ocs_world_t *w, const ocs_change_t *c, double utc);

typedef struct {
  int up;                 /* both connections up */
  int caught_up;          /* the history read (or the wait for it given up) */
  uint64_t read;          /* entries read */
  uint64_t applied;       /* of those, applied to the world (steps: queued) */
  uint64_t skipped;       /* malformed, unknown op, newer version: logged with their ids */
  uint64_t late;          /* applied after their epoch had been built here */
  uint64_t published;     /* this front-end's requests appended */
  uint64_t refused;       /* requests refused: Redis unreachable, or the append failed */
  uint64_t last_epoch;    /* of the last entry applied: its epoch (stepped: the first after it) */
  double last_time;       /* the world time at that epoch's instant, once applied */
  char last_op[16];
  char last_id[48];       /* the stream id of the last entry read */
} ocs_ctl_stats_t;

/*! ocs_ctl_open() : connects (asynchronously) and starts reading from the first entry. The first
 *  epoch waits for the history: ocs_ctl_open() makes the caller leave ocs_epoch_start_timer() to it.
 *  @return 0, OC_EINVAL or OC_ENOMEM, with why. */
int ocs_ctl_open(ocs_ctl_t **out, ocs_server_t *srv, uint64_t frontend_id, char *why, size_t why_len);
/*! ocs_ctl_close() : drops both connections; requests waiting for their entry are not answered. */
void ocs_ctl_close(ocs_ctl_t *c);
/*! ocs_ctl_publish() : appends the change session s asked for (request id `request`). Its reply
 *  comes when this front-end applies the entry (ocs_control_reply_later()), or for a step when the
 *  steps are done; a failed append is answered with its reason. @return 0, or OC_EIO (Redis
 *  unreachable, the history not read yet) / OC_ENOMEM with the refusal in why. */
int ocs_ctl_publish(ocs_ctl_t *c, ocs_session_t *s, uint32_t request, const ocs_change_t *chg, char *why, size_t why_len);
/*! ocs_ctl_idle() : the world is idle (between ticks, production ended): the entries due are applied. */
void ocs_ctl_idle(ocs_ctl_t *c);
/*! ocs_ctl_epoch_ahead() : the epoch a change asked at utc takes effect at, on the clock of period
 *  P: the first n with (n − 1)·P ≥ utc + P/2 + max(P, 250 ms), so at least 2 ticks ahead. */
uint64_t ocs_ctl_epoch_ahead(double utc, double period);
void ocs_ctl_stats(const ocs_ctl_t *c, ocs_ctl_stats_t *out);

/*! ocs_control_reply_later() (net_control.c) : the reply to request `request` of session `session`,
 *  if it is still connected: o (taken; NULL: {}) when error is NULL, else the refusal. */
void ocs_control_reply_later(ocs_server_t *srv, uint32_t session, uint32_t request, struct cJSON *o, const char *error);

#endif /* OC_SERVER_CONTROL_STREAM_H */
