/* net_input.c — what peers send (net_internal.h): reading (a trusted proxy's PROXY header before
 * anything else), frames dispatched by message type and the connection's state, and a frame that
 * needs the world held until the running step ends (reading pauses meanwhile, so a peer cannot
 * queue more behind it). */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"

/* A frame's payload that did not parse (rc < 0) closes the session as MALFORMED, naming why.
 * @return 1 when it did. */
static int closed_malformed(ocs_session_t *s, int rc, const char *why) {
  if (rc >= 0) return 0;
  ocs_session_close(s, OCP_CODE_MALFORMED, why);
  return 1;
}

static void handle_ack(ocs_session_t *s, const uint8_t *p, size_t n) {
  char why[256];
  ocp_ack_t a;
  if (closed_malformed(s, ocp_get_ack(p, n, &a, why, sizeof why), why)) return;
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
  if (closed_malformed(s, ocp_get_camera(p, n, &c, why, sizeof why), why)) return;
  ocs_view_t v = {c.pos, c.forward, c.up, c.vfov_deg, (int)c.width, (int)c.height};
  if (!ocs_view_valid(&v)) {
    ocs_session_close(s, OCP_CODE_MALFORMED, "camera: not a valid view");
    return;
  }
  s->cam = v;
  if (s->srv->stepping) s->cam_new = 1;
  else ocs_viewer_set_view(s->viewer, &v);
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
    ocs_handshake_hello(s, p, hd->length);
    return 0;
  }
  if (hd->version != s->version) {
    snprintf(why, sizeof why, "%s frame of version %u on a version %u connection", name, hd->version, s->version);
    ocs_session_close(s, OCP_CODE_VERSION, why);
    return 0;
  }
  switch (hd->type) {
    case OCP_MSG_KEEPALIVE:
      (void)closed_malformed(s, ocp_get_empty(p, hd->length, why, sizeof why), why);
      return 0;
    case OCP_MSG_GOODBYE:
    case OCP_MSG_ERROR: {
      ocp_text_msg_t t;
      if (closed_malformed(s, ocp_get_text(p, hd->length, &t, why, sizeof why), why)) return 0;
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
      if (closed_malformed(s, ocp_get_control(p, hd->length, &c, why, sizeof why), why)) return 0;
      oc_buf_t b = {0};
      ocs_control_handle(s, &c, &b);
      ocs_session_send(s, &b);
      return 0;
    }
    default: break;
  }
  snprintf(why, sizeof why, "%s is not valid from a %s", name, ocs_role_name(s->role));
  ocs_session_close(s, OCP_CODE_UNEXPECTED, why);
  return 0;
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf);

static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf) {
  (void)suggested;
  ocs_session_t *s = h->data;
  *buf = uv_buf_init((char *)s->srv->readbuf, sizeof s->srv->readbuf);
}

void ocs_input_drain(ocs_session_t *s) {
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

/* The PROXY header's client: the session's name, then the connection limits of its address
 * (a LOCAL header keeps the proxy's own). @return 1 admitted, 0 refused. */
static int proxy_admit(ocs_session_t *s, const ocs_proxy_hdr_t *h) {
  char ip[48], via[64];
  snprintf(via, sizeof via, "%s", s->addr);
  if (h->local) { /* "IP:PORT" or "[IP]:PORT" back to IP */
    const char *a = s->addr + (s->addr[0] == '[');
    int n = (int)(strrchr(s->addr, ':') - a) - (s->addr[0] == '[');
    snprintf(ip, sizeof ip, "%.*s", n, a);
  } else {
    snprintf(ip, sizeof ip, "%s", h->ip);
    snprintf(s->addr, sizeof s->addr, strchr(ip, ':') ? "[%s]:%d" : "%s:%d", ip, h->port);
  }
  oc_log_info("connection %s: PROXY v%d header from %s%s", s->addr, h->version, via, h->local ? " (LOCAL: the proxy's own)" : "");
  return ocs_listener_admit(s, ip);
}

/* A trusted proxy's connection: bytes go to its PROXY header until it is complete (in as many
 * reads as it takes; the handshake deadline bounds the wait); what follows is the wire's.
 * @return 1 when the wire may be read, 0 when the header is not complete, -1 closed. */
static int proxy_input(ocs_session_t *s, const uint8_t *p, size_t n) {
  size_t take = n < OCS_PROXY_MAX - s->proxy_len ? n : OCS_PROXY_MAX - s->proxy_len;
  memcpy(s->proxy_buf + s->proxy_len, p, take);
  s->proxy_len += take;
  ocs_proxy_hdr_t h;
  char why[288], bad[160];
  int r = ocs_proxy_parse(s->proxy_buf, s->proxy_len, &h, bad, sizeof bad);
  if (r == 0) return 0;
  if (r < 0) {
    snprintf(why, sizeof why, "%s is a trusted proxy and must begin with a PROXY header: %s", s->addr, bad);
    ocs_session_refuse(s, OCS_REFUSE_PROXY, why);
    return -1;
  }
  uint8_t *hb = s->proxy_buf;
  s->proxy_buf = NULL;
  int fed = ocp_reader_feed(&s->rd, hb + h.bytes, s->proxy_len - h.bytes) == 0 && ocp_reader_feed(&s->rd, p + take, n - take) == 0;
  free(hb);
  if (!proxy_admit(s, &h)) return -1;
  if (!fed) ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
  return fed ? 1 : -1;
}

/* A PROXY header from a peer that is not a trusted proxy: refused, saying why (a proxy whose
 * address the server does not trust would otherwise fail as "bad frame magic"). @return 1 if so. */
static int untrusted_proxy(ocs_session_t *s, const uint8_t *p, size_t n) {
  if (s->bytes_in != (uint64_t)n || s->state != OCS_SS_HANDSHAKE || !ocs_proxy_signature(p, n)) return 0;
  char why[160];
  snprintf(why, sizeof why, "a PROXY header from %s, which is not a --trusted-proxy", s->addr);
  ocs_session_refuse(s, OCS_REFUSE_PROXY, why);
  return 1;
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf) {
  ocs_session_t *s = st->data;
  if (nread < 0) {
    ocs_session_lost(s, nread == UV_EOF ? "closed by the peer" : uv_strerror((int)nread));
    return;
  }
  if (nread == 0 || s->state == OCS_SS_CLOSING) return;
  s->last_rx = ocs_net_now();
  s->bytes_in += (uint64_t)nread;
  const uint8_t *p = (const uint8_t *)buf->base;
  if (s->proxy_buf) {
    if (proxy_input(s, p, (size_t)nread) == 1) ocs_input_drain(s);
    return;
  }
  if (untrusted_proxy(s, p, (size_t)nread)) return;
  if (ocp_reader_feed(&s->rd, p, (size_t)nread) < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  ocs_input_drain(s);
}

void ocs_input_start(ocs_session_t *s) { uv_read_start((uv_stream_t *)&s->tcp, on_alloc, on_read); }
