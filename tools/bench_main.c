/* overcast-bench — benchmarks; one file per subcommand (bench_*.c). Figures go into
 * docs/performance.md with the command that made them. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "oc_cli.h"

static const char *prog = "overcast-bench";

void oct_bench_usage(FILE *f) {
  fprintf(f,
          "usage: overcast-bench COMMAND [options]\n"
          "\n"
          "commands:\n"
          "  render     CPU reference renderer throughput per thread count\n"
          "  field      brick production of a scene's field sources: bricks/s per core, bound classification\n"
          "  tau        sun optical depth τ: direct march vs group volume, µs per brick and the volume's error\n"
          "  plan       LOD planner: a re-plan of about a million leaves (still, moved, teleported), ms on one core\n"
          "  world      the server core stepped for some epochs: plans, production, cache, refresh savings\n"
          "  wire       epoch encodings side by side: per-brick zstd, batches, deltas, a dictionary\n"
          "  sweep      error against run time: quality knobs swept, RMSE/PSNR against the best setting\n"
          "  truth      Monte Carlo ground truth (delta tracking, every scattering order) for small views\n"
          "  model      the cloud model against stored truth images (truth --save): errors, fit objective\n"
          "  stability  stiff and extreme cases end to end (server, protocol, renderers): finite, bounded, known answers\n"
          "  features   each feature a scene uses turned off alone: server time, bricks, wire, memory, tables, render\n"
          "\n"
          "render options:\n"
          "  --scene FILE        analytic scene (default scenes/analytic_sphere.json)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   (default: the scene's camera)\n"
          "  --size WxH          image size (default 320x180)\n"
          "  --threads LIST      comma-separated thread counts (default 1,2)\n"
          "  --repeat N          renders per thread count; the fastest counts (default 3)\n"
          "  --step-factor X     (default 0.5)\n"
          "  --time T            world time in seconds (default 0)\n"
          "  --png FILE          also write the first thread count's image\n"
          "  --gl                also time the GL compute renderer (headless EGL) on the same state and give\n"
          "                      its RMSE against the CPU image\n"
          "  (scenes with procedural or vdb sources: the state the server core plans for a viewer at\n"
          "   this camera, 8 epochs, 64 MiB)\n"
          "\n"
          "field options:\n"
          "  --scene FILE        scene (default: the built-in procedural planet)\n"
          "  --levels LIST       octree levels (default 10,13,16)\n"
          "  --block N           N³ nodes per level around the scene camera (default 6)\n"
          "  --at LAT,LON        centre of the block (default: the scene camera)\n"
          "  --alt M             altitude of the block's centre in metres (default 2000)\n"
          "  --time T            world time in seconds (default 0)\n"
          "  --march-clear       march τ even where the sun column is proven clear (the state before\n"
          "                      the clear-sky shortcut; the same bits, counted as clear marched)\n"
          "  --exact             also sample the same nodes through the sources' exact box filter: its\n"
          "                      µs per brick beside the fast filter's, and the fast one's error\n"
          "  (prints the anchor beside each level: a scalar 6-octave Perlin fBm once per voxel, bricks/s\n"
          "   per core, and the ratios to it; with shadows, σt + τ as the world makes them, the CPU on\n"
          "   bricks that end up empty, and the τ direct marches proven clear)\n"
          "\n"
          "tau options:\n"
          "  --scene FILE        scene (default: the built-in procedural planet)\n"
          "  --level LIST        octree levels of the nodes (default 13)\n"
          "  --block N           N³ nodes per level, aligned to volume groups (default 8)\n"
          "  --at LAT,LON        centre of the block (default: the scene camera)\n"
          "  --alt M             altitude of the block's centre in metres (default 2000)\n"
          "  --time T            world time in seconds (default 0)\n"
          "  --sun-zenith DEG    the sun this far from the zenith, toward the east, at the block\n"
          "                      (default: the scene's sun)\n"
          "  --repeat N          timed passes; the fastest counts (default 3)\n"
          "  --reference         also compare both methods with a converged march (8x the direct's cost)\n"
          "\n"
          "plan options:\n"
          "  --budget MIB        viewer budget (default 2048; 2048-byte slots, 32-byte records, 2 kept states)\n"
          "  --leaves N          target leaves: alone, sizes the budget for N brick leaves; with --budget,\n"
          "                      stops the build-up at N leaves\n"
          "  --repeat N          re-plans timed per case; the median counts (default 5)\n"
          "\n"
          "world options:\n"
          "  --scene FILE        scene (default: the built-in procedural planet)\n"
          "  --viewers N         viewers, spread around the camera's heading when orbiting (default 1)\n"
          "  --epochs N          epochs to step (default 20)\n"
          "  --budget MIB        each viewer's budget (default 64; 2048-byte slots, 32-byte records)\n"
          "  --threads N         producer threads (default: all cores)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   (default: the scene's camera)\n"
          "  --orbit DEG         heading change per epoch (default 0: a still camera)\n"
          "  --split-fraction X  planner split cap per epoch as a fraction of capacity (default 0.1)\n"
          "  --clocked S         clocked epochs: each tick shows only content that exists, then production\n"
          "                      runs S seconds (0: none); plan-ms includes the target plans (target-ms)\n"
          "\n"
          "wire options (the built-in procedural planet, one viewer at its camera; every decode is checked):\n"
          "  --epochs N          epochs to step (default 8)\n"
          "  --budget MIB        the viewer's budget (default 64; 2048-byte slots, 32-byte records)\n"
          "  --level N           zstd level of every variant, 1..19 (default 3)\n"
          "  --threads N         producer threads (default: all cores)\n"
          "  --csv FILE          also write one row per epoch and variant\n"
          "\n"
          "\n");
  oct_bench_sweep_usage(f);
  oct_bench_truth_usage(f);
  oct_bench_model_usage(f);
  oct_bench_stability_usage(f);
  oct_bench_features_usage(f);
  fprintf(f,
          "\n"
          "  --help, --version\n"
          "\n"
          "exit status: 0 ok, 1 runtime error, 2 usage error\n");
}

int oct_parse_list(const char *p, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n) {
  char buf[256];
  *n = 0;
  snprintf(buf, sizeof buf, "%s", text);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    if (*n == cap) {
      oc_cli_fail(p, 0, "%s: at most %d entries", opt, cap);
      return -1;
    }
    if (oc_cli_int(p, opt, tok, lo, hi, &out[(*n)++])) return -1;
  }
  if (*n == 0) {
    oc_cli_fail(p, 0, "%s: empty list", opt);
    return -1;
  }
  return 0;
}

double oct_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

int oct_parse_at(const char *p, const char *text, double at[2]) {
  if (sscanf(text, "%lf,%lf", &at[0], &at[1]) != 2 || !(at[0] >= -90 && at[0] <= 90 && at[1] >= -360 && at[1] <= 360)) {
    oc_cli_fail(p, 0, "--at: expected LAT,LON in degrees, got \"%s\"", text);
    return -1;
  }
  return 0;
}

int oct_load_scene(const char *p, const char *path, oc_scene_t *sc) {
  char why[1024];
  if (!path) {
    oc_scene_default(sc);
    return 0;
  }
  if (oc_scene_load(sc, path, why, sizeof why) < 0) {
    oc_cli_fail(p, 0, "%s", why);
    return -1;
  }
  return 0;
}

int oct_bench_wire(const char *prog, int argc, char **argv); /* bench_wire.c */

int main(int argc, char **argv) {
  if (argc < 2) return oc_cli_fail(prog, OC_EXIT_USAGE, "missing command (see --help for usage)");
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    oct_bench_usage(stdout);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    oc_cli_version(prog);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "render")) return oct_bench_render(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "field")) return oct_bench_field(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "tau")) return oct_bench_tau(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "plan")) return oct_bench_plan(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "world")) return oct_bench_world(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "wire")) return oct_bench_wire(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "sweep")) return oct_bench_sweep(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "truth")) return oct_bench_truth(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "model")) return oct_bench_model(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "stability")) return oct_bench_stability(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "features")) return oct_bench_features(prog, argc - 1, argv + 1);
  return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown command \"%s\" (see --help)", argv[1]);
}
