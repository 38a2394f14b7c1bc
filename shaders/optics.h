/* optics.h — phase functions, transmittance, the energy-conserving segment weight, multiple-scattering
 * octaves, water content to extinction and tone mapping, written once for C17 and GLSL 4.50.
 *
 * One implementation of each formula (design.md, "Optics (corrected forms)"): the CPU reference renderer
 * includes this file as C, the raymarch kernels get it concatenated after oc_port.h with OC_GLSL
 * defined. Every function is preceded by its equation and the domain of its arguments; cosines go
 * through ocg_clamp_cos and square roots through ocg_safe_sqrt so rounding never produces NaN.
 * mu = cos(theta) is the cosine between the propagation directions of the incoming and scattered light
 * (mu = 1 is forward scattering). Units: metres, m^-1, kg/kg, kg/m^3.
 *
 * C: `#include "optics.h"` (float); define OCG_REAL_DOUBLE before including for the double build the
 * numerics tests use. GLSL: concatenate oc_port.h, then this file, with OC_GLSL defined.
 * Tests: tests/shaders/test_optics.c (float), test_optics_double.c (double), tests/gl/test_glsl_headers.c
 * (GLSL against C). Figures: docs/numerics.md ("Optics").
 *
 * GLSL line numbers: no invocation of a function-like macro (ocg_v3, ocg_max, OCG_R, ...) spans lines.
 * Mesa's glcpp joins such an invocation onto one line, so every later GLSL error would be reported
 * that many lines too early; tests/gl/test_glsl_headers.c checks that each header keeps its lines. */
#ifndef OC_SHADERS_OPTICS_H
#define OC_SHADERS_OPTICS_H

#ifndef OC_GLSL
#include "oc_port.h" /* ocg_real, OCG_R, ocg_vec3 helpers, NaN guards */
#endif

/* ---- Small exact helpers ------------------------------------------------------------------------- */

/*! OCG_SERIES_X : largest x = sigma_t d for which the Taylor series below replaces 1 - e^{-x}.
 * Below it, 1 - e^{-x} computed naively loses log2(1/x) bits to cancellation (1e-18 -> 0 in float);
 * above it the naive form is within about 1 ulp (e^{-x} <= 0.61, so 1 - e^{-x} >= 0.39 and the
 * subtraction is exact). The series is truncated after the term that is below half an ulp at 0.5:
 * x^9/10! in float, x^16/17! in double. Not a tuning knob: changing it needs the series length checked. */
#define OCG_SERIES_X OCG_R(0.5)

/* $\varphi(x) = \frac{1 - e^{-x}}{x} = \sum_{n \ge 0} \frac{(-x)^n}{(n+1)!}
 *            = 1 - \frac{x}{2}\Big(1 - \frac{x}{3}\big(1 - \frac{x}{4}(\cdots)\big)\Big)$
 * Domain: $x \ge 0$ (negative x is clamped to 0). $\varphi(0) = 1$, never 0/0; relative error within
 * about 1 ulp for every x (Horner form of the series for $x \le 0.5$, the quotient above). */
