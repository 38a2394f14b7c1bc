/* atmosphere.h — the clear-sky atmosphere, shared by C and GLSL (style.md §4–§5).
 *
 * One implementation of the atmosphere's formulas for the table builder (common/oc_atmo*.c, which
 * compiles this header in double precision), the CPU reference renderer and the GLSL shaders:
 *   - the medium: Rayleigh and Mie exponential profiles, the ozone tent (Bruneton 2017 defaults,
 *     design.md Optics), extinction and scattering coefficients at a radius r;
 *   - ray–sphere distances in forms that stay accurate in float at planet scale;
 *   - the look-up-table parametrisations: transmittance (r, μ) (Bruneton 2017) and the (r, μs)
 *     tables (Hillaire 2020's multiple-scattering LUT, sky irradiance, sky fluence);
 *   - the sun-disc softening at the horizon (phase functions: shaders/optics.h).
 *
 * Notation (Bruneton 2017): r is the distance from the planet centre, μ the cosine of the view
 * zenith angle, μs that of the sun zenith angle, ν that of the angle between view and sun
 * directions; b = bottom_radius, t = top_radius. Lengths in metres, coefficients in m⁻¹.
 *
 * Precision. All functions are written for float at planet scale: every r² − b² is formed as
 * (r − b)(r + b), and every root of a quadratic that would cancel is taken in its conjugate form,
 * so errors are relative to the quantities computed, not to r² ≈ 4e13 m². A C translation unit
 * that defines OCG_REAL_DOUBLE computes everything in double; the parameter struct keeps the same
 * (float) layout there, so it can cross between float and double translation units.
 *
 * GLSL: the includer prepends oc_port.h and optics.h (GLSL has no #include). */
#ifndef OC_SHADERS_ATMOSPHERE_H
#define OC_SHADERS_ATMOSPHERE_H

#ifndef OC_GLSL
#include "oc_port.h" /* ocg_real, ocg_vec2/3, OCG_R, OC_IN, OC_ASSERT, ocg_safe_sqrt */
#include "optics.h"  /* ocg_phase_rayleigh, ocg_phase_cornette_shanks */
#endif

/* ---- Table sizes -------------------------------------------------------------------------------
 * Texel (i, j) of a w×h table covers u ∈ [i/w, (i+1)/w], v ∈ [j/h, (j+1)/h]; its value is the
 * function at the texel centre ((i+½)/w, (j+½)/h). Row j = 0 is v = 0 (the first row handed to
 * glTexImage2D). */
#define OCG_ATMO_TRANSMITTANCE_W 256 /**< μ axis (Bruneton's x_μ) */
#define OCG_ATMO_TRANSMITTANCE_H 64  /**< r axis (ρ/H) */
#define OCG_ATMO_MULTISCATTER_W 32   /**< μs axis (rational map, ocg_atmo_mus_to_unit) */
#define OCG_ATMO_MULTISCATTER_H 32   /**< r axis (ρ/H) */
#define OCG_ATMO_IRRADIANCE_W 64     /**< μs axis; also the sky fluence table */
#define OCG_ATMO_IRRADIANCE_H 32     /**< r axis (ρ/H); also the sky fluence table */

/* ---- The parameter struct ----------------------------------------------------------------------
 * Scalars are float and spectra float triples in every language, so the C layout is the same in
 * float and double translation units and equals GLSL std140 (each vec3 is followed by a float:
 * 16-byte slots, 96 bytes in all): the client can copy it into a uniform block as is. The fields
 * are therefore grouped by std140 slot rather than by topic. */
/* Boolean results: GLSL bool; C17's built-in _Bool (no <stdbool.h> in shaders/ headers). */
#if defined(OC_GLSL)
#define ocg_atmo_bool bool
#else
#define ocg_atmo_bool _Bool
#endif

