/* oc_brick.c — classification, 16-bit log encoding and decoding of 8³ bricks (oc_brick.h).
 *
 * Decoding is shaders/brick.h's ocg_code_decode(), the same function the shaders run, so the
 * encoder can pick each code by comparing what the renderer will actually see. */
#include "oc_brick.h"

#include <float.h>  /* FLT_MAX */
#include <math.h>   /* log, isnan, isinf, signbit */
#include <stddef.h> /* NULL */
#include <stdint.h> /* uint32_t */
#include <string.h> /* memcpy */

#include "brick.h" /* ocg_code_decode */

/*-*** Sanitising ***/

/* Whether every value's bits, read as an unsigned integer, are at most lim: a branch-free scan in
 * blocks of a fixed 8, which gcc's -O2 cost model vectorises (the per-value paths below are not, and
 * nearly every brick takes none of them). */
static int oc__bits_at_most(const float *v, int n, uint32_t lim) {
  uint32_t over = 0;
  int i = 0;
  for (; i + 8 <= n; i += 8)
    for (int k = 0; k < 8; k++) {
      uint32_t u;
      memcpy(&u, &v[i + k], sizeof u);
      over |= (uint32_t)(u > lim);
    }
  for (; i < n; i++) {
    uint32_t u;
    memcpy(&u, &v[i], sizeof u);
    over |= (uint32_t)(u > lim);
  }
  return !over;
}

/* Whether every value is already what oc_sanitize() leaves, +0 or in (0, OC_VALUE_MAX]: exactly
 * bits ≤ bits(OC_VALUE_MAX), since the sign bit (negatives, −0), infinities and NaNs all lie above
 * it. The per-value branches cost 1.5 % of the world's instructions. */
static int oc__clean(const float *v, int n) {
  const float vmax = OC_VALUE_MAX;
  uint32_t lim;
  memcpy(&lim, &vmax, sizeof lim);
  return oc__bits_at_most(v, n, lim);
}

int oc_all_zero(const float *v, int n) { return v && n >= 0 && oc__bits_at_most(v, n, 0); }

void oc_sanitize(float *v, int n, oc_sanitize_stats_t *stats) {
  oc_sanitize_stats_t st = {0, 0, 0};
  if (!v || n <= 0 || oc__clean(v, n)) return;
  for (int i = 0; i < n; i++) {
    float x = v[i];
    if (isnan(x)) {
      v[i] = 0.0f;
      st.nan++;
    } else if (isinf(x)) {
      v[i] = x > 0.0f ? OC_VALUE_MAX : 0.0f;
      st.inf++;
    } else if (x < 0.0f) {
      v[i] = 0.0f;
      st.negative++;
    } else if (x > OC_VALUE_MAX) {
      v[i] = OC_VALUE_MAX; /* finite but absurd: clamped, not counted (no data error) */
    } else if (x == 0.0f) {
      v[i] = 0.0f; /* −0 → +0, so equal content always encodes to equal bytes */
    }
  }
  /* Counts accumulate, so one stats struct can cover both channels or many bricks. */
  if (stats) {
    stats->nan += st.nan;
    stats->inf += st.inf;
    stats->negative += st.negative;
  }
}

/*-*** Codes ***/

/* A varying range's decoder, its logarithm taken once (ocg_code_decode_at: the decoder's bits), and
 * the margin, in codes, beyond which the log-space position alone decides a value's code
 * (oc__encode_log). */
typedef struct {
  float lo, l2;
  double inv_ln, margin; /* 1 / ln(hi/lo), for a value's position among the codes */
} oc__dec_t;

