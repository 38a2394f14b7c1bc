/* oc_noise.c — deterministic 3D gradient noise and fBm (see oc_noise.h).
 *
 * Everything is IEEE double add/sub/mul/compare and 64-bit unsigned integer arithmetic: no libm,
 * no tables, no branches in the kernel, so the scalar and batch paths give the same bits and gcc
 * can if-convert and vectorise the batch loop. */
#include "oc_noise.h"

#include <math.h>   /* isfinite (parameter checks only) */
#include <stddef.h> /* NULL */
#include <string.h> /* memcpy: bit casts */

#include "oc_err.h"

/*-*** Constants ***/

/*! OC__MAGIC : 1.5·2^52. For |x| < 2^51, x + OC__MAGIC rounds x to the nearest integer n and holds
 *  it exactly, with bit pattern bits(OC__MAGIC) + n; so rounding and the double→int64 conversion
 *  need no libm call and no cvttpd2qq (which only AVX-512 vectorises). */
#define OC__MAGIC 6755399441055744.0

/*! OC__SCALE : 1/1.03636, slightly below 1/B with B = 1.0363538112118 the bound of the unscaled
 *  field for Perlin's edge gradients and the quintic fade (numerical maximum over the cell of the
 *  best-case corner sum; oc_noise.h). */
#define OC__SCALE (1.0 / 1.03636)

/* Per-axis hash multipliers (odd, from the golden ratio and two xxh64 primes). */
#define OC__PX 0x9E3779B97F4A7C15ull
#define OC__PY 0xC2B2AE3D27D4EB4Full
#define OC__PZ 0x165667B19E3779F9ull

/*-*** Kernel ***/

/* The kernel must be inlined into the batch loops for gcc to vectorise them. */
#if defined(__GNUC__)
#define OC__INLINE static inline __attribute__((always_inline))
#else
#define OC__INLINE static inline
#endif

static inline uint64_t oc__bits(double d) {
  uint64_t u;
  memcpy(&u, &d, sizeof u);
  return u;
}

/* Seed premix (splitmix64 finaliser): nearby seeds give unrelated fields. */
static inline uint64_t oc__mix64(uint64_t h) {
  h += 0x9E3779B97F4A7C15ull;
  h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
  h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
  return h ^ (h >> 31);
}

/* Gradient index 0..15 of a corner from its summed axis hashes: two xor-shift-multiply rounds
 * (murmur3 fmix64 constants); the top 4 bits depend on every input bit. */
static inline uint64_t oc__corner(uint64_t h) {
  h ^= h >> 32;
  h *= 0xFF51AFD7ED558CCDull;
  h ^= h >> 29;
  h *= 0xC4CEB9FE1A85EC53ull;
  return h >> 60;
}

static inline double oc__double(uint64_t u) {
  double d;
  memcpy(&d, &u, sizeof d);
  return d;
}

/* Branch-free select on bit patterns: m is all ones (take a) or all zeros (take b). Plain ternaries
 * on doubles keep control flow in the loop that gcc does not if-convert for AVX2. */
static inline double oc__sel(uint64_t m, double a, double b) { return oc__double((oc__bits(a) & m) | (oc__bits(b) & ~m)); }
static inline uint64_t oc__mask(int c) { return (uint64_t)0 - (uint64_t)c; }

/* g·(dx, dy, dz) for Perlin's 16 gradients (12 cube edges, 4 repeated), as selects only. */
static inline double oc__grad(uint64_t h, double dx, double dy, double dz) {
  double u = oc__sel(oc__mask(h < 8), dx, dy);
  double v = oc__sel(oc__mask(h < 4), dy, oc__sel(oc__mask((h == 12) | (h == 14)), dx, dz));
  double su = oc__double(oc__bits(u) ^ ((h & 1) << 63)); /* sign flip */
  double sv = oc__double(oc__bits(v) ^ ((h & 2) << 62));
  return su + sv;
}

static inline double oc__lerp(double a, double b, double t) { return a + t * (b - a); }

/* floor(x) as a double and as the low 64 bits of a two's-complement integer, for |x| < 2^51. */
static inline double oc__floor(double x, uint64_t *ix) {
  double t = x + OC__MAGIC;
  double r = t - OC__MAGIC; /* nearest integer */
  uint64_t i = oc__bits(t) - oc__bits(OC__MAGIC);
  uint64_t above = oc__mask(r > x);
  r = r - oc__double(oc__bits(1.0) & above);
  *ix = i + above; /* above is 0 or -1 */
  return r;
}

/* The noise inside a cell at (fx, fy, fz) in [0, 1)³ from its corners' gradient indices g[c],
 * corner c = x + 2y + 4z: the part of the kernel after the hash (oc_noise3_cell exposes it). */
