/* bench_model.c — `overcast-bench model`: the real-time cloud model against stored Monte Carlo
 * truth images (`overcast-bench truth --save`), one row per case, old and new model side by side,
 * and the sum the fit minimises (--search: Nelder-Mead over the eleven numbers, scored on the fitted set).
 * The truth itself is not re-traced: a few milliseconds per case, so a fit can render every case hundreds
 * of times. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "bench_oracle.h"
#include "bench_util.h"
#include "oc.h"
#include "march.h" /* OCG_MS_CHORD_HALF, … : the fitted constants a search starts from */
#include "truth.h"

typedef struct {
  float fit[OC_RENDER_MS_FIT_N];
  int have_fit, have_abc, legacy, quiet, search, split, rows;
  double abc[3];
  int have_oracle, oracle_cells, oracle_paths, threads;
  oct_oracle_opts_t oracle; /* --oracle: its lmax; the rest from the other three */
} oct__model_opts_t;

/* --oracle: the case with the Monte Carlo kernel's multiply scattered light (bench_oracle.h). */
static int oct__model_oracle(const oc_scene_t *sc, const oct_truth_case_t *c, const oc_state_t *st,
                             const oc_render_desc_t *d, const oct__model_opts_t *o, oc_image_t *img) {
  double len = 0.0;
  for (int i = 0; i < sc->nsources && !(len > 0.0); i++) len = oct_truth_source_length(&sc->sources[i]);
  if (!(len > 0.0)) return OC_EINVAL; /* nothing to size the lattice by */
  oct_oracle_opts_t oo = o->oracle;
  oo.cells = o->oracle_cells, oo.paths = o->oracle_paths, oo.threads = o->threads;
  long points = 0;
  int r = oct_oracle_render(c, st, d, len, &oo, img, &points);
  if (r >= 0 && !o->quiet) fprintf(stderr, "oracle: %ld lattice points, %.1f m apart\n", points, len / oo.cells);
  return r;
}

/* Each row's mean of the image's first channel (the one the score's mean reads), img->h values. */
static void oct__row_means(const oc_image_t *img, double *rows) {
  for (int y = 0; y < img->h; y++) {
    double sum = 0.0;
    for (int x = 0; x < img->w; x++) sum += img->px[4 * ((size_t)y * (size_t)img->w + (size_t)x)];
    rows[y] = sum / img->w;
  }
}

/* Renders one case with one model (single: single scattering alone), its row means to rows unless
 * NULL; @return 0 or an exit status. */
static int oct__model_case(const char *prog, const oct_truth_case_t *c, const oc_scene_t *sc, oc_camera_t cam,
                           const oc_state_t *st, const oct__model_opts_t *o, int legacy, int single,
                           oct_truth_score_t *s, double *rows) {
  oc_render_desc_t d = oct_truth_case_desc(c, sc, cam);
  d.ms_model = legacy ? OC_MS_MODEL_OCTAVES : OC_MS_MODEL_DEPTH;
  if (single) d.ms_octaves = 1;
  if (!legacy && o->have_fit) d.ms_fit = o->fit;
  if (!legacy && o->have_abc) {
    d.ms_a = (float)o->abc[0];
    d.ms_b = (float)o->abc[1];
    d.ms_c = (float)o->abc[2];
  }
  if (legacy) { /* the model before the fit: its 0.5 defaults; it lit no cloud from a constant background */
    d.ms_a = d.ms_b = d.ms_c = 0.5f;
    d.flags |= OC_RF_NO_AMBIENT;
  }
  oc_image_t img = {0};
  if (oc_image_alloc(&img, c->w, c->h) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  int r = !legacy && !single && o->have_oracle ? oct__model_oracle(sc, c, st, &d, o, &img)
                                               : oc_render_state(st, &d, &img, NULL);
  if (o->have_oracle && (r == OC_ERANGE || r == OC_EINVAL)) {
    oc_image_free(&img);
    if (r == OC_EINVAL)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "model --oracle: no sphere, box or slab to size the lattice by");
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "model --oracle: the lattice would pass %d points; give fewer "
                       "--oracle-cells", OCT_ORACLE_MAX_POINTS);
  }
  int rc = r < 0 || oct_truth_score(c, &img, s) < 0;
  if (!rc && rows) oct__row_means(&img, rows);
  oc_image_free(&img);
  return rc ? oc_cli_fail(prog, OC_EXIT_RUNTIME, "model: render failed") : OC_EXIT_OK;
}

