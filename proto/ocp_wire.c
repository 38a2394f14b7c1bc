/* ocp_wire.c — frames and messages of the Overcast wire protocol (ocp_wire.h; docs/protocol.md,
 * "Wire").
 *
 * Each message's fixed part is one table of fields ("Message layouts"): its wire width, its struct
 * member and the rule an honest peer keeps. One encoder and one decoder walk every table; the
 * decoder checks the payload length first, so a short or long payload is reported as such rather
 * than as whatever field happened to be cut. Every check a decoder makes is one an honest peer
 * never fails: the code above sees only well-formed messages. */
#include "ocp_wire.h"

#include <assert.h>
#include <inttypes.h> /* PRIu32, PRIu64 */
#include <math.h>     /* isfinite, fabs */
#include <stdarg.h>
#include <stdio.h>  /* vsnprintf */
#include <string.h> /* memcpy, memchr, strnlen */

#include "oc_err.h"   /* OC_E* */
#include "oc_state.h" /* OC_STATE_MAX_NODES, OC_STATE_MAX_BRICKS */

#define OCP__HELLO_BYTES 64
#define OCP__WELCOME_BYTES 178
#define OCP__CAMERA_BYTES 88
#define OCP__ACK_BYTES 16
#define OCP__BUDGET_BYTES 16
#define OCP__TEXT_BYTES 6
#define OCP__EPOCH_BEGIN_BYTES 64
#define OCP__EPOCH_END_BYTES 16
#define OCP__STATS_BYTES 88     /* version 1 */
#define OCP__STATS_V2_BYTES 148 /* version 2: + queue, produced, split backlog, reserved, ages */
#define OCP__CONTROL_BYTES 8
#define OCP__MAX_DEPTH 21
#define OCP__GPU_BYTES_MAX (1u << 20) /* per brick slot and per node record */
#define OCP__VIEWPORT_MAX 65536u
#define OCP__CONTROL_JSON_MAX (OCP_MAX_PAYLOAD - OCP__CONTROL_BYTES) /* the frame limit of each direction bounds it further */
#define OCP__CAMERA_TOL 1e-3
#define OCP__SUN_TOL 1e-6 /* as oc_state_validate(), so a begun epoch cannot fail on it later */

/*-*** Names and codes ***/

/* The names of message types and the texts of wire codes, as {value, string} rows of their maps. */
typedef struct {
  uint32_t val;
  const char *str;
} ocp__name_t;

#define OCP__NAME_ROW(name, val, str) {(val), (str)},
static const ocp__name_t ocp__msg_names[] = {OCP_MSG_MAP(OCP__NAME_ROW)};
static const ocp__name_t ocp__code_texts[] = {OCP_CODE_MAP(OCP__NAME_ROW)};
#undef OCP__NAME_ROW

static const char *ocp__name_of(const ocp__name_t *t, size_t count, uint32_t val, const char *none) {
  for (size_t i = 0; i < count; i++)
    if (t[i].val == val) return t[i].str;
  return none;
}

const char *ocp_msg_name(int type) {
  if (type < 0) return NULL;
  return ocp__name_of(ocp__msg_names, sizeof ocp__msg_names / sizeof ocp__msg_names[0], (uint32_t)type, NULL);
}

const char *ocp_code_text(uint32_t code) {
  return ocp__name_of(ocp__code_texts, sizeof ocp__code_texts / sizeof ocp__code_texts[0], code, "unknown code");
}

uint32_t ocp_code_from_err(int err) {
  switch (err) {
    case 0:
      return OCP_CODE_OK;
    case OC_EVERSION:
      return OCP_CODE_VERSION;
    case OC_ECORRUPT:
    case OC_ETRUNC:
      return OCP_CODE_MALFORMED;
    case OC_ETOOBIG:
      return OCP_CODE_TOO_BIG;
    case OC_ECHECKSUM:
      return OCP_CODE_CHECKSUM;
    case OC_ERANGE:
      return OCP_CODE_BUDGET;
    default:
      return OCP_CODE_INTERNAL;
  }
}

uint16_t ocp_version_pick(uint16_t their_min, uint16_t their_max) {
  uint16_t lo = their_min > OCP_VERSION_MIN ? their_min : OCP_VERSION_MIN;
  uint16_t hi = their_max < OCP_VERSION_MAX ? their_max : OCP_VERSION_MAX;
  return lo <= hi ? hi : 0;
}

/*-*** Frames ***/

int ocp_header_parse(const uint8_t p[OCP_HEADER_BYTES], uint32_t max_payload, ocp_header_t *out) {
  if (p[0] != OCP_MAGIC0 || p[1] != OCP_MAGIC1) return OC_ECORRUPT;
  out->version = p[2];
  out->type = p[3];
  out->length = oc_get_u32(p + 4);
  return out->length <= max_payload ? 0 : OC_ETOOBIG;
}

void ocp_reader_init(ocp_reader_t *r, uint32_t max_payload) {
  memset(r, 0, sizeof *r);
  r->max_payload = max_payload;
}

void ocp_reader_free(ocp_reader_t *r) {
  oc_buf_free(&r->buf);
  r->start = 0;
  r->err = 0;
}

int ocp_reader_feed(ocp_reader_t *r, const void *p, size_t n) {
  if (r->err) return r->err == OC_ENOMEM ? OC_ENOMEM : 0; /* the stream is dead: drop the bytes */
  if (!n) return 0;
  /* Compact first: what was returned is no longer needed (frames are valid until this call), so
   * the buffer holds at most one partial frame plus these bytes. */
  if (r->start) {
    size_t left = r->buf.len - r->start;
    if (left) memmove(r->buf.data, r->buf.data + r->start, left);
    r->buf.len = left;
    r->start = 0;
  }
  oc_buf_append(&r->buf, p, n);
  if (r->buf.err) {
    r->err = OC_ENOMEM;
    return OC_ENOMEM;
  }
  return 0;
}

