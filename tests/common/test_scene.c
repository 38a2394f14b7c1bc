/* test_scene.c — scene files: every shipped scene loads, defaults, and one test per error kind
 * (the message must name the file and the key path). */
#include <dirent.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_scene.h"

static char g_src[1024]; /* OC_SOURCE_DIR */

static void scene_path(char *dst, size_t cap, const char *name) { snprintf(dst, cap, "%s/scenes/%s", g_src, name); }

static int parse(oc_scene_t *s, const char *json, char *why, size_t cap) {
  return oc_scene_parse(s, json, strlen(json), "t.json", why, cap);
}

/* The JSON must fail with `code` and a message containing every string in the NULL-terminated list. */
static void expect_error(const char *json, int code, ...) {
  oc_scene_t s;
  char why[512];
  memset(&s, 0xAB, sizeof s); /* must be zeroed on failure */
  int r = parse(&s, json, why, sizeof why);
  if (r != code) fail_msg("%s\n -> %d (%s), want %d; why: %s", json, r, oc_err_name(r), code, why);
  if (strncmp(why, "t.json", 6) != 0) fail_msg("message does not start with the file name: %s", why);
  if (strchr(why, '\n')) fail_msg("message is more than one line: %s", why);
  va_list ap;
  va_start(ap, code);
  for (const char *want; (want = va_arg(ap, const char *));)
    if (!strstr(why, want)) fail_msg("%s\n -> message \"%s\" lacks \"%s\"", json, why, want);
  va_end(ap);
  static const oc_scene_t zero;
  assert_memory_equal(&s, &zero, sizeof s);
  oc_scene_free(&s);
}

/* ---- Shipped scenes ---- */

static void test_all_shipped_scenes_load(void **state) {
  (void)state;
  char dir[1200];
  snprintf(dir, sizeof dir, "%s/scenes", g_src);
  DIR *d = opendir(dir);
  assert_non_null(d);
  int count = 0;
  for (struct dirent *e; (e = readdir(d));) {
    size_t n = strlen(e->d_name);
    if (n < 6 || strcmp(e->d_name + n - 5, ".json") != 0) continue;
    char path[1600], why[512];
    snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
    oc_scene_t s;
    int r = oc_scene_load(&s, path, why, sizeof why);
    if (r != 0) fail_msg("%s: %s", path, why);
    assert_true(fabs(oc_dlen(s.sun_dir) - 1.0) < 1e-12);
    oc_scene_free(&s);
    count++;
  }
  closedir(d);
  assert_true(count >= 3);
}

static void test_planet_is_default(void **state) {
  (void)state;
  char path[1200], why[512];
  scene_path(path, sizeof path, "planet.json");
  oc_scene_t a, b;
  assert_int_equal(oc_scene_load(&a, path, why, sizeof why), 0);
  oc_scene_default(&b);
  assert_string_equal(a.name, b.name);
  assert_true(a.seed == b.seed);
  assert_true(a.epoch_period == b.epoch_period);
  assert_int_equal(a.features, b.features);
  assert_true(fabs(a.sun_dir.x - b.sun_dir.x) < 1e-15 && fabs(a.sun_dir.y - b.sun_dir.y) < 1e-15 &&
              fabs(a.sun_dir.z - b.sun_dir.z) < 1e-15);
  assert_memory_equal(&a.camera, &b.camera, sizeof a.camera);
  assert_memory_equal(&a.optics, &b.optics, sizeof a.optics);
  assert_int_equal(a.nsources, 1);
  assert_int_equal(b.nsources, 1);
  assert_int_equal(a.sources[0].type, OC_SOURCE_PROCEDURAL);
  assert_memory_equal(&a.sources[0], &b.sources[0], sizeof a.sources[0]);
  assert_true(oc_scene_has(&b, OC_FEATURE_ANIMATION));
  assert_int_equal(b.features, (1u << OC_FEATURE_COUNT) - 1u);
  /* Subsolar point 20°N 10°E. */
  assert_true(fabs(b.sun_dir.z - sin(20 * OC_DEG)) < 1e-15);
  oc_scene_free(&a);
  oc_scene_free(&b);
}

