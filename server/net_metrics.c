/* net_metrics.c — GET /metrics over HTTP (net_internal.h; docs/operations.md, "Metrics"). The
 * HTTP is libmicrohttpd's, in external-poll mode on the loop thread, so that no second thread
 * reads the server's counters: MHD_USE_EPOLL without an internal thread, a uv_poll on its epoll
 * descriptor and a uv_timer armed from MHD_get_timeout(), MHD_run() when either fires.
 *
 * The figures are those of the stats reply (net_stats.c), read only while the world is free: a
 * scrape that comes while a step or production runs on the pool is suspended, and answered when
 * that ends (ocs_metrics_resume(), from the server's after_step hook), as a control request
 * waits. When the server has a token (the control token, else the viewer token), a scrape
 * presents it as "Authorization: Bearer TOKEN". */
#include <errno.h>
#include <microhttpd.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"
#include "prom_text.h"

/* At most this many scrapes at once (each may wait for the world), this many from one address. */
#define OCS_METRICS_CONNECTIONS 16
#define OCS_METRICS_PER_ADDRESS 4
#define OCS_METRICS_TIMEOUT_S 10

typedef struct ocs_metrics_s ocs_metrics_t;

struct ocs_metrics_s {
  ocs_server_t *srv;
  struct MHD_Daemon *d;
  uv_poll_t poll;     /* on the daemon's epoll descriptor */
  uv_timer_t timer;   /* MHD_get_timeout() */
  int open_handles;   /* freed when the last one has closed */
  int closing;        /* scrapes get 503 */
  struct MHD_Connection *waiting[OCS_METRICS_CONNECTIONS]; /* suspended until the world is free */
  int nwaiting;
};

const char *ocs_metrics_token(const ocs_server_desc_t *d) { return d->control_token ? d->control_token : d->token; }

/*-*** Answers ***/

static enum MHD_Result answer(struct MHD_Connection *c, unsigned status, const char *type, oc_buf_t *body) {
  if (body->err) {
    oc_buf_free(body);
    status = MHD_HTTP_INTERNAL_SERVER_ERROR;
  }
  struct MHD_Response *r = body->len ? MHD_create_response_from_buffer(body->len, body->data, MHD_RESPMEM_MUST_FREE)
                                      : MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
  if (!r) {
    oc_buf_free(body);
    return MHD_NO;
  }
  body->data = NULL; /* the response owns it */
  MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, type);
  if (status == MHD_HTTP_UNAUTHORIZED) MHD_add_response_header(r, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
  enum MHD_Result q = MHD_queue_response(c, status, r);
  MHD_destroy_response(r);
  return q;
}

static enum MHD_Result answer_text(struct MHD_Connection *c, unsigned status, const char *text) {
  oc_buf_t b = {0};
  oc_buf_append(&b, text, strlen(text));
  return answer(c, status, "text/plain; charset=utf-8", &b);
}

static enum MHD_Result answer_metrics(ocs_metrics_t *m, struct MHD_Connection *c) {
  ocs_stats_t st;
  if (ocs_stats_gather(m->srv, &st) < 0) return answer_text(c, MHD_HTTP_INTERNAL_SERVER_ERROR, "out of memory\n");
  oc_buf_t b = {0};
  ocs_metrics_text(&st, &b);
  ocs_stats_free(&st);
  return answer(c, MHD_HTTP_OK, OCS_PROM_CONTENT_TYPE, &b);
}

static int authorized(const ocs_metrics_t *m, struct MHD_Connection *c) {
  const char *want = m->srv->control_token ? m->srv->control_token : m->srv->token;
  if (!want) return 1;
  const char *got = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION);
  if (!got || strncmp(got, "Bearer ", 7) != 0) return 0;
  return ocs_token_equal(want, (const uint8_t *)got + 7, strlen(got + 7));
}

/* MHD calls this first with the headers (nothing is answered then), again for any body (ignored),
 * and once more when the request is complete; and again after a resume. */
static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url, const char *method,
                                  const char *version, const char *upload, size_t *upload_size, void **req) {
  ocs_metrics_t *m = cls;
  (void)version, (void)upload;
  if (!*req) {
    *req = m;
    return MHD_YES;
  }
  if (*upload_size) {
    *upload_size = 0;
    return MHD_YES;
  }
  if (strcmp(method, MHD_HTTP_METHOD_GET) != 0 && strcmp(method, MHD_HTTP_METHOD_HEAD) != 0)
    return answer_text(c, MHD_HTTP_METHOD_NOT_ALLOWED, "GET /metrics\n");
  if (strcmp(url, "/metrics") != 0) return answer_text(c, MHD_HTTP_NOT_FOUND, "not found: the figures are at /metrics\n");
  if (!authorized(m, c)) return answer_text(c, MHD_HTTP_UNAUTHORIZED, "present the token: Authorization: Bearer TOKEN\n");
  if (m->closing) return answer_text(c, MHD_HTTP_SERVICE_UNAVAILABLE, "the server is shutting down\n");
  if (!m->srv->stepping) return answer_metrics(m, c);
  if (m->nwaiting == OCS_METRICS_CONNECTIONS) /* not while the connection limit holds */
    return answer_text(c, MHD_HTTP_SERVICE_UNAVAILABLE, "too many scrapes waiting\n");
  MHD_suspend_connection(c); /* the world is busy: answered when it is free */
  m->waiting[m->nwaiting++] = c;
  return MHD_YES;
}

/*-*** On the loop ***/

static void on_timer(uv_timer_t *t);

