/* fuzz_proxy.c — libFuzzer target for the PROXY protocol header parser and the trusted-proxy list
 * (server/net_proxy.c).
 *
 * Each input is:
 *  - parsed as the first bytes of a connection from an exact-size copy (so ASan sees any
 *    over-read): a header it accepts is at most OCS_PROXY_MAX bytes and no more than arrived, its
 *    address a terminated string; and every shorter prefix of an accepted header must ask for more
 *    (a header split across reads parses the same);
 *  - parsed as a --trusted-proxy list (up to its first NUL).
 * Seeds: tests/fuzz/corpus/proxy/ (v2 IPv4, IPv6 with a TLV, LOCAL; v1 TCP4, UNKNOWN; garbage). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "net_proxy.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  uint8_t *p = malloc(size ? size : 1);
  if (!p) return 0;
  memcpy(p, data, size);
  ocs_proxy_hdr_t h;
  char why[160];
  int r = ocs_proxy_parse(p, size, &h, why, sizeof why);
  if (r == 1) {
    if (h.bytes > size || h.bytes > OCS_PROXY_MAX || !memchr(h.ip, 0, sizeof h.ip) || h.port < 0 || h.port > 65535) abort();
    for (size_t k = 0; k < h.bytes; k++) {
      ocs_proxy_hdr_t g;
      if (ocs_proxy_parse(p, k, &g, why, sizeof why) != 0) abort();
    }
  } else if (r == 0 && size >= OCS_PROXY_MAX) {
    abort(); /* a complete buffer must decide */
  }
  free(p);
  char *list = malloc(size + 1);
  if (!list) return 0;
  memcpy(list, data, size);
  list[size] = 0;
  ocs_proxy_addr_t a[OCS_PROXY_TRUSTED_MAX];
  int n = ocs_proxy_list_parse(list, a, why, sizeof why);
  if (n == 0 || n > OCS_PROXY_TRUSTED_MAX) abort();
  free(list);
  return 0;
}