static void test_analytic_scenes(void **state) {
  (void)state;
  char path[1200], why[512];
  oc_scene_t s;
  scene_path(path, sizeof path, "analytic_sphere.json");
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), 0);
  assert_int_equal(s.nsources, 1);
  assert_int_equal(s.sources[0].type, OC_SOURCE_SPHERE);
  assert_true(s.sources[0].sphere.radius == 2000.0);
  assert_true(s.sources[0].sphere.sigma_t == 0.05);
  assert_true(s.sources[0].sphere.centre.alt == 3000.0);
  assert_false(oc_scene_has(&s, OC_FEATURE_ANIMATION));
  assert_true(oc_scene_has(&s, OC_FEATURE_ATMOSPHERE));
  oc_scene_free(&s);

  scene_path(path, sizeof path, "analytic_slab.json");
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), 0);
  assert_int_equal(s.nsources, 1);
  assert_int_equal(s.sources[0].type, OC_SOURCE_SLAB);
  assert_true(s.sources[0].slab.base == 1000.0 && s.sources[0].slab.top == 2000.0);
  assert_true(s.sources[0].slab.sigma_t == 0.02);
  assert_false(oc_scene_has(&s, OC_FEATURE_ANIMATION));
  assert_string_equal(s.name, "analytic_slab");
  oc_scene_free(&s);
}

/* ---- Defaults ---- */

static void test_defaults(void **state) {
  (void)state;
  oc_scene_t s;
  char why[256];
  assert_int_equal(oc_scene_parse(&s, "{}", 2, "some/dir/my.scene.json", why, sizeof why), 0);
  assert_string_equal(s.name, "my.scene");
  assert_true(s.seed == 1);
  assert_true(s.epoch_period == 1.0);
  /* No time-varying source: animation defaults off, everything else on. */
  assert_int_equal(s.features, ((1u << OC_FEATURE_COUNT) - 1u) & ~(1u << OC_FEATURE_ANIMATION));
  oc_dvec3 sun = s.sun_dir;
  assert_true(fabs(sun.x - cos(20 * OC_DEG) * cos(10 * OC_DEG)) < 1e-15);
  assert_true(fabs(sun.y - cos(20 * OC_DEG) * sin(10 * OC_DEG)) < 1e-15);
  assert_true(s.camera.pos.lat == 45 && s.camera.pos.lon == 0 && s.camera.pos.alt == 2000);
  assert_true(s.camera.heading == 260 && s.camera.pitch == -5 && s.camera.fov == 60);
  assert_true(s.optics.albedo == 1.0 && s.optics.ms_octaves == 4);
  assert_true(s.optics.ms_a == 0.6139 && s.optics.ms_b == 0.5139 && s.optics.ms_c == 0.9924);
  assert_int_equal(s.nsources, 0);
  oc_scene_free(&s);

  /* Without a name for errors. */
  assert_int_equal(oc_scene_parse(&s, " {} ", 4, NULL, NULL, 0), 0);
  assert_string_equal(s.name, "scene");
  oc_scene_free(&s);

  /* Source defaults; a procedural source turns animation on by default. */
  const char *j = "{\"sources\": [{\"type\": \"procedural\"},"
                  " {\"type\": \"box\", \"alt\": 100, \"size\": [1, 2, 3], \"sigma_t\": 0.1},"
                  " {\"type\": \"vdb\", \"file\": \"/data/cloud.vdb\"}]}";
  assert_int_equal(parse(&s, j, why, sizeof why), 0);
  assert_true(oc_scene_has(&s, OC_FEATURE_ANIMATION));
  assert_int_equal(s.sources[0].procedural.preset, OC_PRESET_FAIR);
  assert_true(s.sources[0].procedural.coverage_scale == 1.0 && s.sources[0].procedural.sigma_scale == 1.0);
  assert_true(s.sources[1].box.heading == 0 && s.sources[1].box.base.lat == 0 && s.sources[1].box.size[2] == 3);
  assert_string_equal(s.sources[2].vdb.file, "/data/cloud.vdb");
  assert_string_equal(s.sources[2].vdb.grid, "density");
  assert_int_equal(s.sources[2].vdb.grid_index, -1);
  assert_true(s.sources[2].vdb.scale_m == 0 && s.sources[2].vdb.sigma_scale == 1.0);
  assert_false(s.sources[2].vdb.has_sequence);
  oc_scene_free(&s);

  /* A vdb sequence alone also animates; features.animation overrides the default. */
  j = "{\"sources\": [{\"type\": \"vdb\", \"file\": \"c_####.vdb\", \"sequence\": {\"count\": 10}}]}";
  assert_int_equal(parse(&s, j, why, sizeof why), 0);
  assert_true(oc_scene_has(&s, OC_FEATURE_ANIMATION));
  assert_true(s.sources[0].vdb.sequence.frame_rate == 24 && s.sources[0].vdb.sequence.first == 0);
  assert_int_equal(s.sources[0].vdb.sequence.end, OC_SEQ_LOOP);
  assert_int_equal(s.sources[0].vdb.sequence.count, 10);
  oc_scene_free(&s);
  j = "{\"features\": {\"animation\": false, \"ozone\": false}, \"sources\": [{\"type\": \"procedural\"}]}";
  assert_int_equal(parse(&s, j, why, sizeof why), 0);
  assert_false(oc_scene_has(&s, OC_FEATURE_ANIMATION));
  assert_false(oc_scene_has(&s, OC_FEATURE_OZONE));
  assert_true(oc_scene_has(&s, OC_FEATURE_SHADOWS));
  oc_scene_free(&s);
}

