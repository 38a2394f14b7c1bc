/* net_house.c — housekeeping every OCS_HOUSE_MS (net_internal.h): handshake, idle and stall
 * timeouts, the soft send-queue limit, lingering sessions not resumed in time, and connections
 * whose goodbye did not drain. When the server is stopping and every session is gone, it closes
 * itself and the loop ends. */
#include <inttypes.h>
#include <stdio.h>
#include <linux/sockios.h> /* SIOCOUTQ */
#include <sys/ioctl.h>

#include "net_internal.h"
#include "oc_log.h"

#define OCS_HOUSE_MS 100
#define OCS_CLOSE_GRACE_S 2.0

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

/* A drain ends when no drained viewer is left, or at its deadline, closing what remains. */
static void drain_check(ocs_server_t *srv, double now) {
  int left = 0;
  for (ocs_session_t *s = srv->sessions; s; s = s->next) left += s->drained;
  if (left && now < srv->drain_until) return;
  if (left) oc_log_warn("drain timeout: closing %d viewer(s) still connected", left);
  else oc_log_info("drained: every viewer has left");
  ocs_server_stop(srv); /* closes the drained viewers still connected */
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
          snprintf(why, sizeof why, "no %s within %.1f s", s->proxy_buf ? "PROXY header" : "hello", d->handshake_s);
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
          snprintf(why, sizeof why, "not resumed within %.0f s", d->linger_s);
          ocs_session_let_go(s, why);
        }
        break;
      case OCS_SS_CLOSING:
        if (s->connected && !s->drained && now - s->closing_since > OCS_CLOSE_GRACE_S) ocs_session_close_handle(s);
        break;
      default: break;
    }
  }
  ocs_peer_sweep(srv, now);
  if (srv->draining && !srv->stopping) drain_check(srv, now);
  if (srv->stopping && !srv->sessions && !srv->stepping && !uv_is_closing((uv_handle_t *)&srv->house_timer)) {
    ocs_epoch_close(srv);
    uv_close((uv_handle_t *)&srv->house_timer, NULL);
  }
}

void ocs_house_start(ocs_server_t *srv) {
  uv_timer_init(&srv->loop, &srv->house_timer);
  srv->house_timer.data = srv;
  uv_timer_start(&srv->house_timer, on_house_timer, OCS_HOUSE_MS, OCS_HOUSE_MS);
}
