/* overcast-view — the viewer. Sources: a saved state (--state), the state of a scene planned by the
 * overcast-server next to this program, started on 127.0.0.1:0 for it and stopped again (--scene;
 * client/child.h), or the states received from an overcast-server (--connect; client/net.h). The
 * viewer generates no content.
 * Renderers: the GL compute renderer (client/gl, ocv_gl_render_state) or the CPU reference
 * (oc_render_state); both produce the same linear image, tone-mapped by the same code.
 * Modes: --headless writes PNG frames (EGL, no display needed); --window opens a GLFW window
 * (client/gl/gl_window.c) that renders continuously, with mouse look and WASD flight. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <pthread.h>

#include "camera_path.h"
#include "child.h"
#include "hud.h"
#include "oc_atmo.h"
#include "oc_camera.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_log.h"
#include "oc_planet.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "oc_scene_render.h"
#include "oc_state.h"
#include "net.h"
#include "ocp_viewer.h"
#ifdef OC_HAVE_GL
#include "gl_window.h"
#include "ocv_gl.h"
#endif

static const char *prog = "overcast-view";

/*-*** --connect: receive states from a server ***/

/* What a WELCOME says about the scene: its features, sun, optics and name. */
static void scene_from_welcome(oc_scene_t *sc, const ocp_welcome_t *w) {
  sc->features = w->features;
  sc->sun_dir = w->sun_dir;
  sc->optics.albedo = w->albedo;
  sc->optics.ms_a = w->ms_a;
  sc->optics.ms_b = w->ms_b;
  sc->optics.ms_c = w->ms_c;
  sc->optics.ms_octaves = w->ms_octaves < 1 ? 1 : w->ms_octaves > 8 ? 8 : (int)w->ms_octaves;
  snprintf(sc->name, sizeof sc->name, "%s", w->name);
}


typedef struct {
  int connect, step;
  char host[OCV_HOST_MAX];
  int port;
  const char *token;
  long budget_mib, max_depth, epochs;
  double timeout;
  int width, height;
} view_net_opts_t;

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The newest of `epochs` states (ocv_fetch), with the scene's features, optics and name from the
 * WELCOME. `pose_in` NULL: the WELCOME's default camera, returned in *pose_out. */
static int net_receive(const view_net_opts_t *o, const oc_camera_pose_t *pose_in, oc_camera_pose_t *pose_out,
                       oc_scene_t *sc, oc_state_t *st, char *why, size_t why_len) {
  ocv_fetch_desc_t fd = {.host = o->host, .port = o->port, .token = o->token, .budget = (uint64_t)o->budget_mib << 20,
                         .max_depth = (int)o->max_depth, .width = o->width, .height = o->height, .step = o->step,
                         .epochs = (uint64_t)o->epochs, .timeout_s = o->timeout, .pose = pose_in};
  ocp_welcome_t w;
  int r = ocv_fetch(&fd, st, &w, pose_out, why, why_len);
  if (r == 0) scene_from_welcome(sc, &w);
  return r;
}

/* --scene: the state that the overcast-server next to this program, serving the scene on
 * 127.0.0.1:0 with stepped epochs, plans for `pose` (the newest of net->epochs, as --connect --step
 * takes it); the server is stopped again. */
static int scene_state(const char *scene, long threads, view_net_opts_t *net, const oc_camera_pose_t *pose,
                       oc_scene_t *sc, oc_state_t *st, char *why, size_t why_len) {
  char dir[4000], exe[4096], thr[24];
  if (ocv_exe_dir(dir, sizeof dir) < 0) return oc_errorf(OC_EIO, why, why_len, "cannot read /proc/self/exe");
  snprintf(exe, sizeof exe, "%s/overcast-server", dir);
  snprintf(thr, sizeof thr, "%ld", threads < 64 ? threads : 64);
  char *argv[] = {exe, "--scene", (char *)scene, "--listen", "127.0.0.1:0", "--threads", thr, "--epoch-period", "0",
                  "-q", NULL};
  ocv_child_t child;
  int r = ocv_child_spawn(argv, net->timeout, &child, why, why_len);
  if (r < 0) return r;
  view_net_opts_t o = *net;
  o.step = 1;
  snprintf(o.host, sizeof o.host, "%s", child.host);
  o.port = child.port;
  oc_camera_pose_t unused;
  r = net_receive(&o, pose, &unused, sc, st, why, why_len);
  ocv_child_stop(&child, 5.0);
  return r;
}

/*-*** What every renderer and mode shares ***/

typedef enum { R_AUTO, R_CPU, R_GL } renderer_t;

typedef struct {
  const char *out_dir;
  double step, exposure;
  long octaves, threads;
  int jitter;
  const ocv_path_t *path; /* --path: the camera of frame f is its pose at f / fps */
  double fps;
  int hud;                 /* --hud: the HUD drawn into headless frames too */
  double frame_ms;         /* --frame-ms: the window's frame-time target (0: off, full resolution) */
} view_opts_t;

/* The render description for the scene's optics and features; the caller sets size and camera. */
static oc_render_desc_t make_desc(const oc_scene_t *sc, const view_opts_t *o, const oc_atmo_t *atmo) {
  oc_render_desc_t d = oc_scene_render_desc(sc, atmo);
  d.step_factor = o->step;
  if (o->octaves) d.ms_octaves = (int)o->octaves;
  d.threads = (int)o->threads;
  if (o->jitter) d.flags |= OC_RF_JITTER;
  return d;
}

/* The atmosphere tables when the scene has an atmosphere (*out stays NULL otherwise). */
static int make_atmo(const oc_scene_t *sc, long threads, oc_atmo_t **out) {
  return oc_scene_atmo(sc, (int)threads, out) < 0 ? -1 : 0;
}

/* A PNG with the camera and the settings in text chunks (what --camera-from reads back). */
static int write_frame(const char *path, int w, int h, const uint8_t *rgb, oc_camera_pose_t pose, const char *renderer,
                       const view_opts_t *o, int ms_octaves, char *why, size_t why_len) {
  char cam_text[256], settings[256];
  oc_camera_format(pose, cam_text, sizeof cam_text);
  snprintf(settings, sizeof settings, "renderer=%s step_factor=%g exposure=%g ms_octaves=%d jitter=%d", renderer,
           o->step, o->exposure, ms_octaves, o->jitter);
  oc_png_text_t text[3] = {{"overcast-camera", cam_text}, {"overcast-settings", settings},
                           {"Software", "overcast-view " OC_VERSION}};
  return oc_png_write(path, w, h, rgb, text, 3, why, why_len);
}

static int make_dir(const char *dir, char *why, size_t why_len) {
  if (mkdir(dir, 0777) != 0 && errno != EEXIST)
    return oc_errorf(OC_EIO, why, why_len, "%s: cannot create folder: %s", dir, strerror(errno));
  return 0;
}

static int have_display(void) {
  const char *x = getenv("DISPLAY"), *wl = getenv("WAYLAND_DISPLAY");
  return (x && *x) || (wl && *wl);
}

#ifdef OC_HAVE_GL
/*-*** Headless GL: an EGL context, the renderer and the GPU copy of the state ***/

typedef struct {
  ocv_gl_context_t *ctx;
  ocv_gl_renderer_t *r;
  ocv_gl_state_t gs;
  int have_gs;
} view_gl_t;

static void view_gl_free(view_gl_t *g) {
  if (g->have_gs) ocv_gl_state_free(&g->gs);
  ocv_gl_renderer_free(g->r);
  ocv_gl_context_free(g->ctx);
  memset(g, 0, sizeof *g);
}

