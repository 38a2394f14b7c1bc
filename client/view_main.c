/* overcast-view — the viewer. Today it renders with the CPU reference renderer a saved state
 * (--state), a scene's analytic sources voxelized locally (--scene), or the newest of the states
 * received from overcast-server (--connect; client/net.h). The GL renderer arrives with issue [5/7]. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
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
#include "net.h"
#include "ocp_viewer.h"

static const char *prog = "overcast-view";

static void usage(FILE *f) {
  fprintf(f,
          "usage: overcast-view [options]\n"
          "Renders clouds and atmosphere to PNG frames with the CPU reference renderer.\n"
          "\n"
          "source (one of):\n"
          "  --state FILE          render a saved state file (what a viewer held)\n"
          "  --scene FILE          voxelize the scene's analytic sources locally (default: scenes/analytic_sphere.json\n"
          "                        when no --state or --connect is given)\n"
          "  --connect HOST:PORT   receive states from overcast-server and render the newest; the scene's\n"
          "                        features, optics and default camera come from the server\n"
          "network (with --connect):\n"
          "  --token TEXT          the server's token, if it has one\n"
          "  --budget MIB          memory budget asked for (default 64)\n"
          "  --max-depth N         deepest octree level asked for, 0..21 (default 21)\n"
          "  --epochs N            render once N states have arrived (default 4)\n"
          "  --step                for a server run with --epoch-period 0: ask it (on a second, control\n"
          "                        connection) to step one epoch whenever the previous state arrived\n"
          "  --timeout S           give up when the states have not arrived within S s (default 60)\n"
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

/*-*** --connect: receive states from a server ***/

typedef struct {
  int connect, step;
  char host[OCV_HOST_MAX];
  int port;
  const char *token;
  long budget_mib, max_depth, epochs;
  double timeout;
  int width, height;
} view_net_opts_t;

typedef struct {
  uint64_t states;
  double last_input; /* when the viewer connection last brought bytes (for the step retry) */
  uint32_t reply_for, reply_status; /* the control connection's last reply */
  int reply_ok;
  char reply_error[256];
} view_net_t;

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint64_t bytes_in(ocv_conn_t *c) {
  ocp_viewer_stats_t s;
  ocp_viewer_stats(ocv_conn_session(c), &s);
  return s.bytes_in;
}

static void on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  (void)ctx;
  oc_log_info("welcome: scene %s, session %u%s, %s, budget %.1f MiB granted, depth %u", w->name, w->session,
              resumed ? " (resumed)" : "", w->epoch_period > 0 ? "animated by the clock" : "stepped by command",
              (double)w->budget / (1 << 20), w->max_depth);
}

static void on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  view_net_t *n = ctx;
  n->states++;
  oc_log_info("epoch %llu: %u nodes, %u bricks (%u received)", (unsigned long long)s->epoch, s->node_count,
              s->brick_count, bricks);
}

static void on_reply(void *ctx, const ocp_control_t *c) {
  view_net_t *n = ctx;
  n->reply_for = c->request;
  n->reply_status = (uint32_t)c->status;
  n->reply_ok = c->status == OCP_CODE_OK;
  /* the reply is a JSON object; on refusal its "error" is what matters, shown verbatim */
  snprintf(n->reply_error, sizeof n->reply_error, "%.*s", (int)c->json_len, c->json);
}

/* Connects, sends the camera, (with --step) steps the server, and waits for `epochs` states; then
 * copies the newest into st and overrides the scene's features, optics and name from the WELCOME.
 * `pose_in` NULL: the WELCOME's default camera, returned in *pose_out. */
