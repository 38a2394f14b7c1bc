/* bench_truth.c — `overcast-bench truth`: a Monte Carlo ground truth for small views, and the
 * absolute error of the real-time model against it.
 *
 * The truth traces every scattering order with the kernel of bench_mc.c through the very state the
 * CPU reference renderer draws (an analytic scene voxelized as `overcast-bench render` does), with
 * the renderer's phase function and albedo, lit as the renderer lights it with a constant
 * background (OC_BG_CONSTANT): a delta sun of irradiance 1 and no atmosphere, plus a uniform
 * background radiance B seen by every path that leaves the cloud. The renderer approximates the
 * same light with the τ channel and the multiple-scattering octaves; their difference, beside the
 * Monte Carlo standard error, is the model's error. Before that, the kernel itself is checked on a
 * homogeneous slab against a published result (van de Hulst 1980), the exact single-scattering
 * closed form and energy conservation. Bench only: minutes of CPU, never in CI. */
#include <math.h>
#include <stddef.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_mc.h"
#include "ocs.h"
#include "truth.h" /* oct_truth_source_length, oct_truth_source_sigma */
#include "optics.h" /* ocg_phase_hg_draine for the sampler check */

#define OCT_TRUTH_MAX_TAUS 16
#define OCT_TWO_PI 6.283185307179586477
#define OCT_TRUTH_EXPOSURE 10.0f /* the exposure every bench tone-maps with */

static void oct__stats_add(oct_mc_stats_t *sum, const oct_mc_stats_t *s) {
#define OCT__STATS_ADD(name) sum->name += s->name;
  OCT_MC_STATS_FIELDS(OCT__STATS_ADD)
#undef OCT__STATS_ADD
}


/* ---- Transport checks on a homogeneous slab -----------------------------------------------------------
 * Photons enter the slab 0 ≤ z ≤ τ (σt = 1) at the top, at normal incidence, and are followed with
 * oct_mc_trace() until they leave: upward is reflectance, downward transmittance. */

#define OCT_SLAB_CHUNKS 256

typedef struct {
  double r1, r2, t1, t2;   /* all orders: sums of weights and squares */
  double rs1, rs2, ts1, ts2; /* single scattering only (escapes after exactly one collision) */
} oct__slab_sums_t;

typedef struct {
  oct_mc_medium_t medium;
  oct_mc_params_t prm;
  long photons;
  uint64_t seed, stream0;
  oct__slab_sums_t chunk[OCT_SLAB_CHUNKS];
  oct_mc_stats_t stats[256];
} oct__slab_job_t;

static void oct__slab_chunk(void *ctx, int c, int thread) {
  oct__slab_job_t *job = ctx;
  long lo = job->photons * c / OCT_SLAB_CHUNKS, hi = job->photons * (c + 1) / OCT_SLAB_CHUNKS;
  oct_mc_rng_t rng;
  oct_mc_rng_seed(&rng, job->seed, job->stream0 + (uint64_t)c);
  oct__slab_sums_t s = {0};
  const oc_dvec3 top = oc_dv3(0.0, 0.0, job->medium.slab_tau), down = oc_dv3(0.0, 0.0, -1.0);
  for (long i = lo; i < hi; i++) {
    oct_mc_path_t path;
    oct_mc_trace(&job->medium, &job->prm, top, down, &rng, &path, &job->stats[thread]);
    double w = path.escape_weight;
    int up = path.escape_dir.z > 0.0, single = path.bounces == 1;
    double r = up ? w : 0.0, t = up ? 0.0 : w;
    s.r1 += r;
    s.r2 += r * r;
    s.t1 += t;
    s.t2 += t * t;
    if (single) {
      s.rs1 += r;
      s.rs2 += r * r;
      s.ts1 += t;
      s.ts2 += t * t;
    }
  }
  job->chunk[c] = s;
}

typedef struct {
  double R, R_se, T, T_se, Rs, Rs_se, Ts, Ts_se, RT;
  oct_mc_stats_t stats;
} oct__slab_result_t;

static void oct__slab_run(double tau, double albedo, oct_mc_phase_t phase, long photons, uint64_t seed, uint64_t stream0,
                          int threads, oct__slab_result_t *res) {
  static oct__slab_job_t job; /* large; one check at a time */
  memset(&job, 0, sizeof job);
  job.medium.kind = OCT_MC_MEDIUM_SLAB;
  job.medium.slab_tau = tau;
  job.prm.albedo = albedo;
  job.prm.phase = phase;
  job.prm.max_bounces = 100000000;
  job.photons = photons;
  job.seed = seed;
  job.stream0 = stream0;
  oc_parallel(OCT_SLAB_CHUNKS, threads, oct__slab_chunk, &job);
  oct__slab_sums_t s = {0};
  for (int c = 0; c < OCT_SLAB_CHUNKS; c++) { /* in chunk order: deterministic */
    s.r1 += job.chunk[c].r1;
    s.r2 += job.chunk[c].r2;
    s.t1 += job.chunk[c].t1;
    s.t2 += job.chunk[c].t2;
    s.rs1 += job.chunk[c].rs1;
    s.rs2 += job.chunk[c].rs2;
    s.ts1 += job.chunk[c].ts1;
    s.ts2 += job.chunk[c].ts2;
  }
  memset(res, 0, sizeof *res);
  double n = (double)photons;
  oct_mc_mean_se(s.r1, s.r2, n, &res->R, &res->R_se);
  oct_mc_mean_se(s.t1, s.t2, n, &res->T, &res->T_se);
  oct_mc_mean_se(s.rs1, s.rs2, n, &res->Rs, &res->Rs_se);
  oct_mc_mean_se(s.ts1, s.ts2, n, &res->Ts, &res->Ts_se);
  res->RT = res->R + res->T; /* exactly 1 per photon at albedo 1: checked without an SE */
  for (int i = 0; i < threads; i++) oct__stats_add(&res->stats, &job.stats[i]);
}

/* Composite Simpson on [a, b] with n (even) intervals. */
static double oct__simpson(double (*f)(double x, const double *p), const double *p, double a, double b, int n) {
  double h = (b - a) / n, s = f(a, p) + f(b, p);
  for (int i = 1; i < n; i++) s += (i & 1 ? 4.0 : 2.0) * f(a + i * h, p);
  return s * h / 3.0;
}

/* Single scattering of a normally incident beam by an isotropic slab of optical thickness τ (one
 * collision at depth z with density e^{-z}, scattered with 1/(4π) per sr, escaping along cosine μ
 * with e^{-z/μ} or e^{-(τ-z)/μ}; the z integral done in closed form):
 *   R1 = (a/2) ∫0..1 μ/(1+μ) (1 − e^{−τ(1+1/μ)}) dμ,
 *   T1 = (a/2) ∫0..1 μ e^{−τ} (1 − e^{−τ(1−μ)/μ}) / (1−μ) dμ   (→ τ e^{−τ} at μ = 1). */
