/* vdb_shim.h — the C API of the OpenVDB shim (server/vdb_shim.cpp, the project's only C++ file).
 *
 * The shim is a separate shared object (liboc_vdb_shim.so) opened with dlopen by vdb_loader.c the
 * first time a scene imports VDB, a file is inspected or a region exported: a procedural server
 * never maps OpenVDB, TBB or Boost (design.md, Conventions: CI). It exports ONE symbol,
 * OCS_VDB_SHIM_SYMBOL, a function returning a versioned table of plain C functions. No C++ type
 * and no exception crosses the table: every entry catches everything and returns a negative OC_E*
 * (common/oc_err.h) with a one-line reason in `why`.
 *
 * Objects:
 *   ocs_vdb_file_t   an opened file with every grid read into memory (OpenVDB io::Stream, so
 *                    half floats, zip and blosc, tiles at every level are OpenVDB's own reading);
 *   ocs_vdb_grid_t   one float grid taken out of a file and prepared for box-filtered sampling:
 *                    values sanitised (NaN, ±Inf, negatives → 0, counted), inactive values 0, and a
 *                    sparse pyramid of 2×2×2 means plus per-cell min and max (level 0: the voxels);
 *   ocs_vdb_writer_t grids built from C (tests, export) and saved to a .vdb.
 * A prepared grid is immutable: grid_sample/grid_range may be called from any number of threads. */
#ifndef OC_SERVER_VDB_SHIM_H
#define OC_SERVER_VDB_SHIM_H

#include <stddef.h> /* size_t */
#include <stdint.h> /* int32_t, uint32_t, uint64_t */

