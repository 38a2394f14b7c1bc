/* oc_scene.c — strict scene-file reader (see oc_scene.h, docs/scene.md).
 *
 * Every object is checked against its list of allowed keys before any value is read, so an
 * unknown or duplicate key is reported before anything else in that object. Errors stop at the
 * first problem: one line, "<file>: <key path>: <what is wrong>". */
#include "oc_scene.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h> /* fstat: regular files only */

#include "oc_err.h"
#include "oc_log.h"

/*-*** Defaults (docs/scene.md lists the same values) ***/

#define OC__DEF_SEED 1
#define OC__DEF_EPOCH_PERIOD 1.0
#define OC__DEF_SUN_LAT 20.0
#define OC__DEF_SUN_LON 10.0
#define OC__DEF_CAM_LAT 45.0
#define OC__DEF_CAM_LON 0.0
#define OC__DEF_CAM_ALT 2000.0
#define OC__DEF_CAM_HEADING 260.0
#define OC__DEF_CAM_PITCH -5.0
#define OC__DEF_CAM_FOV 60.0
#define OC__DEF_ALBEDO 1.0
#define OC__DEF_MS_OCTAVES 4
/* Octave factors fitted to the Monte Carlo truth with shaders/march.h's constants (docs/numerics.md). */
#define OC__DEF_MS_A 0.6139
#define OC__DEF_MS_B 0.5139
#define OC__DEF_MS_C 0.9924
#define OC__DEF_VDB_FRAME_RATE 24.0

#define OC__MAX_SEED 9007199254740991.0 /* 2^53 - 1: the largest integer a JSON number holds exactly */
#define OC__SRC_ALT_MIN -1e4
#define OC__SRC_ALT_MAX 1e5

/*-*** Names ***/

static const char *const oc__feature_names[OC_FEATURE_COUNT] = {
    "animation", "atmosphere", "shadows", "multiple_scattering", "ozone", "planet_surface"};
static const char *const oc__preset_names[OC_PRESET_COUNT] = {"clear", "fair", "overcast", "storm", "cirrus"};
static const char *const oc__type_names[] = {NULL, "sphere", "box", "slab", "procedural", "vdb"};
static const char *const oc__seq_end_names[] = {"loop", "hold"};

const char *oc_scene_feature_name(int f) { return f >= 0 && f < OC_FEATURE_COUNT ? oc__feature_names[f] : NULL; }
const char *oc_scene_preset_name(int p) { return p >= 0 && p < OC_PRESET_COUNT ? oc__preset_names[p] : NULL; }
const char *oc_scene_source_type_name(int t) { return t >= OC_SOURCE_SPHERE && t <= OC_SOURCE_VDB ? oc__type_names[t] : NULL; }

int oc_scene_preset_parse(const char *name) {
  if (!name) return OC_EINVAL;
  for (int i = 0; i < OC_PRESET_COUNT; i++)
    if (strcmp(name, oc__preset_names[i]) == 0) return i;
  return OC_EINVAL;
}

/*-*** Parse context: file name, key path, error text ***/

typedef struct {
  const char *file; /* name for errors */
  char *why;
  size_t why_len;
  char path[512]; /* current key path, e.g. "sources[1].size[2]" */
  size_t plen;
} oc__ctx_t;

/* Printable, bounded copy of untrusted text (keys, enum strings) for messages. */
static void oc__sanitize(char *dst, size_t cap, const char *src) {
  size_t n = 0;
  const size_t keep = cap > 44 ? 40 : cap - 4;
  for (; *src && n < keep; src++) dst[n++] = ((unsigned char)*src < 0x20 || *src == 0x7f) ? '?' : *src;
  if (*src) {
    memcpy(dst + n, "...", 3);
    n += 3;
  }
  dst[n] = '\0';
}

static size_t oc__push_key(oc__ctx_t *c, const char *key) {
  size_t old = c->plen;
  char clean[64];
  oc__sanitize(clean, sizeof clean, key);
  int w = snprintf(c->path + c->plen, sizeof c->path - c->plen, "%s%s", c->plen ? "." : "", clean);
  if (w > 0) c->plen = strlen(c->path);
  return old;
}

static size_t oc__push_index(oc__ctx_t *c, int i) {
  size_t old = c->plen;
  int w = snprintf(c->path + c->plen, sizeof c->path - c->plen, "[%d]", i);
  if (w > 0) c->plen = strlen(c->path);
  return old;
}

static void oc__pop(oc__ctx_t *c, size_t old) {
  c->plen = old;
  c->path[old] = '\0';
}

