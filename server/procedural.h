/* procedural.h — the procedural planet's insides, shared by its files (server/, not public):
 * source_procedural.c (the model: layers, point(), bound, time steps, creation),
 * procedural_strata.c (the exact box filter by stratified points: the oracle) and
 * procedural_columns.c (the fast estimate of the same box average that bricks use).
 * docs/procedural.md describes the model; docs/numerics.md the fast estimate's error. */
#ifndef OC_SERVER_PROCEDURAL_H
#define OC_SERVER_PROCEDURAL_H

#include <math.h>
#include <stdatomic.h> /* ocs__col_cell_dropped */
#include <stdint.h>

#include "oc_noise.h"
#include "oc_planet.h"
#include "ocs_field.h"
#include "seqcache.h"
#include "weather.h"

#define OCG_REAL_DOUBLE /* Märkl's conversions in double, from the one shared implementation */
#include "optics.h"     /* ocg_sigma_t_liquid, ocg_sigma_t_ice */

/*-*** Tuning knobs ***/

/*! Fewest strata per axis of the box filter: 4³ = 64 points per sample (ocs_voxelize's default),
 *  all a fine level needs. */
#ifndef OCS_PROC_SUB
#define OCS_PROC_SUB 4
#endif
/*! Coarser levels add strata until their spacing is at most these many metres: along the two most
 *  horizontal axes (cumulus cells are 1–2 km across; with 4 strata a 7 km voxel's brick mean was
 *  off by up to 10%, with 6 by 1%), up to OCS_PROC_MAX_SUB_H, and along the axis closest to the local
 *  vertical (the layers are 0.3–3 km thick with flat bases; 100 m strata keep brick means within
 *  0.2% of 10 m ones), up to OCS_PROC_MAX_SUB_V. */
#ifndef OCS_PROC_DH
#define OCS_PROC_DH 450.0
#endif
#ifndef OCS_PROC_DZ
#define OCS_PROC_DZ 100.0
#endif
#ifndef OCS_PROC_MAX_SUB_H
#define OCS_PROC_MAX_SUB_H 6
#endif
/*! Most strata along the vertical axis (levels 0–4 reach it: their voxels are ≥ 115 km). */
#ifndef OCS_PROC_MAX_SUB_V
#define OCS_PROC_MAX_SUB_V 1024
#endif
/*! Octave truncation of the detail noise: at level L, an octave of period λ is kept while
 *  λ ≥ OCS_PROC_OCTAVE_DROP × the level's voxel size. 0 keeps every octave at every level. Any
 *  non-zero value must pass the parent-vs-descendants mean test (tests/server/test_procedural.c). */
#ifndef OCS_PROC_OCTAVE_DROP
#define OCS_PROC_OCTAVE_DROP 0.0
#endif
/*! Fraction of a voxel the content may move before a level's time step changes. */
#ifndef OCS_PROC_STEP_VOXELS
#define OCS_PROC_STEP_VOXELS 0.25
#endif
/*! Most level steps a layer's own step may span, as a power of two (ocs__layer_steps). */
#define OCS_PROC_MAX_JSTEP 8
/*! Scale height of the air density, ρ_air(h) = 1.225·exp(-h/H): the least-squares fit to the
 *  1976 standard atmosphere over 0–12 km (within 3.5% up to 11 km; above the tropopause the air
 *  thins faster: 7% high at 12 km, 23% at 15 km, where only cumulonimbus tops live). */
#define OCS_PROC_RHO_H 9200.0

#define OCS__R OC_PLANET_RADIUS

/* e^x without libm (source_procedural.c): deterministic bits on every machine. */
double ocs__exp(double x);

static inline double ocs__sat(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }
static inline double ocs__smoothstep(double a, double b, double x) {
  double u = ocs__sat((x - a) / (b - a));
  return u * u * (3.0 - 2.0 * u);
}
/* Biweight bump: (1 - x²)² on |x| < 1, else 0; monotone on each side of 0. */
static inline double ocs__bump(double x) {
  double u = 1.0 - x * x;
  return u > 0.0 ? u * u : 0.0;
}
static inline double ocs__rho_air(double h) { return 1.225 * ocs__exp(-h / OCS_PROC_RHO_H); }