static void test_values(void **state) {
  (void)state;
  oc_scene_t s;
  char why[256];
  const char *j =
      "{\"version\": 1, \"name\": \"x\", \"seed\": 9007199254740991, \"epoch_period\": 60,"
      " \"sun\": {\"direction\": [0, 0, 5]},"
      " \"camera\": {\"lat\": -90, \"lon\": 180, \"alt\": 1e9, \"heading\": -360, \"pitch\": 90, \"fov\": 178.5},"
      " \"optics\": {\"albedo\": 0, \"ms_octaves\": 8.0, \"ms_a\": 0.25, \"ms_b\": 0.75, \"ms_c\": 0.125},"
      " \"sources\": [{\"type\": \"slab\", \"base\": -10000, \"top\": 100000, \"sigma_t\": 1e9},"
      "  {\"type\": \"procedural\", \"preset\": \"cirrus\", \"coverage_scale\": 0, \"sigma_scale\": 0},"
      "  {\"type\": \"vdb\", \"file\": \"a/b_##.vdb\", \"grid_index\": 3, \"scale_m\": 50, \"heading\": 45,"
      "   \"lat\": 10, \"lon\": -20, \"alt\": 500, \"sigma_scale\": 2,"
      "   \"sequence\": {\"frame_rate\": 12.5, \"first\": 7, \"count\": 3, \"end\": \"hold\"}}]}";
  assert_int_equal(parse(&s, j, why, sizeof why), 0);
  assert_true(s.seed == 9007199254740991ull);
  assert_true(s.sun_dir.x == 0 && s.sun_dir.y == 0 && s.sun_dir.z == 1);
  assert_true(s.camera.fov == 178.5 && s.camera.pos.alt == 1e9);
  assert_true(s.optics.ms_octaves == 8 && s.optics.ms_c == 0.125 && s.optics.albedo == 0);
  assert_true(s.sources[0].slab.sigma_t == 1e9);
  assert_int_equal(s.sources[1].procedural.preset, OC_PRESET_CIRRUS);
  const oc_src_vdb_t *v = &s.sources[2].vdb;
  assert_string_equal(v->file, "a/b_##.vdb"); /* oc_scene_parse keeps relative paths */
  assert_int_equal(v->grid_index, 3);
  assert_true(v->anchor.lat == 10 && v->anchor.lon == -20 && v->anchor.alt == 500);
  assert_true(v->has_sequence && v->sequence.first == 7 && v->sequence.count == 3 && v->sequence.end == OC_SEQ_HOLD);
  assert_true(v->sequence.frame_rate == 12.5);

  /* Deep copy. */
  oc_scene_t c;
  assert_int_equal(oc_scene_copy(&c, &s), 0);
  assert_ptr_not_equal(c.sources[2].vdb.file, s.sources[2].vdb.file);
  assert_string_equal(c.sources[2].vdb.file, "a/b_##.vdb");
  oc_scene_free(&s);
  assert_string_equal(c.sources[2].vdb.file, "a/b_##.vdb");
  oc_scene_free(&c);
  oc_scene_free(&c); /* harmless twice */
  oc_scene_free(NULL);

  /* Sun directions that would underflow or overflow a naive normalisation. */
  assert_int_equal(parse(&s, "{\"sun\": {\"direction\": [1e-300, 0, -1e-300]}}", why, sizeof why), 0);
  assert_true(fabs(s.sun_dir.x - sqrt(0.5)) < 1e-15 && fabs(s.sun_dir.z + sqrt(0.5)) < 1e-15);
  assert_int_equal(parse(&s, "{\"sun\": {\"direction\": [1e308, 1e308, 0]}}", why, sizeof why), 0);
  assert_true(fabs(s.sun_dir.x - sqrt(0.5)) < 1e-15 && fabs(oc_dlen(s.sun_dir) - 1) < 1e-15);
  /* Subsolar point given. */
  assert_int_equal(parse(&s, "{\"sun\": {\"lat\": 90}}", why, sizeof why), 0);
  assert_true(fabs(s.sun_dir.z - 1) < 1e-15);
  /* A UTF-8 byte order mark and CRLF line ends are fine. */
  assert_int_equal(parse(&s, "\xEF\xBB\xBF{\r\n\"seed\": 3\r\n}\r\n", why, sizeof why), 0);
  assert_true(s.seed == 3);
}