#if defined(OC_GLSL)
#define OCG_ATMO_F3 vec3
#define ocg_atmo_f3(v) (v)
#elif defined(OCG_REAL_DOUBLE)
typedef struct { float x, y, z; } ocg_atmo_f3_t; /* the same layout as the float ocg_vec3 */
#define OCG_ATMO_F3 ocg_atmo_f3_t
OC_INLINE ocg_vec3 ocg_atmo_f3(ocg_atmo_f3_t v) { return ocg_v3(v.x, v.y, v.z); }
#else
#define OCG_ATMO_F3 ocg_vec3
#define ocg_atmo_f3(v) (v)
#endif

#if defined(OC_GLSL)
struct ocg_atmosphere {
#else
typedef struct ocg_atmosphere {
#endif
  OCG_ATMO_F3 rayleigh_scattering; /**< β_R at the ground, m⁻¹ (RGB); Rayleigh absorbs nothing */
  float rayleigh_scale_height;     /**< H_R, m; > 0 */
  OCG_ATMO_F3 ozone_absorption;    /**< β_O at the tent's peak, m⁻¹ (RGB); absorption only */
  float ozone_center;              /**< altitude of the tent's peak above the ground, m */
  OCG_ATMO_F3 ground_albedo;       /**< Lambertian ground reflectance, [0, 1] (RGB) */
  float ozone_half_width;          /**< the tent falls to 0 this far above and below its peak, m; > 0 */
  OCG_ATMO_F3 solar_irradiance;    /**< E_sun at the top of the atmosphere (RGB; W m⁻² nm⁻¹ at 680/550/440 nm by default) */
  float sun_angular_radius;        /**< α_s, radians; (0, 0.1] */
  float bottom_radius;             /**< b: planet radius, m; the ground */
  float top_radius;                /**< t: radius of the top of the atmosphere, m; > b */
  float mie_scattering;            /**< β_M^s at the ground, m⁻¹ (grey) */
  float mie_extinction;            /**< β_M^e at the ground, m⁻¹; ≥ β_M^s */
  float mie_scale_height;          /**< H_M, m; > 0 */
  float mie_g;                     /**< Cornette–Shanks asymmetry, (-1, 1) */
  float reserved0;                 /**< std140 padding; ignored, keep 0 */
  float reserved1;                 /**< std140 padding; ignored, keep 0 */
#if defined(OC_GLSL)
};
#else
} ocg_atmosphere;
#endif

/* ---- Small helpers -------------------------------------------------------------------------------- */

/* Hermite smoothstep, written out so C and GLSL agree bit for bit (GLSL's built-in is specified by
 * the same formula):
 * $s(e_0,e_1,x) = \tau^2 (3 - 2\tau)$, $\tau = \mathrm{clamp}((x-e_0)/(e_1-e_0), 0, 1)$.
 * Domain: e0 < e1. */
OC_INLINE ocg_real ocg_atmo_smoothstep(ocg_real e0, ocg_real e1, ocg_real x) {
  OC_ASSERT(e0 < e1);
  ocg_real s = ocg_clamp((x - e0) / (e1 - e0), OCG_R(0.0), OCG_R(1.0));
  return s * s * (OCG_R(3.0) - OCG_R(2.0) * s);
}

/* Texture coordinate of the unit-range value x on an n-texel axis, so that x = 0 and x = 1 fall on
 * the centres of the first and last texels (Bruneton 2017, GetTextureCoordFromUnitRange):
 * $u = \frac{1}{2n} + x\,(1 - \frac{1}{n})$. Domain: x ∈ [0, 1], n ≥ 2. */
OC_INLINE ocg_real ocg_atmo_unit_to_tex(ocg_real x, ocg_real n) {
  return OCG_R(0.5) / n + x * (OCG_R(1.0) - OCG_R(1.0) / n);
}

/* Inverse of ocg_atmo_unit_to_tex: $x = (u - \frac{1}{2n}) / (1 - \frac{1}{n})$. Domain: n ≥ 2. */
OC_INLINE ocg_real ocg_atmo_tex_to_unit(ocg_real u, ocg_real n) {
  return (u - OCG_R(0.5) / n) / (OCG_R(1.0) - OCG_R(1.0) / n);
}

/* ---- The medium ---------------------------------------------------------------------------------- */

