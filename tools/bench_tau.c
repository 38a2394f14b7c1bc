/* bench_tau.c — `overcast-bench tau`: the τ channel (server/sun_depth.h), direct march against the
 * group volume, side by side in one run.
 *
 * Takes a block of n³ nodes at each level around a point (aligned to the volume groups), keeps the
 * nodes whose σt is not all zero, and on one thread times ocs_tau_direct() on each against building
 * each group's volume once and looking all its kept nodes up (the build amortised over the kept
 * nodes that share it). The callbacks are backed by a warm brick cache of the field (what the
 * server's shared cache gives), filled by an untimed first pass, so the times are τ work alone;
 * the field fetches each method caused in that first pass are reported beside them. Also reported:
 * the volume's error against the direct march over the kept nodes' samples. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"

/*-*** Options ***/

typedef struct {
  OCT_BLOCK_FIELDS
  double zenith;
  int repeat, reference;
} tau_opts_t;

static const oc_cli_opt_t tau_opts[] = {
    OCT_OPTS_BLOCK(tau_opts_t, "level", 2, "13", "octree levels of the nodes", 32, "8",
                   "N³ nodes per level, aligned to volume groups"),
    OCT_DBL_NOTE(tau_opts_t, zenith, "sun-zenith", "DEG", 0, 180, "the scene's sun", "the sun this far from the "
        "zenith, toward the east, at the block"),
    OCT_INT(tau_opts_t, repeat, "repeat", "N", 1, 100, "3", "timed passes; the fastest counts"),
    OCT_FLAG(tau_opts_t, reference, "reference", "also compare both methods with a converged march (8x the direct's "
        "cost)"),
    OCT_OPTS_END};

OCT_SPEC(tau,
         "Sun optical depth τ: direct march vs group volume, µs per brick and the volume's error.",
         tau_opts);

/*-*** The bench ***/

/* One level's nodes with some σt > 0, in group order, and its caches: `cache` for σt, `cd` and `cv`
 * the direct march's and the volume's own (the field work each causes). */
typedef struct {
  const char *prog;
  int level, nk, ngroups;
  oc_key_t *keys;
  float *td, *tv; /* τ per node: direct, volume */
  oct_fcache_t cache, cd, cv;
  ocs_tau_desc_t dd, dv;
} tau_level_t;

static void tau_level_free(tau_level_t *L) {
  free(L->keys), free(L->td), free(L->tv);
  oct_fcache_free(&L->cache), oct_fcache_free(&L->cd), oct_fcache_free(&L->cv);
}

/* The block around centre, aligned to groups: L->keys, L->nk, L->ngroups. */
static int tau_block(tau_level_t *L, long block, oc_dvec3 centre) {
  int level = L->level, G = 1 << OCS_TAU_DEFAULT_GROUP_LEVELS;
  float s[OC_BRICK_VOXELS];
  uint32_t cx, cy, cz;
  oc_key_coords(oc_key_from_point(level, centre), &cx, &cy, &cz);
  long n = (block + G - 1) / G * G, lim = 1L << level;
  long x0 = ((long)cx - n / 2) / G * G, y0 = ((long)cy - n / 2) / G * G, z0 = ((long)cz - n / 2) / G * G;
  L->keys = malloc(sizeof(oc_key_t) * (size_t)(n * n * n));
  L->td = malloc(sizeof(float) * OC_BRICK_VOXELS * (size_t)(n * n * n));
  L->tv = malloc(sizeof(float) * OC_BRICK_VOXELS * (size_t)(n * n * n));
  if (!L->keys || !L->td || !L->tv) return oc_cli_fail(L->prog, -1, "out of memory");
  for (long gz = z0; gz < z0 + n; gz += G)
    for (long gy = y0; gy < y0 + n; gy += G)
      for (long gx = x0; gx < x0 + n; gx += G) {
        int before = L->nk;
        for (int q = 0; q < G * G * G; q++) {
          long x = gx + q % G, y = gy + (q / G) % G, z = gz + q / (G * G);
          if (x < 0 || y < 0 || z < 0 || x >= lim || y >= lim || z >= lim) continue;
          oc_key_t k = oc_key_make(level, (uint32_t)x, (uint32_t)y, (uint32_t)z);
          float lo, hi;
          oct_fcache_bound(&L->cache, k, &lo, &hi);
          if (!(hi > 0.0f)) continue;
          if (oct_fcache_sigma(&L->cache, k, s) < 0) return oc_cli_fail(L->prog, -1, "sampling failed");
          int any = 0;
          for (int i = 0; i < OC_BRICK_VOXELS; i++) any |= s[i] > 0.0f;
          if (any) L->keys[L->nk++] = k;
        }
        L->ngroups += L->nk > before;
      }
  return 0;
}

