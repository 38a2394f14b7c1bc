/* oc_noise.h — deterministic 3D gradient noise and fBm.
 *
 * Pure functions of (position, seed): no tables, no state, no libm, so every thread, run, compiler
 * and machine that honours IEEE double arithmetic (no -ffast-math, -ffp-contract=off: see the root
 * CMakeLists.txt) gets the same bits.
 *
 * Positions are in lattice units: the caller divides metres by its feature size. The lattice
 * cell of a coordinate is floor(x), held as a 64-bit integer; each corner's gradient comes from a
 * 64-bit integer hash of (ix, iy, iz, seed) (multiply–add per axis, then two xor-shift-multiply
 * rounds). The 16 gradients are Perlin's (2002) cube edges, interpolation weights use the quintic
 * fade 6t^5 - 15t^4 + 10t^3, so the field is C2 and exactly 0 at every lattice point.
 *
 * Bound. With these gradients the unscaled field is at most B = 1.0363538112 in magnitude (the
 * maximum over the cell of Σ w_c · max_g g·(p - c), reached near cell point (0.355, 0.481, 0.5) and
 * its symmetric images: each corner's best gradient gives the sum of the two largest |p - c|
 * components, and a multi-start numerical maximisation of the weighted sum over the cell gives B;
 * at the cell centre it is exactly 1). The output is the unscaled value × 1/1.03636 ≤ 1/B,
 * then clamped to [-1, 1] as a guard against rounding, so |oc_noise3()| ≤ 1 always; the clamp
 * never changes a finite value in practice. Observed over 1e6 random points: -0.964..0.924,
 * mean 0.0001, standard deviation 0.26; at the extremal cell points over 2e5 cells, |n| ≤ 0.957.
 *
 * Domain. Exact for |x|, |y|, |z| < 2^50 (≈ 1.1e15 lattice units; a 6.4e6 m planet at a 1 mm
 * feature size is 6.4e9). Outside that, or for NaN/inf, the result is unspecified (never UB).
 *
 * Lipschitz. |∇n| ≤ 3.88 per lattice unit, proven: inside a cell the largest derivative along a
 * unit direction d over every gradient configuration is S·Σ_c max_g g·v_c, v_c = (d·∇w_c)(p − c) +
 * w_c d (w_c the corner's fade weight; each corner's gradient independent), convex in d; a branch
 * and bound with interval arithmetic over the cell, on the vertices of a subdivided icosahedron
 * (convexity bounds the directions between them), certifies ≤ 3.8772 (tests/common/test_noise.c,
 * docs/numerics.md). The supremum is 3.75·S = 3.6184, at the cell's centre along an axis (every
 * corner's gradient the best for it), which the adversarial test reaches with the kernel itself.
 * The field is C² across cell faces, so the bound holds between any two points. */
#ifndef OC_COMMON_NOISE_H
#define OC_COMMON_NOISE_H

#include <stdint.h>

#define OC_NOISE_LIPSCHITZ 3.88 /**< proven bound on |∇ oc_noise3| per lattice unit (above) */
#define OC_FBM_MAX_OCTAVES 24   /**< octaves beyond this add nothing a double can hold */

/*! oc_noise3() :
 *  Gradient noise at (x, y, z) in lattice units.
 *  @return a value in [-1, 1]; 0 at every integer lattice point. Thread-safe, pure. */
double oc_noise3(double x, double y, double z, uint64_t seed);

/*! oc_noise3_cell() :
 *  The kernel of oc_noise3() inside one lattice cell, at (fx, fy, fz) in [0, 1]³, with the corners'
 *  gradient indices g[c] (0..15, Perlin's list; corner c = x + 2y + 4z) given instead of hashed:
 *  every value oc_noise3() takes is one of these. For tests that search the gradient
 *  configurations (the Lipschitz bound's). */
double oc_noise3_cell(const unsigned char g[8], double fx, double fy, double fz);

/*! oc_noise3_batch() :
 *  out[i] = (float)oc_noise3(xyz[3i], xyz[3i+1], xyz[3i+2], seed) for i < n, bit for bit.
 *  Written branch-free so that gcc vectorises it (AVX2 and AVX-512 clones picked at load
 *  time on x86-64 Linux with gcc; see OC__BATCH in oc_noise.c). About 9x faster per point than
 *  oc_noise3() on an AVX-512 machine.
 *  @return 0, or OC_EINVAL when n < 0 or a pointer is NULL with n > 0. */
int oc_noise3_batch(const double *xyz, int n, uint64_t seed, float *out);