int ocp_reader_next(ocp_reader_t *r, ocp_header_t *hdr, const uint8_t **payload) {
  if (r->err) return r->err;
  size_t left = r->buf.len - r->start;
  if (left < OCP_HEADER_BYTES) return 0;
  const uint8_t *p = r->buf.data + r->start;
  ocp_header_t h;
  int e = ocp_header_parse(p, r->max_payload, &h);
  if (e) {
    r->err = e;
    return e;
  }
  if (left - OCP_HEADER_BYTES < h.length) return 0;
  *hdr = h;
  *payload = p + OCP_HEADER_BYTES;
  r->start += OCP_HEADER_BYTES + (size_t)h.length;
  return 1;
}

size_t ocp_reader_pending(const ocp_reader_t *r) { return r->buf.len - r->start; }

size_t ocp_frame_begin(oc_buf_t *b, uint8_t version, uint8_t type) {
  size_t off = b->len;
  uint8_t *q = oc_buf_grow(b, OCP_HEADER_BYTES);
  if (q) {
    q[0] = OCP_MAGIC0;
    q[1] = OCP_MAGIC1;
    q[2] = version;
    q[3] = type;
    oc_put_u32(q + 4, 0);
  }
  return off;
}

void ocp_frame_end(oc_buf_t *b, size_t header_offset) {
  if (b->err || !b->data || b->len < header_offset + OCP_HEADER_BYTES) return;
  size_t n = b->len - header_offset - OCP_HEADER_BYTES;
  oc_put_u32(b->data + header_offset + 4, (uint32_t)n);
}

/*-*** Message layouts ***/

/* Every message's fixed part is one table of fields in wire order, read by one encoder (ocp__put) and
 * one decoder (ocp__get, ocp__check), so a field's width, place and rule are written down once. */

typedef enum {
  OCP__UINT,  /* unsigned integer of `wire` bytes; its member may be wider (kept_states is an int) */
  OCP__F64,   /* double */
  OCP__DVEC3, /* three doubles x, y, z */
  OCP__BYTES, /* `wire` raw bytes (a u8 array member of as many) */
  OCP__PAD,   /* reserved bytes: sent as zero, refused unless zero; no member */
  OCP__TAIL,  /* u16 length of the variable part that follows the fixed part (name, token, text) */
} ocp__kind_t;

typedef enum {
  OCP__ANY,     /* no check */
  OCP__NONZERO, /* integer ≠ 0 */
  OCP__MAX,     /* integer ≤ hi */
  OCP__IN,      /* integer in lo..hi */
  OCP__MASK,    /* integer with no bit outside hi */
  OCP__FINITE,  /* double or vector: finite */
  OCP__NONNEG,  /* double: finite and ≥ 0 */
  OCP__CLOSED,  /* double: finite and in [lo, hi] */
  OCP__OPEN,    /* double in (lo, hi) */
  OCP__UNIT,    /* vector: finite with |length − 1| ≤ hi */
} ocp__rule_t;

typedef struct {
  uint8_t kind;     /* ocp__kind_t */
  uint8_t wire;     /* bytes on the wire */
  uint8_t size;     /* bytes of the struct member; 0: none */
  uint16_t off;     /* offsetof the member */
  const char *name; /* as reasons name it */
  uint8_t rule;     /* ocp__rule_t */
  uint8_t viewer;   /* a viewer's field: see ocp__peer_t */
  double lo, hi;    /* the rule's bounds; OCP__UNIT: hi is the tolerance; OCP__TAIL: hi is the largest length */
} ocp__field_t;

_Static_assert(sizeof(oc_dvec3) == 24, "a vector member is three doubles, as on the wire");

typedef struct {
  const char *msg;          /* names the message in every reason */
  const ocp__field_t *field;
  size_t count;
  size_t base, bytes;       /* where the fixed part starts in the payload, and its length */
  size_t struct_size;       /* zeroed before decoding */
  int var;                  /* a variable part follows (its length: OCP__TAIL, or the frame's) */
} ocp__layout_t;

/* Table rows, each naming the member m of the message struct T: an integer of w wire bytes (a viewer's:
 * OCP__GRANT), a double, a vector, a byte array, reserved bytes, the variable part's length. */
#define OCP__M(T, m) (uint8_t) sizeof(((T *)0)->m), (uint16_t)offsetof(T, m), #m
#define OCP__INT(T, w, m, rule, lo, hi) {OCP__UINT, w, OCP__M(T, m), rule, 0, lo, hi}
#define OCP__GRANT(T, w, m, rule, lo, hi) {OCP__UINT, w, OCP__M(T, m), rule, 1, lo, hi}
#define OCP__DBL(T, m, rule, lo, hi) {OCP__F64, 8, OCP__M(T, m), rule, 0, lo, hi}
#define OCP__VEC(T, m, rule, tol) {OCP__DVEC3, 24, OCP__M(T, m), rule, 0, 0, tol}
#define OCP__RAW(T, m) {OCP__BYTES, sizeof(((T *)0)->m), OCP__M(T, m), OCP__ANY, 0, 0, 0}
#define OCP__RES(w) {OCP__PAD, w, 0, 0, "reserved", OCP__ANY, 0, 0, 0}
#define OCP__LEN(name, max) {OCP__TAIL, 2, 0, 0, name, OCP__ANY, 0, 0, max}
#define OCP__LAYOUT(msg, T, fields, base, bytes, var) \
  {msg, fields, sizeof fields / sizeof fields[0], base, bytes, sizeof(T), var}

