/* vdb_tools.c — `overcast-server --inspect FILE.vdb [--json]` and `--export-vdb`: VDB files seen
 * through the shim (vdb_shim.h), which is loaded only when one of these runs. */
#include <cjson/cJSON.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "oc_brick.h"
#include "oc_err.h"
#include "oc_key.h"
#include "oc_log.h"
#include "oc_planet.h"
#include "vdb_tools.h"

/*! Nodes sampled per batch by the export's workers (then written in canonical order). */
#ifndef OCS_VDB_EXPORT_BATCH
#define OCS_VDB_EXPORT_BATCH 256
#endif
/*! Most export worker threads. */
#ifndef OCS_VDB_EXPORT_THREADS
#define OCS_VDB_EXPORT_THREADS 16
#endif

/* ---- Progress on a terminal ------------------------------------------------------------------- */

typedef struct {
  const char *path;
  int last_pct, printed;
} ocs__tool_progress_t;

static void ocs__tool_progress(void *ctx, uint64_t done, uint64_t total) {
  ocs__tool_progress_t *p = ctx;
  int pct = total ? (int)(100.0 * (double)done / (double)total) : 100;
  if (pct == p->last_pct) return;
  p->last_pct = pct;
  p->printed = 1;
  fprintf(stderr, "\rovercast: reading %s: %3d%% (%.1f of %.1f MB)", p->path, pct, (double)done / 1e6, (double)total / 1e6);
  fflush(stderr);
}

/* The shim's functions, or NULL with *rc its code and why "path: reason". */
static const ocs_vdb_api_t *ocs__tool_api(const char *path, char *why, size_t why_len, int *rc) {
  char sub[1536];
  const ocs_vdb_api_t *api;
  *rc = ocs_vdb_load(&api, sub, sizeof sub);
  if (*rc >= 0) return api;
  snprintf(why, why_len, "%s: %s", path, sub);
  return NULL;
}

/* ---- Inspect ----------------------------------------------------------------------------------- */

static const char *ocs__type_name(int t) {
  static const char *const names[] = {"other", "float", "double", "int32", "int64", "vec3", "points"};
  return t >= 0 && t <= OCS_VDB_TYPE_POINTS ? names[t] : "other";
}

static const char *ocs__klass_name(int k) {
  static const char *const names[] = {"unknown", "level set", "fog volume", "staggered"};
  return k >= 0 && k <= 3 ? names[k] : "unknown";
}

static void ocs__compression_text(uint32_t c, char *buf, size_t cap) {
  snprintf(buf, cap, "%s%s", c & 0x4 ? "blosc" : c & 0x1 ? "zip" : "none", c & 0x2 ? ", active mask" : "");
}

/* Is the transform more than a scale and a translation? */
static int ocs__rotated(const ocs_vdb_grid_info_t *g) {
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++)
      if (r != c && g->i2w[r][c] != 0.0) return 1;
  return 0;
}

