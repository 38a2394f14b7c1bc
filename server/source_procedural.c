/* source_procedural.c — the procedural planet: the built-in default scene (docs/procedural.md).
 *
 * Four cloud layers at their real altitudes — stratus sheets, cumulus heaps with flat bases,
 * cumulonimbus towers with anvils, thin cirrus — each a pure function of (point, time, seed):
 *
 *   W = sat((C - θ(cov)) / s_w)              coverage: low-frequency fBm C on the sphere
 *   A = W · sat(a0 + a1·K)                   column strength: cell fBm K on the sphere
 *   G = A - Q(h)                             Q: the layer's altitude cost (flat base, top, anvil)
 *   F = G - e·sat(1/2 - k_d·D)               erosion by 3D detail fBm D
 *   φ = sat(F / F_w)
 *   σt = s_σ · σ_Märkl(wc · prof(h) · φ, ρ_air(h))   ocg_sigma_t_liquid / _ice (shaders/optics.h)
 *
 * summed over the layers. Every layer is advected by a solid rotation about its own axis through
 * the planet centre (continuous everywhere, keeps altitudes) and its noise patterns drift slowly
 * in the advected frame (evolution). Weather presets and transitions live in weather.c.
 *
 * Bricks follow the Conventions' filter: each sample is the mean of the finest σt over its
 * footprint, estimated at stratified midpoints (the points of ocs_brick_sample()); at coarse levels
 * the axis closest to the local vertical gets many more strata than the others, because the cloud
 * shell is far thinner than a coarse voxel. The batch noise evaluates the sub-samples of a brick;
 * points that cannot hold cloud are skipped by exact tests (zero stays zero), so a sample is bit
 * for bit the mean of ocs__proc_point() over its strata (unless OCS_PROC_OCTAVE_DROP is set).
 *
 * Everything that reaches the output bits is IEEE +, -, ×, /, sqrt, floor, fmod and ldexp (the
 * noise, the exponential and the rotation's sine included), so the bytes do not depend on libm. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "procedural.h"

/*-*** Deterministic elementary functions (no libm in the output path) ***/

/* e^x: Cody–Waite reduction by ln 2, degree-13 Taylor polynomial on |r| ≤ ln2/2 (truncation below
 * 2e-17 relative), exact scaling by ldexp. */
double ocs__exp(double x) {
  if (x < -700.0) return 0.0;
  if (x > 700.0) x = 700.0;
  double k = floor(x * 1.4426950408889634 + 0.5);
  double r = (x - k * 6.93147180369123816490e-01) - k * 1.90821492927058770002e-10;
  double p = 1.0 / 6227020800.0;
  static const double c[13] = {1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0, 1.0 / 362880.0, 1.0 / 40320.0,
                               1.0 / 5040.0,      1.0 / 720.0,      1.0 / 120.0,     1.0 / 24.0,     1.0 / 6.0,
                               0.5,               1.0,              1.0};
  for (int i = 0; i < 13; i++) p = p * r + c[i];
  return ldexp(p, (int)k);
}

/* sin and cos: reduction modulo 2π (fmod is exact), then a sixteenth of the angle (|x| ≤ 0.393)
 * by Taylor series to x^17, then four double-angle steps. Within 1e-13 of libm for |a| ≤ 2000 rad
 * (the reduction by an inexact 2π dominates); the rotation only has to be deterministic. */
static void ocs__sincos(double a, double *s, double *c) {
  a = fmod(a, 6.283185307179586) * 0.0625;
  double x2 = a * a, sn = 1.0, cs = 1.0;
  for (int k = 16; k >= 2; k -= 2) {
    sn = 1.0 - sn * x2 / ((double)(k + 1) * (double)k);
    cs = 1.0 - cs * x2 / ((double)k * (double)(k - 1));
  }
  sn *= a;
  for (int i = 0; i < 4; i++) {
    double s2 = 2.0 * sn * cs, c2 = cs * cs - sn * sn;
    sn = s2;
    cs = c2;
  }
  *s = sn;
  *c = cs;
}


/* Altitudes, sizes and water contents from the usual cloud climatology (Wakapon's cloud types;
 * LWC/IWC ranges as in Märkl 2018): stratus 0.35–1.35 km; cumulus base 1.2 km, tops 2–5.4 km;
 * cumulonimbus base 1 km, tops to 14.7 km, anvil near 11.5 km, glaciating over 4–7 km; cirrus
 * 8.7–11.3 km. Winds: easterly low stratus, westerlies increasing with height, a 25 m/s jet for
 * cirrus. */
const ocs__layer_t ocs__layers[OCS_LAYER_COUNT] = {
    [OCS_LAYER_STRATUS] = {.name = "stratus",
                           .cov = {800e3, 0, 4, {1.2, -0.8, 0.5}},
                           .cell = {15e3, 0, 3, {0.5, 0.6, -0.4}},
                           .det = {2e3, 0, 4, {0.3, -0.4, 0.6}},
                           .axis = {0.1, 0.05, 1.0}, .wind = -5.0,
                           .s_w = 0.15, .a0 = 0.75, .a1 = 1.5,
                           .h_c = 800.0, .H_lo = 450.0, .H_hi = 550.0, .p_lo = 2, .p_hi = 2,
                           .e = 0.15, .k_d = 2.5, .F_w = 0.15,
                           .phase = OCS__LIQUID, .wc = 0.4e-3, .prof_lo = 1.0},
    [OCS_LAYER_CUMULUS] = {.name = "cumulus",
                           .cov = {600e3, 0, 4, {-1.0, 1.5, 0.7}},
                           .cell = {2e3, 0, 3, {0.8, 0.3, -0.9}},
                           .det = {800.0, 0, 5, {-0.6, 0.9, 1.2}},
                           .axis = {0.25, -0.1, 1.0}, .wind = 9.0,
                           .s_w = 0.2, .a0 = -0.2, .a1 = 4.0,
                           .h_c = 1200.0, .H_lo = 40.0, .H_hi = 4200.0, .p_lo = 1, .p_hi = 1,
                           .e = 0.2, .k_d = 2.5, .F_w = 0.08,
                           .phase = OCS__LIQUID, .wc = 1.1e-3, .prof_lo = 0.3, .prof_dh = 1500.0},
    [OCS_LAYER_CUMULONIMBUS] = {.name = "cumulonimbus",
                                .cov = {400e3, 0, 4, {0.9, 0.9, -1.3}},
                                .cell = {20e3, 0, 3, {1.5, -1.0, 0.4}},
                                .det = {3e3, 0, 5, {0.4, 1.1, 1.6}},
                                .axis = {-0.15, 0.2, 1.0}, .wind = 7.0,
                                .s_w = 0.15, .a0 = -0.5, .a1 = 4.0,
                                .h_c = 1000.0, .H_lo = 60.0, .H_hi = 13000.0, .p_lo = 1, .p_hi = 1,
                                .h_tp = 14500.0, .H_tp = 400.0,
                                .anvil = 0.5, .h_av = 11500.0, .w_av = 2500.0,
                                .e = 0.25, .k_d = 2.5, .F_w = 0.1,
                                .phase = OCS__MIXED, .wc = 2.0e-3, .prof_lo = 0.4, .prof_dh = 3000.0,
                                .thin_lo = 8000.0, .thin_hi = 14000.0, .thin = 0.5,
                                .glac_lo = 4000.0, .glac_hi = 7000.0, .ice_ratio = 0.5},
    [OCS_LAYER_CIRRUS] = {.name = "cirrus",
                          .cov = {1000e3, 0, 4, {-1.5, -0.5, 1.0}},
                          .cell = {30e3, 4e3, 3, {2.0, 1.0, 0.5}},
                          .det = {6e3, 1.5e3, 3, {1.0, -1.5, 0.8}},
                          .axis = {0.1, 0.3, 1.0}, .wind = 25.0,
                          .s_w = 0.25, .a0 = 0.2, .a1 = 3.0,
                          .h_c = 10000.0, .H_lo = 1300.0, .H_hi = 1300.0, .p_lo = 2, .p_hi = 2,
                          .e = 0.3, .k_d = 2.5, .F_w = 0.35,
                          .phase = OCS__ICE, .wc = 2.5e-5, .prof_lo = 1.0},
};


