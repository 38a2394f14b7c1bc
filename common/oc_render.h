/* oc_render.h — the CPU reference renderer: the oracle for GLSL images and error reports.
 *
 * It renders a state (exactly what a viewer holds) with the model the GLSL client uses, from the
 * same shared headers (shaders/optics.h, brick.h, atmosphere.h):
 *   - octree descent through the state's leaves; the step inside a non-empty node is
 *     step_factor × its voxel spacing (node size / 7); nodes whose σt is zero are crossed in one
 *     step (the atmosphere is still integrated over them at its own step length);
 *   - one integral for clouds and air: per segment, total extinction σt = σt_cloud + σt_air (RGB),
 *     energy-conserving segment weights (ocg_segment_weight3), early exit at low transmittance;
 *   - cloud in-scattering: sun irradiance × clear-sky transmittance to the sun × the multiple-
 *     scattering octaves over the τ channel and the HG+Draine phase; plus sky ambient
 *     (fluence / 4π from the atmosphere tables);
 *   - air in-scattering: Rayleigh and Mie single scattering (shadowed by the cloud τ) plus
 *     Hillaire's multiple-scattering term;
 *   - the planet sphere: Lambertian ground lit by the sun (with cloud shadow from τ) and the sky;
 *   - in empty nodes, which carry no τ, the τ of the cloud shadow volume (shaders/shadow.h) built
 *     from the state during each render (each texel when a ray first needs it), centred under the camera;
 *   - without an atmosphere, optionally thin homogeneous air (air_sigma): grey, isotropic, single
 *     scattering in the cloud's shadow, the Monte Carlo truth's air medium (docs/numerics.md).
 * Positions are double on the CPU. Output is deterministic for any thread count. */
#ifndef OC_COMMON_RENDER_H
#define OC_COMMON_RENDER_H

#include <stdint.h>

#include "oc_atmo.h"   /* oc_atmo_t */
#include "oc_camera.h" /* oc_camera_t */
#include "oc_image.h"  /* oc_image_t */
#include "oc_state.h"  /* oc_state_t */

/*! Tuning knobs; each is a field of oc_render_desc_t whose 0 means the default below. */
#define OC_RENDER_DEFAULT_STEP_FACTOR 0.5  /**< × voxel spacing (node size / 7) */
#define OC_RENDER_DEFAULT_AIR_STEPS 32     /**< steps across the atmosphere along a view ray */
#define OC_RENDER_DEFAULT_EXIT_T 1e-3      /**< early exit when max RGB transmittance drops below */
#define OC_RENDER_DEFAULT_MS_OCTAVES 4
#define OC_RENDER_DEFAULT_EXPOSURE 10.0
/* The cloud shadow volume (shaders/shadow.h): a grid centred under the camera. */
#define OC_RENDER_DEFAULT_SHADOW_EXTENT 64000.0 /**< m, its horizontal edge */
#define OC_RENDER_DEFAULT_SHADOW_CELLS 128      /**< texels along each horizontal edge */
#define OC_RENDER_DEFAULT_SHADOW_LEVELS 24      /**< texels from the ground to its top */
#define OC_RENDER_DEFAULT_SHADOW_TOP 12000.0    /**< m, its top: air above it is unshadowed */
#define OC_RENDER_DEFAULT_SHADOW_GROUND_CELLS 512 /**< the ground map's texels along each edge (shadow.h) */
#define OC_RENDER_SHADOW_GROUND_CELLS_MIN 2       /**< the fewest and most it may have (-1: none) */
#define OC_RENDER_SHADOW_GROUND_CELLS_MAX 4096
/* Thin homogeneous air (air_sigma, with no atmosphere): the shell from the planet radius up to this. */
#define OC_RENDER_DEFAULT_AIR_TOP 12000.0       /**< m above OC_PLANET_RADIUS */
#define OC_RENDER_MAX_AIR_SIGMA 1e-3            /**< m⁻¹: τ 1 per km; "thin" means far less */
#define OC_RENDER_MS_FIT_N 8 /**< the numbers oc_render_desc_t.ms_fit points to */
/* The octave factors fitted with march.h's constants to the Monte Carlo truth (docs/numerics.md). */
#define OC_RENDER_DEFAULT_MS_A 0.6139f      /**< octave extinction factor a */
#define OC_RENDER_DEFAULT_MS_B 0.5139f     /**< octave contribution factor b */
#define OC_RENDER_DEFAULT_MS_C 0.9924f     /**< octave eccentricity factor c */

/*! The cloud multiple-scattering model (shaders/march.h). */
typedef enum {
  OC_MS_MODEL_DEPTH = 0,  /**< default: octaves weighted by the run's chord depth and albedo, occluded ambient */
  OC_MS_MODEL_OCTAVES = 1 /**< Wrenninge's octaves alone, unoccluded ambient (the model before the truth fit) */
} oc_ms_model_t;

