/* test_viewer.c — the viewer's sans-IO session (proto/ocp_viewer.c) driven by frames built by hand:
 * WELCOME from ocp_put_welcome(), epochs from the real encoder (ocp_epoch_enc_*) over small valid
 * states like golden_state() of tests/common/test_state.c. Checks the handshake, acknowledgements,
 * differences, the K−1 kept states, resume, and that bad input ends in an ERROR frame. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_state.h"
#include "ocp_epoch.h"
#include "ocp_viewer.h"
#include "ocp_wire.h"
#include "state_fixture.h" /* child, node, golden_codes, golden_state */

#define SESSION 0x5151u
#define SECRET 0xFEEDFACECAFEBEEFull

/*-*** States (as golden_state() in tests/common/test_state.c) ***/

/* The next epoch: the newest brick is refreshed as brick `id` (same node and ranges, so the
 * encoder may send it as a delta) and one uniform node changes value. */
static void evolve(const oc_state_t *prev, oc_state_t *next, uint32_t id) {
  oc_state_init(next);
  assert_int_equal(oc_state_copy(next, prev), 0);
  next->epoch = prev->epoch + 1;
  next->time = prev->time + 1.0;
  oc_brick_t *last = &next->bricks[next->brick_count - 1];
  for (uint32_t i = 0; i < next->node_count; i++)
    if (next->nodes[i].brick_id == last->id) next->nodes[i].brick_id = id;
  last->id = id;
  golden_codes(id, &last->codes);
  for (int v = 0; v < OC_BRICK_VOXELS; v += 3) last->codes.code[1][v] ^= 0x0101; /* not a pure shift */
  oc_node_t *u = &next->nodes[4];
  assert_int_equal(u->kind, OC_NODE_UNIFORM);
  u->range[0].lo = u->range[0].hi = u->range[0].lo * 1.5f;
  char why[256];
  if (oc_state_validate(next, why, sizeof why)) fail_msg("evolved state: %s", why);
}

/*-*** A hand-driven server ***/

/* the version of the hand-driven server's frames (1 but in the BUDGET tests) */
static uint8_t g_version = 1;

static void put_welcome(oc_buf_t *b, int kept, int resumed, uint32_t session, uint64_t budget) {
  ocp_welcome_t w;
  memset(&w, 0, sizeof w);
  w.version = g_version;
  w.flags = resumed ? OCP_WELCOME_RESUMED : 0;
  w.kept_states = (uint8_t)kept;
  w.session = session;
  w.secret = SECRET;
  w.budget = budget;
  w.slot_bytes = kept ? 2048 : 0;
  w.record_bytes = kept ? 32 : 0;
  w.max_depth = 12;
  w.epoch_period = 1.0;
  w.planet_radius = 6371000.0;
  w.time = 1234.5;
  w.sun_dir = oc_dv3(0.0, 0.6, 0.8);
  w.albedo = 1.0;
  w.ms_a = w.ms_b = w.ms_c = 0.5;
  w.ms_octaves = 4;
  w.cam_fov = 60.0;
  snprintf(w.name, sizeof w.name, "test scene");
  ocp_put_welcome(b, g_version, &w);
}

/* The frames of one epoch (and its STATS): `lacking` are the bricks sent, every other brick must be
 * held by the viewer. */
static void put_epoch(oc_buf_t *b, const oc_state_t *s, const oc_state_t *base, const uint32_t *lacking, uint32_t n) {
  ocp_epoch_enc_t *e;
  ocp_enc_desc_t d;
  memset(&d, 0, sizeof d);
  d.deltas = 1;
  assert_int_equal(ocp_epoch_enc_create(&e, &d), 0);
  assert_int_equal(ocp_epoch_enc_begin(e, s, base, lacking, n), 0);
  int r;
  while ((r = ocp_epoch_enc_next(e, g_version, b)) == 1) {
  }
  assert_int_equal(r, 0);
  ocp_epoch_enc_free(e);
  ocp_stats_t st;
  memset(&st, 0, sizeof st);
  st.epoch = s->epoch;
  st.leaves = s->node_count;
  ocp_put_stats(b, g_version, &st);
}

/* Every brick of s, ascending (a viewer that holds nothing). */
static uint32_t all_bricks(const oc_state_t *s, uint32_t *ids) {
  for (uint32_t i = 0; i < s->brick_count; i++) ids[i] = s->bricks[i].id;
  return s->brick_count;
}

/*-*** Events ***/

typedef struct {
  int welcomes, states, stats, replies, closes, budgets;
  uint64_t last_budget;
  int last_resumed;
  uint32_t last_bricks, close_code;
  uint64_t last_epoch, last_checksum, last_stats_epoch;
  char close_text[OCP_TEXT_MAX + 1];
  char reply[256];
  uint32_t reply_request;
} events_t;

static void on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  events_t *e = ctx;
  (void)w;
  e->welcomes++;
  e->last_resumed = resumed;
}
static void on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  events_t *e = ctx;
  e->states++;
  e->last_epoch = s->epoch;
  e->last_checksum = oc_state_checksum(s);
  e->last_bricks = bricks;
}
static void on_stats(void *ctx, const ocp_stats_t *s) {
  events_t *e = ctx;
  e->stats++;
  e->last_stats_epoch = s->epoch;
}
static void on_reply(void *ctx, const ocp_control_t *c) {
  events_t *e = ctx;
  e->replies++;
  e->reply_request = c->request;
  snprintf(e->reply, sizeof e->reply, "%.*s", (int)c->json_len, c->json);
}
static void on_closed(void *ctx, uint32_t code, const char *text) {
  events_t *e = ctx;
  e->closes++;
  e->close_code = code;
  snprintf(e->close_text, sizeof e->close_text, "%s", text);
}

static void on_budget(void *ctx, const oc_budget_t *g) {
  events_t *e = ctx;
  e->budgets++;
  e->last_budget = g->budget;
}

static ocp_viewer_t *make_viewer(events_t *ev, int role) {
  memset(ev, 0, sizeof *ev);
  ocp_viewer_desc_t d;
  memset(&d, 0, sizeof d);
  d.role = (uint8_t)role;
  d.budget = 1u << 20;
  d.max_depth = 12;
  d.width = 640, d.height = 480;
  d.caps = OCP_CAP_ALL;
  d.token = "sesame";
  ocp_viewer_events_t cb = {ev, on_welcome, on_state, on_stats, on_reply, on_closed, on_budget};
  ocp_viewer_t *v = NULL;
  assert_int_equal(ocp_viewer_create(&v, &d, &cb), 0);
  return v;
}

/* The frames in out, in order. */
typedef struct {
  int n;
  ocp_header_t h[16];
  const uint8_t *p[16];
} frames_t;

static frames_t parse_out(const oc_buf_t *out) {
  frames_t f;
  memset(&f, 0, sizeof f);
  size_t at = 0;
  assert_false(out->err);
  while (at < out->len) {
    assert_true(f.n < 16);
    assert_true(out->len - at >= OCP_HEADER_BYTES);
    assert_int_equal(ocp_header_parse(out->data + at, OCP_MAX_PAYLOAD, &f.h[f.n]), 0);
    f.p[f.n] = out->data + at + OCP_HEADER_BYTES;
    at += OCP_HEADER_BYTES + f.h[f.n].length;
    assert_true(at <= out->len);
    f.n++;
  }
  return f;
}

/* The one frame in out, of `type`, decoded. */
static ocp_msg_t only_msg(const oc_buf_t *out, uint8_t type) {
  frames_t f = parse_out(out);
  ocp_msg_t m;
  char why[256];
  assert_int_equal(f.n, 1);
  assert_int_equal(f.h[0].type, type);
  if (ocp_get_msg(f.h[0].version, type, f.p[0], f.h[0].length, &m, why, sizeof why)) fail_msg("%s", why);
  return m;
}

static ocp_hello_t hello_of(const oc_buf_t *out) { return only_msg(out, OCP_MSG_HELLO).hello; }

/* The one ACK in out. */
static ocp_ack_t ack_of(const oc_buf_t *out) { return only_msg(out, OCP_MSG_ACK).ack; }

/* The single ERROR frame in out, with its code. */
static void expect_error_frame(const oc_buf_t *out, uint32_t code) {
  frames_t f = parse_out(out);
  ocp_text_msg_t t;
  char why[256];
  assert_true(f.n >= 1);
  assert_int_equal(f.h[f.n - 1].type, OCP_MSG_ERROR);
  assert_int_equal(ocp_get_text(f.p[f.n - 1], f.h[f.n - 1].length, &t, why, sizeof why), 0);
  if (t.code != code) fail_msg("ERROR code %u (%s), expected %u", t.code, t.text, code);
  assert_true(strlen(t.text) > 0);
}

static int feed(ocp_viewer_t *v, const oc_buf_t *in, oc_buf_t *out, char *why, size_t why_len) {
  out->len = 0;
  return ocp_viewer_feed(v, in->data, in->len, out, why, why_len);
}

