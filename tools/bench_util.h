/* bench_util.h — what the overcast-bench subcommands share (bench_util.c): a clock, option rows and
 * their parsers, the preamble every subcommand begins with (its options, then its scene and camera),
 * and a brick cache in front of a field. bench_main.c only dispatches; it does not define these.
 * Not part of the project's API: tools/ only. */
#ifndef OC_TOOLS_BENCH_UTIL_H
#define OC_TOOLS_BENCH_UTIL_H

#include <stddef.h>

#include "ocs.h"

/*! oct_now() : monotonic seconds. */
double oct_now(void);
/*! oct_median() : the median of v[0..n) (n ≥ 1), sorting v in place. */
double oct_median(double *v, int n);
/*! oct_parse_list() : "a,b,c" of integers in [lo, hi]; 0, or -1 after printing the error. */
int oct_parse_list(const char *prog, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n);
/*! oct_load_scene() : the scene at path, or the built-in planet when path is NULL; 0, or -1 after
 *  printing the error. */
int oct_load_scene(const char *prog, const char *path, oc_scene_t *sc);

/*-*** Option rows (common/oc_cli.h) shared by the subcommands' tables ***/

/*! oct_list_t, oct_dlist_t : a list option of integers ("10,13,16") or of numbers, filled by
 *  oct_opt_list() (at most min(OCT_LIST_MAX, hi - lo + 1) entries) or oct_opt_doubles() (at most
 *  OCT_LIST_MAX), each in the row's [lo, hi]. */
#define OCT_LIST_MAX 16
typedef struct {
  long v[OCT_LIST_MAX];
  int n;
} oct_list_t;
typedef struct {
  double v[OCT_LIST_MAX];
  int n;
} oct_dlist_t;
int oct_opt_list(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);
int oct_opt_doubles(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);

/*! oct_at_t : --at LAT,LON in degrees (oct_opt_at()); given is 0 until the option is seen. */
typedef struct {
  double lat, lon;
  int given;
} oct_at_t;
int oct_opt_at(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);

/*! oct_opt_size() : "WxH" into an int[2] (oc_cli_size()). */
int oct_opt_size(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);

/*! oct_opt_renderer() : "cpu" or "gl" into an int (1: gl); gl is refused where the build has no GL
 *  renderer. */
int oct_opt_renderer(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);

/*! oct_opt_ground_map() : the ground shadow map's texels a side into an int: −1 (none) or what
 *  oc_render_desc_t.shadow_ground_cells accepts, so a bad value fails before any epoch is made. */
int oct_opt_ground_map(const char *prog, const oc_cli_opt_t *o, const char *text, void *base);

/* A table's rows of the common kinds, one option each: T is the subcommand's options struct and f
 * the option's field in it; lo, hi the inclusive range, def the default as an argument would be
 * written (NULL: none), help one sentence. Rows of other kinds are written out. */
#define OCT_INT(T, f, name_, arg_, lo_, hi_, def_, help_)                                                           \
  {.name = name_, .type = OC_CLI_INT, .offset = offsetof(T, f), .arg = arg_, .lo = lo_, .hi = hi_, .def = def_,      \
   .help = help_}
#define OCT_DBL(T, f, name_, arg_, lo_, hi_, def_, help_)                                                           \
  {.name = name_, .type = OC_CLI_DOUBLE, .offset = offsetof(T, f), .arg = arg_, .lo = lo_, .hi = hi_, .def = def_,   \
   .help = help_}
/* the same with no default, only a note of what stands in for one ("all cores") */
#define OCT_INT_NOTE(T, f, name_, arg_, lo_, hi_, note_, help_)                                                     \
  {.name = name_, .type = OC_CLI_INT, .offset = offsetof(T, f), .arg = arg_, .lo = lo_, .hi = hi_,                  \
   .def_note = note_, .help = help_}
#define OCT_DBL_NOTE(T, f, name_, arg_, lo_, hi_, note_, help_)                                                     \
  {.name = name_, .type = OC_CLI_DOUBLE, .offset = offsetof(T, f), .arg = arg_, .lo = lo_, .hi = hi_,               \
   .def_note = note_, .help = help_}
#define OCT_FLAG(T, f, name_, help_) {.name = name_, .type = OC_CLI_FLAG, .offset = offsetof(T, f), .help = help_}
#define OCT_STR(T, f, name_, arg_, help_)                                                                           \
  {.name = name_, .type = OC_CLI_STRING, .offset = offsetof(T, f), .arg = arg_, .help = help_}
