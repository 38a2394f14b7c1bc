/* test_proxy.c — overcast-server --trusted-proxy end to end (server/net_proxy.c, net_input.c):
 * a PROXY header from a peer that is not trusted is refused with its reason; from a trusted one
 * (127.0.0.5 here) the address it carries is the one the per-address limit, the sessions reply,
 * the log and the audit log see (v2 IPv4 and IPv6, v1, LOCAL); a trusted peer without a header, or with one that
 * never completes, is refused. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <arpa/inet.h>

#include "net_fixture.h"
#include "test_main.h"

#define MIB (1ull << 20)
#define PROXY_HOST 5 /* the trusted proxy connects from 127.0.0.5 */

/* A PROXY v2 header for a TCP client ip:port (IPv4 or IPv6) to the server; LOCAL when ip is NULL. */
static size_t v2_header(uint8_t *p, const char *ip, int port) {
  static const uint8_t sig[12] = {0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};
  memcpy(p, sig, sizeof sig);
  int v6 = ip && strchr(ip, ':');
  size_t alen = v6 ? 16 : 4, len = ip ? 2 * alen + 4 : 0;
  p[12] = ip ? 0x21 : 0x20;
  p[13] = !ip ? 0x00 : v6 ? 0x21 : 0x11;
  p[14] = 0;
  p[15] = (uint8_t)len;
  if (!ip) return 16;
  memset(p + 16, 0, len);
  assert_int_equal(inet_pton(v6 ? AF_INET6 : AF_INET, ip, p + 16), 1);
  assert_int_equal(inet_pton(v6 ? AF_INET6 : AF_INET, v6 ? "::1" : "127.0.0.1", p + 16 + alen), 1);
  p[16 + 2 * alen] = (uint8_t)(port >> 8);
  p[16 + 2 * alen + 1] = (uint8_t)port;
  p[16 + 2 * alen + 3] = 1;
  return 16 + len;
}

/* A connection from the trusted proxy carrying client ip:port, its header in two writes. */
static int via_proxy(int port, const char *ip, int client_port) {
  uint8_t h[64];
  size_t n = v2_header(h, ip, client_port);
  int fd = raw_connect_from(PROXY_HOST, port);
  raw_send(fd, h, 7);
  sleep_us(20000); /* usually a read of its own: the split must not matter either way */
  raw_send(fd, h + 7, n - 7);
  return fd;
}

/* A control client behind the proxy: HELLO and one CONTROL request; waits for the connection to
 * end after the reply (ERROR/GOODBYE code, or -1 at EOF). */
static void control_via_proxy(int port, const char *ip, int client_port, const char *json) {
  int fd = via_proxy(port, ip, client_port);
  oc_buf_t b = {0};
  ocp_hello_t hello = {.min_version = 1, .max_version = 1, .role = OCP_ROLE_CONTROL};
  ocp_put_hello(&b, &hello);
  ocp_control_t req = {.request = 1, .json = json, .json_len = (uint32_t)strlen(json)};
  ocp_put_control(&b, 1, OCP_MSG_CONTROL, &req);
  raw_send(fd, b.data, b.len);
  oc_buf_free(&b);
  shutdown(fd, SHUT_WR); /* the server answers, then sees the end and closes */
  raw_read_close_code(fd, 10.0, NULL, 0);
}

static char *slurp(const char *path) {
  FILE *f = fopen(path, "r");
  assert_non_null(f);
  static char buf[1 << 16];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  buf[n] = 0;
  fclose(f);
  return buf;
}

static void log_path(char *path, size_t cap, const char *what) {
  snprintf(path, cap, "/tmp/oc_proxy_%s_%d.log", what, (int)getpid());
}

static void test_proxy__untrusted_header_refused(void **state) {
  (void)state;
  char log[256], text[OCP_TEXT_MAX + 1] = "";
  log_path(log, sizeof log, "untrusted");
  const char *extra[] = {"--scene", scene_sphere, "--trusted-proxy", "127.0.0.5", NULL};
  server_t s;
  start_server_log(&s, extra, log);
  uint8_t h[64];
  size_t n = v2_header(h, "10.0.0.1", 1111);
  int fd = raw_connect(s.port); /* from 127.0.0.1: not trusted */
  raw_send(fd, h, n);
  assert_int_equal(raw_read_close_code(fd, 10.0, text, sizeof text), OCP_CODE_MALFORMED);
  assert_non_null(strstr(text, "a PROXY header from 127.0.0.1:"));
  assert_non_null(strstr(text, "which is not a --trusted-proxy"));
  int32_t st;
  char *r = control_from("127.0.0.9", s.port, NULL, "{\"op\":\"stats\"}", &st);
  assert_int_equal(st, 0);
  assert_int_equal((int)json_num(r, "\"refusals\"", "proxy"), 1);
  free(r);
  assert_int_equal(stop_server(&s), 0);
  assert_non_null(strstr(slurp(log), "which is not a --trusted-proxy"));
  remove(log);
}

