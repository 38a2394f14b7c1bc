/* shadow.h — the cloud shadow volume: the sun optical depth τ in the nodes that carry none (empty
 * nodes, and air outside the root cube), shared by the CPU reference (common/oc_render.c) and the GL
 * renderer (shaders/raymarch.comp.glsl) (design.md: one implementation of each formula).
 *
 * Empty space adds nothing to τ, so the τ toward the sun at a point p is the state's τ channel where
 * the sun ray from p first enters a leaf with σt > 0 (0 if it meets none). Each renderer builds, from
 * the state it holds and per camera region, a grid of that value (the walk to the first cloudy leaf is
 * the renderer's own, as its leaf look-up is), and the march looks it up here with the same addressing
 * and the trilinear reconstruction of brick.h. Nothing of it is on the wire or in a state file.
 *
 * The grid lives in a local frame at the ground point c0 under the camera: x east, y north (metres
 * from c0 along the tangent plane), z = p·up − R (the height above the tangent sphere's level, which
 * the curved ground undercuts by at most (x² + y²)/(2R): the grid starts that far below 0). Texel
 * (i, j, k) sits at lo + (i, j, k)·cell, n_x·n_y·n_z texels, x fastest in memory.
 *
 * GLSL: the includer prepends oc_port.h and brick.h. */
#ifndef OC_SHADERS_SHADOW_H
#define OC_SHADERS_SHADOW_H

#ifndef OC_GLSL
#include "brick.h"   /* ocg_trilerp */
#include "oc_port.h" /* ocg_real, ocg_vec3, OC_IN */
#endif

#if defined(OC_GLSL)
struct ocg_shadow_grid {
#else
typedef struct ocg_shadow_grid {
#endif
  ocg_vec3 lo;   /**< local coordinates of texel (0, 0, 0), m */
  ocg_vec3 cell; /**< texel spacing along x, y, z, m (> 0) */
  ocg_int nx, ny, nz; /**< texels per axis, each ≥ 2; nx = 0: no grid (τ 0 everywhere) */
#if defined(OC_GLSL)
};
#else
} ocg_shadow_grid;
#endif

/* Local coordinates of texel (i, j, k). */
OC_INLINE ocg_vec3 ocg_shadow_texel(OC_IN(ocg_shadow_grid) g, ocg_int i, ocg_int j, ocg_int k) {
  return ocg_add3(g.lo, ocg_mul3(ocg_v3(OCG_TO_REAL(i), OCG_TO_REAL(j), OCG_TO_REAL(k)), g.cell));
}

/* Memory index of texel (i, j, k). */
OC_INLINE ocg_int ocg_shadow_index(OC_IN(ocg_shadow_grid) g, ocg_int i, ocg_int j, ocg_int k) {
  return i + g.nx * (j + g.ny * k);
}

/*! The shadow fades out over this many texels inside the grid's sides, so its edge is not a line. */
#define OCG_SHADOW_FADE_TEXELS OCG_R(8.0)

/* The weight of the grid's τ at continuous texel coordinates c: 1 inside, falling linearly to 0 over
 * the OCG_SHADOW_FADE_TEXELS next to its sides, 0 outside it horizontally. */
OC_INLINE ocg_real ocg_shadow_side(OC_IN(ocg_shadow_grid) g, ocg_vec3 c) {
  ocg_real side = ocg_min(ocg_min(c.x, OCG_TO_REAL(g.nx - 1) - c.x), ocg_min(c.y, OCG_TO_REAL(g.ny - 1) - c.y));
  return ocg_clamp(side / OCG_SHADOW_FADE_TEXELS, OCG_R(0.0), OCG_R(1.0));
}

/* Continuous texel coordinates of the local point q (xyz), and in w the weight of the grid's τ there
 * (ocg_shadow_side), 0 above its top too (below its bottom, inside the planet, the bottom layer holds).
 * Where w = 0, τ is taken as 0: the empty space of the renderers before the grid. */
OC_INLINE ocg_vec4 ocg_shadow_coord(OC_IN(ocg_shadow_grid) g, ocg_vec3 q) {
  if (g.nx < 2) return ocg_v4(OCG_R(0.0), OCG_R(0.0), OCG_R(0.0), OCG_R(0.0));
  ocg_vec3 c = ocg_div3(ocg_sub3(q, g.lo), g.cell);
  ocg_real w = c.z <= OCG_TO_REAL(g.nz - 1) ? ocg_shadow_side(g, c) : OCG_R(0.0);
  return ocg_v4(c.x, c.y, ocg_max(c.z, OCG_R(0.0)), w);
}

/* The texel whose corner cell holds coordinates c (from ocg_shadow_coord with w > 0): base in
 * [0, n − 2] per axis, so base + 1 is a texel too. */
OC_INLINE ocg_vec3 ocg_shadow_base(OC_IN(ocg_shadow_grid) g, ocg_vec4 c) {
  return ocg_v3(ocg_min(ocg_floor(c.x), OCG_TO_REAL(g.nx - 2)), ocg_min(ocg_floor(c.y), OCG_TO_REAL(g.ny - 2)),
                ocg_min(ocg_floor(c.z), OCG_TO_REAL(g.nz - 2)));
}