static double oct__r1_integrand(double mu, const double *p) {
  if (mu <= 0.0) return 0.0;
  return mu / (1.0 + mu) * -expm1(-p[0] * (1.0 + 1.0 / mu));
}

static double oct__t1_integrand(double mu, const double *p) {
  double tau = p[0];
  if (mu <= 0.0) return 0.0;
  if (mu >= 1.0) return tau * exp(-tau);
  return mu * exp(-tau) * -expm1(-tau * (1.0 - mu) / mu) / (1.0 - mu);
}

/* k-th moment of the cloud phase function, 2π ∫ μ^k p(μ) dμ, by Simpson in s = ln(1 − μ) so that the
 * forward peak (width ≈ 1 − g_HG ≈ 0.012) is resolved; the sliver 1 − μ < 1e-12 adds p(1)·2π·1e-12. */
static double oct__moment_integrand(double s, const double *p) {
  double x = exp(s), mu = 1.0 - x;
  return OCT_TWO_PI * pow(mu, p[0]) * ocg_phase_hg_draine((float)mu) * x;
}

static double oct__phase_moment(int k) {
  const double pk = k;
  return oct__simpson(oct__moment_integrand, &pk, log(1e-12), log(2.0), 400000) +
         OCT_TWO_PI * ocg_phase_hg_draine(1.0f) * 1e-12;
}

typedef struct {
  int run, failed;
} oct__verdicts_t;

/* One line of the checks table, with the verdict: |measured − reference| ≤ 3 SE + tolerance. */
static void oct__check_row(oct__verdicts_t *v, const char *name, const char *what, double m, double se, double ref,
                           double tol, const char *source) {
  double z = se > 0.0 ? fabs(m - ref) / se : (m == ref ? 0.0 : INFINITY);
  int pass = fabs(m - ref) <= 3.0 * se + tol;
  v->run++;
  v->failed += !pass;
  printf("| %s | %s | %.5f ± %.5f | %.5f | %s | %.2f | %s |\n", name, what, m, se, ref, source, z, pass ? "pass" : "FAIL");
}

/* The transport checks; @return the number of failed rows. */
static int oct__check_slab(long photons, uint64_t seed, int threads) {
  oct__verdicts_t v = {0};
  double t0 = oct_now();
  printf("# Transport checks: homogeneous slab, normal incidence, %ld photons per case, seed %llu\n\n", photons,
         (unsigned long long)seed);
  printf("Verdict: |measured − reference| ≤ 3 standard errors + the reference's own precision.\n\n");
  printf("| case | quantity | measured ± SE | reference | source | deviation / SE | verdict |\n"
         "|---|---|---:|---:|---|---:|---|\n");

  /* 1. Published: van de Hulst (1980) by the doubling method, as tabulated for the validation of
   *    MCML (Wang, Jacques & Zheng 1995): μa = 10 /cm, μs = 90 /cm, g = 0.75 (HG), d = 0.02 cm,
   *    matched boundaries — albedo 0.9, optical thickness 2. Tt includes the unscattered e^-2. */
  oct__slab_result_t r;
  oct_mc_phase_t hg75 = {OCT_MC_PHASE_HG, 0.75};
  oct__slab_run(2.0, 0.9, hg75, photons, seed, 1u << 20, threads, &r);
  const char *vdh = "van de Hulst 1980, via MCML (Wang et al. 1995)";
  oct__check_row(&v, "τ 2, a 0.9, HG g 0.75", "diffuse reflectance Rd", r.R, r.R_se, 0.09739, 5e-6, vdh);
  oct__check_row(&v, "τ 2, a 0.9, HG g 0.75", "total transmittance Tt", r.T, r.T_se, 0.66096, 5e-6, vdh);

  /* 2. Exact single scattering for an isotropic slab (every order is traced; the first-order escapes
   *    are counted apart), and energy conservation at albedo 1. */
  oct_mc_phase_t iso = {OCT_MC_PHASE_HG, 0.0};
  const double taus[2] = {1.0, 5.0};
  for (int i = 0; i < 2; i++) {
    oct__slab_run(taus[i], 1.0, iso, photons, seed, (2u + (unsigned)i) << 20, threads, &r);
    double p = taus[i];
    double r1 = 0.5 * oct__simpson(oct__r1_integrand, &p, 0.0, 1.0, 20000);
    double t1 = 0.5 * oct__simpson(oct__t1_integrand, &p, 0.0, 1.0, 20000);
    char name[64];
    snprintf(name, sizeof name, "τ %g, a 1, isotropic", taus[i]);
    oct__check_row(&v, name, "single-scattering R1", r.Rs, r.Rs_se, r1, 1e-7, "closed form (quadrature)");
    oct__check_row(&v, name, "single-scattering T1", r.Ts, r.Ts_se, t1, 1e-7, "closed form (quadrature)");
    oct__check_row(&v, name, "R + T", r.RT, 0.0, 1.0, 1e-9 + (double)r.stats.truncated / photons, "energy (albedo 1)");
  }

  /* 3. The cloud phase function in a thick slab: nothing may be lost at albedo 1. */
  oct_mc_phase_t hgd = {OCT_MC_PHASE_HG_DRAINE, 0.0};
  oct__slab_run(20.0, 1.0, hgd, photons / 4, seed, 4u << 20, threads, &r);
  oct__check_row(&v, "τ 20, a 1, HG+Draine", "R + T", r.RT, 0.0, 1.0, 1e-9, "energy (albedo 1)");
  printf("| τ 20, a 1, HG+Draine | R (info) | %.5f ± %.5f | — | — | — | — |\n", r.R, r.R_se);

  /* 4. The HG+Draine sampler draws the function the renderer evaluates: its first two moments
   *    against quadrature of ocg_phase_hg_draine. */
  oct_mc_rng_t rng;
  oct_mc_rng_seed(&rng, seed, 5u << 20);
  double s1 = 0.0, s2 = 0.0, s4 = 0.0; /* Σμ, Σμ², Σμ⁴: means and standard errors of μ and μ² */
  for (long i = 0; i < photons; i++) {
    double mu = oct_mc_phase_sample_mu(&hgd, &rng);
    s1 += mu;
    s2 += mu * mu;
    s4 += mu * mu * mu * mu;
  }
  double n = (double)photons, mean1, se1, mean2, se2;
  oct_mc_mean_se(s1, s2, n, &mean1, &se1);
  oct_mc_mean_se(s2, s4, n, &mean2, &se2);
  oct__check_row(&v, "HG+Draine sampler", "⟨μ⟩ (mean cosine)", mean1, se1, oct__phase_moment(1), 1e-5,
                 "quadrature of ocg_phase_hg_draine");
  oct__check_row(&v, "HG+Draine sampler", "⟨μ²⟩", mean2, se2, oct__phase_moment(2), 1e-5,
                 "quadrature of ocg_phase_hg_draine");
  printf("\n%d checks, %d failed, %.1f s\n\n", v.run, v.failed, oct_now() - t0);
  return v.failed;
}

