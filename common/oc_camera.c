#include "oc_camera.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "oc_err.h"

oc_camera_t oc_camera_from_pose(oc_camera_pose_t pose) {
  oc_camera_t c;
  c.pos = oc_geo_to_xyz(pose.geo);
  oc_enu_t enu = oc_enu_at(c.pos);
  c.forward = oc_heading_pitch_dir(enu, pose.heading, pose.pitch);
  /* Up is the local up tilted with the pitch, so the horizon stays level at any heading. */
  oc_dvec3 right = oc_dcross(c.forward, enu.up);
  if (oc_dlen(right) < 1e-9) right = oc_dcross(c.forward, enu.north); /* looking straight up/down */
  c.right = oc_dnorm(right);
  c.up = oc_dnorm(oc_dcross(c.right, c.forward));
  c.vfov_deg = pose.fov;
  return c;
}

static int oc__field(const char *name, double v, double lo, double hi, char *why, size_t why_len) {
  if (!isfinite(v) || v < lo || v > hi) {
    if (why) snprintf(why, why_len, "camera %s %g outside [%g, %g]", name, v, lo, hi);
    return OC_EINVAL;
  }
  return 0;
}

int oc_camera_parse(const char *text, oc_camera_pose_t *pose, char *why, size_t why_len) {
  static const char *names[6] = {"lat", "lon", "alt", "heading", "pitch", "fov"};
  double v[6];
  const char *s = text;
  for (int i = 0; i < 6; i++) {
    char *end;
    v[i] = strtod(s, &end);
    if (end == s || (i < 5 && *end != ',') || (i == 5 && *end != '\0')) {
      if (why) snprintf(why, why_len, "camera \"%s\": expected lat,lon,alt,heading,pitch,fov (bad %s)", text, names[i]);
      return OC_EINVAL;
    }
    s = end + 1;
  }
  OC_TRY(oc__field("lat", v[0], -90, 90, why, why_len));
  OC_TRY(oc__field("lon", v[1], -360, 360, why, why_len));
  OC_TRY(oc__field("alt", v[2], -OC_PLANET_RADIUS, 1e9, why, why_len));
  OC_TRY(oc__field("heading", v[3], -3600, 3600, why, why_len));
  OC_TRY(oc__field("pitch", v[4], -90, 90, why, why_len));
  OC_TRY(oc__field("fov", v[5], 0.1, 179, why, why_len));
  pose->geo.lat = v[0];
  pose->geo.lon = v[1];
  pose->geo.alt = v[2];
  pose->heading = v[3];
  pose->pitch = v[4];
  pose->fov = v[5];
  return 0;
}

void oc_camera_format(oc_camera_pose_t p, char *out, size_t cap) {
  snprintf(out, cap, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", p.geo.lat, p.geo.lon, p.geo.alt, p.heading, p.pitch, p.fov);
}

oc_dvec3 oc_camera_ray(const oc_camera_t *c, int w, int h, double px, double py) {
  double t = tan(0.5 * c->vfov_deg * OC_DEG);
  double x = (2.0 * (px + 0.5) / w - 1.0) * t * ((double)w / h);
  double y = (1.0 - 2.0 * (py + 0.5) / h) * t;
  return oc_dnorm(oc_dadd(c->forward, oc_dadd(oc_dscale(c->right, x), oc_dscale(c->up, y))));
}
