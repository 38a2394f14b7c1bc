/* bench_stability.c — `overcast-bench stability`: stiff and extreme cases, end to end.
 *
 * Each case is a scene (made here, as JSON, like a user's file) served by a real overcast-server
 * core and loop (server/net.h) running on a thread of this process, on 127.0.0.1 with a free port,
 * stepped by command. A viewer connects over the wire protocol (client/net.h, ocv_fetch: every
 * state is rebuilt from the wire and checked against the server's checksum), asks for a few epochs
 * at the case's camera, budget and depth, and renders the newest state with the CPU reference
 * renderer and, when a GL context can be made, the GL renderer. Each image must be finite with its
 * cloud transmittance in [0, 1]; where the answer is known (one homogeneous analytic medium: the
 * centre ray's transmittance is e^−τ with τ from the closed-form chord) the error is bounded too.
 *
 * The verdict column is what the case asserts; a row that fails makes the command exit 1. The
 * Markdown table goes into docs/numerics.md ("End to end: stiff and extreme cases"). */
#include <math.h>
#include <stddef.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"
#include "ocv.h"

/* The analytic sphere of scenes/analytic_sphere.json: centre 3 km up over (0°, 0°), radius 2 km;
 * the default camera looks at its centre from 10 km west, so the centre ray's chord is 4 km. */
#define SPHERE(sigma) "{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":2000,\"sigma_t\":" sigma "}"
#define CAM_WEST {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}

typedef struct {
  const char *name;
  const char *sources;  /* JSON array body */
  const char *extra;    /* more top-level JSON members ("\"sun\": ..."), or "" */
  oc_camera_pose_t pose;
  double step;          /* step factor; 0 → 0.5 */
  uint64_t budget;      /* bytes asked for */
  int max_depth;
  int vdb;              /* the source is the NaN/Inf VDB written first */
  int big;              /* bench only (--big): a multi-GiB budget */
  double t_bound;       /* > 0: the centre pixel's T has a closed form, within this; < 0: the closed
                           form is shown but not bounded (a step longer than the sphere: nothing
                           but finiteness and T in [0, 1] can be promised) */
} st_case_t;

#define MIB (1ull << 20)
static const st_case_t st_cases[] = {
    {"σt 1e-6 m⁻¹ (τ 0.004 across)", SPHERE("1e-6"), "", CAM_WEST, 0, 64 * MIB, 21, 0, 0, 1e-3},
    {"σt 10 m⁻¹ (τ 40 000 across)", SPHERE("10"), "", CAM_WEST, 0, 64 * MIB, 21, 0, 0, 2e-3},
    {"near-vacuum (1e-6) around a dense core (10) in the same bricks",
     SPHERE("1e-6") ",{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":20,\"sigma_t\":10}", "",
     /* 200 m from the core, inside the thin sphere: close enough that the core is resolved (from far
      * the box filter spreads its mass over coarse voxels and its peak τ drops, as it should) */
     {{0.0, -200.0 / (OC_PLANET_RADIUS + 3000.0) * 57.29577951308232, 3000.0}, 90.0, 0.0, 40.0}, 0, 64 * MIB, 21, 0, 0, 2e-3},
    {"step factor 0.01", SPHERE("0.0005"), "", CAM_WEST, 0.01, 64 * MIB, 21, 0, 0, 0.01},
    {"step factor 64", SPHERE("0.0005"), "", CAM_WEST, 64.0, 64 * MIB, 21, 0, 0, -1},
    /* 1 m outside the sphere's western surface, 6 374 km from the planet's centre, depth 21 */
    {"1 m from the surface, depth 21 next to a coarse root", SPHERE("0.0005"), "",
     {{0.0, -2001.0 / (OC_PLANET_RADIUS + 3000.0) * 57.29577951308232, 3000.0}, 90.0, 0.0, 40.0}, 0, 64 * MIB, 21, 0, 0,
     0.01},
    {"sun at the horizon", SPHERE("0.0005"), ",\"sun\":{\"direction\":[0,1,0]}", CAM_WEST, 0, 64 * MIB, 21, 0, 0, 0.01},
    {"sun 5° below the horizon", SPHERE("0.0005"), ",\"sun\":{\"direction\":[-0.0871557,0.9961947,0]}", CAM_WEST, 0,
     64 * MIB, 21, 0, 0, 0.01},
    {"camera in space (1000 km up)", SPHERE("0.0005"), "", {{0.0, -12.0, 1.0e6}, 90.0, -60.0, 60.0}, 0, 64 * MIB, 21, 0,
     0, 0},
    {"camera at ground level (2 m)", SPHERE("0.0005"), "", {{0.0, -0.03, 2.0}, 90.0, 20.0, 60.0}, 0, 64 * MIB, 21, 0, 0,
     0},
    {"camera inside a dense cloud (σt 10)", SPHERE("10"), "", {{0.0, 0.0, 3000.0}, 90.0, 0.0, 60.0}, 0, 64 * MIB, 21, 0,
     0, 2e-3},
    {"the smallest accepted budget", SPHERE("0.0005"), "", CAM_WEST, 0, 1, 21, 0, 0, 0},
    {"a 4 GiB budget", SPHERE("0.0005"), "", CAM_WEST, 0, 4096 * MIB, 21, 0, 1, 0.01},
    {"NaN, ±Inf and negative values in an imported VDB", NULL, "", {{0.0, -0.02, 2500.0}, 90.0, 0.0, 60.0}, 0, 64 * MIB,
     21, 1, 0, 0},
};
enum { ST_NCASES = sizeof st_cases / sizeof st_cases[0] };

