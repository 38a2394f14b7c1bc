/* noise_volume.c — tiled, pre-filtered noise volumes (noise_volume.h). */
#include "noise_volume.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "oc_err.h"

struct ocs_nvol {
  int log2n;
  double period, scale;                      /* scale: level-0 texels per unit of the fBm */
  float *tex[OCS_NVOL_MAX_LOG2 + 1]; /* the mip chain; tex[m]: (N >> m)³ */
  /* each level's pyramid: lo[m][p], hi[m][p] (p ≥ 1) over blocks of 2^p of its cells */
  float *lo[OCS_NVOL_MAX_LOG2 + 1][OCS_NVOL_MAX_LOG2 + 1], *hi[OCS_NVOL_MAX_LOG2 + 1][OCS_NVOL_MAX_LOG2 + 1];
};

static size_t ocs__idx(int n, int64_t x, int64_t y, int64_t z) {
  int64_t m = n - 1;
  return ((size_t)(z & m) * (size_t)n + (size_t)(y & m)) * (size_t)n + (size_t)(x & m);
}

static int ocs__check(const ocs_nvol_desc_t *d, char *why, size_t why_len) {
  const char *bad = NULL;
  if (!d)
    bad = "no description";
  else if (d->log2_size < 1 || d->log2_size > OCS_NVOL_MAX_LOG2)
    bad = "log2_size outside 1..OCS_NVOL_MAX_LOG2";
  else if (d->period < 1 || d->period > (1 << d->log2_size) || (d->period & (d->period - 1)))
    bad = "period not a power of two in 1..N (each lattice cell needs a texel)";
  else if (oc_fbm_check(&d->fbm) < 0 || d->fbm.lacunarity != 2.0)
    bad = "fbm invalid or its lacunarity not 2";
  if (bad && why && why_len > 0) snprintf(why, why_len, "noise volume: %s", bad);
  return bad ? OC_EINVAL : 0;
}

/* Level 0: the periodic fBm at the texel centres, a row at a time. @return 0 or OC_ENOMEM. */
static int ocs__fill(ocs_nvol_t *v, const ocs_nvol_desc_t *d) {
  int n = 1 << v->log2n;
  double h = v->period / (double)n, *xyz = malloc(sizeof(double) * 3 * (size_t)n);
  if (!xyz) return OC_ENOMEM;
  for (int z = 0; z < n; z++)
    for (int y = 0; y < n; y++) {
      for (int x = 0; x < n; x++) xyz[3 * x] = (x + 0.5) * h, xyz[3 * x + 1] = (y + 0.5) * h, xyz[3 * x + 2] = (z + 0.5) * h;
      oc_fbm3_periodic_batch(xyz, n, &d->fbm, d->period, v->tex[0] + ((size_t)z * (size_t)n + (size_t)y) * (size_t)n);
    }
  free(xyz);
  return 0;
}

/* Level m from level m − 1: each texel the mean of its 2³ children, summed in a fixed order. */
static void ocs__mip(ocs_nvol_t *v, int m) {
  int n = 1 << (v->log2n - m), c = 2 * n;
  const float *s = v->tex[m - 1];
  float *t = v->tex[m];
  for (int z = 0; z < n; z++)
    for (int y = 0; y < n; y++)
      for (int x = 0; x < n; x++) {
        double sum = 0.0;
        for (int k = 0; k < 8; k++) sum += (double)s[ocs__idx(c, 2 * x + (k & 1), 2 * y + (k >> 1 & 1), 2 * z + (k >> 2))];
        t[ocs__idx(n, x, y, z)] = (float)(sum * 0.125);
      }
}

/* Step p of level m's pyramid: block B spans that level's indices [B·2^p, (B + 1)·2^p]. Step 1
 * reads the 3³ texels; step p > 1 its 2³ child blocks, whose closed spans tile the parent's. */
