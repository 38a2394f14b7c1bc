/* procedural_columns.c — the fast estimate of the procedural planet's box filter (procedural.h).
 *
 * A brick's sample is the mean of the finest σt over the sample's cube (Conventions, filtering).
 * procedural_strata.c estimates it from up to tens of thousands of points per coarse voxel (100 m
 * vertical strata through a cloud shell far thinner than the voxel); this file estimates the same
 * mean from few points, integrating along the vertical in closed form and over the finest noise
 * octaves in expectation. One layer's σt (source_procedural.c, regrouped) is
 *
 *   σt = wc · s(h) · sat((A' − Q(h)) / F_w),   A' = W·V(K) − E(D),   E(D) = e·sat(½ − k_d·D)
 *
 * with W the coverage ramp (pattern C), V the cell ramp (pattern K), D the 3D detail. The altitude
 * terms s(h) (water profile, glaciation, air density, Märkl's conversion per unit water content)
 * and Q(h) (flat base, top, tropopause, anvil) are functions of h alone, so for a fixed A' the
 * integral over an altitude range is a difference of one cumulative table per layer:
 *
 *   J(A', h) = ∫_{band_lo}^{h} s(h') · sat((A' − Q(h')) / F_w) dh'     (A' in [0, 1]; Q ≥ 0)
 *
 * (OCS_COL_NA columns in A', rows OCS_COL_DH m apart, each row integrated by the midpoint rule on
 * OCS_COL_SUB sub-steps, which resolves the 3 m ramp of a cumulus base; bilinear between entries).
 *
 * The voxel is cut into nc × nc columns along its most vertical axis (OCS_COL_COARSE a side; two at
 * fine levels), so its volume is partitioned exactly.
 * Along a column dt = (r/|t|)·dh (t the coordinate along the axis), taken at a piece's midpoint.
 * Each pattern's fBm is split per level: octaves at least OCS_COL_KAPPA column spacings long are
 * evaluated ("resolved"), the finer ones are not, and enter through their distribution:
 *   - nothing resolved (coarse levels): one piece per column and layer, W at its middle (or at the
 *     voxel's centre, below), and Ĵ(W, h) = E[J(W·V(K) − E(D), h)], a second table per layer
 *     over the empirical distributions of the layer's cell and detail ramps;
 *   - cells resolved, detail not: J_D(W·V, h) = E[J(W·V − E(D), h)], a third table;
 *   - otherwise: the column is cut into pieces along which the resolved octaves move by at most
 *     1/OCS_COL_KAPPA of their finest period (a tilted column drifts sideways by up to √2 of its
 *     length), W, V(K_res) and D_res at each piece's midpoint, and each unresolved rest a
 *     three-node quadrature (a normal of the rest's variance, clamped to its range) where its
 *     spread on A' matters (above OCS_COL_SPREAD × F_w), else its mean, 0.
 * W is taken at the voxel's centre (the value its bound evaluated) where the coverage's finest
 * octave spans 16 voxels.
 *
 * The estimate differs from the exact filter by what the unresolved octaves do inside a voxel and
 * by the tables' resolution; per level the error against the exact filter and the parent-vs-
 * descendants test are in docs/numerics.md ("The procedural planet's fast box filter"). What it keeps:
 *   - every sample depends on its own position only (shared faces agree bit for bit), and on
 *     nothing but (seed, key, time step);
 *   - the bounds bound the estimate: where a level leaves cell octaves unresolved the estimate may
 *     take K values up to the unresolved octaves' amplitude beyond the evaluated ones, so the
 *     frame carries that margin (ocs__col_margins) and ocs__box_max() adds it, with one table step
 *     of A'; a zero bound therefore means a zero estimate, whichever brick asks. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "procedural.h"

/*-*** Knobs ***/

/*! Columns of a voxel per horizontal axis: OCS_COL_COARSE down to voxels of OCS_COL_FINE metres, two
 *  below. They were the exact filter's horizontal strata (450 m apart, 4 to 6 a side); three a side
 *  keep the images of the main view, a view from 10 km and the storm within 0.02 of their RMSE
 *  against the exact filter (the storm 0.06 nearer), for 0.66–0.82× the server's CPU, though a
 *  voxel's own error grows (docs/performance.md, lever 12; docs/numerics.md). */
#ifndef OCS_COL_FINE
#define OCS_COL_FINE 400.0
#endif
#ifndef OCS_COL_COARSE
#define OCS_COL_COARSE 3
#endif
/*! ...and below OCS_COL_FINE, this many a side (one was tried: 3.5–4× cheaper σt at levels 13–16,
 *  but the main view's image RMSE against the exact filter 0.69 → 1.27; docs/performance.md, lever 17). */
#ifndef OCS_COL_FINE_N
#define OCS_COL_FINE_N 2
#endif
/*! An octave is resolved when its period is at least this many column spacings (or piece
 *  lengths); pieces are cut so that resolved octaves move at most 1/OCS_COL_KAPPA of a period. */
#ifndef OCS_COL_KAPPA
#define OCS_COL_KAPPA 1.0
#endif
/*! In fine voxels (below OCS_COL_FINE metres) where the cells' finest resolved octave spans at least
 *  this many voxels, the cells are evaluated at the voxels' corners and interpolated at the pieces,
 *  instead of evaluated at every piece; a voxel whose corners all fail the cell test makes no pieces
 *  (docs/performance.md, lever 17). 0: never. */
#ifndef OCS_COL_KVOX
#define OCS_COL_KVOX 4.0
#endif
/*! The unresolved rest of a pattern gets a quadrature when its standard deviation moves A' by
 *  more than this fraction of the density ramp F_w. */
#ifndef OCS_COL_SPREAD
#define OCS_COL_SPREAD 0.1
#endif
/*! Standard deviation of one noise octave (oc_noise.h: 0.26 over 1e6 random points). */
#define OCS_COL_NOISE_SD 0.26
/*! The tables: J over A' in [0, 1] and Ĵ over W in [0, 1] at these many columns; rows every
 *  OCS_COL_DH metres, each integrated on OCS_COL_SUB sub-steps; OCS_COL_DIST points of each
 *  pattern's distribution for Ĵ. */