OC__INLINE double oc__cell(const uint64_t g[8], double fx, double fy, double fz) {
  double gx = fx - 1.0, gy = fy - 1.0, gz = fz - 1.0;
  double n000 = oc__grad(g[0], fx, fy, fz);
  double n100 = oc__grad(g[1], gx, fy, fz);
  double n010 = oc__grad(g[2], fx, gy, fz);
  double n110 = oc__grad(g[3], gx, gy, fz);
  double n001 = oc__grad(g[4], fx, fy, gz);
  double n101 = oc__grad(g[5], gx, fy, gz);
  double n011 = oc__grad(g[6], fx, gy, gz);
  double n111 = oc__grad(g[7], gx, gy, gz);
  /* Quintic fade 6t^5 - 15t^4 + 10t^3. */
  double u = fx * fx * fx * (fx * (fx * 6.0 - 15.0) + 10.0);
  double v = fy * fy * fy * (fy * (fy * 6.0 - 15.0) + 10.0);
  double w = fz * fz * fz * (fz * (fz * 6.0 - 15.0) + 10.0);
  double a = oc__lerp(oc__lerp(n000, n100, u), oc__lerp(n010, n110, u), v);
  double b = oc__lerp(oc__lerp(n001, n101, u), oc__lerp(n011, n111, u), v);
  double r = oc__lerp(a, b, w) * OC__SCALE;
  r = oc__sel(oc__mask(r > 1.0), 1.0, r);
  return oc__sel(oc__mask(r < -1.0), -1.0, r);
}

/* The noise inside a cell from the axis hashes of its two corners on each axis: the corners'
 * gradients, then the kernel. Scalars, not arrays, so that gcc still vectorises the batch loops. */
OC__INLINE double oc__hashed_cell(uint64_t hx0, uint64_t hx1, uint64_t hy0, uint64_t hy1, uint64_t hz0, uint64_t hz1,
                                  double fx, double fy, double fz) {
  uint64_t g[8] = {oc__corner(hx0 + hy0 + hz0), oc__corner(hx1 + hy0 + hz0), oc__corner(hx0 + hy1 + hz0),
                   oc__corner(hx1 + hy1 + hz0), oc__corner(hx0 + hy0 + hz1), oc__corner(hx1 + hy0 + hz1),
                   oc__corner(hx0 + hy1 + hz1), oc__corner(hx1 + hy1 + hz1)};
  return oc__cell(g, fx, fy, fz);
}

/* The noise at one point; `s` is the premixed seed. Shared by every entry point. */
OC__INLINE double oc__noise(double x, double y, double z, uint64_t s) {
  uint64_t ix, iy, iz;
  double fx = x - oc__floor(x, &ix);
  double fy = y - oc__floor(y, &iy);
  double fz = z - oc__floor(z, &iz);
  /* Axis hashes of both corners of the cell. */
  uint64_t hx0 = ix * OC__PX + s, hy0 = iy * OC__PY, hz0 = iz * OC__PZ;
  return oc__hashed_cell(hx0, hx0 + OC__PX, hy0, hy0 + OC__PY, hz0, hz0 + OC__PZ, fx, fy, fz);
}

/* The noise at one point with the lattice wrapped every n = mask + 1 cells along each axis (n a
 * power of two): the corners' indices are masked before they are hashed. */
OC__INLINE double oc__noise_wrapped(double x, double y, double z, uint64_t s, uint64_t mask) {
  uint64_t ix, iy, iz;
  double fx = x - oc__floor(x, &ix), fy = y - oc__floor(y, &iy), fz = z - oc__floor(z, &iz);
  return oc__hashed_cell((ix & mask) * OC__PX + s, ((ix + 1) & mask) * OC__PX + s, (iy & mask) * OC__PY,
                         ((iy + 1) & mask) * OC__PY, (iz & mask) * OC__PZ, ((iz + 1) & mask) * OC__PZ, fx, fy, fz);
}

/*-*** Noise ***/

/*! OC__BATCH : the batch loops are built for baseline x86-64, AVX2 (x86-64-v3) and AVX-512
 *  (x86-64-v4), picked at load time (ifunc), and vectorised even at -O2: SSE2 lacks the 64-bit
 *  integer compares the selects need, and gcc's -O2 "very cheap" cost model skips loops that need
 *  an epilogue. Every clone does the same IEEE operations in the same order (-ffp-contract=off
 *  holds inside the attribute: no FMA), so all give the bits of the scalar path; test_noise checks
 *  it on the machine it runs on. Define OC_NOISE_NO_CLONES to build plain functions. */
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 12 && defined(__x86_64__) && \
    defined(__linux__) && !defined(OC_NOISE_NO_CLONES)
