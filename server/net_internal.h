/* net_internal.h — what the files of the network server share (ocs_server.h is the public side).
 * Not a public interface.
 *
 * One file per concern, each calling only the ones above it in this list (no loops; a step's end
 * reaches the higher layers through the after_step hook that net_server.c installs):
 *
 *   net_proxy.c      the PROXY protocol header and the --trusted-proxy list (net_proxy.h: pure)
 *   net_peer.c       per-address connection counts and the handshake rate (token buckets)
 *   net_session.c    a session's lifetime (close, lost, linger within caps) and output (send,
 *                    pump, stream)
 *   net_admit.c      fair admission: budgets, lingering sessions giving theirs back first
 *   net_share.c      bricks shared with other front-ends through Redis, looked up before
 *                    production and stored after it; it opens the control history
 *                    (control_stream.c: changes through a Redis Stream, applied between epochs)
 *   net_epoch.c      ticks on the epoch timer, steps on the thread pool, new states streamed
 *   net_handshake.c  HELLO: version, tokens (constant time; viewer and control), resume, WELCOME
 *   net_stats.c      the server's figures, gathered once for the stats reply and for /metrics
 *   net_audit.c      the audit log: a JSON line per control change
 *   net_control.c    CONTROL requests (weather, time, sun, step, reload, sessions, stats)
 *   net_input.c      reading (a trusted proxy's PROXY header first), frames dispatched by type,
 *                    input held while a step runs
 *   net_listener.c   the listening socket and accepting connections (limits checked first)
 *   net_metrics_text.c  the figures as Prometheus families (what /metrics exports)
 *   net_metrics.c    /metrics over HTTP (libmicrohttpd driven by the loop)
 *   net_house.c      housekeeping: handshake, idle and stall timeouts, lingering sessions
 *   net_server.c     create, run, stop and free; signals; drains (ended by net_house.c) */
#ifndef OC_SERVER_NET_INTERNAL_H
#define OC_SERVER_NET_INTERNAL_H

#include <stdatomic.h>
#include <stdio.h>
#include <uv.h>

#include "histogram.h"
#include "net_proxy.h" /* ocs_proxy_addr_t */
#include "net_share.h" /* ocs_share_stats_t */
#include "ocs_server.h"
#include "ocp_epoch.h"
#include "ocp_wire.h"

/*! The delay a drain's GOODBYE RECONNECT asks of viewers before they come back (ms): long enough for
 *  a restarted server to be listening again. */
#define OCS_RECONNECT_DELAY_MS 1000

typedef enum {
  OCS_SS_HANDSHAKE = 0, /* waiting for HELLO */
  OCS_SS_READY = 1,     /* welcomed */
  OCS_SS_LINGER = 2,    /* connection lost, viewer kept for resume */
  OCS_SS_CLOSING = 3,   /* saying goodbye; freed in the close callback */
  OCS_SS_COUNT
} ocs_session_state_t;

/* Why a connection or a HELLO was refused: counted per reason in the stats reply. */
#define OCS_REFUSALS(XX)                                                 \
  XX(CONNECTIONS, "connections") /* the server's connection limit */    \
  XX(PER_ADDRESS, "per_address") /* that address's connection limit */ \
  XX(RATE, "rate")               /* that address's handshake rate */   \
  XX(VIEWERS, "viewers")         /* the viewer limit */                \
  XX(BUDGET, "budget")           /* not even the minimum budget left */ \
  XX(TOKEN, "token")                                                    \
  XX(VERSION, "version")                                                \
  XX(SHUTDOWN, "shutdown")                                              \
  XX(PROXY, "proxy") /* a PROXY header not from a trusted proxy, or a trusted one's missing or bad */ \
  XX(DRAINING, "draining") /* a viewer's HELLO while the server drains */
typedef enum {
#define OCS__REFUSAL_ENUM(name, key) OCS_REFUSE_##name,
  OCS_REFUSALS(OCS__REFUSAL_ENUM)
#undef OCS__REFUSAL_ENUM
  OCS_REFUSE_COUNT
} ocs_refusal_t;

/* One remote IP address: its open connections and its handshake token bucket. */
typedef struct ocs_peer_s {
  char ip[48];
  int conns;     /* connections open now (accepted, not refused) */
  double tokens; /* handshakes it may start now; refilled at handshake_rate, up to max_per_address */
  double refilled;
} ocs_peer_t;

typedef struct ocs_session_s ocs_session_t;