/*! oc_fbm_t :
 *  Fractional Brownian motion: Σ_{i<octaves} gain^i · n_i(lacunarity^i · p + o_i) / Σ gain^i,
 *  where n_i is oc_noise3() with a per-octave seed derived from `seed`, and o_i a per-octave
 *  offset in [0, 256)^3 (also derived from the seed) so that the octaves' lattices do not line up
 *  (with lacunarity 2 every integer point would otherwise be 0 in every octave). The weighted mean
 *  keeps the result in [-1, 1]. */
typedef struct {
  int octaves;       /**< 1..OC_FBM_MAX_OCTAVES */
  double lacunarity; /**< frequency factor per octave, finite, > 0 (typically 2) */
  double gain;       /**< amplitude factor per octave, finite, > 0 (typically 0.5) */
  uint64_t seed;     /**< any value */
} oc_fbm_t;

/*! oc_fbm_check() : @return 0 when the parameters are valid, else OC_EINVAL. */
int oc_fbm_check(const oc_fbm_t *p);

/*! oc_fbm3() :
 *  fBm at (x, y, z) in lattice units of the first octave.
 *  @return a value in [-1, 1]; 0 when the parameters are invalid (check them with oc_fbm_check()).
 *  note : the highest octave's coordinates are lacunarity^(octaves-1) times larger; keep them
 *  inside the noise domain (|coordinate| < 2^50). */
double oc_fbm3(double x, double y, double z, const oc_fbm_t *p);

/*! oc_fbm3_periodic_batch() :
 *  out[i] = the fBm p at point i with each octave's lattice wrapped so that the field repeats every
 *  `period` units of the first octave's lattice along each axis: octave i masks its corners' indices
 *  to period·2^i cells before hashing them. The same kernel, octave seeds, offsets and bound as
 *  oc_fbm3(), so the same distribution, but a different field (as float, like oc_fbm3_batch()). For
 *  tiled noise volumes (server/noise_volume.h).
 *  @return 0, or OC_EINVAL: invalid parameters, a lacunarity other than 2, a period that is not a
 *  power of two in 1..2^20, period·2^(octaves-1) > 2^30, n < 0, NULL pointers with n > 0. */
int oc_fbm3_periodic_batch(const double *xyz, int n, const oc_fbm_t *p, int period, float *out);
/*! oc_fbm3_periodic() : oc_fbm3_periodic_batch() at one point; 0 for invalid parameters. */
double oc_fbm3_periodic(double x, double y, double z, const oc_fbm_t *p, int period);

/*! oc_fbm3_batch() :
 *  out[i] = (float)oc_fbm3(point i, p) for i < n, bit for bit.
 *  @return 0, or OC_EINVAL for invalid parameters, n < 0, or NULL pointers with n > 0. */
int oc_fbm3_batch(const double *xyz, int n, const oc_fbm_t *p, float *out);

/*! oc_fbm3_batch_octaves() :
 *  Adds octaves [first, last) of the fBm p at n points to sum[i], gain^k · n_k(...) one octave
 *  after the other, unnormalised: from sum[i] = 0, octaves [0, j) then [j, octaves), and
 *  oc_fbm3_batch_finish(), give the bits of oc_fbm3_batch() (the same additions in the same
 *  order). So an fBm can be evaluated in two passes, with oc_fbm3_batch_top() deciding between them
 *  which points need the rest.
 *  @return 0, or OC_EINVAL (invalid parameters, 0 ≤ first ≤ last ≤ octaves violated, n < 0, NULL
 *  pointers with n > 0). */
int oc_fbm3_batch_octaves(const double *xyz, int n, const oc_fbm_t *p, int first, int last, double *sum);

/*! oc_fbm3_batch_finish() : out[i] = the fBm's value from its full sum[i] (sum / Σ gain^k, clamped
 *  to [-1, 1], as float), as oc_fbm3_batch() finishes it. @return 0 or OC_EINVAL. */
int oc_fbm3_batch_finish(const double *sum, int n, const oc_fbm_t *p, float *out);

/*! oc_fbm3_batch_top() :
 *  out[i] = oc_fbm3_batch_finish() of sum[i] + gain^k for each octave k in [first, octaves), added
 *  in the same order in double: the largest value the fBm can take at a point whose partial sum
 *  over octaves [0, first) is sum[i]. Every noise value is in [-1, 1], so an octave adds a rounded
 *  gain^k · n ≤ gain^k, and rounding, the normalisation, the clamp and the float conversion are
 *  monotone: out[i] ≥ the fBm's value there, exactly (no margin needed).
 *  @return 0, or OC_EINVAL (invalid parameters, first outside [0, octaves], n < 0, NULL pointers). */
int oc_fbm3_batch_top(const double *sum, int n, const oc_fbm_t *p, int first, float *out);

#endif /* OC_COMMON_NOISE_H */
