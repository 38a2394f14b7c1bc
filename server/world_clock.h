/* world_clock.h — world time as a pure function of the wall clock and the control history
 * (design.md, Conventions: "World time is a pure function of the wall clock (UTC) and the control
 * history"; docs/architecture.md, "The world's clock").
 *
 * The history is a list of entries (UTC instant u_i, world time w_i, scale s_i), ascending in u:
 * the first is where the clock starts (the server's start and its --time; or, on the virtual
 * clock of stepped mode, instant 0), each later one a control change (time --set, --scale, pause,
 * resume). At any instant u ≥ u_0 the world time is
 *     W(u) = w_i + (u − u_i)·s_i   for the last entry with u_i ≤ u,
 * so servers that share the history agree on the world without talking. Epoch n of period P is
 * due at u = n·P and takes W(n·P), whenever its step actually runs.
 *
 * Entries older than the newest one at or before the instant asked are never needed again by a
 * clock that only moves forward; the history keeps at most OCS_CLOCK_MAX entries, dropping the
 * oldest. */
#ifndef OC_SERVER_WORLD_CLOCK_H
#define OC_SERVER_WORLD_CLOCK_H

#define OCS_CLOCK_MAX 1024

typedef struct {
  double utc;    /**< s since the Unix epoch (or since the virtual clock's 0) */
  double world;  /**< world time at that instant, s */
  double scale;  /**< world seconds per wall second from then on; 0: paused */
  double resume; /**< the scale `resume` returns to (the last non-zero one) */
} ocs_clock_entry_t;

typedef struct ocs_clock_s {
  ocs_clock_entry_t e[OCS_CLOCK_MAX];
  int n;
} ocs_clock_t;

/*! ocs_clock_init() : a history of one entry: world time `world` at `utc`, scale 1. */
void ocs_clock_init(ocs_clock_t *c, double utc, double world);
/*! ocs_clock_world() : W(utc). Before the first entry: the first entry's world time. */
double ocs_clock_world(const ocs_clock_t *c, double utc);
/*! ocs_clock_scale() : the scale in force at utc. */
double ocs_clock_scale(const ocs_clock_t *c, double utc);
/*! ocs_clock_set() : a control change at utc: world time `world` (NAN: W(utc), unchanged) and
 *  scale `scale` (NAN: the one in force) from then on. An instant before the newest entry's is
 *  taken as that entry's (the history stays ascending). @return 0 or OC_EINVAL (|world| > 1e12,
 *  scale outside [0, 1e6], or not finite). */
int ocs_clock_set(ocs_clock_t *c, double utc, double world, double scale);
/*! ocs_clock_pause() / ocs_clock_resume() : scale 0 at utc / back to the last non-zero scale. */
int ocs_clock_pause(ocs_clock_t *c, double utc);
int ocs_clock_resume(ocs_clock_t *c, double utc);

#endif /* OC_SERVER_WORLD_CLOCK_H */
