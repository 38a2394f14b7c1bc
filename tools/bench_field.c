/* bench_field.c — `overcast-bench field`: brick production speed of a scene's field sources.
 *
 * Takes a block of n³ nodes at one level around a point (--at LAT,LON, default the scene camera's
 * position, at the altitude given), asks the bound of each and samples those it cannot classify, on one
 * thread: bricks per second per core, and the fraction the bound classified without sampling.
 *
 * Beside them, in the same run, the anchor of issue 17: a plain scalar 6-octave Perlin fBm
 * (oc_fbm3(), lacunarity 2, gain 0.5, 1 km lattice) evaluated once per voxel, 512 per brick, on the
 * same nodes, as bricks/s per core, and each level's ratio to it. Non-empty bricks (some σt > 0)
 * per second count all the nodes' time. When the scene has shadows, σt + τ together as the world
 * makes them (server/world.c, produce_finish): τ for nodes with σt and for empty ground nodes
 * (ocs_plan_ground_tau), from each group's volume with the direct march as the fallback, through a
 * brick cache that starts cold at each level (coarse σt read only by τ columns is counted). Each
 * brick's CPU is timed and split by whether it ends up empty (σt and τ all 0): the wasted share.
 * The τ counters (sun_depth.h, ocs_tau_stats_t) say how many direct marches were proven clear and
 * how many of those were marched anyway (--march-clear: the state before the clear-sky lever). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bench.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "oc_noise.h"
#include "oc_voxelize.h" /* oc_brick_sample_pos */
#include "ocs_field.h"
#include "planner.h" /* ocs_plan_ground_tau */
#include "sun_depth.h"

/* The anchor: 512 scalar oc_fbm3() per node, one per sample position. @return seconds. */
static double oct__anchor(const oc_key_t *keys, long n, double *sink) {
  const oc_fbm_t fb = {.octaves = 6, .lacunarity = 2.0, .gain = 0.5, .seed = 17};
  double acc = 0.0, t0 = oct_now();
  for (long q = 0; q < n; q++)
    for (int k = 0; k < 8; k++)
      for (int j = 0; j < 8; j++)
        for (int i = 0; i < 8; i++) {
          oc_dvec3 p = oc_brick_sample_pos(keys[q], i, j, k);
          acc += oc_fbm3(p.x * 1e-3, p.y * 1e-3, p.z * 1e-3, &fb);
        }
  *sink += acc;
  return oct_now() - t0;
}

/* τ volumes of one level's block, built on first use (the world's cache of them). */
typedef struct {
  oc_key_t group;
  void *vol;
} oct__vol_t;

static int oct__tau(const ocs_tau_desc_t *d, oct__vol_t *vols, int *nvols, int cap, oc_key_t key, float tau[OC_BRICK_VOXELS]) {
  oc_key_t g = ocs_tau_group_of(d, key);
  int i = 0;
  while (i < *nvols && vols[i].group != g) i++;
  if (i == *nvols) {
    if (i == cap) return OC_ENOMEM;
    size_t bytes;
    OC_TRY(ocs_tau_volume_build(d, g, oc_key_level(key), &vols[i].vol, &bytes));
    vols[i].group = g;
    (*nvols)++;
  }
  int r = ocs_tau_volume_lookup(vols[i].vol, key, tau);
  return r == OC_ENOENT ? ocs_tau_direct(d, key, tau) : r;
}

/* FNV-1a over bytes: the digest line lets a lever that claims to change no bit show it. */
static uint64_t oct__fnv(uint64_t h, const void *data, size_t n) {
  const unsigned char *b = data;
  for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001b3ull;
  return h;
}

