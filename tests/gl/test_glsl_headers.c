/* test_glsl_headers.c — the shared shaders/ headers compile as GLSL 4.50 and evaluate like their C build.
 *
 * 1. optics_matches_c: oc_port.h + optics.h in a compute shader that evaluates every optics function on
 *    a grid of inputs into an SSBO; each result is compared with the C (float) build of the same header.
 *    The case bodies are written once (OPTICS_CASES) in the common subset of C and GLSL and used for
 *    both: stringified into the kernel's switch and pasted into the C evaluator.
 * 2. all_headers_compile: every shared header that exists (oc_port.h, units.h, optics.h, sampling.h,
 *    brick.h, atmosphere.h in that order, then any other header in shaders/, alphabetically) in one kernel;
 *    the list of compiled headers is printed.
 * 3. errors_name_file_and_line: a header with a deliberate error, and a kernel with one, give logs that
 *    name the file and line of the error (ocv_gl_src_t maps GLSL lines back to their segment).
 * 4. headers_keep_their_line_numbers: a probe error appended to each header is reported on the header's
 *    last line + 1, i.e. no construct inside it (a function-like macro invocation spanning lines, which
 *    Mesa's glcpp joins) shifts GLSL error lines. Fails for oc_port.h and optics.h; other headers'
 *    drift is printed as a warning (their owners fix them).
 * 5. log_translation: the mapping itself on canned Mesa and NVIDIA logs (no GL needed).
 *
 * Tolerances: |gpu - c| <= rtol |c| + atol per function. GLSL allows exp/exp2/log/pow errors of
 * (3 + 2|x|) ulp and Mesa's llvmpipe uses polynomial approximations, so functions built on them get a
 * looser rtol than the purely algebraic ones; atol covers results the GPU flushes to zero (denormals).
 * The worst error per function is printed. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <dirent.h> /* opendir: find every header in shaders/ */
#include <math.h>   /* fabs, isfinite */
#include <stdio.h>  /* printf, fopen */
#include <stdlib.h> /* malloc, mkdtemp, qsort */
#include <string.h> /* strstr, strcmp */
#include <unistd.h> /* rmdir, unlink */

#include "gl/gl_harness.h" /* client/gl's context and source builder; skip without GL */
#include "optics.h"        /* the C build the GLSL results are compared with */

/* ---- One list of cases for both languages ------------------------------------------------------------- */
/* X(id, name, rtol, atol, body): the body reads vec4 a, writes vec4 r, and is valid C (ocg_vec4 is a
 * struct with x, y, z, w) and GLSL alike; vec3 results are copied component by component. */
