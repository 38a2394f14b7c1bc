/* net_server.c — the libuv loop: listener, sessions, epochs, backpressure, timeouts, resume
 * (ocs_server.h; wire format in docs/protocol.md). Control requests are in net_control.c. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <linux/sockios.h> /* SIOCOUTQ */
#include <sys/ioctl.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"

/* An epoch's frames are produced only while fewer bytes than this are unsent, in bursts of about
 * OCS_BURST bytes: a session holds at most LOW_WATER + BURST + one frame. */
#define OCS_LOW_WATER (256u << 10)
#define OCS_BURST (256u << 10)
#define OCS_CLOSE_GRACE_S 2.0
#define OCS_HOUSE_MS 100

double ocs_net_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint64_t random_u64(void) {
  uint64_t v = 0;
  if (uv_random(NULL, NULL, &v, sizeof v, 0, NULL) < 0) v = (uint64_t)(ocs_net_now() * 1e9) ^ 0x9E3779B97F4A7C15ull;
  return v ? v : 1;
}

static const char *role_name(int role) { return role == OCP_ROLE_CONTROL ? "control" : "viewer"; }

/*-*** Sessions: lifetime ***/

static void session_unlink(ocs_server_t *srv, ocs_session_t *s) {
  if (s->prev) s->prev->next = s->next;
  else srv->sessions = s->next;
  if (s->next) s->next->prev = s->prev;
  s->prev = s->next = NULL;
}

static void session_free(ocs_session_t *s) {
  ocp_reader_free(&s->rd);
  ocp_epoch_enc_free(s->enc);
  free(s->deferred);
  free(s);
}

/* Removes the viewer from the world now, or after the running step. */
static void drop_viewer(ocs_server_t *srv, ocs_session_t *s) {
  if (!s->viewer) return;
  if (srv->stepping) {
    if (srv->ndoomed == srv->doomed_cap) {
      int nc = srv->doomed_cap ? 2 * srv->doomed_cap : 8;
      ocs_viewer_t **a = realloc(srv->doomed, (size_t)nc * sizeof *a);
      if (!a) abort(); /* cannot defer: a stepping world must not be touched */
      srv->doomed = a;
      srv->doomed_cap = nc;
    }
    srv->doomed[srv->ndoomed++] = s->viewer;
  } else {
    ocs_world_remove_viewer(srv->world, s->viewer);
  }
  s->viewer = NULL;
  s->streaming = s->awaiting_ack = s->ack_pending = 0;
}

static void on_closed(uv_handle_t *h) {
  ocs_session_t *s = h->data;
  ocs_server_t *srv = s->srv;
  srv->nconnected--;
  s->connected = 0;
  if (s->state == OCS_SS_LINGER) return; /* kept for resume; freed by the housekeeper */
  session_unlink(srv, s);
  session_free(s);
}

static void close_handle(ocs_session_t *s) {
  if (!uv_is_closing((uv_handle_t *)&s->tcp)) uv_close((uv_handle_t *)&s->tcp, on_closed);
}

static void on_shutdown(uv_shutdown_t *req, int status) {
  (void)status;
  close_handle(req->data);
}

void ocs_session_close(ocs_session_t *s, uint32_t code, const char *text) {
  ocs_server_t *srv = s->srv;
  if (s->state == OCS_SS_CLOSING) return;
  int is_error = code != OCP_CODE_OK && code != OCP_CODE_SHUTDOWN && code != OCP_CODE_RELOAD && code != OCP_CODE_KICKED;
  if (is_error) srv->closed_errors++;
  oc_log(is_error ? OC_LOG_WARN : OC_LOG_INFO, "session %" PRIu32 " (%s %s): closing: %s%s%s", s->id, role_name(s->role),
         s->addr, ocp_code_text(code), text && *text ? ": " : "", text ? text : "");
  drop_viewer(srv, s);
  int was_linger = s->state == OCS_SS_LINGER;
  s->state = OCS_SS_CLOSING;
  s->closing_since = ocs_net_now();
  if (was_linger && !s->connected) { /* nothing open: free now */
    session_unlink(srv, s);
    session_free(s);
    return;
  }
  uv_read_stop((uv_stream_t *)&s->tcp);
  if (code == OCP_CODE_SLOW || (code == OCP_CODE_TIMEOUT && s->queued)) { /* not draining: queue nothing more */
    close_handle(s);
    return;
  }
  oc_buf_t b = {0};
  ocp_put_text(&b, s->version ? s->version : OCP_VERSION_MAX, is_error ? OCP_MSG_ERROR : OCP_MSG_GOODBYE, code, text);
  ocs_session_send(s, &b);
  s->shut.data = s;
  if (uv_shutdown(&s->shut, (uv_stream_t *)&s->tcp, on_shutdown) < 0) close_handle(s);
}

/* The peer went away: keep a welcomed viewer for resume, drop everything else. */
static void session_lost(ocs_session_t *s, const char *cause) {
  ocs_server_t *srv = s->srv;
  if (s->state == OCS_SS_CLOSING) return;
  if (s->role == OCP_ROLE_VIEWER && s->state == OCS_SS_READY && s->viewer && srv->desc.linger_s > 0 && !srv->stopping) {
    oc_log_info("session %" PRIu32 " (viewer %s): connection lost (%s); kept %.0f s for resume", s->id, s->addr, cause,
                srv->desc.linger_s);
    s->state = OCS_SS_LINGER;
    s->linger_until = ocs_net_now() + srv->desc.linger_s;
    s->streaming = s->awaiting_ack = 0; /* the epoch in flight is lost with the connection */
    uv_read_stop((uv_stream_t *)&s->tcp);
    close_handle(s);
    return;
  }
  oc_log_info("session %" PRIu32 " (%s %s): connection lost (%s)", s->id, role_name(s->role), s->addr, cause);
  drop_viewer(srv, s);
  s->state = OCS_SS_CLOSING;
  s->closing_since = ocs_net_now();
  close_handle(s);
}