#define OCP__T ocp_hello_t
static const ocp__field_t ocp__hello_fields[] = {
    OCP__INT(OCP__T, 2, min_version, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 2, max_version, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 1, role, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 1, max_depth, OCP__MAX, 0, OCP__MAX_DEPTH),
    {OCP__TAIL, 2, OCP__M(OCP__T, token_len), OCP__ANY, 0, 0, OCP_TOKEN_MAX},
    OCP__GRANT(OCP__T, 8, budget, OCP__NONZERO, 0, 0),
    OCP__GRANT(OCP__T, 4, slot_bytes, OCP__IN, 1, OCP__GPU_BYTES_MAX),
    OCP__GRANT(OCP__T, 4, record_bytes, OCP__IN, 1, OCP__GPU_BYTES_MAX),
    OCP__GRANT(OCP__T, 4, width, OCP__IN, 1, OCP__VIEWPORT_MAX),
    OCP__GRANT(OCP__T, 4, height, OCP__IN, 1, OCP__VIEWPORT_MAX),
    OCP__INT(OCP__T, 4, caps, OCP__MASK, 0, OCP_CAP_KNOWN),
    OCP__GRANT(OCP__T, 4, resume_session, OCP__ANY, 0, 0),
    OCP__GRANT(OCP__T, 8, resume_secret, OCP__ANY, 0, 0),
    OCP__GRANT(OCP__T, 8, held_epoch, OCP__ANY, 0, 0),
    OCP__GRANT(OCP__T, 8, held_checksum, OCP__ANY, 0, 0),
};
static const ocp__layout_t OCP__HELLO = OCP__LAYOUT("hello", OCP__T, ocp__hello_fields, 0, OCP__HELLO_BYTES, 1);
#undef OCP__T

#define OCP__T ocp_welcome_t
static const ocp__field_t ocp__welcome_fields[] = {
    OCP__INT(OCP__T, 2, version, OCP__NONZERO, 0, 0),
    OCP__INT(OCP__T, 1, flags, OCP__MASK, 0, OCP_WELCOME_RESUMED),
    OCP__INT(OCP__T, 1, kept_states, OCP__ANY, 0, 0), /* 0, 2 or 3: checked by ocp_get_welcome */
    OCP__INT(OCP__T, 4, session, OCP__NONZERO, 0, 0),
    OCP__INT(OCP__T, 8, secret, OCP__ANY, 0, 0),
    OCP__GRANT(OCP__T, 8, budget, OCP__NONZERO, 0, 0),
    OCP__GRANT(OCP__T, 4, slot_bytes, OCP__IN, 1, OCP__GPU_BYTES_MAX),
    OCP__GRANT(OCP__T, 4, record_bytes, OCP__IN, 1, OCP__GPU_BYTES_MAX),
    OCP__INT(OCP__T, 1, max_depth, OCP__MAX, 0, OCP__MAX_DEPTH),
    OCP__RES(3),
    OCP__INT(OCP__T, 4, features, OCP__ANY, 0, 0),
    OCP__DBL(OCP__T, epoch_period, OCP__NONNEG, 0, 0),
    OCP__DBL(OCP__T, planet_radius, OCP__NONNEG, 0, 0),
    OCP__DBL(OCP__T, time, OCP__FINITE, 0, 0),
    OCP__VEC(OCP__T, sun_dir, OCP__UNIT, OCP__SUN_TOL),
    OCP__DBL(OCP__T, albedo, OCP__CLOSED, 0, 1),
    OCP__DBL(OCP__T, ms_a, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, ms_b, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, ms_c, OCP__FINITE, 0, 0),
    OCP__INT(OCP__T, 4, ms_octaves, OCP__ANY, 0, 0),
    OCP__RES(4),
    OCP__DBL(OCP__T, cam_lat, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, cam_lon, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, cam_alt, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, cam_heading, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, cam_pitch, OCP__FINITE, 0, 0),
    OCP__DBL(OCP__T, cam_fov, OCP__FINITE, 0, 0),
    OCP__LEN("name length", OCP_NAME_MAX),
};
static const ocp__layout_t OCP__WELCOME = OCP__LAYOUT("welcome", OCP__T, ocp__welcome_fields, 0, OCP__WELCOME_BYTES, 1);
#undef OCP__T

#define OCP__T ocp_camera_t
static const ocp__field_t ocp__camera_fields[] = {
    OCP__VEC(OCP__T, pos, OCP__FINITE, 0),
    OCP__VEC(OCP__T, forward, OCP__UNIT, OCP__CAMERA_TOL),
    OCP__VEC(OCP__T, up, OCP__UNIT, OCP__CAMERA_TOL),
    OCP__DBL(OCP__T, vfov_deg, OCP__OPEN, 0, 180),
    OCP__INT(OCP__T, 4, width, OCP__IN, 1, OCP__VIEWPORT_MAX),
    OCP__INT(OCP__T, 4, height, OCP__IN, 1, OCP__VIEWPORT_MAX),
};
static const ocp__layout_t OCP__CAMERA = OCP__LAYOUT("camera", OCP__T, ocp__camera_fields, 0, OCP__CAMERA_BYTES, 0);
#undef OCP__T