OC_INLINE ocg_real ocg_one_minus_exp_div(ocg_real x) {
  x = ocg_max(x, OCG_R(0.0));
  if (x > OCG_SERIES_X) return (OCG_R(1.0) - ocg_exp(-x)) / x;
  ocg_real r = OCG_R(1.0);
#if !defined(OC_GLSL) && defined(OCG_REAL_DOUBLE)
  r = OCG_R(1.0) - x * OCG_R(0.0588235294117647059) * r; /* 1/17 */
  r = OCG_R(1.0) - x * OCG_R(0.0625) * r;                /* 1/16 */
  r = OCG_R(1.0) - x * OCG_R(0.0666666666666666667) * r; /* 1/15 */
  r = OCG_R(1.0) - x * OCG_R(0.0714285714285714286) * r; /* 1/14 */
  r = OCG_R(1.0) - x * OCG_R(0.0769230769230769231) * r; /* 1/13 */
  r = OCG_R(1.0) - x * OCG_R(0.0833333333333333333) * r; /* 1/12 */
  r = OCG_R(1.0) - x * OCG_R(0.0909090909090909091) * r; /* 1/11 */
#endif
  r = OCG_R(1.0) - x * OCG_R(0.1) * r;                   /* 1/10 */
  r = OCG_R(1.0) - x * OCG_R(0.111111111111111111) * r;  /* 1/9 */
  r = OCG_R(1.0) - x * OCG_R(0.125) * r;                 /* 1/8 */
  r = OCG_R(1.0) - x * OCG_R(0.142857142857142857) * r;  /* 1/7 */
  r = OCG_R(1.0) - x * OCG_R(0.166666666666666667) * r;  /* 1/6 */
  r = OCG_R(1.0) - x * OCG_R(0.2) * r;                   /* 1/5 */
  r = OCG_R(1.0) - x * OCG_R(0.25) * r;                  /* 1/4 */
  r = OCG_R(1.0) - x * OCG_R(0.333333333333333333) * r;  /* 1/3 */
  r = OCG_R(1.0) - x * OCG_R(0.5) * r;                   /* 1/2 */
  return r;
}

/* $1 - e^{-x} = x\,\varphi(x)$, the opacity of optical depth x.
 * Domain: $x \ge 0$ (negative x clamped to 0); result in [0, 1], relative error about 1 ulp. */
OC_INLINE ocg_real ocg_one_minus_exp(ocg_real x) {
  x = ocg_max(x, OCG_R(0.0));
  if (x > OCG_SERIES_X) return OCG_R(1.0) - ocg_exp(-x);
  return x * ocg_one_minus_exp_div(x);
}

/* ---- Transmittance and the segment integrator ------------------------------------------------------ */

/* Beer–Lambert over a homogeneous segment: $T = e^{-\sigma_t d}$.
 * Domain: $\sigma_t \ge 0$ [m^-1], $d \ge 0$ [m]; result in [0, 1] (exp underflows to 0, never NaN). */
OC_INLINE ocg_real ocg_transmittance(ocg_real sigma_t, ocg_real d) {
  OC_ASSERT(sigma_t >= OCG_R(0.0) && d >= OCG_R(0.0));
  return ocg_exp(-ocg_max(sigma_t * d, OCG_R(0.0)));
}

/* Energy-conserving segment weight (Hillaire 2015):
 * $w(\sigma_t, d) = \int_0^d e^{-\sigma_t s}\,ds = \frac{1 - e^{-\sigma_t d}}{\sigma_t}
 *                 = d\,\varphi(\sigma_t d) = d\,(1 - \tfrac{\sigma_t d}{2} + \tfrac{(\sigma_t d)^2}{6} - \dots)$.
 * A step of the raymarch adds $T\,\sigma_s\,S\,w$ and then sets $T \mathrel{*}= e^{-\sigma_t d}$; for a
 * homogeneous segment this is exact at any step count ($\sum_k T_k \sigma_t w = 1 - T_N$).
 * Domain: $\sigma_t \ge 0$ (0 gives d), $d \ge 0$; tested for sigma_t in {0, 1e-12 .. 1e9} m^-1 and d in
 * 1e-6 .. 1e7 m, relative error within a few ulps of -expm1(-sigma_t d)/sigma_t. Never 0/0. */
OC_INLINE ocg_real ocg_segment_weight(ocg_real sigma_t, ocg_real d) {
  OC_ASSERT(sigma_t >= OCG_R(0.0) && d >= OCG_R(0.0));
  ocg_real x = ocg_max(sigma_t * d, OCG_R(0.0));
  if (x > OCG_SERIES_X) return (OCG_R(1.0) - ocg_exp(-x)) / sigma_t;
  return d * ocg_one_minus_exp_div(x);
}

/* Per channel: $w_c = (1 - e^{-\sigma_{t,c} d}) / \sigma_{t,c}$ (see ocg_segment_weight).
 * Domain: each component of sigma_t >= 0, d >= 0. */