/* τ at coordinates c from the 8 texels at base + (i, j, k): z0 = (v000, v100, v010, v110), z1 the k = 1
 * layer (brick.h's order), trilinear as between brick samples, times c's weight w. */
OC_INLINE ocg_real ocg_shadow_tau(ocg_vec4 c, ocg_vec3 base, ocg_vec4 z0, ocg_vec4 z1) {
  return c.w * ocg_trilerp(z0, z1, ocg_sub3(ocg_v3(c.x, c.y, c.z), base));
}

/* A leaf without cloud may carry a τ channel of its own (a ground node, docs/architecture.md), its
 * samples leaf_size/7 apart. τ falls from tens to 0 across a shadow's edge, so between samples it
 * spreads the shadow up to a sample beyond where the sun ray meets the cloud, and the spread ends on
 * the leaf's faces against a finer neighbour's: a straight band on the ground (a level-12 node's
 * samples lie 451 m apart, a level-11's 903 m). A grid (the volume, or the ground map) is one grid,
 * so its spread has no such edges. It is taken where the leaf's samples lie more than half a texel
 * of g apart (ocg_shadow_over_leaf); a leaf finer than that keeps its own, sharper τ. @return 1 there. */
#define OCG_SHADOW_LEAF_RATIO OCG_R(0.5)
OC_INLINE ocg_int ocg_shadow_finer(OC_IN(ocg_shadow_grid) g, ocg_real leaf_size) {
  return g.nx >= 2 && leaf_size > OCG_R(7.0) * OCG_SHADOW_LEAF_RATIO * ocg_max(g.cell.x, g.cell.y) ? 1 : 0;
}

/* There, τ from the grid's tau_vol = ocg_shadow_tau() or ocg_shadow_ground_tau() (already × c.w)
 * blended into the leaf's own tau_leaf over the grid's fading sides. */
OC_INLINE ocg_real ocg_shadow_over_leaf(ocg_vec4 c, ocg_real tau_vol, ocg_real tau_leaf) {
  return tau_vol + (OCG_R(1.0) - c.w) * tau_leaf;
}

/* ---- The ground map ----
 * The ground takes its τ from a grid of its own: one layer of texels on the ground under the volume's
 * horizontal extent, finer than the volume (OC_RENDER_DEFAULT_SHADOW_GROUND_CELLS a side: 126 m texels
 * where the volume's are 504 m). Seen from under the clouds, the volume's coarse texels drew a cloud's
 * shadow on the ground as a blur and, where its lowest layer (hundreds of metres up) or a coarse ground
 * node met a cloud's side, as a straight band. The map is an ocg_shadow_grid with nz = 1, addressed by
 * the same functions; texel (i, j) lies on the ground under (x, y), and its τ is read bilinearly. */

/* The height z of the ground (the sphere of radius r about the planet's centre) under the local (x, y):
 * the frame's tangent plane lies at z = 0 and the ground curves away under it (stable for x, y ≪ r). */
OC_INLINE ocg_real ocg_shadow_ground_z(ocg_real x, ocg_real y, ocg_real r) {
  ocg_real s = x * x + y * y;
  return -s / (r + ocg_sqrt(ocg_max(r * r - s, OCG_R(0.0))));
}

/* The ground map's continuous coordinates of the local point q (its z is not read) and the weight w of
 * its τ there (ocg_shadow_side); all 0 without a map. */
OC_INLINE ocg_vec4 ocg_shadow_ground_coord(OC_IN(ocg_shadow_grid) g, ocg_vec3 q) {
  if (g.nx < 2) return ocg_v4(OCG_R(0.0), OCG_R(0.0), OCG_R(0.0), OCG_R(0.0));
  ocg_vec3 c = ocg_v3((q.x - g.lo.x) / g.cell.x, (q.y - g.lo.y) / g.cell.y, OCG_R(0.0));
  return ocg_v4(c.x, c.y, OCG_R(0.0), ocg_shadow_side(g, c));
}

/* The ground map's texel whose corner cell holds coordinates c: base in [0, n − 2] along x and y. */
OC_INLINE ocg_vec3 ocg_shadow_ground_base(OC_IN(ocg_shadow_grid) g, ocg_vec4 c) {
  return ocg_v3(ocg_min(ocg_floor(c.x), OCG_TO_REAL(g.nx - 2)), ocg_min(ocg_floor(c.y), OCG_TO_REAL(g.ny - 2)), OCG_R(0.0));
}

/* τ at ground-map coordinates c from the 4 texels v = (v00, v10, v01, v11) at base + (i, j): bilinear
 * (the trilinear reconstruction at its lower face), times c's weight w. */
OC_INLINE ocg_real ocg_shadow_ground_tau(ocg_vec4 c, ocg_vec3 base, ocg_vec4 v) {
  return c.w * ocg_trilerp(v, v, ocg_v3(c.x - base.x, c.y - base.y, OCG_R(0.0)));
}

/*! The walk from a texel toward the sun gives up after this many leaves (τ 0: a light leak, counted
 *  in docs/numerics.md) and above this height while climbing (no cloud is that high). */
#define OCG_SHADOW_MAX_LEAVES 512
#define OCG_SHADOW_WALK_TOP OCG_R(30000.0)

#endif /* OC_SHADERS_SHADOW_H */