static const ocp__field_t ocp__ack_fields[] = {
    OCP__INT(ocp_ack_t, 8, epoch, OCP__ANY, 0, 0),
    OCP__INT(ocp_ack_t, 8, checksum, OCP__ANY, 0, 0),
};
static const ocp__layout_t OCP__ACK = OCP__LAYOUT("ack", ocp_ack_t, ocp__ack_fields, 0, OCP__ACK_BYTES, 0);

static const ocp__field_t ocp__budget_fields[] = {
    OCP__INT(ocp_budget_t, 8, budget, OCP__ANY, 0, 0), /* ≠ 0: checked by ocp_get_budget */
    OCP__INT(ocp_budget_t, 8, epoch, OCP__ANY, 0, 0),
};
static const ocp__layout_t OCP__BUDGET = OCP__LAYOUT("budget", ocp_budget_t, ocp__budget_fields, 0, OCP__BUDGET_BYTES, 0);

static const ocp__field_t ocp__text_fields[] = {
    OCP__INT(ocp_text_msg_t, 4, code, OCP__ANY, 0, 0),
    OCP__LEN("text length", OCP_TEXT_MAX),
};
static const ocp__layout_t OCP__TEXT = OCP__LAYOUT("error/goodbye", ocp_text_msg_t, ocp__text_fields, 0, OCP__TEXT_BYTES, 1);

#define OCP__T ocp_epoch_begin_t
static const ocp__field_t ocp__epoch_begin_fields[] = {
    OCP__INT(OCP__T, 8, epoch, OCP__ANY, 0, 0),
    OCP__DBL(OCP__T, time, OCP__FINITE, 0, 0),
    OCP__VEC(OCP__T, sun_dir, OCP__UNIT, OCP__SUN_TOL),
    OCP__INT(OCP__T, 8, base_epoch, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, node_count, OCP__IN, 1, OC_STATE_MAX_NODES),
    OCP__INT(OCP__T, 4, brick_count, OCP__IN, 0, OC_STATE_MAX_BRICKS),
    OCP__INT(OCP__T, 4, bricks_sent, OCP__ANY, 0, 0),
    OCP__RES(4),
};
static const ocp__layout_t OCP__EPOCH_BEGIN =
    OCP__LAYOUT("epoch-begin", OCP__T, ocp__epoch_begin_fields, 0, OCP__EPOCH_BEGIN_BYTES, 0);
#undef OCP__T

static const ocp__field_t ocp__epoch_end_fields[] = {
    OCP__INT(ocp_epoch_end_t, 8, epoch, OCP__ANY, 0, 0),
    OCP__INT(ocp_epoch_end_t, 8, checksum, OCP__ANY, 0, 0),
};
static const ocp__layout_t OCP__EPOCH_END =
    OCP__LAYOUT("epoch-end", ocp_epoch_end_t, ocp__epoch_end_fields, 0, OCP__EPOCH_END_BYTES, 0);

#define OCP__T ocp_stats_t
static const ocp__field_t ocp__stats_fields[] = {
    OCP__INT(OCP__T, 8, epoch, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, leaves, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, splits, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, merges, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, deferred, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 8, coalesced, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 8, resident_bytes, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 8, wire_bytes, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 8, raw_bytes, OCP__ANY, 0, 0),
    OCP__DBL(OCP__T, plan_ms, OCP__NONNEG, 0, 0),
    OCP__DBL(OCP__T, produce_ms, OCP__NONNEG, 0, 0),
    OCP__RES(16), /* the listed fields fill 72 of the 88 bytes */
};
/* version 2 appends these */
static const ocp__field_t ocp__stats_v2_fields[] = {
    OCP__INT(OCP__T, 4, queue, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, produced, OCP__ANY, 0, 0),
    OCP__INT(OCP__T, 4, split_backlog, OCP__ANY, 0, 0),
    OCP__RES(4),
    OCP__RAW(OCP__T, age_p50),
    OCP__RAW(OCP__T, age_p99),
};
static const ocp__layout_t OCP__STATS = OCP__LAYOUT("stats", OCP__T, ocp__stats_fields, 0, OCP__STATS_BYTES, 0);
static const ocp__layout_t OCP__STATS_V2 = OCP__LAYOUT("stats", OCP__T, ocp__stats_v2_fields, OCP__STATS_BYTES,
                                                       OCP__STATS_V2_BYTES - OCP__STATS_BYTES, 0);
#undef OCP__T

static const ocp__field_t ocp__control_fields[] = {
    OCP__INT(ocp_control_t, 4, request, OCP__ANY, 0, 0),
    OCP__INT(ocp_control_t, 4, status, OCP__ANY, 0, 0), /* an int32; ≥ 0: checked by ocp_get_control */
};
static const ocp__layout_t OCP__CONTROL = OCP__LAYOUT("control", ocp_control_t, ocp__control_fields, 0, OCP__CONTROL_BYTES, 1);

/* An integer member of `size` bytes, widened. */
static uint64_t ocp__member_uint(const uint8_t *q, size_t size) {
  uint8_t u8;
  uint16_t u16;
  uint32_t u32;
  uint64_t u64;
  switch (size) {
    case 1: return memcpy(&u8, q, 1), u8;
    case 2: return memcpy(&u16, q, 2), u16;
    case 4: return memcpy(&u32, q, 4), u32;
    default: return memcpy(&u64, q, 8), u64;
  }
}

static void ocp__set_member_uint(uint8_t *q, size_t size, uint64_t v) {
  uint8_t u8 = (uint8_t)v;
  uint16_t u16 = (uint16_t)v;
  uint32_t u32 = (uint32_t)v;
  switch (size) {
    case 1: memcpy(q, &u8, 1); break;
    case 2: memcpy(q, &u16, 2); break;
    case 4: memcpy(q, &u32, 4); break;
    default: memcpy(q, &v, 8); break;
  }
}

