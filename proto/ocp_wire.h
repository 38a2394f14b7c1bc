/* ocp_wire.h — frames and messages of the Overcast wire protocol (docs/protocol.md, "Wire").
 *
 * Pure functions, no I/O: encoders append one complete frame (header and payload) to an oc_buf_t,
 * decoders parse one frame's payload into a plain struct and check every field an honest peer
 * would never get wrong (lengths exact, reserved bytes zero, numbers finite and in range), so the
 * code above them never sees a malformed message. Epoch payloads (records and brick batches) are
 * encoded and decoded by ocp_epoch.h; this file only frames them.
 *
 * Every frame: 8-byte header (magic "OW", u8 version, u8 type, u32 payload length), then the
 * payload. The version byte is the negotiated protocol version, except in HELLO, which carries the
 * viewer's highest version and whose payload layout never changes. */
#ifndef OC_PROTO_WIRE_H
#define OC_PROTO_WIRE_H

#include <stddef.h>
#include <stdint.h>

#include "oc_budget.h" /* oc_budget_t */
#include "oc_bytes.h" /* oc_buf_t */
#include "oc_math.h"  /* oc_dvec3 */

#define OCP_MAGIC0 0x4F /* 'O' */
#define OCP_MAGIC1 0x57 /* 'W' */
#define OCP_VERSION_MIN 1 /**< versions this build speaks */
#define OCP_VERSION_MAX 3
#define OCP_VERSION_BUDGET 3 /**< the first version with BUDGET (0x89) */
#define OCP_HEADER_BYTES 8
/*! Largest payload either side ever sends (epoch chunks are at most OCP_CHUNK_RAW_MAX raw). */
#define OCP_MAX_PAYLOAD (4u << 20)
/*! Largest payload a server accepts from a viewer or control client. */
#define OCP_MAX_CLIENT_PAYLOAD (64u << 10)
#define OCP_TOKEN_MAX 256
#define OCP_TEXT_MAX 1024 /**< error and goodbye texts */
#define OCP_NAME_MAX 63   /**< scene name in WELCOME */

/*! Message types. 0x01..0x0F from viewers and control clients, 0x80.. from the server, 0x70..
 *  either way. */
#define OCP_MSG_MAP(XX)                    \
  XX(HELLO, 0x01, "hello")                 \
  XX(CAMERA, 0x02, "camera")               \
  XX(ACK, 0x03, "ack")                     \
  XX(CONTROL, 0x04, "control")             \
  XX(KEEPALIVE, 0x70, "keepalive")         \
  XX(GOODBYE, 0x71, "goodbye")             \
  XX(ERROR, 0x72, "error")                 \
  XX(WELCOME, 0x81, "welcome")             \
  XX(EPOCH_BEGIN, 0x82, "epoch-begin")     \
  XX(RECORDS, 0x83, "records")             \
  XX(BRICKS, 0x84, "bricks")               \
  XX(EPOCH_END, 0x85, "epoch-end")         \
  XX(STATS, 0x86, "stats")                 \
  XX(CONTROL_REPLY, 0x87, "control-reply") \
  XX(DICT, 0x88, "dictionary")             \
  XX(BUDGET, 0x89, "budget")

typedef enum {
#define OCP__MSG_ENUM(name, val, str) OCP_MSG_##name = (val),
  OCP_MSG_MAP(OCP__MSG_ENUM)
#undef OCP__MSG_ENUM
} ocp_msg_type_t;

/*! ocp_msg_name() : "hello", ... or NULL for an unknown type. */
const char *ocp_msg_name(int type);

/*! Wire error codes (ERROR and GOODBYE messages): stable numbers, unlike errno values. */
#define OCP_CODE_MAP(XX)                                           \
  XX(OK, 0, "ok")                                                  \
  XX(VERSION, 1, "no common protocol version")                     \
  XX(MALFORMED, 2, "malformed message")                            \
  XX(TOKEN, 3, "bad token")                                        \
  XX(BUDGET, 4, "budget cannot be granted")                        \
  XX(FULL, 5, "server full")                                       \
  XX(TOO_BIG, 6, "message too big")                                \
  XX(TIMEOUT, 7, "timed out")                                      \
  XX(SLOW, 8, "send queue limit reached")                          \
  XX(CHECKSUM, 9, "state checksum mismatch")                       \
  XX(INTERNAL, 10, "internal error")                               \
  XX(SHUTDOWN, 11, "server shutting down")                         \
  XX(RELOAD, 12, "scene reloaded: reconnect")                      \
  XX(KICKED, 13, "disconnected by the operator")                   \
  XX(REQUEST, 14, "invalid request")                               \
  XX(UNEXPECTED, 15, "message not valid in this state")   \
  XX(RECONNECT, 16, "the server is draining: reconnect")

