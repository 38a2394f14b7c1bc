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
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "oc_brick.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "ocs_field.h"
#include "sun_depth.h"

/*-*** A single-threaded brick cache in front of the field (bench.h: oct_fcache_t) ***/

static oct_fcache_ent_t *oct__find(oct_fcache_t *c, oc_key_t key) {
  if ((c->n + 1) * 2 > c->cap) {
    size_t ncap = c->cap ? c->cap * 2 : 4096;
    oct_fcache_ent_t *nt = calloc(ncap, sizeof *nt);
    if (!nt) return NULL;
    for (size_t i = 0; i < c->cap; i++) {
      if (!c->tab[i].key) continue;
      size_t h = (size_t)((c->tab[i].key * 0x9E3779B97F4A7C15ull) >> 24) & (ncap - 1);
      while (nt[h].key) h = (h + 1) & (ncap - 1);
      nt[h] = c->tab[i];
    }
    free(c->tab);
    c->tab = nt;
    c->cap = ncap;
  }
  size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 24) & (c->cap - 1);
  while (c->tab[h].key && c->tab[h].key != key) h = (h + 1) & (c->cap - 1);
  if (!c->tab[h].key) {
    c->tab[h].key = key;
    c->n++;
  }
  return &c->tab[h];
}

int oct_fcache_sigma(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]) {
  oct_fcache_t *c = ctx;
  c->sigma_calls++;
  oct_fcache_ent_t *e = oct__find(c, key);
  if (!e) return OC_ENOMEM;
  if (!e->brick) {
    if (c->nb == c->pool_cap) {
      size_t ncap = c->pool_cap ? c->pool_cap * 2 : 256;
      float *np = realloc(c->pool, ncap * OC_BRICK_VOXELS * sizeof(float));
      if (!np) return OC_ENOMEM;
      c->pool = np;
      c->pool_cap = ncap;
    }
    float *b = c->pool + c->nb * OC_BRICK_VOXELS;
    OC_TRY(ocs_field_sample(c->f, key, c->t, b));
    oc_sanitize(b, OC_BRICK_VOXELS, NULL);
    e->brick = (int)(++c->nb);
    c->sigma_fetches++;
  }
  memcpy(out, c->pool + (size_t)(e->brick - 1) * OC_BRICK_VOXELS, sizeof(float) * OC_BRICK_VOXELS);
  return 0;
}

void oct_fcache_bound(void *ctx, oc_key_t key, float *lo, float *hi) {
  oct_fcache_t *c = ctx;
  c->bound_calls++;
  oct_fcache_ent_t *e = oct__find(c, key);
  if (!e) { /* out of memory: say "anything" (the sample will fail the same way) */
    *lo = 0.0f, *hi = INFINITY;
    return;
  }
  if (!e->has_bound) {
    ocs_field_bound(c->f, key, c->t, &e->lo, &e->hi);
    e->has_bound = 1;
    c->bound_fetches++;
  }
  *lo = e->lo, *hi = e->hi;
}

void oct_fcache_free(oct_fcache_t *c) {
  free(c->tab);
  free(c->pool);
  c->tab = NULL, c->pool = NULL;
  c->cap = c->n = c->nb = c->pool_cap = 0;
}

static void oct__counts(const oct_fcache_t *c, long out[4]) {
  out[0] = c->sigma_calls, out[1] = c->bound_calls, out[2] = c->sigma_fetches, out[3] = c->bound_fetches;
}

/*-*** The bench ***/

