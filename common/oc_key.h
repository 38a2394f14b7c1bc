/* oc_key.h — octree keys (design.md, Conventions: frames and keys).
 *
 * The root is the cube [-S, S]^3, S = OC_ROOT_HALF (planet radius + 100 km). A node of level L
 * (0..21) has integer cell coordinates ix, iy, iz in [0, 2^L) and origin -S + i·2S/2^L. Its key is
 * a sentinel bit at position 3L above the Morton code of (ix, iy, iz), x in the lowest bit of each
 * triple. Ascending key order is the canonical node order. Bounds are always derived from keys,
 * never accumulated. */
#ifndef OC_COMMON_KEY_H
#define OC_COMMON_KEY_H

#include <stdbool.h>
#include <stdint.h>

#include "oc_math.h" /* oc_dvec3 */

#define OC_KEY_MAX_LEVEL 21
#define OC_KEY_ROOT ((uint64_t)1)
#define OC_KEY_INVALID ((uint64_t)0)

typedef uint64_t oc_key_t;

/*! oc_key_make() : @return the key of cell (ix, iy, iz) at level, or OC_KEY_INVALID when the level
 *  is outside 0..21 or a coordinate is outside [0, 2^level). */
oc_key_t oc_key_make(int level, uint32_t ix, uint32_t iy, uint32_t iz);
/*! oc_key_valid() : true for a sentinel at a multiple of 3 bits, level <= 21. */
bool oc_key_valid(oc_key_t key);
/*! oc_key_level() : @return 0..21, or -1 for an invalid key. */
int oc_key_level(oc_key_t key);
/*! oc_key_coords() : cell coordinates of a valid key ((0, 0, 0) for an invalid one; NULLs allowed). */
void oc_key_coords(oc_key_t key, uint32_t *ix, uint32_t *iy, uint32_t *iz);
/*! oc_key_parent() : @return OC_KEY_INVALID for the root. */
oc_key_t oc_key_parent(oc_key_t key);
/*! oc_key_child() : child i (0..7, bit 0 = +x, bit 1 = +y, bit 2 = +z); OC_KEY_INVALID at level 21. */
oc_key_t oc_key_child(oc_key_t key, int i);
/*! oc_key_ancestor() : ancestor at a level <= the key's own (the key itself at its own level). */
oc_key_t oc_key_ancestor(oc_key_t key, int level);
/*! oc_key_is_ancestor() : true when a is a strict ancestor of b. */
bool oc_key_is_ancestor(oc_key_t a, oc_key_t b);
/*! oc_key_neighbor() : same-level neighbour offset by (dx, dy, dz) cells; OC_KEY_INVALID when it
 *  would fall outside the root cube. */
oc_key_t oc_key_neighbor(oc_key_t key, int dx, int dy, int dz);
/*! oc_key_size() : edge length in metres of a node of this level: 2S / 2^level, exact (no
 *  accumulation); NaN for a level outside 0..21. */
double oc_key_size(int level);
/*! oc_key_bounds() : origin (minimum corner) and edge length in metres of a valid key, both exact
 *  doubles; NaN for an invalid key. */
void oc_key_bounds(oc_key_t key, oc_dvec3 *origin, double *size);
/*! oc_key_center() : centre of the node in metres. */
oc_dvec3 oc_key_center(oc_key_t key);
/*! oc_key_from_point() : the level-`level` node containing p (planet frame, metres);
 *  OC_KEY_INVALID when p is outside the closed root cube [-S, S]^3 (or not finite).
 *  note 1 : points on a shared face go to the upper cell; the root's own max face (a coordinate
 *           exactly +S) belongs to the last cell, so every point of the closed cube has a node.
 *  note 2 : the origin and centre of any key map back to that key exactly. */
oc_key_t oc_key_from_point(int level, oc_dvec3 p);

#endif /* OC_COMMON_KEY_H */
