/* source_vdb.c — OpenVDB grids (one file or a numbered sequence) placed on the planet as a field
 * source. OpenVDB itself is behind the shim (vdb_shim.h), loaded on the first vdb source.
 *
 * Placement (docs/vdb.md, "Placement on the planet"): the grid's world frame is taken as Y-up (OpenVDB's
 * and Houdini's convention: +x east, +y up, +z south before the heading). World positions come
 * from the file's transform (scale_m 0: its own, rotated and non-uniform ones included, in metres)
 * or from scale_m metres per index unit. The centre of the bottom face of the first frame's active
 * bounding box (in world space) goes to the anchor (lat, lon, alt); the heading turns the grid
 * clockwise about the local up; the local frame is the tangent (east-north-up) frame at the anchor.
 * All of it composes into one affine map per frame: index = M·(P - A) + m0 for a planet point P.
 *
 * Filtering (Conventions): sample (i, j, k) of a node is the mean of n³ stratified sub-samples of
 * its footprint (edge size/7), each a trilinear read of the shim's mean pyramid at the level whose
 * cells are no larger than the sub-sample spacing. Coarse samples therefore average every voxel
 * under them (each pyramid cell is an exact mean of its voxels); fine samples (footprint below a
 * voxel) are trilinear point samples of the voxels. The bound comes from the shim's min/max
 * pyramid over the footprint grown by the reach of the trilinear reads.
 *
 * Sequences: frames are loaded lazily into a cache of OCS_VDB_FRAME_CACHE slots (least recently
 * used evicted; a frame in use is never evicted), so memory stays bounded whatever the length.
 * Frame 0 is loaded and validated at creation and every frame file must exist then; a later frame
 * that fails to load is logged once per attempt and its nodes fail to sample (OC_EIO). */
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"
#include "ocs_field.h"
#include "vdb_shim.h"
#include "vdb_tools.h"

/*! Frames of a sequence kept in memory at once (least recently used evicted). */
#ifndef OCS_VDB_FRAME_CACHE
#define OCS_VDB_FRAME_CACHE 4
#endif
/*! Most sub-samples per axis of a sample's box filter (n³ trilinear reads of the mean pyramid).
 *  4 keeps every level's mass within 1 % and samples within a few % of the exact box average
 *  (measured in tests/server/test_vdb.c; 2 and 3 lose up to 5 % of a cloud's mass at levels where it
 *  spans one or two samples: docs/vdb.md). */
#ifndef OCS_VDB_SUB
#define OCS_VDB_SUB 4
#endif
/*! Placement limits: a grid spanning more (or less) than this is an error ("absurd placement"). */
#ifndef OCS_VDB_MAX_EXTENT_M
#define OCS_VDB_MAX_EXTENT_M 1.0e6
#endif
#ifndef OCS_VDB_MIN_EXTENT_M
#define OCS_VDB_MIN_EXTENT_M 0.5
#endif
/*! Lowest altitude any corner of a placed grid may reach, metres. */
#define OCS_VDB_MIN_ALT (-1.0e4)
/*! A progress line is shown (on a terminal) only for files at least this large. */
#ifndef OCS_VDB_PROGRESS_MIN_BYTES
#define OCS_VDB_PROGRESS_MIN_BYTES (4u << 20)
#endif

enum { OCS__EMPTY = 0, OCS__LOADING = 1, OCS__READY = 2, OCS__FAILED = 3 };

typedef struct {
  ocs_vdb_grid_t *grid;     /* owned */
  int levels;               /* pyramid levels */
  double M[3][3], m0[3];    /* planet offset d = P - A → fine index: M·d + m0 */
  double vs[3], vs_min;     /* metres per index step along each index axis; their minimum */
  ocs_vdb_grid_info_t info; /* as read, before sanitising */
  ocs_vdb_prep_stats_t prep;
  int grid_index;
  double seconds;           /* open + prepare */
} ocs__frame_t;

typedef struct {
  int index;     /* sequence index held, -1: none */
  int state;     /* OCS__* */
  int refs;      /* samplers using it */
  uint64_t used; /* tick of the last acquire (LRU) */
  ocs__frame_t fr;
} ocs__slot_t;

typedef struct {
  ocs_source_t base; /* first: the field sees an ocs_source_t */
  const ocs_vdb_api_t *api;
  char *file;                   /* path or pattern (one run of '#') */
  char grid[OC_SCENE_GRID_CAP]; /* by name when grid_index < 0 */
  int grid_index;
  oc_dvec3 A;                   /* anchor, planet frame */
  double K[3][3];               /* planet offset → grid world (Y-up, heading undone): rows */
  double scale_m, sigma_scale;
  int has_w_anchor;
  double w_anchor[3];           /* grid world position that goes to the anchor (from frame 0) */
  double extent[3];             /* east, north, up extent of frame 0's placed box, m */
  ocs__frame_t frame0;          /* frame 0's description (its grid pointer is not kept here) */
  int has_seq;
  oc_src_sequence_t seq;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  uint64_t tick;
  int nslots;
  ocs__slot_t slots[OCS_VDB_FRAME_CACHE];
} ocs__vdb_t;

