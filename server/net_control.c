/* net_control.c — control requests (docs/protocol.md, "CONTROL and CONTROL_REPLY"): weather,
 * world time, sun, stepping, reload, sessions, stats, disconnect, drain, a viewer's budget. Requests and replies are JSON
 * objects (cJSON); they run on the loop thread and never while a step runs (net_input.c holds
 * them). Each op is a row of one table, which also says whether it changes the world: those go to
 * the audit log (net_audit.c) with their outcome. A change of the world (weather, time, pause,
 * resume, sun, step) is read into an ocs_change_t: applied here, or with --redis appended to the
 * shared control history and answered once this front-end applies it (control_stream.h). */
#include <cjson/cJSON.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "control_stream.h"
#include "net_internal.h"
#include "net_share.h"
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
  r = ocs_share_content_id(srv, &sc, &srv->desc.world.content_id, why, why_len); /* the files may have changed */
  if (r >= 0) r = ocs_world_create(&w, &sc, &srv->desc.world, why, why_len);
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
  ocs_share_world_changed(srv);
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

static void fail(ocs_session_t *s, uint32_t request, const char *msg, oc_buf_t *out) {
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

/* One request being handled. An op returns 0 (done), or a negative OC_E*: after writing why it
 * refuses into err (refuse()), or the world's (err empty). */
typedef struct {
  ocs_session_t *s;
  uint32_t request;
  const cJSON *j; /* the request */
  cJSON *o;       /* the reply's members */
  char err[512];
  int waits;      /* answered later (a "step": ocs_control_steps_done()) */
} ctl_t;

static int refuse(ctl_t *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int refuse(ctl_t *c, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(c->err, sizeof c->err, fmt, ap);
  va_end(ap);
  return OC_EINVAL;
}

/* The "world" member: the figures (net_stats.c), also what /metrics shows. */
static int add_world(ctl_t *c) {
  ocs_stats_t st;
  if (ocs_stats_gather(c->s->srv, &st) < 0) return OC_ENOMEM;
  cJSON_AddItemToObject(c->o, "world", ocs_stats_world_json(c->s->srv, &st));
  ocs_stats_free(&st);
  return 0;
}

/* A change of the world: appended to the shared control history with --redis (the reply waits
 * for this front-end to apply it), applied here otherwise. */
static int change(ctl_t *c, const ocs_change_t *chg) {
  ocs_server_t *srv = c->s->srv;
  ocs_ctl_t *ctl = ocs_share_control(srv);
  if (!ctl && srv->desc.redis_host) return refuse(c, "the server is stopping (its shared control history is closed)");
  if (!ctl) return ocs_change_apply(srv->world, chg, ocs_net_utc(srv));
  if (ocs_ctl_publish(ctl, c->s, c->request, chg, c->err, sizeof c->err) < 0) return OC_EIO;
  c->waits = 1;
  return 0;
}

static int op_weather(ctl_t *c) {
  const cJSON *pv = cJSON_GetObjectItemCaseSensitive(c->j, "preset");
  int preset = cJSON_IsString(pv) ? oc_scene_preset_parse(pv->valuestring) : OC_EINVAL;
  double sec = cJSON_GetObjectItemCaseSensitive(c->j, "seconds") ? num(c->j, "seconds") : 0.0;
  if (preset < 0)
    return refuse(c, "weather: \"preset\" must be one of clear, fair, overcast, storm, cirrus (got %s)",
                  cJSON_IsString(pv) ? pv->valuestring : "nothing");
  if (!(sec >= 0 && sec <= 1e7)) return refuse(c, "weather: \"seconds\" must be a number in [0, 1e7]");
  return change(c, &(ocs_change_t){.op = OCS_CHG_WEATHER, .preset = preset, .seconds = sec});
}

static int op_time(ctl_t *c) {
  const cJSON *setv = cJSON_GetObjectItemCaseSensitive(c->j, "set"), *scv = cJSON_GetObjectItemCaseSensitive(c->j, "scale");
  double t = num(c->j, "set"), sc = num(c->j, "scale");
  if ((!setv && !scv) || (setv && !(fabs(t) <= 1e12)) || (scv && !(sc >= 0 && sc <= 1e6)))
    return refuse(c, "time: give \"set\" (s, |t| ≤ 1e12) and/or \"scale\" (0..1e6)");
  return change(c, &(ocs_change_t){.op = OCS_CHG_TIME, .set = setv ? t : NAN, .scale = scv ? sc : NAN});
}

static int op_pause(ctl_t *c) { return change(c, &(ocs_change_t){.op = OCS_CHG_PAUSE}); }

static int op_resume(ctl_t *c) { return change(c, &(ocs_change_t){.op = OCS_CHG_RESUME}); }

static int op_sun(ctl_t *c) {
  const cJSON *dv = cJSON_GetObjectItemCaseSensitive(c->j, "dir");
  oc_dvec3 d;
  if (cJSON_IsArray(dv) && cJSON_GetArraySize(dv) == 3) {
    double v[3];
    for (int i = 0; i < 3; i++) {
      const cJSON *e = cJSON_GetArrayItem(dv, i);
      v[i] = cJSON_IsNumber(e) ? e->valuedouble : NAN;
    }
    d = oc_dv3(v[0], v[1], v[2]);
  } else {
    double lat = num(c->j, "lat"), lon = num(c->j, "lon");
    if (!(fabs(lat) <= 90 && fabs(lon) <= 360))
      return refuse(c, "sun: give \"dir\": [x, y, z] or the subsolar \"lat\" (±90) and \"lon\" (±360)");
    d = oc_geo_to_xyz((oc_geo_t){lat, lon, 0.0});
  }
  double l = oc_dlen(d);
  if (!(l > 1e-9 && isfinite(l))) return refuse(c, "sun: \"dir\" must be a finite non-zero vector");
  return change(c, &(ocs_change_t){.op = OCS_CHG_SUN, .sun = oc_dscale(d, 1.0 / l)});
}

static int op_step(ctl_t *c) {
  ocs_session_t *s = c->s;
  ocs_server_t *srv = s->srv;
  double n = cJSON_GetObjectItemCaseSensitive(c->j, "epochs") ? num(c->j, "epochs") : 1;
  if (!(n >= 1 && n <= 1000 && n == floor(n))) return refuse(c, "step: \"epochs\" must be an integer in 1..1000");
  if (s->step_waiting) /* one waiting reply per connection: a second would lose the first */
    return refuse(c, "step: request %" PRIu32 " is still stepping on this connection; wait for its reply", s->step_request);
  ocs_ctl_t *ctl = ocs_share_control(srv);
  if (ctl && srv->period > 0)
    return refuse(c, "step: with --redis the epochs of a clocked world tick on the clock of every front-end; "
                     "steps are for stepped mode (--epoch-period 0)");
  s->step_waiting = 1;
  s->step_request = c->request;
  c->waits = 1;
  if (ctl) { /* the step is shared: its target is set when this front-end reads it (control_stream.c) */
    s->step_target = UINT64_MAX;
    if (ocs_ctl_publish(ctl, s, c->request, &(ocs_change_t){.op = OCS_CHG_STEP, .epochs = (uint32_t)n}, c->err,
                        sizeof c->err) < 0) {
      s->step_waiting = c->waits = 0;
      return OC_EIO;
    }
    return 0;
  }
  s->step_target = srv->steps_done + srv->steps_queued + (uint64_t)n;
  ocs_server_queue_steps(srv, (uint64_t)n);
  return 0;
}

static int op_reload(ctl_t *c) {
  char why[400];
  return ocs_server_reload(c->s->srv, why, sizeof why) < 0 ? refuse(c, "reload: %s", why) : 0;
}

static int op_sessions(ctl_t *c) {
  ocs_stats_t st;
  if (ocs_stats_gather(c->s->srv, &st) < 0) return OC_ENOMEM;
  cJSON_AddItemToObject(c->o, "sessions", ocs_stats_sessions_json(&st));
  ocs_stats_free(&st);
  return 0;
}

static int op_disconnect(ctl_t *c) {
  double id = num(c->j, "session");
  ocs_session_t *t = NULL;
  for (ocs_session_t *q = c->s->srv->sessions; q; q = q->next)
    if (id == (double)q->id) t = q;
  if (!t) return refuse(c, "disconnect: no session %.0f", isfinite(id) ? id : -1.0);
  if (t == c->s) return refuse(c, "disconnect: session %.0f is this control session", id);
  ocs_session_close(t, OCP_CODE_KICKED, "disconnected by the operator");
  return 0;
}

/* A viewer's budget by hand: "session" and "bytes". The world puts it in force (a raise at the
 * viewer's next plan, a lowering once its newest state fits it) and the viewer hears of it by
 * BUDGET, which only protocol version 3 has. */
static int op_budget(ctl_t *c) {
  double id = num(c->j, "session"), bytes = num(c->j, "bytes");
  if (!(id >= 0 && id == floor(id))) return refuse(c, "budget: \"session\" must be a session id");
  if (!(bytes >= 1 && bytes <= 9.0e15 && bytes == floor(bytes)))
    return refuse(c, "budget: \"bytes\" must be a whole number of bytes in 1..9e15");
  ocs_session_t *t = NULL;
  for (ocs_session_t *q = c->s->srv->sessions; q; q = q->next)
    if (id == (double)q->id) t = q;
  if (!t) return refuse(c, "budget: no session %.0f", id);
  if (t->role != OCP_ROLE_VIEWER) return refuse(c, "budget: session %.0f is a control session", id);
  if (!t->viewer || t->state != OCS_SS_READY)
    return refuse(c, "budget: session %.0f has no viewer connected (it lingers or is closing)", id);
  if (t->version < OCP_VERSION_BUDGET)
    return refuse(c, "budget: session %.0f: this viewer speaks protocol version %u: BUDGET needs %u", id, (unsigned)t->version,
                  OCP_VERSION_BUDGET);
  char why[300];
  ocs_viewer_stats_t was;
  ocs_viewer_stats(t->viewer, &was);
  if (ocs_world_set_budget(c->s->srv->world, t->viewer, (uint64_t)bytes, why, sizeof why) < 0)
    return refuse(c, "budget: session %.0f: %s", id, why);
  cJSON_AddNumberToObject(c->o, "session", id);
  cJSON_AddNumberToObject(c->o, "was", (double)was.budget);
  cJSON_AddNumberToObject(c->o, "budget", bytes);
  return 0;
}

/* Replies before the server stops: the stop comes from the housekeeper (net_house.c), later. */
static int op_drain(ctl_t *c) {
  ocs_server_t *srv = c->s->srv;
  int viewers = 0;
  for (ocs_session_t *s = srv->sessions; s; s = s->next) viewers += s->role == OCP_ROLE_VIEWER && s->state == OCS_SS_READY;
  cJSON_AddBoolToObject(c->o, "already", srv->draining);
  ocs_server_drain(srv);
  cJSON_AddNumberToObject(c->o, "viewers", viewers);
  cJSON_AddNumberToObject(c->o, "timeout_s", srv->desc.drain_s);
  return 0;
}

static const struct {
  const char *name;
  int (*fn)(ctl_t *c);
  int audited; /* changes the world or its sessions: written to the audit log */
} ops[] = {
    {"weather", op_weather, 1}, {"time", op_time, 1},         {"pause", op_pause, 1},
    {"resume", op_resume, 1},   {"sun", op_sun, 1},           {"step", op_step, 1},
    {"reload", op_reload, 1},   {"sessions", op_sessions, 0}, {"disconnect", op_disconnect, 1},
    {"stats", add_world, 0},    {"drain", op_drain, 1},       {"budget", op_budget, 1},
};
#define NOPS (sizeof ops / sizeof ops[0])

static void step_done(ocs_session_t *s) {
  s->step_waiting = 0;
  ctl_t c = {.s = s, .o = cJSON_CreateObject()};
  oc_buf_t b = {0};
  if (add_world(&c) < 0) cJSON_AddStringToObject(c.o, "error", "out of memory for the figures");
  reply(s, s->step_request, OCP_CODE_OK, c.o, &b);
  ocs_session_send(s, &b);
}

void ocs_control_reply_later(ocs_server_t *srv, uint32_t session, uint32_t request, cJSON *o, const char *error) {
  ocs_session_t *s = ocs_session_find(srv, session);
  if (!s || s->state != OCS_SS_READY) {
    cJSON_Delete(o);
    return;
  }
  oc_buf_t b = {0};
  if (error) {
    cJSON_Delete(o);
    fail(s, request, error, &b);
  } else {
    reply(s, request, OCP_CODE_OK, o ? o : cJSON_CreateObject(), &b);
  }
  ocs_session_send(s, &b);
}

void ocs_control_steps_done(ocs_server_t *srv) {
  for (ocs_session_t *s = srv->sessions; s; s = s->next)
    if (s->step_waiting && srv->steps_done >= s->step_target && !srv->steps_queued) step_done(s);
}

/* The op's row, or NOPS after writing the refusal into c->err. */
static size_t find_op(ctl_t *c, const char *op) {
  if (!op) {
    refuse(c, "missing \"op\"");
    return NOPS;
  }
  for (size_t i = 0; i < NOPS; i++)
    if (!strcmp(op, ops[i].name)) return i;
  int n = snprintf(c->err, sizeof c->err, "unknown op \"%.64s\" (", op);
  for (size_t i = 0; i < NOPS && n > 0 && (size_t)n < sizeof c->err; i++)
    n += snprintf(c->err + n, sizeof c->err - (size_t)n, "%s%s", ops[i].name, i + 1 < NOPS ? ", " : ")");
  return NOPS;
}

void ocs_control_handle(ocs_session_t *s, const ocp_control_t *req, oc_buf_t *out) {
  ctl_t c = {.s = s, .request = req->request};
  cJSON *j = cJSON_ParseWithLength(req->json, req->json_len);
  if (!j || !cJSON_IsObject(j)) {
    cJSON_Delete(j);
    fail(s, req->request, "the request is not a JSON object", out);
    return;
  }
  c.j = j;
  const cJSON *opv = cJSON_GetObjectItemCaseSensitive(j, "op");
  size_t k = find_op(&c, cJSON_IsString(opv) ? opv->valuestring : NULL);
  if (k == NOPS) {
    fail(s, req->request, c.err, out);
    cJSON_Delete(j);
    return;
  }
  oc_log_info("session %" PRIu32 " (control %s): %s", s->id, s->addr, ops[k].name);
  c.o = cJSON_CreateObject();
  int r = ops[k].fn(&c);
  if (r < 0 && !c.err[0]) snprintf(c.err, sizeof c.err, "%s", oc_strerror(r));
  if (ops[k].audited) ocs_audit_write(s, ops[k].name, j, r < 0 ? c.err : NULL);
  if (r < 0) {
    cJSON_Delete(c.o);
    fail(s, req->request, c.err, out);
  } else if (!c.waits) {
    reply(s, req->request, OCP_CODE_OK, c.o, out);
  } else {
    cJSON_Delete(c.o);
  }
  cJSON_Delete(j);
}