/* "<file>: <path>: <message>" (no path part at the top level); @return OC_ESCENE. */
static int oc__fail(oc__ctx_t *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int oc__fail(oc__ctx_t *c, const char *fmt, ...) {
  if (c->why && c->why_len) {
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (c->plen)
      snprintf(c->why, c->why_len, "%s: %s: %s", c->file, c->path, msg);
    else
      snprintf(c->why, c->why_len, "%s: %s", c->file, msg);
  }
  return OC_ESCENE;
}

static const char *oc__type_of(const cJSON *v) {
  if (cJSON_IsNumber(v)) return "a number";
  if (cJSON_IsString(v)) return "a string";
  if (cJSON_IsBool(v)) return "a boolean";
  if (cJSON_IsNull(v)) return "null";
  if (cJSON_IsArray(v)) return "an array";
  if (cJSON_IsObject(v)) return "an object";
  return "an invalid value";
}

/* Integers below 1e7 in full ("60", not "6e+01"), else the shortest %g form that reads back as
 * the same double: 0.1 stays "0.1", 2^53-1 stays exact. */
static void oc__fmt_num(char *dst, size_t cap, double v) {
  if (v == floor(v) && fabs(v) < 1e7) {
    snprintf(dst, cap, "%.0f", v);
    return;
  }
  for (int prec = 1; prec <= 17; prec++) {
    snprintf(dst, cap, "%.*g", prec, v);
    if (strtod(dst, NULL) == v) return;
  }
}

/*-*** Keys ***/

static int oc__edit_distance(const char *a, const char *b) {
  size_t la = strlen(a), lb = strlen(b);
  int row[64];
  if (la > 62 || lb > 62) return 99;
  for (size_t j = 0; j <= lb; j++) row[j] = (int)j;
  for (size_t i = 1; i <= la; i++) {
    int diag = row[0];
    row[0] = (int)i;
    for (size_t j = 1; j <= lb; j++) {
      int up = row[j];
      int cost = a[i - 1] == b[j - 1] ? 0 : 1;
      int best = diag + cost;
      if (up + 1 < best) best = up + 1;
      if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
      row[j] = best;
      diag = up;
    }
  }
  return row[lb];
}

/* Every key of `obj` must be in `allowed` (NULL-terminated, at most 32) and appear once. */
static int oc__check_keys(oc__ctx_t *c, const cJSON *obj, const char *const *allowed) {
  uint32_t seen = 0;
  for (const cJSON *it = obj->child; it; it = it->next) {
    const char *key = it->string ? it->string : "";
    int idx = -1;
    for (int i = 0; allowed[i]; i++)
      if (strcmp(key, allowed[i]) == 0) idx = i;
    if (idx < 0) {
      char clean[64];
      const char *best = NULL;
      int bestd = 3;
      oc__sanitize(clean, sizeof clean, key);
      for (int i = 0; allowed[i]; i++) {
        int d = oc__edit_distance(key, allowed[i]);
        if (d < bestd) bestd = d, best = allowed[i];
      }
      if (best) return oc__fail(c, "unknown key \"%s\" (did you mean \"%s\"?)", clean, best);
      char list[512];
      size_t n = 0;
      list[0] = '\0';
      for (int i = 0; allowed[i] && n < sizeof list; i++)
        n += (size_t)snprintf(list + n, sizeof list - n, "%s%s", i ? ", " : "", allowed[i]);
      return oc__fail(c, "unknown key \"%s\" (allowed: %s)", clean, list);
    }
    size_t old = oc__push_key(c, key);
    if (seen & (1u << idx)) return oc__fail(c, "duplicate key");
    seen |= 1u << idx;
    oc__pop(c, old);
  }
  return 0;
}

/*-*** Typed getters ***/

enum {
  OC__REQ = 1u << 0,     /* missing is an error */
  OC__LO_OPEN = 1u << 1, /* (lo, ... */
  OC__HI_OPEN = 1u << 2, /* ..., hi) */
  OC__INT = 1u << 3      /* must be an integer */
};

static int oc__missing(oc__ctx_t *c, const char *key) {
  char clean[64];
  oc__sanitize(clean, sizeof clean, key);
  return oc__fail(c, "missing required key \"%s\"", clean);
}

/* An absent member: an error when it is required (OC__REQ in flags), else 0. */
static int oc__absent(oc__ctx_t *c, const char *key, unsigned flags) { return (flags & OC__REQ) ? oc__missing(c, key) : 0; }

/* Member `key` of obj. Present: .v, with the key pushed onto the error path (oc__pop(c, .old) takes it off).
 * Absent: .v is NULL and .rc is oc__absent's answer (0 when optional, an error when OC__REQ). */
typedef struct {
  const cJSON *v;
  size_t old;
  int rc;
} oc__member_t;

static oc__member_t oc__member(oc__ctx_t *c, const cJSON *obj, const char *key, unsigned flags) {
  oc__member_t m = {cJSON_GetObjectItemCaseSensitive(obj, key), 0, 0};
  if (m.v) m.old = oc__push_key(c, key);
  else m.rc = oc__absent(c, key, flags);
  return m;
}

static int oc__check_num(oc__ctx_t *c, const cJSON *v, double lo, double hi, unsigned flags, double *out) {
  if (!cJSON_IsNumber(v)) return oc__fail(c, "expected %s, got %s", (flags & OC__INT) ? "an integer" : "a number", oc__type_of(v));
  double x = v->valuedouble;
  if (!isfinite(x)) return oc__fail(c, "number is not finite (beyond the range of a double)");
  if ((flags & OC__INT) && x != floor(x)) {
    char xs[32];
    oc__fmt_num(xs, sizeof xs, x);
    return oc__fail(c, "expected an integer, got %s", xs);
  }
  int below = (flags & OC__LO_OPEN) ? !(x > lo) : !(x >= lo);
  int above = (flags & OC__HI_OPEN) ? !(x < hi) : !(x <= hi);
  if (below || above) {
    char xs[32], los[32], his[32];
    oc__fmt_num(xs, sizeof xs, x);
    oc__fmt_num(los, sizeof los, lo);
    oc__fmt_num(his, sizeof his, hi);
    return oc__fail(c, "%s is out of range %c%s, %s%c", xs, (flags & OC__LO_OPEN) ? '(' : '[', los, his,
                    (flags & OC__HI_OPEN) ? ')' : ']');
  }
  *out = x;
  return 0;
}

static int oc__num(oc__ctx_t *c, const cJSON *obj, const char *key, double lo, double hi, unsigned flags, double def,
                   double *out) {
  *out = def; /* kept when absent */
  oc__member_t m = oc__member(c, obj, key, flags);
  if (!m.v) return m.rc;
  OC_TRY(oc__check_num(c, m.v, lo, hi, flags, out));
  oc__pop(c, m.old);
  return 0;
}

static int oc__int(oc__ctx_t *c, const cJSON *obj, const char *key, int lo, int hi, unsigned flags, int def, int *out) {
  double d;
  OC_TRY(oc__num(c, obj, key, lo, hi, flags | OC__INT, def, &d));
  *out = (int)d;
  return 0;
}

static int oc__bool(oc__ctx_t *c, const cJSON *obj, const char *key, bool def, bool *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) {
    *out = def;
    return 0;
  }
  size_t old = oc__push_key(c, key);
  if (!cJSON_IsBool(v)) return oc__fail(c, "expected true or false, got %s", oc__type_of(v));
  *out = cJSON_IsTrue(v);
  oc__pop(c, old);
  return 0;
}