#define OC__BATCH                                                          \
  __attribute__((target_clones("default", "arch=x86-64-v3", "arch=x86-64-v4"), \
                 optimize("tree-loop-vectorize", "vect-cost-model=dynamic")))
#else
#define OC__BATCH
#endif

double oc_noise3(double x, double y, double z, uint64_t seed) { return oc__noise(x, y, z, oc__mix64(seed)); }

double oc_noise3_cell(const unsigned char g[8], double fx, double fy, double fz) {
  uint64_t h[8];
  for (int c = 0; c < 8; c++) h[c] = g[c] & 15u;
  return oc__cell(h, fx, fy, fz);
}

OC__BATCH int oc_noise3_batch(const double *xyz, int n, uint64_t seed, float *out) {
  if (n < 0 || (n > 0 && (!xyz || !out))) return OC_EINVAL;
  uint64_t s = oc__mix64(seed);
  for (int i = 0; i < n; i++) out[i] = (float)oc__noise(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], s);
  return 0;
}

/*-*** fBm ***/

/* Per-octave seed, offset, frequency and amplitude, computed the same way for both paths. */
typedef struct {
  uint64_t s[OC_FBM_MAX_OCTAVES];
  double off[OC_FBM_MAX_OCTAVES][3];
  double freq[OC_FBM_MAX_OCTAVES];
  double amp[OC_FBM_MAX_OCTAVES];
  double inv_norm;
  int octaves;
} oc__fbm_plan_t;

int oc_fbm_check(const oc_fbm_t *p) {
  if (!p) return OC_EINVAL;
  if (p->octaves < 1 || p->octaves > OC_FBM_MAX_OCTAVES) return OC_EINVAL;
  if (!isfinite(p->lacunarity) || !(p->lacunarity > 0.0)) return OC_EINVAL;
  if (!isfinite(p->gain) || !(p->gain > 0.0)) return OC_EINVAL;
  return 0;
}

static void oc__fbm_plan(const oc_fbm_t *p, oc__fbm_plan_t *pl) {
  double amp = 1.0, freq = 1.0, norm = 0.0;
  uint64_t h = oc__mix64(p->seed);
  pl->octaves = p->octaves;
  for (int i = 0; i < p->octaves; i++) {
    h = oc__mix64(h);
    pl->s[i] = h;
    for (int k = 0; k < 3; k++) {
      h = oc__mix64(h);
      /* 53 random bits → [0, 1) exactly, × 256. */
      pl->off[i][k] = (double)(h >> 11) * (1.0 / 9007199254740992.0) * 256.0;
    }
    pl->freq[i] = freq;
    pl->amp[i] = amp;
    norm += amp;
    amp *= p->gain;
    freq *= p->lacunarity;
  }
  pl->inv_norm = 1.0 / norm;
}

static inline double oc__fbm_finish(double sum, double inv_norm) {
  double r = sum * inv_norm;
  r = r > 1.0 ? 1.0 : r;
  r = r < -1.0 ? -1.0 : r;
  return r;
}

double oc_fbm3(double x, double y, double z, const oc_fbm_t *p) {
  oc__fbm_plan_t pl;
  if (oc_fbm_check(p) < 0) return 0.0;
  oc__fbm_plan(p, &pl);
  double sum = 0.0;
  for (int i = 0; i < pl.octaves; i++) {
    double f = pl.freq[i];
    sum += pl.amp[i] * oc__noise(x * f + pl.off[i][0], y * f + pl.off[i][1], z * f + pl.off[i][2], pl.s[i]);
  }
  return oc__fbm_finish(sum, pl.inv_norm);
}

#define OC__FBM_CHUNK 256 /* points per pass over the octaves: the partial sums stay in L1 */

/* Octaves [first, last) at m points added to sum[]: octaves outermost, the same additions in the
 * same order as oc_fbm3(), per point. */
OC__INLINE void oc__fbm_octaves(const oc__fbm_plan_t *pl, const double *q, int m, int first, int last, double *sum) {
  for (int i = first; i < last; i++) {
    double f = pl->freq[i], a = pl->amp[i], ox = pl->off[i][0], oy = pl->off[i][1], oz = pl->off[i][2];
    uint64_t s = pl->s[i];
    for (int j = 0; j < m; j++)
      sum[j] += a * oc__noise(q[3 * j] * f + ox, q[3 * j + 1] * f + oy, q[3 * j + 2] * f + oz, s);
  }
}

