/* test_haproxy.c — docs/operations.md's HAProxy configuration over loopback: TLS terminated by
 * HAProxy (Debian's, run by this test in the foreground, never as a service) with a self-signed
 * certificate made by openssl, PROXY v2 to overcast-server --trusted-proxy, and a viewer whose
 * stream goes through a real TLS client leg (socat's OPENSSL address, its standard input and
 * output the viewer's socket). The viewer verifies every state's checksum over a few clocked
 * epochs, and the server's log names the client's address (127.0.0.1), not HAProxy's (127.0.0.5:
 * its `source`). haproxy, openssl and socat must be installed (scripts/install-deps.sh; CI has
 * them): without them the test fails saying so. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <arpa/inet.h>
#include <fcntl.h>

#include "net_fixture.h"
#include "test_main.h"

#define MIB (1ull << 20)
#define EPOCHS 3

static char dir[64];

static void need(const char *cmd, const char *what) {
  if (system(cmd) != 0) fail_msg("%s is not installed (bash scripts/install-deps.sh installs it; CI has it)", what);
}

/* A free loopback port (bound and released: HAProxy binds it right after). */
static int free_port(void) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(0x7f000001)};
  socklen_t len = sizeof a;
  assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
  assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &len), 0);
  close(fd);
  return ntohs(a.sin_port);
}

/* Replaces the one occurrence of `from` in s (cap bytes) by `to`; fails if there is none. */
static void replace(char *s, size_t cap, const char *from, const char *to) {
  char *p = strstr(s, from);
  if (!p) fail_msg("docs/operations.md's haproxy.cfg no longer has \"%s\"", from);
  size_t tail = strlen(p + strlen(from));
  assert_true(strlen(s) - strlen(from) + strlen(to) < cap);
  memmove(p + strlen(to), p + strlen(from), tail + 1);
  memcpy(p, to, strlen(to));
}

/* The block between the haproxy.cfg markers of docs/operations.md, unindented, into cfg. */
static void docs_config(char *cfg, size_t cap) {
  char path[4096], line[512];
  snprintf(path, sizeof path, "%s/docs/operations.md", getenv("OC_SOURCE_DIR"));
  FILE *f = fopen(path, "r");
  assert_non_null(f);
  int in = 0;
  size_t n = 0;
  cfg[0] = 0;
  while (fgets(line, sizeof line, f)) {
    if (strstr(line, "<!-- haproxy.cfg")) in = 1;
    else if (strstr(line, "<!-- end haproxy.cfg")) in = 0;
    else if (in) n += (size_t)snprintf(cfg + n, cap - n, "%s", strncmp(line, "    ", 4) ? line : line + 4);
    assert_true(n < cap);
  }
  fclose(f);
  if (!strstr(cfg, "send-proxy-v2")) fail_msg("no haproxy.cfg block with send-proxy-v2 in %s", path);
}

static void write_config(int tls_port, int server_port) {
  char cfg[8192], s[128], path[128];
  docs_config(cfg, sizeof cfg);
  snprintf(s, sizeof s, "127.0.0.1:%d", tls_port);
  replace(cfg, sizeof cfg, "0.0.0.0:7443", s);
  snprintf(s, sizeof s, "%s/overcast.pem", dir);
  replace(cfg, sizeof cfg, "/etc/haproxy/overcast.pem", s);
  snprintf(s, sizeof s, "127.0.0.1:%d send-proxy-v2 source 127.0.0.5", server_port);
  replace(cfg, sizeof cfg, "127.0.0.1:7420 send-proxy-v2", s);
  snprintf(path, sizeof path, "%s/haproxy.cfg", dir);
  write_file(path, cfg);
}

/* Becomes argv with stdin/stdout on fd (-1: /dev/null) and stderr into dir/log. */
static void exec_with(const char *const *argv, int fd, const char *log) {
  char path[128];
  snprintf(path, sizeof path, "%s/%s", dir, log);
  int e = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644), nul = open("/dev/null", O_RDWR);
  dup2(fd >= 0 ? fd : nul, 0);
  dup2(fd >= 0 ? fd : e, 1);
  dup2(e, 2);
  execvp(argv[0], (char *const *)argv);
  _exit(127);
}

static pid_t haproxy_pid, leg_pid; /* killed by the teardown when a test failed before stopping them */

static void stop_child(pid_t *pid) {
  if (*pid <= 0) return;
  kill(*pid, SIGTERM);
  waitpid(*pid, NULL, 0);
  *pid = 0;
}

static int teardown(void **state) {
  stop_child(&leg_pid);
  stop_child(&haproxy_pid);
  return net_teardown(state);
}