#define OCS_COL_NA 257
#define OCS_COL_NX 129
#define OCS_COL_NW 65
#define OCS_COL_DH 4.0
#define OCS_COL_SUB 16
#define OCS_COL_DIST 16384

#define OCS__R OC_PLANET_RADIUS
#define OCS__CHUNK 512
#define OCS__LEVELS (OC_KEY_MAX_LEVEL + 1)

/*-*** Tables (shared by every procedural source: they depend on the layer constants only) ***/

typedef struct {
  int nh;         /* rows: altitude h0 + i·OCS_COL_DH, i < nh */
  double h0;      /* the layer's band_lo */
  float *j;       /* J: [nh][OCS_COL_NA] (built [OCS_COL_NA][nh], then transposed: a brick's pieces
                     span a few hundred metres of altitude and any A', so rows by altitude keep a
                     lookup's four entries, and the next lookup's, in a few cache lines) */
  float *jd;      /* J_D: [nh][OCS_COL_NX], the expectation over the full detail */
  float *jbar;    /* Ĵ: [nh][OCS_COL_NW], over the full cells and detail */
} ocs__tab_t;

/* How a pattern's fBm splits at a level: the first n octaves are evaluated (fbm over them times
 * `scale` is their share of the full fBm), the rest has standard deviation sd and range ±amp. */
typedef struct {
  int n;
  double scale, sd, amp;
} ocs__split_t;

/* One layer at one level: columns per axis, the longest piece, how cells and detail split, and
 * how many quadrature nodes each unresolved rest gets (1 or 3). */
typedef struct {
  int nc;
  double u;     /* the level's voxel size */
  double piece; /* m along the column; 0: one piece per column (nothing resolved) */
  ocs__split_t k, d;
  int qk, qd;
  int cvox;       /* the coverage taken at the voxel's centre (its finest octave ≥ 16 voxels) */
  int kvox;       /* the cells at the voxels' corners, trilinear at the pieces (ocs__voxel_cells) */
  double kmargin; /* what the estimate may add to the cells' value beyond the evaluated octaves */
} ocs__plan_t;

static struct {
  ocs__tab_t tab[OCS_LAYER_COUNT];
  ocs__plan_t plan[OCS__LEVELS][OCS_LAYER_COUNT];
  _Atomic int built[OCS_LAYER_COUNT]; /* 1: tab[l] built, 2: it could not be (no memory) */
  pthread_mutex_t lock;
} ocs__T = {.lock = PTHREAD_MUTEX_INITIALIZER};
static pthread_once_t ocs__T_once = PTHREAD_ONCE_INIT;

/* s(h): σt per unit water content (kg/kg) at h, with the layer's profile and phase. */
static double ocs__s_of_h(const ocs__layer_t *L, double h) {
  return ocs__sigma_wc(L, ocs__prof_up(L, h) * ocs__prof_down(L, h), h, ocs__rho_air(h));
}

/* J of a layer: cumulative in h, one row of sub-step sums per A' column. */
static int ocs__build_j(const ocs__layer_t *L, ocs__tab_t *T) {
  int ns = (T->nh - 1) * OCS_COL_SUB;
  double *s = malloc(sizeof(double) * (size_t)ns), *q = malloc(sizeof(double) * (size_t)ns);
  T->j = malloc(sizeof(float) * (size_t)OCS_COL_NA * (size_t)T->nh);
  if (!s || !q || !T->j) {
    free(s), free(q);
    return OC_ENOMEM;
  }
  const double dz = OCS_COL_DH / OCS_COL_SUB;
  for (int k = 0; k < ns; k++) {
    double h = T->h0 + ((double)k + 0.5) * dz;
    s[k] = ocs__s_of_h(L, h) * dz;
    q[k] = ocs__q(L, h);
  }
  for (int a = 0; a < OCS_COL_NA; a++) {
    double A = (double)a / (OCS_COL_NA - 1), sum = 0.0;
    float *row = &T->j[(size_t)a * (size_t)T->nh];
    row[0] = 0.0f;
    for (int i = 1; i < T->nh; i++) {
      for (int k = (i - 1) * OCS_COL_SUB; k < i * OCS_COL_SUB; k++) {
        double g = (A - q[k]) / L->F_w;
        if (g > 0.0) sum += s[k] * (g < 1.0 ? g : 1.0);
      }
      row[i] = (float)sum;
    }
  }
  free(s), free(q);
  return 0;
}

/* The distribution of y = sat(a + b·v) over the values v of an fBm, as masses at the nb + 1
 * points j/nb (each value's mass split between its two neighbours): OCS_COL_DIST values at a
 * fixed sequence of points spread over 64 periods (the distribution does not depend on the seed). */
static int ocs__ramp_dist(const oc_fbm_t *f, double a, double b, int nb, double *mass) {
  enum { N = OCS_COL_DIST };
  double *xyz = malloc(sizeof(double) * 3 * N);
  float *v = malloc(sizeof(float) * N);
  if (!xyz || !v) {
    free(xyz), free(v);
    return OC_ENOMEM;
  }
  uint64_t h = 0x0C0FFEEull;
  for (int i = 0; i < 3 * N; i++) {
    h = h * 6364136223846793005ull + 1442695040888963407ull;
    xyz[i] = (double)(h >> 11) * (64.0 / 9007199254740992.0);
  }
  oc_fbm_t g = *f;
  g.seed = 1;
  oc_fbm3_batch(xyz, N, &g, v);
  for (int j = 0; j <= nb; j++) mass[j] = 0.0;
  for (int i = 0; i < N; i++) {
    double y = ocs__sat(a + b * (double)v[i]) * (double)nb;
    int j = y >= (double)nb ? nb - 1 : (int)y;
    mass[j] += (1.0 - (y - (double)j)) / N;
    mass[j + 1] += (y - (double)j) / N;
  }
  free(xyz), free(v);
  return 0;
}

