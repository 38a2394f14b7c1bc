/* oc_scene.h — scene files: what the world contains (docs/scene.md is the schema reference).
 *
 * A scene is a JSON file read with cJSON into plain C structs. The reader is strict: an unknown
 * key, a wrong type, a value out of range, a non-finite number, a duplicate key or an unknown enum
 * string is an error, reported as one line that names the file and the key path, e.g.
 *   scenes/x.json: sources[1].sigma_t: expected a number, got a string
 *   scenes/x.json: sources[1].sigmat: unknown key (did you mean "sigma_t"?)
 *   scenes/x.json:3:17: JSON syntax error
 * Missing optional keys take the defaults documented in docs/scene.md (and below, per member).
 * Only parsing and validation happen here: field sources are built by server/ from these structs. */
#ifndef OC_COMMON_SCENE_H
#define OC_COMMON_SCENE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "oc_math.h"   /* oc_dvec3 */
#include "oc_planet.h" /* oc_geo_t */

/*-*** Limits ***/

#define OC_SCENE_VERSION 1                /**< the only `version` this reader accepts */
#define OC_SCENE_MAX_SOURCES 64           /**< entries in `sources` */
#define OC_SCENE_MAX_FILE_BYTES (16u << 20) /**< 16 MiB: larger files are refused unread */
#define OC_SCENE_NAME_CAP 64              /**< `name`: at most 63 bytes */
#define OC_SCENE_GRID_CAP 64              /**< vdb `grid`: at most 63 bytes */
#define OC_SCENE_PATH_MAX 4095            /**< vdb `file` after resolution: at most this many bytes */
#define OC_SCENE_SIGMA_MAX 1e9            /**< m⁻¹: upper bound of every sigma_t / sigma_scale */

/*-*** Features ***/

/*! oc_scene_feature_t : bit numbers of oc_scene_t.features, in the order of the JSON keys. */
typedef enum {
  OC_FEATURE_ANIMATION = 0,           /**< "animation": the field changes with world time (3 states kept) */
  OC_FEATURE_ATMOSPHERE = 1,          /**< "atmosphere": clear-sky scattering and its tables */
  OC_FEATURE_SHADOWS = 2,             /**< "shadows": the τ (sun optical depth) channel */
  OC_FEATURE_MULTIPLE_SCATTERING = 3, /**< "multiple_scattering": Wrenninge octaves (optics.ms_*) */
  OC_FEATURE_OZONE = 4,               /**< "ozone": ozone absorption (only with atmosphere) */
  OC_FEATURE_PLANET_SURFACE = 5,      /**< "planet_surface": the ground is drawn and occludes */
  OC_FEATURE_COUNT = 6
} oc_scene_feature_t;

/*! oc_scene_feature_name() : @return the JSON key of feature f ("animation", ...), or NULL. */
const char *oc_scene_feature_name(int f);

/*-*** Sources ***/

typedef enum {
  OC_SOURCE_SPHERE = 1,     /**< homogeneous ball */
  OC_SOURCE_BOX = 2,        /**< homogeneous box in the local east-north-up frame */
  OC_SOURCE_SLAB = 3,       /**< homogeneous spherical shell between two altitudes */
  OC_SOURCE_PROCEDURAL = 4, /**< the procedural cloud field, by weather preset */
  OC_SOURCE_VDB = 5         /**< an OpenVDB grid or sequence of grids */
} oc_source_type_t;

/*! oc_scene_source_type_name() : @return "sphere", "box", ... for an oc_source_type_t, or NULL. */
const char *oc_scene_source_type_name(int type);

typedef enum {
  OC_PRESET_CLEAR = 0,
  OC_PRESET_FAIR = 1,
  OC_PRESET_OVERCAST = 2,
  OC_PRESET_STORM = 3,
  OC_PRESET_CIRRUS = 4,
  OC_PRESET_COUNT = 5
} oc_preset_t;

/*! oc_scene_preset_name() : @return "clear", "fair", ... for an oc_preset_t, or NULL. */
const char *oc_scene_preset_name(int preset);
/*! oc_scene_preset_parse() : @return the oc_preset_t named `name`, or OC_EINVAL (control channel). */
int oc_scene_preset_parse(const char *name);

typedef struct {
  oc_geo_t centre; /**< lat, lon (degrees; default 0), alt (m, [-1e4, 1e5], required) of the centre */
  double radius;   /**< m, (0, 1e6] */
  double sigma_t;  /**< m⁻¹, [0, 1e9] */
} oc_src_sphere_t;

typedef struct {
  oc_geo_t base;   /**< centre of the bottom face: lat, lon (default 0), alt ([-1e4, 1e5], required) */
  double size[3];  /**< m along east, north, up (before heading), each (0, 1e6] */
  double heading;  /**< degrees clockwise from north about the local up, [-360, 360]; default 0 */
  double sigma_t;  /**< m⁻¹, [0, 1e9] */
} oc_src_box_t;

typedef struct {
  double base, top; /**< altitudes, m, [-1e4, 1e5], base < top */
  double sigma_t;   /**< m⁻¹, [0, 1e9] */
} oc_src_slab_t;

typedef struct {
  oc_preset_t preset;    /**< default OC_PRESET_FAIR */
  double coverage_scale; /**< multiplies the preset's coverage, [0, 4]; default 1 */
  double sigma_scale;    /**< multiplies the preset's extinction, [0, 1e9]; default 1 */
} oc_src_procedural_t;

typedef enum { OC_SEQ_LOOP = 0, OC_SEQ_HOLD = 1 } oc_seq_end_t;

