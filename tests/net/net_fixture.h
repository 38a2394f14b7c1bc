/* net_fixture.h — what the tests of the network server share (header-only, after cmocka.h):
 * the overcast-server process (OC_BIN_DIR, 127.0.0.1 port 0, epochs stepped by control
 * requests), viewers and control requests through client/net.h, and raw sockets for hostile
 * peers. */
#ifndef OC_TESTS_NET_FIXTURE_H
#define OC_TESTS_NET_FIXTURE_H

#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "net.h" /* client/net.h */
#include "oc_camera.h"
#include "oc_err.h"
#include "ocp_viewer.h"
#include "ocp_wire.h"

static inline void sleep_us(long us) {
  struct timespec t = {us / 1000000, (us % 1000000) * 1000};
  nanosleep(&t, NULL);
}

/*-*** The server process ***/

typedef struct {
  pid_t pid;
  int port;
  FILE *out;
} server_t;

static char scene_sphere[4096];
static pid_t running = 0; /* killed by the teardown when a test failed before stopping it */

/* Starts overcast-server with `extra` options. log: a file for its log (its stderr, info level
 * and up); NULL: quiet (-q), only errors, to the test's stderr. */
static inline void start_server_log(server_t *s, const char *const *extra, const char *log) {
  const char *bin = getenv("OC_BIN_DIR");
  assert_non_null(bin);
  char path[4096];
  snprintf(path, sizeof path, "%s/overcast-server", bin);
  const char *argv[40] = {path, "--listen", "127.0.0.1:0", "--epoch-period", "0", "--threads", "2", "-q"};
  int n = log ? 7 : 8;
  for (int i = 0; extra && extra[i]; i++) argv[n++] = extra[i];
  argv[n] = NULL;
  int fd[2];
  assert_int_equal(pipe(fd), 0);
  s->pid = fork();
  assert_true(s->pid >= 0);
  if (s->pid == 0) {
    if (log) {
      FILE *f = fopen(log, "w");
      if (!f) _exit(126);
      dup2(fileno(f), 2);
    }
    dup2(fd[1], 1);
    close(fd[0]);
    close(fd[1]);
    execv(path, (char *const *)argv);
    _exit(127);
  }
  close(fd[1]);
  running = s->pid;
  s->out = fdopen(fd[0], "r");
  char line[256] = "";
  assert_non_null(fgets(line, sizeof line, s->out)); /* "listening on 127.0.0.1:PORT" */
  const char *c = strrchr(line, ':');
  assert_non_null(c);
  assert_non_null(strstr(line, "listening on 127.0.0.1:"));
  s->port = atoi(c + 1);
  assert_true(s->port > 0);
}

static inline void start_server(server_t *s, const char *const *extra) { start_server_log(s, extra, NULL); }

/* overcast-server started on the sphere scene (scene_sphere), with more options: a NULL-terminated
 * list of them (NULL alone: none). */
static inline server_t sphere_server(const char *option, ...) {
  const char *extra[32] = {"--scene", scene_sphere};
  int n = 2;
  va_list ap;
  va_start(ap, option);
  for (const char *o = option; o; o = va_arg(ap, const char *)) {
    assert_true(n < 31);
    extra[n++] = o;
  }
  va_end(ap);
  extra[n] = NULL;
  server_t s;
  start_server(&s, extra);
  return s;
}

/* SIGTERM and the exit status (must be 0). SIGTERM drains: a viewer still open must leave (be
 * closed, or polled: it closes on the GOODBYE RECONNECT) within the 15 s this waits. */
static inline int stop_server(server_t *s) {
  running = 0;
  kill(s->pid, SIGTERM);
  int st = 0;
  for (int i = 0; i < 300; i++) {
    if (waitpid(s->pid, &st, WNOHANG) == s->pid) {
      fclose(s->out);
      return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
    }
    sleep_us(50000);
  }
  kill(s->pid, SIGKILL);
  waitpid(s->pid, &st, 0);
  fclose(s->out);
  return -1;
}

/* Closes the connections given (a NULL-terminated list), then stops the server: it must exit 0. */
static inline void close_and_stop(server_t *s, ...) {
  va_list ap;
  va_start(ap, s);
  for (ocv_conn_t *c; (c = va_arg(ap, ocv_conn_t *)) != NULL;) ocv_conn_close(c);
  va_end(ap);
  assert_int_equal(stop_server(s), 0);
}

/* Writes text to path (created or truncated). */
static inline void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

/* A file's whole text ("" when it cannot be opened; the caller frees). */
static inline char *read_file(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return strdup("");
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *t = malloc((size_t)n + 1);
  assert_non_null(t);
  t[fread(t, 1, (size_t)n, f)] = 0;
  fclose(f);
  return t;
}