/* out[i] = Σ_a p[a]·J[a][i]: the table of a distribution p over J's A' columns. */
static void ocs__mix_rows(const ocs__tab_t *T, const double *p, double *acc, float *out) {
  memset(acc, 0, sizeof(double) * (size_t)T->nh);
  for (int a = 1; a < OCS_COL_NA; a++) {
    if (p[a] == 0.0) continue;
    const float *row = &T->j[(size_t)a * (size_t)T->nh];
    for (int i = 0; i < T->nh; i++) acc[i] += p[a] * (double)row[i];
  }
  for (int i = 0; i < T->nh; i++) out[i] = (float)acc[i];
}

/* Adds mass m at A' to p, split linearly between J's two nearest columns (nothing for A' ≤ 0). */
static inline void ocs__put(double *p, double A, double m) {
  if (!(A > 0.0)) return;
  double y = A * (OCS_COL_NA - 1);
  int a = y >= (double)(OCS_COL_NA - 1) ? OCS_COL_NA - 2 : (int)y;
  p[a] += m * (1.0 - (y - (double)a));
  p[a + 1] += m * (y - (double)a);
}

/* J_D(x, h) = E[J(x − E(D), h)] and Ĵ(W, h) = E[J(W·V(K) − E(D), h)] over the full distributions
 * of the layer's detail and cells. */
static int ocs__build_means(const ocs__layer_t *L, const oc_fbm_t *cell, const oc_fbm_t *det, ocs__tab_t *T) {
  enum { NB = 64 };
  double mv[NB + 1], me[NB + 1], p[OCS_COL_NA];
  if (ocs__ramp_dist(cell, L->a0, L->a1, NB, mv) < 0 || ocs__ramp_dist(det, 0.5, -L->k_d, NB, me) < 0)
    return OC_ENOMEM;
  T->jd = malloc(sizeof(float) * (size_t)OCS_COL_NX * (size_t)T->nh);
  T->jbar = malloc(sizeof(float) * (size_t)OCS_COL_NW * (size_t)T->nh);
  double *acc = malloc(sizeof(double) * (size_t)T->nh);
  if (!T->jd || !T->jbar || !acc) {
    free(acc);
    return OC_ENOMEM;
  }
  for (int ix = 0; ix < OCS_COL_NX; ix++) {
    double x = (double)ix / (OCS_COL_NX - 1);
    memset(p, 0, sizeof p);
    for (int j = 0; j <= NB; j++) ocs__put(p, x - L->e * j / NB, me[j]);
    ocs__mix_rows(T, p, acc, &T->jd[(size_t)ix * (size_t)T->nh]);
  }
  for (int iw = 0; iw < OCS_COL_NW; iw++) {
    double W = (double)iw / (OCS_COL_NW - 1);
    memset(p, 0, sizeof p);
    for (int i = 0; i <= NB; i++)
      if (mv[i] > 0.0)
        for (int j = 0; j <= NB; j++) ocs__put(p, W * i / NB - L->e * j / NB, mv[i] * me[j]);
    ocs__mix_rows(T, p, acc, &T->jbar[(size_t)iw * (size_t)T->nh]);
  }
  free(acc);
  return 0;
}

static ocs__split_t ocs__split(const oc_fbm_t *f, double lambda, double spacing) {
  ocs__split_t s = {0, 0.0, 0.0, 0.0};
  double all = 0.0, kept = 0.0, var = 0.0, amp = 1.0;
  while (s.n < f->octaves && ldexp(lambda, -s.n) >= OCS_COL_KAPPA * spacing) s.n++;
  for (int i = 0; i < f->octaves; i++, amp *= f->gain) {
    all += amp;
    if (i < s.n)
      kept += amp;
    else
      var += amp * amp, s.amp += amp;
  }
  s.scale = kept / all;
  s.sd = OCS_COL_NOISE_SD * sqrt(var) / all;
  s.amp /= all;
  return s;
}

/* The plan of a layer at a level (from the layer's constants; the fBm descriptions give the octave
 * counts and gains). */
static void ocs__make_plan(const ocs__layer_t *L, const oc_fbm_t *cell, const oc_fbm_t *det, int level,
                           ocs__plan_t *pl) {
  double u = ocs__voxel_size(level);
  pl->u = u;
  pl->nc = u < OCS_COL_FINE ? OCS_COL_FINE_N : OCS_COL_COARSE;
  double spacing = u / (double)pl->nc;
  double lk = L->cell.lambda_short > 0.0 ? L->cell.lambda_short : L->cell.lambda;
  double ld = L->det.lambda_short > 0.0 ? L->det.lambda_short : L->det.lambda;
  pl->k = ocs__split(cell, lk, spacing);
  pl->d = ocs__split(det, ld, spacing);
  /* pieces: resolved cells drift sideways by up to √2 of the piece's length, detail by its length */
  double piece = 0.0;
  if (pl->k.n > 0) piece = ldexp(lk, -(pl->k.n - 1)) / (OCS_COL_KAPPA * 1.41421356);
  if (pl->d.n > 0) {
    double pd = ldexp(ld, -(pl->d.n - 1)) / OCS_COL_KAPPA;
    piece = piece > 0.0 && piece < pd ? piece : pd;
  }
  pl->piece = piece > 0.0 && piece < spacing ? spacing : piece;
  pl->cvox = ldexp(L->cov.lambda, -(L->cov.octaves - 1)) >= 16.0 * u;
  pl->qk = L->a1 * pl->k.sd > OCS_COL_SPREAD * L->F_w ? 3 : 1;
  pl->kvox = OCS_COL_KVOX > 0.0 && u < OCS_COL_FINE && pl->k.n > 0 && pl->qk == 1 &&
             ldexp(lk, -(pl->k.n - 1)) >= OCS_COL_KVOX * u;
  pl->qd = L->e * L->k_d * pl->d.sd > OCS_COL_SPREAD * L->F_w ? 3 : 1;
  pl->kmargin = pl->qk == 3 || (pl->k.n == 0 && pl->d.n == 0) ? 2.0 * pl->k.amp : 0.0;
}

