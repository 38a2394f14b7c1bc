/* bench_sweep.c — `overcast-bench sweep`: error against run time over the quality knobs.
 *
 * One run is one scene, a list of views and a grid of knob values: server knobs (memory budget,
 * maximum depth) give a state per view — a fresh world of the server core stepped for --epochs
 * epochs for one viewer at that view (bench_sweep_server.c), each epoch encoded as the server sends
 * it — and render knobs (step factor, multiple-scattering octaves, reprojection, interpolation)
 * render it (bench_sweep_render.c). The grid is the cartesian product of the lists.
 *
 * Error: each image tone-mapped (oc_image_tonemap, exposure 10) against the reference, the highest-
 * quality setting of the grid (the largest budget, the deepest depth, the smallest step factor, the
 * most octaves, reprojection and interpolation off), rendered by the same renderer: RMSE on the
 * 0–255 scale and PSNR per view; a setting's figure pools the views' squared errors (sqrt of the
 * mean MSE). On analytic scenes (only spheres, boxes, slabs) each image's cloud transmittance
 * (alpha) is also compared with the closed form e^−τ along every pixel's ray, τ the exact optical
 * depth of the analytic medium up to the ground (server/analytic.h): mean and max |ΔT|.
 * And against a Monte Carlo truth (bench_sweep_truth.c, --truth-size, --truth-paths): each setting
 * rendered once more in the truth's light, box-averaged to the truth's size, scored with
 * oct_truth_score (image-mean relative error, RMSE 0–255, the truth's own seed-to-seed RMSE);
 * --max-truth-error makes the bench exit 1 past a bound.
 *
 * Cost: render ms (the CPU reference's process CPU time over its threads, which other jobs on a
 * shared machine do not inflate; the GL renderer's GPU timer queries on a GPU, its wall time
 * including the read-back on llvmpipe — the `timer` column; wall and CPU times are in the CSV), the
 * server's process CPU ms per epoch (plan + produce, every producer thread), wire bytes per epoch,
 * and the viewer's resident bytes. Everything but the times is deterministic: no random numbers,
 * no jitter, the world stepped by command.
 *
 * Outputs: a Markdown report on stdout (and --md), --csv (one row per setting × view), --plot (RMSE
 * against render ms with the Pareto front marked). Progress on stderr. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_sweep_int.h"
#include "ocs.h"
#include "ocv.h"
#include "truth.h" /* oct_truth_scale */

#define MAXV 64   /* views */
#define MAXK 16   /* values per knob */
#define EXPOSURE 10.0f

static const char *const onoff[2] = {"off", "on"};

/*-*** Options ***/

typedef struct {
  const char *scene, *views, *path, *csv, *md, *plot, *images;
  const char *cameras[MAXV];
  int ncameras;
  int size[2], plan_size[2], truth_size[2];
  int truth_paths;
  double tau, max_truth_error, max_truth_rmse; /* 0: the scene's σt; no check; no check */
  int gl, threads, repeat, path_n, frames, epochs, srv_threads, ref_exact;
  oct_dlist_t budgets, steps;
  oct_list_t depths, octs, reps, ints; /* octs.n 0: the scene's */
  double motion, interp_t, split, reserve, time;
} sweep_opts_t;

static int opt_camera(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  sweep_opts_t *x = base;
  (void)o;
  if (x->ncameras == MAXV) return oc_cli_fail(prog, -1, "--camera: at most %d", MAXV);
  x->cameras[x->ncameras++] = text;
  return 0;
}

static int opt_onoff(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  oct_list_t *l = oc_cli_field(o, base);
  char buf[128];
  snprintf(buf, sizeof buf, "%s", text);
  l->n = 0;
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (l->n == 2) return oc_cli_fail(prog, -1, "--%s: at most 2 values (off,on)", o->name);
    if (!strcmp(tok, "off") || !strcmp(tok, "0")) l->v[l->n++] = 0;
    else if (!strcmp(tok, "on") || !strcmp(tok, "1")) l->v[l->n++] = 1;
    else return oc_cli_fail(prog, -1, "--%s: expected off or on, got \"%s\"", o->name, tok);
  }
  if (l->n == 0) return oc_cli_fail(prog, -1, "--%s: empty list", o->name);
  return 0;
}

/* A list whose only admissible value is the row's default; anything else is refused with why. */
static int opt_only(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  static const char *const why[2] = {
      "the brick atlas is an RG16UI integer texture (codes with a per-brick range), which GL cannot filter; the "
      "shader reconstructs exactly (trilinear of decoded codes), as the CPU reference does",
      "the server core has one refresh policy (a leaf whose content stamp changed is refreshed, nearest first, "
      "within the budget's reserve; otherwise deferred) and no switch for another"};
  char buf[128];
  (void)base;
  snprintf(buf, sizeof buf, "%s", text);
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save))
    if (strcmp(tok, o->def))
      return oc_cli_fail(prog, -1, "--%s %s: not available: %s", o->name, tok, why[!strcmp(o->name, "refresh")]);
  return 0;
}

static int opt_ref_filter(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  if (strcmp(text, "fast") && strcmp(text, "exact"))
    return oc_cli_fail(prog, -1, "--%s: \"%s\" is not fast or exact", o->name, text);
  *(int *)oc_cli_field(o, base) = !strcmp(text, "exact");
  return 0;
}

#define AT(f) offsetof(sweep_opts_t, f)
#define VIEWS "Views"
#define KNOBS "Knobs (each a list; the grid is their product)"
#define RUN "The runs"
#define OUT "Outputs"
#define TRUTH "Error against a Monte Carlo truth (analytic scenes)"