OC_INLINE ocg_vec3 ocg_segment_weight3(ocg_vec3 sigma_t, ocg_real d) {
  ocg_real wx = ocg_segment_weight(sigma_t.x, d), wy = ocg_segment_weight(sigma_t.y, d);
  return ocg_v3(wx, wy, ocg_segment_weight(sigma_t.z, d));
}

/* Beer–powder (Schneider 2015; Páleník eq. 3.14 with k = 2): $P(\tau) = e^{-\tau}(1 - e^{-2\tau})$.
 * Domain: $\tau \ge 0$ (negative clamped to 0); result in [0, 0.3849] (maximum at tau = ln(3)/2). */
OC_INLINE ocg_real ocg_beer_powder(ocg_real tau) {
  tau = ocg_max(tau, OCG_R(0.0));
  return ocg_exp(-tau) * ocg_one_minus_exp(OCG_R(2.0) * tau);
}

/* ---- Phase functions (each integrates to 1 over the sphere) ---------------------------------------- */

/* Henyey–Greenstein denominator base $q(\mu, g) = 1 + g^2 - 2g\mu$, written as a sum of non-negative
 * terms so the forward (backward) peak suffers no cancellation:
 * $q = (1-g)^2 + 2g(1-\mu)$ for $g \ge 0$, $q = (1+g)^2 + 2|g|(1+\mu)$ for $g < 0$.
 * Domain: $\mu \in [-1,1]$ (clamped), $|g| < 1$; floored at 1e-20 so that g = +-1 gives 0, not NaN. */
OC_INLINE ocg_real ocg_hg_q(ocg_real mu, ocg_real g) {
  mu = ocg_clamp_cos(mu);
  ocg_real q = g >= OCG_R(0.0) ? (OCG_R(1.0) - g) * (OCG_R(1.0) - g) + OCG_R(2.0) * g * (OCG_R(1.0) - mu)
                               : (OCG_R(1.0) + g) * (OCG_R(1.0) + g) - OCG_R(2.0) * g * (OCG_R(1.0) + mu);
  return ocg_max(q, OCG_R(1e-20));
}

/* Henyey–Greenstein: $p_{HG}(\mu, g) = \frac{1 - g^2}{4\pi\,(1 + g^2 - 2g\mu)^{3/2}}$ [sr^-1].
 * Domain: $\mu \in [-1, 1]$ (clamped), $g \in (-1, 1)$; finite at mu = +-1 (peak (1+g)/(4 pi (1-g)^2)). */
OC_INLINE ocg_real ocg_phase_hg(ocg_real mu, ocg_real g) {
  OC_ASSERT(g > OCG_R(-1.0) && g < OCG_R(1.0));
  ocg_real q = ocg_hg_q(mu, g);
  return (OCG_R(1.0) - g) * (OCG_R(1.0) + g) * OCG_INV_4PI / (q * ocg_safe_sqrt(q));
}

/* Rayleigh: $p_R(\mu) = \frac{3\,(1 + \mu^2)}{16\pi}$ [sr^-1].  Domain: $\mu \in [-1, 1]$ (clamped). */
OC_INLINE ocg_real ocg_phase_rayleigh(ocg_real mu) {
  mu = ocg_clamp_cos(mu);
  return OCG_R(0.0596831036594607509) * (OCG_R(1.0) + mu * mu); /* 3/(16 pi) */
}

/* Draine (2003): $p_D(\mu, g, \alpha) = \frac{1 - g^2}{4\pi\,(1 + g^2 - 2g\mu)^{3/2}}
 *                 \cdot \frac{1 + \alpha\mu^2}{1 + \alpha(1 + 2g^2)/3}$ [sr^-1].
 * Domain: $\mu \in [-1, 1]$ (clamped), $g \in (-1, 1)$, $\alpha \ge -1$ (alpha = 0: HG; alpha = 1:
 * Cornette–Shanks). Normalised for every such g and alpha. */
