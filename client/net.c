/* net.c — the client connection (ocv_conn_t) and the viewer's network thread (ocv_net_t); net.h.
 *
 * The socket is non-blocking underneath: every wait is a poll() with a deadline, and output is only
 * ever written from inside a loop that also reads, so a server pushing a large epoch while we push
 * ACKs or a control request can never deadlock us. */
#include "net.h"

#include <arpa/inet.h> /* inet_pton */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

#include "oc_err.h"

#define OCV__READ_CHUNK (256u << 10)
#define OCV__READ_MAX_PER_POLL (8u << 20) /* then return, so callers get to run between big epochs */
#define OCV__CLOSE_FLUSH_S 0.5           /* GOODBYE: time to write it, then to see the server's EOF */
#define OCV__ERROR_FLUSH_S 0.5           /* our ERROR frame before closing */

struct ocv_conn_s {
  char host[OCV_HOST_MAX];
  int port;
  char source[OCV_HOST_MAX]; /* local IP to bind before connecting; "": the system's choice */
  char addr[OCV_HOST_MAX + 16]; /* "HOST:PORT" for messages */
  int fd, wake_fd, cancel_fd;
  ocp_viewer_t *v;
  ocp_viewer_events_t user; /* forwarded from our own callbacks */
  oc_buf_t out;             /* unsent output is out.data[out_pos, out.len) */
  size_t out_pos;
  double last_write;
  uint8_t *rbuf;
  int server_closed;
  uint32_t close_code;
  char close_text[OCP_TEXT_MAX + 1];
  uint32_t next_request, want_request;
  int got_reply;
  int32_t reply_status;
  char *reply_json;
  ocv_tap_fn tap; /* sees every byte read, before the session does (ocv_conn_set_tap) */
  void *tap_ctx;
};

/*-*** Helpers ***/

static double ocv__now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Milliseconds left until deadline for poll(): rounded up so a wait never ends just short of it. */
static int ocv__ms_left(double deadline) {
  double left = deadline - ocv__now();
  if (!(left > 0)) return 0;
  if (left > 1e6) return 1000000000;
  return (int)ceil(left * 1e3);
}

static void ocv__errstr(int e, char *buf, size_t cap) {
  if (strerror_r(e, buf, cap) != 0) snprintf(buf, cap, "error %d", e);
}

/* why := "addr: <what><the system's text for err>". @return OC_EIO */
static int ocv__sys_error(const ocv_conn_t *c, int err, const char *what, char *why, size_t why_len) {
  char e[128];
  ocv__errstr(err, e, sizeof e);
  (void)oc_errorf(0, why, why_len, "%s: %s%s", c->addr, what, e);
  return OC_EIO;
}

static size_t ocv__pending(const ocv_conn_t *c) { return c->out.len - c->out_pos; }

static void ocv__close_fd(ocv_conn_t *c) {
  if (c->fd >= 0) close(c->fd);
  c->fd = -1;
}

/* Writes what the socket takes now. @return 0 or OC_EIO (why says why). */
static int ocv__write(ocv_conn_t *c, char *why, size_t why_len) {
  if (c->out.err) {
    (void)oc_errorf(0, why, why_len, "%s: out of memory for output", c->addr);
    return OC_ENOMEM;
  }
  while (c->fd >= 0 && ocv__pending(c)) {
    ssize_t k = send(c->fd, c->out.data + c->out_pos, ocv__pending(c), MSG_NOSIGNAL);
    if (k < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      return ocv__sys_error(c, errno, "send: ", why, why_len);
    }
    c->out_pos += (size_t)k;
    c->last_write = ocv__now();
  }
  if (!ocv__pending(c)) {
    c->out.len = 0;
    c->out_pos = 0;
  } else if (c->out_pos > (64u << 10) && c->out_pos > c->out.len / 2) { /* keep the buffer from creeping */
    memmove(c->out.data, c->out.data + c->out_pos, ocv__pending(c));
    c->out.len -= c->out_pos;
    c->out_pos = 0;
  }
  return 0;
}

/* Writes pending output for at most timeout_s without reading (the connection is being dropped). */
static void ocv__write_for(ocv_conn_t *c, double timeout_s) {
  double deadline = ocv__now() + timeout_s;
  while (c->fd >= 0 && ocv__pending(c)) {
    if (ocv__write(c, NULL, 0) < 0) return;
    if (!ocv__pending(c)) return;
    struct pollfd p = {c->fd, POLLOUT, 0};
    int ms = ocv__ms_left(deadline);
    if (ms == 0) return;
    if (poll(&p, 1, ms) < 0 && errno != EINTR) return;
  }
}

/*-*** Session events: recorded here, then forwarded ***/

static void ocv__on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  ocv_conn_t *c = ctx;
  if (c->user.welcome) c->user.welcome(c->user.ctx, w, resumed);
}

static void ocv__on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  ocv_conn_t *c = ctx;
  if (c->user.state) c->user.state(c->user.ctx, s, bricks);
}

static void ocv__on_stats(void *ctx, const ocp_stats_t *s) {
  ocv_conn_t *c = ctx;
  if (c->user.stats) c->user.stats(c->user.ctx, s);
}

