/* net_server.c — the server's lifecycle (ocs_server.h; the files it is made of are listed in
 * net_internal.h; wire format in docs/protocol.md): create (audit log, world, listener, /metrics,
 * timers), run the loop, stop (every client gets GOODBYE; the loop ends when they have gone), free. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "net_internal.h"
#include "net_share.h"
#include "server_config.h" /* ocs_config_is_loopback */
#include "oc_err.h"
#include "oc_log.h"

static void close_quiet(uv_handle_t *h) {
  if (h->type && !uv_is_closing(h)) uv_close(h, NULL);
}

/* The end of a step, for the layers above net_epoch.c: scrapes that waited for the world are
 * answered (first: the input handled next may start a step), input held back by the step is
 * handled, and "step" requests whose epochs are done are answered. */
static void after_step(ocs_server_t *srv) {
  ocs_share_idle(srv); /* control entries due from the next epoch (control_stream.h) */
  ocs_metrics_resume(srv);
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->blocked && !srv->stepping) ocs_input_drain(s);
  }
  ocs_control_steps_done(srv);
}

/*-*** Server ***/

/* SIGTERM drains (a restart that does not drop viewers on the floor); a second one, or SIGINT,
 * stops at once. */
static void on_signal(uv_signal_t *h, int signum) {
  ocs_server_t *srv = h->data;
  if (signum == SIGTERM && !srv->draining && !srv->stopping) {
    oc_log_info("SIGTERM: draining");
    ocs_server_drain(srv);
    return;
  }
  oc_log_info("%s: shutting down", signum == SIGINT ? "SIGINT" : "SIGTERM");
  ocs_server_stop(srv);
}

void ocs_server_drain(ocs_server_t *srv) {
  if (srv->draining || srv->stopping) return;
  srv->draining = 1;
  srv->drain_until = ocs_net_now() + srv->desc.drain_s;
  uint32_t delay_ms = OCS_RECONNECT_DELAY_MS;
  char text[96];
  snprintf(text, sizeof text, "%" PRIu32 " ms: the server is draining", delay_ms);
  oc_log_info("draining: new viewers are refused; the server stops when every viewer has left, or in %.1f s",
              srv->desc.drain_s);
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->role != OCP_ROLE_VIEWER) continue;
    if (s->state == OCS_SS_LINGER) ocs_session_let_go(s, "the server is draining");
    else if (s->state == OCS_SS_READY) {
      s->drained = 1;
      ocs_session_close(s, OCP_CODE_RECONNECT, text);
    }
  }
}

static void on_stop_async(uv_async_t *h) { ocs_server_stop(h->data); }

void ocs_server_stop_async(ocs_server_t *srv) { uv_async_send(&srv->stop_async); }