typedef enum {
  OC_BG_DEFAULT = 0, /**< atmosphere, planet and sun disc as the flags say; black space */
  OC_BG_CONSTANT = 1 /**< no atmosphere, no planet: a constant background radiance (analytic tests) */
} oc_background_t;

typedef enum {
  OC_RF_NO_ATMOSPHERE = 1 << 0, /**< no air in the integral (clouds still lit by the raw sun) */
  OC_RF_NO_PLANET = 1 << 1,     /**< no ground sphere */
  OC_RF_NO_AMBIENT = 1 << 2,    /**< no sky ambient on clouds */
  OC_RF_NO_SUN_DISC = 1 << 3,
  OC_RF_JITTER = 1 << 4,        /**< per-pixel jitter of the ray start (hash of pixel and frame) */
  OC_RF_NO_EARLY_EXIT = 1 << 5,
  OC_RF_NO_CLOUD_SHADOW = 1 << 6 /**< no shadow volume: air and ground in empty nodes unshadowed (before issue 21) */
} oc_render_flags_t;

/*! Debug views of the GL renderer: what the first cloudy sample along each ray sees. */
typedef enum {
  OC_DEBUG_NONE = 0,
  OC_DEBUG_LOD = 1,    /**< the leaf's level as a hue (blue coarse → red level 21) */
  OC_DEBUG_TAU = 2,    /**< exp(−τ), the cloud's transmittance toward the sun, as grey */
  OC_DEBUG_BOUNDS = 3  /**< the normal image with the edges of the first cloudy leaf drawn */
} oc_debug_view_t;

typedef struct {
  int width, height;     /**< pixels (required) */
  oc_camera_t camera;    /**< required */
  double step_factor;    /**< default OC_RENDER_DEFAULT_STEP_FACTOR */
  int air_steps;         /**< default OC_RENDER_DEFAULT_AIR_STEPS */
  double exit_t;         /**< default OC_RENDER_DEFAULT_EXIT_T; negative disables early exit */
  int ms_octaves;        /**< default OC_RENDER_DEFAULT_MS_OCTAVES; 1 = single scattering */
  float ms_a, ms_b, ms_c;/**< octave attenuation, contribution, eccentricity, each (0, 1]; default OC_RENDER_DEFAULT_MS_* */
  int ms_model;          /**< oc_ms_model_t; default OC_MS_MODEL_DEPTH */
  const float *ms_fit;   /**< NULL, or OC_RENDER_MS_FIT_N overrides of march.h's fitted constants (chord
                              half-depth, albedo power, ambient depth factor, diffuse weight, diffuse decay,
                              forward shrink of the half-depth, absorption along the sun's path, the sun
                              path's share): only for fitting */
  float albedo;          /**< cloud single-scattering albedo; default 1 (0 is valid via flags: use albedo_zero) */
  int albedo_zero;       /**< non-zero: albedo 0 (pure absorber; analytic transmittance tests) */
  float sun_irradiance;  /**< scale of the atmosphere's solar irradiance; default 1 */
  oc_background_t background;
  float background_radiance; /**< for OC_BG_CONSTANT: also a uniform sky lighting the clouds (unless OC_RF_NO_AMBIENT) */
  uint32_t flags;        /**< oc_render_flags_t */
  uint32_t frame;        /**< jitter sequence index */
  int debug_view;        /**< OC_DEBUG_*: the GL renderer's debug views; the CPU reference renders
                              the normal image whatever this says */
  int threads;           /**< default: 1 */
  double shadow_extent;  /**< cloud shadow volume's horizontal edge, m; default OC_RENDER_DEFAULT_SHADOW_EXTENT */
  int shadow_cells;      /**< its texels per horizontal edge [2, 4096]; default OC_RENDER_DEFAULT_SHADOW_CELLS */
  int shadow_levels;     /**< its texels from the ground to its top [2, 1024]; default OC_RENDER_DEFAULT_SHADOW_LEVELS */
  double shadow_top;     /**< its top, m above the ground; default OC_RENDER_DEFAULT_SHADOW_TOP */
  int shadow_ground_cells; /**< the ground map's texels per edge [2, 4096] over the volume's extent; default
                                OC_RENDER_DEFAULT_SHADOW_GROUND_CELLS; -1: none, the ground reads the volume */
  const oc_atmo_t *atmo; /**< required unless OC_RF_NO_ATMOSPHERE or OC_BG_CONSTANT */
  float air_sigma;       /**< thin homogeneous air where there is no atmosphere (OC_BG_CONSTANT or
                              OC_RF_NO_ATMOSPHERE): scattering coefficient, m⁻¹, [0, OC_RENDER_MAX_AIR_SIGMA];
                              grey, isotropic, no absorption, in the first crossing of the shell
                              oc_render_air_shell(); lit through the cloud shadow volume. Default 0: none.
                              CPU reference only: the GL renderer refuses it (OC_EINVAL) */
  double air_top;        /**< that shell's top, m above OC_PLANET_RADIUS, [100, 1e5]; default OC_RENDER_DEFAULT_AIR_TOP */
  /** CPU reference only, for measuring candidate models (`overcast-bench model --oracle`); NULL in use.
   *  Where set, a cloud sample at p seen along the ray direction dir takes its multiply scattered
   *  light from ms_oracle(ms_oracle_ctx, p, dir), the in-scattered radiance per unit sun irradiance
   *  of the light that has already scattered (sr⁻¹-weighted, as ∫ p(μ) L dω), instead of the model's
   *  octaves, diffuse part and chord factor: the sample's source is ω σt (e^{−τ} p(μ) + S) E_sun plus
   *  the sky's ambient as before. The GL renderer ignores it. */
  double (*ms_oracle)(void *ctx, oc_dvec3 p, oc_dvec3 dir);
  void *ms_oracle_ctx;
} oc_render_desc_t;