/* Waits until the server's log has `n` lines with `what` (at most 300 s). */
static inline void wait_log(const char *log, const char *what, int n) {
  for (int i = 0; i < 6000; i++) {
    char *t = read_file(log);
    int k = 0;
    for (const char *p = strstr(t, what); p; p = strstr(p + 1, what)) k++;
    free(t);
    if (k >= n) return;
    sleep_us(50000);
  }
  fail_msg("the server's log never had %d \"%s\"", n, what);
}

/* The exit status of a server that is stopping (at most 300 s). */
static inline int wait_exit(server_t *s) {
  int st = 0, gone = 0;
  for (int i = 0; i < 6000 && !(gone = waitpid(s->pid, &st, WNOHANG) == s->pid); i++) sleep_us(50000);
  if (!gone) return -1; /* the teardown kills it */
  running = 0;
  fclose(s->out);
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/*-*** Viewers and control ***/

typedef struct {
  ocv_conn_t *c;
  int states, welcomes, resumed;
  uint64_t epoch, bricks_last;
  uint64_t granted; /* the budget WELCOME granted */
  uint32_t closed_code;
  char closed_text[256];
  ocp_stats_t last_stats;
} viewer_t;

static inline void ev_stats(void *ctx, const ocp_stats_t *st) { ((viewer_t *)ctx)->last_stats = *st; }

static inline void ev_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  viewer_t *v = ctx;
  v->granted = w->budget;
  v->welcomes++;
  v->resumed += resumed;
}
static inline void ev_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  viewer_t *v = ctx;
  v->states++;
  v->epoch = s->epoch;
  v->bricks_last = bricks;
}
static inline void ev_closed(void *ctx, uint32_t code, const char *text) {
  viewer_t *v = ctx;
  v->closed_code = code;
  snprintf(v->closed_text, sizeof v->closed_text, "%s", text);
}

/* The sphere scene's own camera. */
static inline ocp_camera_t sphere_camera(int w, int h) {
  oc_camera_pose_t p = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cam = oc_camera_from_pose(p);
  return (ocp_camera_t){cam.pos, cam.forward, cam.up, 40.0, (uint32_t)w, (uint32_t)h};
}

/* lean: a viewer that keeps digests, not codes (OCP_CAP_DIGEST). */
/* lean: a viewer that keeps digests, not codes (OCP_CAP_DIGEST). source: the local address to
 * connect from (127.0.0.2, ...; NULL: the system's choice). */
