/* test_vdb.c — VDB import through the OpenVDB shim: files built here through the shim's writer
 * (a fog sphere with known values, tiles, every kind of bad input), the shared Disney cloud,
 * sampling against analytic values, mass between levels, placement, sequences, inspect, export.
 *
 * The first test runs before anything loads the shim: an analytic field must not map OpenVDB. */
#include <cjson/cJSON.h>
#include <dirent.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "test_main.h"
#include "test_util.h"

#include "oc_err.h"
#include "oc_key.h"
#include "oc_planet.h"
#include "oc_scene.h"
#include "voxelize.h"
#include "ocs_field.h"
#include "report.h"
#include "vdb_shim.h"
#include "vdb_tools.h"
#include "server/filter_check.h"

static char g_dir[256];
static const ocs_vdb_api_t *g_api;

static const ocs_vdb_api_t *api(void) {
  if (!g_api) {
    char why[4096];
    if (ocs_vdb_load(&g_api, why, sizeof why) < 0) fail_msg("%s", why);
  }
  return g_api;
}

static void tmp_path(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", g_dir, name); }

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ---- Files built through the shim ------------------------------------------------------------- */

/* The fog sphere: value peak·(1 - r²/R²) inside radius R (index units) around `centre`. */
static double profile(double r, double R) { return r < R ? 1.0 - r * r / (R * R) : 0.0; }

typedef struct {
  const char *name; /* default "density" */
  int type;         /* default float */
  int klass;        /* default fog volume */
  int half;
  double voxel;     /* default 1 */
  int affine;
  double i2w[3][4];
  int R;            /* radius in voxels */
  double peak;      /* default 1 */
  int32_t centre[3];
} sphere_t;

static ocs_vdb_writer_t *new_writer(void) {
  ocs_vdb_writer_t *w;
  assert_int_equal(api()->writer_create(&w), 0);
  return w;
}

/* Adds an empty grid; @return its index. */
static int add_grid(ocs_vdb_writer_t *w, const ocs_vdb_grid_desc_t *d) {
  char why[512];
  int g = api()->writer_add_grid(w, d, why, sizeof why);
  if (g < 0) fail_msg("add_grid: %s", why);
  return g;
}

/* Adds an empty fog grid "density" with voxel_size (the file's transform). */
static int add_density(ocs_vdb_writer_t *w, double voxel_size) {
  ocs_vdb_grid_desc_t d = {.name = "density", .klass = OCS_VDB_CLASS_FOG, .voxel_size = voxel_size};
  return add_grid(w, &d);
}

/* A VDB file being written at a temporary path: a writer holding one empty fog grid "density"
 * of 1 m voxels, index g. */
typedef struct {
  char path[512];
  ocs_vdb_writer_t *w;
  int g;
} density_file_t;

static density_file_t density_file(const char *name) {
  density_file_t f;
  tmp_path(f.path, sizeof f.path, name);
  f.w = new_writer();
  f.g = add_density(f.w, 1.0);
  return f;
}

static void set_voxel(ocs_vdb_writer_t *w, int g, int32_t i, int32_t j, int32_t k, float value) {
  int32_t o[3] = {i, j, k}, one[3] = {1, 1, 1};
  assert_int_equal(api()->writer_set_values(w, g, o, one, &value), 0);
}

static int add_sphere(ocs_vdb_writer_t *w, const sphere_t *sp) {
  ocs_vdb_grid_desc_t d = {.name = sp->name ? sp->name : "density",
                           .type = sp->type,
                           .klass = sp->klass ? sp->klass : OCS_VDB_CLASS_FOG,
                           .half = sp->half,
                           .voxel_size = sp->voxel != 0.0 ? sp->voxel : 1.0,
                           .affine = sp->affine};
  memcpy(d.i2w, sp->i2w, sizeof d.i2w);
  int g = add_grid(w, &d);
  int R = sp->R, n = 2 * R + 1;
  double peak = sp->peak != 0.0 ? sp->peak : 1.0;
  float *v = malloc(sizeof(float) * (size_t)n * n * n);
  assert_non_null(v);
  for (int k = 0; k < n; k++)
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++)
        v[i + n * (j + n * k)] = (float)(peak * profile(sqrt((double)((i - R) * (i - R) + (j - R) * (j - R) + (k - R) * (k - R))), R));
  int32_t origin[3] = {sp->centre[0] - R, sp->centre[1] - R, sp->centre[2] - R}, dims[3] = {n, n, n};
  assert_int_equal(api()->writer_set_values(w, g, origin, dims, v), 0);
  free(v);
  return g;
}

static void save(ocs_vdb_writer_t *w, const char *path, int compression) {
  char why[512];
  int r = api()->writer_save(w, path, compression, why, sizeof why);
  if (r < 0) fail_msg("save %s: %s", path, why);
  api()->writer_free(w);
}

static void write_sphere(const char *path, const sphere_t *sp, int compression) {
  ocs_vdb_writer_t *w = new_writer();
  add_sphere(w, sp);
  save(w, path, compression);
}

static oc_source_t vdb_desc(const char *file, double lat, double lon, double alt, double scale_m, double sigma) {
  oc_source_t d;
  memset(&d, 0, sizeof d);
  d.type = OC_SOURCE_VDB;
  d.vdb.file = (char *)file;
  snprintf(d.vdb.grid, sizeof d.vdb.grid, "density");
  d.vdb.grid_index = -1;
  d.vdb.anchor = (oc_geo_t){lat, lon, alt};
  d.vdb.scale_m = scale_m;
  d.vdb.sigma_scale = sigma;
  return d;
}

static ocs_source_t *must_create(const oc_source_t *d) {
  ocs_source_t *s = NULL;
  char why[2048];
  int r = ocs_source_vdb_create(&s, d, why, sizeof why);
  if (r < 0) fail_msg("vdb create (%s): %s", oc_err_name(r), why);
  return s;
}

/* Creation must fail with `err` and a message naming the file and containing `needle`. */
static void expect_fail(const oc_source_t *d, int err, const char *needle) {
  ocs_source_t *s = NULL;
  char why[2048] = "";
  int r = ocs_source_vdb_create(&s, d, why, sizeof why);
  if (r != err) fail_msg("expected %s, got %d (%s): %s", oc_err_name(err), r, r < 0 ? oc_err_name(r) : "ok", why);
  assert_null(s);
  if (!strstr(why, d->vdb.file)) fail_msg("message does not name the file: %s", why);
  if (!strstr(why, needle)) fail_msg("message lacks \"%s\": %s", needle, why);
  print_message("    error as reported: %s\n", why);
}

/* The file at path, placed at (0, 0, 1000 m) with 10 m voxels, is refused with `err` and a message
 * containing `needle`. */
static void expect_file_fails(const char *path, int err, const char *needle) {
  oc_source_t d = vdb_desc(path, 0, 0, 1000, 10, 1);
  expect_fail(&d, err, needle);
}

static void sample(const ocs_source_t *s, oc_key_t key, double t, float out[512]) {
  memset(out, 0, sizeof(float) * 512);
  assert_int_equal(s->vt->sample(s, key, t, out), 0);
}

/* The mass (σt·m³ at t = 0) of the (2 span + 1)³ nodes at `level` around the one holding p: each
 * node's trapezoid mean × its volume (faces are shared, so interior weights count once). */
static double block_mass(const ocs_source_t *s, int level, oc_dvec3 p, int span) {
  double mass = 0.0, size = oc_key_size(level);
  uint32_t ix, iy, iz;
  oc_key_coords(oc_key_from_point(level, p), &ix, &iy, &iz);
  for (int dz = -span; dz <= span; dz++)
    for (int dy = -span; dy <= span; dy++)
      for (int dx = -span; dx <= span; dx++) {
        float v[512];
        sample(s, oc_key_make(level, ix + dx, iy + dy, iz + dz), 0.0, v);
        mass += oc_test_node_mean(v) * size * size * size;
      }
  return mass;
}

/* `what`'s mass within 1 % of `expect`. */
static void check_mass(const char *what, double mass, double expect) {
  print_message("    %s: mass %.6g vs %.6g (%.2e)\n", what, mass, expect, fabs(mass - expect) / expect);
  assert_true(fabs(mass - expect) / expect < 0.01);
}

/* ---- Placement as the scene defines it (written independently of source_vdb.c) ---------------- */

typedef struct {
  oc_dvec3 A;
  oc_enu_t enu;
  double heading;  /* degrees */
  double R[3][3], t[3]; /* index → grid world */
  double w_anchor[3];
} place_t;

static place_t place_of(const ocs_source_t *s, double heading, double scale_m) {
  ocs_vdb_source_info_t in;
  assert_int_equal(ocs_vdb_source_info(s, &in), 0);
  place_t p;
  memset(&p, 0, sizeof p);
  p.A = in.anchor;
  p.enu = oc_enu_at(p.A);
  p.heading = heading;
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) p.R[r][c] = scale_m > 0 ? (r == c ? scale_m : 0.0) : in.grid.i2w[r][c];
    p.t[r] = scale_m > 0 ? 0.0 : in.grid.i2w[r][3];
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int c = 0; c < 8; c++) {
    double ix[3];
    for (int a = 0; a < 3; a++) ix[a] = (c >> a) & 1 ? in.grid.bbox_max[a] + 0.5 : in.grid.bbox_min[a] - 0.5;
    for (int r = 0; r < 3; r++) {
      double w = p.R[r][0] * ix[0] + p.R[r][1] * ix[1] + p.R[r][2] * ix[2] + p.t[r];
      lo[r] = fmin(lo[r], w);
      hi[r] = fmax(hi[r], w);
    }
  }
  p.w_anchor[0] = 0.5 * (lo[0] + hi[0]);
  p.w_anchor[1] = lo[1];
  p.w_anchor[2] = 0.5 * (lo[2] + hi[2]);
  return p;
}