typedef enum {
#define OCP__CODE_ENUM(name, val, str) OCP_CODE_##name = (val),
  OCP_CODE_MAP(OCP__CODE_ENUM)
#undef OCP__CODE_ENUM
} ocp_code_t;

/*! ocp_code_text() : a static description of a wire code ("unknown code" otherwise). */
const char *ocp_code_text(uint32_t code);
/*! ocp_code_from_err() : the wire code for a negative OC_E* (OC_EVERSION → VERSION, ...). */
uint32_t ocp_code_from_err(int err);

/*-*** Frames ***/

typedef struct {
  uint8_t version, type;
  uint32_t length; /**< payload bytes */
} ocp_header_t;

/*! ocp_header_parse() : checks the magic and `length ≤ max_payload` of the 8 bytes at p.
 *  @return 0, OC_ECORRUPT (bad magic) or OC_ETOOBIG. Type and version are the caller's to judge. */
int ocp_header_parse(const uint8_t p[OCP_HEADER_BYTES], uint32_t max_payload, ocp_header_t *out);

/*! A frame splitter over a byte stream: feed what arrived, take whole frames out. It holds at most
 *  one frame (header + max_payload bytes), so a peer cannot make it buffer more. */
typedef struct {
  oc_buf_t buf;
  size_t start; /**< first unconsumed byte of buf */
  uint32_t max_payload;
  int err; /**< sticky OC_E* once a header was bad */
} ocp_reader_t;

void ocp_reader_init(ocp_reader_t *r, uint32_t max_payload);
void ocp_reader_free(ocp_reader_t *r);
/*! ocp_reader_feed() : appends n bytes. @return 0 or OC_ENOMEM. */
int ocp_reader_feed(ocp_reader_t *r, const void *p, size_t n);
/*! ocp_reader_next() : @return 1 with the next whole frame (payload valid until the next feed or
 *  next call), 0 when more bytes are needed, or a negative OC_E* (bad magic, too big) after which
 *  the stream is unusable. */
int ocp_reader_next(ocp_reader_t *r, ocp_header_t *hdr, const uint8_t **payload);
/*! ocp_reader_pending() : bytes fed but not yet returned as frames. */
size_t ocp_reader_pending(const ocp_reader_t *r);

/*! ocp_frame_begin() / ocp_frame_end() : for encoders of large payloads: begin appends a header
 *  with length 0 and returns its offset; end patches the length from what was appended since. */
size_t ocp_frame_begin(oc_buf_t *b, uint8_t version, uint8_t type);
void ocp_frame_end(oc_buf_t *b, size_t header_offset);

/*-*** Messages ***/

#define OCP_ROLE_VIEWER 0
#define OCP_ROLE_CONTROL 1
#define OCP_CAP_DELTA 0x1u  /**< the viewer applies brick deltas */
#define OCP_CAP_DICT 0x2u   /**< the viewer takes zstd dictionaries */
#define OCP_CAP_DIGEST 0x4u /**< the viewer verifies states by their digest checksum and keeps no codes
                                 (a lean viewer); excludes OCP_CAP_DELTA, which needs the base codes */
/*! What a full viewer sends. */
#define OCP_CAP_ALL (OCP_CAP_DELTA | OCP_CAP_DICT)
/*! Every bit this build knows: HELLO refuses others (and DIGEST together with DELTA). */
#define OCP_CAP_KNOWN (OCP_CAP_DELTA | OCP_CAP_DICT | OCP_CAP_DIGEST)

typedef struct {
  uint16_t min_version, max_version;
  uint8_t role;         /**< OCP_ROLE_* */
  uint8_t max_depth;    /**< 0..21 */
  /** budget, slot and record bytes asked for (viewer; 0 for control); kept_states is 0 */
  OC_BUDGET_MEMBER(ask);
  uint32_t width, height; /**< viewport, 1..65536 (viewer); 0 for control */
  uint32_t caps;        /**< OCP_CAP_* */
  uint32_t resume_session; /**< 0: a new session */
  uint64_t resume_secret;
  uint64_t held_epoch;     /**< newest complete state the viewer holds (resume only) */
  uint64_t held_checksum;  /**< its checksum; its digest checksum when caps has OCP_CAP_DIGEST */
  uint16_t token_len;
  uint8_t token[OCP_TOKEN_MAX];
} ocp_hello_t;

