/* net_proxy.c — the PROXY protocol header and the trusted-proxy list (net_proxy.h). Every length
 * is checked against what has arrived before it is read, so a header split across reads asks for
 * more and garbage is refused as soon as a byte cannot belong to a header. */
#include "net_proxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"

static const uint8_t v2_sig[12] = {0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};
static const char v1_sig[] = "PROXY ";
#define V1_MAX 107 /* the longest v1 line, CRLF included */
#define V2_PRE 16  /* signature, version and command, family, length */

static size_t min_sz(size_t a, size_t b) { return a < b ? a : b; }

int ocs_proxy_signature(const uint8_t *p, size_t n) {
  return n && (!memcmp(p, v2_sig, min_sz(n, sizeof v2_sig)) || !memcmp(p, v1_sig, min_sz(n, sizeof v1_sig - 1)));
}

/*-*** v2 ***/

/* The addresses block of a PROXY command: family (high nibble) and transport (low) in fam. */
static int v2_addresses(uint8_t fam, const uint8_t *a, size_t len, ocs_proxy_hdr_t *h, char *why, size_t why_len) {
  int af = fam >> 4, stream = (fam & 0x0F) == 1;
  if (af == 0) { /* UNSPEC: the receiver uses the connection's own endpoints */
    h->local = 1;
    return 1;
  }
  if ((af != 1 && af != 2) || !stream)
    return oc_errorf(OC_EINVAL, why, why_len, "PROXY v2: address family 0x%02x: only TCP over IPv4 or IPv6", fam);
  size_t alen = af == 1 ? 4 : 16, need = 2 * alen + 4;
  if (len < need)
    return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v2: %zu address bytes, %s needs %zu", len, af == 1 ? "IPv4" : "IPv6", need);
  if (!inet_ntop(af == 1 ? AF_INET : AF_INET6, a, h->ip, sizeof h->ip))
    return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v2: bad source address");
  h->port = (a[2 * alen] << 8) | a[2 * alen + 1];
  return 1; /* TLVs after the addresses are skipped: nothing here needs them */
}

static int parse_v2(const uint8_t *p, size_t n, ocs_proxy_hdr_t *h, char *why, size_t why_len) {
  if (n < V2_PRE) return 0;
  size_t len = ((size_t)p[14] << 8) | p[15];
  if (V2_PRE + len > OCS_PROXY_MAX)
    return oc_errorf(OC_ETOOBIG, why, why_len, "PROXY v2: %zu bytes, over the %d accepted", V2_PRE + len, OCS_PROXY_MAX);
  if ((p[12] >> 4) != 2) return oc_errorf(OC_EVERSION, why, why_len, "PROXY v2: version %d", p[12] >> 4);
  int cmd = p[12] & 0x0F;
  if (cmd > 1) return oc_errorf(OC_EVERSION, why, why_len, "PROXY v2: unknown command %d", cmd);
  if (n < V2_PRE + len) return 0;
  h->version = 2;
  h->bytes = V2_PRE + len;
  if (cmd == 0) { /* LOCAL: the proxy's own connection (a health check); addresses ignored */
    h->local = 1;
    return 1;
  }
  return v2_addresses(p[13], p + V2_PRE, len, h, why, why_len);
}

/*-*** v1 ***/

/* "TCP4 SRC DST SPORT DPORT" (the line after "PROXY ", without CRLF). */
static int v1_fields(char *line, ocs_proxy_hdr_t *h, char *why, size_t why_len) {
  char *save = NULL, *f[6];
  int k = 0;
  for (char *t = strtok_r(line, " ", &save); t; t = strtok_r(NULL, " ", &save))
    if (k < 6) f[k++] = t;
    else return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v1: too many fields");
  if (k >= 1 && !strcmp(f[0], "UNKNOWN")) { /* the proxy's own connection, whatever follows */
    h->local = 1;
    return 1;
  }
  int af = k == 5 && !strcmp(f[0], "TCP4") ? AF_INET : k == 5 && !strcmp(f[0], "TCP6") ? AF_INET6 : 0;
  if (!af) return oc_errorf(OC_EINVAL, why, why_len, "PROXY v1: expected TCP4, TCP6 or UNKNOWN and 4 fields");
  uint8_t a[16];
  if (inet_pton(af, f[1], a) != 1 || inet_pton(af, f[2], a) != 1)
    return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v1: bad %s address", f[0]);
  for (int i = 3; i < 5; i++) { /* 1 to 5 decimal digits: strtol would take blanks and signs */
    size_t len = strspn(f[i], "0123456789");
    long port = len && len <= 5 && !f[i][len] ? strtol(f[i], NULL, 10) : -1;
    if (port < 0 || port > 65535) return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v1: bad port");
    if (i == 3) h->port = (int)port;
  }
  snprintf(h->ip, sizeof h->ip, "%s", f[1]);
  return 1;
}

