/* test_wire.c — frames and messages of the wire protocol (proto/ocp_wire.c; docs/protocol.md,
 * "Wire"): round trips of every message, golden bytes written out by hand from the spec, exact
 * lengths, reserved bytes, field ranges, and the frame reader's splitting and limits. */
#include <math.h>
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
#include "ocp_wire.h"

/*-*** Helpers ***/

/* The single frame in b: header checked, payload returned. */
static const uint8_t *only_frame(const oc_buf_t *b, ocp_header_t *h) {
  assert_false(b->err);
  assert_true(b->len >= OCP_HEADER_BYTES);
  assert_int_equal(ocp_header_parse(b->data, OCP_MAX_PAYLOAD, h), 0);
  assert_int_equal(b->len, OCP_HEADER_BYTES + (size_t)h->length);
  return b->data + OCP_HEADER_BYTES;
}

/* Any message's decoder by type (STATS as version 1); the decoded value is discarded. */
static int decode_any(uint8_t type, const uint8_t *p, size_t n, char *why, size_t why_len) {
  ocp_msg_t m;
  int e = ocp_get_msg(1, type, p, n, &m, why, why_len);
  if (e == 1) fail_msg("no decoder for type 0x%02x", type);
  return e;
}

/* Decodes the payload from an exact-size copy, so ASan sees any over-read. */
static int decode_copy(uint8_t type, const uint8_t *p, size_t n, char *why, size_t why_len) {
  uint8_t *c = malloc(n ? n : 1);
  assert_non_null(c);
  if (n) memcpy(c, p, n);
  int e = decode_any(type, c, n, why, why_len);
  free(c);
  return e;
}

/* The frame in b decodes; with one byte less or one zero byte more it does not. */
static void expect_exact_length(const oc_buf_t *b) {
  ocp_header_t h;
  char why[256];
  const uint8_t *p = only_frame(b, &h);
  int e = decode_copy(h.type, p, h.length, why, sizeof why);
  if (e) fail_msg("%s: valid payload rejected: %s", ocp_msg_name(h.type), why);
  if (h.length > 0) {
    assert_int_equal(decode_copy(h.type, p, h.length - 1, why, sizeof why), OC_ECORRUPT);
    if (!strstr(why, ocp_msg_name(h.type))) fail_msg("reason '%s' does not name the message", why);
  }
  uint8_t *longer = calloc(1, h.length + 1u);
  memcpy(longer, p, h.length);
  assert_int_equal(decode_copy(h.type, longer, h.length + 1u, why, sizeof why), OC_ECORRUPT);
  free(longer);
}

static void expect_reject(int e, const char *why, const char *needle) {
  if (e != OC_ECORRUPT) fail_msg("expected ECORRUPT (%s), got %d", needle, e);
  if (!strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);
}

/* Sample messages, every field set (static: the padding is zero too, so decoded copies compare
 * equal byte for byte). */
static const ocp_hello_t sample_hello = {
    .min_version = 1,
    .max_version = 1,
    .role = OCP_ROLE_VIEWER,
    .max_depth = 12,
    .budget = 0x0102030405060708ull,
    .slot_bytes = 2048,
    .record_bytes = 32,
    .width = 1920,
    .height = 1080,
    .caps = OCP_CAP_ALL,
    .resume_session = 0x11223344u,
    .resume_secret = 0xAABBCCDDEEFF0011ull,
    .held_epoch = 5,
    .held_checksum = 0xc9d949fa8e9ec21bull,
    .token_len = 2,
    .token = {'a', 'b'},
};

static const ocp_welcome_t sample_welcome = {
    .version = 1,
    .flags = OCP_WELCOME_RESUMED,
    .kept_states = 3,
    .session = 77,
    .secret = 0x123456789ABCDEF0ull,
    .budget = 64u << 20,
    .slot_bytes = 2048,
    .record_bytes = 32,
    .max_depth = 14,
    .features = 0x1Fu,
    .epoch_period = 1.0,
    .planet_radius = 6371000.0,
    .time = 3600.25,
    .sun_dir = {0.0, 0.6, 0.8},
    .albedo = 0.99,
    .ms_a = 0.5, .ms_b = 0.45, .ms_c = 0.3,
    .ms_octaves = 4,
    .cam_lat = 47.5, .cam_lon = 8.25, .cam_alt = 1500.0,
    .cam_heading = 90.0, .cam_pitch = 5.0, .cam_fov = 60.0,
    .name = "fair-weather cumulus",
};

static const ocp_camera_t sample_camera = {
    .pos = {1.0, -2.0, 0.5},
    .forward = {0.0, 0.0, -1.0},
    .up = {0.0, 1.0, 0.0},
    .vfov_deg = 60.0,
    .width = 800,
    .height = 600,
};

static const ocp_epoch_begin_t sample_begin = {
    .epoch = 43,
    .time = 1235.5,
    .sun_dir = {0.0, 0.6, 0.8},
    .base_epoch = 42,
    .node_count = 15,
    .brick_count = 3,
    .bricks_sent = 1,
};

static const ocp_stats_t sample_stats = {
    .epoch = 43,
    .leaves = 15, .splits = 2, .merges = 1, .deferred = 4,
    .coalesced = 3,
    .resident_bytes = 123456,
    .wire_bytes = 4567,
    .raw_bytes = 98765,
    .plan_ms = 1.25,
    .produce_ms = 12.5,
};

/* The sample of `type` in a message cleared first (its padding compares too). */
static ocp_msg_t sample_of(uint8_t type) {
  ocp_msg_t m;
  memset(&m, 0, sizeof m);
  switch (type) {
    case OCP_MSG_HELLO: m.hello = sample_hello; break;
    case OCP_MSG_WELCOME: m.welcome = sample_welcome; break;
    case OCP_MSG_CAMERA: m.camera = sample_camera; break;
    case OCP_MSG_EPOCH_BEGIN: m.begin = sample_begin; break;
    case OCP_MSG_STATS: m.stats = sample_stats; break;
    default: fail_msg("no sample of type 0x%02x", type);
  }
  return m;
}

/*-*** Names, codes, versions ***/