/* A string of 1..max_len bytes without control characters; *out points into the cJSON tree. */
static int oc__str(oc__ctx_t *c, const cJSON *obj, const char *key, size_t max_len, unsigned flags, const char *def,
                   const char **out) {
  *out = def; /* kept when absent */
  oc__member_t m = oc__member(c, obj, key, flags);
  if (!m.v) return m.rc;
  if (!cJSON_IsString(m.v) || !m.v->valuestring) return oc__fail(c, "expected a string, got %s", oc__type_of(m.v));
  size_t n = strlen(m.v->valuestring);
  if (n == 0) return oc__fail(c, "must not be empty");
  if (n > max_len) return oc__fail(c, "longer than %zu bytes", max_len);
  for (size_t i = 0; i < n; i++)
    if ((unsigned char)m.v->valuestring[i] < 0x20 || m.v->valuestring[i] == 0x7f)
      return oc__fail(c, "contains a control character");
  *out = m.v->valuestring;
  oc__pop(c, m.old);
  return 0;
}

static int oc__enum(oc__ctx_t *c, const cJSON *obj, const char *key, const char *const *names, int n, const char *what,
                    int def, int *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) {
    *out = def;
    return 0;
  }
  size_t old = oc__push_key(c, key);
  if (!cJSON_IsString(v) || !v->valuestring) return oc__fail(c, "expected a string, got %s", oc__type_of(v));
  for (int i = 0; i < n; i++)
    if (names[i] && strcmp(v->valuestring, names[i]) == 0) {
      *out = i;
      oc__pop(c, old);
      return 0;
    }
  char clean[64], list[256];
  size_t len = 0;
  oc__sanitize(clean, sizeof clean, v->valuestring);
  list[0] = '\0';
  for (int i = 0; i < n; i++)
    if (names[i]) len += (size_t)snprintf(list + len, sizeof list - len, "%s\"%s\"", len ? ", " : "", names[i]);
  return oc__fail(c, "unknown %s \"%s\" (expected one of %s)", what, clean, list);
}

/* `key` must be an object (or absent: *out = NULL). */
static int oc__obj(oc__ctx_t *c, const cJSON *obj, const char *key, const cJSON **out) {
  *out = NULL;
  oc__member_t m = oc__member(c, obj, key, 0);
  if (!m.v) return m.rc;
  if (!cJSON_IsObject(m.v)) return oc__fail(c, "expected an object, got %s", oc__type_of(m.v));
  oc__pop(c, m.old);
  *out = m.v;
  return 0;
}

/* `key` must be an array of exactly n numbers in [lo, hi] (flags as for oc__num). */
static int oc__vec(oc__ctx_t *c, const cJSON *obj, const char *key, int n, double lo, double hi, unsigned flags,
                   double *out) {
  oc__member_t m = oc__member(c, obj, key, flags);
  if (!m.v) return m.rc;
  if (!cJSON_IsArray(m.v)) return oc__fail(c, "expected an array of %d numbers, got %s", n, oc__type_of(m.v));
  int count = cJSON_GetArraySize(m.v);
  if (count != n) return oc__fail(c, "expected %d numbers, got %d", n, count);
  int i = 0;
  for (const cJSON *it = m.v->child; it; it = it->next, i++) {
    size_t o2 = oc__push_index(c, i);
    OC_TRY(oc__check_num(c, it, lo, hi, flags & ~(unsigned)OC__REQ, &out[i]));
    oc__pop(c, o2);
  }
  oc__pop(c, m.old);
  return 0;
}

/*-*** Sections ***/

/* lat/lon/alt of a position; alt in [alt_lo, alt_hi]. */
static int oc__geo(oc__ctx_t *c, const cJSON *o, double alt_lo, double alt_hi, unsigned alt_flags, double def_lat,
                   double def_lon, double def_alt, oc_geo_t *g) {
  OC_TRY(oc__num(c, o, "lat", -90, 90, 0, def_lat, &g->lat));
  OC_TRY(oc__num(c, o, "lon", -180, 180, 0, def_lon, &g->lon));
  OC_TRY(oc__num(c, o, "alt", alt_lo, alt_hi, alt_flags, def_alt, &g->alt));
  return 0;
}