/*-*** The server, on a thread of its own ***/

typedef struct {
  ocs_server_t *srv;
  pthread_t th;
} st_server_t;

static void *st_server_run(void *arg) {
  (void)ocs_server_run(arg, 0);
  return NULL;
}

static int st_server_start(st_server_t *s, const oc_scene_t *sc, int threads, char *why, size_t why_len) {
  ocs_server_desc_t d = {.host = "127.0.0.1", .port = 0, .epoch_period = 0, .linger_s = 0,
                         .world = {.threads = threads, .cache_bytes = 256 * MIB}};
  int r = ocs_server_create(&s->srv, sc, &d, why, why_len);
  if (r < 0) return r;
  if (pthread_create(&s->th, NULL, st_server_run, s->srv) != 0) {
    ocs_server_free(s->srv);
    return oc_errorf(OC_EIO, why, why_len, "no thread for the server");
  }
  return 0;
}

static void st_server_stop(st_server_t *s) {
  ocs_server_stop_async(s->srv);
  pthread_join(s->th, NULL);
  ocs_server_free(s->srv);
}

/*-*** The imported data with bad values ***/

/* A 32³ fog volume of density 0.5 (σt 0.01 m⁻¹ after sigma_scale) 1.6 km across, with NaN, +Inf,
 * −Inf and negative values scattered through it: what the importer must count and sanitise. */
static int st_write_bad_vdb(const char *path, char *why, size_t why_len) {
  const ocs_vdb_api_t *api = NULL;
  int r = ocs_vdb_load(&api, why, why_len);
  if (r < 0) return r;
  ocs_vdb_writer_t *w = NULL;
  if ((r = api->writer_create(&w)) < 0) return oc_errorf(r, why, why_len, "vdb writer: out of memory");
  ocs_vdb_grid_desc_t gd = {.name = "density", .klass = OCS_VDB_CLASS_FOG, .voxel_size = 1.0};
  int g = api->writer_add_grid(w, &gd, why, why_len);
  enum { N = 32 };
  static float v[N * N * N];
  for (int i = 0; i < N * N * N; i++) {
    v[i] = 0.5f;
    switch (i % 97) {
      case 3: v[i] = NAN; break;
      case 17: v[i] = INFINITY; break;
      case 29: v[i] = -INFINITY; break;
      case 41: v[i] = -2.0f; break;
      default: break;
    }
  }
  int32_t o[3] = {0, 0, 0}, dims[3] = {N, N, N};
  if (g < 0 || (r = api->writer_set_values(w, g, o, dims, v)) < 0) r = g < 0 ? g : r;
  else r = api->writer_save(w, path, OCS_VDB_COMPRESS_DEFAULT, why, why_len);
  api->writer_free(w);
  return r;
}

/*-*** One case ***/

typedef struct {
  uint32_t leaves, bricks;
  int deepest;
  double granted_mib;
} st_state_info_t;

typedef struct {
  const char *renderer;
  uint64_t nonfinite;
  double t_min, t_max;
  double t_centre, t_exact; /* t_exact < 0: not known */
  int ok;
} st_check_t;

