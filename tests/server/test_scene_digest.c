/* test_scene_digest.c — a scene's content id (server/scene_digest.h): the same files give the same
 * id, one changed byte in the scene or in a VDB frame another, and a missing file is named. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "scene_digest.h"

static void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static uint64_t digest_of(const char *path, int expect) {
  oc_scene_t sc;
  char why[512];
  if (oc_scene_load(&sc, path, why, sizeof why) < 0) fail_msg("scene: %s", why);
  uint64_t d = 0;
  int r = ocs_scene_digest(path, &sc, &d, why, sizeof why);
  assert_int_equal(r, expect);
  if (r < 0) assert_non_null(strstr(why, "frame_0002.vdb"));
  oc_scene_free(&sc);
  return d;
}

static void test_digest__files_decide(void **st) {
  (void)st;
  char dir[] = "/tmp/oc_digest_XXXXXX";
  assert_non_null(mkdtemp(dir));
  char scene[256], f0[256], f1[256], f2[256];
  snprintf(scene, sizeof scene, "%s/s.json", dir);
  snprintf(f0, sizeof f0, "%s/frame_0000.vdb", dir);
  snprintf(f1, sizeof f1, "%s/frame_0001.vdb", dir);
  snprintf(f2, sizeof f2, "%s/frame_0002.vdb", dir);
  /* the digest reads bytes only: these need not be valid VDB files */
  write_file(f0, "frame zero");
  write_file(f1, "frame one");
  const char *json = "{\"version\":1,\"sources\":[{\"type\":\"vdb\",\"file\":\"frame_####.vdb\","
                     "\"sequence\":{\"count\":2,\"frame_rate\":24}}]}";
  write_file(scene, json);
  uint64_t a = digest_of(scene, 0), b = digest_of(scene, 0);
  assert_true(a != 0 && a == b);
  write_file(f1, "frame One"); /* one byte of the second frame */
  uint64_t c = digest_of(scene, 0);
  assert_true(c != a);
  write_file(scene, "{\"version\":1,\"sources\":[{\"type\":\"vdb\",\"file\":\"frame_####.vdb\","
                    "\"sequence\":{\"count\":3,\"frame_rate\":24}}]}");
  digest_of(scene, OC_ENOENT); /* the third frame is missing, and named */
  write_file(f2, "frame two");
  uint64_t d = digest_of(scene, 0);
  assert_true(d != c);
  /* the built-in planet: by its seed */
  oc_scene_t p, q;
  oc_scene_default(&p);
  oc_scene_default(&q);
  q.seed = p.seed + 1;
  uint64_t dp, dq;
  assert_int_equal(ocs_scene_digest(NULL, &p, &dp, NULL, 0), 0);
  assert_int_equal(ocs_scene_digest(NULL, &q, &dq, NULL, 0), 0);
  assert_true(dp != dq && dp != a);
  oc_scene_free(&p);
  oc_scene_free(&q);
  unlink(f0);
  unlink(f1);
  unlink(f2);
  unlink(scene);
  rmdir(dir);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_digest__files_decide))
