/* sampling.h — deterministic per-pixel random numbers shared by C and GLSL (ray-start jitter).
 *
 * PCG-style integer hash (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering"): uint in,
 * uint out, identical bits in C and GLSL, so the CPU reference reproduces the GPU's jitter. */
#ifndef OC_SHADERS_SAMPLING_H
#define OC_SHADERS_SAMPLING_H

#ifndef OC_GLSL
#include "oc_port.h"
#endif

/* pcg hash: h = state·747796405 + 2891336453; word = ((h >> ((h >> 28) + 4)) ^ h)·277803737;
 * result = (word >> 22) ^ word. All arithmetic modulo 2^32. */
OC_INLINE ocg_uint ocg_pcg_hash(ocg_uint v) {
  ocg_uint state = v * 747796405u + 2891336453u;
  ocg_uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

/* Jitter in [0, 1) for pixel (x, y) of frame f: the top 24 bits of a chained hash, scaled by 2^-24
 * so the value is exact in float. */
OC_INLINE ocg_real ocg_jitter(ocg_uint x, ocg_uint y, ocg_uint f) {
  ocg_uint h = ocg_pcg_hash(x + ocg_pcg_hash(y + ocg_pcg_hash(f)));
  return OCG_TO_REAL(h >> 8u) * OCG_R(5.9604644775390625e-8);
}

#endif /* OC_SHADERS_SAMPLING_H */
