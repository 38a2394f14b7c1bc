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
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_sweep_int.h"
#include "analytic.h"
#include "oc_atmo.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_image.h"
#include "scene_voxelize.h"
#ifdef OC_HAVE_GL
#include "camera_path.h"
#endif

#define MAXV 64   /* views */
#define MAXK 16   /* values per knob */
#define EXPOSURE 10.0f

static const char *const onoff[2] = {"off", "on"};

void oct_bench_sweep_usage(FILE *f) {
  fprintf(f,
          "sweep options (error against run time; the grid is the product of the lists; the reference is its\n"
          "highest-quality setting; outputs a Markdown report on stdout, progress on stderr):\n"
          "  --scene FILE        scene (default: the built-in procedural planet)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   a view (repeatable; default: the scene's camera)\n"
          "  --views PNG[,PNG..] views from screenshots' stored cameras (overcast-camera text chunk)\n"
          "  --path FILE         views sampled from a camera path file (overcast-view --record)\n"
          "  --path-samples N    poses taken evenly over the path's duration (default 4)\n"
          "  --size WxH          image size (default 160x90)\n"
          "  --plan-size WxH     viewport the planner sizes the tree for (default: --size)\n"
          "  --renderer cpu|gl   the CPU reference (default) or the GL compute renderer (headless EGL)\n"
          "  --threads N         CPU reference threads (default 2); its time is process CPU time over all\n"
          "                      threads (gl: wall time on llvmpipe, timer queries on a GPU; LP_NUM_THREADS)\n"
          "  --repeat N          timed renders per setting; the fastest counts (default 2)\n"
          "  --budgets LIST      viewer budgets in MiB (default 1,4,16,64)\n"
          "  --max-depths LIST   deepest octree levels, 0..21 (default 21)\n"
          "  --step-factors LIST step × voxel spacing (default 0.25,0.5,1,2)\n"
          "  --ms-octaves LIST   multiple-scattering octaves, 1..8 (default: the scene's)\n"
          "  --reprojection LIST off,on (gl only): a --frames sequence turning --motion degrees per frame,\n"
          "                      one pixel in 16 traced; the last frame is compared (default off)\n"
          "  --interp LIST       off,on (gl only): newest state blended with the previous at --interp-t\n"
          "                      (default off)\n"
          "  --frames N          reprojection sequence length (default 16)\n"
          "  --motion DEG        heading change per frame of the sequence (default 0.1)\n"
          "  --interp-t X        blend parameter with interpolation on, 0..1 (default 0.5)\n"
          "  --reconstruction LIST  exact only: there is no hardware-filtered path (RG16UI atlas)\n"
          "  --refresh LIST      stamp only: the server core has one refresh policy\n"
          "  --epochs N          epochs stepped per server setting and view (default 8)\n"
          "  --split-fraction X  planner split cap per epoch (default 0.5: converges in fewer epochs)\n"
          "  --reserve X         budget fraction the planner keeps free for change (default 0.1, a viewer's)\n"
          "  --server-threads N  producer threads (default: all cores)\n"
          "  --time T            world time at epoch 0, s (default 0)\n"
          "  --csv FILE          one row per setting and view\n"
          "  --md FILE           the Markdown report (Table 6.1 form: budget × step factor → ms / RMSE)\n"
          "  --plot FILE.png     RMSE against render ms, Pareto front marked\n"
          "  --images DIR        also every image as a PNG (camera in its text chunk), the reference's too\n"
          "  --reference-filter fast|exact  the reference image's bricks from the sources' fast box filter\n"
          "                      (default, as every setting's) or their exact one (a server run of its own at\n"
          "                      the reference's budget and depth): the RMSE column is then each setting's\n"
          "                      error against the exact filter, the fast filter's included\n"
          "\n");
}

/*-*** Options ***/

typedef struct {
  oc_camera_pose_t pose;
  char name[96];
} view_t;

static int parse_doubles(const char *prog, const char *opt, const char *text, double lo, double hi, double *out, int *n) {
  char buf[512];
  snprintf(buf, sizeof buf, "%s", text);
  *n = 0;
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (*n == MAXK) return oc_cli_fail(prog, -1, "%s: at most %d values", opt, MAXK);
    if (oc_cli_double(prog, opt, tok, lo, hi, &out[(*n)++])) return -1;
  }
  if (*n == 0) return oc_cli_fail(prog, -1, "%s: empty list", opt);
  return 0;
}

static int parse_onoff(const char *prog, const char *opt, const char *text, long *out, int *n) {
  char buf[128];
  snprintf(buf, sizeof buf, "%s", text);
  *n = 0;
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (*n == 2) return oc_cli_fail(prog, -1, "%s: at most 2 values (off,on)", opt);
    if (!strcmp(tok, "off") || !strcmp(tok, "0")) out[(*n)++] = 0;
    else if (!strcmp(tok, "on") || !strcmp(tok, "1")) out[(*n)++] = 1;
    else return oc_cli_fail(prog, -1, "%s: expected off or on, got \"%s\"", opt, tok);
  }
  if (*n == 0) return oc_cli_fail(prog, -1, "%s: empty list", opt);
  return 0;
}

