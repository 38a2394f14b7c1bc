/* noise_volume.h — tiled, pre-filtered noise volumes: a pattern as a texture fetch, with exact
 * bounds over any box (issue 17's first lever; docs/numerics.md, "Noise volumes").
 *
 * A volume holds one tile of a periodic fBm (oc_fbm3_periodic(), repeating every `period` units of
 * its first octave's lattice) at the centres of N³ texels, and
 *   - its mip chain: level m has N/2^m texels a side, each the mean of its 2³ children at level
 *     m − 1 (so the mean of its 8^m level-0 texels), a box-filtered copy for coarse samples;
 *   - a min/max pyramid per level: step p ≥ 1 of level m's holds, for block B, the least and the
 *     largest texel of level m with indices in [B·2^p, (B + 1)·2^p] on every axis (both ends in).
 * A fetch at level m is the trilinear interpolation of that level's texels, wrapped, at a point in
 * the fBm's own coordinates (what oc_fbm3() would be given).
 *
 * Bounds. Trilinear interpolation is a convex combination of a cell's 8 corner texels, so over a
 * box a level takes values between the least and the largest of its texels at the corners of the
 * cells the box meets; ocs_nvol_bound() reads that range from the fewest pyramid blocks covering
 * those cells (at most 2 a side). Where the box meets at most 2 cells a side it is exact instead:
 * on each piece of the box inside one cell the interpolation is multilinear, so its extremes lie
 * at the pieces' vertices (at most 3³ fetches, widened by a float ulp for the fetch's rounding).
 * No constant enters.
 *
 * Determinism: the texels are a pure function of the description (IEEE double, a fixed order of
 * operations, no libm in the fBm); the mips sum their children in a fixed order. */
#ifndef OC_SERVER_NOISE_VOLUME_H
#define OC_SERVER_NOISE_VOLUME_H

#include <stddef.h>

#include "oc_noise.h"

/*! The largest volume: 2^OCS_NVOL_MAX_LOG2 texels a side (256³ floats are 64 MiB). */
#define OCS_NVOL_MAX_LOG2 8

typedef struct {
  int log2_size; /* N = 2^log2_size texels a side, 1..OCS_NVOL_MAX_LOG2 */
  int period;    /* the tile, in units of the first octave's lattice: ≥ 1, and N/period ≥ 1 */
  oc_fbm_t fbm;  /* lacunarity 2 (an integer, so every octave's lattice wraps with the tile) */
} ocs_nvol_desc_t;

typedef struct ocs_nvol ocs_nvol_t;

/*! ocs_nvol_create() : builds the volume (level 0, its mips, the pyramids) into a new block.
 *  @return 0, OC_EINVAL (an invalid description: `why` says which field) or OC_ENOMEM. */
int ocs_nvol_create(const ocs_nvol_desc_t *d, ocs_nvol_t **out, char *why, size_t why_len);
void ocs_nvol_destroy(ocs_nvol_t *v);

/*! Levels of the mip chain (log2_size + 1), and a level's texel size in the fBm's units. */
int ocs_nvol_levels(const ocs_nvol_t *v);
double ocs_nvol_texel(const ocs_nvol_t *v, int level);
/*! The tile in the fBm's units (the description's period). */
double ocs_nvol_period(const ocs_nvol_t *v);
/*! Bytes held: the mip chain and the pyramids (about 1.47 × N³ floats). */
size_t ocs_nvol_bytes(const ocs_nvol_t *v);

/*! ocs_nvol_fetch() : the trilinear interpolation of level `level` (clamped to the chain) at p, in
 *  the fBm's units, wrapped into the tile. */
float ocs_nvol_fetch(const ocs_nvol_t *v, int level, const double p[3]);

/*! ocs_nvol_bound() : [*lo, *hi] holds every value ocs_nvol_fetch() at `level` takes in the box
 *  [a, b] (the fBm's units, a ≤ b on every axis; any size: a box a tile wide gets the whole
 *  volume's range). */
void ocs_nvol_bound(const ocs_nvol_t *v, int level, const double a[3], const double b[3], float *lo, float *hi);

/*! The texels of one level (N/2^level a side, x fastest), for tests and statistics. */
const float *ocs_nvol_texels(const ocs_nvol_t *v, int level);

#endif /* OC_SERVER_NOISE_VOLUME_H */
