/* net_admit.c — fair admission of viewers (net_internal.h). A viewer is granted its request
 * clamped to the per-viewer maximum (a fair share of the total by default, world.h). When the
 * total is short, lingering sessions — viewers whose connection was lost, kept for resume — give
 * their budget back first, oldest first; then the viewer gets the largest budget that fits above
 * the minimum, and only when even the minimum does not fit is it refused (FULL). So neither a
 * greedy HELLO nor a greedy client that vanishes can lock the others out. */
#include <inttypes.h>
#include <stdio.h>

#include "net_internal.h"
#include "oc_err.h"
#include "oc_log.h"

/* Lets lingering sessions go, oldest first, until the request fits or none is left. */
static void reclaim_lingering(ocs_session_t *s, const ocs_plan_desc_t *req) {
  ocs_server_t *srv = s->srv;
  ocs_admission_t a;
  ocs_session_t *old;
  char why[160];
  for (;;) {
    ocs_world_admission(srv->world, req, &a);
    if ((a.left >= a.wanted && a.viewers_left > 0) || !(old = ocs_session_oldest_lingering(srv, NULL, NULL))) return;
    snprintf(why, sizeof why, "session %" PRIu32 " needs its %s", s->id, a.viewers_left > 0 ? "budget" : "viewer slot");
    ocs_session_let_go(old, why);
  }
}

int ocs_admit_viewer(ocs_session_t *s, const ocp_hello_t *h) {
  ocs_server_t *srv = s->srv;
  /* the contract as HELLO asked it; the world sets K and clamps the budget */
  ocs_plan_desc_t req = {.grant = h->ask, .max_depth = h->max_depth};
  reclaim_lingering(s, &req);
  char why[256];
  int r = ocs_world_add_viewer(srv->world, &req, &s->viewer, &s->granted, why, sizeof why);
  if (r == OC_ETOOBIG || r == OC_ERANGE) {
    ocs_session_refuse(s, r == OC_ETOOBIG ? OCS_REFUSE_VIEWERS : OCS_REFUSE_BUDGET, why);
    return r;
  }
  if (r < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, why);
    return r;
  }
  return 0;
}