static void ocs__inspect_text(FILE *out, const char *path, uint64_t bytes, uint32_t comp, uint32_t ver, const char *lib,
                              int n, const ocs_vdb_grid_info_t *gi) {
  char cbuf[64];
  ocs__compression_text(comp, cbuf, sizeof cbuf);
  fprintf(out, "%s: %llu bytes, VDB format %u, compression %s, %d grid%s (%s)\n", path, (unsigned long long)bytes, ver, cbuf, n,
          n == 1 ? "" : "s", lib);
  for (int i = 0; i < n; i++) {
    const ocs_vdb_grid_info_t *g = &gi[i];
    fprintf(out, "grid %d '%s'\n", i, g->name);
    fprintf(out, "  type        %s%s%s\n", g->type == OCS_VDB_TYPE_POINTS ? "points, " : "", g->value_type,
            g->half ? " (saved as half floats)" : "");
    fprintf(out, "  class       %s\n", ocs__klass_name(g->klass));
    fprintf(out, "  voxel size  %.6g x %.6g x %.6g\n", g->voxel_size[0], g->voxel_size[1], g->voxel_size[2]);
    if (g->linear)
      fprintf(out, "  transform   linear%s, index (0,0,0) at (%.6g, %.6g, %.6g)\n", ocs__rotated(g) ? ", rotated or sheared" : "",
              g->i2w[0][3], g->i2w[1][3], g->i2w[2][3]);
    else
      fprintf(out, "  transform   non-linear (frustum)\n");
    fprintf(out, "  active      %llu voxels (%llu constant tiles, %llu leaf nodes)\n", (unsigned long long)g->active_voxels,
            (unsigned long long)g->active_tiles, (unsigned long long)g->leaf_nodes);
    if (g->type == OCS_VDB_TYPE_POINTS) fprintf(out, "  points      %llu\n", (unsigned long long)g->points);
    if (g->bbox_min[0] <= g->bbox_max[0])
      fprintf(out, "  bbox        (%d, %d, %d) .. (%d, %d, %d), %lld x %lld x %lld voxels\n", g->bbox_min[0], g->bbox_min[1],
              g->bbox_min[2], g->bbox_max[0], g->bbox_max[1], g->bbox_max[2], (long long)g->bbox_max[0] - g->bbox_min[0] + 1,
              (long long)g->bbox_max[1] - g->bbox_min[1] + 1, (long long)g->bbox_max[2] - g->bbox_min[2] + 1);
    else
      fprintf(out, "  bbox        empty\n");
    if (g->has_range) {
      fprintf(out, "  values      %.6g .. %.6g%s\n", g->vmin, g->vmax, g->type == OCS_VDB_TYPE_VEC3 ? " (lengths)" : "");
      if (g->nan || g->inf || g->negative)
        fprintf(out, "  bad values  %llu NaN, %llu infinite, %llu negative\n", (unsigned long long)g->nan,
                (unsigned long long)g->inf, (unsigned long long)g->negative);
    }
  }
}

static cJSON *ocs__json_vec(const double *v, int n) {
  cJSON *a = cJSON_CreateArray();
  for (int i = 0; a && i < n; i++) cJSON_AddItemToArray(a, cJSON_CreateNumber(v[i]));
  return a;
}

static cJSON *ocs__json_ivec(const int32_t *v) {
  double d[3] = {v[0], v[1], v[2]};
  return ocs__json_vec(d, 3);
}

static int ocs__inspect_json(FILE *out, const char *path, uint64_t bytes, uint32_t comp, uint32_t ver, const char *lib, int n,
                             const ocs_vdb_grid_info_t *gi) {
  cJSON *root = cJSON_CreateObject(), *grids;
  char cbuf[64];
  if (!root) return OC_ENOMEM;
  ocs__compression_text(comp, cbuf, sizeof cbuf);
  cJSON_AddStringToObject(root, "file", path);
  cJSON_AddNumberToObject(root, "bytes", (double)bytes);
  cJSON_AddNumberToObject(root, "format_version", ver);
  cJSON_AddStringToObject(root, "compression", cbuf);
  cJSON_AddStringToObject(root, "library", lib);
  grids = cJSON_AddArrayToObject(root, "grids");
  for (int i = 0; grids && i < n; i++) {
    const ocs_vdb_grid_info_t *g = &gi[i];
    cJSON *o = cJSON_CreateObject();
    if (!o) break;
    cJSON_AddItemToArray(grids, o);
    cJSON_AddNumberToObject(o, "index", i);
    cJSON_AddStringToObject(o, "name", g->name);
    cJSON_AddStringToObject(o, "value_type", g->value_type);
    cJSON_AddStringToObject(o, "type", ocs__type_name(g->type));
    cJSON_AddStringToObject(o, "class", ocs__klass_name(g->klass));
    cJSON_AddBoolToObject(o, "half", g->half);
    cJSON_AddBoolToObject(o, "linear", g->linear);
    cJSON_AddItemToObject(o, "voxel_size", ocs__json_vec(g->voxel_size, 3));
    if (g->linear) {
      cJSON *m = cJSON_AddArrayToObject(o, "index_to_world");
      for (int r = 0; m && r < 3; r++) cJSON_AddItemToArray(m, ocs__json_vec(g->i2w[r], 4));
    }
    cJSON_AddNumberToObject(o, "active_voxels", (double)g->active_voxels);
    cJSON_AddNumberToObject(o, "active_tiles", (double)g->active_tiles);
    cJSON_AddNumberToObject(o, "leaf_nodes", (double)g->leaf_nodes);
    if (g->type == OCS_VDB_TYPE_POINTS) cJSON_AddNumberToObject(o, "points", (double)g->points);
    if (g->bbox_min[0] <= g->bbox_max[0]) {
      cJSON_AddItemToObject(o, "bbox_min", ocs__json_ivec(g->bbox_min));
      cJSON_AddItemToObject(o, "bbox_max", ocs__json_ivec(g->bbox_max));
    } else {
      cJSON_AddNullToObject(o, "bbox_min");
      cJSON_AddNullToObject(o, "bbox_max");
    }
    if (g->has_range) {
      cJSON_AddNumberToObject(o, "value_min", g->vmin);
      cJSON_AddNumberToObject(o, "value_max", g->vmax);
      cJSON_AddNumberToObject(o, "nan", (double)g->nan);
      cJSON_AddNumberToObject(o, "inf", (double)g->inf);
      cJSON_AddNumberToObject(o, "negative", (double)g->negative);
    }
  }
  char *text = cJSON_Print(root);
  cJSON_Delete(root);
  if (!text) return OC_ENOMEM;
  fprintf(out, "%s\n", text);
  free(text);
  return 0;
}