static int oc__parse_features(oc__ctx_t *c, const cJSON *o, uint32_t *features, bool *animation_given) {
  static const char *const keys[] = {"animation", "atmosphere", "shadows", "multiple_scattering", "ozone",
                                     "planet_surface", NULL};
  *animation_given = false;
  if (!o) return 0;
  OC_TRY(oc__check_keys(c, o, keys));
  for (int f = 0; f < OC_FEATURE_COUNT; f++) {
    bool on = true;
    OC_TRY(oc__bool(c, o, oc__feature_names[f], true, &on));
    if (f == OC_FEATURE_ANIMATION) *animation_given = cJSON_GetObjectItemCaseSensitive(o, "animation") != NULL;
    *features = on ? (*features | (1u << f)) : (*features & ~(1u << f));
  }
  return 0;
}

static oc_dvec3 oc__subsolar(double lat_deg, double lon_deg) {
  double lat = lat_deg * OC_DEG, lon = lon_deg * OC_DEG;
  return oc_dv3(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
}

static int oc__parse_sun(oc__ctx_t *c, const cJSON *o, oc_dvec3 *dir) {
  static const char *const keys[] = {"lat", "lon", "direction", NULL};
  *dir = oc__subsolar(OC__DEF_SUN_LAT, OC__DEF_SUN_LON);
  if (!o) return 0;
  OC_TRY(oc__check_keys(c, o, keys));
  if (cJSON_GetObjectItemCaseSensitive(o, "direction")) {
    if (cJSON_GetObjectItemCaseSensitive(o, "lat") || cJSON_GetObjectItemCaseSensitive(o, "lon"))
      return oc__fail(c, "give either lat/lon (subsolar point) or direction, not both");
    double v[3];
    OC_TRY(oc__vec(c, o, "direction", 3, -INFINITY, INFINITY, 0, v));
    /* Scale by the largest component first, so tiny or huge vectors normalise without
     * underflow or overflow. */
    double m = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
    if (!(m > 0)) {
      size_t old = oc__push_key(c, "direction");
      int r = oc__fail(c, "must not be the zero vector");
      oc__pop(c, old);
      return r;
    }
    *dir = oc_dnorm(oc_dv3(v[0] / m, v[1] / m, v[2] / m));
    return 0;
  }
  double lat, lon;
  OC_TRY(oc__num(c, o, "lat", -90, 90, 0, OC__DEF_SUN_LAT, &lat));
  OC_TRY(oc__num(c, o, "lon", -180, 180, 0, OC__DEF_SUN_LON, &lon));
  *dir = oc__subsolar(lat, lon);
  return 0;
}

static int oc__parse_camera(oc__ctx_t *c, const cJSON *o, oc_scene_camera_t *cam) {
  static const char *const keys[] = {"lat", "lon", "alt", "heading", "pitch", "fov", NULL};
  static const cJSON empty = {0};
  if (!o) o = &empty;
  else OC_TRY(oc__check_keys(c, o, keys));
  OC_TRY(oc__geo(c, o, -1e4, 1e9, 0, OC__DEF_CAM_LAT, OC__DEF_CAM_LON, OC__DEF_CAM_ALT, &cam->pos));
  OC_TRY(oc__num(c, o, "heading", -360, 360, 0, OC__DEF_CAM_HEADING, &cam->heading));
  OC_TRY(oc__num(c, o, "pitch", -90, 90, 0, OC__DEF_CAM_PITCH, &cam->pitch));
  OC_TRY(oc__num(c, o, "fov", 0.1, 179, OC__LO_OPEN | OC__HI_OPEN, OC__DEF_CAM_FOV, &cam->fov));
  return 0;
}

static int oc__parse_optics(oc__ctx_t *c, const cJSON *o, oc_scene_optics_t *op) {
  static const char *const keys[] = {"albedo", "ms_octaves", "ms_a", "ms_b", "ms_c", NULL};
  static const cJSON empty = {0};
  if (!o) o = &empty;
  else OC_TRY(oc__check_keys(c, o, keys));
  OC_TRY(oc__num(c, o, "albedo", 0, 1, 0, OC__DEF_ALBEDO, &op->albedo));
  OC_TRY(oc__int(c, o, "ms_octaves", 1, 8, 0, OC__DEF_MS_OCTAVES, &op->ms_octaves));
  OC_TRY(oc__num(c, o, "ms_a", 0, 1, OC__LO_OPEN | OC__HI_OPEN, OC__DEF_MS_A, &op->ms_a));
  OC_TRY(oc__num(c, o, "ms_b", 0, 1, OC__LO_OPEN | OC__HI_OPEN, OC__DEF_MS_B, &op->ms_b));
  OC_TRY(oc__num(c, o, "ms_c", 0, 1, OC__LO_OPEN | OC__HI_OPEN, OC__DEF_MS_C, &op->ms_c));
  return 0;
}

static int oc__sigma(oc__ctx_t *c, const cJSON *o, const char *key, unsigned flags, double def, double *out) {
  return oc__num(c, o, key, 0, OC_SCENE_SIGMA_MAX, flags, def, out);
}

/* Resolves a vdb path against base_dir (NULL: keep as written) into a new heap string. */
static int oc__vdb_path(oc__ctx_t *c, const char *file, const char *base_dir, char **out) {
  size_t nb = (base_dir && file[0] != '/') ? strlen(base_dir) : 0;
  size_t nf = strlen(file);
  if (nb + 1 + nf > OC_SCENE_PATH_MAX) {
    size_t old = oc__push_key(c, "file");
    int r = oc__fail(c, "path longer than %d bytes", OC_SCENE_PATH_MAX);
    oc__pop(c, old);
    return r;
  }
  char *p = malloc(nb + 1 + nf + 1);
  if (!p) return OC_ENOMEM;
  if (nb) {
    memcpy(p, base_dir, nb);
    if (p[nb - 1] != '/') p[nb++] = '/';
  }
  memcpy(p + nb, file, nf + 1);
  *out = p;
  return 0;
}

static int oc__parse_vdb(oc__ctx_t *c, const cJSON *o, const char *base_dir, oc_src_vdb_t *v) {
  static const char *const seq_keys[] = {"frame_rate", "first", "count", "end", NULL};
  const char *file, *grid;
  OC_TRY(oc__str(c, o, "file", OC_SCENE_PATH_MAX, OC__REQ, NULL, &file));
  OC_TRY(oc__str(c, o, "grid", OC_SCENE_GRID_CAP - 1, 0, "density", &grid));
  OC_TRY(oc__int(c, o, "grid_index", 0, 1023, 0, -1, &v->grid_index));
  if (v->grid_index >= 0 && cJSON_GetObjectItemCaseSensitive(o, "grid")) {
    size_t old = oc__push_key(c, "grid_index");
    int r = oc__fail(c, "give grid (a name) or grid_index, not both");
    oc__pop(c, old);
    return r;
  }
  snprintf(v->grid, sizeof v->grid, "%s", grid);
  OC_TRY(oc__geo(c, o, OC__SRC_ALT_MIN, OC__SRC_ALT_MAX, 0, 0, 0, 0, &v->anchor));
  OC_TRY(oc__num(c, o, "scale_m", 0, 1e5, OC__LO_OPEN, 0, &v->scale_m));
  OC_TRY(oc__num(c, o, "heading", -360, 360, 0, 0, &v->heading));
  OC_TRY(oc__sigma(c, o, "sigma_scale", 0, 1.0, &v->sigma_scale));
  const cJSON *seq;
  OC_TRY(oc__obj(c, o, "sequence", &seq));
  if (seq) {
    size_t old = oc__push_key(c, "sequence");
    int end = OC_SEQ_LOOP;
    OC_TRY(oc__check_keys(c, seq, seq_keys));
    OC_TRY(oc__num(c, seq, "frame_rate", 0, 1000, OC__LO_OPEN, OC__DEF_VDB_FRAME_RATE, &v->sequence.frame_rate));
    OC_TRY(oc__int(c, seq, "first", 0, 100000000, 0, 0, &v->sequence.first));
    OC_TRY(oc__int(c, seq, "count", 1, 1000000, OC__REQ, 1, &v->sequence.count));
    OC_TRY(oc__enum(c, seq, "end", oc__seq_end_names, 2, "sequence end", OC_SEQ_LOOP, &end));
    v->sequence.end = (oc_seq_end_t)end;
    v->has_sequence = true;
    oc__pop(c, old);
    /* One run of '#' in the file name stands for the frame number. */
    int runs = 0;
    for (const char *p = file; *p; p++)
      if (*p == '#' && (p == file || p[-1] != '#')) runs++;
    if (runs != 1) {
      old = oc__push_key(c, "file");
      int r = oc__fail(c, "a sequence needs exactly one run of '#' in the file name for the frame number, "
                          "e.g. \"cloud_####.vdb\"");
      oc__pop(c, old);
      return r;
    }
  }
  return oc__vdb_path(c, file, base_dir, &v->file);
}

static int oc__parse_source(oc__ctx_t *c, const cJSON *o, const char *base_dir, oc_source_t *s) {
  static const char *const k_sphere[] = {"type", "lat", "lon", "alt", "radius", "sigma_t", NULL};
  static const char *const k_box[] = {"type", "lat", "lon", "alt", "size", "heading", "sigma_t", NULL};
  static const char *const k_slab[] = {"type", "base", "top", "sigma_t", NULL};
  static const char *const k_proc[] = {"type", "preset", "coverage_scale", "sigma_scale", NULL};
  static const char *const k_vdb[] = {"type",    "file",        "grid",    "grid_index", "lat",      "lon",
                                      "alt",     "scale_m",     "heading", "sigma_scale", "sequence", NULL};
  static const char *const *const keys[] = {NULL, k_sphere, k_box, k_slab, k_proc, k_vdb};
  if (!cJSON_IsObject(o)) return oc__fail(c, "expected an object, got %s", oc__type_of(o));
  const cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "type");
  if (!t) return oc__missing(c, "type");
  int type = 0;
  OC_TRY(oc__enum(c, o, "type", oc__type_names, 6, "source type", 0, &type));
  s->type = (oc_source_type_t)type;
  OC_TRY(oc__check_keys(c, o, keys[type]));
  switch (s->type) {
    case OC_SOURCE_SPHERE:
      OC_TRY(oc__geo(c, o, OC__SRC_ALT_MIN, OC__SRC_ALT_MAX, OC__REQ, 0, 0, 0, &s->sphere.centre));
      OC_TRY(oc__num(c, o, "radius", 0, 1e6, OC__REQ | OC__LO_OPEN, 0, &s->sphere.radius));
      OC_TRY(oc__sigma(c, o, "sigma_t", OC__REQ, 0, &s->sphere.sigma_t));
      break;
    case OC_SOURCE_BOX:
      OC_TRY(oc__geo(c, o, OC__SRC_ALT_MIN, OC__SRC_ALT_MAX, OC__REQ, 0, 0, 0, &s->box.base));
      OC_TRY(oc__vec(c, o, "size", 3, 0, 1e6, OC__REQ | OC__LO_OPEN, s->box.size));
      OC_TRY(oc__num(c, o, "heading", -360, 360, 0, 0, &s->box.heading));
      OC_TRY(oc__sigma(c, o, "sigma_t", OC__REQ, 0, &s->box.sigma_t));
      break;
    case OC_SOURCE_SLAB:
      OC_TRY(oc__num(c, o, "base", OC__SRC_ALT_MIN, OC__SRC_ALT_MAX, OC__REQ, 0, &s->slab.base));
      OC_TRY(oc__num(c, o, "top", OC__SRC_ALT_MIN, OC__SRC_ALT_MAX, OC__REQ, 0, &s->slab.top));
      if (!(s->slab.top > s->slab.base)) {
        char bs[32];
        size_t old = oc__push_key(c, "top");
        oc__fmt_num(bs, sizeof bs, s->slab.base);
        int r = oc__fail(c, "must be greater than base (%s)", bs);
        oc__pop(c, old);
        return r;
      }
      OC_TRY(oc__sigma(c, o, "sigma_t", OC__REQ, 0, &s->slab.sigma_t));
      break;
    case OC_SOURCE_PROCEDURAL: {
      int preset = OC_PRESET_FAIR;
      OC_TRY(oc__enum(c, o, "preset", oc__preset_names, OC_PRESET_COUNT, "preset", OC_PRESET_FAIR, &preset));
      s->procedural.preset = (oc_preset_t)preset;
      OC_TRY(oc__num(c, o, "coverage_scale", 0, 4, 0, 1.0, &s->procedural.coverage_scale));
      OC_TRY(oc__sigma(c, o, "sigma_scale", 0, 1.0, &s->procedural.sigma_scale));
      break;
    }
    case OC_SOURCE_VDB:
      OC_TRY(oc__parse_vdb(c, o, base_dir, &s->vdb));
      break;
  }
  return 0;
}