/*-*** Sessions: output ***/

typedef struct {
  uv_write_t req;
  ocs_session_t *s;
  oc_buf_t buf;
} ocs_send_t;

static void pump(ocs_session_t *s);

static void on_written(uv_write_t *req, int status) {
  ocs_send_t *w = (ocs_send_t *)req;
  ocs_session_t *s = w->s;
  s->queued -= w->buf.len;
  s->bytes_out += status == 0 ? w->buf.len : 0;
  s->last_progress = ocs_net_now();
  oc_buf_free(&w->buf);
  free(w);
  if (status < 0) {
    if (status != UV_ECANCELED) session_lost(s, uv_strerror(status));
    return;
  }
  if (s->state == OCS_SS_READY) pump(s);
}

void ocs_session_send(ocs_session_t *s, oc_buf_t *b) {
  if (b->err) {
    oc_buf_free(b);
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  if (!s->connected || uv_is_closing((uv_handle_t *)&s->tcp) || !b->len) {
    oc_buf_free(b);
    return;
  }
  ocs_send_t *w = malloc(sizeof *w);
  if (!w) {
    oc_buf_free(b);
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  w->s = s;
  w->buf = *b;
  memset(b, 0, sizeof *b);
  if (!s->queued) s->last_progress = ocs_net_now();
  uv_buf_t ub = uv_buf_init((char *)w->buf.data, (unsigned)w->buf.len);
  int r = uv_write(&w->req, (uv_stream_t *)&s->tcp, &ub, 1, on_written);
  if (r < 0) {
    oc_buf_free(&w->buf);
    free(w);
    session_lost(s, uv_strerror(r));
    return;
  }
  s->queued += ub.len;
  if (s->queued > s->srv->desc.queue_hard && s->state != OCS_SS_CLOSING) {
    char t[96];
    snprintf(t, sizeof t, "%" PRIu64 " bytes unsent (hard limit %" PRIu64 ")", s->queued, s->srv->desc.queue_hard);
    ocs_session_close(s, OCP_CODE_SLOW, t);
  }
}

/* Produces the current epoch's next frames while the socket keeps up. */
static void pump(ocs_session_t *s) {
  while (s->streaming && s->queued < OCS_LOW_WATER && s->state == OCS_SS_READY) {
    oc_buf_t b = {0};
    int r;
    do r = ocp_epoch_enc_next(s->enc, s->version, &b);
    while (r == 1 && b.len < OCS_BURST);
    if (r < 0) {
      oc_buf_free(&b);
      ocs_session_close(s, OCP_CODE_INTERNAL, oc_strerror(r));
      return;
    }
    if (r == 0) {
      s->streaming = 0;
      s->awaiting_ack = 1;
      ocp_enc_stats_t es;
      ocp_epoch_enc_stats(s->enc, &es);
      s->stats_msg.wire_bytes = es.wire_bytes;
      s->stats_msg.raw_bytes = es.raw_bytes;
      ocp_put_stats(&b, s->version, &s->stats_msg);
    }
    ocs_session_send(s, &b);
  }
}

/* Starts streaming the viewer's newest state, as a difference from `base` (what it holds). */
static void stream_state(ocs_session_t *s, const oc_state_t *base) {
  ocs_epoch_out_t o;
  if (ocs_viewer_output(s->viewer, &o) < 0) return;
  int r = ocp_epoch_enc_begin(s->enc, o.state, base, o.lacking, o.nlacking);
  if (r < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, oc_strerror(r));
    return;
  }
  /* The epoch's STATS are taken now: a step may run while the frames go out, and the world is
   * not read during a step. */
  ocs_viewer_stats_t vs;
  ocs_viewer_stats(s->viewer, &vs);
  s->stats_msg = (ocp_stats_t){.epoch = o.state->epoch, .leaves = o.plan.leaves, .splits = o.plan.splits,
                               .merges = o.plan.merges, .deferred = o.plan.deferred, .coalesced = vs.coalesced,
                               .resident_bytes = vs.resident_bytes, .plan_ms = s->srv->plan_ms,
                               .produce_ms = s->srv->produce_ms};
  s->streaming = 1;
  s->awaiting_ack = 0;
  s->stream_epoch = o.state->epoch;
  s->stream_checksum = ocp_epoch_enc_checksum(s->enc); /* what EPOCH_END carries, in the session's form */
  s->last_out_epoch = o.state->epoch;
  s->stream_started = ocs_net_now();
  s->epochs++;
  pump(s);
}

/*-*** Sessions: input ***/

static void send_welcome(ocs_session_t *s, int resumed) {
  ocs_server_t *srv = s->srv;
  const oc_scene_t *sc = ocs_world_scene(srv->world);
  ocs_world_stats_t ws;
  ocs_world_stats(srv->world, &ws);
  ocp_welcome_t m;
  memset(&m, 0, sizeof m);
  m.version = s->version;
  m.flags = resumed ? OCP_WELCOME_RESUMED : 0;
  m.session = s->id;
  m.secret = s->secret;
  if (s->role == OCP_ROLE_VIEWER) {
    m.kept_states = (uint8_t)ocs_world_kept_states(srv->world);
    m.budget = s->granted.budget;
    m.slot_bytes = s->granted.slot_bytes;
    m.record_bytes = s->granted.record_bytes;
    m.max_depth = (uint8_t)s->granted.max_depth;
  }
  m.features = sc->features;
  m.epoch_period = srv->period;
  m.planet_radius = OC_PLANET_RADIUS;
  m.time = ws.time;
  m.sun_dir = ocs_world_sun(srv->world);
  m.albedo = sc->optics.albedo;
  m.ms_a = sc->optics.ms_a;
  m.ms_b = sc->optics.ms_b;
  m.ms_c = sc->optics.ms_c;
  m.ms_octaves = (uint32_t)sc->optics.ms_octaves;
  m.cam_lat = sc->camera.pos.lat;
  m.cam_lon = sc->camera.pos.lon;
  m.cam_alt = sc->camera.pos.alt;
  m.cam_heading = sc->camera.heading;
  m.cam_pitch = sc->camera.pitch;
  m.cam_fov = sc->camera.fov;
  snprintf(m.name, sizeof m.name, "%s", sc->name);
  oc_buf_t b = {0};
  ocp_put_welcome(&b, s->version, &m);
  ocs_session_send(s, &b);
}

static ocs_session_t *find_session(ocs_server_t *srv, uint32_t id) {
  for (ocs_session_t *t = srv->sessions; t; t = t->next)
    if (t->id == id) return t;
  return NULL;
}

/* Resume: takes over the viewer of session `old` if the viewer holds one of its states.
 * @return 1 resumed (and streaming started if needed), 0 not resumable. */
static int try_resume(ocs_session_t *s, ocs_session_t *old, const ocp_hello_t *h) {
  ocs_server_t *srv = s->srv;
  if (!old || old == s || old->role != OCP_ROLE_VIEWER || !old->viewer || old->secret != h->resume_secret) return 0;
  if (old->state != OCS_SS_LINGER && old->state != OCS_SS_READY) return 0;
  const oc_state_t *h0 = ocs_viewer_held(old->viewer, 0), *h1 = ocs_viewer_held(old->viewer, 1);
  int in_flight = ocs_viewer_in_flight(old->viewer);
  /* the viewer names its state by the checksum it verified: the digest form for a lean viewer */
  uint64_t (*sum)(const oc_state_t *) = (h->caps & OCP_CAP_DIGEST) ? oc_state_digest : oc_state_checksum;
  int have0 = h0 && h0->epoch == h->held_epoch && sum(h0) == h->held_checksum;
  int have1 = !have0 && in_flight && h1 && h1->epoch == h->held_epoch && sum(h1) == h->held_checksum;
  if (!have0 && !have1) return 0;
  /* Take over: the old connection (if still open) is closed without dropping the viewer. */
  s->viewer = old->viewer;
  old->viewer = NULL;
  s->granted = old->granted;
  s->cam = old->cam;
  s->cam_new = old->cam_new;
  s->id = old->id;
  s->secret = old->secret;
  s->epochs = old->epochs;
  if (old->state == OCS_SS_LINGER && !old->connected) {
    session_unlink(srv, old);
    session_free(old);
  } else {
    old->state = OCS_SS_READY;
    ocs_session_close(old, OCP_CODE_OK, "resumed on another connection");
  }
  srv->resumes++;
  s->state = OCS_SS_READY;
  send_welcome(s, 1);
  oc_log_info("session %" PRIu32 " (viewer %s): resumed at epoch %" PRIu64, s->id, s->addr, h->held_epoch);
  if (have0 && in_flight) ocs_viewer_ack(s->viewer, h0->epoch); /* it arrived; the ACK was lost */
  if (have1) stream_state(s, h1);                                /* re-send the lost epoch */
  return 1;
}

static void handle_hello(ocs_session_t *s, const uint8_t *p, size_t n) {
  ocs_server_t *srv = s->srv;
  char why[256];
  ocp_hello_t h;
  if (ocp_get_hello(p, n, &h, why, sizeof why) < 0) {
    ocs_session_close(s, OCP_CODE_MALFORMED, why);
    return;
  }
  uint16_t v = ocp_version_pick(h.min_version, h.max_version);
  if (!v) {
    snprintf(why, sizeof why, "the viewer speaks versions %u..%u, this server %u..%u", h.min_version, h.max_version,
             OCP_VERSION_MIN, OCP_VERSION_MAX);
    ocs_session_close(s, OCP_CODE_VERSION, why);
    return;
  }
  s->version = (uint8_t)v;
  if (srv->token) {
    size_t tl = strlen(srv->token);
    if (h.token_len != tl || memcmp(h.token, srv->token, tl) != 0) {
      ocs_session_close(s, OCP_CODE_TOKEN, h.token_len ? "the token does not match" : "this server requires a token");
      return;
    }
  }
  s->role = h.role;
  s->caps = h.caps;
  if (h.role == OCP_ROLE_CONTROL) {
    s->state = OCS_SS_READY;
    send_welcome(s, 0);
    oc_log_info("session %" PRIu32 " (control %s): welcomed", s->id, s->addr);
    return;
  }
  ocp_epoch_enc_free(s->enc);
  s->enc = NULL;
  /* HELLO never has DIGEST with DELTA (ocp_get_hello), so a lean viewer never gets a delta */
  ocp_enc_desc_t ed = {.level = srv->desc.zstd_level,
                       .deltas = srv->desc.deltas >= 0 && (h.caps & OCP_CAP_DELTA),
                       .digest = (h.caps & OCP_CAP_DIGEST) != 0};
  int r = ocp_epoch_enc_create(&s->enc, &ed);
  if (r < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, oc_strerror(r));
    return;
  }
  if (h.resume_session) {
    if (try_resume(s, find_session(srv, h.resume_session), &h)) return;
    /* not resumable: the old session (if any and if it is this viewer's) is dropped */
    ocs_session_t *old = find_session(srv, h.resume_session);
    if (old && old != s && old->secret == h.resume_secret && old->state == OCS_SS_LINGER)
      ocs_session_close(old, OCP_CODE_OK, "superseded by a new session");
  }
  ocs_plan_desc_t req = {.budget = h.budget, .slot_bytes = h.slot_bytes, .record_bytes = h.record_bytes,
                         .max_depth = h.max_depth};
  r = ocs_world_add_viewer(srv->world, &req, &s->viewer, &s->granted, why, sizeof why);
  if (r < 0) {
    ocs_session_close(s, r == OC_ERANGE || r == OC_ETOOBIG ? OCP_CODE_FULL : OCP_CODE_INTERNAL,
                      r == OC_ETOOBIG ? "too many viewers" : why);
    return;
  }
  s->state = OCS_SS_READY;
  send_welcome(s, 0);
  oc_log_info("session %" PRIu32 " (viewer %s): welcomed, budget %" PRIu64 " bytes (asked %" PRIu64 "), depth %d", s->id,
              s->addr, s->granted.budget, h.budget, s->granted.max_depth);
}