static void test_wire__names_and_codes(void **state) {
  (void)state;
  assert_string_equal(ocp_msg_name(OCP_MSG_HELLO), "hello");
  assert_string_equal(ocp_msg_name(0x84), "bricks");
  assert_string_equal(ocp_msg_name(OCP_MSG_DICT), "dictionary");
  assert_null(ocp_msg_name(0x00));
  assert_null(ocp_msg_name(0x05));
  assert_null(ocp_msg_name(0xFF));
  assert_null(ocp_msg_name(-1));
  assert_string_equal(ocp_code_text(OCP_CODE_CHECKSUM), "state checksum mismatch");
  assert_string_equal(ocp_code_text(15), "message not valid in this state");
  assert_string_equal(ocp_code_text(OCP_CODE_RECONNECT), "the server is draining: reconnect");
  assert_string_equal(ocp_code_text(17), "unknown code");
  /* GOODBYE RECONNECT's delay: leading digits, then " ms" (docs/protocol.md) */
  assert_int_equal(ocp_reconnect_delay_ms("1000 ms: the server is draining"), 1000);
  assert_int_equal(ocp_reconnect_delay_ms("250 ms"), 250);
  assert_int_equal(ocp_reconnect_delay_ms("1000ms"), 0);
  assert_int_equal(ocp_reconnect_delay_ms("draining"), 0);
  assert_int_equal(ocp_reconnect_delay_ms("1234567890 ms"), 0); /* at most 9 digits */
  assert_int_equal(ocp_reconnect_delay_ms(""), 0);
  assert_int_equal(ocp_reconnect_delay_ms(NULL), 0);
  assert_int_equal(ocp_code_from_err(0), OCP_CODE_OK);
  assert_int_equal(ocp_code_from_err(OC_EVERSION), OCP_CODE_VERSION);
  assert_int_equal(ocp_code_from_err(OC_ECORRUPT), OCP_CODE_MALFORMED);
  assert_int_equal(ocp_code_from_err(OC_ETRUNC), OCP_CODE_MALFORMED);
  assert_int_equal(ocp_code_from_err(OC_ETOOBIG), OCP_CODE_TOO_BIG);
  assert_int_equal(ocp_code_from_err(OC_ECHECKSUM), OCP_CODE_CHECKSUM);
  assert_int_equal(ocp_code_from_err(OC_ERANGE), OCP_CODE_BUDGET);
  assert_int_equal(ocp_code_from_err(OC_ENOMEM), OCP_CODE_INTERNAL);
  assert_int_equal(ocp_code_from_err(OC_EIO), OCP_CODE_INTERNAL);
}

static void test_wire__version_pick(void **state) {
  (void)state;
  assert_int_equal(ocp_version_pick(1, 1), 1);
  assert_int_equal(ocp_version_pick(0, 9), OCP_VERSION_MAX);
  assert_int_equal(ocp_version_pick(1, 65535), OCP_VERSION_MAX);
  assert_int_equal(ocp_version_pick(OCP_VERSION_MAX + 1, OCP_VERSION_MAX + 5), 0); /* all newer */
  assert_int_equal(ocp_version_pick(0, OCP_VERSION_MIN - 1), 0);                   /* all older */
  assert_int_equal(ocp_version_pick(3, 2), 0);                                     /* empty range */
}

/*-*** Golden bytes (written out by hand from docs/protocol.md) ***/

static void test_wire__golden_hello(void **state) {
  (void)state;
  static const uint8_t want[] = {
      0x4F, 0x57, 0x01, 0x01, 0x42, 0x00, 0x00, 0x00, /* "OW", version 1, HELLO, L = 66 */
      0x01, 0x00,                                     /* lowest version 1 */
      0x01, 0x00,                                     /* highest version 1 */
      0x00,                                           /* role viewer */
      0x0C,                                           /* max depth 12 */
      0x02, 0x00,                                     /* token length 2 */
      0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01, /* budget 0x0102030405060708 */
      0x00, 0x08, 0x00, 0x00,                         /* slot bytes 2048 */
      0x20, 0x00, 0x00, 0x00,                         /* record bytes 32 */
      0x80, 0x07, 0x00, 0x00,                         /* width 1920 */
      0x38, 0x04, 0x00, 0x00,                         /* height 1080 */
      0x03, 0x00, 0x00, 0x00,                         /* caps: deltas, dictionaries */
      0x44, 0x33, 0x22, 0x11,                         /* resume session 0x11223344 */
      0x11, 0x00, 0xFF, 0xEE, 0xDD, 0xCC, 0xBB, 0xAA, /* secret 0xAABBCCDDEEFF0011 */
      0x05, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, /* held epoch 5 */
      0x1B, 0xC2, 0x9E, 0x8E, 0xFA, 0x49, 0xD9, 0xC9, /* its checksum 0xc9d949fa8e9ec21b */
      0x61, 0x62,                                     /* token "ab" */
  };
  oc_buf_t b = {0};
  ocp_hello_t m = sample_hello;
  ocp_put_hello(&b, &m);
  assert_int_equal(b.len, sizeof want);
  assert_memory_equal(b.data, want, sizeof want);
  oc_buf_free(&b);
}

static void test_wire__golden_camera(void **state) {
  (void)state;
  static const uint8_t want[] = {
      0x4F, 0x57, 0x01, 0x02, 0x58, 0x00, 0x00, 0x00, /* "OW", version 1, CAMERA, L = 88 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0x3F, /* eye x 1.0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xC0, /* eye y -2.0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xE0, 0x3F, /* eye z 0.5 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, /* forward x 0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, /* forward y 0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0xBF, /* forward z -1.0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, /* up x 0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0x3F, /* up y 1.0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, /* up z 0 */
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x4E, 0x40, /* vertical fov 60.0 */
      0x20, 0x03, 0x00, 0x00,                         /* width 800 */
      0x58, 0x02, 0x00, 0x00,                         /* height 600 */
  };
  oc_buf_t b = {0};
  ocp_camera_t c = sample_camera;
  ocp_put_camera(&b, 1, &c);
  assert_int_equal(b.len, sizeof want);
  assert_memory_equal(b.data, want, sizeof want);
  ocp_camera_t back;
  char why[256];
  assert_int_equal(ocp_get_camera(want + 8, sizeof want - 8, &back, why, sizeof why), 0);
  assert_memory_equal(&back, &c, sizeof c);
  oc_buf_free(&b);
}

