/* bench_oracle.h — the ceiling of a per-point multiply scattered term, measured (`overcast-bench model
 * --oracle`; issue 21's third candidate, docs/numerics.md "What a per-voxel term would need").
 *
 * The CPU reference renders a stored truth case with its model's multiply scattered light replaced
 * by what the Monte Carlo kernel (bench_mc.h) measures at the points of a lattice around the cloud,
 * trilinear between them (oc_render_desc_t.ms_oracle). At each point x the kernel traces paths from x
 * and takes the light that has already scattered at least once, arriving along each direction ω: the
 * in-scattered radiance toward the view v is then
 *   - exact (lmax < 0): ∫ p(ω·v) L(x, ω) dω, directions drawn from the phase function around v;
 *   - truncated (lmax ≥ 0): the same integral with L cut to spherical harmonics of degree ≤ lmax,
 *     directions drawn uniformly: Σ_l (2l + 1)·p_l·P_l(ω·v) per path (the addition theorem and
 *     Funk–Hecke), p_l the phase function's Legendre moments. A per-voxel term stored on the
 *     server would carry (lmax + 1)² numbers per point.
 * Single scattering and the sky's ambient stay the model's. The lattice spacing is the case's length
 * (sphere diameter, slab thickness) over `cells`; only points around samples that hold cloud are
 * traced (a first, single-threaded render records them). Every point's paths depend only on the
 * seed and the point, so the image does not depend on the thread count. */
#ifndef OCT_BENCH_ORACLE_H
#define OCT_BENCH_ORACLE_H

#include "oc.h"
#include "truth.h"

#define OCT_ORACLE_MAX_LMAX 8
#define OCT_ORACLE_MAX_POINTS 1000000 /**< lattice points a case may need (more: OC_ERANGE; the table then
                                           holds at most 2²¹ points of 64 bytes) */

typedef struct {
  int lmax;    /**< -1: exact toward the view; 0..OCT_ORACLE_MAX_LMAX: truncated to that degree */
  int cells;   /**< lattice cells across the case's length, [2, 256] */
  long paths;  /**< paths per lattice point, ≥ 1 */
  int threads; /**< ≥ 1 */
} oct_oracle_opts_t;

/*! oct_oracle_render() : renders the case (its state st, description d from oct_truth_case_desc()
 *  with its own length, oct_truth_source_length()) with the oracle's multiply scattered light into
 *  img. *points: lattice points traced. @return 0, OC_ENOMEM, OC_ERANGE (the lattice would need more
 *  than OCT_ORACLE_MAX_POINTS: fewer cells), or OC_EINVAL (bad options or length). */
int oct_oracle_render(const oct_truth_case_t *c, const oc_state_t *st, const oc_render_desc_t *d, double length,
                      const oct_oracle_opts_t *o, oc_image_t *img, long *points);

#endif /* OCT_BENCH_ORACLE_H */
