/* ocs_server.h — the network server: one libuv loop serving one shared world (world.h) to many viewers
 * and control clients over the wire protocol (docs/protocol.md, "Wire").
 *
 * The loop thread does all I/O and owns every session; ocs_world_step() runs on libuv's thread
 * pool, once per epoch period (or per "step" control request). While a step runs the world's
 * viewers are not touched: cameras and acknowledgements are kept in the sessions and applied
 * before the next step; handshakes and control requests wait for the step to end.
 *
 * Backpressure: an epoch's frames are produced only while the session's unsent bytes are under a
 * low-water mark, so a session never holds more than about one chunk beyond it; soft and hard
 * limits (as Redis's client output buffer limits) and a stall timeout close what still falls
 * behind. A slow viewer does not delay anyone's epoch: it is skipped (coalesced) until it
 * acknowledges, and its next plan is sized from what it absorbed. */
#ifndef OC_SERVER_OCS_SERVER_H
#define OC_SERVER_OCS_SERVER_H

#include <stdint.h>

#include "oc_scene.h"
#include "world.h"

typedef struct ocs_server_s ocs_server_t;

typedef struct {
  const char *host;        /**< address to bind; NULL → "127.0.0.1" */
  int port;                /**< 0: any free port (ocs_server_port() tells which) */
  const char *token;       /**< required from every client (from viewers only when control_token is
                                set); NULL: none */
  const char *control_token; /**< required from control clients instead of token, which is then refused
                                for control (a viewer's credentials cannot change the world); NULL:
                                control clients present token */
  int metrics;             /**< serve Prometheus metrics over HTTP (docs/operations.md) */
  const char *metrics_host; /**< its address; NULL → "127.0.0.1" (another needs a token or insecure) */
  int metrics_port;        /**< 0: any free port (ocs_server_metrics_address() tells which) */
  const char *trusted_proxies; /**< "ADDR[,ADDR...]": peers that must begin with a PROXY protocol header
                                (v2 or v1), whose client address then counts for limits and logs;
                                a PROXY header from any other peer is refused. NULL: none */
  const char *audit_log;   /**< a file that gets one JSON line per control change (appended); NULL: none */
  double epoch_period;     /**< s; < 0 → the scene's; 0 → stepped by control requests only */
  double drain_s;          /**< a drain (SIGTERM, control "drain") waits this long for viewers to leave; 0 → 30 */
  double linger_s;         /**< keep a dropped viewer's session for resume; < 0 → 30, 0 → none */
  double handshake_s;      /**< HELLO must arrive within; 0 → 10 (at most idle_s) */
  double idle_s;           /**< close a connection silent this long; 0 → 60 */
  double stall_s;          /**< close a connection whose unsent bytes do not drain; 0 → 30 */
  double soft_s;           /**< time allowed over the soft limit; 0 → 10 */
  uint64_t queue_soft;     /**< unsent bytes; 0 → 4 MiB */
  uint64_t queue_hard;     /**< unsent bytes; 0 → 16 MiB */
  int max_connections;     /**< viewers and control clients together; 0 → 256 */
  int max_per_address;     /**< connections at once from one IP address; 0 → 32 */
  double handshake_rate;   /**< connections accepted per second from one IP address (a token
                                bucket of max_per_address); 0 → 10 */
  int max_lingering;       /**< dropped viewers kept for resume at once (oldest let go first); 0 → 16 */
  uint64_t linger_budget;  /**< sum of the lingering viewers' budgets; 0 → half the total */
  int insecure;            /**< allow a non-loopback host (and metrics_host) without a token
                                (ocs_server_create refuses it otherwise) */
  int send_buffer;         /**< SO_SNDBUF of each connection, bytes; 0 → the system's */
  const char *step_gate;   /**< tests: each step waits until this file exists (a held producer the
                                test releases), at most 600 s; NULL: none */
  int zstd_level;          /**< 0 → OCP_LEVEL_DEFAULT */
  int deltas;              /**< < 0 → off; otherwise on for viewers that accept them */
  const char *scene_path;  /**< re-read by the "reload" control request; NULL: the built-in planet */
  const char *redis_host;  /**< share bricks with other front-ends through Redis there (clocked
                                epochs only; docs/scale-out.md); NULL: none */
  int redis_port;
  int redis_deadline_ms;    /**< each Redis command's deadline, and the most production waits for
                                a lookup; 0 → 200, production waiting at most a tenth of the period */
  ocs_world_desc_t world;
} ocs_server_desc_t;

/*! ocs_server_create() : builds the world from `scene`, binds and listens. @return 0 or a negative
 *  OC_E* with a one-line reason (e.g. the address is in use). */
int ocs_server_create(ocs_server_t **out, const oc_scene_t *scene, const ocs_server_desc_t *desc, char *why, size_t why_len);
/*! ocs_server_address() : "HOST:PORT" actually bound. */
const char *ocs_server_address(const ocs_server_t *s);
int ocs_server_port(const ocs_server_t *s);
/*! ocs_server_metrics_address() : "HOST:PORT" the metrics endpoint is bound to; NULL: none. */
const char *ocs_server_metrics_address(const ocs_server_t *s);
/*! ocs_metrics_token() : the token a scrape of /metrics presents (Authorization: Bearer): the
 *  control token, else the token; NULL: none asked. */
const char *ocs_metrics_token(const ocs_server_desc_t *d);
/*! ocs_server_run() : runs the loop until SIGINT/SIGTERM (handled when handle_signals) or
 *  ocs_server_stop(). @return 0 or a negative OC_E*. */
int ocs_server_run(ocs_server_t *s, int handle_signals);
/*! ocs_server_stop() : from the loop thread: says GOODBYE to everyone and ends the loop. */
void ocs_server_stop(ocs_server_t *s);
/*! ocs_server_stop_async() : the same, asked from any thread (a server run on a thread of its own,
 *  as overcast-bench and overcast-stress do): ocs_server_run() returns soon after. */
void ocs_server_stop_async(ocs_server_t *s);
void ocs_server_free(ocs_server_t *s);

#endif /* OC_SERVER_OCS_SERVER_H */