/* ---- Errors, one per kind ---- */

static void test_error_unknown_key(void **state) {
  (void)state;
  expect_error("{\"seed\": 1, \"sead\": 2}", OC_ESCENE, "unknown key \"sead\"", "did you mean \"seed\"", NULL);
  expect_error("{\"bogus_key_name\": 2}", OC_ESCENE, "unknown key \"bogus_key_name\"", "allowed:", "epoch_period", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 1, \"radius\": 1, \"sigma_t\": 1},"
               " {\"type\": \"sphere\", \"alt\": 1, \"radius\": 1, \"sigmat\": 1}]}",
               OC_ESCENE, "t.json: sources[1]: unknown key \"sigmat\"", "did you mean \"sigma_t\"", NULL);
  expect_error("{\"features\": {\"shadow\": false}}", OC_ESCENE, "features: unknown key \"shadow\"", "\"shadows\"", NULL);
  expect_error("{\"camera\": {\"fov\": 50, \"zoom\": 2}}", OC_ESCENE, "camera: unknown key \"zoom\"", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"x_#.vdb\", \"sequence\": {\"count\": 1, \"loop\": true}}]}",
               OC_ESCENE, "sources[0].sequence: unknown key \"loop\"", NULL);
  /* A key valid for one source type is unknown for another. */
  expect_error("{\"sources\": [{\"type\": \"slab\", \"base\": 1, \"top\": 2, \"sigma_t\": 1, \"radius\": 3}]}",
               OC_ESCENE, "sources[0]: unknown key \"radius\"", NULL);
  /* Control characters in a key are not echoed raw. */
  expect_error("{\"a\\u0001b\": 1}", OC_ESCENE, "unknown key \"a?b\"", NULL);
}

static void test_error_duplicate_key(void **state) {
  (void)state;
  expect_error("{\"camera\": {\"fov\": 50, \"fov\": 60}}", OC_ESCENE, "camera.fov: duplicate key", NULL);
  expect_error("{\"seed\": 1, \"seed\": 1}", OC_ESCENE, "seed: duplicate key", NULL);
}

static void test_error_wrong_type(void **state) {
  (void)state;
  expect_error("{\"seed\": \"1\"}", OC_ESCENE, "t.json: seed: expected an integer, got a string", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 1, \"radius\": 1, \"sigma_t\": \"0.05\"}]}", OC_ESCENE,
               "sources[0].sigma_t: expected a number, got a string", NULL);
  expect_error("{\"features\": {\"ozone\": 1}}", OC_ESCENE, "features.ozone: expected true or false, got a number", NULL);
  expect_error("{\"features\": [true]}", OC_ESCENE, "features: expected an object, got an array", NULL);
  expect_error("{\"sources\": {}}", OC_ESCENE, "sources: expected an array, got an object", NULL);
  expect_error("{\"sources\": [3]}", OC_ESCENE, "sources[0]: expected an object, got a number", NULL);
  expect_error("{\"name\": null}", OC_ESCENE, "name: expected a string, got null", NULL);
  expect_error("{\"optics\": {\"ms_octaves\": 2.5}}", OC_ESCENE, "optics.ms_octaves: expected an integer, got 2.5", NULL);
  expect_error("{\"sources\": [{\"type\": \"box\", \"alt\": 0, \"size\": [1, \"2\", 3], \"sigma_t\": 1}]}", OC_ESCENE,
               "sources[0].size[1]: expected a number, got a string", NULL);
  expect_error("{\"sources\": [{\"type\": \"box\", \"alt\": 0, \"size\": [1, 2], \"sigma_t\": 1}]}", OC_ESCENE,
               "sources[0].size: expected 3 numbers, got 2", NULL);
  expect_error("{\"sources\": [{\"type\": 4}]}", OC_ESCENE, "sources[0].type: expected a string, got a number", NULL);
  expect_error("[]", OC_ESCENE, "t.json: expected a JSON object at the top level, got an array", NULL);
  expect_error("{\"name\": \"\"}", OC_ESCENE, "name: must not be empty", NULL);
  expect_error("{\"name\": \"a\\nb\"}", OC_ESCENE, "name: contains a control character", NULL);
  expect_error("{\"name\": \"0123456789012345678901234567890123456789012345678901234567890123\"}", OC_ESCENE,
               "name: longer than 63 bytes", NULL);
}

