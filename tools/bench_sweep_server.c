/* bench_sweep_server.c — `overcast-bench sweep`, server side: one viewer of a fresh world stepped
 * for some epochs (as bench_world.c does), each epoch encoded as the server sends it (the epoch
 * encoder of proto/ocp_epoch.h with deltas, zstd level 3, as bench_wire.c's "delta" variant), and
 * what it cost: process CPU time of ocs_world_step() (plan + produce on every producer thread),
 * wire bytes, the viewer's resident bytes. */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_sweep_int.h"
#include "ocs.h"

static double cpu_seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

void octs_server_out_free(octs_server_out_t *o) {
  if (!o) return;
  oc_state_free(&o->newest);
  oc_state_free(&o->prev);
}

/* The epoch's wire bytes: every frame the encoder emits, EPOCH_BEGIN to EPOCH_END. */
static int encode_epoch(ocp_epoch_enc_t *e, const oc_state_t *s, const oc_state_t *base, const uint32_t *lacking, uint32_t n,
                        oc_buf_t *buf, uint64_t *bytes) {
  buf->len = 0;
  int r = ocp_epoch_enc_begin(e, s, base, lacking, n);
  while (r >= 0) {
    r = ocp_epoch_enc_next(e, OCP_VERSION_MAX, buf);
    if (r == 0) break;
  }
  if (r < 0 || buf->err) return r < 0 ? r : OC_ENOMEM;
  *bytes = buf->len;
  return 0;
}

int octs_server_run(const oc_scene_t *sc, const octs_server_desc_t *d, oc_camera_pose_t pose, octs_server_out_t *out,
                    void (*progress)(void *ctx, int epoch, int epochs), void *ctx, char *why, size_t why_len) {
  memset(out, 0, sizeof *out);
  oc_state_init(&out->newest);
  oc_state_init(&out->prev);
  ocs_world_desc_t wd = {.threads = d->threads, .cache_bytes = 1ull << 30, .time = d->time, .exact_filter = d->exact_filter};
  ocs_world_t *w = NULL;
  int r = ocs_world_create(&w, sc, &wd, why, why_len);
  if (r < 0) return r;
  ocs_viewer_t *v = NULL;
  ocs_plan_desc_t req = {.budget = d->budget, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .max_depth = d->max_depth,
                         .split_fraction = d->split_fraction, .reserve = d->reserve};
  ocp_epoch_enc_t *enc = NULL;
  ocp_enc_desc_t ed = {.level = OCP_LEVEL_DEFAULT, .deltas = 1};
  oc_buf_t buf = {0};
  oc_state_t base; /* the state the viewer held before this epoch: the base of the records' difference */
  oc_state_init(&base);
  if ((r = ocs_world_add_viewer(w, &req, &v, NULL, why, why_len)) < 0) goto out;
  if ((r = ocp_epoch_enc_create(&enc, &ed)) < 0) {
    snprintf(why, why_len, "epoch encoder: %s", oc_strerror(r));
    goto out;
  }
  out->animated = ocs_field_animated(ocs_world_field(w));
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, d->plan_w, d->plan_h};
  if ((r = ocs_viewer_set_view(v, &view)) < 0) {
    snprintf(why, why_len, "invalid view for the planner");
    goto out;
  }
  double cpu_sum = 0.0, wall_sum = 0.0, wire_sum = 0.0;
  for (int e = 0; e < d->epochs; e++) {
    double c0 = cpu_seconds(), t0 = oct_now();
    r = ocs_world_step(w);
    double c1 = cpu_seconds(), t1 = oct_now();
    ocs_epoch_out_t o;
    if (r < 0 || (r = ocs_viewer_output(v, &o)) < 0) {
      snprintf(why, why_len, "epoch %d: %s", e, oc_strerror(r));
      goto out;
    }
    uint64_t bytes = 0;
    if ((r = encode_epoch(enc, o.state, base.node_count ? &base : NULL, o.lacking, o.nlacking, &buf, &bytes)) < 0) {
      snprintf(why, why_len, "epoch %d: encoding failed: %s", e, oc_strerror(r));
      goto out;
    }
    cpu_sum += c1 - c0;
    wall_sum += t1 - t0;
    wire_sum += (double)bytes;
    out->cpu_ms_last = 1e3 * (c1 - c0);
    out->wire_last = (double)bytes;
    out->bricks_sent += o.nlacking;
    if ((r = oc_state_copy(&base, o.state)) < 0) {
      snprintf(why, why_len, "out of memory");
      goto out;
    }
    ocs_viewer_ack(v, o.state->epoch);
    if (progress) progress(ctx, e + 1, d->epochs);
  }
  out->cpu_ms_mean = 1e3 * cpu_sum / d->epochs;
  out->wall_ms_mean = 1e3 * wall_sum / d->epochs;
  out->wire_mean = wire_sum / d->epochs;
  ocs_viewer_stats_t vs;
  ocs_viewer_stats(v, &vs);
  out->resident = vs.resident_bytes;
  const oc_state_t *h0 = ocs_viewer_held(v, 0), *h1 = ocs_viewer_held(v, 1);
  if (!h0 || oc_state_copy(&out->newest, h0) < 0 || (h1 && d->epochs > 1 && oc_state_copy(&out->prev, h1) < 0)) {
    r = OC_ENOMEM;
    snprintf(why, why_len, "out of memory (or no state)");
    goto out;
  }
  r = 0;
out:
  oc_state_free(&base);
  oc_buf_free(&buf);
  ocp_epoch_enc_free(enc);
  ocs_world_free(w);
  if (r < 0) octs_server_out_free(out);
  return r;
}