static void handle_ack(ocs_session_t *s, const uint8_t *p, size_t n) {
  char why[256];
  ocp_ack_t a;
  if (ocp_get_ack(p, n, &a, why, sizeof why) < 0) {
    ocs_session_close(s, OCP_CODE_MALFORMED, why);
    return;
  }
  if (!s->awaiting_ack || a.epoch != s->stream_epoch || a.checksum != s->stream_checksum) {
    snprintf(why, sizeof why, "ack of epoch %" PRIu64 " (checksum %016" PRIx64 ") but epoch %" PRIu64 " is %s", a.epoch,
             a.checksum, s->stream_epoch, s->awaiting_ack ? "in flight with another checksum" : "not complete");
    ocs_session_close(s, OCP_CODE_UNEXPECTED, why);
    return;
  }
  s->awaiting_ack = 0;
  s->acks++;
  double lat = ocs_net_now() - s->stream_started;
  s->ack_latency_sum += lat;
  if (lat > s->ack_latency_max) s->ack_latency_max = lat;
  if (s->srv->stepping) s->ack_pending = 1;
  else ocs_viewer_ack(s->viewer, a.epoch);
}

static void handle_camera(ocs_session_t *s, const uint8_t *p, size_t n) {
  char why[256];
  ocp_camera_t c;
  if (ocp_get_camera(p, n, &c, why, sizeof why) < 0) {
    ocs_session_close(s, OCP_CODE_MALFORMED, why);
    return;
  }
  ocs_view_t v = {c.pos, c.forward, c.up, c.vfov_deg, (int)c.width, (int)c.height};
  if (!ocs_view_valid(&v)) {
    ocs_session_close(s, OCP_CODE_MALFORMED, "camera: not a valid view");
    return;
  }
  s->cam = v;
  if (s->srv->stepping) s->cam_new = 1;
  else ocs_viewer_set_view(s->viewer, &v);
}