/* Connects and completes the handshake with a WELCOME of K kept states. */
static void handshake(ocp_viewer_t *v, int kept, oc_buf_t *out) {
  oc_buf_t in = {0};
  char why[256];
  out->len = 0;
  ocp_viewer_connected(v, out);
  put_welcome(&in, kept, 0, SESSION, 1u << 20);
  if (feed(v, &in, out, why, sizeof why)) fail_msg("%s", why);
  assert_true(ocp_viewer_ready(v));
  oc_buf_free(&in);
}

/*-*** Tests ***/

/* The golden state as s, sent whole (every record and brick) into b. */
static void put_golden_epoch(oc_buf_t *b, oc_state_t *s) {
  uint32_t ids[8];
  golden_state(s);
  put_epoch(b, s, NULL, ids, all_bricks(s, ids));
}

/* A viewer under test: its events, what the server sends it (in), what it sends back (out), and
 * the reason when a feed fails. */
typedef struct {
  events_t ev;
  ocp_viewer_t *v;
  oc_buf_t in, out;
  char why[256];
} rig_t;

static void rig_open(rig_t *x, int role) {
  memset(x, 0, sizeof *x);
  x->v = make_viewer(&x->ev, role);
}

/* Feeds x->in to the viewer; its replies are appended to x->out. @return feed()'s result. */
static int rig_feed(rig_t *x) { return feed(x->v, &x->in, &x->out, x->why, sizeof x->why); }

static void rig_close(rig_t *x) {
  oc_buf_free(&x->in);
  oc_buf_free(&x->out);
  ocp_viewer_free(x->v);
}

static void test_viewer__hello_and_welcome(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  assert_false(ocp_viewer_ready(x.v));
  assert_null(ocp_viewer_welcome(x.v));
  /* a camera set before WELCOME is held and sent right after it */
  ocp_camera_t cam = {oc_dv3(0, 0, 6.4e6), oc_dv3(1, 0, 0), oc_dv3(0, 0, 1), 50.0, 1280, 720};
  assert_int_equal(ocp_viewer_camera(x.v, &cam, &x.out), 0);
  assert_int_equal(x.out.len, 0);
  ocp_camera_t bad = cam;
  bad.vfov_deg = 200.0;
  assert_int_equal(ocp_viewer_camera(x.v, &bad, &x.out), OC_EINVAL);
  ocp_viewer_connected(x.v, &x.out);
  ocp_hello_t h = hello_of(&x.out);
  assert_int_equal(h.min_version, OCP_VERSION_MIN);
  assert_int_equal(h.max_version, OCP_VERSION_MAX);
  assert_int_equal(h.role, OCP_ROLE_VIEWER);
  assert_int_equal(h.budget, 1u << 20);
  assert_int_equal(h.slot_bytes, 2048); /* defaults */
  assert_int_equal(h.record_bytes, 32);
  assert_int_equal(h.width, 1280); /* the camera's viewport */
  assert_int_equal(h.height, 720);
  assert_int_equal(h.caps, OCP_CAP_ALL);
  assert_int_equal(h.max_depth, 12);
  assert_int_equal(h.resume_session, 0);
  assert_int_equal(h.token_len, 6);
  assert_memory_equal(h.token, "sesame", 6);
  put_welcome(&x.in, 3, 0, SESSION, 1u << 20);
  assert_int_equal(rig_feed(&x), 0);
  assert_int_equal(x.ev.welcomes, 1);
  assert_int_equal(x.ev.last_resumed, 0);
  assert_true(ocp_viewer_ready(x.v));
  assert_int_equal(ocp_viewer_welcome(x.v)->session, SESSION);
  assert_string_equal(ocp_viewer_welcome(x.v)->name, "test scene");
  frames_t f = parse_out(&x.out);
  assert_int_equal(f.n, 1);
  assert_int_equal(f.h[0].type, OCP_MSG_CAMERA);
  ocp_camera_t back;
  assert_int_equal(ocp_get_camera(f.p[0], f.h[0].length, &back, x.why, sizeof x.why), 0);
  assert_memory_equal(&back, &cam, sizeof cam);
  /* after WELCOME a camera goes out at once; keepalive and goodbye too */
  x.out.len = 0;
  assert_int_equal(ocp_viewer_camera(x.v, &cam, &x.out), 0);
  ocp_viewer_keepalive(x.v, &x.out);
  ocp_viewer_goodbye(x.v, &x.out);
  f = parse_out(&x.out);
  assert_int_equal(f.n, 3);
  assert_int_equal(f.h[0].type, OCP_MSG_CAMERA);
  assert_int_equal(f.h[1].type, OCP_MSG_KEEPALIVE);
  assert_int_equal(f.h[2].type, OCP_MSG_GOODBYE);
  /* a second WELCOME on the same connection is unexpected */
  assert_int_equal(rig_feed(&x), OC_ECORRUPT);
  assert_non_null(strstr(x.why, "welcome"));
  expect_error_frame(&x.out, OCP_CODE_UNEXPECTED);
  rig_close(&x);
}

static void test_viewer__epochs_and_acks(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  oc_state_t s1, s2;
  handshake(x.v, 3, &x.out);
  /* first epoch: every record and brick */
  put_golden_epoch(&x.in, &s1);
  if (rig_feed(&x)) fail_msg("%s", x.why);
  assert_int_equal(x.ev.states, 1);
  assert_int_equal(x.ev.last_epoch, 42);
  assert_true(x.ev.last_checksum == oc_state_checksum(&s1));
  assert_true(x.ev.last_checksum == 0xc9d949fa8e9ec21bull); /* the golden checksum */
  assert_int_equal(x.ev.last_bricks, 3);
  assert_int_equal(x.ev.stats, 1);
  assert_int_equal(x.ev.last_stats_epoch, 42);
  ocp_ack_t ack = ack_of(&x.out);
  assert_int_equal(parse_out(&x.out).h[0].version, 1);
  assert_int_equal(ack.epoch, 42);
  assert_true(ack.checksum == oc_state_checksum(&s1));
  const oc_state_t *held = ocp_viewer_state(x.v, 0);
  assert_non_null(held);
  assert_true(oc_state_checksum(held) == oc_state_checksum(&s1));
  assert_null(ocp_viewer_state(x.v, 1));
  ocp_viewer_stats_t st;
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.states, 1);
  assert_int_equal(st.bricks_in, 3);
  assert_int_equal(st.resident_bytes, 3 * 2048 + 15 * 32);
  /* second epoch as a difference: one refreshed brick (a delta of 42), the rest held */
  evolve(&s1, &s2, 43);
  x.in.len = 0;
  uint32_t lack[] = {43};
  put_epoch(&x.in, &s2, &s1, lack, 1);
  if (rig_feed(&x)) fail_msg("%s", x.why);
  assert_int_equal(x.ev.states, 2);
  assert_int_equal(x.ev.last_epoch, 43);
  assert_int_equal(x.ev.last_bricks, 1);
  assert_true(x.ev.last_checksum == oc_state_checksum(&s2));
  ack = ack_of(&x.out);
  assert_int_equal(ack.epoch, 43);
  assert_true(ack.checksum == oc_state_checksum(&s2));
  assert_int_equal(ocp_viewer_state(x.v, 0)->epoch, 43);
  assert_int_equal(ocp_viewer_state(x.v, 1)->epoch, 42); /* K = 3 keeps two */
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.states, 2);
  assert_int_equal(st.bricks_in, 4);
  assert_int_equal(st.resident_bytes, 4 * 2048 + 30 * 32); /* bricks 3, 7, 42, 43; 2 × 15 records */
  assert_int_equal(st.resident_peak, 4 * 2048 + 30 * 32);
  assert_int_equal(st.over_budget, 0);
  assert_int_equal(st.frames_in, 1 + 2 * 5); /* WELCOME; BEGIN, RECORDS, BRICKS, END, STATS twice */
  oc_state_free(&s1);
  oc_state_free(&s2);
  rig_close(&x);
}

/* K = 2 keeps 1 state, K = 3 keeps 2, over several epochs. */
static void run_kept(int kept) {
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  oc_state_t s[5];
  handshake(x.v, kept, &x.out);
  put_golden_epoch(&x.in, &s[0]);
  for (int i = 1; i < 5; i++) {
    evolve(&s[i - 1], &s[i], 100 + (uint32_t)i);
    uint32_t lack[] = {100 + (uint32_t)i};
    put_epoch(&x.in, &s[i], &s[i - 1], lack, 1);
  }
  if (rig_feed(&x)) fail_msg("%s", x.why); /* all five epochs in one feed */
  assert_int_equal(x.ev.states, 5);
  frames_t f = parse_out(&x.out);
  assert_int_equal(f.n, 5);
  for (int i = 0; i < 5; i++) {
    ocp_ack_t a;
    assert_int_equal(f.h[i].type, OCP_MSG_ACK);
    assert_int_equal(ocp_get_ack(f.p[i], f.h[i].length, &a, x.why, sizeof x.why), 0);
    assert_int_equal(a.epoch, 42 + i);
    assert_true(a.checksum == oc_state_checksum(&s[i]));
  }
  for (int i = 0; i < kept - 1; i++) {
    assert_non_null(ocp_viewer_state(x.v, i));
    assert_true(oc_state_checksum(ocp_viewer_state(x.v, i)) == oc_state_checksum(&s[4 - i]));
  }
  assert_null(ocp_viewer_state(x.v, kept - 1));
  ocp_viewer_stats_t st;
  ocp_viewer_stats(x.v, &st);
  /* the window is the K newest states: 3 shared bricks (3, 7) + one refreshed brick each */
  assert_int_equal(st.resident_bytes, (uint64_t)(2 + kept) * 2048 + (uint64_t)kept * 15 * 32);
  for (int i = 0; i < 5; i++) oc_state_free(&s[i]);
  rig_close(&x);
}