/* Grid world (Y-up) → planet: east = x, up = y, north = -z, then turned clockwise by heading. */
static oc_dvec3 world_to_planet(const place_t *p, const double w[3]) {
  double e0 = w[0] - p->w_anchor[0], u = w[1] - p->w_anchor[1], n0 = -(w[2] - p->w_anchor[2]);
  double h = p->heading * OC_DEG;
  double e = e0 * cos(h) + n0 * sin(h), n = -e0 * sin(h) + n0 * cos(h);
  oc_dvec3 q = oc_dmad(p->A, p->enu.east, e);
  q = oc_dmad(q, p->enu.north, n);
  return oc_dmad(q, p->enu.up, u);
}

static oc_dvec3 index_to_planet(const place_t *p, const double i[3]) {
  double w[3];
  for (int r = 0; r < 3; r++) w[r] = p->R[r][0] * i[0] + p->R[r][1] * i[1] + p->R[r][2] * i[2] + p->t[r];
  return world_to_planet(p, w);
}

/* A source at t = 0 as a filter_check.h source. */
static void source_sample0(const void *s, oc_key_t key, float out[512]) { sample(s, key, 0.0, out); }
static double source_point0(const void *s, oc_dvec3 p) {
  const ocs_source_t *src = s;
  return src->vt->point(src, p, 0.0);
}

/* ---- 1. No OpenVDB for analytic scenes (runs first: nothing has loaded the shim yet) --------- */

static int maps_has(const char *needle) {
  FILE *f = fopen("/proc/self/maps", "r");
  assert_non_null(f);
  char line[1024];
  int found = 0;
  while (fgets(line, sizeof line, f))
    if (strstr(line, needle)) found = 1;
  fclose(f);
  return found;
}

static void test_vdb__analytic_field_maps_no_openvdb(void **st) {
  (void)st;
  const char *json = "{\"sources\": [{\"type\": \"sphere\", \"lat\": 10, \"lon\": 20, \"alt\": 3000, \"radius\": 2000, "
                     "\"sigma_t\": 0.05}], \"features\": {\"animation\": false}}";
  oc_scene_t sc;
  char why[512];
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "analytic.json", why, sizeof why), 0);
  ocs_field_t *f = NULL;
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) fail_msg("%s", why);
  float s[512];
  assert_int_equal(ocs_field_sample(f, oc_key_from_point(12, oc_geo_to_xyz((oc_geo_t){10, 20, 3000})), 0.0, s), 0);
  assert_false(maps_has("libopenvdb"));
  assert_false(maps_has("libtbb"));
  assert_false(maps_has("libboost"));
  assert_false(maps_has(OCS_VDB_SHIM_NAME));
  ocs_field_free(f);
  oc_scene_free(&sc);
  /* ... and the first VDB use maps them. */
  double t0 = now_s();
  api();
  print_message("    loading the shim (dlopen of OpenVDB, TBB, Boost, blosc; openvdb::initialize): %.3f s\n", now_s() - t0);
  assert_true(maps_has(OCS_VDB_SHIM_NAME));
  assert_true(maps_has("libopenvdb"));
}

/* ---- 2. Reading ----------------------------------------------------------------------------------- */

static const char *disney_path(void) {
  static char p[1024];
  const char *shared = getenv("OC_SHARED_DIR");
  snprintf(p, sizeof p, "%s/data/wdas_cloud_sixteenth.vdb", shared ? shared : "../shared");
  return p;
}

typedef struct {
  uint64_t last, total, calls;
  int monotonic;
} progress_t;

static void on_progress(void *ctx, uint64_t done, uint64_t total) {
  progress_t *p = ctx;
  if (done < p->last) p->monotonic = 0;
  p->last = done;
  p->total = total;
  p->calls++;
}

static void test_vdb__shim_reads_disney_with_progress(void **st) {
  (void)st;
  const ocs_vdb_api_t *a = api();
  assert_non_null(strstr(a->version(), "OpenVDB"));
  progress_t pr = {0, 0, 0, 1};
  ocs_vdb_file_t *f = NULL;
  char why[512];
  double t0 = now_s();
  int r = a->open(disney_path(), on_progress, &pr, &f, why, sizeof why);
  if (r < 0) fail_msg("%s: %s", disney_path(), why);
  double t_read = now_s() - t0;
  /* The progress callback: monotonic, reaching the whole file. */
  assert_true(pr.calls >= 2);
  assert_true(pr.monotonic);
  assert_int_equal(pr.last, pr.total);
  assert_int_equal(pr.total, 1631620);
  assert_int_equal(a->grid_count(f), 1);
  ocs_vdb_grid_info_t gi;
  assert_int_equal(a->grid_info(f, 0, 1, &gi), 0);
  assert_string_equal(gi.name, "density");
  assert_int_equal(gi.type, OCS_VDB_TYPE_FLOAT);
  assert_int_equal(gi.klass, OCS_VDB_CLASS_FOG);
  assert_int_equal(gi.active_voxels, 415642);
  assert_int_equal(gi.active_tiles, 130);
  int32_t bmin[3] = {-66, -21, -90}, bmax[3] = {59, 64, 63};
  for (int i = 0; i < 3; i++) {
    assert_int_equal(gi.bbox_min[i], bmin[i]);
    assert_int_equal(gi.bbox_max[i], bmax[i]);
    assert_true(fabs(gi.voxel_size[i] - 3.3333) < 1e-4);
  }
  assert_true(gi.has_range);
  assert_true(gi.vmin == 0.0 && gi.vmax == 1.0);
  assert_int_equal(gi.nan + gi.inf + gi.negative, 0);
  ocs_vdb_grid_t *g = NULL;
  ocs_vdb_prep_stats_t ps;
  assert_int_equal(a->grid_prepare(f, 0, &g, &ps, why, sizeof why), 0);
  print_message("    Disney 1/16: read %.3f s, prepare %.3f s (%d pyramid levels, %.1f MB)\n", t_read, ps.seconds, ps.levels,
                (double)ps.bytes / 1e6);
  assert_true(ps.levels >= 7);
  /* grid_range over everything: [0, 1]; far away: [0, 0] */
  int32_t lo[3] = {-1000, -1000, -1000}, hi[3] = {1000, 1000, 1000}, flo[3] = {500, 500, 500}, fhi[3] = {600, 600, 600};
  float mn, mx;
  a->grid_range(g, lo, hi, &mn, &mx);
  assert_true(mn == 0.0f && mx == 1.0f);
  a->grid_range(g, flo, fhi, &mn, &mx);
  assert_true(mn == 0.0f && mx == 0.0f);
  a->grid_free(g);
  a->close(f);
}

static void test_vdb__inspect_text_and_json(void **st) {
  (void)st;
  char *buf = NULL, why[1024];
  size_t len = 0;
  FILE *m = open_memstream(&buf, &len);
  assert_int_equal(ocs_vdb_inspect(disney_path(), 0, m, why, sizeof why), 0);
  fclose(m);
  assert_non_null(strstr(buf, "'density'"));
  assert_non_null(strstr(buf, "fog volume"));
  assert_non_null(strstr(buf, "415642 voxels (130 constant tiles"));
  assert_non_null(strstr(buf, "(-66, -21, -90) .. (59, 64, 63)"));
  assert_non_null(strstr(buf, "3.33333 x 3.33333 x 3.33333"));
  assert_non_null(strstr(buf, "values      0 .. 1"));
  free(buf);
  m = open_memstream(&buf, &len);
  assert_int_equal(ocs_vdb_inspect(disney_path(), 1, m, why, sizeof why), 0);
  fclose(m);
  cJSON *j = cJSON_Parse(buf);
  assert_non_null(j);
  const cJSON *g = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "grids"), 0);
  assert_string_equal(cJSON_GetObjectItem(g, "name")->valuestring, "density");
  assert_string_equal(cJSON_GetObjectItem(g, "class")->valuestring, "fog volume");
  assert_true(cJSON_GetObjectItem(g, "active_voxels")->valuedouble == 415642);
  assert_true(cJSON_GetObjectItem(g, "active_tiles")->valuedouble == 130);
  assert_true(cJSON_GetArrayItem(cJSON_GetObjectItem(g, "bbox_min"), 2)->valuedouble == -90);
  assert_true(cJSON_GetObjectItem(g, "value_max")->valuedouble == 1.0);
  cJSON_Delete(j);
  free(buf);
  /* Errors name the file. */
  assert_int_equal(ocs_vdb_inspect("/nonexistent/x.vdb", 0, stdout, why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, "/nonexistent/x.vdb"));
}

