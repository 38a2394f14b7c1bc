/* net_control.c — control requests (docs/protocol.md, "CONTROL and CONTROL_REPLY"): weather,
 * world time, sun, stepping, reload, sessions, stats. Requests and replies are JSON objects
 * (cJSON); they run on the loop thread and never while a step runs (net_input.c holds them). */
#include <cjson/cJSON.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"

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
  ocs_world_carry_clock(w, srv->world); /* world time goes on through a reload */
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

static void reply(ocs_session_t *s, uint32_t request, uint32_t code, cJSON *obj, oc_buf_t *out) {
  cJSON_AddBoolToObject(obj, "ok", code == OCP_CODE_OK);
  char *txt = cJSON_PrintUnformatted(obj);
  cJSON_Delete(obj);
  ocp_control_t m = {.request = request, .status = (int32_t)code, .json = txt ? txt : "{}",
                     .json_len = (uint32_t)(txt ? strlen(txt) : 2)};
  ocp_put_control(out, s->version, OCP_MSG_CONTROL_REPLY, &m);
  cJSON_free(txt);
}

static void fail(ocs_session_t *s, uint32_t request, const char *fmt, const char *arg, oc_buf_t *out) {
  char msg[512];
  snprintf(msg, sizeof msg, fmt, arg);
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "error", msg);
  oc_log_warn("session %" PRIu32 " (control %s): request refused: %s", s->id, s->addr, msg);
  reply(s, request, OCP_CODE_REQUEST, o, out);
}

/* A finite number member, or NAN when absent or not a number. */
static double num(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) && isfinite(v->valuedouble) ? v->valuedouble : NAN;
}

static cJSON *world_stats_json(ocs_server_t *srv) {
  ocs_world_stats_t ws;
  ocs_world_stats(srv->world, &ws);
  cJSON *o = cJSON_CreateObject();
  cJSON_AddNumberToObject(o, "epoch", (double)ws.epoch);
  double utc = ocs_net_utc(srv);
  cJSON_AddNumberToObject(o, "time", ocs_world_time_at(srv->world, utc)); /* now, not the last epoch's */
  cJSON_AddNumberToObject(o, "utc", utc);
  cJSON_AddNumberToObject(o, "epoch_period", srv->period);
  cJSON_AddNumberToObject(o, "viewers", ws.viewers);
  cJSON_AddNumberToObject(o, "granted_bytes", (double)ws.granted_bytes);
  cJSON_AddNumberToObject(o, "held_bytes", (double)ws.held_bytes);
  cJSON_AddNumberToObject(o, "bricks_produced", (double)ws.bricks_produced);
  cJSON_AddNumberToObject(o, "brick_requests", (double)ws.brick_requests);
  cJSON_AddNumberToObject(o, "cache_hit_rate", ws.cache_hit_rate);
  cJSON_AddNumberToObject(o, "cache_bytes", (double)ws.cache_bytes);
  cJSON_AddNumberToObject(o, "plan_ms", 1e3 * ws.plan_seconds);
  cJSON_AddNumberToObject(o, "produce_ms", 1e3 * ws.produce_seconds);
  cJSON_AddNumberToObject(o, "late_ticks", (double)srv->late_ticks);
  cJSON_AddNumberToObject(o, "queue", (double)ocs_world_queue_length(srv->world));
  cJSON_AddNumberToObject(o, "bricks_made_between_ticks", (double)srv->bricks_made);
  cJSON_AddNumberToObject(o, "produce_errors", (double)ws.produce_errors);
  cJSON_AddNumberToObject(o, "connections", srv->nconnected);
  cJSON_AddNumberToObject(o, "accepted", (double)srv->accepted);
  cJSON_AddNumberToObject(o, "refused", (double)srv->refused);
  cJSON_AddNumberToObject(o, "closed_errors", (double)srv->closed_errors);
  cJSON_AddNumberToObject(o, "resumes", (double)srv->resumes);
  /* the connection limits in force, so that a client (overcast-stress) can check it is held to them */
  const ocs_server_desc_t *d = &srv->desc;
  cJSON *l = cJSON_AddObjectToObject(o, "limits");
  cJSON_AddNumberToObject(l, "handshake_s", d->handshake_s);
  cJSON_AddNumberToObject(l, "idle_s", d->idle_s);
  cJSON_AddNumberToObject(l, "stall_s", d->stall_s);
  cJSON_AddNumberToObject(l, "soft_s", d->soft_s);
  cJSON_AddNumberToObject(l, "linger_s", d->linger_s);
  cJSON_AddNumberToObject(l, "queue_soft", (double)d->queue_soft);
  cJSON_AddNumberToObject(l, "queue_hard", (double)d->queue_hard);
  cJSON_AddNumberToObject(l, "max_connections", d->max_connections);
  cJSON_AddNumberToObject(l, "max_per_address", d->max_per_address);
  cJSON_AddNumberToObject(l, "handshake_rate", d->handshake_rate);
  cJSON_AddNumberToObject(l, "max_lingering", d->max_lingering);
  cJSON_AddNumberToObject(l, "linger_budget", (double)d->linger_budget);
  ocs_plan_desc_t none = {0};
  ocs_admission_t a;
  ocs_world_admission(srv->world, &none, &a);
  cJSON_AddNumberToObject(l, "max_budget", (double)a.max_budget);
  cJSON_AddNumberToObject(l, "total_budget", (double)ocs_world_total_budget(srv->world));
  cJSON *rf = cJSON_AddObjectToObject(o, "refusals"); /* by reason: connections and HELLOs refused */
  for (int i = 0; i < OCS_REFUSE_COUNT; i++) cJSON_AddNumberToObject(rf, ocs_refusal_key((ocs_refusal_t)i), (double)srv->refusals[i]);
  int nl;
  uint64_t lb;
  ocs_session_oldest_lingering(srv, &nl, &lb);
  cJSON_AddNumberToObject(o, "lingering", nl);
  cJSON_AddNumberToObject(o, "lingering_budget", (double)lb);
  cJSON_AddNumberToObject(o, "admitted", srv->nadmitted);
  return o;
}