int oct_bench_field(const char *prog, int argc, char **argv) {
  enum { O_SCENE = 256, O_LEVELS, O_BLOCK, O_ALT, O_AT, O_TIME, O_MARCH_CLEAR, O_EXACT, O_HELP };
  static const struct option opts[] = {{"scene", required_argument, 0, O_SCENE}, {"levels", required_argument, 0, O_LEVELS},
                                       {"block", required_argument, 0, O_BLOCK}, {"alt", required_argument, 0, O_ALT},
                                       {"at", required_argument, 0, O_AT},
                                       {"time", required_argument, 0, O_TIME},   {"help", no_argument, 0, O_HELP},
                                       {"march-clear", no_argument, 0, O_MARCH_CLEAR},
                                       {"exact", no_argument, 0, O_EXACT},
                                       {0, 0, 0, 0}};
  const char *scene_path = NULL, *levels_text = "10,13,16";
  long block = 6;
  double alt = 2000.0, t = 0.0, at[2];
  int have_at = 0, march_clear = 0, exact = 0;
  int c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_LEVELS: levels_text = optarg; break;
      case O_BLOCK: if (oc_cli_int(prog, "--block", optarg, 1, 64, &block)) return OC_EXIT_USAGE; break;
      case O_ALT: if (oc_cli_double(prog, "--alt", optarg, -1e4, 1e5, &alt)) return OC_EXIT_USAGE; break;
      case O_TIME: if (oc_cli_double(prog, "--time", optarg, -1e12, 1e12, &t)) return OC_EXIT_USAGE; break;
      case O_MARCH_CLEAR: march_clear = 1; break;
      case O_EXACT: exact = 1; break;
      case O_AT:
        if (oct_parse_at(prog, optarg, at)) return OC_EXIT_USAGE;
        have_at = 1;
        break;
      case O_HELP: oct_bench_usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "field: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "field: unexpected argument \"%s\"", argv[optind]);
  long levels[22];
  int nlevels = 0;
  if (oct_parse_list(prog, "--levels", levels_text, 0, 21, levels, 22, &nlevels)) return OC_EXIT_USAGE;

  char why[1024];
  static oc_scene_t sc;
  if (oct_load_scene(prog, scene_path, &sc)) return OC_EXIT_RUNTIME;
  ocs_field_t *f = NULL;
  double tc = oct_now();
  if (ocs_field_create(&f, &sc, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  tc = oct_now() - tc;
  oc_geo_t g = {have_at ? at[0] : sc.camera.pos.lat, have_at ? at[1] : sc.camera.pos.lon, alt};
  oc_dvec3 centre = oc_geo_to_xyz(g);
  printf("# field sources of %s (%d source(s), built in %.3f s), %ld³ nodes per level around %.3f°, %.3f°, %.0f m, "
         "t = %g s, one thread\n\n",
         scene_path ? scene_path : "the built-in planet", sc.nsources, tc, block, g.lat, g.lon, alt, t);
  int shadows = oc_scene_has(&sc, OC_FEATURE_SHADOWS);
  int ground_tau = shadows && oc_scene_has(&sc, OC_FEATURE_PLANET_SURFACE);
  printf("| level | node size (m) | nodes | classified by bound | sampled | bricks/s per core | µs per brick | non-empty samples |"
         " non-empty bricks | non-empty bricks/s per core | anchor bricks/s per core | sampled / anchor | non-empty / anchor |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  char tau_rows[22][512], exact_rows[22][256];
  float *s = malloc(sizeof(float) * OC_BRICK_VOXELS);
  oc_key_t *keys = malloc(sizeof(oc_key_t) * (size_t)(block * block * block));
  oc_key_t *skeys = malloc(sizeof(oc_key_t) * (size_t)(block * block * block));
  float *e = malloc(sizeof(float) * OC_BRICK_VOXELS);
  if (!s || !keys || !skeys || !e) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  double sink = 0.0;
  uint64_t dig_s = 0xcbf29ce484222325ull, dig_t = dig_s;
  for (int li = 0; li < nlevels; li++) {
    int level = (int)levels[li];
    oc_key_t k0 = oc_key_from_point(level, centre);
    long nodes = 0, classified = 0, sampled = 0, nonempty = 0, nonempty_bricks = 0;
    double ts = 0.0;
    for (long z = 0; z < block; z++)
      for (long y = 0; y < block; y++)
        for (long x = 0; x < block; x++) {
          oc_key_t k = oc_key_neighbor(k0, (int)(x - block / 2), (int)(y - block / 2), (int)(z - block / 2));
          if (k == OC_KEY_INVALID) continue;
          keys[nodes++] = k;
          float lo, hi;
          double t0 = oct_now();
          ocs_field_bound(f, k, t, &lo, &hi);
          if (lo == hi) {
            classified++;
            ts += oct_now() - t0;
            nonempty_bricks += hi > 0.0f;
            continue;
          }
          if (ocs_field_sample(f, k, t, s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
          ts += oct_now() - t0;
          skeys[sampled++] = k;
          dig_s = oct__fnv(dig_s, s, sizeof(float) * OC_BRICK_VOXELS);
          int any = 0;
          for (int i = 0; i < OC_BRICK_VOXELS; i++) nonempty += s[i] > 0.0f, any |= s[i] > 0.0f;
          nonempty_bricks += any;
        }
    double ta = oct__anchor(keys, nodes, &sink), anchor = nodes / ta;
    fprintf(stderr, "\r\033[K");
    printf("| %d | %.1f | %ld | %.1f %% | %ld | %.0f | %.1f | %.1f %% | %ld | %.0f | %.0f | %.2f× | %.2f× |\n", level, oc_key_size(level), nodes,
           100.0 * classified / nodes, sampled, sampled ? sampled / ts : 0.0, sampled ? 1e6 * ts / sampled : 0.0,
           sampled ? 100.0 * nonempty / (sampled * 512.0) : 0.0, nonempty_bricks, nonempty_bricks / ts, anchor,
           sampled ? sampled / ts / anchor : 0.0, nonempty_bricks / ts / anchor);
    fflush(stdout);
    exact_rows[li][0] = 0;
    if (exact) { /* the same sampled nodes through the exact box filter: its cost, and the fast one's error */
      double tf = 0.0, tx = 0.0, sf = 0.0, sx = 0.0, sq = 0.0;
      long withc = 0;
      for (long q = 0; q < sampled; q++) {
        double t0 = oct_now();
        ocs_field_set_exact(f, 0);
        if (ocs_field_sample(f, skeys[q], t, s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
        double t1 = oct_now();
        ocs_field_set_exact(f, 1);
        if (ocs_field_sample(f, skeys[q], t, e) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "exact sampling failed");
        tx += oct_now() - t1, tf += t1 - t0;
        double mx = 0.0, d2 = 0.0;
        for (int i = 0; i < OC_BRICK_VOXELS; i++) {
          sf += s[i], sx += e[i], mx = fmax(mx, (double)e[i]);
          d2 += ((double)s[i] - e[i]) * ((double)s[i] - e[i]);
        }
        if (mx > 0.0) sq += d2 / (OC_BRICK_VOXELS * mx * mx), withc++;
      }
      ocs_field_set_exact(f, 0);
      snprintf(exact_rows[li], sizeof exact_rows[li], "| %d | %ld | %.1f | %.1f | %.1f× | %+.2f %% | %.2f %% |\n", level, sampled,
               sampled ? 1e6 * tx / sampled : 0.0, sampled ? 1e6 * tf / sampled : 0.0, tf > 0.0 ? tx / tf : 0.0,
               sx > 0.0 ? 100.0 * (sf / sx - 1.0) : 0.0, withc ? 100.0 * sqrt(sq / withc) : 0.0);
    }
    if (!shadows) continue;
    /* σt + τ as the world makes them, each brick timed, over a cold brick cache */
    oct_fcache_t cache = {.f = f, .t = t};
    ocs_tau_stats_t st = {0};
    ocs_tau_desc_t d = {.sigma = oct_fcache_sigma, .bound = oct_fcache_bound, .ctx = &cache, .sun_dir = sc.sun_dir,
                        .march_clear = march_clear, .stats = &st};
    int vcap = (int)((block / 4 + 2) * (block / 4 + 2) * (block / 4 + 2)), nvols = 0;
    oct__vol_t *vols = malloc(sizeof *vols * (size_t)vcap);
    if (!vols) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    long ne = 0, ground = 0, with_tau = 0;
    double t_all = 0.0, t_empty = 0.0, t_tau = 0.0;
    float tau[OC_BRICK_VOXELS];
    for (long q = 0; q < nodes; q++) {
      oc_key_t k = keys[q];
      double t0 = oct_now();
      float lo, hi;
      oct_fcache_bound(&cache, k, &lo, &hi);
      int any = 0, tany = 0;
      if (hi > 0.0f) {
        if (oct_fcache_sigma(&cache, k, s) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "sampling failed");
        for (int i = 0; i < OC_BRICK_VOXELS; i++) any |= s[i] > 0.0f;
      }
      int gt = !any && ground_tau && ocs_plan_ground_tau(k);
      if (any || gt) {
        double t1 = oct_now();
        if (oct__tau(&d, vols, &nvols, vcap, k, tau) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "τ failed");
        for (int i = 0; i < OC_BRICK_VOXELS; i++) tany |= tau[i] > 0.0f;
        dig_t = oct__fnv(dig_t, tau, sizeof tau);
        with_tau++;
        ground += gt;
        t_tau += oct_now() - t1;
      }
      double dt = oct_now() - t0;
      t_all += dt;
      if (!any && !tany) t_empty += dt;
      ne += any;
    }
    for (int i = 0; i < nvols; i++) free(vols[i].vol);
    free(vols);
    oct_fcache_free(&cache);
    snprintf(tau_rows[li], sizeof tau_rows[li], "| %d | %ld | %ld | %ld | %d | %.1f | %.1f | %.0f | %.2f× | %.1f %% | %ld | %ld | %ld |\n", level, ne,
             with_tau, ground, nvols, 1e3 * t_all, 1e3 * t_tau, ne / t_all, ne / t_all / anchor, t_all > 0.0 ? 100.0 * t_empty / t_all : 0.0,
             (long)atomic_load(&st.direct), (long)atomic_load(&st.clear_proven), (long)atomic_load(&st.clear_marched));
  }
  if (exact) {
    printf("\nThe fast box filter (what bricks hold) against the exact one (--exact), the same sampled nodes:\n\n"
           "| level | nodes | exact µs per brick | fast µs per brick | speed-up | sum of means, fast vs exact | voxel RMS "
           "difference (of each brick's largest) |\n|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int li = 0; li < nlevels; li++) fputs(exact_rows[li], stdout);
  }
  if (shadows) {
    printf("\nσt + τ together, as the world produces them (cold brick cache per level; %s):\n\n"
           "| level | non-empty bricks | with τ | of which empty ground | τ volumes | CPU ms | of which τ ms | non-empty bricks/s per core | / anchor |"
           " CPU on bricks that end up empty | τ direct marches | proven clear | clear marched |\n"
           "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
           march_clear ? "--march-clear: provably clear columns marched anyway" : "clear columns skipped");
    for (int li = 0; li < nlevels; li++) fputs(tau_rows[li], stdout);
  }
  {
    ocs_field_stats_t fs;
    ocs_field_stats(f, &fs);
    printf("\nfield bounds: %llu calls, bound cache %llu hits / %llu misses (hit rate %.3f%s)\n",
           (unsigned long long)fs.bound_calls, (unsigned long long)fs.bound_hits, (unsigned long long)fs.bound_misses,
           fs.bound_hits + fs.bound_misses ? (double)fs.bound_hits / (double)(fs.bound_hits + fs.bound_misses) : 0.0,
           fs.bound_hits + fs.bound_misses ? "" : "; OCS_FIELD_BOUND_CACHE=0 or no cacheable source");
  }
  printf("digest (FNV-1a of the bytes): sampled σt %016llx, τ %016llx\n", (unsigned long long)dig_s,
         (unsigned long long)dig_t);
  if (sink == 1234.5) printf("\n"); /* keeps the anchor's sum alive */
  free(keys);
  free(skeys);
  free(e);
  free(s);
  ocs_field_free(f);
  oc_scene_free(&sc);
  return OC_EXIT_OK;
}
