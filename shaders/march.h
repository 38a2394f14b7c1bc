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
  ocg_vec3 L;       /**< radiance gathered so far */
  ocg_vec3 T;       /**< transmittance from the camera (clouds and air, RGB) */
  ocg_real Tc;      /**< transmittance of the clouds alone: the alpha channel */
  ocg_vec3 L_ms;    /**< multiply scattered radiance of the current cloud run, before its chord factor */
  ocg_vec3 L_msd;   /**< its diffuse (isotropic) part, before its chord factors */
  ocg_real tau_run; /**< cloud optical depth crossed so far in the current run (0 outside clouds) */
  ocg_vec3 L_far;   /**< sky light of the current run from its far side, decayed by the depth crossed since */
  ocg_real d_far;   /**< chord depth crossed past the chord's cap for L_far alone (ocg_march_chord) */
  ocg_real len_run; /**< the current run's length in cloud, m (scaled with tau_run where a gap is bridged) */
  ocg_real gap;     /**< the open gap's effective length since the run's last thick sample, m (ocg_march_run) */
  ocg_real mu;      /**< cos(view, sun) of the ray (the chord factor's half-depth depends on it) */
#if defined(OC_GLSL)
};
#else
} ocg_march;
#endif

/* ---- The multiple-scattering model's fitted constants ----------------------------------------------
 * Fitted to the Monte Carlo truth (tools/bench_truth.c, docs/numerics.md "The real-time model
 * against the truth"); the CPU reference can override them (oc_render_desc_t.ms_fit) to fit them. */
/*! Chord depth at which a run's multiple scattering reaches half its thick-cloud value. */
#ifndef OCG_MS_CHORD_HALF
#define OCG_MS_CHORD_HALF OCG_R(21.74)
#endif
/*! Octave i is weighted by (b·ω^q)^i: each octave stands for about q more bounces, each ×ω. */
#ifndef OCG_MS_ALBEDO_POWER
#define OCG_MS_ALBEDO_POWER OCG_R(0.0)
#endif
/*! Sky ambient from the near side of a cloud falls as exp(−k·κ_d·d) with the depth d to that side,
 *  κ_d the diffusion constant (occluded ambient; fitted to the uniform-sky truth, not to the sun cases). */
#ifndef OCG_AMBIENT_DEPTH_K
#define OCG_AMBIENT_DEPTH_K OCG_R(0.3609)
#endif
/*! The face of a thick cloud keeps α = R∞ + c·(1 − R∞) of the sky's fluence (ocg_ambient_face). */
#ifndef OCG_AMBIENT_FACE_C
#define OCG_AMBIENT_FACE_C OCG_R(0.15)
#endif
/*! Sky ambient from the far side falls as exp(−b·(1 − ω)·d_f) with the view chord's depth d_f to that
 *  side: light already travelling toward the camera, which each scattering on the way keeps but for
 *  the share 1 − ω it absorbs (ocg_ambient_far_kappa). */
#ifndef OCG_AMBIENT_FAR_B
#define OCG_AMBIENT_FAR_B OCG_R(1.2)
#endif
/*! Past the chord's cap (OCG_MS_CHORD_MAX) a march goes on for the far side's light alone until it
 *  has fallen by e^{−OCG_AMBIENT_FAR_DEPTH}, and never beyond this chord depth. */
#ifndef OCG_AMBIENT_FAR_DEPTH
#define OCG_AMBIENT_FAR_DEPTH OCG_R(8.0)
#endif
#ifndef OCG_AMBIENT_FAR_MAX
#define OCG_AMBIENT_FAR_MAX OCG_R(400.0)
#endif
/*! The diffuse (isotropic) part of the multiply scattered light: its weight b_d and its decay a_d
 *  with the sun optical depth, b_d·ω^q/(1 + a_d·τ)/(4π) — diffusion decays linearly, not exponentially. */
#ifndef OCG_MS_DIFFUSE_B
#define OCG_MS_DIFFUSE_B OCG_R(2.767)
#endif
/*! ...and its own growth with the run's chord depth D, D/(D + D_d): a thin cloud's multiply scattered
 *  light is a few forward bounces, a thick one's diffuse (docs/numerics.md). */
#ifndef OCG_MS_DIFFUSE_D
#define OCG_MS_DIFFUSE_D OCG_R(1.5)
#endif
#ifndef OCG_MS_DIFFUSE_A
#define OCG_MS_DIFFUSE_A OCG_R(0.2960)
#endif
/*! The chord factor's half-depth shrinks toward the sun, D½·exp(−β·max(μ, 0)): light multiply scattered
 *  forward is a few small-angle bounces of the sun's beam and needs no cloud behind the sample to come
 *  back from (docs/numerics.md, "The chord factor toward the sun"). */