/*-*** Layers ***/

typedef struct {
  double lambda;       /* m: period of the first octave */
  double lambda_short; /* m: period along the layer's wind axis (streaks across it); 0: isotropic */
  int octaves;         /* lacunarity 2, gain 0.5 */
  double drift[3];     /* m/s: drift of the pattern in the layer's advected frame (evolution) */
} ocs__nspec_t;

enum { OCS__LIQUID = 0, OCS__ICE = 1, OCS__MIXED = 2 };

typedef struct {
  const char *name;
  ocs__nspec_t cov, cell, det; /* coverage C and cells K on the sphere; 3D detail D */
  double axis[3], wind;        /* advection: rotation about axis; m/s at its equator, sea level */
  double s_w;                  /* coverage ramp width (in units of C) */
  double a0, a1;               /* A = W·sat(a0 + a1·K) */
  double h_c, H_lo, H_hi;      /* Q: ((h_c - h)/H_lo)^p_lo below h_c, ((h - h_c)/H_hi)^p_hi above */
  int p_lo, p_hi;              /* 1 or 2 */
  double h_tp, H_tp;           /* above h_tp, add (h - h_tp)/H_tp (H_tp 0: none) */
  double anvil, h_av, w_av;    /* subtract anvil·bump((h - h_av)/w_av) */
  double e, k_d;               /* erosion e·sat(1/2 - k_d·D) */
  double F_w;                  /* width of the density ramp φ = sat(F/F_w) */
  int phase;                   /* OCS__LIQUID, OCS__ICE, OCS__MIXED */
  double wc;                   /* kg/kg: nominal water content */
  double prof_lo, prof_dh;     /* prof = prof_lo + (1 - prof_lo)·sat((h - h_c)/prof_dh) (prof_dh 0: 1) */
  double thin_lo, thin_hi, thin; /* × (1 - thin·smoothstep(thin_lo, thin_hi, h)) */
  double glac_lo, glac_hi, ice_ratio; /* mixed: ice fraction g = smoothstep(glac_lo, glac_hi, h),
                                         liquid (1 - g)·wc, ice g·ice_ratio·wc */
} ocs__layer_t;

/* The four layers' parameters (source_procedural.c). */
extern const ocs__layer_t ocs__layers[OCS_LAYER_COUNT];


/* Q(h) without the anvil: decreasing below h_c, increasing above (the minimum is at h_c). */
static inline double ocs__q_mono(const ocs__layer_t *L, double h) {
  double q;
  if (h < L->h_c) {
    double x = (L->h_c - h) / L->H_lo;
    q = L->p_lo == 2 ? x * x : x;
  } else {
    double x = (h - L->h_c) / L->H_hi;
    q = L->p_hi == 2 ? x * x : x;
  }
  if (L->H_tp > 0.0 && h > L->h_tp) q += (h - L->h_tp) / L->H_tp;
  return q;
}
static inline double ocs__q(const ocs__layer_t *L, double h) {
  double q = ocs__q_mono(L, h);
  if (L->anvil > 0.0) q -= L->anvil * ocs__bump((h - L->h_av) / L->w_av);
  return q;
}
/* The least altitude cost over [a, b] (Q_mono is least at h_c, the anvil's bump largest at h_av). */
static inline double ocs__qmin(const ocs__layer_t *L, double a, double b) {
  double hq = L->h_c < a ? a : (L->h_c > b ? b : L->h_c), q = ocs__q_mono(L, hq);
  if (L->anvil > 0.0) {
    double ha = L->h_av < a ? a : (L->h_av > b ? b : L->h_av);
    q -= L->anvil * ocs__bump((ha - L->h_av) / L->w_av);
  }
  return q;
}
/* Water-content profile: a non-decreasing factor times a non-increasing one. */
static inline double ocs__prof_up(const ocs__layer_t *L, double h) {
  return L->prof_dh > 0.0 ? L->prof_lo + (1.0 - L->prof_lo) * ocs__sat((h - L->h_c) / L->prof_dh) : 1.0;
}
static inline double ocs__prof_down(const ocs__layer_t *L, double h) {
  return L->thin > 0.0 ? 1.0 - L->thin * ocs__smoothstep(L->thin_lo, L->thin_hi, h) : 1.0;
}

