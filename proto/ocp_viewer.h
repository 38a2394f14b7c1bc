/* ocp_viewer.h — the viewer side of the protocol as a state machine without I/O ("sans-IO").
 *
 * The caller owns the socket: it sends what the session appends to its output buffer and feeds
 * what arrives. The session does the handshake (with resume after a reconnect), rebuilds each
 * epoch's state (ocp_epoch.h), verifies it, keeps the newest K−1 complete states (K from WELCOME:
 * 3 animated, 2 static; the K-th is the one arriving), acknowledges each one, and reports what
 * happened through callbacks. overcast-view's network thread, overcast-ctl and overcast-stress all
 * drive this same code, each with its own I/O.
 *
 * Resident bytes (the Conventions' budget measure) are counted here from what the session holds:
 * the K−1 complete states plus the records and bricks of the state being received.
 *
 * A lean session (desc.lean, sent as OCP_CAP_DIGEST) verifies every state exactly as a full one,
 * by the digest checksum (docs/protocol.md, "Digest checksum"), but keeps only the records and one
 * (id, 64-bit digest) pair per brick: 12 bytes a brick instead of 2052, so a process can run many
 * viewers with budgets far above its memory (overcast-stress). Its states, as given to the `state`
 * callback and by ocp_viewer_state(), have brick_count 0 and bricks NULL; ocp_viewer_digests()
 * gives their bricks. Its resident bytes are counted from the same ids, so they equal a full
 * session's on the same stream. */
#ifndef OC_PROTO_VIEWER_H
#define OC_PROTO_VIEWER_H

#include <stddef.h>
#include <stdint.h>

#include "oc_bytes.h" /* oc_buf_t */
#include "oc_state.h"
#include "ocp_wire.h"

typedef struct ocp_viewer_s ocp_viewer_t;

typedef struct {
  uint8_t role;           /**< OCP_ROLE_VIEWER or OCP_ROLE_CONTROL */
  /** what HELLO asks: budget bytes; slot bytes, 0 → OC_SLOT_BYTES; record bytes, 0 →
   *  OC_RECORD_BYTES (kept_states unused: the server decides) */
  OC_BUDGET_MEMBER(ask);
  uint8_t max_depth;      /**< 0..21 */
  uint32_t width, height; /**< viewport */
  uint32_t caps;          /**< OCP_CAP_*; OCP_CAP_ALL normally (OCP_CAP_DICT for a lean viewer) */
  const char *token;      /**< NULL: none */
  int lean;               /**< keep digests, not codes: adds OCP_CAP_DIGEST (either one selects
                               it); with OCP_CAP_DELTA in caps, ocp_viewer_create() is OC_EINVAL */
  uint16_t max_version;   /**< the highest protocol version offered: HELLO offers
                               [OCP_VERSION_MIN, max_version] and a WELCOME choosing another is
                               refused; 0 → OCP_VERSION_MAX; outside [OCP_VERSION_MIN,
                               OCP_VERSION_MAX], ocp_viewer_create() is OC_EINVAL (a test can be a
                               version-N viewer) */
} ocp_viewer_desc_t;

typedef struct {
  void *ctx;
  /*! The handshake completed (resumed: the held states were kept). */
  void (*welcome)(void *ctx, const ocp_welcome_t *w, int resumed);
  /*! A new complete, verified state (now ocp_viewer_state(v, 0)); it has been acknowledged. In a
   *  lean session it has no bricks (ocp_viewer_digests(v, 0) has them). */
  void (*state)(void *ctx, const oc_state_t *s, uint32_t bricks_received);
  void (*stats)(void *ctx, const ocp_stats_t *s);
  void (*control_reply)(void *ctx, const ocp_control_t *c);
  /*! The server said goodbye or sent an error (the connection should be closed; code OCP_CODE_*). */
  void (*closed)(void *ctx, uint32_t code, const char *text);
  /*! The budget in force changed (BUDGET, version 3): a raise at once, a lowering once every state
   *  planned under the old budget has left the window; `grant` is the WELCOME's grant with the
   *  budget now in force: a GPU store may be resized to it. */
  void (*budget)(void *ctx, const oc_budget_t *grant);
} ocp_viewer_events_t;

typedef struct {
  uint64_t states, bytes_in, frames_in, bricks_in;
  uint64_t resident_bytes, resident_peak; /**< counted by the session itself */
  uint64_t over_budget;                   /**< states after which resident > granted budget (never); with
                                               a BUDGET pending, the larger of the budgets its window's
                                               states were planned under */
  uint64_t budgets;                       /**< BUDGET messages taken */
  uint64_t reconnects, resumed;
  uint64_t held_bytes; /**< bytes of the arrays of the kept states in this process (records, and
                            bricks or digests): not the budget measure, what the session costs */
} ocp_viewer_stats_t;

/*! ocp_viewer_create() : @return 0, OC_EINVAL (bad desc) or OC_ENOMEM. */
int ocp_viewer_create(ocp_viewer_t **out, const ocp_viewer_desc_t *desc, const ocp_viewer_events_t *ev);
void ocp_viewer_free(ocp_viewer_t *v);
/*! ocp_viewer_connected() : a (new) connection is up: resets the frame reader and any half-received
 *  epoch, and appends HELLO (with resume fields when a previous session is known) to out. */
void ocp_viewer_connected(ocp_viewer_t *v, oc_buf_t *out);
/*! ocp_viewer_feed() : bytes from the server. Replies (ACK) are appended to out. @return 0, or a
 *  negative OC_E* with a reason after which the caller closes the connection (an ERROR frame
 *  naming the problem has been appended to out for it to send first). */
int ocp_viewer_feed(ocp_viewer_t *v, const void *p, size_t n, oc_buf_t *out, char *why, size_t why_len);
/*! ocp_viewer_camera() / ocp_viewer_control() / ocp_viewer_keepalive() / ocp_viewer_goodbye() :
 *  append the message (camera and control only after WELCOME; earlier ones are kept and sent
 *  with it for the camera, refused with OC_EINVAL for control). */
int ocp_viewer_camera(ocp_viewer_t *v, const ocp_camera_t *c, oc_buf_t *out);
int ocp_viewer_control(ocp_viewer_t *v, uint32_t request, const char *json, oc_buf_t *out);
void ocp_viewer_keepalive(ocp_viewer_t *v, oc_buf_t *out);
void ocp_viewer_goodbye(ocp_viewer_t *v, oc_buf_t *out);

/*! ocp_viewer_ready() : 1 after WELCOME on the current connection. */
int ocp_viewer_ready(const ocp_viewer_t *v);
/*! ocp_viewer_welcome() : the last WELCOME, or NULL before the first. */
const ocp_welcome_t *ocp_viewer_welcome(const ocp_viewer_t *v);
/*! ocp_viewer_state() : the i-th newest complete state (0: newest), or NULL. A lean session's
 *  states hold their records only (brick_count 0, bricks NULL). */
const oc_state_t *ocp_viewer_state(const ocp_viewer_t *v, int i);
/*! ocp_viewer_digests() : a lean session's bricks of state i, ascending (id, digest) pairs, or NULL
 *  (no such state, or a full session). oc_state_digest_checksum(state, digests) is what it ACKed. */
const oc_brick_digests_t *ocp_viewer_digests(const ocp_viewer_t *v, int i);
void ocp_viewer_stats(const ocp_viewer_t *v, ocp_viewer_stats_t *out);

#endif /* OC_PROTO_VIEWER_H */
