/* oc_key.c — octree keys: Morton codes with a sentinel bit (oc_key.h).
 *
 * Geometry is always derived from the key, never accumulated: 2S = 12 942 000 m has 20 significant
 * bits, so 2S·2^-L is exact, i·2S·2^-L (i < 2^21) is exact, and so is -S plus it. Node origins,
 * centres and sizes are therefore exact doubles, and from_point() of an origin returns its key. */
#include "oc_key.h"

#include <math.h> /* ldexp, floor, isfinite, NAN */

#include "oc_planet.h" /* OC_ROOT_HALF */

/*-*** Morton bit spreading ***/

/* Spreads the low 21 bits of v so that bit b lands at bit 3b (the classic magic-number ladder:
 * each step halves the block size and triples the spacing). */
static inline uint64_t oc__spread3(uint32_t v) {
  uint64_t x = v & 0x1fffffu;
  x = (x | x << 32) & 0x001f00000000ffffull;
  x = (x | x << 16) & 0x001f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

/* Inverse of oc__spread3(): gathers bits 0, 3, 6, … into the low 21 bits. */
static inline uint32_t oc__compact3(uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ull;
  x = (x ^ (x >> 4)) & 0x100f00f00f00f00full;
  x = (x ^ (x >> 8)) & 0x001f0000ff0000ffull;
  x = (x ^ (x >> 16)) & 0x001f00000000ffffull;
  x = (x ^ (x >> 32)) & 0x1fffffull;
  return (uint32_t)x;
}

/*-*** Keys ***/

oc_key_t oc_key_make(int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  if (level < 0 || level > OC_KEY_MAX_LEVEL) return OC_KEY_INVALID;
  uint32_t n = 1u << level;
  if (ix >= n || iy >= n || iz >= n) return OC_KEY_INVALID;
  return ((oc_key_t)1 << (3 * level)) | oc__spread3(ix) | oc__spread3(iy) << 1 | oc__spread3(iz) << 2;
}

int oc_key_level(oc_key_t key) {
  if (key == 0) return -1;
  int top = 63 - __builtin_clzll(key);
  /* 64 bits hold a sentinel at most at bit 63, i.e. level 21: every multiple of 3 is in range. */
  return top % 3 == 0 ? top / 3 : -1;
}

bool oc_key_valid(oc_key_t key) { return oc_key_level(key) >= 0; }

void oc_key_coords(oc_key_t key, uint32_t *ix, uint32_t *iy, uint32_t *iz) {
  int level = oc_key_level(key);
  /* An invalid key yields (0, 0, 0) rather than garbage from a misplaced sentinel. */
  uint64_t m = level < 0 ? 0 : key & (((oc_key_t)1 << (3 * level)) - 1);
  if (ix) *ix = oc__compact3(m);
  if (iy) *iy = oc__compact3(m >> 1);
  if (iz) *iz = oc__compact3(m >> 2);
}

oc_key_t oc_key_parent(oc_key_t key) {
  return oc_key_level(key) > 0 ? key >> 3 : OC_KEY_INVALID;
}

oc_key_t oc_key_child(oc_key_t key, int i) {
  int level = oc_key_level(key);
  if (level < 0 || level >= OC_KEY_MAX_LEVEL || i < 0 || i > 7) return OC_KEY_INVALID;
  return key << 3 | (oc_key_t)i;
}

oc_key_t oc_key_ancestor(oc_key_t key, int level) {
  int own = oc_key_level(key);
  if (own < 0 || level < 0 || level > own) return OC_KEY_INVALID;
  return key >> (3 * (own - level));
}

bool oc_key_is_ancestor(oc_key_t a, oc_key_t b) {
  int la = oc_key_level(a), lb = oc_key_level(b);
  return la >= 0 && lb > la && b >> (3 * (lb - la)) == a;
}

oc_key_t oc_key_neighbor(oc_key_t key, int dx, int dy, int dz) {
  int level = oc_key_level(key);
  if (level < 0) return OC_KEY_INVALID;
  uint32_t ix, iy, iz;
  oc_key_coords(key, &ix, &iy, &iz);
  /* int64 so that no offset wraps around into the cube. */
  int64_t n = (int64_t)1 << level, x = (int64_t)ix + dx, y = (int64_t)iy + dy, z = (int64_t)iz + dz;
  if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return OC_KEY_INVALID;
  return oc_key_make(level, (uint32_t)x, (uint32_t)y, (uint32_t)z);
}

/*-*** Geometry ***/

double oc_key_size(int level) {
  if (level < 0 || level > OC_KEY_MAX_LEVEL) return NAN;
  return ldexp(2.0 * OC_ROOT_HALF, -level); /* exact: a power-of-two scaling */
}

void oc_key_bounds(oc_key_t key, oc_dvec3 *origin, double *size) {
  int level = oc_key_level(key);
  if (level < 0) {
    if (origin) *origin = oc_dv3(NAN, NAN, NAN);
    if (size) *size = NAN;
    return;
  }
  uint32_t ix, iy, iz;
  oc_key_coords(key, &ix, &iy, &iz);
  double s = oc_key_size(level);
  if (origin) *origin = oc_dv3(-OC_ROOT_HALF + ix * s, -OC_ROOT_HALF + iy * s, -OC_ROOT_HALF + iz * s);
  if (size) *size = s;
}

oc_dvec3 oc_key_center(oc_key_t key) {
  int level = oc_key_level(key);
  if (level < 0) return oc_dv3(NAN, NAN, NAN);
  uint32_t ix, iy, iz;
  oc_key_coords(key, &ix, &iy, &iz);
  /* -S + (i + 1/2)·2S/2^L = -S + (2i + 1)·S/2^L: still exact (one more bit than the origin). */
  double h = ldexp(OC_ROOT_HALF, -level);
  return oc_dv3(-OC_ROOT_HALF + (2.0 * ix + 1.0) * h, -OC_ROOT_HALF + (2.0 * iy + 1.0) * h,
                -OC_ROOT_HALF + (2.0 * iz + 1.0) * h);
}

/* Cell index of one coordinate, or -1 outside [-S, S]. (c + S)·2^L / 2S: for a node face c + S
 * is exact and so is the quotient, so a point on a shared face lands in the upper cell. The
 * root's max face c == S belongs to the last cell, so the closed cube is covered. */
static int64_t oc__cell(double c, int level) {
  if (!(c >= -OC_ROOT_HALF && c <= OC_ROOT_HALF)) return -1; /* also rejects NaN */
  int64_t n = (int64_t)1 << level;
  int64_t i = (int64_t)floor(ldexp(c + OC_ROOT_HALF, level) / (2.0 * OC_ROOT_HALF));
  return i >= n ? n - 1 : i;
}

oc_key_t oc_key_from_point(int level, oc_dvec3 p) {
  if (level < 0 || level > OC_KEY_MAX_LEVEL) return OC_KEY_INVALID;
  int64_t ix = oc__cell(p.x, level), iy = oc__cell(p.y, level), iz = oc__cell(p.z, level);
  if (ix < 0 || iy < 0 || iz < 0) return OC_KEY_INVALID;
  return oc_key_make(level, (uint32_t)ix, (uint32_t)iy, (uint32_t)iz);
}