#ifndef OCG_MS_FORWARD
#define OCG_MS_FORWARD OCG_R(3.030)
#endif
/*! Absorption along a run's chord, per unit depth and per unit (1 − ω): the light a run returns has
 *  scattered a few times per unit of depth, each ×ω, so it decays as ω^(c·D) ≈ e^{−c(1−ω)D}, linear in
 *  1 − ω (diffusion's κ_d, ∝ √(1 − ω), made ω 0.99 35 % dimmer than ω 1 where the truth is 23 %).
 *  c = κ_d(0.9)/0.1, so the constants fitted at ω 0.9 and 1 keep their values (docs/numerics.md,
 *  "Absorption along the chord"). */
#define OCG_MS_CHORD_ABS OCG_R(2.583)
/*! Absorption along the sun's path, per unit sun optical depth and per unit (1 − ω): the multiply
 *  scattered light at sun depth τ has scattered about s·τ times on its way in, each ×ω, so it falls as
 *  e^{−s(1−ω)τ} on top of its hyperbolic decay, as κ_c along the view chord (docs/numerics.md,
 *  "Absorption along the sun's path"). The factor is 1 at ω = 1. */
#ifndef OCG_MS_SUN_ABS
#define OCG_MS_SUN_ABS OCG_R(0.9241)
#endif
/*! The share of a sample's multiply scattered light that the cloud along the sun's path lights at once,
 *  S = γτ/(γτ + D½(μ)) (ocg_ms_split): light scattered forward on its way in from the sun needs no cloud
 *  behind the sample along the view to come back from, so that share skips the chord factor
 *  (docs/numerics.md, "Absorption along the sun's path, and the share it lights at once"). */
#ifndef OCG_MS_SUN_SHARE
#define OCG_MS_SUN_SHARE OCG_R(0.2214)
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
  ocg_int legacy;  /**< 1: plain Wrenninge octaves, unoccluded ambient (the model before the fit) */
  ocg_real chord_half;   /**< OCG_MS_CHORD_HALF */
  ocg_real albedo_power; /**< OCG_MS_ALBEDO_POWER */
  ocg_real ambient_k;    /**< OCG_AMBIENT_DEPTH_K */
  ocg_real diffuse_b;    /**< OCG_MS_DIFFUSE_B */
  ocg_real diffuse_a;    /**< OCG_MS_DIFFUSE_A */
  ocg_real ms_forward;   /**< OCG_MS_FORWARD */
  ocg_real sun_abs;      /**< OCG_MS_SUN_ABS */
  ocg_real sun_share;    /**< OCG_MS_SUN_SHARE */
#if defined(OC_GLSL)
};
#else
} ocg_cloud_model;
#endif