static void test_error_out_of_range(void **state) {
  (void)state;
  expect_error("{\"epoch_period\": 0}", OC_ESCENE, "t.json: epoch_period: 0 is out of range (0, 60]", NULL);
  expect_error("{\"epoch_period\": 60.5}", OC_ESCENE, "epoch_period: 60.5 is out of range (0, 60]", NULL);
  expect_error("{\"seed\": -1}", OC_ESCENE, "seed: -1 is out of range [0, 9007199254740991]", NULL);
  expect_error("{\"camera\": {\"fov\": 179}}", OC_ESCENE, "camera.fov: 179 is out of range (0.1, 179)", NULL);
  expect_error("{\"camera\": {\"lat\": 90.5}}", OC_ESCENE, "camera.lat: 90.5 is out of range [-90, 90]", NULL);
  expect_error("{\"optics\": {\"ms_octaves\": 9}}", OC_ESCENE, "optics.ms_octaves: 9 is out of range [1, 8]", NULL);
  expect_error("{\"optics\": {\"ms_a\": 1}}", OC_ESCENE, "optics.ms_a: 1 is out of range (0, 1)", NULL);
  expect_error("{\"optics\": {\"albedo\": 1.01}}", OC_ESCENE, "optics.albedo: 1.01 is out of range [0, 1]", NULL);
  expect_error("{\"optics\": {\"albedo\": -0.5}}", OC_ESCENE, "optics.albedo: -0.5 is out of range [0, 1]", NULL);
  expect_error("{\"optics\": {\"ms_b\": 0}}", OC_ESCENE, "optics.ms_b: 0 is out of range (0, 1)", NULL);
  expect_error("{\"optics\": {\"ms_c\": -2}}", OC_ESCENE, "optics.ms_c: -2 is out of range (0, 1)", NULL);
  expect_error("{\"optics\": {\"ms_a\": 1e999}}", OC_ESCENE, "optics.ms_a:", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 3000, \"radius\": 2000, \"sigma_t\": -0.1}]}", OC_ESCENE,
               "sources[0].sigma_t: -0.1 is out of range [0, 1e+09]", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 3000, \"radius\": 0, \"sigma_t\": 1}]}", OC_ESCENE,
               "sources[0].radius: 0 is out of range (0, 1000000]", NULL);
  expect_error("{\"sources\": [{\"type\": \"slab\", \"base\": 2000, \"top\": 1000, \"sigma_t\": 1}]}", OC_ESCENE,
               "sources[0].top: must be greater than base (2000)", NULL);
  expect_error("{\"sources\": [{\"type\": \"box\", \"alt\": 0, \"size\": [1, 0, 3], \"sigma_t\": 1}]}", OC_ESCENE,
               "sources[0].size[1]: 0 is out of range (0, 1000000]", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c_#.vdb\", \"sequence\": {\"count\": 0}}]}", OC_ESCENE,
               "sources[0].sequence.count: 0 is out of range [1, 1000000]", NULL);
  expect_error("{\"version\": 2}", OC_EVERSION, "version: unsupported version 2", NULL);
}

static void test_error_enum(void **state) {
  (void)state;
  expect_error("{\"sources\": [{\"type\": \"procedural\", \"preset\": \"foggy\"}]}", OC_ESCENE,
               "sources[0].preset: unknown preset \"foggy\"", "\"clear\", \"fair\", \"overcast\", \"storm\", \"cirrus\"",
               NULL);
  expect_error("{\"sources\": [{\"type\": \"sphre\"}]}", OC_ESCENE, "sources[0].type: unknown source type \"sphre\"",
               "\"sphere\"", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c_#.vdb\", \"sequence\": {\"count\": 2, \"end\": \"bounce\"}}]}",
               OC_ESCENE, "sources[0].sequence.end: unknown sequence end \"bounce\"", "\"loop\", \"hold\"", NULL);
}