/* The fit's objective per case: the image-mean error in units of its bound lim (±10 %, or ±20 %) and
 * the RMSE in units of its bound, max(6, 2 × the truth's seed-to-seed RMSE), squared and summed. */
static double oct__model_cost(const oct_truth_score_t *s, double lim, double bound) {
  double r = s->rel / lim, e = s->rmse8 / bound;
  return r * r + e * e;
}

/* Every case loaded and voxelized once. */
typedef struct {
  oct_truth_case_t tc;
  oc_scene_t sc;
  oc_state_t st;
  oc_camera_t cam;
  const char *name;
  double *rows; /**< --rows: per image row, the truth's mean, the model's, single scattering's (3 × h) */
  double rel, rmse8, amb; /**< the last scoring: mean error, RMSE 0–255, uniform-sky error (NaN: none) */
  int ok;                 /**< within both bounds */
} oct__mcase_t;

static int oct__fitted(const oct__mcase_t *m, int sky);
static double oct__mean_limit(const oct__mcase_t *m);

/* Whether the stored truth has a uniform-sky image the model is scored against (ω = 1 is the sky
 * itself at every depth, so it is not scored). */
static int oct__has_sky(const oct__mcase_t *m) { return m->tc.env > 0.0 && m->tc.albedo < 1.0; }

/* --split: the case once more with single scattering alone (exact given τ; the stored cases have no
 * sky, so the rest is multiply scattered light). Prints the truth's multiply scattered share and k,
 * the factor by which the model's multiply scattered part would give the truth's image mean. */
static int oct__model_split(const char *prog, const oct__mcase_t *m, const oct__model_opts_t *o,
                            const oct_truth_score_t *s) {
  oct_truth_score_t one;
  double *rows = m->rows ? m->rows + 2 * m->tc.h : NULL; /* --rows: single scattering's row means */
  int rc = oct__model_case(prog, &m->tc, &m->sc, m->cam, &m->st, o, 0, 1, &one, rows);
  if (rc != OC_EXIT_OK) return rc;
  double ms_truth = m->tc.mean - one.mean, ms_model = s->mean - one.mean;
  printf(" %.2f | %.2f |", ms_truth / m->tc.mean, ms_model > 0.0 ? ms_truth / ms_model : NAN);
  return OC_EXIT_OK;
}

/* Scores every case with o's numbers (fitted_only: only the fitted set's terms, as a search does);
 * prints a row per case unless quiet. @return the objective, or NaN when a render failed. */