#define OCP_WELCOME_RESUMED 0x1u

typedef struct {
  uint16_t version;     /**< chosen */
  uint8_t flags;        /**< OCP_WELCOME_* */
  uint32_t session;
  uint64_t secret;      /**< with `session`, lets this viewer resume after a reconnect */
  /** the grant: budget (clamped), slot and record bytes, K (2 static, 3 animated); all 0 for control */
  OC_BUDGET_MEMBER(grant);
  uint8_t max_depth;
  uint32_t features;    /**< oc_scene_t.features bits */
  double epoch_period;  /**< s; 0: epochs are stepped by command */
  double planet_radius; /**< m */
  double time;          /**< world time now, s */
  oc_dvec3 sun_dir;
  double albedo, ms_a, ms_b, ms_c;
  uint32_t ms_octaves;
  double cam_lat, cam_lon, cam_alt, cam_heading, cam_pitch, cam_fov; /**< the scene's default view */
  char name[OCP_NAME_MAX + 1];
} ocp_welcome_t;

typedef struct {
  oc_dvec3 pos, forward, up; /**< planet frame; forward and up unit and orthogonal (±1e-3) */
  double vfov_deg;           /**< (0, 180) */
  uint32_t width, height;    /**< 1..65536 */
} ocp_camera_t;

typedef struct {
  uint64_t epoch, checksum;
} ocp_ack_t;

/*! BUDGET (version 3): the viewer's budget from epoch `epoch` on (docs/protocol.md, "BUDGET"). */
typedef struct {
  uint64_t budget; /**< bytes, ≠ 0; the grant's slot bytes, record bytes and K stay */
  uint64_t epoch;  /**< the first epoch planned under it */
} ocp_budget_t;

typedef struct {
  uint32_t code; /**< OCP_CODE_* */
  char text[OCP_TEXT_MAX + 1];
} ocp_text_msg_t; /* ERROR and GOODBYE */

#define OCP_NO_BASE UINT64_MAX

typedef struct {
  uint64_t epoch;
  double time;
  oc_dvec3 sun_dir;
  uint64_t base_epoch;   /**< epoch of the viewer's state the records are a difference from;
                              OCP_NO_BASE: every record is sent */
  uint32_t node_count;   /**< 1..OC_STATE_MAX_NODES */
  uint32_t brick_count;  /**< bricks of the state, ≤ OC_STATE_MAX_BRICKS */
  uint32_t bricks_sent;  /**< of those, sent in BRICKS frames of this epoch (≤ brick_count) */
} ocp_epoch_begin_t;

typedef struct {
  uint64_t epoch, checksum; /**< XXH3-64 of the state's serialisation (oc_state_checksum), or for a
                                 viewer with OCP_CAP_DIGEST its digest checksum (oc_state_digest) */
} ocp_epoch_end_t;

#define OCP_STATS_LEVELS 22 /**< octree levels 0..21 */

typedef struct {
  uint64_t epoch;
  uint32_t leaves, splits, merges, deferred;
  uint64_t coalesced;      /**< due ticks this viewer got no state of so far (unacknowledged, or skipped) */
  uint64_t resident_bytes; /**< server's count of what the viewer keeps */
  uint64_t wire_bytes;     /**< bytes of this epoch's frames */
  uint64_t raw_bytes;      /**< what they would be uncompressed */
  double plan_ms, produce_ms;
  /* version 2 (zero in a version-1 STATS) */
  uint32_t queue;          /**< bricks waiting in the server's production queue (all viewers) */
  uint32_t produced;       /**< bricks made for this viewer between its previous state and this one */
  uint32_t split_backlog;  /**< splits of this plan that waited for their children's content */
  uint8_t age_p50[OCP_STATS_LEVELS], age_p99[OCP_STATS_LEVELS]; /**< per level, the content age of the
                                state's leaves in time steps behind current (p50, p99); 255: older
                                than the server can tell, or no leaf of that level */
} ocp_stats_t;

typedef struct {
  uint32_t request;  /**< echoed in the reply */
  int32_t status;    /**< replies: OCP_CODE_*; requests: 0 */
  const char *json;  /**< points into the payload; not NUL-terminated */
  uint32_t json_len;
} ocp_control_t;

/*! Encoders: append one whole frame. `version` is the frame header's version byte. They do not
 *  validate (the caller builds honest messages); text is cut at OCP_TEXT_MAX. On allocation
 *  failure b->err is set. */