static cJSON *sessions_json(ocs_server_t *srv) {
  static const char *state_names[] = {"handshake", "ready", "lingering", "closing"};
  cJSON *a = cJSON_CreateArray();
  for (ocs_session_t *t = srv->sessions; t; t = t->next) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "id", t->id);
    cJSON_AddStringToObject(o, "role", t->state == OCS_SS_HANDSHAKE ? "unknown" : t->role == OCP_ROLE_CONTROL ? "control" : "viewer");
    cJSON_AddStringToObject(o, "state", state_names[t->state]);
    cJSON_AddStringToObject(o, "address", t->addr);
    cJSON_AddBoolToObject(o, "lingering", t->state == OCS_SS_LINGER);
    cJSON_AddNumberToObject(o, "queued", (double)t->queued);
    /* what the connection itself costs: its frame reader, a held-back frame, its encoder */
    cJSON_AddNumberToObject(o, "memory", (double)(sizeof *t + t->rd.buf.cap + (t->deferred ? t->deferred_hdr.length : 0) +
                                                  ocp_epoch_enc_memory(t->enc)));
    cJSON_AddNumberToObject(o, "bytes_out", (double)t->bytes_out);
    cJSON_AddNumberToObject(o, "bytes_in", (double)t->bytes_in);
    if (t->viewer) {
      ocs_viewer_stats_t vs;
      ocs_viewer_stats(t->viewer, &vs);
      cJSON_AddNumberToObject(o, "budget", (double)vs.budget);
      cJSON_AddNumberToObject(o, "epochs", (double)vs.epochs_sent);
      cJSON_AddNumberToObject(o, "coalesced", (double)vs.coalesced);
      cJSON_AddNumberToObject(o, "resident", (double)vs.resident_bytes);
      cJSON_AddNumberToObject(o, "ack_latency_ms", t->acks ? 1e3 * t->ack_latency_sum / (double)t->acks : 0.0);
    }
    cJSON_AddItemToArray(a, o);
  }
  return a;
}

static void step_done(ocs_session_t *s) {
  s->step_waiting = 0;
  cJSON *o = cJSON_CreateObject();
  cJSON_AddItemToObject(o, "world", world_stats_json(s->srv));
  oc_buf_t b = {0};
  reply(s, s->step_request, OCP_CODE_OK, o, &b);
  ocs_session_send(s, &b);
}

void ocs_control_steps_done(ocs_server_t *srv) {
  for (ocs_session_t *s = srv->sessions; s; s = s->next)
    if (s->step_waiting && srv->steps_done >= s->step_target && !srv->steps_queued) step_done(s);
}