/* Exponential density profile, normalised to 1 at the ground:
 * $\rho(h) = \min(1, e^{-h/H})$. Domain: H > 0; h ≥ 0 (h < 0 is clamped to the ground value). */
OC_INLINE ocg_real ocg_atmo_exp_density(ocg_real h, ocg_real H) {
  OC_ASSERT(H > OCG_R(0.0));
  return ocg_min(ocg_exp(-h / H), OCG_R(1.0));
}

/* Ozone tent: $\rho_O(h) = \max(0,\ 1 - |h - h_c| / w)$ with h_c = ozone_center, w = ozone_half_width.
 * Bruneton 2017: 0 at 10 km, 1 at 25 km, 0 at 40 km. Domain: w > 0. */
OC_INLINE ocg_real ocg_atmo_ozone_density(OC_IN(ocg_atmosphere) atm, ocg_real h) {
  OC_ASSERT(atm.ozone_half_width > OCG_R(0.0));
  return ocg_max(OCG_R(0.0), OCG_R(1.0) - ocg_abs(h - atm.ozone_center) / atm.ozone_half_width);
}

/* Rayleigh scattering coefficient at radius r: $\beta_R(r) = \beta_R\, e^{-(r-b)/H_R}$ (RGB, m⁻¹).
 * Domain: r ≥ b (below the ground the ground value is returned). */
OC_INLINE ocg_vec3 ocg_atmo_rayleigh_scattering(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  return ocg_scale3(ocg_atmo_f3(atm.rayleigh_scattering),
                    ocg_atmo_exp_density(r - atm.bottom_radius, atm.rayleigh_scale_height));
}

/* Mie scattering coefficient at radius r: $\beta^s_M(r) = \beta^s_M\, e^{-(r-b)/H_M}$ (grey, m⁻¹).
 * Domain: r ≥ b. */
OC_INLINE ocg_real ocg_atmo_mie_scattering(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  return atm.mie_scattering * ocg_atmo_exp_density(r - atm.bottom_radius, atm.mie_scale_height);
}

/* Mie extinction coefficient at radius r: $\beta^e_M(r) = \beta^e_M\, e^{-(r-b)/H_M}$ (grey, m⁻¹).
 * Domain: r ≥ b. */
OC_INLINE ocg_real ocg_atmo_mie_extinction(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  return atm.mie_extinction * ocg_atmo_exp_density(r - atm.bottom_radius, atm.mie_scale_height);
}

/* Ozone absorption coefficient at radius r: $\beta_O(r) = \beta_O\, \rho_O(r - b)$ (RGB, m⁻¹).
 * Domain: r ≥ b. */
OC_INLINE ocg_vec3 ocg_atmo_ozone_absorption(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  return ocg_scale3(ocg_atmo_f3(atm.ozone_absorption), ocg_atmo_ozone_density(atm, r - atm.bottom_radius));
}

/* Total extinction of the clear air at radius r (RGB, m⁻¹):
 * $\sigma_t(r) = \beta_R(r) + \beta^e_M(r) + \beta_O(r)$. Domain: r ≥ b. */
OC_INLINE ocg_vec3 ocg_atmo_extinction(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  return ocg_add3(ocg_add3(ocg_atmo_rayleigh_scattering(atm, r), ocg_v3s(ocg_atmo_mie_extinction(atm, r))),
                  ocg_atmo_ozone_absorption(atm, r));
}

/* Phase functions: the air uses shaders/optics.h's ocg_phase_rayleigh(ν) and
 * ocg_phase_cornette_shanks(ν, mie_g) (one formula, one place). */

/* ---- Ray–sphere geometry ----------------------------------------------------------------------------
 * A ray from radius r with zenith cosine μ is at distance d at radius
 * $r_d = \sqrt{d^2 + 2 r \mu d + r^2}$; it meets the sphere of radius R where
 * $d^2 + 2 r \mu d + r^2 - R^2 = 0$, whose discriminant (over 4) is
 * $\Delta_R = r^2 (\mu^2 - 1) + R^2 = (r\mu)^2 + (R - r)(R + r)$; the second form keeps float
 * accurate when r ≈ R (no cancellation of two 4e13 m² terms). */