/* ---- Small linear algebra --------------------------------------------------------------------- */

static double ocs__det3(const double a[3][3]) {
  return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
         a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/* Inverse of a 3×3 matrix; @return 0, or -1 when singular or not finite. */
static int ocs__inv3(const double a[3][3], double r[3][3]) {
  double d = ocs__det3(a);
  if (!isfinite(d) || d == 0.0) return -1;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
      r[i][j] = (a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]) / d;
    }
  return 0;
}

/* ---- Frames ------------------------------------------------------------------------------------ */

/* The file of sequence index `index` (the '#' run replaced by first + index, zero-padded). */
void ocs_vdb_frame_path(const char *file, int has_seq, int first, int index, char *out, size_t cap) {
  const char *h = has_seq ? strchr(file, '#') : NULL;
  if (!h) {
    snprintf(out, cap, "%s", file);
    return;
  }
  size_t run = strspn(h, "#");
  snprintf(out, cap, "%.*s%0*d%s", (int)(h - file), file, (int)run, first + index, h + run);
}

static void ocs__frame_path(const ocs__vdb_t *s, int index, char *out, size_t cap) {
  ocs_vdb_frame_path(s->file, s->has_seq, s->seq.first, index, out, cap);
}

typedef struct {
  const char *path;
  int show;
  int last_pct;
  int printed;
} ocs__progress_t;

static void ocs__progress_cb(void *ctx, uint64_t done, uint64_t total) {
  ocs__progress_t *p = ctx;
  if (!p->show || !total) return;
  int pct = (int)(100.0 * (double)done / (double)total);
  if (pct == p->last_pct) return;
  p->last_pct = pct;
  p->printed = 1;
  fprintf(stderr, "\rovercast: loading %s: %3d%% (%.1f of %.1f MB)", p->path, pct, (double)done / 1e6, (double)total / 1e6);
  fflush(stderr);
}

static const char *ocs__class_name(int k) {
  return k == OCS_VDB_CLASS_LEVEL_SET ? "level set" : k == OCS_VDB_CLASS_FOG ? "fog volume" : k == OCS_VDB_CLASS_STAGGERED ? "staggered" : "unknown class";
}

/* Appends "'name' (type, class)" of every grid to buf. */
static void ocs__list_grids(const ocs_vdb_api_t *api, const ocs_vdb_file_t *f, char *buf, size_t cap) {
  int n = api->grid_count(f);
  buf[0] = '\0';
  for (int i = 0; i < n; i++) {
    ocs_vdb_grid_info_t gi;
    if (api->grid_info(f, i, 0, &gi) < 0) continue;
    size_t len = strlen(buf);
    if (len + 1 >= cap) break;
    snprintf(buf + len, cap - len, "%s'%s' (%s, %s)", i ? ", " : "", gi.name,
             gi.type == OCS_VDB_TYPE_POINTS ? "points" : gi.value_type, ocs__class_name(gi.klass));
  }
}