static void ocv__on_control_reply(void *ctx, const ocp_control_t *m) {
  ocv_conn_t *c = ctx;
  if (c->want_request && m->request == c->want_request && !c->got_reply) {
    char *j = malloc((size_t)m->json_len + 1);
    if (j) {
      memcpy(j, m->json, m->json_len);
      j[m->json_len] = '\0';
    }
    free(c->reply_json);
    c->reply_json = j; /* NULL (out of memory) is reported by ocv_control_request() */
    c->reply_status = m->status;
    c->got_reply = 1;
  }
  if (c->user.control_reply) c->user.control_reply(c->user.ctx, m);
}

static void ocv__on_budget(void *ctx, const oc_budget_t *grant) {
  ocv_conn_t *c = ctx;
  if (c->user.budget) c->user.budget(c->user.ctx, grant);
}

static void ocv__on_closed(void *ctx, uint32_t code, const char *text) {
  ocv_conn_t *c = ctx;
  c->server_closed = 1;
  c->close_code = code;
  snprintf(c->close_text, sizeof c->close_text, "%s", text ? text : "");
  if (c->user.closed) c->user.closed(c->user.ctx, code, text);
}

/* The reason for a server-side close, naming the server. */
static void ocv__close_reason(const ocv_conn_t *c, char *why, size_t why_len) {
  if (!c->server_closed)
    (void)oc_errorf(0, why, why_len, "%s: connection closed by the server", c->addr);
  else if (c->close_code == OCP_CODE_OK)
    (void)oc_errorf(0, why, why_len, "%s: closed by the server%s%s", c->addr, c->close_text[0] ? ": " : "", c->close_text);
  else if (!c->close_text[0] || !strcmp(c->close_text, ocp_code_text(c->close_code)))
    (void)oc_errorf(0, why, why_len, "%s: closed by the server: %s", c->addr, ocp_code_text(c->close_code));
  else
    (void)oc_errorf(0, why, why_len, "%s: closed by the server: %s: %s", c->addr, ocp_code_text(c->close_code), c->close_text);
}

/*-*** Addresses ***/

int ocv_parse_address(const char *text, char *host, size_t cap, int *port) {
  if (!text || !host || !cap || !port) return OC_EINVAL;
  const char *colon = strrchr(text, ':');
  const char *ps = colon ? colon + 1 : text;
  if (!*ps || *ps == '-' || *ps == '+' || *ps == ' ') return OC_EINVAL;
  char *end;
  errno = 0;
  long p = strtol(ps, &end, 10);
  if (end == ps || *end || errno || p < 1 || p > 65535) return OC_EINVAL;
  const char *h = text;
  size_t n = colon ? (size_t)(colon - text) : 0;
  if (n >= 2 && h[0] == '[' && h[n - 1] == ']') {
    h++;
    n -= 2;
  } else if (n && (h[0] == '[' || h[n - 1] == ']')) {
    return OC_EINVAL;
  }
  if (n == 0) {
    if (colon && colon != text) return OC_EINVAL; /* "[]:7420" */
    h = OCV_DEFAULT_HOST;
    n = strlen(h);
  }
  if (n >= cap) return OC_EINVAL;
  memcpy(host, h, n);
  host[n] = '\0';
  *port = (int)p;
  return 0;
}

/*-*** One connection ***/

int ocv_conn_create(ocv_conn_t **out, const char *host, int port, const ocp_viewer_desc_t *vd,
                    const ocp_viewer_events_t *ev, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!out) return OC_EINVAL;
  *out = NULL;
  if (!host || !*host || strlen(host) >= OCV_HOST_MAX || port < 1 || port > 65535) {
    (void)oc_errorf(0, why, why_len, "bad server address \"%s:%d\"", host ? host : "", port);
    return OC_EINVAL;
  }
  ocv_conn_t *c = calloc(1, sizeof *c);
  if (!c || !(c->rbuf = malloc(OCV__READ_CHUNK))) {
    free(c);
    (void)oc_errorf(0, why, why_len, "out of memory");
    return OC_ENOMEM;
  }
  c->fd = c->wake_fd = c->cancel_fd = -1;
  snprintf(c->host, sizeof c->host, "%s", host);
  c->port = port;
  snprintf(c->addr, sizeof c->addr, strchr(host, ':') ? "[%s]:%d" : "%s:%d", host, port);
  if (ev) c->user = *ev;
  ocp_viewer_events_t mine = {c,           ocv__on_welcome, ocv__on_state, ocv__on_stats, ocv__on_control_reply,
                              ocv__on_closed, ocv__on_budget};
  int r = vd ? ocp_viewer_create(&c->v, vd, &mine) : OC_EINVAL;
  if (r < 0) {
    (void)oc_errorf(0, why, why_len, "%s: %s", c->addr,
             r == OC_ENOMEM ? "out of memory" : "invalid session settings (budget, viewport, depth or token)");
    free(c->rbuf);
    free(c);
    return r;
  }
  c->last_write = ocv__now();
  *out = c;
  return 0;
}