OC__BATCH int oc_fbm3_batch(const double *xyz, int n, const oc_fbm_t *p, float *out) {
  oc__fbm_plan_t pl;
  double sum[OC__FBM_CHUNK];
  if (n < 0 || (n > 0 && (!xyz || !out))) return OC_EINVAL;
  OC_TRY(oc_fbm_check(p));
  oc__fbm_plan(p, &pl);
  for (int base = 0; base < n; base += OC__FBM_CHUNK) {
    int m = n - base < OC__FBM_CHUNK ? n - base : OC__FBM_CHUNK;
    const double *q = xyz + 3 * (size_t)base;
    for (int j = 0; j < m; j++) sum[j] = 0.0;
    oc__fbm_octaves(&pl, q, m, 0, pl.octaves, sum);
    for (int j = 0; j < m; j++) out[base + j] = (float)oc__fbm_finish(sum[j], pl.inv_norm);
  }
  return 0;
}

OC__BATCH int oc_fbm3_batch_octaves(const double *xyz, int n, const oc_fbm_t *p, int first, int last, double *sum) {
  oc__fbm_plan_t pl;
  if (n < 0 || (n > 0 && (!xyz || !sum))) return OC_EINVAL;
  OC_TRY(oc_fbm_check(p));
  if (first < 0 || first > last || last > p->octaves) return OC_EINVAL;
  oc__fbm_plan(p, &pl);
  oc__fbm_octaves(&pl, xyz, n, first, last, sum);
  return 0;
}

OC__BATCH int oc_fbm3_batch_finish(const double *sum, int n, const oc_fbm_t *p, float *out) {
  oc__fbm_plan_t pl;
  if (n < 0 || (n > 0 && (!sum || !out))) return OC_EINVAL;
  OC_TRY(oc_fbm_check(p));
  oc__fbm_plan(p, &pl);
  for (int j = 0; j < n; j++) out[j] = (float)oc__fbm_finish(sum[j], pl.inv_norm);
  return 0;
}

OC__BATCH int oc_fbm3_batch_top(const double *sum, int n, const oc_fbm_t *p, int first, float *out) {
  oc__fbm_plan_t pl;
  if (n < 0 || (n > 0 && (!sum || !out))) return OC_EINVAL;
  OC_TRY(oc_fbm_check(p));
  if (first < 0 || first > p->octaves) return OC_EINVAL;
  oc__fbm_plan(p, &pl);
  for (int j = 0; j < n; j++) {
    double t = sum[j];
    for (int i = first; i < pl.octaves; i++) t += pl.amp[i];
    out[j] = (float)oc__fbm_finish(t, pl.inv_norm);
  }
  return 0;
}

/* Checks of oc_fbm3_periodic's parameters: 0 or OC_EINVAL. */
static int oc__periodic_check(const oc_fbm_t *p, int period) {
  OC_TRY(oc_fbm_check(p));
  if (p->lacunarity != 2.0 || period < 1 || (period & (period - 1)) || period > (1 << 20)) return OC_EINVAL;
  return (double)period * ldexp(1.0, p->octaves - 1) > 1073741824.0 ? OC_EINVAL : 0;
}

OC__BATCH int oc_fbm3_periodic_batch(const double *xyz, int n, const oc_fbm_t *p, int period, float *out) {
  oc__fbm_plan_t pl;
  double sum[OC__FBM_CHUNK];
  if (n < 0 || (n > 0 && (!xyz || !out))) return OC_EINVAL;
  OC_TRY(oc__periodic_check(p, period));
  oc__fbm_plan(p, &pl);
  for (int base = 0; base < n; base += OC__FBM_CHUNK) {
    int m = n - base < OC__FBM_CHUNK ? n - base : OC__FBM_CHUNK;
    const double *q = xyz + 3 * (size_t)base;
    for (int j = 0; j < m; j++) sum[j] = 0.0;
    for (int i = 0; i < pl.octaves; i++) {
      double f = pl.freq[i], a = pl.amp[i], ox = pl.off[i][0], oy = pl.off[i][1], oz = pl.off[i][2];
      uint64_t s = pl.s[i], mask = ((uint64_t)period << i) - 1;
      for (int j = 0; j < m; j++)
        sum[j] += a * oc__noise_wrapped(q[3 * j] * f + ox, q[3 * j + 1] * f + oy, q[3 * j + 2] * f + oz, s, mask);
    }
    for (int j = 0; j < m; j++) out[base + j] = (float)oc__fbm_finish(sum[j], pl.inv_norm);
  }
  return 0;
}

double oc_fbm3_periodic(double x, double y, double z, const oc_fbm_t *p, int period) {
  double q[3] = {x, y, z};
  float v;
  return oc_fbm3_periodic_batch(q, 1, p, period, &v) < 0 ? 0.0 : (double)v;
}
