/* stress_path.c — camera paths for overcast-stress (stress_path.h). */
#include "stress_path.h"

#include <math.h>
#include <string.h>

#include "oc.h"

#define SP_PI 3.14159265358979323846
#define SP_ORBIT_RADIUS 2000.0 /* m */
#define SP_ORBIT_PERIOD 60.0   /* s per turn */
#define SP_DIVE_TOP 1.0e6      /* m */
#define SP_DIVE_BOTTOM 10.0    /* m */
#define SP_CRUISE_ALT 1000.0   /* m */
#define SP_CRUISE_SPEED 250.0  /* m/s */
#define SP_RW_DT 0.1           /* s: random-walk integration step */
#define SP_RW_SEGMENT 1.0      /* s between random-walk choices */

static const char *const sp_names[STRESS_PATH_COUNT] = {"orbit", "dive", "cruise", "teleport", "random"};

const char *stress_path_name(stress_path_kind_t k) { return k < STRESS_PATH_COUNT ? sp_names[k] : "?"; }

int stress_path_parse(const char *name, size_t len) {
  for (int k = 0; k < STRESS_PATH_COUNT; k++)
    if (strlen(sp_names[k]) == len && !strncmp(name, sp_names[k], len)) return k;
  return -1;
}

/* splitmix64: a stateless hash of (seed, stream, index) into [0, 1). */
static uint64_t sp_mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

static double sp_u01(uint64_t seed, uint64_t stream, uint64_t index, int draw) {
  uint64_t h = sp_mix(seed ^ sp_mix(stream * 0x100000001B3ull ^ sp_mix(index * 8u + (uint64_t)draw)));
  return (double)(h >> 11) * 0x1.0p-53;
}

void stress_path_init(stress_path_t *p, stress_path_kind_t kind, oc_camera_pose_t home, uint64_t seed,
                      double teleport_every, double dive_seconds) {
  memset(p, 0, sizeof *p);
  p->kind = kind;
  p->home = home;
  p->seed = seed;
  p->teleport_every = teleport_every > 0 ? teleport_every : 10.0;
  p->dive_seconds = dive_seconds > 0 ? dive_seconds : 30.0;
  p->phase = 2.0 * SP_PI * sp_u01(seed, 1, 0, 0);
  p->rw_lat = home.geo.lat;
  p->rw_lon = home.geo.lon;
  p->rw_alt = fmin(fmax(home.geo.alt, 200.0), 15000.0);
  p->rw_heading = home.heading;
  p->rw_segment = -1;
}

/* Heading (degrees) at `pos` of the horizontal direction `dir`. */
static double sp_heading(oc_dvec3 pos, oc_dvec3 dir) {
  double h, pitch;
  oc_dir_heading_pitch(oc_enu_at(pos), dir, &h, &pitch);
  return h;
}

static oc_camera_pose_t sp_orbit(const stress_path_t *p, double t) {
  oc_dvec3 c = oc_geo_to_xyz(p->home.geo);
  oc_enu_t e = oc_enu_at(c);
  double a = p->phase + 2.0 * SP_PI * t / SP_ORBIT_PERIOD;
  oc_dvec3 pos = oc_dadd(c, oc_dadd(oc_dscale(e.east, SP_ORBIT_RADIUS * cos(a)), oc_dscale(e.north, SP_ORBIT_RADIUS * sin(a))));
  oc_camera_pose_t q = p->home;
  q.geo = oc_xyz_to_geo(pos);
  q.heading = sp_heading(pos, oc_dsub(c, pos));
  q.pitch = -5.0;
  return q;
}

static oc_camera_pose_t sp_dive(const stress_path_t *p, double t, long *jump) {
  double cycles = floor(t / p->dive_seconds), u = t / p->dive_seconds - cycles;
  *jump = (long)cycles;
  oc_camera_pose_t q = p->home;
  q.geo.alt = SP_DIVE_TOP * pow(SP_DIVE_BOTTOM / SP_DIVE_TOP, u);
  q.pitch = -89.0 + 79.0 * u;
  return q;
}