/* [n][nh] → [nh][n], in a new block. */
static int ocs__transpose(float **t, int n, int nh) {
  float *o = malloc(sizeof(float) * (size_t)n * (size_t)nh);
  if (!o) return OC_ENOMEM;
  for (int a = 0; a < n; a++)
    for (int i = 0; i < nh; i++) o[(size_t)i * (size_t)n + (size_t)a] = (*t)[(size_t)a * (size_t)nh + (size_t)i];
  free(*t);
  *t = o;
  return 0;
}

static void ocs__fbms(const ocs__layer_t *L, oc_fbm_t *cell, oc_fbm_t *det) {
  *cell = (oc_fbm_t){.octaves = L->cell.octaves, .lacunarity = 2.0, .gain = 0.5, .seed = 1};
  *det = (oc_fbm_t){.octaves = L->det.octaves, .lacunarity = 2.0, .gain = 0.5, .seed = 1};
}

static void ocs__plans_init(void) {
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    oc_fbm_t cell, det;
    ocs__fbms(&ocs__layers[l], &cell, &det);
    for (int lv = 0; lv < OCS__LEVELS; lv++) ocs__make_plan(&ocs__layers[l], &cell, &det, lv, &ocs__T.plan[lv][l]);
  }
}

int ocs__col_tables(void) {
  pthread_once(&ocs__T_once, ocs__plans_init);
  return 0;
}

/* A layer's tables, built at its first use (only the layers a weather uses cost anything; the
 * cumulonimbus' 14 km band is the dearest, about 0.1 s). NULL: no memory. */
static const ocs__tab_t *ocs__layer_tab(int l) {
  int b = atomic_load_explicit(&ocs__T.built[l], memory_order_acquire);
  if (b) return b == 1 ? &ocs__T.tab[l] : NULL;
  pthread_mutex_lock(&ocs__T.lock);
  if (!atomic_load_explicit(&ocs__T.built[l], memory_order_relaxed)) {
    const ocs__layer_t *L = &ocs__layers[l];
    ocs__tab_t *T = &ocs__T.tab[l];
    double band_lo, band_hi;
    oc_fbm_t cell, det;
    ocs__fbms(L, &cell, &det);
    ocs__layer_band(L, &band_lo, &band_hi);
    T->h0 = band_lo;
    T->nh = (int)ceil((band_hi - band_lo) / OCS_COL_DH) + 2;
    int ok = ocs__build_j(L, T) == 0 && ocs__build_means(L, &cell, &det, T) == 0 &&
             ocs__transpose(&T->j, OCS_COL_NA, T->nh) == 0 && ocs__transpose(&T->jd, OCS_COL_NX, T->nh) == 0 &&
             ocs__transpose(&T->jbar, OCS_COL_NW, T->nh) == 0;
    atomic_store_explicit(&ocs__T.built[l], ok ? 1 : 2, memory_order_release);
  }
  pthread_mutex_unlock(&ocs__T.lock);
  return atomic_load_explicit(&ocs__T.built[l], memory_order_acquire) == 1 ? &ocs__T.tab[l] : NULL;
}

void ocs__col_margins(int level, int layer, double *kmargin, double *amargin) {
  *kmargin = *amargin = 0.0;
  if (level < 0 || level >= OCS__LEVELS || layer < 0 || layer >= OCS_LAYER_COUNT) return;
  *kmargin = ocs__T.plan[level][layer].kmargin;
  *amargin = 1.0 / (OCS_COL_NA - 1);
}

/* A table at (x, h), bilinear: columns x·(n − 1) (x in [0, 1]); 0 below the band, the band's total
 * above it. The row is found once per altitude (ocs__tab_row) and the column once per x
 * (ocs__tab_diff): a piece reads up to 9 columns at the same two rows. */
typedef struct {
  int i, in; /* row; 0 below the band */
  double fz;
} ocs__trow_t;

static inline ocs__trow_t ocs__tab_row(const ocs__tab_t *T, double h) {
  ocs__trow_t r = {0, 0, 0.0};
  double z = (h - T->h0) * (1.0 / OCS_COL_DH);
  if (!(z > 0.0)) return r;
  r.in = 1;
  r.i = z >= (double)(T->nh - 1) ? T->nh - 2 : (int)z;
  r.fz = z - (double)r.i;
  if (r.fz > 1.0) r.fz = 1.0;
  return r;
}

static inline double ocs__tab_lerp(const float *tab, int n, int a, double fy, ocs__trow_t r) {
  if (!r.in) return 0.0;
  const float *r0 = &tab[(size_t)r.i * (size_t)n + (size_t)a], *r1 = r0 + n;
  double v0 = (double)r0[0] + fy * ((double)r0[1] - (double)r0[0]);
  double v1 = (double)r1[0] + fy * ((double)r1[1] - (double)r1[0]);
  return v0 + r.fz * (v1 - v0);
}

/* The table at (x, row h1) minus at (x, row h0): what a piece's altitude range [h0, h1] adds. */
static inline double ocs__tab_diff(const float *tab, int n, double x, ocs__trow_t h0, ocs__trow_t h1) {
  if (!(x > 0.0)) return 0.0;
  double y = x >= 1.0 ? (double)(n - 1) : x * (double)(n - 1);
  int a = y >= (double)(n - 1) ? n - 2 : (int)y;
  double fy = y - (double)a;
  return ocs__tab_lerp(tab, n, a, fy, h1) - ocs__tab_lerp(tab, n, a, fy, h0);
}

/*-*** Columns and pieces of a brick ***/

enum { OCS__KC = 9 }; /* a brick's voxel corners a side (ocs__voxel_cells) */