static int oc__parse_sources(oc__ctx_t *c, const cJSON *root, const char *base_dir, oc_scene_t *sc) {
  const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, "sources");
  if (!arr) return 0;
  size_t old = oc__push_key(c, "sources");
  if (!cJSON_IsArray(arr)) return oc__fail(c, "expected an array, got %s", oc__type_of(arr));
  int n = cJSON_GetArraySize(arr);
  if (n > OC_SCENE_MAX_SOURCES) return oc__fail(c, "%d entries, at most %d allowed", n, OC_SCENE_MAX_SOURCES);
  int i = 0;
  for (const cJSON *it = arr->child; it; it = it->next, i++) {
    size_t o2 = oc__push_index(c, i);
    /* Count each source as it starts, so oc_scene_free() releases a half-parsed vdb too. */
    sc->nsources = i + 1;
    OC_TRY(oc__parse_source(c, it, base_dir, &sc->sources[i]));
    oc__pop(c, o2);
  }
  oc__pop(c, old);
  return 0;
}

/* Default scene name: the base name of the file without its extension. */
static void oc__default_name(char *dst, size_t cap, const char *file) {
  const char *b = strrchr(file, '/');
  b = b ? b + 1 : file;
  const char *dot = strrchr(b, '.');
  size_t n = dot && dot != b ? (size_t)(dot - b) : strlen(b);
  if (n == 0) b = "scene", n = 5;
  if (n >= cap) n = cap - 1;
  memcpy(dst, b, n);
  dst[n] = '\0';
  for (size_t i = 0; i < n; i++)
    if ((unsigned char)dst[i] < 0x20 || dst[i] == 0x7f) dst[i] = '?';
}

