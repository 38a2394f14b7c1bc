/* oc_budget.c — the budget contract (oc_budget.h). */
#include "oc_budget.h"

uint64_t oc_budget_min(const oc_budget_t *b) {
  return (uint64_t)(b->kept_states > 0 ? b->kept_states : 0) * ((uint64_t)b->slot_bytes + b->record_bytes);
}

uint32_t oc_budget_slots(const oc_budget_t *b) {
  if (!b->slot_bytes || !b->record_bytes || b->kept_states < 1 || b->budget < oc_budget_min(b)) return 0;
  uint64_t n = b->budget / ((uint64_t)b->slot_bytes + b->record_bytes);
  return n > UINT32_MAX ? UINT32_MAX : (uint32_t)n;
}