typedef struct {
  int n;
  double p[3 * OCS__CHUNK];       /* midpoint, planet frame */
  double r[OCS__CHUNK];           /* |p| */
  double h0[OCS__CHUNK], h1[OCS__CHUNK], drdt[OCS__CHUNK]; /* altitude range; |dt/dh| = r/|t| */
  uint16_t vox[OCS__CHUNK];
  uint8_t wone[OCS__CHUNK];
  const double *cc; /* the layer's coverage at each voxel's centre (ocs__voxel_bounds) */
  /* scratch */
  int idx[OCS__CHUNK], sel[OCS__CHUNK];
  double q[3 * OCS__CHUNK], xyz[3 * OCS__CHUNK], w[OCS__CHUNK], k[OCS__CHUNK], ksum[OCS__CHUNK];
  float val[OCS__CHUNK];
  double kv[OCS__KC * OCS__KC * OCS__KC]; /* where the plan says kvox, the cells (× k.scale) at the corners */
  const uint32_t *ic;                     /* the brick's key coordinates, and its voxel size */
  double u;
  double sum[OC_BRICK_VOXELS];
} ocs__cws_t;

/* ocs__layer_pieces' cell test: whether a piece of weight W with cell value K (× k.scale), raised
 * by the quadrature's reach, may beat the least altitude cost over its altitudes [h0, h1]. */
static inline int ocs__cell_passes(const ocs__layer_t *L, double W, double K, double reach, double h0, double h1) {
  return W * ocs__v(L, (float)(K + reach)) > ocs__qmin(L, h0, h1);
}

/* The noise coordinates of one pattern (OCS__COV or OCS__CELL, on the reference sphere) at the
 * chunk's points listed in idx[0..m), to ws->xyz, and their positions in idx to ws->sel, except
 * those whose W is proven 1 (coverage: out[j] = 2 marks them; out is not read for cells).
 * @return how many. */
static inline int ocs__pattern_xyz(const ocs__proc_t *P, const ocs__lframe_t *lf, int l, int f, ocs__cws_t *ws, int m,
                                   double *out) {
  const ocs__lstate_t *S = &P->L[l];
  int n = 0;
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j];
    if (f == OCS__COV && (ws->wone[i] >> l & 1u)) {
      out[j] = 2.0; /* marks W = 1 */
      continue;
    }
    const double *q = &ws->q[3 * i];
    double X[3], s = OCS__R / ws->r[i];
    X[0] = q[0] * s, X[1] = q[1] * s, X[2] = q[2] * s;
    ocs__coords(S, f, X, lf->off[f], &ws->xyz[3 * n]);
    ws->sel[n++] = j;
  }
  return n;
}

/* Evaluates one pattern at the chunk's points listed in idx[0..m) (ocs__pattern_xyz): values to
 * out by position in idx. */
static void ocs__pattern(const ocs__proc_t *P, const ocs__lframe_t *lf, int l, int f, const oc_fbm_t *fb,
                         ocs__cws_t *ws, int m, double *out) {
  int n = ocs__pattern_xyz(P, lf, l, f, ws, m, out);
  oc_fbm3_batch(ws->xyz, n, fb, ws->val);
  for (int t = 0; t < n; t++) out[ws->sel[t]] = (double)ws->val[t];
}

int ocs__col_cell_split = 1;
_Atomic long ocs__col_cell_dropped, ocs__col_cell_wrong;

/* ocs__col_cell_split 2: also the last octave at every piece, and how many the first pass dropped
 * that pass the cell test with their exact K (the claim is none), to ocs__col_cell_wrong. */
static void ocs__cells_check(const ocs__layer_t *L, const ocs__plan_t *pl, const oc_fbm_t *kres, double reach,
                             ocs__cws_t *ws, int m) {
  float exact[OCS__CHUNK];
  for (int j = 0; j < m; j++) ws->k[j] = ws->ksum[j];
  oc_fbm3_batch_octaves(ws->xyz, m, kres, pl->k.n - 1, pl->k.n, ws->k);
  oc_fbm3_batch_finish(ws->k, m, kres, exact);
  long wrong = 0;
  for (int j = 0; j < m; j++) {
    double h0 = ws->h0[ws->idx[j]], h1 = ws->h1[ws->idx[j]];
    wrong += !ocs__cell_passes(L, ws->w[j], (double)ws->val[j] * pl->k.scale, reach, h0, h1) &&
             ocs__cell_passes(L, ws->w[j], (double)exact[j] * pl->k.scale, reach, h0, h1);
  }
  atomic_fetch_add_explicit(&ocs__col_cell_wrong, wrong, memory_order_relaxed);
}

/* The resolved cells at the chunk's pieces idx[0..m) (weights w): K = the resolved octaves' fBm ×
 * k.scale into ws->k, for the pieces that may pass ocs__layer_pieces' cell test, W·V(K + the
 * quadrature's reach) > the least altitude cost; the others are dropped from idx, w (order kept).
 * With two or more resolved octaves the last is added only where the first ones' sum, raised by
 * oc_fbm3_batch_top() to the most the last can add, still passes that test through the same
 * operations: rounding and V (a1 > 0 in every layer) are monotone, so a piece dropped there fails
 * the test with its exact K too, and the survivors' K are the bits of a one-pass oc_fbm3_batch().
 * @return m left. */
static int ocs__cells(const ocs__proc_t *P, const ocs__lframe_t *lf, int l, const ocs__plan_t *pl, double kx,
                      ocs__cws_t *ws, int m) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  oc_fbm_t kres = S->fcell;
  kres.octaves = pl->k.n;
  double reach = pl->qk == 3 ? kx : 0.0;
  if (!ocs__col_cell_split || pl->k.n < 2) {
    ocs__pattern(P, lf, l, OCS__CELL, &kres, ws, m, ws->k);
    for (int j = 0; j < m; j++) ws->k[j] *= pl->k.scale;
    return m;
  }
  ocs__pattern_xyz(P, lf, l, OCS__CELL, ws, m, NULL); /* every piece, in order (no W = 1 skip) */
  for (int j = 0; j < m; j++) ws->ksum[j] = 0.0;
  int last = pl->k.n - 1, k = 0;
  oc_fbm3_batch_octaves(ws->xyz, m, &kres, 0, last, ws->ksum);
  oc_fbm3_batch_top(ws->ksum, m, &kres, last, ws->val);
  if (ocs__col_cell_split == 2) ocs__cells_check(L, pl, &kres, reach, ws, m);
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j];
    if (!ocs__cell_passes(L, ws->w[j], (double)ws->val[j] * pl->k.scale, reach, ws->h0[i], ws->h1[i])) continue;
    ws->idx[k] = i, ws->w[k] = ws->w[j], ws->ksum[k] = ws->ksum[j];
    for (int c = 0; c < 3; c++) ws->xyz[3 * k + c] = ws->xyz[3 * j + c];
    k++;
  }
  if (k < m) atomic_fetch_add_explicit(&ocs__col_cell_dropped, m - k, memory_order_relaxed);
  oc_fbm3_batch_octaves(ws->xyz, k, &kres, last, pl->k.n, ws->ksum);
  oc_fbm3_batch_finish(ws->ksum, k, &kres, ws->val);
  for (int j = 0; j < k; j++) ws->k[j] = (double)ws->val[j] * pl->k.scale;
  return k;
}