OC_INLINE ocg_march ocg_march_begin(ocg_real mu) {
  ocg_march m;
  m.mu = mu;
  m.L = ocg_v3s(OCG_R(0.0));
  m.T = ocg_v3s(OCG_R(1.0));
  m.Tc = OCG_R(1.0);
  m.L_ms = ocg_v3s(OCG_R(0.0));
  m.L_msd = ocg_v3s(OCG_R(0.0));
  m.tau_run = OCG_R(0.0);
  m.L_far = ocg_v3s(OCG_R(0.0));
  m.d_far = OCG_R(0.0);
  m.len_run = OCG_R(0.0);
  m.gap = OCG_R(0.0);
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

/* The end of a cloud segment that starts t metres along the ray in a leaf whose step is h: the next
 * multiple of h along the ray, at least 1 % of a step on (the leaf's face may end it sooner). The
 * sample planes are then spheres about the camera shared by all leaves of one level (and, steps being
 * powers of two apart, by the coarser ones), not a grid restarted at each leaf's entry face: a grid per
 * leaf put each leaf's quadrature error on its own phase, and that error jumped across the leaves'
 * faces, drawn as diamond-shaped seams where coarse leaves meet at the horizon (the octree's faces
 * cross the view obliquely). docs/numerics.md, "Sample planes shared across leaves". */
OC_INLINE ocg_real ocg_march_step_end(ocg_real t, ocg_real h) {
  return ocg_max((ocg_floor(t / h + OCG_R(0.01)) + OCG_R(1.0)) * h, t + OCG_R(0.01) * h); /* the max: rounding */
}

/* ---- Cloud sources: radiance scattered toward the camera per metre ------------------------------------
 * A cloud sample sees three lights. Single scattering is exact given the τ channel; multiple
 * scattering and the sky are modelled:
 *
 * $J_c = \omega\,\sigma_c\,[E_{sun} e^{-\tau} p(\mu) + E\,\frac{F}{4\pi}\,A]$ now, and
 * $J_{ms} = \omega\,\sigma_c\,E_{sun}\,e^{-s(1-\omega)\tau} \sum_{i=1}^{n-1} (b\,\omega^q)^i \frac{p(\mu; c^i)}{1 + a^i \tau}$ deferred:
 * the march weights a run's J_ms by $G(D) = D_e/(D_e + D_{1/2} e^{-\beta \max(\mu, 0)})$ once it knows the run's
 * chord optical depth D (where the ray leaves the cloud, or stops; D_e = D at ω = 1, less with absorption:
 * ocg_ms_chord_factor). The octaves alone (Wrenninge) give
 * a thin cloud as much multiple scattering as a thick one; G brings in how much cloud there is behind
 * the sample to send light back (toward the sun little is needed: forward bounces), and the
 * ω^{qi} factor that each octave is several more bounces, each losing 1 − ω. The isotropic part
 * $J_{msd} = \omega\,\sigma_c\,E_{sun}\,e^{-s(1-\omega)\tau}\,\frac{b_d\,\omega^q}{4\pi (1 + a_d \tau)}$ is deferred apart and weighted by
 * G(D)·H(D), H(D) = D/(D + D_d): a thin cloud's multiply scattered light is a few forward bounces,
 * still peaked like the phase function; only a thick cloud's is diffuse. Both fall with absorption
 * along the sun's path, e^{−s(1−ω)τ} (ocg_ms_sun_absorption): without it an absorbing cloud's far side,
 * 20–50 deep toward the sun, kept the light of a conservative one (the hyperbolic decay knows no ω).
 * And a share S = γτ/(γτ + D½(μ)) of both joins the source at once (ocg_ms_split): light scattered
 * forward on its way in from the sun needs no cloud behind the sample, so both are weighted by
 * S + (1 − S)·G(D) in all.
 *
 * Occluded ambient: the sky fluence F reaches a sample through the cloud around it. In a
 * conservative cloud (ω = 1) the diffuse field under a uniform sky is the sky itself at every depth
 * (radiative equilibrium), so A = 1; with absorption it decays with the depth to each side:
 * $A = \alpha\,e^{-\kappa\,d_n} + (1 - \alpha)\,e^{-\kappa_f\,d_f}$, $\kappa = k\,\kappa_d$,
 * $\kappa_d = \sqrt{3(1 - \omega)(1 - \omega \bar g)}$ with the phase function's mean cosine ḡ = 0.864,
 * $\kappa_f = b\,(1 - \omega)$, and α = R∞ + c(1 − R∞) what the face of a semi-infinite cloud keeps.
 * The cloud's phase function is strongly forward, so a sample scatters toward the camera mostly
 * light that travels toward the camera. Near the camera's face of a thick cloud that is the cloud's
 * diffuse reflectance R∞ (van de Hulst's similarity fit, $R_\infty = \frac{(1 - s)(1 - 0.139 s)}{1 + 1.17 s}$,
 * $s = \sqrt{\frac{1 - \omega}{1 - \omega \bar g}}$), plus a share c of the rest for the sky seen off the
 * forward lobe, decaying into the cloud over the diffusion length. The rest, 1 − α, is the sky behind
 * the cloud, come along the view chord through the depth d_f still to cross: forward scattering keeps
 * its direction, and each scattering absorbs 1 − ω of it, so it falls linearly in 1 − ω rather than
 * as diffusion's κ_d (as the chord factor's κ_c). c = 0.15, k = 0.35, b = 1.2: docs/numerics.md,
 * "Sky ambient under a uniform sky". A thin cloud gives A → 1, a thick one's face α, its core 0;
 * ω = 1 gives A = 1 at any depth. The near side's depth d_n = min(τ, τ_run) (toward the sun or the
 * camera, whichever is nearer) is known at the sample; the far side's d_f = D − τ_run only where the
 * run ends, so that term is gathered apart (L_far) and decayed by e^{−κ_f σ_c d} over every later
 * segment of the run, chord steps included, past the chord's cap too (ocg_march_chord).
 *
 * legacy = 1 is the model before the fit: Σ_{i<n} b^i e^{−a^i τ} p(μ; c^i) now, unoccluded ambient.
 * Domain: σ_c ≥ 0, τ ≥ 0, μ ∈ [−1, 1], ω ∈ [0, 1], a, b, c ∈ (0, 1]. */
#define OCG_PHASE_MEAN_COS OCG_R(0.864)
/* κ_d = √(3(1 − ω)(1 − ω ḡ)), the diffusion constant of the cloud's albedo (0 at ω = 1). */
OC_INLINE ocg_real ocg_diffusion_kappa(OC_IN(ocg_cloud_model) cm) {
  ocg_real w = ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0));
  return ocg_safe_sqrt(OCG_R(3.0) * (OCG_R(1.0) - w) * (OCG_R(1.0) - w * OCG_PHASE_MEAN_COS));
}

/* κ = k·κ_d, the ambient's decay per unit optical depth (0 for the legacy model and at ω = 1). */
OC_INLINE ocg_real ocg_ambient_kappa(OC_IN(ocg_cloud_model) cm) {
  if (cm.legacy != 0) return OCG_R(0.0);
  return cm.ambient_k * ocg_diffusion_kappa(cm);
}

/* α = R∞ + c·(1 − R∞): the share of A that a thick cloud keeps at its face (1 at ω = 1). */
OC_INLINE ocg_real ocg_ambient_face(OC_IN(ocg_cloud_model) cm) {
  ocg_real w = ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0));
  ocg_real s = ocg_safe_sqrt((OCG_R(1.0) - w) / (OCG_R(1.0) - w * OCG_PHASE_MEAN_COS));
  ocg_real r_inf = (OCG_R(1.0) - s) * (OCG_R(1.0) - OCG_R(0.139) * s) / (OCG_R(1.0) + OCG_R(1.17) * s);
  return r_inf + OCG_AMBIENT_FACE_C * (OCG_R(1.0) - r_inf);
}