static double oct__model_all(const char *prog, oct__mcase_t *cs, int n, const oct__model_opts_t *o, int print,
                             int fitted_only) {
  double cost = 0.0, worst_rel = 0.0, worst_rmse = 0.0, worst_amb = 0.0;
  int pass = 0;
  for (int i = 0; i < n; i++) {
    oct__mcase_t *m = &cs[i];
    const int fit_sky = (!fitted_only || oct__fitted(m, 1)) && oct__has_sky(m);
    double amb_new = 0.0, amb_old = 0.0; /* image mean under a uniform sky alone, against tc.env */
    m->amb = NAN;
    if (fit_sky) {
      oc_render_desc_t d = oct_truth_case_desc(&m->tc, &m->sc, m->cam);
      if (o->have_fit) d.ms_fit = o->fit;
      if (oct_truth_ambient(&m->tc, &m->st, d, &amb_new) < 0) return NAN;
      d.ms_model = OC_MS_MODEL_OCTAVES;
      d.ms_fit = NULL;
      d.ms_a = d.ms_b = d.ms_c = 0.5f;
      if (print && oct_truth_ambient(&m->tc, &m->st, d, &amb_old) < 0) return NAN;
      amb_new = amb_new / m->tc.env - 1.0;
      amb_old = amb_old / m->tc.env - 1.0;
      m->amb = amb_new;
      cost += (amb_new / 0.05) * (amb_new / 0.05);
      worst_amb = fmax(worst_amb, fabs(amb_new));
    }
    if (fitted_only && !oct__fitted(m, 0)) continue; /* a search renders no sun case it does not fit */
    oct_truth_score_t old = {0}, s;
    int rc = o->legacy && print ? oct__model_case(prog, &m->tc, &m->sc, m->cam, &m->st, o, 1, 0, &old, NULL) : OC_EXIT_OK;
    if (rc == OC_EXIT_OK)
      rc = oct__model_case(prog, &m->tc, &m->sc, m->cam, &m->st, o, 0, 0, &s, m->rows ? m->rows + m->tc.h : NULL);
    if (rc != OC_EXIT_OK) return NAN;
    double bound = fmax(6.0, 2.0 * s.noise8), lim = oct__mean_limit(m);
    int ok = fabs(s.rel) <= lim && s.rmse8 <= bound;
    m->rel = s.rel, m->rmse8 = s.rmse8, m->ok = ok;
    cost += oct__model_cost(&s, lim, bound);
    worst_rel = fmax(worst_rel, fabs(s.rel));
    worst_rmse = fmax(worst_rmse, s.rmse8 / bound);
    pass += ok;
    if (print && !o->quiet) {
      printf("| %s | %g | %g | %.4g ± %.1f %% | %.2f | ", m->name, m->tc.tau, m->tc.albedo, m->tc.mean, 100.0 * s.rel_se,
             s.noise8);
      if (o->legacy) printf("%+.1f %% | %.1f | ", 100.0 * old.rel, old.rmse8);
      printf("%+.1f %% | %.1f | %.1f%s | %+.2f %% (%+.2f %%) |", 100.0 * s.rel, s.rmse8, bound, ok ? "" : " ✗",
             100.0 * amb_new, 100.0 * amb_old);
      if (o->split && oct__model_split(prog, m, o, &s) != OC_EXIT_OK) return NAN;
      printf("\n");
    }
  }
  if (print)
    printf("\n%d cases, %d within bounds; worst |mean error| %.1f %%, worst RMSE / bound %.2f, worst uniform-sky error "
           "%.1f %%\nCOST %.6g\n", n, pass, 100.0 * worst_rel, worst_rmse, 100.0 * worst_amb, cost);
  return cost;
}

/* --rows: where in the image each case's error lies, row by row from the top: the elevation of the row's
 * middle ray above the camera's horizon, the truth's and the model's row means, and with --split single
 * scattering's and k, the factor the row's multiply scattered part lacks. */
static void oct__model_rows(const oct__mcase_t *cs, int n, int split) {
  for (int i = 0; i < n; i++) {
    const oct__mcase_t *m = &cs[i];
    const int h = m->tc.h;
    const double t = tan(0.5 * m->cam.vfov_deg * OC_DEG);
    const oc_dvec3 zen = oc_dnorm(m->cam.pos);
    printf("\nrows of %s\n\n| row | elevation ° | truth | model | error |%s\n|---:|---:|---:|---:|---:|%s\n", m->name,
           split ? " single | k |" : "", split ? "---:|---:|" : "");
    for (int y = 0; y < h; y++) {
      oc_dvec3 dir = oc_dnorm(oc_dmad(m->cam.forward, m->cam.up, t * (1.0 - 2.0 * (y + 0.5) / h)));
      double tr = m->rows[y], mo = m->rows[h + y], sg = m->rows[2 * h + y];
      printf("| %d | %+.1f | %.4g | %.4g | ", y, asin(oc_ddot(dir, zen)) / OC_DEG, tr, mo);
      if (tr > 0.0) printf("%+.1f %% |", 100.0 * (mo / tr - 1.0));
      else printf("— |");
      if (split && mo - sg > 0.0) printf(" %.4g | %.2f |", sg, (tr - sg) / (mo - sg));
      else if (split) printf(" %.4g | — |", sg);
      printf("\n");
    }
  }
}

/* The case's view and shape, from its scene file's name (tests/data/truth/<shape>_<sun>.json). */
static int oct__scene_is(const oct__mcase_t *m, const char *word) {
  const char *slash = strrchr(m->tc.scene, '/');
  return strstr(slash ? slash + 1 : m->tc.scene, word) != NULL;
}

/* The bound on the image mean: ±10 %, or ±20 % at τ 50 and for the silver lining (every case
 * with the sun in front: forward scattering toward the camera). */