/* Every node's τ by the volumes of its groups (the direct march where the volume has no answer), into
 * out (NULL: a scratch brick); *fallbacks and *bytes count. @return 0, or the first error. */
static int tau_volumes(tau_level_t *L, float *out, int *fallbacks, double *bytes) {
  float tmp[OC_BRICK_VOXELS];
  int rc = 0;
  for (int i = 0; i < L->nk && !rc;) {
    oc_key_t grp = ocs_tau_group_of(&L->dv, L->keys[i]);
    void *vol;
    size_t vb;
    if ((rc = ocs_tau_volume_build(&L->dv, grp, L->level, &vol, &vb)) < 0) break;
    if (bytes) *bytes += (double)vb;
    for (; i < L->nk && ocs_tau_group_of(&L->dv, L->keys[i]) == grp && !rc; i++) {
      float *o = out ? out + (size_t)i * OC_BRICK_VOXELS : tmp;
      int lr = ocs_tau_volume_lookup(vol, L->keys[i], o);
      if (lr == OC_ENOENT) { /* σt the march level does not see: the documented fallback */
        lr = ocs_tau_direct(&L->dv, L->keys[i], o);
        if (fallbacks) (*fallbacks)++;
      }
      if (lr < 0) rc = lr;
    }
    free(vol);
  }
  return rc;
}

/* The largest and the RMS differences of τ and of e^-τ between two τ bricks, at the samples holding
 * σt (the renderer reads τ only there), summed over the bricks added. */
typedef struct {
  double emax, esum, tmax, tsum;
  long n;
} tau_err_t;

static void tau_err_add(tau_err_t *E, const float *s, const float *a, const float *b) {
  for (int v = 0; v < OC_BRICK_VOXELS; v++) {
    if (!(s[v] > 0.0f)) continue;
    double e = (double)a[v] - (double)b[v], et = fabs(exp(-(double)a[v]) - exp(-(double)b[v]));
    E->emax = fmax(E->emax, fabs(e)), E->esum += e * e;
    E->tmax = fmax(E->tmax, et), E->tsum += et * et;
    E->n++;
  }
}

/* Timed passes, side by side: the best times, and the callback calls per pass (of the last). */
static void tau_timed(tau_level_t *L, long repeat, double best[2], long calls[2]) {
  best[0] = best[1] = INFINITY;
  float tmp[OC_BRICK_VOXELS];
  for (long r = 0; r < repeat; r++) {
    long a0 = L->cd.sigma_calls + L->cd.bound_calls, b0 = L->cv.sigma_calls + L->cv.bound_calls;
    double t0 = oct_now();
    for (int i = 0; i < L->nk; i++) ocs_tau_direct(&L->dd, L->keys[i], tmp);
    double t1 = oct_now();
    tau_volumes(L, NULL, NULL, NULL);
    double t2 = oct_now();
    best[0] = fmin(best[0], t1 - t0);
    best[1] = fmin(best[1], t2 - t1);
    calls[0] = L->cd.sigma_calls + L->cd.bound_calls - a0;
    calls[1] = L->cv.sigma_calls + L->cv.bound_calls - b0;
  }
}

/* --reference: both against a march with steps and cone 8× finer (the same levels): the direct march
 * integrates exactly, so it must agree to rounding; the volume's difference is its interpolation
 * error. */