#ifdef __cplusplus
extern "C" {
#endif

/*! Version of the table below; bumped on any incompatible change. */
#define OCS_VDB_SHIM_ABI 1
/*! The one exported symbol: const ocs_vdb_api_t *ocs_vdb_shim_api(uint32_t abi). */
#define OCS_VDB_SHIM_SYMBOL "ocs_vdb_shim_api"
/*! The shim's file name (searched by vdb_loader.c). */
#define OCS_VDB_SHIM_NAME "liboc_vdb_shim.so"
/*! Pyramid levels of a prepared grid (level 0 = the voxels; level 30 cells span 2^30 voxels). */
#define OCS_VDB_MAX_LEVELS 31

typedef struct ocs_vdb_file_s ocs_vdb_file_t;
typedef struct ocs_vdb_grid_s ocs_vdb_grid_t;
typedef struct ocs_vdb_writer_s ocs_vdb_writer_t;

/*! Value types as the shim reports them (OpenVDB's valueType() in grid_info.value_type). */
typedef enum {
  OCS_VDB_TYPE_OTHER = 0,  /**< anything else (string, bool, mask, half, ...) */
  OCS_VDB_TYPE_FLOAT = 1,  /**< "float" (also files saved as half floats) */
  OCS_VDB_TYPE_DOUBLE = 2, /**< "double" (imported by conversion to float) */
  OCS_VDB_TYPE_INT32 = 3,
  OCS_VDB_TYPE_INT64 = 4,
  OCS_VDB_TYPE_VEC3 = 5,   /**< vec3s, vec3d, vec3i */
  OCS_VDB_TYPE_POINTS = 6  /**< OpenVDB point data grids ("ptdataidx32") */
} ocs_vdb_type_t;

/*! Grid classes, equal to openvdb::GridClass. */
typedef enum {
  OCS_VDB_CLASS_UNKNOWN = 0,
  OCS_VDB_CLASS_LEVEL_SET = 1,
  OCS_VDB_CLASS_FOG = 2,
  OCS_VDB_CLASS_STAGGERED = 3
} ocs_vdb_class_t;

/*! Compression for writer_save. */
typedef enum {
  OCS_VDB_COMPRESS_DEFAULT = 0, /**< blosc when the library has it, else zip */
  OCS_VDB_COMPRESS_NONE = 1,
  OCS_VDB_COMPRESS_ZIP = 2,
  OCS_VDB_COMPRESS_BLOSC = 3    /**< OC_EINVAL when the library lacks blosc */
} ocs_vdb_compress_t;

/*! What a file says about one grid (grid_info). */
typedef struct {
  char name[128];          /**< grid name (truncated to 127 bytes) */
  char value_type[32];     /**< OpenVDB's valueType(): "float", "vec3s", "ptdataidx32", ... */
  int type;                /**< ocs_vdb_type_t */
  int klass;               /**< ocs_vdb_class_t */
  int half;                /**< saved as 16-bit half floats */
  int linear;              /**< the transform is affine; i2w is valid only then */
  double voxel_size[3];    /**< world units per index step along each index axis */
  double i2w[3][4];        /**< index → world, column vectors: w = R·i + t, R = [..][0..2], t = [..][3] */
  uint64_t active_voxels;  /**< active voxels, tiles counted by the voxels they cover */
  uint64_t active_tiles;   /**< active constant tiles (in internal and root nodes) */
  uint64_t leaf_nodes;
  uint64_t points;         /**< point grids: number of points */
  int32_t bbox_min[3];     /**< active voxel bounding box, index space, inclusive; */
  int32_t bbox_max[3];     /**< min > max when the grid is empty */
  int has_range;           /**< scalar grids: vmin/vmax and the counts below are valid */
  double vmin, vmax;       /**< range of the finite active values (vec3: of their lengths) */
  uint64_t nan, inf, negative; /**< active values (a tile counts once) */
} ocs_vdb_grid_info_t;

/*! What grid_prepare did. */
typedef struct {
  uint64_t nan, inf, negative; /**< active values replaced by 0 (a tile counts its voxels) */
  int levels;                  /**< pyramid levels: OCS_VDB_MAX_LEVELS */
  uint64_t bytes;              /**< memory of the pyramid (OpenVDB's memUsage) */
  double seconds;              /**< time spent preparing */
} ocs_vdb_prep_stats_t;

/*! How writer_add_grid builds a grid. Zero-initialise; every field's default is its zero value. */
typedef struct {
  const char *name;  /**< required, at most 127 bytes */
  int type;          /**< 0 or OCS_VDB_TYPE_FLOAT: float; DOUBLE, INT32, VEC3 (vec3s: the value
                          in x, y = z = 0), POINTS (point data grid, see writer_add_points) */
  int klass;         /**< ocs_vdb_class_t; default 0: unknown (OpenVDB's default) */
  int half;          /**< float grids: save as 16-bit half floats */
  double voxel_size; /**< uniform voxel size when affine is 0. Zero or non-finite values are
                          written into the file as given (tests of bad files: OpenVDB refuses to
                          build such a transform, so the shim patches the saved bytes) */
  int affine;        /**< non-zero: the transform is i2w */
  double i2w[3][4];  /**< index → world, w = R·i + t (R = [..][0..2], t = [..][3]) */
} ocs_vdb_grid_desc_t;

/*! Progress of a read: bytes consumed so far of `total` (the file size). */
typedef void (*ocs_vdb_progress_fn)(void *ctx, uint64_t done, uint64_t total);

typedef struct ocs_vdb_api_s {
  uint32_t abi;  /**< OCS_VDB_SHIM_ABI */
  uint32_t size; /**< sizeof(ocs_vdb_api_t) */

  /*! version() : "OpenVDB 10.0.1 (ABI 10, blosc)". */
  const char *(*version)(void);

  /*-*** Reading ***/
  /*! open() : reads every grid of `path`. progress (may be NULL) is called while reading.
   *  @return 0; OC_ENOENT (missing), OC_EIO (unreadable, a directory), OC_EVERSION (not a VDB
   *  file), OC_ETRUNC (the file ends early), OC_ECORRUPT (OpenVDB refused it), OC_ENOMEM.
   *  `why` says what, without the path (the caller names the file). */
  int (*open)(const char *path, ocs_vdb_progress_fn progress, void *ctx, ocs_vdb_file_t **out, char *why,
              size_t why_len);
  /*! close() : NULL accepted. */
  void (*close)(ocs_vdb_file_t *f);
  /*! file_info() : file size in bytes, compression flags (OpenVDB's io::COMPRESS_* bits), format
   *  version. Any pointer may be NULL. */
  void (*file_info)(const ocs_vdb_file_t *f, uint64_t *bytes, uint32_t *compression, uint32_t *format_version);
  int (*grid_count)(const ocs_vdb_file_t *f);
  /*! grid_info() : grid i (0..count-1). with_range non-zero: scan the values for the range and
   *  the NaN/Inf/negative counts (scalar and vec3 grids). @return 0 or OC_EINVAL. */
  int (*grid_info)(const ocs_vdb_file_t *f, int i, int with_range, ocs_vdb_grid_info_t *out);
  /*! grid_prepare() : takes float (or double) grid i out of the file (the file keeps an empty
   *  slot) and prepares it for sampling. Values: NaN, ±Inf and negatives → 0 (counted in st);
   *  inactive values and the background → 0. @return 0; OC_EINVAL (not a float/double grid);
   *  OC_ENOMEM; OC_ECORRUPT. */
  int (*grid_prepare)(ocs_vdb_file_t *f, int i, ocs_vdb_grid_t **out, ocs_vdb_prep_stats_t *st, char *why,
                      size_t why_len);
  /*! grid_free() : NULL accepted. */
  void (*grid_free)(ocs_vdb_grid_t *g);
  /*! grid_levels() : pyramid levels, ≥ 1. Level l cell (a, b, c) is the mean of the voxels
   *  2^l·(a, b, c) + [0, 2^l)³ (inactive voxels count as 0). */
  int (*grid_levels)(const ocs_vdb_grid_t *g);
  /*! grid_sample() : trilinear interpolation of the level-`level` means at n points given in the
   *  grid's index space (voxel centres at integers; level l cell a is centred at
   *  2^l·a + (2^l - 1)/2). xyz holds 3n doubles; out n floats. level is clamped to the pyramid. */
  void (*grid_sample)(const ocs_vdb_grid_t *g, int level, const double *xyz, size_t n, float *out);
  /*! grid_range() : conservative [min, max] of the voxel values (inactive = 0) over the index
   *  box lo..hi (inclusive): the true range is inside it. */
  void (*grid_range)(const ocs_vdb_grid_t *g, const int32_t lo[3], const int32_t hi[3], float *vmin, float *vmax);

  /*-*** Writing (tests and export) ***/
  /*! writer_create() : @return 0 or OC_ENOMEM. */
  int (*writer_create)(ocs_vdb_writer_t **out);
  /*! writer_free() : NULL accepted. */
  void (*writer_free)(ocs_vdb_writer_t *w);
  /*! writer_add_grid() : @return the new grid's index (≥ 0), or OC_EINVAL with `why`. */
  int (*writer_add_grid)(ocs_vdb_writer_t *w, const ocs_vdb_grid_desc_t *d, char *why, size_t why_len);
  /*! writer_set_values() : a dense block of dims[0]·dims[1]·dims[2] values, x fastest, placed at
   *  index `origin`; every value that is not exactly 0 becomes an active voxel (NaN and negative
   *  values are written as given). Scalar grids only. @return 0 or OC_EINVAL. */
  int (*writer_set_values)(ocs_vdb_writer_t *w, int grid, const int32_t origin[3], const int32_t dims[3],
                           const float *values);
  /*! writer_fill() : active constant value over the index box lo..hi (inclusive); where the box
   *  covers whole nodes OpenVDB stores constant tiles (sparseFill). @return 0 or OC_EINVAL. */
  int (*writer_fill)(ocs_vdb_writer_t *w, int grid, const int32_t lo[3], const int32_t hi[3], float value);
  /*! writer_add_points() : n points (3n doubles, world space) into a POINTS grid (replaces what
   *  it held). @return 0 or OC_EINVAL. */
  int (*writer_add_points)(ocs_vdb_writer_t *w, int grid, const double *xyz, size_t n);
  /*! writer_set_meta() : a double (str NULL) or string metadata item on a grid. */
  int (*writer_set_meta)(ocs_vdb_writer_t *w, int grid, const char *key, double value, const char *str);
  /*! writer_save() : writes every grid to `path` (ocs_vdb_compress_t). @return 0, OC_EINVAL,
   *  OC_EIO (with `why`). */
  int (*writer_save)(ocs_vdb_writer_t *w, const char *path, int compression, char *why, size_t why_len);
} ocs_vdb_api_t;

/*! The shim's one exported function (visibility default); NULL when abi is not OCS_VDB_SHIM_ABI. */
typedef const ocs_vdb_api_t *(*ocs_vdb_shim_api_fn)(uint32_t abi);

/*! ocs_vdb_load() : (vdb_loader.c, in ocs_core) dlopens the shim once per process and returns its
 *  table. Search order: $OC_VDB_SHIM, then the build tree (OCS_VDB_SHIM_BUILD_PATH), then
 *  <folder of /proc/self/exe>/../lib/liboc_vdb_shim.so. Thread-safe; the shim stays loaded.
 *  @return 0, or OC_EIO with every path tried and why each failed in `why`. */
int ocs_vdb_load(const ocs_vdb_api_t **out, char *why, size_t why_len);

#ifdef __cplusplus
}
#endif

#endif /* OC_SERVER_VDB_SHIM_H */