void ocp_put_hello(oc_buf_t *b, const ocp_hello_t *m);
void ocp_put_welcome(oc_buf_t *b, uint8_t version, const ocp_welcome_t *m);
void ocp_put_camera(oc_buf_t *b, uint8_t version, const ocp_camera_t *m);
void ocp_put_ack(oc_buf_t *b, uint8_t version, const ocp_ack_t *m);
void ocp_put_text(oc_buf_t *b, uint8_t version, uint8_t type, uint32_t code, const char *text); /* ERROR, GOODBYE */
/*! ocp_reconnect_delay_ms() : the delay a GOODBYE RECONNECT's text asks for: its leading decimal
 *  digits followed by " ms" (docs/protocol.md); 0 when the text does not begin so. */
uint32_t ocp_reconnect_delay_ms(const char *text);
void ocp_put_empty(oc_buf_t *b, uint8_t version, uint8_t type);                                 /* KEEPALIVE */
void ocp_put_epoch_begin(oc_buf_t *b, uint8_t version, const ocp_epoch_begin_t *m);
void ocp_put_epoch_end(oc_buf_t *b, uint8_t version, const ocp_epoch_end_t *m);
void ocp_put_stats(oc_buf_t *b, uint8_t version, const ocp_stats_t *m);
void ocp_put_control(oc_buf_t *b, uint8_t version, uint8_t type, const ocp_control_t *m); /* CONTROL, CONTROL_REPLY */
void ocp_put_budget(oc_buf_t *b, uint8_t version, const ocp_budget_t *m);

/*! Decoders: one frame's payload. @return 0 or OC_ECORRUPT with a one-line reason in why (which
 *  names the message and the field). */
int ocp_get_hello(const uint8_t *p, size_t n, ocp_hello_t *m, char *why, size_t why_len);
int ocp_get_welcome(const uint8_t *p, size_t n, ocp_welcome_t *m, char *why, size_t why_len);
int ocp_get_camera(const uint8_t *p, size_t n, ocp_camera_t *m, char *why, size_t why_len);
int ocp_get_ack(const uint8_t *p, size_t n, ocp_ack_t *m, char *why, size_t why_len);
/*! ocp_get_budget() : 16 bytes, budget ≠ 0. What depends on the session (the minimum, the epoch
 *  against the states held, the version) is the viewer's to check (ocp_viewer.c). */
int ocp_get_budget(const uint8_t *p, size_t n, ocp_budget_t *m, char *why, size_t why_len);
int ocp_get_text(const uint8_t *p, size_t n, ocp_text_msg_t *m, char *why, size_t why_len);
int ocp_get_empty(const uint8_t *p, size_t n, char *why, size_t why_len);
int ocp_get_epoch_begin(const uint8_t *p, size_t n, ocp_epoch_begin_t *m, char *why, size_t why_len);
int ocp_get_epoch_end(const uint8_t *p, size_t n, ocp_epoch_end_t *m, char *why, size_t why_len);
int ocp_get_stats(uint8_t version, const uint8_t *p, size_t n, ocp_stats_t *m, char *why, size_t why_len);
int ocp_get_control(const uint8_t *p, size_t n, ocp_control_t *m, char *why, size_t why_len);

/*! Any one message, of the type it was decoded as (ocp_get_msg). */
typedef union {
  ocp_hello_t hello;
  ocp_welcome_t welcome;
  ocp_camera_t camera;
  ocp_ack_t ack;
  ocp_budget_t budget;
  ocp_text_msg_t text;   /**< ERROR, GOODBYE */
  ocp_epoch_begin_t begin;
  ocp_epoch_end_t end;
  ocp_stats_t stats;
  ocp_control_t control; /**< CONTROL, CONTROL_REPLY */
} ocp_msg_t;

/*! ocp_get_msg() : the payload decoded by the decoder of `type` (STATS as of `version`; KEEPALIVE
 *  leaves m alone). @return the decoder's result, or 1 for a type without a message decoder here
 *  (epoch payloads: ocp_epoch.h; unknown types). */
int ocp_get_msg(uint8_t version, uint8_t type, const uint8_t *p, size_t n, ocp_msg_t *m, char *why, size_t why_len);
/*! ocp_put_msg() : appends m, a message of `type` (as ocp_get_msg accepts it), as one frame; nothing
 *  for a type ocp_get_msg has no decoder for. */
void ocp_put_msg(oc_buf_t *b, uint8_t version, uint8_t type, const ocp_msg_t *m);

/*! ocp_version_pick() : the highest version in both [min, max] ranges, or 0 when none. */
uint16_t ocp_version_pick(uint16_t their_min, uint16_t their_max);

#endif /* OC_PROTO_WIRE_H */