/* θ(cov): the (1 - cov) quantile of a 4-octave fBm (lacunarity 2, gain 0.5) over the sphere, at
 * cov = k/32 (measured once over 2e6 random directions; mean 0, sd 0.160, range ±0.64), so that
 * the coverage map has cloud (W > 0) on about a fraction cov of the planet. */
static const double ocs__cov_quantile[33] = {
    1.0,       0.295441,  0.247378,  0.214582,  0.188573,  0.166320,  0.146680,  0.128879,  0.112226,
    0.096513,  0.081701,  0.067319,  0.053357,  0.039684,  0.026436,  0.013173,  0.000039,  -0.013193,
    -0.026402, -0.039716, -0.053249, -0.067112, -0.081505, -0.096415, -0.112066, -0.128550, -0.146377,
    -0.165978, -0.188179, -0.214242, -0.247163, -0.295529, -1.0 /* replaced by -1 - s_w */};

static double ocs__theta(double cov, double s_w) {
  if (!(cov > 0.0)) return 1.0;              /* C ≤ 1: W = 0 everywhere */
  if (cov >= 1.0) return -1.0 - s_w;         /* C ≥ -1: W = 1 everywhere */
  double x = cov * 32.0;
  int k = (int)x;
  double f = x - (double)k;
  double a = ocs__cov_quantile[k], b = k + 1 == 32 ? -1.0 - s_w : ocs__cov_quantile[k + 1];
  return a + (b - a) * f;
}

static double ocs__fbm_lipschitz(const oc_fbm_t *f) {
  double num = 0.0, den = 0.0, a = 1.0, fr = 1.0;
  for (int i = 0; i < f->octaves; i++) {
    num += a * fr;
    den += a;
    a *= f->gain;
    fr *= f->lacunarity;
  }
  return OC_NOISE_LIPSCHITZ * num / den;
}


/* Motion step of a level at t (0 when the source is static). */
static int64_t ocs__motion_step(const ocs__proc_t *P, int level, double t) {
  if (!P->base.animated || !isfinite(t)) return 0;
  double y = ldexp(t / P->dt0, level);
  const double lim = 35184372088832.0; /* 2^45 */
  y = y < -lim ? -lim : (y > lim ? lim : y);
  return (int64_t)floor(y);
}

/* m rounded down to a multiple of 2^j (j < 63): the level step at which a layer that moves once
 * every 2^j level steps last moved. */
static int64_t ocs__floor_pow2(int64_t m, int j) {
  int64_t d = (int64_t)1 << j, r = m % d;
  return m - (r < 0 ? r + d : r);
}

/* The evaluation frame. level ≥ 0: a brick of that level (each layer's motion time snapped to its
 * own step, 2^jstep level steps: a quarter of a voxel at the layer's own fastest motion, rounded
 * down to a power of two times the level's, so every layer's step boundary is a level step
 * boundary; weather quantised; detail octaves for the level); level < 0: a point at exactly t. */
void ocs__frame(const ocs__proc_t *P, int level, double t, ocs__frame_t *F) {
  int64_t m = level >= 0 ? ocs__motion_step(P, level, t) : 0;
  double point_t = P->base.animated && isfinite(t) ? t : 0.0;
  ocs_weather_params_t w;
  ocs_weather_at(&P->weather, isfinite(t) ? t : 0.0, level >= 0, &w);
  F->mask = 0;
  F->sigma_scale = P->sigma_scale;
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    const ocs__layer_t *L = &ocs__layers[l];
    const ocs__lstate_t *S = &P->L[l];
    ocs__lframe_t *lf = &F->l[l];
    if (!(w.cov[l] > 0.0) || !(w.wc[l] > 0.0) || !(P->sigma_scale > 0.0)) continue;
    F->mask |= 1u << l;
    double tm = level >= 0 ? (double)ocs__floor_pow2(m, S->jstep) * ldexp(P->dt0, -level) : point_t;
    lf->theta = ocs__theta(w.cov[l], L->s_w);
    lf->wc = L->wc * w.wc[l];
    /* Rodrigues: the rotation by -ω·tm about the axis takes a planet point to where its pattern
     * was at t = 0. */
    double s, c;
    ocs__sincos(-S->omega * tm, &s, &c);
    const double *a = S->axis;
    double k = 1.0 - c;
    lf->M[0] = c + k * a[0] * a[0];
    lf->M[1] = k * a[0] * a[1] - s * a[2];
    lf->M[2] = k * a[0] * a[2] + s * a[1];
    lf->M[3] = k * a[1] * a[0] + s * a[2];
    lf->M[4] = c + k * a[1] * a[1];
    lf->M[5] = k * a[1] * a[2] - s * a[0];
    lf->M[6] = k * a[2] * a[0] - s * a[1];
    lf->M[7] = k * a[2] * a[1] + s * a[0];
    lf->M[8] = c + k * a[2] * a[2];
    const ocs__nspec_t *ns[3] = {&L->cov, &L->cell, &L->det};
    static const double zero[3] = {0.0, 0.0, 0.0};
    for (int f = 0; f < 3; f++) {
      double d[3] = {tm * ns[f]->drift[0], tm * ns[f]->drift[1], tm * ns[f]->drift[2]};
      ocs__coords(S, f, d, zero, lf->off[f]);
    }
    lf->det = S->fdet;
    lf->det_scale = 1.0;
    ocs__col_margins(level, l, &lf->kmargin, &lf->amargin);
    if (level >= 0 && OCS_PROC_OCTAVE_DROP > 0.0) {
      double keep = OCS_PROC_OCTAVE_DROP * ocs__voxel_size(level);
      double lam = L->det.lambda_short > 0.0 ? L->det.lambda_short : L->det.lambda;
      int n = 1;
      while (n < S->fdet.octaves && ldexp(lam, -n) >= keep) n++;
      double used = 0.0, all = 0.0, amp = 1.0;
      for (int i = 0; i < S->fdet.octaves; i++, amp *= S->fdet.gain) {
        all += amp;
        if (i < n) used += amp;
      }
      lf->det.octaves = n;
      lf->det_scale = used / all;
    }
  }
}

/*-*** The finest σt ***/


/* One layer at one point (r = |p|, h = r - R), the scalar twin of ocs__layer_batch(). */
static double ocs__layer_point(const ocs__proc_t *P, const ocs__frame_t *F, int l, const double p[3], double r,
                               double h) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  if (h < S->band_lo || h > S->band_hi) return 0.0;
  double q[3], X[3], xyz[3];
  ocs__rotate(lf->M, p, q);
  double s = OCS__R / r;
  X[0] = q[0] * s, X[1] = q[1] * s, X[2] = q[2] * s;
  ocs__coords(S, OCS__COV, X, lf->off[OCS__COV], xyz);
  double W = ocs__w(L, lf, (float)oc_fbm3(xyz[0], xyz[1], xyz[2], &S->fcov));
  if (!(W > 0.0)) return 0.0;
  ocs__coords(S, OCS__CELL, X, lf->off[OCS__CELL], xyz);
  double V = ocs__v(L, (float)oc_fbm3(xyz[0], xyz[1], xyz[2], &S->fcell));
  if (!(V > 0.0)) return 0.0;
  double G = W * V - ocs__q(L, h);
  if (!(G > 0.0)) return 0.0;
  ocs__coords(S, OCS__DET, q, lf->off[OCS__DET], xyz);
  return ocs__sigma(L, F, lf, G, (float)oc_fbm3(xyz[0], xyz[1], xyz[2], &lf->det), h);
}

static double ocs__eval_point(const ocs__proc_t *P, const ocs__frame_t *F, const double p[3]) {
  double r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), h = r - OCS__R, v = 0.0;
  if (!isfinite(r) || !(r > 0.0)) return 0.0;
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if (F->mask >> l & 1u) v += ocs__layer_point(P, F, l, p, r, h);
  return v;
}