static void test_error_missing_required(void **state) {
  (void)state;
  expect_error("{\"sources\": [{\"alt\": 1}]}", OC_ESCENE, "sources[0]: missing required key \"type\"", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 1, \"radius\": 1}]}", OC_ESCENE,
               "sources[0]: missing required key \"sigma_t\"", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\"}]}", OC_ESCENE, "sources[0]: missing required key \"file\"", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c_#.vdb\", \"sequence\": {}}]}", OC_ESCENE,
               "sources[0].sequence: missing required key \"count\"", NULL);
}

static void test_error_combinations(void **state) {
  (void)state;
  expect_error("{\"sun\": {\"direction\": [0, 0, 0]}}", OC_ESCENE, "t.json: sun.direction: must not be the zero vector", NULL);
  expect_error("{\"sun\": {\"direction\": [-0.0, 0, 0]}}", OC_ESCENE, "sun.direction: must not be the zero vector", NULL);
  expect_error("{\"sun\": {\"lat\": 1, \"direction\": [1, 0, 0]}}", OC_ESCENE, "sun: give either lat/lon", NULL);
  expect_error("{\"sun\": {\"direction\": [1, 0]}}", OC_ESCENE, "sun.direction: expected 3 numbers, got 2", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c.vdb\", \"grid\": \"d\", \"grid_index\": 0}]}", OC_ESCENE,
               "sources[0].grid_index: give grid (a name) or grid_index, not both", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c.vdb\", \"sequence\": {\"count\": 2}}]}", OC_ESCENE,
               "sources[0].file: a sequence needs exactly one run of '#'", NULL);
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"c#_#.vdb\", \"sequence\": {\"count\": 2}}]}", OC_ESCENE,
               "sources[0].file: a sequence needs exactly one run of '#'", NULL);
}

static void test_error_non_finite(void **state) {
  (void)state;
  expect_error("{\"seed\": 1e999}", OC_ESCENE, "t.json: seed: number is not finite", NULL);
  expect_error("{\"sources\": [{\"type\": \"sphere\", \"alt\": 1, \"radius\": 1, \"sigma_t\": -1e999}]}", OC_ESCENE,
               "sources[0].sigma_t: number is not finite", NULL);
  expect_error("{\"sun\": {\"direction\": [1, 1e400, 0]}}", OC_ESCENE, "sun.direction[1]: number is not finite", NULL);
  /* Not JSON at all: NaN and Infinity literals. */
  expect_error("{\"seed\": NaN}", OC_ESCENE, "t.json:1:10: JSON syntax error", NULL);
  expect_error("{\"seed\": -Infinity}", OC_ESCENE, "t.json:1:", "JSON syntax error", NULL);
}

static void test_error_syntax(void **state) {
  (void)state;
  /* Missing comma at the end of line 3: cJSON stops at the next key, line 4 column 3. */
  expect_error("{\n  \"seed\": 1,\n  \"name\": \"x\"\n  \"epoch_period\": 2\n}\n", OC_ESCENE,
               "t.json:4:3: JSON syntax error near '\"epoch_period\": 2'", NULL);
  expect_error("{\"seed\": 1,}", OC_ESCENE, "t.json:1:12: JSON syntax error", NULL);
  expect_error("{\"seed\": 1", OC_ESCENE, "t.json:1:", "JSON syntax error", NULL);
  expect_error("{} {}", OC_ESCENE, "t.json:1:4: unexpected content after the JSON value", NULL);
  expect_error("{}\n\n  x", OC_ESCENE, "t.json:3:3: unexpected content after the JSON value near 'x'", NULL);
  expect_error("", OC_ESCENE, "t.json: empty", NULL);
  expect_error(" \n\t ", OC_ESCENE, "t.json: empty", NULL);
  /* An embedded NUL is content, not the end of the text. */
  oc_scene_t s;
  char why[256];
  assert_int_equal(oc_scene_parse(&s, "{}\0{}", 5, "t.json", why, sizeof why), OC_ESCENE);
  assert_non_null(strstr(why, "t.json:1:3: unexpected content"));
  /* Deep nesting: cJSON's limit, reported as a syntax error, no stack overflow. */
  size_t depth = 5000;
  char *deep = malloc(2 * depth + 16);
  assert_non_null(deep);
  size_t n = (size_t)sprintf(deep, "{\"name\": ");
  for (size_t i = 0; i < depth; i++) deep[n++] = '[';
  for (size_t i = 0; i < depth; i++) deep[n++] = ']';
  deep[n++] = '}';
  assert_int_equal(oc_scene_parse(&s, deep, n, "t.json", why, sizeof why), OC_ESCENE);
  assert_non_null(strstr(why, "JSON syntax error"));
  free(deep);
}