/* The plan's kvox: the resolved cells at the corners of the voxels whose mask holds layer l (9³
 * corners a brick, shared with its neighbours' faces), to ws->kv, and at a piece the trilinear
 * interpolation of its voxel's 8 corners (ocs__pieces_cells). That is a convex combination, so no
 * piece of a voxel has K above its largest corner: a voxel where that fails the cell test over its
 * whole altitude range (with the W its pieces get: the centre's coverage where the plan takes it
 * there, else at most 1) loses layer l from its mask and makes no pieces, which would all have
 * failed the test too. */
int ocs__col_kvox_pretest = 1;
_Atomic long ocs__col_kvox_dropped;

/* Voxel v's lowest corner as an index of the brick's 9³ corners; corner c (bit 0: +x, 1: +y, 2: +z)
 * is that plus ocs__corner_off[c] (computed once per voxel: per corner it was 1 % of the world's
 * instructions). */
static inline int ocs__corner0(int v) { return v % 8 + OCS__KC * (v / 8 % 8) + OCS__KC * OCS__KC * (v / 64); }
static const int ocs__corner_off[8] = {0, 1, OCS__KC, OCS__KC + 1, OCS__KC * OCS__KC, OCS__KC * OCS__KC + 1,
                                       OCS__KC * OCS__KC + OCS__KC, OCS__KC * OCS__KC + OCS__KC + 1};

static void ocs__voxel_cells(const ocs__proc_t *P, const ocs__frame_t *F, int l, const ocs__plan_t *pl,
                             uint8_t vmask[OC_BRICK_VOXELS], const uint8_t vwone[OC_BRICK_VOXELS], ocs__cws_t *ws) {
  const uint32_t *ic = ws->ic;
  double u = ws->u;
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  oc_fbm_t kres = S->fcell;
  kres.octaves = pl->k.n;
  uint8_t need[OCS__KC * OCS__KC * OCS__KC] = {0};
  for (int v = 0; v < OC_BRICK_VOXELS; v++)
    if (vmask[v] >> l & 1u)
      for (int c = 0, c0 = ocs__corner0(v); c < 8; c++) need[c0 + ocs__corner_off[c]] = 1;
  int n = 0, corner[OCS__CHUNK];
  for (int i = 0; i <= OCS__KC * OCS__KC * OCS__KC; i++) {
    if (n == OCS__CHUNK || (i == OCS__KC * OCS__KC * OCS__KC && n)) { /* a batch full, or the last */
      oc_fbm3_batch(ws->xyz, n, &kres, ws->val);
      for (int j = 0; j < n; j++) ws->kv[corner[j]] = (double)ws->val[j] * pl->k.scale;
      n = 0;
    }
    if (i == OCS__KC * OCS__KC * OCS__KC || !need[i]) continue;
    double p[3], q[3], X[3];
    int ijk[3] = {i % OCS__KC, i / OCS__KC % OCS__KC, i / (OCS__KC * OCS__KC)};
    for (int a = 0; a < 3; a++) p[a] = -OC_ROOT_HALF + ((double)(7 * (int64_t)ic[a] + ijk[a]) - 0.5) * u;
    ocs__rotate(lf->M, p, q);
    double sc = OCS__R / sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    for (int a = 0; a < 3; a++) X[a] = q[a] * sc;
    ocs__coords(S, OCS__CELL, X, lf->off[OCS__CELL], &ws->xyz[3 * n]);
    corner[n++] = i;
  }
  if (!ocs__col_kvox_pretest) return;
  long dropped = 0;
  double half = 0.8660254037844386 * u; /* the cube's half-diagonal bounds its altitude range */
  for (int v = 0; v < OC_BRICK_VOXELS; v++) {
    if (!(vmask[v] >> l & 1u)) continue;
    double K = -INFINITY, gg[3], c[3];
    const double *kc = &ws->kv[ocs__corner0(v)];
    for (int k = 0; k < 8; k++) K = kc[ocs__corner_off[k]] > K ? kc[ocs__corner_off[k]] : K; /* fmax is a libm call */
    ocs__voxel_centre(ic, v, u, gg, c);
    double h = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) - OCS__R, C = ws->cc[v];
    double W = pl->cvox && C < 2.0 && !(vwone[v] >> l & 1u) ? ocs__w(L, lf, (float)C) : 1.0;
    if (!ocs__cell_passes(L, W, K, 0.0, h - half, h + half)) {
      vmask[v] &= (uint8_t)~(1u << l);
      dropped++;
    }
  }
  if (dropped) atomic_fetch_add_explicit(&ocs__col_kvox_dropped, dropped, memory_order_relaxed);
}

/* The plan's kvox: the cells of the chunk's pieces idx[0..m) to ws->k, each trilinear between its
 * voxel's 8 corners (ocs__voxel_cells). */
