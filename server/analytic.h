/* analytic.h — closed-form homogeneous media placed on the planet (test oracles).
 *
 * A medium is a list of at most OCS_MEDIUM_MAX_PRIMS homogeneous primitives; where primitives
 * overlap their extinctions add. Everything is exact up to double rounding, so the voxelizer
 * (voxelize.h) and the CPU reference renderer can be compared against it:
 *   - σt at a point (point-in-primitive tests);
 *   - optical depth along a ray segment, σt × chord length summed over primitives (sphere: the
 *     stable quadratic relative to the sphere's centre; box: the slab method in the box frame;
 *     slab: the difference of two chords of spheres centred on the planet);
 *   - τ toward the sun to infinity. The planet's shadow is NOT included (design.md, Conventions:
 *     the renderer multiplies by clear-sky transmittance), so a sun ray that passes through the
 *     planet keeps collecting the slab on the far side.
 *
 * Numerics at planet scale: ray origins are ~6.4e6 m from the planet centre, where the ulp of a
 * double is ~1e-9 m. Sphere chords are computed from o = p − centre with the perpendicular
 * distance |o − (o·d)d| (not b² − c, which cancels catastrophically), the half chord
 * h = √((r − |perp|)(r + |perp|)), c = (|o| − r)(|o| + r), and the roots q = −b − sign(b)·h and c/q
 * (no subtraction of nearly equal numbers). A chord entirely inside [0, tmax] is returned as 2h.
 * The remaining error is the intrinsic one of the ray origin itself: δh ≈ r·ulp(|o|)/h, i.e.
 * ~1e-8 m for non-grazing rays, growing as 1/h for rays that graze a surface. */
#ifndef OCS_ANALYTIC_H
#define OCS_ANALYTIC_H

#include "oc_math.h"   /* oc_dvec3 */
#include "oc_planet.h" /* oc_geo_t */

/*! Most primitives in one medium. */
#define OCS_MEDIUM_MAX_PRIMS 64

typedef enum {
  OCS_PRIM_NONE = 0,   /**< an unused slot: contributes nothing */
  OCS_PRIM_SPHERE = 1, /**< ball: centre, radius */
  OCS_PRIM_BOX = 2,    /**< oriented box standing on the local horizontal plane at its base centre */
  OCS_PRIM_SLAB = 3    /**< spherical shell between two altitudes, around the whole planet */
} ocs_prim_kind_t;

/* A primitive. Build it with ocs_prim_sphere() / ocs_prim_box() / ocs_prim_slab(), which fill the
 * derived planet-frame fields (c, axis, half, r_in, r_out) from the geodetic parameters. */
typedef struct {
  ocs_prim_kind_t kind;
  double sigma_t; /**< extinction inside, m⁻¹, finite, ≥ 0 */
  union {
    struct {
      oc_geo_t centre; /**< as given */
      double radius;   /**< m, > 0 */
      oc_dvec3 c;      /**< derived: centre, planet frame */
    } sphere;
    struct {
      oc_geo_t base;       /**< as given: centre of the bottom face */
      double size[3];      /**< as given: east, north, up extents, m, > 0 (before heading) */
      double heading;      /**< as given: degrees clockwise from north about the local up */
      oc_dvec3 c;          /**< derived: box centre = base + up·size[2]/2, planet frame */
      oc_dvec3 axis[3];    /**< derived: box axes (rotated east, rotated north, up), orthonormal */
      double half[3];      /**< derived: size/2 */
    } box;
    struct {
      double base, top;   /**< as given: altitudes, m, base < top, base ≥ −R */
      double r_in, r_out; /**< derived: R + base, R + top */
    } slab;
  };
} ocs_prim_t;

typedef struct {
  int count;                               /**< 0..OCS_MEDIUM_MAX_PRIMS */
  ocs_prim_t prims[OCS_MEDIUM_MAX_PRIMS];
} ocs_medium_t;

/*! ocs_prim_sphere() : a homogeneous ball centred at a geodetic point.
 *  @return 0, or OC_EINVAL for a non-finite input, radius ≤ 0 or σt < 0. */