int ocv_conn_set_source(ocv_conn_t *c, const char *addr) {
  if (!c) return OC_EINVAL;
  if (!addr || !*addr) {
    c->source[0] = '\0';
    return 0;
  }
  struct in6_addr tmp;
  if (strlen(addr) >= sizeof c->source || (inet_pton(AF_INET, addr, &tmp) != 1 && inet_pton(AF_INET6, addr, &tmp) != 1))
    return OC_EINVAL;
  snprintf(c->source, sizeof c->source, "%s", addr);
  return 0;
}

/* Binds fd (of `family`) to the source address, port 0. @return 0 or -errno (-EAFNOSUPPORT: the
 * source is not of that family). */
static int ocv__bind_source(int fd, int family, const char *source) {
  struct sockaddr_storage ss;
  socklen_t len;
  memset(&ss, 0, sizeof ss);
  if (family == AF_INET) {
    struct sockaddr_in *a = (struct sockaddr_in *)&ss;
    a->sin_family = AF_INET;
    if (inet_pton(AF_INET, source, &a->sin_addr) != 1) return -EAFNOSUPPORT;
    len = sizeof *a;
  } else if (family == AF_INET6) {
    struct sockaddr_in6 *a = (struct sockaddr_in6 *)&ss;
    a->sin6_family = AF_INET6;
    if (inet_pton(AF_INET6, source, &a->sin6_addr) != 1) return -EAFNOSUPPORT;
    len = sizeof *a;
  } else {
    return -EAFNOSUPPORT;
  }
#ifdef IP_BIND_ADDRESS_NO_PORT /* the port is picked at connect(), per destination: no early exhaustion */
  int one = 1;
  setsockopt(fd, IPPROTO_IP, IP_BIND_ADDRESS_NO_PORT, &one, sizeof one);
#endif
  return bind(fd, (struct sockaddr *)&ss, len) < 0 ? -errno : 0;
}

/* Connects one address within the deadline (-ECANCELED once `cancel` is readable), from `source`
 * when it is not "" (a failed bind sets *bind_failed). @return the socket or -errno. */
static int ocv__connect_one(const struct addrinfo *ai, double deadline, int cancel, const char *source, int *bind_failed) {
  *bind_failed = 0;
  int fd = socket(ai->ai_family, ai->ai_socktype, ai->ai_protocol);
  if (fd < 0) return -errno;
  int fl = fcntl(fd, F_GETFL);
  if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0 || fcntl(fd, F_SETFD, FD_CLOEXEC) < 0) {
    int e = errno;
    close(fd);
    return -e;
  }
  if (source[0]) {
    int b = ocv__bind_source(fd, ai->ai_family, source);
    if (b < 0) {
      close(fd);
      *bind_failed = 1;
      return b;
    }
  }
  int r = connect(fd, ai->ai_addr, ai->ai_addrlen);
  if (r < 0 && errno != EINPROGRESS && errno != EINTR) {
    int e = errno;
    close(fd);
    return -e;
  }
  if (r < 0) {
    struct pollfd p[2] = {{fd, POLLOUT, 0}, {cancel, POLLIN, 0}};
    int k;
    do k = poll(p, 2, ocv__ms_left(deadline));
    while (k < 0 && errno == EINTR);
    if (k <= 0 || !p[0].revents) {
      int e = k < 0 ? errno : k == 0 ? ETIMEDOUT : ECANCELED;
      close(fd);
      return -e;
    }
    int err = 0;
    socklen_t len = sizeof err;
    if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) < 0) err = errno;
    if (err) {
      close(fd);
      return -err;
    }
  }
  int one = 1; /* frames are small and latency matters (ACKs, cameras): no Nagle */
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

int ocv_conn_reconnect(ocv_conn_t *c, double timeout_s, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  ocv__close_fd(c);
  c->out.len = c->out_pos = 0; /* what was queued belonged to the old connection */
  c->out.err = 0;
  c->server_closed = 0;
  c->close_code = 0;
  c->close_text[0] = '\0';
  double deadline = ocv__now() + (timeout_s > 0 ? timeout_s : 0);

  char service[16];
  snprintf(service, sizeof service, "%d", c->port);
  struct addrinfo hints, *res = NULL;
  memset(&hints, 0, sizeof hints);
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  int g = getaddrinfo(c->host, service, &hints, &res);
  if (g != 0) {
    (void)oc_errorf(0, why, why_len, "%s: cannot resolve \"%s\": %s", c->addr, c->host, gai_strerror(g));
    return OC_EIO;
  }
  int fd = -ECONNREFUSED, bind_err = 0;
  for (const struct addrinfo *ai = res; ai; ai = ai->ai_next) {
    int bind_failed;
    fd = ocv__connect_one(ai, deadline, c->cancel_fd, c->source, &bind_failed);
    bind_err = bind_failed ? -fd : 0; /* the last try's reason; another address may suit the source */
    if (fd >= 0 || fd == -ETIMEDOUT || fd == -ECANCELED) break;
  }
  freeaddrinfo(res);
  if (fd < 0) {
    if (bind_err == EAFNOSUPPORT) {
      (void)oc_errorf(0, why, why_len, "%s: cannot bind to the source address %s: not of the server's address family",
                      c->addr, c->source);
    } else if (bind_err) {
      char e[128];
      ocv__errstr(bind_err, e, sizeof e);
      (void)oc_errorf(0, why, why_len, "%s: cannot bind to the source address %s: %s", c->addr, c->source, e);
    } else if (fd == -ETIMEDOUT) {
      (void)oc_errorf(0, why, why_len, "%s: cannot connect: timed out after %g s", c->addr, timeout_s);
    } else if (fd == -ECANCELED) {
      (void)oc_errorf(0, why, why_len, "%s: connect cancelled", c->addr);
    } else {
      (void)ocv__sys_error(c, -fd, "cannot connect: ", why, why_len);
    }
    return OC_EIO;
  }
  c->fd = fd;
  ocp_viewer_connected(c->v, &c->out);
  int r = ocv__write(c, why, why_len);
  if (r < 0) ocv__close_fd(c);
  return r;
}

