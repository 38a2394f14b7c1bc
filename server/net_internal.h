/* net_internal.h — what net_server.c (loop, sessions, epochs) and net_control.c (control requests)
 * share. Not a public interface. */
#ifndef OC_SERVER_NET_INTERNAL_H
#define OC_SERVER_NET_INTERNAL_H

#include <uv.h>

#include "ocs_server.h"
#include "ocp_epoch.h"
#include "ocp_wire.h"

typedef enum {
  OCS_SS_HANDSHAKE = 0, /* waiting for HELLO */
  OCS_SS_READY = 1,     /* welcomed */
  OCS_SS_LINGER = 2,    /* connection lost, viewer kept for resume */
  OCS_SS_CLOSING = 3    /* saying goodbye; freed in the close callback */
} ocs_session_state_t;

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
  char addr[64];
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
  uint64_t stream_epoch, stream_checksum, last_out_epoch;
  ocs_view_t cam;
  ocp_stats_t stats_msg; /* the STATS sent after the epoch being streamed */
  double linger_until, stream_started;
  uint64_t epochs, acks;
  double ack_latency_sum, ack_latency_max;
  /* Control: a "step" request answered when its epochs are done. */
  int step_waiting;
  uint32_t step_request;
  uint64_t step_target;
};

struct ocs_server_s {
  uv_loop_t loop;
  uv_tcp_t listener;
  uv_timer_t epoch_timer, house_timer;
  uv_async_t stop_async;     /* ocs_server_stop_async(): a stop asked from another thread */
  uv_idle_t tick_idle;       /* a due tick: keeps the next poll from blocking ... */
  uv_check_t tick_check;     /* ... and starts the step after it, once pending ACKs are read */
  uv_signal_t sig_int, sig_term;
  uv_work_t work;
  int signals;
  ocs_server_desc_t desc;
  char host[64], address[96];
  char *token, *scene_path;
  oc_scene_t scene;
  ocs_world_t *world;
  double period;
  ocs_session_t *sessions; /* every session, lingering ones too */
  int nconnected;
  uint32_t next_id;
  int stepping, step_rc, stopping;
  uint64_t steps_queued, steps_done, late_ticks;
  double plan_ms, produce_ms; /* of the last step, for every viewer's STATS */
  double last_scale;
  /* viewers to remove once the running step ends */
  ocs_viewer_t **doomed;
  int ndoomed, doomed_cap;
  uint64_t accepted, refused, closed_errors, resumes;
  uint8_t readbuf[64 * 1024];
};

double ocs_net_now(void);
/*! ocs_session_send() : queues one buffer of whole frames (takes ownership of b's bytes). */
void ocs_session_send(ocs_session_t *s, oc_buf_t *b);
/*! ocs_session_close() : sends ERROR (code ≠ OK) or GOODBYE (code OK, SHUTDOWN, RELOAD, KICKED)
 *  with text, logs it, and closes; the viewer is removed (not kept for resume). */
void ocs_session_close(ocs_session_t *s, uint32_t code, const char *text);
/*! ocs_server_queue_steps() : n more epochs to step as soon as possible. */
void ocs_server_queue_steps(ocs_server_t *srv, uint64_t n);
/*! ocs_server_reload() : re-reads the scene; on success every viewer gets GOODBYE RELOAD. */
int ocs_server_reload(ocs_server_t *srv, char *why, size_t why_len);

/*! ocs_control_handle() : one CONTROL request of a control session (never while a step runs).
 *  Appends the CONTROL_REPLY to out unless the reply waits (a "step" request: answered by
 *  ocs_control_step_done()). */
void ocs_control_handle(ocs_session_t *s, const ocp_control_t *req, oc_buf_t *out);
void ocs_control_step_done(ocs_session_t *s);

#endif /* OC_SERVER_NET_INTERNAL_H */