int ocs_prim_sphere(ocs_prim_t *out, oc_geo_t centre, double radius, double sigma_t);
/*! ocs_prim_box() : a homogeneous box whose bottom face is centred at `base` and lies in the local
 *  horizontal (east-north) plane there; its edges run along east, north and up rotated by
 *  `heading_deg` clockwise (seen from above) about the local up: at heading 90 its "north" edge
 *  (size_n) points east. The box is Euclidean (it does not bend with the planet).
 *  @return 0, or OC_EINVAL for a non-finite input, a size ≤ 0 or σt < 0. */
int ocs_prim_box(ocs_prim_t *out, oc_geo_t base, double size_e, double size_n, double size_u, double heading_deg,
                double sigma_t);
/*! ocs_prim_slab() : a homogeneous spherical shell R + base ≤ |p| ≤ R + top.
 *  @return 0, or OC_EINVAL for a non-finite input, top ≤ base, base < −R or σt < 0. */
int ocs_prim_slab(ocs_prim_t *out, double base_alt, double top_alt, double sigma_t);

/*! ocs_prim_sigma_t() : σt of one primitive at p (its σt inside, 0 outside; the boundary is inside). */
double ocs_prim_sigma_t(const ocs_prim_t *pr, oc_dvec3 p);
/*! ocs_prim_chord() : length of the part of the segment p + t·d, t in [0, tmax], inside the
 *  primitive. d is normalised here (a zero d gives 0); tmax may be INFINITY; tmax ≤ 0 gives 0.
 *  A ray that only touches the surface (tangent) has chord 0. */
double ocs_prim_chord(const ocs_prim_t *pr, oc_dvec3 p, oc_dvec3 d, double tmax);
/*! ocs_prim_bounds() : axis-aligned bounding box of the primitive, planet frame (slab: ±R_out). */
void ocs_prim_bounds(const ocs_prim_t *pr, oc_dvec3 *lo, oc_dvec3 *hi);
/*! ocs_prim_intersects_box() : true when the closed axis-aligned box [lo, hi] meets the primitive.
 *  Exact for spheres and slabs; for boxes the separating-axis test (15 axes, with a relative
 *  epsilon so near-parallel edges never separate wrongly: it may answer true for boxes closer than
 *  ~1e-9 of their size, never false for boxes that meet). */
int ocs_prim_intersects_box(const ocs_prim_t *pr, oc_dvec3 lo, oc_dvec3 hi);

/*! ocs_medium_init() : an empty medium. */
void ocs_medium_init(ocs_medium_t *m);
/*! ocs_medium_add() : appends a copy of a primitive. @return 0, OC_ENOBUFS when the medium holds
 *  OCS_MEDIUM_MAX_PRIMS already, or OC_EINVAL for a primitive of unknown kind. */
int ocs_medium_add(ocs_medium_t *m, const ocs_prim_t *pr);
/*! ocs_medium_sigma_t() : σt at p, m⁻¹: the sum over the primitives that contain p. */
double ocs_medium_sigma_t(const ocs_medium_t *m, oc_dvec3 p);
/*! ocs_medium_optical_depth() : ∫ σt ds over p + t·d, t in [0, tmax] (d normalised here; tmax in
 *  metres, may be INFINITY): Σ σt_i × chord_i, exact up to rounding (see the file comment). */
double ocs_medium_optical_depth(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 dir, double tmax);
/*! ocs_medium_tau_sun() : optical depth from p toward the sun to infinity, without the planet's
 *  shadow (design.md, Conventions). sun_dir points toward the sun (normalised here). */
double ocs_medium_tau_sun(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 sun_dir);
/*! ocs_medium_bounds() : union of the primitives' bounding boxes; @return 0, or OC_ENOENT (lo, hi
 *  untouched) for a medium without primitives. */
int ocs_medium_bounds(const ocs_medium_t *m, oc_dvec3 *lo, oc_dvec3 *hi);

#endif /* OCS_ANALYTIC_H */
