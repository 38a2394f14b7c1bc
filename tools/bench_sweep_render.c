/* bench_sweep_render.c — `overcast-bench sweep`, the renderers: the CPU reference (common/oc_render.h,
 * timed by process CPU time over its threads) or the GL compute renderer (client/gl/ocv_gl.h) on a
 * headless EGL context, timed by GPU timer queries on a GPU and by wall clock (dispatch and
 * read-back) on Mesa's llvmpipe, whose timer queries read about 0 for compute dispatches.
 *
 * The CPU reference's time (`cpu-ref`) is the process CPU time of the render, summed over its threads:
 * on a shared machine other jobs inflate wall time, not CPU time (the wall time is kept beside it).
 *
 * Frame sequences (GL only):
 *   reprojection  `frames` frames with the camera turning `motion` degrees of heading per frame and
 *                 ending at the view: frame 0 traces every pixel, frames 1.. one pixel in 16 and
 *                 reproject the rest (ocv_gl_render_frame); the last frame is the image, the mean of
 *                 frames 1.. the time;
 *   interpolation the newest state blended with the previous one at t (ocv_gl_renderer_set_prev with
 *                 client/interp.h's previous values), as a viewer shows it part-way through an epoch. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_sweep_int.h"
#include "truth.h" /* oct_truth_light */
#include "ocv.h"

struct octs_renderer_s {
  int gl;
  octs_render_desc_t d;
  const oc_state_t *newest, *prev;
  int animated;
#ifdef OC_HAVE_GL
  ocv_gl_context_t *ctx;
  ocv_gl_renderer_t *r;
  ocv_gl_history_t *hs;
  ocv_gl_state_t gs;
  int have_gs;
  ocv_interp_t ip;
  ocv_gl_prev_t gp;
  int have_gp;
  int gpu_timer; /* a real GPU: timer queries */
#endif
};

octs_renderer_t *octs_renderer_open(int gl, const octs_render_desc_t *d, char *info, size_t info_cap, char *why,
                                    size_t why_len) {
  octs_renderer_t *r = calloc(1, sizeof *r);
  if (!r) {
    snprintf(why, why_len, "out of memory");
    return NULL;
  }
  r->gl = gl;
  r->d = *d;
  if (!gl) {
    snprintf(info, info_cap, "CPU reference renderer, %d thread%s", d->threads, d->threads == 1 ? "" : "s");
    return r;
  }
#ifdef OC_HAVE_GL
  ocv_interp_init(&r->ip);
  if (!(r->ctx = ocv_gl_context_init(why, why_len)) || !(r->r = ocv_gl_renderer_create(why, why_len)) ||
      !(r->hs = ocv_gl_history_create(d->width, d->height, why, why_len))) {
    octs_renderer_close(r);
    return NULL;
  }
  char desc[400];
  ocv_gl_context_describe(r->ctx, desc, sizeof desc);
  r->gpu_timer = !strstr(desc, "llvmpipe") && !strstr(desc, "softpipe") && !strstr(desc, "lavapipe");
  snprintf(info, info_cap, "GL compute renderer: %s", desc);
  return r;
#else
  snprintf(why, why_len, "this build has no GL renderer (libepoxy was not found)");
  free(r);
  return NULL;
#endif
}

void octs_renderer_close(octs_renderer_t *r) {
  if (!r) return;
#ifdef OC_HAVE_GL
  if (r->gl) {
    if (r->have_gp) ocv_gl_prev_free(&r->gp);
    if (r->have_gs) ocv_gl_state_free(&r->gs);
    ocv_interp_free(&r->ip);
    ocv_gl_history_free(r->hs);
    ocv_gl_renderer_free(r->r);
    ocv_gl_context_free(r->ctx);
  }
#endif
  free(r);
}

const char *octs_renderer_timer(const octs_renderer_t *r) {
#ifdef OC_HAVE_GL
  if (r->gl) return r->gpu_timer ? "gpu-timer" : "llvmpipe-wall";
#else
  (void)r;
#endif
  return "cpu-ref";
}

int octs_renderer_set_states(octs_renderer_t *r, const oc_state_t *newest, const oc_state_t *prev, int animated, char *why,
                             size_t why_len) {
  r->newest = newest;
  r->prev = prev && prev->node_count ? prev : NULL;
  r->animated = animated;
#ifdef OC_HAVE_GL
  if (r->gl) {
    if (r->have_gp) ocv_gl_prev_free(&r->gp);
    if (r->have_gs) ocv_gl_state_free(&r->gs);
    r->have_gp = r->have_gs = 0;
    memset(&r->gs, 0, sizeof r->gs);
    int rc = ocv_gl_state_upload(&r->gs, newest, why, why_len);
    if (rc < 0) return rc;
    r->have_gs = 1;
    if (r->prev) {
      if ((rc = ocv_interp_build(&r->ip, r->prev, newest)) < 0)
        return oc_errorf(rc, why, why_len, "previous values: %s", oc_strerror(rc));
      memset(&r->gp, 0, sizeof r->gp);
      if ((rc = ocv_gl_prev_upload(&r->gp, &r->ip, animated, why, why_len)) < 0) return rc;
      r->have_gp = 1;
    }
  }
#endif
  (void)why;
  (void)why_len;
  return 0;
}