/* A peer that stopped reading while everything fit in the kernel's send buffer leaves nothing
 * unsent here, so `queued` cannot tell: the kernel's queue of bytes it has not acknowledged can.
 * @return 1 when that queue is non-empty and has not moved for stall_s. */
static int kernel_stalled(ocs_session_t *s, double now, double stall_s) {
  uv_os_fd_t fd;
  int outq = 0;
  if (uv_fileno((const uv_handle_t *)&s->tcp, &fd) != 0 || ioctl(fd, SIOCOUTQ, &outq) != 0 || outq <= 0) {
    s->kq_last = 0;
    return 0;
  }
  if (outq != s->kq_last) {
    s->kq_last = outq;
    s->kq_since = now;
    return 0;
  }
  return now - s->kq_since > stall_s;
}

/* @return 1 when the frame must wait for the running step to end. */
static int handle_frame(ocs_session_t *s, const ocp_header_t *hd, const uint8_t *p) {
  ocs_server_t *srv = s->srv;
  char why[256];
  const char *name = ocp_msg_name(hd->type);
  if (!name) {
    snprintf(why, sizeof why, "unknown message type 0x%02x", hd->type);
    ocs_session_close(s, OCP_CODE_MALFORMED, why);
    return 0;
  }
  if (s->state == OCS_SS_HANDSHAKE) {
    if (hd->type != OCP_MSG_HELLO) {
      snprintf(why, sizeof why, "%s before hello", name);
      ocs_session_close(s, OCP_CODE_UNEXPECTED, why);
      return 0;
    }
    if (srv->stepping) return 1;
    handle_hello(s, p, hd->length);
    return 0;
  }
  if (hd->version != s->version) {
    snprintf(why, sizeof why, "%s frame of version %u on a version %u connection", name, hd->version, s->version);
    ocs_session_close(s, OCP_CODE_VERSION, why);
    return 0;
  }
  switch (hd->type) {
    case OCP_MSG_KEEPALIVE:
      if (ocp_get_empty(p, hd->length, why, sizeof why) < 0) ocs_session_close(s, OCP_CODE_MALFORMED, why);
      return 0;
    case OCP_MSG_GOODBYE:
    case OCP_MSG_ERROR: {
      ocp_text_msg_t t;
      if (ocp_get_text(p, hd->length, &t, why, sizeof why) < 0) {
        ocs_session_close(s, OCP_CODE_MALFORMED, why);
        return 0;
      }
      if (hd->type == OCP_MSG_ERROR) oc_log_warn("session %" PRIu32 " (%s): peer error: %s: %s", s->id, s->addr, ocp_code_text(t.code), t.text);
      ocs_session_close(s, OCP_CODE_OK, hd->type == OCP_MSG_GOODBYE ? "goodbye from the peer" : "after the peer's error");
      return 0;
    }
    case OCP_MSG_CAMERA:
      if (s->role != OCP_ROLE_VIEWER) break;
      handle_camera(s, p, hd->length);
      return 0;
    case OCP_MSG_ACK:
      if (s->role != OCP_ROLE_VIEWER) break;
      handle_ack(s, p, hd->length);
      return 0;
    case OCP_MSG_CONTROL: {
      if (s->role != OCP_ROLE_CONTROL) break;
      if (srv->stepping) return 1;
      ocp_control_t c;
      if (ocp_get_control(p, hd->length, &c, why, sizeof why) < 0) {
        ocs_session_close(s, OCP_CODE_MALFORMED, why);
        return 0;
      }
      oc_buf_t b = {0};
      ocs_control_handle(s, &c, &b);
      ocs_session_send(s, &b);
      return 0;
    }
    default: break;
  }
  snprintf(why, sizeof why, "%s is not valid from a %s", name, role_name(s->role));
  ocs_session_close(s, OCP_CODE_UNEXPECTED, why);
  return 0;
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf);