#define OPTICS_CASES(X)                                                                                   \
  X(0, "phase_hg", 1e-5, 0, r.x = ocg_phase_hg(a.x, a.y);)                                                \
  X(1, "phase_rayleigh", 1e-5, 0, r.x = ocg_phase_rayleigh(a.x);)                                         \
  X(2, "phase_cornette_shanks", 1e-5, 0, r.x = ocg_phase_cornette_shanks(a.x, a.y);)                      \
  X(3, "phase_draine", 1e-5, 0, r.x = ocg_phase_draine(a.x, a.y, a.z);)                                   \
  X(4, "phase_hg_draine", 1e-5, 0, r.x = ocg_phase_hg_draine(a.x);)                                       \
  X(5, "phase_hg_draine_scaled", 1e-5, 0, r.x = ocg_phase_hg_draine_scaled(a.x, a.y);)                    \
  X(6, "one_minus_exp", 2e-5, 0, r.x = ocg_one_minus_exp(a.x);)                                           \
  X(7, "one_minus_exp_div", 2e-5, 0, r.x = ocg_one_minus_exp_div(a.x);)                                   \
  X(8, "transmittance", 2e-5, 1e-30, r.x = ocg_transmittance(a.x, a.y);)                                  \
  X(9, "segment_weight", 2e-5, 0, r.x = ocg_segment_weight(a.x, a.y);)                                    \
  X(10, "segment_weight3", 2e-5, 0, ocg_vec3 v = ocg_segment_weight3(ocg_v3(a.x, a.y, a.z), a.w);         \
    r.x = v.x; r.y = v.y; r.z = v.z;)                                                                     \
  X(11, "beer_powder", 2e-5, 1e-30, r.x = ocg_beer_powder(a.x);)                                          \
  X(12, "ms_octaves n=1", 2e-5, 1e-30, r.x = ocg_ms_octaves(a.x, a.y, a.z, a.w, OCG_R(0.5), 1);)          \
  X(13, "ms_octaves n=8", 2e-5, 1e-30, r.x = ocg_ms_octaves(a.x, a.y, a.z, a.w, OCG_R(0.5), 8);)          \
  X(14, "sigma_t_liquid", 1e-6, 0, r.x = ocg_sigma_t_liquid(a.x, a.y);)                                   \
  X(15, "sigma_t_ice", 1e-6, 0, r.x = ocg_sigma_t_ice(a.x, a.y);)                                         \
  X(16, "aces_fit", 1e-5, 1e-6, ocg_vec3 v = ocg_aces_fit(ocg_v3(a.x, a.y, a.z));                         \
    r.x = v.x; r.y = v.y; r.z = v.z;)                                                                     \
  X(17, "srgb_encode", 2e-5, 0, r.x = ocg_srgb_encode(a.x);)                                              \
  X(18, "srgb_encode3", 2e-5, 0, ocg_vec3 v = ocg_srgb_encode3(ocg_v3(a.x, a.y, a.z));                    \
    r.x = v.x; r.y = v.y; r.z = v.z;)
#define N_FUNCS 19

static const struct { const char *name; double rtol, atol; } func_info[N_FUNCS] = {
#define X(id, name, rtol, atol, ...) [id] = {name, rtol, atol},
    OPTICS_CASES(X)
#undef X
};

static ocg_vec4 eval_c(int fn, ocg_vec4 a) {
  ocg_vec4 r = ocg_v4(OCG_R(0.0), OCG_R(0.0), OCG_R(0.0), OCG_R(0.0));
  switch (fn) {
#define X(id, name, rtol, atol, ...) \
  case id: {                         \
    __VA_ARGS__                      \
  } break;
    OPTICS_CASES(X)
#undef X
  default: break;
  }
  return r;
}

/* The kernel: the same case bodies as text. */
static char *make_kernel(void) {
  static const char head[] =
      "layout(local_size_x = 64) in;\n"
      "layout(std430, binding = 0) readonly buffer OcIn { vec4 oc_in[]; };\n"
      "layout(std430, binding = 1) readonly buffer OcFn { int oc_fn[]; };\n"
      "layout(std430, binding = 2) writeonly buffer OcOut { vec4 oc_out[]; };\n"
      "layout(location = 0) uniform int oc_count;\n"
      "void main() {\n"
      "  int i = int(gl_GlobalInvocationID.x);\n"
      "  if (i >= oc_count) return;\n"
      "  vec4 a = oc_in[i];\n"
      "  vec4 r = vec4(0.0);\n"
      "  switch (oc_fn[i]) {\n";
  static const char *const cases[] = {
#define X(id, name, rtol, atol, ...) "  case " #id ": { " #__VA_ARGS__ " } break;\n",
      OPTICS_CASES(X)
#undef X
  };
  static const char tail[] = "  default: break;\n  }\n  oc_out[i] = r;\n}\n";
  size_t n = sizeof head + sizeof tail;
  for (size_t i = 0; i < N_FUNCS; ++i) n += strlen(cases[i]);
  char *k = malloc(n);
  if (!k) return NULL;
  strcpy(k, head);
  for (size_t i = 0; i < N_FUNCS; ++i) strcat(k, cases[i]);
  strcat(k, tail);
  return k;
}

/* ---- Input grid ---------------------------------------------------------------------------------------- */

typedef struct {
  ocg_vec4 *in;
  int *fn;
  int n, cap;
} cases_t;

