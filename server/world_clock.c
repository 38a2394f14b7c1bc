/* world_clock.c — the control history and world time from it (world_clock.h). */
#include "world_clock.h"

#include <math.h>
#include <string.h>

#include "oc_err.h"

void ocs_clock_init(ocs_clock_t *c, double utc, double world) {
  c->n = 1;
  c->e[0] = (ocs_clock_entry_t){utc, world, 1.0, 1.0};
}

/* The last entry at or before utc (the first one when utc is before it). */
static const ocs_clock_entry_t *entry_at(const ocs_clock_t *c, double utc) {
  int i = c->n - 1;
  while (i > 0 && c->e[i].utc > utc) i--;
  return &c->e[i];
}

double ocs_clock_world(const ocs_clock_t *c, double utc) {
  const ocs_clock_entry_t *e = entry_at(c, utc);
  return utc > e->utc ? e->world + (utc - e->utc) * e->scale : e->world;
}

double ocs_clock_scale(const ocs_clock_t *c, double utc) { return entry_at(c, utc)->scale; }

int ocs_clock_set(ocs_clock_t *c, double utc, double world, double scale) {
  if (!isfinite(utc) || (!isnan(world) && !(fabs(world) <= 1e12)) || (!isnan(scale) && !(scale >= 0.0 && scale <= 1e6)))
    return OC_EINVAL;
  const ocs_clock_entry_t *last = &c->e[c->n - 1];
  if (utc < last->utc) utc = last->utc;
  ocs_clock_entry_t x = {utc, isnan(world) ? ocs_clock_world(c, utc) : world, isnan(scale) ? last->scale : scale,
                         last->resume};
  if (x.scale > 0.0) x.resume = x.scale;
  if (utc == last->utc) { /* a second change at the same instant replaces the first */
    c->e[c->n - 1] = x;
    return 0;
  }
  if (c->n == OCS_CLOCK_MAX) { /* the oldest entries are behind every instant still asked */
    memmove(&c->e[0], &c->e[1], (size_t)(OCS_CLOCK_MAX - 1) * sizeof c->e[0]);
    c->n--;
  }
  c->e[c->n++] = x;
  return 0;
}

int ocs_clock_pause(ocs_clock_t *c, double utc) { return ocs_clock_set(c, utc, NAN, 0.0); }

int ocs_clock_resume(ocs_clock_t *c, double utc) { return ocs_clock_set(c, utc, NAN, c->e[c->n - 1].resume); }