static const oc_cli_opt_t sweep_opts[] = {
    {.name = "scene", .type = OC_CLI_STRING, .offset = AT(scene), .arg = "FILE",
     .def_note = "the built-in procedural planet", .group = VIEWS, .help = "scene"},
    {.name = "camera", .type = OC_CLI_CUSTOM, .parse = opt_camera, .arg = "LAT,LON,ALT,HEADING,PITCH,FOV",
     .def_note = "the scene's camera", .group = VIEWS, .help = "a view (repeatable)"},
    {.name = "views", .type = OC_CLI_STRING, .offset = AT(views), .arg = "PNG[,PNG..]", .group = VIEWS,
     .help = "views from screenshots' stored cameras (overcast-camera text chunk)"},
    {.name = "path", .type = OC_CLI_STRING, .offset = AT(path), .arg = "FILE", .group = VIEWS,
     .help = "views sampled from a camera path file (overcast-view --record)"},
    {.name = "path-samples", .type = OC_CLI_INT, .offset = AT(path_n), .arg = "N", .lo = 1, .hi = MAXV, .def = "4",
     .group = VIEWS, .help = "poses taken evenly over the path's duration"},
    {.name = "size", .type = OC_CLI_CUSTOM, .parse = oct_opt_size, .offset = AT(size), .arg = "WxH", .def = "160x90",
     .group = VIEWS, .help = "image size"},
    {.name = "plan-size", .type = OC_CLI_CUSTOM, .parse = oct_opt_size, .offset = AT(plan_size), .arg = "WxH",
     .def_note = "--size", .group = VIEWS, .help = "viewport the planner sizes the tree for"},
    {.name = "budgets", .type = OC_CLI_CUSTOM, .parse = oct_opt_doubles, .offset = AT(budgets), .arg = "LIST",
     .lo = 0.0625, .hi = 1 << 20, .def = "1,4,16,64", .group = KNOBS, .help = "viewer budgets in MiB"},
    {.name = "max-depths", .type = OC_CLI_CUSTOM, .parse = oct_opt_list, .offset = AT(depths), .arg = "LIST", .lo = 0,
     .hi = 21, .def = "21", .group = KNOBS, .help = "deepest octree levels"},
    {.name = "step-factors", .type = OC_CLI_CUSTOM, .parse = oct_opt_doubles, .offset = AT(steps), .arg = "LIST",
     .lo = 1e-3, .hi = 1e3, .def = "0.25,0.5,1,2", .group = KNOBS, .help = "step × voxel spacing"},
    {.name = "ms-octaves", .type = OC_CLI_CUSTOM, .parse = oct_opt_list, .offset = AT(octs), .arg = "LIST", .lo = 1,
     .hi = 8, .def_note = "the scene's", .group = KNOBS, .help = "multiple-scattering octaves"},
    {.name = "reprojection", .type = OC_CLI_CUSTOM, .parse = opt_onoff, .offset = AT(reps), .arg = "LIST",
     .def = "off", .group = KNOBS,
     .help = "off,on (gl only): a --frames sequence turning --motion degrees per frame, one pixel in 16 traced; "
             "the last frame is compared"},
    {.name = "interp", .type = OC_CLI_CUSTOM, .parse = opt_onoff, .offset = AT(ints), .arg = "LIST", .def = "off",
     .group = KNOBS, .help = "off,on (gl only): newest state blended with the previous at --interp-t"},
    {.name = "reconstruction", .type = OC_CLI_CUSTOM, .parse = opt_only, .arg = "LIST", .def = "exact",
     .group = KNOBS, .help = "exact only: there is no hardware-filtered path (RG16UI atlas)"},
    {.name = "refresh", .type = OC_CLI_CUSTOM, .parse = opt_only, .arg = "LIST", .def = "stamp", .group = KNOBS,
     .help = "stamp only: the server core has one refresh policy"},
    {.name = "renderer", .type = OC_CLI_CUSTOM, .parse = oct_opt_renderer, .offset = AT(gl), .arg = "cpu|gl",
     .def = "cpu", .group = RUN, .help = "the CPU reference or the GL compute renderer (headless EGL)"},
    {.name = "threads", .type = OC_CLI_INT, .offset = AT(threads), .arg = "N", .lo = 1, .hi = 256, .def = "2",
     .group = RUN,
     .help = "CPU reference threads; its time is process CPU time over all threads (gl: wall time on llvmpipe, "
             "timer queries on a GPU; LP_NUM_THREADS)"},
    {.name = "repeat", .type = OC_CLI_INT, .offset = AT(repeat), .arg = "N", .lo = 1, .hi = 100, .def = "2",
     .group = RUN, .help = "timed renders per setting; the fastest counts"},
    {.name = "frames", .type = OC_CLI_INT, .offset = AT(frames), .arg = "N", .lo = 2, .hi = 1024, .def = "16",
     .group = RUN, .help = "reprojection sequence length"},
    {.name = "motion", .type = OC_CLI_DOUBLE, .offset = AT(motion), .arg = "DEG", .lo = -90, .hi = 90, .def = "0.1",
     .group = RUN, .help = "heading change per frame of the sequence"},
    {.name = "interp-t", .type = OC_CLI_DOUBLE, .offset = AT(interp_t), .arg = "X", .lo = 0, .hi = 1, .def = "0.5",
     .group = RUN, .help = "blend parameter with interpolation on"},
    {.name = "epochs", .type = OC_CLI_INT, .offset = AT(epochs), .arg = "N", .lo = 1, .hi = 1000, .def = "8",
     .group = RUN, .help = "epochs stepped per server setting and view"},
    {.name = "split-fraction", .type = OC_CLI_DOUBLE, .offset = AT(split), .arg = "X", .lo = 0.001, .hi = 1,
     .def = "0.5", .group = RUN, .help = "planner split cap per epoch (0.5 converges in fewer epochs)"},
    {.name = "reserve", .type = OC_CLI_DOUBLE, .offset = AT(reserve), .arg = "X", .lo = 0.001, .hi = 0.5,
     .def = "0.1", .group = RUN, .help = "budget fraction the planner keeps free for change (0.1 is a viewer's)"},
    {.name = "server-threads", .type = OC_CLI_INT, .offset = AT(srv_threads), .arg = "N", .lo = 0, .hi = 64,
     .def_note = "all cores", .group = RUN, .help = "producer threads; 0: all cores"},
    {.name = "time", .type = OC_CLI_DOUBLE, .offset = AT(time), .arg = "T", .lo = -1e12, .hi = 1e12, .def = "0",
     .group = RUN, .help = "world time at epoch 0, s"},
    {.name = "reference-filter", .type = OC_CLI_CUSTOM, .parse = opt_ref_filter, .offset = AT(ref_exact),
     .arg = "fast|exact", .def = "fast", .group = RUN,
     .help = "the reference image's bricks from the sources' fast box filter (as every setting's) or their "
             "exact one (a server run of its own at the reference's budget and depth): the RMSE column is then "
             "each setting's error against the exact filter, the fast filter's included"},
    {.name = "tau", .type = OC_CLI_DOUBLE, .offset = AT(tau), .arg = "T", .lo = 1e-6, .hi = 1e4,
     .def_note = "the scene's σt", .group = TRUTH,
     .help = "analytic scenes: every source's σt scaled so that the first has optical depth T across (sphere "
             "diameter, box or slab height), as `overcast-bench truth --tau`"},
    {.name = "truth-size", .type = OC_CLI_CUSTOM, .parse = oct_opt_size, .offset = AT(truth_size), .arg = "WxH",
     .def = "32x18", .group = TRUTH, .help = "the Monte Carlo truth's size; --size must be a multiple of it"},
    {.name = "truth-paths", .type = OC_CLI_INT, .offset = AT(truth_paths), .arg = "N", .lo = 0, .hi = 100000000,
     .def = "256", .group = TRUTH, .help = "paths per truth pixel; 0: no truth column"},
    {.name = "max-truth-error", .type = OC_CLI_DOUBLE, .offset = AT(max_truth_error), .arg = "PCT", .lo = 1e-9,
     .hi = 1e9, .group = TRUTH,
     .help = "exit 1 unless every setting's image mean is within PCT % of the truth's (a positive, finite truth)"},
    {.name = "max-truth-rmse", .type = OC_CLI_DOUBLE, .offset = AT(max_truth_rmse), .arg = "X", .lo = 1e-9, .hi = 255,
     .group = TRUTH, .help = "exit 1 unless every setting's RMSE 0–255 against the truth is at most X"},
    {.name = "csv", .type = OC_CLI_STRING, .offset = AT(csv), .arg = "FILE", .group = OUT,
     .help = "one row per setting and view"},
    {.name = "md", .type = OC_CLI_STRING, .offset = AT(md), .arg = "FILE", .group = OUT,
     .help = "the Markdown report (Table 6.1 form: budget × step factor → ms / RMSE)"},
    {.name = "plot", .type = OC_CLI_STRING, .offset = AT(plot), .arg = "FILE.png", .group = OUT,
     .help = "RMSE against render ms, Pareto front marked"},
    {.name = "images", .type = OC_CLI_STRING, .offset = AT(images), .arg = "DIR", .group = OUT,
     .help = "also every image as a PNG (camera in its text chunk), the reference's too"},
    {.name = "help", .type = OC_CLI_HELP, .group = OUT, .help = "print this and exit"},
    {0}};

const oc_cli_spec_t oct_bench_sweep_spec = {
    .prog = "overcast-bench sweep",
    .about = "Error against run time: quality knobs swept, RMSE/PSNR against the best setting (and on analytic\n"
             "scenes against a Monte Carlo truth). The grid is the product of the lists; the reference is its\n"
             "highest-quality setting; outputs a Markdown report on stdout, progress on stderr.\n",
    .opts = sweep_opts};