/* ---- Thin air against its closed form -------------------------------------------------------------------
 * The thin homogeneous air medium (oct_mc_medium_t.air_sigma) with no cloud: an empty state, the
 * camera 1 km up in a shell 4 km deep, σ = 2e-5 m⁻¹, the sun 40° up. Along a view ray that crosses
 * the air over [0, ℓ], single scattering is
 *   L1 = ∫0..ℓ σ e^{−σt} (1/4π) E e^{−σ ℓ_sun(t)} dt,
 * ℓ_sun(t) the sun ray's length in the shell from the point at t (oc_render_air_shell, exact
 * spherical geometry; Simpson in t), and the first flight leaves with probability e^{−σℓ}. The truth
 * traces every order; the excess of all orders over single scattering is printed (of order σℓ). */

typedef struct {
  oc_dvec3 o, d, sun;
  double sigma, top;
} oct__air_case_t;

static double oct__air_l1_integrand(double t, const double *p) {
  const oct__air_case_t *c = (const oct__air_case_t *)(const void *)p;
  double a0, a1, g;
  oc_dvec3 x = oc_dmad(c->o, c->d, t);
  double ls = oc_render_air_shell(x, c->sun, c->top, &a0, &a1, &g) ? a1 - a0 : 0.0;
  return c->sigma * exp(-c->sigma * t) * exp(-c->sigma * ls) / (2.0 * OCT_TWO_PI);
}

/* @return the number of failed rows. */
static int oct__check_air(long photons, uint64_t seed) {
  oct__verdicts_t v = {0};
  oc_state_t st;
  oc_state_init(&st);
  oct_mc_medium_t m;
  if (oct_mc_medium_state(&m, &st) < 0) return 1;
  m.air_sigma = 2e-5;
  m.air_top = 4000.0;
  oc_dvec3 o = oc_geo_to_xyz((oc_geo_t){0.0, 0.0, 1000.0});
  oc_enu_t enu = oc_enu_at(o);
  oct_mc_params_t prm = {.albedo = 1.0, .phase = {OCT_MC_PHASE_HG, 0.0}, .sun = oc_heading_pitch_dir(enu, 180.0, 40.0),
                         .sun_irradiance = 1.0, .max_bounces = 1000000};
  printf("# Thin air (σ %g m⁻¹, isotropic, shell 0–%g m, camera at 1 km, sun 40° up), no cloud, %ld paths per ray\n\n",
         m.air_sigma, m.air_top, photons);
  printf("| case | quantity | measured ± SE | reference | source | deviation / SE | verdict |\n"
         "|---|---|---:|---:|---|---:|---|\n");
  const double pitch[3] = {60.0, 10.0, -20.0};
  for (int k = 0; k < 3; k++) {
    oct__air_case_t c = {o, oc_heading_pitch_dir(enu, 90.0, pitch[k]), prm.sun, m.air_sigma, m.air_top};
    double a0, a1, g;
    oc_render_air_shell(o, c.d, c.top, &a0, &a1, &g);
    oct_mc_rng_t rng;
    oct_mc_rng_seed(&rng, seed, (6u + (unsigned)k) << 20);
    oct_mc_stats_t stats = {0};
    double s1 = 0, s2 = 0, l1 = 0, l2 = 0, f1 = 0;
    for (long i = 0; i < photons; i++) {
      oct_mc_path_t path;
      oct_mc_trace(&m, &prm, o, c.d, &rng, &path, &stats);
      s1 += path.sun_single;
      s2 += path.sun_single * path.sun_single;
      l1 += path.sun;
      l2 += path.sun * path.sun;
      f1 += path.first_escaped;
    }
    double n = (double)photons, ms, ms_se, ma, ma_se, fe, fe_se;
    oct_mc_mean_se(s1, s2, n, &ms, &ms_se);
    oct_mc_mean_se(l1, l2, n, &ma, &ma_se);
    oct_mc_mean_se(f1, f1, n, &fe, &fe_se);
    char name[96];
    snprintf(name, sizeof name, "view pitch %+g°, air %.0f m", pitch[k], a1 - a0);
    oct__check_row(&v, name, "single scattering L1", ms, ms_se,
                   oct__simpson(oct__air_l1_integrand, (const double *)(const void *)&c, a0, a1, 4000), 1e-9,
                   "closed form (quadrature)");
    oct__check_row(&v, name, "view transmittance", fe, fe_se, exp(-m.air_sigma * (a1 - a0)), 1e-9, "e^{−σℓ}");
    printf("| %s | all orders (info): (L − L1)/L1 | %+.4f ± %.4f | — | — | — | — |\n", name, (ma - ms) / ms,
           sqrt(ma_se * ma_se + ms_se * ms_se) / ms);
  }
  printf("\n%d checks, %d failed\n\n", v.run, v.failed);
  oct_mc_medium_free(&m);
  oc_state_free(&st);
  return v.failed;
}

/* ---- Scene scaling ------------------------------------------------------------------------------------------ */

/* The length across which --tau is measured and the σt it scales: oct_truth_source_length/_sigma. */
#define oct__source_length oct_truth_source_length
#define oct__source_sigma oct_truth_source_sigma

/* ---- The truth image ---------------------------------------------------------------------------------------- */

typedef struct {
  const char *prog;
  const oct_mc_medium_t *medium;
  oct_mc_params_t prm;
  oc_camera_t cam;
  int w, h;
  long paths;
  uint64_t seed;
  double background;
  double *L, *L_se;     /* sun + B·background: the pixel's radiance and its standard error */
  double *L1, *L1_se;   /* single scattering alone: first-collision sun + B·(first flight escaped) */
  double *env, *env_se; /* radiance per unit background radiance (paths that left the cloud) */
  double *esc, *esc_se; /* fraction of first flights that left: delta tracking's view transmittance */
  double *t_exact;      /* e^{-τ} of the view ray by exact quadrature */
  oct_mc_stats_t stats[256];
  atomic_int rows_done;
  double t0, tau;
  uint64_t salt; /* from the optical depth: each τ its own random numbers, whatever the list */
} oct__truth_job_t;

