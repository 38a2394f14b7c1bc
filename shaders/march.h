/* march.h — the view-ray march itself, shared by the CPU reference (common/oc_render.c, oc__trace)
 * and the GL renderer (shaders/raymarch.comp.glsl, ocv_trace) (design.md: one implementation of each
 * formula; style.md §4–§5).
 *
 * The two renderers differ only in how they find a sample: the octree descent, the brick lookup and
 * the atmosphere tables (C functions on the CPU, textures on the GPU), and the precision of
 * positions. Everything they do with the looked-up values is here: the in-scattered source of cloud
 * and air, the energy-conserving segment update of radiance and transmittance, the air step, the
 * ground and the sun disc at the end of the ray.
 *
 * Notation: L radiance toward the camera, T transmittance from the camera (RGB: cloud and air), T_c
 * the cloud-only transmittance (the alpha channel), σ_t extinction, τ the state's sun optical depth
 * at the sample, μ = cos(view, sun) (μ = 1 forward), μ_s the sun's zenith cosine at the sample,
 * E the solar irradiance (RGB) and E_sun = E·T_sun(r, μ_s) what reaches the sample through clear air.
 *
 * GLSL: the includer prepends oc_port.h, optics.h and atmosphere.h (GLSL has no #include). */
#ifndef OC_SHADERS_MARCH_H
#define OC_SHADERS_MARCH_H

#ifndef OC_GLSL
#include "atmosphere.h" /* ocg_atmosphere, ocg_atmo_*_scattering, ocg_atmo_extinction */
#include "oc_port.h"    /* ocg_real, ocg_vec3, OC_IN, OC_INOUT, OC_DEREF */
#include "optics.h"     /* ocg_segment_weight3, ocg_ms_octaves, phase functions */
#endif

/* ---- The march's running state -------------------------------------------------------------------- */
#if defined(OC_GLSL)
struct ocg_march {
#else
typedef struct ocg_march {
#endif
  ocg_vec3 L;  /**< radiance gathered so far */
  ocg_vec3 T;  /**< transmittance from the camera (clouds and air, RGB) */
  ocg_real Tc; /**< transmittance of the clouds alone: the alpha channel */
#if defined(OC_GLSL)
};
#else
} ocg_march;
#endif

/* The cloud model's parameters (oc_render_desc_t; the scene's optics). */
#if defined(OC_GLSL)
struct ocg_cloud_model {
#else
typedef struct ocg_cloud_model {
#endif
  ocg_real albedo; /**< single-scattering albedo σ_s/σ_t, [0, 1] */
  ocg_real ms_a;   /**< octave extinction factor, (0, 1] */
  ocg_real ms_b;   /**< octave contribution factor, (0, 1] */
  ocg_real ms_c;   /**< octave eccentricity factor, (0, 1] */
  ocg_int ms_n;    /**< octaves; 1 = single scattering */
#if defined(OC_GLSL)
};
#else
} ocg_cloud_model;
#endif

OC_INLINE ocg_march ocg_march_begin(void) {
  ocg_march m;
  m.L = ocg_v3s(OCG_R(0.0));
  m.T = ocg_v3s(OCG_R(1.0));
  m.Tc = OCG_R(1.0);
  return m;
}

/* ---- Step length in the air ------------------------------------------------------------------------
 * The longest air segment from a point at altitude h whose view ray makes |μ_z| with the vertical:
 * $\Delta = \min(\Delta_0, \max(\frac{(h + 500\,m)/4}{\max(|\mu_z|, 10^{-3})}, \Delta_0/16))$, with
 * Δ0 = air_len / air_steps. The air thins with a few-km scale height, so fixed steps leave rings where
 * segment ends move from ray to ray; the floor Δ0/16 bounds the cost of any ray. */
OC_INLINE ocg_real ocg_march_air_step(ocg_real h, ocg_real mu_z, ocg_real air_step) {
  ocg_real lim = OCG_R(0.25) * (ocg_max(h, OCG_R(0.0)) + OCG_R(500.0)) / ocg_max(ocg_abs(mu_z), OCG_R(1e-3));
  return ocg_min(air_step, ocg_max(lim, air_step / OCG_R(16.0)));
}

/* ---- Sources: radiance scattered toward the camera per metre ---------------------------------------
 * Cloud: $J_c = a\,\sigma_c\,[E_{sun}\,M(\tau, \mu) + E\,F/(4\pi)]$, M the multiple-scattering
 * octaves Σ_{i<n} b^i e^{−a^i τ} p_HGD(μ; c^i) (n = 1: single scattering), F the sky fluence per unit
 * solar irradiance (0 without a sky). Domain: σ_c ≥ 0, τ ≥ 0, μ ∈ [−1, 1]. */
OC_INLINE ocg_vec3 ocg_cloud_source(OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real tau, ocg_real mu, ocg_vec3 e_sun,
                                    ocg_vec3 e_fluence) {
  ocg_real ms = ocg_ms_octaves(tau, mu, cm.ms_a, cm.ms_b, cm.ms_c, cm.ms_n);
  ocg_vec3 s = ocg_add3(ocg_scale3(e_sun, ms), ocg_scale3(e_fluence, OCG_INV_4PI));
  return ocg_scale3(s, cm.albedo * sig);
}

