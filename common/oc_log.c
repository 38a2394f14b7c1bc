#include "oc_log.h"

#include <stdarg.h>
#include <stdio.h>

static oc_log_level_t oc__log_level = OC_LOG_INFO;

void oc_log_set_level(oc_log_level_t level) { oc__log_level = level; }
oc_log_level_t oc_log_get_level(void) { return oc__log_level; }

void oc_log(oc_log_level_t level, const char *fmt, ...) {
  static const char *names[] = {"debug", "info", "warning", "error"};
  char line[1024];
  va_list ap;
  if (level < oc__log_level || level > OC_LOG_ERROR) return;
  va_start(ap, fmt);
  vsnprintf(line, sizeof line, fmt, ap);
  va_end(ap);
  /* One fputs per line so lines from several threads never interleave. */
  char out[1100];
  snprintf(out, sizeof out, "overcast: %s: %s\n", names[level], line);
  fputs(out, stderr);
}
