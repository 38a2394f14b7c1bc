/* bench_epoch.h — an epoch's frames decoded as a viewer would, for the benches that encode what the
 * server core produces without a network (wire, features). */
#ifndef OC_TOOLS_BENCH_EPOCH_H
#define OC_TOOLS_BENCH_EPOCH_H

#include <stddef.h>

#include "ocp.h"

/*! oct_epoch_decode() : feeds the frames in `in` (EPOCH_BEGIN … EPOCH_END, as ocp_epoch_enc_next()
 *  wrote them) to `d` as a viewer holding the `nheld` states `held` (any order; the epoch's base and
 *  the bricks it does not carry are looked up there) and writes the state it rebuilds, checked
 *  against EPOCH_END's checksum, into out. @return 0, or a negative OC_E* with a reason in why. */
int oct_epoch_decode(ocp_epoch_dec_t *d, const oc_buf_t *in, const oc_state_t *const *held, int nheld, oc_state_t *out,
                     char *why, size_t why_len);

#endif /* OC_TOOLS_BENCH_EPOCH_H */