/* How far, in codes, a float-decoded code may sit from its exact position lo·(hi/lo)^((c−1)/65534):
 * the rounding of hi/lo, log2f, t = (c−1)/65534 and the product (each relative 2^-24, or 2^-23
 * for log2f; times up to 65534 codes of the exponent: 0.016 codes), and of exp2f and the product
 * with lo (2^-23 and 2^-24 of the value: 0.023/L2 codes, L2 = log2(hi/lo), one code being
 * ln 2·L2/65534 of the value). Twice that, plus the gap between the linear and the logarithmic
 * midpoint of two neighbours (at most an eighth of a code's relative width: 4e-5), is the margin;
 * below L2 = 1 (ratios under 2, whose codes are within the decoder's rounding) the search decides
 * every value. */
static double oc__code_margin(float l2) {
  if (!(l2 >= 1.0f)) return INFINITY;
  return 2.0 * (0.016 + 0.023 / (double)l2) + 1e-4;
}

static oc__dec_t oc__decoder(float lo, float hi) {
  float l2 = ocg_code_log2_ratio(lo, hi);
  return (oc__dec_t){lo, l2, 1.0 / log((double)hi / (double)lo), oc__code_margin(l2)};
}
static float oc__dec(const oc__dec_t *d, uint32_t c) { return ocg_code_decode_at(c, d->lo, d->l2); }

/* Largest code c in 1..65535 with decode(c) ≤ v, given decode(1) = lo ≤ v, and the decoded values
 * of c and c + 1 (FLT_MAX past the top) to *dc, *dn. The decoded sequence is non-decreasing in c
 * (exp2f and the products are monotonic), so this is a bracket search. The log-space guess is
 * almost always within one code, so the neighbourhood is tried first (two or three decodes, which
 * the caller's fix-up reuses); a binary search covers the rare case where float rounding of the
 * decoder is larger than one code step (ratios within ~1e-3 of 1, where many codes decode to one
 * float). */
static uint32_t oc__code_floor(float v, const oc__dec_t *d, uint32_t guess, float *dc, float *dn) {
  uint32_t a, b; /* invariant: decode(a) ≤ v; b == 65536 or decode(b) > v */
  if (guess <= 1) guess = 1;
  if (guess > OC_CODE_MAX) guess = OC_CODE_MAX;
  float g = oc__dec(d, guess);
  if (g <= v) {
    float g1 = guess == OC_CODE_MAX ? FLT_MAX : oc__dec(d, guess + 1);
    if (g1 > v) return *dc = g, *dn = g1, guess;
    float g2 = guess + 1 == OC_CODE_MAX ? FLT_MAX : oc__dec(d, guess + 2);
    if (g2 > v) return *dc = g1, *dn = g2, guess + 1;
    a = guess + 2;
    b = OC_CODE_MAX + 1;
  } else {
    if (guess == 1) return *dc = g, *dn = oc__dec(d, 2), 1; /* only if decode(1) ≠ lo, which the decoder rules out */
    float g0 = oc__dec(d, guess - 1);
    if (g0 <= v) return *dc = g0, *dn = g, guess - 1;
    a = 1;
    b = guess - 1;
  }
  while (b - a > 1) {
    uint32_t m = a + (b - a) / 2;
    if (oc__dec(d, m) <= v)
      a = m;
    else
      b = m;
  }
  *dc = oc__dec(d, a);
  *dn = a == OC_CODE_MAX ? FLT_MAX : oc__dec(d, a + 1);
  return a;
}

/* Best code for lo ≤ v (v may exceed hi) against a range with 0 < lo < hi: |decode(code) − v| the
 * smallest any code achieves (ties go to the lower). x, v's exact position among the codes, decides
 * alone where it lies farther than the decoder's margin from a code and from a midpoint between two
 * (most values of a range wider than 2×: no decode at all); else the nearest in log space is fixed
 * up against the decoded neighbours. */
