/* ocs.h — the public header of server/ (library ocs_core), for tools and tests: the server
 * (ocs_server.h), the world that plans and produces (world.h) with its planner (planner.h), field
 * sources (ocs_field.h), the sun's optical depth (sun_depth.h), the VDB shim's table (vdb_shim.h),
 * and the generators of reference states: analytic media (analytic.h) and the voxelizers
 * (voxelize.h, scene_voxelize.h). Includes proto's ocp.h. Everything else in server/ is private. */
#ifndef OCS_H
#define OCS_H

#include "ocp.h"
#include "analytic.h"       /* closed-form media: ocs_prim_*, ocs_medium_* */
#include "ocs_field.h"      /* field sources */
#include "noise_volume.h"   /* tiled pre-filtered noise volumes: ocs_nvol_* */
#include "ocs_server.h"     /* the server: create, run, stop */
#include "planner.h"        /* the planner: ocs_plan_* */
#include "scene_voxelize.h" /* a scene's analytic sources as one state: ocs_scene_voxelize */
#include "sun_depth.h"      /* the sun's optical depth volume */
#include "vdb_shim.h"       /* the OpenVDB shim's table */
#include "voxelize.h"       /* box-filtered bricks and the state builder: ocs_voxelize */
#include "world.h"          /* the world: plan and produce per viewer */

#endif /* OCS_H */