static void ocs__pieces_cells(ocs__cws_t *ws, int m) {
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j], v = ws->vox[i];
    double gg[3], c[3], f[3], k[8];
    ocs__voxel_centre(ws->ic, v, ws->u, gg, c);
    for (int a = 0; a < 3; a++) f[a] = (ws->p[3 * i + a] - c[a]) / ws->u + 0.5; /* 0..1 across the voxel */
    const double *kc = &ws->kv[ocs__corner0(v)];
    for (int e = 0; e < 8; e++) k[e] = kc[ocs__corner_off[e]];
    for (int e = 0; e < 4; e++) k[e] = k[2 * e] + f[0] * (k[2 * e + 1] - k[2 * e]);
    for (int e = 0; e < 2; e++) k[e] = k[2 * e] + f[1] * (k[2 * e + 1] - k[2 * e]);
    ws->k[j] = k[0] + f[2] * (k[1] - k[0]);
  }
}

/* One layer over the chunk's pieces: W, then (coarse) Ĵ, or (finer) the resolved cells and detail
 * and J over the unresolved rest. Adds σt × length to ws->sum per voxel. */
static void ocs__layer_pieces(const ocs__proc_t *P, const ocs__frame_t *F, int l, const ocs__plan_t *pl,
                              const ocs__tab_t *T, ocs__cws_t *ws) {
  const ocs__layer_t *L = &ocs__layers[l];
  const ocs__lstate_t *S = &P->L[l];
  const ocs__lframe_t *lf = &F->l[l];
  int m = ws->n;
  for (int i = 0; i < m; i++) {
    ocs__rotate(lf->M, &ws->p[3 * i], &ws->q[3 * i]);
    ws->idx[i] = i;
  }
  if (pl->cvox) /* the coverage at the voxel's centre, from its bound */
    for (int j = 0; j < m; j++) {
      int i = ws->idx[j];
      double C = ws->cc[ws->vox[i]];
      ws->w[j] = (ws->wone[i] >> l & 1u) || !(C < 2.0) ? 2.0 : C;
    }
  else
    ocs__pattern(P, lf, l, OCS__COV, &S->fcov, ws, m, ws->w);
  int k = 0;
  for (int j = 0; j < m; j++) {
    double W = ws->w[j] > 1.5 ? 1.0 : ocs__w(L, lf, (float)ws->w[j]);
    if (!(W > 0.0)) continue;
    ws->idx[k] = ws->idx[j], ws->w[k++] = W;
  }
  m = k;
  /* each column holds (u/nc)² of the voxel's u³: its share of the mean is its integral / (nc² u) */
  double f = F->sigma_scale * lf->wc / ((double)pl->nc * (double)pl->nc * pl->u);
  if (pl->k.n == 0 && pl->d.n == 0) { /* nothing resolved: the expectation table */
    for (int j = 0; j < m; j++) {
      int i = ws->idx[j];
      double c = ocs__tab_diff(T->jbar, OCS_COL_NW, ws->w[j], ocs__tab_row(T, ws->h0[i]), ocs__tab_row(T, ws->h1[i]));
      if (c > 0.0) ws->sum[ws->vox[i]] += f * c * ws->drdt[i];
    }
    return;
  }
  /* the resolved cells: V at the piece, and the largest V the quadrature may reach */
  static const double wq[3] = {1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0}, xq[3] = {-1.7320508075688772, 0.0, 1.7320508075688772};
  double kx = fmin(1.7320508075688772 * pl->k.sd, pl->k.amp), dx = fmin(1.7320508075688772 * pl->d.sd, pl->d.amp);
  if (pl->kvox)
    ocs__pieces_cells(ws, m);
  else if (pl->k.n > 0)
    m = ocs__cells(P, lf, l, pl, kx, ws, m);
  k = 0;
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j];
    double K = pl->k.n > 0 ? ws->k[j] : 0.0;
    if (!ocs__cell_passes(L, ws->w[j], K, pl->qk == 3 ? kx : 0.0, ws->h0[i], ws->h1[i])) continue;
    ws->idx[k] = i, ws->w[k] = ws->w[j], ws->k[k++] = K;
  }
  m = k;
  if (!m) return;
  if (pl->d.n > 0) {
    oc_fbm_t dres = lf->det;
    dres.octaves = pl->d.n;
    for (int j = 0; j < m; j++) ocs__coords(S, OCS__DET, &ws->q[3 * ws->idx[j]], lf->off[OCS__DET], &ws->xyz[3 * j]);
    oc_fbm3_batch(ws->xyz, m, &dres, ws->val);
  }
  int full_d = pl->d.n == 0 && pl->qd == 3; /* the detail wholly unresolved: J_D holds its expectation */
  for (int j = 0; j < m; j++) {
    int i = ws->idx[j];
    double d = pl->d.n > 0 ? (double)ws->val[j] * pl->d.scale * lf->det_scale : 0.0, c = 0.0;
    ocs__trow_t r0 = ocs__tab_row(T, ws->h0[i]), r1 = ocs__tab_row(T, ws->h1[i]);
    for (int a = 0; a < pl->qk; a++) {
      double V = ocs__v(L, (float)(ws->k[j] + (pl->qk == 3 ? xq[a] / 1.7320508075688772 * kx : 0.0)));
      double wv = ws->w[j] * V, ca = 0.0;
      if (full_d) {
        ca = ocs__tab_diff(T->jd, OCS_COL_NX, wv, r0, r1);
      } else {
        for (int b = 0; b < pl->qd; b++) {
          double A = wv - L->e * ocs__sat(0.5 - L->k_d * (d + (pl->qd == 3 ? xq[b] / 1.7320508075688772 * dx : 0.0)));
          ca += (pl->qd == 3 ? wq[b] : 1.0) * ocs__tab_diff(T->j, OCS_COL_NA, A, r0, r1);
        }
      }
      c += (pl->qk == 3 ? wq[a] : 1.0) * ca;
    }
    if (c > 0.0) ws->sum[ws->vox[i]] += f * c * ws->drdt[i];
  }
}

/* The pieces of one column (along axis va at the horizontal position xyz[ha], xyz[hb]) inside the
 * voxel's extent [ta, tb] of that axis and the layer's band: one, or pieces at most pl->piece
 * long. */
