/* redis_fixture.h — a real redis-server for tests (header-only, after cmocka.h): started on
 * 127.0.0.1 at a free port, with no persistence, and stopped by its process id. CI installs it
 * (scripts/install-deps.sh): a test that cannot start it fails rather than skips. */
#ifndef OC_TESTS_REDIS_FIXTURE_H
#define OC_TESTS_REDIS_FIXTURE_H

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

typedef struct {
  pid_t pid;
  int port;
} redis_proc_t;

static inline void redis_sleep_ms(long ms) {
  struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

/* A port nobody listens on now (the kernel's pick for port 0). */
static inline int redis_free_port(void) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
  socklen_t n = sizeof a;
  if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || getsockname(fd, (struct sockaddr *)&a, &n) != 0) {
    if (fd >= 0) close(fd);
    return -1;
  }
  close(fd);
  return ntohs(a.sin_port);
}

/* 1 when something accepts TCP connections on 127.0.0.1:port. */
static inline int redis_port_open(int port) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port), .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
  int ok = fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
  if (fd >= 0) close(fd);
  return ok;
}

/* Starts redis-server on `port` (0: a free one); waits until it accepts connections. */
static inline int redis_start(redis_proc_t *p, int port) {
  p->pid = 0; /* nothing to stop if it fails before the fork */
  p->port = port > 0 ? port : redis_free_port();
  if (p->port <= 0) return -1;
  char ports[16];
  snprintf(ports, sizeof ports, "%d", p->port);
  p->pid = fork();
  if (p->pid < 0) return -1;
  if (p->pid == 0) {
    int null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
      dup2(null, 1);
      dup2(null, 2);
    }
    execlp("redis-server", "redis-server", "--port", ports, "--bind", "127.0.0.1", "--save", "", "--appendonly", "no",
           "--protected-mode", "yes", (char *)NULL);
    _exit(127);
  }
  for (int i = 0; i < 1000; i++) { /* up to 20 s on a loaded machine */
    if (redis_port_open(p->port)) return 0;
    int st;
    if (waitpid(p->pid, &st, WNOHANG) == p->pid) return -1; /* it exited: not installed, or the port was taken */
    redis_sleep_ms(20);
  }
  kill(p->pid, SIGKILL);
  waitpid(p->pid, NULL, 0);
  return -1;
}

/* Kills the server at once (SIGKILL: no reply, no goodbye) and reaps it. */
static inline void redis_kill(redis_proc_t *p) {
  kill(p->pid, SIGKILL);
  waitpid(p->pid, NULL, 0);
  p->pid = 0;
}

static inline void redis_stop(redis_proc_t *p) {
  if (p->pid <= 0) return;
  kill(p->pid, SIGCONT);
  kill(p->pid, SIGTERM);
  waitpid(p->pid, NULL, 0);
  p->pid = 0;
}

#endif /* OC_TESTS_REDIS_FIXTURE_H */