/* Chooses the grid per the desc and checks it can be imported. @return its index or an OC_E*. */
static int ocs__select(const ocs__vdb_t *s, const ocs_vdb_file_t *f, const char *path, ocs_vdb_grid_info_t *gi, char *why,
                       size_t why_len) {
  const ocs_vdb_api_t *api = s->api;
  int n = api->grid_count(f), idx = -1;
  char list[768];
  if (n == 0) {
    snprintf(why, why_len, "%s: the file holds no grids", path);
    return OC_EINVAL;
  }
  if (s->grid_index >= 0) {
    if (s->grid_index >= n) {
      ocs__list_grids(api, f, list, sizeof list);
      snprintf(why, why_len, "%s: grid_index %d, but the file has %d grid(s): %s", path, s->grid_index, n, list);
      return OC_EINVAL;
    }
    idx = s->grid_index;
  } else {
    int matches = 0, floats = 0;
    for (int i = 0; i < n; i++) {
      OC_TRY(api->grid_info(f, i, 0, gi));
      if (gi->type == OCS_VDB_TYPE_FLOAT || gi->type == OCS_VDB_TYPE_DOUBLE) floats++;
      if (strcmp(gi->name, s->grid) == 0) {
        if (idx < 0) idx = i;
        matches++;
      }
    }
    if (idx < 0) {
      ocs__list_grids(api, f, list, sizeof list);
      if (!floats) snprintf(why, why_len, "%s: no float grid in the file (it has %s)", path, list);
      else snprintf(why, why_len, "%s: no grid named '%s' (the file has %s); choose one with grid or grid_index", path, s->grid, list);
      return OC_EINVAL;
    }
    if (matches > 1)
      oc_log_warn("%s: %d grids are named '%s'; using the first (index %d): choose another with grid_index", path, matches,
                  s->grid, idx);
  }
  OC_TRY(api->grid_info(f, idx, 1, gi)); /* with the value range, for --check and tests */
  const char *nm = gi->name;
  if (gi->type == OCS_VDB_TYPE_POINTS) {
    snprintf(why, why_len, "%s: grid '%s' is a point data grid (%llu points), not a volume: rasterise it to a float fog volume first",
             path, nm, (unsigned long long)gi->points);
    return OC_EINVAL;
  }
  if (gi->type != OCS_VDB_TYPE_FLOAT && gi->type != OCS_VDB_TYPE_DOUBLE) {
    snprintf(why, why_len, "%s: grid '%s' has value type %s; a float (density) grid is needed", path, nm, gi->value_type);
    return OC_EINVAL;
  }
  if (gi->klass == OCS_VDB_CLASS_LEVEL_SET) {
    snprintf(why, why_len, "%s: grid '%s' is a level set (a signed distance field), not a fog volume: convert it first "
             "(e.g. OpenVDB's sdfToFogVolume)", path, nm);
    return OC_EINVAL;
  }
  if (!gi->linear) {
    snprintf(why, why_len, "%s: grid '%s' has a non-linear (frustum) transform, which is not supported", path, nm);
    return OC_EINVAL;
  }
  for (int a = 0; a < 3; a++)
    if (!isfinite(gi->voxel_size[a]) || gi->voxel_size[a] <= 0.0) {
      snprintf(why, why_len, "%s: grid '%s' has voxel size (%g, %g, %g): it must be finite and positive", path, nm,
               gi->voxel_size[0], gi->voxel_size[1], gi->voxel_size[2]);
      return OC_EINVAL;
    }
  double R[3][3], Ri[3][3];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) R[r][c] = gi->i2w[r][c];
  if (ocs__inv3(R, Ri) < 0 || !isfinite(gi->i2w[0][3] + gi->i2w[1][3] + gi->i2w[2][3])) {
    snprintf(why, why_len, "%s: grid '%s' has a singular or non-finite transform", path, nm);
    return OC_EINVAL;
  }
  if (gi->active_voxels == 0) {
    snprintf(why, why_len, "%s: grid '%s' is empty (no active voxels)", path, nm);
    return OC_EINVAL;
  }
  return idx;
}

/* Index → grid world (metres) for frame fr's grid: R·i + t (R, t from the file or scale_m). */
static void ocs__i2w(const ocs__vdb_t *s, const ocs_vdb_grid_info_t *gi, double R[3][3], double t[3]) {
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) R[r][c] = s->scale_m > 0.0 ? (r == c ? s->scale_m : 0.0) : gi->i2w[r][c];
    t[r] = s->scale_m > 0.0 ? 0.0 : gi->i2w[r][3];
  }
}

/* Computes the frame's planet → index map and checks the placement (frame 0 also fixes the world
 * point that goes to the anchor). @return 0 or OC_ERANGE / OC_EINVAL with why. */
