/* gl_program.c — compute programs assembled from the shared shaders/ headers (docs/architecture.md,
 * "One formula, one place": GLSL has no #include, so the headers are concatenated in dependency order).
 *
 * Every piece is a segment whose first line in the concatenation is recorded, and every segment
 * after the first is preceded by "#line <its first line>" so that drift inside one segment (Mesa's
 * glcpp joins a function-like macro call spanning lines) does not spread to the next. The compiler's
 * "0:LINE(COL)" (Mesa) or "0(LINE)" (NVIDIA) is then rewritten as "shaders/FILE:LINE(COL)".
 * The builder (ocv_gl_src_t) is public: tests/gl assembles its own kernels with it. */
#include <epoxy/gl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocv_gl.h"
#include "oc_err.h" /* oc_errorf */

#ifndef OC_SHADER_DIR
#define OC_SHADER_DIR "shaders"
#endif

/* The shared headers, in the order each needs the ones before it. */
static const char *const ocv__headers[] = {"oc_port.h", "sampling.h",   "optics.h", "brick.h",
                                           "shadow.h",  "atmosphere.h", "march.h"};

const char *ocv_gl_shader_dir(void) {
  const char *d = getenv("OC_SHADER_DIR");
  return d && *d ? d : OC_SHADER_DIR;
}

/* ---- Source builder ------------------------------------------------------------------------------------ */

/* Latches the first failure of s: later adds are no-ops and ocv_gl_src_compile() reports it. */
static int ocv__src_fail(ocv_gl_src_t *s, const char *fmt, ...) {
  s->failed = 1;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(s->why, sizeof s->why, fmt, ap);
  va_end(ap);
  return -1;
}

int ocv_gl_src_add(ocv_gl_src_t *s, const char *name, const char *text) {
  if (s->failed) return -1;
  if (s->nseg == OCV_GL_MAX_SEGMENTS) return ocv__src_fail(s, "more than %d source segments", OCV_GL_MAX_SEGMENTS);
  size_t n = strlen(text);
  int nl = n == 0 || text[n - 1] != '\n';
  char line_dir[32] = ""; /* before every segment but the first: #version must lead */
  if (s->nseg > 0) snprintf(line_dir, sizeof line_dir, "#line %d\n", s->lines + 2);
  size_t ld = strlen(line_dir);
  if (s->len + ld + n + 2 > s->cap) {
    size_t cap = (s->len + ld + n + 2) * 2;
    char *t = realloc(s->text, cap);
    if (!t) return ocv__src_fail(s, "out of memory");
    s->text = t;
    s->cap = cap;
  }
  memcpy(s->text + s->len, line_dir, ld);
  s->len += ld;
  s->lines += ld ? 1 : 0;
  memcpy(s->text + s->len, text, n);
  s->len += n;
  if (nl) s->text[s->len++] = '\n';
  s->text[s->len] = '\0';
  int count = nl;
  for (size_t i = 0; i < n; ++i) count += text[i] == '\n';
  snprintf(s->seg[s->nseg].name, sizeof s->seg[s->nseg].name, "%s", name);
  s->seg[s->nseg].first = s->lines + 1;
  s->seg[s->nseg].count = count;
  s->nseg++;
  s->lines += count;
  return 0;
}

int ocv_gl_src_init(ocv_gl_src_t *s, const char *defines) {
  memset(s, 0, sizeof *s);
  if (ocv_gl_src_add(s, "<prelude>", "#version 450\n#define OC_GLSL\n") != 0) return -1;
  if (defines && ocv_gl_src_add(s, "<defines>", defines) != 0) return -1;
  return 0;
}

void ocv_gl_src_free(ocv_gl_src_t *s) {
  free(s->text);
  memset(s, 0, sizeof *s);
}

char *ocv_gl_read_file(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = NULL;
  long n = -1;
  if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0 && (buf = malloc((size_t)n + 1))) {
    if (fread(buf, 1, (size_t)n, f) != (size_t)n) {
      free(buf);
      buf = NULL;
    } else {
      buf[n] = '\0';
    }
  }
  fclose(f);
  return buf;
}

int ocv_gl_src_add_file(ocv_gl_src_t *s, const char *name, const char *path) {
  if (s->failed) return -1;
  char *buf = ocv_gl_read_file(path);
  if (!buf) return ocv__src_fail(s, "cannot read %s", path);
  int rc = ocv_gl_src_add(s, name ? name : path, buf);
  free(buf);
  return rc;
}

const char *ocv_gl_src_map_line(const ocv_gl_src_t *s, int line, int *local) {
  for (int i = 0; i < s->nseg; ++i) {
    if (line >= s->seg[i].first && line < s->seg[i].first + s->seg[i].count) {
      *local = line - s->seg[i].first + 1;
      return s->seg[i].name;
    }
  }
  return NULL;
}