/* ---- 3. Sampling a fog sphere ---------------------------------------------------------------- */

/* The sphere R = 12 voxels of 20 m (240 m radius) at 30°N 40°E, base at 1500 m, σt peak 0.1. */
#define SPH_R 12
#define SPH_S 20.0
#define SPH_SIGMA 0.1

static ocs_source_t *sphere_source(const char *file, double heading, place_t *p) {
  oc_source_t d = vdb_desc(file, 30.0, 40.0, 1500.0, SPH_S, SPH_SIGMA);
  d.vdb.heading = heading;
  ocs_source_t *s = must_create(&d);
  if (p) *p = place_of(s, heading, SPH_S);
  return s;
}

static oc_dvec3 sphere_centre(const place_t *p) {
  double c[3] = {0, 0, 0};
  return index_to_planet(p, c);
}

/* The sphere as the first sampling test writes it (sphere.vdb), opened with `heading`; *p its
 * placement, *c its centre. */
static ocs_source_t *open_sphere(double heading, place_t *p, oc_dvec3 *c) {
  char path[512];
  tmp_path(path, sizeof path, "sphere.vdb");
  ocs_source_t *s = sphere_source(path, heading, p);
  *c = sphere_centre(p);
  return s;
}

/* σt of the continuous sphere at a planet point. */
static double sphere_sigma(oc_dvec3 c, oc_dvec3 q) { return SPH_SIGMA * profile(oc_dlen(oc_dsub(q, c)) / SPH_S, SPH_R); }

static void test_vdb__fog_sphere_fine_levels_match_analytic(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "sphere.vdb");
  sphere_t sp = {.R = SPH_R};
  write_sphere(path, &sp, OCS_VDB_COMPRESS_DEFAULT);
  place_t p;
  oc_dvec3 c;
  ocs_source_t *s = open_sphere(0.0, &p, &c);
  /* Level 17 (spacing 14 m) and 18 (7 m): footprints below a voxel: trilinear samples. */
  double worst = 0.0;
  int compared = 0;
  for (int level = 17; level <= 18; level++) {
    for (int q = 0; q < 6; q++) {
      oc_dvec3 at = oc_dmad(c, p.enu.east, (q - 3) * 37.0);
      at = oc_dmad(at, p.enu.up, (q % 3 - 1) * 51.0);
      oc_key_t key = oc_key_from_point(level, at);
      float v[512];
      sample(s, key, 0.0, v);
      for (int k = 0; k < 8; k++)
        for (int j = 0; j < 8; j++)
          for (int i = 0; i < 8; i++) {
            oc_dvec3 x = ocs_brick_sample_pos(key, i, j, k);
            if (oc_dlen(oc_dsub(x, c)) > (SPH_R - 1.5) * SPH_S) continue; /* the kink at r = R */
            double e = fabs(v[i + 8 * j + 64 * k] - sphere_sigma(c, x)) / SPH_SIGMA;
            worst = fmax(worst, e);
            compared++;
            /* point() is the same reconstruction */
            double pt = s->vt->point(s, x, 0.0);
            assert_true(fabs(pt - v[i + 8 * j + 64 * k]) <= 1e-6 * SPH_SIGMA);
          }
    }
  }
  print_message("    fine levels: %d samples, worst |error| %.4f of the peak (trilinear bound 0.75/R^2 = %.4f)\n", compared,
                worst, 0.75 / (SPH_R * SPH_R));
  oc_report("vdb", "fog sphere, fine levels vs analytic (fraction of peak)", worst, 0.01, "");
  assert_true(compared > 1000);
  assert_true(worst < 0.01);
  s->vt->destroy(s);
}

/* Box average of the continuous sphere over the cube of edge e centred on x (24³ midpoints). */
static double sphere_box(oc_dvec3 c, oc_dvec3 x, double e) {
  const int n = 24;
  double sum = 0.0;
  for (int k = 0; k < n; k++)
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++) {
        oc_dvec3 q = oc_dv3(x.x + ((i + 0.5) / n - 0.5) * e, x.y + ((j + 0.5) / n - 0.5) * e, x.z + ((k + 0.5) / n - 0.5) * e);
        sum += sphere_sigma(c, q);
      }
  return sum / (n * n * n);
}

static void test_vdb__fog_sphere_coarse_levels_box_average(void **st) {
  (void)st;
  place_t p;
  oc_dvec3 c;
  ocs_source_t *s = open_sphere(0.0, &p, &c);
  /* Level 12..15: footprints of 452, 226, 113, 56 m against 20 m voxels (a 480 m sphere). Per
   * sample: the box average of the continuous sphere (24³ quadrature); per node: the samples'
   * plain mean against the true mean over the extended cube, and the node's mean against its 8
   * and 64 descendants' (tests/server/test_field.c's measures), all relative to the node's peak. */
  double worst_s = 0.0, worst_m = 0.0, worst_d = 0.0;
  for (int level = 12; level <= 15; level++) {
    oc_key_t key = oc_key_from_point(level, c);
    float v[512];
    sample(s, key, 0.0, v);
    double size = oc_key_size(level), worst = 0.0, sum = 0.0, tsum = 0.0, peak = 0.0;
    for (int k = 0; k < 8; k++)
      for (int j = 0; j < 8; j++)
        for (int i = 0; i < 8; i++) {
          oc_dvec3 x = ocs_brick_sample_pos(key, i, j, k);
          double truth = sphere_box(c, x, size / 7.0), got = v[i + 8 * j + 64 * k];
          worst = fmax(worst, fabs(got - truth));
          sum += got / 512.0;
          tsum += truth / 512.0;
          peak = fmax(peak, got);
        }
    filter_src_t src = {s, source_sample0, source_point0};
    double m0 = oc_test_node_mean(v), m1 = filter_descendants_mean(&src, key, 1), m2 = filter_descendants_mean(&src, key, 2);
    double em = fabs(sum - tsum) / peak, ed = fmax(fabs(m1 - m0), fabs(m2 - m0)) / peak;
    print_message("    level %d (footprint %.0f m): worst |sample - box average| %.2e, samples' mean vs true %.2e, node mean vs "
                  "8/64 descendants %.2e %.2e (of peak %.4f)\n", level, size / 7.0, worst / peak, em, fabs(m1 - m0) / peak,
                  fabs(m2 - m0) / peak, peak);
    worst_s = fmax(worst_s, worst / peak);
    worst_m = fmax(worst_m, em);
    worst_d = fmax(worst_d, ed);
  }
  oc_report("filtering", "VDB fog sphere: samples vs analytic box average, levels 12-15", worst_s, 0.05, "of peak");
  oc_report("filtering", "VDB fog sphere: samples' mean vs true mean, levels 12-15", worst_m, 5e-3, "of peak");
  oc_report("filtering", "VDB fog sphere: parent mean vs 8 and 64 descendants, levels 12-15", worst_d, 1e-2, "of peak");
  assert_true(worst_s < 0.05);
  assert_true(worst_m < 5e-3);
  assert_true(worst_d < 1e-2);
  s->vt->destroy(s);
}

/* The same sphere written uncompressed, zip, blosc and as half floats samples the same. */
static void test_vdb__compression_and_half_variants(void **st) {
  (void)st;
  const struct {
    const char *file;
    int comp, half;
  } v[] = {{"s_none.vdb", OCS_VDB_COMPRESS_NONE, 0},
           {"s_zip.vdb", OCS_VDB_COMPRESS_ZIP, 0},
           {"s_blosc.vdb", OCS_VDB_COMPRESS_BLOSC, 0},
           {"s_half_zip.vdb", OCS_VDB_COMPRESS_ZIP, 1},
           {"s_half_blosc.vdb", OCS_VDB_COMPRESS_BLOSC, 1}};
  float ref[2][512];
  for (size_t f = 0; f < sizeof v / sizeof v[0]; f++) {
    char path[512];
    tmp_path(path, sizeof path, v[f].file);
    sphere_t sp = {.R = SPH_R, .half = v[f].half};
    write_sphere(path, &sp, v[f].comp);
    place_t p;
    ocs_source_t *s = sphere_source(path, 0.0, &p);
    ocs_vdb_source_info_t in;
    assert_int_equal(ocs_vdb_source_info(s, &in), 0);
    assert_int_equal(in.grid.half, v[f].half);
    oc_dvec3 c = sphere_centre(&p);
    for (int q = 0; q < 2; q++) {
      float out[512];
      sample(s, oc_key_from_point(q ? 17 : 13, c), 0.0, out);
      if (f == 0) {
        memcpy(ref[q], out, sizeof out);
        continue;
      }
      double worst = 0.0;
      for (int i = 0; i < 512; i++) worst = fmax(worst, fabs(out[i] - ref[q][i]));
      /* half floats: 11-bit significand, relative error ≤ 2^-11 of values ≤ 1 */
      double tol = v[f].half ? SPH_SIGMA / 2048.0 : 0.0;
      if (worst > tol) fail_msg("%s level %d: differs by %g (tolerance %g)", v[f].file, q ? 17 : 13, worst, tol);
    }
    s->vt->destroy(s);
  }
}

