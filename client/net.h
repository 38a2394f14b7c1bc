/* net.h — the client side of the wire protocol (docs/protocol.md, "Wire") over TCP.
 *
 * Two layers over the sans-IO session of proto/ocp_viewer.h:
 *
 * - ocv_conn_t: one TCP connection (POSIX sockets, poll(), TCP_NODELAY) driving an ocp_viewer_t.
 *   Calls block at most for the timeout they are given. Output is written while input is read, so
 *   neither side can fill the other's buffers and stall (the server stops producing an epoch while
 *   its own send queue is full; we must never stop reading because our writes are stuck). The
 *   session survives the socket: ocv_conn_reconnect() opens a new one and the session resumes.
 *   overcast-ctl and overcast-view's batch mode use it directly.
 *
 * - ocv_net_t: a network thread for an interactive viewer: it keeps one viewer connection up
 *   (reconnecting with backoff and resume), sends the newest camera, keeps the connection alive,
 *   and publishes the newest complete state for the render loop to take.
 *
 * Errors are negative OC_E* codes with a one-line reason that names the server ("HOST:PORT: ...").
 * Network failures (refused, reset, timed out) are OC_EIO. */
#ifndef OC_CLIENT_NET_H
#define OC_CLIENT_NET_H

#include <stddef.h>
#include <stdint.h>

#include "oc_backoff.h"
#include "oc_camera.h" /* oc_camera_pose_t */
#include "oc_state.h"
#include "ocp_viewer.h"
#include "ocp_wire.h"

#define OCV_DEFAULT_HOST "127.0.0.1"
#define OCV_DEFAULT_PORT 7420
#define OCV_HOST_MAX 256 /**< bytes of a host name or address, NUL included */
/*! Blocking waits send KEEPALIVE after this long without sending (the server's idle timeout is 60 s
 *  by default, and a "step" reply can take longer than that). */
#define OCV_KEEPALIVE_S 10.0

/*! ocv_parse_address() : "HOST:PORT", "[V6]:PORT", ":PORT" or "PORT" (the last two: host
 *  127.0.0.1). The port must be 1..65535. @return 0 or OC_EINVAL. */
int ocv_parse_address(const char *text, char *host, size_t cap, int *port);

/*-*** One connection ***/

typedef struct ocv_conn_s ocv_conn_t;

/*! ocv_conn_create() : a session for host:port, not connected yet (ocv_conn_reconnect() connects).
 *  `ev` (may be NULL) gets the session's events; the token in `vd` is copied.
 *  @return 0, OC_EINVAL (bad desc or address) or OC_ENOMEM, with a reason in why. */
int ocv_conn_create(ocv_conn_t **out, const char *host, int port, const ocp_viewer_desc_t *vd,
                    const ocp_viewer_events_t *ev, char *why, size_t why_len);
/*! ocv_conn_open() : ocv_conn_create() and connect: resolves host (getaddrinfo), connects within
 *  timeout_s and sends HELLO (it does not wait for WELCOME; ocv_conn_poll() brings it).
 *  On failure *out is NULL. */
int ocv_conn_open(ocv_conn_t **out, const char *host, int port, const ocp_viewer_desc_t *vd,
                  const ocp_viewer_events_t *ev, double timeout_s, char *why, size_t why_len);
/*! ocv_conn_set_source() : later connects (ocv_conn_reconnect()) bind the socket to this local IP
 *  address ("127.0.0.2", "::1"; port 0) before connecting, so a client can choose the address it
 *  comes from (Linux routes all of 127.0.0.0/8 to the loopback). NULL or "": the system's choice
 *  (the default). A failed bind fails the connect with a reason naming the source address.
 *  @return 0, or OC_EINVAL when addr is not a numeric IPv4 or IPv6 address (nothing changed). */