/* A list whose only admissible value is `only`; anything else is refused with `why`. */
static int parse_only(const char *prog, const char *opt, const char *text, const char *only, const char *why) {
  char buf[128];
  snprintf(buf, sizeof buf, "%s", text);
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save))
    if (strcmp(tok, only)) return oc_cli_fail(prog, -1, "%s %s: not available: %s", opt, tok, why);
  return 0;
}

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
} cell_t;

typedef struct { /* one setting over the views */
  int s, r;      /* server and render setting */
  int b, d, st, o, rp, ip; /* knob indices */
  double ms, rmse, psnr, cpu_ms, wall_ms, wire, resident, dt_mean, dt_max;
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

  /* Table 6.1 form: one table per combination of the other knobs (when budget × step is a grid) */
  for (int d = 0; d < R->nd && R->nb * R->ns > 1; d++)
    for (int o = 0; o < R->no; o++)
      for (int rp = 0; rp < R->nr; rp++)
        for (int ip = 0; ip < R->ni; ip++) {
          fprintf(f, "**Render ms / RMSE (0–255)** — depth %ld, %ld octave%s, reprojection %s, interpolation %s:\n\n",
                  R->depths[d], R->octs[o], R->octs[o] == 1 ? "" : "s", onoff[R->reps[rp]], onoff[R->ints[ip]]);
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
              fprintf(f, " %s%.1f / %.2f%s |", a->pareto ? "**" : "", a->ms, a->rmse, a->pareto ? "**" : "");
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
             "resident MiB | RMSE | PSNR dB |%s Pareto |\n",
          R->analytic ? " mean abs ΔT | max abs ΔT |" : "");
  fprintf(f, "|---:|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|%s---|\n", R->analytic ? "---:|---:|" : "");
  for (int i = 0; i < R->nagg; i++) {
    const agg_t *a = &R->agg[i];
    fprintf(f, "| %g | %ld | %g | %ld | %s | %s | %.1f | %.0f | %.1f | %.2f | %.2f | %s |", R->budgets[a->b], R->depths[a->d],
            R->steps[a->st], R->octs[a->o], onoff[R->reps[a->rp]], onoff[R->ints[a->ip]], a->ms, a->cpu_ms, a->wire / 1024.0,
            a->resident / 1048576.0, a->rmse, fmt_psnr(a->psnr, pb, sizeof pb));
    if (R->analytic) fprintf(f, " %.4f | %.4f |", a->dt_mean, a->dt_max);
    fprintf(f, " %s |\n", a->reference ? "reference" : a->pareto ? "yes" : "");
  }
  fprintf(f, "\n");
}

/*-*** The subcommand ***/