static uint64_t ocp__wire_uint(const uint8_t *p, size_t wire) {
  switch (wire) {
    case 1: return oc_get_u8(p);
    case 2: return oc_get_u16(p);
    case 4: return oc_get_u32(p);
    default: return oc_get_u64(p);
  }
}

static void ocp__set_wire_uint(uint8_t *p, size_t wire, uint64_t v) {
  switch (wire) {
    case 1: oc_put_u8(p, (uint8_t)v); break;
    case 2: oc_put_u16(p, (uint16_t)v); break;
    case 4: oc_put_u32(p, (uint32_t)v); break;
    default: oc_put_u64(p, v); break;
  }
}

/* Appends the fixed part of m as laid out by l; `tail` is the OCP__TAIL length. */
static void ocp__put(oc_buf_t *b, const ocp__layout_t *l, const void *m, uint16_t tail) {
  uint8_t *q = oc_buf_grow(b, l->bytes);
  if (!q) return;
  const uint8_t *s = m;
  for (size_t i = 0; i < l->count; i++) {
    const ocp__field_t *f = &l->field[i];
    const uint8_t *v = s + f->off;
    switch (f->kind) {
      case OCP__UINT: ocp__set_wire_uint(q, f->wire, ocp__member_uint(v, f->size)); break;
      case OCP__DVEC3:
      case OCP__F64:
        for (size_t k = 0; k < f->wire; k += 8) {
          double d;
          memcpy(&d, v + k, 8);
          oc_put_f64(q + k, d);
        }
        break;
      case OCP__BYTES: memcpy(q, v, f->wire); break;
      case OCP__PAD: memset(q, 0, f->wire); break;
      case OCP__TAIL: oc_put_u16(q, tail); break;
    }
    q += f->wire;
  }
  assert(q == b->data + b->len); /* the table's widths add up to l->bytes */
}

/* Appends one whole frame: the fixed part of m, then `tail_len` bytes of tail. */
static void ocp__put_frame(oc_buf_t *b, uint8_t version, uint8_t type, const ocp__layout_t *l, const void *m,
                           const void *tail, size_t tail_len) {
  size_t h = ocp_frame_begin(b, version, type);
  ocp__put(b, l, m, (uint16_t)tail_len);
  if (tail_len) oc_buf_append(b, tail, tail_len);
  ocp_frame_end(b, h);
}

/* Reads the fixed part at p + l->base into m; checks nothing (ocp__check does). */
static void ocp__read(const ocp__layout_t *l, const uint8_t *p, void *m) {
  uint8_t *s = m;
  p += l->base;
  for (size_t i = 0; i < l->count; i++) {
    const ocp__field_t *f = &l->field[i];
    uint8_t *v = s + f->off;
    switch (f->kind) {
      case OCP__UINT: ocp__set_member_uint(v, f->size, ocp__wire_uint(p, f->wire)); break;
      case OCP__DVEC3:
      case OCP__F64:
        for (size_t k = 0; k < f->wire; k += 8) {
          double d = oc_get_f64(p + k);
          memcpy(v + k, &d, 8);
        }
        break;
      case OCP__BYTES: memcpy(v, p, f->wire); break;
      case OCP__PAD: break;
      case OCP__TAIL:
        if (f->size) ocp__set_member_uint(v, f->size, oc_get_u16(p));
        break;
    }
    p += f->wire;
  }
}


/*-*** Encoders ***/

void ocp_put_hello(oc_buf_t *b, const ocp_hello_t *m) {
  uint16_t t = m->token_len <= OCP_TOKEN_MAX ? m->token_len : OCP_TOKEN_MAX;
  ocp__put_frame(b, (uint8_t)m->max_version, OCP_MSG_HELLO, &OCP__HELLO, m, m->token, t);
}

void ocp_put_welcome(oc_buf_t *b, uint8_t version, const ocp_welcome_t *m) {
  ocp__put_frame(b, version, OCP_MSG_WELCOME, &OCP__WELCOME, m, m->name, strnlen(m->name, OCP_NAME_MAX));
}

void ocp_put_camera(oc_buf_t *b, uint8_t version, const ocp_camera_t *m) {
  ocp__put_frame(b, version, OCP_MSG_CAMERA, &OCP__CAMERA, m, NULL, 0);
}

void ocp_put_ack(oc_buf_t *b, uint8_t version, const ocp_ack_t *m) {
  ocp__put_frame(b, version, OCP_MSG_ACK, &OCP__ACK, m, NULL, 0);
}

void ocp_put_budget(oc_buf_t *b, uint8_t version, const ocp_budget_t *m) {
  ocp__put_frame(b, version, OCP_MSG_BUDGET, &OCP__BUDGET, m, NULL, 0);
}

void ocp_put_text(oc_buf_t *b, uint8_t version, uint8_t type, uint32_t code, const char *text) {
  size_t n = text ? strnlen(text, OCP_TEXT_MAX + 1) : 0;
  if (n > OCP_TEXT_MAX) {
    n = OCP_TEXT_MAX;
    /* never cut inside a UTF-8 sequence: back up over continuation bytes */
    while (n > 0 && ((uint8_t)text[n] & 0xC0) == 0x80) n--;
  }
  ocp_text_msg_t m = {.code = code};
  ocp__put_frame(b, version, type, &OCP__TEXT, &m, text, n);
}

void ocp_put_empty(oc_buf_t *b, uint8_t version, uint8_t type) {
  size_t h = ocp_frame_begin(b, version, type);
  ocp_frame_end(b, h);
}

