/* oc.h — the public header of common/ (library oc_common): what every layer uses. Other modules and
 * tools include this (or, inside server/ and client/, the oc_*.h headers it names); the shaders'
 * shared GLSL/C headers (the headers in shaders/) are included by name, since a file chooses their precision
 * (OCG_REAL_DOUBLE) before including them. docs/architecture.md, "Modules", has the layering. */
#ifndef OC_H
#define OC_H

#include "oc_atmo.h"         /* atmosphere tables */
#include "oc_backoff.h"      /* reconnect backoff */
#include "oc_brick.h"        /* brick codes */
#include "oc_budget.h"       /* the memory budget's accounting */
#include "oc_bytes.h"        /* little-endian byte access */
#include "oc_camera.h"       /* camera and poses */
#include "oc_cli.h"          /* option tables, --help, exit codes */
#include "oc_err.h"          /* error codes */
#include "oc_image.h"        /* images and PNG */
#include "oc_key.h"          /* octree keys */
#include "oc_log.h"          /* logging */
#include "oc_math.h"         /* double vectors */
#include "oc_noise.h"        /* noise */
#include "oc_parallel.h"     /* a parallel loop over items */
#include "oc_planet.h"       /* planet frame */
#include "oc_render.h"       /* the CPU reference renderer */
#include "oc_scene.h"        /* scene files */
#include "oc_scene_render.h" /* a scene's features for rendering */
#include "oc_state.h"        /* the state and its file */

#endif /* OC_H */