static void add(cases_t *c, int fn, float x, float y, float z, float w) {
  if (c->n == c->cap) {
    c->cap = c->cap ? c->cap * 2 : 1024;
    c->in = realloc(c->in, sizeof *c->in * (size_t)c->cap);
    c->fn = realloc(c->fn, sizeof *c->fn * (size_t)c->cap);
    assert_non_null(c->in);
    assert_non_null(c->fn);
  }
  c->in[c->n] = ocg_v4(x, y, z, w);
  c->fn[c->n] = fn;
  c->n++;
}

#define LEN(a) (int)(sizeof(a) / sizeof((a)[0]))

static void build_cases(cases_t *c) {
  float mus[48];
  int nmu = 0;
  for (int k = -16; k <= 16; ++k) mus[nmu++] = (float)k / 16.0f;
  const float extra_mu[] = {0.999f, 0.99999f, 0.9999999f, -0.999f, -0.99999f, 0.3f, -0.7f};
  for (int k = 0; k < LEN(extra_mu); ++k) mus[nmu++] = extra_mu[k];
  const float gs[] = {-0.999f, -0.9f, -0.5f, 0.0f, 0.3f, 0.76f, 0.9f, 0.99f, 0.999f};
  const float alphas[] = {0.0f, 1.0f, (float)OCG_HGD_ALPHA};
  const float scales[] = {0.0f, 0.3f, 0.7f, 1.0f};
  const float xs[] = {0.0f, 1e-18f, 1e-12f, 1e-8f, 1e-5f, 1e-3f, 0.1f, 0.3f, 0.49f, 0.5f, 0.51f, 0.7f, 1.0f,
                      2.0f, 5.0f, 10.0f, 30.0f, 80.0f};
  const float sigmas[] = {0.0f, 1e-12f, 1e-6f, 1e-3f, 0.05f, 1.0f, 1e3f, 1e9f};
  const float ds[] = {1e-6f, 1e-3f, 0.5f, 1.0f, 10.0f, 250.0f, 1e4f, 1e7f};
  for (int i = 0; i < nmu; ++i) {
    add(c, 1, mus[i], 0, 0, 0);
    add(c, 4, mus[i], 0, 0, 0);
    for (int j = 0; j < LEN(gs); ++j) {
      add(c, 0, mus[i], gs[j], 0, 0);
      add(c, 2, mus[i], gs[j], 0, 0);
      for (int k = 0; k < LEN(alphas); ++k) add(c, 3, mus[i], gs[j], alphas[k], 0);
    }
    for (int j = 0; j < LEN(scales); ++j) add(c, 5, mus[i], scales[j], 0, 0);
  }
  for (int i = 0; i < LEN(xs); ++i) {
    add(c, 6, xs[i], 0, 0, 0);
    add(c, 7, xs[i], 0, 0, 0);
    add(c, 11, xs[i], 0, 0, 0);
  }
  for (int i = 0; i < LEN(sigmas); ++i)
    for (int j = 0; j < LEN(ds); ++j) {
      add(c, 8, sigmas[i], ds[j], 0, 0);
      add(c, 9, sigmas[i], ds[j], 0, 0);
      add(c, 10, sigmas[i], sigmas[(i + 3) % LEN(sigmas)], sigmas[(i + 5) % LEN(sigmas)], ds[j]);
    }
  const float taus[] = {0.0f, 0.01f, 0.1f, 1.0f, 5.0f, 20.0f, 50.0f};
  const float oct_mu[] = {-1.0f, 0.0f, 0.7f, 0.99f, 1.0f};
  const float ab[][2] = {{0.5f, 0.5f}, {0.25f, 0.7f}, {1.0f, 1.0f}};
  for (int i = 0; i < LEN(taus); ++i)
    for (int j = 0; j < LEN(oct_mu); ++j)
      for (int k = 0; k < LEN(ab); ++k) {
        add(c, 12, taus[i], oct_mu[j], ab[k][0], ab[k][1]);
        add(c, 13, taus[i], oct_mu[j], ab[k][0], ab[k][1]);
      }
  const float wc[] = {0.0f, 1e-6f, 1e-4f, 1e-3f, 5e-3f};
  const float rho[] = {0.4f, 1.225f};
  for (int i = 0; i < LEN(wc); ++i)
    for (int j = 0; j < LEN(rho); ++j) {
      add(c, 14, wc[i], rho[j], 0, 0);
      add(c, 15, wc[i], rho[j], 0, 0);
    }
  const float lum[] = {0.0f, 1e-3f, 0.01f, 0.1f, 0.18f, 0.5f, 1.0f, 2.0f, 8.0f, 100.0f};
  const float hue[][3] = {{1, 1, 1}, {1, 0.8f, 0.6f}, {0.5f, 0.7f, 1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int i = 0; i < LEN(lum); ++i)
    for (int j = 0; j < LEN(hue); ++j) add(c, 16, lum[i] * hue[j][0], lum[i] * hue[j][1], lum[i] * hue[j][2], 0);
  for (int i = 0; i <= 100; ++i) add(c, 17, (float)i / 100.0f, 0, 0, 0);
  const float knee[] = {0.003f, 0.0031308f, 0.0032f, 1e-5f, -0.5f, 2.0f};
  for (int i = 0; i < LEN(knee); ++i) add(c, 17, knee[i], 0, 0, 0);
  for (int i = 0; i <= 20; ++i) add(c, 18, (float)i / 20.0f, 1.0f - (float)i / 20.0f, 0.0031308f * (float)i, 0);
}

/* ---- Tests --------------------------------------------------------------------------------------------- */

static const char *const optics_headers[] = {"shaders/oc_port.h", "shaders/optics.h"};

static void test_glsl__optics_matches_c(void **state) {
  (void)state;
  ocv_gl_context_t *ctx = NULL;
  OCGL_REQUIRE_CONTEXT(ctx);
  ocgl_print_info(ctx);

  ocv_gl_src_t src;
  assert_int_equal(ocv_gl_src_init(&src, NULL), 0);
  for (int i = 0; i < LEN(optics_headers); ++i) ocgl_add_file(&src, optics_headers[i]);
  char *kernel = make_kernel();
  assert_non_null(kernel);
  ocv_gl_src_add(&src, "<kernel>", kernel);
  free(kernel);
  char *log = NULL;
  GLuint prog = ocv_gl_src_compile(&src, &log);
  if (!prog) fail_msg("optics kernel does not compile:\n%s", log ? log : "(no log)");
  if (log) printf("compiler said:\n%s", log);
  free(log);

  cases_t c = {0};
  build_cases(&c);
  size_t in_bytes = sizeof(float) * 4 * (size_t)c.n;
  float *in = malloc(in_bytes), *out = calloc((size_t)c.n * 4, sizeof(float));
  assert_non_null(in);
  assert_non_null(out);
  for (int i = 0; i < c.n; ++i) {
    in[4 * i + 0] = c.in[i].x;
    in[4 * i + 1] = c.in[i].y;
    in[4 * i + 2] = c.in[i].z;
    in[4 * i + 3] = c.in[i].w;
  }
  GLuint buf[3];
  glCreateBuffers(3, buf);
  glNamedBufferStorage(buf[0], (GLsizeiptr)in_bytes, in, 0);
  glNamedBufferStorage(buf[1], (GLsizeiptr)(sizeof(int) * (size_t)c.n), c.fn, 0);
  glNamedBufferStorage(buf[2], (GLsizeiptr)in_bytes, NULL, GL_DYNAMIC_STORAGE_BIT);
  for (GLuint b = 0; b < 3; ++b) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b, buf[b]);
  glUseProgram(prog);
  glUniform1i(0, c.n);
  glDispatchCompute((GLuint)(c.n + 63) / 64, 1, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glGetNamedBufferSubData(buf[2], 0, (GLsizeiptr)in_bytes, out);
  assert_int_equal(glGetError(), GL_NO_ERROR);

  double worst[N_FUNCS] = {0}, worst_abs[N_FUNCS] = {0};
  int count[N_FUNCS] = {0}, bad = 0;
  for (int i = 0; i < c.n; ++i) {
    int fn = c.fn[i];
    ocg_vec4 want = eval_c(fn, c.in[i]);
    const float w[4] = {want.x, want.y, want.z, want.w};
    count[fn]++;
    for (int k = 0; k < 4; ++k) {
      double g = out[4 * i + k], e = w[k], diff = fabs(g - e);
      double rel = diff / fmax(fabs(e), 1e-30);
      if (!isfinite(g) || diff > func_info[fn].rtol * fabs(e) + func_info[fn].atol) {
        if (bad++ < 20)
          printf("  MISMATCH %s(%g, %g, %g, %g)[%d]: GLSL %.9g, C %.9g (rel %.3g)\n", func_info[fn].name,
                 (double)c.in[i].x, (double)c.in[i].y, (double)c.in[i].z, (double)c.in[i].w, k, g, e, rel);
      }
      if (diff > func_info[fn].atol && rel > worst[fn]) worst[fn] = rel;
      if (diff > worst_abs[fn]) worst_abs[fn] = diff;
    }
  }
  printf("GLSL vs C (float), %d inputs:\n| function | inputs | worst rel. diff | worst abs. diff | rtol |\n"
         "|---|---:|---:|---:|---:|\n", c.n);
  for (int f = 0; f < N_FUNCS; ++f)
    printf("| %s | %d | %.2e | %.2e | %.0e |\n", func_info[f].name, count[f], worst[f], worst_abs[f], func_info[f].rtol);
  glDeleteBuffers(3, buf);
  glDeleteProgram(prog);
  free(in);
  free(out);
  free(c.in);
  free(c.fn);
  ocv_gl_src_free(&src);
  ocv_gl_context_free(ctx);
  assert_int_equal(bad, 0);
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(const char *const *)a, *(const char *const *)b); }

