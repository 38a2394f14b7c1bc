/* weather.c — preset table and transitions of the procedural planet (see weather.h). */
#include "weather.h"

#include <math.h>   /* isfinite, floor */
#include <string.h> /* memset, memmove */

#include "oc_err.h"

/*-*** Presets ***/

/* Per layer (stratus, cumulus, cumulonimbus, cirrus): coverage fraction and water-content
 * multiplier. "clear" holds no cloud at all; the others follow the usual pictures of each weather:
 * fair-weather cumulus under a little cirrus; an overcast stratus deck; a storm of cumulonimbus
 * towers over nimbostratus-like stratus and cumulus; high cirrus alone. */
static const ocs_weather_params_t ocs__presets[OC_PRESET_COUNT] = {
    [OC_PRESET_CLEAR] = {{0.0, 0.0, 0.0, 0.0}, {1.0, 1.0, 1.0, 1.0}},
    [OC_PRESET_FAIR] = {{0.05, 0.45, 0.0, 0.15}, {0.8, 1.0, 1.0, 0.7}},
    [OC_PRESET_OVERCAST] = {{0.95, 0.15, 0.0, 0.25}, {1.2, 0.8, 1.0, 1.0}},
    [OC_PRESET_STORM] = {{0.55, 0.5, 0.55, 0.35}, {1.4, 1.2, 1.0, 1.2}},
    [OC_PRESET_CIRRUS] = {{0.0, 0.05, 0.0, 0.85}, {1.0, 0.8, 1.0, 1.0}},
};

void ocs_weather_preset(oc_preset_t preset, ocs_weather_params_t *out) {
  if ((int)preset < 0 || preset >= OC_PRESET_COUNT)
    memset(out, 0, sizeof *out);
  else
    *out = ocs__presets[preset];
}

int ocs_weather_init(ocs_weather_t *w, oc_preset_t preset, double coverage_scale) {
  OC_RETURN_IF(!w || (int)preset < 0 || preset >= OC_PRESET_COUNT, OC_EINVAL);
  OC_RETURN_IF(!isfinite(coverage_scale) || coverage_scale < 0.0 || coverage_scale > 4.0, OC_EINVAL);
  memset(w, 0, sizeof *w);
  for (int p = 0; p < OC_PRESET_COUNT; p++) {
    w->preset[p] = ocs__presets[p];
    for (int l = 0; l < OCS_LAYER_COUNT; l++) {
      double c = w->preset[p].cov[l] * coverage_scale;
      w->preset[p].cov[l] = c > 1.0 ? 1.0 : c;
    }
  }
  w->initial = w->preset[preset];
  return 0;
}

/*-*** Evaluation ***/

static double ocs__smoothstep01(double x) {
  x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
  return x * x * (3.0 - 2.0 * x);
}

/* Quantised progress of change c at time t (t ≥ t0): the index of the step holding t, 0..STEPS. */
static double ocs__step_index(const ocs_weather_change_t *c, double t) {
  if (!(c->seconds > 0.0)) return OCS_WEATHER_STEPS;
  double q = floor((t - c->t0) * (double)OCS_WEATHER_STEPS / c->seconds);
  return q < 0.0 ? 0.0 : (q > OCS_WEATHER_STEPS ? OCS_WEATHER_STEPS : q);
}

/* The latest change with t0 ≤ t, or -1. */
static int ocs__governing(const ocs_weather_t *w, double t) {
  int i = w->count - 1;
  while (i >= 0 && t < w->change[i].t0) i--;
  return i;
}

void ocs_weather_at(const ocs_weather_t *w, double t, int quantised, ocs_weather_params_t *out) {
  int i = ocs__governing(w, t);
  if (i < 0) {
    *out = w->initial;
    return;
  }
  const ocs_weather_change_t *c = &w->change[i];
  double x;
  if (!(c->seconds > 0.0))
    x = 1.0;
  else if (quantised)
    x = ocs__step_index(c, t) / (double)OCS_WEATHER_STEPS;
  else
    x = (t - c->t0) / c->seconds;
  double s = ocs__smoothstep01(x);
  const ocs_weather_params_t *to = &w->preset[c->to];
  if (s >= 1.0) { /* exactly the preset once the change is over (a + (b - a) need not be b) */
    *out = *to;
    return;
  }
  for (int l = 0; l < OCS_LAYER_COUNT; l++) {
    out->cov[l] = c->from.cov[l] + (to->cov[l] - c->from.cov[l]) * s;
    out->wc[l] = c->from.wc[l] + (to->wc[l] - c->from.wc[l]) * s;
  }
}

/* Each change contributes 1 when it starts (its frozen starting parameters replace the previous
 * blend) plus its step index, frozen when the next change starts. Every term is non-decreasing in
 * t, so the sum is, and it rises exactly when the governing change or its step does. */
uint64_t ocs_weather_step(const ocs_weather_t *w, double t) {
  uint64_t k = 0;
  for (int i = 0; i < w->count && t >= w->change[i].t0; i++) {
    double end = (i + 1 < w->count && w->change[i + 1].t0 <= t) ? w->change[i + 1].t0 : t;
    k += 1u + (uint64_t)ocs__step_index(&w->change[i], end);
  }
  return k;
}

int ocs_weather_set(ocs_weather_t *w, oc_preset_t preset, double t0, double seconds) {
  OC_RETURN_IF(!w || (int)preset < 0 || preset >= OC_PRESET_COUNT, OC_EINVAL);
  OC_RETURN_IF(!isfinite(t0) || !isfinite(seconds) || seconds < 0.0, OC_EINVAL);
  while (w->count > 0 && w->change[w->count - 1].t0 >= t0) w->count--;
  ocs_weather_change_t c;
  c.t0 = t0;
  c.seconds = seconds;
  c.to = (int)preset;
  ocs_weather_at(w, t0, 0, &c.from); /* continuous: the unquantised blend at t0 */
  if (w->count == OCS_WEATHER_HISTORY) {
    /* Forget the oldest: before the new oldest t0 the weather reads as its starting parameters. */
    memmove(&w->change[0], &w->change[1], (OCS_WEATHER_HISTORY - 1) * sizeof w->change[0]);
    w->count--;
    w->initial = w->change[0].from;
  }
  w->change[w->count++] = c;
  w->generation++;
  return 0;
}