/* Distance to the top of the atmosphere along (r, μ), from inside:
 * $d_t = -r\mu + \sqrt{\Delta_t}$, taken as $\frac{(t - r)(t + r)}{r\mu + \sqrt{\Delta_t}}$ when
 * μ ≥ 0 (the conjugate form: no cancellation for rays that leave steeply from near the top).
 * Domain: b ≤ r ≤ t (r slightly above t gives 0), μ ∈ [-1, 1]. Result ≥ 0. */
OC_INLINE ocg_real ocg_atmo_dist_top(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  OC_ASSERT(mu >= OCG_R(-1.0) && mu <= OCG_R(1.0));
  ocg_real tr = ocg_max(atm.top_radius - r, OCG_R(0.0));
  ocg_real disc = (r * mu) * (r * mu) + tr * (atm.top_radius + r);
  ocg_real s = ocg_safe_sqrt(disc);
  if (mu < OCG_R(0.0)) return ocg_max(-r * mu + s, OCG_R(0.0));
  ocg_real den = r * mu + s;
  return den > OCG_R(0.0) ? tr * (atm.top_radius + r) / den : OCG_R(0.0);
}

/* Whether the ray (r, μ) meets the ground: $\mu < 0 \wedge \Delta_b \ge 0$ with
 * $\Delta_b = (r\mu)^2 - (r - b)(r + b)$. Domain: r ≥ b, μ ∈ [-1, 1]. */
OC_INLINE ocg_atmo_bool ocg_atmo_ray_hits_ground(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  ocg_real rb = ocg_max(r - atm.bottom_radius, OCG_R(0.0));
  return mu < OCG_R(0.0) && (r * mu) * (r * mu) - rb * (r + atm.bottom_radius) >= OCG_R(0.0);
}

/* Distance to the ground along (r, μ) for a ray that meets it:
 * $d_b = -r\mu - \sqrt{\Delta_b} = \frac{(r - b)(r + b)}{-r\mu + \sqrt{\Delta_b}}$, the conjugate
 * form (the first cancels for grazing rays). Domain: r ≥ b and ocg_atmo_ray_hits_ground(r, μ);
 * for other rays the result is finite and ≥ 0 but meaningless. */
OC_INLINE ocg_real ocg_atmo_dist_bottom(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  OC_ASSERT(mu >= OCG_R(-1.0) && mu <= OCG_R(1.0));
  ocg_real rb = ocg_max(r - atm.bottom_radius, OCG_R(0.0));
  ocg_real num = rb * (r + atm.bottom_radius);
  ocg_real den = -r * mu + ocg_safe_sqrt((r * mu) * (r * mu) - num);
  return den > OCG_R(0.0) ? num / den : OCG_R(0.0);
}

/* Distance to the boundary of the atmosphere shell (the ground if the ray meets it, else the top).
 * Domain: b ≤ r ≤ t, μ ∈ [-1, 1]. */
OC_INLINE ocg_real ocg_atmo_dist_boundary(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  return ocg_atmo_ray_hits_ground(atm, r, mu) ? ocg_atmo_dist_bottom(atm, r, mu) : ocg_atmo_dist_top(atm, r, mu);
}

/* Radius after a distance d along (r, μ): $r_d = \sqrt{d^2 + 2 r \mu d + r^2}$, clamped ≥ 0.
 * In float its absolute error is about one ulp of r (0.5 m at the ground). Domain: d ≥ 0. */
OC_INLINE ocg_real ocg_atmo_radius_at(ocg_real r, ocg_real mu, ocg_real d) {
  return ocg_safe_sqrt(d * d + OCG_R(2.0) * r * mu * d + r * r);
}

/* Cosine of a fixed direction's zenith angle after a distance d along a ray: for the ray's own
 * direction $\mu_d = (r\mu + d)/r_d$; for another direction (e.g. the sun, with ν the cosine between
 * it and the ray) $\mu_{s,d} = (r\mu_s + d\,\nu)/r_d$. Call as ocg_atmo_cos_at(r, mu, 1, d, r_d) or
 * ocg_atmo_cos_at(r, mu_s, nu, d, r_d). Domain: r_d > 0. Result clamped to [-1, 1]. */