int ocv_conn_set_source(ocv_conn_t *c, const char *addr);
/*! ocv_conn_reconnect() : closes the socket if any (without GOODBYE: the server keeps the session
 *  for resume), discards unsent output, connects anew and sends HELLO (resume fields when the
 *  session had a WELCOME). @return 0 or a negative OC_E* (the connection stays closed). */
int ocv_conn_reconnect(ocv_conn_t *c, double timeout_s, char *why, size_t why_len);
/*! ocv_conn_poll() : writes pending output and waits up to timeout_s (0: not at all) for input;
 *  feeds all input that is there to the session (events fire from inside this call) and writes
 *  what the session answers. It returns after the first input, or at the timeout, or as soon as
 *  a wake fd (ocv_conn_set_wake()) is readable.
 *  @return 0 while the connection is open; 1 when the server closed it (EOF, or GOODBYE/ERROR: why
 *  holds the server's reason); a negative OC_E* on a network or protocol error (the socket is then
 *  closed; for a protocol error the ERROR frame naming it was sent first). When not connected it
 *  returns 1 at once. */
int ocv_conn_poll(ocv_conn_t *c, double timeout_s, char *why, size_t why_len);
/*! ocv_conn_set_wake() : fds (e.g. self-pipes' read ends; -1: none) that end ocv_conn_poll()'s wait
 *  when readable; `cancel` also aborts a connect in progress (OC_EIO). Neither is read here. */
void ocv_conn_set_wake(ocv_conn_t *c, int wake, int cancel);

/*! ocv_conn_camera() / ocv_conn_control() / ocv_conn_keepalive() : queue the message and write
 *  what fits without blocking (the rest goes with the next poll). A camera given before WELCOME is
 *  kept and sent with it, and again after every reconnect. Control needs role control and WELCOME.
 *  @return 0, OC_EINVAL (refused by the session: see ocp_viewer.h) or OC_EIO (write failed; the
 *  next poll reports it). */
int ocv_conn_camera(ocv_conn_t *c, const ocp_camera_t *cam);
int ocv_conn_control(ocv_conn_t *c, uint32_t request, const char *json);
int ocv_conn_keepalive(ocv_conn_t *c);
/*! ocv_conn_flush() : writes pending output for at most timeout_s while still reading (input is fed
 *  to the session). @return as ocv_conn_poll(); 0 means everything was written. */
int ocv_conn_flush(ocv_conn_t *c, double timeout_s, char *why, size_t why_len);

/*! ocv_conn_wait_ready() : polls until WELCOME arrived on this connection.
 *  @return 0, 1 (closed by the server first), OC_EIO (timed out) or another negative OC_E*. */
int ocv_conn_wait_ready(ocv_conn_t *c, double timeout_s, char *why, size_t why_len);
/*! ocv_control_request() : for role control: waits for WELCOME if needed, sends {json} as a CONTROL
 *  request and waits for its CONTROL_REPLY, keeping the connection alive meanwhile. On 0, *reply_json is the reply's JSON (malloc'd,
 *  NUL-terminated; free() it) and *status its wire status (OCP_CODE_OK or, say, OCP_CODE_REQUEST).
 *  @return 0 or a negative OC_E* (OC_EIO: timed out or closed before the reply) with a reason. */
int ocv_control_request(ocv_conn_t *c, const char *json, double timeout_s, char **reply_json, int32_t *status, char *why,
                        size_t why_len);

/*! ocv_conn_set_tap() : `tap` (NULL: none) sees every chunk of bytes read from the server, in
 *  order, before the session is fed it (overcast-stress times each EPOCH_BEGIN by it). It is
 *  called from inside ocv_conn_poll() and the calls that read, and must not call back into c. */
typedef void (*ocv_tap_fn)(void *ctx, const uint8_t *p, size_t n);
void ocv_conn_set_tap(ocv_conn_t *c, ocv_tap_fn tap, void *ctx);

