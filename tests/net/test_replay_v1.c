/* test_replay_v1.c — a recorded protocol-version-1 session replayed against overcast-server.
 *
 * tests/data/replay_v1/session.txt holds what a version-1 viewer (ocp_viewer pinned with
 * desc.max_version = 1) exchanged with the server on scenes/analytic_sphere.json: budget 4 MiB,
 * viewport 160x90, 3 epochs stepped by control requests, the camera moved after the first; one
 * section for a full viewer (OCP_CAP_ALL) and one for a lean one (DIGEST). Its lines:
 *
 *   section NAME ...            a new server and connection
 *   C NAME HEX                  a client frame, sent verbatim
 *   S NAME LENGTH [KEY=VALUE]   a server frame: its type, payload length, and for EPOCH_BEGIN,
 *                               EPOCH_END and STATS the fields compared (epoch, checksum, ...)
 *   step N                      a control request steps N epochs
 *   S eof                       the server closes the connection
 *
 * Replay (the default): the client frames go out verbatim on a raw socket (no ocp_viewer in the
 * sending path); each recorded server frame must come with the recorded type, header version 1
 * and its v1 layout (WELCOME 178 + n bytes choosing version 1, EPOCH_BEGIN 64, EPOCH_END 16,
 * STATS 88, fields read at their v1 offsets); every epoch is rebuilt with proto's decoder
 * (ocp_epoch_dec_*), its checksum recomputed from the rebuilt state, and compared with the
 * recording (the recorded ACK that follows carries it). WELCOME is compared by layout and
 * version only (its session id and secret are random). RECORDS and BRICKS lengths depend on
 * zstd and are not compared. So it fails when the server stops speaking version 1, changes a
 * v1 layout, or serves other content; the last failure says so and gives the command that
 * re-records.
 *
 * Record: OC_REPLAY_RECORD=FILE (absolute) writes FILE from live v1 viewers, then replays it.
 * Also: version negotiation over a raw socket ([2, 5] is ERROR VERSION while this server's
 * highest is 1; [1, 255] is WELCOME with OCP_VERSION_MAX) and the pinned session itself. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <errno.h>
#include <inttypes.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "net.h" /* client/net.h: the control requests that step epochs */
#include "oc_bytes.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_state.h"
#include "ocp_epoch.h"
#include "ocp_viewer.h"
#include "ocp_wire.h"

#include "net_fixture.h"

#define RP_TIMEOUT_S 60.0
#define RP_EPOCHS 3
#define RP_BUDGET (4u << 20)
#define RP_W 160
#define RP_H 90
#define RP_LINE_MAX 8192

/* The v1 layouts (docs/protocol.md, "Wire"), written out here rather than taken from proto. */
#define V1_WELCOME_FIXED 178
#define V1_EPOCH_BEGIN 64
#define V1_EPOCH_END 16
#define V1_STATS 88

static char g_file[4096], g_build[4096];
static int g_recording;

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/*-*** The server ***/

static void start_rp_server(server_t *s) {
  const char *extra[] = {"--scene", scene_sphere, NULL};
  start_server(s, extra);
}

/*-*** A raw connection ***/

typedef struct {
  int fd;
  ocp_reader_t rd;
  uint8_t buf[65536];
} raw_t;

static void rp_open(raw_t *x, int port) {
  x->fd = socket(AF_INET, SOCK_STREAM, 0);
  assert_true(x->fd >= 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port), .sin_addr.s_addr = htonl(0x7f000001)};
  assert_int_equal(connect(x->fd, (struct sockaddr *)&a, sizeof a), 0);
  ocp_reader_init(&x->rd, OCP_MAX_PAYLOAD);
}

static void rp_close(raw_t *x) {
  if (x->fd >= 0) close(x->fd);
  x->fd = -1;
  ocp_reader_free(&x->rd);
}

static void rp_send(raw_t *x, const void *p, size_t n) {
  const uint8_t *q = p;
  while (n) {
    ssize_t k = send(x->fd, q, n, MSG_NOSIGNAL);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) fail_msg("send: %s", strerror(errno));
    q += k;
    n -= (size_t)k;
  }
}

/* The next whole frame (KEEPALIVE skipped unless keep_alives). @return 1 (the payload is valid
 * until the next call), 0 at EOF, -1 after timeout_s. */
