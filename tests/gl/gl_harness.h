/* gl_harness.h — what GL tests add to client/gl (ocv_gl.h): skipping without a context, and shared
 * headers read from the source tree.
 *
 * Header-only (static functions): each tests/gl/test_*.c is its own executable, linked with oc_gl.
 * The context (ocv_gl_context_init: surfaceless Mesa, then each EGL device, then the default display)
 * and the source builder with line mapping (ocv_gl_src_t: "#version 450\n#define OC_GLSL\n", #line
 * before each segment, compiler logs rewritten to "file:LINE(COL)") are client/gl's; see ocv_gl.h.
 *
 * Context: OCGL_REQUIRE_CONTEXT skips a test when no headless GL 4.5 context can be made, printing
 * why, unless OC_GL_REQUIRE=1 is set in the environment, which turns the skip into a failure (CI
 * machines that are known to have Mesa set it so a broken EGL cannot pass silently).
 * Files: named by a path relative to $OC_SOURCE_DIR (set by CTest; "." if unset), e.g.
 * "shaders/optics.h", or by an absolute path; the name as given is what compiler messages quote.
 *
 * Threads: GL calls only on the thread that made the context (style.md, habit 7). */
#ifndef OC_TESTS_GL_HARNESS_H
#define OC_TESTS_GL_HARNESS_H

#include <stdio.h>  /* printf, snprintf, fopen */
#include <stdlib.h> /* getenv */

#include "ocv_gl.h" /* ocv_gl_context_*, ocv_gl_src_* */

/*! ocgl_path() : full path of `rel`: absolute paths as given, others under $OC_SOURCE_DIR. */
static void ocgl_path(char *dst, size_t n, const char *rel) {
  const char *root = getenv("OC_SOURCE_DIR");
  if (rel[0] == '/' || !root || !*root) snprintf(dst, n, "%s", rel);
  else snprintf(dst, n, "%s/%s", root, rel);
}

/*! ocgl_file_exists() : whether `rel` (ocgl_path rules) can be opened. */
static int ocgl_file_exists(const char *rel) {
  char path[1024];
  ocgl_path(path, sizeof path, rel);
  FILE *f = fopen(path, "rb");
  if (f) fclose(f);
  return f != NULL;
}

/*! ocgl_read_file() : the whole text of `rel` (ocgl_path rules); malloc'd (caller frees), or NULL. */
static char *ocgl_read_file(const char *rel) {
  char path[1024];
  ocgl_path(path, sizeof path, rel);
  return ocv_gl_read_file(path);
}

/*! ocgl_add_file() : ocv_gl_src_add_file() of `rel` (ocgl_path rules), named `rel` in messages. */
static int ocgl_add_file(ocv_gl_src_t *s, const char *rel) {
  char path[1024];
  ocgl_path(path, sizeof path, rel);
  return ocv_gl_src_add_file(s, rel, path);
}

/*! ocgl_print_info() : "GL: vendor | renderer | version | via platform", so logs say which GL was tested. */
static void ocgl_print_info(const ocv_gl_context_t *c) {
  char info[512];
  ocv_gl_context_describe(c, info, sizeof info);
  printf("GL: %s\n", info);
}

#ifdef cmocka_unit_test
/*! OCGL_REQUIRE_CONTEXT(c) : in a cmocka test, c (an ocv_gl_context_t *) = a new current context, or
 *  skip the test saying why (a failure instead of a skip when OC_GL_REQUIRE=1). */
#define OCGL_REQUIRE_CONTEXT(c)                                                      \
  do {                                                                               \
    char why_[1024] = "";                                                            \
    if (((c) = ocv_gl_context_init(why_, sizeof why_)) == NULL) {                    \
      const char *req_ = getenv("OC_GL_REQUIRE");                                    \
      printf("%s\n", why_);                                                          \
      if (req_ && req_[0] == '1') fail_msg("OC_GL_REQUIRE=1 but no GL: %s", why_);  \
      skip();                                                                        \
    }                                                                                \
  } while (0)
#endif

#endif /* OC_TESTS_GL_HARNESS_H */