static void oct__truth_row(void *ctx, int y, int thread) {
  oct__truth_job_t *job = ctx;
  for (int x = 0; x < job->w; x++) {
    size_t i = (size_t)y * (size_t)job->w + (size_t)x;
    oc_dvec3 dir = oc_camera_ray(&job->cam, job->w, job->h, x, y); /* the pixel centre, as the renderer */
    oct_mc_rng_t rng;
    oct_mc_rng_seed(&rng, job->seed, i ^ job->salt);
    double l1 = 0, l2 = 0, s1 = 0, s2 = 0, e1 = 0, e2 = 0, f1 = 0;
    for (long k = 0; k < job->paths; k++) {
      oct_mc_path_t p;
      oct_mc_trace(job->medium, &job->prm, job->cam.pos, dir, &rng, &p, &job->stats[thread]);
      double l = p.sun + job->background * p.escape_weight;
      l1 += l;
      l2 += l * l;
      double ls = p.sun_single + job->background * p.first_escaped;
      s1 += ls;
      s2 += ls * ls;
      e1 += p.escape_weight;
      e2 += p.escape_weight * p.escape_weight;
      f1 += p.first_escaped;
    }
    double n = (double)job->paths;
    oct_mc_mean_se(l1, l2, n, &job->L[i], &job->L_se[i]);
    oct_mc_mean_se(s1, s2, n, &job->L1[i], &job->L1_se[i]);
    oct_mc_mean_se(e1, e2, n, &job->env[i], &job->env_se[i]);
    oct_mc_mean_se(f1, f1, n, &job->esc[i], &job->esc_se[i]); /* indicator: its square is itself */
    job->t_exact[i] = exp(-oct_mc_optical_depth(job->medium, job->cam.pos, dir));
  }
  int done = atomic_fetch_add(&job->rows_done, 1) + 1;
  fprintf(stderr, "\r%s: truth: τ %g: %d/%d rows (%d%%), %.0f s ", job->prog, job->tau, done, job->h, 100 * done / job->h,
          oct_now() - job->t0);
}

/* What one reference render scores against the truth. */
typedef struct {
  int octaves;
  double mean, rel, rel_se, rmse, rmse_denoised, rmse8, frac3, seconds;
} oct__score_t;

static int oct__tonemap(const double *L, const float *px, int w, int h, uint8_t *rgb) {
  oc_image_t img = {0};
  if (oc_image_alloc(&img, w, h) < 0) return -1;
  for (size_t i = 0; i < (size_t)w * (size_t)h; i++) {
    float v = L ? (float)L[i] : px[4 * i];
    img.px[4 * i] = img.px[4 * i + 1] = img.px[4 * i + 2] = v;
    img.px[4 * i + 3] = 1.0f;
  }
  int bad = oc_image_tonemap(&img, OCT_TRUTH_EXPOSURE, rgb);
  oc_image_free(&img);
  return bad;
}

/* Scores a reference image against a truth image t with per-pixel standard errors t_se (rgb_truth:
 * t tone-mapped; rgb_ref receives the reference tone-mapped). */
static void oct__score(const double *t, const double *t_se, const oc_image_t *ref, const uint8_t *rgb_truth,
                       uint8_t *rgb_ref, oct__score_t *sc) {
  size_t n = (size_t)ref->w * (size_t)ref->h;
  double sum_t = 0, sum_r = 0, var_sum = 0, se2 = 0;
  size_t sig = 0;
  for (size_t i = 0; i < n; i++) {
    double r = ref->px[4 * i], d = r - t[i];
    sum_t += t[i];
    sum_r += r;
    se2 += d * d;
    var_sum += t_se[i] * t_se[i];
    /* Significant: beyond 3 standard errors and beyond the float rounding of the reference (a
     * background pixel is B in both, but B is a float in the renderer). */
    if (fabs(d) > 3.0 * t_se[i] && fabs(d) > 2e-6 * fmax(fabs(t[i]), fabs(r)) + 1e-30) sig++;
  }
  double mt = sum_t / n, mt_se = sqrt(var_sum) / n;
  sc->mean = sum_r / n;
  sc->rel = mt > 0.0 ? (sc->mean - mt) / mt : 0.0;
  sc->rel_se = mt > 0.0 ? mt_se / mt : 0.0;
  sc->rmse = sqrt(se2 / n);
  sc->rmse_denoised = sqrt(fmax(0.0, se2 / n - var_sum / n)); /* E[(r − t̂)²] = bias² + SE² */
  oct__tonemap(NULL, ref->px, ref->w, ref->h, rgb_ref);
  sc->rmse8 = oc_rgb8_rmse(rgb_truth, rgb_ref, ref->w, ref->h);
  sc->frac3 = (double)sig / n;
}

/* Signed error map of reference − truth: red where the renderer is brighter, blue where darker,
 * scaled to the largest difference; dark grey where the difference is within 3 standard errors. */
static int oct__write_error_png(const char *path, const oct__truth_job_t *job, const oc_image_t *ref, double *scale,
                                char *why, size_t why_len) {
  size_t n = (size_t)job->w * (size_t)job->h;
  uint8_t *rgb = malloc(3 * n);
  if (!rgb) {
    snprintf(why, why_len, "out of memory");
    return -1;
  }
  double s = 0.0;
  for (size_t i = 0; i < n; i++) s = fmax(s, fabs(ref->px[4 * i] - job->L[i]));
  *scale = s;
  for (size_t i = 0; i < n; i++) {
    double d = ref->px[4 * i] - job->L[i];
    uint8_t *o = rgb + 3 * i;
    if (fabs(d) <= 3.0 * job->L_se[i] || fabs(d) <= 2e-6 * fmax(fabs(job->L[i]), fabs(ref->px[4 * i])) || s == 0.0) {
      o[0] = o[1] = o[2] = 48;
      continue;
    }
    uint8_t v = (uint8_t)lrint(255.0 * fmin(1.0, fabs(d) / s));
    o[0] = d > 0 ? v : 0;
    o[1] = 0;
    o[2] = d < 0 ? v : 0;
  }
  char note[128];
  snprintf(note, sizeof note, "reference - truth, full scale %.6g (linear radiance)", s);
  oc_png_text_t text[1] = {{"overcast-error-scale", note}};
  int r = oc_png_write(path, job->w, job->h, rgb, text, 1, why, why_len);
  free(rgb);
  return r;
}

/* The reference renderer in the constant-background configuration the truth reproduces. */
static oc_render_desc_t oct__ref_desc(const oc_scene_t *sc, oc_camera_t cam, int w, int h, double step, int octaves,
                                      double background, int threads) {
  oc_render_desc_t d = {0};
  d.width = w;
  d.height = h;
  d.camera = cam;
  d.step_factor = step;
  d.ms_octaves = octaves;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)sc->optics.albedo;
  d.albedo_zero = sc->optics.albedo == 0.0;
  oct_truth_light(&d, background); /* no atmosphere, no planet: sun irradiance 1, sky ambient B */
  d.threads = threads;
  return d;
}

typedef struct {
  double tau, sigma, mc_mean, mc_se, seconds;
  oct__score_t score[2], single;
  int nscores;
} oct__summary_t;

/* Everything one optical depth needs. */
typedef struct {
  const char *prog, *scene_path;
  const oc_scene_t *sc;
  oc_camera_t cam;
  int w, h, threads, nref;
  double tau, sigma, step, background;
  double air_sigma, air_top; /* thin air (0: none) */
  oc_state_t st;
  oct_mc_medium_t medium;
  oct__truth_job_t *job;
  double *buf;                     /* the job's per-pixel arrays */
  uint8_t *rgb_t, *rgb_t1, *rgb_r; /* truth, its single scattering, a reference: tone-mapped */
  oc_image_t ref[2];               /* the scene's octave count, then one octave */
  oct__score_t score[2], single;   /* against the truth; one octave against its single scattering */
  long tested;                     /* σt points compared with oc_render_sample_state */
  double t_mc;
  oct_mc_stats_t stats;
} oct__run_t;