static void ocs__pyramid(ocs_nvol_t *v, int m, int p) {
  int n = 1 << (v->log2n - m - p), c = 2 * n, r = p == 1 ? 3 : 2;
  const float *lo_in = p == 1 ? v->tex[m] : v->lo[m][p - 1], *hi_in = p == 1 ? v->tex[m] : v->hi[m][p - 1];
  for (int z = 0; z < n; z++)
    for (int y = 0; y < n; y++)
      for (int x = 0; x < n; x++) {
        float lo = INFINITY, hi = -INFINITY;
        for (int k = 0; k < r * r * r; k++) {
          size_t i = ocs__idx(c, 2 * x + k % r, 2 * y + k / r % r, 2 * z + k / (r * r));
          lo = lo_in[i] < lo ? lo_in[i] : lo;
          hi = hi_in[i] > hi ? hi_in[i] : hi;
        }
        v->lo[m][p][ocs__idx(n, x, y, z)] = lo;
        v->hi[m][p][ocs__idx(n, x, y, z)] = hi;
      }
}

static float *ocs__alloc(int log2n) { return malloc(((size_t)1 << (3 * log2n)) * sizeof(float)); }

int ocs_nvol_create(const ocs_nvol_desc_t *d, ocs_nvol_t **out, char *why, size_t why_len) {
  if (!out) return OC_EINVAL;
  *out = NULL;
  OC_TRY(ocs__check(d, why, why_len));
  ocs_nvol_t *v = calloc(1, sizeof *v);
  if (!v) return OC_ENOMEM;
  v->log2n = d->log2_size;
  v->period = (double)d->period;
  v->scale = (double)(1 << v->log2n) / v->period;
  int bad = 0;
  for (int m = 0; m <= v->log2n; m++) {
    bad |= !(v->tex[m] = ocs__alloc(v->log2n - m));
    for (int p = 1; m + p <= v->log2n; p++)
      bad |= !(v->lo[m][p] = ocs__alloc(v->log2n - m - p)), bad |= !(v->hi[m][p] = ocs__alloc(v->log2n - m - p));
  }
  if (bad || ocs__fill(v, d) < 0) {
    ocs_nvol_destroy(v);
    return OC_ENOMEM;
  }
  for (int m = 0; m <= v->log2n; m++) {
    if (m > 0) ocs__mip(v, m);
    for (int p = 1; m + p <= v->log2n; p++) ocs__pyramid(v, m, p);
  }
  *out = v;
  return 0;
}

void ocs_nvol_destroy(ocs_nvol_t *v) {
  if (!v) return;
  for (int m = 0; m <= OCS_NVOL_MAX_LOG2; m++) {
    free(v->tex[m]);
    for (int p = 0; p <= OCS_NVOL_MAX_LOG2; p++) free(v->lo[m][p]), free(v->hi[m][p]);
  }
  free(v);
}

int ocs_nvol_levels(const ocs_nvol_t *v) { return v->log2n + 1; }
double ocs_nvol_texel(const ocs_nvol_t *v, int level) { return ldexp(1.0 / v->scale, level); }
double ocs_nvol_period(const ocs_nvol_t *v) { return v->period; }
size_t ocs_nvol_bytes(const ocs_nvol_t *v) {
  size_t n = 0;
  for (int m = 0; m <= v->log2n; m++) {
    n += (size_t)1 << (3 * (v->log2n - m));
    for (int p = 1; m + p <= v->log2n; p++) n += (size_t)2 << (3 * (v->log2n - m - p));
  }
  return n * sizeof(float);
}
const float *ocs_nvol_texels(const ocs_nvol_t *v, int level) {
  return level >= 0 && level <= v->log2n ? v->tex[level] : NULL;
}

/* Level m's trilinear interpolation at t, in that level's texel-centre coordinates. */
static double ocs__trilinear(const ocs_nvol_t *v, int m, const double t[3]) {
  int n = 1 << (v->log2n - m);
  double f[3];
  int64_t i[3];
  for (int k = 0; k < 3; k++) {
    double fl = floor(t[k]);
    i[k] = (int64_t)fl;
    f[k] = t[k] - fl;
  }
  const float *x = v->tex[m];
  double c[8];
  for (int k = 0; k < 8; k++) c[k] = (double)x[ocs__idx(n, i[0] + (k & 1), i[1] + (k >> 1 & 1), i[2] + (k >> 2))];
  double x0 = c[0] + f[0] * (c[1] - c[0]), x1 = c[2] + f[0] * (c[3] - c[2]);
  double x2 = c[4] + f[0] * (c[5] - c[4]), x3 = c[6] + f[0] * (c[7] - c[6]);
  double y0 = x0 + f[1] * (x1 - x0), y1 = x2 + f[1] * (x3 - x2);
  return y0 + f[2] * (y1 - y0);
}

