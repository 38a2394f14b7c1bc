/* oc_scene_render.h — what a scene's features and optics mean for rendering, in one place for every
 * renderer and tool (design.md: "leave out what a scene does not need").
 *
 * A scene without an atmosphere builds no tables and renders with OC_RF_NO_ATMOSPHERE; one without
 * a planet surface draws no ground; one without ozone builds its tables with no ozone absorption;
 * one without multiple scattering uses one octave. */
#ifndef OC_COMMON_SCENE_RENDER_H
#define OC_COMMON_SCENE_RENDER_H

#include "oc_atmo.h"   /* oc_atmo_t */
#include "oc_render.h" /* oc_render_desc_t */
#include "oc_scene.h"  /* oc_scene_t */

/*! oc_scene_atmo() : the atmosphere tables the scene needs, built with `threads` threads, into *out;
 *  *out is NULL (and nothing is built) when the scene has no atmosphere.
 *  @return 0, or OC_ENOMEM. */
int oc_scene_atmo(const oc_scene_t *sc, int threads, oc_atmo_t **out);

/*! oc_scene_render_desc() : a render description with the scene's optics and features: albedo,
 *  octaves (1 without multiple scattering) and their parameters, atmosphere (atmo, which must be
 *  what oc_scene_atmo() gave: NULL means OC_RF_NO_ATMOSPHERE), the planet surface. Size, camera and
 *  the tuning knobs are left 0, their defaults; the caller sets them. */
oc_render_desc_t oc_scene_render_desc(const oc_scene_t *sc, const oc_atmo_t *atmo);

#endif /* OC_COMMON_SCENE_RENDER_H */
