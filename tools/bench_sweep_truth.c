/* bench_sweep_truth.c — `overcast-bench sweep`, the error against a Monte Carlo truth on analytic
 * scenes: once per view, the kernel of `overcast-bench truth` (bench_mc.c: every scattering order,
 * the renderer's phase function and albedo) traces a small image through a state voxelized from the
 * analytic sources as that bench voxelizes them — not through the swept states, so the truth does
 * not depend on the knobs. The light is the truth's (oct_truth_light: a delta sun of irradiance 1,
 * OC_BG_CONSTANT with radiance 0, no atmosphere, no planet): the sweep renders each setting once
 * more in that light for this column, since its own images carry the atmosphere's sky and ground,
 * which the truth does not trace. A truth pixel covers kx × ky sweep pixels; its paths go round
 * their centre rays, so it is the box average the sweep's image is reduced by. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench_mc.h"
#include "bench_sweep_int.h"
#include "ocs.h"
#include "truth.h" /* oct_truth_case_t, oct_truth_score */

struct octs_truth_s {
  oct_truth_case_t c; /* w, h, mean, mean_se, L, se: what oct_truth_score reads */
  int kx, ky;
};

typedef struct {
  const oct_mc_medium_t *m;
  oct_mc_params_t prm;
  oc_camera_t cam;
  const octs_truth_desc_t *d;
  int kx, ky;
  oct_truth_case_t *c;
  oct_mc_stats_t *stats; /* per thread */
} truth_job_t;

static void truth_row(void *ctx, int y, int thread) {
  truth_job_t *j = ctx;
  const int n = j->kx * j->ky;
  for (int x = 0; x < j->d->w; x++) {
    size_t i = (size_t)y * (size_t)j->d->w + (size_t)x;
    oct_mc_rng_t rng;
    oct_mc_rng_seed(&rng, 1, i);
    double s1 = 0.0, s2 = 0.0;
    for (long k = 0; k < j->d->paths; k++) {
      int sub = (int)(k % n);
      oc_dvec3 dir = oc_camera_ray(&j->cam, j->d->full_w, j->d->full_h, x * j->kx + sub % j->kx, y * j->ky + sub / j->kx);
      oct_mc_path_t p;
      oct_mc_trace(j->m, &j->prm, j->cam.pos, dir, &rng, &p, &j->stats[thread]);
      s1 += p.sun;
      s2 += p.sun * p.sun;
    }
    oct_mc_mean_se(s1, s2, (double)j->d->paths, &j->c->L[i], &j->c->se[i]);
  }
}

