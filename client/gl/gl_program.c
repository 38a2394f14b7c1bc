/* gl_program.c — compute programs assembled from the shared shaders/ headers (docs/architecture.md,
 * "One formula, one place": GLSL has no #include, so the headers are concatenated in dependency order).
 *
 * Every piece is a segment whose first line in the concatenation is recorded, and every segment
 * after the first is preceded by "#line <its first line>" so that drift inside one segment (Mesa's
 * glcpp joins a function-like macro call spanning lines) does not spread to the next. The compiler's
 * "0:LINE(COL)" (Mesa) or "0(LINE)" (NVIDIA) is then rewritten as "shaders/FILE:LINE(COL)". */
#include <epoxy/gl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocv_gl.h"

#ifndef OC_SHADER_DIR
#define OC_SHADER_DIR "shaders"
#endif

#define OCV__MAX_SEGMENTS 16

/* The shared headers, in the order each needs the ones before it. */
static const char *const ocv__headers[] = {"oc_port.h", "sampling.h", "optics.h", "brick.h", "atmosphere.h"};

typedef struct {
  char *text;
  size_t len, cap;
  int lines; /* lines so far, #line directives included */
  int nseg;
  struct {
    char name[128];
    int first, count;
  } seg[OCV__MAX_SEGMENTS];
} ocv__src_t;

static void ocv__setf(char *dst, size_t n, const char *fmt, ...) {
  if (!dst || !n) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(dst, n, fmt, ap);
  va_end(ap);
}

const char *ocv_gl_shader_dir(void) {
  const char *d = getenv("OC_SHADER_DIR");
  return d && *d ? d : OC_SHADER_DIR;
}

static int ocv__src_add(ocv__src_t *s, const char *name, const char *text) {
  if (s->nseg == OCV__MAX_SEGMENTS) return -1;
  size_t n = strlen(text);
  int nl = n == 0 || text[n - 1] != '\n';
  char line_dir[32] = "";
  if (s->nseg > 0) snprintf(line_dir, sizeof line_dir, "#line %d\n", s->lines + 2);
  size_t ld = strlen(line_dir);
  if (s->len + ld + n + 2 > s->cap) {
    size_t cap = (s->len + ld + n + 2) * 2;
    char *t = realloc(s->text, cap);
    if (!t) return -1;
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

static char *ocv__read_file(const char *path) {
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

static int ocv__src_add_file(ocv__src_t *s, const char *file, char *why, size_t wl) {
  char path[1024], name[160];
  snprintf(path, sizeof path, "%s/%s", ocv_gl_shader_dir(), file);
  snprintf(name, sizeof name, "shaders/%s", file);
  char *buf = ocv__read_file(path);
  if (!buf) {
    ocv__setf(why, wl, "cannot read %s (set OC_SHADER_DIR to the shaders folder)", path);
    return -1;
  }
  int rc = ocv__src_add(s, name, buf);
  free(buf);
  if (rc) ocv__setf(why, wl, "out of memory assembling %s", name);
  return rc;
}

/* Rewrites "0:L(C): msg" (Mesa) and "0(L) : msg" (NVIDIA) as "file:l(C): msg" into why. */
static void ocv__translate_log(const ocv__src_t *s, const char *log, char *why, size_t wl) {
  if (!why || !wl) return;
  size_t n = 0;
  why[0] = '\0';
  for (const char *p = log; *p && n + 1 < wl;) {
    const char *eol = strchr(p, '\n');
    size_t ll = eol ? (size_t)(eol - p) : strlen(p);
    int src = -1, line = -1, col = -1, used = 0;
    if (sscanf(p, "%d:%d(%d)%n", &src, &line, &col, &used) == 3 && used > 0) {
    } else if (sscanf(p, "%d(%d)%n", &src, &line, &used) == 2 && used > 0) {
      col = -1;
    } else {
      used = 0;
    }
    char head[200] = "";
    for (int i = 0; used && i < s->nseg; ++i) {
      if (line >= s->seg[i].first && line < s->seg[i].first + s->seg[i].count) {
        int local = line - s->seg[i].first + 1;
        if (col >= 0) snprintf(head, sizeof head, "%s:%d(%d)", s->seg[i].name, local, col);
        else snprintf(head, sizeof head, "%s:%d", s->seg[i].name, local);
        break;
      }
    }
    if (!head[0]) used = 0;
    int w = snprintf(why + n, wl - n, "%s%.*s%s", head, (int)(ll - (size_t)used), p + used, eol ? "\n" : "");
    if (w < 0) break;
    n += (size_t)w < wl - n ? (size_t)w : wl - n - 1;
    p += ll;
    if (*p == '\n') ++p;
  }
}

GLuint ocv_gl_compute_program(const char *kernel, const char *defines, char *why, size_t why_len) {
  ocv__src_t s;
  memset(&s, 0, sizeof s);
  GLuint prog = 0;
  int bad = ocv__src_add(&s, "<prelude>", "#version 450\n#define OC_GLSL\n");
  if (!bad && defines) bad = ocv__src_add(&s, "<defines>", defines);
  if (bad) ocv__setf(why, why_len, "out of memory assembling %s", kernel);
  for (size_t i = 0; !bad && i < sizeof ocv__headers / sizeof *ocv__headers; ++i)
    bad = ocv__src_add_file(&s, ocv__headers[i], why, why_len);
  if (!bad) bad = ocv__src_add_file(&s, kernel, why, why_len);
  if (bad) goto out;

  GLuint sh = glCreateShader(GL_COMPUTE_SHADER);
  const GLchar *txt = s.text;
  glShaderSource(sh, 1, &txt, NULL);
  glCompileShader(sh);
  GLint ok = 0, len = 0;
  glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    glGetShaderiv(sh, GL_INFO_LOG_LENGTH, &len);
    char *raw = malloc((size_t)(len > 0 ? len : 1) + 1);
    if (raw) {
      glGetShaderInfoLog(sh, len, NULL, raw);
      raw[len > 0 ? len : 0] = '\0';
      ocv__translate_log(&s, raw, why, why_len);
      free(raw);
    }
    glDeleteShader(sh);
    goto out;
  }
  prog = glCreateProgram();
  glAttachShader(prog, sh);
  glLinkProgram(prog);
  glDeleteShader(sh);
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    glGetProgramiv(prog, GL_INFO_LOG_LENGTH, &len);
    char *raw = malloc((size_t)(len > 0 ? len : 1) + 1);
    if (raw) {
      glGetProgramInfoLog(prog, len, NULL, raw);
      raw[len > 0 ? len : 0] = '\0';
      ocv__translate_log(&s, raw, why, why_len);
      free(raw);
    }
    glDeleteProgram(prog);
    prog = 0;
  }
out:
  free(s.text);
  return prog;
}