static int tau_reference(tau_level_t *L, char *row, size_t cap) {
  ocs_tau_desc_t dr = L->dd;
  dr.step_factor = OCS_TAU_DEFAULT_STEP_FACTOR / 8.0;
  dr.cone = OCS_TAU_DEFAULT_CONE / 8.0;
  tau_err_t ed = {0}, ev = {0};
  float tr[OC_BRICK_VOXELS], s[OC_BRICK_VOXELS];
  for (int i = 0; i < L->nk; i++) {
    if (ocs_tau_direct(&dr, L->keys[i], tr) < 0 || oct_fcache_sigma(&L->cache, L->keys[i], s) < 0)
      return oc_cli_fail(L->prog, -1, "reference failed");
    tau_err_add(&ed, s, L->td + (size_t)i * OC_BRICK_VOXELS, tr);
    tau_err_add(&ev, s, L->tv + (size_t)i * OC_BRICK_VOXELS, tr);
  }
  snprintf(row, cap, "| %d | %ld | %.4f | %.3f | %.4f | %.3f | %.2f |\n", L->level, ed.n, sqrt(ed.tsum / (double)ed.n),
           ed.tmax, sqrt(ev.tsum / (double)ev.n), ev.tmax, ed.tsum > 0.0 ? sqrt(ev.tsum / ed.tsum) : INFINITY);
  return 0;
}

/* One level: its row of the table, and its --reference row into ref (when asked). */
static int tau_level(tau_level_t *L, const tau_opts_t *o, oc_dvec3 centre, char *ref, size_t cap) {
  if (tau_block(L, o->block, centre)) return -1;
  int nk = L->nk;
  if (!nk) {
    printf("| %d | %.1f | 0 | 0 | — | — | — | — | — | — | — | — | — | — | — |\n", L->level, oc_key_size(L->level));
    return 0;
  }
  /* First pass (untimed), each method with its own empty cache: the field work it causes (what
   * a cold server cache would fetch); the caches are then warm for the timed passes. */
  for (int i = 0; i < nk; i++)
    if (ocs_tau_direct(&L->dd, L->keys[i], L->td + (size_t)i * OC_BRICK_VOXELS) < 0)
      return oc_cli_fail(L->prog, -1, "direct failed");
  double vol_bytes = 0.0;
  int fallbacks = 0;
  if (tau_volumes(L, L->tv, &fallbacks, &vol_bytes) < 0) return oc_cli_fail(L->prog, -1, "volume failed");
  long fd = L->cd.sigma_fetches, fv = L->cv.sigma_fetches, calls[2] = {0, 0};
  double best[2];
  tau_timed(L, o->repeat, best, calls);
  /* Error of the volume against the direct march, at the samples holding σt. */
  tau_err_t E = {0};
  float s[OC_BRICK_VOXELS];
  for (int i = 0; i < nk; i++) {
    if (oct_fcache_sigma(&L->cache, L->keys[i], s) < 0) return oc_cli_fail(L->prog, -1, "sampling failed");
    tau_err_add(&E, s, L->tv + (size_t)i * OC_BRICK_VOXELS, L->td + (size_t)i * OC_BRICK_VOXELS);
  }
  printf("| %d | %.1f | %d | %d | %d | %.1f | %.1f | %.1f× | %.0f | %ld / %ld | %.0f / %.0f | %.3g | %.3g | %.3g | %.3g |\n",
         L->level, oc_key_size(L->level), nk, L->ngroups, fallbacks, 1e6 * best[0] / nk, 1e6 * best[1] / nk,
         best[0] / best[1], vol_bytes / L->ngroups / 1024.0, fd, fv, (double)calls[0] / nk, (double)calls[1] / nk,
         E.emax, E.n ? sqrt(E.esum / (double)E.n) : 0.0, E.tmax, E.n ? sqrt(E.tsum / (double)E.n) : 0.0);
  fflush(stdout);
  return o->reference ? tau_reference(L, ref, cap) : 0;
}