/* The shared headers that exist, in concatenation order: the known ones first (oc_port.h leads, each
 * header includes only oc_port.h), then any other header in shaders/ alphabetically, so a new header
 * is compile-checked without editing this test. Returns the count; names are malloc'd. */
#define MAX_HEADERS 48
static int collect_headers(char *names[MAX_HEADERS]) {
  static const char *const order[] = {"oc_port.h", "units.h", "optics.h", "sampling.h", "brick.h", "atmosphere.h", "march.h"};
  int n = 0;
  for (int i = 0; i < LEN(order); ++i) {
    char rel[256];
    snprintf(rel, sizeof rel, "shaders/%s", order[i]);
    if (ocgl_file_exists(rel)) names[n++] = strdup(rel);
  }
  char dir[1024];
  ocgl_path(dir, sizeof dir, "shaders");
  DIR *d = opendir(dir);
  assert_non_null(d);
  char *others[MAX_HEADERS];
  int no = 0;
  for (struct dirent *e; (e = readdir(d)) != NULL;) {
    size_t l = strlen(e->d_name);
    if (l < 3 || strcmp(e->d_name + l - 2, ".h") != 0) continue;
    int known = 0;
    for (int i = 0; i < LEN(order); ++i) known |= strcmp(e->d_name, order[i]) == 0;
    if (!known && n + no < MAX_HEADERS) {
      char rel[512];
      snprintf(rel, sizeof rel, "shaders/%s", e->d_name);
      others[no++] = strdup(rel);
    }
  }
  closedir(d);
  qsort(others, (size_t)no, sizeof others[0], cmp_str);
  for (int i = 0; i < no; ++i) names[n++] = others[i];
  return n;
}