int ocv_conn_open(ocv_conn_t **out, const char *host, int port, const ocp_viewer_desc_t *vd,
                  const ocp_viewer_events_t *ev, double timeout_s, char *why, size_t why_len) {
  int r = ocv_conn_create(out, host, port, vd, ev, why, why_len);
  if (r < 0) return r;
  r = ocv_conn_reconnect(*out, timeout_s, why, why_len);
  if (r < 0) {
    ocv_conn_close(*out);
    *out = NULL;
  }
  return r;
}

/* Reads everything there is (up to a bound), feeding the session and writing its answers.
 * @return 0 (still open), 1 (closed by the server) or a negative OC_E*; on 1 and errors the
 * socket is closed. */
static int ocv__read(ocv_conn_t *c, char *why, size_t why_len) {
  size_t total = 0;
  while (total < OCV__READ_MAX_PER_POLL) {
    ssize_t n = recv(c->fd, c->rbuf, OCV__READ_CHUNK, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      int r = ocv__sys_error(c, errno, "", why, why_len);
      ocv__close_fd(c);
      return r;
    }
    if (n == 0) {
      ocv__close_reason(c, why, why_len);
      ocv__close_fd(c);
      return 1;
    }
    total += (size_t)n;
    if (c->tap) c->tap(c->tap_ctx, c->rbuf, (size_t)n);
    char reason[OCP_TEXT_MAX + 1];
    int e = ocp_viewer_feed(c->v, c->rbuf, (size_t)n, &c->out, reason, sizeof reason);
    if (e < 0) { /* the session appended ERROR naming the problem: send it, then close */
      (void)oc_errorf(0, why, why_len, "%s: %s", c->addr, reason[0] ? reason : oc_strerror(e));
      ocv__write_for(c, OCV__ERROR_FLUSH_S);
      ocv__close_fd(c);
      return e;
    }
    if (c->server_closed) { /* after GOODBYE or ERROR the server closes: nothing more to say */
      ocv__close_reason(c, why, why_len);
      ocv__close_fd(c);
      return 1;
    }
    int w = ocv__write(c, why, why_len);
    if (w < 0) {
      ocv__close_fd(c);
      return w;
    }
  }
  return 0;
}

/* One wait: write, poll, read. Returns after input, the deadline, a wake, or (flushing) once all
 * output is written. */
static int ocv__poll(ocv_conn_t *c, double deadline, int until_flushed, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (c->fd < 0) {
    (void)oc_errorf(0, why, why_len, "%s: not connected", c->addr);
    return 1;
  }
  for (;;) {
    int w = ocv__write(c, why, why_len);
    if (w < 0) {
      ocv__close_fd(c);
      return w;
    }
    if (until_flushed && !ocv__pending(c)) return 0;
    /* poll() ignores entries with a negative fd */
    struct pollfd p[3] = {{c->fd, (short)(POLLIN | (ocv__pending(c) ? POLLOUT : 0)), 0}, {c->wake_fd, POLLIN, 0},
                          {c->cancel_fd, POLLIN, 0}};
    int k = poll(p, 3, ocv__ms_left(deadline));
    if (k < 0) {
      if (errno == EINTR) continue;
      return ocv__sys_error(c, errno, "poll: ", why, why_len);
    }
    if (p[0].revents & (POLLIN | POLLHUP | POLLERR)) return ocv__read(c, why, why_len);
    if ((p[1].revents | p[2].revents) & (POLLIN | POLLHUP | POLLERR)) return 0;
    if (k == 0 || ocv__now() >= deadline) return 0;
  }
}

int ocv_conn_poll(ocv_conn_t *c, double timeout_s, char *why, size_t why_len) {
  return ocv__poll(c, ocv__now() + (timeout_s > 0 ? timeout_s : 0), 0, why, why_len);
}

void ocv_conn_set_wake(ocv_conn_t *c, int wake, int cancel) {
  c->wake_fd = wake;
  c->cancel_fd = cancel;
}