/* The sun: the scene's, or --sun-zenith's toward the east at centre. */
static oc_dvec3 tau_sun(const tau_opts_t *o, const oc_scene_t *sc, oc_dvec3 centre, double *zen) {
  oc_dvec3 sun = sc->sun_dir;
  if (o->zenith >= 0.0) {
    oc_enu_t e = oc_enu_at(centre);
    sun = oc_dadd(oc_dscale(e.up, cos(o->zenith * OC_DEG)), oc_dscale(e.east, sin(o->zenith * OC_DEG)));
  }
  *zen = acos(fmax(-1.0, fmin(1.0, oc_ddot(oc_dnorm(centre), oc_dnorm(sun))))) / OC_DEG;
  return sun;
}

int oct_bench_tau(const char *prog, int argc, char **argv) {
  tau_opts_t o = {.zenith = -1.0};
  static oc_scene_t sc;
  int rc = oct_begin(&oct_bench_tau_spec, argc, argv, &o, &o.scene, NULL, &sc, NULL);
  if (rc != OCT_GO) return rc;
  char why[1024];
  ocs_field_t *f = NULL;
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  }
  oc_geo_t g = oct_block_centre(&o.at, o.alt, &sc);
  oc_dvec3 centre = oc_geo_to_xyz(g);
  double zen;
  oc_dvec3 sun = tau_sun(&o, &sc, centre, &zen);
  printf("# τ channel on %s: %d³ nodes per level around %.3f°, %.3f°, %.0f m (aligned to volume groups), t = %g s,\n"
         "# sun %.1f° from the zenith there; default desc (filter 1 level, step factor 1, cone %.2f, min level %d,\n"
         "# groups %d levels up, columns every %.2g voxels, slices every %.2g); one thread, best of %d, warm brick cache\n\n",
         o.scene ? o.scene : "the built-in planet", o.block, g.lat, g.lon, o.alt, o.time, zen, OCS_TAU_DEFAULT_CONE,
         OCS_TAU_DEFAULT_MIN_LEVEL, OCS_TAU_DEFAULT_GROUP_LEVELS, OCS_TAU_COLUMN_SPACING, OCS_TAU_SLICE_SPACING, o.repeat);
  printf("| level | node (m) | nodes with σt | groups | direct fallbacks | direct µs/brick | volume µs/brick (build + lookup) | speed-up |"
         " KiB/volume | field bricks direct / volume | callback calls/brick direct / volume | max |Δτ| | RMS Δτ |"
         " max |Δe^-τ| | RMS Δe^-τ |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  char refrows[OCT_LIST_MAX][256];
  int nref = 0;
  for (int li = 0; li < o.levels.n && rc == OCT_GO; li++) {
    tau_level_t L = {.prog = prog, .level = (int)o.levels.v[li]};
    L.cache = L.cd = L.cv = (oct_fcache_t){.f = f, .t = o.time};
    L.dd = L.dv = (ocs_tau_desc_t){.sigma = oct_fcache_sigma, .bound = oct_fcache_bound, .sun_dir = sun};
    L.dd.ctx = &L.cd, L.dv.ctx = &L.cv;
    refrows[nref][0] = 0;
    if (tau_level(&L, &o, centre, refrows[nref], sizeof refrows[nref])) rc = OC_EXIT_RUNTIME;
    nref += refrows[nref][0] != 0;
    tau_level_free(&L);
  }
  if (nref) {
    printf("\nAgainst a march with step factor and cone 8× smaller (the same levels; the direct march is exact, so\n"
           "its columns must read 0 and the volume's are its interpolation error), samples with σt:\n\n"
           "| level | samples | direct RMS |Δe^-τ| | direct max | volume RMS |Δe^-τ| | volume max | volume/direct RMS |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int i = 0; i < nref; i++) fputs(refrows[i], stdout);
  }
  ocs_field_free(f);
  oc_scene_free(&sc);
  return rc == OCT_GO ? OC_EXIT_OK : rc;
}
