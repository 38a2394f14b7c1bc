/* net_listener.c — the listening socket and new connections (net_internal.h). A connection is
 * checked against the limits before it costs more than its session struct: the server's
 * connection limit, then its address's (net_peer.c). A refused one gets ERROR naming the limit;
 * past a hard ceiling it is closed without a word, so a storm costs bounded memory. A connection
 * from a --trusted-proxy meets those limits only once its PROXY header names the client. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"

/* Refused connections still closing beyond max_connections + this are closed unanswered. */
#define OCS_REFUSING_MAX 256

static uint64_t random_u64(void) {
  uint64_t v = 0;
  if (uv_random(NULL, NULL, &v, sizeof v, 0, NULL) < 0) v = (uint64_t)(ocs_net_now() * 1e9) ^ 0x9E3779B97F4A7C15ull;
  return v ? v : 1;
}

/* "IP" into ip and "IP:PORT" into s->addr; the address itself into *sa. @return 0, or -1 when
 * the peer has no name any more (it left before it was accepted: a health check, say). */
static int peer_name(ocs_session_t *s, char *ip, size_t cap, struct sockaddr_storage *sa) {
  int len = sizeof *sa, port = 0;
  memset(sa, 0, sizeof *sa);
  if (uv_tcp_getpeername(&s->tcp, (struct sockaddr *)sa, &len) != 0) return -1;
  snprintf(ip, cap, "?");
  if (sa->ss_family == AF_INET) {
    uv_ip4_name((struct sockaddr_in *)sa, ip, cap);
    port = ntohs(((struct sockaddr_in *)sa)->sin_port);
  } else if (sa->ss_family == AF_INET6) {
    uv_ip6_name((struct sockaddr_in6 *)sa, ip, cap);
    port = ntohs(((struct sockaddr_in6 *)sa)->sin6_port);
  }
  snprintf(s->addr, sizeof s->addr, strchr(ip, ':') ? "[%s]:%d" : "%s:%d", ip, port);
  return 0;
}

/* A trusted proxy's connection waits for its PROXY header (net_input.c), which names the client
 * whose address the limits then see; the handshake deadline covers the wait. @return 0, or -1
 * (out of memory: closed). */
static int await_proxy(ocs_session_t *s) {
  if (!(s->proxy_buf = malloc(OCS_PROXY_MAX))) {
    s->state = OCS_SS_CLOSING;
    ocs_session_close_handle(s);
    return -1;
  }
  s->version = OCP_VERSION_MAX; /* a refusal is sent before any HELLO was read */
  return 0;
}

int ocs_listener_admit(ocs_session_t *s, const char *ip) {
  ocs_server_t *srv = s->srv;
  const ocs_server_desc_t *d = &srv->desc;
  char why[160];
  ocs_refusal_t r;
  s->version = OCP_VERSION_MAX; /* a refusal is sent before any HELLO was read */
  if (srv->stopping) {
    ocs_session_refuse(s, OCS_REFUSE_SHUTDOWN, "shutting down");
    return 0;
  }
  if (srv->nadmitted >= d->max_connections) {
    snprintf(why, sizeof why, "too many connections (limit %d)", d->max_connections);
    ocs_session_refuse(s, OCS_REFUSE_CONNECTIONS, why);
    return 0;
  }
  if (!(s->peer = ocs_peer_admit(srv, ip, ocs_net_now(), &r))) {
    if (r == OCS_REFUSE_PER_ADDRESS)
      snprintf(why, sizeof why, "too many connections from %s (limit %d per address)", ip, d->max_per_address);
    else if (r == OCS_REFUSE_RATE)
      snprintf(why, sizeof why, "too many new connections from %s (limit %g per second per address)", ip, d->handshake_rate);
    else
      snprintf(why, sizeof why, "too many client addresses at once");
    ocs_session_refuse(s, r, why);
    return 0;
  }
  srv->nadmitted++;
  return 1;
}

static void on_connection(uv_stream_t *ls, int status) {
  ocs_server_t *srv = ls->data;
  if (status < 0) {
    oc_log_warn("accept: %s", uv_strerror(status));
    return;
  }
  ocs_session_t *s = calloc(1, sizeof *s);
  if (!s) return;
  uv_tcp_init(&srv->loop, &s->tcp);
  s->tcp.data = s;
  s->srv = srv;
  s->connected = 1;
  srv->nconnected++;
  ocs_session_link(srv, s);
  char ip[48];
  struct sockaddr_storage sa;
  if (uv_accept(ls, (uv_stream_t *)&s->tcp) < 0 || srv->nconnected - srv->nadmitted > srv->desc.max_connections + OCS_REFUSING_MAX ||
      peer_name(s, ip, sizeof ip, &sa) < 0) {
    s->state = OCS_SS_CLOSING;
    ocs_session_close_handle(s);
    return;
  }
  do s->id = ++srv->next_id;
  while (!s->id);
  s->secret = random_u64();
  s->created = s->last_rx = s->last_progress = ocs_net_now();
  ocp_reader_init(&s->rd, OCP_MAX_CLIENT_PAYLOAD);
  srv->counts.accepted++;
  if (srv->ntrusted && ocs_proxy_list_has(srv->trusted, srv->ntrusted, &sa)) {
    if (await_proxy(s) < 0) return;
  } else if (!ocs_listener_admit(s, ip)) {
    return;
  }
  uv_tcp_nodelay(&s->tcp, 1);
  if (srv->desc.send_buffer > 0) {
    int v = srv->desc.send_buffer;
    uv_send_buffer_size((uv_handle_t *)&s->tcp, &v);
  }
  ocs_input_start(s);
}

int ocs_net_sockaddr(const char *host, int port, struct sockaddr_storage *sa) {
  if (uv_ip4_addr(host, port, (struct sockaddr_in *)sa) == 0 || uv_ip6_addr(host, port, (struct sockaddr_in6 *)sa) == 0)
    return 0;
  return OC_EINVAL;
}

void ocs_net_name(char *out, size_t cap, const char *host, const struct sockaddr_storage *sa) {
  int port = sa->ss_family == AF_INET6 ? ntohs(((const struct sockaddr_in6 *)sa)->sin6_port)
                                       : ntohs(((const struct sockaddr_in *)sa)->sin_port);
  snprintf(out, cap, strchr(host, ':') ? "[%s]:%d" : "%s:%d", host, port);
}

int ocs_listener_open(ocs_server_t *srv, char *why, size_t why_len) {
  const ocs_server_desc_t *d = &srv->desc;
  struct sockaddr_storage sa;
  int r;
  uv_tcp_init(&srv->loop, &srv->listener);
  srv->listener.data = srv;
  if (ocs_net_sockaddr(srv->host, d->port, &sa) < 0) {
    snprintf(why, why_len, "--listen: \"%s\" is not an IPv4 or IPv6 address", srv->host);
    return OC_EINVAL;
  }
  if ((r = uv_tcp_bind(&srv->listener, (struct sockaddr *)&sa, 0)) < 0 ||
      (r = uv_listen((uv_stream_t *)&srv->listener, 128, on_connection)) < 0) {
    snprintf(why, why_len, "cannot listen on %s:%d: %s", srv->host, d->port, uv_strerror(r));
    return OC_EIO;
  }
  int len = sizeof sa;
  uv_tcp_getsockname(&srv->listener, (struct sockaddr *)&sa, &len);
  ocs_net_name(srv->address, sizeof srv->address, srv->host, &sa);
  return 0;
}
