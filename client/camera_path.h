/* camera_path.h — recorded camera paths for benchmarks and bug reports (overcast-view --record,
 * --path): a text file of timed poses, one per line,
 *     # comments and blank lines are ignored
 *     T  LAT,LON,ALT,HEADING,PITCH,FOV
 * (T in seconds from the start, strictly increasing; the pose as oc_camera_parse() reads it, written
 * with oc_camera_format() so it round-trips exactly). Between two keys a pose is interpolated:
 * latitude, longitude and altitude linearly (longitude and heading the short way round), pitch and
 * field of view linearly; before the first key the first, after the last the last. */
#ifndef OC_CLIENT_CAMERA_PATH_H
#define OC_CLIENT_CAMERA_PATH_H

#include <stddef.h>

#include "oc_camera.h"

typedef struct {
  double *t;
  oc_camera_pose_t *pose;
  size_t count, cap;
} ocv_path_t;

void ocv_path_init(ocv_path_t *p);
void ocv_path_free(ocv_path_t *p);
/*! ocv_path_add() : appends a key (t must be greater than the last). @return 0, OC_EINVAL, OC_ENOMEM. */
int ocv_path_add(ocv_path_t *p, double t, oc_camera_pose_t pose);
/*! ocv_path_load() / ocv_path_save() : errors name the file and line ("path.txt:3: ..."). */
int ocv_path_load(ocv_path_t *p, const char *file, char *why, size_t why_len);
int ocv_path_save(const ocv_path_t *p, const char *file, char *why, size_t why_len);
/*! ocv_path_sample() : the pose at time t (an empty path gives OC_EINVAL). */
int ocv_path_sample(const ocv_path_t *p, double t, oc_camera_pose_t *out);
/*! ocv_path_duration() : the last key's time (0 when empty). */
double ocv_path_duration(const ocv_path_t *p);

#endif /* OC_CLIENT_CAMERA_PATH_H */
