/* ocp_wire.c — frames and messages of the Overcast wire protocol (ocp_wire.h; docs/protocol.md,
 * "Wire").
 *
 * Encoders pack field by field through oc_bytes.h; decoders read through an oc_reader_t after
 * checking the exact payload length first, so a short or long payload is reported as such rather
 * than as whatever field happened to be cut. Every check a decoder makes is one an honest peer
 * never fails: the code above sees only well-formed messages. */
#include "ocp_wire.h"

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

const char *ocp_msg_name(int type) {
  switch (type) {
#define OCP__MSG_NAME(name, val, str) \
  case (val):                         \
    return str;
    OCP_MSG_MAP(OCP__MSG_NAME)
#undef OCP__MSG_NAME
    default:
      return NULL;
  }
}

const char *ocp_code_text(uint32_t code) {
  switch (code) {
#define OCP__CODE_TEXT(name, val, str) \
  case (val):                          \
    return str;
    OCP_CODE_MAP(OCP__CODE_TEXT)
#undef OCP__CODE_TEXT
    default:
      return "unknown code";
  }
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

/*-*** Encoders ***/

void ocp_put_hello(oc_buf_t *b, const ocp_hello_t *m) {
  uint16_t t = m->token_len <= OCP_TOKEN_MAX ? m->token_len : OCP_TOKEN_MAX;
  size_t h = ocp_frame_begin(b, (uint8_t)m->max_version, OCP_MSG_HELLO);
  oc_buf_u16(b, m->min_version);
  oc_buf_u16(b, m->max_version);
  oc_buf_u8(b, m->role);
  oc_buf_u8(b, m->max_depth);
  oc_buf_u16(b, t);
  oc_buf_u64(b, m->budget);
  oc_buf_u32(b, m->slot_bytes);
  oc_buf_u32(b, m->record_bytes);
  oc_buf_u32(b, m->width);
  oc_buf_u32(b, m->height);
  oc_buf_u32(b, m->caps);
  oc_buf_u32(b, m->resume_session);
  oc_buf_u64(b, m->resume_secret);
  oc_buf_u64(b, m->held_epoch);
  oc_buf_u64(b, m->held_checksum);
  oc_buf_append(b, m->token, t);
  ocp_frame_end(b, h);
}

void ocp_put_welcome(oc_buf_t *b, uint8_t version, const ocp_welcome_t *m) {
  size_t n = strnlen(m->name, OCP_NAME_MAX);
  size_t h = ocp_frame_begin(b, version, OCP_MSG_WELCOME);
  oc_buf_u16(b, m->version);
  oc_buf_u8(b, m->flags);
  oc_buf_u8(b, m->kept_states);
  oc_buf_u32(b, m->session);
  oc_buf_u64(b, m->secret);
  oc_buf_u64(b, m->budget);
  oc_buf_u32(b, m->slot_bytes);
  oc_buf_u32(b, m->record_bytes);
  oc_buf_u8(b, m->max_depth);
  oc_buf_u8(b, 0); /* reserved 33..35 */
  oc_buf_u16(b, 0);
  oc_buf_u32(b, m->features);
  oc_buf_f64(b, m->epoch_period);
  oc_buf_f64(b, m->planet_radius);
  oc_buf_f64(b, m->time);
  oc_buf_f64(b, m->sun_dir.x);
  oc_buf_f64(b, m->sun_dir.y);
  oc_buf_f64(b, m->sun_dir.z);
  oc_buf_f64(b, m->albedo);
  oc_buf_f64(b, m->ms_a);
  oc_buf_f64(b, m->ms_b);
  oc_buf_f64(b, m->ms_c);
  oc_buf_u32(b, m->ms_octaves);
  oc_buf_u32(b, 0); /* reserved 124..127 */
  oc_buf_f64(b, m->cam_lat);
  oc_buf_f64(b, m->cam_lon);
  oc_buf_f64(b, m->cam_alt);
  oc_buf_f64(b, m->cam_heading);
  oc_buf_f64(b, m->cam_pitch);
  oc_buf_f64(b, m->cam_fov);
  oc_buf_u16(b, (uint16_t)n);
  oc_buf_append(b, m->name, n);
  ocp_frame_end(b, h);
}

static void ocp__buf_dvec3(oc_buf_t *b, oc_dvec3 v) {
  oc_buf_f64(b, v.x);
  oc_buf_f64(b, v.y);
  oc_buf_f64(b, v.z);
}

void ocp_put_camera(oc_buf_t *b, uint8_t version, const ocp_camera_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_CAMERA);
  ocp__buf_dvec3(b, m->pos);
  ocp__buf_dvec3(b, m->forward);
  ocp__buf_dvec3(b, m->up);
  oc_buf_f64(b, m->vfov_deg);
  oc_buf_u32(b, m->width);
  oc_buf_u32(b, m->height);
  ocp_frame_end(b, h);
}