/* Constant tiles: a 128³ tile (upper internal node) and an 8³ tile (lower internal node), no leaves. */
static void test_vdb__constant_tiles(void **st) {
  (void)st;
  density_file_t f = density_file("tiles.vdb");
  int32_t lo[3] = {0, 0, 0}, hi[3] = {127, 127, 127}, lo2[3] = {128, 0, 0}, hi2[3] = {135, 7, 7};
  assert_int_equal(api()->writer_fill(f.w, f.g, lo, hi, 0.5f), 0);
  assert_int_equal(api()->writer_fill(f.w, f.g, lo2, hi2, 1.0f), 0);
  save(f.w, f.path, OCS_VDB_COMPRESS_DEFAULT);
  /* 10 m voxels: a 1280 m cube; σt = value × 0.1 */
  oc_source_t desc = vdb_desc(f.path, -20.0, 100.0, 2000.0, 10.0, 0.1);
  ocs_source_t *s = must_create(&desc);
  ocs_vdb_source_info_t in;
  assert_int_equal(ocs_vdb_source_info(s, &in), 0);
  assert_int_equal(in.grid.active_tiles, 2);
  assert_int_equal(in.grid.leaf_nodes, 0);
  assert_int_equal(in.grid.active_voxels, 128 * 128 * 128 + 512);
  place_t p = place_of(s, 0.0, 10.0);
  /* Inside the big tile: every level whose node and footprint fit gives exactly 0.05, and the
   * bound says uniform (level 15: a 395 m node around the centre of the 1280 m cube). */
  double mid[3] = {63.5, 63.5, 63.5};
  oc_dvec3 c = index_to_planet(&p, mid);
  for (int level = 15; level <= 19; level++) {
    oc_key_t key = oc_key_from_point(level, c);
    float v[512], mn, mx;
    oc_dvec3 o;
    double size, gr;
    oc_key_bounds(key, &o, &size);
    gr = size / 14.0;
    s->vt->bound(s, oc_dv3(o.x - gr, o.y - gr, o.z - gr), oc_dv3(o.x + size + gr, o.y + size + gr, o.z + size + gr), 0.0, &mn, &mx);
    sample(s, key, 0.0, v);
    for (int i = 0; i < 512; i++) assert_true(fabsf(v[i] - 0.05f) < 1e-7f);
    assert_true(mn == mx && fabsf(mx - 0.05f) < 1e-7f);
  }
  /* The small tile (a reader that visits only leaves would see nothing there). */
  double small[3] = {131.5, 3.5, 3.5};
  assert_true(fabs(s->vt->point(s, index_to_planet(&p, small), 0.0) - 0.1) < 1e-7);
  /* The 3³ level-12 nodes around the cube's centre (it may straddle node faces) hold it whole:
   * mass = 0.5·128³ + 1·8³ voxels of 1000 m³, × 0.1. */
  check_mass("tiles, level-12 nodes", block_mass(s, 12, c, 1), 0.1 * (0.5 * 128 * 128 * 128 + 512) * 1000.0);
  s->vt->destroy(s);
}

/* A blob on the grid's +x, +y and -z sides ends up east, above and north; heading 90 turns east
 * into south. */
static void test_vdb__placement_orientation_and_heading(void **st) {
  (void)st;
  /* single voxels: 1 at index (0,0,0), 2 at (20,0,0), 3 at (0,20,0) and at (0,0,-20) */
  density_file_t f = density_file("blobs.vdb");
  set_voxel(f.w, f.g, 0, 0, 0, 1.0f);
  set_voxel(f.w, f.g, 20, 0, 0, 2.0f);
  set_voxel(f.w, f.g, 0, 20, 0, 3.0f);
  set_voxel(f.w, f.g, 0, 0, -20, 3.0f);
  save(f.w, f.path, OCS_VDB_COMPRESS_DEFAULT);
  for (int hi = 0; hi < 2; hi++) {
    double heading = hi ? 90.0 : 0.0;
    oc_source_t desc = vdb_desc(f.path, 45.0, -70.0, 500.0, 10.0, 1.0);
    desc.vdb.heading = heading;
    ocs_source_t *s = must_create(&desc);
    place_t p = place_of(s, heading, 10.0);
    oc_enu_t enu = p.enu;
    /* heading 90 turns the grid's east (+x) to the south and its north (-z) to the east */
    oc_dvec3 east = hi ? oc_dscale(enu.north, -1.0) : enu.east, north = hi ? enu.east : enu.north;
    double i0[3] = {0, 0, 0}, ix[3] = {20, 0, 0}, iy[3] = {0, 20, 0}, iz[3] = {0, 0, -20};
    oc_dvec3 P0 = index_to_planet(&p, i0), Px = index_to_planet(&p, ix), Py = index_to_planet(&p, iy), Pz = index_to_planet(&p, iz);
    assert_true(oc_dlen(oc_dsub(oc_dsub(Px, P0), oc_dscale(east, 200.0))) < 1e-6);
    assert_true(oc_dlen(oc_dsub(oc_dsub(Py, P0), oc_dscale(enu.up, 200.0))) < 1e-6);
    assert_true(oc_dlen(oc_dsub(oc_dsub(Pz, P0), oc_dscale(north, 200.0))) < 1e-6);
    assert_true(fabs(s->vt->point(s, P0, 0.0) - 1.0) < 1e-6);
    assert_true(fabs(s->vt->point(s, Px, 0.0) - 2.0) < 1e-6);
    assert_true(fabs(s->vt->point(s, Py, 0.0) - 3.0) < 1e-6);
    assert_true(fabs(s->vt->point(s, Pz, 0.0) - 3.0) < 1e-6);
    assert_true(s->vt->point(s, oc_dmad(P0, east, -200.0), 0.0) == 0.0);
    /* the bottom face (half a voxel below the lowest voxel centres) is at the anchor's altitude
     * (plus the tangent plane's rise over the sphere 141 m away: d²/2R = 1.6 mm) */
    oc_geo_t gb = oc_xyz_to_geo(oc_dmad(P0, enu.up, -5.0));
    assert_true(fabs(gb.alt - 500.0 - 141.42 * 141.42 / (2.0 * OC_PLANET_RADIUS)) < 1e-4);
    /* and the centre of the bottom face is the anchor itself */
    ocs_vdb_source_info_t in;
    assert_int_equal(ocs_vdb_source_info(s, &in), 0);
    oc_dvec3 bc = oc_dmad(oc_dmad(oc_dmad(P0, enu.up, -5.0), east, 100.0), north, 100.0);
    assert_true(oc_dlen(oc_dsub(bc, in.anchor)) < 1e-6);
    s->vt->destroy(s);
  }
}

/* A rotated, non-uniform transform in the file (scale_m 0): samples follow the file's own frame. */
static void test_vdb__rotated_nonuniform_transform(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "rotated.vdb");
  /* R = rotation of 30° about y times diag(8, 12, 16) m, translated. */
  double a = 30.0 * OC_DEG, sc[3] = {8.0, 12.0, 16.0}, rot[3][3] = {{cos(a), 0, sin(a)}, {0, 1, 0}, {-sin(a), 0, cos(a)}};
  sphere_t sp = {.R = 10, .affine = 1};
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) sp.i2w[r][c] = rot[r][c] * sc[c];
    sp.i2w[r][3] = 1000.0 * (r + 1);
  }
  write_sphere(path, &sp, OCS_VDB_COMPRESS_DEFAULT);
  oc_source_t desc = vdb_desc(path, -33.0, 151.0, 800.0, 0.0, 0.2);
  desc.vdb.heading = 25.0;
  ocs_source_t *s = must_create(&desc);
  ocs_vdb_source_info_t in;
  assert_int_equal(ocs_vdb_source_info(s, &in), 0);
  for (int i = 0; i < 3; i++) assert_true(fabs(in.voxel_m[i] - sc[i]) < 1e-9);
  place_t p = place_of(s, 25.0, 0.0);
  /* Points given in index space map to planet points where point() returns the profile. */
  double worst = 0.0;
  srand(7);
  for (int q = 0; q < 2000; q++) {
    double ix[3];
    for (int k = 0; k < 3; k++) ix[k] = ((double)rand() / RAND_MAX - 0.5) * 14.0;
    double r = sqrt(ix[0] * ix[0] + ix[1] * ix[1] + ix[2] * ix[2]);
    if (r > 8.5) continue;
    double got = s->vt->point(s, index_to_planet(&p, ix), 0.0), want = 0.2 * profile(r, 10);
    worst = fmax(worst, fabs(got - want));
  }
  print_message("    rotated non-uniform: worst |point - profile| %.5f (peak 0.2)\n", worst);
  assert_true(worst < 0.2 * 0.75 / 100.0 + 1e-6);
  /* Mass: the sphere's integral is ∫ρ = (8π/15) R³ voxels of 8·12·16 m³ (continuous); samples of
   * a node holding it all (plain mean × the extended cube's volume) agree within 2 %. */
  double c0[3] = {0, 0, 0};
  oc_dvec3 c = index_to_planet(&p, c0);
  for (int level = 13; level <= 14; level++) {
    double mass = block_mass(s, level, c, 1);
    /* discrete truth: the voxel values' sum × voxel volume */
    double vsum = 0.0;
    for (int k = -10; k <= 10; k++)
      for (int j = -10; j <= 10; j++)
        for (int i = -10; i <= 10; i++) vsum += (float)profile(sqrt((double)(i * i + j * j + k * k)), 10);
    char what[64];
    snprintf(what, sizeof what, "rotated, level %d", level);
    check_mass(what, mass, 0.2 * vsum * 8.0 * 12.0 * 16.0);
  }
  s->vt->destroy(s);
}

