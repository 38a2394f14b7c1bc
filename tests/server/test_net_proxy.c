/* test_net_proxy.c — the PROXY protocol header parser and the trusted-proxy list
 * (server/net_proxy.c): v2 IPv4, IPv6 and LOCAL, v1 lines, a header arriving a byte at a time,
 * truncated, oversized and garbage input, and matching peer addresses. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <string.h>

#include "test_main.h"
#include "net_proxy.h"
#include "oc_err.h"

static const uint8_t sig[12] = {0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};

/* A v2 header: command (0 LOCAL, 1 PROXY), family byte, `len` bytes of addresses at p + 16. */
static size_t v2(uint8_t *p, int cmd, uint8_t fam, size_t len) {
  memcpy(p, sig, 12);
  p[12] = (uint8_t)(0x20 | cmd);
  p[13] = fam;
  p[14] = (uint8_t)(len >> 8);
  p[15] = (uint8_t)len;
  memset(p + 16, 0, len);
  return 16 + len;
}

static size_t v2_ipv4(uint8_t *p) {
  size_t n = v2(p, 1, 0x11, 12);
  const uint8_t a[12] = {10, 1, 2, 3, 192, 168, 0, 1, 0x1F, 0x90, 0x1D, 0x0F}; /* :8080 -> :7439 */
  memcpy(p + 16, a, sizeof a);
  return n;
}

static void test_net_proxy__v2_ipv4(void **state) {
  (void)state;
  uint8_t p[300];
  size_t n = v2_ipv4(p);
  p[n] = 'O'; /* the wire that follows is not the header's */
  ocs_proxy_hdr_t h;
  assert_int_equal(ocs_proxy_parse(p, n + 1, &h, NULL, 0), 1);
  assert_int_equal(h.version, 2);
  assert_int_equal(h.local, 0);
  assert_string_equal(h.ip, "10.1.2.3");
  assert_int_equal(h.port, 8080);
  assert_int_equal(h.bytes, 28);
}

static void test_net_proxy__v2_ipv6_with_tlvs(void **state) {
  (void)state;
  uint8_t p[128];
  size_t n = v2(p, 1, 0x21, 36 + 7); /* 7 bytes of TLVs after the addresses: skipped */
  assert_int_equal(inet_pton(AF_INET6, "2001:db8::42", p + 16), 1);
  p[16 + 32] = 0xC3;
  p[16 + 33] = 0x50; /* 50000 */
  ocs_proxy_hdr_t h;
  assert_int_equal(ocs_proxy_parse(p, n, &h, NULL, 0), 1);
  assert_string_equal(h.ip, "2001:db8::42");
  assert_int_equal(h.port, 50000);
  assert_int_equal(h.bytes, n);
}

static void test_net_proxy__v2_local_and_unspec(void **state) {
  (void)state;
  uint8_t p[300];
  ocs_proxy_hdr_t h;
  size_t n = v2(p, 0, 0x00, 0); /* LOCAL: a health check */
  assert_int_equal(ocs_proxy_parse(p, n, &h, NULL, 0), 1);
  assert_int_equal(h.local, 1);
  assert_int_equal(h.bytes, 16);
  n = v2(p, 1, 0x00, 0); /* PROXY with UNSPEC: the connection's own endpoints too */
  assert_int_equal(ocs_proxy_parse(p, n, &h, NULL, 0), 1);
  assert_int_equal(h.local, 1);
}

static void test_net_proxy__split_byte_by_byte(void **state) {
  (void)state;
  uint8_t p[300];
  size_t n = v2_ipv4(p);
  ocs_proxy_hdr_t h;
  for (size_t k = 0; k < n; k++) assert_int_equal(ocs_proxy_parse(p, k, &h, NULL, 0), 0);
  assert_int_equal(ocs_proxy_parse(p, n, &h, NULL, 0), 1);
  const char *line = "PROXY TCP4 10.9.8.7 127.0.0.1 4321 7420\r\n";
  size_t m = strlen(line);
  for (size_t k = 0; k < m; k++) assert_int_equal(ocs_proxy_parse((const uint8_t *)line, k, &h, NULL, 0), 0);
  assert_int_equal(ocs_proxy_parse((const uint8_t *)line, m, &h, NULL, 0), 1);
  assert_string_equal(h.ip, "10.9.8.7");
  assert_int_equal(h.port, 4321);
  assert_int_equal(h.bytes, m);
}

static void test_net_proxy__v1_forms(void **state) {
  (void)state;
  ocs_proxy_hdr_t h;
  const char *v6 = "PROXY TCP6 2001:db8::1 ::1 65535 7420\r\nOW";
  assert_int_equal(ocs_proxy_parse((const uint8_t *)v6, strlen(v6), &h, NULL, 0), 1);
  assert_string_equal(h.ip, "2001:db8::1");
  assert_int_equal(h.port, 65535);
  assert_int_equal(h.bytes, strlen(v6) - 2);
  const char *unknown = "PROXY UNKNOWN whatever\r\n";
  assert_int_equal(ocs_proxy_parse((const uint8_t *)unknown, strlen(unknown), &h, NULL, 0), 1);
  assert_int_equal(h.local, 1);
  const char *bad[] = {"PROXY TCP4 10.0.0.300 1.2.3.4 1 2\r\n", "PROXY TCP4 10.0.0.1 1.2.3.4 1 65536\r\n",
                       "PROXY TCP4 ::1 ::1 1 2\r\n", "PROXY TCP4 1.2.3.4 1.2.3.4 1\r\n", "PROXY UDP4 1.2.3.4 1.2.3.4 1 2\r\n",
                       "PROXY TCP4 1.2.3.4 1.2.3.4 -1 2\r\n", "PROXY TCP4 1.2.3.4 1.2.3.4 \t-2 1\r\n", "PROXY \r\n"};
  char why[160];
  for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
    assert_true(ocs_proxy_parse((const uint8_t *)bad[i], strlen(bad[i]), &h, why, sizeof why) < 0);
    assert_non_null(strstr(why, "PROXY v1"));
  }
}

