/* stress_fault.c — overcast-stress's misbehaving clients (--faults): connections that stop
 * reading, that vanish mid-handshake or mid-epoch, and that send garbage. They run on one thread
 * of their own, beside the measured viewers, with non-blocking sockets and poll(); the
 * coordinator asks for a round of them before a step (stress_faults_round) and checks the rest:
 * the measured viewers miss no epoch, the server's RSS stays within its own accounting.
 *
 * Each round opens one connection of each kind asked for, cycling through the kind's variants:
 *
 *   stall    0  a viewer that takes its WELCOME, sends its camera, then never reads nor writes
 *            1  the same, but it keeps the connection alive with KEEPALIVE (never times out)
 *   drop     0  connect, then reset at once
 *            1  half a HELLO, then reset
 *            2  a viewer reset at the first byte of its first epoch (mid-epoch)
 *            3  a viewer reset right after its first complete state (acknowledged)
 *   garbage  0  64 random bytes (no frame magic)
 *            1  a frame header announcing 4 GiB
 *            2  a HELLO whose payload is 3 bytes
 *            3  after WELCOME, a frame of unknown type 0x5A
 *            4  after WELCOME, a CAMERA whose position is NaN
 *            5  3 bytes of a header, then silence
 *
 * Garbage must be answered with an ERROR frame and closed by the server within its handshake
 * timeout plus STRESS_FAULT_GRACE seconds of being sent (garbage after WELCOME: of the WELCOME,
 * which a running step may hold back for up to STRESS_FAULT_WELCOME_WAIT); anything else (no ERROR, still open, or served as if
 * valid) is a failure. A stalled viewer must be let go within the server's stall timeout plus
 * STRESS_FAULT_STALL_GRACE (seen at the end, by reading it to its EOF); meanwhile its unsent bytes are
 * read from the "sessions" request by the coordinator. Drops need no answer. */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <arpa/inet.h>
#include <time.h>
#include <unistd.h>

#include "ocp.h"
#include "stress.h"

#define SF_MAX_CONNS STRESS_FAULT_MAX_CONNS
static const int sf_variants[STRESS_FK_COUNT] = {2, 4, 6};
static const char *const sf_kind_names[STRESS_FK_COUNT] = {"stall", "drop", "garbage"};

typedef struct {
  int kind, variant;
  int fd;
  double opened, sent;     /* sent: when the garbage went out */
  double deadline;         /* garbage must be closed by then (0: none) */
  ocp_viewer_t *sess;      /* stall, drop 2..3, garbage 3..4: the handshake */
  ocp_reader_t rd;         /* garbage 0..2, 5: frames from the server */
  oc_buf_t out;
  int welcomed, injected, got_error, states;
  uint32_t error_code;
  double last_keepalive;
  double stalled_at; /* stall: when it stopped reading (after its WELCOME) */
} sf_conn_t;

struct stress_faults_s {
  stress_run_t *run;
  pthread_t thread;
  int started;
  /* under run->mu */
  int rounds_asked, stopping, restarted, restart_seen;
  /* the thread's own */
  int rounds_done;
  sf_conn_t **c; /* each on its own: the sessions' callbacks hold its address */
  int n;
  uint64_t rng;
  stress_fault_conns_t st;
};

const char *stress_fault_kind_name(int kind) { return kind >= 0 && kind < STRESS_FK_COUNT ? sf_kind_names[kind] : "?"; }