static double oct__mean_limit(const oct__mcase_t *m) {
  return m->tc.tau > 20.0 || oct__scene_is(m, "_front") ? 0.2 : 0.1;
}

/* The fitted set of docs/numerics.md: sun behind or in front, albedo 1 or 0.9, τ 1, 5 or 20. The
 * uniform sky's: sun behind, τ 1, 5 or 20. Every other case is held out. */
static int oct__fitted(const oct__mcase_t *m, int sky) {
  double t = m->tc.tau, a = m->tc.albedo;
  int tau_ok = t == 1.0 || t == 5.0 || t == 20.0;
  if (sky) return tau_ok && oct__scene_is(m, "_behind");
  return tau_ok && (a == 1.0 || a == 0.9) && (oct__scene_is(m, "_behind") || oct__scene_is(m, "_front"));
}

/* One summary row over the cases whose scene name holds `shape` and `sun` (NULL: any), in the
 * fitted set (1), the held-out set (0) or either (-1), at optical depth `tau` (0: any). */
static void oct__set_row(const char *label, const oct__mcase_t *cs, int n, const char *shape, const char *sun,
                         int fitted, double tau) {
  double *e = malloc(2 * sizeof(double) * (size_t)(n > 0 ? n : 1)), *r = e + n, worst = 0.0;
  int k = 0, ok = 0;
  if (!e) return;
  for (int i = 0; i < n; i++) {
    const oct__mcase_t *m = &cs[i];
    if ((shape && !oct__scene_is(m, shape)) || (sun && !oct__scene_is(m, sun)) ||
        (fitted >= 0 && oct__fitted(m, 0) != fitted) || (tau > 0.0 && m->tc.tau != tau))
      continue;
    e[k] = fabs(m->rel), r[k] = m->rmse8, ok += m->ok, worst = fmax(worst, e[k]);
    k++;
  }
  if (k) printf("| %s | %d | %d | %.1f %% | %.1f %% | %.1f |\n", label, k, ok, 100.0 * oct_median(e, k), 100.0 * worst,
                oct_median(r, k));
  free(e);
}

/* The report: the fitted set and the held-out set apart, then by view and by τ; the uniform
 * sky's worst error in its own fitted and held-out sets. */
static void oct__model_sets(const oct__mcase_t *cs, int n) {
  printf("\n| set | cases | within both bounds | median \\|mean error\\| | worst | median RMSE 0–255 |\n"
         "|---|---:|---:|---:|---:|---:|\n");
  oct__set_row("fitted", cs, n, NULL, NULL, 1, 0.0);
  oct__set_row("held out", cs, n, NULL, NULL, 0, 0.0);
  static const char *shapes[] = {"sphere", "slab"}, *suns[] = {"_behind", "_beside", "_front"};
  for (int a = 0; a < 2; a++)
    for (int b = 0; b < 3; b++) {
      char label[64];
      snprintf(label, sizeof label, "%s, sun %s", shapes[a], suns[b] + 1);
      oct__set_row(label, cs, n, shapes[a], suns[b], -1, 0.0);
    }
  static const double taus[] = {0.5, 1, 2, 5, 10, 20, 50};
  for (int t = 0; t < 7; t++) {
    char label[32];
    snprintf(label, sizeof label, "τ %g", taus[t]);
    oct__set_row(label, cs, n, NULL, NULL, -1, taus[t]);
  }
  double worst[2] = {-1.0, -1.0};
  for (int i = 0; i < n; i++)
    if (!isnan(cs[i].amb)) {
      int f = oct__fitted(&cs[i], 1);
      worst[f] = fmax(worst[f], fabs(cs[i].amb));
    }
  char w[2][32];
  for (int f = 0; f < 2; f++)
    snprintf(w[f], sizeof w[f], worst[f] >= 0.0 ? "%.1f %%" : "no case", 100.0 * worst[f]);
  if (worst[0] >= 0.0 || worst[1] >= 0.0) printf("\nuniform sky, worst |error|: fitted %s, held out %s\n", w[1], w[0]);
}

