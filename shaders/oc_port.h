/* oc_port.h — the macro layer that lets shaders/ headers compile as C17 and as GLSL 4.50.
 *
 * The includer defines OC_GLSL (shaders; client/gl/gl_program.c prepends it) or nothing (C). The same
 * function bodies then serve the CPU reference renderer and the GPU, as PNanoVDB.h does for NanoVDB.
 *
 * Rules for code in shaders/ headers (style.md §4):
 *   - no pointers, recursion, VLAs, or libc beyond <stdint.h>, <string.h>, <math.h> under C;
 *   - arithmetic on vectors goes through the ocg_*3 helpers (C has no operator overloading);
 *   - literals are written OCG_R(1.0): a float literal in GLSL and in C (1.0f), a double literal in
 *     a C translation unit that defines OCG_REAL_DOUBLE before including (used by numerics tests to
 *     run the same formulas in double precision);
 *   - conversions are OCG_TO_REAL(x) / OCG_TO_UINT(x) / OCG_TO_INT(x) (constructor in GLSL, cast in C);
 *   - OC_IN(T) passes by value in both languages; OC_INOUT(T)/OC_DEREF are for the rare out-params. */
#ifndef OC_SHADERS_PORT_H
#define OC_SHADERS_PORT_H

#if defined(OC_GLSL)
/* ---- GLSL ------------------------------------------------------------------------------------ */
/* Pure renames are object-like macros: Mesa's preprocessor joins a function-like macro call that
 * spans lines onto one line, which would shift the line numbers of later compile errors. */
#define OC_INLINE
#define OC_IN(T) in T
#define OC_INOUT(T) inout T
#define OC_DEREF(x) (x)
#define OC_REF(x) (x)
#define OC_ASSERT(x)
#define OCG_R(x) x
#define ocg_real float
#define ocg_uint uint
#define ocg_int int
#define ocg_vec2 vec2
#define ocg_vec3 vec3
#define ocg_vec4 vec4
#define ocg_v2 vec2
#define ocg_v3 vec3
#define ocg_v3s vec3
#define ocg_v4 vec4
#define OCG_TO_REAL float
#define OCG_TO_UINT uint
#define OCG_TO_INT int
#define ocg_exp exp
#define ocg_exp2 exp2
#define ocg_log log
#define ocg_log2 log2
#define ocg_sqrt sqrt
#define ocg_pow pow
#define ocg_abs abs
#define ocg_floor floor
#define ocg_min min
#define ocg_max max
#define ocg_clamp clamp
#define ocg_mix mix
#define ocg_sin sin
#define ocg_cos cos
#define ocg_atan2 atan
#define ocg_isfinite(x) (!isnan(x) && !isinf(x))
#define ocg_add3(a, b) ((a) + (b))
#define ocg_sub3(a, b) ((a) - (b))
#define ocg_mul3(a, b) ((a) * (b))
#define ocg_div3(a, b) ((a) / (b))
#define ocg_scale3(a, s) ((a) * (s))
#define ocg_exp3 exp
#define ocg_min3 min
#define ocg_max3 max
#define ocg_mix3 mix
#define ocg_dot3 dot
#define ocg_length3 length
#define ocg_normalize3 normalize
#define ocg_cross3 cross

#else
/* ---- C17 ------------------------------------------------------------------------------------- */
#include <math.h>   /* expf, logf, ... */
#include <stdint.h> /* uint32_t */
#include <assert.h> /* OC_ASSERT */

#define OC_INLINE static inline
#define OC_IN(T) T
#define OC_INOUT(T) T *
#define OC_DEREF(x) (*(x))
#define OC_REF(x) (&(x))
#define OC_ASSERT(x) assert(x)
typedef uint32_t ocg_uint;
typedef int32_t ocg_int;

#if defined(OCG_REAL_DOUBLE)
#define OCG_R(x) x
typedef double ocg_real;
#define OCG__F(name) name
#else
#define OCG_R(x) x##f
typedef float ocg_real;
#define OCG__F(name) name##f
#endif

#define OCG_TO_REAL(x) ((ocg_real)(x))
#define OCG_TO_UINT(x) ((ocg_uint)(x))
#define OCG_TO_INT(x) ((ocg_int)(x))

typedef struct { ocg_real x, y; } ocg_vec2;
typedef struct { ocg_real x, y, z; } ocg_vec3;
typedef struct { ocg_real x, y, z, w; } ocg_vec4;

