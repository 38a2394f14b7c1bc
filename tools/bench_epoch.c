/* bench_epoch.c — see bench_epoch.h. */
#include "bench_epoch.h"

#include <stdio.h>

#include "ocp.h"

typedef struct {
  const oc_state_t *const *s;
  int n;
} oct__held_t;

static const oc_brick_codes_t *oct__lookup(void *ctx, uint32_t id) {
  const oct__held_t *h = ctx;
  for (int i = 0; i < h->n; i++) {
    const oc_brick_t *b = h->s[i] ? oc_state_find_brick(h->s[i], id) : NULL;
    if (b) return &b->codes;
  }
  return NULL;
}

int oct_epoch_decode(ocp_epoch_dec_t *d, const oc_buf_t *in, const oc_state_t *const *held, int nheld, oc_state_t *out,
                     char *why, size_t why_len) {
  oct__held_t h = {held, nheld};
  int r = OC_ECORRUPT;
  snprintf(why, why_len, "no epoch end");
  for (size_t at = 0; at + OCP_HEADER_BYTES <= in->len;) {
    ocp_header_t hd;
    if ((r = ocp_header_parse(in->data + at, OCP_MAX_PAYLOAD, &hd)) < 0) return r;
    const uint8_t *p = in->data + at + OCP_HEADER_BYTES;
    at += OCP_HEADER_BYTES + hd.length;
    switch (hd.type) {
      case OCP_MSG_EPOCH_BEGIN: {
        ocp_epoch_begin_t m;
        if ((r = ocp_get_epoch_begin(p, hd.length, &m, why, why_len)) < 0) return r;
        const oc_state_t *base = NULL;
        for (int i = 0; i < nheld && m.base_epoch != OCP_NO_BASE && !base; i++)
          if (held[i] && held[i]->epoch == m.base_epoch) base = held[i];
        r = ocp_epoch_dec_begin(d, &m, base, oct__lookup, &h, why, why_len);
        break;
      }
      case OCP_MSG_RECORDS: r = ocp_epoch_dec_records(d, p, hd.length, why, why_len); break;
      case OCP_MSG_BRICKS: r = ocp_epoch_dec_bricks(d, p, hd.length, why, why_len); break;
      case OCP_MSG_DICT: r = ocp_epoch_dec_dict(d, p, hd.length, why, why_len); break;
      case OCP_MSG_EPOCH_END: {
        ocp_epoch_end_t m;
        if ((r = ocp_get_epoch_end(p, hd.length, &m, why, why_len)) < 0) return r;
        return ocp_epoch_dec_end(d, &m, out, why, why_len);
      }
      default: snprintf(why, why_len, "unexpected frame type 0x%02x", hd.type); return OC_ECORRUPT;
    }
    if (r < 0) return r;
  }
  return r < 0 ? r : OC_ECORRUPT;
}
