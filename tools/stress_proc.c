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

#include "oc_err.h"
#include "stress.h"

static void sp_sleep(double s) {
  struct timespec t = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
  nanosleep(&t, NULL);
}

int stress_server_spawn(char *const argv[], double timeout_s, stress_child_t *c, char *why, size_t why_len) {
  memset(c, 0, sizeof *c);
  c->pid = -1;
  c->out_fd = -1;
  int fd[2];
  if (pipe(fd) < 0) return oc_errorf(OC_EIO, why, why_len, "pipe: %s", strerror(errno));
  pid_t parent = getpid();
  pid_t pid = fork();
  if (pid < 0) {
    close(fd[0]);
    close(fd[1]);
    return oc_errorf(OC_EIO, why, why_len, "fork: %s", strerror(errno));
  }
  if (pid == 0) {
    /* the server must not outlive us (a killed or crashed stress run leaves no server behind) */
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(127);
    dup2(fd[1], STDOUT_FILENO);
    close(fd[0]);
    close(fd[1]);
    execv(argv[0], argv);
    fprintf(stderr, "overcast-stress: cannot run %s: %s\n", argv[0], strerror(errno));
    _exit(127);
  }
  close(fd[1]);
  fcntl(fd[0], F_SETFD, FD_CLOEXEC);
  c->pid = pid;
  c->out_fd = fd[0];
  /* "listening on HOST:PORT\n" */
  char line[512];
  size_t n = 0;
  double deadline = stress_now() + timeout_s;
  for (;;) {
    char *nl = n ? memchr(line, '\n', n) : NULL;
    if (nl) {
      *nl = '\0';
      break;
    }
    double left = deadline - stress_now();
    struct pollfd p = {fd[0], POLLIN, 0};
    int k = left > 0 ? poll(&p, 1, (int)(left * 1e3) + 1) : 0;
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) {
      stress_server_stop(c, 5);
      return oc_errorf(OC_EIO, why, why_len, "%s: no \"listening on\" line within %g s", argv[0], timeout_s);
    }
    ssize_t got = read(fd[0], line + n, sizeof line - 1 - n);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0 || n + (size_t)got >= sizeof line - 1) {
      int st = stress_server_stop(c, 5);
      if (got <= 0)
        return oc_errorf(OC_EIO, why, why_len, "%s exited (status %d) before listening", argv[0], st);
      return oc_errorf(OC_EIO, why, why_len, "%s: unexpected output before \"listening on\"", argv[0]);
    }
    n += (size_t)got;
  }
  const char *prefix = "listening on ";
  if (strncmp(line, prefix, strlen(prefix)) != 0 ||
      ocv_parse_address(line + strlen(prefix), c->host, sizeof c->host, &c->port) < 0) {
    stress_server_stop(c, 5);
    return oc_errorf(OC_EIO, why, why_len, "%s: unexpected first line \"%.200s\"", argv[0], line);
  }
  return 0;
}

int stress_server_stop(stress_child_t *c, double timeout_s) {
  int status = -1, st = 0;
  if (c->pid > 0) {
    kill(c->pid, SIGTERM);
    double deadline = stress_now() + timeout_s;
    pid_t w = 0;
    while ((w = waitpid(c->pid, &st, WNOHANG)) == 0 && stress_now() < deadline) sp_sleep(0.02);
    if (w == 0) {
      kill(c->pid, SIGKILL);
      w = waitpid(c->pid, &st, 0);
    }
    if (w == c->pid) status = WIFEXITED(st) ? WEXITSTATUS(st) : WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1;
    c->pid = -1;
  }
  if (c->out_fd >= 0) close(c->out_fd);
  c->out_fd = -1;
  return status;
}

int stress_server_kill(stress_child_t *c) {
  int status = -1, st = 0;
  if (c->pid > 0) {
    kill(c->pid, SIGKILL);
    if (waitpid(c->pid, &st, 0) == c->pid)
      status = WIFEXITED(st) ? WEXITSTATUS(st) : WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1;
    c->pid = -1;
  }
  if (c->out_fd >= 0) close(c->out_fd);
  c->out_fd = -1;
  return status;
}

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

int stress_exe_dir(char *buf, size_t cap) {
  ssize_t n = readlink("/proc/self/exe", buf, cap - 1);
  if (n <= 0 || (size_t)n >= cap - 1) return -1;
  buf[n] = '\0';
  char *slash = strrchr(buf, '/');
  if (!slash) return -1;
  *slash = '\0';
  return 0;
}