static int oc__parse_root(oc__ctx_t *c, const cJSON *root, const char *base_dir, oc_scene_t *sc) {
  static const char *const keys[] = {"version", "name", "seed", "epoch_period", "features", "sun",
                                     "camera", "optics", "sources", NULL};
  if (!cJSON_IsObject(root)) return oc__fail(c, "expected a JSON object at the top level, got %s", oc__type_of(root));
  OC_TRY(oc__check_keys(c, root, keys));
  int version;
  OC_TRY(oc__int(c, root, "version", 0, 1000000, 0, OC_SCENE_VERSION, &version));
  if (version != OC_SCENE_VERSION) {
    size_t old = oc__push_key(c, "version");
    oc__fail(c, "unsupported version %d (this build reads version %d)", version, OC_SCENE_VERSION);
    oc__pop(c, old);
    return OC_EVERSION;
  }
  const char *name;
  OC_TRY(oc__str(c, root, "name", OC_SCENE_NAME_CAP - 1, 0, NULL, &name));
  if (name) snprintf(sc->name, sizeof sc->name, "%s", name);
  else oc__default_name(sc->name, sizeof sc->name, c->file);
  double seed;
  OC_TRY(oc__num(c, root, "seed", 0, OC__MAX_SEED, OC__INT, OC__DEF_SEED, &seed));
  sc->seed = (uint64_t)seed;
  OC_TRY(oc__num(c, root, "epoch_period", 0, 60, OC__LO_OPEN, OC__DEF_EPOCH_PERIOD, &sc->epoch_period));
  const cJSON *o;
  bool animation_given;
  sc->features = (1u << OC_FEATURE_COUNT) - 1u;
  OC_TRY(oc__obj(c, root, "features", &o));
  if (o) {
    size_t old = oc__push_key(c, "features");
    OC_TRY(oc__parse_features(c, o, &sc->features, &animation_given));
    oc__pop(c, old);
  } else {
    animation_given = false;
  }
  OC_TRY(oc__obj(c, root, "sun", &o));
  {
    size_t old = oc__push_key(c, "sun");
    OC_TRY(oc__parse_sun(c, o, &sc->sun_dir));
    oc__pop(c, old);
  }
  OC_TRY(oc__obj(c, root, "camera", &o));
  {
    size_t old = oc__push_key(c, "camera");
    OC_TRY(oc__parse_camera(c, o, &sc->camera));
    oc__pop(c, old);
  }
  OC_TRY(oc__obj(c, root, "optics", &o));
  {
    size_t old = oc__push_key(c, "optics");
    OC_TRY(oc__parse_optics(c, o, &sc->optics));
    oc__pop(c, old);
  }
  OC_TRY(oc__parse_sources(c, root, base_dir, sc));
  if (!animation_given) {
    /* Default: animated exactly when something in the scene changes with time. */
    bool varies = false;
    for (int i = 0; i < sc->nsources; i++)
      varies |= sc->sources[i].type == OC_SOURCE_PROCEDURAL ||
                (sc->sources[i].type == OC_SOURCE_VDB && sc->sources[i].vdb.has_sequence);
    if (!varies) sc->features &= ~(1u << OC_FEATURE_ANIMATION);
  }
  return 0;
}