void ocs_control_handle(ocs_session_t *s, const ocp_control_t *req, oc_buf_t *out) {
  ocs_server_t *srv = s->srv;
  char why[512];
  cJSON *j = cJSON_ParseWithLength(req->json, req->json_len);
  if (!j || !cJSON_IsObject(j)) {
    cJSON_Delete(j);
    fail(s, req->request, "%s", "the request is not a JSON object", out);
    return;
  }
  const cJSON *opv = cJSON_GetObjectItemCaseSensitive(j, "op");
  const char *op = cJSON_IsString(opv) ? opv->valuestring : NULL;
  cJSON *o = cJSON_CreateObject();
  int r = 0;
  if (!op) {
    fail(s, req->request, "%s", "missing \"op\"", out);
    goto done;
  }
  oc_log_info("session %" PRIu32 " (control %s): %s", s->id, s->addr, op);
  if (!strcmp(op, "weather")) {
    const cJSON *pv = cJSON_GetObjectItemCaseSensitive(j, "preset");
    int preset = cJSON_IsString(pv) ? oc_scene_preset_parse(pv->valuestring) : OC_EINVAL;
    double sec = cJSON_GetObjectItemCaseSensitive(j, "seconds") ? num(j, "seconds") : 0.0;
    if (preset < 0) {
      fail(s, req->request, "weather: \"preset\" must be one of clear, fair, overcast, storm, cirrus (got %s)",
           cJSON_IsString(pv) ? pv->valuestring : "nothing", out);
      goto done;
    }
    if (!(sec >= 0 && sec <= 1e7)) {
      fail(s, req->request, "%s", "weather: \"seconds\" must be a number in [0, 1e7]", out);
      goto done;
    }
    r = ocs_world_set_weather(srv->world, ocs_net_utc(srv), (oc_preset_t)preset, sec);
  } else if (!strcmp(op, "time")) {
    const cJSON *setv = cJSON_GetObjectItemCaseSensitive(j, "set"), *scv = cJSON_GetObjectItemCaseSensitive(j, "scale");
    double t = num(j, "set"), sc = num(j, "scale");
    if ((!setv && !scv) || (setv && !(fabs(t) <= 1e12)) || (scv && !(sc >= 0 && sc <= 1e6))) {
      fail(s, req->request, "%s", "time: give \"set\" (s, |t| ≤ 1e12) and/or \"scale\" (0..1e6)", out);
      goto done;
    }
    if (setv) r = ocs_world_set_time(srv->world, ocs_net_utc(srv), t);
    if (r >= 0 && scv) r = ocs_world_set_time_scale(srv->world, ocs_net_utc(srv), sc);
  } else if (!strcmp(op, "pause")) {
    r = ocs_world_pause(srv->world, ocs_net_utc(srv));
  } else if (!strcmp(op, "resume")) {
    r = ocs_world_resume(srv->world, ocs_net_utc(srv));
  } else if (!strcmp(op, "sun")) {
    const cJSON *dv = cJSON_GetObjectItemCaseSensitive(j, "dir");
    oc_dvec3 d;
    if (cJSON_IsArray(dv) && cJSON_GetArraySize(dv) == 3) {
      double c[3];
      for (int i = 0; i < 3; i++) {
        const cJSON *e = cJSON_GetArrayItem(dv, i);
        c[i] = cJSON_IsNumber(e) ? e->valuedouble : NAN;
      }
      d = oc_dv3(c[0], c[1], c[2]);
    } else {
      double lat = num(j, "lat"), lon = num(j, "lon");
      if (!(fabs(lat) <= 90 && fabs(lon) <= 360)) {
        fail(s, req->request, "%s", "sun: give \"dir\": [x, y, z] or the subsolar \"lat\" (±90) and \"lon\" (±360)", out);
        goto done;
      }
      d = oc_geo_to_xyz((oc_geo_t){lat, lon, 0.0});
    }
    double l = oc_dlen(d);
    if (!(l > 1e-9 && isfinite(l))) {
      fail(s, req->request, "%s", "sun: \"dir\" must be a finite non-zero vector", out);
      goto done;
    }
    r = ocs_world_set_sun(srv->world, oc_dscale(d, 1.0 / l));
  } else if (!strcmp(op, "step")) {
    double n = num(j, "epochs");
    if (!cJSON_GetObjectItemCaseSensitive(j, "epochs")) n = 1;
    if (!(n >= 1 && n <= 1000 && n == floor(n))) {
      fail(s, req->request, "%s", "step: \"epochs\" must be an integer in 1..1000", out);
      goto done;
    }
    if (s->step_waiting) { /* one waiting reply per connection: a second would lose the first */
      snprintf(why, sizeof why, "%" PRIu32, s->step_request);
      fail(s, req->request, "step: request %s is still stepping on this connection; wait for its reply", why, out);
      goto done;
    }
    s->step_waiting = 1;
    s->step_request = req->request;
    s->step_target = srv->steps_done + srv->steps_queued + (uint64_t)n;
    ocs_server_queue_steps(srv, (uint64_t)n);
    cJSON_Delete(o);
    cJSON_Delete(j);
    return; /* answered by ocs_control_steps_done() */
  } else if (!strcmp(op, "reload")) {
    if ((r = ocs_server_reload(srv, why, sizeof why)) < 0) {
      fail(s, req->request, "reload: %s", why, out);
      goto done;
    }
  } else if (!strcmp(op, "sessions")) {
    cJSON_AddItemToObject(o, "sessions", sessions_json(srv));
  } else if (!strcmp(op, "disconnect")) {
    double id = num(j, "session");
    ocs_session_t *t = NULL;
    for (ocs_session_t *q = srv->sessions; q; q = q->next)
      if (id == (double)q->id) t = q;
    if (!t || t == s) {
      snprintf(why, sizeof why, "%.0f", isfinite(id) ? id : -1.0);
      fail(s, req->request, t ? "disconnect: session %s is this control session" : "disconnect: no session %s", why, out);
      goto done;
    }
    ocs_session_close(t, OCP_CODE_KICKED, "disconnected by the operator");
  } else if (!strcmp(op, "stats")) {
    cJSON_AddItemToObject(o, "world", world_stats_json(srv));
  } else {
    fail(s, req->request, "unknown op \"%s\" (weather, time, pause, resume, sun, step, reload, sessions, disconnect, stats)", op,
         out);
    goto done;
  }
  if (r < 0) {
    fail(s, req->request, "%s", oc_strerror(r), out);
    goto done;
  }
  reply(s, req->request, OCP_CODE_OK, o, out);
  o = NULL;
done:
  cJSON_Delete(o);
  cJSON_Delete(j);
}