/*-*** Round trips ***/

/* m, a message of `type`, encoded as `version` is one frame of that type whose payload is `length`
 * bytes and decodes back to m (its first `size` bytes). @return the frame's header. */
static ocp_header_t expect_round_trip(uint8_t version, uint8_t type, const ocp_msg_t *m, size_t size, size_t length) {
  oc_buf_t b = {0};
  ocp_header_t h;
  char why[256];
  ocp_msg_t back;
  ocp_put_msg(&b, version, type, m);
  const uint8_t *p = only_frame(&b, &h);
  assert_int_equal(h.type, type);
  assert_int_equal(h.length, length);
  if (ocp_get_msg(version, type, p, h.length, &back, why, sizeof why)) fail_msg("%s: %s", ocp_msg_name(type), why);
  assert_memory_equal(&back, m, size);
  oc_buf_free(&b);
  return h;
}

static void test_wire__round_trip_hello(void **state) {
  (void)state;
  ocp_msg_t m = sample_of(OCP_MSG_HELLO);
  ocp_header_t h = expect_round_trip(1, OCP_MSG_HELLO, &m, sizeof m.hello, 64 + 2);
  assert_int_equal(h.version, m.hello.max_version);
  /* a control client: viewer fields zero, the longest token */
  memset(&m, 0, sizeof m);
  m.hello.min_version = 1, m.hello.max_version = 1, m.hello.role = OCP_ROLE_CONTROL;
  m.hello.token_len = OCP_TOKEN_MAX;
  for (int i = 0; i < OCP_TOKEN_MAX; i++) m.hello.token[i] = (uint8_t)(i * 7 + 1);
  expect_round_trip(1, OCP_MSG_HELLO, &m, sizeof m.hello, 64 + OCP_TOKEN_MAX);
}

static void test_wire__round_trip_welcome(void **state) {
  (void)state;
  ocp_msg_t m = sample_of(OCP_MSG_WELCOME);
  expect_round_trip(1, OCP_MSG_WELCOME, &m, sizeof m.welcome, 178 + strlen(m.welcome.name));
  /* control grant: K = 0, nothing granted; the longest name */
  memset(&m, 0, sizeof m);
  m.welcome.version = 1, m.welcome.session = 1;
  m.welcome.sun_dir = oc_dv3(1, 0, 0);
  memset(m.welcome.name, 'n', OCP_NAME_MAX);
  expect_round_trip(1, OCP_MSG_WELCOME, &m, sizeof m.welcome, 178 + OCP_NAME_MAX);
}

static void test_wire__round_trip_small(void **state) {
  (void)state;
  ocp_msg_t m = sample_of(OCP_MSG_CAMERA);
  m.camera.pos = oc_dv3(6371000.5, -1234.25, 1e-3);
  m.camera.forward = oc_dnorm(oc_dv3(1, 2, 3));
  m.camera.up = oc_dnorm(oc_dcross(oc_dcross(m.camera.forward, oc_dv3(0, 0, 1)), m.camera.forward));
  m.camera.width = 65536, m.camera.height = 1;
  expect_round_trip(1, OCP_MSG_CAMERA, &m, sizeof m.camera, 88);
  m.ack = (ocp_ack_t){UINT64_MAX - 1, 0x0123456789ABCDEFull};
  expect_round_trip(1, OCP_MSG_ACK, &m, sizeof m.ack, 16);
  expect_round_trip(1, OCP_MSG_KEEPALIVE, &m, 0, 0);
  /* epoch begin, with a base and without; end */
  m = sample_of(OCP_MSG_EPOCH_BEGIN);
  expect_round_trip(1, OCP_MSG_EPOCH_BEGIN, &m, sizeof m.begin, 64);
  m.begin.base_epoch = OCP_NO_BASE;
  expect_round_trip(1, OCP_MSG_EPOCH_BEGIN, &m, sizeof m.begin, 64);
  m.end = (ocp_epoch_end_t){43, 0xc9d949fa8e9ec21bull};
  expect_round_trip(1, OCP_MSG_EPOCH_END, &m, sizeof m.end, 16);
  m = sample_of(OCP_MSG_STATS);
  expect_round_trip(1, OCP_MSG_STATS, &m, sizeof m.stats, 88);
}

/* STATS by version: version 1 keeps its 88 bytes (a v1 viewer never sees the new fields); version 2
 * adds the production queue, bricks made, the split backlog and content age per level, at the
 * offsets docs/protocol.md gives; each version refuses the other's length and bad v2 fields. */
static void test_wire__stats_versions(void **state) {
  (void)state;
  ocp_stats_t s = sample_stats, sb;
  s.queue = 1234, s.produced = 567, s.split_backlog = 89;
  for (int l = 0; l < OCP_STATS_LEVELS; l++) s.age_p50[l] = (uint8_t)(l % 3), s.age_p99[l] = (uint8_t)(l % 3 + 1);
  s.age_p50[21] = s.age_p99[21] = 255;
  oc_buf_t b = {0};
  ocp_header_t h;
  char why[256];
  ocp_put_stats(&b, 1, &s);
  const uint8_t *p = only_frame(&b, &h);
  assert_int_equal(h.length, 88);
  assert_int_equal(ocp_get_stats(1, p, h.length, &sb, why, sizeof why), 0);
  assert_true(sb.queue == 0 && sb.produced == 0 && sb.age_p99[5] == 0); /* not on a v1 wire */
  expect_reject(ocp_get_stats(2, p, h.length, &sb, why, sizeof why), why, "expected 148");
  b.len = 0;
  ocp_put_stats(&b, 2, &s);
  p = only_frame(&b, &h);
  assert_int_equal(h.version, 2);
  assert_int_equal(h.length, 148);
  assert_int_equal(oc_get_u32(p + 88), 1234);
  assert_int_equal(oc_get_u32(p + 92), 567);
  assert_int_equal(oc_get_u32(p + 96), 89);
  assert_int_equal(p[104 + 4], 1);      /* level 4's p50 */
  assert_int_equal(p[104 + 22 + 4], 2); /* its p99 */
  assert_int_equal(ocp_get_stats(2, p, h.length, &sb, why, sizeof why), 0);
  assert_memory_equal(&sb, &s, sizeof s);
  expect_reject(ocp_get_stats(1, p, h.length, &sb, why, sizeof why), why, "expected 88");
  uint8_t bad[148];
  memcpy(bad, p, 148);
  bad[101] = 1;
  expect_reject(ocp_get_stats(2, bad, 148, &sb, why, sizeof why), why, "reserved bytes 100..103");
  memcpy(bad, p, 148);
  bad[104 + 3] = 9; /* p50 over p99 */
  expect_reject(ocp_get_stats(2, bad, 148, &sb, why, sizeof why), why, "level 3's age p50 9 is over its p99");
  oc_buf_free(&b);
}