/* The checks between options; 0, or -1 after printing the error. */
static int sweep_check(const char *prog, sweep_opts_t *o) {
  if (!o->plan_size[0]) o->plan_size[0] = o->size[0], o->plan_size[1] = o->size[1];
  if (!o->gl && (o->reps.v[o->reps.n - 1] || o->reps.v[0] || o->ints.v[0] || o->ints.v[o->ints.n - 1]))
    return oc_cli_fail(prog, -1, "--reprojection on and --interp on need --renderer gl (the CPU reference has neither)");
  if (o->path && (o->ncameras || o->views))
    return oc_cli_fail(prog, -1, "--path gives the views: no --camera or --views with it");
#ifndef OC_HAVE_GL
  if (o->path) return oc_cli_fail(prog, -1, "--path: this build has no client library (camera paths)");
#endif
  if ((o->max_truth_error > 0.0 || o->max_truth_rmse > 0.0) && o->truth_paths == 0)
    return oc_cli_fail(prog, -1, "--max-truth-error and --max-truth-rmse need the truth (--truth-paths > 0)");
  return 0;
}

typedef struct {
  oc_camera_pose_t pose;
  char name[96];
} view_t;

static int add_view(const char *prog, view_t *v, int *nv, oc_camera_pose_t pose, const char *name) {
  if (*nv == MAXV) return oc_cli_fail(prog, -1, "at most %d views", MAXV);
  v[*nv].pose = pose;
  snprintf(v[*nv].name, sizeof v[*nv].name, "%s", name);
  (*nv)++;
  return 0;
}

/*-*** Results ***/

typedef struct { /* one server setting at one view */
  double cpu_ms, cpu_last, wall_ms, wire, wire_last;
  uint64_t resident;
  uint32_t nodes, bricks, sent;
} srv_t;

typedef struct { /* one setting at one view */
  double ms, wall, cpu, mse, dt_mean, dt_max;
  octs_truth_err_t t; /* against the Monte Carlo truth (analytic scenes, --truth-paths > 0) */
} cell_t;

typedef struct { /* one setting over the views */
  int s, r;      /* server and render setting */
  int b, d, st, o, rp, ip; /* knob indices */
  double ms, rmse, psnr, cpu_ms, wall_ms, wire, resident, dt_mean, dt_max;
  double t_rel, t_rmse8, t_noise8; /* against the truth: mean relative error, RMSEs pooled over the views */
  int pareto, reference;
} agg_t;

static double psnr_of(double rmse) { return rmse > 0.0 ? 20.0 * log10(255.0 / rmse) : INFINITY; }

static const char *fmt_psnr(double p, char *buf, size_t cap) {
  if (isinf(p)) snprintf(buf, cap, "inf");
  else snprintf(buf, cap, "%.2f", p);
  return buf;
}

/* The first positive hit of the ray with the ground sphere, or INFINITY. */
static double ground_hit(oc_dvec3 o, oc_dvec3 d, double R) {
  double lo = oc_dlen(o), b = oc_ddot(o, d), c = (lo - R) * (lo + R), disc = b * b - c;
  if (c < 0.0 || disc < 0.0) return INFINITY;
  double t = -b - sqrt(disc);
  return t > 0.0 ? t : INFINITY;
}

/* DIR/NAME_vN.png with the camera in its text chunk (what overcast-view --camera-from reads). */
static int write_image(const char *dir, const char *name, int v, oc_camera_pose_t pose, int w, int h, const uint8_t *rgb, char *why,
                       size_t why_len) {
  char path[1024], cam[160];
  snprintf(path, sizeof path, "%s/%s_v%d.png", dir, name, v + 1);
  oc_camera_format(pose, cam, sizeof cam);
  oc_png_text_t text[1] = {{"overcast-camera", cam}};
  return oc_png_write(path, w, h, rgb, text, 1, why, why_len);
}

/*-*** Progress ***/

typedef struct {
  const char *prog;
  char head[160];
  int tty; /* epoch by epoch only on a terminal (a log keeps one line per server setting) */
} progress_t;

static void server_progress(void *ctx, int e, int n) {
  progress_t *p = ctx;
  if (!p->tty) return;
  fprintf(stderr, "\r%s: %s: epoch %d/%d ", p->prog, p->head, e, n);
  fflush(stderr);
}

/*-*** Report ***/

typedef struct {
  const char *prog, *scene_name, *renderer_info, *timer, *cmdline;
  int w, h, pw, ph, nv, epochs, threads, frames, repeat;
  double motion, interp_t, split, reserve;
  const view_t *views;
  double budgets[MAXK], steps[MAXK];
  long depths[MAXK], octs[MAXK], reps[2], ints[2];
  int nb, nd, ns, no, nr, ni;
  int analytic;
  int truth, tw, th, tpaths; /* the truth column: on, its size and paths per pixel */
  double tau;                /* --tau, 0: the scene's */
  int ref_exact;
  const agg_t *agg;
  int nagg;
} report_t;

static const agg_t *find_agg(const report_t *R, int b, int d, int st, int o, int rp, int ip) {
  for (int i = 0; i < R->nagg; i++) {
    const agg_t *a = &R->agg[i];
    if (a->b == b && a->d == d && a->st == st && a->o == o && a->rp == rp && a->ip == ip) return a;
  }
  return NULL;
}

