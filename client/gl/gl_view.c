/* gl_view.c — the viewer's frame loop on the GPU (ocv_gl.h, "The viewer's frame loop"): kept states
 * in the store, bounded uploads, previous values and the blend, reprojection. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "interp.h"
#include "oc_err.h"
#include "ocv_gl.h"

struct ocv_gl_view_s {
  ocv_gl_renderer_t *r;
  ocv_gl_view_desc_t d;
  ocv_gl_store_t *store;
  oc_state_t shown;         /* CPU copy of the state shown: the next previous values need it */
  oc_state_t staged[2];     /* the store points at staged[cur] until it is complete */
  int cur, have_shown, have_staged;
  double shown_at;          /* when the shown state became complete; < 0: at the next frame */
  double blend_s;           /* how long its blend from the state before lasts */
  ocv_interp_t ip;
  ocv_gl_prev_t prev;
  int have_prev;
  ocv_gl_history_t *hist;
  int hw, hh;
  GLuint out;               /* the buffer of the last frame */
};

ocv_gl_view_t *ocv_gl_view_create(ocv_gl_renderer_t *r, const ocv_gl_view_desc_t *d, char *why, size_t why_len) {
  if (!r || !d) {
    (void)oc_errorf(0, why, why_len, "gl view: need a renderer and a grant");
    return NULL;
  }
  ocv_gl_view_t *v = calloc(1, sizeof *v);
  if (!v) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  v->r = r;
  v->d = *d;
  if (!v->d.upload_per_frame) v->d.upload_per_frame = 4u << 20;
  /* the store keeps the shown states and stages one more: K states in all, as the budget counts */
  v->store = ocv_gl_store_create(&d->grant, why, why_len);
  if (!v->store) {
    free(v);
    return NULL;
  }
  oc_state_init(&v->shown);
  oc_state_init(&v->staged[0]);
  oc_state_init(&v->staged[1]);
  ocv_interp_init(&v->ip);
  return v;
}

void ocv_gl_view_free(ocv_gl_view_t *v) {
  if (!v) return;
  ocv_gl_store_free(v->store);
  oc_state_free(&v->shown);
  oc_state_free(&v->staged[0]);
  oc_state_free(&v->staged[1]);
  ocv_interp_free(&v->ip);
  if (v->have_prev) ocv_gl_prev_free(&v->prev);
  ocv_gl_history_free(v->hist);
  free(v);
}

int ocv_gl_view_push(ocv_gl_view_t *v, const oc_state_t *s, char *why, size_t why_len) {
  if (!v || !s) return oc_errorf(OC_EINVAL, why, why_len, "gl view: no state");
  int i = 1 - v->cur; /* not referenced by the store: the old staged state stays valid while it unstages it */
  oc_state_free(&v->staged[i]);
  if (oc_state_copy(&v->staged[i], s) < 0) return oc_errorf(OC_ENOMEM, why, why_len, "gl view: out of memory");
  int rc = ocv_gl_store_stage(v->store, &v->staged[i], why, why_len); /* releases the state staged before */
  oc_state_free(&v->staged[v->cur]);
  v->cur = i;
  v->have_staged = rc == 0;
  if (rc < 0) oc_state_free(&v->staged[i]);
  return rc;
}

int ocv_gl_view_staging(const ocv_gl_view_t *v) { return v && v->have_staged; }

/* The staged state is complete: it is shown from now on, blended from the state shown before. */
static int ocv__switch(ocv_gl_view_t *v, double now, char *why, size_t why_len) {
  if (v->have_prev) ocv_gl_prev_free(&v->prev);
  v->have_prev = 0;
  oc_state_t *next = &v->staged[v->cur];
  int rc = ocv_interp_build(&v->ip, v->have_shown ? &v->shown : NULL, next);
  if (rc < 0) return oc_errorf(rc, why, why_len, "gl view: previous values of epoch %llu: %s",
                               (unsigned long long)next->epoch, oc_strerror(rc));
  v->blend_s = v->have_shown ? ocv_interp_blend_seconds(v->d.epoch_period, v->shown.epoch, next->epoch) : 0.0;
  if (v->have_shown && v->d.epoch_period > 0.0) {
    if ((rc = ocv_gl_prev_upload(&v->prev, &v->ip, v->d.animated, why, why_len)) < 0) return rc;
    v->have_prev = 1;
  }
  oc_state_free(&v->shown);
  v->shown = *next; /* the store keeps only the ids of a complete state: the arrays may move */
  oc_state_init(next);
  v->have_shown = 1;
  v->have_staged = 0;
  v->shown_at = now;
  if (v->hist) ocv_gl_history_reset(v->hist); /* the history shows the state before */
  return 0;
}

int ocv_gl_view_frame(ocv_gl_view_t *v, const oc_render_desc_t *desc, double now, int reproject, oc_image_t *img,
                      ocv_gl_view_stats_t *st, char *why, size_t why_len) {
  ocv_gl_view_stats_t s;
  memset(&s, 0, sizeof s);
  if (!v || !desc) return oc_errorf(OC_EINVAL, why, why_len, "gl view: NULL argument");
  ocv_gl_store_stats_t before, after;
  ocv_gl_store_stats(v->store, &before);
  if (v->have_staged) {
    int r = ocv_gl_store_pump(v->store, v->d.upload_per_frame, why, why_len);
    if (r < 0) return r;
    if (r == 1 && (r = ocv__switch(v, now, why, why_len)) < 0) return r;
  }
  ocv_gl_store_stats(v->store, &after);
  s.uploaded_bytes = after.uploaded_bytes - before.uploaded_bytes;
  s.pending = after.pending;
  s.resident_bytes = after.resident_bytes;
  s.bricks = after.used;
  int rc = 0;
  const ocv_gl_state_t *gs = ocv_gl_store_state(v->store, 0);
  if (gs && v->have_shown) {
    s.epoch = v->shown.epoch;
    s.t = v->have_prev ? ocv_interp_param(now, v->shown_at, v->blend_s) : 1.0f;
    ocv_gl_renderer_set_prev(v->r, v->have_prev ? &v->prev : NULL, s.t);
    if (reproject && (!v->hist || v->hw != desc->width || v->hh != desc->height)) {
      ocv_gl_history_free(v->hist);
      v->hist = ocv_gl_history_create(desc->width, desc->height, why, why_len);
      v->hw = desc->width;
      v->hh = desc->height;
      if (!v->hist) rc = OC_ENOMEM;
    }
    if (rc == 0) {
      if (reproject) rc = ocv_gl_render_frame(v->r, v->hist, gs, desc, 1, img, &s.frame, why, why_len);
      else {
        rc = ocv_gl_render_state(v->r, gs, desc, img, why, why_len);
        s.frame.traced = (uint32_t)(desc->width * desc->height);
      }
    }
    ocv_gl_renderer_set_prev(v->r, NULL, 1.0f);
    s.shown = rc == 0;
    if (s.shown) v->out = reproject ? ocv_gl_history_output(v->hist) : ocv_gl_renderer_output(v->r);
  }
  if (st) *st = s;
  return rc;
}

GLuint ocv_gl_view_output(const ocv_gl_view_t *v) { return v ? v->out : 0; }