/* Waits until 127.0.0.1:port accepts a connection (HAProxy is up). */
static void wait_listening(int port, pid_t pid) {
  for (int i = 0; i < 400; i++) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port), .sin_addr.s_addr = htonl(0x7f000001)};
    int ok = connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
    close(fd);
    if (ok) return;
    if (waitpid(pid, NULL, WNOHANG) == pid) fail_msg("haproxy exited: see %s/haproxy.log", dir);
    sleep_us(50000);
  }
  fail_msg("haproxy did not listen on port %d within 20 s", port);
}

/* The TLS client leg: a local port whose one connection socat carries to tls_port over TLS (its
 * standard input and output that connection; the self-signed certificate is not verified). */
static pid_t tls_leg(int tls_port, int *port) {
  int l = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(0x7f000001)};
  socklen_t len = sizeof a;
  assert_int_equal(bind(l, (struct sockaddr *)&a, sizeof a), 0);
  assert_int_equal(listen(l, 1), 0);
  assert_int_equal(getsockname(l, (struct sockaddr *)&a, &len), 0);
  *port = ntohs(a.sin_port);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int c = accept(l, NULL, NULL);
    if (c < 0) _exit(126);
    char to[96];
    snprintf(to, sizeof to, "OPENSSL:127.0.0.1:%d,verify=0", tls_port);
    const char *argv[] = {"socat", "-", to, NULL};
    close(l);
    exec_with(argv, c, "socat.log");
  }
  close(l);
  return pid;
}

static void make_cert(void) {
  char cmd[1024];
  snprintf(cmd, sizeof cmd,
           "cd %s && openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 1 "
           "-subj /CN=localhost -keyout key.pem -out cert.pem 2>openssl.log && cat cert.pem key.pem > overcast.pem",
           dir);
  if (system(cmd) != 0) fail_msg("openssl req failed: see %s/openssl.log", dir);
}

static void test_haproxy__tls_and_proxy_v2(void **state) {
  (void)state;
  need("haproxy -v >/dev/null 2>&1", "haproxy");
  need("openssl version >/dev/null 2>&1", "openssl");
  need("socat -V >/dev/null 2>&1", "socat");
  snprintf(dir, sizeof dir, "/tmp/oc_haproxy_XXXXXX");
  assert_non_null(mkdtemp(dir));
  make_cert();
  char log[128];
  snprintf(log, sizeof log, "%s/server.log", dir);
  /* clocked (the fixture's --epoch-period 0 overridden): a stepped server would skip the state of a
   * step that runs before the ACK of the previous one has come through the proxy, since the step
   * requests come straight from here and may overtake it */
  const char *extra[] = {"--scene", scene_sphere, "--trusted-proxy", "127.0.0.5", "--epoch-period", "0.5", NULL};
  server_t s;
  start_server_log(&s, extra, log);
  int tls_port = free_port(), leg_port;
  write_config(tls_port, s.port);
  char cfg[128];
  snprintf(cfg, sizeof cfg, "%s/haproxy.cfg", dir);
  const char *hargv[] = {"haproxy", "-f", cfg, "-db", NULL};
  assert_true((haproxy_pid = fork()) >= 0);
  if (!haproxy_pid) exec_with(hargv, -1, "haproxy.log");
  wait_listening(tls_port, haproxy_pid);
  leg_pid = tls_leg(tls_port, &leg_port);
  viewer_t v;
  viewer_open(&v, leg_port, 4 * MIB, NULL);
  int r = viewer_wait(&v, EPOCHS, 120.0); /* each state's checksum verified before it counts */
  if (r != 0) fail_msg("viewer through TLS: %d states: %s (closed: %u %s)", v.states, oc_strerror(r), v.closed_code, v.closed_text);
  ocv_conn_close(v.c);
  stop_child(&leg_pid);
  stop_child(&haproxy_pid);
  assert_int_equal(stop_server(&s), 0);
  FILE *f = fopen(log, "r");
  assert_non_null(f);
  char line[1024];
  int client = 0, proxied = 0, as_proxy = 0;
  while (fgets(line, sizeof line, f)) {
    client += strstr(line, "(viewer 127.0.0.1:") && strstr(line, "welcomed") != NULL;
    proxied += strstr(line, "PROXY v2 header from 127.0.0.5:") != NULL;
    as_proxy += strstr(line, "(viewer 127.0.0.5:") && strstr(line, "welcomed"); /* not LOCAL health checks */
  }
  fclose(f);
  if (client != 1 || !proxied || as_proxy) fail_msg("the server log (%s) does not name the client through the proxy", log);
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
  assert_int_equal(system(cmd), 0);
}

OC_TEST_MAIN(net_setup, NULL,
             cmocka_unit_test_teardown(test_haproxy__tls_and_proxy_v2, teardown))
