/* oc_camera.h — a pinhole camera in the planet frame.
 *
 * Text form (command line, PNG text chunk "overcast-camera"): "lat,lon,alt,heading,pitch,fov" in
 * degrees, degrees, metres, degrees, degrees, degrees — the viewer's --camera format. */
#ifndef OC_COMMON_CAMERA_H
#define OC_COMMON_CAMERA_H

#include <stddef.h>

#include "oc_math.h"   /* oc_dvec3 */
#include "oc_planet.h" /* oc_geo_t */

typedef struct {
  oc_dvec3 pos;                  /**< planet frame, m */
  oc_dvec3 forward, right, up;   /**< orthonormal, right-handed: right = forward × up */
  double vfov_deg;               /**< vertical field of view, (0, 180) */
} oc_camera_t;

typedef struct {
  oc_geo_t geo;
  double heading, pitch, fov; /**< degrees */
} oc_camera_pose_t;

/*! oc_camera_from_pose() : the camera for a geodetic pose (ENU frame at the position). */
oc_camera_t oc_camera_from_pose(oc_camera_pose_t pose);
/*! oc_camera_parse() : "lat,lon,alt,heading,pitch,fov" → pose. @return 0 or OC_EINVAL with a
 *  reason naming the bad field (lat in [-90,90], lon in [-360,360], alt in [-R, 1e9] m,
 *  pitch in [-90,90], fov in (0.1,179)). */
int oc_camera_parse(const char *text, oc_camera_pose_t *pose, char *why, size_t why_len);
/*! oc_camera_format() : the inverse of oc_camera_parse() (round-trips exactly with %.17g). */
void oc_camera_format(oc_camera_pose_t pose, char *out, size_t cap);
/*! oc_camera_ray() : direction through pixel centre (px + 0.5, py + 0.5) of a w×h image. */
oc_dvec3 oc_camera_ray(const oc_camera_t *c, int w, int h, double px, double py);

#endif /* OC_COMMON_CAMERA_H */