/* κ_f = b·(1 − ω), the far side's decay per unit optical depth along the view chord (0 for the legacy
 * model and at ω = 1). */
OC_INLINE ocg_real ocg_ambient_far_kappa(OC_IN(ocg_cloud_model) cm) {
  if (cm.legacy != 0) return OCG_R(0.0);
  return OCG_AMBIENT_FAR_B * (OCG_R(1.0) - ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0)));
}

/* e^{−κ d_n}: the near side's decay at the sample (the legacy model: 1, unoccluded). */
OC_INLINE ocg_real ocg_ambient_occlusion(OC_IN(ocg_cloud_model) cm, ocg_real tau, ocg_real tau_run) {
  if (cm.legacy != 0) return OCG_R(1.0);
  return ocg_exp(-ocg_ambient_kappa(cm) * ocg_max(ocg_min(tau, tau_run), OCG_R(0.0)));
}

/* The far side's source ω σ_c F/(4π)·(1 − α), before its decay e^{−κ_f d_f} (0 for the legacy model). */
OC_INLINE ocg_vec3 ocg_cloud_source_far(OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_vec3 e_fluence) {
  if (cm.legacy != 0) return ocg_v3s(OCG_R(0.0));
  return ocg_scale3(e_fluence, (OCG_R(1.0) - ocg_ambient_face(cm)) * OCG_INV_4PI * cm.albedo * sig);
}

OC_INLINE ocg_vec3 ocg_cloud_source(OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real tau, ocg_real tau_run, ocg_real mu,
                                    ocg_vec3 e_sun, ocg_vec3 e_fluence) {
  ocg_real n = cm.legacy != 0 ? ocg_ms_octaves(tau, mu, cm.ms_a, cm.ms_b, cm.ms_c, cm.ms_n)
                              : ocg_exp(-ocg_max(tau, OCG_R(0.0))) * ocg_phase_hg_draine(mu);
  ocg_real face = cm.legacy != 0 ? OCG_R(1.0) : ocg_ambient_face(cm);
  ocg_real amb = OCG_INV_4PI * face * ocg_ambient_occlusion(cm, tau, tau_run);
  ocg_vec3 s = ocg_add3(ocg_scale3(e_sun, n), ocg_scale3(e_fluence, amb));
  return ocg_scale3(s, cm.albedo * sig);
}

/* e^{−s(1−ω)τ}: what absorption leaves of the multiply scattered light at sun depth τ ≥ 0. */
OC_INLINE ocg_real ocg_ms_sun_absorption(OC_IN(ocg_cloud_model) cm, ocg_real t) {
  return ocg_exp(-cm.sun_abs * (OCG_R(1.0) - ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0))) * t);
}

/* ω^q: each octave (and the diffuse part) stands for about q more bounces, each ×ω. */
OC_INLINE ocg_real ocg_ms_albedo_weight(OC_IN(ocg_cloud_model) cm) {
  return cm.albedo > OCG_R(0.0) ? ocg_pow(ocg_min(cm.albedo, OCG_R(1.0)), cm.albedo_power) : OCG_R(0.0);
}

OC_INLINE ocg_vec3 ocg_cloud_source_ms(OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real tau, ocg_real mu, ocg_vec3 e_sun) {
  if (cm.legacy != 0 || cm.ms_n < 2) return ocg_v3s(OCG_R(0.0));
  ocg_real t = ocg_max(tau, OCG_R(0.0));
  ocg_real wq = ocg_ms_albedo_weight(cm);
  ocg_real bw = cm.ms_b * wq;
  ocg_real sum = OCG_R(0.0), ai = cm.ms_a, bi = bw, ci = cm.ms_c;
  for (ocg_int i = 1; i < cm.ms_n; ++i) {
    sum += bi / (OCG_R(1.0) + ai * t) * ocg_phase_hg_draine_scaled(mu, ci);
    ai *= cm.ms_a;
    bi *= bw;
    ci *= cm.ms_c;
  }
  return ocg_scale3(e_sun, sum * cm.albedo * sig * ocg_ms_sun_absorption(cm, t));
}

/* The diffuse part of the multiply scattered light, b_d·ω^q/(1 + a_d·τ)/(4π), deferred apart. */
OC_INLINE ocg_vec3 ocg_cloud_source_msd(OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real tau, ocg_vec3 e_sun) {
  if (cm.legacy != 0 || cm.ms_n < 2) return ocg_v3s(OCG_R(0.0));
  ocg_real wq = ocg_ms_albedo_weight(cm);
  ocg_real t = ocg_max(tau, OCG_R(0.0));
  ocg_real w = cm.diffuse_b * wq * OCG_INV_4PI / (OCG_R(1.0) + cm.diffuse_a * t) * ocg_ms_sun_absorption(cm, t);
  return ocg_scale3(e_sun, w * cm.albedo * sig);
}