/*-*** The source ***/

typedef struct {
  double axis[3];          /* unit wind axis */
  double omega;            /* rad/s */
  double band_lo, band_hi; /* m: outside, Q ≥ 1 + anvil and the layer is exactly empty */
  oc_fbm_t fcov, fcell, fdet;
  double inv[3][2];        /* [cov, cell, det][1/λ, 1/λ_short] */
  int aniso[3];
  double lip_cov, lip_cell; /* bound on |∇C|, |∇K| per metre of the point on the reference sphere */
  double vmax;              /* m/s: fastest motion of the layer's patterns (wind at band_hi plus drift) */
  int jstep;                /* the layer moves once every 2^jstep level steps (ocs__frame) */
} ocs__lstate_t;

typedef struct {
  ocs_source_t base; /* first: the field holds ocs_source_t pointers */
  ocs_weather_t weather;
  double sigma_scale;
  double vmax; /* m/s: fastest motion of any pattern */
  double dt0;  /* s: motion time step at level 0 */
  ocs__lstate_t L[OCS_LAYER_COUNT];
  ocs_seqcache_t *nbc; /* node bounds by (key, time step), ocs__brick_begin; NULL: none */
} ocs__proc_t;

/* What one evaluation needs at one (level, time): snapped motion time, blended weather. */
typedef struct {
  double M[9];                /* rotation planet frame → layer's advected frame */
  double theta, wc;           /* coverage threshold; water content kg/kg */
  double off[3][3];           /* [cov, cell, det]: noise-space drift offsets */
  oc_fbm_t det;               /* detail fBm with this level's octaves */
  double det_scale;           /* Σ kept amplitudes / Σ all */
  double kmargin, amargin;    /* ocs__col_margins() of the frame's level */
} ocs__lframe_t;

typedef struct {
  unsigned mask; /* layers that may hold cloud */
  double sigma_scale;
  ocs__lframe_t l[OCS_LAYER_COUNT];
} ocs__frame_t;

enum { OCS__COV = 0, OCS__CELL = 1, OCS__DET = 2 };

static inline void ocs__rotate(const double M[9], const double *p, double *q) {
  q[0] = M[0] * p[0] + M[1] * p[1] + M[2] * p[2];
  q[1] = M[3] * p[0] + M[4] * p[1] + M[5] * p[2];
  q[2] = M[6] * p[0] + M[7] * p[1] + M[8] * p[2];
}

/* Noise-space coordinates of a pattern at X (metres): X/λ, or with streaks, the component along
 * the wind axis over λ_short and the rest over λ; plus the drift offset. */
static inline void ocs__coords(const ocs__lstate_t *S, int f, const double X[3], const double off[3], double *out) {
  double il = S->inv[f][0];
  if (!S->aniso[f]) {
    out[0] = X[0] * il + off[0];
    out[1] = X[1] * il + off[1];
    out[2] = X[2] * il + off[2];
  } else {
    double is = S->inv[f][1], d = X[0] * S->axis[0] + X[1] * S->axis[1] + X[2] * S->axis[2];
    for (int k = 0; k < 3; k++) {
      double par = d * S->axis[k];
      out[k] = (X[k] - par) * il + par * is + off[k];
    }
  }
}

static inline double ocs__voxel_size(int level) { return ldexp(2.0 * OC_ROOT_HALF / 7.0, -level); }

/* Voxel v of the brick at integer corner ic (voxel size u): its global lattice coordinates gg and
 * centre c, planet frame. @return its most vertical axis (the largest |c|: a face sample shared
 * with a neighbour gets the same axis, and so the same strata or columns, from either brick). */