static double ocs__proc_point(const ocs_source_t *s, oc_dvec3 p, double t) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  ocs__frame_t F;
  ocs__frame(P, -1, t, &F);
  double pp[3] = {p.x, p.y, p.z};
  return ocs__eval_point(P, &F, pp);
}

/*-*** Bound ***/

/* The directions a box covers: within angle θ of its centre's direction ĉ. */
typedef struct {
  double c[3];       /* box centre, planet frame */
  double u[3];       /* ĉ */
  double e1[3], e2[3]; /* tangent frame at ĉ */
  double chord, tan_t; /* 2 sin(θ/2), tan θ */
} ocs__cap_t;

/*! Lipschitz margin below which the grid is not refined further, and above which it is not worth
 *  evaluating (the noise values span about ±0.6). */
#define OCS__GRID_EPS 0.02
#define OCS__GRID_USEFUL 0.3
/* The first grids' largest half-size (ocs__layer_ranges; procedural.h). */
int ocs__grid_first = 2;

/* The grid half-size m (≤ grid) of a pattern over a cap: 0 where no grid could bring the Lipschitz
 * margin under OCS__GRID_USEFUL (or where the whole cap's is already under OCS__GRID_EPS). */
static int ocs__dir_m(const ocs__proc_t *P, int l, int f, const ocs__cap_t *cap, int grid) {
  const ocs__lstate_t *S = &P->L[l];
  double lip = (f == OCS__COV ? S->lip_cov : S->lip_cell) * OCS__R;
  if (!(grid > 0 && lip * cap->chord > OCS__GRID_EPS && lip * cap->tan_t * 0.70710678 / grid < OCS__GRID_USEFUL)) return 0;
  double want = ceil(lip * cap->tan_t * 0.70710678 / OCS__GRID_EPS);
  return want > grid ? grid : (int)want;
}

/* Range of a pattern on the reference sphere (coverage or cells: functions of direction only)
 * over the directions of a box. m = 0: its value at ĉ ± Lipschitz × R·chord. m > 0: a (2m + 1)²
 * grid over the gnomonic tangent plane at ĉ, t in [-tan θ, tan θ]²; the map t → normalize(ĉ + t)
 * is 1-Lipschitz (|ĉ + t| ≥ 1), so every covered direction's point lies within R·δ/√2 of a grid
 * point's, δ = tan θ / m. The noise Lipschitz bound (OC_NOISE_LIPSCHITZ) turns that into a margin;
 * 1e-6 more covers the float rounding of the noise values. *margin: the margin added to the samples'
 * extremes. */
static void ocs__dir_range(const ocs__proc_t *P, const ocs__lframe_t *lf, int l, int f, const ocs__cap_t *cap, int m,
                           double *vmin, double *vmax, double *margin) {
  const ocs__lstate_t *S = &P->L[l];
  const oc_fbm_t *fb = f == OCS__COV ? &S->fcov : &S->fcell;
  double lip = (f == OCS__COV ? S->lip_cov : S->lip_cell) * OCS__R;
  enum { MAXP = (2 * OCS_PROC_BOUND_GRID + 1) * (2 * OCS_PROC_BOUND_GRID + 1) };
  double xyz[3 * MAXP];
  float val[MAXP];
  int n = 0, side = 2 * m + 1;
  double delta = m > 0 ? cap->tan_t / m : 0.0;
  do { /* at least the centre */
    double i = (double)(n % side - m) * delta, j = (double)(n / side - m) * delta, v[3], X[3], q[3];
    for (int k = 0; k < 3; k++) v[k] = cap->u[k] + i * cap->e1[k] + j * cap->e2[k];
    double s = OCS__R / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    X[0] = v[0] * s, X[1] = v[1] * s, X[2] = v[2] * s;
    ocs__rotate(lf->M, X, q);
    ocs__coords(S, f, q, lf->off[f], &xyz[3 * n]);
  } while (++n < side * side);
  oc_fbm3_batch(xyz, n, fb, val);
  double lo = val[0], hi = val[0];
  for (int i = 1; i < n; i++) {
    lo = val[i] < lo ? (double)val[i] : lo;
    hi = val[i] > hi ? (double)val[i] : hi;
  }
  *margin = (m > 0 ? lip * delta * 0.70710679 : lip * cap->chord) * (1.0 + 1e-9) + 1e-6;
  *vmin = lo - *margin;
  *vmax = hi + *margin;
}

/* The directions and altitudes an axis-aligned box covers. far = 0: the box reaches the planet
 * centre (no finite angle; patterns range over [-1, 1]). */
typedef struct {
  double hmin, hmax; /* altitude range of the box, widened by 1e-6 m */
  int far;
  double sn;         /* sin θ */
  ocs__cap_t cap;
} ocs__geom_t;

static void ocs__box_geom(const double lo[3], const double hi[3], int tangent, ocs__geom_t *g) {
  ocs__cap_t *cap = &g->cap;
  double near2 = 0.0, far2 = 0.0, d2 = 0.0, *c = cap->c;
  for (int k = 0; k < 3; k++) {
    double n = lo[k] > 0.0 ? lo[k] : (hi[k] < 0.0 ? -hi[k] : 0.0);
    double f = fabs(lo[k]) > fabs(hi[k]) ? fabs(lo[k]) : fabs(hi[k]);
    near2 += n * n;
    far2 += f * f;
    c[k] = 0.5 * (lo[k] + hi[k]);
    d2 += 0.25 * (hi[k] - lo[k]) * (hi[k] - lo[k]);
  }
  g->hmin = sqrt(near2) - OCS__R - 1e-6, g->hmax = sqrt(far2) - OCS__R + 1e-6;
  double cr = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), d = sqrt(d2);
  /* A finite angle (the box does not reach the planet centre). */
  g->far = cr > 1.000001 * d;
  if (!g->far) return;
  double sn = d / cr, cs = sqrt(1.0 - sn * sn);
  g->sn = sn;
  cap->chord = sn / sqrt(0.5 * (1.0 + cs)) * (1.0 + 1e-9); /* 2 sin(θ/2) without cancellation */
  cap->tan_t = sn / cs * (1.0 + 1e-9);
  for (int k = 0; k < 3; k++) cap->u[k] = c[k] / cr;
  if (!tangent) return;
  /* e1 ⊥ ĉ from the axis least aligned with it, e2 = ĉ × e1. */
  double au[3] = {fabs(cap->u[0]), fabs(cap->u[1]), fabs(cap->u[2])};
  int a = au[0] < au[1] ? (au[0] < au[2] ? 0 : 2) : (au[1] < au[2] ? 1 : 2);
  double ax[3] = {a == 0, a == 1, a == 2}, dt = cap->u[a];
  double e[3] = {ax[0] - dt * cap->u[0], ax[1] - dt * cap->u[1], ax[2] - dt * cap->u[2]};
  double en = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
  for (int k = 0; k < 3; k++) cap->e1[k] = e[k] / en;
  cap->e2[0] = cap->u[1] * cap->e1[2] - cap->u[2] * cap->e1[1];
  cap->e2[1] = cap->u[2] * cap->e1[0] - cap->u[0] * cap->e1[2];
  cap->e2[2] = cap->u[0] * cap->e1[1] - cap->u[1] * cap->e1[0];
}

/* ocs__layer_max() up to its σt: G, the most the layer's density argument A' − Q(h) may reach over
 * the box (> 0: the layer may hold cloud there), or 0, with bb's ranges, mask and wone set as
 * ocs__layer_max() sets them. Where only whether a box may hold cloud matters (the sampler's voxel
 * bounds) this is enough: the σt after it costs two libm powers, 1 % of the world's instructions. */