/* The half-depth toward the sun, D½(μ) = D½·exp(−β·max(μ, 0)) (ocg_ms_chord_factor, ocg_ms_split). */
OC_INLINE ocg_real ocg_ms_half_depth(OC_IN(ocg_cloud_model) cm, ocg_real mu) {
  return cm.chord_half * ocg_exp(-cm.ms_forward * ocg_max(mu, OCG_R(0.0)));
}

/* The share S = γτ/(γτ + D½(μ)) of a sample's multiply scattered light (octaves j_ms and diffuse part j_msd,
 * at sun optical depth τ) joins its source j now; the rest stays deferred for the chord factor, so the
 * light is weighted by S + (1 − S)·G(D) in all. */
OC_INLINE void ocg_ms_split(OC_IN(ocg_cloud_model) cm, ocg_real tau, ocg_real mu, OC_INOUT(ocg_vec3) j,
                            OC_INOUT(ocg_vec3) j_ms, OC_INOUT(ocg_vec3) j_msd) {
  ocg_real gt = cm.sun_share * ocg_max(tau, OCG_R(0.0));
  if (!(gt > OCG_R(0.0))) return;
  ocg_real s = gt / (gt + ocg_ms_half_depth(cm, mu));
  OC_DEREF(j) = ocg_add3(OC_DEREF(j), ocg_scale3(ocg_add3(OC_DEREF(j_ms), OC_DEREF(j_msd)), s));
  OC_DEREF(j_ms) = ocg_scale3(OC_DEREF(j_ms), OCG_R(1.0) - s);
  OC_DEREF(j_msd) = ocg_scale3(OC_DEREF(j_msd), OCG_R(1.0) - s);
}

/* The diffuse part's own growth with the run's depth, H(D) = D/(D + D_d). */
OC_INLINE ocg_real ocg_ms_diffuse_factor(ocg_real d) {
  return d / (d + OCG_MS_DIFFUSE_D);
}

/* The chord factor G(D) = D_e/(D_e + D½(μ)) of a run of chord optical depth D ≥ 0 seen at μ = cos(view, sun),
 * D½(μ) = D½·exp(−β·max(μ, 0)), D_e = (1 − e^{−κ_c D})/κ_c the depth that still returns light, κ_c = c·(1 − ω). */
OC_INLINE ocg_real ocg_ms_chord_factor(OC_IN(ocg_cloud_model) cm, ocg_real d, ocg_real mu) {
  ocg_real kc = OCG_MS_CHORD_ABS * (OCG_R(1.0) - ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0)));
  ocg_real de = kc * d > OCG_R(1e-3) ? (OCG_R(1.0) - ocg_exp(-kc * d)) / kc : d;
  return de / (de + ocg_ms_half_depth(cm, mu));
}

/* ---- The cloud's shadow ------------------------------------------------------------------------------
 * The share of the sun's light that reaches a point with sun optical depth τ (air or ground below or
 * beside a cloud): the direct beam e^{−τ} plus what the cloud transmits diffusely,
 * $S = e^{-\tau} + \omega\,\max(T_d - e^{-\tau}, 0)$, $T_d = \frac{2 e^{-x}}{1 + e^{-2x} + a_s\tau\,(1 - e^{-2x})/x}$,
 * x = κ_d τ: the two-stream slab's transmission, 1/(1 + a_s τ) at ω = 1 (diffusion falls linearly
 * with depth, not exponentially), e^{−κ_d τ}-like with absorption. A slab would have a_s = ¾(1 − ḡ)
 * = 0.10; a finite cloud spreads what it transmits beyond its own shadow, faster the thicker it is,
 * so a_s is fitted to the thin-air truth (docs/numerics.md "Thin air and the cloud's shadow in it").
 * Written with e^{−x} only, so a deep τ cannot overflow; the legacy model keeps e^{−τ}. */
#ifndef OCG_SHADOW_DIFFUSE_A
#define OCG_SHADOW_DIFFUSE_A OCG_R(0.5)
#endif
OC_INLINE ocg_real ocg_cloud_shadow(OC_IN(ocg_cloud_model) cm, ocg_real tau) {
  ocg_real t = ocg_max(tau, OCG_R(0.0)), direct = ocg_exp(-t);
  if (cm.legacy != 0 || !(t > OCG_R(0.0))) return direct;
  ocg_real x = ocg_diffusion_kappa(cm) * t, e = ocg_exp(-x);
  ocg_real span = x > OCG_R(1e-3) ? (OCG_R(1.0) - e * e) / x : OCG_R(2.0) * (OCG_R(1.0) - x); /* (1 − e^{−2x})/x */
  ocg_real td = OCG_R(2.0) * e / (OCG_R(1.0) + e * e + OCG_SHADOW_DIFFUSE_A * t * span);
  return direct + ocg_clamp(cm.albedo, OCG_R(0.0), OCG_R(1.0)) * ocg_max(td - direct, OCG_R(0.0));
}

/* Air at radius r: $J_a = (\beta_R p_R(\mu) + \beta_M p_{CS}(\mu, g_M))\,E_{sun} S
 * + (\beta_R + \beta_M)\,E\,\Psi_{ms}$: single scattering in the cloud's shadow (S = ocg_cloud_shadow of
 * the state's τ at the sample) plus Hillaire's multiple-scattering term (e_multi = E·Ψ_ms from the table). */