int ocs_vdb_inspect(const char *path, int json, FILE *out, char *why, size_t why_len) {
  char scratch[8], sub[1536];
  if (!why) {
    why = scratch;
    why_len = sizeof scratch;
  }
  if (!path || !out) {
    snprintf(why, why_len, "inspect: no file");
    return OC_EINVAL;
  }
  int r;
  const ocs_vdb_api_t *api = ocs__tool_api(path, why, why_len, &r);
  if (!api) return r;
  ocs__tool_progress_t prog = {path, -1, 0};
  struct stat st;
  int show = isatty(2) && stat(path, &st) == 0 && st.st_size >= (4 << 20);
  ocs_vdb_file_t *f = NULL;
  r = api->open(path, show ? ocs__tool_progress : NULL, &prog, &f, sub, sizeof sub);
  if (prog.printed) fprintf(stderr, "\r\033[K");
  if (r < 0) {
    snprintf(why, why_len, "%s: %s", path, sub);
    return r;
  }
  int n = api->grid_count(f);
  ocs_vdb_grid_info_t *gi = calloc(n ? (size_t)n : 1, sizeof *gi);
  if (!gi) {
    api->close(f);
    return OC_ENOMEM;
  }
  for (int i = 0; i < n && r == 0; i++) r = api->grid_info(f, i, 1, &gi[i]);
  uint64_t bytes;
  uint32_t comp, ver;
  api->file_info(f, &bytes, &comp, &ver);
  if (r == 0) {
    if (json) r = ocs__inspect_json(out, path, bytes, comp, ver, api->version(), n, gi);
    else ocs__inspect_text(out, path, bytes, comp, ver, api->version(), n, gi);
  }
  if (r < 0) snprintf(why, why_len, "%s: %s", path, oc_strerror(r));
  free(gi);
  api->close(f);
  return r;
}

/* ---- Export ------------------------------------------------------------------------------------ */

typedef struct {
  const ocs_field_t *f;
  double t;
  int level;
  uint32_t i0[3], n[3];   /* first node and node counts per axis */
  uint64_t first, count;  /* the batch: node numbers [first, first + count) */
  atomic_ullong next;     /* next node of the batch to take */
  float (*vals)[OC_BRICK_VOXELS];
  unsigned char *kind;    /* 0 skipped (empty), 1 sampled */
  atomic_int err;         /* an error of some node (any non-zero wins) */
} ocs__export_t;

static oc_key_t ocs__export_key(const ocs__export_t *e, uint64_t node) {
  uint32_t x = (uint32_t)(node % e->n[0]), y = (uint32_t)((node / e->n[0]) % e->n[1]), z = (uint32_t)(node / e->n[0] / e->n[1]);
  return oc_key_make(e->level, e->i0[0] + x, e->i0[1] + y, e->i0[2] + z);
}