/* The render description of the scene's optics and features (as overcast-view makes it). */
static oc_render_desc_t make_desc(const octs_renderer_t *r, oc_camera_pose_t pose, const octs_render_knobs_t *k) {
  const oc_scene_t *sc = r->d.scene;
  oc_render_desc_t d = {0};
  d.width = r->d.width;
  d.height = r->d.height;
  d.camera = oc_camera_from_pose(pose);
  d.step_factor = k->step_factor;
  d.ms_octaves = k->ms_octaves;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)sc->optics.albedo;
  d.albedo_zero = sc->optics.albedo == 0.0;
  d.atmo = r->d.atmo;
  d.threads = r->d.threads;
  d.flags = (r->d.atmo ? 0 : OC_RF_NO_ATMOSPHERE) | (oc_scene_has(sc, OC_FEATURE_PLANET_SURFACE) ? 0 : OC_RF_NO_PLANET);
  if (k->truth_light) oct_truth_light(&d, 0.0);
  return d;
}

static double cpu_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

int octs_render(octs_renderer_t *r, oc_camera_pose_t pose, const octs_render_knobs_t *k, oc_image_t *img, octs_times_t *tm,
                char *why, size_t why_len) {
  oc_render_desc_t d = make_desc(r, pose, k);
  octs_times_t best = {INFINITY, INFINITY, INFINITY};
  if (!r->gl) {
    if (k->reproject || k->interp) return oc_errorf(OC_EINVAL, why, why_len, "reprojection and interpolation need the GL renderer");
    for (int i = 0; i < r->d.repeat; i++) {
      oc_render_stats_t rs = {0};
      double t0 = oct_now(), c0 = cpu_now();
      if (oc_render_state(r->newest, &d, img, &rs) < 0) return oc_errorf(OC_EINVAL, why, why_len, "CPU render failed");
      double c = cpu_now() - c0, t = oct_now() - t0;
      if (rs.nonfinite) return oc_errorf(OC_ERANGE, why, why_len, "%llu non-finite pixels", (unsigned long long)rs.nonfinite);
      best.wall = fmin(best.wall, 1e3 * t);
      best.cpu = fmin(best.cpu, 1e3 * c);
    }
    best.ms = best.cpu; /* cpu-ref: CPU time of every render thread, insensitive to other jobs */
    *tm = best;
    return 0;
  }
#ifdef OC_HAVE_GL
  int rc;
  if (k->interp && !r->have_gp)
    return oc_errorf(OC_EINVAL, why, why_len, "interpolation needs two states (--epochs 2 or more)");
  ocv_gl_renderer_set_prev(r->r, k->interp ? &r->gp : NULL, k->interp ? r->d.interp_t : 1.0f);
  for (int i = 0; i < r->d.repeat; i++) {
    double wall = 0.0, cpu = 0.0, gpu = 0.0; /* s per frame */
    if (!k->reproject) {
      double t0 = oct_now(), c0 = cpu_now();
      if ((rc = ocv_gl_render_state(r->r, &r->gs, &d, img, why, why_len)) < 0) goto out;
      wall = oct_now() - t0, cpu = cpu_now() - c0;
      ocv_gl_renderer_timings(r->r, &gpu, NULL);
      gpu *= 1e-3;
    } else {
      ocv_gl_history_reset(r->hs);
      for (int f = 0; f < r->d.frames; f++) {
        oc_camera_pose_t p = pose;
        p.heading += r->d.motion * (double)(f - (r->d.frames - 1));
        d.camera = oc_camera_from_pose(p);
        d.frame = (uint32_t)f;
        ocv_gl_frame_stats_t fs;
        double t0 = oct_now(), c0 = cpu_now();
        if ((rc = ocv_gl_render_frame(r->r, r->hs, &r->gs, &d, f > 0, img, &fs, why, why_len)) < 0) goto out;
        double t = oct_now() - t0, c = cpu_now() - c0, trace = -1.0, rep = -1.0;
        ocv_gl_renderer_timings(r->r, &trace, &rep);
        if (f > 0) wall += t, cpu += c, gpu += 1e-3 * (trace + rep);
      }
      wall /= (double)(r->d.frames - 1), cpu /= (double)(r->d.frames - 1), gpu /= (double)(r->d.frames - 1);
    }
    best.wall = fmin(best.wall, 1e3 * wall);
    best.cpu = fmin(best.cpu, 1e3 * cpu);
    best.ms = fmin(best.ms, 1e3 * (r->gpu_timer ? gpu : wall));
  }
  *tm = best;
  rc = 0;
out:
  ocv_gl_renderer_set_prev(r->r, NULL, 1.0f);
  return rc;
#else
  return oc_errorf(OC_EINVAL, why, why_len, "this build has no GL renderer");
#endif
}