OC_INLINE ocg_real ocg_atmo_cos_at(ocg_real r, ocg_real c, ocg_real nu, ocg_real d, ocg_real r_d) {
  return ocg_clamp_cos((r * c + d * nu) / r_d);
}

/* Cosine of the zenith angle of the horizon seen from radius r:
 * $\mu_h = -\sqrt{1 - (b/r)^2} = -\sqrt{(r - b)(r + b)}/r$. Rays with μ < μ_h meet the ground.
 * Domain: r ≥ b (r < b is treated as r = b, giving 0). */
OC_INLINE ocg_real ocg_atmo_horizon_mu(OC_IN(ocg_atmosphere) atm, ocg_real r) {
  ocg_real rb = ocg_max(r - atm.bottom_radius, OCG_R(0.0));
  return -ocg_safe_sqrt(rb * (r + atm.bottom_radius)) / ocg_max(r, atm.bottom_radius);
}

/* A point outside the atmosphere (r > t) moved to where its ray enters the atmosphere, so the
 * (r, μ) tables apply: the entry distance is $d_i = -r\mu - \sqrt{\Delta_t}$ and the result is
 * (t, (rμ + d_i)/t, 1). A ray that never enters (μ ≥ 0 or Δ_t < 0) gives (r, μ, 0); a point inside
 * gives (r, μ, 1) unchanged. Domain: μ ∈ [-1, 1]. */
OC_INLINE ocg_vec3 ocg_atmo_enter(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  if (r <= atm.top_radius) return ocg_v3(r, mu, OCG_R(1.0));
  ocg_real disc = (r * mu) * (r * mu) - (r - atm.top_radius) * (r + atm.top_radius);
  if (mu >= OCG_R(0.0) || disc < OCG_R(0.0)) return ocg_v3(r, mu, OCG_R(0.0));
  /* d_i = -rμ - √Δ = (r - t)(r + t) / (-rμ + √Δ): the conjugate form again. */
  ocg_real d = (r - atm.top_radius) * (r + atm.top_radius) / (-r * mu + ocg_sqrt(disc));
  return ocg_v3(atm.top_radius, ocg_clamp_cos((r * mu + d) / atm.top_radius), OCG_R(1.0));
}

/* ---- Sun-disc softening at the horizon ----------------------------------------------------------------
 * Fraction of the sun disc above the horizon seen from radius r (Bruneton 2017,
 * GetTransmittanceToSun): with $\sin\theta_h = b/r$ and $\cos\theta_h = -\sqrt{1 - (b/r)^2}$,
 * $V(r, \mu_s) = \mathrm{smoothstep}(-\sin\theta_h\,\alpha_s,\ \sin\theta_h\,\alpha_s,\ \mu_s - \cos\theta_h)$.
 * 0 when the whole disc is below the horizon (the planet's shadow), 1 when it is all above.
 * Domain: r ≥ b, μs ∈ [-1, 1], α_s > 0. */
OC_INLINE ocg_real ocg_atmo_sun_visibility(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu_s) {
  ocg_real sin_h = atm.bottom_radius / ocg_max(r, atm.bottom_radius);
  ocg_real cos_h = ocg_atmo_horizon_mu(atm, r);
  ocg_real w = sin_h * atm.sun_angular_radius;
  return ocg_atmo_smoothstep(-w, w, mu_s - cos_h);
}

/* ---- Transmittance table (r, μ) ↔ uv (Bruneton 2017) ------------------------------------------------
 * With $H = \sqrt{t^2 - b^2}$ (distance to the top along the horizon from the ground) and
 * $\rho = \sqrt{r^2 - b^2}$: $x_r = \rho / H$ and, with $d = d_t(r, \mu)$,
 * $d_{min} = t - r$, $d_{max} = \rho + H$: $x_\mu = (d - d_{min}) / (d_{max} - d_{min})$.
 * x_μ = 0 is the zenith, x_μ = 1 the horizon; rays below the horizon are not in the table. Both are
 * mapped to texel centres (ocg_atmo_unit_to_tex). The texel rows are dense near the ground and
 * the columns near the horizon, where transmittance changes fastest. */