OC_INLINE ocg_real ocg_phase_draine(ocg_real mu, ocg_real g, ocg_real alpha) {
  OC_ASSERT(g > OCG_R(-1.0) && g < OCG_R(1.0) && alpha >= OCG_R(-1.0));
  mu = ocg_clamp_cos(mu);
  ocg_real shape = (OCG_R(1.0) + alpha * mu * mu) /
                   (OCG_R(1.0) + alpha * (OCG_R(1.0) + OCG_R(2.0) * g * g) * OCG_R(0.333333333333333333));
  return ocg_phase_hg(mu, g) * shape;
}

/* Cornette–Shanks: $p_{CS}(\mu, g) = \frac{3\,(1 - g^2)(1 + \mu^2)}{8\pi\,(2 + g^2)(1 + g^2 - 2g\mu)^{3/2}}$
 * [sr^-1], i.e. Draine with alpha = 1.  Domain: $\mu \in [-1, 1]$ (clamped), $g \in (-1, 1)$. */
OC_INLINE ocg_real ocg_phase_cornette_shanks(ocg_real mu, ocg_real g) {
  mu = ocg_clamp_cos(mu);
  return ocg_phase_hg(mu, g) * OCG_R(1.5) * (OCG_R(1.0) + mu * mu) / (OCG_R(2.0) + g * g);
}

/*! HG+Draine fit of Mie scattering by water droplets of diameter d = 10 µm (Jendersie & d'Eon 2023):
 * $g_{HG} = e^{-0.0990567/(d - 1.67154)}$, $g_D = e^{-2.20679/(d + 3.91029) - 0.428934}$,
 * $\alpha = e^{3.62489 - 8.29288/(d + 5.52825)}$, $w = e^{-0.599085/(d - 0.641583) - 0.664888}$
 * (Ford 2024 eqs. 3.14–3.17 lost the minus signs; design.md has the corrected forms). Evaluated in
 * double at d = 10; tests/shaders/test_optics.c recomputes them. */
#define OCG_HGD_G_HG OCG_R(0.988176691700256)
#define OCG_HGD_G_D OCG_R(0.555671254783950)
#define OCG_HGD_ALPHA OCG_R(21.9955208562746)
#define OCG_HGD_W OCG_R(0.482437628330324)

/* HG+Draine with both asymmetries scaled (multiple-scattering octave i uses gscale = c^i):
 * $p_{HGD}(\mu; s) = (1 - w)\,p_{HG}(\mu, s\,g_{HG}) + w\,p_D(\mu, s\,g_D, \alpha)$ [sr^-1].
 * Domain: $\mu \in [-1, 1]$ (clamped), $s \in [0, 1]$ (s = 0 gives the isotropic-plus-Draine-shape
 * lobe, still normalised). */
OC_INLINE ocg_real ocg_phase_hg_draine_scaled(ocg_real mu, ocg_real gscale) {
  OC_ASSERT(gscale >= OCG_R(0.0) && gscale <= OCG_R(1.0));
  return (OCG_R(1.0) - OCG_HGD_W) * ocg_phase_hg(mu, OCG_HGD_G_HG * gscale) +
         OCG_HGD_W * ocg_phase_draine(mu, OCG_HGD_G_D * gscale, OCG_HGD_ALPHA);
}

/* HG+Draine for d = 10 µm droplets: $p_{HGD}(\mu) = (1 - w)\,p_{HG}(\mu, g_{HG}) + w\,p_D(\mu, g_D, \alpha)$.
 * Domain: $\mu \in [-1, 1]$ (clamped). Peak p(1) = 586.3 sr^-1, p(-1) = 0.01273 sr^-1. */
OC_INLINE ocg_real ocg_phase_hg_draine(ocg_real mu) { return ocg_phase_hg_draine_scaled(mu, OCG_R(1.0)); }

/* ---- Multiple scattering ---------------------------------------------------------------------------- */