/* The eleven numbers in an unbounded space: logits of a, b, c ∈ (0, 1), logarithms of the rest (> 0). */
static void oct__model_unpack(const double x[3 + OC_RENDER_MS_FIT_N], oct__model_opts_t *o) {
  for (int i = 0; i < 3; i++) o->abc[i] = fmin(1.0 / (1.0 + exp(-x[i])), 0.999);
  for (int i = 0; i < OC_RENDER_MS_FIT_N; i++) o->fit[i] = (float)fmin(exp(x[3 + i]), 999.0);
  o->have_abc = o->have_fit = 1;
}

static double oct__model_eval(const char *prog, oct__mcase_t *cs, int n, oct__model_opts_t *o,
                              const double x[3 + OC_RENDER_MS_FIT_N]) {
  oct__model_unpack(x, o);
  double c = oct__model_all(prog, cs, n, o, 0, 1);
  return isnan(c) ? 1e300 : c;
}

/* Nelder-Mead (reflection 1, expansion 2, contraction ½, shrink ½) from the start in o. */
static void oct__model_search(const char *prog, oct__mcase_t *cs, int n, oct__model_opts_t *o, int iters) {
  enum { N = 3 + OC_RENDER_MS_FIT_N };
  double p[N + 1][N], v[N + 1];
  const double fit0[OC_RENDER_MS_FIT_N] = {OCG_MS_CHORD_HALF, OCG_MS_ALBEDO_POWER, OCG_AMBIENT_DEPTH_K,
                                           OCG_MS_DIFFUSE_B,  OCG_MS_DIFFUSE_A,    OCG_MS_FORWARD,
                                           OCG_MS_SUN_ABS,    OCG_MS_SUN_SHARE};
  const double abc0[3] = {OC_RENDER_DEFAULT_MS_A, OC_RENDER_DEFAULT_MS_B, OC_RENDER_DEFAULT_MS_C};
  for (int j = 0; j < 3; j++) {
    double a = o->have_abc ? o->abc[j] : abc0[j];
    p[0][j] = log(a / (1.0 - a));
  }
  for (int j = 0; j < OC_RENDER_MS_FIT_N; j++) p[0][3 + j] = log(fmax(o->have_fit ? o->fit[j] : fit0[j], 1e-6));
  for (int i = 1; i <= N; i++) {
    memcpy(p[i], p[0], sizeof p[0]);
    p[i][i - 1] += 0.7;
  }
  for (int i = 0; i <= N; i++) v[i] = oct__model_eval(prog, cs, n, o, p[i]);
  for (int it = 0; it < iters; it++) {
    for (int i = 1; i <= N; i++) /* sort: best first */
      for (int k = i; k > 0 && v[k] < v[k - 1]; k--) {
        double t[N], tv = v[k];
        memcpy(t, p[k], sizeof t);
        memcpy(p[k], p[k - 1], sizeof t);
        memcpy(p[k - 1], t, sizeof t);
        v[k] = v[k - 1];
        v[k - 1] = tv;
      }
    double c[N] = {0}, xr[N], xe[N], xc[N];
    for (int i = 0; i < N; i++)
      for (int j = 0; j < N; j++) c[j] += p[i][j] / N;
    for (int j = 0; j < N; j++) xr[j] = 2.0 * c[j] - p[N][j];
    double fr = oct__model_eval(prog, cs, n, o, xr);
    if (fr < v[0]) {
      for (int j = 0; j < N; j++) xe[j] = 3.0 * c[j] - 2.0 * p[N][j];
      double fe = oct__model_eval(prog, cs, n, o, xe);
      memcpy(p[N], fe < fr ? xe : xr, sizeof xe);
      v[N] = fe < fr ? fe : fr;
    } else if (fr < v[N - 1]) {
      memcpy(p[N], xr, sizeof xr);
      v[N] = fr;
    } else {
      for (int j = 0; j < N; j++) xc[j] = 0.5 * (c[j] + p[N][j]);
      double fc = oct__model_eval(prog, cs, n, o, xc);
      if (fc < v[N]) {
        memcpy(p[N], xc, sizeof xc);
        v[N] = fc;
      } else {
        for (int i = 1; i <= N; i++) {
          for (int j = 0; j < N; j++) p[i][j] = 0.5 * (p[0][j] + p[i][j]);
          v[i] = oct__model_eval(prog, cs, n, o, p[i]);
        }
      }
    }
    if (it % 10 == 0) fprintf(stderr, "search: iteration %d, objective %.4g\n", it, v[0]);
  }
  int best = 0;
  for (int i = 1; i <= N; i++)
    if (v[i] < v[best]) best = i;
  oct__model_unpack(p[best], o);
  printf("search: %d iterations, objective on the fitted set %.6g: --abc %.4f,%.4f,%.4f "
         "--fit %.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n\n", iters, v[best], o->abc[0], o->abc[1], o->abc[2], o->fit[0],
         o->fit[1], o->fit[2], o->fit[3], o->fit[4], o->fit[5], o->fit[6], o->fit[7]);
}