static int view_gl_open(view_gl_t *g, const oc_state_t *st, char *why, size_t why_len) {
  memset(g, 0, sizeof *g);
  char w2[1024];
  if (!(g->ctx = ocv_gl_context_init(w2, sizeof w2)))
    return oc_errorf(OC_EIO, why, why_len, "no GL context: %s", w2);
  if (!(g->r = ocv_gl_renderer_create(w2, sizeof w2))) {
    view_gl_free(g);
    return oc_errorf(OC_EIO, why, why_len, "GL renderer: %s", w2);
  }
  int r = ocv_gl_state_upload(&g->gs, st, w2, sizeof w2);
  if (r < 0) {
    view_gl_free(g);
    return oc_errorf(r, why, why_len, "GL state upload: %s", w2);
  }
  g->have_gs = 1;
  return 0;
}
#endif

/*-*** Headless: --frames PNGs ***/

static int run_headless(renderer_t renderer, const oc_state_t *st, const oc_scene_t *sc, const oc_atmo_t *atmo,
                        oc_camera_pose_t pose, int w, int h, long frames, const view_opts_t *o) {
  char why[1024];
  int rc = OC_EXIT_OK;
  int use_gl = 0;
#ifdef OC_HAVE_GL
  view_gl_t g = {0};
  if (renderer != R_CPU) {
    if (view_gl_open(&g, st, why, sizeof why) == 0) {
      use_gl = 1;
      char info[512];
      ocv_gl_context_describe(g.ctx, info, sizeof info);
      oc_log_info("GL: %s", info);
    } else if (renderer == R_GL) {
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s", why);
    } else {
      oc_log_warn("%s: rendering with the CPU reference renderer (--renderer cpu)", why);
    }
  }
#else
  if (renderer == R_GL)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: this build has no GL renderer (libepoxy was not found)");
#endif
  if (make_dir(o->out_dir, why, sizeof why) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    goto out_gl;
  }
  uint8_t *rgb = malloc((size_t)w * (size_t)h * 3);
  oc_image_t img = {0};
  if (!rgb || oc_image_alloc(&img, w, h) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory for a %dx%d image", w, h);
    goto out;
  }
  oc_render_desc_t d = make_desc(sc, o, atmo);
  d.width = w;
  d.height = h;
  d.camera = oc_camera_from_pose(pose);
  for (long f = 0; f < frames; f++) {
    oc_render_stats_t rs = {0};
    struct timespec t0, t1;
    d.frame = (uint32_t)f;
    if (o->path) { /* --path: this frame's camera */
      (void)ocv_path_sample(o->path, (double)f / o->fps, &pose);
      d.camera = oc_camera_from_pose(pose);
    }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int r;
#ifdef OC_HAVE_GL
    if (use_gl) r = ocv_gl_render_state(g.r, &g.gs, &d, &img, why, sizeof why);
    else
#endif
    {
      r = oc_render_state(st, &d, &img, &rs);
      if (r < 0) snprintf(why, sizeof why, "%s", oc_strerror(r));
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (r < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed: %s", why);
      break;
    }
    int bad = oc_image_tonemap(&img, (float)o->exposure, rgb);
    if (bad) oc_log_warn("frame %ld: %d non-finite pixels drawn black", f, bad);
    if (o->hud) {
      double sec = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
      ocv_hud_stats_t hs = {.frame_ms = 1e3 * sec, .trace_ms = -1, .epoch = st->epoch, .bricks = st->brick_count,
                            .resident_bytes = (uint64_t)st->brick_count * 2048 + (uint64_t)st->node_count * 32,
                            .budget_bytes = (uint64_t)st->brick_count * 2048 + (uint64_t)st->node_count * 32,
                            .renderer = use_gl ? "gl" : "cpu"};
      char text[512];
      ocv_hud_format(&hs, text, sizeof text);
      ocv_hud_text(rgb, w, h, 4, 4, 1, text, (const uint8_t[3]){255, 255, 255});
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/frame_%04ld.png", o->out_dir, f);
    if (write_frame(path, w, h, rgb, pose, use_gl ? "gl" : "cpu", o, d.ms_octaves, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      break;
    }
    double sec = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    if (use_gl) oc_log_info("frame %ld: %.3f s (gl)", f, sec);
    else oc_log_info("frame %ld: %.2f s, %.1f M samples/s", f, sec, rs.samples / sec * 1e-6);
    printf("%s\n", path);
    fflush(stdout);
  }
out:
  free(rgb);
  oc_image_free(&img);
out_gl:
#ifdef OC_HAVE_GL
  view_gl_free(&g);
#endif
  return rc;
}

#ifdef OC_HAVE_GL
/*-*** The window ***/

/* World state (sun, weather, time) belongs to the server: window keys ask for it on a control
 * connection of their own, in a detached thread so a slow or refusing server never stalls a frame. */
typedef struct {
  char host[OCV_HOST_MAX];
  int port;
  char token[256];
  char json[256];
} world_request_t;

static void *world_request_run(void *arg) {
  world_request_t *q = arg;
  char why[512], *reply = NULL;
  int32_t status = 0;
  ocv_conn_t *cc = NULL;
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = q->token[0] ? q->token : NULL};
  int r = ocv_conn_open(&cc, q->host, q->port, &cd, NULL, 5.0, why, sizeof why);
  if (r == 0) r = ocv_control_request(cc, q->json, 5.0, &reply, &status, why, sizeof why);
  if (r < 0) oc_log_warn("%s: %s", q->json, why);
  else if (status != OCP_CODE_OK) oc_log_warn("%s: refused: %s%s", q->json, reply ? reply : "",
                                              q->token[0] ? "" : " (does the server want --token?)");
  else oc_log_info("%s: done", q->json);
  free(reply);
  ocv_conn_close(cc);
  free(q);
  return NULL;
}

static void world_request(const view_net_opts_t *o, const char *json) {
  world_request_t *q = calloc(1, sizeof *q);
  pthread_t th;
  if (!q) return;
  snprintf(q->host, sizeof q->host, "%s", o->host);
  q->port = o->port;
  snprintf(q->token, sizeof q->token, "%s", o->token ? o->token : "");
  snprintf(q->json, sizeof q->json, "%s", json);
  if (pthread_create(&th, NULL, world_request_run, q) != 0) {
    oc_log_warn("%s: no thread for the request", json);
    free(q);
    return;
  }
  pthread_detach(th);
}

/* The sun's direction, planet frame, moved by `deg` of longitude (westward negative): the time of day. */
static void sun_request(const view_net_opts_t *o, oc_dvec3 sun, double deg) {
  char json[160];
  double lat = asin(fmax(-1.0, fmin(1.0, sun.z))) / OC_DEG, lon = atan2(sun.y, sun.x) / OC_DEG + deg;
  lon = fmod(lon + 540.0, 360.0) - 180.0;
  snprintf(json, sizeof json, "{\"op\":\"sun\",\"lat\":%.6f,\"lon\":%.6f}", lat, lon);
  world_request(o, json);
}

typedef struct {
  ocv_window_t *win;
  ocv_net_t *net; /* --connect */
  const view_net_opts_t *net_opts;
  oc_scene_t *sc;
  oc_state_t *st; /* --state / --scene: the state; --connect: the newest taken */
  int have_state;
  oc_camera_pose_t pose;
  int have_pose;
  view_opts_t o;
  ocv_path_t *record; /* --record: poses of the flight, saved at exit */
  double record_t0;
} view_win_t;

static void net_wake(void *ctx) {
  (void)ctx; /* the loop renders continuously: nothing to wake */
}

/* One line per reconnect attempt, and the last on giving up (network thread). */
static void net_log(void *ctx, const char *line) {
  (void)ctx;
  oc_log_warn("%s", line);
}

static ocp_camera_t wire_camera(oc_camera_pose_t pose, int w, int h) {
  oc_camera_t c = oc_camera_from_pose(pose);
  return (ocp_camera_t){c.pos, c.forward, c.up, pose.fov, (uint32_t)w, (uint32_t)h};
}

/* Mouse look and flight: speed = altitude above ground per second (≥ 1 m/s), Shift ×10. */
static int fly(oc_camera_pose_t *pose, const ocv_window_input_t *in, double dt) {
  int moved = 0;
  if (in->look_dx != 0 || in->look_dy != 0) {
    double deg_per_px = 0.1 * pose->fov / 60.0;
    pose->heading = fmod(pose->heading + in->look_dx * deg_per_px + 360.0, 360.0);
    pose->pitch = fmax(-89.9, fmin(89.9, pose->pitch - in->look_dy * deg_per_px));
    moved = 1;
  }
  double f = in->held[OCV_KEY_FORWARD] - in->held[OCV_KEY_BACK];
  double s = in->held[OCV_KEY_RIGHT] - in->held[OCV_KEY_LEFT];
  double u = in->held[OCV_KEY_UP] - in->held[OCV_KEY_DOWN];
  if ((f != 0 || s != 0 || u != 0) && dt > 0) {
    oc_camera_t c = oc_camera_from_pose(*pose);
    oc_enu_t enu = oc_enu_at(c.pos);
    double speed = fmax(1.0, fabs(pose->geo.alt)) * (in->held[OCV_KEY_FAST] ? 10.0 : 1.0);
    double k = speed * fmin(dt, 0.25);
    oc_dvec3 p = c.pos;
    p.x += k * (f * c.forward.x + s * c.right.x + u * enu.up.x);
    p.y += k * (f * c.forward.y + s * c.right.y + u * enu.up.y);
    p.z += k * (f * c.forward.z + s * c.right.z + u * enu.up.z);
    oc_geo_t g = oc_xyz_to_geo(p);
    if (g.alt < 1.0) g.alt = 1.0; /* stay above ground */
    pose->geo = g;
    moved = 1;
  }
  return moved;
}

static int screenshot(const view_win_t *v, int w, int h, const uint8_t *rgb, int ms_octaves, char *why, size_t why_len) {
  if (make_dir(v->o.out_dir, why, why_len) < 0) return -1;
  char path[4096];
  struct stat sb;
  for (int i = 0; i < 100000; i++) {
    snprintf(path, sizeof path, "%s/screenshot_%04d.png", v->o.out_dir, i);
    if (stat(path, &sb) != 0) break;
  }
  if (write_frame(path, w, h, rgb, v->pose, "gl", &v->o, ms_octaves, why, why_len) < 0) return -1;
  printf("%s\n", path);
  fflush(stdout);
  return 0;
}

enum { WIN_OVERLAY_H = 48, WIN_ARRIVALS = 16, WIN_STATS_S = 5 };

/* The window loop's state between frames. */
typedef struct {
  ocv_gl_renderer_t *r;
  ocv_gl_view_t *view; /* kept states, bounded uploads, blending, reprojection */
  ocv_gl_present_t *present; /* tone mapping and HUD on the GPU */
  oc_atmo_t *atmo;
  int have_gs, reproject, hud, debug, weather, paused;
  int scene_ready; /* with --connect: once the WELCOME brought features and optics */
  int repush;      /* a store resized for BUDGET takes the newest state again */
  int cam_dirty;
  uint64_t epoch, welcomes_seen, budgets_seen, bytes_prev;
  double shown_at, bytes_at, bytes_rate, frame_ms, title_at; /* frame_ms: the whole last frame */
  ocv_gl_view_stats_t vs;
  ocv_net_status_t ns;
  uint8_t *overlay; /* the HUD: premultiplied RGBA8, the frame's width × WIN_OVERLAY_H */
  GLuint picture;
  int iw, ih;
  struct { uint64_t epoch; double at; } arrived[WIN_ARRIVALS]; /* when the newest states arrived */
  uint64_t newest; /* the newest epoch received */
  double stats_at, shown_lag; /* the last stats line; the shown state's wait from arrival to screen */
  double stats_worst;         /* the longest frame drawn since the last stats line, ms */
  long stats_frames;
} win_loop_t;

/* Drops the GL view and the atmosphere: the next WELCOME builds them again. */
static void win_unready(win_loop_t *L) {
  ocv_gl_view_free(L->view);
  L->view = NULL;
  oc_atmo_free(L->atmo);
  L->atmo = NULL;
  L->scene_ready = L->have_gs = 0;
}

/* A WELCOME in force and no view yet: the scene, default camera, atmosphere and GL view from it. */
static int win_welcome(view_win_t *v, win_loop_t *L) {
  char why[1024];
  const ocp_welcome_t *w = &L->ns.welcome;
  scene_from_welcome(v->sc, w);
  if (!v->have_pose) {
    v->pose = (oc_camera_pose_t){{w->cam_lat, w->cam_lon, w->cam_alt}, w->cam_heading, w->cam_pitch, w->cam_fov};
    v->have_pose = 1;
  }
  if (make_atmo(v->sc, v->o.threads, &L->atmo) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
  ocv_gl_view_desc_t vd = {.grant = w->grant, /* the contract as granted: the atlas is sized from it */
                           .animated = (w->features >> OC_FEATURE_ANIMATION) & 1u,
                           .epoch_period = w->epoch_period > 0 ? w->epoch_period : 1.0,
                           .frame_ms = v->o.frame_ms};
  if (!(L->view = ocv_gl_view_create(L->r, &vd, why, sizeof why)))
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "GL view: %s", why);
  L->scene_ready = 1;
  L->cam_dirty = 1;
  if (L->repush && ocv_gl_view_push(L->view, v->st, why, sizeof why) == 0) L->have_gs = 1;
  L->repush = 0;
  return OC_EXIT_OK;
}

/* --connect, once a frame: sessions, BUDGET, WELCOME, the newest state, bytes/s. */
static int win_net(view_win_t *v, win_loop_t *L, double t) {
  char why[1024];
  ocv_net_status(v->net, &L->ns);
  if (L->ns.gave_up) /* the reconnects ran out: say so and stop, never hang on a dead server */
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", L->ns.error);
  if (L->scene_ready && L->ns.welcomes != L->welcomes_seen && !L->ns.resumed) {
    /* a new session (a restarted server): nothing held is valid (its brick ids may name other
     * bricks now) and the grant may differ, so the view starts again from this WELCOME */
    oc_log_info("%s: a new session: the view starts afresh", v->net_opts->host);
    win_unready(L);
  }
  L->welcomes_seen = L->ns.welcomes;
  if (L->scene_ready && L->ns.budgets != L->budgets_seen) {
    /* BUDGET took effect (a raise at once, a lowering once the old budget's states have left
     * the window): the store is sized again from the grant now in force, and takes the newest
     * state again at once */
    oc_log_info("%s: budget now %.1f MiB: the GPU store is resized", v->net_opts->host,
                (double)L->ns.welcome.grant.budget / 1048576.0);
    L->repush = L->have_gs;
    win_unready(L);
  }
  L->budgets_seen = L->ns.budgets;
  int rc;
  if (!L->scene_ready && L->ns.have_welcome && (rc = win_welcome(v, L)) != OC_EXIT_OK) return rc;
  if (L->ns.states > 0 && L->ns.epoch != L->newest) { /* arrived (to within a frame): for the state's age */
    L->newest = L->ns.epoch;
    L->arrived[L->newest % WIN_ARRIVALS].epoch = L->newest;
    L->arrived[L->newest % WIN_ARRIVALS].at = t;
  }
  uint64_t e;
  /* the newest state, once the one uploading is complete: replacing it every time a newer one came
   * kept a slow window (llvmpipe, 1280×720) on its first state for minutes */
  if (L->view && !ocv_gl_view_staging(L->view) && ocv_net_take_state(v->net, v->st, &e) == 1) {
    if (ocv_gl_view_push(L->view, v->st, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "GL state upload (epoch %llu): %s", (unsigned long long)e, why);
    L->have_gs = 1;
  }
  if (t - L->bytes_at >= 1.0) { /* bytes/s received, for the HUD */
    L->bytes_rate = (double)(L->ns.viewer.bytes_in - L->bytes_prev) / (t - L->bytes_at);
    L->bytes_prev = L->ns.viewer.bytes_in;
    L->bytes_at = t;
  }
  return OC_EXIT_OK;
}

/* Keys and mouse: flight, step, exposure, toggles, and the server's world (sun, weather, time). */
static void win_keys(view_win_t *v, win_loop_t *L, const ocv_window_input_t *in, double dt) {
  if (v->have_pose && fly(&v->pose, in, dt)) L->cam_dirty = 1;
  for (int i = 0; i < in->presses[OCV_ACT_STEP_MUL]; i++) v->o.step = fmin(v->o.step * 1.25, 1e3);
  for (int i = 0; i < in->presses[OCV_ACT_STEP_DIV]; i++) v->o.step = fmax(v->o.step / 1.25, 1e-3);
  for (int i = 0; i < in->presses[OCV_ACT_EXPOSURE_UP]; i++) v->o.exposure = fmin(v->o.exposure * 1.25, 1e6);
  for (int i = 0; i < in->presses[OCV_ACT_EXPOSURE_DOWN]; i++) v->o.exposure = fmax(v->o.exposure / 1.25, 1e-6);
  if (in->presses[OCV_ACT_REPROJECT] & 1) L->reproject = !L->reproject;
  if (in->presses[OCV_ACT_HUD] & 1) L->hud = !L->hud;
  if (in->presses[OCV_ACT_JITTER] & 1) v->o.jitter = !v->o.jitter;
  for (int i = 0; i < in->presses[OCV_ACT_OCTAVES]; i++) {
    long cur = v->o.octaves ? v->o.octaves : make_desc(v->sc, &v->o, L->atmo).ms_octaves;
    v->o.octaves = cur % 8 + 1;
  }
  int world_keys = in->presses[OCV_ACT_WEATHER] + in->presses[OCV_ACT_SUN_WEST] + in->presses[OCV_ACT_SUN_EAST] +
                   in->presses[OCV_ACT_TIME];
  if (world_keys && !v->net) oc_log_warn("sun, weather and time are the server's: keys N, K, L, T need --connect");
  else if (world_keys && L->scene_ready) {
    oc_dvec3 sun = L->have_gs ? v->st->sun_dir : v->sc->sun_dir;
    if (in->presses[OCV_ACT_WEATHER]) {
      L->weather = (L->weather + in->presses[OCV_ACT_WEATHER]) % OC_PRESET_COUNT;
      char json[128];
      snprintf(json, sizeof json, "{\"op\":\"weather\",\"preset\":\"%s\",\"seconds\":10}",
               oc_scene_preset_name(L->weather));
      world_request(v->net_opts, json);
    }
    int sun_steps = in->presses[OCV_ACT_SUN_EAST] - in->presses[OCV_ACT_SUN_WEST];
    if (sun_steps) sun_request(v->net_opts, sun, 15.0 * sun_steps);
    if (in->presses[OCV_ACT_TIME] & 1) {
      L->paused = !L->paused;
      world_request(v->net_opts, L->paused ? "{\"op\":\"pause\"}" : "{\"op\":\"resume\"}");
    }
  }
  L->debug = (L->debug + in->presses[OCV_ACT_DEBUG]) % 4;
  if (in->resized) L->cam_dirty = 1;
  if (v->net && L->cam_dirty && v->have_pose && in->fb_w > 0 && in->fb_h > 0) {
    ocp_camera_t wc = wire_camera(v->pose, in->fb_w, in->fb_h);
    if (ocv_net_set_camera(v->net, &wc) < 0) oc_log_warn("camera refused by the session (invalid camera)");
  }
  L->cam_dirty = 0;
}

/* The HUD into L->overlay (oh rows) for the frame rendered at t0. */
static void win_hud(const view_win_t *v, win_loop_t *L, double t0, int oh) {
  memset(L->overlay, 0, (size_t)L->iw * WIN_OVERLAY_H * 4);
  ocv_hud_stats_t hs = {.frame_ms = L->frame_ms, .epoch = L->epoch, .epoch_age_s = t0 - L->shown_at,
                        .bricks = L->vs.bricks, .trace_w = L->vs.trace_w, .trace_h = L->vs.trace_h,
                        .trace_scale = L->vs.scale,
                        .resident_bytes = L->vs.resident_bytes,
                        .budget_bytes = v->net ? L->ns.welcome.grant.budget : L->vs.resident_bytes,
                        .bytes_per_s = L->bytes_rate, .renderer = L->reproject ? "gl, reprojected" : "gl"};
  ocv_gl_renderer_timings(L->r, &hs.trace_ms, &hs.reproject_ms);
  if (!L->reproject) hs.reproject_ms = -1.0;
  char text[512];
  ocv_hud_format(&hs, text, sizeof text);
  ocv_hud_text_rgba(L->overlay, L->iw, oh, 6, 6, 1, text, (const uint8_t[3]){255, 255, 255});
}

/* One frame of the shown state at the window's size, tone-mapped with the HUD into L->picture;
 * *drawn 1 when there is one. */
static int win_draw(view_win_t *v, win_loop_t *L, const ocv_window_input_t *in, int *drawn, int *ms_octaves) {
  char why[1024];
  *drawn = 0;
  if (!(L->have_gs && L->scene_ready && v->have_pose && in->fb_w > 0 && in->fb_h > 0)) return OC_EXIT_OK;
  if (in->fb_w != L->iw || in->fb_h != L->ih) {
    free(L->overlay);
    if (!(L->overlay = malloc((size_t)in->fb_w * WIN_OVERLAY_H * 4)))
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory for a %dx%d HUD", in->fb_w, (int)WIN_OVERLAY_H);
    L->iw = in->fb_w;
    L->ih = in->fb_h;
  }
  oc_render_desc_t d = make_desc(v->sc, &v->o, L->atmo);
  d.width = L->iw;
  d.height = L->ih;
  d.camera = oc_camera_from_pose(v->pose);
  d.debug_view = L->debug;
  *ms_octaves = d.ms_octaves;
  double t0 = now_s();
  if (ocv_gl_view_frame(L->view, &d, t0, L->reproject, NULL, &L->vs, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "render failed: %s", why);
  if (L->vs.shown) {
    if (L->vs.epoch != L->epoch) { /* a new state on screen: its age counts from its arrival */
      const uint64_t e = L->vs.epoch;
      L->shown_at = L->arrived[e % WIN_ARRIVALS].epoch == e ? L->arrived[e % WIN_ARRIVALS].at : t0;
      L->shown_lag = t0 - L->shown_at;
    }
    L->epoch = L->vs.epoch;
    int oh = L->ih < WIN_OVERLAY_H ? L->ih : WIN_OVERLAY_H;
    if (L->hud) win_hud(v, L, t0, oh);
    /* traced at vs.trace_w × vs.trace_h (the frame-time target), upsampled to the window */
    L->picture = ocv_gl_present_upsample(L->present, ocv_gl_view_output(L->view), L->vs.trace_w, L->vs.trace_h, L->iw,
                                         L->ih, (float)v->o.exposure, L->hud ? L->overlay : NULL, L->iw, oh, why,
                                         sizeof why);
    if (!L->picture) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    *drawn = 1;
  }
  if (v->record) {
    if (!v->record->count || t0 - v->record_t0 > v->record->t[v->record->count - 1] + 1e-3)
      (void)ocv_path_add(v->record, v->record->count ? t0 - v->record_t0 : 0.0, v->pose);
    if (v->record->count == 1) v->record_t0 = t0;
  }
  return OC_EXIT_OK;
}

/* F12 / P: the picture shown, read back once, as a PNG with the camera. */
static void win_screenshot(const view_win_t *v, win_loop_t *L, int drawn, int ms_octaves) {
  char why[1024];
  if (!drawn) {
    oc_log_warn("screenshot: nothing rendered yet");
    return;
  }
  uint8_t *rgb = malloc((size_t)L->iw * (size_t)L->ih * 3); /* the only read-back: a screenshot */
  if (!rgb) oc_log_error("screenshot: out of memory");
  else if (ocv_gl_present_read(L->present, rgb, why, sizeof why) < 0 ||
           screenshot(v, L->iw, L->ih, rgb, ms_octaves, why, sizeof why) < 0)
    oc_log_error("screenshot: %s", why);
  free(rgb);
}

/* The title, four times a second: the connection while no state is held, else epoch and settings. */
static void win_title(const view_win_t *v, win_loop_t *L, double t) {
  if (t - L->title_at < 0.25) return;
  char title[512];
  const ocv_net_status_t *ns = &L->ns;
  if (v->net && !L->have_gs)
    snprintf(title, sizeof title, "overcast-view — %.200s — %.200s", v->net_opts->host,
             ns->error[0] ? ns->error : ns->connected ? "waiting for the first state" : "connecting");
  else
    snprintf(title, sizeof title, "overcast-view — %s — epoch %llu — %.1f ms — step %.3g, exposure %.3g%s",
             v->sc->name[0] ? v->sc->name : "state", (unsigned long long)L->epoch, L->frame_ms, v->o.step,
             v->o.exposure, v->net && !ns->connected ? " — reconnecting" : "");
  ocv_window_set_title(v->win, title);
  L->title_at = t;
}

/* Every WIN_STATS_S s, a line for benchmarks (scripts/window_fps.sh): frames/s, the longest frame, the
 * traced size, and the shown state against the newest received. */
static void win_stats(const view_win_t *v, win_loop_t *L, double t, int drawn) {
  L->stats_frames += drawn;
  if (drawn && L->frame_ms > L->stats_worst) L->stats_worst = L->frame_ms;
  if (t - L->stats_at < WIN_STATS_S) return;
  if (L->have_gs)
    oc_log_info("window: %.2f frames/s over %.1f s, worst frame %.0f ms, trace %dx%d (1/%d) of %dx%d, epoch %llu shown "
                "(%.2f s from its arrival to the screen), newest received %llu, %s",
                (double)L->stats_frames / (t - L->stats_at), t - L->stats_at, L->stats_worst, L->vs.trace_w,
                L->vs.trace_h, L->vs.scale, L->iw, L->ih, (unsigned long long)L->epoch, L->shown_lag,
                (unsigned long long)(v->net ? L->newest : L->epoch), L->reproject ? "reprojected" : "every pixel traced");
  L->stats_at = t;
  L->stats_frames = 0;
  L->stats_worst = 0.0;
}

/* One local state (--state, --scene): a GL view whose budget holds it, nothing to blend. */
static int win_local_state(view_win_t *v, win_loop_t *L) {
  char why[1024];
  /* K = 2 (the state and none staged beside it) with the GL store's own sizes */
  oc_budget_t g = {.slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 2};
  g.budget = ((uint64_t)v->st->brick_count + 2) * (OC_SLOT_BYTES + OC_RECORD_BYTES); /* ≥ the minimum */
  ocv_gl_view_desc_t vd = {.grant = g, .frame_ms = v->o.frame_ms};
  if (!(L->view = ocv_gl_view_create(L->r, &vd, why, sizeof why)) || ocv_gl_view_push(L->view, v->st, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "GL state upload: %s", why);
  L->have_gs = 1;
  return OC_EXIT_OK;
}

static int run_window(view_win_t *v) {
  char why[1024];
  int rc = OC_EXIT_OK;
  win_loop_t L = {.hud = 1, .reproject = 1, .weather = OC_PRESET_FAIR, .cam_dirty = 1};
  if (!(L.r = ocv_gl_renderer_create(why, sizeof why))) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "GL renderer: %s", why);
  if (!(L.present = ocv_gl_present_create(why, sizeof why))) {
    ocv_gl_renderer_free(L.r);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "GL picture: %s", why);
  }
  L.epoch = v->have_state ? v->st->epoch : 0;
  L.shown_at = L.bytes_at = L.stats_at = now_s();
  L.scene_ready = !v->net;
  if (L.scene_ready && make_atmo(v->sc, v->o.threads, &L.atmo) < 0)
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
  if (rc == OC_EXIT_OK && v->have_state) rc = win_local_state(v, &L);
  double last = now_s();
  while (rc == OC_EXIT_OK) {
    ocv_window_input_t in;
    ocv_window_poll(v->win, &in);
    if (in.presses[OCV_ACT_QUIT]) break;
    double t = now_s(), dt = t - last;
    last = t;
    if (v->net && (rc = win_net(v, &L, t)) != OC_EXIT_OK) break;
    win_keys(v, &L, &in, dt);
    int drawn = 0, ms_octaves = 1;
    if ((rc = win_draw(v, &L, &in, &drawn, &ms_octaves)) != OC_EXIT_OK) break;
    if (ocv_window_present(v->win, drawn ? L.picture : 0, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      break;
    }
    if (in.presses[OCV_ACT_SCREENSHOT]) win_screenshot(v, &L, drawn, ms_octaves);
    /* the whole frame (network, keys, render, picture, swap): what the frame-time target keeps */
    double end = now_s();
    if (drawn) {
      L.frame_ms = 1e3 * (end - t);
      ocv_gl_view_frame_time(L.view, L.frame_ms);
    }
    win_stats(v, &L, end, drawn);
    win_title(v, &L, t);
  }
  free(L.overlay);
  ocv_gl_view_free(L.view);
  ocv_gl_present_free(L.present);
  ocv_gl_renderer_free(L.r);
  oc_atmo_free(L.atmo);
  return rc;
}
#endif

/* What the command line asked for (parse_args). */
typedef struct {
  const char *state_path, *scene_path, *camera_text, *camera_png, *save_path, *record_path, *path_file;
  const char *connect; /* --connect, parsed into net.host and net.port after the table */
  int w, h;
  long frames;
  int frames_given;
  view_opts_t vo;
  ocv_path_t cam_path; /* --path */
  view_net_opts_t net;
  renderer_t renderer;
  int net_opts, want_window, want_headless, batch_opts, batch_net, quiet;
} view_args_t;

/*-*** The options: one table (common/oc_cli.h), from which they are parsed and --help is printed ***/

/* An integer in the row's range into a long. */
static int opt_long(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  char opt[80];
  snprintf(opt, sizeof opt, "--%s", o->name);
  return oc_cli_int(p, opt, text, (long)o->lo, (long)o->hi, oc_cli_field(o, base));
}

/* --size WxH: the image's, or the window's initial size. */
static int opt_size(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  view_args_t *a = base;
  (void)o;
  return oc_cli_size(p, "--size", text, &a->w, &a->h);
}

/* --renderer gl|cpu. */
static int opt_renderer(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  renderer_t *r = oc_cli_field(o, base);
  if (!strcmp(text, "cpu")) *r = R_CPU;
  else if (!strcmp(text, "gl")) *r = R_GL;
  else return oc_cli_fail(p, -1, "--renderer %s: expected gl or cpu", text);
  return 0;
}

/* Rows indexed by R_*, so that given[R_*] says what the command line holds. */
enum { R_STATE, R_SCENE, R_CONNECT, R_TOKEN, R_BUDGET, R_MAX_DEPTH, R_WAIT_EPOCHS, R_EPOCHS, R_STEP, R_TIMEOUT,
       R_WINDOW, R_HEADLESS, R_CAMERA, R_CAMERA_FROM, R_SIZE, R_FRAMES, R_OUT, R_RENDERER, R_STEP_FACTOR, R_EXPOSURE,
       R_MS_OCTAVES, R_JITTER, R_THREADS, R_SAVE_STATE, R_PATH, R_FPS, R_HUD, R_RECORD, R_FRAME_MS, R_QUIET, R_HELP,
       R_VERSION, R_COUNT };

#define SOURCE "source (one of)"
#define NETWORK "network (with --connect or --scene)"
#define MODE "mode"
#define VIEW "view"
#define RENDER "rendering"
#define OTHER "other"
#define AT(field) offsetof(view_args_t, field)
#define LONG_ROW(field) .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(field)

static const oc_cli_opt_t opts[R_COUNT + 1] = {
    [R_STATE] = {.name = "state", .type = OC_CLI_STRING, .offset = AT(state_path), .arg = "FILE", .group = SOURCE,
                 .help = "render a saved state file (what a viewer held)"},
    [R_SCENE] = {.name = "scene", .type = OC_CLI_STRING, .offset = AT(scene_path), .arg = "FILE",
                 .def_note = "scenes/analytic_sphere.json when no --state or --connect is given", .group = SOURCE,
                 .help = "start the overcast-server next to this program on 127.0.0.1:0 with the scene and stepped "
                         "epochs, take the state it plans for the camera (as --connect --step does), stop it, and "
                         "render that state as with --state"},
    [R_CONNECT] = {.name = "connect", .type = OC_CLI_STRING, .offset = AT(connect), .arg = "HOST:PORT",
                   .group = SOURCE,
                   .help = "receive states from overcast-server and render the newest; the scene's features, "
                           "optics and default camera come from the server"},
    [R_TOKEN] = {.name = "token", .type = OC_CLI_STRING, .offset = AT(net.token), .arg = "TEXT", .lo = 1,
                 .hi = OCP_TOKEN_MAX, .group = NETWORK, .help = "the server's token, if it has one"},
    [R_BUDGET] = {.name = "budget", LONG_ROW(net.budget_mib), .arg = "MIB", .lo = 1, .hi = 1 << 20, .def = "64",
                  .group = NETWORK, .help = "memory budget asked for"},
    [R_MAX_DEPTH] = {.name = "max-depth", LONG_ROW(net.max_depth), .arg = "N", .lo = 0, .hi = 21, .def = "21",
                     .group = NETWORK, .help = "deepest octree level asked for"},
    [R_WAIT_EPOCHS] = {.name = "wait-epochs", LONG_ROW(net.epochs), .arg = "N", .lo = 1, .hi = 100000, .def = "4",
                       .group = NETWORK, .help = "headless: render once N complete states have arrived"},
    [R_EPOCHS] = {.name = "epochs", LONG_ROW(net.epochs), .arg = "N", .lo = 1, .hi = 100000, .group = NETWORK,
                  .help = "the same as --wait-epochs"},
    [R_STEP] = {.name = "step", .type = OC_CLI_FLAG, .offset = AT(net.step), .group = NETWORK,
                .help = "headless, for a server run with --epoch-period 0: ask it (on a second, control connection) "
                        "to step one epoch whenever the previous state arrived"},
    [R_TIMEOUT] = {.name = "timeout", .type = OC_CLI_DOUBLE, .offset = AT(net.timeout), .arg = "S", .lo = 0.01,
                   .hi = 86400, .def = "60", .group = NETWORK,
                   .help = "headless: give up when the states have not arrived within S s; window: the connect "
                           "timeout (at most 10 s). A lost connection or a draining server (GOODBYE RECONNECT) is "
                           "retried with backoff and jitter, one line per attempt, and given up after 10 attempts "
                           "or 120 s"},
    [R_WINDOW] = {.name = "window", .type = OC_CLI_FLAG, .offset = AT(want_window), .group = MODE,
                  .help = "a window (OpenGL 4.5 core through GLFW) rendering continuously; the default when DISPLAY "
                          "or WAYLAND_DISPLAY is set and none of --headless, --frames, --out, --save-state, "
                          "--epochs, --step is given"},
    [R_HEADLESS] = {.name = "headless", .type = OC_CLI_FLAG, .offset = AT(want_headless), .group = MODE,
                    .help = "render --frames PNG frames into --out and exit (no display needed)"},
    [R_CAMERA] = {.name = "camera", .type = OC_CLI_STRING, .offset = AT(camera_text),
                  .arg = "LAT,LON,ALT,HEADING,PITCH,FOV", .def_note = "the scene's camera", .group = VIEW,
                  .help = "degrees, metres"},
    [R_CAMERA_FROM] = {.name = "camera-from", .type = OC_CLI_STRING, .offset = AT(camera_png), .arg = "PNG",
                       .group = VIEW, .help = "restore the camera stored in a screenshot's text chunk"},
    [R_SIZE] = {.name = "size", .type = OC_CLI_CUSTOM, .parse = opt_size, .arg = "WxH", .def = "640x360",
                .group = VIEW, .help = "image size, or the window's initial size"},
    [R_FRAMES] = {.name = "frames", LONG_ROW(frames), .arg = "N", .lo = 1, .hi = 100000,
                  .def_note = "1; with --path, the path's length", .group = VIEW,
                  .help = "headless: frames to write (with --jitter each frame has its own jitter)"},
    [R_OUT] = {.name = "out", .type = OC_CLI_STRING, .offset = AT(vo.out_dir), .arg = "DIR", .def = "out",
               .group = VIEW,
               .help = "output folder: frame_NNNN.png headless, screenshot_NNNN.png in the window"},
    [R_RENDERER] = {.name = "renderer", .type = OC_CLI_CUSTOM, .parse = opt_renderer, .offset = AT(renderer),
                    .arg = "gl|cpu", .def_note = "gl when a GL context can be made, else cpu with a notice",
                    .group = RENDER,
                    .help = "gl: the GL compute renderer (headless through EGL); cpu: the CPU reference renderer "
                            "(headless only); a forced gl without a context is an error"},
    [R_STEP_FACTOR] = {.name = "step-factor", .type = OC_CLI_DOUBLE, .offset = AT(vo.step), .arg = "X", .lo = 1e-3,
                       .hi = 1e3, .def = "0.5", .group = RENDER, .help = "step = X × voxel spacing"},
    [R_EXPOSURE] = {.name = "exposure", .type = OC_CLI_DOUBLE, .offset = AT(vo.exposure), .arg = "X", .lo = 1e-6,
                    .hi = 1e6, .def = "10", .group = RENDER, .help = "exposure of the tone mapping"},
    [R_MS_OCTAVES] = {.name = "ms-octaves", LONG_ROW(vo.octaves), .arg = "N", .lo = 1, .hi = 8,
                      .def_note = "the scene's", .group = RENDER, .help = "multiple-scattering octaves"},
    [R_JITTER] = {.name = "jitter", .type = OC_CLI_FLAG, .offset = AT(vo.jitter), .group = RENDER,
                  .help = "per-pixel ray-start jitter"},
    [R_THREADS] = {.name = "threads", LONG_ROW(vo.threads), .arg = "N", .lo = 1, .hi = 256, .def = "2",
                   .group = RENDER,
                   .help = "render threads of the CPU renderer and tables, and the producer threads of --scene's "
                           "server"},
    [R_SAVE_STATE] = {.name = "save-state", .type = OC_CLI_STRING, .offset = AT(save_path), .arg = "FILE",
                      .group = RENDER, .help = "headless: also write the state that was rendered"},
    [R_PATH] = {.name = "path", .type = OC_CLI_STRING, .offset = AT(path_file), .arg = "FILE", .group = RENDER,
                .help = "headless: a recorded camera path (lines \"T LAT,LON,ALT,HEADING,PITCH,FOV\"); frame f is "
                        "its pose at f / --fps s"},
    [R_FPS] = {.name = "fps", .type = OC_CLI_DOUBLE, .offset = AT(vo.fps), .arg = "X", .lo = 0.01, .hi = 1000,
               .def = "30", .group = RENDER, .help = "frames per second of --path"},
    [R_HUD] = {.name = "hud", .type = OC_CLI_FLAG, .offset = AT(vo.hud), .group = RENDER,
               .help = "headless: draw the HUD into the frames too (the window has it on H)"},
    [R_RECORD] = {.name = "record", .type = OC_CLI_STRING, .offset = AT(record_path), .arg = "FILE",
                  .group = RENDER, .help = "window: record the flight as a camera path (saved at exit)"},
    [R_FRAME_MS] = {.name = "frame-ms", .type = OC_CLI_DOUBLE, .offset = AT(vo.frame_ms), .arg = "MS", .lo = 0,
                    .hi = 60000, .def = "100", .group = RENDER,
                    .help = "window: the frame-time target, kept by tracing at full, 1/2, 1/4 or 1/8 of the size "
                            "per axis (upsampled; the HUD shows the traced size), starting at the coarsest; 0: "
                            "every frame traced at full size"},
    [R_QUIET] = {.name = "quiet", .short_name = 'q', .type = OC_CLI_FLAG, .offset = AT(quiet), .group = OTHER,
                 .help = "only errors"},
    [R_HELP] = {.name = "help", .type = OC_CLI_HELP, .group = OTHER, .help = "print this and exit"},
    [R_VERSION] = {.name = "version", .type = OC_CLI_VERSION, .group = OTHER, .help = "print the version and exit"},
    [R_COUNT] = {0}};

static const oc_cli_spec_t spec = {
    .prog = "overcast-view",
    .about = "Renders clouds and atmosphere in a window, or headless to PNG frames, with the GL renderer\n"
             "or the CPU reference renderer.\n",
    .epilog = "window keys:\n"
              "  left mouse button + drag   look around\n"
              "  W A S D, Q E               fly forward/left/back/right, down/up (arrow keys too); speed =\n"
              "                             altitude above ground per second (at least 1 m/s), Shift ×10\n"
              "  [ ]                        step factor × / ÷ 1.25\n"
              "  - =                        exposure ÷ / × 1.25\n"
              "  F12 or P                   screenshot (PNG with the camera in a text chunk, for --camera-from)\n"
              "  R                          reprojection on/off (on at start: one pixel in 16 traced per frame)\n"
              "  V                          debug views: off, level of detail, τ channel, node bounds\n"
              "  H                          HUD on/off (frame and GPU pass times, epoch and age, resident\n"
              "                             bytes against the budget, bytes/s received)\n"
              "  J                          per-pixel ray-start jitter on/off (averaged by reprojection)\n"
              "  M                          multiple-scattering octaves: 1, 2, ... 8, cycled\n"
              "  N                          --connect: the server's next weather preset (clear, fair, overcast,\n"
              "                             storm, cirrus; a 10 s transition), through a control connection\n"
              "  K L                        --connect: the sun 15° west / east (time of day)\n"
              "  T                          --connect: world time paused / resumed\n"
              "                             (N, K, L, T use --token when the server has one)\n"
              "  Esc                        quit\n"
              "The window's viewport and every camera move are sent to the server with --connect.\n"
              "\n"
              "exit status: 0 ok, 1 runtime error, 2 usage error\n",
    .opts = opts,
};

/* The options into *a; returns -1 to go on, else the exit status (--help, --version, a usage error). */
static int parse_args(int argc, char **argv, view_args_t *a) {
  unsigned char given[R_COUNT];
  *a = (view_args_t){.frames = 1, .renderer = R_AUTO};
  ocv_path_init(&a->cam_path);
  int r = oc_cli_parse(&spec, argc, argv, a, given, NULL);
  if (r) return r > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  if (a->quiet) oc_log_set_level(OC_LOG_ERROR);
  if ((a->net.connect = given[R_CONNECT]) &&
      ocv_parse_address(a->connect, a->net.host, sizeof a->net.host, &a->net.port) < 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect: expected HOST:PORT (port 1..65535), got \"%s\"", a->connect);
  for (int i = 0; i < R_COUNT; i++) a->net_opts |= given[i] && !strcmp(opts[i].group, NETWORK);
  a->frames_given = given[R_FRAMES];
  a->batch_opts = (given[R_FRAMES] || given[R_PATH] || given[R_SAVE_STATE]) | (given[R_OUT] << 1);
  a->batch_net = given[R_WAIT_EPOCHS] || given[R_EPOCHS] || given[R_STEP];
  a->want_window |= given[R_RECORD];
  return -1;
}

/* Options that exclude or need each other; --path loaded. Returns -1 to go on, else the exit status. */
static int check_args(view_args_t *a) {
  if (a->state_path && a->scene_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--state and --scene exclude each other");
  if (a->net.connect && (a->state_path || a->scene_path))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect excludes --state and --scene");
  if (a->net_opts && a->state_path)
    return oc_cli_fail(prog, OC_EXIT_USAGE,
                       "--token, --budget, --max-depth, --epochs, --step and --timeout go with --connect or --scene");
  if (a->camera_text && a->camera_png) return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera and --camera-from exclude each other");
  if (a->path_file && (a->camera_text || a->camera_png)) return oc_cli_fail(prog, OC_EXIT_USAGE, "--path gives the camera: no --camera or --camera-from");
  if (a->record_path && a->want_headless) return oc_cli_fail(prog, OC_EXIT_USAGE, "--record records a window's flight: not with --headless");
  if (a->path_file) {
    char pwhy[512];
    if (ocv_path_load(&a->cam_path, a->path_file, pwhy, sizeof pwhy) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--path: %s", pwhy);
    a->vo.path = &a->cam_path;
    if (!a->frames_given) a->frames = (long)floor(ocv_path_duration(&a->cam_path) * a->vo.fps) + 1;
  }
  if (a->want_window && a->want_headless) return oc_cli_fail(prog, OC_EXIT_USAGE, "--window and --headless exclude each other");
  if (a->want_window && ((a->batch_opts & 1) || a->batch_net))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--frames, --save-state, --epochs and --step go with --headless, not --window");
  if (a->want_window && a->renderer == R_CPU)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--window renders with GL: --renderer cpu goes with --headless");
  return -1;
}

/* The camera: --camera, --camera-from's text chunk, else the scene's. *have_pose 0: the server's
 * (--connect). Returns OC_EXIT_OK or the exit status of an error. */
static int initial_pose(const view_args_t *a, const oc_scene_t *sc, oc_camera_pose_t *pose, int *have_pose) {
  char why[1024];
  *pose = (oc_camera_pose_t){sc->camera.pos, sc->camera.heading, sc->camera.pitch, sc->camera.fov};
  *have_pose = a->camera_text || a->camera_png || !a->net.connect; /* --state, --scene: the scene's camera unless given */
  if (a->camera_text && oc_camera_parse(a->camera_text, pose, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
  if (a->camera_png) {
    int pw, ph;
    uint8_t *px;
    char text[256];
    if (oc_png_read(a->camera_png, &pw, &ph, &px, "overcast-camera", text, sizeof text, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from: %s", why);
    free(px);
    if (!text[0]) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from %s: no overcast-camera text chunk", a->camera_png);
    if (oc_camera_parse(text, pose, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--camera-from %s: %s", a->camera_png, why);
  }
  return OC_EXIT_OK;
}

/* The state to render (not for a --connect window, which takes states as they come): --scene's,
 * --connect's newest, or --state's; saved with --save-state. */
static int source_state(view_args_t *a, int window, oc_camera_pose_t *pose, int have_pose, oc_scene_t *sc,
                        oc_state_t *st) {
  char why[1024];
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  if (!a->state_path && !a->net.connect) {
    a->net.width = a->w;
    a->net.height = a->h;
    if (scene_state(a->scene_path, a->vo.threads, &a->net, pose, sc, st, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--scene %s: %s", a->scene_path, why);
  }
  if (a->net.connect && !window) {
    a->net.width = a->w;
    a->net.height = a->h;
    if (net_receive(&a->net, have_pose ? pose : NULL, pose, sc, st, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  }
  if (a->state_path && oc_state_load(st, a->state_path, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  if (!(a->net.connect && window)) {
    clock_gettime(CLOCK_MONOTONIC, &t1);
    oc_log_info("state: %u nodes, %u bricks (%.2f s)", st->node_count, st->brick_count,
                (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec));
  }
  if (a->save_path && oc_state_save(st, a->save_path, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  return OC_EXIT_OK;
}

#ifdef OC_HAVE_GL
/* The window mode: with --connect the network thread, then the window loop; --record saved. */
static int window_mode(const view_args_t *a, ocv_window_t *win, oc_scene_t *sc, oc_state_t *st, oc_camera_pose_t pose,
                       int have_pose) {
  const view_net_opts_t *net = &a->net;
  int rc;
  view_win_t v = {.win = win, .net_opts = net, .sc = sc, .st = st, .have_state = !net->connect, .pose = pose,
                  .have_pose = have_pose || !net->connect, .o = a->vo};
  if (net->connect) {
    ocv_net_desc_t nd = {.host = net->host, .port = net->port,
                         .viewer = {.role = OCP_ROLE_VIEWER, .budget = (uint64_t)net->budget_mib << 20,
                                    .max_depth = (uint8_t)net->max_depth, .width = (uint32_t)a->w,
                                    .height = (uint32_t)a->h, .caps = OCP_CAP_ALL, .token = net->token},
                         .connect_timeout_s = fmin(net->timeout, 10.0), .on_state = net_wake, .on_log = net_log};
    int r = ocv_net_start(&v.net, &nd);
    if (r < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s:%d: cannot start the network thread (%s)", net->host, net->port,
                         oc_strerror(r));
    if (have_pose) {
      ocp_camera_t wc = wire_camera(pose, a->w, a->h);
      (void)ocv_net_set_camera(v.net, &wc);
    }
  }
  ocv_path_t rec;
  ocv_path_init(&rec);
  if (a->record_path) v.record = &rec;
  rc = run_window(&v);
  ocv_net_stop(v.net);
  if (a->record_path) {
    char pwhy[512];
    if (ocv_path_save(&rec, a->record_path, pwhy, sizeof pwhy) < 0)
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--record: %s", pwhy);
    else oc_log_info("%zu camera keys recorded in %s", rec.count, a->record_path);
  }
  ocv_path_free(&rec);
  return rc;
}
#endif

int main(int argc, char **argv) {
  view_args_t a;
  int rc = parse_args(argc, argv, &a);
  if (rc < 0) rc = check_args(&a);
  if (rc >= 0) {
    ocv_path_free(&a.cam_path);
    return rc;
  }
  /* A window by default when there is a display to show it and nothing asks for batch output. */
  int window = a.want_window ||
               (!a.want_headless && !a.batch_opts && !a.batch_net && a.renderer != R_CPU && have_display());

  char why[1024];
  rc = OC_EXIT_OK;
  oc_state_t st;
  oc_state_init(&st);
  oc_atmo_t *atmo = NULL;
#ifdef OC_HAVE_GL
  ocv_window_t *win = NULL;
#endif
  oc_scene_t *sc = calloc(1, sizeof *sc);
  if (!sc) {
    ocv_path_free(&a.cam_path);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  }
  if (window) { /* first, so that a missing display is said before any work */
    if (!have_display()) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--window: no display (DISPLAY and WAYLAND_DISPLAY are unset); use --headless");
      goto out;
    }
#ifdef OC_HAVE_GL
    if (!(win = ocv_window_open(a.w, a.h, "overcast-view", why, sizeof why))) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--window: %s (or use --headless)", why);
      goto out;
    }
#else
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--window: this build has no GL (libepoxy was not found); use --headless");
    goto out;
#endif
  }
  if (!a.state_path && !a.net.connect) {
    if (!a.scene_path) a.scene_path = "scenes/analytic_sphere.json";
    if (oc_scene_load(sc, a.scene_path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      goto out;
    }
  } else {
    oc_scene_default(sc);
  }
  oc_camera_pose_t pose;
  int have_pose;
  if ((rc = initial_pose(&a, sc, &pose, &have_pose)) != OC_EXIT_OK) goto out;
  if ((rc = source_state(&a, window, &pose, have_pose, sc, &st)) != OC_EXIT_OK) goto out;
  if (window) {
#ifdef OC_HAVE_GL
    rc = window_mode(&a, win, sc, &st, pose, have_pose);
#endif
    goto out;
  }
  if (make_atmo(sc, a.vo.threads, &atmo) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
    goto out;
  }
  rc = run_headless(a.renderer, &st, sc, atmo, pose, a.w, a.h, a.frames, &a.vo);
out:
  ocv_path_free(&a.cam_path);
#ifdef OC_HAVE_GL
  ocv_window_close(win);
#endif
  oc_atmo_free(atmo);
  oc_state_free(&st);
  oc_scene_free(sc);
  free(sc);
  return rc;
}