static inline void viewer_open_from(viewer_t *v, const char *source, int port, uint64_t budget, const char *token, int lean) {
  memset(v, 0, sizeof *v);
  ocp_viewer_desc_t d = {.role = OCP_ROLE_VIEWER, .budget = budget, .max_depth = 21, .width = 160, .height = 90,
                         .caps = lean ? OCP_CAP_DICT : OCP_CAP_ALL, .token = token, .lean = lean};
  ocp_viewer_events_t ev = {.ctx = v, .welcome = ev_welcome, .state = ev_state, .stats = ev_stats, .closed = ev_closed};
  char why[512];
  if (ocv_conn_create(&v->c, "127.0.0.1", port, &d, &ev, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  if (source && ocv_conn_set_source(v->c, source) < 0) fail_msg("viewer: cannot use source address %s", source);
  if (ocv_conn_reconnect(v->c, 5.0, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  ocp_camera_t cam = sphere_camera(160, 90);
  assert_int_equal(ocv_conn_camera(v->c, &cam), 0);
}

static inline void viewer_open_as(viewer_t *v, int port, uint64_t budget, const char *token, int lean) {
  viewer_open_from(v, NULL, port, budget, token, lean);
}

static inline void viewer_open(viewer_t *v, int port, uint64_t budget, const char *token) { viewer_open_as(v, port, budget, token, 0); }

/* A viewer opened and welcomed (within 5 s). */
static inline void viewer_welcomed(viewer_t *v, int port, uint64_t budget) {
  viewer_open(v, port, budget, NULL);
  char why[256];
  if (ocv_conn_wait_ready(v->c, 5, why, sizeof why) != 0) fail_msg("viewer not welcomed: %s", why);
}

/* Polls until the viewer has `n` states, or is closed (returns its poll result). */
static inline int viewer_wait(viewer_t *v, int n, double timeout_s) {
  char why[512];
  struct timespec t0, t;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  while (v->states < n) {
    int r = ocv_conn_poll(v->c, 0.05, why, sizeof why);
    if (r != 0) return r;
    clock_gettime(CLOCK_MONOTONIC, &t);
    if ((double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec) > timeout_s) return OC_EIO;
  }
  return 0;
}

/* One control request from `source` (NULL: any); returns the reply (malloc'd) and its status. */
static inline char *control_from(const char *source, int port, const char *token, const char *json, int32_t *status) {
  ocp_viewer_desc_t d = {.role = OCP_ROLE_CONTROL, .token = token};
  ocv_conn_t *c = NULL;
  char why[512];
  if (ocv_conn_create(&c, "127.0.0.1", port, &d, NULL, why, sizeof why) < 0) fail_msg("control: %s", why);
  if (source && ocv_conn_set_source(c, source) < 0) fail_msg("control: cannot use source address %s", source);
  if (ocv_conn_reconnect(c, 5.0, why, sizeof why) < 0) fail_msg("control: %s", why);
  char *reply = NULL;
  int32_t st = -1;
  int r = ocv_control_request(c, json, 120.0, &reply, &st, why, sizeof why);
  ocv_conn_close(c);
  if (r < 0) {
    if (status) *status = -1;
    return strdup(why);
  }
  if (status) *status = st;
  return reply;
}

static inline char *control(int port, const char *token, const char *json, int32_t *status) {
  return control_from(NULL, port, token, json, status);
}

static inline void step(int port, int n) {
  char json[64];
  snprintf(json, sizeof json, "{\"op\":\"step\",\"epochs\":%d}", n);
  int32_t st;
  char *r = control(port, NULL, json, &st);
  if (st != 0) {
    char why[512];
    snprintf(why, sizeof why, "%s", r ? r : "?");
    free(r);
    r = NULL; /* fail_msg() does not return, which gcc cannot see: no "use after free" */
    fail_msg("step %d: status %d: %s", n, (int)st, why);
  }
  free(r);
}

/* One epoch, stepped once the viewer's messages (its camera, its ACK) have reached the server;
 * waits for the viewer's n-th state (60 s). */
static inline void step_to(viewer_t *v, int port, int n) {
  char why[256];
  assert_int_equal(ocv_conn_flush(v->c, 5, why, sizeof why), 0);
  sleep_us(50000);
  step(port, 1);
  assert_int_equal(viewer_wait(v, n, 60), 0);
}

/* A number in the JSON text after `"key":` (first occurrence after `after`, if given). */
static inline double json_num(const char *json, const char *after, const char *key) {
  const char *p = after ? strstr(json, after) : json;
  assert_non_null(p);
  char pat[64];
  snprintf(pat, sizeof pat, "\"%s\":", key);
  p = strstr(p, pat);
  assert_non_null(p);
  return strtod(p + strlen(pat), NULL);
}

/*-*** Raw sockets (hostile peers) ***/

/* A TCP connection to 127.0.0.1:port from 127.0.0.<host> (0: the system's choice). */
static inline int raw_connect_from(int host, int port) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  assert_true(fd >= 0);
  if (host) {
    struct sockaddr_in src = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(0x7f000000u | (uint32_t)host)};
    assert_int_equal(bind(fd, (struct sockaddr *)&src, sizeof src), 0);
  }
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port), .sin_addr.s_addr = htonl(0x7f000001)};
  assert_int_equal(connect(fd, (struct sockaddr *)&a, sizeof a), 0);
  return fd;
}

static inline int raw_connect(int port) { return raw_connect_from(0, port); }

/* Waits up to 50 ms for bytes on a raw socket and feeds them to rd: 1 fed, 0 none yet, -1 EOF. */
static inline int raw_feed(int fd, ocp_reader_t *rd) {
  uint8_t buf[65536];
  struct pollfd p = {fd, POLLIN, 0};
  if (poll(&p, 1, 50) <= 0) return 0;
  ssize_t n = read(fd, buf, sizeof buf);
  if (n <= 0) return -1;
  ocp_reader_feed(rd, buf, (size_t)n);
  return 1;
}

/* Reads frames until EOF (within timeout); returns the code of the last ERROR/GOODBYE, or -1. */
static inline int raw_read_close_code(int fd, double timeout_s, char *text, size_t cap) {
  ocp_reader_t rd;
  ocp_reader_init(&rd, OCP_MAX_PAYLOAD);
  int code = -1;
  for (int i = 0; i < (int)(timeout_s * 20); i++) {
    int got = raw_feed(fd, &rd);
    if (got < 0) break;
    ocp_header_t h;
    const uint8_t *pl;
    while (ocp_reader_next(&rd, &h, &pl) == 1)
      if (h.type == OCP_MSG_ERROR || h.type == OCP_MSG_GOODBYE) {
        ocp_text_msg_t t;
        if (ocp_get_text(pl, h.length, &t, NULL, 0) == 0) {
          code = (int)t.code;
          if (text) snprintf(text, cap, "%s", t.text);
        }
      }
  }
  ocp_reader_free(&rd);
  close(fd);
  return code;
}