static void test_wire__round_trip_text(void **state) {
  (void)state;
  ocp_msg_t m;
  memset(&m, 0, sizeof m);
  m.text.code = OCP_CODE_CHECKSUM;
  snprintf(m.text.text, sizeof m.text.text, "epoch 43: checksum mismatch");
  expect_round_trip(1, OCP_MSG_ERROR, &m, sizeof m.text, 6 + strlen(m.text.text));
  memset(&m, 0, sizeof m);
  expect_round_trip(1, OCP_MSG_GOODBYE, &m, sizeof m.text, 6);
  /* no text (NULL) goes as the empty text */
  oc_buf_t b = {0}, empty = {0};
  ocp_put_text(&b, 1, OCP_MSG_GOODBYE, OCP_CODE_OK, NULL);
  ocp_put_text(&empty, 1, OCP_MSG_GOODBYE, OCP_CODE_OK, "");
  assert_int_equal(b.len, empty.len);
  assert_memory_equal(b.data, empty.data, b.len);
  oc_buf_free(&empty);
  ocp_header_t h;
  char why[256];
  ocp_text_msg_t t;
  const uint8_t *p;
  /* a long text is cut at OCP_TEXT_MAX, never inside a UTF-8 sequence */
  char *lng = malloc(3000);
  memset(lng, 'x', 2999);
  lng[2999] = '\0';
  b.len = 0;
  ocp_put_text(&b, 1, OCP_MSG_ERROR, OCP_CODE_INTERNAL, lng);
  p = only_frame(&b, &h);
  assert_int_equal(h.length, 6 + OCP_TEXT_MAX);
  assert_int_equal(ocp_get_text(p, h.length, &t, why, sizeof why), 0);
  assert_int_equal(strlen(t.text), OCP_TEXT_MAX);
  lng[OCP_TEXT_MAX - 1] = (char)0xC3, lng[OCP_TEXT_MAX] = (char)0xA9; /* "é" across the cut */
  b.len = 0;
  ocp_put_text(&b, 1, OCP_MSG_ERROR, OCP_CODE_INTERNAL, lng);
  p = only_frame(&b, &h);
  assert_int_equal(h.length, 6 + OCP_TEXT_MAX - 1);
  free(lng);
  oc_buf_free(&b);
}

static void test_wire__round_trip_control(void **state) {
  (void)state;
  oc_buf_t b = {0};
  ocp_header_t h;
  char why[256];
  const char *json = "{\"op\": \"step\", \"epochs\": 3}";
  ocp_control_t c = {9, 0, json, (uint32_t)strlen(json)}, back;
  ocp_put_control(&b, 1, OCP_MSG_CONTROL, &c);
  const uint8_t *p = only_frame(&b, &h);
  assert_int_equal(h.type, OCP_MSG_CONTROL);
  assert_int_equal(h.length, 8 + strlen(json));
  assert_int_equal(ocp_get_control(p, h.length, &back, why, sizeof why), 0);
  assert_int_equal(back.request, 9);
  assert_int_equal(back.status, 0);
  assert_int_equal(back.json_len, strlen(json));
  assert_memory_equal(back.json, json, strlen(json));
  assert_ptr_equal(back.json, (const char *)p + 8);
  c.status = OCP_CODE_REQUEST;
  c.json = "{\"ok\": false, \"error\": \"no such op\"}";
  c.json_len = (uint32_t)strlen(c.json);
  b.len = 0;
  ocp_put_control(&b, 1, OCP_MSG_CONTROL_REPLY, &c);
  p = only_frame(&b, &h);
  assert_int_equal(h.type, OCP_MSG_CONTROL_REPLY);
  assert_int_equal(ocp_get_control(p, h.length, &back, why, sizeof why), 0);
  assert_int_equal(back.status, OCP_CODE_REQUEST);
  /* limits: fewer than 8 bytes, json over the 4 MiB frame − 8, a negative status, a NUL */
  uint8_t *big = calloc(1, OCP_MAX_PAYLOAD + 1);
  memset(big + 8, ' ', OCP_MAX_PAYLOAD - 8 + 1);
  assert_int_equal(ocp_get_control(big, OCP_MAX_PAYLOAD, &back, why, sizeof why), 0);
  expect_reject(ocp_get_control(big, OCP_MAX_PAYLOAD + 1, &back, why, sizeof why), why, "control: json");
  expect_reject(ocp_get_control(big, 7, &back, why, sizeof why), why, "control: payload is 7 bytes");
  assert_int_equal(ocp_get_control(big, 8, &back, why, sizeof why), 0);
  big[7] = 0x80; /* status −2^31 */
  expect_reject(ocp_get_control(big, 16, &back, why, sizeof why), why, "status");
  big[7] = 0;
  big[12] = 0;
  expect_reject(ocp_get_control(big, 16, &back, why, sizeof why), why, "NUL");
  free(big);
  oc_buf_free(&b);
}

/*-*** Exact lengths ***/

/* m encoded as `type`: the frame decodes; with one byte less or one zero byte more it does not. */
static void expect_exact_length_of(uint8_t type, const ocp_msg_t *m) {
  oc_buf_t b = {0};
  ocp_put_msg(&b, 1, type, m);
  expect_exact_length(&b);
  oc_buf_free(&b);
}

