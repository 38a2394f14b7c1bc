/* child.c — overcast-server as a child process (child.h). */
#include "child.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "oc_err.h"

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void sleep_s(double s) {
  struct timespec t = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
  nanosleep(&t, NULL);
}

int ocv_child_spawn(char *const argv[], double timeout_s, ocv_child_t *c, char *why, size_t why_len) {
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
    /* the server must not outlive us (a killed or crashed parent leaves no server behind) */
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(127);
    dup2(fd[1], STDOUT_FILENO);
    close(fd[0]);
    close(fd[1]);
    execv(argv[0], argv);
    fprintf(stderr, "cannot run %s: %s\n", argv[0], strerror(errno));
    _exit(127);
  }
  close(fd[1]);
  fcntl(fd[0], F_SETFD, FD_CLOEXEC);
  c->pid = pid;
  c->out_fd = fd[0];
  /* "listening on HOST:PORT\n" */
  char line[512];
  size_t n = 0;
  double deadline = now_s() + timeout_s;
  for (;;) {
    char *nl = n ? memchr(line, '\n', n) : NULL;
    if (nl) {
      *nl = '\0';
      break;
    }
    double left = deadline - now_s();
    struct pollfd p = {fd[0], POLLIN, 0};
    int k = left > 0 ? poll(&p, 1, (int)(left * 1e3) + 1) : 0;
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) {
      ocv_child_stop(c, 5);
      return oc_errorf(OC_EIO, why, why_len, "%s: no \"listening on\" line within %g s", argv[0], timeout_s);
    }
    ssize_t got = read(fd[0], line + n, sizeof line - 1 - n);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0 || n + (size_t)got >= sizeof line - 1) {
      int st = ocv_child_stop(c, 5);
      if (got <= 0)
        return oc_errorf(OC_EIO, why, why_len, "%s exited (status %d) before listening", argv[0], st);
      return oc_errorf(OC_EIO, why, why_len, "%s: unexpected output before \"listening on\"", argv[0]);
    }
    n += (size_t)got;
  }
  const char *prefix = "listening on ";
  if (strncmp(line, prefix, strlen(prefix)) != 0 ||
      ocv_parse_address(line + strlen(prefix), c->host, sizeof c->host, &c->port) < 0) {
    ocv_child_stop(c, 5);
    return oc_errorf(OC_EIO, why, why_len, "%s: unexpected first line \"%.200s\"", argv[0], line);
  }
  return 0;
}

int ocv_child_stop(ocv_child_t *c, double timeout_s) {
  int status = -1, st = 0;
  if (c->pid > 0) {
    kill(c->pid, SIGTERM);
    double deadline = now_s() + timeout_s;
    pid_t w = 0;
    while ((w = waitpid(c->pid, &st, WNOHANG)) == 0 && now_s() < deadline) sleep_s(0.02);
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

int ocv_child_kill(ocv_child_t *c) {
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

int ocv_exe_dir(char *buf, size_t cap) {
  ssize_t n = readlink("/proc/self/exe", buf, cap - 1);
  if (n <= 0 || (size_t)n >= cap - 1) return -1;
  buf[n] = '\0';
  char *slash = strrchr(buf, '/');
  if (!slash) return -1;
  *slash = '\0';
  return 0;
}