static void test_viewer__kept_states(void **state) {
  (void)state;
  run_kept(2);
  run_kept(3);
}

static void test_viewer__resume(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  oc_state_t s1, s2;
  handshake(x.v, 3, &x.out);
  put_golden_epoch(&x.in, &s1);
  evolve(&s1, &s2, 43);
  uint32_t lack[] = {43};
  put_epoch(&x.in, &s2, &s1, lack, 1);
  /* the connection drops in the middle of a third epoch: half of it is fed */
  oc_state_t s3;
  evolve(&s2, &s3, 44);
  size_t whole = x.in.len;
  uint32_t lack3[] = {44};
  put_epoch(&x.in, &s3, &s2, lack3, 1);
  x.in.len = whole + (x.in.len - whole) / 2;
  if (rig_feed(&x)) fail_msg("%s", x.why);
  assert_int_equal(x.ev.states, 2);
  /* reconnect: HELLO names the session, its secret and the newest complete state */
  x.out.len = 0;
  ocp_viewer_connected(x.v, &x.out);
  assert_false(ocp_viewer_ready(x.v));
  ocp_hello_t h = hello_of(&x.out);
  assert_int_equal(h.resume_session, SESSION);
  assert_true(h.resume_secret == SECRET);
  assert_int_equal(h.held_epoch, 43);
  assert_true(h.held_checksum == oc_state_checksum(&s2));
  /* resumed: the states stay, and the epoch continues as a difference from 43 */
  x.in.len = 0;
  put_welcome(&x.in, 3, 1, SESSION, 1u << 20);
  put_epoch(&x.in, &s3, &s2, lack3, 1);
  if (rig_feed(&x)) fail_msg("%s", x.why);
  assert_int_equal(x.ev.welcomes, 2);
  assert_int_equal(x.ev.last_resumed, 1);
  assert_int_equal(x.ev.states, 3);
  assert_int_equal(ocp_viewer_state(x.v, 0)->epoch, 44);
  assert_int_equal(ocp_viewer_state(x.v, 1)->epoch, 43);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.reconnects, 1);
  assert_int_equal(st.resumed, 1);
  /* a server that lost the session starts a new one: everything held is dropped */
  x.out.len = 0;
  ocp_viewer_connected(x.v, &x.out);
  h = hello_of(&x.out);
  assert_int_equal(h.held_epoch, 44);
  x.in.len = 0;
  put_welcome(&x.in, 3, 0, SESSION + 1, 1u << 20);
  if (rig_feed(&x)) fail_msg("%s", x.why);
  assert_int_equal(x.ev.last_resumed, 0);
  assert_null(ocp_viewer_state(x.v, 0));
  /* and the next HELLO names the new session with no state */
  x.out.len = 0;
  ocp_viewer_connected(x.v, &x.out);
  h = hello_of(&x.out);
  assert_int_equal(h.resume_session, SESSION + 1);
  assert_int_equal(h.held_epoch, 0);
  assert_int_equal(h.held_checksum, 0);
  /* a WELCOME claiming to resume a session that was not asked for is refused */
  x.in.len = 0;
  put_welcome(&x.in, 3, 1, SESSION + 7, 1u << 20);
  assert_int_equal(rig_feed(&x), OC_ECORRUPT);
  assert_non_null(strstr(x.why, "resume"));
  expect_error_frame(&x.out, OCP_CODE_MALFORMED);
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.reconnects, 3);
  oc_state_free(&s1);
  oc_state_free(&s2);
  oc_state_free(&s3);
  rig_close(&x);
}

/* Offset of the n-th frame of `type` in b. */
static size_t find_frame(const oc_buf_t *b, uint8_t type, int nth) {
  size_t at = 0;
  while (at + OCP_HEADER_BYTES <= b->len) {
    ocp_header_t h;
    assert_int_equal(ocp_header_parse(b->data + at, OCP_MAX_PAYLOAD, &h), 0);
    if (h.type == type && nth-- == 0) return at;
    at += OCP_HEADER_BYTES + h.length;
  }
  fail_msg("no frame of type 0x%02x", type);
  return 0;
}

static void test_viewer__corrupt_bricks(void **state) {
  (void)state;
  events_t ev;
  oc_buf_t out = {0}, in = {0};
  char why[256];
  oc_state_t s1;
  put_golden_epoch(&in, &s1);
  size_t at = find_frame(&in, OCP_MSG_BRICKS, 0);
  /* (a) the raw length of the batch disagrees with its zstd frame: malformed */
  for (int variant = 0; variant < 2; variant++) {
    ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
    handshake(v, 3, &out);
    oc_buf_t bad = {0};
    oc_buf_append(&bad, in.data, in.len);
    if (variant == 0)
      bad.data[at + OCP_HEADER_BYTES + 4] ^= 0x01; /* raw length */
    else
      bad.data[at + OCP_HEADER_BYTES] = 9; /* a dictionary id never sent */
    int e = feed(v, &bad, &out, why, sizeof why);
    assert_true(e < 0);
    assert_int_equal(e, OC_ECORRUPT);
    assert_true(strlen(why) > 0);
    expect_error_frame(&out, OCP_CODE_MALFORMED);
    assert_int_equal(ev.states, 0);
    assert_null(ocp_viewer_state(v, 0));
    /* the session refuses more input until the next connection, and sends no second ERROR */
    out.len = 0;
    assert_true(ocp_viewer_feed(v, in.data, in.len, &out, why, sizeof why) < 0);
    assert_int_equal(out.len, 0);
    oc_buf_free(&bad);
    ocp_viewer_free(v);
  }
  /* (b) a delta against a base brick the server has different from the viewer's: the rebuilt
   * state fails its checksum (docs/protocol.md, BRICKS) */
  ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
  handshake(v, 3, &out);
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  oc_state_t s2, server_base;
  evolve(&s1, &s2, 43);
  oc_state_init(&server_base);
  oc_state_copy(&server_base, &s1);
  server_base.bricks[2].codes.code[0][17] ^= 0x40; /* brick 42 as the server (wrongly) has it */
  in.len = 0;
  uint32_t lack[] = {43};
  put_epoch(&in, &s2, &server_base, lack, 1);
  int e = feed(v, &in, &out, why, sizeof why);
  assert_int_equal(e, OC_ECHECKSUM);
  assert_non_null(strstr(why, "checksum"));
  expect_error_frame(&out, OCP_CODE_CHECKSUM);
  assert_int_equal(ev.states, 1);
  assert_int_equal(ocp_viewer_state(v, 0)->epoch, 42); /* the held state is untouched */
  oc_state_free(&s1);
  oc_state_free(&s2);
  oc_state_free(&server_base);
  oc_buf_free(&in);
  oc_buf_free(&out);
  ocp_viewer_free(v);
}