/* The per-address limit of 1 counts the PROXY addresses: every client of the one proxy gets in
 * once, and a second connection of one client is refused naming that client's address. */
static void test_proxy__trusted_address_meets_limits(void **state) {
  (void)state;
  char log[256], text[OCP_TEXT_MAX + 1] = "";
  log_path(log, sizeof log, "trusted");
  char audit[256];
  log_path(audit, sizeof audit, "audit");
  const char *extra[] = {"--scene", scene_sphere, "--trusted-proxy", "::1,127.0.0.5", "--max-per-address", "1",
                         "--audit-log", audit, NULL};
  server_t s;
  start_server_log(&s, extra, log);
  int code;
  int a = via_proxy(s.port, "10.0.0.1", 1111), b = via_proxy(s.port, "10.0.0.2", 2222);
  int c = via_proxy(s.port, "2001:db8::7", 3333);
  assert_true(raw_hello(a, 4 * MIB, &code) > 0);
  assert_true(raw_hello(b, 4 * MIB, &code) > 0);
  assert_true(raw_hello(c, 4 * MIB, &code) > 0);
  int v1 = raw_connect_from(PROXY_HOST, s.port);
  const char *line = "PROXY TCP4 10.0.0.3 127.0.0.1 4444 7420\r\n";
  raw_send(v1, line, strlen(line));
  assert_true(raw_hello(v1, 4 * MIB, &code) > 0);
  int again = via_proxy(s.port, "10.0.0.1", 5555);
  assert_int_equal(raw_read_close_code(again, 10.0, text, sizeof text), OCP_CODE_FULL);
  assert_non_null(strstr(text, "too many connections from 10.0.0.1 (limit 1 per address)"));
  int32_t st;
  char *r = control_from("127.0.0.9", s.port, NULL, "{\"op\":\"sessions\"}", &st);
  assert_int_equal(st, 0);
  assert_non_null(strstr(r, "\"10.0.0.1:1111\""));
  assert_non_null(strstr(r, "\"[2001:db8::7]:3333\""));
  assert_null(strstr(r, "127.0.0.5"));
  free(r);
  close(a);
  close(b);
  close(c);
  close(v1);
  control_via_proxy(s.port, "10.0.0.9", 9999, "{\"op\":\"pause\"}");
  assert_int_equal(stop_server(&s), 0);
  assert_non_null(strstr(slurp(audit), "\"peer\":\"10.0.0.9:9999\""));
  remove(audit);
  const char *l = slurp(log);
  assert_non_null(strstr(l, "(viewer 10.0.0.1:1111): welcomed"));
  assert_non_null(strstr(l, "(viewer 10.0.0.3:4444): welcomed"));
  assert_non_null(strstr(l, "PROXY v2 header from 127.0.0.5:"));
  assert_null(strstr(l, "(viewer 127.0.0.5"));
  remove(log);
}

/* A trusted peer must begin with the header: a HELLO first is refused; a LOCAL header (a health
 * check) is the proxy's own connection; a header that never completes times out. */
static void test_proxy__trusted_without_header(void **state) {
  (void)state;
  char text[OCP_TEXT_MAX + 1] = "";
  const char *extra[] = {"--scene", scene_sphere, "--trusted-proxy", "127.0.0.5", "--idle-timeout", "1", NULL};
  server_t s;
  start_server(&s, extra);
  int code;
  int fd = raw_connect_from(PROXY_HOST, s.port);
  oc_buf_t b = {0};
  ocp_hello_t hello = {.min_version = 1, .max_version = 1, .role = OCP_ROLE_VIEWER};
  ocp_put_hello(&b, &hello);
  raw_send(fd, b.data, b.len);
  oc_buf_free(&b);
  assert_int_equal(raw_read_close_code(fd, 10.0, text, sizeof text), OCP_CODE_MALFORMED);
  assert_non_null(strstr(text, "is a trusted proxy and must begin with a PROXY header"));
  uint8_t h[64];
  fd = raw_connect_from(PROXY_HOST, s.port);
  raw_send(fd, h, v2_header(h, NULL, 0)); /* LOCAL */
  assert_true(raw_hello(fd, 4 * MIB, &code) > 0);
  close(fd);
  fd = raw_connect_from(PROXY_HOST, s.port);
  raw_send(fd, h, 10); /* never completes: the handshake deadline (1 s here) */
  assert_int_equal(raw_read_close_code(fd, 30.0, text, sizeof text), OCP_CODE_TIMEOUT);
  assert_non_null(strstr(text, "no PROXY header within"));
  assert_int_equal(stop_server(&s), 0);
}

OC_TEST_MAIN(net_setup, NULL,
             cmocka_unit_test_teardown(test_proxy__untrusted_header_refused, net_teardown),
             cmocka_unit_test_teardown(test_proxy__trusted_address_meets_limits, net_teardown),
             cmocka_unit_test_teardown(test_proxy__trusted_without_header, net_teardown))