int oct_bench_tau(const char *prog, int argc, char **argv) {
  enum { O_SCENE = 256, O_LEVEL, O_BLOCK, O_ALT, O_AT, O_TIME, O_SUN, O_REPEAT, O_REF, O_HELP };
  static const struct option opts[] = {
      {"scene", required_argument, 0, O_SCENE}, {"level", required_argument, 0, O_LEVEL},
      {"block", required_argument, 0, O_BLOCK}, {"alt", required_argument, 0, O_ALT},
      {"at", required_argument, 0, O_AT},       {"time", required_argument, 0, O_TIME},
      {"sun-zenith", required_argument, 0, O_SUN}, {"repeat", required_argument, 0, O_REPEAT},
      {"reference", no_argument, 0, O_REF},
      {"help", no_argument, 0, O_HELP},         {0, 0, 0, 0}};
  const char *scene_path = NULL, *levels_text = "13";
  long block = 8, repeat = 3;
  double alt = 2000.0, t = 0.0, at[2], zenith = -1.0;
  int have_at = 0, reference = 0, c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_LEVEL: levels_text = optarg; break;
      case O_BLOCK: if (oc_cli_int(prog, "--block", optarg, 1, 32, &block)) return OC_EXIT_USAGE; break;
      case O_REPEAT: if (oc_cli_int(prog, "--repeat", optarg, 1, 100, &repeat)) return OC_EXIT_USAGE; break;
      case O_ALT: if (oc_cli_double(prog, "--alt", optarg, -1e4, 1e5, &alt)) return OC_EXIT_USAGE; break;
      case O_TIME: if (oc_cli_double(prog, "--time", optarg, -1e12, 1e12, &t)) return OC_EXIT_USAGE; break;
      case O_REF: reference = 1; break;
      case O_SUN: if (oc_cli_double(prog, "--sun-zenith", optarg, 0.0, 180.0, &zenith)) return OC_EXIT_USAGE; break;
      case O_AT:
        if (oct_parse_at(prog, optarg, at)) return OC_EXIT_USAGE;
        have_at = 1;
        break;
      case O_HELP: oct_bench_usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "tau: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "tau: unexpected argument \"%s\"", argv[optind]);
  long levels[22];
  int nlevels = 0;
  if (oct_parse_list(prog, "--level", levels_text, 2, 21, levels, 22, &nlevels)) return OC_EXIT_USAGE;

  char why[1024];
  static oc_scene_t sc;
  if (oct_load_scene(prog, scene_path, &sc)) return OC_EXIT_RUNTIME;
  ocs_field_t *f = NULL;
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  oc_geo_t g = {have_at ? at[0] : sc.camera.pos.lat, have_at ? at[1] : sc.camera.pos.lon, alt};
  oc_dvec3 centre = oc_geo_to_xyz(g), sun = sc.sun_dir;
  if (zenith >= 0.0) {
    oc_enu_t e = oc_enu_at(centre);
    sun = oc_dadd(oc_dscale(e.up, cos(zenith * OC_DEG)), oc_dscale(e.east, sin(zenith * OC_DEG)));
  }
  double zen = acos(fmax(-1.0, fmin(1.0, oc_ddot(oc_dnorm(centre), oc_dnorm(sun))))) / OC_DEG;
  printf("# τ channel on %s: %ld³ nodes per level around %.3f°, %.3f°, %.0f m (aligned to volume groups), t = %g s,\n"
         "# sun %.1f° from the zenith there; default desc (filter 1 level, step factor 1, cone %.2f, min level %d,\n"
         "# groups %d levels up, columns every %.2g voxels, slices every %.2g); one thread, best of %ld, warm brick cache\n\n",
         scene_path ? scene_path : "the built-in planet", block, g.lat, g.lon, alt, t, zen, OCS_TAU_DEFAULT_CONE,
         OCS_TAU_DEFAULT_MIN_LEVEL, OCS_TAU_DEFAULT_GROUP_LEVELS, OCS_TAU_COLUMN_SPACING, OCS_TAU_SLICE_SPACING, repeat);
  printf("| level | node (m) | nodes with σt | groups | direct fallbacks | direct µs/brick | volume µs/brick (build + lookup) | speed-up |"
         " KiB/volume | field bricks direct / volume | callback calls/brick direct / volume | max |Δτ| | RMS Δτ |"
         " max |Δe^-τ| | RMS Δe^-τ |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");

  int gl = OCS_TAU_DEFAULT_GROUP_LEVELS, G = 1 << gl;
  char refrows[22][256];
  int nref = 0;
  float s[OC_BRICK_VOXELS];
  int rc = OC_EXIT_OK;
  for (int li = 0; li < nlevels && rc == OC_EXIT_OK; li++) {
    int level = (int)levels[li];
    oct_fcache_t cache = {.f = f, .t = t};
    ocs_tau_desc_t d = {0};
    d.sigma = oct_fcache_sigma, d.bound = oct_fcache_bound, d.ctx = &cache, d.sun_dir = sun;
    /* The block, aligned to groups; the nodes with some σt > 0, in group order. */
    uint32_t cx, cy, cz;
    oc_key_coords(oc_key_from_point(level, centre), &cx, &cy, &cz);
    long n = (block + G - 1) / G * G, lim = 1L << level;
    long x0 = ((long)cx - n / 2) / G * G, y0 = ((long)cy - n / 2) / G * G, z0 = ((long)cz - n / 2) / G * G;
    oc_key_t *keys = malloc(sizeof(oc_key_t) * (size_t)(n * n * n));
    float *td = malloc(sizeof(float) * OC_BRICK_VOXELS * (size_t)(n * n * n));
    float *tv = malloc(sizeof(float) * OC_BRICK_VOXELS * (size_t)(n * n * n));
    if (!keys || !td || !tv) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    int nk = 0, ngroups = 0;
    for (long gz = z0; gz < z0 + n; gz += G)
      for (long gy = y0; gy < y0 + n; gy += G)
        for (long gx = x0; gx < x0 + n; gx += G) {
          int before = nk;
          for (int q = 0; q < G * G * G; q++) {
            long x = gx + q % G, y = gy + (q / G) % G, z = gz + q / (G * G);
            if (x < 0 || y < 0 || z < 0 || x >= lim || y >= lim || z >= lim) continue;
            oc_key_t k = oc_key_make(level, (uint32_t)x, (uint32_t)y, (uint32_t)z);
            float lo, hi;
            oct_fcache_bound(&cache, k, &lo, &hi);
            if (!(hi > 0.0f)) continue;
            if (oct_fcache_sigma(&cache, k, s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
            int any = 0;
            for (int i = 0; i < OC_BRICK_VOXELS; i++) any |= s[i] > 0.0f;
            if (any) keys[nk++] = k;
          }
          ngroups += nk > before;
        }
    if (!nk) {
      printf("| %d | %.1f | 0 | 0 | — | — | — | — | — | — | — | — | — | — | — |\n", level, oc_key_size(level));
      free(keys), free(td), free(tv);
      free(cache.tab), free(cache.pool);
      continue;
    }
    /* First pass (untimed), each method with its own empty cache: the field work it causes (what
     * a cold server cache would fetch); the caches are then warm for the timed passes. */
    oct_fcache_t cd = {.f = f, .t = t}, cv = {.f = f, .t = t};
    ocs_tau_desc_t dd = d, dv = d;
    dd.ctx = &cd, dv.ctx = &cv;
    for (int i = 0; i < nk; i++)
      if (ocs_tau_direct(&dd, keys[i], td + (size_t)i * OC_BRICK_VOXELS) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "direct failed");
    double vol_bytes = 0.0;
    int fallbacks = 0;
    for (int i = 0; i < nk;) {
      oc_key_t grp = ocs_tau_group_of(&dv, keys[i]);
      void *vol;
      size_t bytes;
      if (ocs_tau_volume_build(&dv, grp, level, &vol, &bytes) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "volume failed");
      vol_bytes += (double)bytes;
      for (; i < nk && ocs_tau_group_of(&dv, keys[i]) == grp; i++) {
        float *out = tv + (size_t)i * OC_BRICK_VOXELS;
        int lr = ocs_tau_volume_lookup(vol, keys[i], out);
        if (lr == OC_ENOENT) { /* σt the march level does not see: the documented fallback */
          lr = ocs_tau_direct(&dv, keys[i], out);
          fallbacks++;
        }
        if (lr < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "lookup failed");
      }
      free(vol);
    }
    long kd[4], kv[4];
    oct__counts(&cd, kd);
    oct__counts(&cv, kv);
    /* Timed passes, side by side (calls per brick counted on the last one). */
    double best_d = INFINITY, best_v = INFINITY;
    float tmp[OC_BRICK_VOXELS];
    long calls_d = 0, calls_v = 0;
    for (long r = 0; r < repeat; r++) {
      long a0 = cd.sigma_calls + cd.bound_calls, b0 = cv.sigma_calls + cv.bound_calls;
      double t0 = oct_now();
      for (int i = 0; i < nk; i++) ocs_tau_direct(&dd, keys[i], tmp);
      double t1 = oct_now();
      for (int i = 0; i < nk;) {
        oc_key_t grp = ocs_tau_group_of(&dv, keys[i]);
        void *vol;
        size_t bytes;
        ocs_tau_volume_build(&dv, grp, level, &vol, &bytes);
        for (; i < nk && ocs_tau_group_of(&dv, keys[i]) == grp; i++)
          if (ocs_tau_volume_lookup(vol, keys[i], tmp) == OC_ENOENT) ocs_tau_direct(&dv, keys[i], tmp);
        free(vol);
      }
      double t2 = oct_now();
      best_d = fmin(best_d, t1 - t0);
      best_v = fmin(best_v, t2 - t1);
      calls_d = cd.sigma_calls + cd.bound_calls - a0;
      calls_v = cv.sigma_calls + cv.bound_calls - b0;
    }
    /* Error of the volume against the direct march, at the samples holding σt (the renderer reads
     * τ only there). */
    double emax = 0.0, esum = 0.0, tmax = 0.0, tsum = 0.0;
    long ns = 0;
    for (int i = 0; i < nk; i++) {
      if (oct_fcache_sigma(&cache, keys[i], s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
      for (int v = 0; v < OC_BRICK_VOXELS; v++) {
        if (!(s[v] > 0.0f)) continue;
        size_t q = (size_t)i * OC_BRICK_VOXELS + (size_t)v;
        double e = (double)tv[q] - (double)td[q], et = fabs(exp(-(double)tv[q]) - exp(-(double)td[q]));
        emax = fmax(emax, fabs(e));
        esum += e * e;
        tmax = fmax(tmax, et);
        tsum += et * et;
        ns++;
      }
    }
    printf("| %d | %.1f | %d | %d | %d | %.1f | %.1f | %.1f× | %.0f | %ld / %ld | %.0f / %.0f | %.3g | %.3g | %.3g | %.3g |\n", level,
           oc_key_size(level), nk, ngroups, fallbacks, 1e6 * best_d / nk, 1e6 * best_v / nk, best_d / best_v,
           vol_bytes / ngroups / 1024.0, kd[2], kv[2], (double)calls_d / nk, (double)calls_v / nk, emax, ns ? sqrt(esum / (double)ns) : 0.0, tmax, ns ? sqrt(tsum / (double)ns) : 0.0);
    fflush(stdout);
    if (reference) { /* both against a march with steps and cone 8× finer (the same levels): the direct
                      * march integrates exactly, so it must agree to rounding; the volume's
                      * difference is its interpolation error */
      ocs_tau_desc_t dr = dd;
      dr.step_factor = OCS_TAU_DEFAULT_STEP_FACTOR / 8.0;
      dr.cone = OCS_TAU_DEFAULT_CONE / 8.0;
      double dm = 0.0, ds = 0.0, vm = 0.0, vs = 0.0;
      long nr = 0;
      float tr[OC_BRICK_VOXELS];
      for (int i = 0; i < nk; i++) {
        if (ocs_tau_direct(&dr, keys[i], tr) < 0 || oct_fcache_sigma(&cache, keys[i], s) < 0)
          return oc_cli_fail(prog, OC_EXIT_RUNTIME, "reference failed");
        for (int v = 0; v < OC_BRICK_VOXELS; v++) {
          if (!(s[v] > 0.0f)) continue;
          size_t q = (size_t)i * OC_BRICK_VOXELS + (size_t)v;
          double a = fabs(exp(-(double)td[q]) - exp(-(double)tr[v])), b = fabs(exp(-(double)tv[q]) - exp(-(double)tr[v]));
          dm = fmax(dm, a), ds += a * a, vm = fmax(vm, b), vs += b * b, nr++;
        }
      }
      snprintf(refrows[nref++], sizeof refrows[0], "| %d | %ld | %.4f | %.3f | %.4f | %.3f | %.2f |\n", level, nr,
               sqrt(ds / (double)nr), dm, sqrt(vs / (double)nr), vm, ds > 0.0 ? sqrt(vs / ds) : INFINITY);
    }
    free(keys), free(td), free(tv);
    free(cache.tab), free(cache.pool), free(cd.tab), free(cd.pool), free(cv.tab), free(cv.pool);
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
  return rc;
}