struct ocs_session_s {
  uv_tcp_t tcp; /* handle; data → the session */
  uv_shutdown_t shut;
  ocs_server_t *srv;
  ocs_session_t *prev, *next;
  uint32_t id;
  uint64_t secret;
  int role;  /* OCP_ROLE_* once welcomed */
  int state; /* ocs_session_state_t */
  int connected; /* tcp is open (not yet uv_close'd) */
  int drained;   /* told GOODBYE RECONNECT: closing once the peer leaves, or at the drain's end */
  char addr[64]; /* "IP:PORT" of the peer: the client's, as a trusted proxy's header says */
  uint8_t *proxy_buf; /* from a trusted proxy: its PROXY header so far (OCS_PROXY_MAX bytes);
                         NULL once it is complete, or for a direct peer */
  size_t proxy_len;
  ocs_peer_t *peer; /* its address's entry while it counts there (admitted, open); else NULL */
  ocp_reader_t rd;
  uint8_t version; /* negotiated */
  double created, last_rx, last_progress, soft_since, closing_since;
  uint64_t queued; /* bytes handed to uv_write and not yet written */
  int kq_last;      /* bytes in the kernel's send queue not acknowledged by the peer, last look */
  double kq_since;  /* since when it has stayed kq_last */
  uint64_t bytes_out, bytes_in;
  /* Input held while a step runs (a frame that needs the world). */
  int blocked;
  ocp_header_t deferred_hdr;
  uint8_t *deferred;
  /* Viewer. */
  ocs_viewer_t *viewer;
  ocs_plan_desc_t granted;
  uint32_t caps;
  ocp_epoch_enc_t *enc;
  int streaming, awaiting_ack, ack_pending, cam_new;
  int prepared;            /* the newest state's stream is set up (ocs_session_prepare), not started */
  uint64_t stream_epoch, stream_checksum, last_out_epoch;
  ocs_view_t cam;
  ocp_stats_t stats_msg; /* the STATS sent after the epoch being streamed */
  double linger_since, linger_until, stream_started;
  uint64_t epochs, acks;
  uint64_t budgets_sent; /* BUDGET messages */
  double ack_latency_sum, ack_latency_max;
  /* Control: a "step" request answered when its epochs are done. */
  int step_waiting;
  uint32_t step_request;
  uint64_t step_target;
};

/* The server's connection counters since it started: kept in the server, copied whole into its
 * figures (ocs_stats_t). */
typedef struct {
  uint64_t accepted, refused, closed_errors, resumes;
  uint64_t budget_lowerings; /* viewers lowered by admission to make room (net_admit.c) */
  uint64_t refusals[OCS_REFUSE_COUNT]; /* connections and HELLOs refused, by reason */
} ocs_net_counts_t;

