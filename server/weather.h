/* weather.h — weather presets of the procedural planet and their transitions over world time.
 *
 * A preset is a parameter set per cloud layer (coverage fraction and water-content multiplier).
 * The weather is a pure function of world time: the initial preset, then a short history of
 * changes, each "from the parameters in force at t0, move to preset P over [t0, t0 + seconds]"
 * with a smoothstep weight. Every viewer evaluates the same function of the same clock, so all
 * see the same sky at once (docs/procedural.md, "Weather").
 *
 * Not thread-safe for writers: ocs_weather_set() must not race with readers (the field's caller
 * serialises it, ocs_field.h). Readers are pure. */
#ifndef OC_SERVER_WEATHER_H
#define OC_SERVER_WEATHER_H

#include <stdint.h>

#include "oc_scene.h" /* oc_preset_t, OC_PRESET_COUNT */

/*! Cloud layers of the procedural planet, in the order their σt is summed. */
typedef enum {
  OCS_LAYER_STRATUS = 0,
  OCS_LAYER_CUMULUS = 1,
  OCS_LAYER_CUMULONIMBUS = 2,
  OCS_LAYER_CIRRUS = 3,
  OCS_LAYER_COUNT = 4
} ocs_layer_t;

/*! Transitions are quantised into this many steps for sampled bricks (the brick cache needs a
 *  content that is constant between time-step changes); point queries see the continuous blend. */
#define OCS_WEATHER_STEPS 32
/*! Changes remembered; older ones are forgotten (before the oldest kept t0, the weather reads as
 *  that change's starting parameters). */
#define OCS_WEATHER_HISTORY 32

typedef struct {
  double cov[OCS_LAYER_COUNT]; /**< area fraction of the layer's coverage map that may hold cloud, [0, 1] */
  double wc[OCS_LAYER_COUNT];  /**< multiplier of the layer's nominal water content, ≥ 0 */
} ocs_weather_params_t;

typedef struct {
  double t0, seconds;        /**< world time the change starts; its duration (0: a switch) */
  int to;                    /**< oc_preset_t reached at t0 + seconds */
  ocs_weather_params_t from; /**< the (continuous) parameters in force at t0 */
} ocs_weather_change_t;

typedef struct {
  ocs_weather_params_t preset[OC_PRESET_COUNT]; /**< the table with coverage_scale applied */
  ocs_weather_params_t initial;                 /**< in force before the first change */
  int count;                                    /**< changes held, ascending t0 */
  ocs_weather_change_t change[OCS_WEATHER_HISTORY];
  uint64_t generation; /**< incremented by every ocs_weather_set() */
} ocs_weather_t;

/*! ocs_weather_preset() : the unscaled parameters of a preset (zeros for an invalid one). */
void ocs_weather_preset(oc_preset_t preset, ocs_weather_params_t *out);

/*! ocs_weather_init() : starts in `preset`; every coverage is multiplied by coverage_scale and
 *  clamped to [0, 1]. @return 0, or OC_EINVAL for a bad preset or scale (finite, [0, 4]). */
int ocs_weather_init(ocs_weather_t *w, oc_preset_t preset, double coverage_scale);

/*! ocs_weather_set() : from the parameters in force at t0, move to `preset` over
 *  [t0, t0 + seconds]. Changes already held with a start at or after t0 are dropped (the latest
 *  call decides the weather from t0 on). @return 0, or OC_EINVAL (bad preset, non-finite t0,
 *  seconds negative or non-finite). */
int ocs_weather_set(ocs_weather_t *w, oc_preset_t preset, double t0, double seconds);

/*! ocs_weather_at() : the parameters at world time t. quantised = 0: the continuous blend;
 *  quantised = 1: the blend at the start of the transition step holding t (what bricks use). */
void ocs_weather_at(const ocs_weather_t *w, double t, int quantised, ocs_weather_params_t *out);

/*! ocs_weather_step() : a count, non-decreasing in t, that changes exactly when the quantised
 *  parameters may change (0 before the first change). */
uint64_t ocs_weather_step(const ocs_weather_t *w, double t);

#endif /* OC_SERVER_WEATHER_H */