static double ocs__layer_g(const ocs__proc_t *P, const ocs__frame_t *F, int l, double hmin, double hmax, double cmin,
                           double cmax, double kmax, ocs__bb_t *bb) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  double a = hmin > S->band_lo ? hmin : S->band_lo, b = hmax < S->band_hi ? hmax : S->band_hi;
  bb->cmin[l] = cmin, bb->cmax[l] = cmax, bb->kmax[l] = kmax;
  if (a > b) return 0.0;
  double W = ocs__sat((cmax - lf->theta) / L->s_w);
  if (!(W > 0.0)) return 0.0;
  double km = kmax + lf->kmargin; /* the fast filter's estimate may reach this far (procedural_columns.c) */
  double A = W * ocs__sat(L->a0 + L->a1 * (km > 1.0 ? 1.0 : km)) + lf->amargin;
  double G = A - ocs__qmin(L, a, b) + 1e-9;
  if (!(G > 0.0)) return 0.0;
  bb->mask |= 1u << l;
  if (cmin >= lf->theta + L->s_w + 1e-9) bb->wone |= 1u << l;
  return G;
}

/* A layer's σt maximum over altitudes [hmin, hmax] given its coverage range [cmin, cmax] and cell
 * maximum kmax (recorded in bb, with the layer's mask and W = 1 bits). Detail erosion is ≥ 0, so it
 * never raises the bound; the frame's margins cover the fast filter's estimate; small margins
 * cover ulp-level non-monotonicity. */
static double ocs__layer_max(const ocs__proc_t *P, const ocs__frame_t *F, int l, double hmin, double hmax,
                             double cmin, double cmax, double kmax, ocs__bb_t *bb) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  double G = ocs__layer_g(P, F, l, hmin, hmax, cmin, cmax, kmax, bb);
  if (!(G > 0.0)) return 0.0;
  double a = hmin > S->band_lo ? hmin : S->band_lo, b = hmax < S->band_hi ? hmax : S->band_hi;
  double phi = ocs__sat(G / L->F_w);
  double wc = lf->wc * ocs__prof_up(L, b) * ocs__prof_down(L, a) * phi, rho = ocs__rho_air(a), s;
  if (L->phase == OCS__LIQUID)
    s = ocg_sigma_t_liquid(wc, rho);
  else if (L->phase == OCS__ICE)
    s = ocg_sigma_t_ice(wc, rho);
  else {
    double sl = ocg_sigma_t_liquid(wc, rho), si = ocg_sigma_t_ice(wc * L->ice_ratio, rho);
    s = sl > si ? sl : si; /* σt is a convex combination of the two */
  }
  return F->sigma_scale * s * (1.0 + 1e-6);
}

/* Intersects layer l's ranges with grids of half-sizes pc (coverage) and pk (cells), 0: none. *rc,
 * *rk: the least the upper ends can be after any finer grid (the samples' extremes without their
 * margins, within the ranges), or the ranges' own ends where no grid ran. */
static void ocs__grid_ranges(const ocs__proc_t *P, const ocs__lframe_t *lf, int l, const ocs__geom_t *g, int pc, int pk,
                             double *cmin, double *cmax, double *kmax, double *rc, double *rk) {
  double lo, hi, mg;
  *rc = *cmax, *rk = *kmax;
  if (pc > 0) {
    ocs__dir_range(P, lf, l, OCS__COV, &g->cap, pc, &lo, &hi, &mg);
    *cmin = fmax(*cmin, lo), *cmax = fmin(*cmax, hi), *rc = fmin(*cmax, hi - mg);
  }
  if (pk > 0 && *cmax > lf->theta) { /* else W = 0 */
    ocs__dir_range(P, lf, l, OCS__CELL, &g->cap, pk, &lo, &hi, &mg);
    *kmax = fmin(*kmax, hi), *rk = fmin(*kmax, hi - mg);
  }
}

/* Ranges of layer l's coverage (cmin, cmax) and cells (kmax) over the directions of g, each the
 * intersection of conservative ranges, cheapest first (docs/performance.md, levers 15 and 16):
 *   1. the centre's values with their Lipschitz margins over the whole cap (two noise points);
 *   2. where the layer stays positive, grids of at most ocs__grid_first a side (up to 25 points);
 *   3. the full grids (up to (2·grid + 1)² points) only where they may still bound the layer to 0:
 *      a full grid's upper end is at least every coarse sample (each lies within the full grid's
 *      δ/√2 of one of its points), so where the coarse samples' extremes, without margins, keep the
 *      layer positive, the full grid cannot decide, and is not evaluated. */
static void ocs__layer_ranges(const ocs__proc_t *P, const ocs__frame_t *F, int l, const ocs__geom_t *g, int grid,
                              double *cmin, double *cmax, double *kmax) {
  const ocs__lframe_t *lf = &F->l[l];
  double kmin, mg, rc, rk;
  ocs__bb_t scratch;
  *kmax = 1.0;
  ocs__dir_range(P, lf, l, OCS__COV, &g->cap, 0, cmin, cmax, &mg);
  if (*cmax > lf->theta) ocs__dir_range(P, lf, l, OCS__CELL, &g->cap, 0, &kmin, kmax, &mg); /* else W = 0 */
  if (grid <= 0 || !(ocs__layer_max(P, F, l, g->hmin, g->hmax, *cmin, *cmax, *kmax, &scratch) > 0.0)) return;
  int mc = ocs__dir_m(P, l, OCS__COV, &g->cap, grid), mk = ocs__dir_m(P, l, OCS__CELL, &g->cap, grid);
  int fc = mc < ocs__grid_first ? mc : ocs__grid_first, fk = mk < ocs__grid_first ? mk : ocs__grid_first;
  ocs__grid_ranges(P, lf, l, g, fc, fk, cmin, cmax, kmax, &rc, &rk);
  if (mc == fc && mk == fk) return; /* no finer grid */
  if (!(ocs__layer_max(P, F, l, g->hmin, g->hmax, *cmin, *cmax, *kmax, &scratch) > 0.0)) return; /* decided */
  if (ocs__layer_max(P, F, l, g->hmin, g->hmax, *cmin, rc, rk, &scratch) > 0.0) return;             /* cannot decide */
  ocs__grid_ranges(P, lf, l, g, mc > fc ? mc : 0, mk > fk ? mk : 0, cmin, cmax, kmax, &rc, &rk);
}

/* Conservative maximum of σt over an axis-aligned box, restricted to the layers in `only`. The
 * coverage and cell values are bounded by ocs__dir_range() (grid ≤ `grid`, 0: the centre only);
 * layers in `reuse` take their ranges from `inherit` (an enclosing box) instead. */
double ocs__box_max(const ocs__proc_t *P, const ocs__frame_t *F, unsigned only, const double lo[3],
                    const double hi[3], int grid, const ocs__bb_t *inherit, unsigned reuse, ocs__bb_t *bb) {
  bb->mask = bb->wone = 0;
  unsigned todo = F->mask & only;
  if (!todo) return 0.0;
  ocs__geom_t g;
  ocs__box_geom(lo, hi, 1, &g);
  if (g.far && !(g.sn < 0.866)) grid = 0; /* the tangent grid needs an angle below 60° */
  double total = 0.0;
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    if (!(todo >> l & 1u)) continue;
    const ocs__lstate_t *S = &P->L[l];
    if ((g.hmin > S->band_lo ? g.hmin : S->band_lo) > (g.hmax < S->band_hi ? g.hmax : S->band_hi)) continue;
    double cmin = -1.0, cmax = 1.0, kmax = 1.0;
    if (inherit && (reuse >> l & 1u))
      cmin = inherit->cmin[l], cmax = inherit->cmax[l], kmax = inherit->kmax[l];
    else if (g.far)
      ocs__layer_ranges(P, F, l, &g, grid, &cmin, &cmax, &kmax);
    total += ocs__layer_max(P, F, l, g.hmin, g.hmax, cmin, cmax, kmax, bb);
  }
  return total;
}

/*-*** The node bound, remembered ***/

static uint64_t ocs__proc_time_step(const ocs_source_t *s, int level, double t);
static uint64_t ocs__proc_node_step(const ocs_source_t *s, oc_key_t key, double t);