/* Multiple-scattering octaves (Wrenninge 2015, as Ford 2024 eq. 3.8–3.9 uses them): sunlit in-scattered
 * radiance per unit sun irradiance at a point with sun optical depth tau,
 * $L(\tau, \mu) = \sum_{i=0}^{n-1} b^i\, e^{-a^i \tau}\, p_{HGD}(\mu; c^i)$ [sr^-1].
 * Octave 0 is single scattering, $e^{-\tau} p_{HGD}(\mu)$.
 * Domain: $\tau \ge 0$ (clamped), $\mu \in [-1,1]$, $a, b, c \in (0, 1]$, $n \ge 0$ (n = 0 gives 0).
 * Bounded by $\sum b^i \max p$; for b < 1 the sum converges as n grows. */
OC_INLINE ocg_real ocg_ms_octaves(ocg_real tau_sun, ocg_real mu, ocg_real a, ocg_real b, ocg_real c,
                                  ocg_int n) {
  OC_ASSERT(a > OCG_R(0.0) && a <= OCG_R(1.0) && b > OCG_R(0.0) && b <= OCG_R(1.0));
  OC_ASSERT(c > OCG_R(0.0) && c <= OCG_R(1.0) && n >= 0);
  ocg_real tau = ocg_max(tau_sun, OCG_R(0.0));
  ocg_real sum = OCG_R(0.0), ai = OCG_R(1.0), bi = OCG_R(1.0), ci = OCG_R(1.0);
  for (ocg_int i = 0; i < n; ++i) {
    sum += bi * ocg_exp(-ai * tau) * ocg_phase_hg_draine_scaled(mu, ci);
    ai *= a;
    bi *= b;
    ci *= c;
  }
  return sum;
}

/* ---- Water content to extinction (Märkl 2018, eqs. 4.1–4.2) ---------------------------------------- */

/*! Physical constants of the water-content conversion (Märkl 2018; Met.3D defaults). */
#define OCG_RHO_AIR OCG_R(1.225)          /* kg/m^3, sea-level air density (default argument) */
#define OCG_RHO_WATER OCG_R(1000.0)       /* kg/m^3 */
#define OCG_RHO_ICE OCG_R(917.0)          /* kg/m^3 */
#define OCG_R_EFF_LIQUID OCG_R(10.0e-6)   /* m, mean effective droplet radius */
#define OCG_R_EFF_ICE OCG_R(25.0e-6)      /* m, mean effective ice-crystal radius */

/* Liquid water: $\sigma_t = \frac{3}{2}\,\frac{LWC\,\rho_{air}}{\rho_w\, r_{eff}}$ [m^-1], with
 * $\rho_w = 1000$ kg/m^3, $r_{eff} = 10$ µm (LWC 1e-3 kg/kg at rho_air 1.225 -> 0.18375 m^-1).
 * Domain: LWC >= 0 [kg/kg], rho_air > 0 [kg/m^3]. */
OC_INLINE ocg_real ocg_sigma_t_liquid(ocg_real lwc, ocg_real rho_air) {
  OC_ASSERT(lwc >= OCG_R(0.0) && rho_air > OCG_R(0.0));
  return OCG_R(1.5) * lwc * rho_air / (OCG_RHO_WATER * OCG_R_EFF_LIQUID);
}

/* Ice (Fu 1996 via Märkl): $\sigma_t = \frac{4\sqrt{3}}{3}\,\frac{IWC\,\rho_{air}}{\rho_{ice}\, r_{eff}}$
 * [m^-1], with $\rho_{ice} = 917$ kg/m^3, $r_{eff} = 25$ µm (IWC 1e-3 at 1.225 -> 0.123403 m^-1).
 * Domain: IWC >= 0 [kg/kg], rho_air > 0 [kg/m^3]. */
OC_INLINE ocg_real ocg_sigma_t_ice(ocg_real iwc, ocg_real rho_air) {
  OC_ASSERT(iwc >= OCG_R(0.0) && rho_air > OCG_R(0.0));
  return OCG_R(2.30940107675850305) * iwc * rho_air / (OCG_RHO_ICE * OCG_R_EFF_ICE); /* 4 sqrt(3)/3 */
}

/* ---- Tone mapping ----------------------------------------------------------------------------------- */

