/* overcast-server — the server. By default it serves the scene's world to viewers and control
 * clients over TCP (ocs_server.h). Other modes: load a scene and build its field (--check), inspect VDB
 * files (--inspect), export a region of the field to a .vdb (--export-vdb), and run the server
 * core for one viewer offline, writing the state it would hold (--save-state). */
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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
#include "ocp_wire.h"
#include "world.h"

static const char *prog = "overcast-server";

static void usage(FILE *f) {
  fprintf(f,
          "usage: overcast-server [options]\n"
          "Owns the cloud field of a scene (procedural, analytic, or imported from OpenVDB) and serves\n"
          "it to viewers (overcast-view) and control clients (overcast-ctl) over TCP.\n"
          "\n"
          "  --scene FILE          scene file (default: the built-in procedural planet)\n"
          "Serving (the default mode):\n"
          "  --listen HOST:PORT    address to listen on (default 127.0.0.1:7420; port 0 picks a free\n"
          "                        port; the address bound is printed as \"listening on HOST:PORT\")\n"
          "  --token TEXT          clients must present this token (viewers and control alike)\n"
          "  --epoch-period S      seconds between epochs (default: the scene's, 1); 0: epochs are\n"
          "                        stepped only by control requests (overcast-ctl step)\n"
          "  --max-viewers N       viewers at once (default 64)\n"
          "  --max-budget MIB      largest budget granted to one viewer (default: the total)\n"
          "  --total-budget MIB    sum of all viewers' budgets (default 4096)\n"
          "  --cache MIB           shared brick cache (default 256)\n"
          "  --linger S            keep a dropped viewer's session this long for resume (default 30; 0 off)\n"
          "  --idle-timeout S      close connections silent this long (default 60)\n"
          "  --stall-timeout S     close connections that stop reading this long (default 30)\n"
          "  --queue-limits SOFT,HARD  unsent bytes per connection in MiB (default 4,16)\n"
          "  --zstd-level N        compression level 1..19 (default 3)\n"
          "  --send-buffer KIB     kernel send buffer per connection (default: the system's); smaller\n"
          "                        keeps more of a slow viewer's backlog under the server's own limits\n"
          "  --no-deltas           send refreshed bricks whole\n"
          "Other modes:\n"
          "  --check               load the scene, build every source, print a summary and exit\n"
          "  --inspect FILE.vdb    print the grids of a VDB file and exit (types, classes, voxel size,\n"
          "                        active voxels, bounding box, value range)\n"
          "  --json                with --inspect: machine-readable output\n"
          "  --export-vdb OUT.vdb  write a region of the field as a float grid \"density\" and exit\n"
          "  --region LAT,LON,ALT,RADIUS   the region to export: a cube of half-size RADIUS metres\n"
          "                        around a point (default: the scene camera's position, 5000 m)\n"
          "  --level N             octree level of the exported voxels (default 16)\n"
          "  --time T              world time in seconds for --export-vdb and --save-state (default 0)\n"
          "  --save-state OUT      run the server core for one viewer and write the state it holds after\n"
          "                        the last epoch (a state file: overcast-view --state OUT renders it)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   the viewer's camera (default: the scene's)\n"
          "  --epochs N            epochs to step for --save-state (default 8)\n"
          "  --budget MIB          the viewer's budget for --save-state (default 64; 2048-byte slots,\n"
          "                        32-byte records)\n"
          "  --viewport WxH        the viewer's viewport for --save-state (default 1280x720)\n"
          "  --threads N           producer threads (default: all cores)\n"
          "  -q, --quiet           only errors\n"
          "  --help, --version\n"
          "\n"
          "SIGINT or SIGTERM: every client gets a goodbye and the server exits with status 0.\n"
          "exit status: 0 ok, 1 runtime error (bad scene or file), 2 usage error\n");
}