static void test_wire__exact_lengths(void **state) {
  (void)state;
  ocp_msg_t m = {.hello = sample_hello};
  expect_exact_length_of(OCP_MSG_HELLO, &m);
  m.hello.token_len = 0;
  expect_exact_length_of(OCP_MSG_HELLO, &m);
  m.welcome = sample_welcome;
  expect_exact_length_of(OCP_MSG_WELCOME, &m);
  m.welcome.name[0] = '\0';
  expect_exact_length_of(OCP_MSG_WELCOME, &m);
  m.camera = sample_camera;
  expect_exact_length_of(OCP_MSG_CAMERA, &m);
  m.ack = (ocp_ack_t){1, 2};
  expect_exact_length_of(OCP_MSG_ACK, &m);
  m.text = (ocp_text_msg_t){2, "bad"};
  expect_exact_length_of(OCP_MSG_ERROR, &m);
  m.text = (ocp_text_msg_t){0, ""};
  expect_exact_length_of(OCP_MSG_GOODBYE, &m);
  expect_exact_length_of(OCP_MSG_KEEPALIVE, &m);
  m.begin = sample_begin;
  expect_exact_length_of(OCP_MSG_EPOCH_BEGIN, &m);
  m.end = (ocp_epoch_end_t){43, 44};
  expect_exact_length_of(OCP_MSG_EPOCH_END, &m);
  m.stats = sample_stats;
  expect_exact_length_of(OCP_MSG_STATS, &m);
  /* CONTROL has no fixed length (json_len = n − 8): its bounds are in round_trip_control */
  char why[256];
  uint8_t z[200] = {0};
  expect_reject(ocp_get_hello(z, 63, &m.hello, why, sizeof why), why, "hello: payload is 63 bytes");
  expect_reject(ocp_get_welcome(z, 177, &m.welcome, why, sizeof why), why, "welcome: payload is 177 bytes");
  expect_reject(ocp_get_camera(z, 87, &m.camera, why, sizeof why), why, "camera: payload is 87 bytes, expected 88");
  expect_reject(ocp_get_ack(z, 17, &m.ack, why, sizeof why), why, "ack: payload is 17 bytes, expected 16");
  expect_reject(ocp_get_text(z, 5, &m.text, why, sizeof why), why, "payload is 5 bytes");
  expect_reject(ocp_get_empty(z, 1, why, sizeof why), why, "keepalive: payload is 1 bytes, expected 0");
  expect_reject(ocp_get_stats(1, z, 89, &m.stats, why, sizeof why), why, "stats: payload is 89 bytes, expected 88");
}

/*-*** Field checks ***/

/* Encodes m as `type`, overwrites n payload bytes at off, decodes. */
static int decode_patched(uint8_t type, const ocp_msg_t *m, size_t off, const uint8_t *bytes, size_t n, char *why,
                          size_t why_len) {
  oc_buf_t b = {0};
  ocp_msg_t back;
  ocp_put_msg(&b, 1, type, m);
  assert_true(off + n <= b.len - OCP_HEADER_BYTES);
  memcpy(b.data + OCP_HEADER_BYTES + off, bytes, n);
  int e = ocp_get_msg(1, type, b.data + OCP_HEADER_BYTES, b.len - OCP_HEADER_BYTES, &back, why, why_len);
  oc_buf_free(&b);
  return e;
}

static int hello_with(const ocp_hello_t *m, size_t off, const uint8_t *bytes, size_t n, char *why, size_t why_len) {
  return decode_patched(OCP_MSG_HELLO, &(ocp_msg_t){.hello = *m}, off, bytes, n, why, why_len);
}

static void test_wire__hello_fields(void **state) {
  (void)state;
  char why[256];
  ocp_hello_t m = sample_hello;
  oc_buf_t b = {0};
  m.max_depth = 30;
  ocp_put_hello(&b, &m);
  expect_reject(ocp_get_hello(b.data + 8, b.len - 8, &m, why, sizeof why), why, "hello: max_depth 30 is above 21");
  m = sample_hello;
  expect_reject(hello_with(&m, 0, (const uint8_t[]){2, 0, 1, 0}, 4, why, sizeof why), why, "min_version 2 is above max_version 1");
  expect_reject(hello_with(&m, 4, (const uint8_t[]){2}, 1, why, sizeof why), why, "role 2");
  expect_reject(hello_with(&m, 32, (const uint8_t[]){8}, 1, why, sizeof why), why, "caps 0x8 has unknown bits");
  /* a lean viewer (digest) cannot take deltas: the pair is refused, naming both */
  expect_reject(hello_with(&m, 32, (const uint8_t[]){OCP_CAP_DIGEST | OCP_CAP_DELTA}, 1, why, sizeof why), why,
                "caps 0x5 combine digest (0x4) with delta (0x1)");
  assert_int_equal(hello_with(&m, 32, (const uint8_t[]){OCP_CAP_DIGEST | OCP_CAP_DICT}, 1, why, sizeof why), 0);
  assert_int_equal(hello_with(&m, 32, (const uint8_t[]){OCP_CAP_DIGEST}, 1, why, sizeof why), 0);
  expect_reject(hello_with(&m, 8, (const uint8_t[8]){0}, 8, why, sizeof why), why, "budget is zero");
  expect_reject(hello_with(&m, 16, (const uint8_t[4]){0}, 4, why, sizeof why), why, "slot_bytes 0 is outside 1..1048576");
  expect_reject(hello_with(&m, 20, (const uint8_t[4]){1, 0, 0x10, 0}, 4, why, sizeof why), why, "record_bytes 1048577");
  expect_reject(hello_with(&m, 24, (const uint8_t[4]){1, 0, 1, 0}, 4, why, sizeof why), why, "width 65537");
  expect_reject(hello_with(&m, 28, (const uint8_t[4]){0}, 4, why, sizeof why), why, "height 0");
  /* token length: 257 is over the limit, and a length that disagrees with the payload */
  expect_reject(hello_with(&m, 6, (const uint8_t[2]){1, 1}, 2, why, sizeof why), why, "token_len 257 is above 256");
  expect_reject(hello_with(&m, 6, (const uint8_t[2]){3, 0}, 2, why, sizeof why), why, "hello: payload is 66 bytes, expected 67");
  /* a control client with a viewer field set */
  memset(&m, 0, sizeof m);
  m.min_version = m.max_version = 1;
  m.role = OCP_ROLE_CONTROL;
  b.len = 0;
  ocp_put_hello(&b, &m);
  assert_int_equal(ocp_get_hello(b.data + 8, b.len - 8, &m, why, sizeof why), 0);
  expect_reject(hello_with(&m, 8, (const uint8_t[]){1}, 1, why, sizeof why), why, "budget (control) is not zero");
  expect_reject(hello_with(&m, 36, (const uint8_t[]){1}, 1, why, sizeof why), why, "resume_session (control)");
  oc_buf_free(&b);
}

