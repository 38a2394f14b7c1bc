/* wire_any.h — any wire message by its type, for the tests and fuzz targets that go over every
 * type (tests/proto/test_wire.c, tests/fuzz/fuzz_wire.c). */
#ifndef OC_TESTS_WIRE_ANY_H
#define OC_TESTS_WIRE_ANY_H

#include <stddef.h>
#include <stdint.h>

#include "ocp_wire.h"

/*! One decoded message, of the type it was decoded as. */
typedef union {
  ocp_hello_t hello;
  ocp_welcome_t welcome;
  ocp_camera_t camera;
  ocp_ack_t ack;
  ocp_budget_t budget;
  ocp_text_msg_t text;
  ocp_epoch_begin_t begin;
  ocp_epoch_end_t end;
  ocp_stats_t stats;
  ocp_control_t control;
} wire_msg_t;

/*! wire_get_any() : the payload p decoded by the decoder of `type` (STATS as of `version`).
 *  @return the decoder's result, or 1 for a type without a message decoder (epoch payloads,
 *  unknown types). */
static inline int wire_get_any(uint8_t version, uint8_t type, const uint8_t *p, size_t n, wire_msg_t *m, char *why,
                               size_t why_len) {
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

/*! wire_put_any() : appends m, which wire_get_any() accepted as `type`, encoded again as one frame. */
static inline void wire_put_any(oc_buf_t *b, uint8_t version, uint8_t type, const wire_msg_t *m) {
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

#endif /* OC_TESTS_WIRE_ANY_H */