int ocv_conn_flush(ocv_conn_t *c, double timeout_s, char *why, size_t why_len) {
  double deadline = ocv__now() + (timeout_s > 0 ? timeout_s : 0);
  for (;;) {
    int r = ocv__poll(c, deadline, 1, why, why_len);
    if (r != 0) return r;
    if (!ocv__pending(c)) return 0;
    if (ocv__now() >= deadline) {
      (void)oc_errorf(0, why, why_len, "%s: timed out after %g s with %zu bytes unsent", c->addr, timeout_s, ocv__pending(c));
      return OC_EIO;
    }
  }
}

/* After queueing a message: write what fits now (errors surface at the next poll). */
static int ocv__queued(ocv_conn_t *c) {
  if (c->out.err) return OC_ENOMEM;
  return ocv__write(c, NULL, 0) < 0 ? OC_EIO : 0;
}

int ocv_conn_camera(ocv_conn_t *c, const ocp_camera_t *cam) {
  int r = ocp_viewer_camera(c->v, cam, &c->out);
  return r < 0 ? r : ocv__queued(c);
}

int ocv_conn_control(ocv_conn_t *c, uint32_t request, const char *json) {
  if (c->fd < 0) return OC_EINVAL;
  int r = ocp_viewer_control(c->v, request, json, &c->out);
  return r < 0 ? r : ocv__queued(c);
}

int ocv_conn_keepalive(ocv_conn_t *c) {
  if (c->fd < 0) return OC_EINVAL;
  ocp_viewer_keepalive(c->v, &c->out);
  return ocv__queued(c);
}

int ocv_conn_wait_ready(ocv_conn_t *c, double timeout_s, char *why, size_t why_len) {
  double deadline = ocv__now() + (timeout_s > 0 ? timeout_s : 0);
  while (!(c->fd >= 0 && ocp_viewer_ready(c->v))) {
    if (ocv__now() >= deadline) {
      (void)oc_errorf(0, why, why_len, "%s: no welcome within %g s", c->addr, timeout_s);
      return OC_EIO;
    }
    int r = ocv__poll(c, deadline, 0, why, why_len);
    if (r != 0) return r;
  }
  return 0;
}

int ocv_control_request(ocv_conn_t *c, const char *json, double timeout_s, char **reply_json, int32_t *status, char *why,
                        size_t why_len) {
  if (reply_json) *reply_json = NULL;
  if (!json || !reply_json) return OC_EINVAL;
  double t0 = ocv__now(), deadline = t0 + (timeout_s > 0 ? timeout_s : 0);
  int r = ocv_conn_wait_ready(c, timeout_s, why, why_len);
  if (r == 1) return OC_EIO;
  if (r < 0) return r;
  uint32_t id = ++c->next_request ? c->next_request : ++c->next_request;
  c->want_request = id;
  c->got_reply = 0;
  r = ocv_conn_control(c, id, json);
  if (r == OC_EINVAL) {
    (void)oc_errorf(0, why, why_len, "%s: request refused before sending (not a control session, or over %u bytes)", c->addr,
             (unsigned)(OCP_MAX_CLIENT_PAYLOAD - 8u));
    c->want_request = 0;
    return r;
  }
  while (!c->got_reply) {
    if (ocv__now() >= deadline) {
      (void)oc_errorf(0, why, why_len, "%s: no reply within %g s", c->addr, timeout_s);
      r = OC_EIO;
      break;
    }
    if (ocv_conn_silence(c) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(c);
    r = ocv__poll(c, fmin(deadline, ocv__now() + OCV_KEEPALIVE_S), 0, why, why_len);
    if (r == 1) r = OC_EIO; /* closed before the reply: why holds the server's reason */
    if (r < 0) break;
  }
  c->want_request = 0;
  if (!c->got_reply) return r;
  c->got_reply = 0;
  if (!c->reply_json) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return OC_ENOMEM;
  }
  *reply_json = c->reply_json;
  c->reply_json = NULL;
  if (status) *status = c->reply_status;
  return 0;
}

void ocv_conn_set_tap(ocv_conn_t *c, ocv_tap_fn tap, void *ctx) {
  if (!c) return;
  c->tap = tap;
  c->tap_ctx = ctx;
}

ocp_viewer_t *ocv_conn_session(ocv_conn_t *c) { return c->v; }
int ocv_conn_fd(const ocv_conn_t *c) { return c->fd; }
const char *ocv_conn_address(const ocv_conn_t *c) { return c->addr; }
size_t ocv_conn_pending(const ocv_conn_t *c) { return ocv__pending(c); }
double ocv_conn_silence(const ocv_conn_t *c) { return ocv__now() - c->last_write; }

