/* bench_field.c — `overcast-bench field`: brick production speed of a scene's field sources.
 *
 * Takes a block of n³ nodes at one level around a point (--at LAT,LON, default the scene camera's
 * position, at the altitude given), asks the bound of each and samples those it cannot classify, on one
 * thread: bricks per second per core, and the fraction the bound classified without sampling. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bench.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "ocs_field.h"

int oct_bench_field(const char *prog, int argc, char **argv) {
  enum { O_SCENE = 256, O_LEVELS, O_BLOCK, O_ALT, O_AT, O_TIME, O_HELP };
  static const struct option opts[] = {{"scene", required_argument, 0, O_SCENE}, {"levels", required_argument, 0, O_LEVELS},
                                       {"block", required_argument, 0, O_BLOCK}, {"alt", required_argument, 0, O_ALT},
                                       {"at", required_argument, 0, O_AT},
                                       {"time", required_argument, 0, O_TIME},   {"help", no_argument, 0, O_HELP},
                                       {0, 0, 0, 0}};
  const char *scene_path = NULL, *levels_text = "10,13,16";
  long block = 6;
  double alt = 2000.0, t = 0.0, at[2];
  int have_at = 0;
  int c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_LEVELS: levels_text = optarg; break;
      case O_BLOCK: if (oc_cli_int(prog, "--block", optarg, 1, 64, &block)) return OC_EXIT_USAGE; break;
      case O_ALT: if (oc_cli_double(prog, "--alt", optarg, -1e4, 1e5, &alt)) return OC_EXIT_USAGE; break;
      case O_TIME: if (oc_cli_double(prog, "--time", optarg, -1e12, 1e12, &t)) return OC_EXIT_USAGE; break;
      case O_AT:
        if (oct_parse_at(prog, optarg, at)) return OC_EXIT_USAGE;
        have_at = 1;
        break;
      case O_HELP: oct_bench_usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "field: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "field: unexpected argument \"%s\"", argv[optind]);
  long levels[22];
  int nlevels = 0;
  if (oct_parse_list(prog, "--levels", levels_text, 0, 21, levels, 22, &nlevels)) return OC_EXIT_USAGE;

  char why[1024];
  static oc_scene_t sc;
  if (oct_load_scene(prog, scene_path, &sc)) return OC_EXIT_RUNTIME;
  ocs_field_t *f = NULL;
  double tc = oct_now();
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  tc = oct_now() - tc;
  oc_geo_t g = {have_at ? at[0] : sc.camera.pos.lat, have_at ? at[1] : sc.camera.pos.lon, alt};
  oc_dvec3 centre = oc_geo_to_xyz(g);
  printf("# field sources of %s (%d source(s), built in %.3f s), %ld³ nodes per level around %.3f°, %.3f°, %.0f m, "
         "t = %g s, one thread\n\n",
         scene_path ? scene_path : "the built-in planet", sc.nsources, tc, block, g.lat, g.lon, alt, t);
  printf("| level | node size (m) | nodes | classified by bound | sampled | bricks/s per core | µs per brick | non-empty samples |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  float *s = malloc(sizeof(float) * OC_BRICK_VOXELS);
  for (int li = 0; li < nlevels; li++) {
    int level = (int)levels[li];
    oc_key_t k0 = oc_key_from_point(level, centre);
    uint32_t ix, iy, iz;
    oc_key_coords(k0, &ix, &iy, &iz);
    long nodes = 0, classified = 0, sampled = 0, nonempty = 0;
    double ts = 0.0;
    for (long z = 0; z < block; z++)
      for (long y = 0; y < block; y++)
        for (long x = 0; x < block; x++) {
          oc_key_t k = oc_key_neighbor(k0, (int)(x - block / 2), (int)(y - block / 2), (int)(z - block / 2));
          if (k == OC_KEY_INVALID) continue;
          nodes++;
          float lo, hi;
          double t0 = oct_now();
          ocs_field_bound(f, k, t, &lo, &hi);
          if (lo == hi) {
            classified++;
            ts += oct_now() - t0;
            continue;
          }
          if (ocs_field_sample(f, k, t, s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
          ts += oct_now() - t0;
          sampled++;
          for (int i = 0; i < OC_BRICK_VOXELS; i++) nonempty += s[i] > 0.0f;
        }
    fprintf(stderr, "\r\033[K");
    printf("| %d | %.1f | %ld | %.1f %% | %ld | %.0f | %.1f | %.1f %% |\n", level, oc_key_size(level), nodes,
           100.0 * classified / nodes, sampled, sampled ? sampled / ts : 0.0, sampled ? 1e6 * ts / sampled : 0.0,
           sampled ? 100.0 * nonempty / (sampled * 512.0) : 0.0);
    fflush(stdout);
  }
  free(s);
  ocs_field_free(f);
  oc_scene_free(&sc);
  return OC_EXIT_OK;
}