static void test_viewer__unexpected(void **state) {
  (void)state;
  events_t ev;
  oc_buf_t out = {0}, in = {0};
  char why[256];
  oc_state_t s1;
  uint32_t ids[8];
  golden_state(&s1);
  /* before WELCOME: an epoch, a keepalive, a client's message */
  static const uint8_t early[] = {OCP_MSG_EPOCH_BEGIN, OCP_MSG_KEEPALIVE, OCP_MSG_STATS, OCP_MSG_CAMERA};
  for (size_t i = 0; i < sizeof early; i++) {
    ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
    out.len = 0;
    ocp_viewer_connected(v, &out);
    in.len = 0;
    if (early[i] == OCP_MSG_EPOCH_BEGIN)
      put_epoch(&in, &s1, NULL, ids, all_bricks(&s1, ids));
    else if (early[i] == OCP_MSG_KEEPALIVE)
      ocp_put_empty(&in, 1, OCP_MSG_KEEPALIVE);
    else if (early[i] == OCP_MSG_STATS)
      ocp_put_stats(&in, 1, &(ocp_stats_t){0});
    else
      ocp_put_camera(&in, 1, &(ocp_camera_t){oc_dv3(0, 0, 1), oc_dv3(1, 0, 0), oc_dv3(0, 1, 0), 60, 1, 1});
    assert_int_equal(feed(v, &in, &out, why, sizeof why), OC_ECORRUPT);
    assert_non_null(strstr(why, "before welcome"));
    expect_error_frame(&out, OCP_CODE_UNEXPECTED);
    assert_int_equal(ev.welcomes, 0);
    ocp_viewer_free(v);
  }
  /* after WELCOME: RECORDS without EPOCH_BEGIN; BRICKS before RECORDS; EPOCH_END too early; a
   * client's message; an unknown type; a frame of another version */
  oc_buf_t ep = {0};
  put_epoch(&ep, &s1, NULL, ids, all_bricks(&s1, ids));
  size_t at_begin = find_frame(&ep, OCP_MSG_EPOCH_BEGIN, 0), at_rec = find_frame(&ep, OCP_MSG_RECORDS, 0);
  size_t at_bricks = find_frame(&ep, OCP_MSG_BRICKS, 0), at_end = find_frame(&ep, OCP_MSG_EPOCH_END, 0);
  for (int c = 0; c < 6; c++) {
    ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
    handshake(v, 3, &out);
    in.len = 0;
    const char *needle = NULL;
    uint32_t code = OCP_CODE_UNEXPECTED;
    switch (c) {
      case 0: /* RECORDS without EPOCH_BEGIN */
        oc_buf_append(&in, ep.data + at_rec, at_bricks - at_rec);
        needle = "records: not valid outside an epoch";
        break;
      case 1: /* EPOCH_BEGIN, then BRICKS */
        oc_buf_append(&in, ep.data + at_begin, at_rec - at_begin);
        oc_buf_append(&in, ep.data + at_bricks, at_end - at_bricks);
        needle = "bricks: not valid before records";
        break;
      case 2: /* EPOCH_BEGIN, then EPOCH_END */
        oc_buf_append(&in, ep.data + at_begin, at_rec - at_begin);
        oc_buf_append(&in, ep.data + at_end, 8 + 16);
        needle = "epoch-end: not valid before records";
        break;
      case 3: /* a viewer's own message */
        ocp_put_ack(&in, 1, &(ocp_ack_t){1, 2});
        needle = "ack: not valid from a server";
        break;
      case 4: /* an unknown type */
        ocp_put_empty(&in, 1, 0x99);
        needle = "unknown message type 0x99";
        break;
      case 5: /* the wrong version byte */
        ocp_put_empty(&in, 2, OCP_MSG_KEEPALIVE);
        needle = "frame version 2, negotiated 1";
        code = OCP_CODE_MALFORMED;
        break;
    }
    int e = feed(v, &in, &out, why, sizeof why);
    assert_int_equal(e, OC_ECORRUPT);
    if (!strstr(why, needle)) fail_msg("case %d: '%s' lacks '%s'", c, why, needle);
    expect_error_frame(&out, code);
    ocp_viewer_free(v);
  }
  /* a bad magic and an oversized frame */
  for (int c = 0; c < 2; c++) {
    ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
    handshake(v, 3, &out);
    uint8_t hdr[8] = {0x4F, 0x57, 1, OCP_MSG_RECORDS, 0, 0, 0, 0};
    if (c == 0)
      hdr[0] = 'X';
    else
      oc_put_u32(hdr + 4, OCP_MAX_PAYLOAD + 1);
    out.len = 0;
    int e = ocp_viewer_feed(v, hdr, sizeof hdr, &out, why, sizeof why);
    assert_int_equal(e, c == 0 ? OC_ECORRUPT : OC_ETOOBIG);
    expect_error_frame(&out, c == 0 ? OCP_CODE_MALFORMED : OCP_CODE_TOO_BIG);
    ocp_viewer_free(v);
  }
  oc_state_free(&s1);
  oc_buf_free(&ep);
  oc_buf_free(&in);
  oc_buf_free(&out);
}

static void test_viewer__byte_at_a_time(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  oc_state_t s1, s2;
  uint32_t ids[8];
  ocp_viewer_connected(x.v, &x.out);
  x.out.len = 0;
  golden_state(&s1);
  evolve(&s1, &s2, 43);
  uint32_t lack[] = {43};
  put_welcome(&x.in, 2, 0, SESSION, 1u << 20);
  ocp_put_empty(&x.in, 1, OCP_MSG_KEEPALIVE);
  put_epoch(&x.in, &s1, NULL, ids, all_bricks(&s1, ids));
  put_epoch(&x.in, &s2, &s1, lack, 1);
  for (size_t i = 0; i < x.in.len; i++)
    if (ocp_viewer_feed(x.v, x.in.data + i, 1, &x.out, x.why, sizeof x.why)) fail_msg("byte %zu: %s", i, x.why);
  assert_int_equal(x.ev.states, 2);
  assert_int_equal(x.ev.stats, 2);
  assert_true(x.ev.last_checksum == oc_state_checksum(&s2));
  assert_int_equal(ocp_viewer_state(x.v, 0)->epoch, 43);
  assert_null(ocp_viewer_state(x.v, 1)); /* K = 2 keeps one */
  ocp_viewer_stats_t st;
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.bytes_in, x.in.len);
  assert_int_equal(st.frames_in, 2 + 2 * 5);
  assert_int_equal(parse_out(&x.out).n, 2); /* two ACKs */
  oc_state_free(&s1);
  oc_state_free(&s2);
  rig_close(&x);
}

static void test_viewer__over_budget_and_close(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_VIEWER);
  oc_state_t s1;
  uint32_t ids[8];
  golden_state(&s1);
  ocp_viewer_connected(x.v, &x.out);
  put_welcome(&x.in, 3, 0, SESSION, 1000); /* a grant the state does not fit in */
  put_epoch(&x.in, &s1, NULL, ids, all_bricks(&s1, ids));
  ocp_put_text(&x.in, 1, OCP_MSG_GOODBYE, OCP_CODE_SHUTDOWN, "server shutting down");
  ocp_put_empty(&x.in, 1, 0xEE); /* after GOODBYE: not looked at */
  assert_int_equal(rig_feed(&x), 0);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(x.v, &st);
  assert_int_equal(st.over_budget, 1);
  assert_int_equal(st.resident_bytes, 3 * 2048 + 15 * 32);
  assert_int_equal(x.ev.closes, 1);
  assert_int_equal(x.ev.close_code, OCP_CODE_SHUTDOWN);
  assert_string_equal(x.ev.close_text, "server shutting down");
  /* an ERROR from the server before WELCOME is reported the same way */
  x.out.len = 0;
  ocp_viewer_connected(x.v, &x.out);
  x.in.len = 0;
  ocp_put_text(&x.in, 1, OCP_MSG_ERROR, OCP_CODE_TOKEN, "bad token");
  assert_int_equal(rig_feed(&x), 0);
  assert_int_equal(x.ev.closes, 2);
  assert_int_equal(x.ev.close_code, OCP_CODE_TOKEN);
  assert_int_equal(x.out.len, 0);
  oc_state_free(&s1);
  rig_close(&x);
}

/*-*** BUDGET (version 3) ***/

static void put_budget(oc_buf_t *b, uint64_t budget, uint64_t epoch) {
  ocp_budget_t m = {budget, epoch};
  ocp_put_budget(b, g_version, &m);
}

/* One epoch fed; the viewer's counters after it. */
static ocp_viewer_stats_t feed_epoch(ocp_viewer_t *v, const oc_state_t *s, const oc_state_t *base, uint32_t lack) {
  oc_buf_t in = {0}, out = {0};
  char why[256];
  uint32_t ids[8];
  if (base) put_epoch(&in, s, base, &lack, 1);
  else put_epoch(&in, s, NULL, ids, all_bricks(s, ids));
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  ocp_viewer_stats_t st;
  ocp_viewer_stats(v, &st);
  oc_buf_free(&in);
  oc_buf_free(&out);
  return st;
}

/* A lowering: the old budget counts for every window that still holds a state planned under it;
 * once they have left the window (K = 3: two states of the new epoch held) the new one is in force,
 * the event says so, and a window over it is counted. A raise holds at once. */
static void test_viewer__budget_lowered_then_raised(void **state) {
  (void)state;
  g_version = OCP_VERSION_BUDGET;
  events_t ev;
  ocp_viewer_t *v = make_viewer(&ev, OCP_ROLE_VIEWER);
  oc_buf_t out = {0}, in = {0};
  char why[256];
  oc_state_t s[5];
  golden_state(&s[0]); /* epoch 42: 3 bricks, 15 records */
  for (int i = 1; i < 5; i++) evolve(&s[i - 1], &s[i], 43 + (uint32_t)i - 1);
  handshake(v, 3, &out); /* 1 MiB */
  assert_int_equal(feed_epoch(v, &s[0], NULL, 0).over_budget, 0);
  /* 10000 bytes from epoch 43: above the minimum (3 × 2080), below the 3-state windows here (11680) */
  put_budget(&in, 10000, 43);
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  assert_int_equal(out.len, 0);
  assert_int_equal(ev.budgets, 0); /* not yet: epoch 42, planned under 1 MiB, is held */
  assert_int_equal(feed_epoch(v, &s[1], &s[0], 43).over_budget, 0);
  assert_int_equal(ev.budgets, 0);
  ocp_viewer_stats_t st = feed_epoch(v, &s[2], &s[1], 44); /* window 42..44: 11680, 42's 1 MiB counts */
  assert_int_equal(st.resident_bytes, 5 * 2048 + 45 * 32);
  assert_int_equal(st.over_budget, 0);
  assert_int_equal(ev.budgets, 1); /* 42 has left: 43 and 44 held, the next one planned under 10000 */
  assert_int_equal(ev.last_budget, 10000);
  assert_int_equal(st.budgets, 1);
  st = feed_epoch(v, &s[3], &s[2], 45); /* window 43..45: 11680 > 10000 */
  assert_int_equal(st.over_budget, 1);
  /* a raise: at once */
  in.len = 0;
  put_budget(&in, 2u << 20, 47);
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  assert_int_equal(ev.budgets, 2);
  assert_int_equal(ev.last_budget, 2u << 20);
  assert_int_equal(feed_epoch(v, &s[4], &s[3], 46).over_budget, 1);
  /* a lowering pending, then a raise from a later epoch: the store grows at once, and the raise is
   * not undone when the lowering's states leave */
  in.len = 0;
  put_budget(&in, 20000, 47);
  put_budget(&in, 3u << 20, 48);
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  assert_int_equal(ev.budgets, 3);
  assert_int_equal(ev.last_budget, 3u << 20);
  for (int i = 0; i < 5; i++) oc_state_free(&s[i]);
  oc_buf_free(&in);
  oc_buf_free(&out);
  ocp_viewer_free(v);
  g_version = 1;
}