static uint16_t oc__encode_log(float v, const oc__dec_t *d) {
  double x = log((double)v / (double)d->lo) * d->inv_ln * (double)OC_CODE_STEPS + 1.0;
  if (x >= 1.0 && x < (double)OC_CODE_MAX) {
    double c0 = floor(x), f = x - c0, m = d->margin;
    if (f > m && f < 1.0 - m && fabs(f - 0.5) > m) return (uint16_t)(c0 + (f > 0.5 ? 1.0 : 0.0));
  }
  uint32_t guess = x >= (double)OC_CODE_MAX ? OC_CODE_MAX : x <= 1.0 ? 1u : (uint32_t)(x + 0.5);
  float dc, dn;
  uint32_t c = oc__code_floor(v, d, guess, &dc, &dn);
  if (c < OC_CODE_MAX) {
    double below = (double)v - (double)dc;
    double above = (double)dn - (double)v;
    if (above < below) c++;
  }
  return (uint16_t)c;
}

uint16_t oc_code_encode(float v, oc_range_t r) {
  /* NaN, ≤ 0, or a zero / malformed range: exact zero is the only faithful code. */
  if (!(v > 0.0f) || !(r.lo > 0.0f) || !(r.hi >= r.lo)) return OC_CODE_ZERO;
  if ((double)v < (double)r.hi / OC_CODE_MAX_RATIO) return OC_CODE_ZERO; /* flushed */
  if (v < r.lo) return 2.0 * (double)v >= (double)r.lo ? 1 : OC_CODE_ZERO; /* nearer of 0 and lo */
  if (!(r.hi > r.lo)) return 1;                                             /* uniform range */
  oc__dec_t d = oc__decoder(r.lo, r.hi);
  return oc__encode_log(v, &d);
}

/* Exact for the C float decoder: decoded values are non-decreasing in the code, so any v in
 * [lo, hi] lies between two neighbours a ≤ v ≤ b, and the nearer one is off by at most
 * (b − a)/(a + b) relative (worst at the midpoint). Enumerating the 65534 gaps costs ~1 ms, which
 * is fine for tests and diagnostics and gives a bound with no slack: the analytic form
 * exp(ln(hi/lo)/(2·65534)) − 1 plus a rigorous float-rounding term would exceed 1.6e-4 at the
 * largest ratio, while the real decoder stays below it. */
double oc_code_rel_error_bound(oc_range_t r) {
  if (!(r.lo > 0.0f) || !(r.hi > r.lo)) return 0.0; /* zero channel, or uniform: exact */
  double worst = 0.0, prev = (double)ocg_code_decode(1, r.lo, r.hi);
  for (uint32_t c = 2; c <= OC_CODE_MAX; c++) {
    double d = (double)ocg_code_decode(c, r.lo, r.hi);
    double e = fabs(d - prev) / (d + prev);
    if (e > worst) worst = e;
    prev = d;
  }
  /* Values between the decoded top code and hi (if the decoder lands below hi) map to the top. */
  if (prev < (double)r.hi) {
    double e = ((double)r.hi - prev) / (double)r.hi;
    if (e > worst) worst = e;
  }
  return worst;
}

/*-*** Bricks ***/

typedef enum { OC__CH_ZERO, OC__CH_UNIFORM, OC__CH_VARYING } oc__ch_kind_t;

/* Reads one channel defensively (non-finite or negative values act as sanitised ones, so even an
 * unsanitised caller cannot produce NaN ranges), classifies it and sets its range. v is left
 * unwritten for a zero channel (nothing reads it then). */
