/* overcast-bench — benchmarks. Figures go into docs/performance.md with the command that made them.
 *
 *   render   CPU reference renderer throughput (samples/s) per thread count, side by side in one
 *            run, and a check that every thread count produced the same image. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "oc_atmo.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_log.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "oc_scene_voxelize.h"

static const char *prog = "overcast-bench";

static void usage(FILE *f) {
  fprintf(f,
          "usage: overcast-bench COMMAND [options]\n"
          "\n"
          "commands:\n"
          "  render     CPU reference renderer throughput per thread count\n"
          "\n"
          "render options:\n"
          "  --scene FILE        analytic scene (default scenes/analytic_sphere.json)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   (default: the scene's camera)\n"
          "  --size WxH          image size (default 320x180)\n"
          "  --threads LIST      comma-separated thread counts (default 1,2)\n"
          "  --repeat N          renders per thread count; the fastest counts (default 3)\n"
          "  --step-factor X     (default 0.5)\n"
          "  --help, --version\n"
          "\n"
          "exit status: 0 ok, 1 runtime error, 2 usage error\n");
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmd_render(int argc, char **argv) {
  enum { O_SCENE = 256, O_CAMERA, O_SIZE, O_THREADS, O_REPEAT, O_STEP, O_HELP };
  static const struct option opts[] = {{"scene", required_argument, 0, O_SCENE},   {"camera", required_argument, 0, O_CAMERA},
                                       {"size", required_argument, 0, O_SIZE},     {"threads", required_argument, 0, O_THREADS},
                                       {"repeat", required_argument, 0, O_REPEAT}, {"step-factor", required_argument, 0, O_STEP},
                                       {"help", no_argument, 0, O_HELP},           {0, 0, 0, 0}};
  const char *scene_path = "scenes/analytic_sphere.json", *camera_text = NULL, *threads_text = "1,2";
  int w = 320, h = 180;
  long repeat = 3;
  double step = 0.5;
  int c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_CAMERA: camera_text = optarg; break;
      case O_SIZE: if (oc_cli_size(prog, "--size", optarg, &w, &h)) return OC_EXIT_USAGE; break;
      case O_THREADS: threads_text = optarg; break;
      case O_REPEAT: if (oc_cli_int(prog, "--repeat", optarg, 1, 1000, &repeat)) return OC_EXIT_USAGE; break;
      case O_STEP: if (oc_cli_double(prog, "--step-factor", optarg, 1e-3, 1e3, &step)) return OC_EXIT_USAGE; break;
      case O_HELP: usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "render: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "render: unexpected argument \"%s\"", argv[optind]);
  long threads[32];
  int nthreads = 0;
  char buf[256];
  snprintf(buf, sizeof buf, "%s", threads_text);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    if (nthreads == 32) return oc_cli_fail(prog, OC_EXIT_USAGE, "--threads: at most 32 entries");
    if (oc_cli_int(prog, "--threads", tok, 1, 256, &threads[nthreads++])) return OC_EXIT_USAGE;
  }
  if (nthreads == 0) return oc_cli_fail(prog, OC_EXIT_USAGE, "--threads: empty list");

  char why[512];
  static oc_scene_t sc;
  if (oc_scene_load(&sc, scene_path, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  oc_camera_pose_t pose = {sc.camera.pos, sc.camera.heading, sc.camera.pitch, sc.camera.fov};
  if (camera_text && oc_camera_parse(camera_text, &pose, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
  oc_camera_t cam = oc_camera_from_pose(pose);
  oc_state_t st;
  oc_state_init(&st);
  oc_scene_voxelize_desc_t vd = {cam, h, 2.0, 16, 0, 2};
  if (oc_scene_voxelize(&st, &sc, &vd, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", scene_path, why);
  ocg_atmosphere ap;
  oc_atmo_params_default(&ap);
  double ta = now();
  oc_atmo_t *atmo = oc_atmo_create(&ap, 2);
  ta = now() - ta;
  if (!atmo) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");

  printf("# CPU reference renderer: %s, %dx%d, step factor %g, state %u nodes / %u bricks, atmosphere tables %.3f s\n\n",
         scene_path, w, h, step, st.node_count, st.brick_count, ta);
  printf("| threads | best of %ld (s) | samples | M samples/s | M rays/s | speed-up | image |\n", repeat);
  printf("|---:|---:|---:|---:|---:|---:|---|\n");
  oc_image_t ref = {0}, img = {0};
  double base = 0.0;
  int rc = OC_EXIT_OK;
  for (int i = 0; i < nthreads; i++) {
    oc_render_desc_t d = {0};
    d.width = w;
    d.height = h;
    d.camera = cam;
    d.step_factor = step;
    d.atmo = atmo;
    d.threads = (int)threads[i];
    if (oc_image_alloc(&img, w, h) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    double best = 1e30;
    oc_render_stats_t rs = {0};
    for (long r = 0; r < repeat; r++) {
      fprintf(stderr, "\r%s: render: %ld threads, run %ld/%ld ", prog, threads[i], r + 1, repeat);
      double t0 = now();
      if (oc_render_state(&st, &d, &img, &rs) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed");
      double t = now() - t0;
      if (t < best) best = t;
    }
    fprintf(stderr, "\r\033[K");
    if (i == 0) base = best;
    const char *same = "reference";
    if (i == 0) {
      ref = img;
      img.px = NULL;
    } else {
      same = memcmp(ref.px, img.px, sizeof(float) * 4 * (size_t)w * (size_t)h) == 0 ? "identical" : "DIFFERS";
      if (same[0] == 'D') rc = OC_EXIT_RUNTIME;
      oc_image_free(&img);
    }
    printf("| %ld | %.3f | %llu | %.2f | %.3f | %.2f | %s |\n", threads[i], best, (unsigned long long)rs.samples,
           rs.samples / best * 1e-6, (double)w * h / best * 1e-6, base / best, same);
  }
  oc_image_free(&ref);
  oc_atmo_free(atmo);
  oc_state_free(&st);
  oc_scene_free(&sc);
  if (rc) fprintf(stderr, "%s: images differ between thread counts\n", prog);
  return rc;
}

int main(int argc, char **argv) {
  if (argc < 2) return oc_cli_fail(prog, OC_EXIT_USAGE, "missing command (see --help for usage)");
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    usage(stdout);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    oc_cli_version(prog);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "render")) return cmd_render(argc - 1, argv + 1);
  return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown command \"%s\" (see --help)", argv[1]);
}