/* Each bad BUDGET closes the session with an ERROR whose text names the fault. */
static void expect_budget_refused(int version, int role, void (*put)(oc_buf_t *), uint32_t code, const char *text) {
  g_version = (uint8_t)version;
  events_t ev;
  ocp_viewer_t *v = make_viewer(&ev, role);
  oc_buf_t out = {0}, in = {0};
  char why[256];
  handshake(v, role == OCP_ROLE_VIEWER ? 3 : 0, &out);
  oc_state_t s1;
  golden_state(&s1);
  if (role == OCP_ROLE_VIEWER) feed_epoch(v, &s1, NULL, 0);
  put(&in);
  assert_true(feed(v, &in, &out, why, sizeof why) < 0);
  expect_error_frame(&out, code);
  if (!strstr(why, text)) fail_msg("\"%s\" does not say \"%s\"", why, text);
  oc_state_free(&s1);
  oc_buf_free(&in);
  oc_buf_free(&out);
  ocp_viewer_free(v);
  g_version = 1;
}

static void put_short(oc_buf_t *b) {
  size_t h = ocp_frame_begin(b, g_version, OCP_MSG_BUDGET);
  oc_buf_u64(b, 1u << 20);
  oc_buf_u32(b, 50);
  ocp_frame_end(b, h);
}
static void put_zero(oc_buf_t *b) { put_budget(b, 0, 50); }
static void put_small(oc_buf_t *b) { put_budget(b, 6239, 50); }
static void put_stale(oc_buf_t *b) { put_budget(b, 1u << 20, 42); }
static void put_good(oc_buf_t *b) { put_budget(b, 1u << 20, 50); }
static void put_mid_epoch(oc_buf_t *b) {
  oc_state_t s2;
  golden_state(&s2);
  s2.epoch = 50;
  ocp_epoch_begin_t m = {.epoch = 50, .time = s2.time, .sun_dir = s2.sun_dir, .base_epoch = OCP_NO_BASE,
                         .node_count = s2.node_count, .brick_count = s2.brick_count, .bricks_sent = s2.brick_count};
  ocp_put_epoch_begin(b, g_version, &m);
  put_good(b);
  oc_state_free(&s2);
}

static void test_viewer__budget_refused(void **state) {
  (void)state;
  expect_budget_refused(3, OCP_ROLE_VIEWER, put_short, OCP_CODE_MALFORMED, "budget: payload is 12 bytes, expected 16");
  expect_budget_refused(3, OCP_ROLE_VIEWER, put_zero, OCP_CODE_MALFORMED, "budget: budget is 0");
  expect_budget_refused(3, OCP_ROLE_VIEWER, put_small, OCP_CODE_MALFORMED, "below the minimum 6240 (K = 3)");
  expect_budget_refused(3, OCP_ROLE_VIEWER, put_stale, OCP_CODE_MALFORMED, "effective epoch 42 is not after the newest state's 42");
  expect_budget_refused(3, OCP_ROLE_VIEWER, put_mid_epoch, OCP_CODE_UNEXPECTED, "budget: not valid inside an epoch");
  expect_budget_refused(3, OCP_ROLE_CONTROL, put_good, OCP_CODE_UNEXPECTED, "budget: not valid for a control client");
  /* versions 1 and 2 have no BUDGET: a server must never send it there */
  expect_budget_refused(1, OCP_ROLE_VIEWER, put_good, OCP_CODE_UNEXPECTED, "budget: not in protocol version 1");
  expect_budget_refused(2, OCP_ROLE_VIEWER, put_good, OCP_CODE_UNEXPECTED, "budget: not in protocol version 2");
}

static void test_viewer__control(void **state) {
  (void)state;
  rig_t x;
  rig_open(&x, OCP_ROLE_CONTROL);
  assert_int_equal(ocp_viewer_control(x.v, 1, "{\"op\": \"pause\"}", &x.out), OC_EINVAL); /* before WELCOME */
  ocp_viewer_connected(x.v, &x.out);
  ocp_hello_t h = hello_of(&x.out);
  assert_int_equal(h.role, OCP_ROLE_CONTROL);
  assert_int_equal(h.budget, 0);
  assert_int_equal(h.width, 0);
  put_welcome(&x.in, 0, 0, SESSION, 0);
  assert_int_equal(rig_feed(&x), 0);
  assert_true(ocp_viewer_ready(x.v));
  x.out.len = 0;
  assert_int_equal(ocp_viewer_control(x.v, 7, "{\"op\": \"pause\"}", &x.out), 0);
  frames_t f = parse_out(&x.out);
  assert_int_equal(f.n, 1);
  assert_int_equal(f.h[0].type, OCP_MSG_CONTROL);
  ocp_control_t c;
  assert_int_equal(ocp_get_control(f.p[0], f.h[0].length, &c, x.why, sizeof x.why), 0);
  assert_int_equal(c.request, 7);
  assert_int_equal(c.status, 0);
  assert_memory_equal(c.json, "{\"op\": \"pause\"}", c.json_len);
  ocp_camera_t cam = {oc_dv3(0, 0, 1), oc_dv3(1, 0, 0), oc_dv3(0, 1, 0), 60, 1, 1};
  assert_int_equal(ocp_viewer_camera(x.v, &cam, &x.out), OC_EINVAL);
  x.in.len = 0;
  ocp_control_t rep = {7, 0, "{\"ok\": true}", 12};
  ocp_put_control(&x.in, 1, OCP_MSG_CONTROL_REPLY, &rep);
  assert_int_equal(rig_feed(&x), 0);
  assert_int_equal(x.ev.replies, 1);
  assert_int_equal(x.ev.reply_request, 7);
  assert_string_equal(x.ev.reply, "{\"ok\": true}");
  /* epochs are not for control clients */
  x.in.len = 0;
  oc_state_t s1;
  put_golden_epoch(&x.in, &s1);
  assert_int_equal(rig_feed(&x), OC_ECORRUPT);
  expect_error_frame(&x.out, OCP_CODE_UNEXPECTED);
  /* a viewer never takes a control reply, nor a control client a viewer's grant */
  ocp_viewer_free(x.v);
  x.v = make_viewer(&x.ev, OCP_ROLE_VIEWER);
  handshake(x.v, 2, &x.out);
  assert_int_equal(ocp_viewer_control(x.v, 1, "{}", &x.out), OC_EINVAL);
  assert_int_equal(rig_feed(&x), 0); /* the epoch above is fine here */
  x.in.len = 0;
  ocp_put_control(&x.in, 1, OCP_MSG_CONTROL_REPLY, &rep);
  assert_int_equal(rig_feed(&x), OC_ECORRUPT);
  expect_error_frame(&x.out, OCP_CODE_UNEXPECTED);
  ocp_viewer_free(x.v);
  x.v = make_viewer(&x.ev, OCP_ROLE_CONTROL);
  x.out.len = 0;
  ocp_viewer_connected(x.v, &x.out);
  x.in.len = 0;
  put_welcome(&x.in, 3, 0, SESSION, 1u << 20);
  assert_int_equal(rig_feed(&x), OC_ECORRUPT);
  assert_non_null(strstr(x.why, "kept_states 3 for a control client"));
  oc_state_free(&s1);
  rig_close(&x);
}

static void test_viewer__create_rejects(void **state) {
  (void)state;
  ocp_viewer_t *v = NULL;
  ocp_viewer_desc_t d;
  memset(&d, 0, sizeof d);
  d.budget = 1000, d.width = 1, d.height = 1;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), 0);
  ocp_viewer_free(v);
  d.budget = 0;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.budget = 1000, d.width = 0;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.width = 1, d.max_depth = 22;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.max_depth = 0, d.role = 2;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.role = 0, d.caps = 0x10;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.caps = 0;
  char tok[300];
  memset(tok, 't', sizeof tok - 1);
  tok[sizeof tok - 1] = '\0';
  d.token = tok;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  assert_null(v);
  ocp_viewer_free(NULL);
}

/*-*** Lean sessions (OCP_CAP_DIGEST) ***/