static void write_report(FILE *f, const report_t *R) {
  char pb[32];
  fprintf(f, "Command: `%s`\n\n", R->cmdline);
  const char *tdesc = !strcmp(R->timer, "cpu-ref")         ? "the CPU reference renderer's process CPU time summed over its "
                                                             "threads (wall time, which other jobs inflate, is in the CSV)"
                      : !strcmp(R->timer, "llvmpipe-wall") ? "wall time of the GL dispatch and read-back on llvmpipe "
                                                             "(software; CPU time in the CSV)"
                                                           : "GPU timer queries of the trace (and reprojection) passes";
  fprintf(f, "Scene `%s`, %d view%s, %dx%d (planner viewport %dx%d), renderer: %s. Render ms: `%s`, %s, best of %d%s. "
             "Server CPU ms and KiB per epoch: mean over %d epochs from an empty viewer (build-up included; split "
             "fraction %g, reserve %g); CPU is process time of the world step (plan + produce, all producer threads); KiB are the "
             "epoch as encoded for the wire (zstd, deltas). Resident: the viewer's kept states after the last epoch.\n\n",
          R->scene_name, R->nv, R->nv == 1 ? "" : "s", R->w, R->h, R->pw, R->ph, R->renderer_info, R->timer, tdesc, R->repeat,
          R->nr > 1 || R->reps[0] ? " (reprojection on: the mean frame of the sequence after the first)" : "", R->epochs, R->split,
          R->reserve);
  if (R->nr > 1 || R->reps[0])
    fprintf(f, "Reprojection: %d frames turning %g° of heading per frame and ending at the view; frame 0 traces every pixel, "
               "the others one in 16; the last frame is compared.\n\n",
            R->frames, R->motion);
  if (R->ni > 1 || R->ints[0])
    fprintf(f, "Interpolation: the last epoch's state blended with the one before at t = %g (client/interp.h previous "
               "values); the reference shows the last state alone.\n\n",
            R->interp_t);
  fprintf(f, "Views:");
  for (int v = 0; v < R->nv; v++) {
    char cam[160];
    oc_camera_format(R->views[v].pose, cam, sizeof cam);
    fprintf(f, "%s `%s` (%s)", v ? ";" : "", R->views[v].name, cam);
  }
  fprintf(f, ".\n\n");
  const agg_t *ref = NULL;
  for (int i = 0; i < R->nagg; i++)
    if (R->agg[i].reference) ref = &R->agg[i];
  fprintf(f, "Reference (the highest-quality setting): budget %g MiB, depth %ld, step factor %g, %ld octave%s, "
             "reprojection off, interpolation off, bricks from the %s box filter",
          R->budgets[0], R->depths[0], R->steps[0], R->octs[0], R->octs[0] == 1 ? "" : "s",
          R->ref_exact ? "sources' exact" : "same fast");
  if (ref) fprintf(f, " — %.1f ms a frame%s", ref->ms, R->ref_exact ? " (its fast-filter twin's time)" : "");
  if (R->ref_exact) fprintf(f, "; every setting's bricks come from the fast filter, so its RMSE includes the fast filter's error");
  fprintf(f, ". Not swept: sample reconstruction (exact trilinear only: the RG16UI code atlas cannot be hardware "
             "filtered) and the server refresh policy (the core has one: stamp-driven, nearest first).\n\n");

  if (R->analytic)
    fprintf(f, "Closed form (analytic scene): mean and max |ΔT| of each image's cloud transmittance (alpha) against e^−τ, "
               "τ the exact optical depth of the medium along the pixel's ray up to the ground (server/analytic.h); "
               "the max comes from pixels grazing a surface, which the box-filtered voxels soften over a voxel.\n\n");
  if (R->truth)
    fprintf(f, "Against the truth (analytic scene%s): a Monte Carlo image per view (`overcast-bench truth`'s kernel, every "
               "scattering order, %d paths per pixel at %dx%d, through a state voxelized from the analytic sources, not the "
               "swept ones) in the truth's light — a delta sun of irradiance 1, constant background 0, no atmosphere, no "
               "planet — in which each setting is rendered once more for this column (its own image has the sky and "
               "ground); that image box-averaged to %dx%d. Mean error: the image mean's relative error (mean over the "
               "views); RMSE 0–255 at exposure 10; truth noise: the RMSE two truth seeds would show. The model's known "
               "errors against the truth are in docs/numerics.md.\n\n",
            R->tau > 0.0 ? ", σt scaled to --tau" : "", R->tpaths, R->tw, R->th, R->tw, R->th);
  else
    fprintf(f, "Against the truth: — (%s).\n\n", R->analytic ? "--truth-paths 0" : "not an analytic scene");

  /* Table 6.1 form: one table per combination of the other knobs (when budget × step is a grid) */
  for (int d = 0; d < R->nd && R->nb * R->ns > 1; d++)
    for (int o = 0; o < R->no; o++)
      for (int rp = 0; rp < R->nr; rp++)
        for (int ip = 0; ip < R->ni; ip++) {
          fprintf(f, "**Render ms / RMSE (0–255) against the best setting / against the Monte Carlo truth (at %dx%d)** — "
                     "depth %ld, %ld octave%s, reprojection %s, interpolation %s:\n\n",
                  R->tw, R->th, R->depths[d], R->octs[o], R->octs[o] == 1 ? "" : "s", onoff[R->reps[rp]], onoff[R->ints[ip]]);
          fprintf(f, "| budget \\ step factor |");
          for (int s = 0; s < R->ns; s++) fprintf(f, " %g |", R->steps[s]);
          fprintf(f, " server CPU ms/epoch | KiB/epoch | resident MiB |\n|---|");
          for (int s = 0; s < R->ns; s++) fprintf(f, "---:|");
          fprintf(f, "---:|---:|---:|\n");
          for (int b = 0; b < R->nb; b++) {
            fprintf(f, "| %g MiB |", R->budgets[b]);
            const agg_t *any = NULL;
            for (int s = 0; s < R->ns; s++) {
              const agg_t *a = find_agg(R, b, d, s, o, rp, ip);
              if (!a) {
                fprintf(f, " — |");
                continue;
              }
              any = a;
              char tb[32] = "—";
              if (R->truth) snprintf(tb, sizeof tb, "%.2f", a->t_rmse8);
              fprintf(f, " %s%.1f / %.2f / %s%s |", a->pareto ? "**" : "", a->ms, a->rmse, tb, a->pareto ? "**" : "");
            }
            if (any)
              fprintf(f, " %.0f | %.1f | %.2f |\n", any->cpu_ms, any->wire / 1024.0, any->resident / 1048576.0);
            else
              fprintf(f, " — | — | — |\n");
          }
          fprintf(f, "\n");
        }
  if (R->nb * R->ns > 1)
    fprintf(f, "Bold: on the Pareto front of render ms against RMSE (no setting is both faster and closer).\n\n");

  /* every setting */
  fprintf(f, "| budget MiB | depth | step | octaves | reproj. | interp. | render ms | server CPU ms/epoch | KiB/epoch | "
             "resident MiB | RMSE | PSNR dB |%s truth: mean error | truth: RMSE | truth noise | Pareto |\n",
          R->analytic ? " mean abs ΔT | max abs ΔT |" : "");
  fprintf(f, "|---:|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|%s---:|---:|---:|---|\n",
          R->analytic ? "---:|---:|" : "");
  for (int i = 0; i < R->nagg; i++) {
    const agg_t *a = &R->agg[i];
    fprintf(f, "| %g | %ld | %g | %ld | %s | %s | %.1f | %.0f | %.1f | %.2f | %.2f | %s |", R->budgets[a->b], R->depths[a->d],
            R->steps[a->st], R->octs[a->o], onoff[R->reps[a->rp]], onoff[R->ints[a->ip]], a->ms, a->cpu_ms, a->wire / 1024.0,
            a->resident / 1048576.0, a->rmse, fmt_psnr(a->psnr, pb, sizeof pb));
    if (R->analytic) fprintf(f, " %.4f | %.4f |", a->dt_mean, a->dt_max);
    if (R->truth) fprintf(f, " %+.1f %% | %.2f | %.2f |", 100.0 * a->t_rel, a->t_rmse8, a->t_noise8);
    else fprintf(f, " — | — | — |");
    fprintf(f, " %s |\n", a->reference ? "reference" : a->pareto ? "yes" : "");
  }
  fprintf(f, "\n");
}

/*-*** The subcommand ***/

typedef struct {
  const char *prog;
  const sweep_opts_t *o;
  report_t R;
  oc_scene_t *sc;
  view_t *views;
  int nv, S, RS, done;
  oc_atmo_t *atmo;
  octs_renderer_t *ren;
  char rinfo[512];
  float *truth;      /* per view: e^−τ of each pixel's ray (analytic scenes) */
  octs_truth_t *mc[MAXV]; /* per view: the Monte Carlo truth (analytic scenes, --truth-paths > 0) */
  uint8_t *ref_rgb;  /* per view: the reference image */
  uint8_t *rgb;
  srv_t *srv;
  cell_t *cell;
  agg_t *agg;
  oc_image_t img;
  double t_start;
} sweep_t;