/* --fit D,Q,K,BD,AD,B,S,G and --abc A,B,C: eight or three numbers. */
static int opt_numbers(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  oct__model_opts_t *m = base;
  int fit = !strcmp(o->name, "fit"), want = fit ? OC_RENDER_MS_FIT_N : 3;
  double v[OC_RENDER_MS_FIT_N];
  int got = 0, used = 0;
  const char *p = text;
  for (; got < want && sscanf(p, got ? ",%lf%n" : "%lf%n", &v[got], &used) == 1; got++) p += used;
  if (got != want || *p != '\0') /* exactly `want` numbers, nothing after */
    return oc_cli_fail(prog, -1, "--%s wants %d comma-separated numbers", o->name, want);
  if (fit) {
    for (int i = 0; i < OC_RENDER_MS_FIT_N; i++) m->fit[i] = (float)v[i];
    m->have_fit = 1;
  } else {
    memcpy(m->abc, v, sizeof m->abc);
    m->have_abc = 1;
  }
  return 0;
}

/* --oracle view | shL. */
static int opt_oracle(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  oct__model_opts_t *m = base;
  int l = -1, used = 0;
  if (strcmp(text, "view") != 0 &&
      !(sscanf(text, "sh%d%n", &l, &used) == 1 && text[used] == '\0' && l >= 0 && l <= OCT_ORACLE_MAX_LMAX))
    return oc_cli_fail(prog, -1, "--%s: expected view or sh0..sh%d, got \"%s\"", o->name, OCT_ORACLE_MAX_LMAX, text);
  m->oracle.lmax = l;
  m->have_oracle = 1;
  return 0;
}

static const oc_cli_opt_t model_opts[] = {
    {.name = "fit", .type = OC_CLI_CUSTOM, .parse = opt_numbers, .arg = "D,Q,K,BD,AD,B,S,G", .def_note = "march.h's",
     .help = "override march.h's fitted constants: chord half-depth, albedo power, ambient depth, diffuse weight, "
             "diffuse decay, the half-depth's shrink toward the sun, absorption along the sun's path, the sun "
             "path's share"},
    {.name = "abc", .type = OC_CLI_CUSTOM, .parse = opt_numbers, .arg = "A,B,C", .def_note = "the scene's",
     .help = "octave factors"},
    OCT_FLAG(oct__model_opts_t, legacy, "legacy", "also score the plain octaves (the model before the fit)"),
    OCT_FLAG(oct__model_opts_t, quiet, "quiet", "only the summary and the fit objective"),
    OCT_FLAG(oct__model_opts_t, rows, "rows", "also print, per case, each image row's mean in the truth and the "
             "model (and with --split single scattering's): where in the image the error lies"),
    OCT_FLAG(oct__model_opts_t, split, "split", "also render each case with single scattering alone and print "
             "the truth's multiply scattered share and k, the factor the model's multiply scattered part lacks"),
    OCT_INT_NOTE(oct__model_opts_t, search, "search", "N", 1, 100000, "none", "N Nelder-Mead iterations on the "
        "eleven numbers from the given (or default) start, scored on the fitted set alone (docs/numerics.md); "
        "prints the best --abc and --fit, then scores every case with them"),
    {.name = "oracle", .type = OC_CLI_CUSTOM, .parse = opt_oracle, .arg = "MODE", .def_note = "none",
     .help = "replace the model's multiply scattered light by the Monte Carlo kernel's, traced at lattice points "
             "around the cloud: view, exact toward the view; shL, the incoming light cut to spherical harmonics of "
             "degree L (0..8)"},
    OCT_INT(oct__model_opts_t, oracle_cells, "oracle-cells", "N", 2, 256, "32",
            "lattice cells across the case's length (sphere diameter, slab thickness)"),
    OCT_INT(oct__model_opts_t, oracle_paths, "oracle-paths", "N", 1, 1000000, "128", "paths per lattice point"),
    OCT_INT(oct__model_opts_t, threads, "threads", "N", 1, 256, "2", "threads tracing the lattice points"),
    OCT_OPTS_END};