static void run(ocs_metrics_t *m) {
  MHD_UNSIGNED_LONG_LONG ms;
  MHD_run(m->d);
  if (m->closing) return;
  if (MHD_get_timeout(m->d, &ms) == MHD_YES) uv_timer_start(&m->timer, on_timer, ms, 0);
  else uv_timer_stop(&m->timer);
}

static void on_timer(uv_timer_t *t) { run(t->data); }

static void on_poll(uv_poll_t *p, int status, int events) {
  (void)status, (void)events; /* an error shows in MHD_run() as well */
  run(p->data);
}

static void on_handle_closed(uv_handle_t *h) {
  ocs_metrics_t *m = h->data;
  if (--m->open_handles == 0) free(m);
}

static void log_mhd(void *cls, const char *fmt, va_list ap) {
  char msg[512];
  (void)cls;
  vsnprintf(msg, sizeof msg, fmt, ap);
  size_t n = strlen(msg);
  while (n && msg[n - 1] == '\n') msg[--n] = 0;
  oc_log_warn("metrics: %s", msg);
}

static struct MHD_Daemon *start_daemon(ocs_metrics_t *m, const struct sockaddr_storage *sa) {
  unsigned flags = MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG;
  if (sa->ss_family == AF_INET6) flags |= MHD_USE_IPv6;
  return MHD_start_daemon(flags, (uint16_t)m->srv->desc.metrics_port, NULL, NULL, on_request, m,
                          MHD_OPTION_EXTERNAL_LOGGER, log_mhd, NULL, /* first, or MHD logs to stderr before it */
                          MHD_OPTION_SOCK_ADDR, (const struct sockaddr *)sa,
                          MHD_OPTION_LISTENING_ADDRESS_REUSE, 1u,
                          MHD_OPTION_CONNECTION_LIMIT, (unsigned)OCS_METRICS_CONNECTIONS,
                          MHD_OPTION_PER_IP_CONNECTION_LIMIT, (unsigned)OCS_METRICS_PER_ADDRESS,
                          MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)OCS_METRICS_TIMEOUT_S, MHD_OPTION_END);
}

/* The address bound, as "HOST:PORT", into srv->metrics_address. */
static void name_bound(ocs_metrics_t *m, const char *host) {
  struct sockaddr_storage sa = {0};
  socklen_t len = sizeof sa;
  const union MHD_DaemonInfo *li = MHD_get_daemon_info(m->d, MHD_DAEMON_INFO_LISTEN_FD);
  if (li) getsockname(li->listen_fd, (struct sockaddr *)&sa, &len);
  ocs_net_name(m->srv->metrics_address, sizeof m->srv->metrics_address, host, &sa);
}

int ocs_metrics_open(ocs_server_t *srv, char *why, size_t why_len) {
  const ocs_server_desc_t *d = &srv->desc;
  const char *host = d->metrics_host ? d->metrics_host : "127.0.0.1";
  struct sockaddr_storage sa;
  if (!d->metrics) return 0;
  if (ocs_net_sockaddr(host, d->metrics_port, &sa) < 0)
    return oc_errorf(OC_EINVAL, why, why_len, "--metrics-listen: \"%s\" is not an IPv4 or IPv6 address", host);
  ocs_metrics_t *m = calloc(1, sizeof *m);
  if (!m) return OC_ENOMEM;
  m->srv = srv;
  errno = 0;
  if (!(m->d = start_daemon(m, &sa))) {
    int e = errno;
    free(m);
    return oc_errorf(OC_EIO, why, why_len, "cannot serve metrics on %s:%d: %s", host, d->metrics_port,
                     e ? strerror(e) : "libmicrohttpd did not start");
  }
  const union MHD_DaemonInfo *ep = MHD_get_daemon_info(m->d, MHD_DAEMON_INFO_EPOLL_FD);
  int r = ep ? uv_poll_init(&srv->loop, &m->poll, ep->epoll_fd) : UV_EINVAL;
  if (r < 0) {
    MHD_stop_daemon(m->d);
    free(m);
    return oc_errorf(OC_EIO, why, why_len, "metrics: cannot poll the HTTP daemon: %s", uv_strerror(r));
  }
  uv_timer_init(&srv->loop, &m->timer);
  m->poll.data = m->timer.data = m;
  m->open_handles = 2;
  srv->metrics = m;
  name_bound(m, host);
  uv_poll_start(&m->poll, UV_READABLE, on_poll);
  run(m);
  return 0;
}

void ocs_metrics_resume(ocs_server_t *srv) {
  ocs_metrics_t *m = srv->metrics;
  if (!m || !m->nwaiting) return;
  int n = m->nwaiting;
  m->nwaiting = 0; /* a scrape that finds the world busy again waits again */
  for (int i = 0; i < n; i++) MHD_resume_connection(m->waiting[i]);
  run(m);
}

void ocs_metrics_close(ocs_server_t *srv) {
  ocs_metrics_t *m = srv->metrics;
  if (!m) return;
  srv->metrics = NULL;
  m->closing = 1;
  for (int i = 0; i < m->nwaiting; i++) MHD_resume_connection(m->waiting[i]); /* none may stay suspended */
  m->nwaiting = 0;
  MHD_run(m->d); /* waiting scrapes get 503 */
  uv_close((uv_handle_t *)&m->poll, on_handle_closed); /* before the daemon closes the descriptor */
  uv_close((uv_handle_t *)&m->timer, on_handle_closed);
  MHD_stop_daemon(m->d);
}