static void test_net_proxy__truncated_and_oversized(void **state) {
  (void)state;
  uint8_t p[2048];
  ocs_proxy_hdr_t h;
  char why[160];
  size_t n = v2(p, 1, 0x11, 8); /* IPv4 needs 12 address bytes */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_ECORRUPT);
  n = v2(p, 1, 0x21, 12); /* IPv6 needs 36 */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_ECORRUPT);
  v2(p, 1, 0x11, OCS_PROXY_MAX - 16 + 1); /* refused from its 16 bytes, before the rest arrives */
  assert_int_equal(ocs_proxy_parse(p, 16, &h, why, sizeof why), OC_ETOOBIG);
  n = v2(p, 1, 0x11, OCS_PROXY_MAX - 16); /* the largest accepted */
  assert_int_equal(ocs_proxy_parse(p, n, &h, NULL, 0), 1);
  memset(p, 'x', 200);
  memcpy(p, "PROXY ", 6); /* no CRLF within 107 bytes */
  assert_int_equal(ocs_proxy_parse(p, 107, &h, why, sizeof why), OC_ETOOBIG);
  assert_int_equal(ocs_proxy_parse(p, 106, &h, why, sizeof why), 0);
}

static void test_net_proxy__garbage(void **state) {
  (void)state;
  uint8_t p[300];
  ocs_proxy_hdr_t h;
  char why[160];
  assert_int_equal(ocs_proxy_parse((const uint8_t *)"OW\x01\x01", 4, &h, why, sizeof why), OC_ECORRUPT);
  assert_non_null(strstr(why, "not a PROXY protocol header"));
  assert_int_equal(ocs_proxy_parse((const uint8_t *)"PROXz", 5, &h, why, sizeof why), OC_ECORRUPT);
  size_t n = v2_ipv4(p);
  p[5] ^= 1; /* bad signature */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_ECORRUPT);
  v2_ipv4(p);
  p[12] = 0x31; /* version 3 */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_EVERSION);
  p[12] = 0x22; /* command 2 */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_EVERSION);
  n = v2(p, 1, 0x31, 216); /* AF_UNIX */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_EINVAL);
  n = v2(p, 1, 0x12, 12); /* UDP over IPv4 */
  assert_int_equal(ocs_proxy_parse(p, n, &h, why, sizeof why), OC_EINVAL);
  assert_true(ocs_proxy_signature((const uint8_t *)"\r\n", 2));
  assert_true(ocs_proxy_signature((const uint8_t *)"PRO", 3));
  assert_false(ocs_proxy_signature((const uint8_t *)"OW", 2));
}

static struct sockaddr_storage sa_of(int af, const char *ip) {
  struct sockaddr_storage sa;
  memset(&sa, 0, sizeof sa);
  sa.ss_family = (sa_family_t)af;
  void *a = af == AF_INET ? (void *)&((struct sockaddr_in *)&sa)->sin_addr : (void *)&((struct sockaddr_in6 *)&sa)->sin6_addr;
  assert_int_equal(inet_pton(af, ip, a), 1);
  return sa;
}

static void test_net_proxy__trusted_list(void **state) {
  (void)state;
  ocs_proxy_addr_t l[OCS_PROXY_TRUSTED_MAX];
  char why[160];
  int n = ocs_proxy_list_parse("127.0.0.5,::1,10.0.0.1", l, why, sizeof why);
  assert_int_equal(n, 3);
  struct sockaddr_storage a = sa_of(AF_INET, "127.0.0.5"), b = sa_of(AF_INET6, "::ffff:127.0.0.5"),
                          c = sa_of(AF_INET6, "::1"), d = sa_of(AF_INET, "127.0.0.1");
  assert_true(ocs_proxy_list_has(l, n, &a));
  assert_true(ocs_proxy_list_has(l, n, &b)); /* a dual-stack listener sees IPv4 peers mapped */
  assert_true(ocs_proxy_list_has(l, n, &c));
  assert_false(ocs_proxy_list_has(l, n, &d));
  assert_int_equal(ocs_proxy_list_parse("127.0.0.1,,::1", l, why, sizeof why), OC_EINVAL);
  assert_int_equal(ocs_proxy_list_parse("haproxy.local", l, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "haproxy.local"));
  assert_int_equal(ocs_proxy_list_parse("", l, why, sizeof why), OC_EINVAL);
  assert_int_equal(ocs_proxy_list_parse("1.1.1.1,1.1.1.2,1.1.1.3,1.1.1.4,1.1.1.5,1.1.1.6,1.1.1.7,1.1.1.8,1.1.1.9,"
                                        "1.1.1.10,1.1.1.11,1.1.1.12,1.1.1.13,1.1.1.14,1.1.1.15,1.1.1.16,1.1.1.17",
                                        l, why, sizeof why),
                   OC_EINVAL);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_net_proxy__v2_ipv4),
             cmocka_unit_test(test_net_proxy__v2_ipv6_with_tlvs),
             cmocka_unit_test(test_net_proxy__v2_local_and_unspec),
             cmocka_unit_test(test_net_proxy__split_byte_by_byte),
             cmocka_unit_test(test_net_proxy__v1_forms),
             cmocka_unit_test(test_net_proxy__truncated_and_oversized),
             cmocka_unit_test(test_net_proxy__garbage),
             cmocka_unit_test(test_net_proxy__trusted_list))