static void oct__run_free(oct__run_t *r) {
  oc_image_free(&r->ref[0]);
  oc_image_free(&r->ref[1]);
  oct_mc_medium_free(&r->medium);
  free(r->buf);
  free(r->rgb_t);
  free(r->rgb_t1);
  free(r->rgb_r);
  oc_state_free(&r->st);
}

/* The state (voxelized as `overcast-bench render` does), buffers, the kernel's medium, and the proof
 * that the kernel reads σt as the renderer does. @return 0 or an exit status. */
static int oct__run_setup(oct__run_t *r) {
  char why[1024];
  size_t n = (size_t)r->w * (size_t)r->h;
  oc_state_init(&r->st);
  ocs_scene_voxelize_desc_t vd = {r->cam, r->h, 2.0, 16, 0, r->threads};
  if (ocs_scene_voxelize(&r->st, r->sc, &vd, why, sizeof why) < 0)
    return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "%s: %s", r->scene_path, why);
  r->buf = calloc(9 * n, sizeof *r->buf);
  r->rgb_t = malloc(3 * n);
  r->rgb_t1 = malloc(3 * n);
  r->rgb_r = malloc(3 * n);
  if (!r->buf || !r->rgb_t || !r->rgb_t1 || !r->rgb_r || oct_mc_medium_state(&r->medium, &r->st) < 0)
    return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "out of memory");
  r->medium.air_sigma = r->air_sigma;
  r->medium.air_top = r->air_top;
  long differ = oct_mc_check_reconstruction(&r->medium, r->job->seed, 200000, &r->tested);
  if (differ)
    return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "truth: %ld of %ld σt samples differ from oc_render_sample_state",
                       differ, r->tested);
  for (int i = 0; i < r->sc->nsources; i++) /* σt of the source --tau measures */
    if (oct__source_length(&r->sc->sources[i]) > 0.0) {
      r->sigma = *oct__source_sigma((oc_source_t *)&r->sc->sources[i]);
      break;
    }
  return OC_EXIT_OK;
}

/* The Monte Carlo image: rows to threads, every pixel its own random numbers. */
static int oct__run_truth(oct__run_t *r, long paths, long max_bounces, double sun_lobe) {
  oct__truth_job_t *job = r->job;
  size_t n = (size_t)r->w * (size_t)r->h;
  job->prog = r->prog;
  job->medium = &r->medium;
  job->prm.albedo = r->sc->optics.albedo;
  job->prm.phase.kind = OCT_MC_PHASE_HG_DRAINE;
  job->prm.sun = r->st.sun_dir;
  job->prm.sun_irradiance = 1.0; /* the renderer's sun_e without an atmosphere (sun_irradiance default 1) */
  job->prm.max_bounces = max_bounces;
  job->prm.sun_lobe = sun_lobe;
  job->cam = r->cam;
  job->w = r->w;
  job->h = r->h;
  job->paths = paths;
  job->background = r->background;
  double *b = r->buf;
  job->L = b;
  job->L_se = b + n;
  job->L1 = b + 2 * n;
  job->L1_se = b + 3 * n;
  job->env = b + 4 * n;
  job->env_se = b + 5 * n;
  job->esc = b + 6 * n;
  job->esc_se = b + 7 * n;
  job->t_exact = b + 8 * n;
  job->tau = r->tau;
  memcpy(&job->salt, &r->tau, sizeof job->salt);
  job->salt *= UINT64_C(0x9e3779b97f4a7c15);
  atomic_init(&job->rows_done, 0);
  job->t0 = oct_now();
  oc_parallel(r->h, r->threads, oct__truth_row, job);
  r->t_mc = oct_now() - job->t0;
  fprintf(stderr, "\r\033[K");
  for (int i = 0; i < r->threads; i++) oct__stats_add(&r->stats, &job->stats[i]);
  if (oct__tonemap(job->L, NULL, r->w, r->h, r->rgb_t) != 0 || oct__tonemap(job->L1, NULL, r->w, r->h, r->rgb_t1) != 0)
    return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "truth: non-finite pixels");
  return OC_EXIT_OK;
}

/* The reference renders — the scene's octave count, and one octave (single scattering) — scored
 * against the truth; one octave also against the truth's own single scattering. */
static int oct__run_references(oct__run_t *r) {
  const int octs[2] = {r->sc->optics.ms_octaves, 1};
  r->nref = octs[0] == 1 ? 1 : 2;
  for (int k = 0; k < r->nref; k++) {
    oc_render_desc_t d = oct__ref_desc(r->sc, r->cam, r->w, r->h, r->step, octs[k], r->background, r->threads);
    d.air_sigma = (float)r->air_sigma;
    d.air_top = r->air_top;
    oc_render_stats_t rs;
    if (oc_image_alloc(&r->ref[k], r->w, r->h) < 0) return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "out of memory");
    double t0 = oct_now();
    if (oc_render_state(&r->st, &d, &r->ref[k], &rs) < 0)
      return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "reference render failed");
    r->score[k].seconds = oct_now() - t0;
    r->score[k].octaves = octs[k];
    oct__score(r->job->L, r->job->L_se, &r->ref[k], r->rgb_t, r->rgb_r, &r->score[k]);
    if (octs[k] == 1) oct__score(r->job->L1, r->job->L1_se, &r->ref[k], r->rgb_t1, r->rgb_r, &r->single);
  }
  return OC_EXIT_OK;
}

/* Image means (and the standard error of the mean) of a per-pixel array. */
static void oct__image_mean(const double *v, const double *se, size_t n, double *mean, double *mean_se) {
  double s = 0.0, var = 0.0;
  for (size_t i = 0; i < n; i++) {
    s += v[i];
    if (se) var += se[i] * se[i];
  }
  *mean = s / n;
  if (mean_se) *mean_se = sqrt(var) / n;
}

