/* bench_mc.h — the Monte Carlo transport kernel behind `overcast-bench truth` (bench_truth.c).
 *
 * Unbiased volume path tracing with every scattering order, in double precision:
 *   - free flights by delta (Woodcock) tracking against piecewise-constant majorants: per sample
 *     cell of a brick leaf (the largest of its 8 decoded corners), per uniform or empty leaf, or
 *     one for a homogeneous slab (the published-slab check);
 *   - σt from the reconstruction the CPU reference renderer and the shaders use (shaders/brick.h,
 *     as oc_render_sample_state() reads it; checked bit for bit against that function), so the
 *     truth sees exactly the state they see; leaves come from an index built once per state;
 *   - next-event estimation toward a delta sun whose transmittance is computed exactly (not
 *     estimated): along a line, trilinear σt is a cubic inside each sample cell, and two-point
 *     Gauss–Legendre per cell integrates a cubic exactly — the expectation of ratio tracking with
 *     none of its variance;
 *   - phase functions sampled exactly (HG by inversion; Draine by rejection from HG) and evaluated
 *     with the shared functions of shaders/optics.h, so the sampling weight is 1.
 * Random numbers come from xoshiro256** seeded through splitmix64 from (seed, stream): a pixel's
 * paths depend only on the seed and its index, never on the thread that traced them. */
#ifndef OC_TOOLS_BENCH_MC_H
#define OC_TOOLS_BENCH_MC_H

#include <stdint.h>

#include "oc.h"

/* ---- Random numbers ------------------------------------------------------------------------------ */

typedef struct {
  uint64_t s[4];
} oct_mc_rng_t;

/*! oct_mc_rng_seed() : an independent stream for (seed, stream), e.g. (--seed, pixel index). */
void oct_mc_rng_seed(oct_mc_rng_t *r, uint64_t seed, uint64_t stream);
/*! oct_mc_uniform() : a double in [0, 1) with 53 random bits. */
double oct_mc_uniform(oct_mc_rng_t *r);
/*! oct_mc_mean_se() : the mean and the standard error of the mean from a sum s1 and a sum of
 *  squares s2 over n samples. */
void oct_mc_mean_se(double s1, double s2, double n, double *mean, double *se);

/* ---- Phase functions ----------------------------------------------------------------------------- */

typedef enum {
  OCT_MC_PHASE_HG_DRAINE = 0, /**< the cloud phase function: ocg_phase_hg_draine (d = 10 µm) */
  OCT_MC_PHASE_HG = 1         /**< Henyey–Greenstein with asymmetry g (g = 0: isotropic) */
} oct_mc_phase_kind_t;

typedef struct {
  oct_mc_phase_kind_t kind;
  double g; /**< OCT_MC_PHASE_HG only, (-1, 1) */
} oct_mc_phase_t;

/*! oct_mc_phase_eval() : p(mu) in sr⁻¹, mu the cosine between propagation directions (optics.h). */
double oct_mc_phase_eval(const oct_mc_phase_t *ph, double mu);
/*! oct_mc_phase_sample_mu() : a cosine distributed exactly as p(mu) 2π dmu. */
double oct_mc_phase_sample_mu(const oct_mc_phase_t *ph, oct_mc_rng_t *r);
/*! oct_mc_phase_sample() : a new unit direction scattered from unit d by the phase function. */
oc_dvec3 oct_mc_phase_sample(const oct_mc_phase_t *ph, oc_dvec3 d, oct_mc_rng_t *r);

/* ---- Media --------------------------------------------------------------------------------------- */

typedef enum {
  OCT_MC_MEDIUM_STATE = 0, /**< an octree state, planet frame, metres */
  OCT_MC_MEDIUM_SLAB = 1   /**< homogeneous slab 0 ≤ z ≤ tau with σt = 1 (lengths in optical depth) */
} oct_mc_medium_kind_t;

typedef struct {
  oct_mc_medium_kind_t kind;
  const oc_state_t *state;     /**< OCT_MC_MEDIUM_STATE (set up with oct_mc_medium_state) */
  struct oct_mc_index *index;  /**< its leaf index */
  double slab_tau;             /**< OCT_MC_MEDIUM_SLAB */
  double air_sigma;            /**< OCT_MC_MEDIUM_STATE: thin homogeneous air, σ in m⁻¹ (0: none), in the
                                    shell of oc_render_air_shell(): grey, isotropic, no absorption; a
                                    path that reaches the planet radius leaves (as through the top) */
  double air_top;              /**< that shell's top, m above OC_PLANET_RADIUS */
} oct_mc_medium_t;