static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf) {
  (void)suggested;
  ocs_session_t *s = h->data;
  *buf = uv_buf_init((char *)s->srv->readbuf, sizeof s->srv->readbuf);
}


/* Handles buffered frames until one must wait for the step (then reading pauses). */
static void drain_input(ocs_session_t *s) {
  if (s->blocked) {
    s->blocked = 0;
    int wait = handle_frame(s, &s->deferred_hdr, s->deferred);
    free(s->deferred);
    s->deferred = NULL;
    if (wait) abort(); /* only called when no step runs */
    if (s->state == OCS_SS_CLOSING || s->state == OCS_SS_LINGER) return;
    uv_read_start((uv_stream_t *)&s->tcp, on_alloc, on_read);
  }
  ocp_header_t hd;
  const uint8_t *p;
  int r;
  while (s->state == OCS_SS_HANDSHAKE || s->state == OCS_SS_READY) {
    r = ocp_reader_next(&s->rd, &hd, &p);
    if (r == 0) return;
    if (r < 0) {
      ocs_session_close(s, r == OC_ETOOBIG ? OCP_CODE_TOO_BIG : OCP_CODE_MALFORMED,
                        r == OC_ETOOBIG ? "frame over the 64 KiB limit" : "bad frame magic");
      return;
    }
    if (handle_frame(s, &hd, p)) {
      s->deferred = malloc(hd.length ? hd.length : 1);
      if (!s->deferred) {
        ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
        return;
      }
      memcpy(s->deferred, p, hd.length);
      s->deferred_hdr = hd;
      s->blocked = 1;
      uv_read_stop((uv_stream_t *)&s->tcp);
      return;
    }
  }
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf) {
  ocs_session_t *s = st->data;
  if (nread < 0) {
    session_lost(s, nread == UV_EOF ? "closed by the peer" : uv_strerror((int)nread));
    return;
  }
  if (nread == 0 || s->state == OCS_SS_CLOSING) return;
  s->last_rx = ocs_net_now();
  s->bytes_in += (uint64_t)nread;
  if (ocp_reader_feed(&s->rd, buf->base, (size_t)nread) < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  drain_input(s);
}

static void on_connection(uv_stream_t *ls, int status) {
  ocs_server_t *srv = ls->data;
  if (status < 0) {
    oc_log_warn("accept: %s", uv_strerror(status));
    return;
  }
  ocs_session_t *s = calloc(1, sizeof *s);
  if (!s) return;
  uv_tcp_init(&srv->loop, &s->tcp);
  s->tcp.data = s;
  s->srv = srv;
  s->connected = 1;
  srv->nconnected++;
  if (uv_accept(ls, (uv_stream_t *)&s->tcp) < 0) {
    s->state = OCS_SS_CLOSING;
    s->next = srv->sessions;
    if (srv->sessions) srv->sessions->prev = s;
    srv->sessions = s;
    close_handle(s);
    return;
  }
  s->next = srv->sessions;
  if (srv->sessions) srv->sessions->prev = s;
  srv->sessions = s;
  do s->id = ++srv->next_id;
  while (!s->id);
  s->secret = random_u64();
  s->created = s->last_rx = s->last_progress = ocs_net_now();
  ocp_reader_init(&s->rd, OCP_MAX_CLIENT_PAYLOAD);
  struct sockaddr_storage sa;
  int len = sizeof sa;
  snprintf(s->addr, sizeof s->addr, "?");
  if (uv_tcp_getpeername(&s->tcp, (struct sockaddr *)&sa, &len) == 0) {
    char ip[48] = "?";
    int port = 0;
    if (sa.ss_family == AF_INET) {
      uv_ip4_name((struct sockaddr_in *)&sa, ip, sizeof ip);
      port = ntohs(((struct sockaddr_in *)&sa)->sin_port);
    } else if (sa.ss_family == AF_INET6) {
      uv_ip6_name((struct sockaddr_in6 *)&sa, ip, sizeof ip);
      port = ntohs(((struct sockaddr_in6 *)&sa)->sin6_port);
    }
    snprintf(s->addr, sizeof s->addr, "%s:%d", ip, port);
  }
  uv_tcp_nodelay(&s->tcp, 1);
  if (srv->desc.send_buffer > 0) {
    int v = srv->desc.send_buffer;
    uv_send_buffer_size((uv_handle_t *)&s->tcp, &v);
  }
  srv->accepted++;
  if (srv->stopping || srv->nconnected > srv->desc.max_connections) {
    srv->refused++;
    s->version = OCP_VERSION_MAX;
    ocs_session_close(s, srv->stopping ? OCP_CODE_SHUTDOWN : OCP_CODE_FULL,
                      srv->stopping ? "shutting down" : "too many connections");
    return;
  }
  uv_read_start((uv_stream_t *)&s->tcp, on_alloc, on_read);
}

/*-*** Epochs ***/

static void start_step(ocs_server_t *srv);

/* What a viewer said while a step ran (its acknowledgement, its newest camera) reaches the world. */
static void apply_pending(ocs_session_t *s) {
  if (s->ack_pending) {
    ocs_viewer_ack(s->viewer, s->stream_epoch);
    s->ack_pending = 0;
  }
  if (s->cam_new) {
    ocs_viewer_set_view(s->viewer, &s->cam);
    s->cam_new = 0;
  }
}

static void step_work(uv_work_t *req) {
  ocs_server_t *srv = req->data;
  srv->step_rc = ocs_world_step(srv->world);
}

static void step_done(uv_work_t *req, int status) {
  ocs_server_t *srv = req->data;
  (void)status;
  srv->stepping = 0;
  srv->steps_done++;
  if (srv->step_rc < 0) oc_log_error("epoch step failed: %s (viewers keep their states)", oc_strerror(srv->step_rc));
  ocs_world_stats_t ws; /* once per step, not once per viewer */
  ocs_world_stats(srv->world, &ws);
  srv->plan_ms = 1e3 * ws.plan_seconds;
  srv->produce_ms = 1e3 * ws.produce_seconds;
  for (int i = 0; i < srv->ndoomed; i++) ocs_world_remove_viewer(srv->world, srv->doomed[i]);
  srv->ndoomed = 0;
  /* New states go out; deferred input is handled; waiting "step" requests are answered. The list
   * may change under these calls (sessions close), so walk it with care. */
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->state != OCS_SS_READY || !s->viewer) continue;
    apply_pending(s);
    const oc_state_t *h0 = ocs_viewer_held(s->viewer, 0);
    if (h0 && ocs_viewer_in_flight(s->viewer) && h0->epoch != s->last_out_epoch && !s->streaming && !s->awaiting_ack)
      stream_state(s, ocs_viewer_held(s->viewer, 1));
  }
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->blocked && !srv->stepping) drain_input(s);
  }
  for (ocs_session_t *s = srv->sessions; s; s = s->next)
    if (s->step_waiting && srv->steps_done >= s->step_target && !srv->steps_queued) ocs_control_step_done(s);
  if (srv->steps_queued && !srv->stopping) start_step(srv);
}