int oct_bench_sweep(const char *prog, int argc, char **argv) {
  enum {
    O_SCENE = 256, O_CAMERA, O_VIEWS, O_PATH, O_PATH_N, O_SIZE, O_PLAN_SIZE, O_RENDERER, O_THREADS, O_REPEAT, O_BUDGETS,
    O_DEPTHS, O_STEPS, O_OCTS, O_REPROJ, O_INTERP, O_FRAMES, O_MOTION, O_INTERP_T, O_RECON, O_REFRESH, O_EPOCHS, O_SPLIT,
    O_SRV_THREADS, O_RESERVE, O_TIME, O_CSV, O_MD, O_PLOT, O_IMAGES, O_REF_FILTER, O_HELP
  };
  static const struct option opts[] = {
      {"scene", required_argument, 0, O_SCENE},         {"camera", required_argument, 0, O_CAMERA},
      {"views", required_argument, 0, O_VIEWS},         {"path", required_argument, 0, O_PATH},
      {"path-samples", required_argument, 0, O_PATH_N}, {"size", required_argument, 0, O_SIZE},
      {"plan-size", required_argument, 0, O_PLAN_SIZE}, {"renderer", required_argument, 0, O_RENDERER},
      {"threads", required_argument, 0, O_THREADS},     {"repeat", required_argument, 0, O_REPEAT},
      {"budgets", required_argument, 0, O_BUDGETS},     {"max-depths", required_argument, 0, O_DEPTHS},
      {"step-factors", required_argument, 0, O_STEPS},  {"ms-octaves", required_argument, 0, O_OCTS},
      {"reprojection", required_argument, 0, O_REPROJ}, {"interp", required_argument, 0, O_INTERP},
      {"frames", required_argument, 0, O_FRAMES},       {"motion", required_argument, 0, O_MOTION},
      {"interp-t", required_argument, 0, O_INTERP_T},   {"reconstruction", required_argument, 0, O_RECON},
      {"refresh", required_argument, 0, O_REFRESH},     {"epochs", required_argument, 0, O_EPOCHS},
      {"split-fraction", required_argument, 0, O_SPLIT}, {"server-threads", required_argument, 0, O_SRV_THREADS},
      {"reserve", required_argument, 0, O_RESERVE},     {"time", required_argument, 0, O_TIME},
      {"csv", required_argument, 0, O_CSV},             {"md", required_argument, 0, O_MD},
      {"plot", required_argument, 0, O_PLOT},           {"images", required_argument, 0, O_IMAGES},
      {"reference-filter", required_argument, 0, O_REF_FILTER},
      {"help", no_argument, 0, O_HELP},                 {0, 0, 0, 0}};
  const char *scene_path = NULL, *views_text = NULL, *path_file = NULL, *csv_path = NULL, *md_path = NULL, *plot_path = NULL,
             *images_dir = NULL;
  const char *cameras[MAXV];
  int ncameras = 0;
  const char *budgets_text = "1,4,16,64", *depths_text = "21", *steps_text = "0.25,0.5,1,2", *octs_text = NULL;
  const char *reproj_text = "off", *interp_text = "off";
  long path_n = 4, threads = 2, repeat = 2, frames = 16, epochs = 8, srv_threads = 0;
  double motion = 0.1, interp_t = 0.5, split = 0.5, reserve = 0.1, world_time = 0.0;
  int ref_exact = 0;
  int w = 160, h = 90, pw = 0, ph = 0, gl = 0, c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_CAMERA:
        if (ncameras == MAXV) return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: at most %d", MAXV);
        cameras[ncameras++] = optarg;
        break;
      case O_VIEWS: views_text = optarg; break;
      case O_PATH: path_file = optarg; break;
      case O_PATH_N: if (oc_cli_int(prog, "--path-samples", optarg, 1, MAXV, &path_n)) return OC_EXIT_USAGE; break;
      case O_SIZE: if (oc_cli_size(prog, "--size", optarg, &w, &h)) return OC_EXIT_USAGE; break;
      case O_PLAN_SIZE: if (oc_cli_size(prog, "--plan-size", optarg, &pw, &ph)) return OC_EXIT_USAGE; break;
      case O_RENDERER:
        if (!strcmp(optarg, "cpu")) gl = 0;
        else if (!strcmp(optarg, "gl")) gl = 1;
        else return oc_cli_fail(prog, OC_EXIT_USAGE, "--renderer: expected cpu or gl, got \"%s\"", optarg);
#ifndef OC_HAVE_GL
        if (gl) return oc_cli_fail(prog, OC_EXIT_USAGE, "--renderer gl: this build has no GL renderer (libepoxy was not found)");
#endif
        break;
      case O_THREADS: if (oc_cli_int(prog, "--threads", optarg, 1, 256, &threads)) return OC_EXIT_USAGE; break;
      case O_REPEAT: if (oc_cli_int(prog, "--repeat", optarg, 1, 100, &repeat)) return OC_EXIT_USAGE; break;
      case O_BUDGETS: budgets_text = optarg; break;
      case O_DEPTHS: depths_text = optarg; break;
      case O_STEPS: steps_text = optarg; break;
      case O_OCTS: octs_text = optarg; break;
      case O_REPROJ: reproj_text = optarg; break;
      case O_INTERP: interp_text = optarg; break;
      case O_FRAMES: if (oc_cli_int(prog, "--frames", optarg, 2, 1024, &frames)) return OC_EXIT_USAGE; break;
      case O_MOTION: if (oc_cli_double(prog, "--motion", optarg, -90, 90, &motion)) return OC_EXIT_USAGE; break;
      case O_INTERP_T: if (oc_cli_double(prog, "--interp-t", optarg, 0, 1, &interp_t)) return OC_EXIT_USAGE; break;
      case O_RECON:
        if (parse_only(prog, "--reconstruction", optarg, "exact",
                       "the brick atlas is an RG16UI integer texture (codes with a per-brick range), which GL cannot "
                       "filter; the shader reconstructs exactly (trilinear of decoded codes), as the CPU reference does"))
          return OC_EXIT_USAGE;
        break;
      case O_REFRESH:
        if (parse_only(prog, "--refresh", optarg, "stamp",
                       "the server core has one refresh policy (a leaf whose content stamp changed is refreshed, nearest "
                       "first, within the budget's reserve; otherwise deferred) and no switch for another"))
          return OC_EXIT_USAGE;
        break;
      case O_EPOCHS: if (oc_cli_int(prog, "--epochs", optarg, 1, 1000, &epochs)) return OC_EXIT_USAGE; break;
      case O_SPLIT: if (oc_cli_double(prog, "--split-fraction", optarg, 0.001, 1, &split)) return OC_EXIT_USAGE; break;
      case O_SRV_THREADS: if (oc_cli_int(prog, "--server-threads", optarg, 0, 64, &srv_threads)) return OC_EXIT_USAGE; break;
      case O_RESERVE: if (oc_cli_double(prog, "--reserve", optarg, 0.001, 0.5, &reserve)) return OC_EXIT_USAGE; break;
      case O_TIME: if (oc_cli_double(prog, "--time", optarg, -1e12, 1e12, &world_time)) return OC_EXIT_USAGE; break;
      case O_CSV: csv_path = optarg; break;
      case O_MD: md_path = optarg; break;
      case O_PLOT: plot_path = optarg; break;
      case O_IMAGES: images_dir = optarg; break;
      case O_REF_FILTER:
        if (strcmp(optarg, "fast") && strcmp(optarg, "exact"))
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--reference-filter: \"%s\" is not fast or exact", optarg);
        ref_exact = !strcmp(optarg, "exact");
        break;
      case O_HELP: oct_bench_usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "sweep: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "sweep: unexpected argument \"%s\"", argv[optind]);
  if (!pw) pw = w, ph = h;

  report_t R;
  memset(&R, 0, sizeof R);
  if (parse_doubles(prog, "--budgets", budgets_text, 0.0625, 1 << 20, R.budgets, &R.nb) ||
      oct_parse_list(prog, "--max-depths", depths_text, 0, 21, R.depths, MAXK, &R.nd) ||
      parse_doubles(prog, "--step-factors", steps_text, 1e-3, 1e3, R.steps, &R.ns) ||
      parse_onoff(prog, "--reprojection", reproj_text, R.reps, &R.nr) || parse_onoff(prog, "--interp", interp_text, R.ints, &R.ni))
    return OC_EXIT_USAGE;
  if (!gl && (R.reps[R.nr - 1] || R.reps[0] || R.ints[0] || R.ints[R.ni - 1]))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--reprojection on and --interp on need --renderer gl (the CPU reference has neither)");
  if (path_file && (ncameras || views_text))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--path gives the views: no --camera or --views with it");