static inline int ocs__voxel_centre(const uint32_t ic[3], int v, double u, double gg[3], double c[3]) {
  int ijk[3] = {v % 8, v / 8 % 8, v / 64};
  for (int a = 0; a < 3; a++) {
    gg[a] = (double)(7 * (int64_t)ic[a] + ijk[a]);
    c[a] = -OC_ROOT_HALF + gg[a] * u;
  }
  int va = fabs(c[1]) > fabs(c[0]) ? 1 : 0;
  return fabs(c[2]) > fabs(c[va]) ? 2 : va;
}

/* The evaluation frame. level ≥ 0: a brick of that level (motion time snapped to the level's
 * step, weather quantised, detail octaves for the level); level < 0: a point at exactly t. */
void ocs__frame(const ocs__proc_t *P, int level, double t, ocs__frame_t *F);

/*-*** The finest σt ***/

/* The coverage ramp W from the coverage value C, and the cell ramp V from the cell value K; the
 * column strength is A = W·V, and there is no cloud where it is 0. */
static inline double ocs__w(const ocs__layer_t *L, const ocs__lframe_t *lf, float C) {
  return ocs__sat(((double)C - lf->theta) / L->s_w);
}
static inline double ocs__v(const ocs__layer_t *L, float K) { return ocs__sat(L->a0 + L->a1 * (double)K); }
/* σt of water content wc at the altitude h (air density rho there) in the layer's phase: a mixed
 * layer splits it between liquid and ice by its glaciation ramp. */
static inline double ocs__sigma_wc(const ocs__layer_t *L, double wc, double h, double rho) {
  if (L->phase == OCS__LIQUID) return ocg_sigma_t_liquid(wc, rho);
  if (L->phase == OCS__ICE) return ocg_sigma_t_ice(wc, rho);
  double g = ocs__smoothstep(L->glac_lo, L->glac_hi, h);
  return ocg_sigma_t_liquid(wc * (1.0 - g), rho) + ocg_sigma_t_ice(wc * g * L->ice_ratio, rho);
}
/* σt of a layer from G > 0, the detail value D and the altitude. */
static inline double ocs__sigma(const ocs__layer_t *L, const ocs__frame_t *F, const ocs__lframe_t *lf, double G,
                                float D, double h) {
  double d = (double)D * lf->det_scale;
  double phi = ocs__sat((G - L->e * ocs__sat(0.5 - L->k_d * d)) / L->F_w);
  if (!(phi > 0.0)) return 0.0;
  double wc = lf->wc * ocs__prof_up(L, h) * ocs__prof_down(L, h) * phi;
  return F->sigma_scale * ocs__sigma_wc(L, wc, h, ocs__rho_air(h));
}

/* What a box bound learns per layer: the coverage range and the cell maximum over the box (a
 * sub-box may reuse them: they bound it too), the layers that may be non-zero, and those whose
 * coverage ramp is exactly 1 over the whole box (their coverage noise need not be evaluated). */
typedef struct {
  double cmin[OCS_LAYER_COUNT], cmax[OCS_LAYER_COUNT], kmax[OCS_LAYER_COUNT];
  unsigned mask, wone;
} ocs__bb_t;

/*! Slots of the node-bound cache (source_procedural.c, ocs__node_max: 136 bytes each). */
#ifndef OCS_PROC_NODE_CACHE_SLOTS
#define OCS_PROC_NODE_CACHE_SLOTS 16384
#endif

/*! Largest grid half-size m of ocs__dir_range(): (2m + 1)² = 289 noise points per field (after
 *  grids of at most 5 × 5, and only where they may decide: ocs__grid_first below). */
#ifndef OCS_PROC_BOUND_GRID
#define OCS_PROC_BOUND_GRID 8
#endif

/* The node bound's first grids' largest half-size (source_procedural.c, ocs__layer_ranges): 2 (the
 * default) evaluates grids of at most 5 × 5 points first, and the full grids only where they may
 * still bound a layer to 0; OCS_PROC_BOUND_GRID or more evaluates the full grids at once. Both give
 * the same zero or non-zero bound for every box; tests switch it (no thread may bound meanwhile). */
extern int ocs__grid_first;

/* Conservative maximum of σt over an axis-aligned box, restricted to the layers in `only`
 * (source_procedural.c, where it is explained). */