/* The views: --camera, --views, --path, or the scene's camera. @return 0 or the exit status. */
static int sweep_views(sweep_t *W) {
  const sweep_opts_t *o = W->o;
  const char *prog = W->prog;
  char why[1024];
  for (int i = 0; i < o->ncameras; i++) {
    oc_camera_pose_t pose;
    char name[32];
    if (oc_camera_parse(o->cameras[i], &pose, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
    snprintf(name, sizeof name, "camera %d", i + 1);
    if (add_view(prog, W->views, &W->nv, pose, name)) return OC_EXIT_USAGE;
  }
  if (o->views) {
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", o->views);
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
      int iw, ih;
      uint8_t *px = NULL;
      char text[256] = "";
      oc_camera_pose_t pose;
      if (oc_png_read(tok, &iw, &ih, &px, "overcast-camera", text, sizeof text, why, sizeof why) < 0)
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views: %s", why);
      free(px);
      if (!text[0]) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views %s: no overcast-camera text chunk", tok);
      if (oc_camera_parse(text, &pose, why, sizeof why) < 0)
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views %s: %s", tok, why);
      const char *base = strrchr(tok, '/');
      if (add_view(prog, W->views, &W->nv, pose, base ? base + 1 : tok)) return OC_EXIT_USAGE;
    }
  }
#ifdef OC_HAVE_GL
  if (o->path) {
    ocv_path_t path;
    ocv_path_init(&path);
    if (ocv_path_load(&path, o->path, why, sizeof why) < 0 || path.count == 0) {
      ocv_path_free(&path);
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--path: %s", path.count ? why : "no poses");
    }
    double dur = ocv_path_duration(&path), t0 = path.t[0];
    for (long i = 0; i < o->path_n; i++) {
      double t = o->path_n == 1 ? t0 : t0 + (dur - t0) * (double)i / (double)(o->path_n - 1);
      oc_camera_pose_t pose;
      char name[48];
      ocv_path_sample(&path, t, &pose);
      snprintf(name, sizeof name, "path t=%.2f s", t);
      add_view(prog, W->views, &W->nv, pose, name);
    }
    ocv_path_free(&path);
  }
#endif
  if (W->nv == 0) {
    oc_camera_pose_t pose = {W->sc->camera.pos, W->sc->camera.heading, W->sc->camera.pitch, W->sc->camera.fov};
    add_view(prog, W->views, &W->nv, pose, "scene camera");
  }
  return 0;
}

static int desc_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x < y) - (x > y);
}
static int asc_d(const void *a, const void *b) { return desc_d(b, a); }
static int desc_l(const void *a, const void *b) {
  long x = *(const long *)a, y = *(const long *)b;
  return (x < y) - (x > y);
}

/* The knob lists into the report, reordered so that the reference (the best of every knob) comes
 * first: budgets and depths descending, steps ascending, octaves descending, off before on. */
static void sweep_knobs(sweep_t *W) {
  const sweep_opts_t *o = W->o;
  report_t *R = &W->R;
  _Static_assert(OCT_LIST_MAX == MAXK, "the knob lists hold MAXK values");
  memcpy(R->budgets, o->budgets.v, sizeof R->budgets), R->nb = o->budgets.n;
  memcpy(R->depths, o->depths.v, sizeof R->depths), R->nd = o->depths.n;
  memcpy(R->steps, o->steps.v, sizeof R->steps), R->ns = o->steps.n;
  memcpy(R->octs, o->octs.v, sizeof R->octs), R->no = o->octs.n;
  memcpy(R->reps, o->reps.v, sizeof R->reps), R->nr = o->reps.n;
  memcpy(R->ints, o->ints.v, sizeof R->ints), R->ni = o->ints.n;
  if (!R->no) {
    R->octs[0] = oc_scene_has(W->sc, OC_FEATURE_MULTIPLE_SCATTERING) ? W->sc->optics.ms_octaves : 1;
    R->no = 1;
  }
  qsort(R->budgets, (size_t)R->nb, sizeof *R->budgets, desc_d);
  qsort(R->depths, (size_t)R->nd, sizeof *R->depths, desc_l);
  qsort(R->steps, (size_t)R->ns, sizeof *R->steps, asc_d);
  qsort(R->octs, (size_t)R->no, sizeof *R->octs, desc_l);
  if (R->nr == 2 && R->reps[0]) R->reps[0] = 0, R->reps[1] = 1;
  if (R->ni == 2 && R->ints[0]) R->ints[0] = 0, R->ints[1] = 1;
}

/* The atmosphere tables, the renderer, the buffers, the closed form. */
static int sweep_open(sweep_t *W) {
  const sweep_opts_t *o = W->o;
  const int w = o->size[0], h = o->size[1];
  char why[1024];
  if (oc_scene_has(W->sc, OC_FEATURE_ATMOSPHERE)) {
    ocg_atmosphere ap;
    oc_atmo_params_default(&ap);
    if (!oc_scene_has(W->sc, OC_FEATURE_OZONE)) ap.ozone_absorption = ocg_v3s(0.0f);
    if (!(W->atmo = oc_atmo_create(&ap, o->threads)))
      return oc_cli_fail(W->prog, -1, "could not build the atmosphere tables");
  }
  octs_render_desc_t rd = {w, h, o->threads, o->repeat, o->frames, o->motion, (float)o->interp_t, W->sc, W->atmo};
  if (!(W->ren = octs_renderer_open(o->gl, &rd, W->rinfo, sizeof W->rinfo, why, sizeof why)))
    return oc_cli_fail(W->prog, -1, "--renderer %s: %s", o->gl ? "gl" : "cpu", why);
  ocs_medium_t medium;
  W->R.analytic = ocs_scene_medium(W->sc, &medium, NULL, 0) == 0;
  size_t npx = (size_t)w * (size_t)h, nv = (size_t)W->nv;
  W->S = W->R.nb * W->R.nd, W->RS = W->R.ns * W->R.no * W->R.nr * W->R.ni;
  W->srv = calloc((size_t)W->S * nv, sizeof *W->srv);
  W->cell = calloc((size_t)W->S * W->RS * nv, sizeof *W->cell);
  W->agg = calloc((size_t)W->S * W->RS, sizeof *W->agg);
  W->ref_rgb = malloc(npx * 3 * nv);
  W->rgb = malloc(npx * 3);
  if (W->R.analytic) W->truth = malloc(sizeof *W->truth * npx * nv);
  if (!W->srv || !W->cell || !W->agg || !W->ref_rgb || !W->rgb || (W->R.analytic && !W->truth) ||
      oc_image_alloc(&W->img, w, h) < 0)
    return oc_cli_fail(W->prog, -1, "out of memory");
  if (!W->R.analytic && (o->max_truth_error > 0.0 || o->max_truth_rmse > 0.0))
    return oc_cli_fail(W->prog, -1, "--max-truth-error, --max-truth-rmse: no truth (not an analytic scene)");
  if (!W->R.analytic) return 0;
  W->R.truth = o->truth_paths > 0;
  octs_truth_desc_t td = {o->truth_size[0], o->truth_size[1], w, h, o->truth_paths, o->threads};
  for (int v = 0; v < W->nv && W->R.truth; v++) {
    double t0 = oct_now();
    if (!(W->mc[v] = octs_truth_make(W->sc, W->views[v].pose, &td, why, sizeof why)))
      return oc_cli_fail(W->prog, -1, "--truth-size, --truth-paths: %s", why);
    fprintf(stderr, "%s: Monte Carlo truth, view %d/%d: %dx%d, %d paths per pixel ... %.1f s\n", W->prog, v + 1, W->nv,
            td.w, td.h, o->truth_paths, oct_now() - t0);
  }
  int ground = oc_scene_has(W->sc, OC_FEATURE_PLANET_SURFACE);
  for (int v = 0; v < W->nv; v++) {
    oc_camera_t cam = oc_camera_from_pose(W->views[v].pose);
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        oc_dvec3 dir = oc_camera_ray(&cam, w, h, x, y);
        double tmax = ground ? ground_hit(cam.pos, dir, OC_PLANET_RADIUS) : INFINITY;
        W->truth[(size_t)v * npx + (size_t)y * w + x] = (float)exp(-ocs_medium_optical_depth(&medium, cam.pos, dir, tmax));
      }
  }
  return 0;
}