void ocv_conn_close(ocv_conn_t *c) {
  if (!c) return;
  if (c->fd >= 0) {
    /* GOODBYE, then half-close and read until the server's EOF: closing with unread input would
     * reset the connection and could discard the GOODBYE before the server reads it. */
    ocp_viewer_goodbye(c->v, &c->out);
    double deadline = ocv__now() + OCV__CLOSE_FLUSH_S;
    while (c->fd >= 0 && ocv__pending(c) && ocv__now() < deadline) {
      struct pollfd p = {c->fd, POLLIN | POLLOUT, 0};
      if (poll(&p, 1, ocv__ms_left(deadline)) < 0 && errno != EINTR) break;
      if (ocv__write(c, NULL, 0) < 0) break;
      if ((p.revents & POLLIN) && recv(c->fd, c->rbuf, OCV__READ_CHUNK, 0) == 0) break;
    }
    shutdown(c->fd, SHUT_WR);
    deadline = ocv__now() + OCV__CLOSE_FLUSH_S;
    for (;;) {
      struct pollfd p = {c->fd, POLLIN, 0};
      int k = poll(&p, 1, ocv__ms_left(deadline));
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) break;
      ssize_t n = recv(c->fd, c->rbuf, OCV__READ_CHUNK, 0);
      if (n == 0 || (n < 0 && errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK)) break;
    }
    ocv__close_fd(c);
  }
  ocp_viewer_free(c->v);
  oc_buf_free(&c->out);
  free(c->reply_json);
  free(c->rbuf);
  free(c);
}

int64_t ocv_conn_close_code(const ocv_conn_t *c, const char **text) {
  if (text) *text = c && c->server_closed ? c->close_text : "";
  return c && c->server_closed ? (int64_t)c->close_code : -1;
}

/*-*** Reconnects ***/

void ocv_retry_init(ocv_retry_t *r, uint32_t max_attempts, double max_s, uint64_t seed) {
  memset(r, 0, sizeof *r);
  r->max_attempts = max_attempts ? max_attempts : OCV_RETRY_ATTEMPTS;
  r->max_s = max_s > 0 ? max_s : OCV_RETRY_S;
  r->seed = seed;
}

double ocv_retry_next(ocv_retry_t *r, uint32_t server_ms, double now, const char *cause, char *line, size_t cap) {
  if (!r->running) {
    r->running = 1;
    r->since = now;
    r->attempts = 0;
    oc_backoff_init(&r->bo, server_ms, r->seed++); /* another run, other jitter */
  }
  double wait = oc_backoff_next(&r->bo) / 1e3;
  if (server_ms / 1e3 > wait) wait = server_ms / 1e3; /* told again (a HELLO during the drain) */
  if (r->attempts >= r->max_attempts || now + wait - r->since > r->max_s) {
    snprintf(line, cap, "%s; gave up after %u reconnect attempt%s in %.1f s", cause, r->attempts,
             r->attempts == 1 ? "" : "s", now - r->since);
    return -1;
  }
  r->attempts++;
  snprintf(line, cap, "%s; reconnect attempt %u of %u in %.2f s", cause, r->attempts, r->max_attempts, wait);
  return wait;
}

void ocv_retry_done(ocv_retry_t *r) {
  r->running = 0;
  r->attempts = 0;
}

int ocv_retry_fatal(int64_t code) {
  return code == OCP_CODE_VERSION || code == OCP_CODE_TOKEN || code == OCP_CODE_KICKED;
}

/*-*** The network thread ***/

struct ocv_net_s {
  ocv_net_desc_t d;
  char host[OCV_HOST_MAX];
  char token[OCP_TOKEN_MAX + 1];
  pthread_t thread;
  int pipe_rd, pipe_wr; /* wakes the thread for a new camera (drained) */
  int stop_rd, stop_wr; /* written once by ocv_net_stop(), never drained: ends every wait, connects too */
  ocv_conn_t *c;        /* the thread's own */
  pthread_mutex_t mu;   /* guards everything below */
  int stop;
  int cam_new;
  ocp_camera_t cam;
  oc_state_t latest; /* the newest complete state, a copy owned here */
  uint64_t latest_seq, taken_seq;
  ocv_net_status_t st;
};

static void ocv__net_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  ocv_net_t *n = ctx;
  pthread_mutex_lock(&n->mu);
  n->st.resumed = resumed;
  n->st.connected = 1;
  n->st.have_welcome = 1;
  n->st.welcome = *w;
  n->st.welcomes++;
  pthread_mutex_unlock(&n->mu);
}

/* BUDGET: the grant in force changes in the one place the HUD reads it (the status' WELCOME). */
static void ocv__net_budget(void *ctx, const oc_budget_t *grant) {
  ocv_net_t *n = ctx;
  pthread_mutex_lock(&n->mu);
  n->st.welcome.grant = *grant;
  n->st.budgets++;
  pthread_mutex_unlock(&n->mu);
}

static void ocv__net_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  ocv_net_t *n = ctx;
  (void)bricks;
  pthread_mutex_lock(&n->mu);
  int r = oc_state_copy(&n->latest, s);
  if (r == 0) {
    n->latest_seq++;
    n->st.states++;
    n->st.epoch = s->epoch;
  } else {
    snprintf(n->st.error, sizeof n->st.error, "epoch %llu: out of memory for a copy of the state",
             (unsigned long long)s->epoch);
  }
  pthread_mutex_unlock(&n->mu);
  if (r == 0 && n->d.on_state) n->d.on_state(n->d.ctx);
}

static void ocv__net_stats(void *ctx, const ocp_stats_t *s) {
  ocv_net_t *n = ctx;
  pthread_mutex_lock(&n->mu);
  n->st.have_stats = 1;
  n->st.server_stats = *s;
  pthread_mutex_unlock(&n->mu);
}