static void test_glsl__all_shared_headers_compile(void **state) {
  (void)state;
  ocv_gl_context_t *ctx = NULL;
  OCGL_REQUIRE_CONTEXT(ctx);
  char *names[MAX_HEADERS];
  int n = collect_headers(names);
  ocv_gl_src_t src;
  assert_int_equal(ocv_gl_src_init(&src, NULL), 0);
  printf("compiling as one GLSL 4.50 compute shader:");
  for (int i = 0; i < n; ++i) {
    printf(" %s", names[i]);
    ocgl_add_file(&src, names[i]);
  }
  printf("\n");
  ocv_gl_src_add(&src, "<kernel>", "layout(local_size_x = 1) in;\nvoid main() {}\n");
  char *log = NULL;
  GLuint prog = ocv_gl_src_compile(&src, &log);
  if (log) printf("compiler said:\n%s", log);
  int ok = prog != 0;
  if (prog) glDeleteProgram(prog);
  for (int i = 0; i < n; ++i) free(names[i]);
  ocv_gl_src_free(&src);
  ocv_gl_context_free(ctx);
  if (!ok) fail_msg("shared headers do not compile as GLSL:\n%s", log ? log : "(no log)");
  free(log);
}

static void test_glsl__headers_keep_their_line_numbers(void **state) {
  (void)state;
  ocv_gl_context_t *ctx = NULL;
  OCGL_REQUIRE_CONTEXT(ctx);
  char *names[MAX_HEADERS];
  int n = collect_headers(names), bad_own = 0;
  for (int h = 0; h < n; ++h) {
    ocv_gl_src_t src;
    assert_int_equal(ocv_gl_src_init(&src, NULL), 0);
    for (int i = 0; i < h; ++i) ocgl_add_file(&src, names[i]);
    char *text = ocgl_read_file(names[h]);
    assert_non_null(text);
    size_t len = strlen(text);
    int lines = 0;
    for (size_t i = 0; i < len; ++i) lines += text[i] == '\n';
    if (len && text[len - 1] != '\n') lines++;
    static const char probe[] = "float oc_line_probe_ = oc_line_probe_undeclared_;\n";
    char *t = malloc(len + sizeof probe + 2);
    assert_non_null(t);
    snprintf(t, len + sizeof probe + 2, "%s%s%s", text, (len && text[len - 1] != '\n') ? "\n" : "", probe);
    ocv_gl_src_add(&src, names[h], t);
    free(t);
    free(text);
    ocv_gl_src_add(&src, "<kernel>", "layout(local_size_x = 1) in;\nvoid main() {}\n");
    char *log = NULL;
    GLuint prog = ocv_gl_src_compile(&src, &log);
    assert_int_equal(prog, 0);
    assert_non_null(log);
    char want[300];
    snprintf(want, sizeof want, "%s:%d(", names[h], lines + 1);
    const char *at = strstr(log, names[h]);
    int got = -1;
    if (at) sscanf(at + strlen(names[h]), ":%d", &got);
    int own = strcmp(names[h], "shaders/oc_port.h") == 0 || strcmp(names[h], "shaders/optics.h") == 0;
    if (strstr(log, want)) {
      printf("  %-24s %4d lines: GLSL error lines exact\n", names[h], lines);
    } else {
      printf("  %-24s %4d lines: %s GLSL reports the last line as %d (drift %d): a function-like macro\n"
             "  %-24s            invocation spans lines (Mesa's glcpp joins it onto one line)\n",
             names[h], lines, own ? "FAIL" : "WARNING", got - 1, lines + 1 - got, "");
      bad_own += own;
    }
    free(log);
    ocv_gl_src_free(&src);
  }
  for (int i = 0; i < n; ++i) free(names[i]);
  ocv_gl_context_free(ctx);
  assert_int_equal(bad_own, 0);
}

