/* oc_budget.h — the budget contract (design.md, Conventions: budget; docs/protocol.md, "Resident
 * bytes"): one struct carried from the viewer's HELLO through admission, the planner and WELCOME to
 * the viewer's GPU store, and the one definition of the sizes a viewer that keeps the codes as they
 * are declares. */
#ifndef OC_COMMON_BUDGET_H
#define OC_COMMON_BUDGET_H

#include <stdint.h>

#include "oc_brick.h" /* OC_BRICK_CODE_BYTES: a slot that keeps the codes as they are */

/*! GPU bytes of one node record in the GL store (client/gl: the leaf record the kernel reads). */
#define OC_RECORD_BYTES 32u
/*! GPU bytes of one brick slot in the GL store: the codes as they are, 8³ × 2 channels × u16. */
#define OC_SLOT_BYTES OC_BRICK_CODE_BYTES

/*! What a viewer may hold: resident = distinct bricks of its K states × slot_bytes + their records ×
 *  record_bytes ≤ budget. A HELLO names budget, slot and record bytes (kept_states 0: the server
 *  decides); a grant (WELCOME, the planner) names all four. */
typedef struct {
  uint64_t budget;       /**< bytes */
  uint32_t slot_bytes;   /**< GPU bytes per brick slot, 1..1 MiB on the wire */
  uint32_t record_bytes; /**< GPU bytes per node record, 1..1 MiB on the wire */
  int kept_states;       /**< K: the window of states the budget covers, 2 (static) or 3 (animated) */
} oc_budget_t;

/*! OC_BUDGET_MEMBER(name) : a struct's budget contract as the oc_budget_t `name`, its members also
 *  reachable by their own names (s.name.budget is s.budget): an anonymous union of the struct and
 *  an anonymous struct of the same members in the same order (C11; their common initial sequence),
 *  so that the contract travels as one value and older code reading s.budget stays right. */
#define OC_BUDGET_MEMBER(name)                 \
  union {                                      \
    oc_budget_t name;                          \
    struct {                                   \
      uint64_t budget;                         \
      uint32_t slot_bytes, record_bytes;       \
      int kept_states;                         \
    };                                         \
  }

/*! oc_budget_min() : the smallest budget that holds a window: the root as a brick in each of the K
 *  states, K · (slot bytes + record bytes). */
uint64_t oc_budget_min(const oc_budget_t *b);
/*! oc_budget_slots() : the most distinct bricks a window within the budget can hold, which sizes a
 *  brick atlas: n bricks take n slots and at least n records (each is a leaf of some state), so
 *  n·(slot + record) ≤ budget. The records are taken off: a budget of slot bytes × n holds fewer
 *  than n bricks. At least K from oc_budget_min() up (the root in each state, K records, ≤ K
 *  bricks); 0 below it or for a zero size. */
uint32_t oc_budget_slots(const oc_budget_t *b);

#endif /* OC_COMMON_BUDGET_H */