OC_INLINE ocg_vec3 ocg_air_source(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu, ocg_vec3 e_sun, ocg_real shadow,
                                  ocg_vec3 e_multi) {
  ocg_vec3 sr = ocg_atmo_rayleigh_scattering(atm, r);
  ocg_real sm = ocg_atmo_mie_scattering(atm, r);
  ocg_vec3 single = ocg_add3(ocg_scale3(sr, ocg_phase_rayleigh(mu)), ocg_v3s(sm * ocg_phase_cornette_shanks(mu, atm.mie_g)));
  ocg_vec3 lit = ocg_scale3(e_sun, shadow);
  return ocg_add3(ocg_mul3(single, lit), ocg_mul3(ocg_add3(sr, ocg_v3s(sm)), e_multi));
}

/* Thin homogeneous air (oc_render_desc_t.air_sigma, where there is no atmosphere): grey, no absorption,
 * isotropic phase 1/(4π) (as the Monte Carlo truth's air medium, tools/bench_mc.c): single scattering
 * of the sun in the cloud's shadow S (ocg_cloud_shadow), plus a uniform sky of radiance B (OC_BG_CONSTANT):
 * $J_a = \sigma\,[E_{sun} S/(4\pi) + B]$, with E_sun already through the air toward the sun,
 * $e^{-\sigma \ell_{sun}}$ (the caller's: the same E_sun lights the clouds in the air).
 * Its multiple scattering is left out: of order σ·ℓ of the single (docs/numerics.md, "Thin air"). */
OC_INLINE ocg_vec3 ocg_thin_air_source(ocg_real sigma, ocg_vec3 e_sun, ocg_real shadow, ocg_real sky) {
  ocg_real lit = shadow * OCG_INV_4PI;
  return ocg_add3(ocg_scale3(e_sun, sigma * lit), ocg_v3s(sigma * sky));
}

/* The share of a segment of cloud extinction sig that counts as cloud in the current run: 1 at half the
 * run's mean extinction or more, in proportion below it (the rest is gap: ocg_march_run below); 1 for
 * the run's first segment. */
OC_INLINE ocg_real ocg_march_thick(OC_IN(ocg_march) m, ocg_real sig) {
  if (!(sig > OCG_R(0.0))) return OCG_R(0.0);
  ocg_real ref = m.len_run > OCG_R(0.0) ? OCG_R(0.5) * m.tau_run / m.len_run : OCG_R(0.0);
  return sig >= ref ? OCG_R(1.0) : sig / ref;
}

/* ---- One segment -----------------------------------------------------------------------------------
 * Over a segment of length d with constant σ_t (RGB, clouds and air) and source J (Hillaire 2015):
 * $L \mathrel{+}= T\,J\,\frac{1 - e^{-\sigma_t d}}{\sigma_t}$, then $T \mathrel{*}= e^{-\sigma_t d}$ and
 * $T_c \mathrel{*}= e^{-\sigma_c d}$. Exact for a homogeneous segment at any length; the weight's series
 * (optics.h) keeps σ_t → 0 finite. The far-side ambient j_far joins L_far at the segment's middle depth
 * and L_far decays by e^{−κ σ_c d} (κ = ocg_ambient_far_kappa). */
OC_INLINE void ocg_march_segment(OC_INOUT(ocg_march) m, ocg_vec3 sigma_t, ocg_real sig, ocg_vec3 j, ocg_vec3 j_ms,
                                  ocg_vec3 j_msd, ocg_vec3 j_far, ocg_real kappa, ocg_real d) {
  ocg_vec3 w = ocg_segment_weight3(sigma_t, d);
  ocg_real decay = ocg_exp(-kappa * sig * d);
  OC_DEREF(m).L_far = ocg_add3(ocg_scale3(OC_DEREF(m).L_far, decay),
                               ocg_scale3(ocg_mul3(OC_DEREF(m).T, ocg_mul3(j_far, w)), ocg_exp(OCG_R(-0.5) * kappa * sig * d)));
  OC_DEREF(m).L = ocg_add3(OC_DEREF(m).L, ocg_mul3(OC_DEREF(m).T, ocg_mul3(j, w)));
  OC_DEREF(m).L_ms = ocg_add3(OC_DEREF(m).L_ms, ocg_mul3(OC_DEREF(m).T, ocg_mul3(j_ms, w)));
  OC_DEREF(m).L_msd = ocg_add3(OC_DEREF(m).L_msd, ocg_mul3(OC_DEREF(m).T, ocg_mul3(j_msd, w)));
  OC_DEREF(m).len_run = OC_DEREF(m).len_run + d * ocg_march_thick(OC_DEREF(m), sig);
  OC_DEREF(m).tau_run = OC_DEREF(m).tau_run + sig * d;
  OC_DEREF(m).T = ocg_mul3(OC_DEREF(m).T, ocg_exp3(ocg_scale3(sigma_t, -d)));
  OC_DEREF(m).Tc = OC_DEREF(m).Tc * ocg_exp(-sig * d);
}