static int welcome_with(size_t off, const uint8_t *bytes, size_t n, char *why, size_t why_len) {
  return decode_patched(OCP_MSG_WELCOME, &(ocp_msg_t){.welcome = sample_welcome}, off, bytes, n, why, why_len);
}

static void test_wire__welcome_fields(void **state) {
  (void)state;
  char why[256];
  uint8_t nan[8];
  oc_put_f64(nan, NAN);
  expect_reject(welcome_with(0, (const uint8_t[2]){0}, 2, why, sizeof why), why, "welcome: version is zero");
  expect_reject(welcome_with(2, (const uint8_t[]){2}, 1, why, sizeof why), why, "flags 0x2 has unknown bits");
  expect_reject(welcome_with(3, (const uint8_t[]){1}, 1, why, sizeof why), why, "kept_states 1 is not 0, 2 or 3");
  expect_reject(welcome_with(3, (const uint8_t[]){4}, 1, why, sizeof why), why, "kept_states 4");
  expect_reject(welcome_with(4, (const uint8_t[4]){0}, 4, why, sizeof why), why, "session is zero");
  expect_reject(welcome_with(32, (const uint8_t[]){22}, 1, why, sizeof why), why, "max_depth 22 is above 21");
  expect_reject(welcome_with(48, nan, 8, why, sizeof why), why, "planet_radius is not finite");
  expect_reject(welcome_with(56, nan, 8, why, sizeof why), why, "welcome: time is not finite");
}

static void test_wire__welcome_sun_and_name(void **state) {
  (void)state;
  char why[256];
  uint8_t two[8];
  oc_put_f64(two, 0.61);
  expect_reject(welcome_with(72, two, 8, why, sizeof why), why, "welcome: sun_dir");
  uint8_t bad_albedo[8];
  oc_put_f64(bad_albedo, 1.5);
  expect_reject(welcome_with(88, bad_albedo, 8, why, sizeof why), why, "albedo 1.5");
  /* a NUL inside the name */
  expect_reject(welcome_with(178 + 3, (const uint8_t[]){0}, 1, why, sizeof why), why, "name contains a NUL");
  /* name length 64 */
  oc_buf_t b = {0};
  ocp_welcome_t w = sample_welcome, back;
  ocp_put_welcome(&b, 1, &w);
  oc_put_u16(b.data + 8 + 176, 64);
  expect_reject(ocp_get_welcome(b.data + 8, b.len - 8, &back, why, sizeof why), why, "name length 64 is above 63");
  /* a viewer grant of nothing */
  w.budget = 0;
  b.len = 0;
  ocp_put_welcome(&b, 1, &w);
  expect_reject(ocp_get_welcome(b.data + 8, b.len - 8, &back, why, sizeof why), why, "welcome: budget is zero");
  oc_buf_free(&b);
}

static void test_wire__reserved_bytes(void **state) {
  (void)state;
  char why[256];
  for (size_t off = 33; off < 36; off++)
    expect_reject(welcome_with(off, (const uint8_t[]){1}, 1, why, sizeof why), why, "welcome: reserved bytes 33..35");
  for (size_t off = 124; off < 128; off++)
    expect_reject(welcome_with(off, (const uint8_t[]){0x80}, 1, why, sizeof why), why, "welcome: reserved bytes 124..127");
  oc_buf_t b = {0};
  ocp_epoch_begin_t eb = sample_begin, ebb;
  ocp_put_epoch_begin(&b, 1, &eb);
  for (size_t off = 60; off < 64; off++) {
    b.data[8 + off] = 1;
    expect_reject(ocp_get_epoch_begin(b.data + 8, 64, &ebb, why, sizeof why), why, "epoch-begin: reserved bytes 60..63");
    b.data[8 + off] = 0;
  }
  assert_int_equal(ocp_get_epoch_begin(b.data + 8, 64, &ebb, why, sizeof why), 0);
  ocp_stats_t s = sample_stats, sb;
  b.len = 0;
  ocp_put_stats(&b, 1, &s);
  for (size_t off = 72; off < 88; off++) {
    b.data[8 + off] = 0x10;
    expect_reject(ocp_get_stats(1, b.data + 8, 88, &sb, why, sizeof why), why, "stats: reserved bytes 72..87");
    b.data[8 + off] = 0;
  }
  assert_int_equal(ocp_get_stats(1, b.data + 8, 88, &sb, why, sizeof why), 0);
  oc_buf_free(&b);
}

static int camera_check(const ocp_camera_t *c, char *why, size_t why_len) {
  oc_buf_t b = {0};
  ocp_camera_t back;
  ocp_put_camera(&b, 1, c);
  int e = ocp_get_camera(b.data + 8, b.len - 8, &back, why, why_len);
  oc_buf_free(&b);
  return e;
}

static void test_wire__camera_fields(void **state) {
  (void)state;
  char why[256];
  ocp_camera_t c = sample_camera;
  assert_int_equal(camera_check(&c, why, sizeof why), 0);
  c.pos.y = NAN;
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: pos is not finite");
  c = sample_camera;
  c.forward.x = NAN;
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: forward is not finite");
  c = sample_camera;
  c.up.z = INFINITY;
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: up is not finite");
  c = sample_camera;
  c.vfov_deg = NAN;
  expect_reject(camera_check(&c, why, sizeof why), why, "vfov_deg");
  c = sample_camera;
  c.forward.z = -1.002; /* length off by 2e-3 */
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: forward");
  c.forward.z = -1.0009; /* within 1e-3 */
  assert_int_equal(camera_check(&c, why, sizeof why), 0);
  c = sample_camera;
  c.up = oc_dnorm(oc_dv3(0.0, 1.0, 0.002)); /* dot = −0.002 */
  expect_reject(camera_check(&c, why, sizeof why), why, "not orthogonal");
  c = sample_camera;
  c.vfov_deg = 0.0;
  expect_reject(camera_check(&c, why, sizeof why), why, "vfov_deg 0 is outside (0, 180)");
  c.vfov_deg = 180.0;
  expect_reject(camera_check(&c, why, sizeof why), why, "vfov_deg 180");
  c = sample_camera;
  c.width = 0;
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: width 0");
  c = sample_camera;
  c.height = 65537;
  expect_reject(camera_check(&c, why, sizeof why), why, "camera: height 65537");
}