#ifndef OC_HAVE_GL
  if (path_file) return oc_cli_fail(prog, OC_EXIT_USAGE, "--path: this build has no client library (camera paths)");
#endif

  char why[1024];
  static oc_scene_t sc;
  if (oct_load_scene(prog, scene_path, &sc)) return OC_EXIT_RUNTIME;
  int rc = OC_EXIT_OK;
  if (octs_text) {
    if (oct_parse_list(prog, "--ms-octaves", octs_text, 1, 8, R.octs, MAXK, &R.no)) {
      oc_scene_free(&sc);
      return OC_EXIT_USAGE;
    }
  } else {
    R.octs[0] = oc_scene_has(&sc, OC_FEATURE_MULTIPLE_SCATTERING) ? sc.optics.ms_octaves : 1;
    R.no = 1;
  }

  /* the views */
  static view_t views[MAXV];
  int nv = 0;
  for (int i = 0; i < ncameras; i++) {
    oc_camera_pose_t pose;
    char name[32];
    if (oc_camera_parse(cameras[i], &pose, why, sizeof why) < 0) {
      oc_scene_free(&sc);
      return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
    }
    snprintf(name, sizeof name, "camera %d", i + 1);
    if (add_view(prog, views, &nv, pose, name)) return OC_EXIT_USAGE;
  }
  if (views_text) {
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", views_text);
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
      int iw, ih;
      uint8_t *px = NULL;
      char text[256] = "";
      oc_camera_pose_t pose;
      if (oc_png_read(tok, &iw, &ih, &px, "overcast-camera", text, sizeof text, why, sizeof why) < 0) {
        oc_scene_free(&sc);
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views: %s", why);
      }
      free(px);
      if (!text[0]) {
        oc_scene_free(&sc);
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views %s: no overcast-camera text chunk", tok);
      }
      if (oc_camera_parse(text, &pose, why, sizeof why) < 0) {
        oc_scene_free(&sc);
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--views %s: %s", tok, why);
      }
      const char *base = strrchr(tok, '/');
      if (add_view(prog, views, &nv, pose, base ? base + 1 : tok)) return OC_EXIT_USAGE;
    }
  }
#ifdef OC_HAVE_GL
  if (path_file) {
    ocv_path_t path;
    ocv_path_init(&path);
    if (ocv_path_load(&path, path_file, why, sizeof why) < 0 || path.count == 0) {
      ocv_path_free(&path);
      oc_scene_free(&sc);
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--path: %s", path.count ? why : "no poses");
    }
    double dur = ocv_path_duration(&path), t0 = path.t[0];
    for (long i = 0; i < path_n; i++) {
      double t = path_n == 1 ? t0 : t0 + (dur - t0) * (double)i / (double)(path_n - 1);
      oc_camera_pose_t pose;
      char name[48];
      ocv_path_sample(&path, t, &pose);
      snprintf(name, sizeof name, "path t=%.2f s", t);
      add_view(prog, views, &nv, pose, name);
    }
    ocv_path_free(&path);
  }
