/* net_admit.c — fair admission of viewers (net_internal.h). A viewer is granted its request
 * clamped to the per-viewer maximum (a fair share of the total by default, world.h). When the
 * total is short, lingering sessions — viewers whose connection was lost, kept for resume — give
 * their budget back first, oldest first; then viewers of protocol version 3 holding more than a
 * fair share (ocs_world_fair_share) are lowered to it with BUDGET (a version 1/2 viewer's grant is
 * fixed). The new viewer is admitted at once with the largest budget that fits above the minimum
 * (the lowered viewers' old budgets stay reserved until their states planned under them have left
 * their windows), and the room they free later raises it toward its request with BUDGET if it
 * speaks version 3 (world.c, budgets_settle). Only when even the minimum does not fit is it
 * refused (FULL), saying that room is being made. So neither a greedy HELLO nor a greedy client
 * that vanishes can lock the others out. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

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

/* Lowers version-3 viewers above a fair share to it when the request does not fit what is left.
 * @return how many were lowered. */
static int lower_greedy(ocs_session_t *s, const ocs_plan_desc_t *req) {
  ocs_server_t *srv = s->srv;
  ocs_admission_t a;
  ocs_world_admission(srv->world, req, &a);
  if (a.left >= a.wanted || a.viewers_left <= 0) return 0;
  uint64_t fair = ocs_world_fair_share(ocs_world_total_budget(srv->world));
  int n = 0;
  for (ocs_session_t *t = srv->sessions; t; t = t->next) {
    if (t == s || t->role != OCP_ROLE_VIEWER || !t->viewer || t->version < OCP_VERSION_BUDGET) continue;
    ocs_viewer_stats_t vs;
    ocs_viewer_stats(t->viewer, &vs);
    if (vs.budget <= fair) continue;
    char why[200];
    if (ocs_world_set_budget(srv->world, t->viewer, fair, why, sizeof why) < 0) {
      oc_log_warn("session %" PRIu32 ": not lowered for session %" PRIu32 ": %s", t->id, s->id, why);
      continue;
    }
    oc_log_info("session %" PRIu32 " (viewer %s): lowered from %" PRIu64 " to a fair share, %" PRIu64
                " bytes, to make room for session %" PRIu32, t->id, t->addr, vs.budget, fair, s->id);
    srv->counts.budget_lowerings++;
    n++;
  }
  return n;
}

int ocs_admit_viewer(ocs_session_t *s, const ocp_hello_t *h) {
  ocs_server_t *srv = s->srv;
  /* the contract as HELLO asked it; the world sets K and clamps the budget */
  ocs_plan_desc_t req = {.grant = h->ask, .max_depth = h->max_depth};
  reclaim_lingering(s, &req);
  int lowered = lower_greedy(s, &req);
  char why[320];
  int r = ocs_world_add_viewer(srv->world, &req, &s->viewer, &s->granted, why, sizeof why);
  if (r == OC_ERANGE && lowered) {
    size_t n = strlen(why);
    snprintf(why + n, sizeof why - n, "; %d viewer(s) are being lowered to a fair share: retry in a few epochs", lowered);
  }
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
