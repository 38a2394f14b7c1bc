#include "oc_err.h"

#include <stdarg.h>
#include <stdio.h>

/* Every code with its name and message: success, then the rows of OC_ERRNO_MAP. */
static const struct {
  int val;
  const char *name, *msg;
} oc__errs[] = {
    {0, "OK", "success"},
#define OC__ERR_ROW(name, val, msg) {(val), #name, (msg)},
    OC_ERRNO_MAP(OC__ERR_ROW)
#undef OC__ERR_ROW
};

/* The row of err, or -1. */
static int oc__err_row(int err) {
  for (size_t i = 0; i < sizeof oc__errs / sizeof oc__errs[0]; i++)
    if (oc__errs[i].val == err) return (int)i;
  return -1;
}

const char *oc_strerror(int err) {
  int i = oc__err_row(err);
  return i < 0 ? "unknown error" : oc__errs[i].msg;
}

const char *oc_err_name(int err) {
  int i = oc__err_row(err);
  return i < 0 ? "UNKNOWN" : oc__errs[i].name;
}

int oc_errorf(int code, char *why, size_t why_len, const char *fmt, ...) {
  if (why && why_len) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, why_len, fmt, ap);
    va_end(ap);
  }
  return code;
}