/* Steps the server core for one viewer and writes the state it holds at the end. */
static int save_state(const oc_scene_t *sc, const oc_camera_pose_t *pose, double t, int epochs, uint64_t budget, int vw,
                      int vh, int threads, const char *path) {
  char why[1024];
  ocs_world_desc_t wd = {.threads = threads, .time = t};
  ocs_world_t *w = NULL;
  if (ocs_world_create(&w, sc, &wd, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  ocs_plan_desc_t d = {.budget = budget, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 21};
  oc_camera_t cam = oc_camera_from_pose(*pose);
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose->fov, vw, vh};
  oc_state_t st;
  oc_state_init(&st);
  int rc = OC_EXIT_OK;
  if (ocs_world_plan_offline(w, &d, &view, epochs, &st, why, sizeof why) < 0 || oc_state_save(&st, path, why, sizeof why) < 0)
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  else
    printf("%s\n", path);
  oc_state_free(&st);
  ocs_world_free(w);
  return rc;
}

/* "HOST:PORT" or "[V6]:PORT" or ":PORT" or "PORT". */
static int parse_listen(const char *text, char *host, size_t cap, int *port) {
  const char *colon = strrchr(text, ':');
  const char *ps = colon ? colon + 1 : text;
  char *end;
  long p = strtol(ps, &end, 10);
  if (end == ps || *end || p < 0 || p > 65535) return -1;
  *port = (int)p;
  if (!colon || colon == text) {
    snprintf(host, cap, "127.0.0.1");
    return 0;
  }
  const char *h = text;
  size_t n = (size_t)(colon - text);
  if (h[0] == '[' && n >= 2 && h[n - 1] == ']') {
    h++;
    n -= 2;
  }
  if (n == 0 || n >= cap) return -1;
  memcpy(host, h, n);
  host[n] = 0;
  return 0;
}

/* Serves the world until SIGINT/SIGTERM. */
static int serve(const oc_scene_t *sc, ocs_server_desc_t *d) {
  char why[1024];
  ocs_server_t *srv = NULL;
  signal(SIGPIPE, SIG_IGN); /* a vanished peer is an error code on write, not a killed server */
  if (ocs_server_create(&srv, sc, d, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  printf("listening on %s\n", ocs_server_address(srv));
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

static int parse_region(const char *text, double v[4]) {
  char *end;
  const char *s = text;
  for (int i = 0; i < 4; i++) {
    v[i] = strtod(s, &end);
    if (end == s || (i < 3 && *end != ',') || (i == 3 && *end)) return -1;
    s = end + 1;
  }
  return (v[0] >= -90 && v[0] <= 90 && v[1] >= -360 && v[1] <= 360 && v[3] > 0 && v[3] <= 1e6) ? 0 : -1;
}

int main(int argc, char **argv) {
  enum { O_SCENE = 256, O_CHECK, O_INSPECT, O_JSON, O_EXPORT, O_REGION, O_LEVEL, O_TIME, O_SAVE, O_CAMERA, O_EPOCHS,
         O_BUDGET, O_VIEWPORT, O_THREADS, O_HELP, O_VERSION, O_LISTEN, O_TOKEN, O_PERIOD, O_MAXV, O_MAXB, O_TOTAL,
         O_CACHE, O_LINGER, O_IDLE, O_STALL, O_QUEUE, O_ZLEVEL, O_NODELTA, O_SNDBUF };
  static const struct option opts[] = {
      {"scene", required_argument, 0, O_SCENE},   {"check", no_argument, 0, O_CHECK},
      {"inspect", required_argument, 0, O_INSPECT}, {"json", no_argument, 0, O_JSON},
      {"export-vdb", required_argument, 0, O_EXPORT}, {"region", required_argument, 0, O_REGION},
      {"level", required_argument, 0, O_LEVEL},   {"time", required_argument, 0, O_TIME},
      {"save-state", required_argument, 0, O_SAVE}, {"camera", required_argument, 0, O_CAMERA},
      {"epochs", required_argument, 0, O_EPOCHS}, {"budget", required_argument, 0, O_BUDGET},
      {"viewport", required_argument, 0, O_VIEWPORT}, {"threads", required_argument, 0, O_THREADS},
      {"quiet", no_argument, 0, 'q'},             {"help", no_argument, 0, O_HELP},
      {"version", no_argument, 0, O_VERSION},     {"listen", required_argument, 0, O_LISTEN},
      {"token", required_argument, 0, O_TOKEN},   {"epoch-period", required_argument, 0, O_PERIOD},
      {"max-viewers", required_argument, 0, O_MAXV}, {"max-budget", required_argument, 0, O_MAXB},
      {"total-budget", required_argument, 0, O_TOTAL}, {"cache", required_argument, 0, O_CACHE},
      {"linger", required_argument, 0, O_LINGER}, {"idle-timeout", required_argument, 0, O_IDLE},
      {"stall-timeout", required_argument, 0, O_STALL}, {"queue-limits", required_argument, 0, O_QUEUE},
      {"zstd-level", required_argument, 0, O_ZLEVEL}, {"no-deltas", no_argument, 0, O_NODELTA},
      {"send-buffer", required_argument, 0, O_SNDBUF},
      {0, 0, 0, 0}};
  const char *scene_path = NULL, *inspect = NULL, *export_path = NULL, *region_text = NULL, *save_path = NULL,
             *camera_text = NULL;
  int check = 0, json = 0, c, vw = 1280, vh = 720;
  long level = 16, epochs = 8, budget_mib = 64, threads = 0;
  double t = 0.0;
  ocs_server_desc_t sd = {.epoch_period = -1, .linger_s = -1};
  char host[64] = "127.0.0.1";
  int port = 7420, serve_opts = 0;
  long lv;
  opterr = 0;
  while ((c = getopt_long(argc, argv, "q", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_CHECK: check = 1; break;
      case O_INSPECT: inspect = optarg; break;
      case O_JSON: json = 1; break;
      case O_EXPORT: export_path = optarg; break;
      case O_REGION: region_text = optarg; break;
      case O_LEVEL: if (oc_cli_int(prog, "--level", optarg, 0, 21, &level)) return OC_EXIT_USAGE; break;
      case O_TIME: if (oc_cli_double(prog, "--time", optarg, -1e12, 1e12, &t)) return OC_EXIT_USAGE; break;
      case O_SAVE: save_path = optarg; break;
      case O_CAMERA: camera_text = optarg; break;
      case O_EPOCHS: if (oc_cli_int(prog, "--epochs", optarg, 1, 100000, &epochs)) return OC_EXIT_USAGE; break;
      case O_BUDGET: if (oc_cli_int(prog, "--budget", optarg, 1, 1 << 20, &budget_mib)) return OC_EXIT_USAGE; break;
      case O_THREADS: if (oc_cli_int(prog, "--threads", optarg, 0, 64, &threads)) return OC_EXIT_USAGE; break;
      case O_VIEWPORT:
        if (sscanf(optarg, "%dx%d", &vw, &vh) != 2 || vw < 1 || vh < 1 || vw > 16384 || vh > 16384)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--viewport: expected WxH (1..16384), got \"%s\"", optarg);
        break;
      case O_LISTEN:
        if (parse_listen(optarg, host, sizeof host, &port) < 0)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--listen: expected HOST:PORT (port 0..65535), got \"%s\"", optarg);
        serve_opts = 1;
        break;
      case O_TOKEN:
        if (!*optarg || strlen(optarg) > OCP_TOKEN_MAX)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--token: 1..%d bytes", OCP_TOKEN_MAX);
        sd.token = optarg;
        serve_opts = 1;
        break;
      case O_PERIOD: if (oc_cli_double(prog, "--epoch-period", optarg, 0, 60, &sd.epoch_period)) return OC_EXIT_USAGE; serve_opts = 1; break;
      case O_MAXV: if (oc_cli_int(prog, "--max-viewers", optarg, 1, 100000, &lv)) return OC_EXIT_USAGE; sd.world.max_viewers = (int)lv; serve_opts = 1; break;
      case O_MAXB: if (oc_cli_int(prog, "--max-budget", optarg, 1, 1 << 24, &lv)) return OC_EXIT_USAGE; sd.world.max_budget = (uint64_t)lv << 20; serve_opts = 1; break;
      case O_TOTAL: if (oc_cli_int(prog, "--total-budget", optarg, 1, 1 << 24, &lv)) return OC_EXIT_USAGE; sd.world.viewer_bytes = (uint64_t)lv << 20; serve_opts = 1; break;
      case O_CACHE: if (oc_cli_int(prog, "--cache", optarg, 1, 1 << 20, &lv)) return OC_EXIT_USAGE; sd.world.cache_bytes = (uint64_t)lv << 20; serve_opts = 1; break;
      case O_LINGER: if (oc_cli_double(prog, "--linger", optarg, 0, 86400, &sd.linger_s)) return OC_EXIT_USAGE; serve_opts = 1; break;
      case O_IDLE: if (oc_cli_double(prog, "--idle-timeout", optarg, 0.1, 86400, &sd.idle_s)) return OC_EXIT_USAGE; serve_opts = 1; break;
      case O_STALL: if (oc_cli_double(prog, "--stall-timeout", optarg, 0.1, 86400, &sd.stall_s)) return OC_EXIT_USAGE; serve_opts = 1; break;
      case O_QUEUE: {
        long a, b;
        char extra;
        if (sscanf(optarg, "%ld,%ld%c", &a, &b, &extra) != 2 || a < 1 || b < a || b > 65536)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--queue-limits: expected SOFT,HARD in MiB (1 ≤ SOFT ≤ HARD ≤ 65536), got \"%s\"", optarg);
        sd.queue_soft = (uint64_t)a << 20;
        sd.queue_hard = (uint64_t)b << 20;
        serve_opts = 1;
        break;
      }
      case O_ZLEVEL: if (oc_cli_int(prog, "--zstd-level", optarg, 1, 19, &lv)) return OC_EXIT_USAGE; sd.zstd_level = (int)lv; serve_opts = 1; break;
      case O_NODELTA: sd.deltas = -1; serve_opts = 1; break;
      case O_SNDBUF: if (oc_cli_int(prog, "--send-buffer", optarg, 1, 1 << 20, &lv)) return OC_EXIT_USAGE; sd.send_buffer = (int)lv << 10; serve_opts = 1; break;
      case 'q': oc_log_set_level(OC_LOG_ERROR); break;
      case O_HELP: usage(stdout); return OC_EXIT_OK;
      case O_VERSION: oc_cli_version(prog); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown or incomplete option \"%s\" (see --help)", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "unexpected argument \"%s\" (see --help)", argv[optind]);
  if (json && !inspect) return oc_cli_fail(prog, OC_EXIT_USAGE, "--json goes with --inspect");
  if (inspect && (check || export_path || scene_path))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--inspect takes no scene, --check or --export-vdb");
  if ((region_text || level != 16) && !export_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--region and --level go with --export-vdb");
  double region[4] = {0, 0, 0, 5000};
  if (region_text && parse_region(region_text, region))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--region: expected LAT,LON,ALT,RADIUS (radius in (0, 1e6] m), got \"%s\"", region_text);

  char why[1024];
  if (inspect) {
    if (ocs_vdb_inspect(inspect, json, stdout, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    return OC_EXIT_OK;
  }
  int serving = !check && !export_path && !save_path;
  if (serve_opts && !serving) return oc_cli_fail(prog, OC_EXIT_USAGE, "serving options go without --check, --export-vdb and --save-state");
  if (camera_text && !save_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera goes with --save-state");
  oc_camera_pose_t pose;
  if (camera_text && oc_camera_parse(camera_text, &pose, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);

  oc_scene_t *sc = calloc(1, sizeof *sc);
  ocs_field_t *field = NULL;
  int rc = OC_EXIT_OK;
  if (!sc) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  if (scene_path) {
    if (oc_scene_load(sc, scene_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else {
    oc_scene_default(sc);
  }
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if ((check || export_path) && ocs_field_create(&field, sc, why, sizeof why) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", scene_path ? scene_path : "built-in planet", why);
    goto out;
  }
  clock_gettime(CLOCK_MONOTONIC, &t1);
  if (check) {
    printf("scene %s: %d source(s), %s, field built in %.3f s\n", sc->name, sc->nsources,
           ocs_field_animated(field) ? "animated (3 kept states)" : "static (2 kept states)",
           (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec));
    for (int i = 0; i < sc->nsources; i++) printf("  sources[%d]: %s\n", i, oc_scene_source_type_name(sc->sources[i].type));
  }
  if (export_path) {
    if (!region_text) {
      region[0] = sc->camera.pos.lat;
      region[1] = sc->camera.pos.lon;
      region[2] = sc->camera.pos.alt;
    }
    oc_geo_t g = {region[0], region[1], region[2]};
    oc_dvec3 c0 = oc_geo_to_xyz(g), r = oc_dv3(region[3], region[3], region[3]);
    if (ocs_vdb_export(field, t, oc_dsub(c0, r), oc_dadd(c0, r), (int)level, export_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
    printf("%s\n", export_path);
  }
  if (serving) {
    sd.host = host;
    sd.port = port;
    sd.scene_path = scene_path;
    sd.world.threads = (int)threads;
    sd.world.time = t;
    rc = serve(sc, &sd);
  }
  if (save_path) {
    if (!camera_text) pose = (oc_camera_pose_t){sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
    rc = save_state(sc, &pose, t, (int)epochs, (uint64_t)budget_mib << 20, vw, vh, (int)threads, save_path);
  }
out:
  ocs_field_free(field);
  oc_scene_free(sc);
  free(sc);
  return rc;
}