void ocp_put_epoch_begin(oc_buf_t *b, uint8_t version, const ocp_epoch_begin_t *m) {
  ocp__put_frame(b, version, OCP_MSG_EPOCH_BEGIN, &OCP__EPOCH_BEGIN, m, NULL, 0);
}

void ocp_put_epoch_end(oc_buf_t *b, uint8_t version, const ocp_epoch_end_t *m) {
  ocp__put_frame(b, version, OCP_MSG_EPOCH_END, &OCP__EPOCH_END, m, NULL, 0);
}

void ocp_put_stats(oc_buf_t *b, uint8_t version, const ocp_stats_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_STATS);
  ocp__put(b, &OCP__STATS, m, 0);
  if (version >= 2) ocp__put(b, &OCP__STATS_V2, m, 0);
  ocp_frame_end(b, h);
}

void ocp_put_control(oc_buf_t *b, uint8_t version, uint8_t type, const ocp_control_t *m) {
  ocp__put_frame(b, version, type, &OCP__CONTROL, m, m->json, m->json_len);
}

/*-*** Decoders ***/

static void ocp__why_clear(char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
}

/* The payload length must be exactly `want`: names the message and both lengths. */
static int ocp__exact(const char *msg, size_t n, size_t want, char *why, size_t why_len) {
  if (n == want) return 0;
  return oc_errorf(OC_ECORRUPT, why, why_len, "%s: payload is %zu bytes, expected %zu", msg, n, want);
}

/* Starts a decoder: clears why and m, checks the payload length n (exactly l->bytes, or at least that when a
 * variable part follows) and reads the fixed part. @return 0 or OC_ECORRUPT. */
static int ocp__get(const ocp__layout_t *l, const uint8_t *p, size_t n, void *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, l->struct_size);
  if (!l->var) OC_TRY(ocp__exact(l->msg, n, l->bytes, why, why_len));
  if (n < l->bytes)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: payload is %zu bytes, shorter than %zu", l->msg, n, l->bytes);
  ocp__read(l, p, m);
  return 0;
}

/* The variable part after l's fixed part, as long as its OCP__TAIL field says (at most that field's hi) and
 * filling the rest of the payload, is copied to dst. `text` names it when it must hold no NUL byte. */
static int ocp__get_tail(const ocp__layout_t *l, const uint8_t *p, size_t n, const char *text, void *dst, char *why,
                         size_t why_len) {
  size_t pos = 0;
  const ocp__field_t *f = l->field;
  while (f->kind != OCP__TAIL) pos += f++->wire;
  uint16_t len = oc_get_u16(p + pos);
  if (len > f->hi)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %u is above %u", l->msg, f->name, (unsigned)len, (unsigned)f->hi);
  OC_TRY(ocp__exact(l->msg, n, l->bytes + len, why, why_len));
  const uint8_t *q = p + l->bytes;
  if (text && len && memchr(q, 0, len)) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s contains a NUL byte", l->msg, text);
  if (len) memcpy(dst, q, len);
  return 0;
}