ocp_viewer_t *ocv_conn_session(ocv_conn_t *c);
/*! ocv_conn_fd() : the socket, or -1 while not connected. */
int ocv_conn_fd(const ocv_conn_t *c);
/*! ocv_conn_address() : "HOST:PORT" (IPv6 hosts in brackets), as used in messages. */
const char *ocv_conn_address(const ocv_conn_t *c);
/*! ocv_conn_pending() : bytes queued but not yet written. */
size_t ocv_conn_pending(const ocv_conn_t *c);
/*! ocv_conn_silence() : seconds since bytes were last written on this connection. */
double ocv_conn_silence(const ocv_conn_t *c);
/*! ocv_conn_close_code() : the code of the GOODBYE or ERROR that closed the last connection, with
 *  its text in *text (may be NULL); -1 when the server sent none (EOF, reset, never connected). */
int64_t ocv_conn_close_code(const ocv_conn_t *c, const char **text);
/*! ocv_conn_close() : GOODBYE (best effort, bounded to about a second), close, free. NULL is fine. */
void ocv_conn_close(ocv_conn_t *c);

/*-*** Reconnects ***/

/*! Bounds on one run of reconnect attempts (defaults of ocv_retry_init() for 0). */
#define OCV_RETRY_ATTEMPTS 10
#define OCV_RETRY_S 120.0

/*! ocv_retry_t : the reconnect policy of overcast-view and overcast-stress. After a lost connection
 *  or a GOODBYE RECONNECT, each attempt waits oc_backoff_next() (exponential backoff with full
 *  jitter, starting at the delay the server asked for); after max_attempts attempts, or once the
 *  next wait would end more than max_s after the first failure, it gives up. A WELCOME
 *  (ocv_retry_done()) ends the run: the next failure starts again at the server's delay. */
typedef struct {
  oc_backoff_t bo;
  uint32_t max_attempts, attempts; /* attempts of the current run */
  double max_s, since;             /* since: the first failure of the run */
  int running;                     /* a run of attempts is under way */
  uint64_t seed;
} ocv_retry_t;

void ocv_retry_init(ocv_retry_t *r, uint32_t max_attempts, double max_s, uint64_t seed);
/*! ocv_retry_next() : after a failure at `now` (seconds, any monotonic clock) whose reason is
 *  `cause` and for which the server asked `server_ms` (0: nothing asked): the wait in seconds before
 *  the next attempt, with the one line to print in `line` ("CAUSE; reconnect attempt K of N in
 *  S s"); or -1 when it gives up, `line` then saying so ("CAUSE; gave up after K reconnect attempts
 *  in S s"). A server's delay asked mid-run is never cut short. */
double ocv_retry_next(ocv_retry_t *r, uint32_t server_ms, double now, const char *cause, char *line, size_t cap);
/*! ocv_retry_done() : welcomed again; the next failure starts a new run. */
void ocv_retry_done(ocv_retry_t *r);
/*! ocv_retry_fatal() : close codes after which reconnecting cannot help (VERSION, TOKEN, KICKED). */
int ocv_retry_fatal(int64_t code);

/*-*** The network thread ***/

typedef struct ocv_net_s ocv_net_t;

typedef struct {
  const char *host;          /**< NULL → 127.0.0.1 */
  int port;                  /**< 0 → 7420 */
  ocp_viewer_desc_t viewer;  /**< role must be OCP_ROLE_VIEWER; the token is copied */
  double connect_timeout_s;  /**< 0 → 5 */
  uint32_t retry_attempts;   /**< reconnect attempts before giving up; 0 → OCV_RETRY_ATTEMPTS */
  double retry_s;            /**< and the time they may take; 0 → OCV_RETRY_S (ocv_retry_t) */
  uint64_t seed;             /**< the backoff's jitter; 0 → from the clock and the pid */
  /*! One line per reconnect attempt, and the last one on giving up (NULL: none); network thread. */
  void (*on_log)(void *ctx, const char *line);
  double keepalive_s;        /**< KEEPALIVE after this long without sending; 0 → 10 */
  /*! Called on the network thread after a new state was published (e.g. to wake a GL event loop
   *  with glfwPostEmptyEvent()); may be NULL. It must not call back into ocv_net. */
  void (*on_state)(void *ctx);
  void *ctx;
} ocv_net_desc_t;

