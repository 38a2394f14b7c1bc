/* stress_proc.c — overcast-server as a child process of overcast-stress, and what /proc says about
 * it: its resident set (VmRSS, peak VmHWM) and CPU time, apart from the tool's own (getrusage). */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "oc.h"
#include "stress.h"

void stress_proc_sample(long pid, stress_proc_t *out) {
  memset(out, 0, sizeof *out);
  if (pid <= 0) return;
  char path[64], buf[4096];
  snprintf(path, sizeof path, "/proc/%ld/status", pid);
  FILE *f = fopen(path, "r");
  if (!f) return;
  int have = 0;
  while (fgets(buf, sizeof buf, f)) {
    double kb;
    if (sscanf(buf, "VmRSS: %lf kB", &kb) == 1) {
      out->rss_mib = kb / 1024.0;
      have |= 1;
    } else if (sscanf(buf, "VmHWM: %lf kB", &kb) == 1) {
      out->hwm_mib = kb / 1024.0;
      have |= 2;
    }
  }
  fclose(f);
  snprintf(path, sizeof path, "/proc/%ld/stat", pid);
  f = fopen(path, "r");
  if (!f) return;
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = '\0';
  /* after "pid (comm)": field 3 is the state; utime and stime are fields 14 and 15 */
  const char *p = strrchr(buf, ')');
  if (!p) return;
  unsigned long long ut = 0, stt = 0;
  if (sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &ut, &stt) != 2) return;
  long hz = sysconf(_SC_CLK_TCK);
  out->cpu_s = (double)(ut + stt) / (double)(hz > 0 ? hz : 100);
  out->ok = have == 3;
}

double stress_self_cpu(void) {
  struct rusage u;
  if (getrusage(RUSAGE_SELF, &u) < 0) return 0;
  return (double)u.ru_utime.tv_sec + 1e-6 * (double)u.ru_utime.tv_usec + (double)u.ru_stime.tv_sec +
         1e-6 * (double)u.ru_stime.tv_usec;
}