static int ocp__dvec3_finite(oc_dvec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/* Finite with |len − 1| ≤ tol. */
static int ocp__check_unit(const char *msg, const char *field, oc_dvec3 v, double tol, char *why, size_t why_len) {
  if (!ocp__dvec3_finite(v)) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is not finite", msg, field);
  double len = oc_dlen(v);
  if (!(fabs(len - 1.0) <= tol))
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s (%g, %g, %g) is not a unit vector", msg, field, v.x, v.y, v.z);
  return 0;
}

static int ocp__check_uint(const char *msg, const ocp__field_t *f, uint64_t x, char *why, size_t why_len) {
  uint64_t lo = (uint64_t)f->lo, hi = (uint64_t)f->hi;
  switch (f->rule) {
    case OCP__NONZERO:
      return x ? 0 : oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is zero", msg, f->name);
    case OCP__MAX:
      return x <= hi ? 0 : oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %" PRIu64 " is above %" PRIu64, msg, f->name, x, hi);
    case OCP__IN:
      if (x >= lo && x <= hi) return 0;
      return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %" PRIu64 " is outside %" PRIu64 "..%" PRIu64, msg, f->name, x, lo, hi);
    case OCP__MASK:
      return !(x & ~hi) ? 0 : oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s 0x%" PRIx64 " has unknown bits", msg, f->name, x);
    default:
      return 0;
  }
}

static int ocp__check_f64(const char *msg, const ocp__field_t *f, double x, char *why, size_t why_len) {
  if (f->rule != OCP__ANY && f->rule != OCP__OPEN && !isfinite(x))
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is not finite", msg, f->name);
  if (f->rule == OCP__NONNEG && x < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %g is negative", msg, f->name, x);
  if (f->rule == OCP__CLOSED && (x < f->lo || x > f->hi))
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %g is outside [%g, %g]", msg, f->name, x, f->lo, f->hi);
  if (f->rule == OCP__OPEN && !(x > f->lo && x < f->hi))
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %g is outside (%g, %g)", msg, f->name, x, f->lo, f->hi);
  return 0;
}

/* Whom a message's viewer fields (OCP__GRANT) come from: a viewer's are held to their rules, a control
 * client's must be zero, and in a WELCOME without a grant they are not looked at. */
typedef enum { OCP__PEER_VIEWER, OCP__PEER_CONTROL, OCP__PEER_NO_GRANT } ocp__peer_t;

/* Checks the fields of l read into m, in wire order (reserved bytes from the payload p). */
static int ocp__check(const ocp__layout_t *l, const uint8_t *p, const void *m, ocp__peer_t peer, char *why, size_t why_len) {
  const uint8_t *s = m;
  size_t pos = l->base;
  for (size_t i = 0; i < l->count; pos += l->field[i].wire, i++) {
    const ocp__field_t *f = &l->field[i];
    const uint8_t *v = s + f->off;
    if (f->viewer && peer == OCP__PEER_NO_GRANT) continue;
    if (f->viewer && peer == OCP__PEER_CONTROL) {
      if (ocp__member_uint(v, f->size)) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s (control) is not zero", l->msg, f->name);
      continue;
    }
    if (f->kind == OCP__UINT) OC_TRY(ocp__check_uint(l->msg, f, ocp__member_uint(v, f->size), why, why_len));
    if (f->kind == OCP__F64) {
      double x;
      memcpy(&x, v, sizeof x);
      OC_TRY(ocp__check_f64(l->msg, f, x, why, why_len));
    }
    if (f->kind == OCP__DVEC3) {
      oc_dvec3 d;
      memcpy(&d, v, sizeof d);
      if (f->rule == OCP__FINITE && !ocp__dvec3_finite(d))
        return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is not finite", l->msg, f->name);
      if (f->rule == OCP__UNIT) OC_TRY(ocp__check_unit(l->msg, f->name, d, f->hi, why, why_len));
    }
    if (f->kind == OCP__PAD)
      for (size_t k = 0; k < f->wire; k++)
        if (p[pos + k])
          return oc_errorf(OC_ECORRUPT, why, why_len, "%s: reserved bytes %zu..%zu are not zero", l->msg, pos, pos + f->wire - 1);
  }
  return 0;
}

int ocp_get_hello(const uint8_t *p, size_t n, ocp_hello_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__HELLO, p, n, m, why, why_len));
  OC_TRY(ocp__get_tail(&OCP__HELLO, p, n, NULL, m->token, why, why_len));
  if (m->min_version > m->max_version)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: min_version %u is above max_version %u", (unsigned)m->min_version,
                     (unsigned)m->max_version);
  if (m->role != OCP_ROLE_VIEWER && m->role != OCP_ROLE_CONTROL)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: role %u is neither viewer (0) nor control (1)", (unsigned)m->role);
  /* a control client's viewer fields are zero */
  OC_TRY(ocp__check(&OCP__HELLO, p, m, m->role == OCP_ROLE_VIEWER ? OCP__PEER_VIEWER : OCP__PEER_CONTROL, why, why_len));
  if ((m->caps & OCP_CAP_DIGEST) && (m->caps & OCP_CAP_DELTA))
    return oc_errorf(OC_ECORRUPT, why, why_len,
                     "hello: caps 0x%" PRIx32 " combine digest (0x4) with delta (0x1): a viewer without codes cannot apply deltas",
                     m->caps);
  return 0;
}

int ocp_get_welcome(const uint8_t *p, size_t n, ocp_welcome_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__WELCOME, p, n, m, why, why_len));
  OC_TRY(ocp__get_tail(&OCP__WELCOME, p, n, "name", m->name, why, why_len));
  if (m->kept_states != 0 && m->kept_states != 2 && m->kept_states != 3)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: kept_states %u is not 0, 2 or 3", (unsigned)m->kept_states);
  /* kept_states 0: a control client's WELCOME, without a grant */
  return ocp__check(&OCP__WELCOME, p, m, m->kept_states ? OCP__PEER_VIEWER : OCP__PEER_NO_GRANT, why, why_len);
}

int ocp_get_camera(const uint8_t *p, size_t n, ocp_camera_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__CAMERA, p, n, m, why, why_len));
  OC_TRY(ocp__check(&OCP__CAMERA, p, m, OCP__PEER_VIEWER, why, why_len));
  double d = oc_ddot(m->forward, m->up);
  if (!(fabs(d) <= OCP__CAMERA_TOL))
    return oc_errorf(OC_ECORRUPT, why, why_len, "camera: forward and up are not orthogonal (dot %g)", d);
  return 0;
}

int ocp_get_ack(const uint8_t *p, size_t n, ocp_ack_t *m, char *why, size_t why_len) {
  return ocp__get(&OCP__ACK, p, n, m, why, why_len);
}

int ocp_get_budget(const uint8_t *p, size_t n, ocp_budget_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__BUDGET, p, n, m, why, why_len));
  if (m->budget == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "budget: budget is 0");
  return 0;
}

uint32_t ocp_reconnect_delay_ms(const char *text) {
  uint64_t ms = 0;
  int digits = 0;
  for (; text && *text >= '0' && *text <= '9' && digits < 9; text++, digits++) ms = ms * 10 + (uint64_t)(*text - '0');
  return digits && !strncmp(text, " ms", 3) ? (uint32_t)ms : 0;
}

int ocp_get_text(const uint8_t *p, size_t n, ocp_text_msg_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__TEXT, p, n, m, why, why_len));
  return ocp__get_tail(&OCP__TEXT, p, n, "text", m->text, why, why_len);
}

int ocp_get_empty(const uint8_t *p, size_t n, char *why, size_t why_len) {
  (void)p;
  ocp__why_clear(why, why_len);
  return ocp__exact("keepalive", n, 0, why, why_len);
}