/* By name, by index, and repeated names (first wins with a warning; grid_index picks another). */
static void test_vdb__grid_selection(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "multi.vdb");
  ocs_vdb_writer_t *w = new_writer();
  sphere_t a = {.R = 5, .peak = 1.0}, b = {.R = 5, .peak = 2.0}, c = {.name = "temperature", .R = 5, .peak = 3.0};
  sphere_t v = {.name = "vel", .type = OCS_VDB_TYPE_VEC3, .R = 3};
  add_sphere(w, &v);
  add_sphere(w, &a);
  add_sphere(w, &b);
  add_sphere(w, &c);
  save(w, path, OCS_VDB_COMPRESS_DEFAULT);
  const struct {
    const char *grid;
    int index;
    double peak;
    int expect_index;
  } cases[] = {{"density", -1, 1.0, 1}, {"temperature", -1, 3.0, 3}, {NULL, 2, 2.0, 2}, {NULL, 1, 1.0, 1}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    oc_source_t d = vdb_desc(path, 0.0, 0.0, 1000.0, 10.0, 1.0);
    if (cases[i].grid) snprintf(d.vdb.grid, sizeof d.vdb.grid, "%s", cases[i].grid);
    d.vdb.grid_index = cases[i].index;
    ocs_source_t *s = must_create(&d);
    ocs_vdb_source_info_t in;
    assert_int_equal(ocs_vdb_source_info(s, &in), 0);
    assert_int_equal(in.grid_index, cases[i].expect_index);
    assert_true(fabs(in.grid.vmax - cases[i].peak) < 1e-6);
    s->vt->destroy(s);
  }
  oc_source_t d = vdb_desc(path, 0.0, 0.0, 1000.0, 10.0, 1.0);
  snprintf(d.vdb.grid, sizeof d.vdb.grid, "smoke");
  expect_fail(&d, OC_EINVAL, "no grid named 'smoke'");
  d.vdb.grid_index = 9;
  expect_fail(&d, OC_EINVAL, "grid_index 9");
  snprintf(d.vdb.grid, sizeof d.vdb.grid, "vel");
  d.vdb.grid_index = -1;
  expect_fail(&d, OC_EINVAL, "value type vec3s");
}

/* A numbered sequence: frames 1..6 hold spheres of peak 1..6; 2 frames per second. */
static void test_vdb__sequence_loop_hold_and_cache(void **st) {
  (void)st;
  char pattern[512], path[512];
  for (int f = 1; f <= 6; f++) {
    char name[64];
    snprintf(name, sizeof name, "seq_%03d.vdb", f);
    tmp_path(path, sizeof path, name);
    sphere_t sp = {.R = 6, .peak = f};
    write_sphere(path, &sp, OCS_VDB_COMPRESS_DEFAULT);
  }
  tmp_path(pattern, sizeof pattern, "seq_###.vdb");
  for (int end = 0; end < 2; end++) {
    oc_source_t d = vdb_desc(pattern, 10.0, 10.0, 1000.0, 10.0, 1.0);
    d.vdb.has_sequence = true;
    d.vdb.sequence = (oc_src_sequence_t){.frame_rate = 2.0, .first = 1, .count = 6, .end = end ? OC_SEQ_HOLD : OC_SEQ_LOOP};
    ocs_source_t *s = must_create(&d);
    assert_true(s->animated);
    ocs_vdb_source_info_t in;
    assert_int_equal(ocs_vdb_source_info(s, &in), 0);
    assert_int_equal(in.frames, 6);
    assert_true(in.cache_slots <= 4);
    place_t p = place_of(s, 0.0, 10.0);
    double c0[3] = {0, 0, 0};
    oc_dvec3 c = index_to_planet(&p, c0);
    /* t → frame: floor(2t), then loop (mod 6) or hold (clamp) */
    const double ts[] = {0.0, 0.49, 0.5, 1.2, 2.9, 3.0, 4.4, 7.1, -0.3, 100.0, 1.0, 0.1};
    for (size_t i = 0; i < sizeof ts / sizeof ts[0]; i++) {
      int64_t fl = (int64_t)floor(ts[i] * 2.0);
      int idx = end ? (int)(fl < 0 ? 0 : fl > 5 ? 5 : fl) : (int)(((fl % 6) + 6) % 6);
      double v = s->vt->point(s, c, ts[i]);
      if (fabs(v - (idx + 1)) > 1e-6) fail_msg("%s t=%g: value %g, expected frame %d", end ? "hold" : "loop", ts[i], v, idx + 1);
      assert_int_equal(s->vt->time_step(s, 10, ts[i]), (uint64_t)idx);
      float b[512];
      sample(s, oc_key_from_point(15, c), ts[i], b);
      assert_true(b[0] >= 0.0f);
    }
    s->vt->destroy(s);
  }
  /* Animation off (the scene's feature; the field clears the flag): the first frame at any time,
   * for point, bound and sample alike, as its time step (0) says. */
  {
    oc_source_t d = vdb_desc(pattern, 10.0, 10.0, 1000.0, 10.0, 1.0);
    d.vdb.has_sequence = true;
    d.vdb.sequence = (oc_src_sequence_t){.frame_rate = 2.0, .first = 1, .count = 6};
    ocs_source_t *s = must_create(&d);
    s->animated = 0;
    place_t p = place_of(s, 0.0, 10.0);
    double c0[3] = {0, 0, 0};
    oc_dvec3 c = index_to_planet(&p, c0);
    oc_key_t k = oc_key_from_point(15, c);
    float lo0, hi0, lo, hi, b0[512], b[512];
    s->vt->bound(s, oc_dv3(c.x - 5, c.y - 5, c.z - 5), oc_dv3(c.x + 5, c.y + 5, c.z + 5), 0.0, &lo0, &hi0);
    sample(s, k, 0.0, b0);
    for (double t = 0.5; t < 3.0; t += 0.5) {
      assert_true(fabs(s->vt->point(s, c, t) - 1.0) < 1e-6);
      s->vt->bound(s, oc_dv3(c.x - 5, c.y - 5, c.z - 5), oc_dv3(c.x + 5, c.y + 5, c.z + 5), t, &lo, &hi);
      assert_true(lo == lo0 && hi == hi0);
      sample(s, k, t, b);
      assert_memory_equal(b, b0, sizeof b);
      assert_int_equal(s->vt->time_step(s, 10, t), 0);
    }
    s->vt->destroy(s);
  }
  /* A frame that vanished after creation: its bound claims nothing (not "empty", which would draw
   * a silently clear sky) and its sample fails with OC_EIO. */
  {
    char dir[512], pat[600], f6[600];
    tmp_path(dir, sizeof dir, "vanish");
    mkdir(dir, 0755);
    for (int f = 1; f <= 6; f++) {
      snprintf(f6, sizeof f6, "%s/v_%d.vdb", dir, f);
      sphere_t sp = {.R = 6, .peak = f};
      write_sphere(f6, &sp, OCS_VDB_COMPRESS_DEFAULT);
    }
    snprintf(pat, sizeof pat, "%s/v_#.vdb", dir);
    oc_source_t d = vdb_desc(pat, 10.0, 10.0, 1000.0, 10.0, 1.0);
    d.vdb.has_sequence = true;
    d.vdb.sequence = (oc_src_sequence_t){.frame_rate = 2.0, .first = 1, .count = 6};
    ocs_source_t *s = must_create(&d);
    assert_int_equal(unlink(f6), 0); /* frame 6: world time 2.5 .. 3 */
    place_t p = place_of(s, 0.0, 10.0);
    double c0[3] = {0, 0, 0};
    oc_dvec3 c = index_to_planet(&p, c0);
    float lo, hi, b[512];
    s->vt->bound(s, oc_dv3(c.x - 5, c.y - 5, c.z - 5), oc_dv3(c.x + 5, c.y + 5, c.z + 5), 2.7, &lo, &hi);
    assert_true(hi > 0.0f);
    memset(b, 0, sizeof b);
    assert_int_equal(s->vt->sample(s, oc_key_from_point(15, c), 2.7, b), OC_EIO);
    s->vt->destroy(s);
  }
  /* A missing frame is an error at creation, naming the frame's file. */
  oc_source_t d = vdb_desc(pattern, 10.0, 10.0, 1000.0, 10.0, 1.0);
  d.vdb.has_sequence = true;
  d.vdb.sequence = (oc_src_sequence_t){.frame_rate = 24.0, .first = 1, .count = 7};
  ocs_source_t *s = NULL;
  char why[1024];
  assert_int_equal(ocs_source_vdb_create(&s, &d, why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, "seq_007.vdb"));
  /* One frame only: static. */
  d.vdb.sequence.count = 1;
  s = must_create(&d);
  assert_false(s->animated);
  assert_int_equal(s->vt->time_step(s, 5, 123.0), 0);
  s->vt->destroy(s);
}

