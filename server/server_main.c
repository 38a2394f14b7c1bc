/* overcast-server — the server. By default it serves the scene's world to viewers and control
 * clients over TCP (ocs_server.h). Other modes: load a scene and build its field (--check), inspect VDB
 * files (--inspect), export a region of the field to a .vdb (--export-vdb), and run the server
 * core for one viewer offline, writing the state it would hold (--save-state). The options are one
 * table (server_config.c), which also generates --help; this file parses with it and dispatches. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "oc_cli.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_scene.h"
#include "oc_camera.h"
#include "oc_state.h"
#include "ocs_field.h"
#include "vdb_tools.h"
#include "ocs_server.h"
#include "server_config.h"
#include "world.h"

static const char *prog = "overcast-server";

/* Steps the server core for one viewer and writes the state it holds at the end. */
static int save_state(const oc_scene_t *sc, const ocs_config_t *c) {
  char why[1024];
  ocs_world_desc_t wd = {.threads = c->threads, .time = c->time};
  ocs_world_t *w = NULL;
  if (ocs_world_create(&w, sc, &wd, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  oc_camera_pose_t pose = c->camera;
  if (!c->camera_given) pose = (oc_camera_pose_t){sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  ocs_plan_desc_t d = {.budget = c->budget, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .max_depth = 21};
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, c->viewport[0], c->viewport[1]};
  oc_state_t st;
  oc_state_init(&st);
  int rc = OC_EXIT_OK;
  if (ocs_world_plan_offline(w, &d, &view, c->epochs, &st, why, sizeof why) < 0 ||
      oc_state_save(&st, c->save_path, why, sizeof why) < 0)
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  else
    printf("%s\n", c->save_path);
  oc_state_free(&st);
  ocs_world_free(w);
  return rc;
}

/* Serves the world until SIGINT/SIGTERM. */
static int serve(const oc_scene_t *sc, const ocs_server_desc_t *d) {
  char why[1024];
  ocs_server_t *srv = NULL;
  signal(SIGPIPE, SIG_IGN); /* a vanished peer is an error code on write, not a killed server */
  if (ocs_server_create(&srv, sc, d, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  printf("listening on %s\n", ocs_server_address(srv));
  if (ocs_server_metrics_address(srv)) printf("metrics on %s\n", ocs_server_metrics_address(srv));
  fflush(stdout);
  oc_log_info("serving scene %s (%s), epoch period %s", sc->name,
              oc_scene_has(sc, OC_FEATURE_ANIMATION) ? "animated" : "static",
              d->epoch_period == 0 ? "0: stepped by command" : "as configured");
  int r = ocs_server_run(srv, 1);
  ocs_server_free(srv);
  if (r < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", oc_strerror(r));
  oc_log_info("stopped");
  return OC_EXIT_OK;
}

/* --check and --export-vdb: builds the field, prints the summary, writes the region. */
static int field_modes(const oc_scene_t *sc, const ocs_config_t *c) {
  char why[1024];
  ocs_field_t *field = NULL;
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if (ocs_field_create(&field, sc, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", c->scene_path ? c->scene_path : "built-in planet", why);
  clock_gettime(CLOCK_MONOTONIC, &t1);
  if (c->check) {
    printf("scene %s: %d source(s), %s, field built in %.3f s\n", sc->name, sc->nsources,
           ocs_field_animated(field) ? "animated (3 kept states)" : "static (2 kept states)",
           (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec));
    for (int i = 0; i < sc->nsources; i++)
      printf("  sources[%d]: %s\n", i, oc_scene_source_type_name(sc->sources[i].type));
  }
  int rc = OC_EXIT_OK;
  if (c->export_path) {
    double lat = c->region[0], lon = c->region[1], alt = c->region[2], rad = c->region[3];
    if (!c->region_given) lat = sc->camera.pos.lat, lon = sc->camera.pos.lon, alt = sc->camera.pos.alt;
    oc_dvec3 c0 = oc_geo_to_xyz((oc_geo_t){lat, lon, alt}), r = oc_dv3(rad, rad, rad);
    if (ocs_vdb_export(field, c->time, oc_dsub(c0, r), oc_dadd(c0, r), c->level, c->export_path, why, sizeof why) < 0)
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    else
      printf("%s\n", c->export_path);
  }
  ocs_field_free(field);
  return rc;
}

/* Every mode but --inspect: loads the scene, then checks, exports, serves or saves a state. */
static int scene_modes(ocs_config_t *c) {
  char why[1024];
  oc_scene_t *sc = calloc(1, sizeof *sc);
  if (!sc) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  int rc = OC_EXIT_OK;
  if (c->scene_path && oc_scene_load(sc, c->scene_path, why, sizeof why) < 0)
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  else if (!c->scene_path)
    oc_scene_default(sc);
  if (rc == OC_EXIT_OK && (c->check || c->export_path)) rc = field_modes(sc, c);
  if (rc == OC_EXIT_OK && c->serving) rc = serve(sc, &c->desc);
  if (rc == OC_EXIT_OK && c->save_path) rc = save_state(sc, c);
  oc_scene_free(sc);
  free(sc);
  return rc;
}

int main(int argc, char **argv) {
  ocs_config_t cfg;
  int rc = ocs_config_parse(&cfg, argc, argv);
  if (rc != OCS_CONFIG_RUN) return rc;
  if (cfg.quiet) oc_log_set_level(OC_LOG_ERROR);
  if (cfg.inspect) {
    char why[1024];
    if (ocs_vdb_inspect(cfg.inspect, cfg.json, stdout, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    return OC_EXIT_OK;
  }
  return scene_modes(&cfg);
}
