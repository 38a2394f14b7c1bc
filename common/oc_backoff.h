/* oc_backoff.h — reconnect delays: exponential backoff with jitter, pure and seeded, so that a
 * client's retries are testable and many clients told to reconnect at once do not all return in
 * the same instant. */
#ifndef OC_COMMON_BACKOFF_H
#define OC_COMMON_BACKOFF_H

#include <stdint.h>

#define OC_BACKOFF_MIN_MS 250u    /* the floor of every delay, whatever the server asked */
#define OC_BACKOFF_CAP_MS 10000u  /* no delay is longer */

typedef struct {
  uint32_t base_ms;  /* the first delay: max(the server's, OC_BACKOFF_MIN_MS) */
  uint32_t cap_ms;
  uint32_t attempt;  /* delays handed out so far */
  uint64_t rng;      /* splitmix64 state */
} oc_backoff_t;

/*! oc_backoff_init() : server_ms is the delay the server asked for (GOODBYE RECONNECT; 0: none). */
void oc_backoff_init(oc_backoff_t *b, uint32_t server_ms, uint64_t seed);
/*! oc_backoff_next() : the next delay in ms. The first is base_ms exactly (the server's wish);
 *  attempt n ≥ 1 is uniform in [base_ms, min(cap_ms, base_ms·2ⁿ)]: the ceiling doubles up to the
 *  cap, and the jitter spreads clients over the whole window above the floor. */
uint32_t oc_backoff_next(oc_backoff_t *b);

#endif /* OC_COMMON_BACKOFF_H */