static void oct__run_report(const oct__run_t *r, double *mc_mean, double *mc_se) {
  const oct__truth_job_t *job = r->job;
  const oct_mc_stats_t *st = &r->stats;
  size_t n = (size_t)r->w * (size_t)r->h;
  double l1, l1_se, env, env_se, esc, esc_se, tex, sum_se = 0.0, max_se = 0.0, tc = 0.0;
  oct__image_mean(job->L, job->L_se, n, mc_mean, mc_se);
  oct__image_mean(job->L1, job->L1_se, n, &l1, &l1_se);
  oct__image_mean(job->env, job->env_se, n, &env, &env_se);
  oct__image_mean(job->esc, job->esc_se, n, &esc, &esc_se);
  oct__image_mean(job->t_exact, NULL, n, &tex, NULL);
  for (size_t i = 0; i < n; i++) {
    sum_se += job->L_se[i];
    max_se = fmax(max_se, job->L_se[i]);
    tc += r->ref[0].px[4 * i + 3];
  }
  tc /= n;
  printf("## τ %g (σt %.6g m⁻¹): %dx%d, %ld paths per pixel, seed %llu, state %u nodes / %u bricks\n\n", r->tau, r->sigma,
         r->w, r->h, job->paths, (unsigned long long)job->seed, r->st.node_count, r->st.brick_count);
  printf("σt as the kernel reads it = oc_render_sample_state() at %ld random points, bit for bit.\n", r->tested);
  printf("Monte Carlo: %.1f s on %d threads (%.3g paths/s), %.1f scattering events and %.1f null collisions per "
         "path; majorant violations %llu, truncated paths %llu.\n\n",
         r->t_mc, r->threads, st->paths / r->t_mc, (double)st->real_collisions / st->paths,
         (double)st->null_collisions / st->paths, (unsigned long long)st->majorant_violations,
         (unsigned long long)st->truncated);
  printf("| image | mean radiance | rel. error of the mean | MC SE of the mean (rel.) | RMSE (linear) | RMSE less MC "
         "noise | RMSE 0–255 | pixels off by > 3 SE | render (s) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  printf("| Monte Carlo truth | %.6g | — | %.2e (%.2e) | mean pixel SE %.3g, max %.3g | — | — | — | %.1f |\n", *mc_mean,
         *mc_se, *mc_mean > 0 ? *mc_se / *mc_mean : 0.0, sum_se / n, max_se, r->t_mc);
  for (int k = 0; k < r->nref; k++) {
    const oct__score_t *s = &r->score[k];
    printf("| reference, %d octave%s, step %g | %.6g | %+.4f | %.4f | %.4g | %.4g | %.2f | %.1f%% | %.3f |\n", s->octaves,
           s->octaves == 1 ? "" : "s", r->step, s->mean, s->rel, s->rel_se, s->rmse, s->rmse_denoised, s->rmse8,
           100.0 * s->frac3, s->seconds);
  }
  printf("| Monte Carlo, single scattering only | %.6g | — | %.2e (%.2e) | — | — | — | — | — |\n", l1, l1_se,
         l1 > 0 ? l1_se / l1 : 0.0);
  printf("| reference, 1 octave, against MC single scattering | %.6g | %+.4f | %.4f | %.4g | %.4g | %.2f | %.1f%% | — |\n",
         r->single.mean, r->single.rel, r->single.rel_se, r->single.rmse, r->single.rmse_denoised, r->single.rmse8,
         100.0 * r->single.frac3);
  double a = r->sc->optics.albedo;
  printf("\n| check | Monte Carlo | reference |\n|---|---:|---:|\n");
  printf("| view transmittance, delta tracking vs exact quadrature (mean) | %.6f ± %.6f | %.6f (quadrature) |\n", esc,
         esc_se, tex);
  printf("| view transmittance, exact quadrature vs renderer (mean) | %.6f | %.6f (renderer alpha) |\n", tex, tc);
  printf("| radiance per unit background radiance (mean) | %.6f ± %.6f | %.6f without ambient (T); %.6f with the "
         "ambient formula, a·(1−T) + T |\n\n",
         env, env_se, tc, a * (1.0 - tc) + tc);
  if (st->majorant_violations || st->truncated)
    printf("WARNING: %llu majorant violations and %llu truncated paths bias this truth.\n\n",
           (unsigned long long)st->majorant_violations, (unsigned long long)st->truncated);
}

/* PREFIX-tauT-{truth,reference,error}.png; the reference is the scene's octave count. */
static int oct__run_pngs(oct__run_t *r, const char *prefix) {
  char path[1024], why[1024];
  double scale = 0.0;
  snprintf(path, sizeof path, "%s-tau%g-truth.png", prefix, r->tau);
  int e = oc_png_write(path, r->w, r->h, r->rgb_t, NULL, 0, why, sizeof why);
  if (e == 0) {
    oct__tonemap(NULL, r->ref[0].px, r->w, r->h, r->rgb_r);
    snprintf(path, sizeof path, "%s-tau%g-reference.png", prefix, r->tau);
    e = oc_png_write(path, r->w, r->h, r->rgb_r, NULL, 0, why, sizeof why);
  }
  if (e == 0) {
    snprintf(path, sizeof path, "%s-tau%g-error.png", prefix, r->tau);
    e = oct__write_error_png(path, r->job, &r->ref[0], &scale, why, sizeof why);
  }
  if (e < 0) return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "%s", why);
  printf("Wrote %s-tau%g-{truth,reference,error}.png (error full scale %.4g).\n\n", prefix, r->tau, scale);
  return OC_EXIT_OK;
}

/* PREFIX-tauT.txt: what tests/tools/test_truth.c and `overcast-bench truth --model` read back —
 * "key value" lines (the scene file, τ, size, paths, seed, albedo, background, the camera if not the
 * scene's, the image mean ± SE, the image mean of the radiance per unit uniform-sky radiance ± SE), then "pixels" and one "radiance se" line per pixel, row-major from
 * the top. 6 significant digits: far below the Monte Carlo noise. */
static int oct__run_save(const oct__run_t *r, const char *prefix, const char *camera_text) {
  char path[1024];
  snprintf(path, sizeof path, "%s-tau%g.txt", prefix, r->tau);
  FILE *f = fopen(path, "w");
  if (!f) return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "%s: cannot write", path);
  size_t n = (size_t)r->w * (size_t)r->h;
  double mean, mean_se;
  oct__image_mean(r->job->L, r->job->L_se, n, &mean, &mean_se);
  fprintf(f, "# overcast-bench truth: Monte Carlo radiance per pixel (delta sun of irradiance 1, OC_BG_CONSTANT)\n");
  fprintf(f, "scene %s\ntau %.9g\nsize %d %d\npaths %ld\nseed %llu\nalbedo %.9g\nbackground %.9g\n", r->scene_path,
          r->tau, r->w, r->h, r->job->paths, (unsigned long long)r->job->seed, r->sc->optics.albedo, r->background);
  if (camera_text) fprintf(f, "camera %s\n", camera_text);
  if (r->air_sigma > 0.0) fprintf(f, "air_sigma %.9g\nair_top %.9g\n", r->air_sigma, r->air_top);
  double env, env_se;
  oct__image_mean(r->job->env, r->job->env_se, n, &env, &env_se);
  fprintf(f, "mean %.6g %.6g\nenv %.6g %.6g\npixels\n", mean, mean_se, env, env_se);
  for (size_t i = 0; i < n; i++) fprintf(f, "%.6g %.3g\n", r->job->L[i], r->job->L_se[i]);
  if (fclose(f) != 0) return oc_cli_fail(r->prog, OC_EXIT_RUNTIME, "%s: write failed", path);
  return OC_EXIT_OK;
}

/* One optical depth: voxelize, trace the truth, render the references, print and write the
 * comparison. @return 0 or an exit status. */