/* The share s of the current run's deferred light joins L: its multiple scattering with the chord
 * factor of the depth crossed so far, its far-side ambient as decayed; 1 − s stays deferred. */
OC_INLINE void ocg_march_commit(OC_INOUT(ocg_march) m, OC_IN(ocg_cloud_model) cm, ocg_real s) {
  if (OC_DEREF(m).tau_run > OCG_R(0.0)) {
    ocg_real g = ocg_ms_chord_factor(cm, OC_DEREF(m).tau_run, OC_DEREF(m).mu), h = ocg_ms_diffuse_factor(OC_DEREF(m).tau_run);
    OC_DEREF(m).L = ocg_add3(OC_DEREF(m).L, ocg_scale3(ocg_add3(OC_DEREF(m).L_ms, ocg_scale3(OC_DEREF(m).L_msd, h)), g * s));
  }
  OC_DEREF(m).L = ocg_add3(OC_DEREF(m).L, ocg_scale3(OC_DEREF(m).L_far, s));
  OC_DEREF(m).L_far = ocg_scale3(OC_DEREF(m).L_far, OCG_R(1.0) - s);
  OC_DEREF(m).L_ms = ocg_scale3(OC_DEREF(m).L_ms, OCG_R(1.0) - s);
  OC_DEREF(m).L_msd = ocg_scale3(OC_DEREF(m).L_msd, OCG_R(1.0) - s);
}

/* The end of a cloud run (a long gap, the ground, the end of the ray): all its deferred light joins L. */
OC_INLINE void ocg_march_end_run(OC_INOUT(ocg_march) m, OC_IN(ocg_cloud_model) cm) {
  ocg_march_commit(m, cm, OCG_R(1.0));
  OC_DEREF(m).L_far = ocg_v3s(OCG_R(0.0));
  OC_DEREF(m).L_ms = ocg_v3s(OCG_R(0.0));
  OC_DEREF(m).L_msd = ocg_v3s(OCG_R(0.0));
  OC_DEREF(m).tau_run = OCG_R(0.0);
  OC_DEREF(m).d_far = OCG_R(0.0);
  OC_DEREF(m).len_run = OCG_R(0.0);
  OC_DEREF(m).gap = OCG_R(0.0);
}

/* ---- Runs across gaps ----------------------------------------------------------------------------
 * A run is the stretch of cloud whose chord depth D weights its multiply scattered light. It used to
 * end at the first sample with σ_c = 0 exactly. Between samples the σ_c of a state is trilinear, so
 * its zero sets are unions of cubes: a ray through a cube of clear air ended its run and the ray
 * beside it, through a trace of cloud, did not, and the light drew the cubes (the Disney cloud's
 * shaded side, docs/numerics.md "Runs across gaps"). Now the run is continuous in the field:
 *
 * - a segment thinner than half the run's mean extinction σ̄ = D/ℓ (ℓ the run's length in cloud)
 *   opens a gap, of effective length $g \mathrel{+}= d\,(1 - 2\sigma_c/\bar\sigma)$: clear air counts in
 *   full, thin cloud in part;
 * - at the next segment at least σ̄/2 thick the run goes on with the coupling $k = e^{-g/\ell}$ (the
 *   cloud on both sides of a gap short beside the run is one cloud): the share 1 − k of its deferred
 *   light joins L with the chord factor of the depth so far (ocg_march_commit), the share k stays, and
 *   the depth and length carried on are scaled by $k_D = \max(1 - j(1 - k)/k, 0)$, j = OCG_RUN_JUMP;
 * - a gap of OCG_RUN_GAP_END·ℓ ends the run.
 *
 * Every limit is the old rule's: no gap, one run; a long gap, two runs; a ray that leaves the cloud and
 * never meets it again, one run with the depth it crossed. A ray that meets a sliver of cloud after a
 * gap differs from one that does not by k·(G(D) − G(k_D·D)) ≤ k(1 − k_D) ≤ j(1 − k) of the run's
 * octaves (G is concave, G(0) = 0), twice that of its diffuse part (G·H), where a cube's edge moved
 * all of it; a separate cloud behind the gap is credited k_D of the depth before it, none past a gap
 * of ln((1 + j)/j)·ℓ ≈ 3ℓ. */
#ifndef OCG_RUN_GAP_END
#define OCG_RUN_GAP_END OCG_R(4.0)
#endif
#ifndef OCG_RUN_JUMP
#define OCG_RUN_JUMP OCG_R(0.05)
#endif

/* A run's gaps (above), before a segment of length d whose cloud extinction is sig: opens or widens the
 * gap, bridges it, or ends the run. */