static void start_step(ocs_server_t *srv) {
  if (srv->stepping || srv->stopping) return;
  if (srv->steps_queued) srv->steps_queued--;
  for (ocs_session_t *s = srv->sessions; s; s = s->next)
    if (s->viewer) apply_pending(s);
  srv->stepping = 1;
  srv->work.data = srv;
  uv_queue_work(&srv->loop, &srv->work, step_work, step_done);
}

void ocs_server_queue_steps(ocs_server_t *srv, uint64_t n) {
  srv->steps_queued += n;
  start_step(srv);
}

static void on_tick_idle(uv_idle_t *h) { (void)h; }

/* After the poll that followed the tick: the acknowledgements that had arrived are applied by
 * now, so a viewer that has its epoch is not skipped for want of reading its ACK. */
static void on_tick_check(uv_check_t *h) {
  ocs_server_t *srv = h->data;
  uv_idle_stop(&srv->tick_idle);
  uv_check_stop(&srv->tick_check);
  if (!srv->stepping && !srv->stopping) start_step(srv);
}

/* libuv runs timers before it polls sockets: a step started here would not yet see ACKs that
 * arrived since the last poll. The step starts right after the next poll instead (which the idle
 * handle keeps from blocking). */
static void on_epoch_timer(uv_timer_t *t) {
  ocs_server_t *srv = t->data;
  if (srv->stepping) {
    srv->late_ticks++; /* the previous step is still running: this tick is skipped */
    return;
  }
  uv_idle_start(&srv->tick_idle, on_tick_idle);
  uv_check_start(&srv->tick_check, on_tick_check);
}

/*-*** Housekeeping: timeouts, limits, lingering sessions ***/

static void close_quiet(uv_handle_t *h) {
  if (h->type && !uv_is_closing(h)) uv_close(h, NULL);
}