/* (r, μ) → uv. Domain: b ≤ r ≤ t, μ ≥ μ_h(r) (below the horizon x_μ > 1: clamp or handle first). */
OC_INLINE ocg_vec2 ocg_atmo_transmittance_uv(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu) {
  ocg_real b = atm.bottom_radius, t = atm.top_radius;
  ocg_real H = ocg_safe_sqrt((t - b) * (t + b));
  ocg_real rho = ocg_safe_sqrt((r - b) * (r + b));
  ocg_real d = ocg_atmo_dist_top(atm, r, mu);
  ocg_real d_min = t - r;
  ocg_real d_max = rho + H;
  ocg_real x_mu = (d - d_min) / (d_max - d_min);
  ocg_real x_r = rho / H;
  return ocg_v2(ocg_atmo_unit_to_tex(x_mu, OCG_TO_REAL(OCG_ATMO_TRANSMITTANCE_W)),
                ocg_atmo_unit_to_tex(x_r, OCG_TO_REAL(OCG_ATMO_TRANSMITTANCE_H)));
}

/* uv → (r, μ), the inverse: $\rho = H x_r$, $r = \sqrt{\rho^2 + b^2}$,
 * $d = d_{min} + x_\mu (d_{max} - d_{min})$, $\mu = \frac{H^2 - \rho^2 - d^2}{2 r d}$ (μ = 1 when d = 0).
 * Used by the table builder in double; in float r loses precision near the ground.
 * Domain: uv ∈ [0, 1]². Returns (r, μ). */
OC_INLINE ocg_vec2 ocg_atmo_transmittance_rmu(OC_IN(ocg_atmosphere) atm, ocg_vec2 uv) {
  ocg_real b = atm.bottom_radius, t = atm.top_radius;
  ocg_real x_mu = ocg_clamp(ocg_atmo_tex_to_unit(uv.x, OCG_TO_REAL(OCG_ATMO_TRANSMITTANCE_W)), OCG_R(0.0), OCG_R(1.0));
  ocg_real x_r = ocg_clamp(ocg_atmo_tex_to_unit(uv.y, OCG_TO_REAL(OCG_ATMO_TRANSMITTANCE_H)), OCG_R(0.0), OCG_R(1.0));
  ocg_real H = ocg_safe_sqrt((t - b) * (t + b));
  ocg_real rho = H * x_r;
  ocg_real r = ocg_sqrt(rho * rho + b * b);
  ocg_real d_min = t - r;
  ocg_real d_max = rho + H;
  ocg_real d = d_min + x_mu * (d_max - d_min);
  ocg_real mu = d == OCG_R(0.0) ? OCG_R(1.0) : (H * H - rho * rho - d * d) / (OCG_R(2.0) * r * d);
  return ocg_v2(r, ocg_clamp_cos(mu));
}

/* ---- (r, μs) tables ↔ uv: multiple scattering, sky irradiance, sky fluence ----------------------------
 * $u = \mathrm{tex}(x_{\mu_s}, w)$, $v = \mathrm{tex}(\rho / H, h)$ with the odd rational map
 * $x_{\mu_s} = \frac{1}{2}\left(1 + \frac{(1 + k)\,\mu_s}{|\mu_s| + k}\right)$, k = OCG_ATMO_MUS_K.
 * Hillaire 2020 maps r and μs linearly. ρ/H (as the transmittance table) gives cloud altitudes more
 * rows; the rational map gives the horizon (1 + k)/k times the linear density of columns, where
 * sunset and twilight change these tables fastest, and the zenith k/(1 + k) times, where they are
 * smooth (k = OCG_ATMO_MUS_K; no transcendental function, cheap in a shader). */

/*! Width of the μs band around the horizon that the (r, μs) tables resolve finely (see above). Part
 * of the table format: C and GLSL must agree, so it is not overridable. */