/* 8³ leaves at level 3: three in four are bricks (ids 1..), the rest uniform. */
static void big_state(oc_state_t *s) {
  state_begin(s, 100, 5.0, oc_dv3(0.0, 0.6, 0.8));
  uint32_t id = 1;
  for (int i = 0; i < 512; i++) {
    oc_key_t k = child(child(child(OC_KEY_ROOT, i / 64), (i / 8) % 8), i % 8);
    oc_node_t n = i % 4 == 3 ? node(k, OC_NODE_UNIFORM, 0, 0.02f, 0.02f, 1.0f, 1.0f)
                             : node(k, OC_NODE_BRICK, id++, 0.01f, 0.5f, i % 4 == 2 ? 0.0f : 0.25f, i % 4 == 2 ? 0.0f : 2.0f);
    oc_state_add_node(s, &n);
    if (n.kind == OC_NODE_BRICK) {
      oc_brick_codes_t c;
      golden_codes(n.brick_id, &c);
      if (n.range[1].hi == 0.0f) memset(c.code[1], 0, sizeof c.code[1]);
      oc_state_add_brick(s, n.brick_id, &c);
    }
  }
  oc_state_canonicalize(s);
}

/* The next epoch of big_state: one brick in eight refreshed as a new id (same ranges: a delta for a
 * full viewer); record 0's brick leaves on odd steps and comes back, with its old id, on even ones
 * (the viewer still holds it in its older state, so it is not sent). */
static void big_next(const oc_state_t *prev, const oc_state_t *first, oc_state_t *next, int step) {
  oc_state_init(next);
  assert_int_equal(oc_state_copy(next, prev), 0);
  next->epoch = prev->epoch + 1;
  next->time = prev->time + 1.0;
  oc_state_t tmp;
  oc_state_init(&tmp);
  tmp.epoch = next->epoch, tmp.time = next->time, tmp.sun_dir = next->sun_dir;
  for (uint32_t i = 0; i < next->node_count; i++) {
    oc_node_t n = next->nodes[i];
    const oc_brick_t *b = n.kind == OC_NODE_BRICK ? oc_state_find_brick(prev, n.brick_id) : NULL;
    if (i == 0) {
      n = first->nodes[0];
      if (step % 2) n = node(n.key, OC_NODE_UNIFORM, 0, 0.03f, 0.03f, 1.0f, 1.0f);
      b = n.kind == OC_NODE_BRICK ? oc_state_find_brick(first, n.brick_id) : NULL;
    } else if (b && i % 8 == (uint32_t)step % 8) {
      oc_brick_codes_t c = b->codes;
      for (int ch = 0; ch < OC_CHANNELS; ch++)
        if (n.range[ch].hi != 0.0f)
          for (int v = 0; v < OC_BRICK_VOXELS; v += 5) c.code[ch][v] = (uint16_t)(c.code[ch][v] + 7u * (uint32_t)step);
      n.brick_id = 10000u * (uint32_t)step + i;
      assert_int_equal(oc_state_add_brick(&tmp, n.brick_id, &c), 0);
      b = NULL;
    }
    assert_int_equal(oc_state_add_node(&tmp, &n), 0);
    if (b) assert_int_equal(oc_state_add_brick(&tmp, b->id, &b->codes), 0);
  }
  oc_state_free(next);
  *next = tmp;
  oc_state_canonicalize(next);
  char why[256];
  if (oc_state_validate(next, why, sizeof why)) fail_msg("big_next: %s", why);
}

/* One epoch as the server sends it to a full (deltas) or lean (digest checksum) session. */
static void put_epoch_as(oc_buf_t *b, int lean, const oc_state_t *s, const oc_state_t *base, const uint32_t *lacking, uint32_t n) {
  ocp_epoch_enc_t *e;
  ocp_enc_desc_t d;
  memset(&d, 0, sizeof d);
  d.deltas = !lean;
  d.digest = lean;
  assert_int_equal(ocp_epoch_enc_create(&e, &d), 0);
  assert_int_equal(ocp_epoch_enc_begin(e, s, base, lacking, n), 0);
  while (ocp_epoch_enc_next(e, 1, b) == 1) {
  }
  ocp_epoch_enc_free(e);
  ocp_put_stats(b, 1, &(ocp_stats_t){.epoch = s->epoch});
}

/* Ids of s not in held[0..n) (what the server sends), ascending; *m of them. */
static uint32_t *lacking_of(const oc_state_t *s, const oc_state_t *const *held, int n, uint32_t *m) {
  uint32_t *ids = malloc(sizeof *ids * (s->brick_count + 1));
  assert_non_null(ids);
  *m = 0;
  for (uint32_t i = 0; i < s->brick_count; i++) {
    int have = 0;
    for (int k = 0; k < n && !have; k++) have = held[k] && oc_state_find_brick(held[k], s->bricks[i].id) != NULL;
    if (!have) ids[(*m)++] = s->bricks[i].id;
  }
  return ids;
}

static ocp_viewer_t *make_lean_viewer(events_t *ev) {
  memset(ev, 0, sizeof *ev);
  ocp_viewer_desc_t d;
  memset(&d, 0, sizeof d);
  d.role = OCP_ROLE_VIEWER;
  d.budget = 1u << 20;
  d.max_depth = 12;
  d.width = 640, d.height = 480;
  d.caps = OCP_CAP_DICT;
  d.lean = 1;
  ocp_viewer_events_t cb = {ev, on_welcome, on_state, on_stats, on_reply, on_closed, on_budget};
  ocp_viewer_t *v = NULL;
  assert_int_equal(ocp_viewer_create(&v, &d, &cb), 0);
  return v;
}

/* A lean session holds state i as s's records and the digests of s's bricks. */
static void expect_lean_state(ocp_viewer_t *v, int i, const oc_state_t *s) {
  const oc_state_t *h = ocp_viewer_state(v, i);
  const oc_brick_digests_t *d = ocp_viewer_digests(v, i);
  assert_non_null(h);
  assert_non_null(d);
  expect_lean_equal(s, h, d);
}

/* A lean and a full session take the same states (kept, refreshed and returning bricks, a resume in
 * the middle of an epoch): both verify and acknowledge every one, count the same resident bytes,
 * and the lean one holds a small fraction of the full one's memory. */