typedef struct {
  uint64_t samples;        /**< cloud-or-air segments evaluated (the throughput unit) */
  uint64_t node_lookups;   /**< leaf searches */
  uint64_t skipped_nodes;  /**< nodes crossed in one step */
  uint64_t early_exits;    /**< rays ended by low transmittance */
  uint64_t nonfinite;      /**< pixels that came out non-finite (must stay 0) */
} oc_render_stats_t;

/*! oc_render_state() : renders a validated state into img (allocated by the caller, w×h of desc).
 *  @return 0, or OC_EINVAL for a bad desc (with an oc_log_error line naming the field). */
int oc_render_state(const oc_state_t *s, const oc_render_desc_t *desc, oc_image_t *img, oc_render_stats_t *stats);

/*! The cloud shadow volume's place (shaders/shadow.h): the grids both renderers build, the volume and
 *  the ground map (its texels follow the volume's in the GL renderer's buffer). */
typedef struct {
  int n[3];                          /**< texels per axis; n[0] = 0: no shadow volume */
  double lo[3], cell[3];             /**< texel (0, 0, 0) and spacing in the local frame, m */
  int ground_n;                      /**< the ground map's texels per edge (0: none), from lo[0], lo[1] */
  double ground_cell;                /**< their spacing, m */
  oc_dvec3 c0, east, north, up;      /**< the local frame: c0 = ground_r·up under the camera */
} oc_shadow_frame_t;

/*! oc_render_shadow_frame() : the shadow volume of desc (its shadow_* options, defaults applied) under
 *  the camera at `camera` over a ground of radius ground_r (> 0); f->n[0] = 0 when desc's flags turn
 *  it off. @return 0, or OC_EINVAL for a bad option (with an oc_log_error line naming the field). */
int oc_render_shadow_frame(const oc_render_desc_t *desc, oc_dvec3 camera, double ground_r, oc_shadow_frame_t *f);

/*! oc_render_air_shell() : where the ray o + t·d (d unit, t ≥ 0) first crosses the thin air's shell
 *  OC_PLANET_RADIUS ≤ r ≤ OC_PLANET_RADIUS + top, up to the sphere of the planet radius (the ground,
 *  which ends the air: a ray does not come out on the planet's far side): [*t0, *t1], and *t_ground the
 *  distance to that sphere (INFINITY if the ray misses it). The truth (tools/bench_mc.c) and the
 *  renderer both use it. @return 1, or 0 when the ray crosses no air (or starts inside the planet). */
int oc_render_air_shell(oc_dvec3 o, oc_dvec3 d, double top, double *t0, double *t1, double *t_ground);

/*! oc_render_sample_state() : σt and τ of the state at a planet-frame point (0, 0 outside the
 *  root cube): the reconstruction the renderer and the shaders use. */
void oc_render_sample_state(const oc_state_t *s, oc_dvec3 p, float *sigma_t, float *tau);

/*! oc_render_sample_leaf() : channel ch (OC_CH_*) at planet-frame point p of the leaf node n, whose cube
 *  has corner origin and edge size, and b its payload (NULL when it has none: read as range.lo); the same
 *  reconstruction as oc_render_sample_state(), for callers that find their leaves themselves. 0 when n
 *  is NULL or empty. */
float oc_render_sample_leaf(const oc_node_t *n, const oc_brick_t *b, oc_dvec3 origin, double size, int ch,
                            oc_dvec3 p);

#endif /* OC_COMMON_RENDER_H */