/*-*** JSON text ***/

static void oc__line_col(const char *json, size_t pos, int *line, int *col) {
  int l = 1, cc = 1;
  for (size_t i = 0; i < pos; i++) {
    if (json[i] == '\n') l++, cc = 1;
    else cc++;
  }
  *line = l;
  *col = cc;
}

static int oc__is_ws(char ch) { return ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r'; }

static int oc__syntax(oc__ctx_t *c, const char *json, size_t len, size_t pos, const char *what) {
  int line, col;
  char near[32];
  size_t n = 0;
  if (pos > len) pos = len;
  oc__line_col(json, pos, &line, &col);
  for (size_t i = pos; i < len && n < 20 && json[i] != '\n'; i++)
    near[n++] = ((unsigned char)json[i] < 0x20 || json[i] == 0x7f) ? '?' : json[i];
  near[n] = '\0';
  if (c->why && c->why_len) {
    if (n)
      snprintf(c->why, c->why_len, "%s:%d:%d: %s near '%s'", c->file, line, col, what, near);
    else
      snprintf(c->why, c->why_len, "%s:%d:%d: %s", c->file, line, col, what);
  }
  return OC_ESCENE;
}

static int oc__parse(oc_scene_t *out, const char *json, size_t len, const char *name, const char *base_dir, char *why,
                     size_t why_len) {
  oc__ctx_t c;
  memset(&c, 0, sizeof c);
  c.file = name ? name : "scene";
  c.why = why;
  c.why_len = why_len;
  if (why && why_len) why[0] = '\0';
  if (!out || (!json && len)) {
    if (out) memset(out, 0, sizeof *out);
    if (why && why_len) snprintf(why, why_len, "%s: invalid argument", c.file);
    return OC_EINVAL;
  }
  memset(out, 0, sizeof *out);
  if (len > OC_SCENE_MAX_FILE_BYTES) {
    if (why && why_len) snprintf(why, why_len, "%s: larger than %u bytes", c.file, OC_SCENE_MAX_FILE_BYTES);
    return OC_ETOOBIG;
  }
  size_t first = 0;
  while (first < len && oc__is_ws(json[first])) first++;
  if (first == len) {
    if (why && why_len) snprintf(why, why_len, "%s: empty; expected a JSON object", c.file);
    return OC_ESCENE;
  }
  /* cJSON gets its own NUL-terminated copy: the caller's buffer need not be terminated, and no
   * cJSON version can then read past it. */
  char *text = malloc(len + 1);
  if (!text) {
    if (why && why_len) snprintf(why, why_len, "%s: out of memory", c.file);
    return OC_ENOMEM;
  }
  memcpy(text, json, len);
  text[len] = '\0';
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(text, len, &end, 0);
  size_t end_pos = end ? (size_t)(end - text) : len;
  free(text);
  if (!root) {
    /* cJSON reports the failing position (also on its rare allocation failures). */
    return oc__syntax(&c, json, len, end_pos, "JSON syntax error");
  }
  size_t pos = end_pos;
  while (pos < len && oc__is_ws(json[pos])) pos++;
  if (pos < len) {
    cJSON_Delete(root);
    return oc__syntax(&c, json, len, pos, "unexpected content after the JSON value");
  }
  oc_scene_t *sc = out;
  /* Defaults first; the parse overwrites what the file gives. */
  sc->seed = OC__DEF_SEED;
  sc->epoch_period = OC__DEF_EPOCH_PERIOD;
  int r = oc__parse_root(&c, root, base_dir, sc);
  cJSON_Delete(root);
  if (r < 0) {
    oc_scene_free(out);
    return r;
  }
  if (oc_scene_has(sc, OC_FEATURE_OZONE) && !oc_scene_has(sc, OC_FEATURE_ATMOSPHERE))
    oc_log_debug("%s: features.ozone has no effect without features.atmosphere", c.file);
  return 0;
}

/*-*** Public API ***/

int oc_scene_parse(oc_scene_t *out, const char *json, size_t len, const char *name_for_errors, char *why,
                   size_t why_len) {
  return oc__parse(out, json, len, name_for_errors, NULL, why, why_len);
}

int oc_scene_load(oc_scene_t *out, const char *path, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (out) memset(out, 0, sizeof *out);
  if (!out || !path) {
    if (why && why_len) snprintf(why, why_len, "scene: invalid argument");
    return OC_EINVAL;
  }
  FILE *f = fopen(path, "rb");
  if (!f) {
    int e = errno;
    if (why && why_len) snprintf(why, why_len, "%s: cannot open: %s", path, strerror(e));
    return e == ENOENT ? OC_ENOENT : OC_EIO;
  }
  struct stat st;
  if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
    fclose(f);
    if (why && why_len) snprintf(why, why_len, "%s: not a regular file", path);
    return OC_EIO;
  }
  if ((uintmax_t)st.st_size > OC_SCENE_MAX_FILE_BYTES) {
    fclose(f);
    if (why && why_len) snprintf(why, why_len, "%s: larger than %u bytes", path, OC_SCENE_MAX_FILE_BYTES);
    return OC_ETOOBIG;
  }
  /* Read up to one byte past the limit: the file may have grown since fstat. */
  size_t cap = (size_t)st.st_size + 1, n = 0;
  char *buf = malloc(cap);
  if (!buf) {
    fclose(f);
    if (why && why_len) snprintf(why, why_len, "%s: out of memory", path);
    return OC_ENOMEM;
  }
  for (;;) {
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (n < cap) break;
    if (cap > OC_SCENE_MAX_FILE_BYTES) break;
    size_t ncap = cap * 2 > (size_t)OC_SCENE_MAX_FILE_BYTES + 1 ? (size_t)OC_SCENE_MAX_FILE_BYTES + 1 : cap * 2;
    char *nb = realloc(buf, ncap);
    if (!nb) {
      free(buf);
      fclose(f);
      if (why && why_len) snprintf(why, why_len, "%s: out of memory", path);
      return OC_ENOMEM;
    }
    buf = nb;
    cap = ncap;
  }
  int rerr = ferror(f);
  int e = errno;
  fclose(f);
  if (rerr) {
    free(buf);
    if (why && why_len) snprintf(why, why_len, "%s: read error: %s", path, strerror(e));
    return OC_EIO;
  }
  if (n > OC_SCENE_MAX_FILE_BYTES) {
    free(buf);
    if (why && why_len) snprintf(why, why_len, "%s: larger than %u bytes", path, OC_SCENE_MAX_FILE_BYTES);
    return OC_ETOOBIG;
  }
  /* Relative vdb paths are relative to the scene file's folder. */
  char *dir = NULL;
  const char *slash = strrchr(path, '/');
  if (slash) {
    size_t dl = slash == path ? 1 : (size_t)(slash - path);
    dir = malloc(dl + 1);
    if (!dir) {
      free(buf);
      return OC_ENOMEM;
    }
    memcpy(dir, path, dl);
    dir[dl] = '\0';
  }
  int r = oc__parse(out, buf, n, path, dir, why, why_len);
  free(dir);
  free(buf);
  if (r == 0) oc_log_debug("%s: scene \"%s\", %d source(s)", path, out->name, out->nsources);
  return r;
}