float ocs_nvol_fetch(const ocs_nvol_t *v, int level, const double p[3]) {
  level = level < 0 ? 0 : (level > v->log2n ? v->log2n : level);
  double s = ldexp(v->scale, -level), t[3] = {p[0] * s - 0.5, p[1] * s - 0.5, p[2] * s - 0.5};
  return (float)ocs__trilinear(v, level, t);
}

/* A box meeting at most 2 cells a side, [ta, tb] in texel-centre coordinates: each piece of it inside
 * one cell is a box on which the interpolation is multilinear, so its extremes lie at the pieces'
 * vertices, the points of {ta, the cell boundary between, tb} on each axis. Widened by a float ulp:
 * a fetch inside rounds its double to a float, and may round the other way. */
static void ocs__vertex_range(const ocs_nvol_t *v, int level, const double ta[3], const double tb[3], float *lo,
                              float *hi) {
  double g[3][3];
  int ng[3];
  for (int k = 0; k < 3; k++) {
    double cut = floor(tb[k]);
    ng[k] = 0;
    g[k][ng[k]++] = ta[k];
    if (cut > ta[k]) g[k][ng[k]++] = cut;
    g[k][ng[k]++] = tb[k];
  }
  double l = INFINITY, h = -INFINITY;
  for (int z = 0; z < ng[2]; z++)
    for (int y = 0; y < ng[1]; y++)
      for (int x = 0; x < ng[0]; x++) {
        double t[3] = {g[0][x], g[1][y], g[2][z]}, f = ocs__trilinear(v, level, t);
        l = f < l ? f : l, h = f > h ? f : h;
      }
  *lo = nextafterf((float)l, -INFINITY), *hi = nextafterf((float)h, INFINITY);
}

/* The least and largest texel of `level` in the cells [ca, cb] (per axis; cell j has corners j and
 * j + 1), from the fewest pyramid blocks that cover them: at most 2 a side. */
static void ocs__cells_range(const ocs_nvol_t *v, int level, const int64_t ca[3], const int64_t cb[3], float *lo,
                             float *hi) {
  int n = 1 << (v->log2n - level), top = v->log2n - level, p = 0;
  while (p < top && ((cb[0] >> p) - (ca[0] >> p) > 1 || (cb[1] >> p) - (ca[1] >> p) > 1 || (cb[2] >> p) - (ca[2] >> p) > 1))
    p++;
  float l = INFINITY, h = -INFINITY;
  int nb = p ? n >> p : n, e = p ? 0 : 1; /* step 0: the corner texels themselves */
  const float *L = p ? v->lo[level][p] : v->tex[level], *H = p ? v->hi[level][p] : v->tex[level];
  for (int64_t z = ca[2] >> p; z <= (cb[2] >> p) + e; z++)
    for (int64_t y = ca[1] >> p; y <= (cb[1] >> p) + e; y++)
      for (int64_t x = ca[0] >> p; x <= (cb[0] >> p) + e; x++) {
        size_t i = ocs__idx(nb, x, y, z);
        l = L[i] < l ? L[i] : l, h = H[i] > h ? H[i] : h;
      }
  *lo = l, *hi = h;
}

void ocs_nvol_bound(const ocs_nvol_t *v, int level, const double a[3], const double b[3], float *lo, float *hi) {
  level = level < 0 ? 0 : (level > v->log2n ? v->log2n : level);
  int n = 1 << (v->log2n - level);
  double s = ldexp(v->scale, -level);
  int64_t ca[3], cb[3];
  double ta[3], tb[3];
  int few = 1; /* at most 2 cells a side */
  for (int k = 0; k < 3; k++) {
    ta[k] = a[k] * s - 0.5, tb[k] = b[k] * s - 0.5;
    if (!(tb[k] - ta[k] < (double)(n - 1)) || !(ta[k] > -4.0e18 && tb[k] < 4.0e18)) { /* a tile or more, NaN */
      ca[0] = ca[1] = ca[2] = 0, cb[0] = cb[1] = cb[2] = n - 1, few = 0;
      break;
    }
    ca[k] = (int64_t)floor(ta[k]), cb[k] = (int64_t)floor(tb[k]);
    few &= cb[k] - ca[k] <= 1;
  }
  if (few)
    ocs__vertex_range(v, level, ta, tb, lo, hi);
  else
    ocs__cells_range(v, level, ca, cb, lo, hi);
}