/* RRT+ODT rational fit (Stephen Hill, BakingLab ACES.hlsl):
 * $f(v) = \frac{v\,(v + 0.0245786) - 0.000090537}{v\,(0.983729\,v + 0.4329510) + 0.238081}$.
 * Domain: v >= 0 after the input matrix (negative clamped to 0); f increases monotonically from
 * -3.8e-4 at 0 to 1.0165 as v -> infinity. */
OC_INLINE ocg_real ocg_aces_rrt_odt_fit(ocg_real v) {
  v = ocg_max(v, OCG_R(0.0));
  ocg_real a = v * (v + OCG_R(0.0245786)) - OCG_R(0.000090537);
  ocg_real b = v * (OCG_R(0.983729) * v + OCG_R(0.4329510)) + OCG_R(0.238081);
  return a / b;
}

/* Stephen Hill's ACES fit: $c' = \mathrm{sat}\big(M_{out}\, f(M_{in}\, c)\big)$ with
 * $M_{in}$ = sRGB -> XYZ -> D65_2_D60 -> AP1 -> RRT_SAT and $M_{out}$ = ODT_SAT -> XYZ -> D60_2_D65 -> sRGB
 * (rows below), f = ocg_aces_rrt_odt_fit per channel, sat = clamp to [0, 1].
 * Domain: linear scene-referred sRGB-primaries radiance >= 0 (exposure already applied);
 * output linear display values in [0, 1], to be sRGB-encoded. */
OC_INLINE ocg_vec3 ocg_aces_fit(ocg_vec3 c) {
  ocg_real ix = OCG_R(0.59719) * c.x + OCG_R(0.35458) * c.y + OCG_R(0.04823) * c.z; /* M_in row 0 */
  ocg_real iy = OCG_R(0.07600) * c.x + OCG_R(0.90834) * c.y + OCG_R(0.01566) * c.z; /* M_in row 1 */
  ocg_real iz = OCG_R(0.02840) * c.x + OCG_R(0.13383) * c.y + OCG_R(0.83777) * c.z; /* M_in row 2 */
  ocg_real fx = ocg_aces_rrt_odt_fit(ix), fy = ocg_aces_rrt_odt_fit(iy), fz = ocg_aces_rrt_odt_fit(iz);
  ocg_real ox = OCG_R(1.60475) * fx - OCG_R(0.53108) * fy - OCG_R(0.07367) * fz;  /* M_out row 0 */
  ocg_real oy = OCG_R(-0.10208) * fx + OCG_R(1.10813) * fy - OCG_R(0.00605) * fz; /* M_out row 1 */
  ocg_real oz = OCG_R(-0.00327) * fx - OCG_R(0.07276) * fy + OCG_R(1.07602) * fz; /* M_out row 2 */
  ocg_real one = OCG_R(1.0), zero = OCG_R(0.0);
  return ocg_v3(ocg_clamp(ox, zero, one), ocg_clamp(oy, zero, one), ocg_clamp(oz, zero, one));
}

/* sRGB encoding (IEC 61966-2-1): $E(x) = 12.92\,x$ for $x \le 0.0031308$, else
 * $1.055\,x^{1/2.4} - 0.055$.  Domain: x in [0, 1] (clamped; NaN maps to 0 in C); result in [0, 1]. */
OC_INLINE ocg_real ocg_srgb_encode(ocg_real x) {
  x = ocg_clamp(x, OCG_R(0.0), OCG_R(1.0));
  if (x <= OCG_R(0.0031308)) return OCG_R(12.92) * x;
  return OCG_R(1.055) * ocg_pow(x, OCG_R(0.416666666666666667)) - OCG_R(0.055);
}

/* Per channel sRGB encoding, see ocg_srgb_encode. Domain: components in [0, 1] (clamped). */
OC_INLINE ocg_vec3 ocg_srgb_encode3(ocg_vec3 c) {
  return ocg_v3(ocg_srgb_encode(c.x), ocg_srgb_encode(c.y), ocg_srgb_encode(c.z));
}

#endif /* OC_SHADERS_OPTICS_H */
