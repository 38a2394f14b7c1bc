/* fetch.c — one complete state from a server, the simple way (net.h, ocv_fetch): what
 * overcast-view's headless --connect and the benches use. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "net.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_log.h"

typedef struct {
  uint64_t states;
  double last_input; /* when the viewer connection last brought bytes (for the step retry) */
  uint32_t reply_for, reply_status; /* the control connection's last reply */
  int reply_ok;
  char reply_error[256];
} ocv__fetch_t;

static double ocv__now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint64_t ocv__bytes_in(ocv_conn_t *c) {
  ocp_viewer_stats_t s;
  ocp_viewer_stats(ocv_conn_session(c), &s);
  return s.bytes_in;
}

static void ocv__on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  (void)ctx;
  oc_log_info("welcome: scene %s, session %u%s, %s, budget %.1f MiB granted, depth %u", w->name, w->session,
              resumed ? " (resumed)" : "", w->epoch_period > 0 ? "animated by the clock" : "stepped by command",
              (double)w->budget / (1 << 20), w->max_depth);
}

static void ocv__on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  ocv__fetch_t *n = ctx;
  n->states++;
  oc_log_info("epoch %llu: %u nodes, %u bricks (%u received)", (unsigned long long)s->epoch, s->node_count,
              s->brick_count, bricks);
}

static void ocv__on_reply(void *ctx, const ocp_control_t *c) {
  ocv__fetch_t *n = ctx;
  n->reply_for = c->request;
  n->reply_status = (uint32_t)c->status;
  n->reply_ok = c->status == OCP_CODE_OK;
  /* the reply is a JSON object; on refusal its "error" is what matters, shown verbatim */
  snprintf(n->reply_error, sizeof n->reply_error, "%.*s", (int)c->json_len, c->json);
}

int ocv_fetch(const ocv_fetch_desc_t *o, oc_state_t *st, ocp_welcome_t *welcome, oc_camera_pose_t *pose_out, char *why,
              size_t why_len) {
  const oc_camera_pose_t *pose_in = o->pose;
  oc_camera_pose_t pose_local;
  if (!pose_out) pose_out = &pose_local;
  ocv__fetch_t n = {0};
  ocv_conn_t *vc = NULL, *cc = NULL;
  double deadline = ocv__now() + o->timeout_s;
  ocp_viewer_desc_t vd = {.role = OCP_ROLE_VIEWER, .budget = o->budget,
                          .max_depth = (uint8_t)o->max_depth, .width = (uint32_t)o->width,
                          .height = (uint32_t)o->height, .caps = OCP_CAP_ALL, .token = o->token};
  ocp_viewer_events_t ev = {.ctx = &n, .welcome = ocv__on_welcome, .state = ocv__on_state};
  int r = ocv_conn_open(&vc, o->host, o->port, &vd, &ev, o->timeout_s, why, why_len);
  if (r < 0) return r;
  const char *addr = ocv_conn_address(vc);
  r = ocv_conn_wait_ready(vc, deadline - ocv__now(), why, why_len);
  if (r) goto done;
  const ocp_welcome_t *w = ocp_viewer_welcome(ocv_conn_session(vc));
  if (pose_in) {
    *pose_out = *pose_in;
  } else {
    *pose_out = (oc_camera_pose_t){{w->cam_lat, w->cam_lon, w->cam_alt}, w->cam_heading, w->cam_pitch, w->cam_fov};
  }
  oc_camera_t cam = oc_camera_from_pose(*pose_out);
  ocp_camera_t oc = {cam.pos, cam.forward, cam.up, pose_out->fov, (uint32_t)o->width, (uint32_t)o->height};
  if ((r = ocv_conn_camera(vc, &oc)) < 0) {
    snprintf(why, why_len, "%s: the camera was refused (%s)", addr, oc_strerror(r));
    goto done;
  }
  /* the camera goes out before the first step is asked for, so that epoch is planned for it */
  if ((r = ocv_conn_flush(vc, deadline - ocv__now(), why, why_len))) goto done;
  if (o->step) {
    ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = o->token};
    ocp_viewer_events_t cev = {.ctx = &n, .control_reply = ocv__on_reply};
    if ((r = ocv_conn_open(&cc, o->host, o->port, &cd, &cev, deadline - ocv__now(), why, why_len)) < 0) goto done;
    if ((r = ocv_conn_wait_ready(cc, deadline - ocv__now(), why, why_len))) goto done;
  }

  /* Stepping: one step at a time, the next once the previous one's state arrived. A step that
   * reached the server before our ACK of the previous state skips this viewer (it had a state in
   * flight), so a step whose reply came but whose state did not is asked again after a quiet second. */
  uint32_t request = 0;
  int awaiting_reply = 0;
  uint64_t states_at_step = 0;
  double replied_at = 0;
  n.last_input = ocv__now();
  while (n.states < o->epochs) {
    double t = ocv__now();
    if (t >= deadline) {
      if (n.states == 0)
        snprintf(why, why_len, "%s: no state within %g s%s", addr, o->timeout_s,
                 !o->step && w->epoch_period == 0 ? " (the server steps by command: add --step)" : "");
      else
        snprintf(why, why_len, "%s: %llu of %llu states within %g s", addr, (unsigned long long)n.states, (unsigned long long)o->epochs,
                 o->timeout_s);
      r = OC_EIO;
      goto done;
    }
    if (cc) {
      if (awaiting_reply && n.reply_for == request) {
        awaiting_reply = 0;
        replied_at = t;
        if (!n.reply_ok) {
          snprintf(why, why_len, "%s: step refused (%s): %s", addr, ocp_code_text(n.reply_status), n.reply_error);
          r = OC_EIO;
          goto done;
        }
      }
      int again = !awaiting_reply && n.states == states_at_step && request && t - replied_at > 1.0 && t - n.last_input > 1.0;
      if (!awaiting_reply && (request == 0 || n.states > states_at_step || again)) {
        if (again) oc_log_info("step %u brought no state yet: stepping again", request);
        states_at_step = n.states;
        if ((r = ocv_conn_control(cc, ++request, "{\"op\":\"step\",\"epochs\":1}")) < 0) {
          snprintf(why, why_len, "%s: cannot send the step request (%s)", addr, oc_strerror(r));
          goto done;
        }
        awaiting_reply = 1;
      }
    }
    /* a step can outlast the server's idle timeout: say we are still here */
    if (ocv_conn_silence(vc) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(vc);
    if (cc && ocv_conn_silence(cc) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(cc);
    uint64_t before = ocv__bytes_in(vc);
    r = ocv_conn_poll(vc, fmin(deadline - t, cc ? 0.05 : 0.5), why, why_len);
    if (ocv__bytes_in(vc) != before) n.last_input = ocv__now();
    if (r) break;
    if (cc && (r = ocv_conn_poll(cc, 0, why, why_len))) break;
  }
  if (r == 1) { /* closed by the server before enough states: why holds its reason */
    r = OC_EIO;
    goto done;
  }
  if (r < 0) goto done;
  r = oc_state_copy(st, ocp_viewer_state(ocv_conn_session(vc), 0));
  if (r < 0) {
    snprintf(why, why_len, "out of memory for a copy of the state");
    goto done;
  }
  if (welcome) *welcome = *w;
done:
  if (r == 1) r = OC_EIO; /* closed by the server: why holds its reason */
  ocv_conn_close(cc);
  ocv_conn_close(vc);
  return r;
}