/* Node key's sample footprint: the node grown by size/14 on every side. */
static void ocs__footprint(oc_key_t key, double lo[3], double hi[3]) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = size / 14.0, a[3] = {o.x, o.y, o.z};
  for (int k = 0; k < 3; k++) lo[k] = a[k] - g, hi[k] = a[k] + size + g;
}

/* A node's bound over its sample footprint, as the node-bound cache holds it: the total and the
 * bb (masks, per-layer ranges) as 64-bit words, bit for bit. */
enum { OCS__NB_WORDS = 2 + 3 * OCS_LAYER_COUNT };

static void ocs__nb_pack(double total, const ocs__bb_t *bb, uint64_t w[OCS__NB_WORDS]) {
  memcpy(&w[0], &total, sizeof total);
  w[1] = (uint64_t)bb->mask << 32 | bb->wone;
  memcpy(&w[2], bb->cmin, sizeof bb->cmin);
  memcpy(&w[2 + OCS_LAYER_COUNT], bb->cmax, sizeof bb->cmax);
  memcpy(&w[2 + 2 * OCS_LAYER_COUNT], bb->kmax, sizeof bb->kmax);
}

static double ocs__nb_unpack(const uint64_t w[OCS__NB_WORDS], ocs__bb_t *bb) {
  double total;
  memcpy(&total, &w[0], sizeof total);
  bb->mask = (unsigned)(w[1] >> 32), bb->wone = (unsigned)w[1];
  memcpy(bb->cmin, &w[2], sizeof bb->cmin);
  memcpy(bb->cmax, &w[2 + OCS_LAYER_COUNT], sizeof bb->cmax);
  memcpy(bb->kmax, &w[2 + 2 * OCS_LAYER_COUNT], sizeof bb->kmax);
  return total;
}

/* σt's maximum over node key's sample footprint (the node grown by size/14) at the frame F of the
 * key's level at t, with its ranges in nb. The planner's bound of a node and its sampler's
 * ocs__brick_begin() ask the same question one after the other: the answer, a pure function of
 * (key, the node's own step: the layers it skips are those whose band misses the footprint, which
 * ocs__proc_node_step leaves out too), is remembered in P->nbc and returned bit for bit. */
static double ocs__node_max(const ocs__proc_t *P, oc_key_t key, double t, const ocs__frame_t *F, ocs__bb_t *nb) {
  uint64_t step = 0, w[OCS__NB_WORDS];
  if (P->nbc) {
    step = ocs__proc_node_step(&P->base, key, t);
    if (ocs_seqcache_get(P->nbc, key, step, w)) return ocs__nb_unpack(w, nb);
  }
  double lo[3], hi[3];
  ocs__footprint(key, lo, hi);
  memset(nb, 0, sizeof *nb); /* layers the box skips leave their ranges unset: cached as 0 */
  double m = ocs__box_max(P, F, ~0u, lo, hi, OCS_PROC_BOUND_GRID, NULL, 0, nb);
  if (P->nbc) {
    ocs__nb_pack(m, nb, w);
    ocs_seqcache_put(P->nbc, key, step, w);
  }
  return m;
}

int ocs__brick_begin(const ocs_source_t *s, oc_key_t key, double t, ocs__brick_t *B) {
  const ocs__proc_t *P = B->P = (const ocs__proc_t *)s;
  ocs__frame_t *F = &B->F;
  ocs__bb_t *nb = &B->nb;
  int level = B->level = oc_key_level(key);
  if (level < 0) return OC_EINVAL;
  ocs__frame(P, level, t, F);
  if (!F->mask) return 0;
  if (!(ocs__node_max(P, key, t, F, nb) > 0.0)) return 0;
  /* Per-voxel bounds re-evaluate a layer's noise only where that can decide something: the node's
   * coverage is in the ramp (a voxel may be all 0 or all 1), or the cell bound is informative at
   * the voxel's size (Lipschitz step below 1/2). Elsewhere they reuse the node's ranges. */
  double u = ocs__voxel_size(level);
  B->reuse = 0;
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if ((nb->wone >> l & 1u) && P->L[l].lip_cell * 0.8660254 * u >= 0.5) B->reuse |= 1u << l;
  return 1;
}

/* The geometry of n³ cubes of c voxels a side tiling a brick (c = 1: its voxels; c = 2: blocks of
 * 2³ voxels) for their bounds: ocs__box_geom(tangent 0) of each, except that the cap's chord (the
 * Lipschitz margin's length) is the largest of them, from a half-diagonal above every cube's (the
 * edges hi − lo come out within 4e-9 m of c·u) and the least distance of a cube's centre from the
 * planet centre: chord grows with d/|centre|, so it bounds every cube's and the bounds stay
 * conservative, looser by under (7√3·u/|centre|) of a margin. It saves three square roots and four
 * divisions per cube, and the cap of a cube that no active layer's band meets, or that is not live
 * (live[i] = 0: a cube already proven empty), is not made at all. The direction ĉ, whose coverage
 * is the estimate's W, is the same division as ocs__box_geom's. Where the shortcut does not apply
 * (cubes that subtend large angles: the first levels) each cube gets ocs__box_geom. */
static inline void ocs__cube_box(const uint32_t ic[3], double u, int c, int v, double lo[3], double hi[3]) {
  int n = 8 / c, ijk[3] = {v % n, v / n % n, v / (n * n)};
  for (int a = 0; a < 3; a++) {
    double cc = -OC_ROOT_HALF + ((double)(7 * (int64_t)ic[a] + c * ijk[a]) + 0.5 * (double)(c - 1)) * u;
    lo[a] = cc - 0.5 * (double)c * u, hi[a] = cc + 0.5 * (double)c * u;
  }
}

/* Per axis and cube index along it, what ocs__cube_geoms adds up per cube: the squares of the
 * nearest and farthest coordinates and the centre (a cube's box is a product of its axes' ranges,
 * so these are 3 × 8 values, not 3 per cube; the sums keep their order, so the same bits). */
typedef struct {
  double near2[3][8], far2[3][8], cen[3][8];
} ocs__axes_t;

static void ocs__cube_axes(const uint32_t ic[3], double u, int c, ocs__axes_t *x) {
  int n = 8 / c;
  for (int j = 0; j < n; j++) {
    double lo[3], hi[3];
    ocs__cube_box(ic, u, c, j * (1 + n + n * n), lo, hi); /* cube (j, j, j): each axis at index j */
    for (int a = 0; a < 3; a++) {
      double nr = lo[a] > 0.0 ? lo[a] : (hi[a] < 0.0 ? -hi[a] : 0.0);
      double f = fabs(lo[a]) > fabs(hi[a]) ? fabs(lo[a]) : fabs(hi[a]);
      x->near2[a][j] = nr * nr, x->far2[a][j] = f * f, x->cen[a][j] = 0.5 * (lo[a] + hi[a]);
    }
  }
}