static void sweep_close(sweep_t *W) {
  oc_image_free(&W->img);
  free(W->truth);
  for (int v = 0; v < W->nv; v++) octs_truth_free(W->mc[v]);
  free(W->ref_rgb);
  free(W->rgb);
  free(W->srv);
  free(W->cell);
  free(W->agg);
  octs_renderer_close(W->ren);
  oc_atmo_free(W->atmo);
}

/* The reference image of view v (the renderer holds server setting 0's states, so): with
 * --reference-filter exact, from a server run of its own. */
static int sweep_reference(sweep_t *W, int v, octs_server_desc_t sd, const octs_server_out_t *so, progress_t *pg) {
  const sweep_opts_t *o = W->o;
  const char *prog = W->prog;
  const size_t npx = (size_t)o->size[0] * (size_t)o->size[1];
  octs_render_knobs_t k = {W->R.steps[0], (int)W->R.octs[0], 0, 0, 0};
  octs_times_t tm;
  octs_server_out_t ro; /* --reference-filter exact: the same setting, bricks from the exact filter */
  char why[1024];
  int r;
  if (o->ref_exact) {
    sd.exact_filter = 1;
    snprintf(pg->head, sizeof pg->head, "reference (exact filter), view %d/%d", v + 1, W->nv);
    if ((r = octs_server_run(W->sc, &sd, W->views[v].pose, &ro, server_progress, pg, why, sizeof why)) < 0 ||
        (r = octs_renderer_set_states(W->ren, &ro.newest, &ro.prev, ro.animated, why, sizeof why)) < 0)
      return oc_cli_fail(prog, -1, "%s: %s", pg->head, why);
    fprintf(stderr, "%s%s: %s: %u nodes, %u bricks ... done\n", pg->tty ? "\r\033[K" : "", prog, pg->head,
            ro.newest.node_count, ro.newest.brick_count);
  }
  r = octs_render(W->ren, W->views[v].pose, &k, &W->img, &tm, why, sizeof why);
  if (o->ref_exact) {
    int r2 = octs_renderer_set_states(W->ren, &so->newest, &so->prev, so->animated, why, sizeof why);
    octs_server_out_free(&ro);
    if (r >= 0) r = r2;
  }
  if (r < 0) return oc_cli_fail(prog, -1, "reference, view %d: %s", v + 1, why);
  uint8_t *ref = W->ref_rgb + (size_t)v * npx * 3;
  oc_image_tonemap(&W->img, EXPOSURE, ref);
  if (o->images && write_image(o->images, "reference", v, W->views[v].pose, o->size[0], o->size[1], ref, why, sizeof why) < 0)
    return oc_cli_fail(prog, -1, "--images: %s", why);
  return 0;
}

/* Render setting rs of server setting s at view v: rendered, timed, compared. */
static int sweep_cell(sweep_t *W, int s, int rs, int v) {
  const sweep_opts_t *o = W->o;
  const report_t *R = &W->R;
  const char *prog = W->prog;
  const int w = o->size[0], h = o->size[1];
  const size_t npx = (size_t)w * (size_t)h;
  int b = s / R->nd, d = s % R->nd;
  int ip = rs % R->ni, rp = rs / R->ni % R->nr, oc = rs / (R->ni * R->nr) % R->no, st = rs / (R->ni * R->nr * R->no);
  octs_render_knobs_t k = {R->steps[st], (int)R->octs[oc], (int)R->reps[rp], (int)R->ints[ip], 0};
  octs_times_t tm;
  char why[1024];
  double t1 = oct_now();
  if (octs_render(W->ren, W->views[v].pose, &k, &W->img, &tm, why, sizeof why) < 0)
    return oc_cli_fail(prog, -1, "render: %s", why);
  int bad = oc_image_tonemap(&W->img, EXPOSURE, W->rgb);
  if (bad) return oc_cli_fail(prog, -1, "render: %d non-finite pixels", bad);
  if (o->images) {
    char name[128];
    snprintf(name, sizeof name, "b%g_d%ld_s%g_o%ld_r%ld_i%ld", R->budgets[b], R->depths[d], R->steps[st], R->octs[oc],
             R->reps[rp], R->ints[ip]);
    if (write_image(o->images, name, v, W->views[v].pose, w, h, W->rgb, why, sizeof why) < 0)
      return oc_cli_fail(prog, -1, "--images: %s", why);
  }
  cell_t *ce = &W->cell[((size_t)s * W->RS + rs) * W->nv + v];
  double e = oc_rgb8_rmse(W->rgb, W->ref_rgb + (size_t)v * npx * 3, w, h);
  ce->ms = tm.ms, ce->wall = tm.wall, ce->cpu = tm.cpu;
  ce->mse = e * e;
  if (R->analytic) {
    double sum = 0.0, mx = 0.0;
    const float *tv = W->truth + (size_t)v * npx;
    for (size_t i = 0; i < npx; i++) {
      double dd = fabs((double)W->img.px[4 * i + 3] - tv[i]);
      sum += dd;
      mx = fmax(mx, dd);
    }
    ce->dt_mean = sum / (double)npx;
    ce->dt_max = mx;
  }
  if (W->mc[v]) { /* once more in the truth's light (not timed) */
    k.truth_light = 1;
    octs_times_t tt;
    if (octs_render(W->ren, W->views[v].pose, &k, &W->img, &tt, why, sizeof why) < 0)
      return oc_cli_fail(prog, -1, "render in the truth's light: %s", why);
    if (octs_truth_score(W->mc[v], &W->img, &ce->t) < 0) return oc_cli_fail(prog, -1, "out of memory");
  }
  W->done++;
  fprintf(stderr, "%s: setting %d/%d: budget %g MiB, depth %ld, step %g, octaves %ld, reprojection %s, interpolation %s, "
                  "view %d/%d: %.1f ms (%s), RMSE %.3f ... %.1f s (%.0f s in all)\n",
          prog, W->done, W->S * W->RS * W->nv, R->budgets[b], R->depths[d], R->steps[st], R->octs[oc], onoff[R->reps[rp]],
          onoff[R->ints[ip]], v + 1, W->nv, tm.ms, octs_renderer_timer(W->ren), e, oct_now() - t1, oct_now() - W->t_start);
  return 0;
}

/* Server setting s at view v: the states, then (s = 0) the reference, then every render setting. */
static int sweep_server(sweep_t *W, int s, int v) {
  const sweep_opts_t *o = W->o;
  const report_t *R = &W->R;
  const char *prog = W->prog;
  int b = s / R->nd, d = s % R->nd;
  char why[1024];
  progress_t pg = {prog, "", isatty(fileno(stderr))};
  snprintf(pg.head, sizeof pg.head, "server %d/%d: budget %g MiB, depth %ld, view %d/%d", s + 1, W->S, R->budgets[b],
           R->depths[d], v + 1, W->nv);
  octs_server_desc_t sd = {(uint64_t)(R->budgets[b] * 1048576.0), (int)R->depths[d], o->epochs, o->srv_threads,
                           o->split, o->reserve, o->time, o->plan_size[0], o->plan_size[1], 0};
  octs_server_out_t so;
  double t0 = oct_now();
  if (octs_server_run(W->sc, &sd, W->views[v].pose, &so, server_progress, &pg, why, sizeof why) < 0) {
    if (pg.tty) fprintf(stderr, "\n");
    return oc_cli_fail(prog, -1, "%s: %s", pg.head, why);
  }
  srv_t *sv = &W->srv[(size_t)s * W->nv + v];
  *sv = (srv_t){so.cpu_ms_mean, so.cpu_ms_last, so.wall_ms_mean, so.wire_mean, so.wire_last, so.resident,
                so.newest.node_count, so.newest.brick_count, so.bricks_sent};
  fprintf(stderr, "%s%s: %s: %u nodes, %u bricks, %.2f MiB resident, %.0f ms CPU and %.1f KiB an epoch ... %.1f s\n",
          pg.tty ? "\r\033[K" : "", prog, pg.head, sv->nodes, sv->bricks, sv->resident / 1048576.0, sv->cpu_ms,
          sv->wire / 1024.0, oct_now() - t0);
  int rc = 0;
  if (octs_renderer_set_states(W->ren, &so.newest, &so.prev, so.animated, why, sizeof why) < 0)
    rc = oc_cli_fail(prog, -1, "%s: %s", pg.head, why);
  if (!rc && s == 0) rc = sweep_reference(W, v, sd, &so, &pg);
  for (int rs = 0; rs < W->RS && !rc; rs++) rc = sweep_cell(W, s, rs, v);
  octs_server_out_free(&so);
  return rc;
}

