/* vdb_tools.h — VDB files from the command line: inspect a file, export a region of the field.
 *
 * Both load the OpenVDB shim on demand (vdb_loader.c): a server that never inspects, exports or
 * imports VDB never maps OpenVDB, TBB or Boost. docs/vdb.md describes the formats. */
#ifndef OC_SERVER_VDB_TOOLS_H
#define OC_SERVER_VDB_TOOLS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "oc_math.h"   /* oc_dvec3 */
#include "ocs_field.h" /* ocs_field_t, ocs_source_t */
#include "vdb_shim.h"  /* ocs_vdb_grid_info_t, ocs_vdb_prep_stats_t */

/*! Most voxels ocs_vdb_export() writes (counted over the lattice of the region, before empty
 *  nodes are skipped). */
#ifndef OCS_VDB_EXPORT_MAX_VOXELS
#define OCS_VDB_EXPORT_MAX_VOXELS ((uint64_t)1 << 28)
#endif

/*! ocs_vdb_inspect() :
 *  Prints every grid of a .vdb file to `out`: name, value type, class, voxel size, transform kind,
 *  active voxel count (and constant tiles), index bounding box, value range and counts of
 *  non-finite and negative values (scalar grids). `json` non-zero: one JSON object (cJSON).
 *  @return 0, or a negative OC_E* (OC_ENOENT, OC_EVERSION for a file that is not a VDB, OC_ETRUNC,
 *  OC_ECORRUPT, OC_EIO when the shim cannot be loaded) with one line naming the file in `why`. */
int ocs_vdb_inspect(const char *path, int json, FILE *out, char *why, size_t why_len);

/*! ocs_vdb_export() :
 *  Writes the field's σt at world time t over the planet-frame box [lo, hi] to `path` as one float
 *  fog-volume grid named "density" (blosc-compressed when the library has it, else zip).
 *  Voxels are the global sample lattice of `level` (spacing size(level)/7, the corner samples of
 *  every node of that level meeting the box, each from ocs_field_sample, so each value is the
 *  field's box-filtered σt at that level). Values are σt in m⁻¹ (zeros are left inactive).
 *  The transform maps index space to metres in a local Y-up frame at the box centre C:
 *  x = east, y = up, z = south (-north) of C, origin C (Houdini's and OpenVDB's Y-up convention);
 *  the grid's metadata records C (overcast_origin_lat/lon/alt) and the level.
 *  Importing the file with scale_m 0, heading 0 and the anchor at the position of the bottom-face
 *  centre of its active box puts the voxels back where they were (round trip in tests/server/test_vdb.c).
 *  @return 0; OC_EINVAL (bad box or level); OC_ETOOBIG (more than OCS_VDB_EXPORT_MAX_VOXELS);
 *  OC_EIO (shim not loadable, write failed); with one line in `why`. */
int ocs_vdb_export(const ocs_field_t *f, double t, oc_dvec3 lo, oc_dvec3 hi, int level, const char *path, char *why,
                   size_t why_len);

/*! What a vdb source holds (source_vdb.c), for --check, tests and benches. */
typedef struct {
  ocs_vdb_grid_info_t grid;  /**< frame 0's grid as read (before sanitising) */
  ocs_vdb_prep_stats_t prep; /**< frame 0's sanitised values, pyramid levels and memory */
  int grid_index;            /**< position of the grid in its file */
  double load_seconds;       /**< frame 0: open, read, prepare, place */
  double extent_m[3];        /**< the placed active box along east, north, up, metres */
  double voxel_m[3];         /**< metres per index step along each index axis */
  oc_dvec3 anchor;           /**< planet-frame position of the anchor */
  int frames;                /**< 1, or the sequence's count */
  int cache_slots;           /**< frames kept in memory at most */
} ocs_vdb_source_info_t;

/*! ocs_vdb_source_info() : @return 0, or OC_EINVAL when src is not a vdb source. */
int ocs_vdb_source_info(const ocs_source_t *src, ocs_vdb_source_info_t *out);

/*! ocs_vdb_frame_path() : the file of a VDB source's frame `index`: with a sequence, the file's
 *  run of '#' replaced by first + index, zero-padded to the run's length; else the file itself. */
void ocs_vdb_frame_path(const char *file, int has_seq, int first, int index, char *out, size_t cap);

#endif /* OC_SERVER_VDB_TOOLS_H */