typedef struct {
  int connected;                /**< WELCOME received on the current connection */
  int have_welcome;
  ocp_welcome_t welcome;        /**< the last WELCOME (valid when have_welcome); its grant is the
                                     one in force, BUDGET messages included */
  uint64_t budgets;             /**< budget changes taken into force (BUDGET, version 3) */
  int have_stats;
  ocp_stats_t server_stats;     /**< the server's STATS of the last epoch */
  ocp_viewer_stats_t viewer;    /**< the session's counters */
  uint64_t states;              /**< complete states received */
  uint64_t epoch;               /**< epoch of the newest (valid when states > 0) */
  uint64_t connects;            /**< successful TCP connects */
  uint64_t welcomes;            /**< WELCOMEs (the first and every reconnect's) */
  int resumed;                  /**< the last WELCOME resumed the session (states kept) */
  uint32_t attempt;             /**< reconnect attempts of the current run (0: connected or none) */
  int gave_up;                  /**< the reconnects ran out (error says why); the thread is idle */
  char error[512];              /**< the last error or close reason ("" if none) */
} ocv_net_status_t;

/*! ocv_net_start() : starts the thread, which connects at once. @return 0, OC_EINVAL or OC_ENOMEM
 *  (or a pthread failure as OC_EIO). */
int ocv_net_start(ocv_net_t **out, const ocv_net_desc_t *d);
/*! ocv_net_set_camera() : thread-safe; the newest camera is sent as soon as possible and again after
 *  each reconnect. @return 0 or OC_EINVAL (an invalid camera: see ocp_viewer_camera()). */
int ocv_net_set_camera(ocv_net_t *n, const ocp_camera_t *cam);
/*! ocv_net_take_state() : when a state newer than the last one taken has arrived, moves it into dst
 *  (an initialised state whose arrays may be reused) and returns 1 with its epoch; 0: nothing new. */
int ocv_net_take_state(ocv_net_t *n, oc_state_t *dst, uint64_t *epoch);
void ocv_net_status(ocv_net_t *n, ocv_net_status_t *out);
/*! ocv_net_stop() : GOODBYE, joins the thread, frees. NULL is fine. */
void ocv_net_stop(ocv_net_t *n);

/* ---- One state, the simple way (fetch.c) ---------------------------------------------------------- */

typedef struct {
  const char *host;
  int port;
  const char *token;              /**< NULL: none */
  uint64_t budget;                /**< bytes asked for */
  int max_depth;                  /**< 0..21 */
  int width, height;              /**< the viewport the camera is planned for */
  const oc_camera_pose_t *pose;   /**< the camera; NULL: the WELCOME's default camera */
  int step;                       /**< the server steps by command: ask for each epoch on a control
                                       connection of our own (token as above) */
  uint64_t epochs;                /**< complete states to wait for (≥ 1) */
  double timeout_s;               /**< for everything */
} ocv_fetch_desc_t;

/*! ocv_fetch() : connects as a viewer, sends the camera, (step) steps the server one epoch at a time,
 *  waits for `epochs` complete, verified states, and copies the newest into st (initialised), the
 *  WELCOME into *welcome and the camera used into *pose_out (either may be NULL). Closes with
 *  GOODBYE. @return 0, or a negative OC_E* with a one-line reason naming the server (OC_EIO:
 *  refused, closed, timed out). */
int ocv_fetch(const ocv_fetch_desc_t *d, oc_state_t *st, ocp_welcome_t *welcome, oc_camera_pose_t *pose_out, char *why,
              size_t why_len);

#endif /* OC_CLIENT_NET_H */