static int ocs__place(ocs__vdb_t *s, ocs__frame_t *fr, const char *path, char *why, size_t why_len) {
  const ocs_vdb_grid_info_t *gi = &fr->info;
  double R[3][3], Ri[3][3], t[3];
  ocs__i2w(s, gi, R, t);
  if (ocs__inv3(R, Ri) < 0) {
    snprintf(why, why_len, "%s: grid '%s' has a singular transform", path, gi->name);
    return OC_EINVAL;
  }
  /* World corners of the active box (voxel i covers [i - 1/2, i + 1/2]). */
  double wc[8][3], wlo[3] = {INFINITY, INFINITY, INFINITY}, whi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int c = 0; c < 8; c++) {
    double ix[3];
    for (int a = 0; a < 3; a++) ix[a] = ((c >> a) & 1) ? gi->bbox_max[a] + 0.5 : gi->bbox_min[a] - 0.5;
    for (int r = 0; r < 3; r++) {
      wc[c][r] = R[r][0] * ix[0] + R[r][1] * ix[1] + R[r][2] * ix[2] + t[r];
      wlo[r] = fmin(wlo[r], wc[c][r]);
      whi[r] = fmax(whi[r], wc[c][r]);
    }
  }
  int first = !s->has_w_anchor;
  if (first) {
    s->w_anchor[0] = 0.5 * (wlo[0] + whi[0]);
    s->w_anchor[1] = wlo[1]; /* Y-up: the bottom face */
    s->w_anchor[2] = 0.5 * (wlo[2] + whi[2]);
    s->has_w_anchor = 1;
  }
  /* index = Ri·(K·d + w_anchor - t) */
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) fr->M[r][c] = Ri[r][0] * s->K[0][c] + Ri[r][1] * s->K[1][c] + Ri[r][2] * s->K[2][c];
    fr->m0[r] = Ri[r][0] * (s->w_anchor[0] - t[0]) + Ri[r][1] * (s->w_anchor[1] - t[1]) + Ri[r][2] * (s->w_anchor[2] - t[2]);
  }
  fr->vs_min = INFINITY;
  for (int a = 0; a < 3; a++) {
    fr->vs[a] = sqrt(R[0][a] * R[0][a] + R[1][a] * R[1][a] + R[2][a] * R[2][a]);
    fr->vs_min = fmin(fr->vs_min, fr->vs[a]);
  }
  /* The placed box: its extent in the local east-north-up frame and its corners' altitudes. */
  oc_enu_t enu = oc_enu_at(s->A);
  double llo[3] = {INFINITY, INFINITY, INFINITY}, lhi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double ext = 0.0, alt_lo = INFINITY, alt_hi = -INFINITY;
  for (int c = 0; c < 8; c++) {
    double r[3] = {wc[c][0] - s->w_anchor[0], wc[c][1] - s->w_anchor[1], wc[c][2] - s->w_anchor[2]};
    /* K is a rotation: the planet offset is Kᵀ·r */
    oc_dvec3 d = oc_dv3(s->K[0][0] * r[0] + s->K[1][0] * r[1] + s->K[2][0] * r[2],
                        s->K[0][1] * r[0] + s->K[1][1] * r[1] + s->K[2][1] * r[2],
                        s->K[0][2] * r[0] + s->K[1][2] * r[1] + s->K[2][2] * r[2]);
    double l[3] = {oc_ddot(d, enu.east), oc_ddot(d, enu.north), oc_ddot(d, enu.up)};
    for (int a = 0; a < 3; a++) {
      llo[a] = fmin(llo[a], l[a]);
      lhi[a] = fmax(lhi[a], l[a]);
    }
    double alt = oc_dlen(oc_dadd(s->A, d)) - OC_PLANET_RADIUS;
    alt_lo = fmin(alt_lo, alt);
    alt_hi = fmax(alt_hi, alt);
  }
  for (int a = 0; a < 3; a++) ext = fmax(ext, lhi[a] - llo[a]);
  if (!(ext <= OCS_VDB_MAX_EXTENT_M)) {
    snprintf(why, why_len, "%s: absurd placement: grid '%s' would span %.3g km (limit %.0f km); check scale_m or the file's units",
             path, gi->name, ext / 1000.0, OCS_VDB_MAX_EXTENT_M / 1000.0);
    return OC_ERANGE;
  }
  if (!(ext >= OCS_VDB_MIN_EXTENT_M)) {
    snprintf(why, why_len, "%s: absurd placement: grid '%s' would span only %.3g m (at least %.1f m); check scale_m or the file's units",
             path, gi->name, ext, OCS_VDB_MIN_EXTENT_M);
    return OC_ERANGE;
  }
  if (!(alt_hi <= OC_ATMOSPHERE_HEIGHT) || !(alt_lo >= OCS_VDB_MIN_ALT)) {
    snprintf(why, why_len, "%s: absurd placement: grid '%s' would reach altitudes %.3g to %.3g km (allowed %.0f to %.0f km)", path,
             gi->name, alt_lo / 1000.0, alt_hi / 1000.0, OCS_VDB_MIN_ALT / 1000.0, OC_ATMOSPHERE_HEIGHT / 1000.0);
    return OC_ERANGE;
  }
  if (first)
    for (int a = 0; a < 3; a++) s->extent[a] = lhi[a] - llo[a];
  return 0;
}

static void ocs__frame_free(const ocs__vdb_t *s, ocs__frame_t *fr) {
  if (fr->grid) s->api->grid_free(fr->grid);
  *fr = (ocs__frame_t){0}; /* not memset: gcc -O3 inlining reports a false array-bounds error */
}