/* What one image says: non-finite values, the transmittance range, the centre pixel. */
static st_check_t st_check(const char *renderer, const oc_image_t *img, double t_exact, double bound) {
  st_check_t c = {renderer, 0, 1e30, -1e30, 0, t_exact, 1};
  size_t n = (size_t)img->w * (size_t)img->h;
  for (size_t i = 0; i < n; i++) {
    const float *p = img->px + 4 * i;
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]) || !isfinite(p[3]) || p[0] < 0 || p[1] < 0 || p[2] < 0) {
      c.nonfinite++;
      continue;
    }
    if (p[3] < c.t_min) c.t_min = p[3];
    if (p[3] > c.t_max) c.t_max = p[3];
  }
  /* the centre ray: the pixel at (w/2, h/2) of an even-sized image is the one whose ray the
   * closed form uses (computed for exactly that pixel in st_exact_t) */
  c.t_centre = img->px[4 * ((size_t)(img->h / 2) * (size_t)img->w + (size_t)(img->w / 2)) + 3];
  c.ok = c.nonfinite == 0 && c.t_min >= 0.0 && c.t_max <= 1.0;
  if (t_exact >= 0.0 && bound > 0 && !(fabs(c.t_centre - t_exact) <= bound)) c.ok = 0;
  return c;
}

/* e^−τ along the ray of pixel (w/2, h/2), τ from the closed-form chords of the scene's analytic
 * sources; −1 when the scene has any other source. */
static double st_exact_t(const oc_scene_t *sc, oc_camera_t cam, int w, int h) {
  ocs_medium_t m;
  if (ocs_scene_medium(sc, &m, NULL, 0) < 0) return -1.0;
  oc_dvec3 dir = oc_camera_ray(&cam, w, h, w / 2, h / 2);
  return exp(-ocs_medium_optical_depth(&m, cam.pos, dir, 1e9));
}

typedef struct {
  int w, h, threads, epochs;
  int want_cpu, want_gl;
  int big;        /* --big */
  const char *md; /* --md */
#ifdef OC_HAVE_GL
  ocv_gl_renderer_t *gl;
#endif
} st_opts_t;

static int st_run_case(const st_case_t *k, const st_opts_t *o, const char *tmpdir, st_state_info_t *info,
                       st_check_t checks[2], int *nchecks, char *why, size_t why_len) {
  char json[4096], vdb_path[1024];
  *nchecks = 0;
  memset(info, 0, sizeof *info);
  if (k->vdb) {
    snprintf(vdb_path, sizeof vdb_path, "%s/bad_values.vdb", tmpdir);
    int r = st_write_bad_vdb(vdb_path, why, why_len);
    if (r < 0) return r;
    snprintf(json, sizeof json,
             "{\"version\":1,\"name\":\"stability\",\"features\":{\"animation\":false},\"sources\":[{\"type\":\"vdb\","
             "\"file\":\"%s\",\"lat\":0,\"lon\":0,\"alt\":2000,\"scale_m\":50,\"sigma_scale\":0.02}]%s}",
             vdb_path, k->extra);
  } else {
    snprintf(json, sizeof json, "{\"version\":1,\"name\":\"stability\",\"features\":{\"animation\":false},\"sources\":[%s]%s}",
             k->sources, k->extra);
  }
  oc_scene_t sc;
  int r = oc_scene_parse(&sc, json, strlen(json), "case", why, why_len);
  if (r < 0) return r;
  st_server_t srv;
  if ((r = st_server_start(&srv, &sc, o->threads, why, why_len)) < 0) {
    oc_scene_free(&sc);
    return r;
  }
  oc_state_t st;
  oc_state_init(&st);
  ocp_welcome_t wl;
  ocv_fetch_desc_t fd = {.host = "127.0.0.1", .port = ocs_server_port(srv.srv), .budget = k->budget,
                         .max_depth = k->max_depth, .width = o->w, .height = o->h, .pose = &k->pose, .step = 1,
                         .epochs = (uint64_t)o->epochs, .timeout_s = 600};
  r = ocv_fetch(&fd, &st, &wl, NULL, why, why_len);
  st_server_stop(&srv);
  if (r < 0) goto out;
  info->leaves = st.node_count;
  info->bricks = st.brick_count;
  info->granted_mib = (double)wl.budget / (double)MIB;
  for (uint32_t i = 0; i < st.node_count; i++)
    if (oc_key_level(st.nodes[i].key) > info->deepest) info->deepest = oc_key_level(st.nodes[i].key);

  oc_atmo_t *atmo = NULL;
  if ((r = oc_scene_atmo(&sc, o->threads, &atmo)) < 0) {
    snprintf(why, why_len, "atmosphere tables: out of memory");
    goto out;
  }
  oc_camera_t cam = oc_camera_from_pose(k->pose);
  oc_render_desc_t d = oc_scene_render_desc(&sc, atmo);
  d.width = o->w;
  d.height = o->h;
  d.camera = cam;
  d.step_factor = k->step > 0 ? k->step : 0.5;
  d.threads = o->threads;
  double t_exact = k->t_bound != 0 ? st_exact_t(&sc, cam, o->w, o->h) : -1.0;
  oc_image_t img = {0};
  if ((r = oc_image_alloc(&img, o->w, o->h)) < 0) goto out_atmo;
  if (o->want_cpu) {
    if ((r = oc_render_state(&st, &d, &img, NULL)) < 0) {
      snprintf(why, why_len, "CPU render refused the case");
      goto out_img;
    }
    checks[(*nchecks)++] = st_check("cpu", &img, t_exact, k->t_bound);
  }
#ifdef OC_HAVE_GL
  if (o->gl) {
    ocv_gl_state_t gs;
    if ((r = ocv_gl_state_upload(&gs, &st, why, why_len)) < 0) goto out_img;
    r = ocv_gl_render_state(o->gl, &gs, &d, &img, why, why_len);
    ocv_gl_state_free(&gs);
    if (r < 0) goto out_img;
    checks[(*nchecks)++] = st_check("gl", &img, t_exact, k->t_bound);
  }
#endif
out_img:
  oc_image_free(&img);
out_atmo:
  oc_atmo_free(atmo);
out:
  oc_state_free(&st);
  oc_scene_free(&sc);
  return r;
}