static int oct__truth_one(oct__run_t *r, long paths, uint64_t seed, long max_bounces, double sun_lobe,
                          const char *png_prefix, const char *save, const char *camera_text, FILE *csv,
                          oct__summary_t *sum) {
  static oct__truth_job_t job; /* large (per-thread counters); one optical depth at a time */
  memset(&job, 0, sizeof job);
  job.seed = seed;
  r->job = &job;
  int rc = oct__run_setup(r);
  if (rc == OC_EXIT_OK) rc = oct__run_truth(r, paths, max_bounces, sun_lobe);
  if (rc == OC_EXIT_OK) rc = oct__run_references(r);
  if (rc == OC_EXIT_OK) {
    oct__run_report(r, &sum->mc_mean, &sum->mc_se);
    if (png_prefix) rc = oct__run_pngs(r, png_prefix);
    if (save && rc == OC_EXIT_OK) rc = oct__run_save(r, save, camera_text);
    for (int k = 0; k < r->nref && csv; k++) {
      const oct__score_t *s = &r->score[k];
      fprintf(csv, "%s,%g,%.9g,%d,%d,%ld,%g,%d,%g,%.9g,%.9g,%.9g,%.6f,%.6f,%.9g,%.9g,%.4f,%.6f,%.3f\n", r->scene_path,
              r->tau, r->sigma, r->w, r->h, paths, r->background, s->octaves, r->step, sum->mc_mean, sum->mc_se, s->mean,
              s->rel, s->rel_se, s->rmse, s->rmse_denoised, s->rmse8, s->frac3, r->t_mc);
    }
    sum->tau = r->tau;
    sum->sigma = r->sigma;
    sum->seconds = r->t_mc;
    sum->nscores = r->nref;
    memcpy(sum->score, r->score, sizeof r->score);
    sum->single = r->single;
  }
  oct__run_free(r);
  return rc;
}

/* "a,b,c" of doubles in [lo, hi]. */

/*-*** Options ***/

typedef struct {
  const char *scene, *camera, *png, *csv, *save;
  int size[2], paths, seed, threads, max_bounces, photons, check_only, no_check;
  oct_dlist_t taus;
  double sigma_scale, step, background, albedo, sun_lobe; /* sigma_scale 0: --tau */
  double air_sigma, air_top; /* thin air (0: none) */
} truth_opts_t;

#define AT(f) offsetof(truth_opts_t, f)
static const oc_cli_opt_t truth_opts[] = {
    {.name = "scene", .type = OC_CLI_STRING, .offset = AT(scene), .arg = "FILE", .def = "scenes/analytic_sphere.json",
     .help = "analytic scene"},
    OCT_OPT_CAMERA(truth_opts_t),
    {.name = "size", .type = OC_CLI_CUSTOM, .parse = oct_opt_size, .offset = AT(size), .arg = "WxH", .def = "64x36",
     .help = "image size"},
    {.name = "tau", .type = OC_CLI_CUSTOM, .parse = oct_opt_doubles, .offset = AT(taus), .arg = "LIST", .lo = 1e-6,
     .hi = 1e4, .def_note = "1,5,20",
     .help = "optical depths of the first source across (sphere diameter, slab or box height), comma-separated; "
             "every source's σt is scaled alike"},
    {.name = "sigma-scale", .type = OC_CLI_DOUBLE, .offset = AT(sigma_scale), .arg = "X", .lo = 1e-9, .hi = 1e9,
     .help = "instead of --tau: multiply every source's σt by X"},
    {.name = "paths", .type = OC_CLI_INT, .offset = AT(paths), .arg = "N", .lo = 2, .hi = 100000000, .def = "1024",
     .help = "paths per pixel"},
    {.name = "seed", .type = OC_CLI_INT, .offset = AT(seed), .arg = "N", .lo = 0, .hi = 0x7fffffff, .def = "1",
     .help = "random seed; the image does not depend on --threads"},
    {.name = "threads", .type = OC_CLI_INT, .offset = AT(threads), .arg = "N", .lo = 1, .hi = 256,
     .def_note = "all cores", .help = "worker threads"},
    {.name = "step-factor", .type = OC_CLI_DOUBLE, .offset = AT(step), .arg = "X", .lo = 1e-3, .hi = 1e3,
     .def = "0.25", .help = "the reference renderer's step factor"},
    {.name = "background", .type = OC_CLI_DOUBLE, .offset = AT(background), .arg = "B", .lo = 0, .hi = 1e6,
     .def = "0", .help = "constant background radiance for both; 0: sun only"},
    {.name = "albedo", .type = OC_CLI_DOUBLE, .offset = AT(albedo), .arg = "A", .lo = 0, .hi = 1,
     .def_note = "the scene's", .help = "single-scattering albedo for both"},
    {.name = "air-sigma", .type = OC_CLI_DOUBLE, .offset = AT(air_sigma), .arg = "S", .lo = 0,
     .hi = OC_RENDER_MAX_AIR_SIGMA, .def = "0",
     .help = "thin homogeneous air for both, m⁻¹: grey, isotropic, no absorption, from the planet radius to "
             "--air-top (oc_render_air_shell); 0: none"},
    {.name = "air-top", .type = OC_CLI_DOUBLE, .offset = AT(air_top), .arg = "H", .lo = 100, .hi = OC_ATMOSPHERE_HEIGHT,
     .def = "12000", .help = "the thin air's top, m above the planet radius"},
    {.name = "max-bounces", .type = OC_CLI_INT, .offset = AT(max_bounces), .arg = "N", .lo = 1, .hi = 1000000000,
     .def = "1000000", .help = "scattering events before a path is cut and counted"},
    {.name = "sun-lobe", .type = OC_CLI_DOUBLE, .offset = AT(sun_lobe), .arg = "X", .lo = 0, .hi = 0.9, .def = "0.02",
     .help = "share of path directions drawn from the phase lobe around the sun, weighted by one-sample MIS; 0: "
             "plain phase sampling"},
    {.name = "png-prefix", .type = OC_CLI_STRING, .offset = AT(png), .arg = "P",
     .help = "write P-tauT-truth.png, P-tauT-reference.png, P-tauT-error.png"},
    {.name = "csv", .type = OC_CLI_STRING, .offset = AT(csv), .arg = "FILE",
     .help = "one row per optical depth and reference setting"},
    {.name = "save", .type = OC_CLI_STRING, .offset = AT(save), .arg = "P",
     .help = "write P-tauT.txt: the case's parameters and the truth's per-pixel mean radiance and standard error "
             "(text; tests/data holds such files)"},
    {.name = "check-slab", .type = OC_CLI_FLAG, .offset = AT(check_only),
     .help = "run only the transport checks (published slab, single scattering, energy, phase sampling); they "
             "also run before every truth run"},
    {.name = "slab-photons", .type = OC_CLI_INT, .offset = AT(photons), .arg = "N", .lo = 1000, .hi = 1000000000,
     .def = "1000000", .help = "photons per slab case"},
    {.name = "no-slab-check", .type = OC_CLI_FLAG, .offset = AT(no_check), .help = "skip those checks before the truth run"},
    OCT_OPTS_END};