int ocp_get_epoch_begin(const uint8_t *p, size_t n, ocp_epoch_begin_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__EPOCH_BEGIN, p, n, m, why, why_len));
  OC_TRY(ocp__check(&OCP__EPOCH_BEGIN, p, m, OCP__PEER_VIEWER, why, why_len));
  /* epochs only move forward, so a base is always older than the state built on it */
  if (m->base_epoch != OCP_NO_BASE && m->base_epoch >= m->epoch)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: base_epoch %" PRIu64 " is not before epoch %" PRIu64, m->base_epoch,
                     m->epoch);
  if (m->bricks_sent > m->brick_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: bricks_sent %" PRIu32 " is above brick_count %" PRIu32, m->bricks_sent,
                     m->brick_count);
  if (m->brick_count > m->node_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: brick_count %" PRIu32 " is above node_count %" PRIu32, m->brick_count,
                     m->node_count);
  return 0;
}

int ocp_get_epoch_end(const uint8_t *p, size_t n, ocp_epoch_end_t *m, char *why, size_t why_len) {
  return ocp__get(&OCP__EPOCH_END, p, n, m, why, why_len);
}

int ocp_get_stats(uint8_t version, const uint8_t *p, size_t n, ocp_stats_t *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact("stats", n, version >= 2 ? OCP__STATS_V2_BYTES : OCP__STATS_BYTES, why, why_len));
  ocp__read(&OCP__STATS, p, m);
  OC_TRY(ocp__check(&OCP__STATS, p, m, OCP__PEER_VIEWER, why, why_len));
  if (version >= 2) {
    ocp__read(&OCP__STATS_V2, p, m);
    OC_TRY(ocp__check(&OCP__STATS_V2, p, m, OCP__PEER_VIEWER, why, why_len));
    for (int l = 0; l < OCP_STATS_LEVELS; l++)
      if (m->age_p50[l] > m->age_p99[l])
        return oc_errorf(OC_ECORRUPT, why, why_len, "stats: level %d's age p50 %u is over its p99 %u", l, m->age_p50[l],
                         m->age_p99[l]);
  }
  return 0;
}

int ocp_get_control(const uint8_t *p, size_t n, ocp_control_t *m, char *why, size_t why_len) {
  OC_TRY(ocp__get(&OCP__CONTROL, p, n, m, why, why_len));
  if (n - OCP__CONTROL_BYTES > OCP__CONTROL_JSON_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "control: json of %zu bytes is above %u", n - OCP__CONTROL_BYTES,
                     (unsigned)OCP__CONTROL_JSON_MAX);
  m->json_len = (uint32_t)(n - OCP__CONTROL_BYTES);
  m->json = (const char *)p + OCP__CONTROL_BYTES;
  if (m->status < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "control: status %" PRId32 " is negative", m->status);
  if (m->json_len && memchr(m->json, 0, m->json_len)) return oc_errorf(OC_ECORRUPT, why, why_len, "control: json contains a NUL byte");
  return 0;
}

/*-*** Any message by its type ***/

int ocp_get_msg(uint8_t version, uint8_t type, const uint8_t *p, size_t n, ocp_msg_t *m, char *why, size_t why_len) {
  switch (type) {
    case OCP_MSG_HELLO:
      return ocp_get_hello(p, n, &m->hello, why, why_len);
    case OCP_MSG_WELCOME:
      return ocp_get_welcome(p, n, &m->welcome, why, why_len);
    case OCP_MSG_CAMERA:
      return ocp_get_camera(p, n, &m->camera, why, why_len);
    case OCP_MSG_ACK:
      return ocp_get_ack(p, n, &m->ack, why, why_len);
    case OCP_MSG_BUDGET:
      return ocp_get_budget(p, n, &m->budget, why, why_len);
    case OCP_MSG_ERROR:
    case OCP_MSG_GOODBYE:
      return ocp_get_text(p, n, &m->text, why, why_len);
    case OCP_MSG_KEEPALIVE:
      return ocp_get_empty(p, n, why, why_len);
    case OCP_MSG_EPOCH_BEGIN:
      return ocp_get_epoch_begin(p, n, &m->begin, why, why_len);
    case OCP_MSG_EPOCH_END:
      return ocp_get_epoch_end(p, n, &m->end, why, why_len);
    case OCP_MSG_STATS:
      return ocp_get_stats(version, p, n, &m->stats, why, why_len);
    case OCP_MSG_CONTROL:
    case OCP_MSG_CONTROL_REPLY:
      return ocp_get_control(p, n, &m->control, why, why_len);
    default:
      return 1;
  }
}

void ocp_put_msg(oc_buf_t *b, uint8_t version, uint8_t type, const ocp_msg_t *m) {
  switch (type) {
    case OCP_MSG_HELLO: ocp_put_hello(b, &m->hello); break;
    case OCP_MSG_WELCOME: ocp_put_welcome(b, version, &m->welcome); break;
    case OCP_MSG_CAMERA: ocp_put_camera(b, version, &m->camera); break;
    case OCP_MSG_ACK: ocp_put_ack(b, version, &m->ack); break;
    case OCP_MSG_BUDGET: ocp_put_budget(b, version, &m->budget); break;
    case OCP_MSG_ERROR:
    case OCP_MSG_GOODBYE: ocp_put_text(b, version, type, m->text.code, m->text.text); break;
    case OCP_MSG_KEEPALIVE: ocp_put_empty(b, version, type); break;
    case OCP_MSG_EPOCH_BEGIN: ocp_put_epoch_begin(b, version, &m->begin); break;
    case OCP_MSG_EPOCH_END: ocp_put_epoch_end(b, version, &m->end); break;
    case OCP_MSG_STATS: ocp_put_stats(b, version, &m->stats); break;
    case OCP_MSG_CONTROL:
    case OCP_MSG_CONTROL_REPLY: ocp_put_control(b, version, type, &m->control); break;
    default: break;
  }
}