octs_truth_t *octs_truth_make(const oc_scene_t *sc, oc_camera_pose_t pose, const octs_truth_desc_t *d, char *why,
                              size_t why_len) {
  if (d->w <= 0 || d->h <= 0 || d->full_w % d->w || d->full_h % d->h || d->paths < 2) {
    snprintf(why, why_len, "the image size %dx%d is not a multiple of the truth's %dx%d", d->full_w, d->full_h, d->w, d->h);
    return NULL;
  }
  octs_truth_t *t = calloc(1, sizeof *t);
  size_t n = (size_t)d->w * (size_t)d->h;
  int threads = d->threads > 0 ? d->threads : 1;
  oct_mc_stats_t *stats = calloc((size_t)threads, sizeof *stats);
  if (!t || !stats || !(t->c.L = calloc(n, sizeof *t->c.L)) || !(t->c.se = calloc(n, sizeof *t->c.se))) {
    snprintf(why, why_len, "out of memory");
    free(stats);
    octs_truth_free(t);
    return NULL;
  }
  t->c.w = d->w, t->c.h = d->h, t->kx = d->full_w / d->w, t->ky = d->full_h / d->h;
  oc_camera_t cam = oc_camera_from_pose(pose);
  oc_state_t st;
  oc_state_init(&st);
  /* As `overcast-bench truth`, refined for the camera, a voxel ≤ 2 pixels — of a viewport of twice
   * the sweep's rows, at least 90: at 18 rows the sphere's sunlit rim (at τ 200 nearly all the light
   * comes from its first metres) was a few coarse voxels, the truth of another medium (image mean
   * up to 10 % above the converged one); from 90 rows to 360 the image means of the sphere at τ 20 and 200
   * and of the slab move by ≤ 1.1 % (the slab's voxelization costs 11 s at 90 rows, 55 s at 360). */
  ocs_scene_voxelize_desc_t vd = {cam, d->full_h * 2 > 90 ? d->full_h * 2 : 90, 2.0, 16, 0, threads};
  oct_mc_medium_t m = {0};
  oc_scene_t sigma_only = *sc; /* the Monte Carlo reads σt alone: no τ channel to filter */
  sigma_only.features &= ~(1u << OC_FEATURE_SHADOWS);
  int rc = ocs_scene_voxelize(&st, &sigma_only, &vd, why, why_len);
  if (rc >= 0 && oct_mc_medium_state(&m, &st) < 0) rc = oc_errorf(OC_ENOMEM, why, why_len, "out of memory");
  if (rc >= 0) {
    truth_job_t j = {.m = &m, .cam = cam, .d = d, .kx = t->kx, .ky = t->ky, .c = &t->c, .stats = stats};
    j.prm.albedo = sc->optics.albedo;
    j.prm.phase.kind = OCT_MC_PHASE_HG_DRAINE;
    j.prm.sun = st.sun_dir;
    j.prm.sun_irradiance = 1.0; /* oct_truth_light's sun */
    j.prm.max_bounces = 1000000; /* `overcast-bench truth`'s defaults */
    j.prm.sun_lobe = 0.02;
    oc_parallel(d->h, threads, truth_row, &j);
    oct_mc_stats_t sum = {0};
    for (int i = 0; i < threads; i++) sum.truncated += stats[i].truncated, sum.majorant_violations += stats[i].majorant_violations;
    if (sum.truncated || sum.majorant_violations)
      rc = oc_errorf(OC_ERANGE, why, why_len, "truth: %llu truncated paths, %llu majorant violations",
                     (unsigned long long)sum.truncated, (unsigned long long)sum.majorant_violations);
    double var = 0.0, s = 0.0;
    for (size_t i = 0; i < n; i++) s += t->c.L[i], var += t->c.se[i] * t->c.se[i];
    t->c.mean = s / (double)n, t->c.mean_se = sqrt(var) / (double)n;
  }
  oct_mc_medium_free(&m);
  oc_state_free(&st);
  free(stats);
  if (rc < 0) {
    octs_truth_free(t);
    return NULL;
  }
  return t;
}

void octs_truth_free(octs_truth_t *t) {
  if (!t) return;
  oct_truth_case_free(&t->c);
  free(t);
}

int octs_truth_score(const octs_truth_t *t, const oc_image_t *img, octs_truth_err_t *e) {
  oc_image_t small = {0};
  if (oc_image_alloc(&small, t->c.w, t->c.h) < 0) return OC_ENOMEM;
  const double inv = 1.0 / (double)(t->kx * t->ky);
  for (int y = 0; y < t->c.h; y++)
    for (int x = 0; x < t->c.w; x++)
      for (int ch = 0; ch < 4; ch++) {
        double s = 0.0;
        for (int j = 0; j < t->ky; j++)
          for (int i = 0; i < t->kx; i++) s += img->px[4 * ((size_t)(y * t->ky + j) * (size_t)img->w + (size_t)(x * t->kx + i)) + ch];
        small.px[4 * ((size_t)y * (size_t)t->c.w + (size_t)x) + ch] = (float)(s * inv);
      }
  oct_truth_score_t s;
  int rc = oct_truth_score(&t->c, &small, &s);
  oc_image_free(&small);
  if (rc < 0) return rc;
  e->rel = s.rel, e->rmse8 = s.rmse8, e->noise8 = s.noise8, e->truth_mean = t->c.mean;
  return 0;
}