OCT_SPEC(model,
         "The cloud model against stored truth images (FILE... from `overcast-bench truth --save`): errors, fit\n"
         "objective.",
         model_opts, .synopsis = "[options] FILE...");

int oct_bench_model(const char *prog, int argc, char **argv) {
  oct__model_opts_t o = {0};
  int first = argc; /* the first truth file */
  int r = oc_cli_parse(&oct_bench_model_spec, argc, argv, &o, NULL, &first);
  if (r) return r > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  const long iters = o.search;
  if (iters > 0 && o.have_oracle) return oc_cli_fail(prog, OC_EXIT_USAGE, "model: --oracle does not go with --search");
  int n = argc - first;
  if (n <= 0) return oc_cli_fail(prog, OC_EXIT_USAGE, "model: give truth files (overcast-bench truth --save)");
  oct__mcase_t *cs = calloc((size_t)n, sizeof *cs);
  if (!cs) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  int loaded = 0, rc = OC_EXIT_OK;
  for (; loaded < n; loaded++) {
    oct__mcase_t *m = &cs[loaded];
    char why[1024];
    const char *path = argv[first + loaded], *slash = strrchr(path, '/');
    m->name = slash ? slash + 1 : path;
    if (oct_truth_case_load(&m->tc, path, why, sizeof why) < 0) {
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      break;
    }
    if (oct_truth_case_state(&m->tc, NULL, &m->sc, &m->cam, &m->st, why, sizeof why) < 0) {
      oct_truth_case_free(&m->tc);
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
      break;
    }
    if (o.rows && !(m->rows = calloc(3 * (size_t)m->tc.h, sizeof *m->rows))) {
      loaded++; /* freed below with the others */
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
      break;
    }
    for (int y = 0; m->rows && y < m->tc.h; y++) { /* the truth's row means: what the model's are held to */
      for (int x = 0; x < m->tc.w; x++) m->rows[y] += m->tc.L[(size_t)y * (size_t)m->tc.w + (size_t)x];
      m->rows[y] /= m->tc.w;
    }
  }
  int fitted = 0;
  for (int i = 0; i < loaded; i++) fitted += oct__fitted(&cs[i], 0) || (oct__fitted(&cs[i], 1) && oct__has_sky(&cs[i]));
  if (rc == OC_EXIT_OK && iters > 0 && fitted == 0)
    rc = oc_cli_fail(prog, OC_EXIT_USAGE, "model --search: none of the files is in the fitted set (docs/numerics.md)");
  if (rc == OC_EXIT_OK) {
    if (iters > 0) oct__model_search(prog, cs, n, &o, (int)iters);
    if (!o.quiet)
      printf("| case | τ | albedo | truth mean ± rel. SE | seed RMSE | %snew: mean error | RMSE 0–255 | bound | uniform sky: "
             "new (unoccluded) |%s\n|---|---:|---:|---:|---:|%s---:|---:|---:|---:|%s\n",
             o.legacy ? "old: mean error | RMSE 0–255 | " : "", o.split ? " multiply scattered share | k |" : "",
             o.legacy ? "---:|---:|" : "", o.split ? "---:|---:|" : "");
    if (isnan(oct__model_all(prog, cs, n, &o, 1, 0))) rc = OC_EXIT_RUNTIME;
    else oct__model_sets(cs, n);
    if (rc == OC_EXIT_OK && o.rows) oct__model_rows(cs, n, o.split && !o.quiet); /* --quiet renders no split */
  }
  for (int i = 0; i < loaded; i++) {
    oc_state_free(&cs[i].st);
    oc_scene_free(&cs[i].sc);
    oct_truth_case_free(&cs[i].tc);
    free(cs[i].rows);
  }
  free(cs);
  return rc;
}
