#include "oc_cli.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#ifndef OC_VERSION
#define OC_VERSION "0.0.0"
#endif

int oc_cli_fail(const char *prog, int code, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  fprintf(stderr, "%s: %s\n", prog, msg);
  return code;
}

int oc_cli_int(const char *prog, const char *opt, const char *text, long lo, long hi, long *out) {
  char *end;
  errno = 0;
  long v = strtol(text, &end, 10);
  if (end == text || *end || errno) {
    oc_cli_fail(prog, 0, "%s: expected an integer, got \"%s\"", opt, text);
    return -1;
  }
  if (v < lo || v > hi) {
    oc_cli_fail(prog, 0, "%s: %ld is outside [%ld, %ld]", opt, v, lo, hi);
    return -1;
  }
  *out = v;
  return 0;
}

int oc_cli_double(const char *prog, const char *opt, const char *text, double lo, double hi, double *out) {
  char *end;
  double v = strtod(text, &end);
  if (end == text || *end || !isfinite(v)) {
    oc_cli_fail(prog, 0, "%s: expected a finite number, got \"%s\"", opt, text);
    return -1;
  }
  if (v < lo || v > hi) {
    oc_cli_fail(prog, 0, "%s: %g is outside [%g, %g]", opt, v, lo, hi);
    return -1;
  }
  *out = v;
  return 0;
}

int oc_cli_size(const char *prog, const char *opt, const char *text, int *w, int *h) {
  char *end;
  long a = strtol(text, &end, 10), b;
  if (end == text || *end != 'x') goto bad;
  const char *s = end + 1;
  b = strtol(s, &end, 10);
  if (end == s || *end) goto bad;
  if (a < 1 || a > 16384 || b < 1 || b > 16384) {
    oc_cli_fail(prog, 0, "%s: %s: each side must be 1..16384", opt, text);
    return -1;
  }
  *w = (int)a;
  *h = (int)b;
  return 0;
bad:
  oc_cli_fail(prog, 0, "%s: expected WxH, got \"%s\"", opt, text);
  return -1;
}

void oc_cli_version(const char *prog) { printf("%s %s\n", prog, OC_VERSION); }