static void ocs__cube_geoms(const uint32_t ic[3], double u, int c, double band_lo, double band_hi,
                            const uint8_t *live, ocs__geom_t *g) {
  int n = 8 / c, N = n * n * n;
  double crmin = INFINITY, e = (double)c * u;
  ocs__axes_t x;
  ocs__cube_axes(ic, u, c, &x);
  for (int v = 0; v < N; v++) {
    g[v].far = 0;
    if (live && !live[v]) { /* skipped by every layer's band test */
      g[v].hmin = INFINITY, g[v].hmax = -INFINITY;
      continue;
    }
    int ijk[3] = {v % n, v / n % n, v / (n * n)};
    double near2 = 0.0, far2 = 0.0;
    for (int a = 0; a < 3; a++) near2 += x.near2[a][ijk[a]], far2 += x.far2[a][ijk[a]];
    g[v].hmin = sqrt(near2) - OCS__R - 1e-6, g[v].hmax = sqrt(far2) - OCS__R + 1e-6;
    if (g[v].hmin > band_hi || g[v].hmax < band_lo) continue; /* no active layer here: no cap */
    double *cen = g[v].cap.c;
    for (int k = 0; k < 3; k++) cen[k] = x.cen[k][ijk[k]];
    double cr = sqrt(cen[0] * cen[0] + cen[1] * cen[1] + cen[2] * cen[2]);
    for (int k = 0; k < 3; k++) g[v].cap.u[k] = cen[k] / cr;
    g[v].far = 1;
    crmin = cr < crmin ? cr : crmin;
  }
  if (crmin == INFINITY) return; /* no cube meets a band */
  double d = 0.86602540378443876 * (e + 4e-9) * (1.0 + 1e-12), sn = d / crmin;
  if (sn < 0.5) {
    double cs = sqrt(1.0 - sn * sn), chord = sn / sqrt(0.5 * (1.0 + cs)) * (1.0 + 1e-9) * (1.0 + 1e-12);
    for (int v = 0; v < N; v++)
      if (g[v].far) g[v].sn = sn, g[v].cap.chord = chord;
    return;
  }
  for (int v = 0; v < N; v++) {
    if (!g[v].far) continue;
    double lo[3], hi[3];
    ocs__cube_box(ic, u, c, v, lo, hi);
    ocs__box_geom(lo, hi, 0, &g[v]);
  }
}

/* The bounds' workspace: one brick's cubes (156 KiB, thread-local: made once per producer thread). */
typedef struct {
  ocs__geom_t g[OC_BRICK_VOXELS];
  ocs__bb_t bb[OC_BRICK_VOXELS];
  double total[OC_BRICK_VOXELS], cmin[OC_BRICK_VOXELS], cmax[OC_BRICK_VOXELS], kmax[OC_BRICK_VOXELS];
  double xyz[3 * OC_BRICK_VOXELS];
  float val[OC_BRICK_VOXELS];
  int sel[OC_BRICK_VOXELS];
} ocs__cubes_t;

/* The pattern ranges of one layer over the cubes w->g[0..n) (ocs__dir_range with grid 0), each
 * pattern evaluated for all cubes in one batch (a call per cube and pattern spent more on the
 * fBm's set-up than on its octaves). */
static void ocs__cube_ranges(const ocs__brick_t *B, int l, int n, ocs__cubes_t *w, double *ccentre) {
  const ocs__lstate_t *S = &B->P->L[l];
  const ocs__lframe_t *lf = &B->F.l[l];
  const ocs__bb_t *nb = &B->nb;
  int inh = (B->reuse >> l & 1u) != 0;
  double lip_k = S->lip_cell * OCS__R;
  for (int f = OCS__COV; f <= OCS__CELL; f++) {
    int m = 0;
    for (int v = 0; v < n; v++) {
      const ocs__geom_t *g = &w->g[v];
      if (f == OCS__COV) w->cmin[v] = -1.0, w->cmax[v] = 1.0, w->kmax[v] = 1.0;
      if ((g->hmin > S->band_lo ? g->hmin : S->band_lo) > (g->hmax < S->band_hi ? g->hmax : S->band_hi)) continue;
      if (inh) {
        w->cmin[v] = nb->cmin[l], w->cmax[v] = nb->cmax[l], w->kmax[v] = nb->kmax[l];
        if (ccentre) ccentre[v] = INFINITY; /* inherited only where W = 1 over the node */
        continue;
      }
      if (!g->far || (f == OCS__CELL && !(w->cmax[v] > lf->theta))) continue;
      /* |K| ≤ 1, so K(centre) + margin ≥ margin − 1: where that reaches the node's cell bound,
       * the cube's evaluation cannot beat it (levels whose resolved cells are finer than a cube) */
      if (f == OCS__CELL && lip_k * g->cap.chord * (1.0 + 1e-9) + 1e-6 - 1.0 >= nb->kmax[l]) {
        w->kmax[v] = nb->kmax[l];
        continue;
      }
      double X[3], q[3];
      for (int k = 0; k < 3; k++) X[k] = g->cap.u[k] * OCS__R;
      ocs__rotate(lf->M, X, q);
      ocs__coords(S, f, q, lf->off[f], &w->xyz[3 * m]);
      w->sel[m++] = v;
    }
    oc_fbm3_batch(w->xyz, m, f == OCS__COV ? &S->fcov : &S->fcell, w->val);
    double lip = (f == OCS__COV ? S->lip_cov : S->lip_cell) * OCS__R;
    for (int i = 0; i < m; i++) {
      int v = w->sel[i];
      double margin = lip * w->g[v].cap.chord * (1.0 + 1e-9) + 1e-6;
      if (f == OCS__COV) {
        w->cmin[v] = (double)w->val[i] - margin, w->cmax[v] = (double)w->val[i] + margin;
        if (ccentre) ccentre[v] = (double)w->val[i];
      } else /* the node's cell bound holds in the cube too */
        w->kmax[v] = fmin((double)w->val[i] + margin, nb->kmax[l]);
    }
  }
}

/* For each of the cubes w->g[0..n): w->bb as ocs__box_max(grid 0) gives it, and w->total > 0 where that
 * bound is > 0 (the sum of the layers' ocs__layer_g(), not σt: only its sign is read). */
static void ocs__cube_bounds(const ocs__brick_t *B, int n, ocs__cubes_t *w, double (*ccentre)[OC_BRICK_VOXELS]) {
  for (int v = 0; v < n; v++) w->bb[v].mask = w->bb[v].wone = 0, w->total[v] = 0.0;
  unsigned todo = B->F.mask & B->nb.mask;
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    if (!(todo >> l & 1u)) continue;
    const ocs__lstate_t *S = &B->P->L[l];
    ocs__cube_ranges(B, l, n, w, ccentre ? ccentre[l] : NULL);
    for (int v = 0; v < n; v++) {
      const ocs__geom_t *g = &w->g[v];
      if ((g->hmin > S->band_lo ? g->hmin : S->band_lo) > (g->hmax < S->band_hi ? g->hmax : S->band_hi)) continue;
      /* only whether a cube may hold cloud is read (vmask, live): G > 0 for every cube where σt's
       * bound is > 0 (a few more where the water profile makes it 0: pieces then find 0) */
      w->total[v] += ocs__layer_g(B->P, &B->F, l, g->hmin, g->hmax, w->cmin[v], w->cmax[v], w->kmax[v], &w->bb[v]);
    }
  }
}

/* The per-voxel bounds of a brick, in two passes: blocks of 2³ voxels first, then the voxels of the
 * blocks that may hold cloud (a voxel inside a block proven empty is empty: the block's bound
 * holds over the voxel's cube too). A block costs what a voxel costs; around the planet's camera
 * 60 % of the blocks at levels 14–16 are proven empty, and the process CPU fell 2–3 % (a first
 * pass of 4³ octants saved less than it cost; docs/performance.md, lever 11). */
void ocs__voxel_bounds(const ocs__brick_t *B, oc_key_t key, uint8_t vmask[OC_BRICK_VOXELS], uint8_t vwone[OC_BRICK_VOXELS],
                       double (*ccentre)[OC_BRICK_VOXELS]) {
  enum { N = OC_BRICK_VOXELS, NB = N / 8 };
  static _Thread_local ocs__cubes_t w;
  const ocs__proc_t *P = B->P;
  double u = ocs__voxel_size(oc_key_level(key));
  uint32_t ic[3];
  oc_key_coords(key, &ic[0], &ic[1], &ic[2]);
  double blo = INFINITY, bhi = -INFINITY; /* the active layers' bands together */
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if (B->F.mask & B->nb.mask & (1u << l)) blo = fmin(blo, P->L[l].band_lo), bhi = fmax(bhi, P->L[l].band_hi);
  uint8_t live[N];
  ocs__cube_geoms(ic, u, 2, blo, bhi, NULL, w.g);
  ocs__cube_bounds(B, NB, &w, NULL);
  for (int v = 0; v < N; v++) live[v] = w.total[v % 8 / 2 + 4 * (v / 8 % 8 / 2) + 16 * (v / 64 / 2)] > 0.0;
  ocs__cube_geoms(ic, u, 1, blo, bhi, live, w.g);
  ocs__cube_bounds(B, N, &w, ccentre);
  for (int v = 0; v < N; v++) {
    vmask[v] = w.total[v] > 0.0 ? (uint8_t)w.bb[v].mask : 0;
    vwone[v] = (uint8_t)w.bb[v].wone;
  }
}