static void sf_fail(stress_faults_t *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sf_fail(stress_faults_t *f, const char *fmt, ...) {
  if (f->st.failure[0]) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(f->st.failure, sizeof f->st.failure, fmt, ap);
  va_end(ap);
}

static uint64_t sf_rand(stress_faults_t *f) { /* splitmix64 */
  uint64_t z = (f->rng += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/* Closes with a reset (SO_LINGER 0): the peer sees ECONNRESET, not an orderly end. */
static void sf_reset(int fd) {
  struct linger lg = {1, 0};
  setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
  close(fd);
}

static void sf_conn_free(sf_conn_t *c, int reset) {
  if (c->fd >= 0) {
    if (reset) sf_reset(c->fd);
    else close(c->fd);
  }
  c->fd = -1;
  ocp_viewer_free(c->sess);
  c->sess = NULL;
  ocp_reader_free(&c->rd);
  oc_buf_free(&c->out);
}

static void sf_on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  (void)w;
  (void)resumed;
  ((sf_conn_t *)ctx)->welcomed = 1;
}
static void sf_on_state(void *ctx, const oc_state_t *s, uint32_t b) {
  (void)s;
  (void)b;
  ((sf_conn_t *)ctx)->states++;
}
static void sf_on_closed(void *ctx, uint32_t code, const char *text) {
  (void)text;
  sf_conn_t *c = ctx;
  c->got_error = 1;
  c->error_code = code;
}

static int sf_uses_session(int kind, int variant) {
  return kind == STRESS_FK_STALL || (kind == STRESS_FK_DROP && variant >= 2) ||
         (kind == STRESS_FK_GARBAGE && (variant == 3 || variant == 4));
}

/* Writes what is queued without blocking. @return 0 or -1 (the connection is gone). */
static int sf_flush(sf_conn_t *c) {
  while (c->out.len) {
    ssize_t k = send(c->fd, c->out.data, c->out.len, MSG_NOSIGNAL);
    if (k < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
    memmove(c->out.data, c->out.data + k, c->out.len - (size_t)k);
    c->out.len -= (size_t)k;
  }
  return 0;
}

/* The connection's fate is known: count it (closed by the server: `by_server`). */
static void sf_resolve(stress_faults_t *f, sf_conn_t *c, int by_server, double now) {
  int k = c->kind;
  if (by_server) {
    f->st.closed[k]++;
    double s = now - (c->sent ? c->sent : c->opened);
    if (s > f->st.close_s_max[k]) f->st.close_s_max[k] = s;
  }
  if (c->got_error) f->st.errors[k]++;
  if (k == STRESS_FK_GARBAGE) {
    if (!by_server) {
      f->st.late++;
      if (!c->sent) sf_fail(f, "garbage %d: no WELCOME %.1f s after its HELLO", c->variant, now - c->opened);
      else
        sf_fail(f, "garbage %d: still open %.1f s after it was sent (the server's handshake timeout is %.0f s)", c->variant,
                now - c->sent, f->st.handshake_s);
    } else if (!c->got_error) {
      f->st.unanswered++;
      sf_fail(f, "garbage %d: closed without an ERROR frame naming the problem", c->variant);
    } else if (c->states) {
      f->st.unanswered++;
      sf_fail(f, "garbage %d: served %d state%s before its ERROR", c->variant, c->states, c->states == 1 ? "" : "s");
    }
  }
  sf_conn_free(c, !by_server && k == STRESS_FK_DROP);
}

/* c's socket: a small receive window for a stall, bound to --source-address, connected to the
 * server, non-blocking. @return 0, or -1 (socket and c freed; refused or failed is counted). */
static int sf_connect(stress_faults_t *f, sf_conn_t *c) {
  stress_run_t *run = f->run;
  int kind = c->kind, variant = c->variant;
  c->fd = socket(AF_INET, SOCK_STREAM, 0);
  f->st.opened[kind]++;
  if (c->fd < 0) {
    sf_fail(f, "%s %d: socket: %s", sf_kind_names[kind], variant, strerror(errno));
    free(c);
    return -1;
  }
  if (kind == STRESS_FK_STALL) { /* a small window: the server's socket stops draining at once */
    int sz = 4096;
    setsockopt(c->fd, SOL_SOCKET, SO_RCVBUF, &sz, sizeof sz);
  }
  if (run->o->source) { /* --source-address: from that local address, port 0 */
    struct sockaddr_in src = {.sin_family = AF_INET};
    const char *err = NULL;
    if (inet_pton(AF_INET, run->o->source, &src.sin_addr) != 1) err = "not an IPv4 address, as the fault connections need";
    else if (bind(c->fd, (struct sockaddr *)&src, sizeof src) < 0) err = strerror(errno);
    if (err) {
      sf_fail(f, "%s %d: cannot bind to the source address %s: %s", sf_kind_names[kind], variant, run->o->source, err);
      close(c->fd);
      free(c);
      return -1;
    }
  }
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)run->port)};
  inet_pton(AF_INET, run->host, &a.sin_addr);
  if (connect(c->fd, (struct sockaddr *)&a, sizeof a) < 0) { /* loopback: immediate */
    f->st.refused[kind]++;
    close(c->fd);
    free(c);
    return -1;
  }
  int one = 1;
  setsockopt(c->fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  fcntl(c->fd, F_SETFL, fcntl(c->fd, F_GETFL) | O_NONBLOCK);
  return 0;
}

/* Garbage before any HELLO, variant 0..3: random bytes (never the magic), a 4 GiB frame, a short
 * HELLO, a stalled header. */
static void sf_garbage(stress_faults_t *f, sf_conn_t *c) {
  uint8_t b[64];
  size_t len = 0;
  if (c->variant == 0) {
    for (size_t i = 0; i < sizeof b; i++) b[i] = (uint8_t)sf_rand(f);
    b[0] = 0xEE; /* never the magic */
    len = sizeof b;
  } else if (c->variant == 1) {
    uint8_t h[8] = {OCP_MAGIC0, OCP_MAGIC1, OCP_VERSION_MAX, OCP_MSG_HELLO, 0xF0, 0xFF, 0xFF, 0xFF};
    memcpy(b, h, 8);
    len = 8;
  } else if (c->variant == 2) {
    uint8_t h[11] = {OCP_MAGIC0, OCP_MAGIC1, OCP_VERSION_MAX, OCP_MSG_HELLO, 3, 0, 0, 0, 1, 2, 3};
    memcpy(b, h, sizeof h);
    len = sizeof h;
  } else {
    uint8_t h[3] = {OCP_MAGIC0, OCP_MAGIC1, OCP_VERSION_MAX};
    memcpy(b, h, sizeof h);
    len = sizeof h;
  }
  oc_buf_append(&c->out, b, len);
}

/* Drop variants 0 and 1: reset at once, or after half a HELLO. */
static void sf_drop_now(sf_conn_t *c) {
  if (c->variant == 1) {
    ocp_hello_t h = {.min_version = OCP_VERSION_MIN, .max_version = OCP_VERSION_MAX, .role = OCP_ROLE_VIEWER,
                     .budget = 1u << 20, .max_depth = 21, .width = 64, .height = 64, .caps = OCP_CAP_ALL};
    oc_buf_t tmp = {0};
    ocp_put_hello(&tmp, &h);
    oc_buf_append(&c->out, tmp.data, tmp.len / 2);
    oc_buf_free(&tmp);
    sf_flush(c);
  }
  sf_reset(c->fd);
  c->fd = -1;
  sf_conn_free(c, 0);
  free(c);
}

static void sf_open(stress_faults_t *f, int kind, int variant, double now) {
  stress_run_t *run = f->run;
  if (f->n >= SF_MAX_CONNS) return;
  sf_conn_t *c = calloc(1, sizeof *c);
  if (!c) {
    sf_fail(f, "out of memory");
    return;
  }
  c->kind = kind;
  c->variant = variant;
  c->opened = now;
  if (sf_connect(f, c) < 0) return;
  f->c[f->n] = c;
  ocp_reader_init(&c->rd, OCP_MAX_PAYLOAD);
  f->n++;
  if (kind == STRESS_FK_GARBAGE) c->deadline = now + f->st.handshake_s + STRESS_FAULT_GRACE;
  if (kind == STRESS_FK_GARBAGE && sf_uses_session(kind, variant)) c->deadline += STRESS_FAULT_WELCOME_WAIT;
  else if (kind == STRESS_FK_GARBAGE) c->sent = now;
  if (sf_uses_session(kind, variant)) {
    ocp_viewer_desc_t vd = {.role = OCP_ROLE_VIEWER, .budget = run->o->fault_budget_mib << 20, .max_depth = 21,
                            .width = (uint32_t)run->o->width, .height = (uint32_t)run->o->height, .caps = OCP_CAP_ALL,
                            .token = run->o->token};
    ocp_viewer_events_t ev = {.ctx = c, .welcome = sf_on_welcome, .state = sf_on_state, .closed = sf_on_closed};
    if (ocp_viewer_create(&c->sess, &vd, &ev) < 0) {
      sf_fail(f, "%s %d: cannot create a session", sf_kind_names[kind], variant);
      sf_conn_free(c, 0);
      free(c);
      f->n--;
      return;
    }
    ocp_viewer_connected(c->sess, &c->out);
    /* a camera the server accepts: the WELCOME's default is sent once it is known (below) */
  } else if (kind == STRESS_FK_DROP) {
    sf_drop_now(c); /* variants 0 and 1 end here */
    f->n--;
    return;
  } else {
    sf_garbage(f, c);
  }
  if (sf_flush(c) < 0) {
    sf_resolve(f, c, 1, now);
    free(c);
    f->n--;
  }
}

/* Frames from the server on a connection without a session (garbage before HELLO, and what a
 * stalled viewer never read): an ERROR is noted, a WELCOME counts as being served. */
static void sf_scan(sf_conn_t *c, const uint8_t *buf, size_t n) {
  if (ocp_reader_feed(&c->rd, buf, n) < 0) return;
  ocp_header_t h;
  const uint8_t *p;
  while (ocp_reader_next(&c->rd, &h, &p) == 1) {
    ocp_text_msg_t t;
    if (h.type == OCP_MSG_ERROR && ocp_get_text(p, h.length, &t, NULL, 0) == 0) {
      c->got_error = 1;
      c->error_code = t.code;
    } else if (h.type == OCP_MSG_WELCOME && !c->sess) {
      c->states++; /* garbage accepted as a HELLO: counted as served */
    }
  }
}

/* Input on c. @return 1 when the server closed it (EOF, reset), 0 otherwise. */
static int sf_read(stress_faults_t *f, sf_conn_t *c, double now) {
  uint8_t buf[65536];
  for (;;) {
    ssize_t k = recv(c->fd, buf, sizeof buf, 0);
    if (k == 0) return 1;
    if (k < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : 1;
    if (c->sess) {
      int had_welcome = c->welcomed;
      char why[512];
      int first_epoch_byte = c->welcomed && !c->states && c->kind == STRESS_FK_DROP && c->variant == 2;
      ocp_viewer_feed(c->sess, buf, (size_t)k, &c->out, why, sizeof why);
      if (first_epoch_byte) return -1; /* reset now, mid-epoch */
      if (!had_welcome && c->welcomed) {
        const ocp_welcome_t *w = ocp_viewer_welcome(c->sess);
        oc_camera_pose_t pose = {{w->cam_lat, w->cam_lon, w->cam_alt}, w->cam_heading, w->cam_pitch, w->cam_fov};
        oc_camera_t cam = oc_camera_from_pose(pose);
        ocp_camera_t cm = {cam.pos, cam.forward, cam.up, pose.fov, (uint32_t)f->run->o->width, (uint32_t)f->run->o->height};
        ocp_viewer_camera(c->sess, &cm, &c->out);
        c->last_keepalive = now;
        if (c->kind == STRESS_FK_GARBAGE && !c->injected) {
          c->injected = 1;
          c->sent = now; /* the clock on the server's answer starts here, not at the connect */
          c->deadline = now + f->st.handshake_s + STRESS_FAULT_GRACE;
          if (c->variant == 3) {
            uint8_t h[12] = {OCP_MAGIC0, OCP_MAGIC1, (uint8_t)w->version, 0x5A, 4, 0, 0, 0, 0xDE, 0xAD, 0xBE, 0xEF};
            oc_buf_append(&c->out, h, sizeof h);
          } else {
            ocp_camera_t bad = cm;
            bad.pos.x = NAN;
            ocp_put_camera(&c->out, (uint8_t)w->version, &bad); /* the session would refuse it: the encoder does not */
          }
        }
      }
      if (c->kind == STRESS_FK_DROP && c->variant == 3 && c->states) {
        sf_flush(c); /* the ACK goes out, then the reset */
        return -1;
      }
      if (c->kind == STRESS_FK_STALL && c->welcomed) {
        sf_flush(c);
        c->stalled_at = now;
        return 0; /* from now on it never reads */
      }
    } else {
      sf_scan(c, buf, (size_t)k);
    }
  }
}

/* Reads a stalled connection to its end: frames scanned for ERROR/GOODBYE, at most `timeout_s`
 * (and 64 MiB). @return 1 at EOF or a reset (the server closed it), 0 when it stays open. */
static int sf_drain(sf_conn_t *c, double timeout_s) {
  uint8_t buf[65536];
  size_t total = 0;
  double until = stress_now() + timeout_s;
  int eof = 0;
  while (!eof && stress_now() < until && total < (64u << 20)) {
    struct pollfd p = {c->fd, POLLIN, 0};
    if (poll(&p, 1, 100) <= 0) continue;
    ssize_t k = recv(c->fd, buf, sizeof buf, 0);
    if (k <= 0) {
      eof = k == 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
      continue;
    }
    total += (size_t)k;
    sf_scan(c, buf, (size_t)k);
  }
  return eof;
}

/* One connection after a poll: read what came, keep a stalled viewer's session alive, write what
 * waits, judge a deadline. @return 1 when the connection is resolved (gone), else 0. */
static int sf_tend(stress_faults_t *f, sf_conn_t *c, short revents, double now) {
  if (revents & (POLLIN | POLLHUP | POLLERR)) {
    int r = revents & POLLIN || !(c->kind == STRESS_FK_STALL && c->welcomed) ? sf_read(f, c, now) : 1;
    if (r < 0) { /* our own reset (drop) */
      sf_reset(c->fd);
      c->fd = -1;
      if (c->variant == 3) f->st.states_before_drop += (uint64_t)c->states;
      sf_resolve(f, c, 0, now);
      return 1;
    }
    if (r > 0) {
      sf_resolve(f, c, 1, now);
      return 1;
    }
  }
  if (c->kind == STRESS_FK_STALL && c->variant == 1 && c->welcomed && now - c->last_keepalive >= 1.0) {
    ocp_viewer_keepalive(c->sess, &c->out);
    c->last_keepalive = now;
  }
  if (c->out.len && sf_flush(c) < 0) {
    sf_resolve(f, c, 1, now);
    return 1;
  }
  if (c->deadline > 0 && now > c->deadline) {
    sf_resolve(f, c, 0, now);
    return 1;
  }
  return 0;
}

/* The end of the thread: every connection left judged and freed. */
static void sf_finish(stress_faults_t *f) {
  /* What is left: stalled viewers (and drops waiting for an epoch). Whether the server let a
   * stalled one go shows only by reading what it could not deliver: EOF after it, or nothing more. */
  double end = stress_now();
  for (int i = 0; i < f->n; i++) {
    sf_conn_t *c = f->c[i];
    if (c->kind == STRESS_FK_STALL && c->stalled_at > 0) {
      int eof = sf_drain(c, 3.0);
      double held = end - c->stalled_at;
      if (eof) {
        f->st.closed[STRESS_FK_STALL]++;
        if (c->got_error) f->st.errors[STRESS_FK_STALL]++;
      } else {
        f->st.open_at_end++;
        if (f->st.stall_s > 0 && held > f->st.stall_s + STRESS_FAULT_STALL_GRACE) {
          f->st.late++;
          sf_fail(f, "stall %d: a viewer that stopped reading is still held %.1f s later (the server's stall timeout is %.0f s)",
                  c->variant, held, f->st.stall_s);
        }
      }
    }
    sf_conn_free(c, 0);
    free(c);
  }
  f->n = 0;
}

static void *sf_main(void *arg) {
  stress_faults_t *f = arg;
  stress_run_t *run = f->run;
  const stress_opts_t *o = run->o;
  struct pollfd *pf = calloc(SF_MAX_CONNS, sizeof *pf);
  if (!pf) {
    sf_fail(f, "out of memory");
    return NULL;
  }
  for (;;) {
    pthread_mutex_lock(&run->mu);
    int asked = f->rounds_asked, stopping = f->stopping, restarted = f->restarted != f->restart_seen;
    f->restart_seen = f->restarted;
    pthread_cond_broadcast(&run->cv);
    pthread_mutex_unlock(&run->mu);
    double now = stress_now();
    if (restarted) { /* the server is killed under them: nothing to judge */
      for (int i = 0; i < f->n; i++) {
        sf_conn_free(f->c[i], 0);
        free(f->c[i]);
      }
      f->n = 0;
    }
    while (f->rounds_done < asked && !stopping) {
      int r = f->rounds_done++;
      for (int k = 0; k < STRESS_FK_COUNT; k++)
        if (o->faults & (1 << k)) sf_open(f, k, r % sf_variants[k], now);
    }
    /* the end: what is left is judged once every garbage connection is settled or late */
    if (stopping) {
      int pending = 0;
      for (int i = 0; i < f->n; i++)
        if (f->c[i]->kind == STRESS_FK_GARBAGE && now < f->c[i]->deadline) pending++;
      if (!pending) break;
    }
    for (int i = 0; i < f->n; i++) {
      sf_conn_t *c = f->c[i];
      int stalled = c->kind == STRESS_FK_STALL && c->welcomed;
      pf[i].fd = c->fd;
      pf[i].events = (short)((stalled ? 0 : POLLIN) | (c->out.len ? POLLOUT : 0));
      pf[i].revents = 0;
    }
    poll(pf, (nfds_t)f->n, 50);
    now = stress_now();
    for (int i = 0; i < f->n; i++) {
      sf_conn_t *c = f->c[i];
      if (sf_tend(f, c, pf[i].revents, now)) {
        free(c);
        f->c[i] = f->c[--f->n];
        pf[i] = pf[f->n];
        i--;
      }
    }
  }
  sf_finish(f);
  free(pf);
  return NULL;
}

int stress_faults_start(stress_run_t *run, double handshake_s, double stall_s) {
  stress_faults_t *f = calloc(1, sizeof *f);
  if (!f) return OC_ENOMEM;
  f->c = calloc(SF_MAX_CONNS, sizeof *f->c);
  if (!f->c) {
    free(f);
    return OC_ENOMEM;
  }
  f->run = run;
  f->rng = run->o->seed * 0x2545F4914F6CDD1Dull + 7;
  f->st.handshake_s = handshake_s;
  f->st.stall_s = stall_s;
  if (pthread_create(&f->thread, NULL, sf_main, f) != 0) {
    free(f->c);
    free(f);
    return OC_EIO;
  }
  f->started = 1;
  run->faults = f;
  return 0;
}

void stress_faults_round(stress_run_t *run) {
  if (!run->faults) return;
  pthread_mutex_lock(&run->mu);
  run->faults->rounds_asked++;
  pthread_mutex_unlock(&run->mu);
}

void stress_faults_restarted(stress_run_t *run) {
  stress_faults_t *f = run->faults;
  if (!f) return;
  pthread_mutex_lock(&run->mu);
  int n = ++f->restarted;
  while (f->restart_seen != n) { /* the thread has let go of them before the server dies */
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    t.tv_nsec += 100000000;
    if (t.tv_nsec >= 1000000000) t.tv_sec++, t.tv_nsec -= 1000000000;
    pthread_cond_timedwait(&run->cv, &run->mu, &t);
  }
  pthread_mutex_unlock(&run->mu);
}

void stress_faults_stop(stress_run_t *run, stress_fault_conns_t *out) {
  stress_faults_t *f = run->faults;
  if (!f) return;
  pthread_mutex_lock(&run->mu);
  f->stopping = 1;
  pthread_mutex_unlock(&run->mu);
  if (f->started) pthread_join(f->thread, NULL);
  if (out) *out = f->st;
  free(f->c);
  free(f);
  run->faults = NULL;
}