/* Several threads play the sequence at once: frames load, evict and reload under them (6 frames,
 * at most 4 resident), and every value is the right frame's. */
typedef struct {
  const ocs_source_t *s;
  oc_dvec3 c;
  unsigned seed;
  int bad;
} seq_worker_t;

static void *seq_worker(void *arg) {
  seq_worker_t *w = arg;
  for (int it = 0; it < 300; it++) {
    w->seed = w->seed * 1103515245u + 12345u;
    double t = (double)((w->seed >> 8) % 6000) / 1000.0; /* 0..6 s: frames 0..11, looping */
    int idx = (int)floor(t * 2.0) % 6;
    double v = w->s->vt->point(w->s, w->c, t);
    if (fabs(v - (idx + 1)) > 1e-6) w->bad++;
    float b[512];
    memset(b, 0, sizeof b);
    if (w->s->vt->sample(w->s, oc_key_from_point(16 + it % 3, w->c), t, b) != 0) w->bad++;
    for (int i = 0; i < 512; i++)
      if (!(b[i] >= 0.0f && b[i] <= idx + 1 + 1e-4f)) {
        w->bad++;
        break;
      }
  }
  return NULL;
}

static void test_vdb__sequence_threads(void **st) {
  (void)st;
  char pattern[512];
  tmp_path(pattern, sizeof pattern, "seq_###.vdb"); /* written by the sequence test */
  oc_source_t d = vdb_desc(pattern, 10.0, 10.0, 1000.0, 10.0, 1.0);
  d.vdb.has_sequence = true;
  d.vdb.sequence = (oc_src_sequence_t){.frame_rate = 2.0, .first = 1, .count = 6, .end = OC_SEQ_LOOP};
  ocs_source_t *s = must_create(&d);
  place_t p = place_of(s, 0.0, 10.0);
  double c0[3] = {0, 0, 0};
  seq_worker_t w[4];
  pthread_t th[4];
  for (int i = 0; i < 4; i++) {
    w[i] = (seq_worker_t){s, index_to_planet(&p, c0), 17u + (unsigned)i * 7919u, 0};
    assert_int_equal(pthread_create(&th[i], NULL, seq_worker, &w[i]), 0);
  }
  for (int i = 0; i < 4; i++) {
    pthread_join(th[i], NULL);
    assert_int_equal(w[i].bad, 0);
  }
  s->vt->destroy(s);
}

/* The bound holds every sample of random nodes near the sphere, and is exact far away. */
static void test_vdb__bound_is_conservative(void **st) {
  (void)st;
  place_t p;
  oc_dvec3 c;
  ocs_source_t *s = open_sphere(33.0, &p, &c);
  srand(11);
  int empty = 0, nodes = 0;
  for (int q = 0; q < 400; q++) {
    int level = 12 + rand() % 8;
    oc_dvec3 at = oc_dv3(c.x + ((double)rand() / RAND_MAX - 0.5) * 800.0, c.y + ((double)rand() / RAND_MAX - 0.5) * 800.0,
                         c.z + ((double)rand() / RAND_MAX - 0.5) * 800.0);
    oc_key_t key = oc_key_from_point(level, at);
    oc_dvec3 o;
    double size;
    oc_key_bounds(key, &o, &size);
    double g = size / 14.0;
    float mn, mx, v[512];
    s->vt->bound(s, oc_dv3(o.x - g, o.y - g, o.z - g), oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g), 0.0, &mn, &mx);
    sample(s, key, 0.0, v);
    for (int i = 0; i < 512; i++)
      if (v[i] < mn * (1 - 1e-6f) || v[i] > mx * (1 + 1e-6f) + 1e-12f)
        fail_msg("level %d sample %d = %g outside bound [%g, %g]", level, i, v[i], mn, mx);
    empty += mx == 0.0f;
    nodes++;
  }
  print_message("    bound: %d of %d random nodes classified empty without sampling\n", empty, nodes);
  /* far away: exactly empty */
  float mn, mx;
  oc_dvec3 far = oc_dmad(c, p.enu.east, 5000.0);
  s->vt->bound(s, oc_dsub(far, oc_dv3(100, 100, 100)), oc_dadd(far, oc_dv3(100, 100, 100)), 0.0, &mn, &mx);
  assert_true(mn == 0.0f && mx == 0.0f);
  s->vt->destroy(s);
}

/* ---- 4. Bad input: one test each -------------------------------------------------------------- */

static void test_vdb__bad_missing_file(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "does_not_exist.vdb");
  expect_file_fails(path, OC_ENOENT, "no such file");
}

static void test_vdb__bad_not_a_vdb(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "not_a.vdb");
  FILE *f = fopen(path, "w");
  fputs("{\"this is\": \"json, not a VDB file\"}\n", f);
  fclose(f);
  expect_file_fails(path, OC_EVERSION, "not a VDB file");
  tmp_path(path, sizeof path, "empty_file.vdb");
  f = fopen(path, "w");
  fclose(f);
  expect_file_fails(path, OC_EVERSION, "not a VDB file");
}

static void test_vdb__bad_truncated(void **st) {
  (void)st;
  char src[512], path[512];
  tmp_path(src, sizeof src, "trunc_src.vdb");
  sphere_t sp = {.R = 20};
  write_sphere(src, &sp, OCS_VDB_COMPRESS_ZIP);
  FILE *f = fopen(src, "rb");
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  rewind(f);
  char *buf = malloc((size_t)n);
  assert_int_equal(fread(buf, 1, (size_t)n, f), (size_t)n);
  fclose(f);
  /* cut in the header, in the middle of the voxels, and just before the end */
  const long cuts[] = {40, n / 2, n - 3};
  for (int i = 0; i < 3; i++) {
    tmp_path(path, sizeof path, "truncated.vdb");
    f = fopen(path, "wb");
    fwrite(buf, 1, (size_t)cuts[i], f);
    fclose(f);
    expect_file_fails(path, OC_ETRUNC, "truncated");
  }
  free(buf);
}

static void test_vdb__bad_no_float_grid(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "no_float.vdb");
  ocs_vdb_writer_t *w = new_writer();
  sphere_t v = {.name = "velocity", .type = OCS_VDB_TYPE_VEC3, .R = 3}, n = {.name = "flags", .type = OCS_VDB_TYPE_INT32, .R = 3};
  add_sphere(w, &v);
  add_sphere(w, &n);
  save(w, path, OCS_VDB_COMPRESS_DEFAULT);
  expect_file_fails(path, OC_EINVAL, "no float grid");
}

static void test_vdb__bad_level_set(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "level_set.vdb");
  sphere_t sp = {.R = 6, .klass = OCS_VDB_CLASS_LEVEL_SET};
  write_sphere(path, &sp, OCS_VDB_COMPRESS_DEFAULT);
  expect_file_fails(path, OC_EINVAL, "is a level set");
}

static void test_vdb__bad_point_grid(void **st) {
  (void)st;
  char path[512], why[256];
  tmp_path(path, sizeof path, "points.vdb");
  ocs_vdb_writer_t *w = new_writer();
  ocs_vdb_grid_desc_t gd = {.name = "density", .type = OCS_VDB_TYPE_POINTS, .voxel_size = 0.5};
  int g = add_grid(w, &gd);
  double pts[30];
  for (int i = 0; i < 30; i++) pts[i] = (i * 7 % 11) * 0.3;
  assert_int_equal(api()->writer_add_points(w, g, pts, 10), 0);
  save(w, path, OCS_VDB_COMPRESS_DEFAULT);
  expect_file_fails(path, OC_EINVAL, "point data grid (10 points)");
  /* inspect reports it as points */
  char *buf = NULL;
  size_t len = 0;
  FILE *m = open_memstream(&buf, &len);
  assert_int_equal(ocs_vdb_inspect(path, 0, m, why, sizeof why), 0);
  fclose(m);
  assert_non_null(strstr(buf, "points      10"));
  free(buf);
}

static void test_vdb__bad_empty_grid(void **st) {
  (void)st;
  density_file_t f = density_file("empty_grid.vdb");
  save(f.w, f.path, OCS_VDB_COMPRESS_DEFAULT);
  expect_file_fails(f.path, OC_EINVAL, "is empty");
}

static void test_vdb__bad_voxel_size(void **st) {
  (void)st;
  const double bad[] = {0.0, NAN, INFINITY, -2.0};
  for (int i = 0; i < 4; i++) {
    char path[512], name[64];
    snprintf(name, sizeof name, "voxel_size_%d.vdb", i);
    tmp_path(path, sizeof path, name);
    ocs_vdb_writer_t *w = new_writer();
    set_voxel(w, add_density(w, bad[i]), 0, 0, 0, 1.0f);
    save(w, path, OCS_VDB_COMPRESS_DEFAULT);
    oc_source_t d = vdb_desc(path, 0, 0, 1000, 0.0, 1); /* the file's own transform */
    expect_fail(&d, OC_EINVAL, "voxel size");
    /* scale_m would replace the transform, but a broken file is refused all the same */
    d = vdb_desc(path, 0, 0, 1000, 10.0, 1);
    expect_fail(&d, OC_EINVAL, "voxel size");
  }
}