void oc_scene_free(oc_scene_t *s) {
  if (!s) return;
  for (int i = 0; i < s->nsources && i < OC_SCENE_MAX_SOURCES; i++)
    if (s->sources[i].type == OC_SOURCE_VDB) free(s->sources[i].vdb.file);
  memset(s, 0, sizeof *s);
}

int oc_scene_copy(oc_scene_t *dst, const oc_scene_t *src) {
  if (!dst || !src || dst == src) return OC_EINVAL;
  memcpy(dst, src, sizeof *dst);
  for (int i = 0; i < dst->nsources; i++) {
    oc_source_t *s = &dst->sources[i];
    if (s->type != OC_SOURCE_VDB || !s->vdb.file) continue;
    size_t n = strlen(src->sources[i].vdb.file) + 1;
    s->vdb.file = malloc(n);
    if (!s->vdb.file) {
      dst->nsources = i; /* free only the copies made so far */
      oc_scene_free(dst);
      return OC_ENOMEM;
    }
    memcpy(s->vdb.file, src->sources[i].vdb.file, n);
  }
  return 0;
}

void oc_scene_default(oc_scene_t *out) {
  if (!out) return;
  memset(out, 0, sizeof *out);
  snprintf(out->name, sizeof out->name, "planet");
  out->seed = OC__DEF_SEED;
  out->epoch_period = OC__DEF_EPOCH_PERIOD;
  out->features = (1u << OC_FEATURE_COUNT) - 1u;
  out->sun_dir = oc__subsolar(OC__DEF_SUN_LAT, OC__DEF_SUN_LON);
  out->camera.pos.lat = OC__DEF_CAM_LAT;
  out->camera.pos.lon = OC__DEF_CAM_LON;
  out->camera.pos.alt = OC__DEF_CAM_ALT;
  out->camera.heading = OC__DEF_CAM_HEADING;
  out->camera.pitch = OC__DEF_CAM_PITCH;
  out->camera.fov = OC__DEF_CAM_FOV;
  out->optics.albedo = OC__DEF_ALBEDO;
  out->optics.ms_octaves = OC__DEF_MS_OCTAVES;
  out->optics.ms_a = OC__DEF_MS_A;
  out->optics.ms_b = OC__DEF_MS_B;
  out->optics.ms_c = OC__DEF_MS_C;
  out->nsources = 1;
  out->sources[0].type = OC_SOURCE_PROCEDURAL;
  out->sources[0].procedural.preset = OC_PRESET_FAIR;
  out->sources[0].procedural.coverage_scale = 1.0;
  out->sources[0].procedural.sigma_scale = 1.0;
}
