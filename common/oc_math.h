/* oc_math.h — double-precision vectors for the planet frame (header-only).
 *
 * Planet-scale positions are always double on the CPU (the ulp of a float at 6.4e6 m is 0.5 m);
 * the GPU only ever sees camera-relative floats (oc_planet.h, oc_camrel_*). */
#ifndef OC_COMMON_MATH_H
#define OC_COMMON_MATH_H

#include <math.h> /* sqrt */

typedef struct { double x, y, z; } oc_dvec3;

static inline oc_dvec3 oc_dv3(double x, double y, double z) { oc_dvec3 r = {x, y, z}; return r; }
static inline oc_dvec3 oc_dadd(oc_dvec3 a, oc_dvec3 b) { return oc_dv3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline oc_dvec3 oc_dsub(oc_dvec3 a, oc_dvec3 b) { return oc_dv3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline oc_dvec3 oc_dscale(oc_dvec3 a, double s) { return oc_dv3(a.x * s, a.y * s, a.z * s); }
static inline double oc_ddot(oc_dvec3 a, oc_dvec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline double oc_dlen(oc_dvec3 a) { return sqrt(oc_ddot(a, a)); }
static inline oc_dvec3 oc_dnorm(oc_dvec3 a) { return oc_dscale(a, 1.0 / oc_dlen(a)); }
static inline oc_dvec3 oc_dcross(oc_dvec3 a, oc_dvec3 b) {
  return oc_dv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline oc_dvec3 oc_dmad(oc_dvec3 a, oc_dvec3 b, double s) { return oc_dv3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }

#define OC_PI 3.14159265358979323846
#define OC_DEG (OC_PI / 180.0)

#endif /* OC_COMMON_MATH_H */
