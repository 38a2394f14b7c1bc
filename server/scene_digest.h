/* scene_digest.h — what a scene's bricks depend on, as one number, so that front-ends that load
 * the same scene with the same build share bricks (world.h, "Sharing bricks"), and front-ends that
 * differ in either never do. */
#ifndef OC_SERVER_SCENE_DIGEST_H
#define OC_SERVER_SCENE_DIGEST_H

#include <stddef.h>
#include <stdint.h>

#include "oc_scene.h"

/*! ocs_scene_digest() : XXH3-64 over the build's identity (the commit it was configured at, and
 *  the version), the scene file's bytes (NULL path: the built-in planet, by its seed), and the
 *  bytes of every VDB file the scene names, each frame of a sequence included. Never 0.
 *  @return 0, or OC_ENOENT / OC_EIO with the file named in why. */
int ocs_scene_digest(const char *scene_path, const oc_scene_t *scene, uint64_t *out, char *why, size_t why_len);

#endif /* OC_SERVER_SCENE_DIGEST_H */