void ocp_put_ack(oc_buf_t *b, uint8_t version, const ocp_ack_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_ACK);
  oc_buf_u64(b, m->epoch);
  oc_buf_u64(b, m->checksum);
  ocp_frame_end(b, h);
}

void ocp_put_budget(oc_buf_t *b, uint8_t version, const ocp_budget_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_BUDGET);
  oc_buf_u64(b, m->budget);
  oc_buf_u64(b, m->epoch);
  ocp_frame_end(b, h);
}

void ocp_put_text(oc_buf_t *b, uint8_t version, uint8_t type, uint32_t code, const char *text) {
  size_t n = text ? strnlen(text, OCP_TEXT_MAX + 1) : 0;
  if (n > OCP_TEXT_MAX) {
    n = OCP_TEXT_MAX;
    /* never cut inside a UTF-8 sequence: back up over continuation bytes */
    while (n > 0 && ((uint8_t)text[n] & 0xC0) == 0x80) n--;
  }
  size_t h = ocp_frame_begin(b, version, type);
  oc_buf_u32(b, code);
  oc_buf_u16(b, (uint16_t)n);
  oc_buf_append(b, text, n);
  ocp_frame_end(b, h);
}

void ocp_put_empty(oc_buf_t *b, uint8_t version, uint8_t type) {
  size_t h = ocp_frame_begin(b, version, type);
  ocp_frame_end(b, h);
}

void ocp_put_epoch_begin(oc_buf_t *b, uint8_t version, const ocp_epoch_begin_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_EPOCH_BEGIN);
  oc_buf_u64(b, m->epoch);
  oc_buf_f64(b, m->time);
  ocp__buf_dvec3(b, m->sun_dir);
  oc_buf_u64(b, m->base_epoch);
  oc_buf_u32(b, m->node_count);
  oc_buf_u32(b, m->brick_count);
  oc_buf_u32(b, m->bricks_sent);
  oc_buf_u32(b, 0); /* reserved */
  ocp_frame_end(b, h);
}

void ocp_put_epoch_end(oc_buf_t *b, uint8_t version, const ocp_epoch_end_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_EPOCH_END);
  oc_buf_u64(b, m->epoch);
  oc_buf_u64(b, m->checksum);
  ocp_frame_end(b, h);
}

void ocp_put_stats(oc_buf_t *b, uint8_t version, const ocp_stats_t *m) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_STATS);
  oc_buf_u64(b, m->epoch);
  oc_buf_u32(b, m->leaves);
  oc_buf_u32(b, m->splits);
  oc_buf_u32(b, m->merges);
  oc_buf_u32(b, m->deferred);
  oc_buf_u64(b, m->coalesced);
  oc_buf_u64(b, m->resident_bytes);
  oc_buf_u64(b, m->wire_bytes);
  oc_buf_u64(b, m->raw_bytes);
  oc_buf_f64(b, m->plan_ms);
  oc_buf_f64(b, m->produce_ms);
  oc_buf_u64(b, 0); /* reserved 72..87: the listed fields fill 72 of the 88 bytes */
  oc_buf_u64(b, 0);
  if (version >= 2) {
    oc_buf_u32(b, m->queue);
    oc_buf_u32(b, m->produced);
    oc_buf_u32(b, m->split_backlog);
    oc_buf_u32(b, 0); /* reserved 100..103 */
    oc_buf_append(b, m->age_p50, OCP_STATS_LEVELS);
    oc_buf_append(b, m->age_p99, OCP_STATS_LEVELS);
  }
  ocp_frame_end(b, h);
}