#endif
  if (nv == 0) {
    oc_camera_pose_t pose = {sc.camera.pos, sc.camera.heading, sc.camera.pitch, sc.camera.fov};
    add_view(prog, views, &nv, pose, "scene camera");
  }

  /* the reference: best of every knob, first in each list's slot 0 (lists are reordered so that the
   * reference comes first: budgets and depths descending, steps ascending, octaves descending) */
  for (int i = 0; i < R.nb; i++) /* simple insertion sorts; lists are short */
    for (int j = i; j > 0 && R.budgets[j] > R.budgets[j - 1]; j--) {
      double t = R.budgets[j];
      R.budgets[j] = R.budgets[j - 1], R.budgets[j - 1] = t;
    }
  for (int i = 0; i < R.nd; i++)
    for (int j = i; j > 0 && R.depths[j] > R.depths[j - 1]; j--) {
      long t = R.depths[j];
      R.depths[j] = R.depths[j - 1], R.depths[j - 1] = t;
    }
  for (int i = 0; i < R.ns; i++)
    for (int j = i; j > 0 && R.steps[j] < R.steps[j - 1]; j--) {
      double t = R.steps[j];
      R.steps[j] = R.steps[j - 1], R.steps[j - 1] = t;
    }
  for (int i = 0; i < R.no; i++)
    for (int j = i; j > 0 && R.octs[j] > R.octs[j - 1]; j--) {
      long t = R.octs[j];
      R.octs[j] = R.octs[j - 1], R.octs[j - 1] = t;
    }
  if (R.nr == 2 && R.reps[0]) R.reps[0] = 0, R.reps[1] = 1;
  if (R.ni == 2 && R.ints[0]) R.ints[0] = 0, R.ints[1] = 1;

  /* the atmosphere tables, the renderer, the closed form */
  oc_atmo_t *atmo = NULL;
  if (oc_scene_has(&sc, OC_FEATURE_ATMOSPHERE)) {
    ocg_atmosphere ap;
    oc_atmo_params_default(&ap);
    if (!oc_scene_has(&sc, OC_FEATURE_OZONE)) ap.ozone_absorption = ocg_v3s(0.0f);
    if (!(atmo = oc_atmo_create(&ap, (int)threads))) {
      oc_scene_free(&sc);
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "could not build the atmosphere tables");
    }
  }
  octs_render_desc_t rd = {w, h, (int)threads, (int)repeat, (int)frames, motion, (float)interp_t, &sc, atmo};
  char rinfo[512];
  octs_renderer_t *ren = octs_renderer_open(gl, &rd, rinfo, sizeof rinfo, why, sizeof why);
  if (!ren) {
    oc_atmo_free(atmo);
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer %s: %s", gl ? "gl" : "cpu", why);
  }
  ocs_medium_t medium;
  R.analytic = ocs_scene_medium(&sc, &medium, NULL, 0) == 0;
  size_t npx = (size_t)w * (size_t)h;
  float *truth = NULL; /* per view: e^−τ of each pixel's ray */
  uint8_t *ref_rgb = NULL, *rgb = NULL;
  const int S = R.nb * R.nd, RS = R.ns * R.no * R.nr * R.ni;
  srv_t *srv = calloc((size_t)S * nv, sizeof *srv);
  cell_t *cell = calloc((size_t)S * RS * nv, sizeof *cell);
  agg_t *agg = calloc((size_t)S * RS, sizeof *agg);
  oc_image_t img = {0};
  FILE *csv = NULL;
  ref_rgb = malloc(npx * 3 * (size_t)nv);
  rgb = malloc(npx * 3);
  if (R.analytic) truth = malloc(sizeof *truth * npx * (size_t)nv);
  if (!srv || !cell || !agg || !ref_rgb || !rgb || (R.analytic && !truth) || oc_image_alloc(&img, w, h) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    goto out;
  }
  if (R.analytic) {
    int ground = oc_scene_has(&sc, OC_FEATURE_PLANET_SURFACE);
    for (int v = 0; v < nv; v++) {
      oc_camera_t cam = oc_camera_from_pose(views[v].pose);
      for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
          oc_dvec3 dir = oc_camera_ray(&cam, w, h, x, y);
          double tmax = ground ? ground_hit(cam.pos, dir, OC_PLANET_RADIUS) : INFINITY;
          truth[(size_t)v * npx + (size_t)y * w + x] = (float)exp(-ocs_medium_optical_depth(&medium, cam.pos, dir, tmax));
        }
    }
  }
  if (csv_path && !(csv = fopen(csv_path, "w"))) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--csv: cannot open '%s'", csv_path);
    goto out;
  }

  fprintf(stderr, "%s: sweep: %s, %d view(s), %d server setting(s) × %d render setting(s); %s\n", prog, sc.name, nv, S, RS, rinfo);
  fprintf(stderr, "%s: sample reconstruction: exact only (no hardware-filtered path: the RG16UI atlas cannot be filtered); "
                  "refresh policy: not swept (the server core has one)\n", prog);
  double t_start = oct_now();
  int done = 0, total = S * RS * nv;
  for (int s = 0; s < S && rc == OC_EXIT_OK; s++) { /* s = 0 is the reference's server setting */
    int b = s / R.nd, d = s % R.nd;
    for (int v = 0; v < nv && rc == OC_EXIT_OK; v++) {
      progress_t pg = {prog, "", isatty(fileno(stderr))};
      snprintf(pg.head, sizeof pg.head, "server %d/%d: budget %g MiB, depth %ld, view %d/%d", s + 1, S, R.budgets[b],
               R.depths[d], v + 1, nv);
      octs_server_desc_t sd = {(uint64_t)(R.budgets[b] * 1048576.0), (int)R.depths[d], (int)epochs, (int)srv_threads, split,
                               reserve, world_time, pw, ph, 0};
      octs_server_out_t so;
      double t0 = oct_now();
      int r = octs_server_run(&sc, &sd, views[v].pose, &so, server_progress, &pg, why, sizeof why);
      if (r < 0) {
        if (pg.tty) fprintf(stderr, "\n");
        rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", pg.head, why);
        break;
      }
      srv_t *sv = &srv[(size_t)s * nv + v];
      *sv = (srv_t){so.cpu_ms_mean, so.cpu_ms_last, so.wall_ms_mean, so.wire_mean, so.wire_last, so.resident,
                    so.newest.node_count, so.newest.brick_count, so.bricks_sent};
      fprintf(stderr, "%s%s: %s: %u nodes, %u bricks, %.2f MiB resident, %.0f ms CPU and %.1f KiB an epoch ... %.1f s\n",
              pg.tty ? "\r\033[K" : "", prog, pg.head, sv->nodes, sv->bricks, sv->resident / 1048576.0, sv->cpu_ms,
              sv->wire / 1024.0, oct_now() - t0);
      if ((r = octs_renderer_set_states(ren, &so.newest, &so.prev, so.animated, why, sizeof why)) < 0) {
        octs_server_out_free(&so);
        rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", pg.head, why);
        break;
      }
      if (s == 0) { /* the reference image of this view */
        octs_render_knobs_t k = {R.steps[0], (int)R.octs[0], 0, 0};
        octs_times_t tm;
        octs_server_out_t ro; /* --reference-filter exact: the same setting, bricks from the exact filter */
        if (ref_exact) {
          sd.exact_filter = 1;
          snprintf(pg.head, sizeof pg.head, "reference (exact filter), view %d/%d", v + 1, nv);
          if ((r = octs_server_run(&sc, &sd, views[v].pose, &ro, server_progress, &pg, why, sizeof why)) < 0 ||
              (r = octs_renderer_set_states(ren, &ro.newest, &ro.prev, ro.animated, why, sizeof why)) < 0) {
            octs_server_out_free(&so);
            rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: %s", pg.head, why);
            break;
          }
          fprintf(stderr, "%s%s: %s: %u nodes, %u bricks ... done\n", pg.tty ? "\r\033[K" : "", prog, pg.head,
                  ro.newest.node_count, ro.newest.brick_count);
        }
        r = octs_render(ren, views[v].pose, &k, &img, &tm, why, sizeof why);
        if (ref_exact) {
          int r2 = octs_renderer_set_states(ren, &so.newest, &so.prev, so.animated, why, sizeof why);
          octs_server_out_free(&ro);
          if (r >= 0) r = r2;
        }
        if (r < 0) {
          octs_server_out_free(&so);
          rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "reference, view %d: %s", v + 1, why);
          break;
        }
        oc_image_tonemap(&img, EXPOSURE, ref_rgb + (size_t)v * npx * 3);
        if (images_dir && write_image(images_dir, "reference", v, views[v].pose, w, h, ref_rgb + (size_t)v * npx * 3, why,
                                      sizeof why) < 0) {
          octs_server_out_free(&so);
          rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--images: %s", why);
          break;
        }
      }
      for (int rs = 0; rs < RS; rs++) {
        int ip = rs % R.ni, rp = rs / R.ni % R.nr, o = rs / (R.ni * R.nr) % R.no, st = rs / (R.ni * R.nr * R.no);
        octs_render_knobs_t k = {R.steps[st], (int)R.octs[o], (int)R.reps[rp], (int)R.ints[ip]};
        octs_times_t tm;
        double t1 = oct_now();
        if ((r = octs_render(ren, views[v].pose, &k, &img, &tm, why, sizeof why)) < 0) {
          rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "render: %s", why);
          break;
        }
        int bad = oc_image_tonemap(&img, EXPOSURE, rgb);
        if (bad) {
          rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "render: %d non-finite pixels", bad);
          break;
        }
        if (images_dir) {
          char name[128];
          snprintf(name, sizeof name, "b%g_d%ld_s%g_o%ld_r%ld_i%ld", R.budgets[b], R.depths[d], R.steps[st], R.octs[o], R.reps[rp],
                   R.ints[ip]);
          if (write_image(images_dir, name, v, views[v].pose, w, h, rgb, why, sizeof why) < 0) {
            rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--images: %s", why);
            break;
          }
        }
        cell_t *ce = &cell[((size_t)s * RS + rs) * nv + v];
        double e = oc_rgb8_rmse(rgb, ref_rgb + (size_t)v * npx * 3, w, h);
        ce->ms = tm.ms, ce->wall = tm.wall, ce->cpu = tm.cpu;
        ce->mse = e * e;
        if (R.analytic) {
          double sum = 0.0, mx = 0.0;
          const float *tv = truth + (size_t)v * npx;
          for (size_t i = 0; i < npx; i++) {
            double dd = fabs((double)img.px[4 * i + 3] - tv[i]);
            sum += dd;
            mx = fmax(mx, dd);
          }
          ce->dt_mean = sum / (double)npx;
          ce->dt_max = mx;
        }
        done++;
        fprintf(stderr, "%s: setting %d/%d: budget %g MiB, depth %ld, step %g, octaves %ld, reprojection %s, interpolation %s, "
                        "view %d/%d: %.1f ms (%s), RMSE %.3f ... %.1f s (%.0f s in all)\n",
                prog, done, total, R.budgets[b], R.depths[d], R.steps[st], R.octs[o], onoff[R.reps[rp]], onoff[R.ints[ip]], v + 1,
                nv, tm.ms, octs_renderer_timer(ren), e, oct_now() - t1, oct_now() - t_start);
      }
      octs_server_out_free(&so);
    }
  }
  if (rc != OC_EXIT_OK) goto out;

  /* aggregate over views, the Pareto front */
  int na = 0;
  for (int s = 0; s < S; s++)
    for (int rs = 0; rs < RS; rs++) {
      agg_t *a = &agg[na++];
      a->s = s, a->r = rs;
      a->b = s / R.nd, a->d = s % R.nd;
      a->ip = rs % R.ni, a->rp = rs / R.ni % R.nr, a->o = rs / (R.ni * R.nr) % R.no, a->st = rs / (R.ni * R.nr * R.no);
      double mse = 0.0;
      for (int v = 0; v < nv; v++) {
        const cell_t *ce = &cell[((size_t)s * RS + rs) * nv + v];
        const srv_t *sv = &srv[(size_t)s * nv + v];
        a->ms += ce->ms / nv, mse += ce->mse / nv;
        a->cpu_ms += sv->cpu_ms / nv, a->wall_ms += sv->wall_ms / nv, a->wire += sv->wire / nv, a->resident += (double)sv->resident / nv;
        a->dt_mean += ce->dt_mean / nv, a->dt_max = fmax(a->dt_max, ce->dt_max);
      }
      a->rmse = sqrt(mse);
      a->psnr = psnr_of(a->rmse);
      a->reference = s == 0 && a->st == 0 && a->o == 0 && R.reps[a->rp] == 0 && R.ints[a->ip] == 0;
    }
  for (int i = 0; i < na; i++) {
    agg[i].pareto = 1;
    for (int j = 0; j < na && agg[i].pareto; j++)
      if (j != i && agg[j].ms <= agg[i].ms && agg[j].rmse <= agg[i].rmse && (agg[j].ms < agg[i].ms || agg[j].rmse < agg[i].rmse))
        agg[i].pareto = 0;
  }
  R.agg = agg, R.nagg = na;

  /* the command line, for the report */
  char cmdline[2048];
  size_t cl = (size_t)snprintf(cmdline, sizeof cmdline, "overcast-bench sweep");
  for (int i = 1; i < argc && cl < sizeof cmdline; i++) cl += (size_t)snprintf(cmdline + cl, sizeof cmdline - cl, " %s", argv[i]);
  R.prog = prog, R.scene_name = sc.name, R.renderer_info = rinfo, R.timer = octs_renderer_timer(ren), R.cmdline = cmdline;
  R.w = w, R.h = h, R.pw = pw, R.ph = ph, R.nv = nv, R.epochs = (int)epochs, R.threads = (int)threads, R.frames = (int)frames;
  R.repeat = (int)repeat;
  R.motion = motion, R.interp_t = interp_t, R.split = split, R.reserve = reserve, R.views = views;
  R.ref_exact = ref_exact;
  fprintf(stderr, "%s: sweep done in %.1f s\n", prog, oct_now() - t_start);
  write_report(stdout, &R);
  if (md_path) {
    FILE *f = fopen(md_path, "w");
    if (!f) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--md: cannot open '%s'", md_path);
      goto out;
    }
    write_report(f, &R);
    if (fclose(f) != 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--md: cannot write '%s'", md_path);
      goto out;
    }
  }
  if (csv) {
    fprintf(csv, "scene,renderer,timer,width,height,view,camera,budget_mib,max_depth,step_factor,ms_octaves,reprojection,"
                 "interpolation,reconstruction,refresh,render_ms,render_wall_ms,render_cpu_ms,render_threads,"
                 "server_cpu_ms_per_epoch,server_wall_ms_per_epoch,"
                 "server_cpu_ms_last,wire_bytes_per_epoch,wire_bytes_last,resident_bytes,nodes,bricks,bricks_sent,rmse,psnr,"
                 "analytic_mean_abs_dT,analytic_max_abs_dT,reference,pareto\n");
    for (int i = 0; i < na; i++) {
      const agg_t *a = &agg[i];
      for (int v = 0; v < nv; v++) {
        const cell_t *ce = &cell[((size_t)a->s * RS + a->r) * nv + v];
        const srv_t *sv = &srv[(size_t)a->s * nv + v];
        char cam[160], pb[32];
        oc_camera_format(views[v].pose, cam, sizeof cam);
        double e = sqrt(ce->mse);
        fprintf(csv,
                "%s,%s,%s,%d,%d,\"%s\",\"%s\",%g,%ld,%g,%ld,%s,%s,exact,stamp,%.3f,%.3f,%.3f,%d,%.3f,%.3f,%.3f,%.0f,%.0f,%llu,"
                "%u,%u,%u,%.4f,%s,",
                sc.name, gl ? "gl" : "cpu", R.timer, w, h, views[v].name, cam, R.budgets[a->b], R.depths[a->d], R.steps[a->st],
                R.octs[a->o], onoff[R.reps[a->rp]], onoff[R.ints[a->ip]], ce->ms, ce->wall, ce->cpu, gl ? 0 : (int)threads,
                sv->cpu_ms, sv->wall_ms,
                sv->cpu_last, sv->wire, sv->wire_last, (unsigned long long)sv->resident, sv->nodes, sv->bricks, sv->sent, e,
                fmt_psnr(psnr_of(e), pb, sizeof pb));
        if (R.analytic) fprintf(csv, "%.6f,%.6f,", ce->dt_mean, ce->dt_max);
        else fprintf(csv, ",,");
        fprintf(csv, "%d,%d\n", a->reference, a->pareto);
      }
    }
  }
  if (plot_path) {
    octs_plot_point_t *pts = calloc((size_t)na, sizeof *pts);
    if (!pts) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
      goto out;
    }
    for (int i = 0; i < na; i++) {
      const agg_t *a = &agg[i];
      pts[i].x = a->ms, pts[i].y = a->rmse, pts[i].group = a->b % OCTS_PLOT_GROUPS;
      pts[i].pareto = a->pareto, pts[i].reference = a->reference;
      int n = snprintf(pts[i].label, sizeof pts[i].label, "%gM s%g", R.budgets[a->b], R.steps[a->st]);
      if (R.nd > 1 && n > 0 && n < (int)sizeof pts[i].label)
        n += snprintf(pts[i].label + n, sizeof pts[i].label - (size_t)n, " d%ld", R.depths[a->d]);
      if (R.no > 1 && n > 0 && n < (int)sizeof pts[i].label)
        n += snprintf(pts[i].label + n, sizeof pts[i].label - (size_t)n, " o%ld", R.octs[a->o]);
      if (R.reps[a->rp] && n > 0 && n < (int)sizeof pts[i].label)
        n += snprintf(pts[i].label + n, sizeof pts[i].label - (size_t)n, " R");
      if (R.ints[a->ip] && n > 0 && n < (int)sizeof pts[i].label) snprintf(pts[i].label + n, sizeof pts[i].label - (size_t)n, " I");
    }
    char names[OCTS_PLOT_GROUPS][32], title[160], sub[256];
    octs_plot_desc_t pd = {.title = title, .subtitle = sub,
                           .xlabel = gl ? "render ms per frame" : "render CPU ms per frame (all threads)",
                           .ylabel = "RMSE (0-255)", .ngroups = R.nb < OCTS_PLOT_GROUPS ? R.nb : OCTS_PLOT_GROUPS};
    if (R.nr > 1 || R.ni > 1 || R.reps[0] || R.ints[0]) pd.note = "R: reprojection on\nI: interpolation on";
    for (int g = 0; g < pd.ngroups; g++) {
      snprintf(names[g], sizeof names[g], "%g MiB", R.budgets[g]);
      pd.group_name[g] = names[g];
    }
    snprintf(title, sizeof title, "Error against render time: %s, %dx%d, %d view%s", sc.name, w, h, nv, nv == 1 ? "" : "s");
    snprintf(sub, sizeof sub, "times: %s; labels: budget M, step s; reference %g MiB, step %g", R.timer, R.budgets[0], R.steps[0]);
    int r = octs_plot_png(plot_path, pts, na, &pd, why, sizeof why);
    free(pts);
    if (r < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--plot: %s", why);
      goto out;
    }
  }

out:
  if (csv && fclose(csv) != 0 && rc == OC_EXIT_OK) rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--csv: cannot write '%s'", csv_path);
  oc_image_free(&img);
  free(truth);
  free(ref_rgb);
  free(rgb);
  free(srv);
  free(cell);
  free(agg);
  octs_renderer_close(ren);
  oc_atmo_free(atmo);
  oc_scene_free(&sc);
  return rc;
}
