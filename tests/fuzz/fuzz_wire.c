/* fuzz_wire.c — libFuzzer target for the wire's frame reader, message decoders and the viewer's
 * session (proto/ocp_wire.c, proto/ocp_viewer.c).
 *
 * Each input is read twice:
 *  - as a stream of frames: every frame is decoded by its type from an exact-size copy (so ASan
 *    sees any over-read), and whatever a decoder accepts must encode back to the same bytes (each
 *    message has one byte form);
 *  - as what a server sends a viewer (full and lean) and a control client after a synthetic WELCOME,
 *    fed in chunks: the session must fail cleanly (an ERROR frame last in its output) or keep only
 *    valid states, never more than K − 1, and survive a reconnect with resume.
 * Seeds: tests/fuzz/corpus/wire/ (written by tests/proto/test_viewer.c with
 * OC_FUZZ_WIRE_CORPUS_OUT=<dir>). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "oc_state.h"
#include "ocp_viewer.h"
#include "ocp_wire.h"

/*-*** Decoders ***/

/* The payload p re-encoded by the type's encoder equals p. */
static void check_same(const oc_buf_t *b, const uint8_t *p, size_t n) {
  if (b->err) return;
  if (b->len != OCP_HEADER_BYTES + n || memcmp(b->data + OCP_HEADER_BYTES, p, n) != 0) abort();
}

static void check_frame(const ocp_header_t *h, const uint8_t *payload) {
  uint8_t *p = malloc(h->length ? h->length : 1);
  if (!p) return;
  memcpy(p, payload, h->length);
  size_t n = h->length;
  char why[256];
  ocp_msg_t m;
  int e = ocp_get_msg(h->version, h->type, p, n, &m, why, sizeof why);
  if (e == 0) { /* what a decoder accepts has one byte form */
    oc_buf_t b = {0};
    ocp_put_msg(&b, h->version, h->type, &m);
    check_same(&b, p, n);
    oc_buf_free(&b);
    if (h->type == OCP_MSG_HELLO) (void)ocp_version_pick(m.hello.min_version, m.hello.max_version);
    if (h->type == OCP_MSG_ERROR || h->type == OCP_MSG_GOODBYE) (void)ocp_code_text(m.text.code);
    if ((h->type == OCP_MSG_CONTROL || h->type == OCP_MSG_CONTROL_REPLY) && m.control.json != (const char *)p + 8) abort();
  } else if (e == 1) { /* epoch payloads: fuzz_epoch.c, and the viewer below */
    (void)ocp_msg_name(h->type);
  }
  free(p);
}

static void fuzz_frames(const uint8_t *data, size_t size) {
  ocp_reader_t r;
  ocp_header_t h;
  const uint8_t *p;
  ocp_reader_init(&r, OCP_MAX_PAYLOAD);
  if (ocp_reader_feed(&r, data, size) == 0) {
    int e;
    while ((e = ocp_reader_next(&r, &h, &p)) == 1) check_frame(&h, p);
    if (e == 0 && ocp_reader_pending(&r) > size) abort();
  }
  ocp_reader_free(&r);
}

/*-*** Viewer ***/

/* ctx: points to the session when it is lean (its states hold records only; its bricks are digests). */
static void on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  ocp_viewer_t *lean = *(ocp_viewer_t **)ctx;
  const oc_brick_digests_t *d = lean ? ocp_viewer_digests(lean, 0) : NULL;
  if (lean) {
    if (!d || bricks > d->count || s->brick_count || oc_state_validate_lean(s, d, NULL, 0) != 0) abort();
  } else if (bricks > s->brick_count || oc_state_validate(s, NULL, 0) != 0) {
    abort();
  }
}

/* out ends with an ERROR frame. */
static void check_error_last(const oc_buf_t *out) {
  size_t at = 0, last = SIZE_MAX;
  ocp_header_t h;
  while (at + OCP_HEADER_BYTES <= out->len) {
    if (ocp_header_parse(out->data + at, OCP_MAX_PAYLOAD, &h) != 0) abort();
    last = at;
    at += OCP_HEADER_BYTES + (size_t)h.length;
  }
  if (at != out->len || last == SIZE_MAX) abort();
  ocp_header_parse(out->data + last, OCP_MAX_PAYLOAD, &h);
  if (h.type != OCP_MSG_ERROR) abort();
}