#define OCG_ATMO_MUS_K OCG_R(0.3)

/* $x = \frac{1}{2}(1 + \frac{(1+k)\mu_s}{|\mu_s| + k})$. Domain: μs ∈ [-1, 1] (clamped). */
OC_INLINE ocg_real ocg_atmo_mus_to_unit(ocg_real mu_s) {
  ocg_real m = ocg_clamp_cos(mu_s);
  return OCG_R(0.5) + OCG_R(0.5) * (OCG_R(1.0) + OCG_ATMO_MUS_K) * m / (ocg_abs(m) + OCG_ATMO_MUS_K);
}

/* The inverse: with $y = 2x - 1$, $\mu_s = \frac{k\,y}{1 + k - |y|}$. Domain: x ∈ [0, 1] (clamped). */
OC_INLINE ocg_real ocg_atmo_unit_to_mus(ocg_real x) {
  ocg_real y = ocg_clamp(OCG_R(2.0) * x - OCG_R(1.0), OCG_R(-1.0), OCG_R(1.0));
  return ocg_clamp_cos(OCG_ATMO_MUS_K * y / (OCG_R(1.0) + OCG_ATMO_MUS_K - ocg_abs(y)));
}

/* (r, μs) → uv on a w×h table. Domain: b ≤ r ≤ t (clamped), μs ∈ [-1, 1]. */
OC_INLINE ocg_vec2 ocg_atmo_rmus_uv(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu_s, ocg_real w, ocg_real h) {
  ocg_real b = atm.bottom_radius, t = atm.top_radius;
  ocg_real rc = ocg_clamp(r, b, t);
  ocg_real H = ocg_safe_sqrt((t - b) * (t + b));
  ocg_real rho = ocg_safe_sqrt((rc - b) * (rc + b));
  return ocg_v2(ocg_atmo_unit_to_tex(ocg_atmo_mus_to_unit(mu_s), w),
                ocg_atmo_unit_to_tex(rho / H, h));
}

/* uv → (r, μs) on a w×h table, the inverse: μs from ocg_atmo_unit_to_mus, $r = \sqrt{(H x_r)^2 + b^2}$.
 * Domain: uv ∈ [0, 1]². Returns (r, μs). */
OC_INLINE ocg_vec2 ocg_atmo_rmus_from_uv(OC_IN(ocg_atmosphere) atm, ocg_vec2 uv, ocg_real w, ocg_real h) {
  ocg_real b = atm.bottom_radius, t = atm.top_radius;
  ocg_real x_mu = ocg_clamp(ocg_atmo_tex_to_unit(uv.x, w), OCG_R(0.0), OCG_R(1.0));
  ocg_real x_r = ocg_clamp(ocg_atmo_tex_to_unit(uv.y, h), OCG_R(0.0), OCG_R(1.0));
  ocg_real rho = ocg_safe_sqrt((t - b) * (t + b)) * x_r;
  return ocg_v2(ocg_sqrt(rho * rho + b * b), ocg_atmo_unit_to_mus(x_mu));
}

/* The multiple-scattering table's uv (Hillaire 2020's Ψ_ms LUT, 32×32). */
OC_INLINE ocg_vec2 ocg_atmo_multiscatter_uv(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu_s) {
  return ocg_atmo_rmus_uv(atm, r, mu_s, OCG_TO_REAL(OCG_ATMO_MULTISCATTER_W), OCG_TO_REAL(OCG_ATMO_MULTISCATTER_H));
}

/* The sky irradiance and sky fluence tables' uv (64×32). */
OC_INLINE ocg_vec2 ocg_atmo_irradiance_uv(OC_IN(ocg_atmosphere) atm, ocg_real r, ocg_real mu_s) {
  return ocg_atmo_rmus_uv(atm, r, mu_s, OCG_TO_REAL(OCG_ATMO_IRRADIANCE_W), OCG_TO_REAL(OCG_ATMO_IRRADIANCE_H));
}

#endif /* OC_SHADERS_ATMOSPHERE_H */