/* The level whose node footprint (or node) a box is: bound() is asked about footprints, and a
 * brick's content is snapped to its level's time step. */
static int ocs__level_of_box(oc_dvec3 lo, oc_dvec3 hi) {
  double e = fmax(hi.x - lo.x, fmax(hi.y - lo.y, hi.z - lo.z));
  int best = 0;
  double bestq = INFINITY;
  for (int L = 0; L <= OC_KEY_MAX_LEVEL; L++) {
    double r = e / (oc_key_size(L) * (8.0 / 7.0));
    double q = r > 1.0 ? r : 1.0 / r;
    if (q < bestq) bestq = q, best = L;
  }
  return best;
}

static float ocs__round_up(double x) {
  float f = (float)x;
  if ((double)f < x) f = nextafterf(f, INFINITY);
  return f;
}

/* Reads t only through ocs__frame(level, t): the motion step of the level and the quantised weather
 * (ocs_weather_at(quantised), fixed by the weather step). Both steps are non-decreasing in t, so
 * their sum in ocs__proc_time_step() is equal at two times only when both are: within one weather
 * generation, equal time steps give equal frames and the same bits (bound_by_step; the field caches). */
static void ocs__proc_bound(const ocs_source_t *s, oc_dvec3 lo, oc_dvec3 hi, double t, float *smin, float *smax) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  ocs__frame_t F;
  ocs__frame(P, ocs__level_of_box(lo, hi), t, &F);
  double l3[3] = {lo.x, lo.y, lo.z}, h3[3] = {hi.x, hi.y, hi.z};
  ocs__bb_t bb;
  *smin = 0.0f;
  *smax = ocs__round_up(ocs__box_max(P, &F, ~0u, l3, h3, OCS_PROC_BOUND_GRID, NULL, 0, &bb));
}

/* The bound of a node's sample footprint (ocs_source_vtbl_t.node_bound): ocs__proc_bound's bits
 * (the footprint's level_of_box is the key's level), through the node-bound cache. */
static void ocs__proc_node_bound(const ocs_source_t *s, oc_key_t key, double t, float *smin, float *smax) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  ocs__frame_t F;
  ocs__frame(P, oc_key_level(key), t, &F);
  ocs__bb_t bb;
  *smin = 0.0f;
  *smax = F.mask ? ocs__round_up(ocs__node_max(P, key, t, &F, &bb)) : 0.0f;
}

/*-*** Time ***/

/* The motion part moves one level step every OCS_PROC_STEP_VOXELS voxels of the fastest pattern
 * (Δ_L = Δ_0·2^-L, so a coarse step boundary is always a fine one); the weather part counts
 * transition steps; the generation (high bits) separates the time steps of successive
 * ocs_weather_set() calls so a cached brick from before a change is never reused after it. */
static uint64_t ocs__step_index(const ocs__proc_t *P, uint64_t m, double t) {
  uint64_t k = ocs_weather_step(&P->weather, isfinite(t) ? t : 0.0);
  return (P->weather.generation << 48) + ((m + k) & (((uint64_t)1 << 48) - 1));
}

static uint64_t ocs__proc_time_step(const ocs_source_t *s, int level, double t) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  if (level < 0) level = 0;
  if (level > OC_KEY_MAX_LEVEL) level = OC_KEY_MAX_LEVEL;
  uint64_t m = P->base.animated ? (uint64_t)(ocs__motion_step(P, level, t) + ((int64_t)1 << 46)) : 0;
  return ocs__step_index(P, m, t);
}

/* The jstep of the fastest-stepping layer (the least jstep) whose band meets node key's sample
 * footprint; 63: none. */
static int ocs__node_jstep(const ocs__proc_t *P, oc_key_t key) {
  double lo[3], hi[3];
  ocs__footprint(key, lo, hi);
  ocs__geom_t g;
  ocs__box_geom(lo, hi, 0, &g);
  double h0 = g.hmin - 1.0, h1 = g.hmax + 1.0; /* ocs__box_max's altitudes, 1 m wider for the samples' rounding */
  int j = 63;
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if (P->L[l].band_lo <= h1 && P->L[l].band_hi >= h0 && P->L[l].jstep < j) j = P->L[l].jstep;
  return j;
}

/* The time step of node key's own content (ocs_source_vtbl_t.node_step): the level's, with the
 * motion part rounded down to the step of the fastest-stepping layer whose band meets the node's
 * sample footprint. The layers that do not meet it add exactly 0 there (columns and strata are cut
 * to the band), so the content moves only with those that do; none: with the weather alone. */
static uint64_t ocs__proc_node_step(const ocs_source_t *s, oc_key_t key, double t) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  int level = oc_key_level(key);
  if (!P->base.animated || level < 0) return ocs__proc_time_step(s, level, t);
  int j = ocs__node_jstep(P, key);
  int64_t m = j < 63 ? ocs__floor_pow2(ocs__motion_step(P, level, t), j) : 0;
  return ocs__step_index(P, (uint64_t)(m + ((int64_t)1 << 46)), t);
}

/* An instant in node key's previous own step (ocs_source_vtbl_t.step_before): the middle of the
 * first level step of the 2^j before the one t is in. */
static int ocs__proc_step_before(const ocs_source_t *s, oc_key_t key, double t, double *t0) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  int level = oc_key_level(key);
  if (!P->base.animated || level < 0 || !isfinite(t)) return 0;
  int j = ocs__node_jstep(P, key);
  if (j == 63) return 0; /* it moves with the weather alone */
  int64_t m0 = ocs__floor_pow2(ocs__motion_step(P, level, t), j) - ((int64_t)1 << j);
  *t0 = ldexp(((double)m0 + 0.5) * P->dt0, -level);
  return 1;
}

/* Whether node key's samples at t0 and t1 are the same bits (ocs_source_vtbl_t.same_samples).
 * The samplers read a layer only where the node's bound says it may be non-zero (nb.mask: the
 * voxels' bounds, columns and strata skip the others), and a layer's frame is a function of the
 * quantised weather and the layer's own step alone. So with the same weather step, the layers
 * whose own step differs between t0 and t1 absent from the node's bound at both instants, and the
 * others in the same frame, both samplings make the same operations on the same values. The
 * world keeps the node's σt of its previous step so, instead of sampling it again: on the planet,
 * nodes of levels 9–12 that span every band, whose step is the cirrus's where there is no cirrus
 * (docs/performance.md, lever 29). */
static int ocs__proc_same_samples(const ocs_source_t *s, oc_key_t key, double t0, double t1) {
  const ocs__proc_t *P = (const ocs__proc_t *)s;
  int level = oc_key_level(key);
  if (level < 0 || !isfinite(t0) || !isfinite(t1)) return 0;
  if (ocs_weather_step(&P->weather, t0) != ocs_weather_step(&P->weather, t1)) return 0;
  ocs__frame_t F0, F1;
  ocs__frame(P, level, t0, &F0);
  ocs__frame(P, level, t1, &F1);
  if (F0.mask != F1.mask) return 0; /* the same weather makes the same mask: a safeguard */
  int64_t m0 = ocs__motion_step(P, level, t0), m1 = ocs__motion_step(P, level, t1);
  unsigned moved = 0;
  for (int l = 0; l < OCS_LAYER_COUNT; l++)
    if ((F0.mask >> l & 1u) && ocs__floor_pow2(m0, P->L[l].jstep) != ocs__floor_pow2(m1, P->L[l].jstep)) moved |= 1u << l;
  if (!moved) return 1;
  ocs__bb_t nb0, nb1;
  ocs__node_max(P, key, t0, &F0, &nb0);
  ocs__node_max(P, key, t1, &F1, &nb1);
  return !((nb0.mask | nb1.mask) & moved);
}

