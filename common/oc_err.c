#include "oc_err.h"

#include <stdarg.h>
#include <stdio.h>

const char *oc_strerror(int err) {
  switch (err) {
#define OC__ERR_MSG(name, val, msg) \
  case (val):                       \
    return msg;
    OC_ERRNO_MAP(OC__ERR_MSG)
#undef OC__ERR_MSG
    case 0:
      return "success";
    default:
      return "unknown error";
  }
}

const char *oc_err_name(int err) {
  switch (err) {
#define OC__ERR_NAME(name, val, msg) \
  case (val):                        \
    return #name;
    OC_ERRNO_MAP(OC__ERR_NAME)
#undef OC__ERR_NAME
    case 0:
      return "OK";
    default:
      return "UNKNOWN";
  }
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