static int raw_next(raw_t *x, double timeout_s, int keep_alives, ocp_header_t *h, const uint8_t **p) {
  double deadline = now_s() + timeout_s;
  for (;;) {
    int r = ocp_reader_next(&x->rd, h, p);
    if (r < 0) fail_msg("the server sent a bad frame header: %s", oc_strerror(r));
    if (r == 1 && (h->type != OCP_MSG_KEEPALIVE || keep_alives)) return 1;
    if (r == 1) continue;
    double left = deadline - now_s();
    if (left <= 0) return -1;
    struct pollfd pf = {x->fd, POLLIN, 0};
    if (poll(&pf, 1, (int)(left * 1000) + 1) <= 0) continue;
    ssize_t n = recv(x->fd, x->buf, sizeof x->buf, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return 0; /* EOF or reset */
    assert_int_equal(ocp_reader_feed(&x->rd, x->buf, (size_t)n), 0);
  }
}

/* A valid HELLO offering [lo, hi]. */
static void hello_bytes(oc_buf_t *b, uint16_t lo, uint16_t hi) {
  ocp_hello_t h = {.min_version = lo, .max_version = hi, .role = OCP_ROLE_VIEWER, .max_depth = 21, .budget = RP_BUDGET,
                   .slot_bytes = 2048, .record_bytes = 32, .width = RP_W, .height = RP_H, .caps = OCP_CAP_ALL};
  ocp_put_hello(b, &h);
}

/*-*** Recording: live version-1 viewers ***/

static ocp_camera_t camera_at(double lon) {
  oc_camera_pose_t p = {{0.0, lon, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cam = oc_camera_from_pose(p);
  return (ocp_camera_t){cam.pos, cam.forward, cam.up, 40.0, RP_W, RP_H};
}
#define RP_LON_FIRST (-0.09) /* the scene's own camera */
#define RP_LON_MOVED (-0.06) /* after the first epoch: 3.3 km closer */

static const char *msg_name(int type) {
  const char *n = ocp_msg_name(type);
  return n ? n : "unknown";
}

/* Writes every frame in b as a C line (checking that it carries version 1) and sends it. */
static void rec_client(FILE *f, raw_t *x, oc_buf_t *b) {
  assert_int_equal(b->err, 0);
  size_t at = 0;
  while (at < b->len) {
    ocp_header_t h;
    assert_true(b->len - at >= OCP_HEADER_BYTES);
    assert_int_equal(ocp_header_parse(b->data + at, OCP_MAX_PAYLOAD, &h), 0);
    size_t n = OCP_HEADER_BYTES + h.length;
    if (h.version != 1) fail_msg("the viewer pinned to version 1 wrote a %s frame of version %u", msg_name(h.type), h.version);
    fprintf(f, "C %s ", msg_name(h.type));
    for (size_t i = 0; i < n; i++) fprintf(f, "%02x", b->data[at + i]);
    fputc('\n', f);
    at += n;
  }
  rp_send(x, b->data, b->len);
  b->len = 0;
}

/* One server frame: fed to the session (its answers written and sent), then its S line. */
static int rec_server(FILE *f, raw_t *x, ocp_viewer_t *v, oc_buf_t *out, const ocp_header_t *h, const uint8_t *p) {
  if (h->version != 1) fail_msg("the server wrote a %s frame of version %u to a version-1 viewer", msg_name(h->type), h->version);
  uint8_t hdr[OCP_HEADER_BYTES] = {OCP_MAGIC0, OCP_MAGIC1, h->version, h->type};
  oc_put_u32(hdr + 4, h->length);
  char why[OCP_TEXT_MAX + 64];
  int e = ocp_viewer_feed(v, hdr, sizeof hdr, out, why, sizeof why);
  if (!e) e = ocp_viewer_feed(v, p, h->length, out, why, sizeof why);
  if (e) fail_msg("the v1 viewer refused the server's %s: %s", msg_name(h->type), why);
  fprintf(f, "S %s %" PRIu32, msg_name(h->type), h->length);
  if (h->type == OCP_MSG_WELCOME) fprintf(f, " version=%u", (unsigned)oc_get_u16(p));
  if (h->type == OCP_MSG_EPOCH_BEGIN) {
    uint64_t base = oc_get_u64(p + 40);
    fprintf(f, " epoch=%" PRIu64 " base=%" PRId64 " nodes=%" PRIu32 " bricks=%" PRIu32 " sent=%" PRIu32, oc_get_u64(p),
            base == OCP_NO_BASE ? (int64_t)-1 : (int64_t)base, oc_get_u32(p + 48), oc_get_u32(p + 52), oc_get_u32(p + 56));
  }
  if (h->type == OCP_MSG_EPOCH_END) {
    fprintf(f, " epoch=%" PRIu64 " checksum=%016" PRIx64, oc_get_u64(p), oc_get_u64(p + 8));
    const oc_state_t *s = ocp_viewer_state(v, 0);
    const oc_brick_digests_t *d = ocp_viewer_digests(v, 0);
    assert_non_null(s);
    fprintf(f, " digest=%016" PRIx64, d ? oc_state_digest_checksum(s, d) : oc_state_digest(s)); /* the lean form, both */
  }
  if (h->type == OCP_MSG_STATS) fprintf(f, " epoch=%" PRIu64, oc_get_u64(p));
  fputc('\n', f);
  if (out->len) rec_client(f, x, out);
  return h->type;
}

/* Frames until one of type `until` (included). */
static void rec_until(FILE *f, raw_t *x, ocp_viewer_t *v, oc_buf_t *out, int until) {
  for (;;) {
    ocp_header_t h;
    const uint8_t *p;
    int r = raw_next(x, RP_TIMEOUT_S, 0, &h, &p);
    if (r <= 0) fail_msg("recording: no %s from the server (%s)", msg_name(until), r ? "timed out" : "connection closed");
    if (h.type == OCP_MSG_ERROR || h.type == OCP_MSG_GOODBYE) {
      ocp_text_msg_t t;
      fail_msg("recording: the server closed: %s",
               ocp_get_text(p, h.length, &t, NULL, 0) == 0 ? t.text : "(undecodable ERROR/GOODBYE)");
    }
    if (rec_server(f, x, v, out, &h, p) == until) return;
  }
}

/* One section: a fresh server and a version-1 viewer through its whole session. */
static void record_section(FILE *f, const char *name, int lean) {
  server_t s;
  start_rp_server(&s);
  raw_t x;
  rp_open(&x, s.port);
  ocp_viewer_desc_t d = {.role = OCP_ROLE_VIEWER, .budget = RP_BUDGET, .max_depth = 21, .width = RP_W, .height = RP_H,
                         .caps = lean ? OCP_CAP_DICT : OCP_CAP_ALL, .lean = lean, .max_version = 1};
  ocp_viewer_t *v = NULL;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), 0);
  fprintf(f, "section %s caps=0x%x budget=%u viewport=%dx%d depth=21 max_version=1\n", name, (unsigned)d.caps | (lean ? OCP_CAP_DIGEST : 0),
          RP_BUDGET, RP_W, RP_H);
  oc_buf_t out = {0};
  ocp_camera_t cam = camera_at(RP_LON_FIRST);
  assert_int_equal(ocp_viewer_camera(v, &cam, &out), 0); /* kept: sent after WELCOME */
  ocp_viewer_connected(v, &out);
  rec_client(f, &x, &out); /* HELLO */
  rec_until(f, &x, v, &out, OCP_MSG_WELCOME); /* and the CAMERA after it */
  assert_int_equal(ocp_viewer_welcome(v)->version, 1);
  for (int e = 1; e <= RP_EPOCHS; e++) {
    sleep_us(100000); /* the camera and the ACK reach the server before the step */
    fprintf(f, "step 1\n");
    step(s.port, 1);
    rec_until(f, &x, v, &out, OCP_MSG_STATS); /* EPOCH_BEGIN .. EPOCH_END, our ACK, STATS */
    if (e == 1) {
      cam = camera_at(RP_LON_MOVED);
      assert_int_equal(ocp_viewer_camera(v, &cam, &out), 0);
      rec_client(f, &x, &out);
    }
  }
  ocp_viewer_stats_t st;
  ocp_viewer_stats(v, &st);
  assert_int_equal(st.states, RP_EPOCHS);
  assert_int_equal(st.over_budget, 0);
  ocp_viewer_goodbye(v, &out);
  rec_client(f, &x, &out);
  for (;;) { /* whatever the server says before it closes */
    ocp_header_t h;
    const uint8_t *p;
    int r = raw_next(&x, RP_TIMEOUT_S, 0, &h, &p);
    if (r < 0) fail_msg("recording: the server did not close the connection after GOODBYE");
    if (r == 0) break;
    fprintf(f, "S %s %" PRIu32 "\n", msg_name(h.type), h.length);
  }
  fprintf(f, "S eof\n");
  rp_close(&x);
  ocp_viewer_free(v);
  oc_buf_free(&out);
  assert_int_equal(stop_server(&s), 0);
}

static void test_replay_v1__record(void **state) {
  (void)state;
  char tmp[4200];
  snprintf(tmp, sizeof tmp, "%s.tmp", g_file);
  FILE *f = fopen(tmp, "w");
  if (!f) fail_msg("OC_REPLAY_RECORD: cannot write %s: %s", tmp, strerror(errno));
  fprintf(f,
          "# Overcast wire protocol version 1: a recorded session, replayed by tests/net/test_replay_v1.c.\n"
          "# Made by a viewer pinned to version 1 (ocp_viewer desc.max_version = 1) against overcast-server\n"
          "# on scenes/analytic_sphere.json (--epoch-period 0): budget 4 MiB, viewport 160x90, depth 21,\n"
          "# %d epochs stepped by control requests, the camera moved after the first. Sections: full\n"
          "# (OCP_CAP_ALL) and lean (OCP_CAP_DICT | OCP_CAP_DIGEST), each with its own server.\n"
          "# Lines: \"C NAME HEX\" a client frame (sent verbatim); \"S NAME LENGTH KEY=VALUE...\" a server\n"
          "# frame (RECORDS and BRICKS lengths depend on zstd and are not compared; digest= is the\n"
          "# recorder's digest checksum of the state, which the lean section's EPOCH_END must carry);\n"
          "# \"step N\" a control request stepping N epochs; \"S eof\" the server closes.\n"
          "# Re-record (after an intended change of the server's content):\n"
          "#   OC_REPLAY_RECORD=$PWD/tests/data/replay_v1/session.txt ctest --test-dir build -R net_test_replay_v1\n",
          RP_EPOCHS);
  record_section(f, "full", 0);
  record_section(f, "lean", 1);
  assert_int_equal(fclose(f), 0);
  if (rename(tmp, g_file) != 0) fail_msg("cannot rename %s to %s: %s", tmp, g_file, strerror(errno));
  print_message("recorded %s\n", g_file);
}

/*-*** Replay ***/

typedef struct {
  char **line;
  int *lineno;
  int n;
} lines_t;

/* The recording's lines of section `name` (comments and blanks dropped). */
static void load_section(const char *name, lines_t *L) {
  memset(L, 0, sizeof *L);
  FILE *f = fopen(g_file, "r");
  if (!f) fail_msg("%s: %s (record it: OC_REPLAY_RECORD=FILE)", g_file, strerror(errno));
  static char buf[RP_LINE_MAX];
  int in = 0, no = 0;
  while (fgets(buf, sizeof buf, f)) {
    no++;
    size_t k = strlen(buf);
    if (k && buf[k - 1] != '\n' && !feof(f)) fail_msg("%s:%d: line too long", g_file, no);
    while (k && (buf[k - 1] == '\n' || buf[k - 1] == '\r')) buf[--k] = '\0';
    if (!k || buf[0] == '#') continue;
    if (!strncmp(buf, "section ", 8)) {
      size_t nl = strcspn(buf + 8, " ");
      in = nl == strlen(name) && !strncmp(buf + 8, name, nl);
      continue;
    }
    if (!in) continue;
    L->line = realloc(L->line, (size_t)(L->n + 1) * sizeof *L->line);
    L->lineno = realloc(L->lineno, (size_t)(L->n + 1) * sizeof *L->lineno);
    assert_non_null(L->line);
    assert_non_null(L->lineno);
    L->line[L->n] = strdup(buf);
    L->lineno[L->n++] = no;
  }
  fclose(f);
  if (!L->n) fail_msg("%s: no section \"%s\"", g_file, name);
}

static void free_lines(lines_t *L) {
  for (int i = 0; i < L->n; i++) free(L->line[i]);
  free(L->line);
  free(L->lineno);
}

/* KEY=VALUE from a line as an unsigned number (hex when `hex`); fails when missing. */
static uint64_t field(const char *line, int no, const char *key, int hex) {
  char pat[64];
  snprintf(pat, sizeof pat, " %s=", key);
  const char *p = strstr(line, pat);
  if (!p) fail_msg("%s:%d: no %s= in \"%s\"", g_file, no, key, line);
  return strtoull(p + strlen(pat), NULL, hex ? 16 : 10);
}

/* The state being replayed. */
typedef struct {
  const char *section;
  int no;       /* file line of the current recorded line */
  int lean;     /* from the recorded HELLO's caps */
  int kept;     /* K from WELCOME */
  ocp_epoch_dec_t *dec;
  oc_state_t held[2];              /* newest first: the K − 1 the server assumes we hold */
  oc_brick_digests_t hdig[2];
  int nheld;
  uint64_t end_epoch, end_checksum; /* the last EPOCH_END, verified */
  int have_end;
  const lines_t *full;             /* lean replay: the full section, for its digests */
} replay_t;

/* Fails the test at r's line: the server's content changed (changed = 1: re-record if meant) or
 * it broke protocol version 1 (changed = 0). */
static void rp_fail(const replay_t *r, int changed, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void rp_fail(const replay_t *r, int changed, const char *fmt, ...) {
  char what[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(what, sizeof what, fmt, ap);
  va_end(ap);
  if (changed)
    fail_msg("%s:%d (section %s): the server's content changed: %s.\n"
             "It still speaks version 1, but serves other states than the recording. If that change is intended,\n"
             "re-record, check the diff and commit the file:\n"
             "  OC_REPLAY_RECORD=%s ctest --test-dir %s -R net_test_replay_v1 --output-on-failure",
             g_file, r->no, r->section, what, g_file, g_build);
  else
    fail_msg("%s:%d (section %s): the server broke protocol version 1: %s (a version-1 viewer must still be served "
             "exactly as recorded; docs/protocol.md, \"Wire\")",
             g_file, r->no, r->section, what);
}
#define content_changed(r, ...) rp_fail(r, 1, __VA_ARGS__)
#define protocol_broken(r, ...) rp_fail(r, 0, __VA_ARGS__)

static const oc_brick_codes_t *rp_lookup(void *ctx, uint32_t id) {
  const replay_t *r = ctx;
  return oc_states_find_codes(r->held, r->nheld, id);
}

static int rp_dlookup(void *ctx, uint32_t id, uint64_t *digest) {
  const replay_t *r = ctx;
  return oc_brick_digests_lookup(r->hdig, r->nheld, id, digest);
}

static int is_content_frame(int type) { return type == OCP_MSG_RECORDS || type == OCP_MSG_BRICKS; }

/* The recorded digest= of epoch `epoch` in the full section (0: none). */
static uint64_t full_digest(const lines_t *full, uint64_t epoch) {
  for (int i = 0; full && i < full->n; i++)
    if (!strncmp(full->line[i], "S epoch-end ", 12) && field(full->line[i], full->lineno[i], "epoch", 0) == epoch)
      return field(full->line[i], full->lineno[i], "digest", 1);
  return 0;
}

/* One recorded server frame against the one that came. */
static void check_server_frame(replay_t *r, const char *line, const ocp_header_t *h, const uint8_t *p) {
  char name[64];
  if (sscanf(line, "S %63s", name) != 1) fail_msg("%s:%d: bad line \"%s\"", g_file, r->no, line);
  if ((h->type == OCP_MSG_ERROR || h->type == OCP_MSG_GOODBYE) && strcmp(name, msg_name(h->type)) != 0) {
    ocp_text_msg_t t;
    int ok = ocp_get_text(p, h->length, &t, NULL, 0) == 0;
    protocol_broken(r, "expected %s, the server sent %s %s: %s", name, msg_name(h->type),
                    ok ? ocp_code_text(t.code) : "(undecodable)", ok ? t.text : "");
  }
  if (h->version != 1) protocol_broken(r, "a %s frame of version %u, not 1", msg_name(h->type), (unsigned)h->version);
  if (strcmp(name, msg_name(h->type)) != 0) {
    int want = -1;
    for (int t = 0; t < 256 && want < 0; t++)
      if (ocp_msg_name(t) && !strcmp(ocp_msg_name(t), name)) want = t;
    if (is_content_frame(h->type) || is_content_frame(want))
      content_changed(r, "expected a %s frame, got %s (the epoch's records or bricks take other frames)", name, msg_name(h->type));
    protocol_broken(r, "expected a %s frame, got %s", name, msg_name(h->type));
  }
  char why[OCP_TEXT_MAX + 1] = "";
  switch (h->type) {
    case OCP_MSG_WELCOME: {
      if (h->length < V1_WELCOME_FIXED || h->length != V1_WELCOME_FIXED + (uint32_t)oc_get_u16(p + 176))
        protocol_broken(r, "WELCOME of %" PRIu32 " bytes, not %d + the name's length", h->length, V1_WELCOME_FIXED);
      if (oc_get_u16(p) != 1) protocol_broken(r, "WELCOME chooses version %u, not 1", (unsigned)oc_get_u16(p));
      ocp_welcome_t w;
      if (ocp_get_welcome(p, h->length, &w, why, sizeof why) < 0) protocol_broken(r, "WELCOME: %s", why);
      if (w.version != 1 || w.kept_states < 2 || w.kept_states > 3) protocol_broken(r, "WELCOME: version %u, K = %u", w.version, w.kept_states);
      r->kept = w.kept_states;
      return;
    }
    case OCP_MSG_EPOCH_BEGIN: {
      if (h->length != V1_EPOCH_BEGIN) protocol_broken(r, "EPOCH_BEGIN of %" PRIu32 " bytes, not %d", h->length, V1_EPOCH_BEGIN);
      ocp_epoch_begin_t m;
      if (ocp_get_epoch_begin(p, h->length, &m, why, sizeof why) < 0) protocol_broken(r, "EPOCH_BEGIN: %s", why);
      if (m.epoch != oc_get_u64(p) || m.base_epoch != oc_get_u64(p + 40) || m.node_count != oc_get_u32(p + 48) ||
          m.brick_count != oc_get_u32(p + 52) || m.bricks_sent != oc_get_u32(p + 56) || oc_get_u32(p + 60) != 0)
        protocol_broken(r, "EPOCH_BEGIN: fields not at their v1 offsets");
      int64_t base = m.base_epoch == OCP_NO_BASE ? -1 : (int64_t)m.base_epoch;
      uint64_t re = field(line, r->no, "epoch", 0), rn = field(line, r->no, "nodes", 0), rb = field(line, r->no, "bricks", 0),
               rs = field(line, r->no, "sent", 0);
      int64_t rbase = strtoll(strstr(line, " base=") ? strstr(line, " base=") + 6 : "x", NULL, 10);
      if (m.epoch != re || base != rbase)
        content_changed(r, "epoch %" PRIu64 " on base %" PRId64 ", recorded epoch %" PRIu64 " on base %" PRId64, m.epoch, base, re,
                        rbase);
      if (m.node_count != rn || m.brick_count != rb || m.bricks_sent != rs)
        content_changed(r, "epoch %" PRIu64 ": %" PRIu32 " records, %" PRIu32 " bricks, %" PRIu32 " sent; recorded %" PRIu64
                           ", %" PRIu64 ", %" PRIu64, m.epoch, m.node_count, m.brick_count, m.bricks_sent, rn, rb, rs);
      const oc_state_t *bs = NULL;
      for (int i = 0; i < r->nheld && !bs; i++)
        if (r->held[i].epoch == m.base_epoch) bs = &r->held[i];
      if (m.base_epoch != OCP_NO_BASE && !bs) protocol_broken(r, "EPOCH_BEGIN: base epoch %" PRIu64 " is not one we hold", m.base_epoch);
      int e = r->lean ? ocp_epoch_dec_begin_lean(r->dec, &m, bs, rp_dlookup, r, why, sizeof why)
                      : ocp_epoch_dec_begin(r->dec, &m, bs, rp_lookup, r, why, sizeof why);
      if (e) protocol_broken(r, "EPOCH_BEGIN does not decode: %s", why);
      return;
    }
    case OCP_MSG_RECORDS:
      if (ocp_epoch_dec_records(r->dec, p, h->length, why, sizeof why) < 0) protocol_broken(r, "RECORDS do not decode: %s", why);
      return;
    case OCP_MSG_BRICKS:
      if (ocp_epoch_dec_bricks(r->dec, p, h->length, why, sizeof why) < 0) protocol_broken(r, "BRICKS do not decode: %s", why);
      return;
    case OCP_MSG_DICT:
      if (ocp_epoch_dec_dict(r->dec, p, h->length, why, sizeof why) < 0) protocol_broken(r, "DICT does not decode: %s", why);
      return;
    case OCP_MSG_EPOCH_END: {
      if (h->length != V1_EPOCH_END) protocol_broken(r, "EPOCH_END of %" PRIu32 " bytes, not %d", h->length, V1_EPOCH_END);
      ocp_epoch_end_t m;
      if (ocp_get_epoch_end(p, h->length, &m, why, sizeof why) < 0) protocol_broken(r, "EPOCH_END: %s", why);
      if (m.epoch != oc_get_u64(p) || m.checksum != oc_get_u64(p + 8)) protocol_broken(r, "EPOCH_END: fields not at their v1 offsets");
      /* the state rebuilt from the frames, and its checksum recomputed here */
      oc_state_t s;
      oc_brick_digests_t dg = {0};
      oc_state_init(&s);
      int e = r->lean ? ocp_epoch_dec_end_lean(r->dec, &m, &s, &dg, why, sizeof why) : ocp_epoch_dec_end(r->dec, &m, &s, why, sizeof why);
      if (e) protocol_broken(r, "epoch %" PRIu64 " does not rebuild to its own checksum: %s", m.epoch, why);
      uint64_t mine = r->lean ? oc_state_digest_checksum(&s, &dg) : oc_state_checksum(&s);
      if (mine != m.checksum)
        protocol_broken(r, "epoch %" PRIu64 ": the rebuilt state's checksum %016" PRIx64 " is not EPOCH_END's %016" PRIx64, m.epoch, mine,
                        m.checksum);
      uint64_t re = field(line, r->no, "epoch", 0), rc = field(line, r->no, "checksum", 1);
      if (m.epoch != re || m.checksum != rc)
        content_changed(r, "epoch %" PRIu64 " has checksum %016" PRIx64 " (verified by rebuilding it), recorded epoch %" PRIu64
                           " with %016" PRIx64, m.epoch, m.checksum, re, rc);
      uint64_t fd = r->lean ? full_digest(r->full, m.epoch) : 0;
      if (fd && fd != m.checksum)
        content_changed(r, "the lean viewer's epoch %" PRIu64 " (digest checksum %016" PRIx64 ") is not the full viewer's (%016" PRIx64 ")",
                        m.epoch, m.checksum, fd);
      /* keep the K − 1 newest, as the server assumes */
      int keep = r->kept - 1;
      while (r->nheld >= keep && r->nheld > 0) {
        r->nheld--;
        oc_state_free(&r->held[r->nheld]);
        oc_brick_digests_free(&r->hdig[r->nheld]);
      }
      memmove(&r->held[1], &r->held[0], (size_t)r->nheld * sizeof r->held[0]);
      memmove(&r->hdig[1], &r->hdig[0], (size_t)r->nheld * sizeof r->hdig[0]);
      r->held[0] = s;
      r->hdig[0] = dg;
      r->nheld++;
      r->end_epoch = m.epoch;
      r->end_checksum = m.checksum;
      r->have_end = 1;
      return;
    }
    case OCP_MSG_GOODBYE:
    case OCP_MSG_ERROR: {
      ocp_text_msg_t t;
      if (ocp_get_text(p, h->length, &t, why, sizeof why) < 0) protocol_broken(r, "%s: %s", msg_name(h->type), why);
      return;
    }
    case OCP_MSG_STATS: {
      if (h->length != V1_STATS) protocol_broken(r, "STATS of %" PRIu32 " bytes, not %d", h->length, V1_STATS);
      ocp_stats_t m;
      if (ocp_get_stats(1, p, h->length, &m, why, sizeof why) < 0) protocol_broken(r, "STATS: %s", why);
      if (m.epoch != oc_get_u64(p) || m.epoch != field(line, r->no, "epoch", 0))
        protocol_broken(r, "STATS of epoch %" PRIu64 ", not the recorded %" PRIu64, m.epoch, field(line, r->no, "epoch", 0));
      return;
    }
    default:
      protocol_broken(r, "an unexpected %s frame", msg_name(h->type));
  }
}

static size_t unhex(const replay_t *r, const char *hex, uint8_t *out, size_t cap) {
  size_t n = strlen(hex);
  if (n % 2 || n / 2 > cap) fail_msg("%s:%d: bad hex", g_file, r->no);
  for (size_t i = 0; i < n / 2; i++) {
    unsigned v;
    if (sscanf(hex + 2 * i, "%2x", &v) != 1) fail_msg("%s:%d: bad hex", g_file, r->no);
    out[i] = (uint8_t)v;
  }
  return n / 2;
}

static void replay_section(const char *section, const lines_t *full) {
  lines_t L;
  load_section(section, &L);
  replay_t r = {.section = section, .full = full, .kept = 2};
  assert_int_equal(ocp_epoch_dec_create(&r.dec), 0);
  server_t s;
  start_rp_server(&s);
  raw_t x;
  rp_open(&x, s.port);
  static uint8_t frame[RP_LINE_MAX / 2];
  int epochs = 0, ended = 0;
  for (int i = 0; i < L.n; i++) {
    const char *line = L.line[i];
    r.no = L.lineno[i];
    if (!strncmp(line, "C ", 2)) {
      char name[64];
      const char *hex = strrchr(line, ' ') + 1;
      if (sscanf(line, "C %63s", name) != 1) fail_msg("%s:%d: bad line", g_file, r.no);
      size_t n = unhex(&r, hex, frame, sizeof frame);
      ocp_header_t h;
      if (n < OCP_HEADER_BYTES || ocp_header_parse(frame, OCP_MAX_CLIENT_PAYLOAD, &h) < 0 || n != OCP_HEADER_BYTES + h.length ||
          h.version != 1 || strcmp(name, msg_name(h.type)) != 0)
        fail_msg("%s:%d: not one whole version-1 %s frame", g_file, r.no, name);
      if (h.type == OCP_MSG_HELLO) { /* a v1 HELLO: offering exactly [1, 1] */
        ocp_hello_t m;
        assert_int_equal(ocp_get_hello(frame + OCP_HEADER_BYTES, h.length, &m, NULL, 0), 0);
        assert_int_equal(m.min_version, 1);
        assert_int_equal(m.max_version, 1);
        r.lean = (m.caps & OCP_CAP_DIGEST) != 0;
      }
      if (h.type == OCP_MSG_ACK) { /* the recorded ACK acknowledges what we verified just now */
        ocp_ack_t a;
        assert_int_equal(ocp_get_ack(frame + OCP_HEADER_BYTES, h.length, &a, NULL, 0), 0);
        if (!r.have_end || a.epoch != r.end_epoch || a.checksum != r.end_checksum)
          content_changed(&r, "the recorded ACK (epoch %" PRIu64 ", %016" PRIx64 ") does not match the server's last epoch", a.epoch,
                          a.checksum);
        r.have_end = 0;
        epochs++;
      }
      rp_send(&x, frame, n);
    } else if (!strncmp(line, "step ", 5)) {
      sleep_us(100000); /* our camera and ACK reach the server before the step */
      step(s.port, atoi(line + 5));
    } else if (!strcmp(line, "S eof")) {
      ocp_header_t h;
      const uint8_t *p;
      int k = raw_next(&x, RP_TIMEOUT_S, 0, &h, &p);
      if (k < 0) protocol_broken(&r, "the server did not close the connection after our GOODBYE");
      if (k > 0) protocol_broken(&r, "expected the connection's end, got a %s frame", msg_name(h.type));
      ended = 1;
    } else if (!strncmp(line, "S ", 2)) {
      ocp_header_t h;
      const uint8_t *p;
      int k = raw_next(&x, RP_TIMEOUT_S, 0, &h, &p);
      if (k <= 0) {
        char name[64] = "";
        sscanf(line, "S %63s", name);
        protocol_broken(&r, "no %s frame from the server (%s)", name, k ? "timed out after 60 s" : "it closed the connection");
      }
      check_server_frame(&r, line, &h, p);
    } else {
      fail_msg("%s:%d: unknown line \"%s\"", g_file, r.no, line);
    }
  }
  assert_true(ended);
  assert_int_equal(epochs, RP_EPOCHS);
  print_message("section %s: %d epochs replayed, each rebuilt and matching the recording\n", section, epochs);
  rp_close(&x);
  for (int i = 0; i < r.nheld; i++) {
    oc_state_free(&r.held[i]);
    oc_brick_digests_free(&r.hdig[i]);
  }
  ocp_epoch_dec_free(r.dec);
  free_lines(&L);
  assert_int_equal(stop_server(&s), 0);
}

static void test_replay_v1__full(void **state) {
  (void)state;
  replay_section("full", NULL);
}

static void test_replay_v1__lean(void **state) {
  (void)state;
  lines_t full;
  load_section("full", &full);
  replay_section("lean", &full);
  free_lines(&full);
}

/*-*** Version negotiation ***/

/* HELLO [lo, hi] on a raw socket: @return the WELCOME's chosen version, or -(ERROR code). */
static int negotiate(int port, uint16_t lo, uint16_t hi, char *text, size_t cap) {
  raw_t x;
  rp_open(&x, port);
  oc_buf_t b = {0};
  hello_bytes(&b, lo, hi);
  rp_send(&x, b.data, b.len);
  oc_buf_free(&b);
  ocp_header_t h;
  const uint8_t *p;
  int k = raw_next(&x, RP_TIMEOUT_S, 0, &h, &p), res = 0;
  if (k <= 0) fail_msg("HELLO [%u, %u]: no answer (%s)", lo, hi, k ? "timed out" : "closed");
  if (h.type == OCP_MSG_ERROR) {
    ocp_text_msg_t t;
    assert_int_equal(ocp_get_text(p, h.length, &t, NULL, 0), 0);
    snprintf(text, cap, "%s", t.text);
    res = -(int)t.code;
  } else {
    if (h.type != OCP_MSG_WELCOME) fail_msg("HELLO [%u, %u]: answered with %s", lo, hi, msg_name(h.type));
    ocp_welcome_t w;
    assert_int_equal(ocp_get_welcome(p, h.length, &w, NULL, 0), 0);
    assert_int_equal(h.version, w.version); /* the frame carries the chosen version */
    res = w.version;
    b = (oc_buf_t){0};
    ocp_put_text(&b, (uint8_t)w.version, OCP_MSG_GOODBYE, OCP_CODE_OK, "");
    rp_send(&x, b.data, b.len);
    oc_buf_free(&b);
  }
  rp_close(&x);
  return res;
}

static void test_replay_v1__versions(void **state) {
  (void)state;
  server_t s;
  start_rp_server(&s);
  char text[OCP_TEXT_MAX + 1];
  int v = negotiate(s.port, 2, 5, text, sizeof text); /* a viewer that no longer speaks 1 */
  if (OCP_VERSION_MAX < 2) {
    assert_int_equal(v, -(int)OCP_CODE_VERSION);
    assert_non_null(strstr(text, "2..5"));
  } else {
    assert_int_equal(v, OCP_VERSION_MAX < 5 ? OCP_VERSION_MAX : 5);
  }
  v = negotiate(s.port, OCP_VERSION_MAX + 1, OCP_VERSION_MAX + 4, text, sizeof text); /* only newer ones */
  assert_int_equal(v, -(int)OCP_CODE_VERSION);
  v = negotiate(s.port, 1, 255, text, sizeof text); /* every version: the server's highest */
  assert_int_equal(v, OCP_VERSION_MAX);
  v = negotiate(s.port, 1, 1, text, sizeof text);
  assert_int_equal(v, 1);
  assert_int_equal(stop_server(&s), 0);
}

/* The pinned session (ocp_viewer desc.max_version): its HELLO offers [1, N], it refuses a WELCOME
 * choosing more, and a live version-1 session writes version 1 in every frame (the recorder checks
 * each frame both ways; the output is thrown away). */
static void test_replay_v1__pinned_viewer(void **state) {
  (void)state;
  ocp_viewer_desc_t d = {.role = OCP_ROLE_VIEWER, .budget = RP_BUDGET, .width = RP_W, .height = RP_H, .caps = OCP_CAP_ALL};
  ocp_viewer_t *v = NULL;
  d.max_version = OCP_VERSION_MAX + 1;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  for (int pin = 0; pin <= 1; pin++) {
    d.max_version = (uint16_t)pin; /* 0: OCP_VERSION_MAX */
    assert_int_equal(ocp_viewer_create(&v, &d, NULL), 0);
    oc_buf_t out = {0};
    ocp_viewer_connected(v, &out);
    uint16_t want = pin ? 1 : OCP_VERSION_MAX;
    assert_true(out.len >= OCP_HEADER_BYTES + 4);
    assert_int_equal(out.data[2], want);                           /* HELLO's header: the highest offered */
    assert_int_equal(oc_get_u16(out.data + OCP_HEADER_BYTES), OCP_VERSION_MIN);
    assert_int_equal(oc_get_u16(out.data + OCP_HEADER_BYTES + 2), want);
    /* a WELCOME choosing one more than offered */
    ocp_welcome_t w = {.version = (uint16_t)(want + 1), .kept_states = 2, .session = 7, .budget = RP_BUDGET, .slot_bytes = 2048,
                       .record_bytes = 32, .max_depth = 21, .planet_radius = 6371000.0, .sun_dir = {0, 0, 1}, .albedo = 0.9,
                       .ms_a = 0.5, .ms_b = 0.5, .ms_c = 0.5, .ms_octaves = 4, .cam_fov = 40.0};
    oc_buf_t in = {0};
    ocp_put_welcome(&in, (uint8_t)w.version, &w);
    out.len = 0;
    char why[OCP_TEXT_MAX + 1];
    assert_int_equal(ocp_viewer_feed(v, in.data, in.len, &out, why, sizeof why), OC_EVERSION);
    assert_true(out.len >= OCP_HEADER_BYTES);
    assert_int_equal(out.data[2], want); /* our ERROR: still the version HELLO offered */
    oc_buf_free(&in);
    oc_buf_free(&out);
    ocp_viewer_free(v);
  }
  FILE *f = fopen("/dev/null", "w");
  assert_non_null(f);
  record_section(f, "live", 0);
  fclose(f);
}

int main(void) {
  const char *src = getenv("OC_SOURCE_DIR"), *bin = getenv("OC_BIN_DIR"), *rec = getenv("OC_REPLAY_RECORD");
  if (!src || !bin) {
    fprintf(stderr, "test_replay_v1: OC_SOURCE_DIR and OC_BIN_DIR must be set (ctest sets them)\n");
    return 1;
  }
  snprintf(scene_sphere, sizeof scene_sphere, "%s/scenes/analytic_sphere.json", src);
  snprintf(g_build, sizeof g_build, "%s", bin);
  char *slash = strrchr(g_build, '/');
  if (slash && !strcmp(slash, "/bin")) *slash = '\0'; /* OC_BIN_DIR is BUILD/bin */
  g_recording = rec && *rec;
  if (g_recording) {
    if (rec[0] != '/') {
      fprintf(stderr, "test_replay_v1: OC_REPLAY_RECORD must be an absolute path (got \"%s\")\n", rec);
      return 1;
    }
    snprintf(g_file, sizeof g_file, "%s", rec);
  } else {
    snprintf(g_file, sizeof g_file, "%s/tests/data/replay_v1/session.txt", src);
  }
  signal(SIGPIPE, SIG_IGN);
  int failed = 0;
  if (g_recording) {
    const struct CMUnitTest rec_tests[] = {cmocka_unit_test_teardown(test_replay_v1__record, net_teardown)};
    failed = cmocka_run_group_tests_name("record", rec_tests, NULL, NULL);
    if (failed) return failed;
  }
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_replay_v1__full, net_teardown),
      cmocka_unit_test_teardown(test_replay_v1__lean, net_teardown),
      cmocka_unit_test_teardown(test_replay_v1__versions, net_teardown),
      cmocka_unit_test_teardown(test_replay_v1__pinned_viewer, net_teardown),
  };
  return cmocka_run_group_tests_name("replay_v1", tests, NULL, NULL);
}
