/* bench_noise.c — overcast-bench noise: the procedural patterns' two forms side by side: the fBm
 * evaluated (common/oc_noise.h, the batch path bricks use) against a tiled pre-filtered volume of the
 * same fBm (server/noise_volume.h): build time and memory, ns per point, ns per box bound, and how
 * wide each bound is over boxes of a few sizes (the volume's pyramid against the fBm's Lipschitz
 * bound, beside the range a dense search finds inside: no bound can be narrower than that). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "bench.h"
#include "bench_util.h"
#include "oc.h"
#include "ocs.h"

typedef struct {
  int log2_size, period, points;
  oct_list_t octaves;
} noise_opts_t;

static const oc_cli_opt_t noise_opts[] = {
    OCT_INT(noise_opts_t, log2_size, "log2-size", "K", 3, OCS_NVOL_MAX_LOG2, "7", "volumes of 2^K texels a side"),
    OCT_INT(noise_opts_t, period, "period", "P", 1, 256, "2", "the tile, in periods of the first octave (a power of two)"),
    OCT_LIST(noise_opts_t, octaves, "octaves", 1, 12, "3,4,5", "fBm octave counts (lacunarity 2, gain 0.5)"),
    OCT_INT(noise_opts_t, points, "points", "N", 1024, 1 << 24, "1048576", "points timed per form"),
    OCT_OPTS_END};

OCT_SPEC(noise, "The fBm evaluated against a tiled pre-filtered volume of it: build, ns per point, bounds.", noise_opts,
         .epilog = "Box edges are in periods of the first octave; 'dense' is the range 9³ fetches inside each box find.\n"
                   "The points are random over 64 periods, so most fetches miss the cache (a brick's are coherent).\n");

/* Uniform in [0, 1) from a 64-bit LCG: the same points for both forms. */
static double unit(uint64_t *s) {
  *s = *s * 6364136223846793005ull + 1442695040888963407ull;
  return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

/* Mean widths over `boxes` random boxes of edge e: the volume's bound, the dense range inside. */
static void widths(const ocs_nvol_t *v, double e, int boxes, double *bound, double *dense) {
  uint64_t s = 99;
  *bound = *dense = 0.0;
  for (int b = 0; b < boxes; b++) {
    double a[3], c[3], lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < 3; k++) a[k] = 64.0 * unit(&s), c[k] = a[k] + e;
    float bl, bh;
    ocs_nvol_bound(v, 0, a, c, &bl, &bh);
    for (int i = 0; i < 729; i++) {
      double p[3] = {a[0] + e * (i % 9) / 8.0, a[1] + e * (i / 9 % 9) / 8.0, a[2] + e * (i / 81) / 8.0};
      double f = ocs_nvol_fetch(v, 0, p);
      lo = fmin(lo, f), hi = fmax(hi, f);
    }
    *bound += (double)(bh - bl) / boxes, *dense += (hi - lo) / boxes;
  }
}

static int noise_one(const noise_opts_t *o, int octaves, const double *xyz, float *out) {
  ocs_nvol_desc_t d = {o->log2_size, o->period, {.octaves = octaves, .lacunarity = 2.0, .gain = 0.5, .seed = 17}};
  ocs_nvol_t *v;
  char why[256];
  double t0 = oct_now();
  if (ocs_nvol_create(&d, &v, why, sizeof why) < 0) return fprintf(stderr, "overcast-bench noise: %s\n", why), -1;
  double build = oct_now() - t0, mib = (double)ocs_nvol_bytes(v) / 1048576.0;
  t0 = oct_now();
  oc_fbm3_batch(xyz, o->points, &d.fbm, out);
  double fbm = oct_now() - t0, sink = 0.0;
  t0 = oct_now();
  for (int i = 0; i < o->points; i++) sink += ocs_nvol_fetch(v, 0, &xyz[3 * i]);
  double fetch = oct_now() - t0;
  const int NB = o->points < 20000 ? o->points : 20000; /* boxes at the first points */
  t0 = oct_now();
  for (int i = 0; i < NB; i++) {
    double a[3] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}, c[3] = {a[0] + 0.05, a[1] + 0.05, a[2] + 0.05};
    float lo, hi;
    ocs_nvol_bound(v, 0, a, c, &lo, &hi);
    sink += hi - lo;
  }
  double bound = oct_now() - t0;
  double lip = 0.0, amp = 1.0, norm = 0.0;
  for (int i = 0; i < octaves; i++, amp *= 0.5) lip += amp * ldexp(1.0, i), norm += amp;
  lip *= OC_NOISE_LIPSCHITZ / norm;
  printf("| %d | %.2f | %.1f | %.1f | %.1f | %.0f |", octaves, build, mib, 1e9 * fbm / o->points, 1e9 * fetch / o->points,
         1e9 * bound / NB);
  static const double edges[] = {1.0 / 64, 1.0 / 16, 1.0 / 4};
  for (int k = 0; k < 3; k++) {
    double bw, dw;
    widths(v, edges[k], 300, &bw, &dw);
    printf(" %.3f / %.3f / %.3f |", bw, fmin(2.0, 2.0 * lip * edges[k] * 0.8660254), dw);
  }
  printf("%s\n", sink == 1234.5 ? " " : "");
  ocs_nvol_destroy(v);
  return 0;
}

int oct_bench_noise(const char *prog, int argc, char **argv) {
  noise_opts_t o = {0};
  int rc = oct_begin(&oct_bench_noise_spec, argc, argv, &o, NULL, NULL, NULL, NULL);
  if (rc != OCT_GO) return rc;
  if (o.period & (o.period - 1) || o.period > (1 << o.log2_size))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "noise: --period must be a power of two no larger than 2^K");
  double *xyz = malloc(sizeof(double) * 3 * (size_t)o.points);
  float *out = malloc(sizeof(float) * (size_t)o.points);
  if (!xyz || !out) {
    free(xyz), free(out);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "noise: out of memory");
  }
  uint64_t s = 7;
  for (int i = 0; i < 3 * o.points; i++) xyz[i] = 64.0 * unit(&s);
  printf("# noise: %d³-texel volumes, tile %d periods, %d random points per form, one thread\n\n", 1 << o.log2_size,
         o.period, o.points);
  printf("| octaves | build s | MiB (mips + pyramids) | fBm ns/point (batch) | volume fetch ns/point | bound ns/box |"
         " edge 1/64: volume / Lipschitz / dense | edge 1/16 | edge 1/4 |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  rc = OC_EXIT_OK;
  for (int i = 0; i < o.octaves.n && rc == OC_EXIT_OK; i++)
    if (noise_one(&o, (int)o.octaves.v[i], xyz, out) < 0) rc = OC_EXIT_RUNTIME;
  free(xyz), free(out);
  return rc;
}
