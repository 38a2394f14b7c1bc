/* overcast-view — the viewer. Today it renders with the CPU reference renderer, either a saved
 * state (--state) or a scene's analytic sources voxelized locally (--scene); the GL renderer and
 * the connection to overcast-server arrive with issues [4/7] and [5/7]. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "oc_atmo.h"
#include "oc_camera.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_log.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "oc_scene_voxelize.h"
#include "oc_state.h"

static const char *prog = "overcast-view";

static void usage(FILE *f) {
  fprintf(f,
          "usage: overcast-view [options]\n"
          "Renders clouds and atmosphere to PNG frames with the CPU reference renderer.\n"
          "\n"
          "source (one of):\n"
          "  --state FILE          render a saved state file (what a viewer held)\n"
          "  --scene FILE          voxelize the scene's analytic sources locally (default: scenes/analytic_sphere.json\n"
          "                        when no --state is given)\n"
          "view:\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   degrees, metres (default: the scene's camera)\n"
          "  --camera-from PNG     restore the camera stored in a screenshot's text chunk\n"
          "  --size WxH            image size (default 640x360)\n"
          "  --frames N            frames to write (default 1; with --jitter each frame has its own jitter)\n"
          "  --out DIR             output folder (default out), files frame_NNNN.png\n"
          "rendering:\n"
          "  --renderer cpu        the CPU reference renderer (the only one in this build)\n"
          "  --step-factor X       step = X × voxel spacing (default 0.5)\n"
          "  --exposure X          (default 10)\n"
          "  --ms-octaves N        multiple-scattering octaves 1..8 (default: the scene's)\n"
          "  --jitter              per-pixel ray-start jitter\n"
          "  --threads N           render threads (default 2)\n"
          "  --max-level N         deepest octree level for --scene (default 16)\n"
          "  --save-state FILE     also write the state that was rendered\n"
          "  -q, --quiet           only errors\n"
          "  --help, --version\n"
          "\n"
          "exit status: 0 ok, 1 runtime error, 2 usage error\n");
}

int main(int argc, char **argv) {
  enum { O_STATE = 256, O_SCENE, O_CAMERA, O_CAMERA_FROM, O_SIZE, O_FRAMES, O_OUT, O_RENDERER, O_STEP, O_EXPOSURE,
         O_OCTAVES, O_JITTER, O_THREADS, O_MAXLEVEL, O_SAVE, O_HELP, O_VERSION };
  static const struct option opts[] = {
      {"state", required_argument, 0, O_STATE},       {"scene", required_argument, 0, O_SCENE},
      {"camera", required_argument, 0, O_CAMERA},     {"camera-from", required_argument, 0, O_CAMERA_FROM},
      {"size", required_argument, 0, O_SIZE},         {"frames", required_argument, 0, O_FRAMES},
      {"out", required_argument, 0, O_OUT},           {"renderer", required_argument, 0, O_RENDERER},
      {"step-factor", required_argument, 0, O_STEP},  {"exposure", required_argument, 0, O_EXPOSURE},
      {"ms-octaves", required_argument, 0, O_OCTAVES}, {"jitter", no_argument, 0, O_JITTER},
      {"threads", required_argument, 0, O_THREADS},   {"max-level", required_argument, 0, O_MAXLEVEL},
      {"save-state", required_argument, 0, O_SAVE},   {"quiet", no_argument, 0, 'q'},
      {"help", no_argument, 0, O_HELP},               {"version", no_argument, 0, O_VERSION},
      {0, 0, 0, 0}};
  const char *state_path = NULL, *scene_path = NULL, *camera_text = NULL, *camera_png = NULL, *out_dir = "out";
  const char *save_path = NULL;
  int w = 640, h = 360, jitter = 0;
  long frames = 1, threads = 2, max_level = 16, octaves = 0;
  double step = 0.5, exposure = 10.0;
  int c;
  opterr = 0;
  while ((c = getopt_long(argc, argv, "q", opts, NULL)) != -1) {
    switch (c) {
      case O_STATE: state_path = optarg; break;
      case O_SCENE: scene_path = optarg; break;
      case O_CAMERA: camera_text = optarg; break;
      case O_CAMERA_FROM: camera_png = optarg; break;
      case O_SIZE: if (oc_cli_size(prog, "--size", optarg, &w, &h)) return OC_EXIT_USAGE; break;
      case O_FRAMES: if (oc_cli_int(prog, "--frames", optarg, 1, 100000, &frames)) return OC_EXIT_USAGE; break;
      case O_OUT: out_dir = optarg; break;
      case O_RENDERER:
        if (strcmp(optarg, "cpu") != 0)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--renderer %s: only \"cpu\" is available in this build", optarg);
        break;
      case O_STEP: if (oc_cli_double(prog, "--step-factor", optarg, 1e-3, 1e3, &step)) return OC_EXIT_USAGE; break;
      case O_EXPOSURE: if (oc_cli_double(prog, "--exposure", optarg, 1e-6, 1e6, &exposure)) return OC_EXIT_USAGE; break;
      case O_OCTAVES: if (oc_cli_int(prog, "--ms-octaves", optarg, 1, 8, &octaves)) return OC_EXIT_USAGE; break;
      case O_JITTER: jitter = 1; break;
      case O_THREADS: if (oc_cli_int(prog, "--threads", optarg, 1, 256, &threads)) return OC_EXIT_USAGE; break;
      case O_MAXLEVEL: if (oc_cli_int(prog, "--max-level", optarg, 0, 21, &max_level)) return OC_EXIT_USAGE; break;
      case O_SAVE: save_path = optarg; break;
      case 'q': oc_log_set_level(OC_LOG_ERROR); break;
      case O_HELP: usage(stdout); return OC_EXIT_OK;
      case O_VERSION: oc_cli_version(prog); return OC_EXIT_OK;
      default:
        return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown or incomplete option \"%s\" (see --help)", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "unexpected argument \"%s\" (see --help)", argv[optind]);
  if (state_path && scene_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--state and --scene exclude each other");
  if (camera_text && camera_png) return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera and --camera-from exclude each other");

  char why[512];
  int rc = OC_EXIT_OK;
  oc_state_t st;
  oc_state_init(&st);
  oc_atmo_t *atmo = NULL;
  uint8_t *rgb = NULL;
  oc_image_t img = {0};
  oc_scene_t *sc = calloc(1, sizeof *sc);
  if (!sc) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  if (!state_path) {
    if (!scene_path) scene_path = "scenes/analytic_sphere.json";
    if (oc_scene_load(sc, scene_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else {
    oc_scene_default(sc);
  }

  oc_camera_pose_t pose = {sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  if (camera_text && oc_camera_parse(camera_text, &pose, why, sizeof why) < 0)
    {
      rc = oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
      goto out;
    }
  if (camera_png) {
    int pw, ph;
    uint8_t *px;
    char text[256];
    if (oc_png_read(camera_png, &pw, &ph, &px, "overcast-camera", text, sizeof text, why, sizeof why) < 0)
      {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from: %s", why);
      goto out;
    }
    free(px);
    if (!text[0]) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from %s: no overcast-camera text chunk", camera_png);
      goto out;
    }
    if (oc_camera_parse(text, &pose, why, sizeof why) < 0)
      {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from %s: %s", camera_png, why);
      goto out;
    }
  }
  oc_camera_t cam = oc_camera_from_pose(pose);

  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if (state_path) {
    if (oc_state_load(&st, state_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else {
    oc_scene_voxelize_desc_t vd = {cam, h, 2.0, (int)max_level, 0, (int)threads};
    if (oc_scene_voxelize(&st, sc, &vd, why, sizeof why) < 0)
      {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", scene_path, why);
      goto out;
    }
  }
  clock_gettime(CLOCK_MONOTONIC, &t1);
  oc_log_info("state: %u nodes, %u bricks (%.2f s)", st.node_count, st.brick_count,
              (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec));
  if (save_path && oc_state_save(&st, save_path, why, sizeof why) < 0)
    {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }

  int use_atmo = oc_scene_has(sc, OC_FEATURE_ATMOSPHERE);
  if (use_atmo) {
    ocg_atmosphere ap;
    oc_atmo_params_default(&ap);
    if (!oc_scene_has(sc, OC_FEATURE_OZONE)) ap.ozone_absorption = ocg_v3s(0.0f);
    atmo = oc_atmo_create(&ap, (int)threads);
    if (!atmo) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
      goto out;
    }
  }

  if (mkdir(out_dir, 0777) != 0 && errno != EEXIST)
    {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: cannot create folder: %s", out_dir, strerror(errno));
      goto out;
    }

  oc_render_desc_t d = {0};
  d.width = w;
  d.height = h;
  d.camera = cam;
  d.step_factor = step;
  d.ms_octaves = octaves ? (int)octaves : oc_scene_has(sc, OC_FEATURE_MULTIPLE_SCATTERING) ? sc->optics.ms_octaves : 1;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)sc->optics.albedo;
  d.albedo_zero = sc->optics.albedo == 0.0;
  d.atmo = atmo;
  d.threads = (int)threads;
  d.flags = (use_atmo ? 0 : OC_RF_NO_ATMOSPHERE) | (oc_scene_has(sc, OC_FEATURE_PLANET_SURFACE) ? 0 : OC_RF_NO_PLANET) |
            (jitter ? OC_RF_JITTER : 0);
  rgb = malloc((size_t)w * (size_t)h * 3);
  if (!rgb || oc_image_alloc(&img, w, h) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory for a %dx%d image", w, h);
      goto out;
    }

  char cam_text[256], settings[256];
  oc_camera_format(pose, cam_text, sizeof cam_text);
  snprintf(settings, sizeof settings, "renderer=cpu step_factor=%g exposure=%g ms_octaves=%d jitter=%d", step, exposure,
           d.ms_octaves, jitter);
  oc_png_text_t text[3] = {{"overcast-camera", cam_text}, {"overcast-settings", settings},
                           {"Software", "overcast-view " OC_VERSION}};
  for (long f = 0; f < frames; f++) {
    oc_render_stats_t rs;
    d.frame = (uint32_t)f;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int r = oc_render_state(&st, &d, &img, &rs);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (r < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed: %s", oc_strerror(r));
      break;
    }
    int bad = oc_image_tonemap(&img, (float)exposure, rgb);
    if (bad) oc_log_warn("frame %ld: %d non-finite pixels drawn black", f, bad);
    char path[4096];
    snprintf(path, sizeof path, "%s/frame_%04ld.png", out_dir, f);
    if (oc_png_write(path, w, h, rgb, text, 3, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      break;
    }
    double sec = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    oc_log_info("frame %ld: %.2f s, %.1f M samples/s", f, sec, rs.samples / sec * 1e-6);
    printf("%s\n", path);
    fflush(stdout);
  }
out:
  free(rgb);
  oc_image_free(&img);
  oc_atmo_free(atmo);
  oc_state_free(&st);
  oc_scene_free(sc);
  free(sc);
  return rc;
}
