/* gl_harness.h — headless OpenGL 4.5 core for GL tests: EGL context without a window, and compute
 * programs assembled from the shared shaders/ headers the way client/shader_src.c does it.
 *
 * Header-only (static functions): each tests/gl/test_*.c is its own executable.
 *
 * Context (design.md, "Testing without a GPU"): libepoxy's EGL (never <EGL/egl.h>, whose Khronos
 * headers clash with epoxy's), platform tried in order
 *   1. EGL_PLATFORM_SURFACELESS_MESA via eglGetPlatformDisplayEXT (Mesa: llvmpipe, no X server);
 *   2. EGL_PLATFORM_DEVICE_EXT on each device of eglQueryDevicesEXT (NVIDIA's headless path);
 *   3. eglGetDisplay(EGL_DEFAULT_DISPLAY);
 * then eglBindAPI(EGL_OPENGL_API), a 4.5 core context (EGL_KHR_no_config_context when offered, else
 * any config with EGL_OPENGL_BIT) made current with no surface (EGL_KHR_surfaceless_context).
 * If none works the reason is kept in ocgl_ctx.why and the test is skipped (OCGL_REQUIRE_CONTEXT),
 * unless OC_GL_REQUIRE=1 is set in the environment, which turns the skip into a failure (CI machines
 * that are known to have Mesa set it so a broken EGL cannot pass silently).
 *
 * Sources: "#version 450\n#define OC_GLSL\n" + extra prelude + headers + kernel. Every piece is a
 * segment whose first line in the concatenation is recorded, so the compiler's "0:LINE(COL)" (Mesa) or
 * "0(LINE)" (NVIDIA) is rewritten as "shaders/optics.h:LINE(COL)" in the log: a GLSL error names the
 * header file and line, like a C compiler would. Every segment after the first is preceded by
 * "#line <its own first line>", which changes nothing when line counting is exact but stops drift in
 * one segment from spreading to the next: Mesa's glcpp joins a function-like macro invocation that
 * spans lines onto one line, so later GLSL lines are reported that many lines early. The source-string
 * number of "#line N S" is not used: Mesa 22.3 prints S in some messages and 0 in others.
 * Headers are read from $OC_SOURCE_DIR (set by CTest) unless given as absolute paths.
 *
 * Threads: GL calls only on the thread that called ocgl_init (style.md, habit 7). */
#ifndef OC_TESTS_GL_HARNESS_H
#define OC_TESTS_GL_HARNESS_H

#include <epoxy/gl.h>  /* GL 4.5 entry points through libepoxy */
#include <epoxy/egl.h> /* EGL through libepoxy (not <EGL/egl.h>) */
#include <stdarg.h>    /* va_list for ocgl__setf */
#include <stdio.h>     /* fopen, snprintf */
#include <stdlib.h>    /* malloc, getenv */
#include <string.h>    /* strstr, memcpy */

/* ---- Context ----------------------------------------------------------------------------------------- */

typedef struct ocgl_ctx_s {
  EGLDisplay dpy;
  EGLContext ctx;
  const char *platform; /* which path of the three worked */
  char why[512];        /* empty on success; otherwise why no context could be made */
} ocgl_ctx;

static void ocgl__setf(char *dst, size_t n, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(dst, n, fmt, ap);
  va_end(ap);
}