static void ocv__drain_pipe(int fd) {
  char buf[64];
  while (read(fd, buf, sizeof buf) > 0) {
  }
}

/* Sleeps up to t seconds unless woken; @return 1 when asked to stop. */
static int ocv__net_sleep(ocv_net_t *n, double t) {
  struct pollfd p[2] = {{n->pipe_rd, POLLIN, 0}, {n->stop_rd, POLLIN, 0}};
  double deadline = ocv__now() + t;
  int stop;
  for (;;) {
    pthread_mutex_lock(&n->mu);
    stop = n->stop;
    pthread_mutex_unlock(&n->mu);
    if (stop || ocv__now() >= deadline) return stop;
    if (poll(p, 2, ocv__ms_left(deadline)) > 0 && p[0].revents) ocv__drain_pipe(n->pipe_rd);
  }
}

/* After a failure (why): waits for the next attempt, or gives up. @return 1 to leave the loop
 * (stopped, or given up: the status says so). */
static int ocv__net_retry(ocv_net_t *n, ocv_retry_t *rt, const char *why) {
  const char *text;
  int64_t code = ocv_conn_close_code(n->c, &text);
  uint32_t server_ms = code == OCP_CODE_RECONNECT ? ocp_reconnect_delay_ms(text) : 0;
  char line[sizeof n->st.error];
  double wait = ocv_retry_fatal(code) ? -1 : ocv_retry_next(rt, server_ms, ocv__now(), why, line, sizeof line);
  if (wait < 0 && ocv_retry_fatal(code)) snprintf(line, sizeof line, "%s; not reconnecting", why);
  pthread_mutex_lock(&n->mu);
  memcpy(n->st.error, line, sizeof line);
  n->st.attempt = rt->attempts;
  n->st.gave_up = wait < 0;
  pthread_mutex_unlock(&n->mu);
  if (n->d.on_log) n->d.on_log(n->d.ctx, line);
  return wait < 0 || ocv__net_sleep(n, wait);
}

static void *ocv__net_main(void *arg) {
  ocv_net_t *n = arg;
  char why[512];
  ocv_retry_t rt;
  ocv_retry_init(&rt, n->d.retry_attempts, n->d.retry_s, n->d.seed);
  int connected = 0, stop = 0;
  uint64_t welcomes = 0;
  while (!stop) {
    pthread_mutex_lock(&n->mu);
    stop = n->stop;
    int cam_new = n->cam_new;
    ocp_camera_t cam = n->cam;
    n->cam_new = 0;
    pthread_mutex_unlock(&n->mu);
    if (stop) break;
    /* The session keeps the camera (also while disconnected: its viewport goes into the next HELLO)
     * and sends it with every WELCOME, so one call covers reconnects. */
    if (cam_new) ocv_conn_camera(n->c, &cam);
    if (!connected) {
      if (ocv_conn_reconnect(n->c, n->d.connect_timeout_s, why, sizeof why) < 0) {
        stop = ocv__net_retry(n, &rt, why);
        continue;
      }
      connected = 1;
      pthread_mutex_lock(&n->mu);
      n->st.connects++;
      pthread_mutex_unlock(&n->mu);
    }
    ocp_viewer_t *v = ocv_conn_session(n->c);
    double silence = ocv_conn_silence(n->c);
    if (ocp_viewer_ready(v) && silence >= n->d.keepalive_s) {
      ocv_conn_keepalive(n->c);
      silence = 0;
    }
    double wait = n->d.keepalive_s - silence;
    int r = ocv_conn_poll(n->c, wait < 0.01 ? 0.01 : wait, why, sizeof why);
    ocv__drain_pipe(n->pipe_rd);
    pthread_mutex_lock(&n->mu);
    n->st.connected = r == 0 && ocp_viewer_ready(v);
    ocp_viewer_stats(v, &n->st.viewer);
    if (n->st.welcomes != welcomes) { /* welcomed again: this run of attempts is over */
      welcomes = n->st.welcomes;
      ocv_retry_done(&rt);
      n->st.attempt = 0;
    }
    pthread_mutex_unlock(&n->mu);
    if (r == 0) continue;
    connected = 0;
    stop = ocv__net_retry(n, &rt, why);
  }
  ocv_conn_close(n->c); /* GOODBYE */
  n->c = NULL;
  pthread_mutex_lock(&n->mu);
  n->st.connected = 0;
  pthread_mutex_unlock(&n->mu);
  return NULL;
}

/* A camera the server would refuse is refused here (the same check as ocp_viewer_camera()). */
static int ocv__camera_valid(const ocp_camera_t *cam) {
  oc_buf_t b = {0};
  ocp_camera_t back;
  ocp_put_camera(&b, OCP_VERSION_MAX, cam);
  int e = b.err ? OC_ENOMEM : ocp_get_camera(b.data + OCP_HEADER_BYTES, b.len - OCP_HEADER_BYTES, &back, NULL, 0);
  oc_buf_free(&b);
  return e == 0;
}