/* Loads sequence index `index` into fr: open, select, prepare, place. */
static int ocs__frame_load(ocs__vdb_t *s, int index, int show_progress, ocs__frame_t *fr, char *why, size_t why_len) {
  char path[OC_SCENE_PATH_MAX + 32], sub[512];
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  memset(fr, 0, sizeof *fr);
  ocs__frame_path(s, index, path, sizeof path);
  struct stat st;
  ocs__progress_t prog = {path, show_progress && isatty(2) && stat(path, &st) == 0 && st.st_size >= (off_t)OCS_VDB_PROGRESS_MIN_BYTES, -1, 0};
  ocs_vdb_file_t *f = NULL;
  int r = s->api->open(path, ocs__progress_cb, &prog, &f, sub, sizeof sub);
  if (prog.printed) fprintf(stderr, "\r\033[K");
  if (r < 0) {
    snprintf(why, why_len, "%s: %s", path, sub);
    return r;
  }
  r = ocs__select(s, f, path, &fr->info, why, why_len);
  if (r >= 0) {
    fr->grid_index = r;
    r = s->api->grid_prepare(f, fr->grid_index, &fr->grid, &fr->prep, sub, sizeof sub);
    if (r < 0) snprintf(why, why_len, "%s: %s", path, sub);
  }
  s->api->close(f);
  if (r < 0) {
    ocs__frame_free(s, fr);
    return r;
  }
  fr->levels = s->api->grid_levels(fr->grid);
  if (fr->prep.nan || fr->prep.inf || fr->prep.negative)
    oc_log_warn("%s: grid '%s': %llu NaN, %llu infinite and %llu negative voxel values replaced by 0", path, fr->info.name,
                (unsigned long long)fr->prep.nan, (unsigned long long)fr->prep.inf, (unsigned long long)fr->prep.negative);
  r = ocs__place(s, fr, path, why, why_len);
  if (r < 0) {
    ocs__frame_free(s, fr);
    return r;
  }
  clock_gettime(CLOCK_MONOTONIC, &t1);
  fr->seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
  return 0;
}

/* Sequence index shown at world time t. */
static int ocs__frame_at(const ocs__vdb_t *s, double t) {
  /* animation off (the scene's feature): the first frame always, as time_step() says */
  if (!s->has_seq || s->seq.count <= 1 || !s->base.animated || !isfinite(t)) return 0;
  double fl = floor(t * s->seq.frame_rate);
  int64_t n = s->seq.count;
  if (s->seq.end == OC_SEQ_HOLD) return fl <= 0.0 ? 0 : fl >= (double)(n - 1) ? (int)(n - 1) : (int)fl;
  double m = fmod(fl, (double)n);
  if (m < 0) m += (double)n;
  return (int)m;
}

/* The frame for index, loaded if needed. NULL when it cannot be loaded. Pair with ocs__release. */
static ocs__slot_t *ocs__acquire(ocs__vdb_t *s, int index) {
  if (!s->has_seq) return &s->slots[0]; /* loaded at creation, never evicted */
  pthread_mutex_lock(&s->mu);
  for (;;) {
    ocs__slot_t *hit = NULL, *victim = NULL;
    for (int i = 0; i < s->nslots; i++) {
      ocs__slot_t *sl = &s->slots[i];
      if (sl->index == index) {
        hit = sl;
        break;
      }
      if (sl->refs == 0 && sl->state != OCS__LOADING && (!victim || sl->used < victim->used)) victim = sl;
    }
    if (hit) {
      if (hit->state == OCS__LOADING) {
        pthread_cond_wait(&s->cv, &s->mu);
        continue;
      }
      if (hit->state != OCS__READY) {
        pthread_mutex_unlock(&s->mu);
        return NULL;
      }
      hit->refs++;
      hit->used = ++s->tick;
      pthread_mutex_unlock(&s->mu);
      return hit;
    }
    if (!victim) { /* every slot busy: wait for a release */
      pthread_cond_wait(&s->cv, &s->mu);
      continue;
    }
    ocs__frame_t old = victim->fr;
    memset(&victim->fr, 0, sizeof victim->fr);
    victim->index = index;
    victim->state = OCS__LOADING;
    victim->refs = 1;
    victim->used = ++s->tick;
    pthread_mutex_unlock(&s->mu);
    ocs__frame_free(s, &old);
    ocs__frame_t fr;
    char why[1024];
    int r = ocs__frame_load(s, index, 0, &fr, why, sizeof why);
    if (r < 0) oc_log_error("vdb sequence frame %d: %s", index, why);
    pthread_mutex_lock(&s->mu);
    if (r < 0) {
      victim->state = OCS__FAILED;
      victim->refs = 0;
    } else {
      victim->fr = fr;
      victim->state = OCS__READY;
    }
    pthread_cond_broadcast(&s->cv);
    pthread_mutex_unlock(&s->mu);
    return r < 0 ? NULL : victim;
  }
}

static void ocs__release(ocs__vdb_t *s, ocs__slot_t *sl) {
  if (!s->has_seq) return;
  pthread_mutex_lock(&s->mu);
  if (--sl->refs == 0) pthread_cond_broadcast(&s->cv);
  pthread_mutex_unlock(&s->mu);
}

/* ---- Sampling ---------------------------------------------------------------------------------- */