/* an oct_list_t (oct_opt_list()), an int[2] "WxH" (oct_opt_size()) */
#define OCT_LIST(T, f, name_, lo_, hi_, def_, help_)                                                                \
  {.name = name_, .type = OC_CLI_CUSTOM, .parse = oct_opt_list, .offset = offsetof(T, f), .arg = "LIST", .lo = lo_, \
   .hi = hi_, .def = def_, .help = help_}
#define OCT_SIZE(T, f, name_, def_, help_)                                                                          \
  {.name = name_, .type = OC_CLI_CUSTOM, .parse = oct_opt_size, .offset = offsetof(T, f), .arg = "WxH", .def = def_, \
   .help = help_}

/* Rows that mean the same in every subcommand. */
#define OCT_OPT_SCENE(T)                                                                                         \
  {.name = "scene", .type = OC_CLI_STRING, .offset = offsetof(T, scene), .arg = "FILE",                          \
   .def_note = "the built-in procedural planet", .help = "scene"}
#define OCT_OPT_CAMERA(T)                                                                                        \
  {.name = "camera", .type = OC_CLI_STRING, .offset = offsetof(T, camera), .arg = "LAT,LON,ALT,HEADING,PITCH,FOV", \
   .def_note = "the scene's camera", .help = "the viewer's camera"}
/* --at and --alt: the centre of a block of nodes (an oct_at_t at and a double alt) */
#define OCT_OPT_PLACE(T)                                                                                         \
  {.name = "at", .type = OC_CLI_CUSTOM, .parse = oct_opt_at, .offset = offsetof(T, at), .arg = "LAT,LON",        \
   .def_note = "the scene camera", .help = "centre of the block, in degrees"},                                   \
      OCT_DBL(T, alt, "alt", "M", -1e4, 1e5, "2000", "altitude of the block's centre in metres")
#define OCT_OPT_TIME(T) OCT_DBL(T, time, "time", "T", -1e12, 1e12, "0", "world time in seconds")
/* --ground-map N: an int ground_map (oct_opt_ground_map()); its default and range are the renderer's */
#define OCT__STR(x) #x
#define OCT__XSTR(x) OCT__STR(x)
#define OCT_OPT_GROUND_MAP(T)                                                                                    \
  {.name = "ground-map", .type = OC_CLI_CUSTOM, .parse = oct_opt_ground_map, .offset = offsetof(T, ground_map),  \
   .arg = "N", .def = OCT__XSTR(OC_RENDER_DEFAULT_SHADOW_GROUND_CELLS),                                         \
   .help = "the ground shadow map's texels a side, " OCT__XSTR(OC_RENDER_SHADOW_GROUND_CELLS_MIN) ".."             \
           OCT__XSTR(OC_RENDER_SHADOW_GROUND_CELLS_MAX) " (shadows on the ground); -1: none, the ground reads "   \
           "the coarser shadow volume (for comparison)"}
/* A block of block³ nodes at each of some octree levels, around a place, at a time: the fields a
 * subcommand's options struct takes for OCT_OPTS_BLOCK (its rows: --scene, the levels' list option,
 * --block, --at, --alt, --time); oct_block_centre() is the place. */
#define OCT_BLOCK_FIELDS \
  const char *scene;     \
  oct_list_t levels;     \
  int block;             \
  oct_at_t at;           \
  double alt, time;
#define OCT_OPTS_BLOCK(T, levels_name_, levels_lo_, levels_def_, levels_help_, block_hi_, block_def_, block_help_) \
  OCT_OPT_SCENE(T), OCT_LIST(T, levels, levels_name_, levels_lo_, 21, levels_def_, levels_help_),                  \
      OCT_INT(T, block, "block", "N", 1, block_hi_, block_def_, block_help_), OCT_OPT_PLACE(T), OCT_OPT_TIME(T)
/*! oct_block_centre() : the block's centre: --at (else the scene camera's latitude and longitude) at --alt. */
static inline oc_geo_t oct_block_centre(const oct_at_t *at, double alt, const oc_scene_t *sc) {
  return (oc_geo_t){at->given ? at->lat : sc->camera.pos.lat, at->given ? at->lon : sc->camera.pos.lon, alt};
}
#define OCT_OPT_THREADS(T) OCT_INT_NOTE(T, threads, "threads", "N", 0, 64, "all cores", "producer threads; 0: all cores")
#define OCT_OPT_RENDERER(T, text)                                                                                \
  {.name = "renderer", .type = OC_CLI_CUSTOM, .parse = oct_opt_renderer, .offset = offsetof(T, gl), .arg = "cpu|gl", \
   .def = "cpu", .help = text}