static void test_vdb__bad_values_sanitised(void **st) {
  (void)st;
  density_file_t f = density_file("bad_values.vdb");
  float v[4 * 4 * 4];
  for (int i = 0; i < 64; i++) v[i] = 0.5f;
  v[1] = NAN;
  v[5] = NAN;
  v[9] = INFINITY;
  v[20] = -1.0f;
  v[21] = -INFINITY;
  v[40] = -0.25f;
  int32_t o[3] = {0, 0, 0}, dd[3] = {4, 4, 4};
  assert_int_equal(api()->writer_set_values(f.w, f.g, o, dd, v), 0);
  save(f.w, f.path, OCS_VDB_COMPRESS_DEFAULT);
  oc_source_t d = vdb_desc(f.path, 5, 5, 1000, 10, 1);
  ocs_source_t *s = must_create(&d);
  ocs_vdb_source_info_t in;
  assert_int_equal(ocs_vdb_source_info(s, &in), 0);
  assert_int_equal(in.prep.nan, 2);
  assert_int_equal(in.prep.inf, 2);
  assert_int_equal(in.prep.negative, 2);
  /* as read, inspect counts them too */
  assert_int_equal(in.grid.nan, 2);
  assert_int_equal(in.grid.inf, 2);
  place_t p = place_of(s, 0.0, 10.0);
  double c0[3] = {1.5, 1.5, 1.5};
  oc_dvec3 c = index_to_planet(&p, c0);
  for (int level = 14; level <= 19; level++) {
    float b[512];
    sample(s, oc_key_from_point(level, c), 0.0, b);
    for (int i = 0; i < 512; i++) assert_true(isfinite(b[i]) && b[i] >= 0.0f && b[i] <= 0.5f + 1e-6f);
  }
  s->vt->destroy(s);
}

static void test_vdb__bad_absurd_placement(void **st) {
  (void)st;
  char path[512];
  tmp_path(path, sizeof path, "sphere.vdb");
  oc_source_t d = vdb_desc(path, 0, 0, 1000, 1e5, 1); /* 25 voxels × 100 km */
  expect_fail(&d, OC_ERANGE, "absurd placement");
  d = vdb_desc(path, 0, 0, 95000, 400.0, 1); /* 10 km tall from 95 km */
  expect_fail(&d, OC_ERANGE, "altitudes");
  d = vdb_desc(path, 0, 0, 1000, 1e-3, 1); /* 2.5 cm wide */
  expect_fail(&d, OC_ERANGE, "span only");
}

/* ---- 5. The Disney cloud ---------------------------------------------------------------------- */

static void test_vdb__disney_cloud(void **st) {
  (void)st;
  /* As in scenes/disney_cloud.json: 20 m per voxel (2.5 × 1.7 × 3.1 km), σt peak 0.1 m⁻¹. */
  oc_source_t d = vdb_desc(disney_path(), 47.0, 8.5, 1000.0, 20.0, 0.1);
  double t0 = now_s();
  ocs_source_t *s = must_create(&d);
  double t_load = now_s() - t0;
  ocs_vdb_source_info_t in;
  assert_int_equal(ocs_vdb_source_info(s, &in), 0);
  assert_int_equal(in.grid.active_voxels, 415642);
  assert_int_equal(in.grid.active_tiles, 130);
  assert_int_equal(in.grid.bbox_min[0], -66);
  assert_int_equal(in.grid.bbox_min[1], -21);
  assert_int_equal(in.grid.bbox_min[2], -90);
  assert_int_equal(in.grid.bbox_max[0], 59);
  assert_int_equal(in.grid.bbox_max[1], 64);
  assert_int_equal(in.grid.bbox_max[2], 63);
  assert_true(fabs(in.grid.voxel_size[0] - 3.3333) < 1e-4);
  assert_true(in.grid.vmin == 0.0 && in.grid.vmax == 1.0);
  assert_int_equal(in.prep.nan + in.prep.inf + in.prep.negative, 0);
  print_message("    Disney: created in %.3f s (%d levels, %.1f MB), placed %.0f x %.0f x %.0f m (E, N, U)\n", t_load,
                in.prep.levels, (double)in.prep.bytes / 1e6, in.extent_m[0], in.extent_m[1], in.extent_m[2]);
  assert_true(fabs(in.extent_m[0] - 126 * 20.0) < 1e-6 && fabs(in.extent_m[1] - 154 * 20.0) < 1e-6 &&
              fabs(in.extent_m[2] - 86 * 20.0) < 1e-6);
  place_t p = place_of(s, 0.0, 20.0);
  /* The whole cloud fits in a 3×3×3 block of level-10 nodes (12.6 km): its total mass is the
   * same at every level (σt·m³; trapezoid node means × node volumes). */
  double mid[3] = {-3.5, 21.5, -13.5};
  oc_dvec3 c = index_to_planet(&p, mid);
  double masses[3];
  for (int level = 10; level <= 12; level++)
    masses[level - 10] = block_mass(s, level, c, level == 12 ? 2 : 1); /* 5³ level-12 nodes cover the level-10 block's middle */
  print_message("    Disney mass (σt·m³) at levels 10, 11, 12: %.6g %.6g %.6g\n", masses[0], masses[1], masses[2]);
  /* The Conventions' test (filter_check.h), as tests/server/test_field.c: for nodes through the
   * cloud at levels 11..16, the samples' plain mean against the true mean over the extended cube
   * (64³ point quadrature of the voxels' trilinear reconstruction), and the node's mean against
   * its 8 and 64 descendants', both relative to the node's peak σt. */
  filter_src_t src = {s, source_sample0, source_point0};
  filter_worst_t worst = {0};
  for (int level = 11; level <= 16; level++) {
    filter_check_t r = filter_check(&src, oc_key_from_point(level, c), 64);
    print_message("    level %d: samples' mean %.5g vs true %.5g (%.1e of peak); node mean %.5g, 8 children %.1e, 64 "
                  "grandchildren %.1e of peak\n", level, r.plain, r.truth, r.exact, r.m0, fabs(r.m1 - r.m0) / r.peak,
                  fabs(r.m2 - r.m0) / r.peak);
    filter_worst_add(&worst, &r);
  }
  filter_worst_check(&worst, "Disney cloud", "levels 11-16", 5e-3);
  assert_true(fabs(masses[1] - masses[0]) / masses[0] < 0.01);
  assert_true(fabs(masses[2] - masses[0]) / masses[0] < 0.01);
  /* σt stays within [0, 0.1]; the root's bound covers it. */
  float mn, mx;
  s->vt->bound(s, oc_dv3(-OC_ROOT_HALF, -OC_ROOT_HALF, -OC_ROOT_HALF), oc_dv3(OC_ROOT_HALF, OC_ROOT_HALF, OC_ROOT_HALF), 0.0, &mn, &mx);
  assert_true(mn == 0.0f && fabsf(mx - 0.1f) < 1e-7f);
  /* Throughput on one core: bricks per second at a coarse, a middle and a fine level, over nodes
   * the bound cannot classify (neither empty nor uniform), along the cloud's east-west axis. */
  const int levels[3] = {13, 15, 17};
  for (int q = 0; q < 3; q++) {
    int level = levels[q], n = 0, nk = 0;
    double size = oc_key_size(level);
    oc_key_t keys[64];
    for (int i = -200; i <= 200 && nk < 64; i++) {
      oc_key_t k = oc_key_from_point(level, oc_dmad(c, p.enu.east, i * size / 4.0));
      oc_dvec3 o;
      double sz;
      float lo, hi;
      oc_key_bounds(k, &o, &sz);
      double g = sz / 14.0;
      s->vt->bound(s, oc_dv3(o.x - g, o.y - g, o.z - g), oc_dv3(o.x + sz + g, o.y + sz + g, o.z + sz + g), 0.0, &lo, &hi);
      if (lo != hi && (nk == 0 || keys[nk - 1] != k)) keys[nk++] = k;
    }
    assert_true(nk > 0);
    double start = now_s();
    float v[512];
    while (now_s() - start < 0.5)
      for (int j = 0; j < nk; j++, n++) sample(s, keys[j], 0.0, v);
    double rate = n / (now_s() - start);
    print_message("    sampling level %d (node %.0f m, footprint %.1f m = %.2f voxels), %d mixed nodes: %.0f bricks/s on one core\n",
                  level, size, size / 7.0, size / 7.0 / 20.0, nk, rate);
  }
  s->vt->destroy(s);
}

