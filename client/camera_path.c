/* camera_path.c — timed camera poses: file, interpolation (camera_path.h). */
#include "camera_path.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"

void ocv_path_init(ocv_path_t *p) { memset(p, 0, sizeof *p); }

void ocv_path_free(ocv_path_t *p) {
  if (!p) return;
  free(p->t);
  free(p->pose);
  memset(p, 0, sizeof *p);
}

int ocv_path_add(ocv_path_t *p, double t, oc_camera_pose_t pose) {
  if (!p || !isfinite(t) || (p->count && !(t > p->t[p->count - 1]))) return OC_EINVAL;
  if (p->count == p->cap) {
    size_t nc = p->cap ? 2 * p->cap : 64;
    double *nt = realloc(p->t, nc * sizeof *nt);
    if (!nt) return OC_ENOMEM;
    p->t = nt;
    oc_camera_pose_t *np = realloc(p->pose, nc * sizeof *np);
    if (!np) return OC_ENOMEM;
    p->pose = np;
    p->cap = nc;
  }
  p->t[p->count] = t;
  p->pose[p->count++] = pose;
  return 0;
}

int ocv_path_load(ocv_path_t *p, const char *file, char *why, size_t why_len) {
  ocv_path_free(p);
  FILE *f = fopen(file, "r");
  if (!f) return oc_errorf(OC_ENOENT, why, why_len, "%s: cannot open: %s", file, strerror(errno));
  char line[1024];
  int n = 0, rc = 0;
  while (rc == 0 && fgets(line, sizeof line, f)) {
    n++;
    char *s = line;
    while (*s == ' ' || *s == '\t') s++;
    if (*s == '#' || *s == '\n' || *s == '\r' || !*s) continue;
    if (!strchr(line, '\n') && !feof(f)) {
      rc = oc_errorf(OC_ECORRUPT, why, why_len, "%s:%d: line longer than %zu bytes", file, n, sizeof line - 2);
      break;
    }
    char *end;
    double t = strtod(s, &end);
    if (end == s || !isfinite(t)) {
      rc = oc_errorf(OC_ECORRUPT, why, why_len, "%s:%d: expected a time in seconds first", file, n);
      break;
    }
    while (*end == ' ' || *end == '\t') end++;
    end[strcspn(end, "\r\n")] = 0;
    oc_camera_pose_t pose;
    char cwhy[256];
    if (oc_camera_parse(end, &pose, cwhy, sizeof cwhy) < 0) {
      rc = oc_errorf(OC_ECORRUPT, why, why_len, "%s:%d: %s", file, n, cwhy);
      break;
    }
    int r = ocv_path_add(p, t, pose);
    if (r == OC_EINVAL) rc = oc_errorf(OC_ECORRUPT, why, why_len, "%s:%d: time %g is not after the previous key", file, n, t);
    else if (r < 0) rc = oc_errorf(r, why, why_len, "%s: out of memory", file);
  }
  fclose(f);
  if (rc == 0 && p->count == 0) rc = oc_errorf(OC_ECORRUPT, why, why_len, "%s: no camera keys", file);
  if (rc) ocv_path_free(p);
  return rc;
}

int ocv_path_save(const ocv_path_t *p, const char *file, char *why, size_t why_len) {
  FILE *f = fopen(file, "w");
  if (!f) return oc_errorf(OC_EIO, why, why_len, "%s: cannot create: %s", file, strerror(errno));
  fprintf(f, "# overcast camera path: T LAT,LON,ALT,HEADING,PITCH,FOV\n");
  for (size_t i = 0; i < p->count; i++) {
    char c[256];
    oc_camera_format(p->pose[i], c, sizeof c);
    fprintf(f, "%.17g %s\n", p->t[i], c);
  }
  int bad = ferror(f);
  if (fclose(f) != 0 || bad) return oc_errorf(OC_EIO, why, why_len, "%s: write failed", file);
  return 0;
}

/* a + s·(b − a) for angles, the short way round (degrees). */
static double ocv__lerp_deg(double a, double b, double s) {
  double d = fmod(b - a, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return a + s * d;
}

int ocv_path_sample(const ocv_path_t *p, double t, oc_camera_pose_t *out) {
  if (!p || !p->count || !out) return OC_EINVAL;
  if (!(t > p->t[0])) { /* also NaN */
    *out = p->pose[0];
    return 0;
  }
  if (t >= p->t[p->count - 1]) {
    *out = p->pose[p->count - 1];
    return 0;
  }
  size_t lo = 0, hi = p->count - 1; /* t[lo] < t ≤ t[hi] */
  while (hi - lo > 1) {
    size_t mid = lo + (hi - lo) / 2;
    if (p->t[mid] < t) lo = mid;
    else hi = mid;
  }
  double s = (t - p->t[lo]) / (p->t[hi] - p->t[lo]);
  const oc_camera_pose_t *a = &p->pose[lo], *b = &p->pose[hi];
  out->geo.lat = a->geo.lat + s * (b->geo.lat - a->geo.lat);
  out->geo.lon = ocv__lerp_deg(a->geo.lon, b->geo.lon, s);
  if (out->geo.lon > 180.0) out->geo.lon -= 360.0;
  if (out->geo.lon < -180.0) out->geo.lon += 360.0;
  out->geo.alt = a->geo.alt + s * (b->geo.alt - a->geo.alt);
  out->heading = ocv__lerp_deg(a->heading, b->heading, s);
  out->pitch = a->pitch + s * (b->pitch - a->pitch);
  out->fov = a->fov + s * (b->fov - a->fov);
  return 0;
}

double ocv_path_duration(const ocv_path_t *p) { return p && p->count ? p->t[p->count - 1] : 0.0; }
