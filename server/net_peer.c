/* net_peer.c — per-address limits (net_internal.h): how many connections one IP address holds
 * open, and how fast it may start handshakes (a token bucket of max_per_address tokens refilled
 * at handshake_rate per second). A connect storm from one address is refused here, before it
 * costs a session, so it cannot crowd out the others. */
#include <stdlib.h>
#include <string.h>

#include "net_internal.h"
#include "oc_bytes.h" /* oc_grow */

/* Entries beyond this are refused (CONNECTIONS): the table is bounded whatever the peers do. */
#define OCS_PEERS_MAX 4096

const char *ocs_refusal_key(ocs_refusal_t r) {
  static const char *keys[] = {
#define OCS__REFUSAL_KEY(name, key) key,
      OCS_REFUSALS(OCS__REFUSAL_KEY)
#undef OCS__REFUSAL_KEY
  };
  return (unsigned)r < OCS_REFUSE_COUNT ? keys[r] : "?";
}

static void refill(const ocs_server_t *srv, ocs_peer_t *p, double now) {
  double cap = (double)srv->desc.max_per_address;
  p->tokens += (now - p->refilled) * srv->desc.handshake_rate;
  if (p->tokens > cap) p->tokens = cap;
  p->refilled = now;
}

static ocs_peer_t *peer_get(ocs_server_t *srv, const char *ip, double now) {
  for (int i = 0; i < srv->npeers; i++)
    if (!strcmp(srv->peers[i]->ip, ip)) return srv->peers[i];
  if (srv->npeers == OCS_PEERS_MAX) ocs_peer_sweep(srv, now);
  if (srv->npeers == OCS_PEERS_MAX) return NULL;
  ocs_peer_t **a = oc_grow(srv->peers, &srv->peers_cap, (size_t)srv->npeers, sizeof *a, 16);
  if (!a) return NULL;
  srv->peers = a;
  ocs_peer_t *p = calloc(1, sizeof *p);
  if (!p) return NULL;
  size_t n = strlen(ip);
  if (n >= sizeof p->ip) n = sizeof p->ip - 1;
  memcpy(p->ip, ip, n);
  p->tokens = (double)srv->desc.max_per_address;
  p->refilled = now;
  srv->peers[srv->npeers++] = p;
  return p;
}

ocs_peer_t *ocs_peer_admit(ocs_server_t *srv, const char *ip, double now, ocs_refusal_t *refusal) {
  ocs_peer_t *p = peer_get(srv, ip, now);
  if (!p) {
    *refusal = OCS_REFUSE_CONNECTIONS;
    return NULL;
  }
  refill(srv, p, now);
  if (p->conns >= srv->desc.max_per_address) {
    *refusal = OCS_REFUSE_PER_ADDRESS;
    return NULL;
  }
  if (p->tokens < 1.0) {
    *refusal = OCS_REFUSE_RATE;
    return NULL;
  }
  p->tokens -= 1.0;
  p->conns++;
  return p;
}

void ocs_peer_release(ocs_peer_t *p) {
  if (p && p->conns > 0) p->conns--;
}

void ocs_peer_sweep(ocs_server_t *srv, double now) {
  int k = 0;
  for (int i = 0; i < srv->npeers; i++) {
    ocs_peer_t *p = srv->peers[i];
    refill(srv, p, now);
    if (!p->conns && p->tokens >= (double)srv->desc.max_per_address) free(p);
    else srv->peers[k++] = p;
  }
  srv->npeers = k;
}

void ocs_peer_free_all(ocs_server_t *srv) {
  for (int i = 0; i < srv->npeers; i++) free(srv->peers[i]);
  free(srv->peers);
  srv->peers = NULL;
  srv->npeers = 0;
  srv->peers_cap = 0;
}