/*-*** The subcommand ***/

/* --size WxH: even sides 2..4096 (the centre pixel is checked). */
static int opt_even_size(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  st_opts_t *x = base;
  (void)o;
  if (sscanf(text, "%dx%d", &x->w, &x->h) != 2 || x->w < 2 || x->h < 2 || x->w > 4096 || x->h > 4096 || (x->w | x->h) & 1)
    return oc_cli_fail(prog, -1, "--size: expected WxH with even sides 2..4096, got \"%s\"", text);
  return 0;
}

/* --renderer cpu, gl or cpu,gl. */
static int opt_renderers(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  st_opts_t *x = base;
  (void)o;
  x->want_cpu = strstr(text, "cpu") != NULL;
  x->want_gl = strstr(text, "gl") != NULL;
  if (!x->want_cpu && !x->want_gl) return oc_cli_fail(prog, -1, "--renderer: expected cpu, gl or cpu,gl");
  return 0;
}

static const oc_cli_opt_t st_opts[] = {
    {.name = "size", .type = OC_CLI_CUSTOM, .parse = opt_even_size, .arg = "WxH", .def = "64x36",
     .help = "image size; even sides, the centre pixel is checked"},
    {.name = "renderer", .type = OC_CLI_CUSTOM, .parse = opt_renderers, .arg = "LIST",
     .def_note = "cpu,gl when a GL context can be made", .help = "cpu, gl or cpu,gl"},
    OCT_INT(st_opts_t, epochs, "epochs", "N", 1, 100, "3", "states each case waits for"),
    OCT_INT(st_opts_t, threads, "threads", "N", 1, 64, "2", "server producer and CPU render threads"),
    OCT_FLAG(st_opts_t, big, "big", "also the multi-GiB budget case (plans for a 4 GiB viewer)"),
    OCT_STR(st_opts_t, md, "md", "FILE", "also write the table as Markdown"),
    OCT_OPTS_END};

OCT_SPEC(stability,
         "Stiff and extreme cases end to end, each through a server on 127.0.0.1, the wire protocol and the\n"
         "renderers: finite, bounded, known answers.",
         st_opts);