void ocs_server_stop(ocs_server_t *srv) {
  if (srv->stopping) return;
  ocs_epoch_flush(srv); /* a tick built ahead goes out now */
  srv->stopping = 1;
  uv_timer_stop(&srv->epoch_timer);
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->state == OCS_SS_LINGER && !s->connected) {
      ocs_session_drop_viewer(srv, s);
      ocs_session_unlink(srv, s);
      ocs_session_free(s);
    } else if (s->state != OCS_SS_CLOSING) {
      ocs_session_close(s, OCP_CODE_SHUTDOWN, "the server is shutting down");
    } else if (s->drained) { /* told to reconnect and not gone: the drain is over for it */
      ocs_session_close_handle(s);
    }
  }
  close_quiet((uv_handle_t *)&srv->listener);
  ocs_metrics_close(srv);
  ocs_share_close(srv);
  close_quiet((uv_handle_t *)&srv->epoch_timer);
  close_quiet((uv_handle_t *)&srv->send_timer);
  close_quiet((uv_handle_t *)&srv->stop_async);
  close_quiet((uv_handle_t *)&srv->tick_idle);
  close_quiet((uv_handle_t *)&srv->tick_check);
  if (srv->signals) {
    close_quiet((uv_handle_t *)&srv->sig_int);
    close_quiet((uv_handle_t *)&srv->sig_term);
  }
  /* the housekeeper closes itself once every session is gone and no step runs: the loop ends */
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
  if (!(d->drain_s > 0)) d->drain_s = 30;
  if (!d->queue_soft) d->queue_soft = 4u << 20;
  if (!d->queue_hard) d->queue_hard = 16u << 20;
  if (d->queue_hard < d->queue_soft) d->queue_hard = d->queue_soft;
  if (d->max_connections <= 0) d->max_connections = 256;
  if (d->max_per_address <= 0) d->max_per_address = 32;
  if (!(d->handshake_rate > 0)) d->handshake_rate = 10;
  if (d->max_lingering <= 0) d->max_lingering = 16;
  snprintf(srv->host, sizeof srv->host, "%s", d->host ? d->host : "127.0.0.1");
  if (!d->token && !d->insecure && ocs_config_is_loopback(srv->host) == 0) { /* the CLI says so first (exit 2) */
    snprintf(why, why_len, "refusing to listen on %s without a token: anyone who reaches it could take the budget "
             "(give a token, or insecure)", srv->host);
    free(srv);
    return OC_EINVAL;
  }
  if (d->metrics && !ocs_metrics_token(d) && !d->insecure && ocs_config_is_loopback(d->metrics_host) == 0) {
    snprintf(why, why_len, "refusing to serve metrics on %s without a token (give a control token or a token, or "
             "insecure)", d->metrics_host);
    free(srv);
    return OC_EINVAL;
  }
  char bad[160];
  if (d->trusted_proxies && (srv->ntrusted = ocs_proxy_list_parse(d->trusted_proxies, srv->trusted, bad, sizeof bad)) < 0) {
    snprintf(why, why_len, "trusted proxies: %s", bad);
    free(srv);
    return OC_EINVAL;
  }
  d->trusted_proxies = NULL; /* parsed into srv->trusted */
  srv->token = d->token ? strdup(d->token) : NULL;
  srv->control_token = d->control_token ? strdup(d->control_token) : NULL;
  srv->scene_path = d->scene_path ? strdup(d->scene_path) : NULL;
  d->host = d->token = d->control_token = d->scene_path = NULL; /* the copies above are what is used */
  ocs_hist_init(&srv->tick_lateness, ocs_hist_seconds);
  int r = oc_scene_copy(&srv->scene, scene);
  if (r < 0 || (desc->token && !srv->token) || (desc->control_token && !srv->control_token) ||
      (desc->scene_path && !srv->scene_path)) {
    ocs_server_free(srv);
    return OC_ENOMEM;
  }
  if ((r = ocs_audit_open(srv, why, why_len)) < 0) { /* before the world: a bad path fails fast */
    ocs_server_free(srv);
    return r;
  }
  srv->period = d->epoch_period < 0 ? scene->epoch_period : d->epoch_period;
  d->world.clocked = srv->period > 0; /* production runs behind the ticks */
  if (srv->period > 0 && !d->world.start_utc) { /* the clock starts now, at the world time asked */
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    d->world.start_utc = (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
  }
  if ((r = ocs_share_content_id(srv, &srv->scene, &d->world.content_id, why, why_len)) < 0 ||
      (r = ocs_world_create(&srv->world, &srv->scene, &d->world, why, why_len)) < 0) {
    ocs_server_free(srv);
    return r;
  }
  if (!d->linger_budget) d->linger_budget = ocs_world_total_budget(srv->world) / 2;
  if ((r = uv_loop_init(&srv->loop)) < 0) {
    snprintf(why, why_len, "libuv: %s", uv_strerror(r));
    ocs_server_free(srv); /* nothing of the loop to close: the listener is not initialised */
    return OC_EIO;
  }
  if ((r = ocs_listener_open(srv, why, why_len)) < 0 || (r = ocs_metrics_open(srv, why, why_len)) < 0 ||
      (r = ocs_share_open(srv, why, why_len)) < 0) {
    ocs_server_free(srv);
    return r;
  }
  uv_async_init(&srv->loop, &srv->stop_async, on_stop_async);
  srv->stop_async.data = srv;
  ocs_epoch_init(srv);
  srv->after_step = after_step;
  *out = srv;
  return 0;
}

const char *ocs_server_address(const ocs_server_t *s) { return s->address; }
const char *ocs_server_metrics_address(const ocs_server_t *s) { return s->metrics ? s->metrics_address : NULL; }
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
  if (!ocs_share_control(srv)) ocs_epoch_start_timer(srv); /* else once the control history is read */
  ocs_house_start(srv);
  uv_run(&srv->loop, UV_RUN_DEFAULT);
  return 0;
}

static void walk_close(uv_handle_t *h, void *arg) {
  (void)arg;
  if (!uv_is_closing(h)) uv_close(h, h->type == UV_TCP && h->data && h->data != arg ? ocs_session_on_closed : NULL);
}

void ocs_server_free(ocs_server_t *srv) {
  if (!srv) return;
  ocs_metrics_close(srv);
  ocs_share_close(srv); /* its handles close through its own callbacks, before the walk below */
  if (srv->listener.type) {
    /* Close every handle and let the callbacks run (sessions free themselves in on_closed). */
    for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
      nx = s->next;
      if (s->state == OCS_SS_LINGER) s->state = OCS_SS_CLOSING;
      if (!s->connected) {
        ocs_session_unlink(srv, s);
        ocs_session_free(s);
      }
    }
    uv_walk(&srv->loop, walk_close, srv);
    while (uv_run(&srv->loop, UV_RUN_NOWAIT)) {
    }
    uv_loop_close(&srv->loop);
  }
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    ocs_session_free(s);
  }
  for (int i = 0; i < srv->ndoomed; i++) ocs_world_remove_viewer(srv->world, srv->doomed[i]);
  free(srv->doomed);
  ocs_peer_free_all(srv);
  ocs_world_free(srv->world);
  oc_scene_free(&srv->scene);
  ocs_audit_close(srv);
  free(srv->token);
  free(srv->control_token);
  free(srv->scene_path);
  free(srv);
}