static int parse_v1(const uint8_t *p, size_t n, ocs_proxy_hdr_t *h, char *why, size_t why_len) {
  size_t lim = min_sz(n, V1_MAX), end = 0;
  for (size_t i = sizeof v1_sig - 1; i + 1 < lim && !end; i++)
    if (p[i] == '\r' && p[i + 1] == '\n') end = i;
  if (!end) {
    if (n >= V1_MAX) return oc_errorf(OC_ETOOBIG, why, why_len, "PROXY v1: no CRLF within %d bytes", V1_MAX);
    return memchr(p, 0, n) ? oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v1: a NUL byte") : 0;
  }
  char line[V1_MAX];
  size_t len = end - (sizeof v1_sig - 1);
  memcpy(line, p + sizeof v1_sig - 1, len);
  line[len] = 0;
  if (strlen(line) != len) return oc_errorf(OC_ECORRUPT, why, why_len, "PROXY v1: a NUL byte");
  h->version = 1;
  h->bytes = end + 2;
  return v1_fields(line, h, why, why_len);
}

int ocs_proxy_parse(const uint8_t *p, size_t n, ocs_proxy_hdr_t *h, char *why, size_t why_len) {
  memset(h, 0, sizeof *h);
  if (!ocs_proxy_signature(p, n)) {
    if (!n) return 0;
    return oc_errorf(OC_ECORRUPT, why, why_len, "not a PROXY protocol header (first byte 0x%02x)", p[0]);
  }
  if (p[0] == v2_sig[0]) return n < sizeof v2_sig ? 0 : parse_v2(p, n, h, why, why_len);
  return n < sizeof v1_sig - 1 ? 0 : parse_v1(p, n, h, why, why_len);
}

/*-*** Trusted addresses ***/

/* sa's address into a (IPv4-mapped IPv6 folded to IPv4). @return 0, or -1 for another family. */
static int addr_of(const struct sockaddr_storage *sa, ocs_proxy_addr_t *a) {
  static const uint8_t mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF, 0xFF};
  memset(a, 0, sizeof *a);
  if (sa->ss_family == AF_INET) {
    a->family = AF_INET;
    memcpy(a->addr, &((const struct sockaddr_in *)sa)->sin_addr, 4);
    return 0;
  }
  if (sa->ss_family != AF_INET6) return -1;
  const uint8_t *b = ((const struct sockaddr_in6 *)sa)->sin6_addr.s6_addr;
  a->family = memcmp(b, mapped, 12) ? AF_INET6 : AF_INET;
  memcpy(a->addr, a->family == AF_INET ? b + 12 : b, a->family == AF_INET ? 4 : 16);
  return 0;
}

/* One numeric address of the list into a. @return 0 or -1. */
static int list_item(const char *text, ocs_proxy_addr_t *a) {
  struct sockaddr_storage sa;
  memset(&sa, 0, sizeof sa);
  if (inet_pton(AF_INET, text, &((struct sockaddr_in *)&sa)->sin_addr) == 1) sa.ss_family = AF_INET;
  else if (inet_pton(AF_INET6, text, &((struct sockaddr_in6 *)&sa)->sin6_addr) == 1) sa.ss_family = AF_INET6;
  else return -1;
  return addr_of(&sa, a);
}

int ocs_proxy_list_parse(const char *list, ocs_proxy_addr_t *out, char *why, size_t why_len) {
  int n = 0;
  const char *p = list;
  for (;;) {
    const char *comma = strchr(p, ',');
    size_t len = comma ? (size_t)(comma - p) : strlen(p);
    char item[64];
    if (len == 0 || len >= sizeof item) return oc_errorf(OC_EINVAL, why, why_len, "an empty or overlong address in \"%s\"", list);
    memcpy(item, p, len);
    item[len] = 0;
    if (n == OCS_PROXY_TRUSTED_MAX)
      return oc_errorf(OC_EINVAL, why, why_len, "more than %d addresses", OCS_PROXY_TRUSTED_MAX);
    if (list_item(item, &out[n]) < 0)
      return oc_errorf(OC_EINVAL, why, why_len, "\"%s\" is not a numeric IPv4 or IPv6 address", item);
    n++;
    if (!comma) return n;
    p = comma + 1;
  }
}

int ocs_proxy_list_has(const ocs_proxy_addr_t *list, int n, const struct sockaddr_storage *sa) {
  ocs_proxy_addr_t a;
  if (addr_of(sa, &a) < 0) return 0;
  for (int i = 0; i < n; i++)
    if (list[i].family == a.family && !memcmp(list[i].addr, a.addr, a.family == AF_INET ? 4 : 16)) return 1;
  return 0;
}