/* Sub-samples per axis n and pyramid level for samples whose footprint edge is `foot` metres.
 * n grows with the footprint in voxels up to OCS_VDB_SUB; the sub-samples form a regular lattice of
 * spacing d = foot/n (continuous across samples). The level's cells (2^l voxels) are the nearest
 * power of two to d: cells much smaller than d would alias (the lattice would skip cells and the
 * level's mass would depend on where the lattice falls), much larger ones would blur. */
static void ocs__plan(const ocs__frame_t *fr, double foot, int *n_out, int *level_out) {
  double e = foot / fr->vs_min; /* footprint in the finest voxels */
  int n = e <= 1.0 + 1e-9 ? 1 : e >= (double)OCS_VDB_SUB ? OCS_VDB_SUB : (int)ceil(e - 1e-9);
  double d = INFINITY;
  for (int a = 0; a < 3; a++) d = fmin(d, foot / ((double)n * fr->vs[a]));
  int l = d > 1.0 ? (int)lround(log2(d)) : 0;
  if (l > fr->levels - 1) l = fr->levels - 1;
  *n_out = n;
  *level_out = l;
}

static inline void ocs__to_index(const ocs__frame_t *fr, const double d[3], double out[3]) {
  for (int r = 0; r < 3; r++) out[r] = fr->M[r][0] * d[0] + fr->M[r][1] * d[1] + fr->M[r][2] * d[2] + fr->m0[r];
}

/* Raw grid-value range over a planet box, grown by the reach of the trilinear reads that sample
 * nodes whose footprint box this is (edge 8/7 of the node). */
static void ocs__frame_range(const ocs__vdb_t *s, const ocs__frame_t *fr, oc_dvec3 lo, oc_dvec3 hi, float *vmin, float *vmax) {
  double ilo[3] = {INFINITY, INFINITY, INFINITY}, ihi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int c = 0; c < 8; c++) {
    double d[3] = {(c & 1 ? hi.x : lo.x) - s->A.x, (c & 2 ? hi.y : lo.y) - s->A.y, (c & 4 ? hi.z : lo.z) - s->A.z}, x[3];
    ocs__to_index(fr, d, x);
    for (int a = 0; a < 3; a++) {
      ilo[a] = fmin(ilo[a], x[a]);
      ihi[a] = fmax(ihi[a], x[a]);
    }
  }
  double edge = fmax(hi.x - lo.x, fmax(hi.y - lo.y, hi.z - lo.z));
  int n, l;
  ocs__plan(fr, edge / 8.0, &n, &l);
  double reach = 1.5 * ldexp(1.0, l) + 1.0;
  int32_t qlo[3], qhi[3];
  for (int a = 0; a < 3; a++) {
    double a0 = floor(ilo[a] - reach), a1 = ceil(ihi[a] + reach);
    if (!(a0 == a0) || !(a1 == a1)) { /* NaN box */
      *vmin = *vmax = 0.0f;
      return;
    }
    qlo[a] = (int32_t)fmax(-1073741824.0, fmin(1073741824.0, a0));
    qhi[a] = (int32_t)fmax(-1073741824.0, fmin(1073741824.0, a1));
  }
  s->api->grid_range(fr->grid, qlo, qhi, vmin, vmax);
}

static void ocs__vdb_bound(const ocs_source_t *src, oc_dvec3 lo, oc_dvec3 hi, double t, float *smin, float *smax) {
  ocs__vdb_t *s = (ocs__vdb_t *)src;
  *smin = 0.0f;
  *smax = FLT_MAX; /* a frame that cannot be read: nothing is known, and its sample() fails (OC_EIO) */
  ocs__slot_t *sl = ocs__acquire(s, ocs__frame_at(s, t));
  if (!sl) return;
  float a, b;
  ocs__frame_range(s, &sl->fr, lo, hi, &a, &b);
  ocs__release(s, sl);
  *smin = (float)(a * s->sigma_scale);
  *smax = (float)(b * s->sigma_scale);
}