static void on_house_timer(uv_timer_t *t) {
  ocs_server_t *srv = t->data;
  const ocs_server_desc_t *d = &srv->desc;
  double now = ocs_net_now();
  char why[128];
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    switch (s->state) {
      case OCS_SS_HANDSHAKE:
        /* a HELLO held back by a running step has arrived: it is answered when the step ends */
        if (!s->blocked && now - s->created > d->handshake_s) {
          snprintf(why, sizeof why, "no hello within %.1f s", d->handshake_s);
          ocs_session_close(s, OCP_CODE_TIMEOUT, why);
        }
        break;
      case OCS_SS_READY:
        if (now - s->last_rx > d->idle_s) {
          snprintf(why, sizeof why, "nothing received for %.1f s", d->idle_s);
          ocs_session_close(s, OCP_CODE_TIMEOUT, why);
        } else if (s->queued && now - s->last_progress > d->stall_s) {
          snprintf(why, sizeof why, "%" PRIu64 " bytes unsent and none written for %.1f s", s->queued, d->stall_s);
          ocs_session_close(s, OCP_CODE_TIMEOUT, why);
        } else if (!s->queued && s->connected && kernel_stalled(s, now, d->stall_s)) {
          snprintf(why, sizeof why, "%d bytes sent and none read by the peer for %.1f s", s->kq_last, d->stall_s);
          ocs_session_close(s, OCP_CODE_TIMEOUT, why);
        } else if (s->queued > d->queue_soft) {
          if (!s->soft_since) s->soft_since = now;
          else if (now - s->soft_since > d->soft_s) {
            snprintf(why, sizeof why, "over the soft limit of %" PRIu64 " bytes for %.1f s", d->queue_soft, d->soft_s);
            ocs_session_close(s, OCP_CODE_SLOW, why);
          }
        } else {
          s->soft_since = 0;
        }
        break;
      case OCS_SS_LINGER:
        if (now > s->linger_until && !s->connected) {
          oc_log_info("session %" PRIu32 " (viewer %s): not resumed within %.0f s; dropped", s->id, s->addr, d->linger_s);
          drop_viewer(srv, s);
          session_unlink(srv, s);
          session_free(s);
        }
        break;
      case OCS_SS_CLOSING:
        if (s->connected && now - s->closing_since > OCS_CLOSE_GRACE_S) close_handle(s);
        break;
      default: break;
    }
  }
  if (srv->stopping && !srv->sessions && !srv->stepping) close_quiet((uv_handle_t *)&srv->house_timer);
}

/*-*** Server ***/

static void on_signal(uv_signal_t *h, int signum) {
  ocs_server_t *srv = h->data;
  oc_log_info("%s: shutting down", signum == SIGINT ? "SIGINT" : "SIGTERM");
  ocs_server_stop(srv);
}

static void on_stop_async(uv_async_t *h) { ocs_server_stop(h->data); }

void ocs_server_stop_async(ocs_server_t *srv) { uv_async_send(&srv->stop_async); }

void ocs_server_stop(ocs_server_t *srv) {
  if (srv->stopping) return;
  srv->stopping = 1;
  uv_timer_stop(&srv->epoch_timer);
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->state == OCS_SS_LINGER && !s->connected) {
      drop_viewer(srv, s);
      session_unlink(srv, s);
      session_free(s);
    } else if (s->state != OCS_SS_CLOSING) {
      ocs_session_close(s, OCP_CODE_SHUTDOWN, "the server is shutting down");
    }
  }
  close_quiet((uv_handle_t *)&srv->listener);
  close_quiet((uv_handle_t *)&srv->epoch_timer);
  close_quiet((uv_handle_t *)&srv->stop_async);
  close_quiet((uv_handle_t *)&srv->tick_idle);
  close_quiet((uv_handle_t *)&srv->tick_check);
  if (srv->signals) {
    close_quiet((uv_handle_t *)&srv->sig_int);
    close_quiet((uv_handle_t *)&srv->sig_term);
  }
  /* the housekeeper closes itself once every session is gone and no step runs: the loop ends */
}

int ocs_server_reload(ocs_server_t *srv, char *why, size_t why_len) {
  oc_scene_t sc;
  int r;
  if (srv->scene_path) r = oc_scene_load(&sc, srv->scene_path, why, why_len);
  else {
    oc_scene_default(&sc);
    r = 0;
  }
  if (r < 0) return r;
  ocs_world_t *w = NULL;
  r = ocs_world_create(&w, &sc, &srv->desc.world, why, why_len);
  if (r < 0) {
    oc_scene_free(&sc);
    return r;
  }
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->role == OCP_ROLE_VIEWER && (s->viewer || s->state == OCS_SS_LINGER))
      ocs_session_close(s, OCP_CODE_RELOAD, "the scene was reloaded");
  }
  ocs_world_free(srv->world);
  srv->world = w;
  oc_scene_free(&srv->scene);
  srv->scene = sc;
  if (srv->desc.epoch_period < 0) srv->period = sc.epoch_period;
  oc_log_info("scene %s reloaded", sc.name);
  return 0;
}