#define ocg_exp(x) OCG__F(exp)(x)
#define ocg_exp2(x) OCG__F(exp2)(x)
#define ocg_log(x) OCG__F(log)(x)
#define ocg_log2(x) OCG__F(log2)(x)
#define ocg_sqrt(x) OCG__F(sqrt)(x)
#define ocg_pow(x, y) OCG__F(pow)(x, y)
#define ocg_abs(x) OCG__F(fabs)(x)
#define ocg_floor(x) OCG__F(floor)(x)
#define ocg_sin(x) OCG__F(sin)(x)
#define ocg_cos(x) OCG__F(cos)(x)
#define ocg_atan2(y, x) OCG__F(atan2)(y, x)
#define ocg_isfinite(x) isfinite(x)

static inline ocg_real ocg_min(ocg_real a, ocg_real b) { return a < b ? a : b; }
static inline ocg_real ocg_max(ocg_real a, ocg_real b) { return a > b ? a : b; }
static inline ocg_real ocg_clamp(ocg_real x, ocg_real a, ocg_real b) { return ocg_min(ocg_max(x, a), b); }
static inline ocg_real ocg_mix(ocg_real a, ocg_real b, ocg_real t) { return a * (OCG_R(1.0) - t) + b * t; }

static inline ocg_vec2 ocg_v2(ocg_real x, ocg_real y) { ocg_vec2 r = {x, y}; return r; }
static inline ocg_vec3 ocg_v3(ocg_real x, ocg_real y, ocg_real z) { ocg_vec3 r = {x, y, z}; return r; }
static inline ocg_vec3 ocg_v3s(ocg_real s) { ocg_vec3 r = {s, s, s}; return r; }
static inline ocg_vec4 ocg_v4(ocg_real x, ocg_real y, ocg_real z, ocg_real w) { ocg_vec4 r = {x, y, z, w}; return r; }
static inline ocg_vec3 ocg_add3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline ocg_vec3 ocg_sub3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline ocg_vec3 ocg_mul3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline ocg_vec3 ocg_div3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(a.x / b.x, a.y / b.y, a.z / b.z); }
static inline ocg_vec3 ocg_scale3(ocg_vec3 a, ocg_real s) { return ocg_v3(a.x * s, a.y * s, a.z * s); }
static inline ocg_vec3 ocg_exp3(ocg_vec3 a) { return ocg_v3(ocg_exp(a.x), ocg_exp(a.y), ocg_exp(a.z)); }
static inline ocg_vec3 ocg_min3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(ocg_min(a.x, b.x), ocg_min(a.y, b.y), ocg_min(a.z, b.z)); }
static inline ocg_vec3 ocg_max3(ocg_vec3 a, ocg_vec3 b) { return ocg_v3(ocg_max(a.x, b.x), ocg_max(a.y, b.y), ocg_max(a.z, b.z)); }
static inline ocg_vec3 ocg_mix3(ocg_vec3 a, ocg_vec3 b, ocg_real t) { return ocg_add3(ocg_scale3(a, OCG_R(1.0) - t), ocg_scale3(b, t)); }
static inline ocg_real ocg_dot3(ocg_vec3 a, ocg_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline ocg_real ocg_length3(ocg_vec3 a) { return ocg_sqrt(ocg_dot3(a, a)); }
static inline ocg_vec3 ocg_normalize3(ocg_vec3 a) { return ocg_scale3(a, OCG_R(1.0) / ocg_length3(a)); }
static inline ocg_vec3 ocg_cross3(ocg_vec3 a, ocg_vec3 b) {
  return ocg_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
#endif

/* ---- Shared constants -------------------------------------------------------------------------- */
#define OCG_PI OCG_R(3.14159265358979323846)
#define OCG_INV_4PI OCG_R(0.0795774715459476679)

/* NaN guards (Bruneton's ClampCosine / SafeSqrt). */
OC_INLINE ocg_real ocg_clamp_cos(ocg_real mu) { return ocg_clamp(mu, OCG_R(-1.0), OCG_R(1.0)); }
OC_INLINE ocg_real ocg_safe_sqrt(ocg_real x) { return ocg_sqrt(ocg_max(x, OCG_R(0.0))); }

#endif /* OC_SHADERS_PORT_H */
