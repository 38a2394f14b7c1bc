/* oc_atmo.h — the clear-sky atmosphere: parameters, precomputed tables, and their look-ups.
 *
 * The tables follow Hillaire 2020 ("A Scalable and Production Ready Sky and Atmosphere Rendering
 * Technique") with Bruneton 2017's transmittance parametrisation, computed in C (double precision)
 * from shaders/atmosphere.h, the same formulas the shaders run. The CPU reference renderer uses the
 * look-ups below; the client uploads the raw tables (oc_atmo_table) as RGBA32F textures with
 * GL_LINEAR filtering and GL_CLAMP_TO_EDGE, which the look-ups reproduce exactly (bilinear at texel
 * centres), so both see the same sky (design.md, Conventions: filtering and tables).
 *
 *   table          size    axes (u, v)      value (RGB; alpha = 1)
 *   transmittance  256×64  (x_μ, ρ/H)       T(r, μ) to the top of the atmosphere
 *   multiscatter    32×32  (μs, ρ/H)        Ψ_ms(r, μs), sr⁻¹ per unit solar irradiance
 *   irradiance      64×32  (μs, ρ/H)        sky irradiance on a horizontal surface / E_sun
 *   fluence         64×32  (μs, ρ/H)        ∫_4π sky radiance dω / E_sun
 *
 * The mappings are ocg_atmo_transmittance_uv and ocg_atmo_rmus_uv; the integrals and how the renderer
 * uses them are written out in docs/numerics.md (atmosphere section). Radii are metres from the
 * planet centre; cosines are clamped to [-1, 1]; non-finite inputs give (0, 0, 0). */
#ifndef OC_COMMON_ATMO_H
#define OC_COMMON_ATMO_H

#if defined(OCG_REAL_DOUBLE)
#error "oc_atmo.h is a float API (it returns float ocg_vec3): include it without OCG_REAL_DOUBLE"
#endif

#include "atmosphere.h" /* ocg_atmosphere, ocg_vec3, OCG_ATMO_* table sizes */

typedef struct oc_atmo_s oc_atmo_t;

/*! Raw tables for oc_atmo_table(). */
typedef enum {
  OC_ATMO_TABLE_TRANSMITTANCE = 0, /**< OCG_ATMO_TRANSMITTANCE_W × _H */
  OC_ATMO_TABLE_MULTISCATTER = 1,  /**< OCG_ATMO_MULTISCATTER_W × _H */
  OC_ATMO_TABLE_IRRADIANCE = 2,    /**< OCG_ATMO_IRRADIANCE_W × _H */
  OC_ATMO_TABLE_FLUENCE = 3,       /**< OCG_ATMO_IRRADIANCE_W × _H (same mapping as irradiance) */
  OC_ATMO_TABLE_COUNT = 4
} oc_atmo_table_t;

/*! oc_atmo_params_default() : Bruneton 2017's Earth (design.md, Optics) on Overcast's planet.
 *  bottom_radius OC_PLANET_RADIUS, top_radius + OC_ATMOSPHERE_HEIGHT; Rayleigh (5.802, 13.558,
 *  33.1)e-6 m⁻¹, H_R 8 km; Mie scattering 3.996e-6, extinction 4.44e-6 m⁻¹, H_M 1.2 km, g 0.8;
 *  ozone (0.650, 1.881, 0.085)e-6 m⁻¹ in a tent 10–25–40 km; ground albedo 0.1; sun angular radius
 *  0.004675 rad; solar irradiance (1.474, 1.8504, 1.91198) (Bruneton's W m⁻² nm⁻¹ at 680, 550,
 *  440 nm). */
void oc_atmo_params_default(ocg_atmosphere *p);

/*! oc_atmo_create() : validates p and computes the four tables.
 *  @threads : worker threads (≤ 0: one per online processor); the tables are bit-identical for any
 *             count.
 *  @return : the tables, or NULL on bad parameters (an oc_log_error names the field) or no memory.
 *  Costs about 0.8 s of CPU, split over the threads (docs/numerics.md has the measured figures). */
oc_atmo_t *oc_atmo_create(const ocg_atmosphere *p, int threads);

/*! oc_atmo_free() : NULL is accepted. */
void oc_atmo_free(oc_atmo_t *a);

/*! oc_atmo_params() : @return the parameters the tables were computed with (reserved fields 0). */
const ocg_atmosphere *oc_atmo_params(const oc_atmo_t *a);

/*! oc_atmo_transmittance() : transmittance from radius r along zenith cosine mu to the top of the
 *  atmosphere; 0 if the ray meets the ground. r < bottom is treated as the ground; from outside the
 *  atmosphere (r > top) the ray is followed to where it enters (1 if it never does). */
ocg_vec3 oc_atmo_transmittance(const oc_atmo_t *a, double r, double mu);

/*! oc_atmo_sun_transmittance() : transmittance to the sun at sun zenith cosine mu_s, times the
 *  fraction of the sun disc above the horizon (ocg_atmo_sun_visibility): exactly 0 once the whole
 *  disc is below the horizon (the planet's shadow), softened across it. Same r handling as
 *  oc_atmo_transmittance(). */
ocg_vec3 oc_atmo_sun_transmittance(const oc_atmo_t *a, double r, double mu_s);

/*! oc_atmo_multiscatter() : Hillaire's Ψ_ms(r, mu_s), sr⁻¹ per unit solar irradiance; the air's
 *  multiple-scattering source is σ_s(r) · Ψ_ms · E_sun with σ_s = β_R + β^s_M. r is clamped to the
 *  atmosphere shell. */
ocg_vec3 oc_atmo_multiscatter(const oc_atmo_t *a, double r, double mu_s);

/*! oc_atmo_sky_irradiance() : irradiance on a horizontal surface at radius r from the sky of the
 *  upper hemisphere (no direct sun), per unit solar irradiance (dimensionless). Ground lighting is
 *  E_sun (T_sun μs⁺ + this). r is clamped to the atmosphere shell. */
ocg_vec3 oc_atmo_sky_irradiance(const oc_atmo_t *a, double r, double mu_s);

/*! oc_atmo_sky_fluence() : ∫ over all directions of the sky radiance at radius r (no direct sun;
 *  below the horizon the lit ground), per unit solar irradiance (dimensionless). The sky-ambient
 *  in-scattering of an isotropic medium is σ_s · E_sun · fluence / (4π). r is clamped to the
 *  atmosphere shell. */
ocg_vec3 oc_atmo_sky_fluence(const oc_atmo_t *a, double r, double mu_s);

/*! oc_atmo_table() : a raw table for GPU upload: RGBA float texels, row-major, row 0 first
 *  (v = 0: upload as is with glTexImage2D).
 *  @return : 0, or OC_EINVAL for a NULL argument or an unknown table. */
int oc_atmo_table(const oc_atmo_t *a, int which, int *w, int *h, const float **rgba);

#endif /* OC_COMMON_ATMO_H */