typedef struct {
  double frame_rate; /**< frames per second of world time, (0, 1000]; default 24 */
  int first;         /**< frame number of the first file, [0, 1e8]; default 0 */
  int count;         /**< number of frames, [1, 1e6]; required */
  oc_seq_end_t end;  /**< after the last frame: loop (default) or hold it */
} oc_src_sequence_t;

typedef struct {
  char *file;                   /**< owned (oc_scene_free); relative paths are resolved against the
                                     scene file's folder by oc_scene_load(), kept as written by
                                     oc_scene_parse(). With a sequence, its one run of '#' stands for
                                     the frame number, zero-padded to the run's length */
  char grid[OC_SCENE_GRID_CAP]; /**< grid name; default "density" (ignored when grid_index ≥ 0) */
  int grid_index;               /**< grid by position in the file, [0, 1023]; -1 (default): by name */
  oc_geo_t anchor;              /**< where the centre of the bottom face of the grid's active
                                     bounding box goes; alt in [-1e4, 1e5]; all default 0 */
  double scale_m;               /**< metres per index unit, (0, 1e5]; 0 (default): the file's own
                                     transform (in metres) */
  double heading;               /**< degrees about the local up, [-360, 360]; default 0 */
  double sigma_scale;           /**< grid value → σt (m⁻¹), [0, 1e9]; default 1 */
  bool has_sequence;            /**< false: a single file */
  oc_src_sequence_t sequence;   /**< valid when has_sequence */
} oc_src_vdb_t;

typedef struct {
  oc_source_type_t type;
  union {
    oc_src_sphere_t sphere;
    oc_src_box_t box;
    oc_src_slab_t slab;
    oc_src_procedural_t procedural;
    oc_src_vdb_t vdb;
  };
} oc_source_t;

/*-*** Scene ***/

typedef struct {
  oc_geo_t pos;   /**< lat [-90, 90], lon [-180, 180] (degrees), alt [-1e4, 1e9] m */
  double heading; /**< degrees clockwise from north, [-360, 360] */
  double pitch;   /**< degrees, positive up, [-90, 90] */
  double fov;     /**< vertical field of view, degrees, (0.1, 179) */
} oc_scene_camera_t;

typedef struct {
  double albedo;  /**< single-scattering albedo σs/σt, [0, 1]; default 1 */
  int ms_octaves; /**< multiple-scattering octaves N, [1, 8]; default 4 */
  double ms_a;    /**< extinction factor per octave, (0, 1); default 0.6139 (fitted to the truth) */
  double ms_b;    /**< contribution factor per octave, (0, 1); default 0.5139 (fitted) */
  double ms_c;    /**< phase eccentricity factor per octave, (0, 1); default 0.9924 (fitted) */
} oc_scene_optics_t;

typedef struct {
  char name[OC_SCENE_NAME_CAP]; /**< default: the file's base name without extension */
  uint64_t seed;                /**< [0, 2^53 - 1]; default 1 */
  double epoch_period;          /**< s, (0, 60]; default 1 */
  uint32_t features;            /**< bit (1u << OC_FEATURE_*) set when enabled */
  oc_dvec3 sun_dir;             /**< unit vector from the planet centre toward the sun, planet frame */
  oc_scene_camera_t camera;     /**< the default view */
  oc_scene_optics_t optics;
  int nsources;                 /**< 0..OC_SCENE_MAX_SOURCES */
  oc_source_t sources[OC_SCENE_MAX_SOURCES];
} oc_scene_t;

/*! oc_scene_has() : @return true when feature f is enabled. */
static inline bool oc_scene_has(const oc_scene_t *s, oc_scene_feature_t f) { return (s->features >> f) & 1u; }

/*! oc_scene_default() :
 *  The built-in procedural planet (identical to scenes/planet.json): one procedural "fair"
 *  source, all features on, sun over 20°N 10°E, every other value at its default. */
void oc_scene_default(oc_scene_t *out);

/*! oc_scene_parse() :
 *  Parses and validates `len` bytes of JSON (NUL termination not needed). `name_for_errors`
 *  (may be NULL: "scene") starts every error message and gives the default `name`.
 *  @return 0; OC_EINVAL for NULL arguments; OC_ETOOBIG over OC_SCENE_MAX_FILE_BYTES; OC_ESCENE for
 *  a syntax error or an invalid scene; OC_ENOMEM. On error, `why` (if not NULL) holds one line and
 *  *out is zeroed (oc_scene_free() on it is harmless). */
int oc_scene_parse(oc_scene_t *out, const char *json, size_t len, const char *name_for_errors, char *why,
                   size_t why_len);

/*! oc_scene_load() :
 *  Reads `path` (a regular file of at most OC_SCENE_MAX_FILE_BYTES) and parses it; relative vdb
 *  file paths are resolved against the folder of `path`.
 *  @return as oc_scene_parse(), plus OC_ENOENT (no such file), OC_EIO (unreadable, a directory). */
int oc_scene_load(oc_scene_t *out, const char *path, char *why, size_t why_len);

/*! oc_scene_free() : releases what a scene owns (the vdb file strings) and zeroes it. NULL is
 *  accepted; so is a zeroed or default scene. A scene must not be copied with `=` (the copies would
 *  share the strings): use oc_scene_copy(). */
void oc_scene_free(oc_scene_t *s);

/*! oc_scene_copy() : deep copy of src into dst (dst is overwritten, not freed first).
 *  @return 0, OC_EINVAL, or OC_ENOMEM (dst zeroed). */
int oc_scene_copy(oc_scene_t *dst, const oc_scene_t *src);

#endif /* OC_COMMON_SCENE_H */