static int net_receive(const view_net_opts_t *o, const oc_camera_pose_t *pose_in, oc_camera_pose_t *pose_out,
                       oc_scene_t *sc, oc_state_t *st, char *why, size_t why_len) {
  view_net_t n = {0};
  ocv_conn_t *vc = NULL, *cc = NULL;
  double deadline = now_s() + o->timeout;
  ocp_viewer_desc_t vd = {.role = OCP_ROLE_VIEWER, .budget = (uint64_t)o->budget_mib << 20,
                          .max_depth = (uint8_t)o->max_depth, .width = (uint32_t)o->width,
                          .height = (uint32_t)o->height, .caps = OCP_CAP_ALL, .token = o->token};
  ocp_viewer_events_t ev = {.ctx = &n, .welcome = on_welcome, .state = on_state};
  int r = ocv_conn_open(&vc, o->host, o->port, &vd, &ev, o->timeout, why, why_len);
  if (r < 0) return r;
  const char *addr = ocv_conn_address(vc);
  r = ocv_conn_wait_ready(vc, deadline - now_s(), why, why_len);
  if (r) goto done;
  const ocp_welcome_t *w = ocp_viewer_welcome(ocv_conn_session(vc));
  if (pose_in) {
    *pose_out = *pose_in;
  } else {
    *pose_out = (oc_camera_pose_t){{w->cam_lat, w->cam_lon, w->cam_alt}, w->cam_heading, w->cam_pitch, w->cam_fov};
  }
  oc_camera_t cam = oc_camera_from_pose(*pose_out);
  ocp_camera_t oc = {cam.pos, cam.forward, cam.up, pose_out->fov, (uint32_t)o->width, (uint32_t)o->height};
  if ((r = ocv_conn_camera(vc, &oc)) < 0) {
    snprintf(why, why_len, "%s: the camera was refused (%s)", addr, oc_strerror(r));
    goto done;
  }
  /* the camera goes out before the first step is asked for, so that epoch is planned for it */
  if ((r = ocv_conn_flush(vc, deadline - now_s(), why, why_len))) goto done;
  if (o->step) {
    ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = o->token};
    ocp_viewer_events_t cev = {.ctx = &n, .control_reply = on_reply};
    if ((r = ocv_conn_open(&cc, o->host, o->port, &cd, &cev, deadline - now_s(), why, why_len)) < 0) goto done;
    if ((r = ocv_conn_wait_ready(cc, deadline - now_s(), why, why_len))) goto done;
  }

  /* Stepping: one step at a time, the next once the previous one's state arrived. A step that
   * reached the server before our ACK of the previous state skips this viewer (it had a state in
   * flight), so a step whose reply came but whose state did not is asked again after a quiet second. */
  uint32_t request = 0;
  int awaiting_reply = 0;
  uint64_t states_at_step = 0;
  double replied_at = 0;
  n.last_input = now_s();
  while (n.states < (uint64_t)o->epochs) {
    double t = now_s();
    if (t >= deadline) {
      if (n.states == 0)
        snprintf(why, why_len, "%s: no state within %g s%s", addr, o->timeout,
                 !o->step && w->epoch_period == 0 ? " (the server steps by command: add --step)" : "");
      else
        snprintf(why, why_len, "%s: %llu of %ld states within %g s", addr, (unsigned long long)n.states, o->epochs,
                 o->timeout);
      r = OC_EIO;
      goto done;
    }
    if (cc) {
      if (awaiting_reply && n.reply_for == request) {
        awaiting_reply = 0;
        replied_at = t;
        if (!n.reply_ok) {
          snprintf(why, why_len, "%s: step refused (%s): %s", addr, ocp_code_text(n.reply_status), n.reply_error);
          r = OC_EIO;
          goto done;
        }
      }
      int again = !awaiting_reply && n.states == states_at_step && request && t - replied_at > 1.0 && t - n.last_input > 1.0;
      if (!awaiting_reply && (request == 0 || n.states > states_at_step || again)) {
        if (again) oc_log_info("step %u brought no state yet: stepping again", request);
        states_at_step = n.states;
        if ((r = ocv_conn_control(cc, ++request, "{\"op\":\"step\",\"epochs\":1}")) < 0) {
          snprintf(why, why_len, "%s: cannot send the step request (%s)", addr, oc_strerror(r));
          goto done;
        }
        awaiting_reply = 1;
      }
    }
    /* a step can outlast the server's idle timeout: say we are still here */
    if (ocv_conn_silence(vc) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(vc);
    if (cc && ocv_conn_silence(cc) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(cc);
    uint64_t before = bytes_in(vc);
    r = ocv_conn_poll(vc, fmin(deadline - t, cc ? 0.05 : 0.5), why, why_len);
    if (bytes_in(vc) != before) n.last_input = now_s();
    if (r) break;
    if (cc && (r = ocv_conn_poll(cc, 0, why, why_len))) break;
  }
  if (r == 1) { /* closed by the server before enough states: why holds its reason */
    r = OC_EIO;
    goto done;
  }
  if (r < 0) goto done;
  r = oc_state_copy(st, ocp_viewer_state(ocv_conn_session(vc), 0));
  if (r < 0) {
    snprintf(why, why_len, "out of memory for a copy of the state");
    goto done;
  }
  sc->features = w->features;
  sc->sun_dir = w->sun_dir;
  sc->optics.albedo = w->albedo;
  sc->optics.ms_a = w->ms_a;
  sc->optics.ms_b = w->ms_b;
  sc->optics.ms_c = w->ms_c;
  sc->optics.ms_octaves = w->ms_octaves < 1 ? 1 : w->ms_octaves > 8 ? 8 : (int)w->ms_octaves;
  snprintf(sc->name, sizeof sc->name, "%s", w->name);
done:
  if (r == 1) r = OC_EIO; /* closed by the server: why holds its reason */
  ocv_conn_close(cc);
  ocv_conn_close(vc);
  return r;
}

int main(int argc, char **argv) {
  enum { O_STATE = 256, O_SCENE, O_CAMERA, O_CAMERA_FROM, O_SIZE, O_FRAMES, O_OUT, O_RENDERER, O_STEP, O_EXPOSURE,
         O_OCTAVES, O_JITTER, O_THREADS, O_MAXLEVEL, O_SAVE, O_HELP, O_VERSION, O_CONNECT, O_TOKEN, O_BUDGET,
         O_MAXDEPTH, O_EPOCHS, O_NETSTEP, O_TIMEOUT };
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
      {"connect", required_argument, 0, O_CONNECT},   {"token", required_argument, 0, O_TOKEN},
      {"budget", required_argument, 0, O_BUDGET},     {"max-depth", required_argument, 0, O_MAXDEPTH},
      {"epochs", required_argument, 0, O_EPOCHS},     {"step", no_argument, 0, O_NETSTEP},
      {"timeout", required_argument, 0, O_TIMEOUT},
      {0, 0, 0, 0}};
  const char *state_path = NULL, *scene_path = NULL, *camera_text = NULL, *camera_png = NULL, *out_dir = "out";
  const char *save_path = NULL;
  int w = 640, h = 360, jitter = 0;
  long frames = 1, threads = 2, max_level = 16, octaves = 0;
  double step = 0.5, exposure = 10.0;
  view_net_opts_t net = {.budget_mib = 64, .max_depth = 21, .epochs = 4, .timeout = 60.0};
  int net_opts = 0;
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
      case O_CONNECT:
        if (ocv_parse_address(optarg, net.host, sizeof net.host, &net.port) < 0)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect: expected HOST:PORT (port 1..65535), got \"%s\"", optarg);
        net.connect = 1;
        break;
      case O_TOKEN:
        if (!*optarg || strlen(optarg) > OCP_TOKEN_MAX)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--token: 1..%d bytes", OCP_TOKEN_MAX);
        net.token = optarg;
        net_opts = 1;
        break;
      case O_BUDGET: if (oc_cli_int(prog, "--budget", optarg, 1, 1 << 20, &net.budget_mib)) return OC_EXIT_USAGE; net_opts = 1; break;
      case O_MAXDEPTH: if (oc_cli_int(prog, "--max-depth", optarg, 0, 21, &net.max_depth)) return OC_EXIT_USAGE; net_opts = 1; break;
      case O_EPOCHS: if (oc_cli_int(prog, "--epochs", optarg, 1, 100000, &net.epochs)) return OC_EXIT_USAGE; net_opts = 1; break;
      case O_NETSTEP: net.step = 1; net_opts = 1; break;
      case O_TIMEOUT: if (oc_cli_double(prog, "--timeout", optarg, 0.01, 86400, &net.timeout)) return OC_EXIT_USAGE; net_opts = 1; break;
      case 'q': oc_log_set_level(OC_LOG_ERROR); break;
      case O_HELP: usage(stdout); return OC_EXIT_OK;
      case O_VERSION: oc_cli_version(prog); return OC_EXIT_OK;
      default:
        return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown or incomplete option \"%s\" (see --help)", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "unexpected argument \"%s\" (see --help)", argv[optind]);
  if (state_path && scene_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--state and --scene exclude each other");
  if (net.connect && (state_path || scene_path))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect excludes --state and --scene");
  if (net_opts && !net.connect)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--token, --budget, --max-depth, --epochs, --step and --timeout go with --connect");
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
  if (!state_path && !net.connect) {
    if (!scene_path) scene_path = "scenes/analytic_sphere.json";
    if (oc_scene_load(sc, scene_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else {
    oc_scene_default(sc);
  }

  oc_camera_pose_t pose = {sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  int have_pose = camera_text || camera_png;
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

  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if (net.connect) {
    net.width = w;
    net.height = h;
    if (net_receive(&net, have_pose ? &pose : NULL, &pose, sc, &st, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  }
  oc_camera_t cam = oc_camera_from_pose(pose);
  if (state_path) {
    if (oc_state_load(&st, state_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else if (!net.connect) {
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