void ocp_put_control(oc_buf_t *b, uint8_t version, uint8_t type, const ocp_control_t *m) {
  size_t h = ocp_frame_begin(b, version, type);
  oc_buf_u32(b, m->request);
  oc_buf_u32(b, (uint32_t)m->status);
  if (m->json_len) oc_buf_append(b, m->json, m->json_len);
  ocp_frame_end(b, h);
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

static oc_dvec3 ocp__read_dvec3(oc_reader_t *r) {
  oc_dvec3 v;
  v.x = oc_read_f64(r);
  v.y = oc_read_f64(r);
  v.z = oc_read_f64(r);
  return v;
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

static int ocp__check_finite(const char *msg, const char *field, double x, char *why, size_t why_len) {
  return isfinite(x) ? 0 : oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is not finite", msg, field);
}

static int ocp__check_range_u32(const char *msg, const char *field, uint32_t x, uint32_t lo, uint32_t hi, char *why,
                                size_t why_len) {
  if (x >= lo && x <= hi) return 0;
  return oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s %" PRIu32 " is outside %" PRIu32 "..%" PRIu32, msg, field, x, lo, hi);
}

static int ocp__check_zero(const char *msg, const char *field, uint64_t x, char *why, size_t why_len) {
  return x == 0 ? 0 : oc_errorf(OC_ECORRUPT, why, why_len, "%s: %s is not zero", msg, field);
}

int ocp_get_hello(const uint8_t *p, size_t n, ocp_hello_t *m, char *why, size_t why_len) {
  static const char *msg = "hello";
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  if (n < OCP__HELLO_BYTES)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: payload is %zu bytes, shorter than %d", n, OCP__HELLO_BYTES);
  oc_reader_t r = oc_reader(p, n);
  m->min_version = oc_read_u16(&r);
  m->max_version = oc_read_u16(&r);
  m->role = oc_read_u8(&r);
  m->max_depth = oc_read_u8(&r);
  m->token_len = oc_read_u16(&r);
  m->budget = oc_read_u64(&r);
  m->slot_bytes = oc_read_u32(&r);
  m->record_bytes = oc_read_u32(&r);
  m->width = oc_read_u32(&r);
  m->height = oc_read_u32(&r);
  m->caps = oc_read_u32(&r);
  m->resume_session = oc_read_u32(&r);
  m->resume_secret = oc_read_u64(&r);
  m->held_epoch = oc_read_u64(&r);
  m->held_checksum = oc_read_u64(&r);
  if (m->token_len > OCP_TOKEN_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: token_len %u is above %d", (unsigned)m->token_len, OCP_TOKEN_MAX);
  OC_TRY(ocp__exact(msg, n, (size_t)OCP__HELLO_BYTES + m->token_len, why, why_len));
  const uint8_t *tok = oc_reader_take(&r, m->token_len);
  if (r.err || !tok) return oc_errorf(OC_ECORRUPT, why, why_len, "hello: truncated"); /* cannot happen after the length check */
  if (m->token_len) memcpy(m->token, tok, m->token_len);
  if (m->min_version > m->max_version)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: min_version %u is above max_version %u", (unsigned)m->min_version,
                     (unsigned)m->max_version);
  if (m->role != OCP_ROLE_VIEWER && m->role != OCP_ROLE_CONTROL)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: role %u is neither viewer (0) nor control (1)", (unsigned)m->role);
  if (m->max_depth > OCP__MAX_DEPTH)
    return oc_errorf(OC_ECORRUPT, why, why_len, "hello: max_depth %u is above %d", (unsigned)m->max_depth, OCP__MAX_DEPTH);
  if (m->caps & ~OCP_CAP_KNOWN) return oc_errorf(OC_ECORRUPT, why, why_len, "hello: caps 0x%" PRIx32 " has unknown bits", m->caps);
  if ((m->caps & OCP_CAP_DIGEST) && (m->caps & OCP_CAP_DELTA))
    return oc_errorf(OC_ECORRUPT, why, why_len,
                     "hello: caps 0x%" PRIx32 " combine digest (0x4) with delta (0x1): a viewer without codes cannot apply deltas",
                     m->caps);
  if (m->role == OCP_ROLE_VIEWER) {
    if (m->budget == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "hello: budget is zero");
    OC_TRY(ocp__check_range_u32(msg, "slot_bytes", m->slot_bytes, 1, OCP__GPU_BYTES_MAX, why, why_len));
    OC_TRY(ocp__check_range_u32(msg, "record_bytes", m->record_bytes, 1, OCP__GPU_BYTES_MAX, why, why_len));
    OC_TRY(ocp__check_range_u32(msg, "width", m->width, 1, OCP__VIEWPORT_MAX, why, why_len));
    OC_TRY(ocp__check_range_u32(msg, "height", m->height, 1, OCP__VIEWPORT_MAX, why, why_len));
  } else { /* control: the viewer-only fields are zero */
    OC_TRY(ocp__check_zero(msg, "budget (control)", m->budget, why, why_len));
    OC_TRY(ocp__check_zero(msg, "slot_bytes (control)", m->slot_bytes, why, why_len));
    OC_TRY(ocp__check_zero(msg, "record_bytes (control)", m->record_bytes, why, why_len));
    OC_TRY(ocp__check_zero(msg, "width (control)", m->width, why, why_len));
    OC_TRY(ocp__check_zero(msg, "height (control)", m->height, why, why_len));
    OC_TRY(ocp__check_zero(msg, "resume_session (control)", m->resume_session, why, why_len));
    OC_TRY(ocp__check_zero(msg, "resume_secret (control)", m->resume_secret, why, why_len));
    OC_TRY(ocp__check_zero(msg, "held_epoch (control)", m->held_epoch, why, why_len));
    OC_TRY(ocp__check_zero(msg, "held_checksum (control)", m->held_checksum, why, why_len));
  }
  return 0;
}

int ocp_get_welcome(const uint8_t *p, size_t n, ocp_welcome_t *m, char *why, size_t why_len) {
  static const char *msg = "welcome";
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  if (n < OCP__WELCOME_BYTES)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: payload is %zu bytes, shorter than %d", n, OCP__WELCOME_BYTES);
  oc_reader_t r = oc_reader(p, n);
  m->version = oc_read_u16(&r);
  m->flags = oc_read_u8(&r);
  m->kept_states = oc_read_u8(&r);
  m->session = oc_read_u32(&r);
  m->secret = oc_read_u64(&r);
  m->budget = oc_read_u64(&r);
  m->slot_bytes = oc_read_u32(&r);
  m->record_bytes = oc_read_u32(&r);
  m->max_depth = oc_read_u8(&r);
  uint32_t res0 = oc_read_u8(&r);
  res0 |= oc_read_u16(&r);
  m->features = oc_read_u32(&r);
  m->epoch_period = oc_read_f64(&r);
  m->planet_radius = oc_read_f64(&r);
  m->time = oc_read_f64(&r);
  m->sun_dir = ocp__read_dvec3(&r);
  m->albedo = oc_read_f64(&r);
  m->ms_a = oc_read_f64(&r);
  m->ms_b = oc_read_f64(&r);
  m->ms_c = oc_read_f64(&r);
  m->ms_octaves = oc_read_u32(&r);
  uint32_t res1 = oc_read_u32(&r);
  m->cam_lat = oc_read_f64(&r);
  m->cam_lon = oc_read_f64(&r);
  m->cam_alt = oc_read_f64(&r);
  m->cam_heading = oc_read_f64(&r);
  m->cam_pitch = oc_read_f64(&r);
  m->cam_fov = oc_read_f64(&r);
  uint16_t name_len = oc_read_u16(&r);
  if (name_len > OCP_NAME_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: name length %u is above %d", (unsigned)name_len, OCP_NAME_MAX);
  OC_TRY(ocp__exact(msg, n, (size_t)OCP__WELCOME_BYTES + name_len, why, why_len));
  const uint8_t *name = oc_reader_take(&r, name_len);
  if (r.err || !name) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: truncated");
  if (name_len && memchr(name, 0, name_len)) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: name contains a NUL byte");
  if (name_len) memcpy(m->name, name, name_len);
  m->name[name_len] = '\0';
  if (m->version == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: version is zero");
  if (m->flags & ~OCP_WELCOME_RESUMED)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: flags 0x%x has unknown bits", (unsigned)m->flags);
  if (m->kept_states != 0 && m->kept_states != 2 && m->kept_states != 3)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: kept_states %u is not 0, 2 or 3", (unsigned)m->kept_states);
  if (m->session == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: session is zero");
  if (m->max_depth > OCP__MAX_DEPTH)
    return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: max_depth %u is above %d", (unsigned)m->max_depth, OCP__MAX_DEPTH);
  if (res0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: reserved bytes 33..35 are not zero");
  if (res1) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: reserved bytes 124..127 are not zero");
  if (m->kept_states) { /* a viewer's grant */
    if (m->budget == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: budget is zero");
    OC_TRY(ocp__check_range_u32(msg, "slot_bytes", m->slot_bytes, 1, OCP__GPU_BYTES_MAX, why, why_len));
    OC_TRY(ocp__check_range_u32(msg, "record_bytes", m->record_bytes, 1, OCP__GPU_BYTES_MAX, why, why_len));
  }
  OC_TRY(ocp__check_finite(msg, "epoch_period", m->epoch_period, why, why_len));
  if (m->epoch_period < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: epoch_period %g is negative", m->epoch_period);
  OC_TRY(ocp__check_finite(msg, "planet_radius", m->planet_radius, why, why_len));
  if (m->planet_radius < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: planet_radius %g is negative", m->planet_radius);
  OC_TRY(ocp__check_finite(msg, "time", m->time, why, why_len));
  OC_TRY(ocp__check_unit(msg, "sun_dir", m->sun_dir, OCP__SUN_TOL, why, why_len));
  OC_TRY(ocp__check_finite(msg, "albedo", m->albedo, why, why_len));
  if (m->albedo < 0 || m->albedo > 1) return oc_errorf(OC_ECORRUPT, why, why_len, "welcome: albedo %g is outside [0, 1]", m->albedo);
  OC_TRY(ocp__check_finite(msg, "ms_a", m->ms_a, why, why_len));
  OC_TRY(ocp__check_finite(msg, "ms_b", m->ms_b, why, why_len));
  OC_TRY(ocp__check_finite(msg, "ms_c", m->ms_c, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_lat", m->cam_lat, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_lon", m->cam_lon, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_alt", m->cam_alt, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_heading", m->cam_heading, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_pitch", m->cam_pitch, why, why_len));
  OC_TRY(ocp__check_finite(msg, "cam_fov", m->cam_fov, why, why_len));
  return 0;
}

int ocp_get_camera(const uint8_t *p, size_t n, ocp_camera_t *m, char *why, size_t why_len) {
  static const char *msg = "camera";
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact(msg, n, OCP__CAMERA_BYTES, why, why_len));
  oc_reader_t r = oc_reader(p, n);
  m->pos = ocp__read_dvec3(&r);
  m->forward = ocp__read_dvec3(&r);
  m->up = ocp__read_dvec3(&r);
  m->vfov_deg = oc_read_f64(&r);
  m->width = oc_read_u32(&r);
  m->height = oc_read_u32(&r);
  if (!ocp__dvec3_finite(m->pos)) return oc_errorf(OC_ECORRUPT, why, why_len, "camera: pos is not finite");
  OC_TRY(ocp__check_unit(msg, "forward", m->forward, OCP__CAMERA_TOL, why, why_len));
  OC_TRY(ocp__check_unit(msg, "up", m->up, OCP__CAMERA_TOL, why, why_len));
  double d = oc_ddot(m->forward, m->up);
  if (!(fabs(d) <= OCP__CAMERA_TOL))
    return oc_errorf(OC_ECORRUPT, why, why_len, "camera: forward and up are not orthogonal (dot %g)", d);
  if (!(m->vfov_deg > 0 && m->vfov_deg < 180))
    return oc_errorf(OC_ECORRUPT, why, why_len, "camera: vfov_deg %g is outside (0, 180)", m->vfov_deg);
  OC_TRY(ocp__check_range_u32(msg, "width", m->width, 1, OCP__VIEWPORT_MAX, why, why_len));
  OC_TRY(ocp__check_range_u32(msg, "height", m->height, 1, OCP__VIEWPORT_MAX, why, why_len));
  return 0;
}

int ocp_get_ack(const uint8_t *p, size_t n, ocp_ack_t *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact("ack", n, OCP__ACK_BYTES, why, why_len));
  m->epoch = oc_get_u64(p);
  m->checksum = oc_get_u64(p + 8);
  return 0;
}

int ocp_get_budget(const uint8_t *p, size_t n, ocp_budget_t *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact("budget", n, OCP__BUDGET_BYTES, why, why_len));
  m->budget = oc_get_u64(p);
  m->epoch = oc_get_u64(p + 8);
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
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  if (n < OCP__TEXT_BYTES)
    return oc_errorf(OC_ECORRUPT, why, why_len, "error/goodbye: payload is %zu bytes, shorter than %d", n, OCP__TEXT_BYTES);
  m->code = oc_get_u32(p);
  uint16_t len = oc_get_u16(p + 4);
  if (len > OCP_TEXT_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "error/goodbye: text length %u is above %d", (unsigned)len, OCP_TEXT_MAX);
  OC_TRY(ocp__exact("error/goodbye", n, (size_t)OCP__TEXT_BYTES + len, why, why_len));
  if (len && memchr(p + OCP__TEXT_BYTES, 0, len)) return oc_errorf(OC_ECORRUPT, why, why_len, "error/goodbye: text contains a NUL byte");
  if (len) memcpy(m->text, p + OCP__TEXT_BYTES, len);
  m->text[len] = '\0';
  return 0;
}

int ocp_get_empty(const uint8_t *p, size_t n, char *why, size_t why_len) {
  (void)p;
  ocp__why_clear(why, why_len);
  return ocp__exact("keepalive", n, 0, why, why_len);
}

int ocp_get_epoch_begin(const uint8_t *p, size_t n, ocp_epoch_begin_t *m, char *why, size_t why_len) {
  static const char *msg = "epoch-begin";
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact(msg, n, OCP__EPOCH_BEGIN_BYTES, why, why_len));
  oc_reader_t r = oc_reader(p, n);
  m->epoch = oc_read_u64(&r);
  m->time = oc_read_f64(&r);
  m->sun_dir = ocp__read_dvec3(&r);
  m->base_epoch = oc_read_u64(&r);
  m->node_count = oc_read_u32(&r);
  m->brick_count = oc_read_u32(&r);
  m->bricks_sent = oc_read_u32(&r);
  uint32_t res = oc_read_u32(&r);
  if (res) return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: reserved bytes 60..63 are not zero");
  OC_TRY(ocp__check_finite(msg, "time", m->time, why, why_len));
  OC_TRY(ocp__check_unit(msg, "sun_dir", m->sun_dir, OCP__SUN_TOL, why, why_len));
  /* epochs only move forward, so a base is always older than the state built on it */
  if (m->base_epoch != OCP_NO_BASE && m->base_epoch >= m->epoch)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: base_epoch %" PRIu64 " is not before epoch %" PRIu64, m->base_epoch,
                     m->epoch);
  OC_TRY(ocp__check_range_u32(msg, "node_count", m->node_count, 1, OC_STATE_MAX_NODES, why, why_len));
  OC_TRY(ocp__check_range_u32(msg, "brick_count", m->brick_count, 0, OC_STATE_MAX_BRICKS, why, why_len));
  if (m->bricks_sent > m->brick_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: bricks_sent %" PRIu32 " is above brick_count %" PRIu32, m->bricks_sent,
                     m->brick_count);
  if (m->brick_count > m->node_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch-begin: brick_count %" PRIu32 " is above node_count %" PRIu32, m->brick_count,
                     m->node_count);
  return 0;
}

int ocp_get_epoch_end(const uint8_t *p, size_t n, ocp_epoch_end_t *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact("epoch-end", n, OCP__EPOCH_END_BYTES, why, why_len));
  m->epoch = oc_get_u64(p);
  m->checksum = oc_get_u64(p + 8);
  return 0;
}

int ocp_get_stats(uint8_t version, const uint8_t *p, size_t n, ocp_stats_t *m, char *why, size_t why_len) {
  static const char *msg = "stats";
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  OC_TRY(ocp__exact(msg, n, version >= 2 ? OCP__STATS_V2_BYTES : OCP__STATS_BYTES, why, why_len));
  oc_reader_t r = oc_reader(p, n);
  m->epoch = oc_read_u64(&r);
  m->leaves = oc_read_u32(&r);
  m->splits = oc_read_u32(&r);
  m->merges = oc_read_u32(&r);
  m->deferred = oc_read_u32(&r);
  m->coalesced = oc_read_u64(&r);
  m->resident_bytes = oc_read_u64(&r);
  m->wire_bytes = oc_read_u64(&r);
  m->raw_bytes = oc_read_u64(&r);
  m->plan_ms = oc_read_f64(&r);
  m->produce_ms = oc_read_f64(&r);
  uint64_t res = oc_read_u64(&r);
  res |= oc_read_u64(&r);
  if (res) return oc_errorf(OC_ECORRUPT, why, why_len, "stats: reserved bytes 72..87 are not zero");
  if (version >= 2) {
    m->queue = oc_read_u32(&r);
    m->produced = oc_read_u32(&r);
    m->split_backlog = oc_read_u32(&r);
    if (oc_read_u32(&r)) return oc_errorf(OC_ECORRUPT, why, why_len, "stats: reserved bytes 100..103 are not zero");
    memcpy(m->age_p50, p + 104, OCP_STATS_LEVELS);
    memcpy(m->age_p99, p + 104 + OCP_STATS_LEVELS, OCP_STATS_LEVELS);
    for (int l = 0; l < OCP_STATS_LEVELS; l++)
      if (m->age_p50[l] > m->age_p99[l])
        return oc_errorf(OC_ECORRUPT, why, why_len, "stats: level %d's age p50 %u is over its p99 %u", l, m->age_p50[l],
                         m->age_p99[l]);
  }
  OC_TRY(ocp__check_finite(msg, "plan_ms", m->plan_ms, why, why_len));
  OC_TRY(ocp__check_finite(msg, "produce_ms", m->produce_ms, why, why_len));
  if (m->plan_ms < 0 || m->produce_ms < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "stats: negative plan_ms or produce_ms");
  return 0;
}

int ocp_get_control(const uint8_t *p, size_t n, ocp_control_t *m, char *why, size_t why_len) {
  ocp__why_clear(why, why_len);
  memset(m, 0, sizeof *m);
  if (n < OCP__CONTROL_BYTES)
    return oc_errorf(OC_ECORRUPT, why, why_len, "control: payload is %zu bytes, shorter than %d", n, OCP__CONTROL_BYTES);
  if (n - OCP__CONTROL_BYTES > OCP__CONTROL_JSON_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "control: json of %zu bytes is above %u", n - OCP__CONTROL_BYTES,
                     (unsigned)OCP__CONTROL_JSON_MAX);
  m->request = oc_get_u32(p);
  m->status = (int32_t)oc_get_u32(p + 4);
  m->json_len = (uint32_t)(n - OCP__CONTROL_BYTES);
  m->json = (const char *)p + OCP__CONTROL_BYTES;
  if (m->status < 0) return oc_errorf(OC_ECORRUPT, why, why_len, "control: status %" PRId32 " is negative", m->status);
  if (m->json_len && memchr(m->json, 0, m->json_len)) return oc_errorf(OC_ECORRUPT, why, why_len, "control: json contains a NUL byte");
  return 0;
}