/* Two VDB sources in one scene (each its own source) add up in the field. */
static void test_vdb__two_vdbs_in_one_field(void **st) {
  (void)st;
  char path[512], json[2048], why[1024];
  tmp_path(path, sizeof path, "sphere.vdb");
  snprintf(json, sizeof json,
           "{\"sources\": [{\"type\": \"vdb\", \"file\": \"%s\", \"lat\": 30, \"lon\": 40, \"alt\": 1500, \"scale_m\": 20,"
           " \"sigma_scale\": 0.1}, {\"type\": \"vdb\", \"file\": \"%s\", \"lat\": 30, \"lon\": 40, \"alt\": 1500, \"scale_m\": 20,"
           " \"sigma_scale\": 0.05}], \"features\": {\"animation\": false}}",
           path, disney_path());
  oc_scene_t sc;
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "two.json", why, sizeof why), 0);
  ocs_field_t *f = NULL;
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) fail_msg("%s", why);
  assert_false(ocs_field_animated(f));
  oc_source_t d1 = vdb_desc(path, 30, 40, 1500, 20, 0.1), d2 = vdb_desc(disney_path(), 30, 40, 1500, 20, 0.05);
  ocs_source_t *s1 = must_create(&d1), *s2 = must_create(&d2);
  oc_key_t key = oc_key_from_point(15, oc_geo_to_xyz((oc_geo_t){30, 40, 1800}));
  float a[512], b[512], c[512];
  assert_int_equal(ocs_field_sample(f, key, 0.0, a), 0);
  sample(s1, key, 0.0, b);
  sample(s2, key, 0.0, c);
  double peak = 0.0;
  for (int i = 0; i < 512; i++) {
    assert_true(fabsf(a[i] - (b[i] + c[i])) <= 1e-6f * fabsf(a[i]) + 1e-12f);
    peak = fmax(peak, a[i]);
  }
  assert_true(peak > 0.0);
  s1->vt->destroy(s1);
  s2->vt->destroy(s2);
  ocs_field_free(f);
  oc_scene_free(&sc);
  /* A bad file in a scene: the field names the source and the file. */
  snprintf(json, sizeof json, "{\"sources\": [{\"type\": \"vdb\", \"file\": \"%s/nope.vdb\", \"alt\": 100}]}", g_dir);
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "bad.json", why, sizeof why), 0);
  assert_int_equal(ocs_field_create(&f, &sc, why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, "nope.vdb"));
  assert_non_null(strstr(why, "sources[0]"));
  oc_scene_free(&sc);
}

/* ---- 6. Export and re-import ------------------------------------------------------------------ */

static void test_vdb__export_round_trip(void **st) {
  (void)st;
  char src[512], out[512], why[1024], json[1024];
  tmp_path(src, sizeof src, "sphere.vdb");
  tmp_path(out, sizeof out, "exported.vdb");
  snprintf(json, sizeof json,
           "{\"sources\": [{\"type\": \"vdb\", \"file\": \"%s\", \"lat\": 30, \"lon\": 40, \"alt\": 1500, \"scale_m\": 20,"
           " \"sigma_scale\": 0.1}], \"features\": {\"animation\": false}}",
           src);
  oc_scene_t sc;
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "rt.json", why, sizeof why), 0);
  ocs_field_t *f = NULL;
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) fail_msg("%s", why);
  place_t p;
  ocs_source_t *orig = sphere_source(src, 0.0, &p);
  oc_dvec3 c = sphere_centre(&p), r = oc_dv3(400, 400, 400);
  const int level = 17; /* 14.1 m lattice */
  double t0 = now_s();
  int rc = ocs_vdb_export(f, 0.0, oc_dsub(c, r), oc_dadd(c, r), level, out, why, sizeof why);
  if (rc < 0) fail_msg("export: %s", why);
  double t_export = now_s() - t0;
  /* What was written: one float fog grid "density", voxel 14.1 m, rotated (local Y-up) frame. */
  ocs_vdb_file_t *vf;
  assert_int_equal(api()->open(out, NULL, NULL, &vf, why, sizeof why), 0);
  ocs_vdb_grid_info_t gi;
  assert_int_equal(api()->grid_info(vf, 0, 1, &gi), 0);
  api()->close(vf);
  assert_string_equal(gi.name, "density");
  assert_int_equal(gi.klass, OCS_VDB_CLASS_FOG);
  assert_true(fabs(gi.voxel_size[0] - oc_key_size(level) / 7.0) < 1e-9);
  print_message("    export: %llu active voxels, values %.4g..%.4g, in %.3f s\n", (unsigned long long)gi.active_voxels, gi.vmin,
                gi.vmax, t_export);
  /* Re-import with the file's own transform: the anchor is where the bottom-face centre of its
   * active box lies, i.e. C + Qᵀ·w (Q: rows east, up, -north at the region centre C). */
  oc_dvec3 C = c;
  oc_enu_t ce = oc_enu_at(C);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int k = 0; k < 8; k++) {
    double ix[3];
    for (int a = 0; a < 3; a++) ix[a] = (k >> a) & 1 ? gi.bbox_max[a] + 0.5 : gi.bbox_min[a] - 0.5;
    for (int rr = 0; rr < 3; rr++) {
      double w = gi.i2w[rr][0] * ix[0] + gi.i2w[rr][1] * ix[1] + gi.i2w[rr][2] * ix[2] + gi.i2w[rr][3];
      lo[rr] = fmin(lo[rr], w);
      hi[rr] = fmax(hi[rr], w);
    }
  }
  double wa[3] = {0.5 * (lo[0] + hi[0]), lo[1], 0.5 * (lo[2] + hi[2])};
  oc_dvec3 A = oc_dmad(oc_dmad(oc_dmad(C, ce.east, wa[0]), ce.up, wa[1]), ce.north, -wa[2]);
  oc_geo_t ag = oc_xyz_to_geo(A);
  oc_source_t d = vdb_desc(out, ag.lat, ag.lon, ag.alt, 0.0, 1.0);
  ocs_source_t *back = must_create(&d);
  /* At the export level the lattice points are the voxel centres: values come back as written;
   * coarser levels average the same data. */
  for (int lv = level - 4; lv <= level; lv++) {
    double worst = 0.0, peak = 0.0, m0 = 0.0, m1 = 0.0;
    for (int q = 0; q < 4; q++) {
      oc_dvec3 at = oc_dmad(c, p.enu.east, (q - 1.5) * 60.0);
      oc_key_t key = oc_key_from_point(lv, at);
      float a[512], b[512];
      sample(orig, key, 0.0, a);
      sample(back, key, 0.0, b);
      for (int i = 0; i < 512; i++) {
        worst = fmax(worst, fabs(a[i] - b[i]));
        peak = fmax(peak, a[i]);
      }
      m0 += oc_test_node_mean(a);
      m1 += oc_test_node_mean(b);
    }
    print_message("    round trip level %d: worst |orig - reimported| %.2e of peak %.4g, mean %.6g vs %.6g\n", lv, worst / peak, peak,
                  m0, m1);
    double tol = lv == level ? 1e-3 : 0.05;
    assert_true(worst <= tol * peak);
    assert_true(fabs(m1 - m0) <= 0.01 * m0);
  }
  orig->vt->destroy(orig);
  back->vt->destroy(back);
  /* Errors: a region beyond the limit; an unwritable path. */
  assert_int_equal(ocs_vdb_export(f, 0.0, oc_dsub(c, oc_dv3(1e5, 1e5, 1e5)), oc_dadd(c, oc_dv3(1e5, 1e5, 1e5)), 21, out, why, sizeof why),
                   OC_ETOOBIG);
  assert_int_equal(ocs_vdb_export(f, 0.0, oc_dsub(c, r), oc_dadd(c, r), 12, "/nonexistent/dir/x.vdb", why, sizeof why), OC_EIO);
  assert_non_null(strstr(why, "/nonexistent/dir/x.vdb"));
  ocs_field_free(f);
  oc_scene_free(&sc);
}

/* ---- Group ------------------------------------------------------------------------------------ */

OC_TEST_TMPDIR_FIXTURE(g_dir, "vdb")

OC_TEST_MAIN(tmpdir_setup, tmpdir_teardown,
             cmocka_unit_test(test_vdb__analytic_field_maps_no_openvdb), /* first: before any VDB use */
             cmocka_unit_test(test_vdb__shim_reads_disney_with_progress),
             cmocka_unit_test(test_vdb__inspect_text_and_json),
             cmocka_unit_test(test_vdb__fog_sphere_fine_levels_match_analytic),
             cmocka_unit_test(test_vdb__fog_sphere_coarse_levels_box_average),
             cmocka_unit_test(test_vdb__compression_and_half_variants),
             cmocka_unit_test(test_vdb__constant_tiles),
             cmocka_unit_test(test_vdb__placement_orientation_and_heading),
             cmocka_unit_test(test_vdb__rotated_nonuniform_transform),
             cmocka_unit_test(test_vdb__grid_selection),
             cmocka_unit_test(test_vdb__sequence_loop_hold_and_cache),
             cmocka_unit_test(test_vdb__sequence_threads),
             cmocka_unit_test(test_vdb__bound_is_conservative),
             cmocka_unit_test(test_vdb__bad_missing_file),
             cmocka_unit_test(test_vdb__bad_not_a_vdb),
             cmocka_unit_test(test_vdb__bad_truncated),
             cmocka_unit_test(test_vdb__bad_no_float_grid),
             cmocka_unit_test(test_vdb__bad_level_set),
             cmocka_unit_test(test_vdb__bad_point_grid),
             cmocka_unit_test(test_vdb__bad_empty_grid),
             cmocka_unit_test(test_vdb__bad_voxel_size),
             cmocka_unit_test(test_vdb__bad_values_sanitised),
             cmocka_unit_test(test_vdb__bad_absurd_placement),
             cmocka_unit_test(test_vdb__disney_cloud),
             cmocka_unit_test(test_vdb__two_vdbs_in_one_field),
             cmocka_unit_test(test_vdb__export_round_trip))