/* Aggregates over the views, and the Pareto front. */
static void sweep_aggregate(sweep_t *W) {
  report_t *R = &W->R;
  const int nv = W->nv, RS = W->RS;
  int na = 0;
  for (int s = 0; s < W->S; s++)
    for (int rs = 0; rs < RS; rs++) {
      agg_t *a = &W->agg[na++];
      a->s = s, a->r = rs;
      a->b = s / R->nd, a->d = s % R->nd;
      a->ip = rs % R->ni, a->rp = rs / R->ni % R->nr, a->o = rs / (R->ni * R->nr) % R->no, a->st = rs / (R->ni * R->nr * R->no);
      double mse = 0.0;
      for (int v = 0; v < nv; v++) {
        const cell_t *ce = &W->cell[((size_t)s * RS + rs) * nv + v];
        const srv_t *sv = &W->srv[(size_t)s * nv + v];
        a->ms += ce->ms / nv, mse += ce->mse / nv;
        a->cpu_ms += sv->cpu_ms / nv, a->wall_ms += sv->wall_ms / nv, a->wire += sv->wire / nv, a->resident += (double)sv->resident / nv;
        a->dt_mean += ce->dt_mean / nv, a->dt_max = fmax(a->dt_max, ce->dt_max);
        a->t_rel += ce->t.rel / nv, a->t_rmse8 += ce->t.rmse8 * ce->t.rmse8 / nv, a->t_noise8 += ce->t.noise8 * ce->t.noise8 / nv;
      }
      a->t_rmse8 = sqrt(a->t_rmse8), a->t_noise8 = sqrt(a->t_noise8);
      a->rmse = sqrt(mse);
      a->psnr = psnr_of(a->rmse);
      a->reference = s == 0 && a->st == 0 && a->o == 0 && R->reps[a->rp] == 0 && R->ints[a->ip] == 0;
    }
  agg_t *agg = W->agg;
  for (int i = 0; i < na; i++) {
    agg[i].pareto = 1;
    for (int j = 0; j < na && agg[i].pareto; j++)
      if (j != i && agg[j].ms <= agg[i].ms && agg[j].rmse <= agg[i].rmse && (agg[j].ms < agg[i].ms || agg[j].rmse < agg[i].rmse))
        agg[i].pareto = 0;
  }
  R->agg = agg, R->nagg = na;
}

/* --csv: one row per setting and view. */
static int sweep_csv(const sweep_t *W) {
  const sweep_opts_t *o = W->o;
  const report_t *R = &W->R;
  FILE *csv = fopen(o->csv, "w");
  if (!csv) return oc_cli_fail(W->prog, -1, "--csv: cannot open '%s'", o->csv);
  fprintf(csv, "scene,renderer,timer,width,height,view,camera,budget_mib,max_depth,step_factor,ms_octaves,reprojection,"
               "interpolation,reconstruction,refresh,render_ms,render_wall_ms,render_cpu_ms,render_threads,"
               "server_cpu_ms_per_epoch,server_wall_ms_per_epoch,"
               "server_cpu_ms_last,wire_bytes_per_epoch,wire_bytes_last,resident_bytes,nodes,bricks,bricks_sent,rmse,psnr,"
               "analytic_mean_abs_dT,analytic_max_abs_dT,truth_rel_error,truth_rmse,truth_noise_rmse,truth_mean,reference,pareto\n");
  for (int i = 0; i < R->nagg; i++) {
    const agg_t *a = &R->agg[i];
    for (int v = 0; v < W->nv; v++) {
      const cell_t *ce = &W->cell[((size_t)a->s * W->RS + a->r) * W->nv + v];
      const srv_t *sv = &W->srv[(size_t)a->s * W->nv + v];
      char cam[160], pb[32];
      oc_camera_format(W->views[v].pose, cam, sizeof cam);
      double e = sqrt(ce->mse);
      fprintf(csv,
              "%s,%s,%s,%d,%d,\"%s\",\"%s\",%g,%ld,%g,%ld,%s,%s,exact,stamp,%.3f,%.3f,%.3f,%d,%.3f,%.3f,%.3f,%.0f,%.0f,%llu,"
              "%u,%u,%u,%.4f,%s,",
              W->sc->name, o->gl ? "gl" : "cpu", R->timer, o->size[0], o->size[1], W->views[v].name, cam, R->budgets[a->b],
              R->depths[a->d], R->steps[a->st], R->octs[a->o], onoff[R->reps[a->rp]], onoff[R->ints[a->ip]], ce->ms,
              ce->wall, ce->cpu, o->gl ? 0 : o->threads, sv->cpu_ms, sv->wall_ms, sv->cpu_last, sv->wire, sv->wire_last,
              (unsigned long long)sv->resident, sv->nodes, sv->bricks, sv->sent, e, fmt_psnr(psnr_of(e), pb, sizeof pb));
      if (R->analytic) fprintf(csv, "%.6f,%.6f,", ce->dt_mean, ce->dt_max);
      else fprintf(csv, ",,");
      if (R->truth) fprintf(csv, "%.6f,%.4f,%.4f,%.6g,", ce->t.rel, ce->t.rmse8, ce->t.noise8, ce->t.truth_mean);
      else fprintf(csv, ",,,,");
      fprintf(csv, "%d,%d\n", a->reference, a->pareto);
    }
  }
  if (fclose(csv) != 0) return oc_cli_fail(W->prog, -1, "--csv: cannot write '%s'", o->csv);
  return 0;
}

/* A plot point's label: "4M s0.5", with " dN", " oN", " R", " I" where those knobs vary or are on. */
static void plot_label(const report_t *R, const agg_t *a, char *buf, size_t cap) {
  size_t n = (size_t)snprintf(buf, cap, "%gM s%g", R->budgets[a->b], R->steps[a->st]);
  if (R->nd > 1 && n < cap) n += (size_t)snprintf(buf + n, cap - n, " d%ld", R->depths[a->d]);
  if (R->no > 1 && n < cap) n += (size_t)snprintf(buf + n, cap - n, " o%ld", R->octs[a->o]);
  if (R->reps[a->rp] && n < cap) n += (size_t)snprintf(buf + n, cap - n, " R");
  if (R->ints[a->ip] && n < cap) snprintf(buf + n, cap - n, " I");
}