static int ocgl__has_ext(const char *list, const char *name) {
  size_t n = strlen(name);
  for (const char *p = list; p && (p = strstr(p, name)) != NULL; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return 1;
  return 0;
}

/* Tries one display: initialise, bind GL, create a 4.5 core context and make it current. */
static int ocgl__try_display(ocgl_ctx *c, EGLDisplay dpy, const char *platform) {
  EGLint major = 0, minor = 0;
  if (dpy == EGL_NO_DISPLAY) {
    ocgl__setf(c->why, sizeof c->why, "%s: no display (EGL error 0x%x)", platform, (unsigned)eglGetError());
    return -1;
  }
  if (!eglInitialize(dpy, &major, &minor)) {
    ocgl__setf(c->why, sizeof c->why, "%s: eglInitialize failed (0x%x)", platform, (unsigned)eglGetError());
    return -1;
  }
  const char *ext = eglQueryString(dpy, EGL_EXTENSIONS);
  if (!ocgl__has_ext(ext, "EGL_KHR_surfaceless_context")) {
    ocgl__setf(c->why, sizeof c->why, "%s: EGL %d.%d lacks EGL_KHR_surfaceless_context", platform, major, minor);
    eglTerminate(dpy);
    return -1;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    ocgl__setf(c->why, sizeof c->why, "%s: eglBindAPI(EGL_OPENGL_API) failed (0x%x)", platform, (unsigned)eglGetError());
    eglTerminate(dpy);
    return -1;
  }
  EGLConfig cfg = EGL_NO_CONFIG_KHR;
  if (!ocgl__has_ext(ext, "EGL_KHR_no_config_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(dpy, want, &cfg, 1, &n) || n < 1) {
      ocgl__setf(c->why, sizeof c->why, "%s: no EGL config with EGL_OPENGL_BIT", platform);
      eglTerminate(dpy);
      return -1;
    }
  }
  const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION,       4,
                          EGL_CONTEXT_MINOR_VERSION,       5,
                          EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                          EGL_NONE};
  EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, attrs);
  if (ctx == EGL_NO_CONTEXT) {
    ocgl__setf(c->why, sizeof c->why, "%s: no OpenGL 4.5 core context (0x%x)", platform, (unsigned)eglGetError());
    eglTerminate(dpy);
    return -1;
  }
  if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
    ocgl__setf(c->why, sizeof c->why, "%s: eglMakeCurrent without surface failed (0x%x)", platform,
               (unsigned)eglGetError());
    eglDestroyContext(dpy, ctx);
    eglTerminate(dpy);
    return -1;
  }
  if (epoxy_gl_version() < 45 || !epoxy_is_desktop_gl()) {
    ocgl__setf(c->why, sizeof c->why, "%s: context is GL %d, need desktop 4.5", platform, epoxy_gl_version());
    eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(dpy, ctx);
    eglTerminate(dpy);
    return -1;
  }
  c->dpy = dpy;
  c->ctx = ctx;
  c->platform = platform;
  c->why[0] = '\0';
  return 0;
}

/*! ocgl_init() : make a headless GL 4.5 core context current on this thread.
 *  @return : 0 on success; -1 with c->why set when no platform gives one. */
static int ocgl_init(ocgl_ctx *c) {
  memset(c, 0, sizeof *c);
  c->dpy = EGL_NO_DISPLAY;
  c->ctx = EGL_NO_CONTEXT;
  char first[512] = "";
  const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS); /* NULL without EGL_EXT_client_extensions */
  int has_platform = ocgl__has_ext(client, "EGL_EXT_platform_base");
  if (has_platform && ocgl__has_ext(client, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (ocgl__try_display(c, d, "EGL_PLATFORM_SURFACELESS_MESA") == 0) return 0;
    memcpy(first, c->why, sizeof first);
  }
  if (has_platform && ocgl__has_ext(client, "EGL_EXT_platform_device") &&
      ocgl__has_ext(client, "EGL_EXT_device_enumeration")) {
    EGLDeviceEXT devs[8];
    EGLint n = 0;
    if (eglQueryDevicesEXT(8, devs, &n)) {
      for (EGLint i = 0; i < n; ++i) {
        EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
        if (ocgl__try_display(c, d, "EGL_PLATFORM_DEVICE_EXT") == 0) return 0;
      }
    }
  }
  if (ocgl__try_display(c, eglGetDisplay(EGL_DEFAULT_DISPLAY), "EGL_DEFAULT_DISPLAY") == 0) return 0;
  if (first[0]) {
    char last[512];
    memcpy(last, c->why, sizeof last);
    ocgl__setf(c->why, sizeof c->why, "%.240s; %.240s", first, last);
  }
  return -1;
}

/*! ocgl_close() : release the context (accepts a context that failed to initialise).
 *  note 1 : the display is not terminated: eglTerminate makes Mesa dlclose its driver, after which
 *           LeakSanitizer reports the driver's own small leaks against "<unknown module>", where no
 *           suppression can name them. A display is per process and eglInitialize on it again is a
 *           no-op, so the next ocgl_init reuses it; the process exit reclaims it. */
