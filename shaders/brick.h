/* brick.h — brick codes and sample reconstruction shared by C and GLSL (design.md, Conventions:
 * bricks and codes; style.md §4).
 *
 * One implementation of "code → value" and "eight corner values → value at a point" serves the
 * CPU reference renderer (common/oc_render.c), the encoder's round-trip fix-up (common/oc_brick.c)
 * and the raymarch shaders, so the three cannot drift. Linear interpolation of DECODED values is
 * the reference reconstruction; hardware filtering of raw codes would interpolate in code space
 * (i.e. geometrically), and its error against this header belongs in docs/numerics.md.
 *
 * GLSL has no #include: client/gl/gl_program.c concatenates oc_port.h, then this file. Everything
 * here is pointer-free and written with oc_port.h macros so it compiles as C17 and GLSL 4.50. */
#ifndef OC_SHADERS_BRICK_H
#define OC_SHADERS_BRICK_H

#ifndef OC_GLSL
#include "oc_port.h" /* ocg_real, ocg_uint, ocg_vec3/4, OCG_R, OCG_TO_REAL */
#endif

/* ---- Layout (must equal common/oc_brick.h; tests/common/test_brick.c checks) ------------------ */
#define OCG_BRICK_EDGE 8u       /* samples per edge, corner-sampled: sample i sits at i·size/7 */
#define OCG_BRICK_VOXELS 512u   /* 8³, x fastest */
#define OCG_CODE_MAX 65535u     /* codes are 16 bit; 0 is exact zero */
#define OCG_CODE_STEPS 65534u   /* log steps between lo (code 1) and hi (code 65535) */
/* Ratio clamp inside the decoder: validated ranges never exceed 1e9 (OC_CODE_MAX_RATIO), so this
 * changes nothing for them; it only keeps a corrupt range from producing Inf or NaN on the GPU. */
#define OCG_CODE_RATIO_CLAMP OCG_R(1e30)

/*! ocg_code_decode() : the value of a 16-bit code against its channel's range [lo, hi].
 *    code 0           → exactly 0
 *    code 1..65535    → lo·2^(log2(hi/lo)·(code−1)/65534)
 *  @return : 0 for code 0 or a zero range (lo ≤ 0, the all-zero channel); exactly lo when
 *  hi ≤ lo (uniform channel), without relying on log2(1) and exp2(0) being exact, which GLSL
 *  does not promise.
 *  note 1 : hi/lo, not log2(hi) − log2(lo): one rounded division costs ≈ 6e-8 relative, while two
 *           logarithms of values near 2^±20 cost ≈ 2e-6 absolute in the exponent.
 *  note 2 : no 0/0 (lo > 0 is checked first) and no overflow: the result is at most lo·(hi/lo). */
OC_INLINE ocg_real ocg_code_log2_ratio(ocg_real lo, ocg_real hi) { return ocg_log2(ocg_min(hi / lo, OCG_CODE_RATIO_CLAMP)); }

/*! ocg_code_decode_at() : code 1..65535 of a varying range (0 < lo < hi) given l2 =
 *  ocg_code_log2_ratio(lo, hi): the same operations as ocg_code_decode, so the same bits, with the
 *  logarithm taken once per range (the encoder decodes 2–4 codes per value). */
OC_INLINE ocg_real ocg_code_decode_at(ocg_uint code, ocg_real lo, ocg_real l2) {
  ocg_real t = OCG_TO_REAL(code - 1u) / OCG_R(65534.0);
  return lo * ocg_exp2(l2 * t);
}

OC_INLINE ocg_real ocg_code_decode(ocg_uint code, ocg_real lo, ocg_real hi) {
  if (code == 0u || !(lo > OCG_R(0.0))) return OCG_R(0.0);
  if (!(hi > lo)) return lo;
  return ocg_code_decode_at(code, lo, ocg_code_log2_ratio(lo, hi));
}

/*! ocg_brick_voxel() : memory index of sample (i, j, k), each 0..7: i + 8j + 64k (x fastest). */
OC_INLINE ocg_uint ocg_brick_voxel(ocg_uint i, ocg_uint j, ocg_uint k) { return i + 8u * j + 64u * k; }

/*! ocg_brick_base() : the sample cell holding local position u ∈ [0,1]³ of a node: per axis
 *  floor(clamp(u, 0, 1)·7) clamped to 0..6, as integer-valued reals (convert with OCG_TO_UINT).
 *  note : clamping the base to 6 (not 7) puts u = 1 on the far face of the last cell with fraction
 *         1, so the eight corners base + {0,1}³ are always inside the brick. */
OC_INLINE ocg_vec3 ocg_brick_base(ocg_vec3 u) {
  return ocg_v3(ocg_min(ocg_floor(ocg_clamp(u.x, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0)), OCG_R(6.0)),
                ocg_min(ocg_floor(ocg_clamp(u.y, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0)), OCG_R(6.0)),
                ocg_min(ocg_floor(ocg_clamp(u.z, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0)), OCG_R(6.0)));
}

/*! ocg_brick_frac() : interpolation weights of u inside the cell `base` (from ocg_brick_base):
 *  clamp(u, 0, 1)·7 − base, each in [0, 1]. */
OC_INLINE ocg_vec3 ocg_brick_frac(ocg_vec3 u, ocg_vec3 base) {
  return ocg_v3(ocg_clamp(u.x, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0) - base.x,
                ocg_clamp(u.y, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0) - base.y,
                ocg_clamp(u.z, OCG_R(0.0), OCG_R(1.0)) * OCG_R(7.0) - base.z);
}

/*! ocg_brick_base_voxel() : memory index of the cell's lowest corner; the other seven corners are
 *  at + 1 (x), + 8 (y), + 64 (z). */
OC_INLINE ocg_uint ocg_brick_base_voxel(ocg_vec3 base) {
  return ocg_brick_voxel(OCG_TO_UINT(base.x), OCG_TO_UINT(base.y), OCG_TO_UINT(base.z));
}

/*! ocg_trilerp() : trilinear interpolation of eight decoded corner values, the reference
 *  reconstruction between samples.
 *  z0 = (v000, v100, v010, v110), z1 = (v001, v101, v011, v111) with v_ijk at base + (i, j, k);
 *  f = fraction from ocg_brick_frac(). x first, then y, then z, so C and GLSL round alike.
 *  @return : the value at base + f (under C, exactly the corner value when f is a corner; GLSL's
 *  mix() may be a + t·(b − a) and round differently by an ulp). */
OC_INLINE ocg_real ocg_trilerp(ocg_vec4 z0, ocg_vec4 z1, ocg_vec3 f) {
  ocg_real a = ocg_mix(z0.x, z0.y, f.x); /* y0 z0 */
  ocg_real b = ocg_mix(z0.z, z0.w, f.x); /* y1 z0 */
  ocg_real c = ocg_mix(z1.x, z1.y, f.x); /* y0 z1 */
  ocg_real d = ocg_mix(z1.z, z1.w, f.x); /* y1 z1 */
  return ocg_mix(ocg_mix(a, b, f.y), ocg_mix(c, d, f.y), f.z);
}

#endif /* OC_SHADERS_BRICK_H */