struct ocs_server_s {
  uv_loop_t loop;
  uv_tcp_t listener;
  uv_timer_t epoch_timer, house_timer;
  uv_timer_t send_timer;     /* a tick built ahead of its due instant: its states go out then */
  uv_async_t taken_async;    /* production has taken its bricks: a tick that waited may start */
  uv_async_t stop_async;     /* ocs_server_stop_async(): a stop asked from another thread */
  uv_idle_t tick_idle;       /* a due tick: keeps the next poll from blocking ... */
  uv_check_t tick_check;     /* ... and starts the step after it, once pending ACKs are read */
  uv_signal_t sig_int, sig_term;
  uv_work_t work, produce_work; /* a step; production between ticks (both may run at once) */
  int signals;
  ocs_server_desc_t desc;
  char host[64], address[96];
  char *token, *control_token, *scene_path;
  ocs_proxy_addr_t trusted[OCS_PROXY_TRUSTED_MAX]; /* --trusted-proxy */
  int ntrusted;
  FILE *audit;                   /* --audit-log, appended; NULL: none */
  struct ocs_metrics_s *metrics; /* the /metrics endpoint (net_metrics.c); NULL: none */
  struct ocs_share_s *share;     /* bricks shared through Redis (net_share.c); NULL: none */
  char metrics_address[96];
  oc_scene_t scene;
  ocs_world_t *world;
  double period;
  ocs_session_t *sessions; /* every session, lingering ones too */
  int nconnected;          /* open connections, refused ones still closing included */
  int nadmitted;           /* open connections that passed the connection limits */
  uint32_t next_id;
  int draining;       /* no new viewers; the server stops once the drained ones have left */
  double drain_until; /* ocs_net_now() at which a drain closes what remains */
  int stepping, step_rc, stopping; /* stepping: the world is busy (ticking or producing) */
  int ticking;                      /* a step runs */
  uint64_t steps_queued, steps_done, late_ticks;
  ocs_hist_t tick_lateness; /* s: clocked ticks' first frames after their due instants (0: on time) */
  uint64_t step_epoch;  /* the running step's epoch (clocked); 0: the virtual clock's next */
  uint64_t tick_epoch;  /* the due epoch the last tick asked for */
  uint64_t armed_epoch; /* the epoch the timer waits for */
  double tick_lead;     /* s: a clock tick is built this long before its due instant (learnt) */
  double step_took;     /* s: the last step's time on its thread */
  int tick_hold;        /* the running step is a clock tick: its states wait for the due instant */
  int producing;        /* the world's production queue is being worked on (stepping is set too) */
  atomic_int overlap;   /* production has taken its bricks (ocs_world_produce_run): a tick may run */
  int produce_rc;       /* ocs_world_produce_begin()'s */
  uint64_t production_epoch; /* the world's epoch when production started */
  int end_due;          /* production ended during a tick: ocs_world_produce_end() when it ends */
  int tick_overrun;     /* a tick came due before production took its bricks: it starts when
                           production ends */
  double produce_s;     /* this production's time limit */
  uint64_t bricks_made; /* by production between ticks */
  uint64_t produce_errors; /* bricks whose production failed, as last reported */
  double plan_ms, produce_ms; /* of the last step, for every viewer's STATS */
  /* viewers to remove once the running step ends */
  ocs_viewer_t **doomed;
  int ndoomed;
  size_t doomed_cap;
  ocs_peer_t **peers; /* addresses with open connections or a bucket still refilling */
  int npeers;
  size_t peers_cap;
  void (*after_step)(ocs_server_t *srv); /* net_server.c: held input, waiting "step" requests */
  ocs_net_counts_t counts;
  uint8_t readbuf[64 * 1024];
};

/*-*** net_peer.c ***/

/*! ocs_peer_admit() : counts a new connection from `ip` against its address's limits.
 *  @return the entry (the connection holds it until ocs_peer_release()), or NULL with the reason
 *  in *refusal (PER_ADDRESS, RATE, or CONNECTIONS when the table itself is full). */
ocs_peer_t *ocs_peer_admit(ocs_server_t *srv, const char *ip, double now, ocs_refusal_t *refusal);
void ocs_peer_release(ocs_peer_t *p);
/*! ocs_peer_sweep() : frees entries with no connection whose bucket is full again. */
void ocs_peer_sweep(ocs_server_t *srv, double now);
void ocs_peer_free_all(ocs_server_t *srv);
const char *ocs_refusal_key(ocs_refusal_t r);

/*-*** net_session.c ***/

double ocs_net_now(void);
const char *ocs_role_name(int role);
/*! ocs_session_state_name() : "handshake", "ready", "lingering" or "closing". */
const char *ocs_session_state_name(int state);
void ocs_session_link(ocs_server_t *srv, ocs_session_t *s);
void ocs_session_unlink(ocs_server_t *srv, ocs_session_t *s);
void ocs_session_free(ocs_session_t *s);
ocs_session_t *ocs_session_find(ocs_server_t *srv, uint32_t id);
/*! ocs_session_drop_viewer() : removes the session's viewer from the world now, or after the
 *  running step. */
void ocs_session_drop_viewer(ocs_server_t *srv, ocs_session_t *s);
void ocs_session_close_handle(ocs_session_t *s);
void ocs_session_on_closed(uv_handle_t *h);
/*! ocs_session_send() : queues one buffer of whole frames (takes ownership of b's bytes). */
void ocs_session_send(ocs_session_t *s, oc_buf_t *b);
/*! ocs_session_close() : sends ERROR (code ≠ OK) or GOODBYE (code OK, SHUTDOWN, RELOAD, KICKED)
 *  with text, logs it, and closes; the viewer is removed (not kept for resume). */
void ocs_session_close(ocs_session_t *s, uint32_t code, const char *text);
/*! ocs_session_refuse() : ocs_session_close() with the code of a refusal, counted by reason. */
void ocs_session_refuse(ocs_session_t *s, ocs_refusal_t why, const char *text);
/*! ocs_session_lost() : the peer went away: a welcomed viewer lingers for resume (within the
 *  lingering caps: the oldest lingering sessions are let go to make room), anything else is
 *  dropped. */
