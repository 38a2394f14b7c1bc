/* stress_path.h — the camera paths of overcast-stress: each viewer flies one of them.
 *
 * A path is a pose as a function of path time t (seconds, non-decreasing from call to call), built
 * around a home pose (the scene's camera from WELCOME) and a seed:
 *   orbit     a circle of 2 km radius around the home position, at its altitude, one turn per 60 s,
 *             looking at the centre, 5° down;
 *   dive      from 1000 km straight down to 10 m above the home point, the altitude falling
 *             exponentially over `dive_seconds` (pitch from -89° to -10°), then again from the top;
 *   cruise    1 km above the ground at 250 m/s along the great circle leaving home on its heading;
 *   teleport  a uniformly random point of the planet, 500 m to 5 km up, random heading, every
 *             `teleport_every` seconds, holding still in between (the first jump is at t = 0);
 *   random    a random walk from home: every second a new turn rate (±10°/s), speed (50..400 m/s)
 *             and climb rate (±50 m/s), altitude kept within 200 m..15 km.
 * Every path is a pure function of (kind, home, seed, t): two runs with the same seed fly the same
 * cameras at the same path times. */
#ifndef OC_TOOLS_STRESS_PATH_H
#define OC_TOOLS_STRESS_PATH_H

#include <stdint.h>

#include "oc.h"

typedef enum { STRESS_ORBIT = 0, STRESS_DIVE, STRESS_CRUISE, STRESS_TELEPORT, STRESS_RANDOM, STRESS_PATH_COUNT } stress_path_kind_t;

typedef struct {
  stress_path_kind_t kind;
  oc_camera_pose_t home;
  uint64_t seed;
  double teleport_every, dive_seconds;
  double phase; /* orbit: starting angle (radians), from the seed */
  /* random walk: integrated in fixed steps up to the last t asked for */
  double rw_t, rw_lat, rw_lon, rw_alt, rw_heading, rw_turn, rw_speed, rw_climb;
  long rw_segment;
} stress_path_t;

/*! stress_path_name() : "orbit", ... ; stress_path_parse() : the kind for a name, or -1. */
const char *stress_path_name(stress_path_kind_t k);
int stress_path_parse(const char *name, size_t len);
/*! stress_path_init() : teleport_every and dive_seconds in path seconds (> 0). */
void stress_path_init(stress_path_t *p, stress_path_kind_t kind, oc_camera_pose_t home, uint64_t seed,
                      double teleport_every, double dive_seconds);
/*! stress_path_at() : the pose at path time t (t ≥ the previous call's). *jump (may be NULL) gets the
 *  index of the current discontinuity: it changes exactly when the camera jumped (teleport: each
 *  new place, counted from 1 at t = 0; dive: each restart from the top; others: always 0). */
oc_camera_pose_t stress_path_at(stress_path_t *p, double t, long *jump);

#endif /* OC_TOOLS_STRESS_PATH_H */
