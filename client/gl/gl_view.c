/* gl_view.c — the viewer's frame loop on the GPU (ocv_gl.h, "The viewer's frame loop"): kept states
 * in the store, bounded uploads, previous values and the blend, reprojection. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

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
  int level;                /* the frame-time target's scale: divisor 1 << level */
  int over, under;          /* frames in a row over the target, or fitting it one level finer */
  int count_last;           /* the last frame counts for the controller (a state shown, no switch) */
  int rows;                 /* the last frame's height: the coarsest level allowed follows from it */
};

/* The coarsest level that keeps ≥ OCV_GL_SCALE_MIN_ROWS rows of `rows` (0 when none does). */
static int ocv__max_level(int rows) {
  int l = 0;
  while ((1 << (l + 1)) <= OCV_GL_SCALE_MAX && rows / (1 << (l + 1)) >= OCV_GL_SCALE_MIN_ROWS) l++;
  return l;
}

static double ocv__now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

void ocv_gl_view_trace_size(int w, int h, int scale, int *tw, int *th) {
  if (scale < 1) scale = 1;
  int a = (w + scale / 2) / scale, b = (h + scale / 2) / scale;
  *tw = a > 0 ? a : 1;
  *th = b > 0 ? b : 1;
}

int ocv_gl_view_scale(const ocv_gl_view_t *v, int h) {
  if (!v) return 1;
  int top = ocv__max_level(h);
  return 1 << (v->level < top ? v->level : top);
}

void ocv_gl_view_frame_time(ocv_gl_view_t *v, double ms) {
  if (!v || !(v->d.frame_ms > 0.0) || !v->count_last || !(ms >= 0.0)) return;
  v->count_last = 0;
  double target = v->d.frame_ms;
  int top = ocv__max_level(v->rows);
  v->over = ms > 1.25 * target ? v->over + 1 : 0;
  v->under = ms * 4.0 <= 0.6 * target && v->level > 0 ? v->under + 1 : 0;
  if ((v->over >= 2 || ms > 3.0 * target) && v->level < top) {
    /* as many levels coarser as bring the predicted time (∝ pixels) under 0.7 × the target */
    while (v->level < top && ms > 0.7 * target) {
      v->level++;
      ms /= 4.0;
    }
    v->over = v->under = 0;
  } else if (v->under >= 3) {
    while (v->level > 0 && ms * 4.0 <= 0.6 * target) {
      v->level--;
      ms *= 4.0;
    }
    v->over = v->under = 0;
  }
}

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
  if (!(v->d.frame_ms >= 0.0 && v->d.frame_ms < 1e7)) {
    (void)oc_errorf(0, why, why_len, "gl view: frame-time target %g ms is not in [0, 1e7)", v->d.frame_ms);
    free(v);
    return NULL;
  }
  if (v->d.frame_ms > 0.0) /* the first frame at the coarsest scale its size allows */
    while ((1 << (v->level + 1)) <= OCV_GL_SCALE_MAX) v->level++;
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
  /* the history shows the state before: blended in from it, the picture goes on from the history
   * (clamped to what is traced now), else it starts again */
  if (v->hist && v->have_prev) ocv_gl_history_refresh(v->hist);
  else if (v->hist) ocv_gl_history_reset(v->hist);
  return 0;
}

int ocv_gl_view_frame(ocv_gl_view_t *v, const oc_render_desc_t *desc, double now, int reproject, oc_image_t *img,
                      ocv_gl_view_stats_t *st, char *why, size_t why_len) {
  ocv_gl_view_stats_t s;
  memset(&s, 0, sizeof s);
  if (!v || !desc) return oc_errorf(OC_EINVAL, why, why_len, "gl view: NULL argument");
  oc_render_desc_t dd = *desc; /* at the traced size */
  if (v->d.frame_ms > 0.0) {
    int top = ocv__max_level(desc->height);
    if (v->level > top) v->level = top;
    v->rows = desc->height;
    ocv_gl_view_trace_size(desc->width, desc->height, 1 << v->level, &dd.width, &dd.height);
    if (img && (img->w != dd.width || img->h != dd.height))
      return oc_errorf(OC_EINVAL, why, why_len, "gl view: the image is %dx%d, the frame is traced at %dx%d", img->w,
                       img->h, dd.width, dd.height);
    desc = &dd;
  }
  ocv_gl_store_stats_t before, after;
  ocv_gl_store_stats(v->store, &before);
  if (v->have_staged) {
    int r;
    if (v->d.frame_ms > 0.0) { /* steps while they took less than a quarter of the frame-time target */
      uint64_t step = v->d.upload_per_frame / 16 ? v->d.upload_per_frame / 16 : 1;
      double t0 = ocv__now_ms();
      do r = ocv_gl_store_pump(v->store, step, why, why_len);
      while (r == 0 && ocv_gl_view_staging(v) && ocv__now_ms() - t0 < 0.25 * v->d.frame_ms);
    } else
      r = ocv_gl_store_pump(v->store, v->d.upload_per_frame, why, why_len);
    if (r < 0) return r;
    s.switched = r == 1;
    if (s.switched && (r = ocv__switch(v, now, why, why_len)) < 0) return r;
  }
  ocv_gl_store_stats(v->store, &after);
  s.uploaded_bytes = after.uploaded_bytes - before.uploaded_bytes;
  s.pending = after.pending;
  s.resident_bytes = after.resident_bytes;
  s.bricks = after.used;
  int rc = 0;
  const ocv_gl_state_t *gs = ocv_gl_store_state(v->store, 0);
  s.scale = 1 << v->level;
  s.trace_w = desc->width;
  s.trace_h = desc->height;
  v->count_last = 0;
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
    ocv_gl_renderer_set_shadow_age(v->r, v->d.frame_ms > 0.0 ? OCV_GL_SHADOW_MAX_AGE_S : 0.0, now);
    ocv_gl_renderer_set_shadow_slices(v->r, v->d.frame_ms > 0.0 ? OCV_GL_SHADOW_SLICES : 1);
    if (rc == 0) {
      if (reproject) rc = ocv_gl_render_frame(v->r, v->hist, gs, desc, 1, img, &s.frame, why, why_len);
      else {
        rc = ocv_gl_render_state(v->r, gs, desc, img, why, why_len);
        s.frame.traced = (uint32_t)(desc->width * desc->height);
      }
    }
    ocv_gl_renderer_set_prev(v->r, NULL, 1.0f);
    ocv_gl_renderer_set_shadow_age(v->r, 0.0, now);
    ocv_gl_renderer_set_shadow_slices(v->r, 1);
    s.shown = rc == 0;
    if (s.shown) v->out = reproject ? ocv_gl_history_output(v->hist) : ocv_gl_renderer_output(v->r);
    v->count_last = s.shown && !s.switched;
  }
  if (st) *st = s;
  return rc;
}

GLuint ocv_gl_view_output(const ocv_gl_view_t *v) { return v ? v->out : 0; }
