/* net_audit.c — the audit log (net_internal.h; docs/operations.md, "Audit log"): every control
 * request that changes the world or its sessions appends one JSON object on a line of its own to
 * the --audit-log file: when (UTC, ISO 8601, ms), who (the peer's address and session), the op,
 * the request's other members as its arguments, and the outcome ("ok": true, or false with the
 * "error"). Opened for appending, so that restarts add to one file, and flushed per line, so that
 * a crash loses none that was acknowledged. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <inttypes.h>
#include <string.h>
#include <time.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"

int ocs_audit_open(ocs_server_t *srv, char *why, size_t why_len) {
  const char *path = srv->desc.audit_log;
  if (!path) return 0;
  if (!(srv->audit = fopen(path, "a")))
    return oc_errorf(OC_EIO, why, why_len, "--audit-log %s: cannot open it for appending: %s", path, strerror(errno));
  srv->desc.audit_log = NULL; /* the caller's string is not kept */
  return 0;
}

void ocs_audit_close(ocs_server_t *srv) {
  if (srv->audit) fclose(srv->audit);
  srv->audit = NULL;
}

/* "2025-01-31T23:59:59.123Z": the wall clock, whatever the world's clock says. */
static void utc_iso8601(char *out, size_t cap) {
  struct timespec t;
  struct tm tm;
  clock_gettime(CLOCK_REALTIME, &t);
  gmtime_r(&t.tv_sec, &tm);
  size_t n = strftime(out, cap, "%Y-%m-%dT%H:%M:%S", &tm);
  snprintf(out + n, cap - n, ".%03ldZ", t.tv_nsec / 1000000);
}

static cJSON *audit_entry(const ocs_session_t *s, const char *op, const cJSON *req, const char *error) {
  char when[40];
  utc_iso8601(when, sizeof when);
  cJSON *e = cJSON_CreateObject();
  cJSON_AddStringToObject(e, "time", when);
  cJSON_AddStringToObject(e, "peer", s->addr);
  cJSON_AddNumberToObject(e, "session", s->id);
  cJSON_AddStringToObject(e, "op", op);
  cJSON *args = cJSON_Duplicate(req, 1);
  cJSON_DeleteItemFromObjectCaseSensitive(args, "op");
  cJSON_AddItemToObject(e, "args", args ? args : cJSON_CreateObject());
  cJSON_AddBoolToObject(e, "ok", !error);
  if (error) cJSON_AddStringToObject(e, "error", error);
  return e;
}

void ocs_audit_write(ocs_session_t *s, const char *op, const cJSON *req, const char *error) {
  FILE *f = s->srv->audit;
  if (!f) return;
  cJSON *e = audit_entry(s, op, req, error);
  char *line = cJSON_PrintUnformatted(e);
  cJSON_Delete(e);
  if (!line || fprintf(f, "%s\n", line) < 0 || fflush(f) != 0) /* the change happened: said, not undone */
    oc_log_error("audit log: the %s request of session %" PRIu32 " could not be written: %s", op, s->id,
                 line ? strerror(errno) : "out of memory");
  cJSON_free(line);
}