static void test_viewer__lean_matches_full(void **state) {
  (void)state;
  enum { EPOCHS = 6, CUT = 4 };
  events_t ev[2];
  ocp_viewer_t *v[2] = {make_viewer(&ev[0], OCP_ROLE_VIEWER), make_lean_viewer(&ev[1])};
  oc_buf_t out = {0}, in = {0};
  char why[256];
  oc_state_t s[EPOCHS];
  big_state(&s[0]);
  for (int i = 1; i < EPOCHS; i++) big_next(&s[i - 1], &s[0], &s[i], i);
  assert_true(s[0].brick_count >= 384);
  for (int k = 0; k < 2; k++) { /* a grant the three kept states fit in */
    out.len = 0;
    ocp_viewer_connected(v[k], &out);
    put_welcome(&in, 3, 0, SESSION, 8u << 20);
    if (feed(v[k], &in, &out, why, sizeof why)) fail_msg("%s", why);
    in.len = 0;
  }
  uint64_t sent_total = 0;
  for (int i = 0; i < EPOCHS; i++) {
    /* the server knows the viewer holds the two states before this one (K = 3) */
    const oc_state_t *held[2] = {i >= 1 ? &s[i - 1] : NULL, i >= 2 ? &s[i - 2] : NULL};
    uint32_t n, *lack = lacking_of(&s[i], held, 2, &n);
    if (i % 2 == 0 && i > 0) { /* record 0's brick is back: held in the older state only, so not sent */
      uint32_t back = s[i].nodes[0].brick_id;
      assert_null(oc_state_find_brick(&s[i - 1], back));
      assert_non_null(oc_state_find_brick(&s[i - 2], back));
      for (uint32_t k = 0; k < n; k++) assert_int_not_equal(lack[k], back);
    }
    sent_total += n;
    uint64_t resident[2];
    for (int k = 0; k < 2; k++) {
      in.len = 0;
      put_epoch_as(&in, k, &s[i], held[0], lack, n);
      if (i == CUT) { /* the connection drops halfway through this epoch; the session resumes */
        oc_buf_t half = {0};
        oc_buf_append(&half, in.data, in.len / 2);
        if (feed(v[k], &half, &out, why, sizeof why)) fail_msg("%s", why);
        oc_buf_free(&half);
        out.len = 0;
        ocp_viewer_connected(v[k], &out);
        ocp_hello_t h = hello_of(&out);
        assert_int_equal(h.caps, k ? (OCP_CAP_DIGEST | OCP_CAP_DICT) : OCP_CAP_ALL);
        assert_int_equal(h.resume_session, SESSION);
        assert_int_equal(h.held_epoch, s[i - 1].epoch);
        assert_true(h.held_checksum == (k ? oc_state_digest(&s[i - 1]) : oc_state_checksum(&s[i - 1])));
        oc_buf_t w = {0};
        put_welcome(&w, 3, 1, SESSION, 8u << 20);
        if (feed(v[k], &w, &out, why, sizeof why)) fail_msg("%s", why);
        assert_int_equal(ev[k].last_resumed, 1);
        oc_buf_free(&w);
      }
      if (feed(v[k], &in, &out, why, sizeof why)) fail_msg("%s session, epoch %d: %s", k ? "lean" : "full", i, why);
      assert_int_equal(ev[k].states, i + 1);
      ocp_ack_t a = ack_of(&out);
      assert_int_equal(a.epoch, s[i].epoch);
      assert_true(a.checksum == (k ? oc_state_digest(&s[i]) : oc_state_checksum(&s[i])));
      for (int j = 0; j <= i && j < 2; j++) {
        if (k)
          expect_lean_state(v[k], j, &s[i - j]);
        else
          states_equal(ocp_viewer_state(v[k], j), &s[i - j]);
      }
      assert_null(ocp_viewer_digests(v[0], 0));
      ocp_viewer_stats_t st;
      ocp_viewer_stats(v[k], &st);
      resident[k] = st.resident_bytes;
      assert_int_equal(st.over_budget, 0);
    }
    const oc_state_t *window[3] = {&s[i], held[0], held[1]};
    assert_int_equal(resident[0], oc_resident_bytes(window, i < 2 ? i + 1 : 3, 2048, 32));
    assert_int_equal(resident[1], resident[0]);
    free(lack);
  }
  ocp_viewer_stats_t fs, ls;
  ocp_viewer_stats(v[0], &fs);
  ocp_viewer_stats(v[1], &ls);
  assert_int_equal(fs.states, EPOCHS);
  assert_int_equal(ls.states, EPOCHS);
  assert_int_equal(ls.bricks_in, sent_total);
  assert_int_equal(ls.bricks_in, fs.bricks_in);
  assert_int_equal(ls.resident_peak, fs.resident_peak);
  assert_int_equal(ls.resumed, 1);
  /* held bytes: exactly the kept arrays; 12 bytes a brick instead of a whole oc_brick_t */
  const oc_state_t *last = &s[EPOCHS - 1], *prev = &s[EPOCHS - 2];
  uint64_t recs = ((uint64_t)last->node_count + prev->node_count) * sizeof(oc_node_t);
  uint64_t bricks = (uint64_t)last->brick_count + prev->brick_count;
  assert_int_equal(fs.held_bytes, recs + bricks * sizeof(oc_brick_t));
  assert_int_equal(ls.held_bytes, recs + bricks * 12u);
  print_message("held bytes for %llu kept bricks and %u + %u records: full %llu, lean %llu (%.1fx less); resident %llu both\n",
                (unsigned long long)bricks, last->node_count, prev->node_count, (unsigned long long)fs.held_bytes,
                (unsigned long long)ls.held_bytes, (double)fs.held_bytes / (double)ls.held_bytes,
                (unsigned long long)ls.resident_bytes);
  assert_true(ls.held_bytes * 20 < fs.held_bytes);
  for (int i = 0; i < EPOCHS; i++) oc_state_free(&s[i]);
  oc_buf_free(&in);
  oc_buf_free(&out);
  for (int k = 0; k < 2; k++) ocp_viewer_free(v[k]);
}

/* A lean session still catches what a full one does: a flipped bit in a brick it received, a held
 * brick the server has otherwise (a wrong held digest), and a delta it cannot apply. */
static void test_viewer__lean_detects(void **state) {
  (void)state;
  events_t ev;
  oc_buf_t out = {0}, in = {0}, first = {0};
  char why[256];
  oc_state_t s0, s1;
  golden_state(&s0);
  evolve(&s0, &s1, 43);
  uint32_t ids[8], lack[] = {43};
  put_epoch_as(&first, 1, &s0, NULL, ids, all_bricks(&s0, ids));
  for (int c = 0; c < 3; c++) {
    ocp_viewer_t *v = make_lean_viewer(&ev);
    handshake(v, 3, &out);
    if (feed(v, &first, &out, why, sizeof why)) fail_msg("%s", why);
    assert_int_equal(ack_of(&out).checksum, oc_state_digest(&s0));
    oc_state_t bad;
    oc_state_init(&bad);
    assert_int_equal(oc_state_copy(&bad, &s1), 0);
    in.len = 0;
    if (c == 0) { /* brick 43 as sent has one bit flipped; EPOCH_END is the honest state's */
      ((oc_brick_t *)oc_state_find_brick(&bad, 43))->codes.code[0][200] ^= 0x0020;
      put_epoch_as(&in, 1, &bad, &s0, lack, 1);
      size_t at = find_frame(&in, OCP_MSG_EPOCH_END, 0);
      oc_put_u64(in.data + at + OCP_HEADER_BYTES + 8, oc_state_digest(&s1));
    } else if (c == 1) { /* the server's brick 7 differs from the one the viewer holds */
      ((oc_brick_t *)oc_state_find_brick(&bad, 7))->codes.code[1][3] ^= 0x0001;
      put_epoch_as(&in, 1, &bad, &s0, lack, 1);
    } else { /* a delta, as for a full viewer */
      put_epoch_as(&in, 0, &s1, &s0, lack, 1);
    }
    int e = feed(v, &in, &out, why, sizeof why);
    if (c < 2) {
      assert_int_equal(e, OC_ECHECKSUM);
      assert_non_null(strstr(why, "digest checksum mismatch"));
      expect_error_frame(&out, OCP_CODE_CHECKSUM);
    } else {
      assert_int_equal(e, OC_ECORRUPT);
      assert_non_null(strstr(why, "to a lean viewer"));
      expect_error_frame(&out, OCP_CODE_MALFORMED);
    }
    assert_int_equal(ev.states, 1);
    expect_lean_state(v, 0, &s0); /* what it held is untouched */
    oc_state_free(&bad);
    ocp_viewer_free(v);
  }
  /* the honest epoch is accepted */
  ocp_viewer_t *v = make_lean_viewer(&ev);
  handshake(v, 3, &out);
  in.len = 0;
  oc_buf_append(&in, first.data, first.len);
  put_epoch_as(&in, 1, &s1, &s0, lack, 1);
  if (feed(v, &in, &out, why, sizeof why)) fail_msg("%s", why);
  assert_int_equal(ev.states, 2);
  expect_lean_state(v, 0, &s1);
  expect_lean_state(v, 1, &s0);
  ocp_viewer_free(v);
  /* lean and DIGEST are one choice, and exclude DELTA */
  ocp_viewer_desc_t d;
  memset(&d, 0, sizeof d);
  d.budget = 1000, d.width = 1, d.height = 1;
  d.lean = 1, d.caps = OCP_CAP_ALL;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.lean = 0, d.caps = OCP_CAP_DIGEST | OCP_CAP_DELTA;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), OC_EINVAL);
  d.caps = OCP_CAP_DIGEST;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), 0);
  out.len = 0;
  ocp_viewer_connected(v, &out);
  assert_int_equal(hello_of(&out).caps, OCP_CAP_DIGEST);
  ocp_viewer_free(v);
  d.caps = 0, d.lean = 1;
  assert_int_equal(ocp_viewer_create(&v, &d, NULL), 0);
  out.len = 0;
  ocp_viewer_connected(v, &out);
  assert_int_equal(hello_of(&out).caps, OCP_CAP_DIGEST);
  ocp_viewer_free(v);
  oc_state_free(&s0);
  oc_state_free(&s1);
  oc_buf_free(&in);
  oc_buf_free(&out);
  oc_buf_free(&first);
}

/*-*** Fuzz seeds ***/

/* 64 brick leaves (root split twice), enough samples to train a dictionary. */
static void many_bricks_state(oc_state_t *s) {
  state_begin(s, 5, 10.0, oc_dv3(1.0, 0.0, 0.0));
  for (int i = 0; i < 64; i++) {
    oc_brick_codes_t c;
    oc_node_t n = node(child(child(OC_KEY_ROOT, i / 8), i % 8), OC_NODE_BRICK, (uint32_t)(1 + i), 0.5f, 1.0f, 0.0f, 0.0f);
    for (int v = 0; v < OC_BRICK_VOXELS; v++) c.code[0][v] = (uint16_t)(((v & 7) + (v >> 6)) * 1000u + (uint32_t)i);
    memset(c.code[1], 0, sizeof c.code[1]);
    oc_state_add_node(s, &n);
    oc_state_add_brick(s, n.brick_id, &c);
  }
  oc_state_canonicalize(s);
  char why[256];
  if (oc_state_validate(s, why, sizeof why)) fail_msg("many-bricks state: %s", why);
}

/* Seeds for tests/fuzz/fuzz_wire.c: what a server sends after WELCOME (the target supplies that),
 * plus the clients' messages for the decoders. */