double ocs__box_max(const ocs__proc_t *P, const ocs__frame_t *F, unsigned only, const double lo[3], const double hi[3],
                    int grid, const ocs__bb_t *inherit, unsigned reuse, ocs__bb_t *bb);

/* A brick that a sampler has begun (ocs__brick_begin): the source, the frame of the key's level at
 * t, the node's bound over its sample footprint (nb), and the layers whose per-voxel bounds take
 * the node's ranges (reuse). */
typedef struct {
  const ocs__proc_t *P;
  ocs__frame_t F;
  ocs__bb_t nb;
  unsigned reuse;
  int level;
} ocs__brick_t;

/* What both samplers do first: fills B for the key at t. @return 1 when the brick may hold cloud,
 * 0 when it is empty, or OC_EINVAL (a bad key). */
int ocs__brick_begin(const ocs_source_t *s, oc_key_t key, double t, ocs__brick_t *B);

/* The per-voxel bounds of a brick (ocs__box_max() with grid 0 on each voxel's cube, batched, after
 * a first pass over blocks of 2³ voxels that skips the voxels of blocks proven empty):
 * the layers that may be non-zero, and those whose W is 1, per voxel. B->nb is the node's bound,
 * whose ranges the layers in B->reuse take. ccentre (may be NULL) gets each layer's coverage value
 * C at each voxel's centre where it was evaluated (+inf where the layer took the node's ranges:
 * W = 1 there). */
void ocs__voxel_bounds(const ocs__brick_t *B, oc_key_t key, uint8_t vmask[OC_BRICK_VOXELS], uint8_t vwone[OC_BRICK_VOXELS],
                       double (*ccentre)[OC_BRICK_VOXELS]);

/* Strata of the exact box filter at a level: sub_h along the two most horizontal axes of a voxel,
 * sub_v along the most vertical (procedural_strata.c). */
void ocs__subs(int level, int *sub_h, int *sub_v);

/* A layer's band: outside [lo, hi], Q ≥ 1 + anvil and the layer is exactly empty. */
void ocs__layer_band(const ocs__layer_t *L, double *lo, double *hi);

/* The fast filter's tables, built once per process (thread-safe; the layers' constants are all
 * they depend on). @return 0 or OC_ENOMEM. */
int ocs__col_tables(void);
/* What the fast filter's estimate of a layer at a level may exceed the evaluated field by: cell
 * values up to kmargin beyond the evaluated octaves, A' up to amargin (one table step); 0 for
 * level < 0 (points). ocs__frame() puts them in the frame, ocs__box_max() adds them. */
void ocs__col_margins(int level, int layer, double *kmargin, double *amargin);

/* The fast filter's two-pass cells (procedural_columns.c, ocs__cells): 1 (the default) adds the
 * last resolved cell octave only at pieces the first ones leave in doubt; 0 evaluates every octave
 * at every piece; 2 does as 1 and also checks each dropped piece against its exact value. All give
 * the same bits; tests switch it (no thread may sample meanwhile) and read how many pieces the
 * first pass dropped and how many of those the exact value would have kept (relaxed atomics,
 * summed over every thread; the claim is that the second stays 0). */
extern int ocs__col_cell_split;
extern _Atomic long ocs__col_cell_dropped, ocs__col_cell_wrong;

/* The fast filter's cells at the voxels' corners (procedural_columns.c, ocs__voxel_cells; fine voxels
 * where the cells' finest resolved octave spans OCS_COL_KVOX voxels): 1 (the default) drops the voxels
 * whose largest corner cannot pass the cell test before they make pieces, 0 makes every live voxel's
 * pieces. Both give the same bits; tests switch it (no thread may sample meanwhile) and read how many
 * voxel layers it dropped (relaxed atomic, summed over every thread). */
extern int ocs__col_kvox_pretest;
extern _Atomic long ocs__col_kvox_dropped;

/* The two samplers of a brick (the vtable's sample() and sample_exact()): ADD the source's σt. */
int ocs__proc_sample_strata(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]);
int ocs__proc_sample_columns(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]);

#endif /* OC_SERVER_PROCEDURAL_H */
