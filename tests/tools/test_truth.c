/* test_truth.c — the real-time cloud model against stored Monte Carlo truth images.
 *
 * tests/data/truth holds 32×18 truth images made by `overcast-bench truth --save` (the parameters
 * lead each file; the scenes beside them) and the sun positions of scripts/truth_cases.sh. Each case
 * is voxelized and rendered as the truth was and held to the error the fitted model reaches
 * (docs/numerics.md, "The real-time model against the truth") plus a margin for float differences
 * between machines; the octaves before the fit fail these bounds, which the test checks too, so a
 * regression to them cannot pass. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include <cmocka.h>

#include "test_main.h"
#include "truth.h"

typedef struct {
  const char *file;
  double rel;   /**< bound on |image-mean error| */
  double rmse8; /**< bound on the RMSE 0–255 */
} case_t;

/* Measured with the fitted model (docs/numerics.md): mean error, RMSE → bound; before the diffuse
 * part's own chord factor H(D) in brackets (that model fails six of these seven bounds). */
static const case_t cases[] = {
    {"sphere_behind_a1-tau1.txt", 0.18, 6.0},    /* −14.2 %, 3.6 [+19.4 %] (the octaves: +401 %, 23.2) */
    {"sphere_behind_a1-tau5.txt", 0.09, 11.0},   /* +5.3 %, 8.2 [+12.3 %] (+62 %, 17.4) */
    {"sphere_behind_a1-tau20.txt", 0.05, 11.0},  /* −1.4 %, 9.1 [−14.8 %] (−51 %, 25.8) */
    {"sphere_front_a1-tau20.txt", 0.15, 20.0},   /* +11.4 %, 17.4 [+10.6 %] (−56 %, 58.1) */
    {"sphere_beside_a0.99-tau2.txt", 0.14, 7.0}, /* held out: −10.2 %, 3.8 [+24.0 %] (+276 %, 23.1) */
    {"slab_behind_a1-tau5.txt", 0.08, 30.0},     /* +4.8 %, 26.4 [−12.5 %] (−52 %, 46.6) */
    {"slab_behind_a1-tau20.txt", 0.10, 20.0},    /* −7.2 %, 15.5 [−25.9 %] (−73 %, 70.0) */
};
enum { NCASES = sizeof cases / sizeof cases[0] };

/* A stored case, its scene, camera and voxelized state. */
typedef struct {
  oct_truth_case_t tc;
  oc_scene_t sc;
  oc_state_t st;
  oc_camera_t cam;
} loaded_t;

static void load_case(const char *file, loaded_t *c) {
  const char *root = getenv("OC_SOURCE_DIR");
  char path[1024], why[1024];
  snprintf(path, sizeof path, "%s/tests/data/truth/%s", root ? root : ".", file);
  if (oct_truth_case_load(&c->tc, path, why, sizeof why) < 0) fail_msg("%s", why);
  if (oct_truth_case_state(&c->tc, root ? root : ".", &c->sc, &c->cam, &c->st, why, sizeof why) < 0) fail_msg("%s", why);
}

static void free_case(loaded_t *c) {
  oc_state_free(&c->st);
  oc_scene_free(&c->sc);
  oct_truth_case_free(&c->tc);
}

static int render_case(const char *file, int legacy, oct_truth_score_t *s) {
  loaded_t c;
  load_case(file, &c);
  oct_truth_case_t tc = c.tc;
  oc_render_desc_t d = oct_truth_case_desc(&tc, &c.sc, c.cam);
  if (legacy) { /* the model before the fit, with its defaults */
    d.ms_model = OC_MS_MODEL_OCTAVES;
    d.ms_a = d.ms_b = d.ms_c = 0.5f;
  }
  oc_image_t img = {0};
  assert_int_equal(oc_image_alloc(&img, tc.w, tc.h), 0);
  oc_render_stats_t rs;
  assert_int_equal(oc_render_state(&c.st, &d, &img, &rs), 0);
  assert_int_equal(rs.nonfinite, 0);
  assert_int_equal(oct_truth_score(&tc, &img, s), 0);
  oc_image_free(&img);
  free_case(&c);
  return 0;
}