char *ocv_gl_src_translate_log(const ocv_gl_src_t *s, const char *log) {
  size_t cap = strlen(log) * 2 + 1024, n = 0;
  char *out = malloc(cap);
  if (!out) return NULL;
  for (const char *p = log; *p;) {
    const char *eol = strchr(p, '\n');
    size_t ll = eol ? (size_t)(eol - p) : strlen(p);
    int src = -1, line = -1, col = -1, used = 0;
    if (sscanf(p, "%d:%d(%d)%n", &src, &line, &col, &used) == 3 && used > 0) {
    } else if (sscanf(p, "%d(%d)%n", &src, &line, &used) == 2 && used > 0) {
      col = -1;
    } else {
      used = 0;
    }
    int local = 0;
    const char *name = used ? ocv_gl_src_map_line(s, line, &local) : NULL;
    char head[320] = "";
    if (!name) used = 0;
    else if (col >= 0) snprintf(head, sizeof head, "%s:%d(%d)", name, local, col);
    else snprintf(head, sizeof head, "%s:%d", name, local);
    size_t hl = strlen(head);
    if (n + hl + ll + 2 > cap) {
      cap = (n + hl + ll + 2) * 2;
      char *t = realloc(out, cap);
      if (!t) {
        free(out);
        return NULL;
      }
      out = t;
    }
    memcpy(out + n, head, hl);
    n += hl;
    memcpy(out + n, p + used, ll - (size_t)used);
    n += ll - (size_t)used;
    out[n++] = '\n';
    p += ll;
    if (*p == '\n') ++p;
  }
  out[n] = '\0';
  return out;
}

/* The info log of a shader (is_prog 0) or program, translated; NULL when empty or out of memory. */
static char *ocv__info_log(const ocv_gl_src_t *s, GLuint obj, int is_prog) {
  GLint len = 0;
  if (is_prog) glGetProgramiv(obj, GL_INFO_LOG_LENGTH, &len);
  else glGetShaderiv(obj, GL_INFO_LOG_LENGTH, &len);
  if (len <= 1) return NULL;
  char *raw = malloc((size_t)len + 1), *out = NULL;
  if (!raw) return NULL;
  if (is_prog) glGetProgramInfoLog(obj, len, NULL, raw);
  else glGetShaderInfoLog(obj, len, NULL, raw);
  raw[len] = '\0';
  out = ocv_gl_src_translate_log(s, raw);
  free(raw);
  return out;
}

GLuint ocv_gl_src_compile(const ocv_gl_src_t *s, char **log) {
  char *msg = NULL;
  GLuint prog = 0;
  if (s->failed || !s->text) {
    const char *why = s->failed ? s->why : "empty source";
    msg = malloc(strlen(why) + 1);
    if (msg) strcpy(msg, why);
    goto out;
  }
  GLuint sh = glCreateShader(GL_COMPUTE_SHADER);
  const GLchar *txt = s->text;
  glShaderSource(sh, 1, &txt, NULL);
  glCompileShader(sh);
  GLint ok = 0;
  glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
  msg = ocv__info_log(s, sh, 0);
  if (!ok) {
    glDeleteShader(sh);
    goto out;
  }
  prog = glCreateProgram();
  glAttachShader(prog, sh);
  glLinkProgram(prog);
  glDeleteShader(sh);
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    free(msg);
    msg = ocv__info_log(s, prog, 1);
    glDeleteProgram(prog);
    prog = 0;
  }
out:
  if (log) *log = msg;
  else free(msg);
  return prog;
}

/* ---- The renderer's programs ------------------------------------------------------------------------- */

/* Appends shader-directory file `file` as "shaders/FILE"; on failure why says what went wrong. */
static int ocv__add_shader(ocv_gl_src_t *s, const char *file, char *why, size_t wl) {
  char path[1024], name[160];
  snprintf(path, sizeof path, "%s/%s", ocv_gl_shader_dir(), file);
  snprintf(name, sizeof name, "shaders/%s", file);
  char *buf = ocv_gl_read_file(path);
  if (!buf) {
    (void)oc_errorf(0, why, wl, "cannot read %s (set OC_SHADER_DIR to the shaders folder)", path);
    return -1;
  }
  int rc = ocv_gl_src_add(s, name, buf);
  free(buf);
  if (rc) (void)oc_errorf(0, why, wl, "%s assembling %s", s->why, name);
  return rc;
}

GLuint ocv_gl_compute_program(const char *kernel, const char *defines, char *why, size_t why_len) {
  ocv_gl_src_t s;
  GLuint prog = 0;
  int bad = ocv_gl_src_init(&s, defines);
  if (bad) (void)oc_errorf(0, why, why_len, "%s assembling %s", s.why, kernel);
  for (size_t i = 0; !bad && i < sizeof ocv__headers / sizeof *ocv__headers; ++i)
    bad = ocv__add_shader(&s, ocv__headers[i], why, why_len);
  if (!bad) bad = ocv__add_shader(&s, kernel, why, why_len);
  if (!bad) {
    char *log = NULL;
    prog = ocv_gl_src_compile(&s, &log);
    if (!prog) (void)oc_errorf(0, why, why_len, "%s", log ? log : "compute program failed (no log)");
    free(log);
  }
  ocv_gl_src_free(&s);
  return prog;
}
