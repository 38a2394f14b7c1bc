/* programs.h — for tests that run the built programs (header-only): where they are, and running a
 * shell command with its exit status. */
#ifndef OC_TESTS_PROGRAMS_H
#define OC_TESTS_PROGRAMS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h> /* readlink */

/* The programs' folder: $OC_BIN_DIR, else ../bin beside this test (BUILD/tests → BUILD/bin); the
 * source tree: $OC_SOURCE_DIR, else the current folder. */
static inline void oc_test_dirs(char *bin, size_t bin_len, char *src, size_t src_len) {
  const char *b = getenv("OC_BIN_DIR"), *s = getenv("OC_SOURCE_DIR");
  if (b && *b) {
    snprintf(bin, bin_len, "%s", b);
  } else {
    char exe[1800];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = '\0';
    char *slash = strrchr(exe, '/');
    if (slash) *slash = '\0';
    snprintf(bin, bin_len, "%s/../bin", n > 0 ? exe : ".");
  }
  if (src) snprintf(src, src_len, "%s", s && *s ? s : ".");
}

/* Runs cmd with sh (echoed first, for the log). @return its exit status, 128 when it died of a
 * signal, −1 when it could not be run. */
static inline int oc_test_run(const char *cmd) {
  printf("$ %s\n", cmd);
  fflush(stdout);
  int r = system(cmd);
  return r == -1 ? -1 : WIFEXITED(r) ? WEXITSTATUS(r) : 128;
}

/* Starts cmd in the background (in dir, unless NULL) with its pid written to pid_file, then waits up to
 * tenths × 0.1 s for the shell test `ready` to hold. @return 0 once it holds, else nonzero. */
static inline int oc_test_start(const char *dir, const char *cmd, const char *pid_file, const char *ready, int tenths) {
  char sh[16384];
  int n = snprintf(sh, sizeof sh,
                   "%s%s%s(%s & echo $! >'%s') && for i in $(seq %d); do %s && break; sleep 0.1; done; %s",
                   dir ? "cd '" : "", dir ? dir : "", dir ? "' && " : "", cmd, pid_file, tenths, ready, ready);
  if (n < 0 || (size_t)n >= sizeof sh) return -1;
  return oc_test_run(sh);
}

#endif /* OC_TESTS_PROGRAMS_H */