static int ocs__vdb_sample(const ocs_source_t *src, oc_key_t key, double t, float out[OC_BRICK_VOXELS]) {
  ocs__vdb_t *s = (ocs__vdb_t *)src;
  int level = oc_key_level(key);
  if (level < 0) return OC_EINVAL;
  ocs__slot_t *sl = ocs__acquire(s, ocs__frame_at(s, t));
  if (!sl) return OC_EIO;
  const ocs__frame_t *fr = &sl->fr;
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = size / 14.0;
  float vmin, vmax;
  ocs__frame_range(s, fr, oc_dv3(o.x - g, o.y - g, o.z - g), oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g), &vmin, &vmax);
  if (vmax <= 0.0f) goto done;
  if (vmin == vmax) {
    float v = (float)(vmax * s->sigma_scale);
    for (int i = 0; i < OC_BRICK_VOXELS; i++) out[i] += v;
    goto done;
  }
  int n, l;
  ocs__plan(fr, size / 7.0, &n, &l);
  {
    /* Global lattice coordinates, as ocs_brick_sample: −S + (g + f)·u, the same from any node, so
     * shared face samples agree bit for bit. Per axis, its contribution to the index position. */
    uint32_t ic[3];
    oc_key_coords(key, &ic[0], &ic[1], &ic[2]);
    double u = ldexp(2.0 * OC_ROOT_HALF / 7.0, -level), A[3] = {s->A.x, s->A.y, s->A.z};
    double part[3][8][OCS_VDB_SUB][3]; /* [axis][sample][sub][index component] */
    for (int a = 0; a < 3; a++)
      for (int i = 0; i < 8; i++)
        for (int m = 0; m < n; m++) {
          double off = ((double)m + 0.5) / (double)n - 0.5;
          double d = -OC_ROOT_HALF + ((double)(7 * (int64_t)ic[a] + i) + off) * u - A[a];
          for (int r = 0; r < 3; r++) part[a][i][m][r] = fr->M[r][a] * d;
        }
    double pts[8 * OCS_VDB_SUB * OCS_VDB_SUB * OCS_VDB_SUB * 3];
    float vals[8 * OCS_VDB_SUB * OCS_VDB_SUB * OCS_VDB_SUB];
    int per = n * n * n;
    double scale = s->sigma_scale / (double)per;
    for (int k = 0; k < 8; k++)
      for (int j = 0; j < 8; j++) {
        int c = 0;
        for (int i = 0; i < 8; i++)
          for (int mz = 0; mz < n; mz++)
            for (int my = 0; my < n; my++)
              for (int mx = 0; mx < n; mx++, c++)
                for (int r = 0; r < 3; r++)
                  pts[3 * c + r] = part[0][i][mx][r] + part[1][j][my][r] + part[2][k][mz][r] + fr->m0[r];
        s->api->grid_sample(fr->grid, l, pts, (size_t)c, vals);
        for (int i = 0; i < 8; i++) {
          double sum = 0.0;
          for (int q = 0; q < per; q++) sum += vals[i * per + q];
          out[i + 8 * j + 64 * k] += (float)(sum * scale);
        }
      }
  }
done:
  ocs__release(s, sl);
  return 0;
}

static uint64_t ocs__vdb_step(const ocs_source_t *src, int level, double t) {
  (void)level;
  const ocs__vdb_t *s = (const ocs__vdb_t *)src;
  return src->animated ? (uint64_t)ocs__frame_at(s, t) : 0;
}

static double ocs__vdb_point(const ocs_source_t *src, oc_dvec3 p, double t) {
  ocs__vdb_t *s = (ocs__vdb_t *)src;
  ocs__slot_t *sl = ocs__acquire(s, ocs__frame_at(s, t));
  if (!sl) return 0.0;
  double d[3] = {p.x - s->A.x, p.y - s->A.y, p.z - s->A.z}, x[3];
  float v;
  ocs__to_index(&sl->fr, d, x);
  s->api->grid_sample(sl->fr.grid, 0, x, 1, &v);
  ocs__release(s, sl);
  return v * s->sigma_scale;
}

static void ocs__vdb_destroy(ocs_source_t *src) {
  ocs__vdb_t *s = (ocs__vdb_t *)src;
  if (!s) return;
  for (int i = 0; i < s->nslots; i++) ocs__frame_free(s, &s->slots[i].fr);
  pthread_cond_destroy(&s->cv);
  pthread_mutex_destroy(&s->mu);
  free(s->file);
  free(s);
}

static const ocs_source_vtbl_t ocs__vdb_vt = {.name = "vdb",
                                              .bound = ocs__vdb_bound,
                                              .sample = ocs__vdb_sample,
                                              .time_step = ocs__vdb_step,
                                              .point = ocs__vdb_point,
                                              .destroy = ocs__vdb_destroy,
                                              .bound_by_step = 0 /* bound() reads the frame of t, loading files: not cached */};