#undef AT

OCT_SPEC(truth,
         "Monte Carlo ground truth (delta tracking, every scattering order) for small views, against the CPU\n"
         "reference renderer; bench only.",
         truth_opts);

/*-*** The subcommand ***/

/* --tau is measured across the first source with a length; all σt are scaled by one factor. The
 * sources' σt into sigma0, the first length and σt; --sigma-scale's τ. @return 0, or -1 when the
 * first source has nothing to scale. */
static int truth_scale(oc_scene_t *sc, truth_opts_t *o, double *sigma0, double *len0, double *first_sigma) {
  *len0 = *first_sigma = 0.0;
  for (int i = 0; i < sc->nsources; i++) {
    double *s = oct__source_sigma(&sc->sources[i]);
    sigma0[i] = s ? *s : 0.0;
    if (*len0 == 0.0 && oct__source_length(&sc->sources[i]) > 0.0) {
      *len0 = oct__source_length(&sc->sources[i]);
      *first_sigma = sigma0[i];
    }
  }
  if (!(*first_sigma > 0.0)) return -1;
  if (o->sigma_scale > 0.0) {
    o->taus.v[0] = o->sigma_scale * *first_sigma * *len0;
    o->taus.n = 1;
  }
  return 0;
}

static void truth_summary(const oc_scene_t *sc, const oct__summary_t *sums, int done) {
  printf("## Summary: relative error of the image-mean radiance (the truth's relative SE beside it) and RMSE "
         "0–255; τ channel: 1 octave against the truth's single scattering\n\n");
  printf("| τ | σt (m⁻¹) | truth mean ± SE | %d octaves: rel. error | RMSE 0–255 | 1 octave: rel. error | RMSE 0–255 "
         "| τ channel | MC time (s) |\n",
         sc->optics.ms_octaves);
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int k = 0; k < done; k++) {
    const oct__summary_t *s = &sums[k];
    const oct__score_t *b = &s->score[s->nscores - 1];
    printf("| %g | %.4g | %.5g ± %.2g | %+.4f ± %.4f | %.2f | %+.4f ± %.4f | %.2f | %+.4f ± %.4f | %.1f |\n", s->tau,
           s->sigma, s->mc_mean, s->mc_se, s->score[0].rel, s->score[0].rel_se, s->score[0].rmse8, b->rel, b->rel_se,
           b->rmse8, s->single.rel, s->single.rel_se, s->seconds);
  }
  printf("\n");
}

/* Every optical depth, after the scene is loaded; @return the exit status. */
static int truth_run(const char *prog, truth_opts_t *o, oc_scene_t *sc, oc_camera_t cam) {
  double sigma0[OC_SCENE_MAX_SOURCES] = {0}, len0, first_sigma;
  if (truth_scale(sc, o, sigma0, &len0, &first_sigma))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "truth: %s: the first source has no extinction to scale", o->scene);
  FILE *csv = NULL;
  if (o->csv) {
    if (!(csv = fopen(o->csv, "w"))) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: cannot write", o->csv);
    fprintf(csv, "scene,tau,sigma_t,width,height,paths,background,ms_octaves,step_factor,mc_mean,mc_mean_se,ref_mean,"
                 "rel_err,rel_err_se,rmse_lin,rmse_lin_denoised,rmse_8bit,frac_over_3se,mc_seconds\n");
  }
  printf("# Monte Carlo truth: %s, albedo %g, HG+Draine phase, sun-lobe share %g, delta sun of irradiance 1 (no "
         "atmosphere), background %g, thin air σ %g m⁻¹ to %g m; reference: CPU renderer, OC_BG_CONSTANT, %d octaves (a %g, b %g, c %g) and 1, step factor %g\n\n",
         o->scene, sc->optics.albedo, o->sun_lobe, o->background, o->air_sigma, o->air_top, sc->optics.ms_octaves,
         sc->optics.ms_a, sc->optics.ms_b, sc->optics.ms_c, o->step);
  oct__summary_t sums[OCT_TRUTH_MAX_TAUS];
  int rc = OC_EXIT_OK, done = 0;
  for (int k = 0; k < o->taus.n && rc == OC_EXIT_OK; k++) {
    double f = o->taus.v[k] / (first_sigma * len0);
    for (int i = 0; i < sc->nsources; i++) {
      double *s = oct__source_sigma(&sc->sources[i]);
      if (s) *s = sigma0[i] * f;
    }
    oct__run_t run = {.prog = prog, .scene_path = o->scene, .sc = sc, .cam = cam, .w = o->size[0], .h = o->size[1],
                      .threads = o->threads, .tau = o->taus.v[k], .step = o->step, .background = o->background,
                      .air_sigma = o->air_sigma, .air_top = o->air_top};
    rc = oct__truth_one(&run, o->paths, (uint64_t)o->seed, o->max_bounces, o->sun_lobe, o->png, o->save, o->camera, csv,
                        &sums[k]);
    if (rc == OC_EXIT_OK) done++;
  }
  if (done > 1) truth_summary(sc, sums, done);
  if (csv) fclose(csv);
  return rc;
}

int oct_bench_truth(const char *prog, int argc, char **argv) {
  long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
  truth_opts_t o = {.threads = ncpu < 1 ? 1 : ncpu > 256 ? 256 : (int)ncpu, .albedo = -1.0};
  int rc = oct_begin(&oct_bench_truth_spec, argc, argv, &o, NULL, NULL, NULL, NULL);
  if (rc != OCT_GO) return rc;
  if (o.taus.n && o.sigma_scale > 0.0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "truth: --tau and --sigma-scale exclude each other");
  if (o.check_only && o.no_check)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "truth: --check-slab and --no-slab-check exclude each other");
  if (!o.taus.n) o.taus = (oct_dlist_t){{1, 5, 20}, 3};
  int failed = 0;
  if (!o.no_check) failed = oct__check_slab(o.photons, (uint64_t)o.seed, o.threads) + oct__check_air(o.photons / 4, (uint64_t)o.seed);
  if (o.check_only) return failed ? OC_EXIT_RUNTIME : OC_EXIT_OK;

  char why[512];
  static oc_scene_t sc;
  oc_camera_pose_t pose;
  ocs_medium_t medium;
  if ((rc = oct_scene_camera(prog, o.scene, o.camera, &sc, &pose)) != OCT_GO) return rc;
  if (ocs_scene_medium(&sc, &medium, why, sizeof why) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_USAGE, "truth: analytic scenes only: %s", why);
  }
  if (o.albedo >= 0.0) sc.optics.albedo = o.albedo;
  rc = truth_run(prog, &o, &sc, oc_camera_from_pose(pose));
  oc_scene_free(&sc);
  if (rc == OC_EXIT_OK && failed) {
    fprintf(stderr, "%s: truth: %d transport check%s failed\n", prog, failed, failed == 1 ? "" : "s");
    return OC_EXIT_RUNTIME;
  }
  return rc;
}