static void ocs__column(const ocs__proc_t *P, const ocs__frame_t *F, int l, const ocs__plan_t *pl,
                        const ocs__tab_t *T, ocs__cws_t *ws, const double xyz[3], int va, double ta, double tb, int v,
                        unsigned wone) {
  const ocs__lstate_t *S = &P->L[l];
  double a2 = 0.0;
  for (int k = 0; k < 3; k++)
    if (k != va) a2 += xyz[k] * xyz[k];
  double rlo = OCS__R + S->band_lo, rhi = OCS__R + S->band_hi;
  double hi2 = rhi * rhi - a2, lo2 = rlo * rlo - a2;
  if (!(hi2 > 0.0)) return;
  /* |t| over the voxel (ta..tb never contains 0: |centre| along va is ≥ |centre|/√3 ≫ a voxel) */
  /* ternaries, not fmin/fmax: without -ffinite-math-only those are libm calls, 24 M per 8 epochs */
  double aa = fabs(ta), ab = fabs(tb), sgn = ta + tb < 0.0 ? -1.0 : 1.0, u0 = aa < ab ? aa : ab, u1 = aa < ab ? ab : aa;
  double b0 = lo2 > 0.0 ? sqrt(lo2) : 0.0, b1 = sqrt(hi2);
  u0 = u0 > b0 ? u0 : b0;
  u1 = u1 < b1 ? u1 : b1;
  if (!(u1 > u0)) return;
  int n = pl->piece > 0.0 ? (int)ceil((u1 - u0) / pl->piece) : 1;
  if (n < 1) n = 1;
  double step = (u1 - u0) / (double)n;
  /* piece boundaries' radii shared by neighbours; the midpoint's radius is their mean (r(t) is
   * convex, but over a piece the difference is below 1e-9 of a voxel) */
  double t0 = u0, r0 = sqrt(a2 + u0 * u0);
  for (int m = 0; m < n; m++) {
    double t1 = m + 1 == n ? u1 : u0 + (double)(m + 1) * step, r1 = sqrt(a2 + t1 * t1), tm = 0.5 * (t0 + t1);
    double r = 0.5 * (r0 + r1);
    int at = ws->n++;
    double *p = &ws->p[3 * at];
    for (int k = 0; k < 3; k++) p[k] = xyz[k];
    p[va] = sgn * tm;
    ws->r[at] = r;
    ws->h0[at] = r0 - OCS__R;
    ws->h1[at] = r1 - OCS__R;
    ws->drdt[at] = r / tm;
    t0 = t1, r0 = r1;
    ws->vox[at] = (uint16_t)v;
    ws->wone[at] = (uint8_t)wone;
    if (ws->n == OCS__CHUNK) {
      ocs__layer_pieces(P, F, l, pl, T, ws);
      ws->n = 0;
    }
  }
}

int ocs__proc_sample_columns(const ocs_source_t *s, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) {
  if (!out) return OC_EINVAL;
  if (ocs__col_tables() < 0) return OC_ENOMEM;
  ocs__brick_t B;
  int r = ocs__brick_begin(s, key, t, &B);
  if (r <= 0) return r;
  double u = ocs__voxel_size(B.level);
  const ocs__plan_t *plan = ocs__T.plan[B.level];
  ocs__cws_t *ws = malloc(sizeof *ws);
  if (!ws) return OC_ENOMEM;
  memset(ws->sum, 0, sizeof ws->sum);
  uint32_t ic[3];
  oc_key_coords(key, &ic[0], &ic[1], &ic[2]);
  /* Which layers may be non-zero in each voxel (the bound bounds the estimate: a skip changes no
   * value, so the brick-wide ranges it inherits do not make values depend on the brick). */
  uint8_t vmask[OC_BRICK_VOXELS], vwone[OC_BRICK_VOXELS];
  double (*cc)[OC_BRICK_VOXELS] = malloc(sizeof(double) * OCS_LAYER_COUNT * OC_BRICK_VOXELS);
  if (!cc) {
    free(ws);
    return OC_ENOMEM;
  }
  ocs__voxel_bounds(&B, key, vmask, vwone, cc);
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    if (!(B.nb.mask >> l & 1u)) continue;
    const ocs__plan_t *pl = &plan[l];
    const ocs__tab_t *T = ocs__layer_tab(l);
    if (!T) {
      free(ws);
      free(cc);
      return OC_ENOMEM;
    }
    double off[OCS_COL_COARSE > OCS_COL_FINE_N ? OCS_COL_COARSE : OCS_COL_FINE_N];
    for (int m = 0; m < pl->nc; m++) off[m] = ((double)m + 0.5) / (double)pl->nc - 0.5;
    ws->n = 0;
    ws->cc = cc[l];
    ws->ic = ic;
    ws->u = u;
    if (pl->kvox) ocs__voxel_cells(B.P, &B.F, l, pl, vmask, vwone, ws);
    for (int v = 0; v < OC_BRICK_VOXELS; v++) {
      if (!(vmask[v] >> l & 1u)) continue;
      double gg[3], c[3];
      int va = ocs__voxel_centre(ic, v, u, gg, c);
      int ha = va == 0 ? 1 : 0, hb = va == 2 ? 1 : 2;
      for (int mb = 0; mb < pl->nc; mb++)
        for (int ma = 0; ma < pl->nc; ma++) {
          double xyz[3];
          xyz[ha] = -OC_ROOT_HALF + (gg[ha] + off[ma]) * u;
          xyz[hb] = -OC_ROOT_HALF + (gg[hb] + off[mb]) * u;
          xyz[va] = c[va];
          ocs__column(B.P, &B.F, l, pl, T, ws, xyz, va, c[va] - 0.5 * u, c[va] + 0.5 * u, v, vwone[v]);
        }
    }
    if (ws->n) ocs__layer_pieces(B.P, &B.F, l, pl, T, ws);
  }
  for (int v = 0; v < OC_BRICK_VOXELS; v++)
    if (ws->sum[v] > 0.0) out[v] += (float)ws->sum[v];
  free(ws);
  free(cc);
  return 0;
}