static void test_wire__epoch_begin_fields(void **state) {
  (void)state;
  char why[256];
  oc_buf_t b = {0};
  ocp_epoch_begin_t m, back;
#define CHECK(edit, needle)                                                               \
  do {                                                                                    \
    m = sample_begin;                                                                   \
    edit;                                                                                 \
    b.len = 0;                                                                            \
    ocp_put_epoch_begin(&b, 1, &m);                                                       \
    expect_reject(ocp_get_epoch_begin(b.data + 8, b.len - 8, &back, why, sizeof why), why, needle); \
  } while (0)
  CHECK(m.node_count = 0, "node_count 0 is outside 1..16777216");
  CHECK(m.node_count = OC_STATE_MAX_NODES + 1, "node_count 16777217");
  CHECK((m.node_count = OC_STATE_MAX_NODES, m.brick_count = OC_STATE_MAX_BRICKS + 1), "brick_count 4194305");
  CHECK(m.bricks_sent = 4, "bricks_sent 4 is above brick_count 3");
  CHECK(m.time = NAN, "epoch-begin: time is not finite");
  CHECK(m.sun_dir = oc_dv3(0, 0.6, 0.8000021), "epoch-begin: sun_dir");
  CHECK(m.base_epoch = 43, "base_epoch 43 is not before epoch 43");
#undef CHECK
  m = sample_begin;
  m.node_count = OC_STATE_MAX_NODES, m.brick_count = OC_STATE_MAX_BRICKS, m.bricks_sent = OC_STATE_MAX_BRICKS;
  b.len = 0;
  ocp_put_epoch_begin(&b, 1, &m);
  assert_int_equal(ocp_get_epoch_begin(b.data + 8, b.len - 8, &back, why, sizeof why), 0);
  oc_buf_free(&b);
}

static void test_wire__text_fields(void **state) {
  (void)state;
  char why[256];
  ocp_text_msg_t t;
  uint8_t p[6 + 1025];
  memset(p, 'a', sizeof p);
  oc_put_u32(p, 2);
  oc_put_u16(p + 4, 1025);
  expect_reject(ocp_get_text(p, sizeof p, &t, why, sizeof why), why, "text length 1025 is above 1024");
  oc_put_u16(p + 4, 1024);
  assert_int_equal(ocp_get_text(p, 6 + 1024, &t, why, sizeof why), 0);
  p[6 + 500] = 0;
  expect_reject(ocp_get_text(p, 6 + 1024, &t, why, sizeof why), why, "NUL");
}

/*-*** Frames and the reader ***/

static void test_wire__header(void **state) {
  (void)state;
  ocp_header_t h;
  uint8_t p[8] = {0x4F, 0x57, 1, 0x83, 0x00, 0x00, 0x40, 0x00}; /* L = 4 MiB */
  assert_int_equal(ocp_header_parse(p, OCP_MAX_PAYLOAD, &h), 0);
  assert_int_equal(h.version, 1);
  assert_int_equal(h.type, OCP_MSG_RECORDS);
  assert_int_equal(h.length, OCP_MAX_PAYLOAD);
  p[4] = 1; /* 4 MiB + 1 */
  assert_int_equal(ocp_header_parse(p, OCP_MAX_PAYLOAD, &h), OC_ETOOBIG);
  p[4] = 0, p[6] = 0, p[5] = 1; /* 256 bytes, over a 255-byte limit */
  assert_int_equal(ocp_header_parse(p, 255, &h), OC_ETOOBIG);
  p[1] = 0x58;
  assert_int_equal(ocp_header_parse(p, OCP_MAX_PAYLOAD, &h), OC_ECORRUPT);
  /* frame_begin / frame_end patch the length of whatever was appended */
  oc_buf_t b = {0};
  oc_buf_u8(&b, 0xEE); /* frames need not start at offset 0 */
  size_t off = ocp_frame_begin(&b, 1, OCP_MSG_RECORDS);
  assert_int_equal(off, 1);
  oc_buf_u32(&b, 5);
  oc_buf_append(&b, "hello", 5);
  ocp_frame_end(&b, off);
  assert_int_equal(ocp_header_parse(b.data + 1, OCP_MAX_PAYLOAD, &h), 0);
  assert_int_equal(h.length, 9);
  assert_int_equal(h.type, OCP_MSG_RECORDS);
  oc_buf_free(&b);
}

/* A stream of several frames of different sizes. */
static void build_stream(oc_buf_t *b) {
  ocp_welcome_t w = sample_welcome;
  ocp_camera_t c = sample_camera;
  ocp_stats_t s = sample_stats;
  ocp_put_welcome(b, 1, &w);
  ocp_put_empty(b, 1, OCP_MSG_KEEPALIVE);
  ocp_put_camera(b, 1, &c);
  ocp_put_text(b, 1, OCP_MSG_GOODBYE, 0, "bye");
  ocp_put_stats(b, 1, &s);
  ocp_put_empty(b, 1, OCP_MSG_KEEPALIVE);
}
static const uint8_t stream_types[] = {OCP_MSG_WELCOME, OCP_MSG_KEEPALIVE, OCP_MSG_CAMERA,
                                       OCP_MSG_GOODBYE, OCP_MSG_STATS,     OCP_MSG_KEEPALIVE};