/*! oct_mc_medium_state() : the medium of a state (kept by pointer), with its leaf index.
 *  @return 0, or -1 out of memory. Free with oct_mc_medium_free(). */
int oct_mc_medium_state(oct_mc_medium_t *m, const oc_state_t *s);
void oct_mc_medium_free(oct_mc_medium_t *m);
/*! oct_mc_check_reconstruction() : σt as the kernel reads it (its own leaf index, then the shared
 *  brick.h reconstruction) against oc_render_sample_state() at n random points of non-empty
 *  leaves, a quarter of them on sample-cell faces. @return how many differ in any bit;
 *  *tested: points compared. */
long oct_mc_check_reconstruction(const oct_mc_medium_t *m, uint64_t seed, long n, long *tested);

/*! Event counters (per thread; add them up), listed once as X(name), each a uint64_t. */
#define OCT_MC_STATS_FIELDS(X)                                                                            \
  X(paths)                                                                                                \
  X(real_collisions)     /**< scattering events */                                                        \
  X(null_collisions)     /**< tentative collisions rejected by delta tracking */                          \
  X(majorant_violations) /**< σt above the span's majorant at a tentative collision (must stay 0; each   \
                              one is a small bias) */                                                     \
  X(truncated)           /**< paths stopped at max_bounces (a bias; must stay 0) */                       \
  X(nee_rays)            /**< exact transmittance evaluations toward the sun */

#define OCT_MC_STATS_FIELD(name) uint64_t name;
typedef struct {
  OCT_MC_STATS_FIELDS(OCT_MC_STATS_FIELD)
} oct_mc_stats_t;
#undef OCT_MC_STATS_FIELD

/*! oct_mc_optical_depth() : ∫σt along o + t·d for t in [0, ∞), exact for the medium's
 *  reconstruction (see the file comment); d unit. */
double oct_mc_optical_depth(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d);
/*! oct_mc_flight() : delta tracking from o along unit d. @return 1 with *t the distance to a real
 *  collision in the cloud, 2 with the distance to one in the thin air, or 0 when the ray leaves the
 *  medium. The air's free path is drawn analytically and the cloud tracked up to it: the first of
 *  the two independent collisions is the first collision in their sum. */
int oct_mc_flight(const oct_mc_medium_t *m, oc_dvec3 o, oc_dvec3 d, oct_mc_rng_t *r, double *t, oct_mc_stats_t *st);

/* ---- Paths ----------------------------------------------------------------------------------------- */

typedef struct {
  double albedo;          /**< single-scattering albedo σs/σt, [0, 1] */
  oct_mc_phase_t phase;
  oc_dvec3 sun;           /**< unit vector toward the sun */
  double sun_irradiance;  /**< irradiance of the delta sun; 0 turns next-event estimation off */
  long max_bounces;       /**< scattering events before a path is cut (counted as truncated) */
  double sun_lobe;        /**< probability ε of drawing a new direction from the phase lobe around the
                               sun instead of around the path (one-sample MIS; 0: plain phase sampling) */
} oct_mc_params_t;

typedef struct {
  double sun;            /**< radiance brought by next-event estimation toward the sun */
  double sun_air;        /**< its share from collisions in the thin air (all orders) */
  double sun_single;     /**< its first-collision share: single scattering alone */
  double escape_weight;  /**< throughput with which the path left the medium (0: absorbed or cut) */
  oc_dvec3 escape_dir;   /**< its direction then */
  int first_escaped;     /**< the first flight left the medium (a sample of the view transmittance) */
  long bounces;          /**< scattering events */
} oct_mc_path_t;

/*! oct_mc_trace() : one path from o along unit d (a camera ray, or a photon for the slab check:
 *  the random walk is the same because the phase functions are symmetric). Throughput is
 *  multiplied by the albedo at each collision, with Russian roulette below 0.1 (unbiased). The
 *  radiance seen along -d is out->sun + B·out->escape_weight for a uniform background B. */
void oct_mc_trace(const oct_mc_medium_t *m, const oct_mc_params_t *p, oc_dvec3 o, oc_dvec3 d, oct_mc_rng_t *r,
                  oct_mc_path_t *out, oct_mc_stats_t *st);

#endif /* OC_TOOLS_BENCH_MC_H */