static void test_glsl__errors_name_file_and_line(void **state) {
  (void)state;
  ocv_gl_context_t *ctx = NULL;
  OCGL_REQUIRE_CONTEXT(ctx);
  char dir[] = "/tmp/oc_glsl_test_XXXXXX";
  assert_non_null(mkdtemp(dir));
  char path[512];
  snprintf(path, sizeof path, "%s/broken.h", dir);
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs("/* broken.h: a deliberate GLSL error on line 5 */\n"
        "#ifndef OC_TEST_BROKEN_H\n"
        "#define OC_TEST_BROKEN_H\n"
        "OC_INLINE ocg_real ocg_broken(ocg_real x) {\n"
        "  return x * undefined_symbol_for_the_test;\n"
        "}\n"
        "#endif\n",
        f);
  assert_int_equal(fclose(f), 0);

  /* Error in a header, after the two real headers. */
  ocv_gl_src_t src;
  assert_int_equal(ocv_gl_src_init(&src, NULL), 0);
  for (int i = 0; i < LEN(optics_headers); ++i) ocgl_add_file(&src, optics_headers[i]);
  ocgl_add_file(&src, path);
  ocv_gl_src_add(&src, "<kernel>", "layout(local_size_x = 1) in;\nvoid main() {}\n");
  char *log = NULL;
  GLuint prog = ocv_gl_src_compile(&src, &log);
  printf("header error log:\n%s", log ? log : "(none)\n");
  assert_int_equal(prog, 0);
  assert_non_null(log);
  char want[600];
  snprintf(want, sizeof want, "%s:5", path);
  if (!strstr(log, want)) fail_msg("log does not name %s", want);
  free(log);
  ocv_gl_src_free(&src);

  /* Error in the kernel, line 3 of the kernel. */
  assert_int_equal(ocv_gl_src_init(&src, NULL), 0);
  for (int i = 0; i < LEN(optics_headers); ++i) ocgl_add_file(&src, optics_headers[i]);
  ocv_gl_src_add(&src, "<kernel>", "layout(local_size_x = 1) in;\nvoid main() {\n  float y = ocg_phase_hg(0.5);\n}\n");
  prog = ocv_gl_src_compile(&src, &log);
  printf("kernel error log:\n%s", log ? log : "(none)\n");
  assert_int_equal(prog, 0);
  assert_non_null(log);
  assert_non_null(strstr(log, "<kernel>:3"));
  free(log);
  ocv_gl_src_free(&src);

  unlink(path);
  rmdir(dir);
  ocv_gl_context_free(ctx);
}