static int ocs__proc_set_weather(ocs_source_t *s, oc_preset_t preset, double t0, double seconds) {
  ocs__proc_t *P = (ocs__proc_t *)s;
  ocs_seqcache_clear(P->nbc); /* a generation wrap of the time step can never revive an entry */
  return ocs_weather_set(&P->weather, preset, t0, seconds);
}

static void ocs__proc_destroy(ocs_source_t *s) {
  ocs_seqcache_free(((ocs__proc_t *)s)->nbc);
  free(s);
}

static const ocs_source_vtbl_t ocs__proc_vt = {
    .name = "procedural",
    .bound = ocs__proc_bound,
    .node_bound = ocs__proc_node_bound,
    .sample = ocs__proc_sample_columns,
    .sample_exact = ocs__proc_sample_strata,
    .time_step = ocs__proc_time_step,
    .node_step = ocs__proc_node_step,
    .step_before = ocs__proc_step_before,
    .same_samples = ocs__proc_same_samples,
    .point = ocs__proc_point,
    .set_weather = ocs__proc_set_weather,
    .destroy = ocs__proc_destroy,
    .bound_by_step = 1, /* the bound reads t only through ocs__frame(level_of_box, t): see ocs__proc_time_step */
};

/*-*** Creation ***/

static uint64_t ocs__mix(uint64_t h) {
  h += 0x9E3779B97F4A7C15ull;
  h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
  h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
  return h ^ (h >> 31);
}

/* Altitude above which Q_mono ≥ 1 + anvil (Q_mono is increasing above h_c): bisection. */
static double ocs__band_top(const ocs__layer_t *L) {
  double lim = 1.0 + L->anvil, a = L->h_c, b = L->h_c + 1e3;
  while (ocs__q_mono(L, b) < lim) b += 1e3;
  for (int i = 0; i < 200; i++) {
    double m = 0.5 * (a + b);
    if (ocs__q_mono(L, m) < lim) a = m; else b = m;
  }
  return b + 1.0;
}

void ocs__layer_band(const ocs__layer_t *L, double *lo, double *hi) {
  double lim = 1.0 + L->anvil;
  *lo = L->h_c - L->H_lo * (L->p_lo == 2 ? sqrt(lim) : lim) - 1.0;
  *hi = ocs__band_top(L);
}

static void ocs__init_layer(ocs__proc_t *P, int l, uint64_t seed) {
  const ocs__layer_t *L = &ocs__layers[l];
  ocs__lstate_t *S = &P->L[l];
  double an = sqrt(L->axis[0] * L->axis[0] + L->axis[1] * L->axis[1] + L->axis[2] * L->axis[2]);
  for (int k = 0; k < 3; k++) S->axis[k] = L->axis[k] / an;
  S->omega = L->wind / OCS__R;
  ocs__layer_band(L, &S->band_lo, &S->band_hi);
  const ocs__nspec_t *ns[3] = {&L->cov, &L->cell, &L->det};
  oc_fbm_t *fb[3] = {&S->fcov, &S->fcell, &S->fdet};
  double vmax = fabs(L->wind) * (OCS__R + S->band_hi) / OCS__R, drift = 0.0;
  for (int f = 0; f < 3; f++) {
    *fb[f] = (oc_fbm_t){.octaves = ns[f]->octaves, .lacunarity = 2.0, .gain = 0.5,
                        .seed = ocs__mix(seed ^ ocs__mix(0x0C5u + 16u * (uint64_t)l + (uint64_t)f))};
    S->inv[f][0] = 1.0 / ns[f]->lambda;
    S->aniso[f] = ns[f]->lambda_short > 0.0;
    S->inv[f][1] = S->aniso[f] ? 1.0 / ns[f]->lambda_short : S->inv[f][0];
    const double *dv = ns[f]->drift;
    drift = fmax(drift, sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]));
  }
  /* Streaked coordinates stretch by at most 1/λ_short. */
  S->lip_cov = ocs__fbm_lipschitz(&S->fcov) * fmax(S->inv[0][0], S->inv[0][1]);
  S->lip_cell = ocs__fbm_lipschitz(&S->fcell) * fmax(S->inv[1][0], S->inv[1][1]);
  S->vmax = vmax + drift;
  P->vmax = fmax(P->vmax, S->vmax);
}

/* Each layer's step in level steps, 2^jstep: the most that keeps its own motion per step within
 * OCS_PROC_STEP_VOXELS of a voxel (the level step keeps the fastest layer's). */
static void ocs__layer_steps(ocs__proc_t *P) {
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    ocs__lstate_t *S = &P->L[l];
    S->jstep = 0;
    while (S->jstep < OCS_PROC_MAX_JSTEP && ldexp(S->vmax, S->jstep + 1) <= P->vmax) S->jstep++;
  }
}

/*! ocs_source_procedural_create() : the procedural planet of `desc` (preset, coverage_scale,
 *  sigma_scale) for the scene's seed; `animated` starts at 1.
 *  @return 0, OC_EINVAL with a one-line reason in why, or OC_ENOMEM. */
int ocs_source_procedural_create(ocs_source_t **out, const oc_source_t *desc, uint64_t seed, char *why,
                                 size_t why_len) {
/* Messages name the key; the field prefixes "sources[i] (procedural): ". */
#define OCS__FAIL(...)                                        \
  do {                                                        \
    if (why && why_len) snprintf(why, why_len, __VA_ARGS__); \
    return OC_EINVAL;                                         \
  } while (0)
  if (!out) OCS__FAIL("no output pointer");
  *out = NULL;
  if (!desc) OCS__FAIL("no source description");
  if (desc->type != OC_SOURCE_PROCEDURAL) OCS__FAIL("source type %d is not procedural", (int)desc->type);
  const oc_src_procedural_t *d = &desc->procedural;
  if ((int)d->preset < 0 || d->preset >= OC_PRESET_COUNT)
    OCS__FAIL("preset %d is not one of clear, fair, overcast, storm, cirrus", (int)d->preset);
  if (!isfinite(d->coverage_scale) || d->coverage_scale < 0.0 || d->coverage_scale > 4.0)
    OCS__FAIL("coverage_scale %g outside [0, 4]", d->coverage_scale);
  if (!isfinite(d->sigma_scale) || d->sigma_scale < 0.0 || d->sigma_scale > OC_SCENE_SIGMA_MAX)
    OCS__FAIL("sigma_scale %g outside [0, %g]", d->sigma_scale, OC_SCENE_SIGMA_MAX);
#undef OCS__FAIL
  ocs__proc_t *P = calloc(1, sizeof *P);
  if (!P) return OC_ENOMEM;
  P->base.vt = &ocs__proc_vt;
  P->base.animated = 1; /* the field clears it when the scene's animation is off */
  P->sigma_scale = d->sigma_scale;
  int rc = ocs_weather_init(&P->weather, d->preset, d->coverage_scale);
  if (rc < 0) {
    free(P);
    return rc;
  }
  for (int l = 0; l < OCS_LAYER_COUNT; l++) ocs__init_layer(P, l, seed);
  if (ocs__col_tables() < 0) {
    ocs__proc_destroy(&P->base);
    return OC_ENOMEM;
  }
  P->dt0 = OCS_PROC_STEP_VOXELS * ocs__voxel_size(0) / P->vmax;
  ocs__layer_steps(P);
  const char *env = getenv("OCS_PROC_NODE_CACHE"); /* "0": no node-bound cache (before/after benches) */
  if (!(env && strcmp(env, "0") == 0) && !(P->nbc = ocs_seqcache_new(OCS_PROC_NODE_CACHE_SLOTS, OCS__NB_WORDS))) {
    ocs__proc_destroy(&P->base);
    return OC_ENOMEM;
  }
  *out = &P->base;
  return 0;
}