int ocs_source_vdb_create(ocs_source_t **out, const oc_source_t *desc, char *why, size_t why_len) {
  char scratch[8];
  if (!why) {
    why = scratch;
    why_len = sizeof scratch;
  }
  if (!out) return OC_EINVAL;
  *out = NULL;
  if (!desc || desc->type != OC_SOURCE_VDB || !desc->vdb.file || !desc->vdb.file[0]) {
    snprintf(why, why_len, "not a vdb source with a file");
    return OC_EINVAL;
  }
  const oc_src_vdb_t *v = &desc->vdb;
  if (!(v->scale_m >= 0.0) || !isfinite(v->scale_m) || !(v->sigma_scale >= 0.0) || !isfinite(v->sigma_scale) ||
      !isfinite(v->heading) || !isfinite(v->anchor.lat) || !isfinite(v->anchor.lon) || !isfinite(v->anchor.alt) ||
      fabs(v->anchor.lat) > 90.0) {
    snprintf(why, why_len, "%s: invalid placement (scale_m, sigma_scale, heading, lat/lon/alt)", v->file);
    return OC_EINVAL;
  }
  if (v->has_sequence && (v->sequence.count < 1 || !(v->sequence.frame_rate > 0.0) || !strchr(v->file, '#'))) {
    snprintf(why, why_len, "%s: a sequence needs count ≥ 1, frame_rate > 0 and a run of '#' in the file name", v->file);
    return OC_EINVAL;
  }
  const ocs_vdb_api_t *api;
  char sub[1536];
  int r = ocs_vdb_load(&api, sub, sizeof sub);
  if (r < 0) {
    snprintf(why, why_len, "%s: %s", v->file, sub);
    return r;
  }
  ocs__vdb_t *s = calloc(1, sizeof *s);
  if (!s) return OC_ENOMEM;
  s->file = strdup(v->file);
  if (!s->file) {
    free(s);
    return OC_ENOMEM;
  }
  s->api = api;
  snprintf(s->grid, sizeof s->grid, "%s", v->grid[0] ? v->grid : "density");
  s->grid_index = v->grid_index;
  s->scale_m = v->scale_m;
  s->sigma_scale = v->sigma_scale;
  s->has_seq = v->has_sequence;
  s->seq = v->sequence;
  s->A = oc_geo_to_xyz(v->anchor);
  /* K: planet offset → grid world relative to the anchor (Y-up: x east, y up, z south), with the
   * heading undone: e0 = e cos h − n sin h, n0 = e sin h + n cos h; rows (e0, u, −n0). */
  oc_enu_t enu = oc_enu_at(s->A);
  double h = v->heading * OC_DEG, ch = cos(h), sh = sin(h);
  oc_dvec3 row0 = oc_dsub(oc_dscale(enu.east, ch), oc_dscale(enu.north, sh));
  oc_dvec3 row2 = oc_dscale(oc_dadd(oc_dscale(enu.east, sh), oc_dscale(enu.north, ch)), -1.0);
  oc_dvec3 rows[3] = {row0, enu.up, row2};
  for (int i = 0; i < 3; i++) {
    s->K[i][0] = rows[i].x;
    s->K[i][1] = rows[i].y;
    s->K[i][2] = rows[i].z;
  }
  pthread_mutex_init(&s->mu, NULL);
  pthread_cond_init(&s->cv, NULL);
  s->nslots = !s->has_seq ? 1 : s->seq.count < OCS_VDB_FRAME_CACHE ? s->seq.count : OCS_VDB_FRAME_CACHE;
  for (int i = 0; i < s->nslots; i++) s->slots[i].index = -1;
  s->base.vt = &ocs__vdb_vt;
  s->base.animated = s->has_seq && s->seq.count > 1;
  /* Every frame file must exist now; frame 0 is loaded and checked (it fixes the placement). */
  if (s->has_seq) {
    for (int i = 0; i < s->seq.count; i++) {
      char path[OC_SCENE_PATH_MAX + 32];
      struct stat st;
      ocs__frame_path(s, i, path, sizeof path);
      if (stat(path, &st) != 0) {
        snprintf(why, why_len, "%s: frame %d of %d: no such file", path, i, s->seq.count);
        ocs__vdb_destroy(&s->base);
        return OC_ENOENT;
      }
    }
  }
  r = ocs__frame_load(s, 0, 1, &s->slots[0].fr, why, why_len);
  if (r < 0) {
    ocs__vdb_destroy(&s->base);
    return r;
  }
  s->frame0 = s->slots[0].fr;
  s->frame0.grid = NULL;
  s->slots[0].index = 0;
  s->slots[0].state = OCS__READY;
  s->slots[0].used = ++s->tick;
  *out = &s->base;
  return 0;
}

int ocs_vdb_source_info(const ocs_source_t *src, ocs_vdb_source_info_t *out) {
  if (!src || !out || src->vt != &ocs__vdb_vt) return OC_EINVAL;
  const ocs__vdb_t *s = (const ocs__vdb_t *)src;
  const ocs__frame_t *fr = &s->frame0;
  memset(out, 0, sizeof *out);
  out->grid = fr->info;
  out->prep = fr->prep;
  out->grid_index = fr->grid_index;
  out->load_seconds = fr->seconds;
  for (int a = 0; a < 3; a++) {
    out->extent_m[a] = s->extent[a];
    out->voxel_m[a] = fr->vs[a];
  }
  out->anchor = s->A;
  out->frames = s->has_seq ? s->seq.count : 1;
  out->cache_slots = s->nslots;
  return 0;
}