static void test_harness__log_translation(void **state) {
  (void)state;
  ocv_gl_src_t src;
  assert_int_equal(ocv_gl_src_init(&src, NULL), 0);              /* lines 1-2 */
  assert_int_equal(ocv_gl_src_add(&src, "a.h", "x\ny\nz\n"), 0); /* "#line 4" on line 3, a.h on 4-6 */
  assert_int_equal(ocv_gl_src_add(&src, "b.h", "p\nq"), 0);      /* "#line 8" on 7, b.h on 8-9 (newline supplied) */
  assert_int_equal(ocv_gl_src_add(&src, "<kernel>", "k\n"), 0);  /* "#line 11" on 10, kernel on 11 */
  assert_string_equal(src.text, "#version 450\n#define OC_GLSL\n#line 4\nx\ny\nz\n#line 8\np\nq\n#line 11\nk\n");
  int local = 0;
  assert_string_equal(ocv_gl_src_map_line(&src, 5, &local), "a.h");
  assert_int_equal(local, 2);
  assert_string_equal(ocv_gl_src_map_line(&src, 9, &local), "b.h");
  assert_int_equal(local, 2);
  assert_string_equal(ocv_gl_src_map_line(&src, 11, &local), "<kernel>");
  assert_int_equal(local, 1);
  assert_null(ocv_gl_src_map_line(&src, 7, &local)); /* a #line directive */
  assert_null(ocv_gl_src_map_line(&src, 12, &local));
  char *t = ocv_gl_src_translate_log(&src, "0:6(12): error: `foo' undeclared\n0(8) : error C1008: bar\n"
                                     "1:2(1): error: baz\nplain line\n");
  assert_non_null(t);
  assert_string_equal(t, "a.h:3(12): error: `foo' undeclared\nb.h:1 : error C1008: bar\n<prelude>:2(1): error: baz\n"
                         "plain line\n");
  free(t);
  ocv_gl_src_free(&src);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_harness__log_translation),
      cmocka_unit_test(test_glsl__optics_matches_c),
      cmocka_unit_test(test_glsl__all_shared_headers_compile),
      cmocka_unit_test(test_glsl__errors_name_file_and_line),
      cmocka_unit_test(test_glsl__headers_keep_their_line_numbers),
  };
  return cmocka_run_group_tests_name("glsl_headers", tests, NULL, NULL);
}