static void test_error_too_many_sources(void **state) {
  (void)state;
  char *j = malloc(65 * 100 + 64);
  assert_non_null(j);
  for (int count = 64; count <= 65; count++) {
    size_t n = (size_t)sprintf(j, "{\"sources\": [");
    for (int i = 0; i < count; i++)
      n += (size_t)sprintf(j + n, "%s{\"type\": \"vdb\", \"file\": \"f%d.vdb\"}", i ? "," : "", i);
    sprintf(j + n, "]}");
    if (count == 64) {
      oc_scene_t s;
      char why[256];
      assert_int_equal(parse(&s, j, why, sizeof why), 0);
      assert_int_equal(s.nsources, 64);
      assert_string_equal(s.sources[63].vdb.file, "f63.vdb");
      oc_scene_free(&s);
    } else {
      expect_error(j, OC_ESCENE, "t.json: sources: 65 entries, at most 64 allowed", NULL);
    }
  }
  /* A failure after some vdb sources were parsed frees their strings (ASan would see a leak). */
  expect_error("{\"sources\": [{\"type\": \"vdb\", \"file\": \"a.vdb\"}, {\"type\": \"vdb\", \"file\": \"b.vdb\", \"x\": 1}]}",
               OC_ESCENE, "sources[1]: unknown key \"x\"", NULL);
  free(j);
}

/* ---- Files ---- */

static char g_tmp[256];

static void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static void test_files(void **state) {
  (void)state;
  oc_scene_t s;
  char why[512], path[512];
  /* Missing file. */
  snprintf(path, sizeof path, "%s/nope.json", g_tmp);
  memset(&s, 0x5A, sizeof s);
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, path));
  assert_non_null(strstr(why, "No such file"));
  assert_int_equal(s.nsources, 0);
  /* A directory. */
  assert_int_equal(oc_scene_load(&s, g_tmp, why, sizeof why), OC_EIO);
  assert_non_null(strstr(why, "not a regular file"));
  /* Over the size limit: refused from its size, unread (a sparse file). */
  snprintf(path, sizeof path, "%s/big.json", g_tmp);
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(ftruncate(fileno(f), (off_t)OC_SCENE_MAX_FILE_BYTES + 1), 0);
  fclose(f);
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), OC_ETOOBIG);
  assert_non_null(strstr(why, "big.json: larger than 16777216 bytes"));
  unlink(path);
  /* Exactly at the limit is read (and here fails as JSON, after the whitespace). */
  f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(ftruncate(fileno(f), (off_t)OC_SCENE_MAX_FILE_BYTES), 0);
  fputs("{}", f);
  fclose(f);
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), OC_ESCENE);
  unlink(path);
  /* Parse from memory over the limit. */
  assert_int_equal(oc_scene_parse(&s, "{}", (size_t)OC_SCENE_MAX_FILE_BYTES + 1, "m.json", why, sizeof why), OC_ETOOBIG);
  /* Syntax errors from a file carry the path and line:column. */
  snprintf(path, sizeof path, "%s/bad.json", g_tmp);
  write_file(path, "{\n  \"seed\": 1\n  \"name\": \"x\"\n}\n");
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), OC_ESCENE);
  char want[600];
  snprintf(want, sizeof want, "%s:3:3: JSON syntax error", path);
  if (!strstr(why, want)) fail_msg("%s lacks %s", why, want);
  unlink(path);
  /* Relative vdb paths resolve against the scene file's folder; absolute ones stay. */
  snprintf(path, sizeof path, "%s/v.json", g_tmp);
  write_file(path, "{\"sources\": [{\"type\": \"vdb\", \"file\": \"clouds/a.vdb\"},"
                   " {\"type\": \"vdb\", \"file\": \"/abs/b.vdb\"}]}");
  assert_int_equal(oc_scene_load(&s, path, why, sizeof why), 0);
  snprintf(want, sizeof want, "%s/clouds/a.vdb", g_tmp);
  assert_string_equal(s.sources[0].vdb.file, want);
  assert_string_equal(s.sources[1].vdb.file, "/abs/b.vdb");
  assert_string_equal(s.name, "v");
  oc_scene_free(&s);
  unlink(path);
  /* NULL arguments. */
  assert_int_equal(oc_scene_load(NULL, path, why, sizeof why), OC_EINVAL);
  assert_int_equal(oc_scene_load(&s, NULL, why, sizeof why), OC_EINVAL);
  assert_int_equal(oc_scene_parse(NULL, "{}", 2, "x", why, sizeof why), OC_EINVAL);
  assert_int_equal(oc_scene_parse(&s, NULL, 2, "x", why, sizeof why), OC_EINVAL);
  /* A small or absent message buffer is fine. */
  char tiny[8];
  assert_int_equal(oc_scene_parse(&s, "{\"seed\": -1}", 12, "t.json", tiny, sizeof tiny), OC_ESCENE);
  assert_int_equal(strlen(tiny), 7);
  assert_int_equal(oc_scene_parse(&s, "{\"seed\": -1}", 12, "t.json", NULL, 0), OC_ESCENE);
}