void ocs_session_lost(ocs_session_t *s, const char *cause);
/*! ocs_session_let_go() : drops a lingering session, its viewer and budget, logging why. */
void ocs_session_let_go(ocs_session_t *t, const char *why);
/*! ocs_session_oldest_lingering() : the session lingering longest (NULL: none), and how many
 *  linger with how much budget. */
ocs_session_t *ocs_session_oldest_lingering(ocs_server_t *srv, int *count, uint64_t *budget);
/*! ocs_session_stream() : starts streaming the viewer's newest state, as a difference from `base`
 *  (what it holds): ocs_session_prepare() then ocs_session_go(). */
void ocs_session_stream(ocs_session_t *s, const oc_state_t *base);
/*! ocs_session_prepare() : everything of ocs_session_stream() but the sending (the encoder's set-up:
 *  the record differences, the checksum over tens of MB of codes), so a tick built ahead of its due
 *  instant sends its first frame at that instant. @return 0, or -1 (nothing to send, or the session
 *  was closed). ocs_session_go() : starts sending a prepared stream (nothing otherwise). */
int ocs_session_prepare(ocs_session_t *s, const oc_state_t *base);
void ocs_session_go(ocs_session_t *s);
/*! ocs_session_encode() : the part of ocs_session_prepare() that touches only this session and
 *  reads the world (safe on another thread while nothing else uses the session): OC_ENOENT when
 *  the viewer has nothing to send, another OC_E* for the caller to close the session with. */
int ocs_session_encode(ocs_session_t *s, const oc_state_t *base);

/*-*** net_admit.c ***/

/*! ocs_admit_viewer() : adds the HELLO's viewer to the world with a fair budget: at most the
 *  per-viewer maximum; lingering sessions give their budget back first, oldest first; then the
 *  largest budget that fits above the minimum. @return 0, or a negative OC_E* after the session
 *  was refused (FULL, naming what was short). */
int ocs_admit_viewer(ocs_session_t *s, const ocp_hello_t *h);

/*-*** net_epoch.c ***/

/*! ocs_server_queue_steps() : n more epochs to step as soon as possible. */
void ocs_server_queue_steps(ocs_server_t *srv, uint64_t n);
void ocs_epoch_start_timer(ocs_server_t *srv);
/*! ocs_epoch_flush() : a tick built ahead of its due instant sends its states now (on stopping). */
void ocs_epoch_flush(ocs_server_t *srv);
/*! ocs_epoch_close() : closes the epoch layer's handles that production signals (once no step or
 *  production runs). */
void ocs_epoch_close(ocs_server_t *srv);
/*! ocs_net_utc() : now on the server's clock: the wall clock (UTC, s since the Unix epoch) when
 *  epochs are clocked; the virtual instant of the last epoch when they are stepped. */
double ocs_net_utc(const ocs_server_t *srv);
void ocs_epoch_init(ocs_server_t *srv);

/*-*** net_handshake.c ***/

/*! ocs_handshake_hello() : the HELLO of a session in handshake (never while a step runs). */
void ocs_handshake_hello(ocs_session_t *s, const uint8_t *p, size_t n);
/*! ocs_token_equal() : whether `got` is the token `want`, in a time that depends on neither's
 *  bytes nor their lengths (up to OCP_TOKEN_MAX). */
int ocs_token_equal(const char *want, const uint8_t *got, size_t got_len);

/*-*** net_stats.c ***/

struct cJSON;

/* One session's figures. */
typedef struct {
  uint32_t id;
  int role, state;   /* OCP_ROLE_* (meaningless in handshake), ocs_session_state_t */
  char addr[64];
  uint64_t queued, memory, bytes_out, bytes_in;
  int has_viewer;    /* vs and ack_latency_ms are its viewer's */
  ocs_viewer_stats_t vs;
  double ack_latency_ms;
} ocs_stats_session_t;

/* The server's figures at one instant: what the stats and sessions replies and /metrics show, so
 * that they agree by construction. */
typedef struct {
  ocs_world_stats_t world;
  double utc, time;                /* now: the server's clock and the world time */
  uint64_t ticks, late_ticks;      /* steps done; due ticks skipped */
  uint64_t queue, bricks_made;     /* the production queue; bricks made between ticks */
  ocs_net_counts_t counts;
  int connections, admitted, lingering, by_state[OCS_SS_COUNT];
  uint64_t lingering_budget, total_budget, max_budget;
  ocs_hist_view_t tick_lateness;
  uint64_t rss;                    /* the process's resident memory, bytes (0: unknown) */
  ocs_share_stats_t share;         /* bricks shared through Redis (enabled 0: not) */
  ocs_stats_session_t *sessions;
  size_t nsessions;
} ocs_stats_t;

