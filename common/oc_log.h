/* oc_log.h — one-line diagnostics on stderr.
 *
 * Errors are one line that names the cause (README: exit 1 runtime, 2 usage). The level threshold
 * is process-wide and set once at start-up, before any thread is spawned. */
#ifndef OC_COMMON_LOG_H
#define OC_COMMON_LOG_H

typedef enum { OC_LOG_DEBUG = 0, OC_LOG_INFO = 1, OC_LOG_WARN = 2, OC_LOG_ERROR = 3, OC_LOG_QUIET = 4 } oc_log_level_t;

void oc_log_set_level(oc_log_level_t level);
oc_log_level_t oc_log_get_level(void);
/*! oc_log() : printf-style; prefixes "overcast: <level>: " and appends a newline. */
void oc_log(oc_log_level_t level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#define oc_log_debug(...) oc_log(OC_LOG_DEBUG, __VA_ARGS__)
#define oc_log_info(...) oc_log(OC_LOG_INFO, __VA_ARGS__)
#define oc_log_warn(...) oc_log(OC_LOG_WARN, __VA_ARGS__)
#define oc_log_error(...) oc_log(OC_LOG_ERROR, __VA_ARGS__)

#endif /* OC_COMMON_LOG_H */