static void ocgl_close(ocgl_ctx *c) {
  if (c->dpy == EGL_NO_DISPLAY) return;
  eglMakeCurrent(c->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (c->ctx != EGL_NO_CONTEXT) eglDestroyContext(c->dpy, c->ctx);
  c->dpy = EGL_NO_DISPLAY;
  c->ctx = EGL_NO_CONTEXT;
}

/* Prints the renderer once; tests quote it in their output so logs say which GL was tested. */
static void ocgl_print_info(const ocgl_ctx *c) {
  printf("GL: %s | %s | %s | via %s\n", (const char *)glGetString(GL_VENDOR), (const char *)glGetString(GL_RENDERER),
         (const char *)glGetString(GL_VERSION), c->platform);
}

#ifdef cmocka_unit_test
/*! OCGL_REQUIRE_CONTEXT(c) : in a cmocka test, initialise c or skip the test, saying why
 *  (a failure instead of a skip when OC_GL_REQUIRE=1). */
#define OCGL_REQUIRE_CONTEXT(c)                                                       \
  do {                                                                                \
    if (ocgl_init(c) != 0) {                                                          \
      const char *req_ = getenv("OC_GL_REQUIRE");                                     \
      printf("no headless OpenGL 4.5 context: %s\n", (c)->why);                       \
      if (req_ && req_[0] == '1') fail_msg("OC_GL_REQUIRE=1 but no GL: %s", (c)->why); \
      skip();                                                                         \
    }                                                                                 \
  } while (0)
#endif

/* ---- Source assembly with line mapping ------------------------------------------------------------------ */

#define OCGL_MAX_SEGMENTS 32

typedef struct ocgl_src_s {
  char *text;
  size_t len, cap;
  int lines; /* lines in text so far (text always ends with '\n'), #line directives included */
  int nseg;
  struct {
    char name[256];
    int first; /* 1-based line of the segment's first line in text */
    int count;
  } seg[OCGL_MAX_SEGMENTS];
  int failed; /* an add failed (out of memory, too many segments, unreadable file) */
  char why[512];
} ocgl_src;

static void ocgl_src_free(ocgl_src *s) {
  free(s->text);
  memset(s, 0, sizeof *s);
}

/*! ocgl_src_add() : append a named piece of source; a missing final newline is supplied.
 *  @return : 0, or -1 with s->why set (and s->failed, so later calls are no-ops). */
static int ocgl_src_add(ocgl_src *s, const char *name, const char *text) {
  if (s->failed) return -1;
  size_t n = strlen(text);
  int nl = (n == 0 || text[n - 1] != '\n');
  if (s->nseg == OCGL_MAX_SEGMENTS) {
    s->failed = 1;
    ocgl__setf(s->why, sizeof s->why, "more than %d source segments", OCGL_MAX_SEGMENTS);
    return -1;
  }
  char line_dir[32] = ""; /* "#line <first>" before every segment but the first (#version must lead) */
  if (s->nseg > 0) ocgl__setf(line_dir, sizeof line_dir, "#line %d\n", s->lines + 2);
  size_t ld = strlen(line_dir);
  if (s->len + ld + n + 2 > s->cap) {
    size_t cap = (s->len + ld + n + 2) * 2;
    char *t = realloc(s->text, cap);
    if (!t) {
      s->failed = 1;
      ocgl__setf(s->why, sizeof s->why, "out of memory");
      return -1;
    }
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
  int count = nl ? 1 : 0;
  for (size_t i = 0; i < n; ++i) count += text[i] == '\n';
  ocgl__setf(s->seg[s->nseg].name, sizeof s->seg[s->nseg].name, "%s", name);
  s->seg[s->nseg].first = s->lines + 1;
  s->seg[s->nseg].count = count;
  s->nseg++;
  s->lines += count;
  return 0;
}

/*! ocgl_src_init() : start a program's source with "#version 450\n#define OC_GLSL\n" (segment
 *  "<prelude>"), then `extra` (e.g. generated constants, SSBO declarations; may be NULL). */
static int ocgl_src_init(ocgl_src *s, const char *extra) {
  memset(s, 0, sizeof *s);
  if (ocgl_src_add(s, "<prelude>", "#version 450\n#define OC_GLSL\n") != 0) return -1;
  if (extra && ocgl_src_add(s, "<prelude-extra>", extra) != 0) return -1;
  return 0;
}

/* Full path of a header: absolute paths as given, others under $OC_SOURCE_DIR (or "." if unset). */
static void ocgl_src_path(char *dst, size_t n, const char *rel) {
  const char *root = getenv("OC_SOURCE_DIR");
  if (rel[0] == '/' || !root || !*root) ocgl__setf(dst, n, "%s", rel);
  else ocgl__setf(dst, n, "%s/%s", root, rel);
}

/*! ocgl_file_exists() : whether a header (same path rules as ocgl_src_add_file) can be opened. */
static int ocgl_file_exists(const char *rel) {
  char path[1024];
  ocgl_src_path(path, sizeof path, rel);
  FILE *f = fopen(path, "rb");
  if (f) fclose(f);
  return f != NULL;
}

/*! ocgl_read_file() : the whole text of a header (same path rules as ocgl_src_add_file).
 *  @return : a malloc'd, NUL-terminated string (caller frees), or NULL with why set. */
static char *ocgl_read_file(const char *rel, char *why, size_t whylen) {
  char path[1024];
  ocgl_src_path(path, sizeof path, rel);
  FILE *f = fopen(path, "rb");
  if (!f) {
    ocgl__setf(why, whylen, "cannot open %s", path);
    return NULL;
  }
  size_t cap = 1 << 16, n = 0;
  char *buf = malloc(cap);
  while (buf) {
    n += fread(buf + n, 1, cap - 1 - n, f);
    if (n < cap - 1) break;
    char *b = realloc(buf, cap * 2);
    if (!b) {
      free(buf);
      buf = NULL;
      break;
    }
    buf = b;
    cap *= 2;
  }
  int err = ferror(f);
  fclose(f);
  if (!buf || err) {
    free(buf);
    ocgl__setf(why, whylen, "cannot read %s", path);
    return NULL;
  }
  buf[n] = '\0';
  return buf;
}

/*! ocgl_src_add_file() : append a file, named by `rel` in error messages. */
static int ocgl_src_add_file(ocgl_src *s, const char *rel) {
  if (s->failed) return -1;
  char *buf = ocgl_read_file(rel, s->why, sizeof s->why);
  if (!buf) {
    s->failed = 1;
    return -1;
  }
  int rc = ocgl_src_add(s, rel, buf);
  free(buf);
  return rc;
}

/*! ocgl_src_map_line() : segment name and line within it of line `line` of the concatenation.
 *  @return : the name, or NULL when the line is outside every segment (or a #line directive). */
static const char *ocgl_src_map_line(const ocgl_src *s, int line, int *local) {
  for (int i = 0; i < s->nseg; ++i) {
    if (line >= s->seg[i].first && line < s->seg[i].first + s->seg[i].count) {
      *local = line - s->seg[i].first + 1;
      return s->seg[i].name;
    }
  }
  return NULL;
}

/*! ocgl_translate_log() : rewrite a GLSL info log so each "0:L(C): msg" (Mesa) or "0(L) : msg" (NVIDIA)
 *  reads "file:l(C): msg". Unrecognised lines are copied unchanged.
 *  @return : a malloc'd string (caller frees), or NULL on out of memory. */
static char *ocgl_translate_log(const ocgl_src *s, const char *log) {
  size_t cap = strlen(log) * 2 + 1024, n = 0;
  char *out = malloc(cap);
  if (!out) return NULL;
  const char *p = log;
  while (*p) {
    const char *eol = strchr(p, '\n');
    size_t ll = eol ? (size_t)(eol - p) : strlen(p);
    int src = -1, line = -1, col = -1, used = 0;
    /* Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error C0000: ..." (the source number is ignored) */
    if (sscanf(p, "%d:%d(%d)%n", &src, &line, &col, &used) == 3 && used > 0) {
    } else if (sscanf(p, "%d(%d)%n", &src, &line, &used) == 2 && used > 0) {
      col = -1;
    } else {
      used = 0;
    }
    int local = 0;
    const char *name = used ? ocgl_src_map_line(s, line, &local) : NULL;
    char head[320] = "";
    if (name) {
      if (col >= 0) ocgl__setf(head, sizeof head, "%s:%d(%d)", name, local, col);
      else ocgl__setf(head, sizeof head, "%s:%d", name, local);
    } else {
      used = 0;
    }
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

/*! ocgl_compute_program() : compile and link s as a compute shader.
 *  @return : the program, or 0 with *log (malloc'd, caller frees; file:line form) saying why.
 *  note 1 : on success *log holds the compiler's warnings, if any (else NULL). */
static GLuint ocgl_compute_program(const ocgl_src *s, char **log) {
  *log = NULL;
  if (s->failed) {
    *log = malloc(strlen(s->why) + 1);
    if (*log) strcpy(*log, s->why);
    return 0;
  }
  GLuint sh = glCreateShader(GL_COMPUTE_SHADER);
  const GLchar *txt = s->text;
  glShaderSource(sh, 1, &txt, NULL);
  glCompileShader(sh);
  GLint ok = 0, len = 0;
  glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
  glGetShaderiv(sh, GL_INFO_LOG_LENGTH, &len);
  if (len > 1) {
    char *raw = malloc((size_t)len + 1);
    if (raw) {
      glGetShaderInfoLog(sh, len, NULL, raw);
      raw[len] = '\0';
      *log = ocgl_translate_log(s, raw);
      free(raw);
    }
  }
  if (!ok) {
    glDeleteShader(sh);
    return 0;
  }
  GLuint prog = glCreateProgram();
  glAttachShader(prog, sh);
  glLinkProgram(prog);
  glDeleteShader(sh);
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    glGetProgramiv(prog, GL_INFO_LOG_LENGTH, &len);
    char *raw = malloc((size_t)len + 64);
    if (raw) {
      glGetProgramInfoLog(prog, len, NULL, raw);
      raw[len > 0 ? len : 0] = '\0';
      free(*log);
      *log = ocgl_translate_log(s, raw);
      free(raw);
    }
    glDeleteProgram(prog);
    return 0;
  }
  return prog;
}

#endif /* OC_TESTS_GL_HARNESS_H */
