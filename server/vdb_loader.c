/* vdb_loader.c — opens the OpenVDB shim (liboc_vdb_shim.so) with dlopen, once, on first use.
 *
 * Nothing else in ocs_core links OpenVDB: a server whose scene has no vdb source, and that never
 * inspects or exports, never maps OpenVDB, TBB or Boost (tests/server/test_vdb.c checks
 * /proc/self/maps). The shim stays loaded until the process exits (no dlclose: OpenVDB and TBB
 * keep process-wide registries and threads). */
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "oc_err.h"
#include "vdb_shim.h"

static pthread_mutex_t ocs__vdb_mu = PTHREAD_MUTEX_INITIALIZER;
static const ocs_vdb_api_t *ocs__vdb_api; /* guarded by ocs__vdb_mu */

/* Appends "; path: reason" to the list of attempts (truncating quietly). */
static void ocs__tried(char *buf, size_t cap, const char *what, const char *path, const char *reason) {
  size_t n = strlen(buf);
  if (n < cap) snprintf(buf + n, cap - n, "%s%s %.900s (%.400s)", n ? "; " : "", what, path, reason);
}

/* Opens one candidate and checks its table. @return the table, or NULL with a reason. */
static const ocs_vdb_api_t *ocs__try(const char *path, char *reason, size_t reason_len) {
  void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
  if (!h) {
    const char *e = dlerror();
    snprintf(reason, reason_len, "%s", e ? e : "dlopen failed");
    return NULL;
  }
  ocs_vdb_shim_api_fn fn;
  void *sym = dlsym(h, OCS_VDB_SHIM_SYMBOL);
  memcpy(&fn, &sym, sizeof fn); /* object pointer → function pointer without a pedantic cast */
  if (!sym) {
    snprintf(reason, reason_len, "no symbol %s", OCS_VDB_SHIM_SYMBOL);
    dlclose(h);
    return NULL;
  }
  const ocs_vdb_api_t *api = fn(OCS_VDB_SHIM_ABI);
  if (!api || api->abi != OCS_VDB_SHIM_ABI || api->size < sizeof(ocs_vdb_api_t)) {
    snprintf(reason, reason_len, "ABI mismatch: this server wants shim ABI %d", OCS_VDB_SHIM_ABI);
    dlclose(h);
    return NULL;
  }
  return api; /* h is kept open for the life of the process */
}

int ocs_vdb_load(const ocs_vdb_api_t **out, char *why, size_t why_len) {
  if (!out) return OC_EINVAL;
  pthread_mutex_lock(&ocs__vdb_mu);
  if (ocs__vdb_api) {
    *out = ocs__vdb_api;
    pthread_mutex_unlock(&ocs__vdb_mu);
    return 0;
  }
  char tried[4096] = "", reason[512];
  const ocs_vdb_api_t *api = NULL;
  const char *env = getenv("OC_VDB_SHIM");
  if (env && env[0]) {
    api = ocs__try(env, reason, sizeof reason);
    if (!api) ocs__tried(tried, sizeof tried, "$OC_VDB_SHIM =", env, reason);
  }
#ifdef OCS_VDB_SHIM_BUILD_PATH
  if (!api) {
    api = ocs__try(OCS_VDB_SHIM_BUILD_PATH, reason, sizeof reason);
    if (!api) ocs__tried(tried, sizeof tried, "build tree", OCS_VDB_SHIM_BUILD_PATH, reason);
  }
#endif
  if (!api) {
    char exe[4096], path[4200];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
      exe[n] = '\0';
      char *slash = strrchr(exe, '/');
      if (slash) *slash = '\0';
      snprintf(path, sizeof path, "%s/../lib/%s", exe, OCS_VDB_SHIM_NAME);
      api = ocs__try(path, reason, sizeof reason);
      if (!api) ocs__tried(tried, sizeof tried, "next to the program", path, reason);
    } else {
      ocs__tried(tried, sizeof tried, "next to the program", "/proc/self/exe", "unreadable");
    }
  }
  ocs__vdb_api = api;
  pthread_mutex_unlock(&ocs__vdb_mu);
  if (!api) {
    if (why) snprintf(why, why_len, "cannot load the OpenVDB shim %s: tried %s", OCS_VDB_SHIM_NAME, tried);
    return OC_EIO;
  }
  *out = api;
  return 0;
}