static void ocv__net_free(ocv_net_t *n) {
  ocv_conn_close(n->c);
  int fds[4] = {n->pipe_rd, n->pipe_wr, n->stop_rd, n->stop_wr};
  for (int i = 0; i < 4; i++)
    if (fds[i] >= 0) close(fds[i]);
  oc_state_free(&n->latest);
  pthread_mutex_destroy(&n->mu);
  free(n);
}

int ocv_net_start(ocv_net_t **out, const ocv_net_desc_t *d) {
  if (!out) return OC_EINVAL;
  *out = NULL;
  if (!d || d->viewer.role != OCP_ROLE_VIEWER || d->port < 0 || d->port > 65535 ||
      (d->host && strlen(d->host) >= OCV_HOST_MAX) || (d->viewer.token && strlen(d->viewer.token) > OCP_TOKEN_MAX))
    return OC_EINVAL;
  ocv_net_t *n = calloc(1, sizeof *n);
  if (!n) return OC_ENOMEM;
  n->pipe_rd = n->pipe_wr = n->stop_rd = n->stop_wr = -1;
  if (pthread_mutex_init(&n->mu, NULL) != 0) {
    free(n);
    return OC_ENOMEM;
  }
  oc_state_init(&n->latest);
  n->d = *d;
  snprintf(n->host, sizeof n->host, "%s", d->host ? d->host : OCV_DEFAULT_HOST);
  n->d.host = n->host;
  if (!n->d.port) n->d.port = OCV_DEFAULT_PORT;
  if (d->viewer.token) {
    snprintf(n->token, sizeof n->token, "%s", d->viewer.token);
    n->d.viewer.token = n->token;
  }
  if (!(n->d.connect_timeout_s > 0)) n->d.connect_timeout_s = 5.0;
  if (!n->d.seed) n->d.seed = (uint64_t)(ocv__now() * 1e9) ^ ((uint64_t)getpid() << 32);
  if (!(n->d.keepalive_s > 0)) n->d.keepalive_s = OCV_KEEPALIVE_S;

  int p[2], q[2];
  if (pipe(p) != 0) {
    ocv__net_free(n);
    return OC_EIO;
  }
  n->pipe_rd = p[0];
  n->pipe_wr = p[1];
  if (pipe(q) != 0) {
    ocv__net_free(n);
    return OC_EIO;
  }
  n->stop_rd = q[0];
  n->stop_wr = q[1];
  int fds[4] = {p[0], p[1], q[0], q[1]};
  for (int i = 0; i < 4; i++)
    if (fcntl(fds[i], F_SETFL, fcntl(fds[i], F_GETFL) | O_NONBLOCK) < 0 || fcntl(fds[i], F_SETFD, FD_CLOEXEC) < 0) {
      ocv__net_free(n);
      return OC_EIO;
    }
  ocp_viewer_events_t ev = {n, ocv__net_welcome, ocv__net_state, ocv__net_stats, NULL, NULL, ocv__net_budget};
  char why[256];
  int r = ocv_conn_create(&n->c, n->host, n->d.port, &n->d.viewer, &ev, why, sizeof why);
  if (r < 0) {
    ocv__net_free(n);
    return r;
  }
  ocv_conn_set_wake(n->c, n->pipe_rd, n->stop_rd);
  if (pthread_create(&n->thread, NULL, ocv__net_main, n) != 0) {
    ocv__net_free(n);
    return OC_EIO;
  }
  *out = n;
  return 0;
}

static void ocv__net_wake(int fd) {
  char b = 1;
  ssize_t k;
  do k = write(fd, &b, 1);
  while (k < 0 && errno == EINTR); /* EAGAIN: the pipe is full, so the thread is woken anyway */
}

int ocv_net_set_camera(ocv_net_t *n, const ocp_camera_t *cam) {
  if (!n || !cam || !ocv__camera_valid(cam)) return OC_EINVAL;
  pthread_mutex_lock(&n->mu);
  n->cam = *cam;
  n->cam_new = 1;
  pthread_mutex_unlock(&n->mu);
  ocv__net_wake(n->pipe_wr);
  return 0;
}

int ocv_net_take_state(ocv_net_t *n, oc_state_t *dst, uint64_t *epoch) {
  int got = 0;
  pthread_mutex_lock(&n->mu);
  if (n->latest_seq != n->taken_seq) {
    /* swap rather than copy: dst gets the state, we keep dst's arrays for the next copy */
    oc_state_t t = *dst;
    *dst = n->latest;
    n->latest = t;
    n->taken_seq = n->latest_seq;
    if (epoch) *epoch = dst->epoch;
    got = 1;
  }
  pthread_mutex_unlock(&n->mu);
  return got;
}

void ocv_net_status(ocv_net_t *n, ocv_net_status_t *out) {
  pthread_mutex_lock(&n->mu);
  *out = n->st;
  pthread_mutex_unlock(&n->mu);
}

void ocv_net_stop(ocv_net_t *n) {
  if (!n) return;
  pthread_mutex_lock(&n->mu);
  n->stop = 1;
  pthread_mutex_unlock(&n->mu);
  ocv__net_wake(n->stop_wr);
  pthread_join(n->thread, NULL);
  ocv__net_free(n); /* the thread closed and freed its connection */
}