#define OCT_OPT_EPOCHS(T, def_, help_) OCT_INT(T, epochs, "epochs", "N", 1, 100000, def_, help_)
#define OCT_OPT_BUDGET(T, def_, whose_)                                                                            \
  OCT_INT(T, budget, "budget", "MIB", 1, 1 << 20, def_, whose_ " budget (2048-byte slots, 32-byte records)")
#define OCT_OPT_HELP {.name = "help", .type = OC_CLI_HELP, .help = "print this and exit"}
/* a table's last rows: --help and the terminator */
#define OCT_OPTS_END OCT_OPT_HELP, {0}

/*! OCT_SPEC() : defines oct_bench_<cmd>_spec (bench.h) from a line or two about the subcommand (ending
 *  without a newline) and its table, optionally followed by more of the spec's fields
 *  (`.synopsis = ...`, `.epilog = ...`). */
#define OCT_SPEC(cmd, about_, ...)                                                                                 \
  const oc_cli_spec_t oct_bench_##cmd##_spec = {                                                                   \
      .prog = "overcast-bench " #cmd, .about = about_ "\n\noptions:\n", .opts = __VA_ARGS__}

/*-*** The preamble ***/

/*! OCT_GO : oct_begin() says "go on" (any other value is the exit status to return). */
#define OCT_GO (-1)

/*! oct_begin() : what every subcommand begins with. Parses argv (argv[0] the subcommand's name) by
 *  spec into opts; then, when sc is not NULL, loads the scene *scene names (oct_load_scene(); NULL:
 *  the built-in planet); then, when pose is not NULL, the camera: the scene's, or *camera parsed
 *  (oc_camera_parse(); the scene is freed on error).
 *  @return OCT_GO, or the exit status: OC_EXIT_OK after --help, OC_EXIT_USAGE after a usage error,
 *  OC_EXIT_RUNTIME when the scene does not load. */
int oct_begin(const oc_cli_spec_t *spec, int argc, char **argv, void *opts, const char *const *scene,
              const char *const *camera, oc_scene_t *sc, oc_camera_pose_t *pose);
/*! oct_scene_camera() : oct_begin()'s second half: the scene at path (NULL: the built-in planet)
 *  and, when pose is not NULL, the camera (camera NULL: the scene's). @return OCT_GO or the exit
 *  status. */
int oct_scene_camera(const char *prog, const char *path, const char *camera, oc_scene_t *sc, oc_camera_pose_t *pose);

/*-*** A single-threaded brick cache in front of a field ***/

/*! oct_fcache_t : a single-threaded brick cache in front of a field at time t (what the server's
 *  shared cache gives the τ callbacks): oct_fcache_sigma() and oct_fcache_bound() are
 *  ocs_tau_desc_t callbacks with ctx an oct_fcache_t; zero-initialise with f and t set, release
 *  with oct_fcache_free(). */
typedef struct {
  oc_key_t key;
  int has_bound, brick; /* brick: index + 1 into the pool, 0: not sampled */
  float lo, hi;
} oct_fcache_ent_t;
typedef struct {
  const ocs_field_t *f;
  double t;
  oct_fcache_ent_t *tab;
  size_t cap, n;
  float *pool;
  size_t nb, pool_cap;
  long sigma_calls, bound_calls, sigma_fetches, bound_fetches; /* callback calls; field work */
  int err;
} oct_fcache_t;
int oct_fcache_sigma(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]);
void oct_fcache_bound(void *ctx, oc_key_t key, float *lo, float *hi);
void oct_fcache_free(oct_fcache_t *c);

/*! oct_anchor_seconds() : issue 17's anchor, a plain scalar 6-octave Perlin fBm (oc_fbm3(),
 *  lacunarity 2, gain 0.5, a 1 km lattice) once per sample position of each of the n nodes: the
 *  seconds it took, so n / seconds is the anchor's bricks/s per core. Its sum is added to *sink:
 *  a store the compiler must keep, so the work is not optimised away. */
double oct_anchor_seconds(const oc_key_t *keys, long n, double *sink);

#endif /* OC_TOOLS_BENCH_UTIL_H */