static void test_unterminated_buffer(void **state) {
  (void)state;
  /* The text need not be NUL-terminated: an exact-size heap copy lets ASan catch over-reads. */
  static const char *texts[] = {"{\"seed\": 12}", "{\"seed\": 12", "{\"name\": \"abc", "{\"seed\": 1e5", "  {  }  "};
  for (size_t i = 0; i < sizeof texts / sizeof *texts; i++) {
    size_t n = strlen(texts[i]);
    char *b = malloc(n);
    assert_non_null(b);
    memcpy(b, texts[i], n);
    oc_scene_t s;
    char why[256];
    int r = oc_scene_parse(&s, b, n, "u.json", why, sizeof why);
    assert_true(r == 0 || r == OC_ESCENE);
    if (i == 0) assert_true(r == 0 && s.seed == 12);
    oc_scene_free(&s);
    free(b);
  }
}

static void test_names(void **state) {
  (void)state;
  assert_string_equal(oc_scene_feature_name(OC_FEATURE_ANIMATION), "animation");
  assert_string_equal(oc_scene_feature_name(OC_FEATURE_MULTIPLE_SCATTERING), "multiple_scattering");
  assert_string_equal(oc_scene_feature_name(OC_FEATURE_PLANET_SURFACE), "planet_surface");
  assert_null(oc_scene_feature_name(-1));
  assert_null(oc_scene_feature_name(OC_FEATURE_COUNT));
  assert_string_equal(oc_scene_source_type_name(OC_SOURCE_SLAB), "slab");
  assert_null(oc_scene_source_type_name(0));
  assert_string_equal(oc_scene_preset_name(OC_PRESET_STORM), "storm");
  assert_null(oc_scene_preset_name(OC_PRESET_COUNT));
  assert_int_equal(oc_scene_preset_parse("overcast"), OC_PRESET_OVERCAST);
  assert_int_equal(oc_scene_preset_parse("Overcast"), OC_EINVAL);
  assert_int_equal(oc_scene_preset_parse(NULL), OC_EINVAL);
}

static int setup(void **state) {
  (void)state;
  const char *src = getenv("OC_SOURCE_DIR");
  snprintf(g_src, sizeof g_src, "%s", src ? src : ".");
  snprintf(g_tmp, sizeof g_tmp, "/tmp/oc_test_scene_XXXXXX");
  if (!mkdtemp(g_tmp)) return -1;
  oc_log_set_level(OC_LOG_WARN);
  return 0;
}

static int teardown(void **state) {
  (void)state;
  rmdir(g_tmp);
  return 0;
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_all_shipped_scenes_load),
             cmocka_unit_test(test_planet_is_default),
             cmocka_unit_test(test_analytic_scenes),
             cmocka_unit_test(test_defaults),
             cmocka_unit_test(test_values),
             cmocka_unit_test(test_error_unknown_key),
             cmocka_unit_test(test_error_duplicate_key),
             cmocka_unit_test(test_error_wrong_type),
             cmocka_unit_test(test_error_out_of_range),
             cmocka_unit_test(test_error_enum),
             cmocka_unit_test(test_error_missing_required),
             cmocka_unit_test(test_error_combinations),
             cmocka_unit_test(test_error_non_finite),
             cmocka_unit_test(test_error_syntax),
             cmocka_unit_test(test_error_too_many_sources),
             cmocka_unit_test(test_files),
             cmocka_unit_test(test_unterminated_buffer),
             cmocka_unit_test(test_names))