/*! ocs_stats_gather() : the figures now; only while the world is free (no step or production).
 *  @return 0 or OC_ENOMEM (nothing to free then). */
int ocs_stats_gather(ocs_server_t *srv, ocs_stats_t *st);
void ocs_stats_free(ocs_stats_t *st);
/*! ocs_stats_world_json() / ocs_stats_sessions_json() : the "world" object of the stats reply
 *  and the "sessions" array (cJSON objects for the caller). */
struct cJSON *ocs_stats_world_json(const ocs_server_t *srv, const ocs_stats_t *st);
struct cJSON *ocs_stats_sessions_json(const ocs_stats_t *st);

/*-*** net_audit.c ***/

/*! ocs_audit_open() : opens desc.audit_log for appending (nothing when none is given).
 *  @return 0, or OC_EIO with a reason naming the file. */
int ocs_audit_open(ocs_server_t *srv, char *why, size_t why_len);
/*! ocs_audit_write() : one line for a control change of session s: when, who, the op, the
 *  request's arguments and the outcome (error NULL: ok). */
void ocs_audit_write(ocs_session_t *s, const char *op, const struct cJSON *req, const char *error);
void ocs_audit_close(ocs_server_t *srv);

/*-*** net_control.c ***/

/*! ocs_control_handle() : one CONTROL request of a control session (never while a step runs).
 *  Appends the CONTROL_REPLY to out unless the reply waits (a "step" request: answered by
 *  ocs_control_steps_done()). */
void ocs_control_handle(ocs_session_t *s, const ocp_control_t *req, oc_buf_t *out);
/*! ocs_control_steps_done() : answers the "step" requests whose epochs are done. */
void ocs_control_steps_done(ocs_server_t *srv);
/*! ocs_server_reload() : re-reads the scene; on success every viewer gets GOODBYE RELOAD. */
int ocs_server_reload(ocs_server_t *srv, char *why, size_t why_len);

/*-*** net_input.c ***/

void ocs_input_start(ocs_session_t *s);
/*! ocs_input_drain() : handles buffered frames (the held one first) until one must wait for a
 *  step; then reading pauses. */
void ocs_input_drain(ocs_session_t *s);

/*-*** net_listener.c ***/

int ocs_listener_open(ocs_server_t *srv, char *why, size_t why_len);
/*! ocs_listener_admit() : the connection limits for a connection from `ip` (the server's, then that
 *  address's). @return 1 admitted; 0 refused (the session is closing). */
int ocs_listener_admit(ocs_session_t *s, const char *ip);
/*! ocs_net_sockaddr() : a numeric IPv4 or IPv6 host and a port. @return 0 or OC_EINVAL. */
int ocs_net_sockaddr(const char *host, int port, struct sockaddr_storage *sa);
/*! ocs_net_name() : "HOST:PORT" ("[V6]:PORT" for IPv6) with the port of a bound address. */
void ocs_net_name(char *out, size_t cap, const char *host, const struct sockaddr_storage *sa);

/*-*** net_metrics.c ***/

/*! ocs_metrics_open() : starts the /metrics endpoint when desc.metrics asks for it (on the loop:
 *  libmicrohttpd in external-poll mode). @return 0, or a negative OC_E* with a reason. */
int ocs_metrics_open(ocs_server_t *srv, char *why, size_t why_len);
/*! ocs_metrics_resume() : the world is free: scrapes that waited for it are answered now. */
void ocs_metrics_resume(ocs_server_t *srv);
/*! ocs_metrics_close() : stops the endpoint and closes its handles (idempotent). */
void ocs_metrics_close(ocs_server_t *srv);
/*! ocs_metrics_text() : the figures as Prometheus text (exposition format 0.0.4). */
void ocs_metrics_text(const ocs_stats_t *st, oc_buf_t *out);

/*-*** net_house.c ***/

void ocs_house_start(ocs_server_t *srv);

/*-*** net_server.c ***/

/*! ocs_server_drain() : stops admitting viewers, tells each one GOODBYE RECONNECT, and stops the
 *  server once they have left or desc.drain_s has passed (net_house.c). Idempotent. */
void ocs_server_drain(ocs_server_t *srv);

#endif /* OC_SERVER_NET_INTERNAL_H */