static inline void raw_send(int fd, const void *p, size_t n) { assert_int_equal(write(fd, p, n), (ssize_t)n); }

/* Sends a HELLO on a raw socket; `camera` (NULL: none) follows it in the same write. */
static inline void raw_send_hello(int fd, const ocp_hello_t *h, const ocp_camera_t *camera) {
  oc_buf_t b = {0};
  ocp_put_hello(&b, h);
  if (camera) ocp_put_camera(&b, 1, camera);
  raw_send(fd, b.data, b.len);
  oc_buf_free(&b);
}

/* A raw viewer's HELLO asking `budget`; returns the WELCOME's granted budget (0: refused, with
 * the ERROR's code in *code). The socket stays open. */
static inline uint64_t raw_hello(int fd, uint64_t budget, int *code) {
  ocp_hello_t h = {.min_version = 1, .max_version = OCP_VERSION_MAX, .role = OCP_ROLE_VIEWER, .max_depth = 21,
                   .budget = budget, .slot_bytes = 2048, .record_bytes = 32, .width = 160, .height = 90};
  raw_send_hello(fd, &h, NULL);
  ocp_reader_t rd;
  ocp_reader_init(&rd, OCP_MAX_PAYLOAD);
  uint64_t granted = 0;
  *code = -1;
  for (int i = 0; i < 600 && *code < 0; i++) {
    int got = raw_feed(fd, &rd);
    if (got < 0) break;
    ocp_header_t hd;
    const uint8_t *pl;
    while (*code < 0 && ocp_reader_next(&rd, &hd, &pl) == 1) {
      ocp_welcome_t w;
      ocp_text_msg_t t;
      if (hd.type == OCP_MSG_WELCOME && ocp_get_welcome(pl, hd.length, &w, NULL, 0) == 0) {
        granted = w.budget;
        *code = OCP_CODE_OK;
      } else if (hd.type == OCP_MSG_ERROR && ocp_get_text(pl, hd.length, &t, NULL, 0) == 0) {
        *code = (int)t.code;
      }
    }
  }
  ocp_reader_free(&rd);
  return granted;
}

/* A viewer on a raw socket with a small receive window: HELLO and camera sent, then never read. */
static inline int raw_stalled_viewer(int port, uint64_t budget, uint32_t w, uint32_t h) {
  int fd = raw_connect(port);
  int small = 4096;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  ocp_hello_t hello = {.min_version = 1, .max_version = 1, .role = OCP_ROLE_VIEWER, .max_depth = 21, .budget = budget,
                       .slot_bytes = 2048, .record_bytes = 32, .width = w, .height = h, .caps = OCP_CAP_ALL};
  ocp_camera_t cam = sphere_camera((int)w, (int)h);
  raw_send_hello(fd, &hello, &cam);
  return fd;
}


static inline void ev_reply(void *ctx, const ocp_control_t *c) {
  (void)c;
  *(int *)ctx = 1;
}

/* A control connection, welcomed; each CONTROL_REPLY sets *replied to 1 (ev_reply). */
static inline ocv_conn_t *control_open(int port, int *replied) {
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL};
  ocp_viewer_events_t cev = {.ctx = replied, .control_reply = ev_reply};
  ocv_conn_t *ctl = NULL;
  char why[512];
  if (ocv_conn_open(&ctl, "127.0.0.1", port, &cd, &cev, 5.0, why, sizeof why) < 0) fail_msg("control: %s", why);
  assert_int_equal(ocv_conn_wait_ready(ctl, 5.0, why, sizeof why), 0);
  return ctl;
}

/* A test program's group setup: scene_sphere from OC_SOURCE_DIR ("." when unset), and a peer that
 * went away is an error return, not SIGPIPE. */
static inline int net_setup(void **state) {
  (void)state;
  const char *src = getenv("OC_SOURCE_DIR");
  snprintf(scene_sphere, sizeof scene_sphere, "%s/scenes/analytic_sphere.json", src ? src : ".");
  signal(SIGPIPE, SIG_IGN);
  return 0;
}

/* A test's teardown: the server it started is killed when the test failed before stopping it. */
static inline int net_teardown(void **state) {
  (void)state;
  if (running > 0) {
    kill(running, SIGKILL);
    waitpid(running, NULL, 0);
    running = 0;
  }
  return 0;
}

#endif /* OC_TESTS_NET_FIXTURE_H */