static void test_wire__reader_split(void **state) {
  (void)state;
  oc_buf_t b = {0};
  build_stream(&b);
  char why[256];
  ocp_reader_t r;
  ocp_header_t h;
  const uint8_t *p;
  /* all at once: every frame comes out in order, then "need more" */
  ocp_reader_init(&r, OCP_MAX_PAYLOAD);
  assert_int_equal(ocp_reader_feed(&r, b.data, b.len), 0);
  assert_int_equal(ocp_reader_pending(&r), b.len);
  for (size_t i = 0; i < sizeof stream_types; i++) {
    assert_int_equal(ocp_reader_next(&r, &h, &p), 1);
    assert_int_equal(h.type, stream_types[i]);
    if (decode_any(h.type, p, h.length, why, sizeof why)) fail_msg("frame %zu: %s", i, why);
  }
  assert_int_equal(ocp_reader_next(&r, &h, &p), 0);
  assert_int_equal(ocp_reader_pending(&r), 0);
  /* one byte at a time: each frame appears exactly when its last byte arrives, and the reader
   * never holds more than the frame in progress plus the byte just fed */
  size_t end = 0, k = 0;
  for (size_t i = 0; i < b.len; i++) {
    assert_int_equal(ocp_reader_feed(&r, b.data + i, 1), 0);
    assert_true(r.buf.len <= 8 + 178 + 64 + 1);
    int got = ocp_reader_next(&r, &h, &p);
    if (k < sizeof stream_types && i + 1 == end + 8 + (size_t)oc_get_u32(b.data + end + 4)) {
      assert_int_equal(got, 1);
      assert_int_equal(h.type, stream_types[k]);
      assert_memory_equal(p, b.data + end + 8, h.length);
      if (decode_any(h.type, p, h.length, why, sizeof why)) fail_msg("frame %zu: %s", k, why);
      end = i + 1;
      k++;
      assert_int_equal(ocp_reader_next(&r, &h, &p), 0);
    } else {
      assert_int_equal(got, 0);
    }
  }
  assert_int_equal(k, sizeof stream_types);
  assert_int_equal(ocp_reader_pending(&r), 0);
  /* in uneven chunks, several frames per feed and frames cut across feeds */
  size_t at = 0;
  k = 0;
  for (size_t step = 1; at < b.len; step = step * 3 + 1) {
    size_t n = b.len - at < step ? b.len - at : step;
    assert_int_equal(ocp_reader_feed(&r, b.data + at, n), 0);
    at += n;
    while (ocp_reader_next(&r, &h, &p) == 1) assert_int_equal(h.type, stream_types[k++]);
  }
  assert_int_equal(k, sizeof stream_types);
  ocp_reader_free(&r);
  oc_buf_free(&b);
}

static void test_wire__reader_errors(void **state) {
  (void)state;
  ocp_reader_t r;
  ocp_header_t h;
  const uint8_t *p;
  oc_buf_t b = {0};
  ocp_put_empty(&b, 1, OCP_MSG_KEEPALIVE);
  /* bad magic after a good frame: the good one comes out, then the error sticks */
  ocp_reader_init(&r, OCP_MAX_CLIENT_PAYLOAD);
  assert_int_equal(ocp_reader_feed(&r, b.data, b.len), 0);
  assert_int_equal(ocp_reader_feed(&r, "XW\x01\x70\0\0\0\0", 8), 0);
  assert_int_equal(ocp_reader_next(&r, &h, &p), 1);
  assert_int_equal(ocp_reader_next(&r, &h, &p), OC_ECORRUPT);
  assert_int_equal(ocp_reader_next(&r, &h, &p), OC_ECORRUPT);
  assert_int_equal(ocp_reader_feed(&r, b.data, b.len), 0); /* dropped */
  assert_int_equal(ocp_reader_next(&r, &h, &p), OC_ECORRUPT);
  ocp_reader_free(&r);
  /* an oversized length is refused as soon as the header is whole, before the payload arrives */
  ocp_reader_init(&r, OCP_MAX_CLIENT_PAYLOAD);
  uint8_t hdr[8] = {0x4F, 0x57, 1, OCP_MSG_CAMERA, 0, 0, 0, 0};
  oc_put_u32(hdr + 4, OCP_MAX_CLIENT_PAYLOAD + 1);
  assert_int_equal(ocp_reader_feed(&r, hdr, 7), 0);
  assert_int_equal(ocp_reader_next(&r, &h, &p), 0);
  assert_int_equal(ocp_reader_feed(&r, hdr + 7, 1), 0);
  assert_int_equal(ocp_reader_next(&r, &h, &p), OC_ETOOBIG);
  ocp_reader_free(&r);
  /* the limit itself is fine */
  ocp_reader_init(&r, 16);
  oc_put_u32(hdr + 4, 16);
  assert_int_equal(ocp_reader_feed(&r, hdr, 8), 0);
  assert_int_equal(ocp_reader_next(&r, &h, &p), 0);
  uint8_t body[16] = {0};
  assert_int_equal(ocp_reader_feed(&r, body, 16), 0);
  assert_int_equal(ocp_reader_next(&r, &h, &p), 1);
  assert_int_equal(h.length, 16);
  ocp_reader_free(&r);
  oc_buf_free(&b);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_wire__names_and_codes),
             cmocka_unit_test(test_wire__version_pick),
             cmocka_unit_test(test_wire__golden_hello),
             cmocka_unit_test(test_wire__golden_camera),
             cmocka_unit_test(test_wire__round_trip_hello),
             cmocka_unit_test(test_wire__round_trip_welcome),
             cmocka_unit_test(test_wire__round_trip_small),
             cmocka_unit_test(test_wire__round_trip_text),
             cmocka_unit_test(test_wire__stats_versions),
             cmocka_unit_test(test_wire__round_trip_control),
             cmocka_unit_test(test_wire__exact_lengths),
             cmocka_unit_test(test_wire__hello_fields),
             cmocka_unit_test(test_wire__welcome_fields),
             cmocka_unit_test(test_wire__welcome_sun_and_name),
             cmocka_unit_test(test_wire__reserved_bytes),
             cmocka_unit_test(test_wire__camera_fields),
             cmocka_unit_test(test_wire__epoch_begin_fields),
             cmocka_unit_test(test_wire__text_fields),
             cmocka_unit_test(test_wire__header),
             cmocka_unit_test(test_wire__reader_split),
             cmocka_unit_test(test_wire__reader_errors))