static oc_camera_pose_t sp_cruise(const stress_path_t *p, double t) {
  oc_geo_t g0 = p->home.geo;
  g0.alt = 0;
  oc_dvec3 p0 = oc_dnorm(oc_geo_to_xyz(g0));
  oc_enu_t e = oc_enu_at(p0);
  double h = p->home.heading * SP_PI / 180.0;
  oc_dvec3 d = oc_dadd(oc_dscale(e.north, cos(h)), oc_dscale(e.east, sin(h)));
  double r = OC_PLANET_RADIUS + SP_CRUISE_ALT, th = SP_CRUISE_SPEED * t / r;
  oc_dvec3 u = oc_dadd(oc_dscale(p0, cos(th)), oc_dscale(d, sin(th)));
  oc_dvec3 tangent = oc_dadd(oc_dscale(p0, -sin(th)), oc_dscale(d, cos(th)));
  oc_dvec3 pos = oc_dscale(u, r);
  oc_camera_pose_t q = p->home;
  q.geo = oc_xyz_to_geo(pos);
  q.geo.alt = SP_CRUISE_ALT;
  q.heading = sp_heading(pos, tangent);
  q.pitch = -5.0;
  return q;
}

static oc_camera_pose_t sp_teleport(const stress_path_t *p, double t, long *jump) {
  long k = (long)floor(t / p->teleport_every);
  *jump = k + 1;
  oc_camera_pose_t q = p->home;
  double z = 2.0 * sp_u01(p->seed, 2, (uint64_t)k, 0) - 1.0;
  q.geo.lat = asin(z) * 180.0 / SP_PI;
  q.geo.lon = 360.0 * sp_u01(p->seed, 2, (uint64_t)k, 1) - 180.0;
  q.geo.alt = 500.0 + 4500.0 * sp_u01(p->seed, 2, (uint64_t)k, 2);
  q.heading = 360.0 * sp_u01(p->seed, 2, (uint64_t)k, 3);
  q.pitch = -15.0 * sp_u01(p->seed, 2, (uint64_t)k, 4);
  return q;
}

/* One random-walk step of SP_RW_DT seconds from p->rw_t. */
static void sp_rw_step(stress_path_t *p, double dt) {
  long seg = (long)floor(p->rw_t / SP_RW_SEGMENT + 1e-9);
  if (seg != p->rw_segment) {
    p->rw_segment = seg;
    p->rw_turn = 20.0 * sp_u01(p->seed, 3, (uint64_t)seg, 0) - 10.0;
    p->rw_speed = 50.0 + 350.0 * sp_u01(p->seed, 3, (uint64_t)seg, 1);
    p->rw_climb = 100.0 * sp_u01(p->seed, 3, (uint64_t)seg, 2) - 50.0;
  }
  double r = OC_PLANET_RADIUS + p->rw_alt, h = p->rw_heading * SP_PI / 180.0, d = p->rw_speed * dt / r;
  p->rw_lat += d * cos(h) * 180.0 / SP_PI;
  p->rw_lon += d * sin(h) * 180.0 / SP_PI / fmax(cos(p->rw_lat * SP_PI / 180.0), 0.05);
  if (p->rw_lat > 85.0 || p->rw_lat < -85.0) { /* turn back before the pole */
    p->rw_lat = p->rw_lat > 0 ? 170.0 - p->rw_lat : -170.0 - p->rw_lat;
    p->rw_heading = 180.0 - p->rw_heading;
  }
  p->rw_lon = remainder(p->rw_lon, 360.0);
  p->rw_heading = fmod(p->rw_heading + p->rw_turn * dt + 360.0, 360.0);
  p->rw_alt += p->rw_climb * dt;
  if (p->rw_alt < 200.0 || p->rw_alt > 15000.0) {
    p->rw_alt = fmin(fmax(p->rw_alt, 200.0), 15000.0);
    p->rw_climb = -p->rw_climb;
  }
  p->rw_t += dt;
}

static oc_camera_pose_t sp_random(stress_path_t *p, double t) {
  while (p->rw_t + SP_RW_DT <= t + 1e-9) sp_rw_step(p, SP_RW_DT);
  stress_path_t tmp = *p; /* the part step, without moving the integrated state */
  if (t > tmp.rw_t) sp_rw_step(&tmp, t - tmp.rw_t);
  oc_camera_pose_t q = p->home;
  q.geo = (oc_geo_t){tmp.rw_lat, tmp.rw_lon, tmp.rw_alt};
  q.heading = tmp.rw_heading;
  q.pitch = -5.0;
  return q;
}

oc_camera_pose_t stress_path_at(stress_path_t *p, double t, long *jump) {
  long j = 0;
  oc_camera_pose_t q;
  if (t < 0) t = 0;
  switch (p->kind) {
    case STRESS_ORBIT: q = sp_orbit(p, t); break;
    case STRESS_DIVE: q = sp_dive(p, t, &j); break;
    case STRESS_CRUISE: q = sp_cruise(p, t); break;
    case STRESS_TELEPORT: q = sp_teleport(p, t, &j); break;
    default: q = sp_random(p, t); break;
  }
  if (jump) *jump = j;
  return q;
}
