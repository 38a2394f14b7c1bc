/* oc_planet.h — the planet frame (design.md, Conventions: frames and keys).
 *
 * Right-handed, metres, origin at the planet centre; +Z through the north pole, +X through
 * 0°N 0°E, +Y through 0°N 90°E. The planet is a sphere of radius OC_PLANET_RADIUS, so geodetic and
 * geocentric latitude coincide. Local frames are east-north-up. Heading is degrees clockwise from
 * north, pitch degrees positive up, field of view vertical degrees.
 *
 * Poles and wrap: on the Z axis longitude is undefined; oc_xyz_to_geo() reports lon 0 there and
 * oc_enu_at() uses the limit of the frame along lon 0: east +Y, so north is -X at the north pole
 * and +X at the south pole. Input longitudes may be any angle (190 is -170); output longitudes are
 * in (-180, 180], so -180 comes back as 180. Latitude is expected in [-90, 90]. Looking straight
 * up or down the heading is undefined and comes back as 0. Angles are reduced in degrees first, so
 * the cardinal ones are exact (lat 90 gives x = y = 0, heading 90 is exactly east). */
#ifndef OC_COMMON_PLANET_H
#define OC_COMMON_PLANET_H

#include <stdint.h>

#include "oc_key.h"  /* oc_key_t, OC_KEY_MAX_LEVEL */
#include "oc_math.h" /* oc_dvec3 */

#define OC_PLANET_RADIUS 6371000.0   /**< m */
#define OC_ATMOSPHERE_HEIGHT 100000.0 /**< m above the surface: top of the atmosphere */
#define OC_ROOT_HALF (OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT) /**< S: the root cube is [-S, S]^3 */

typedef struct {
  double lat, lon, alt; /**< degrees, degrees, metres above the surface */
} oc_geo_t;

typedef struct {
  oc_dvec3 east, north, up; /**< orthonormal; at the poles east is +Y and north follows from up × east */
} oc_enu_t;

/*! oc_geo_to_xyz() : geodetic (spherical planet) to planet-frame Cartesian. */
oc_dvec3 oc_geo_to_xyz(oc_geo_t g);
/*! oc_xyz_to_geo() : inverse of oc_geo_to_xyz(); lon in (-180, 180], lat in [-90, 90]. */
oc_geo_t oc_xyz_to_geo(oc_dvec3 p);
/*! oc_enu_at() : the east-north-up frame at a point (any point off the centre). */
oc_enu_t oc_enu_at(oc_dvec3 p);
/*! oc_heading_pitch_dir() : unit view direction for heading/pitch (degrees) in the ENU frame. */
oc_dvec3 oc_heading_pitch_dir(oc_enu_t enu, double heading_deg, double pitch_deg);
/*! oc_dir_heading_pitch() : inverse of oc_heading_pitch_dir(): heading in [0, 360), pitch in
 *  [-90, 90]; dir need not be unit length. */
void oc_dir_heading_pitch(oc_enu_t enu, oc_dvec3 dir, double *heading_deg, double *pitch_deg);

/* ---- Camera-relative positions for the GPU --------------------------------------------------------
 * The GPU never sees absolute planet coordinates. The camera is held as its level-21 cell
 * (int64: the camera may be outside the root cube, e.g. in space) plus a float fraction in [0,1);
 * a node's position relative to the camera is the exact integer difference of level-21 cells,
 * converted to float, minus the fraction. */
typedef struct {
  int64_t cell[3]; /**< floor((p + S) / cell21) per axis */
  float frac[3];   /**< (p + S) / cell21 - cell, in [0, 1) */
} oc_camrel_t;

#define OC_CELL21_SIZE (2.0 * OC_ROOT_HALF / (double)(1u << OC_KEY_MAX_LEVEL)) /**< m, about 6.17 */

/*! oc_camrel_make() : the camera anchor for a planet-frame position (finite; positions beyond
 *  2^60 cells are clamped). */
oc_camrel_t oc_camrel_make(oc_dvec3 cam);
/*! oc_camrel_node() : origin of node `key` relative to the camera, metres, as floats: the GPU's
 *  formula (float)(cell difference)·cell21 - frac·cell21, within about one float ulp of the
 *  result (3e-5 m at 500 m, see docs/numerics.md). NaN for an invalid key. */
void oc_camrel_node(const oc_camrel_t *c, oc_key_t key, float out[3]);
/*! oc_camrel_point() : any planet-frame point relative to the camera, metres, as floats. */
void oc_camrel_point(const oc_camrel_t *c, oc_dvec3 p, float out[3]);

/*! oc_key_radius_range() : nearest and farthest distance from the planet centre to the box of a
 *  valid key, metres (whether a node lies inside the planet, meets the ground, or is above the
 *  atmosphere). */
void oc_key_radius_range(oc_key_t key, double *rmin, double *rmax);
/*! oc_key_meets_ground() : the box of the key contains points of the planet's surface. */
int oc_key_meets_ground(oc_key_t key);

#endif /* OC_COMMON_PLANET_H */