/* One case's rows (to stdout and md); @return the rows that failed. */
static int st_case_rows(const char *prog, const st_case_t *k, int i, st_opts_t *o, const char *tmpdir, FILE *md) {
  char why[2048];
  fprintf(stderr, "\r\033[K%s: stability: case %d/%d: %s ...", prog, i + 1, ST_NCASES, k->name);
  st_state_info_t info;
  st_check_t ch[2];
  int n = 0, failed = 0;
  double t0 = oct_now();
  int r = st_run_case(k, o, tmpdir, &info, ch, &n, why, sizeof why);
  fprintf(stderr, " %.1f s", oct_now() - t0);
  if (r < 0) {
    char line[4096];
    snprintf(line, sizeof line, "| %s | — | — | — | — | — | — | — | — | — | FAILED: %s |\n", k->name, why);
    printf("%s", line);
    if (md) fputs(line, md);
    return 1;
  }
  for (int j = 0; j < n; j++) {
    char exact[64] = "—", line[2048];
    if (ch[j].t_exact >= 0 && k->t_bound > 0) snprintf(exact, sizeof exact, "%.4g (±%g)", ch[j].t_exact, k->t_bound);
    else if (ch[j].t_exact >= 0) snprintf(exact, sizeof exact, "%.4g (not bounded)", ch[j].t_exact);
    snprintf(line, sizeof line, "| %s | %u | %u | %d | %.3g | %s | %llu | %.4g … %.4g | %.4g | %s | %s |\n",
             j ? "″" : k->name, info.leaves, info.bricks, info.deepest, info.granted_mib, ch[j].renderer,
             (unsigned long long)ch[j].nonfinite, ch[j].t_min, ch[j].t_max, ch[j].t_centre, exact,
             ch[j].ok ? "pass" : "FAIL");
    printf("%s", line);
    if (md) fputs(line, md);
    if (!ch[j].ok) failed++;
  }
  fflush(stdout);
  return failed;
}

/* Every case, in a temporary folder; @return the rows that failed, or -1 after printing the error. */
static int st_all(const char *prog, st_opts_t *o) {
  char tmpdir[] = "/tmp/overcast_stability_XXXXXX";
  if (!mkdtemp(tmpdir)) return oc_cli_fail(prog, -1, "cannot make a temporary folder");
  oc_log_set_level(OC_LOG_WARN); /* the servers' connection chatter */
  FILE *md = o->md ? fopen(o->md, "w") : NULL;
  if (o->md && !md) return oc_cli_fail(prog, -1, "%s: cannot create", o->md);
  const char *head = "| case | leaves | bricks | deepest level | granted MiB | renderer | non-finite pixels | T range | "
                     "centre T | closed form | verdict |\n|---|---:|---:|---:|---:|---|---:|---|---:|---:|---|\n";
  printf("%s", head);
  if (md) fputs(head, md);
  int failed = 0;
  for (int i = 0; i < ST_NCASES; i++)
    if (!st_cases[i].big || o->big) failed += st_case_rows(prog, &st_cases[i], i, o, tmpdir, md);
  fprintf(stderr, "\r\033[K");
  if (md) fclose(md);
  char cmd[256];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
  if (system(cmd) != 0) fprintf(stderr, "%s: could not remove %s\n", prog, tmpdir);
  return failed;
}

int oct_bench_stability(const char *prog, int argc, char **argv) {
  st_opts_t o = {.want_cpu = 1, .want_gl = -1};
  int rc = oct_begin(&oct_bench_stability_spec, argc, argv, &o, NULL, NULL, NULL, NULL);
  if (rc != OCT_GO) return rc;
#ifdef OC_HAVE_GL
  char why[2048];
  ocv_gl_context_t *ctx = NULL;
  if (o.want_gl) {
    ctx = ocv_gl_context_init(why, sizeof why);
    if (ctx) o.gl = ocv_gl_renderer_create(why, sizeof why);
    if (!o.gl && o.want_gl == 1) {
      ocv_gl_context_free(ctx);
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s", why);
    }
    if (!o.gl) fprintf(stderr, "%s: stability: no GL renderer (%s): the CPU reference only\n", prog, why);
  }
#else
  if (o.want_gl == 1) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: this build has no GL renderer");
#endif
  int failed = st_all(prog, &o);
#ifdef OC_HAVE_GL
  ocv_gl_renderer_free(o.gl);
  ocv_gl_context_free(ctx);
#endif
  if (failed < 0) return OC_EXIT_RUNTIME;
  if (failed) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "stability: %d row(s) failed", failed);
  printf("\nall cases passed\n");
  return OC_EXIT_OK;
}