/* --plot: RMSE against render ms, the Pareto front marked. */
static int sweep_plot(const sweep_t *W) {
  const sweep_opts_t *o = W->o;
  const report_t *R = &W->R;
  int na = R->nagg;
  char why[1024];
  octs_plot_point_t *pts = calloc((size_t)na, sizeof *pts);
  if (!pts) return oc_cli_fail(W->prog, -1, "out of memory");
  for (int i = 0; i < na; i++) {
    const agg_t *a = &R->agg[i];
    pts[i].x = a->ms, pts[i].y = a->rmse, pts[i].group = a->b % OCTS_PLOT_GROUPS;
    pts[i].pareto = a->pareto, pts[i].reference = a->reference;
    plot_label(R, a, pts[i].label, sizeof pts[i].label);
  }
  char names[OCTS_PLOT_GROUPS][32], title[160], sub[256];
  octs_plot_desc_t pd = {.title = title, .subtitle = sub,
                         .xlabel = o->gl ? "render ms per frame" : "render CPU ms per frame (all threads)",
                         .ylabel = "RMSE (0-255)", .ngroups = R->nb < OCTS_PLOT_GROUPS ? R->nb : OCTS_PLOT_GROUPS};
  if (R->nr > 1 || R->ni > 1 || R->reps[0] || R->ints[0]) pd.note = "R: reprojection on\nI: interpolation on";
  for (int g = 0; g < pd.ngroups; g++) {
    snprintf(names[g], sizeof names[g], "%g MiB", R->budgets[g]);
    pd.group_name[g] = names[g];
  }
  snprintf(title, sizeof title, "Error against render time: %s, %dx%d, %d view%s", W->sc->name, o->size[0], o->size[1],
           W->nv, W->nv == 1 ? "" : "s");
  snprintf(sub, sizeof sub, "times: %s; labels: budget M, step s; reference %g MiB, step %g", R->timer, R->budgets[0],
           R->steps[0]);
  int r = octs_plot_png(o->plot, pts, na, &pd, why, sizeof why);
  free(pts);
  if (r < 0) return oc_cli_fail(W->prog, -1, "--plot: %s", why);
  return 0;
}

/* The report on stdout and --md, then --csv and --plot. */
static int sweep_outputs(sweep_t *W, int argc, char **argv) {
  const sweep_opts_t *o = W->o;
  report_t *R = &W->R;
  char cmdline[2048];
  size_t cl = (size_t)snprintf(cmdline, sizeof cmdline, "overcast-bench sweep");
  for (int i = 1; i < argc && cl < sizeof cmdline; i++) cl += (size_t)snprintf(cmdline + cl, sizeof cmdline - cl, " %s", argv[i]);
  R->prog = W->prog, R->scene_name = W->sc->name, R->renderer_info = W->rinfo, R->timer = octs_renderer_timer(W->ren);
  R->cmdline = cmdline;
  R->w = o->size[0], R->h = o->size[1], R->pw = o->plan_size[0], R->ph = o->plan_size[1], R->nv = W->nv;
  R->epochs = o->epochs, R->threads = o->threads, R->frames = o->frames, R->repeat = o->repeat;
  R->motion = o->motion, R->interp_t = o->interp_t, R->split = o->split, R->reserve = o->reserve, R->views = W->views;
  R->ref_exact = o->ref_exact;
  R->tw = o->truth_size[0], R->th = o->truth_size[1], R->tpaths = o->truth_paths, R->tau = o->tau;
  fprintf(stderr, "%s: sweep done in %.1f s\n", W->prog, oct_now() - W->t_start);
  write_report(stdout, R);
  if (o->md) {
    FILE *f = fopen(o->md, "w");
    if (!f) return oc_cli_fail(W->prog, -1, "--md: cannot open '%s'", o->md);
    write_report(f, R);
    if (fclose(f) != 0) return oc_cli_fail(W->prog, -1, "--md: cannot write '%s'", o->md);
  }
  if (o->csv && sweep_csv(W)) return -1;
  if (o->plot && sweep_plot(W)) return -1;
  return 0;
}

/* --max-truth-error, --max-truth-rmse: every setting at every view within PCT % of a positive,
 * finite truth's image mean, and within X of it in RMSE 0–255. */
static int sweep_truth_check(const sweep_t *W) {
  const double pct = W->o->max_truth_error > 0.0 ? W->o->max_truth_error : INFINITY;
  const double rmse = W->o->max_truth_rmse > 0.0 ? W->o->max_truth_rmse : INFINITY;
  if (isinf(pct) && isinf(rmse)) return OC_EXIT_OK;
  if (!W->R.truth) return oc_cli_fail(W->prog, OC_EXIT_RUNTIME, "--max-truth-*: no truth column (not an analytic scene)");
  int bad = 0;
  for (size_t i = 0; i < (size_t)W->S * W->RS * W->nv; i++) {
    const octs_truth_err_t *t = &W->cell[i].t;
    if (!(t->truth_mean > 0.0) || !isfinite(t->truth_mean) || !(fabs(100.0 * t->rel) <= pct) || !(t->rmse8 <= rmse)) bad++;
  }
  if (bad)
    return oc_cli_fail(W->prog, OC_EXIT_RUNTIME, "--max-truth-error %g %%, --max-truth-rmse %g: %d of %d images off the "
                       "truth by more (or no lit truth)", pct, rmse, bad, W->S * W->RS * W->nv);
  fprintf(stderr, "%s: every image within %g %% of the truth's image mean and RMSE %g\n", W->prog, pct, rmse);
  return OC_EXIT_OK;
}

/* The whole sweep; @return the exit status. */
static int sweep_run(sweep_t *W, int argc, char **argv) {
  int rc = sweep_views(W);
  if (rc) return rc;
  if (sweep_open(W)) return OC_EXIT_RUNTIME;
  const char *prog = W->prog;
  if (W->o->csv) { /* refused before the work, as the file is written after it */
    FILE *f = fopen(W->o->csv, "w");
    if (!f) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--csv: cannot open '%s'", W->o->csv);
    fclose(f);
  }
  fprintf(stderr, "%s: sweep: %s, %d view(s), %d server setting(s) × %d render setting(s); %s\n", prog, W->sc->name,
          W->nv, W->S, W->RS, W->rinfo);
  fprintf(stderr, "%s: sample reconstruction: exact only (no hardware-filtered path: the RG16UI atlas cannot be filtered); "
                  "refresh policy: not swept (the server core has one)\n", prog);
  W->t_start = oct_now();
  for (int s = 0; s < W->S; s++) /* s = 0 is the reference's server setting */
    for (int v = 0; v < W->nv; v++)
      if (sweep_server(W, s, v)) return OC_EXIT_RUNTIME;
  sweep_aggregate(W);
  if (sweep_outputs(W, argc, argv)) return OC_EXIT_RUNTIME;
  return sweep_truth_check(W);
}

int oct_bench_sweep(const char *prog, int argc, char **argv) {
  static sweep_opts_t o;
  static oc_scene_t sc;
  static view_t views[MAXV];
  static sweep_t W;
  memset(&o, 0, sizeof o);
  int rc = oct_begin(&oct_bench_sweep_spec, argc, argv, &o, NULL, NULL, NULL, NULL);
  if (rc != OCT_GO) return rc;
  if (sweep_check(prog, &o)) return OC_EXIT_USAGE;
  if (oct_load_scene(prog, o.scene, &sc)) return OC_EXIT_RUNTIME;
  if (o.tau > 0.0 && oct_truth_scale(&sc, o.tau) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--tau: the scene has no sphere, box or slab with extinction to scale");
  }
  W = (sweep_t){.prog = prog, .o = &o, .sc = &sc, .views = views};
  sweep_knobs(&W);
  rc = sweep_run(&W, argc, argv);
  sweep_close(&W);
  oc_scene_free(&sc);
  return rc;
}
