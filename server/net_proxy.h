/* net_proxy.h — the PROXY protocol header (HAProxy's proxy-protocol.txt, v2 binary and v1 text)
 * that a trusted proxy sends before the wire protocol, and the --trusted-proxy list. Pure
 * functions over bytes (no libuv), so the parser is unit-tested and fuzzed alone
 * (tests/server/test_net_proxy.c, tests/fuzz/fuzz_proxy.c). Not a public interface. */
#ifndef OC_SERVER_NET_PROXY_H
#define OC_SERVER_NET_PROXY_H

#include <stddef.h>
#include <stdint.h>
#include <sys/socket.h> /* struct sockaddr_storage */

/*! The longest header accepted: 16 bytes of v2 preamble and 520 of addresses and TLVs (what the
 *  specification asks a receiver to read at least); v1 lines are at most 107 bytes. */
#define OCS_PROXY_MAX 536
/*! Addresses in a --trusted-proxy list. */
#define OCS_PROXY_TRUSTED_MAX 16

/* What a complete header says. */
typedef struct {
  int local;    /* LOCAL command (v2), UNSPEC family or "UNKNOWN" (v1): the proxy's own connection
                   (a health check); ip and port are then empty */
  int version;  /* 1 or 2 */
  char ip[48];  /* the client's address, numeric */
  int port;     /* the client's port */
  size_t bytes; /* the header's length on the stream */
} ocs_proxy_hdr_t;

/*! ocs_proxy_parse() : the header at the start of p[0..n).
 *  @return 1 with *h filled (h->bytes consumed), 0 when every byte so far fits a header that is not
 *  complete yet, or a negative OC_E* with a one-line reason: OC_ECORRUPT (not a PROXY header, or a
 *  malformed one), OC_ETOOBIG (longer than OCS_PROXY_MAX), OC_EVERSION (an unknown version or
 *  command), OC_EINVAL (an address family other than IPv4 and IPv6). */
int ocs_proxy_parse(const uint8_t *p, size_t n, ocs_proxy_hdr_t *h, char *why, size_t why_len);

/*! ocs_proxy_signature() : whether p[0..n) (n ≥ 1) begins like a PROXY header of either version:
 *  how a header from a peer that is not trusted is told from other garbage. */
int ocs_proxy_signature(const uint8_t *p, size_t n);

/* One trusted address: IPv4 as AF_INET, IPv4-mapped IPv6 folded to it. */
typedef struct {
  int family;
  uint8_t addr[16];
} ocs_proxy_addr_t;

/*! ocs_proxy_list_parse() : "ADDR[,ADDR...]" (numeric IPv4 or IPv6, at most OCS_PROXY_TRUSTED_MAX).
 *  @return how many (≥ 1) into out, or OC_EINVAL with a reason naming the bad one. */
int ocs_proxy_list_parse(const char *list, ocs_proxy_addr_t *out, char *why, size_t why_len);

/*! ocs_proxy_list_has() : whether the peer address sa is one of list[0..n). */
int ocs_proxy_list_has(const ocs_proxy_addr_t *list, int n, const struct sockaddr_storage *sa);

#endif /* OC_SERVER_NET_PROXY_H */
