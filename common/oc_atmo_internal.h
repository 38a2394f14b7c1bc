/* oc_atmo_internal.h — shared by common/oc_atmo.c (the float API) and common/oc_atmo_bake.c (the
 * table builder, compiled with OCG_REAL_DOUBLE so the shared formulas run in double).
 *
 * Only plain C types and ocg_atmosphere cross between the two: ocg_atmosphere has the same (float)
 * layout in both translation units (shaders/atmosphere.h), ocg_vec3 does not. */
#ifndef OC_COMMON_ATMO_INTERNAL_H
#define OC_COMMON_ATMO_INTERNAL_H

#include "atmosphere.h" /* ocg_atmosphere, OCG_ATMO_* table sizes */

#define OC__ATMO_NTABLES 4   /* transmittance, multiscatter, irradiance, fluence: OC_ATMO_TABLE_* order */
#define OC__ATMO_MAX_SHELLS 24
#define OC__ATMO_MAX_RULE 24
#define OC__ATMO_MAX_PHI 32

/* A Gauss–Legendre rule on [0, 1] and its integration matrix: S[i][j] = ∫_0^{x_i} ℓ_j, so that
 * Σ_j S[i][j] f(x_j) is the integral from 0 to node i of the degree n−1 interpolant of f. */
typedef struct {
  int n;
  double x[OC__ATMO_MAX_RULE], w[OC__ATMO_MAX_RULE];
  double S[OC__ATMO_MAX_RULE][OC__ATMO_MAX_RULE];
} oc__atmo_rule_t;

typedef struct {
  int w, h;
  float *rgba; /* w·h texels, row-major, row 0 = v near 0 */
} oc__atmo_tab_t;

struct oc_atmo_s {
  ocg_atmosphere p;
  oc__atmo_tab_t tab[OC__ATMO_NTABLES];
  /* Quadrature set-up (oc__atmo_prepare): radii at which rays are split so that each piece spans at
   * most two scale heights of every profile and no kink of the ozone tent. */
  int nshell;
  double shell[OC__ATMO_MAX_SHELLS];
  oc__atmo_rule_t rule_tau; /* along rays, transmittance table */
  oc__atmo_rule_t rule_ray; /* along rays, scattering tables */
  oc__atmo_rule_t rule_mu;  /* zenith cosine, after the horizon substitution */
};

/* Fills the quadrature set-up of a (a->p must be set). */
void oc__atmo_prepare(struct oc_atmo_s *a);
/* Computes row `row` of table `which` (0..3) from a->p and the tables before it. */
void oc__atmo_bake_row(struct oc_atmo_s *a, int which, int row);

/* The table's integral evaluated directly at (r, μ or μs), without the table (tests measure the
 * tables' interpolation error with it); r is clamped to the shell. */
void oc__atmo_eval(const struct oc_atmo_s *a, int which, double r, double mu, double out[3]);

/* Look-ups in double (see oc_atmo.h for their meaning); out is RGB. */
void oc__atmo_transmittance(const struct oc_atmo_s *a, double r, double mu, double out[3]);
void oc__atmo_sun_transmittance(const struct oc_atmo_s *a, double r, double mu_s, double out[3]);
void oc__atmo_rmus_lookup(const struct oc_atmo_s *a, int which, double r, double mu_s, double out[3]);

#endif /* OC_COMMON_ATMO_INTERNAL_H */