/* Air at radius r: $J_a = (\beta_R p_R(\mu) + \beta_M p_{CS}(\mu, g_M))\,E_{sun} e^{-\tau}
 * + (\beta_R + \beta_M)\,E\,\Psi_{ms}$: single scattering in the cloud's shadow (τ of the state at the
 * sample) plus Hillaire's multiple-scattering term (e_multi = E·Ψ_ms from the table). */
OC_INLINE ocg_vec3 ocg_air_source(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu, ocg_vec3 e_sun, ocg_real tau,
                                  ocg_vec3 e_multi) {
  ocg_vec3 sr = ocg_atmo_rayleigh_scattering(atm, r);
  ocg_real sm = ocg_atmo_mie_scattering(atm, r);
  ocg_vec3 single = ocg_add3(ocg_scale3(sr, ocg_phase_rayleigh(mu)), ocg_v3s(sm * ocg_phase_cornette_shanks(mu, atm.mie_g)));
  ocg_vec3 lit = ocg_scale3(e_sun, ocg_exp(-tau));
  return ocg_add3(ocg_mul3(single, lit), ocg_mul3(ocg_add3(sr, ocg_v3s(sm)), e_multi));
}

/* ---- One segment -----------------------------------------------------------------------------------
 * Over a segment of length d with constant σ_t (RGB, clouds and air) and source J (Hillaire 2015):
 * $L \mathrel{+}= T\,J\,\frac{1 - e^{-\sigma_t d}}{\sigma_t}$, then $T \mathrel{*}= e^{-\sigma_t d}$ and
 * $T_c \mathrel{*}= e^{-\sigma_c d}$. Exact for a homogeneous segment at any length; the weight's series
 * (optics.h) keeps σ_t → 0 finite. */
OC_INLINE void ocg_march_segment(OC_INOUT(ocg_march) m, ocg_vec3 sigma_t, ocg_real sig, ocg_vec3 j, ocg_real d) {
  ocg_vec3 w = ocg_segment_weight3(sigma_t, d);
  OC_DEREF(m).L = ocg_add3(OC_DEREF(m).L, ocg_mul3(OC_DEREF(m).T, ocg_mul3(j, w)));
  OC_DEREF(m).T = ocg_mul3(OC_DEREF(m).T, ocg_exp3(ocg_scale3(sigma_t, -d)));
  OC_DEREF(m).Tc = OC_DEREF(m).Tc * ocg_exp(-sig * d);
}

/* Early exit: every channel of T below exit_t (exit_t ≤ 0: never). What is left is at most exit_t of
 * the background's radiance. */
OC_INLINE ocg_atmo_bool ocg_march_done(OC_IN(ocg_march) m, ocg_real exit_t) {
  return exit_t > OCG_R(0.0) && ocg_max(m.T.x, ocg_max(m.T.y, m.T.z)) < exit_t;
}

/* ---- The end of the ray ---------------------------------------------------------------------------
 * Lambertian ground of albedo ρ: $L_g = \frac{\rho}{\pi} E\,[T_{sun} \max(\mu_s, 0)\,e^{-\tau_g} + I]$,
 * τ_g the state's sun optical depth at the ground (cloud shadow), I the sky irradiance per unit solar
 * irradiance (0 without a sky). */
OC_INLINE ocg_vec3 ocg_ground_radiance(ocg_vec3 t_sun, ocg_real mu_s, ocg_real tau_g, ocg_vec3 sky_irr, ocg_vec3 albedo,
                                       ocg_vec3 e) {
  ocg_vec3 irr = ocg_add3(ocg_scale3(t_sun, ocg_max(mu_s, OCG_R(0.0)) * ocg_exp(-tau_g)), sky_irr);
  return ocg_mul3(ocg_scale3(albedo, OCG_R(1.0) / OCG_PI), ocg_mul3(e, irr));
}

/* The sun's disc, a uniform disc of angular radius α_s: radiance E/(2π(1 − cos α_s)) where μ > cos α_s,
 * else 0 (black space). */
OC_INLINE ocg_vec3 ocg_sun_disc(ocg_real mu, ocg_real alpha_s, ocg_vec3 e) {
  ocg_real cos_r = ocg_cos(alpha_s);
  if (!(mu > cos_r)) return ocg_v3s(OCG_R(0.0));
  return ocg_scale3(e, OCG_R(1.0) / (OCG_R(2.0) * OCG_PI * (OCG_R(1.0) - cos_r)));
}

/* Adds what lies behind the march's end, seen through T. */
OC_INLINE void ocg_march_background(OC_INOUT(ocg_march) m, ocg_vec3 l_bg) {
  OC_DEREF(m).L = ocg_add3(OC_DEREF(m).L, ocg_mul3(OC_DEREF(m).T, l_bg));
}

#endif /* OC_SHADERS_MARCH_H */