static void test_truth__model_within_measured_bounds(void **state) {
  (void)state;
  int old_fails = 0;
  for (int i = 0; i < NCASES; i++) {
    oct_truth_score_t s, o;
    render_case(cases[i].file, 0, &s);
    render_case(cases[i].file, 1, &o);
    int old_ok = fabs(o.rel) <= cases[i].rel && o.rmse8 <= cases[i].rmse8;
    old_fails += !old_ok;
    printf("%-30s model %+6.1f %% RMSE %5.1f | octaves %+7.1f %% RMSE %5.1f | bounds ±%.0f %%, %.0f | truth seed RMSE %.1f\n",
           cases[i].file, 100.0 * s.rel, s.rmse8, 100.0 * o.rel, o.rmse8, 100.0 * cases[i].rel, cases[i].rmse8, s.noise8);
    assert_true(fabs(s.rel) <= cases[i].rel);
    assert_true(s.rmse8 <= cases[i].rmse8);
  }
  assert_int_equal(old_fails, NCASES); /* every bound would catch a return to the old octaves */
}

/* Sky ambient under a uniform sky (the truth's env line: image mean per unit sky radiance, no sun)
 * against the occluded ambient of shaders/march.h. k and c were fitted on τ 1, 5, 20; τ 10 and 50
 * are held out (docs/numerics.md, "Sky ambient under a uniform sky"). The unoccluded ambient (the
 * legacy model) fails every bound: +14 % to +123 %. */
static const case_t ambient_cases[] = {
    {"slab_behind_a0.9-tau1.txt", 0.05, 0},   /* +3.6 % (unoccluded +24 %) */
    {"slab_behind_a0.9-tau5.txt", 0.05, 0},   /* −0.2 % (+74 %) */
    {"slab_behind_a0.9-tau20.txt", 0.05, 0},  /* −3.1 % (+123 %) */
    {"slab_behind_a0.99-tau10.txt", 0.05, 0}, /* held out: −4.1 % (+14 %) */
    {"slab_behind_a0.99-tau50.txt", 0.09, 0}, /* held out: +7.3 % (+38 %): past the issue's ±5 % */
};

static void test_truth__ambient_under_uniform_sky(void **state) {
  (void)state;
  for (size_t i = 0; i < sizeof ambient_cases / sizeof ambient_cases[0]; i++) {
    loaded_t c;
    load_case(ambient_cases[i].file, &c);
    assert_true(c.tc.env > 0.0);
    oc_render_desc_t d = oct_truth_case_desc(&c.tc, &c.sc, c.cam);
    double model, old;
    assert_int_equal(oct_truth_ambient(&c.tc, &c.st, d, &model), 0);
    d.ms_model = OC_MS_MODEL_OCTAVES;
    assert_int_equal(oct_truth_ambient(&c.tc, &c.st, d, &old), 0);
    double rel = model / c.tc.env - 1.0, rel_old = old / c.tc.env - 1.0;
    printf("%-30s ambient %+6.2f %% | unoccluded %+7.2f %% | bound ±%.0f %% | truth %.4g ± %.2f %%\n", ambient_cases[i].file,
           100.0 * rel, 100.0 * rel_old, 100.0 * ambient_cases[i].rel, c.tc.env, 100.0 * c.tc.env_se / c.tc.env);
    assert_true(fabs(rel) <= ambient_cases[i].rel);
    assert_true(fabs(rel_old) > ambient_cases[i].rel);
    free_case(&c);
  }
}

/* A stored file that is cut short or names no scene is an error, not a silent zero image. */
static void test_truth__bad_files_rejected(void **state) {
  (void)state;
  char path[] = "/tmp/oct_truth_XXXXXX", why[512];
  int fd = mkstemp(path);
  assert_true(fd >= 0);
  FILE *f = fdopen(fd, "w");
  fprintf(f, "scene tests/data/truth/sphere_behind.json\ntau 5\nsize 2 2\nalbedo 1\nbackground 0\nmean 1 0\npixels\n1 0\n");
  fclose(f);
  oct_truth_case_t tc;
  assert_true(oct_truth_case_load(&tc, path, why, sizeof why) < 0);
  f = fopen(path, "w");
  fprintf(f, "tau 5\nsize 1 1\nalbedo 1.5\npixels\n1 0\n");
  fclose(f);
  assert_true(oct_truth_case_load(&tc, path, why, sizeof why) < 0);
  remove(path);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_truth__model_within_measured_bounds),
             cmocka_unit_test(test_truth__ambient_under_uniform_sky),
             cmocka_unit_test(test_truth__bad_files_rejected))
