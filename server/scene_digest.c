/* scene_digest.c — a scene's content id for sharing bricks (scene_digest.h). */
#include "scene_digest.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <xxhash.h>

#include "oc_err.h"
#include "vdb_tools.h"

#ifndef OCS_BUILD_ID
#define OCS_BUILD_ID "unknown"
#endif

/* Streams one file's bytes (with its length, so that files do not run into each other). */
static int ocs__digest_file(XXH3_state_t *st, const char *path, char *why, size_t why_len) {
  FILE *f = fopen(path, "rb");
  if (!f) return oc_errorf(errno == ENOENT ? OC_ENOENT : OC_EIO, why, why_len, "%s: %s", path, strerror(errno));
  static _Thread_local unsigned char buf[1 << 16];
  uint64_t total = 0;
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) {
    XXH3_64bits_update(st, buf, n);
    total += n;
  }
  int bad = ferror(f);
  fclose(f);
  if (bad) return oc_errorf(OC_EIO, why, why_len, "%s: read error", path);
  XXH3_64bits_update(st, &total, sizeof total);
  return 0;
}

static int ocs__digest_vdb(XXH3_state_t *st, const oc_src_vdb_t *v, char *why, size_t why_len) {
  int frames = v->has_sequence ? v->sequence.count : 1;
  char path[4096];
  for (int i = 0; i < frames; i++) {
    ocs_vdb_frame_path(v->file, v->has_sequence, v->has_sequence ? v->sequence.first : 0, i, path, sizeof path);
    OC_TRY(ocs__digest_file(st, path, why, why_len));
  }
  return 0;
}

int ocs_scene_digest(const char *scene_path, const oc_scene_t *scene, uint64_t *out, char *why, size_t why_len) {
  if (!scene || !out) return OC_EINVAL;
  XXH3_state_t *st = XXH3_createState();
  if (!st) return OC_ENOMEM;
  XXH3_64bits_reset(st);
  static const char build[] = "overcast " OC_VERSION " " OCS_BUILD_ID;
  XXH3_64bits_update(st, build, sizeof build);
  int r = 0;
  if (scene_path) {
    r = ocs__digest_file(st, scene_path, why, why_len);
  } else {
    static const char builtin[] = "built-in planet";
    XXH3_64bits_update(st, builtin, sizeof builtin);
    XXH3_64bits_update(st, &scene->seed, sizeof scene->seed);
  }
  for (int i = 0; r == 0 && i < scene->nsources; i++)
    if (scene->sources[i].type == OC_SOURCE_VDB) r = ocs__digest_vdb(st, &scene->sources[i].vdb, why, why_len);
  uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  if (r < 0) return r;
  *out = h ? h : 1; /* 0 means "not shared" */
  return 0;
}
