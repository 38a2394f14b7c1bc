/* net_handshake.c — a connection's HELLO (net_internal.h): the version (the highest both speak),
 * the token (the viewer's, or the control token for a control client when the server has one),
 * resume of a lingering or still-open session, admission, and WELCOME. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"

/* Compares in a time that depends on neither the tokens' bytes nor their lengths: every one of
 * OCP_TOKEN_MAX positions is read, so a peer cannot find the token a byte at a time by timing. */
int ocs_token_equal(const char *want, const uint8_t *got, size_t got_len) {
  size_t want_len = strlen(want);
  volatile unsigned diff = (unsigned)(want_len ^ got_len);
  for (size_t i = 0; i < OCP_TOKEN_MAX; i++) {
    unsigned a = i < want_len ? (uint8_t)want[i] : 0u, b = i < got_len ? got[i] : 0u;
    diff |= a ^ b;
  }
  return diff == 0;
}

/* The token a HELLO must present: the control token for a control client when the server has one
 * (the viewer token is then refused for control, saying so), else the viewer token; the control
 * token also admits a viewer (an operator's overcast-view --step presents one token for both).
 * @return 1 accepted; 0 refused (TOKEN). */
static int token_accepted(ocs_session_t *s, const ocp_hello_t *h) {
  const ocs_server_t *srv = s->srv;
  int control = h->role == OCP_ROLE_CONTROL && srv->control_token;
  const char *want = control ? srv->control_token : srv->token;
  if (!want || ocs_token_equal(want, h->token, h->token_len)) return 1;
  if (!control && srv->control_token && ocs_token_equal(srv->control_token, h->token, h->token_len)) return 1;
  const char *why = "the token does not match";
  if (!h->token_len) why = control ? "this server requires the control token for control requests" : "this server requires a token";
  else if (control && srv->token && ocs_token_equal(srv->token, h->token, h->token_len))
    why = "the viewer token cannot run control requests: present the control token";
  ocs_session_refuse(s, OCS_REFUSE_TOKEN, why);
  return 0;
}

static void send_welcome(ocs_session_t *s, int resumed) {
  ocs_server_t *srv = s->srv;
  const oc_scene_t *sc = ocs_world_scene(srv->world);
  ocp_welcome_t m;
  memset(&m, 0, sizeof m);
  m.version = s->version;
  m.flags = resumed ? OCP_WELCOME_RESUMED : 0;
  m.session = s->id;
  m.secret = s->secret;
  if (s->role == OCP_ROLE_VIEWER) {
    m.grant = s->granted.grant; /* the contract the planner plans under, K included */
    m.max_depth = (uint8_t)s->granted.max_depth;
  }
  m.features = sc->features;
  m.epoch_period = srv->period;
  m.planet_radius = OC_PLANET_RADIUS;
  m.time = ocs_world_time_at(srv->world, ocs_net_utc(srv));
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
    ocs_session_unlink(srv, old);
    ocs_session_free(old);
  } else {
    old->state = OCS_SS_READY;
    ocs_session_close(old, OCP_CODE_OK, "resumed on another connection");
  }
  srv->counts.resumes++;
  s->state = OCS_SS_READY;
  /* WELCOME names the largest budget its window may still use (the viewer counts its held states
   * against it); a lowering in force is told again after it */
  ocs_viewer_stats_t vs;
  ocs_viewer_stats(s->viewer, &vs);
  s->granted.budget = vs.reserved;
  ocs_viewer_budget_changes(s->viewer, s->version >= OCP_VERSION_BUDGET);
  if (s->version >= OCP_VERSION_BUDGET) ocs_viewer_budget_resend(s->viewer);
  send_welcome(s, 1);
  oc_log_info("session %" PRIu32 " (viewer %s): resumed at epoch %" PRIu64, s->id, s->addr, h->held_epoch);
  if (have0 && in_flight) ocs_viewer_ack(s->viewer, h0->epoch); /* it arrived; the ACK was lost */
  if (have1) ocs_session_stream(s, h1);                                /* re-send the lost epoch */
  return 1;
}

void ocs_handshake_hello(ocs_session_t *s, const uint8_t *p, size_t n) {
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
    ocs_session_refuse(s, OCS_REFUSE_VERSION, why);
    return;
  }
  s->version = (uint8_t)v;
  if (!token_accepted(s, &h)) return;
  s->role = h.role;
  s->caps = h.caps;
  if (h.role == OCP_ROLE_CONTROL) {
    s->state = OCS_SS_READY;
    send_welcome(s, 0);
    oc_log_info("session %" PRIu32 " (control %s): welcomed", s->id, s->addr);
    return;
  }
  if (srv->draining) { /* control clients are still welcome: they watch the drain */
    snprintf(why, sizeof why, "%d ms: the server is draining", OCS_RECONNECT_DELAY_MS);
    ocs_session_refuse(s, OCS_REFUSE_DRAINING, why);
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
    if (try_resume(s, ocs_session_find(srv, h.resume_session), &h)) return;
    /* not resumable: the old session (if any and if it is this viewer's) is dropped */
    ocs_session_t *old = ocs_session_find(srv, h.resume_session);
    if (old && old != s && old->secret == h.resume_secret && old->state == OCS_SS_LINGER)
      ocs_session_close(old, OCP_CODE_OK, "superseded by a new session");
  }
  if (ocs_admit_viewer(s, &h) < 0) return;
  ocs_viewer_budget_changes(s->viewer, s->version >= OCP_VERSION_BUDGET); /* v1/v2: its grant is fixed */
  s->state = OCS_SS_READY;
  send_welcome(s, 0);
  oc_log_info("session %" PRIu32 " (viewer %s): welcomed, budget %" PRIu64 " bytes (asked %" PRIu64 "), depth %d", s->id,
              s->addr, s->granted.budget, h.budget, s->granted.max_depth);
}