static oc__ch_kind_t oc__channel(const float *in, float v[OC_BRICK_VOXELS], oc_range_t *r) {
  if (oc__bits_at_most(in, OC_BRICK_VOXELS, 0)) { /* all +0: most bricks made are empty (0.16 µs, not 1.3) */
    r->lo = r->hi = 0.0f;
    return OC__CH_ZERO;
  }
  float mn = OC_VALUE_MAX, mx = 0.0f;
  for (int i = 0; i < OC_BRICK_VOXELS; i++) {
    float x = in[i];
    if (!(x > 0.0f)) x = 0.0f; /* NaN, −0 and negatives */
    if (x > OC_VALUE_MAX) x = OC_VALUE_MAX;
    v[i] = x;
    if (x < mn) mn = x;
    if (x > mx) mx = x;
  }
  if (mx == 0.0f) {
    r->lo = r->hi = 0.0f;
    return OC__CH_ZERO;
  }
  if ((double)mx <= (double)mn * (1.0 + OC_UNIFORM_TOL)) {
    /* The mean lies in [mn, mx], so it is positive and keeps the channel's level. Summed only here,
     * in the same order: few bricks are uniform, and the scan above no longer carries a chain of
     * 512 dependent double additions. */
    double sum = 0.0;
    for (int i = 0; i < OC_BRICK_VOXELS; i++) sum += v[i];
    r->lo = r->hi = (float)(sum / OC_BRICK_VOXELS);
    return OC__CH_UNIFORM;
  }
  double flush = (double)mx / OC_CODE_MAX_RATIO;
  float lo = mx;
  for (int i = 0; i < OC_BRICK_VOXELS; i++)
    if ((double)v[i] >= flush && v[i] < lo) lo = v[i];
  r->lo = lo;
  r->hi = mx;
  return OC__CH_VARYING;
}

static void oc__channel_codes(const float v[OC_BRICK_VOXELS], oc__ch_kind_t kind, oc_range_t r, uint16_t *code) {
  if (kind != OC__CH_VARYING) {
    for (int i = 0; i < OC_BRICK_VOXELS; i++) code[i] = kind == OC__CH_ZERO ? OC_CODE_ZERO : 1;
    return;
  }
  double flush = (double)r.hi / OC_CODE_MAX_RATIO;
  if (r.hi == r.lo) { /* zeros and one repeated value: code 1 decodes to it exactly */
    for (int i = 0; i < OC_BRICK_VOXELS; i++) code[i] = v[i] == 0.0f ? OC_CODE_ZERO : 1;
    return;
  }
  oc__dec_t d = oc__decoder(r.lo, r.hi);
  for (int i = 0; i < OC_BRICK_VOXELS; i++) code[i] = (double)v[i] < flush ? OC_CODE_ZERO : oc__encode_log(v[i], &d);
}

oc_node_kind_t oc_brick_encode(const float sigma[OC_BRICK_VOXELS], const float tau[OC_BRICK_VOXELS],
                               oc_brick_codes_t *codes, oc_range_t range[OC_CHANNELS]) {
  float v[OC_CHANNELS][OC_BRICK_VOXELS];
  oc__ch_kind_t k[OC_CHANNELS];
  k[OC_CH_SIGMA] = oc__channel(sigma, v[OC_CH_SIGMA], &range[OC_CH_SIGMA]);
  k[OC_CH_TAU] = oc__channel(tau, v[OC_CH_TAU], &range[OC_CH_TAU]);
  /* Empty or uniform only if both channels are (design.md): a shadowed but clear node (σt = 0,
   * τ > 0) still carries τ for the air inside it. */
  if (k[0] == OC__CH_ZERO && k[1] == OC__CH_ZERO) return OC_NODE_EMPTY;
  if (k[0] != OC__CH_VARYING && k[1] != OC__CH_VARYING) return OC_NODE_UNIFORM;
  if (codes)
    for (int c = 0; c < OC_CHANNELS; c++) oc__channel_codes(v[c], k[c], range[c], codes->code[c]);
  return OC_NODE_BRICK;
}

void oc_brick_decode(const oc_brick_codes_t *codes, const oc_range_t range[OC_CHANNELS],
                     float sigma[OC_BRICK_VOXELS], float tau[OC_BRICK_VOXELS]) {
  float *out[OC_CHANNELS] = {sigma, tau};
  for (int c = 0; c < OC_CHANNELS; c++)
    for (int i = 0; i < OC_BRICK_VOXELS; i++) out[c][i] = ocg_code_decode(codes->code[c][i], range[c].lo, range[c].hi);
}