static void *ocs__export_worker(void *arg) {
  ocs__export_t *e = arg;
  for (;;) {
    uint64_t i = atomic_fetch_add(&e->next, 1);
    if (i >= e->count) break;
    oc_key_t key = ocs__export_key(e, e->first + i);
    float mn, mx;
    ocs_field_bound(e->f, key, e->t, &mn, &mx);
    if (!(mx > 0.0f)) {
      e->kind[i] = 0;
      continue;
    }
    int r = ocs_field_sample(e->f, key, e->t, e->vals[i]);
    if (r < 0) {
      atomic_store(&e->err, r);
      e->kind[i] = 0;
      continue;
    }
    e->kind[i] = 1;
  }
  return NULL;
}

int ocs_vdb_export(const ocs_field_t *f, double t, oc_dvec3 lo, oc_dvec3 hi, int level, const char *path, char *why,
                   size_t why_len) {
  char scratch[8], sub[1536];
  if (!why) {
    why = scratch;
    why_len = sizeof scratch;
  }
  if (!f || !path || level < 0 || level > OC_KEY_MAX_LEVEL || !isfinite(t)) {
    snprintf(why, why_len, "export: needs a field, a file and a level in 0..%d", OC_KEY_MAX_LEVEL);
    return OC_EINVAL;
  }
  double L[3] = {lo.x, lo.y, lo.z}, H[3] = {hi.x, hi.y, hi.z};
  const double S = OC_ROOT_HALF, size = oc_key_size(level), u = size / 7.0;
  uint32_t top = (1u << level) - 1u;
  ocs__export_t e;
  memset(&e, 0, sizeof e);
  uint64_t voxels = 1;
  for (int a = 0; a < 3; a++) {
    if (!isfinite(L[a]) || !isfinite(H[a]) || L[a] > H[a] || H[a] < -S || L[a] > S) {
      snprintf(why, why_len, "%s: export region must be a finite box meeting the root cube (lo ≤ hi)", path);
      return OC_EINVAL;
    }
    double a0 = floor((fmax(L[a], -S) + S) / size), a1 = floor((fmin(H[a], S) + S) / size);
    uint32_t i0 = a0 < 0 ? 0 : a0 > top ? top : (uint32_t)a0, i1 = a1 < 0 ? 0 : a1 > top ? top : (uint32_t)a1;
    e.i0[a] = i0;
    e.n[a] = i1 - i0 + 1;
    voxels *= 7u * (uint64_t)e.n[a] + 1u;
    if (voxels > OCS_VDB_EXPORT_MAX_VOXELS) break;
  }
  if (voxels > OCS_VDB_EXPORT_MAX_VOXELS) {
    snprintf(why, why_len, "%s: export of level %d over that region needs more than %llu voxels: choose a coarser level or a smaller region",
             path, level, (unsigned long long)OCS_VDB_EXPORT_MAX_VOXELS);
    return OC_ETOOBIG;
  }
  int r;
  const ocs_vdb_api_t *api = ocs__tool_api(path, why, why_len, &r);
  if (!api) return r;
  /* Frame: local Y-up at the centre C of the region: rows of Q are east, up, -north. */
  oc_dvec3 C = oc_dscale(oc_dadd(lo, hi), 0.5);
  oc_enu_t enu = oc_enu_at(C);
  oc_dvec3 Q[3] = {enu.east, enu.up, oc_dscale(enu.north, -1.0)};
  oc_dvec3 P0 = oc_dv3(-S + (double)(7u * e.i0[0]) * u, -S + (double)(7u * e.i0[1]) * u, -S + (double)(7u * e.i0[2]) * u);
  oc_dvec3 dP = oc_dsub(P0, C);
  ocs_vdb_grid_desc_t d;
  memset(&d, 0, sizeof d);
  d.name = "density";
  d.type = OCS_VDB_TYPE_FLOAT;
  d.klass = OCS_VDB_CLASS_FOG;
  d.affine = 1;
  for (int r2 = 0; r2 < 3; r2++) {
    d.i2w[r2][0] = u * Q[r2].x;
    d.i2w[r2][1] = u * Q[r2].y;
    d.i2w[r2][2] = u * Q[r2].z;
    d.i2w[r2][3] = oc_ddot(Q[r2], dP);
  }
  ocs_vdb_writer_t *w = NULL;
  int gi = -1;
  r = api->writer_create(&w);
  if (r == 0) gi = r = api->writer_add_grid(w, &d, sub, sizeof sub);
  if (r < 0) {
    snprintf(why, why_len, "%s: %s", path, r == OC_ENOMEM ? "out of memory" : sub);
    api->writer_free(w);
    return r;
  }
  oc_geo_t cg = oc_xyz_to_geo(C);
  api->writer_set_meta(w, gi, "overcast_origin_lat", cg.lat, NULL);
  api->writer_set_meta(w, gi, "overcast_origin_lon", cg.lon, NULL);
  api->writer_set_meta(w, gi, "overcast_origin_alt", cg.alt, NULL);
  api->writer_set_meta(w, gi, "overcast_level", level, NULL);
  api->writer_set_meta(w, gi, "overcast_time", t, NULL);
  api->writer_set_meta(w, gi, "overcast_frame", 0, "metres, Y-up tangent frame at the origin: +x east, +y up, +z south");
  api->writer_set_meta(w, gi, "overcast_units", 0, "extinction sigma_t in 1/m");

  /* Sample in batches on worker threads, then write each batch in canonical node order. */
  uint64_t total = (uint64_t)e.n[0] * e.n[1] * e.n[2];
  e.f = f;
  e.t = t;
  e.level = level;
  e.vals = malloc(sizeof *e.vals * OCS_VDB_EXPORT_BATCH);
  e.kind = malloc(OCS_VDB_EXPORT_BATCH);
  long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
  int nthreads = ncpu < 1 ? 1 : ncpu > OCS_VDB_EXPORT_THREADS ? OCS_VDB_EXPORT_THREADS : (int)ncpu;
  oc_sanitize_stats_t san;
  memset(&san, 0, sizeof san);
  uint64_t written = 0;
  r = e.vals && e.kind ? 0 : OC_ENOMEM;
  for (uint64_t first = 0; r == 0 && first < total; first += OCS_VDB_EXPORT_BATCH) {
    e.first = first;
    e.count = total - first < OCS_VDB_EXPORT_BATCH ? total - first : OCS_VDB_EXPORT_BATCH;
    atomic_store(&e.next, 0);
    pthread_t th[OCS_VDB_EXPORT_THREADS];
    int started = 0;
    for (int i = 1; i < nthreads && (uint64_t)i < e.count; i++)
      if (pthread_create(&th[started], NULL, ocs__export_worker, &e) == 0) started++;
    ocs__export_worker(&e);
    for (int i = 0; i < started; i++) pthread_join(th[i], NULL);
    if (atomic_load(&e.err)) {
      r = atomic_load(&e.err);
      snprintf(why, why_len, "%s: sampling the field failed: %s", path, oc_strerror(r));
      break;
    }
    for (uint64_t i = 0; i < e.count && r == 0; i++) {
      if (!e.kind[i]) continue;
      uint64_t node = first + i;
      int32_t origin[3] = {(int32_t)(7 * (node % e.n[0])), (int32_t)(7 * ((node / e.n[0]) % e.n[1])),
                           (int32_t)(7 * (node / e.n[0] / e.n[1]))};
      int32_t dims[3] = {8, 8, 8};
      oc_sanitize(e.vals[i], OC_BRICK_VOXELS, &san);
      r = api->writer_set_values(w, gi, origin, dims, e.vals[i]);
      written++;
    }
  }
  free(e.vals);
  free(e.kind);
  if (r == 0) {
    r = api->writer_save(w, path, OCS_VDB_COMPRESS_DEFAULT, sub, sizeof sub);
    if (r < 0) snprintf(why, why_len, "%s: %s", path, sub);
  } else if (!strstr(why, path)) {
    snprintf(why, why_len, "%s: export failed: %s", path, oc_strerror(r));
  }
  api->writer_free(w);
  if (r == 0 && (san.nan || san.inf || san.negative))
    oc_log_warn("%s: the field gave %u NaN, %u infinite and %u negative values (written as 0 or the maximum)", path, san.nan,
                san.inf, san.negative);
  if (r == 0) oc_log_info("%s: %llu of %llu level-%d nodes written", path, (unsigned long long)written, (unsigned long long)total, level);
  return r;
}