int ocs_server_create(ocs_server_t **out, const oc_scene_t *scene, const ocs_server_desc_t *desc, char *why, size_t why_len) {
  if (!out || !scene || !desc) return OC_EINVAL;
  *out = NULL;
  ocs_server_t *srv = calloc(1, sizeof *srv);
  if (!srv) return OC_ENOMEM;
  srv->desc = *desc;
  ocs_server_desc_t *d = &srv->desc;
  if (d->linger_s < 0) d->linger_s = 30;
  if (!(d->handshake_s > 0)) d->handshake_s = 10;
  if (d->idle_s > 0 && d->handshake_s > d->idle_s) d->handshake_s = d->idle_s;
  if (!(d->idle_s > 0)) d->idle_s = 60;
  if (!(d->stall_s > 0)) d->stall_s = 30;
  if (!(d->soft_s > 0)) d->soft_s = 10;
  if (!d->queue_soft) d->queue_soft = 4u << 20;
  if (!d->queue_hard) d->queue_hard = 16u << 20;
  if (d->queue_hard < d->queue_soft) d->queue_hard = d->queue_soft;
  if (d->max_connections <= 0) d->max_connections = 256;
  snprintf(srv->host, sizeof srv->host, "%s", d->host ? d->host : "127.0.0.1");
  srv->token = d->token ? strdup(d->token) : NULL;
  srv->scene_path = d->scene_path ? strdup(d->scene_path) : NULL;
  d->host = d->token = d->scene_path = NULL; /* the copies above are what is used */
  int r = oc_scene_copy(&srv->scene, scene);
  if (r < 0 || (desc->token && !srv->token) || (desc->scene_path && !srv->scene_path)) {
    ocs_server_free(srv);
    return OC_ENOMEM;
  }
  srv->period = d->epoch_period < 0 ? scene->epoch_period : d->epoch_period;
  srv->last_scale = 1.0;
  if ((r = ocs_world_create(&srv->world, &srv->scene, &d->world, why, why_len)) < 0) {
    ocs_server_free(srv);
    return r;
  }
  if ((r = uv_loop_init(&srv->loop)) < 0) {
    snprintf(why, why_len, "libuv: %s", uv_strerror(r));
    ocs_world_free(srv->world);
    srv->world = NULL;
    free(srv->token);
    free(srv->scene_path);
    oc_scene_free(&srv->scene);
    free(srv);
    return OC_EIO;
  }
  uv_tcp_init(&srv->loop, &srv->listener);
  srv->listener.data = srv;
  struct sockaddr_storage sa;
  if (uv_ip4_addr(srv->host, d->port, (struct sockaddr_in *)&sa) < 0 &&
      uv_ip6_addr(srv->host, d->port, (struct sockaddr_in6 *)&sa) < 0) {
    snprintf(why, why_len, "--listen: \"%s\" is not an IPv4 or IPv6 address", srv->host);
    ocs_server_free(srv);
    return OC_EINVAL;
  }
  if ((r = uv_tcp_bind(&srv->listener, (struct sockaddr *)&sa, 0)) < 0 ||
      (r = uv_listen((uv_stream_t *)&srv->listener, 128, on_connection)) < 0) {
    snprintf(why, why_len, "cannot listen on %s:%d: %s", srv->host, d->port, uv_strerror(r));
    ocs_server_free(srv);
    return OC_EIO;
  }
  int len = sizeof sa;
  uv_tcp_getsockname(&srv->listener, (struct sockaddr *)&sa, &len);
  int port = sa.ss_family == AF_INET6 ? ntohs(((struct sockaddr_in6 *)&sa)->sin6_port) : ntohs(((struct sockaddr_in *)&sa)->sin_port);
  snprintf(srv->address, sizeof srv->address, strchr(srv->host, ':') ? "[%s]:%d" : "%s:%d", srv->host, port);
  uv_async_init(&srv->loop, &srv->stop_async, on_stop_async);
  srv->stop_async.data = srv;
  uv_idle_init(&srv->loop, &srv->tick_idle);
  uv_check_init(&srv->loop, &srv->tick_check);
  srv->tick_idle.data = srv->tick_check.data = srv;
  uv_timer_init(&srv->loop, &srv->epoch_timer);
  uv_timer_init(&srv->loop, &srv->house_timer);
  srv->epoch_timer.data = srv->house_timer.data = srv;
  *out = srv;
  return 0;
}

const char *ocs_server_address(const ocs_server_t *s) { return s->address; }
int ocs_server_port(const ocs_server_t *s) {
  const char *c = strrchr(s->address, ':');
  return c ? atoi(c + 1) : 0;
}

int ocs_server_run(ocs_server_t *srv, int handle_signals) {
  if (handle_signals) {
    uv_signal_init(&srv->loop, &srv->sig_int);
    uv_signal_init(&srv->loop, &srv->sig_term);
    srv->sig_int.data = srv->sig_term.data = srv;
    uv_signal_start(&srv->sig_int, on_signal, SIGINT);
    uv_signal_start(&srv->sig_term, on_signal, SIGTERM);
    srv->signals = 1;
  }
  if (srv->period > 0) {
    uint64_t ms = (uint64_t)llround(srv->period * 1e3);
    uv_timer_start(&srv->epoch_timer, on_epoch_timer, ms, ms ? ms : 1);
  }
  uv_timer_start(&srv->house_timer, on_house_timer, OCS_HOUSE_MS, OCS_HOUSE_MS);
  uv_run(&srv->loop, UV_RUN_DEFAULT);
  return 0;
}

static void walk_close(uv_handle_t *h, void *arg) {
  (void)arg;
  if (!uv_is_closing(h)) uv_close(h, h->type == UV_TCP && h->data && h->data != arg ? on_closed : NULL);
}

void ocs_server_free(ocs_server_t *srv) {
  if (!srv) return;
  if (srv->listener.type) {
    /* Close every handle and let the callbacks run (sessions free themselves in on_closed). */
    for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
      nx = s->next;
      if (s->state == OCS_SS_LINGER) s->state = OCS_SS_CLOSING;
      if (!s->connected) {
        session_unlink(srv, s);
        session_free(s);
      }
    }
    uv_walk(&srv->loop, walk_close, srv);
    while (uv_run(&srv->loop, UV_RUN_NOWAIT)) {
    }
    uv_loop_close(&srv->loop);
  }
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    session_free(s);
  }
  for (int i = 0; i < srv->ndoomed; i++) ocs_world_remove_viewer(srv->world, srv->doomed[i]);
  free(srv->doomed);
  ocs_world_free(srv->world);
  oc_scene_free(&srv->scene);
  free(srv->token);
  free(srv->scene_path);
  free(srv);
}