OC_INLINE void ocg_march_run(OC_INOUT(ocg_march) m, OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real d) {
  if (!(OC_DEREF(m).tau_run > OCG_R(0.0))) return;
  ocg_real thick = ocg_march_thick(OC_DEREF(m), sig), len = OC_DEREF(m).len_run;
  if (thick < OCG_R(1.0)) {
    OC_DEREF(m).gap = OC_DEREF(m).gap + d * (OCG_R(1.0) - thick);
    if (OC_DEREF(m).gap >= OCG_RUN_GAP_END * len) ocg_march_end_run(m, cm);
  } else if (OC_DEREF(m).gap > OCG_R(0.0)) {
    ocg_real k = ocg_exp(-OC_DEREF(m).gap / len), kd = ocg_max(OCG_R(1.0) - OCG_RUN_JUMP * (OCG_R(1.0) - k) / k, OCG_R(0.0));
    ocg_march_commit(m, cm, OCG_R(1.0) - k);
    OC_DEREF(m).tau_run = OC_DEREF(m).tau_run * kd;
    OC_DEREF(m).len_run = len * kd;
    OC_DEREF(m).gap = OCG_R(0.0);
  }
}

/*! Past the early exit the march goes on through the current cloud run only to measure its chord
 *  depth D (one σ_t lookup per step, steps OCG_MS_CHORD_STEP times longer, no lighting), up to
 *  OCG_MS_CHORD_MAX: the lit face of a thick cloud is bright because of the cloud behind it. */
#ifndef OCG_MS_CHORD_STEP
#define OCG_MS_CHORD_STEP 8.0
#endif
#ifndef OCG_MS_CHORD_MAX
#define OCG_MS_CHORD_MAX OCG_R(40.0)
#endif

/* Whether a march past its early exit measures the chord at all: only the fitted model uses it. */
OC_INLINE ocg_atmo_bool ocg_march_wants_chord(OC_IN(ocg_march) m, OC_IN(ocg_cloud_model) cm) {
  return cm.legacy == 0 && cm.ms_n > 1 && m.tau_run > OCG_R(0.0);
}

/* One chord-only step of length d (κ: ocg_ambient_far_kappa): @return whether to go on: the run not
 * ended (its gaps as in the lit march, ocg_march_run), and D below the cap, or past it (D = the cap's
 * crossing, d_far beyond) while the far side's light has not yet fallen by e^{−OCG_AMBIENT_FAR_DEPTH}
 * since, up to OCG_AMBIENT_FAR_MAX in all. A run without that light (the sun alone, ω = 1) stops at the
 * cap, and the chord factor never sees d_far. */
OC_INLINE ocg_atmo_bool ocg_march_chord(OC_INOUT(ocg_march) m, OC_IN(ocg_cloud_model) cm, ocg_real sig, ocg_real kappa,
                                        ocg_real d) {
  ocg_march_run(m, cm, sig, d);
  ocg_atmo_bool open = OC_DEREF(m).tau_run > OCG_R(0.0);
  if (open && sig > OCG_R(0.0)) {
    if (OC_DEREF(m).tau_run < OCG_MS_CHORD_MAX) {
      OC_DEREF(m).len_run = OC_DEREF(m).len_run + d * ocg_march_thick(OC_DEREF(m), sig);
      OC_DEREF(m).tau_run = OC_DEREF(m).tau_run + sig * d;
    } else {
      OC_DEREF(m).d_far = OC_DEREF(m).d_far + sig * d;
    }
    OC_DEREF(m).L_far = ocg_scale3(OC_DEREF(m).L_far, ocg_exp(-kappa * sig * d));
  }
  ocg_real lf = ocg_max(OC_DEREF(m).L_far.x, ocg_max(OC_DEREF(m).L_far.y, OC_DEREF(m).L_far.z));
  ocg_atmo_bool far = lf > OCG_R(0.0) && kappa * OC_DEREF(m).d_far < OCG_AMBIENT_FAR_DEPTH &&
                      OC_DEREF(m).tau_run + OC_DEREF(m).d_far < OCG_AMBIENT_FAR_MAX;
  return open && (OC_DEREF(m).tau_run < OCG_MS_CHORD_MAX || far);
}

/* Early exit: every channel of T below exit_t (exit_t ≤ 0: never). What is left is at most exit_t of
 * the background's radiance. */
OC_INLINE ocg_atmo_bool ocg_march_done(OC_IN(ocg_march) m, ocg_real exit_t) {
  return exit_t > OCG_R(0.0) && ocg_max(m.T.x, ocg_max(m.T.y, m.T.z)) < exit_t;
}

/* ---- The end of the ray ---------------------------------------------------------------------------
 * Lambertian ground of albedo ρ: $L_g = \frac{\rho}{\pi} E\,[T_{sun} \max(\mu_s, 0)\,S_g + I]$,
 * S_g the cloud's shadow (ocg_cloud_shadow of the state's sun optical depth at the ground), I the sky
 * irradiance per unit solar irradiance (0 without a sky). */
OC_INLINE ocg_vec3 ocg_ground_radiance(ocg_vec3 t_sun, ocg_real mu_s, ocg_real shadow, ocg_vec3 sky_irr, ocg_vec3 albedo,
                                       ocg_vec3 e) {
  ocg_vec3 irr = ocg_add3(ocg_scale3(t_sun, ocg_max(mu_s, OCG_R(0.0)) * shadow), sky_irr);
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
