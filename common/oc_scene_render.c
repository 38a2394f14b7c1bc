#include "oc_scene_render.h"

#include "oc_err.h"

int oc_scene_atmo(const oc_scene_t *sc, int threads, oc_atmo_t **out) {
  *out = NULL;
  if (!oc_scene_has(sc, OC_FEATURE_ATMOSPHERE)) return 0;
  ocg_atmosphere ap;
  oc_atmo_params_default(&ap);
  if (!oc_scene_has(sc, OC_FEATURE_OZONE)) ap.ozone_absorption = ocg_v3s(0.0f);
  *out = oc_atmo_create(&ap, threads);
  return *out ? 0 : OC_ENOMEM;
}

oc_render_desc_t oc_scene_render_desc(const oc_scene_t *sc, const oc_atmo_t *atmo) {
  oc_render_desc_t d = {0};
  d.ms_octaves = oc_scene_has(sc, OC_FEATURE_MULTIPLE_SCATTERING) ? sc->optics.ms_octaves : 1;
  d.ms_a = (float)sc->optics.ms_a;
  d.ms_b = (float)sc->optics.ms_b;
  d.ms_c = (float)sc->optics.ms_c;
  d.albedo = (float)sc->optics.albedo;
  d.albedo_zero = sc->optics.albedo == 0.0;
  d.atmo = atmo;
  d.flags = (atmo ? 0u : (uint32_t)OC_RF_NO_ATMOSPHERE) |
            (oc_scene_has(sc, OC_FEATURE_PLANET_SURFACE) ? 0u : (uint32_t)OC_RF_NO_PLANET);
  return d;
}