static void build_seed(int i, oc_buf_t *b, int *viewer_ok, int *control_ok, int *lean_ok) {
  oc_state_t s1, s2;
  uint32_t ids[64];
  *viewer_ok = *control_ok = *lean_ok = 0;
  switch (i) {
    case 0: /* two epochs: all records and bricks, then a difference with a delta brick */
      golden_state(&s1);
      evolve(&s1, &s2, 43);
      put_epoch(b, &s1, NULL, ids, all_bricks(&s1, ids));
      ocp_put_empty(b, 1, OCP_MSG_KEEPALIVE);
      uint32_t lack[] = {43};
      put_epoch(b, &s2, &s1, lack, 1);
      oc_state_free(&s1);
      oc_state_free(&s2);
      *viewer_ok = 1;
      break;
    case 1: { /* a dictionary, then an epoch whose bricks use it */
      many_bricks_state(&s1);
      const oc_brick_codes_t *codes[64];
      for (uint32_t k = 0; k < s1.brick_count; k++) codes[k] = &s1.bricks[k].codes;
      oc_buf_t dict = {0};
      assert_int_equal(ocp_dict_train(codes, s1.brick_count, 2048, &dict), 0);
      ocp_put_dict(b, 1, 5, dict.data, dict.len);
      ocp_epoch_enc_t *e;
      ocp_enc_desc_t d;
      memset(&d, 0, sizeof d);
      d.dict_id = 5, d.dict = dict.data, d.dict_len = dict.len, d.batch_max = 32;
      assert_int_equal(ocp_epoch_enc_create(&e, &d), 0);
      assert_int_equal(ocp_epoch_enc_begin(e, &s1, NULL, ids, all_bricks(&s1, ids)), 0);
      while (ocp_epoch_enc_next(e, 1, b) == 1) {
      }
      ocp_epoch_enc_free(e);
      oc_buf_free(&dict);
      oc_state_free(&s1);
      *viewer_ok = 1;
      break;
    }
    case 2: { /* a control client's conversation */
      ocp_control_t rep = {3, 0, "{\"ok\": true, \"sessions\": []}", 28};
      ocp_put_control(b, 1, OCP_MSG_CONTROL_REPLY, &rep);
      ocp_put_empty(b, 1, OCP_MSG_KEEPALIVE);
      ocp_put_text(b, 1, OCP_MSG_GOODBYE, OCP_CODE_RELOAD, "scene reloaded");
      *control_ok = 1;
      break;
    }
    case 3: { /* every client message, for the decoders */
      ocp_hello_t h;
      memset(&h, 0, sizeof h);
      h.min_version = h.max_version = 1;
      h.max_depth = 10, h.budget = 1u << 24, h.slot_bytes = 2048, h.record_bytes = 32, h.width = 64, h.height = 48;
      h.caps = OCP_CAP_ALL, h.token_len = 3;
      memcpy(h.token, "abc", 3);
      ocp_put_hello(b, &h);
      ocp_put_camera(b, 1, &(ocp_camera_t){oc_dv3(0, 0, 6.4e6), oc_dv3(1, 0, 0), oc_dv3(0, 0, 1), 60, 64, 48});
      ocp_put_ack(b, 1, &(ocp_ack_t){42, 0xc9d949fa8e9ec21bull});
      ocp_control_t req = {1, 0, "{\"op\": \"step\", \"epochs\": 2}", 27};
      ocp_put_control(b, 1, OCP_MSG_CONTROL, &req);
      ocp_put_text(b, 1, OCP_MSG_ERROR, OCP_CODE_CHECKSUM, "state epoch 42: checksum mismatch");
      break;
    }
    case 5: { /* two epochs for a lean viewer: digest checksums, the refreshed brick whole */
      golden_state(&s1);
      evolve(&s1, &s2, 43);
      put_epoch_as(b, 1, &s1, NULL, ids, all_bricks(&s1, ids));
      uint32_t lack[] = {43};
      put_epoch_as(b, 1, &s2, &s1, lack, 1);
      oc_state_free(&s1);
      oc_state_free(&s2);
      *lean_ok = 1;
      break;
    }
    case 6: /* version 3: an epoch, BUDGET lowering from the next, two more epochs (it takes effect) */
      golden_state(&s1);
      evolve(&s1, &s2, 43);
      put_epoch(b, &s1, NULL, ids, all_bricks(&s1, ids));
      put_budget(b, 1u << 19, 43);
      {
        uint32_t lack[] = {43};
        put_epoch(b, &s2, &s1, lack, 1);
        oc_state_t s3;
        evolve(&s2, &s3, 44);
        lack[0] = 44;
        put_epoch(b, &s3, &s2, lack, 1);
        oc_state_free(&s3);
      }
      oc_state_free(&s1);
      oc_state_free(&s2);
      *viewer_ok = 1; /* full checksums: not a lean viewer's */
      break;
    case 7: /* version 3: a BUDGET four bytes short, for the decoder and the viewer's refusal */
      put_short(b);
      break;
    case 4: { /* a WELCOME and STATS, then the server's error */
      put_welcome(b, 3, 0, SESSION, 1u << 20);
      ocp_stats_t st;
      memset(&st, 0, sizeof st);
      st.epoch = 9, st.leaves = 15, st.plan_ms = 0.5, st.produce_ms = 2.0;
      ocp_put_stats(b, 1, &st);
      ocp_put_text(b, 1, OCP_MSG_ERROR, OCP_CODE_SLOW, "send queue over its hard limit");
      break;
    }
  }
}

/* A viewer (lean or not) or control client after WELCOME takes the whole seed without error. */
static int seed_accepted(const uint8_t *p, size_t n, int role, int lean) {
  events_t ev;
  ocp_viewer_t *v = lean ? make_lean_viewer(&ev) : make_viewer(&ev, role);
  oc_buf_t out = {0}, in = {0};
  char why[256];
  ocp_viewer_connected(v, &out);
  put_welcome(&in, role == OCP_ROLE_VIEWER ? 3 : 0, 0, SESSION, role == OCP_ROLE_VIEWER ? 1u << 20 : 0);
  int e = feed(v, &in, &out, why, sizeof why);
  if (e == 0) e = ocp_viewer_feed(v, p, n, &out, why, sizeof why);
  oc_buf_free(&in);
  oc_buf_free(&out);
  ocp_viewer_free(v);
  return e == 0;
}

static void test_viewer__fuzz_seeds(void **state) {
  (void)state;
  static const char *names[] = {"epochs.bin",      "dict_epoch.bin",    "control.bin",     "client_msgs.bin",
                                "welcome_error.bin", "lean_epochs.bin", "budget_v3.bin", "budget_short_v3.bin"};
  const char *out = getenv("OC_FUZZ_WIRE_CORPUS_OUT"), *src = getenv("OC_SOURCE_DIR");
  char path[1024];
  for (int i = 0; i < 8; i++) {
    g_version = i >= 6 ? OCP_VERSION_BUDGET : 1; /* the BUDGET seeds speak version 3 */
    oc_buf_t b = {0};
    int viewer_ok, control_ok, lean_ok;
    build_seed(i, &b, &viewer_ok, &control_ok, &lean_ok);
    assert_false(b.err);
    assert_true(b.len < 16384); /* seeds stay small */
    assert_int_equal(seed_accepted(b.data, b.len, OCP_ROLE_VIEWER, 0), viewer_ok);
    assert_int_equal(seed_accepted(b.data, b.len, OCP_ROLE_CONTROL, 0), control_ok);
    assert_int_equal(seed_accepted(b.data, b.len, OCP_ROLE_VIEWER, 1), lean_ok);
    if (out) {
      snprintf(path, sizeof path, "%s/%s", out, names[i]);
      FILE *f = fopen(path, "wb");
      assert_non_null(f);
      assert_int_equal(fwrite(b.data, 1, b.len, f), b.len);
      fclose(f);
    }
    if (src) { /* the committed seeds are still what a viewer accepts (zstd's bytes may differ) */
      snprintf(path, sizeof path, "%s/tests/fuzz/corpus/wire/%s", src, names[i]);
      FILE *f = fopen(path, "rb");
      if (!f) fail_msg("missing seed %s", path);
      uint8_t *buf = malloc(65536);
      size_t n = fread(buf, 1, 65536, f);
      fclose(f);
      assert_int_equal(seed_accepted(buf, n, OCP_ROLE_VIEWER, 0), viewer_ok);
      assert_int_equal(seed_accepted(buf, n, OCP_ROLE_CONTROL, 0), control_ok);
      assert_int_equal(seed_accepted(buf, n, OCP_ROLE_VIEWER, 1), lean_ok);
      free(buf);
    }
    oc_buf_free(&b);
  }
  g_version = 1;
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_viewer__hello_and_welcome),
             cmocka_unit_test(test_viewer__epochs_and_acks),
             cmocka_unit_test(test_viewer__kept_states),
             cmocka_unit_test(test_viewer__resume),
             cmocka_unit_test(test_viewer__corrupt_bricks),
             cmocka_unit_test(test_viewer__unexpected),
             cmocka_unit_test(test_viewer__byte_at_a_time),
             cmocka_unit_test(test_viewer__over_budget_and_close),
             cmocka_unit_test(test_viewer__control),
             cmocka_unit_test(test_viewer__budget_lowered_then_raised),
             cmocka_unit_test(test_viewer__budget_refused),
             cmocka_unit_test(test_viewer__create_rejects),
             cmocka_unit_test(test_viewer__lean_matches_full),
             cmocka_unit_test(test_viewer__lean_detects),
             cmocka_unit_test(test_viewer__fuzz_seeds))