static void put_welcome(oc_buf_t *b, int kept, int resumed) {
  ocp_welcome_t w;
  memset(&w, 0, sizeof w);
  w.version = OCP_VERSION_MAX;
  w.flags = resumed ? OCP_WELCOME_RESUMED : 0;
  w.kept_states = (uint8_t)kept;
  w.session = 1;
  w.secret = 2;
  w.budget = kept ? 1u << 20 : 0;
  w.slot_bytes = kept ? 2048 : 0;
  w.record_bytes = kept ? 32 : 0;
  w.sun_dir = oc_dv3(0, 0, 1);
  ocp_put_welcome(b, OCP_VERSION_MAX, &w);
}

/* Feeds data in chunks of `chunk` bytes; @return the first error, or 0. */
static int feed_chunks(ocp_viewer_t *v, const uint8_t *data, size_t size, size_t chunk, oc_buf_t *out) {
  char why[256];
  for (size_t at = 0; at < size; at += chunk) {
    size_t n = size - at < chunk ? size - at : chunk;
    out->len = 0;
    int e = ocp_viewer_feed(v, data + at, n, out, why, sizeof why);
    if (e < 0) {
      if (!why[0]) abort(); /* a failure always has a reason */
      check_error_last(out);
      return e;
    }
  }
  return 0;
}

static void fuzz_viewer(const uint8_t *data, size_t size, int role, int kept, size_t chunk, int lean) {
  ocp_viewer_desc_t d;
  memset(&d, 0, sizeof d);
  d.role = (uint8_t)role;
  d.budget = 1u << 20;
  d.width = d.height = 64;
  d.caps = lean ? OCP_CAP_DICT : OCP_CAP_ALL;
  d.lean = lean;
  ocp_viewer_t *v, *lean_v = NULL;
  ocp_viewer_events_t ev = {&lean_v, NULL, on_state, NULL, NULL, NULL, NULL};
  if (ocp_viewer_create(&v, &d, &ev) != 0) return;
  if (lean && role == OCP_ROLE_VIEWER) lean_v = v;
  oc_buf_t out = {0}, w = {0};
  char why[256];
  for (int conn = 0; conn < 2; conn++) { /* a viewer's second connection resumes */
    out.len = w.len = 0;
    ocp_viewer_connected(v, &out);
    put_welcome(&w, role == OCP_ROLE_VIEWER ? kept : 0, conn == 1 && role == OCP_ROLE_VIEWER);
    if (ocp_viewer_feed(v, w.data, w.len, &out, why, sizeof why) != 0) abort();
    if (!ocp_viewer_ready(v)) abort();
    (void)feed_chunks(v, data, size, chunk, &out);
    /* what is held: at most K − 1 states, all valid, newest first */
    for (int i = 0; i < 3; i++) {
      const oc_state_t *s = ocp_viewer_state(v, i);
      const oc_brick_digests_t *dg = ocp_viewer_digests(v, i);
      if (role != OCP_ROLE_VIEWER || i >= kept - 1) {
        if (s || dg) abort();
      } else if (s && (lean ? !dg || oc_state_validate_lean(s, dg, NULL, 0) != 0 : dg || oc_state_validate(s, NULL, 0) != 0)) {
        abort();
      }
    }
  }
  ocp_viewer_stats_t st;
  ocp_viewer_stats(v, &st);
  if (st.reconnects != 1) abort();
  oc_buf_free(&out);
  oc_buf_free(&w);
  ocp_viewer_free(v);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  fuzz_frames(data, size);
  /* the chunk size comes from the input's length, so every byte stays part of the stream */
  size_t chunk = 1 + size % 509;
  fuzz_viewer(data, size, OCP_ROLE_VIEWER, 2 + (int)(size & 1), size, 0);
  fuzz_viewer(data, size, OCP_ROLE_VIEWER, 3, chunk, 0);
  fuzz_viewer(data, size, OCP_ROLE_VIEWER, 3, chunk, 1); /* lean: digests, no codes */
  fuzz_viewer(data, size, OCP_ROLE_CONTROL, 0, chunk, 0);
  return 0;
}
