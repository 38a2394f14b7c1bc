/* oc_brick.h — 8³ corner-sampled bricks and their codes (design.md, Conventions: bricks and codes).
 *
 * Sample (i, j, k), 0..7, sits at origin + (i, j, k)·size/7; x varies fastest in memory. Two
 * channels: extinction σt (m⁻¹) and sun optical depth τ (dimensionless). Each channel is stored as
 * 16-bit logarithmic codes against a per-brick range [lo, hi]:
 *   code 0            exact zero
 *   code 1..65535     lo·(hi/lo)^((code-1)/65534)      (decode: shaders/brick.h, ocg_code_decode)
 * so the relative error of a non-zero value is at most exp(ln(hi/lo)/(2·65534)) − 1 (1.6e-4 for the
 * largest allowed ratio), independent of where 1e-6..10 m⁻¹ a brick lies. Values below
 * hi / OC_CODE_MAX_RATIO are flushed to exact zero (absolute error < hi / OC_CODE_MAX_RATIO).
 *
 * A brick is empty only if both channels are all zero, and uniform only if both channels are
 * uniform; empty and uniform nodes carry no payload (their values sit in the node record). */
#ifndef OC_COMMON_BRICK_H
#define OC_COMMON_BRICK_H

#include <stdint.h>

#define OC_BRICK_EDGE 8
#define OC_BRICK_VOXELS 512
#define OC_CHANNELS 2
#define OC_CH_SIGMA 0 /**< extinction σt, m⁻¹ */
#define OC_CH_TAU 1   /**< optical depth toward the sun, dimensionless */
#define OC_CODE_ZERO 0
#define OC_CODE_MAX 65535
#define OC_CODE_STEPS 65534 /**< log steps between lo (code 1) and hi (code 65535) */
/*! Largest hi/lo kept inside one brick; smaller values flush to zero. */
#define OC_CODE_MAX_RATIO 1e9
/*! A channel is uniform when max ≤ min·(1 + OC_UNIFORM_TOL); it is then stored as its mean. */
#define OC_UNIFORM_TOL 1e-5
/*! Sanitised values are clamped to this (m⁻¹ for σt; τ likewise): +Inf from data becomes this. */
#define OC_VALUE_MAX 1e9f
/*! Bytes of one brick's codes (both channels). */
#define OC_BRICK_CODE_BYTES (OC_CHANNELS * OC_BRICK_VOXELS * 2)

typedef enum { OC_NODE_EMPTY = 0, OC_NODE_UNIFORM = 1, OC_NODE_BRICK = 2 } oc_node_kind_t;

typedef struct {
  float lo, hi; /**< both 0 for an all-zero channel; else 0 < lo ≤ hi, finite; uniform: lo == hi */
} oc_range_t;

typedef struct {
  uint16_t code[OC_CHANNELS][OC_BRICK_VOXELS]; /**< [channel][i + 8j + 64k] */
} oc_brick_codes_t;

typedef struct {
  uint32_t nan, inf, negative; /**< values replaced: NaN → 0, ±Inf → OC_VALUE_MAX or 0, < 0 → 0 */
} oc_sanitize_stats_t;

/*! oc_sanitize() : makes n values safe to integrate, in place, and counts what it changed.
 *  NaN → 0, +Inf → OC_VALUE_MAX, −Inf and negatives → 0, values above OC_VALUE_MAX clamp to it. */
void oc_sanitize(float *v, int n, oc_sanitize_stats_t *stats);
/*! oc_all_zero() : whether all n values are +0 (bits 0: −0 is not); one vectorised scan. */
int oc_all_zero(const float *v, int n);

/*! oc_brick_encode() : classifies and encodes one brick from sanitised samples (non-negative,
 *  finite; use oc_sanitize() first on untrusted data).
 *  @return the node kind. For OC_NODE_BRICK, codes and range[] are filled; for OC_NODE_UNIFORM,
 *  range[c].lo == range[c].hi == the channel's mean; for OC_NODE_EMPTY both ranges are zero.
 *  `codes` may be NULL when only the classification is wanted. */
oc_node_kind_t oc_brick_encode(const float sigma[OC_BRICK_VOXELS], const float tau[OC_BRICK_VOXELS],
                               oc_brick_codes_t *codes, oc_range_t range[OC_CHANNELS]);
/*! oc_brick_decode() : decoded values of both channels (float, through shaders/brick.h). */
void oc_brick_decode(const oc_brick_codes_t *codes, const oc_range_t range[OC_CHANNELS],
                     float sigma[OC_BRICK_VOXELS], float tau[OC_BRICK_VOXELS]);
/*! oc_code_encode() : one value against a range (the inverse of ocg_code_decode). */
uint16_t oc_code_encode(float v, oc_range_t r);
/*! oc_code_rel_error_bound() : the worst relative error of a decoded non-zero value in range r,
 *  including float rounding of the decoder. */
double oc_code_rel_error_bound(oc_range_t r);

#endif /* OC_COMMON_BRICK_H */
