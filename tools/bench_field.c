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
 * (ocs_plan_ground_tau), from each group's volume (which covers the ground that is not proven
 * clear: ocs_tau_desc_t.ground), and the rest by the direct march, as the world does, through a
 * brick cache that starts cold at each level (coarse σt read only by τ columns is counted). Each
 * brick's CPU is timed and split by whether it ends up empty (σt and τ all 0): the wasted share.
 * The τ counters (sun_depth.h, ocs_tau_stats_t) say how many direct marches were proven clear and
 * how many of those were marched anyway (--march-clear: the state before the clear-sky lever). */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"

/* τ volumes of one level's block, built on first use (the world's cache of them). */
typedef struct {
  oc_key_t group;
  void *vol;
} oct__vol_t;

static int oct__ground(void *ctx, oc_key_t key) {
  (void)ctx;
  return ocs_plan_ground_tau(key);
}

static int oct__tau(const ocs_tau_desc_t *d, oct__vol_t *vols, int *nvols, int cap, oc_key_t key,
                    float tau[OC_BRICK_VOXELS]) {
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
  if (r != OC_ENOENT) return r;
  if (d->ground && d->ground(d->ctx, key)) { /* left out of the volume: proven clear */
    memset(tau, 0, OC_BRICK_VOXELS * sizeof *tau);
    return 0;
  }
  return ocs_tau_direct(d, key, tau); /* as the world's tau_get */
}

/* FNV-1a over bytes: the digest line lets a lever that claims to change no bit show it. */
static uint64_t oct__fnv(uint64_t h, const void *data, size_t n) {
  const unsigned char *b = data;
  for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001b3ull;
  return h;
}

/*-*** Options ***/

typedef struct {
  OCT_BLOCK_FIELDS
  int march_clear, exact;
} field_opts_t;

static const oc_cli_opt_t field_opts[] = {
    OCT_OPTS_BLOCK(field_opts_t, "levels", 0, "10,13,16", "octree levels", 64, "6",
                   "N³ nodes per level around the scene camera"),
    OCT_FLAG(field_opts_t, march_clear, "march-clear", "march τ even where the sun column is proven clear (the "
        "state before the clear-sky shortcut; the same bits, counted as clear marched)"),
    OCT_FLAG(field_opts_t, exact, "exact", "also sample the same nodes through the sources' exact box filter: its "
        "µs per brick beside the fast filter's, and the fast one's error"),
    OCT_OPTS_END};

OCT_SPEC(field, "Brick production of a scene's field sources: bricks/s per core, bound classification.", field_opts,
         .epilog = "Prints the anchor beside each level: a scalar 6-octave Perlin fBm once per voxel, bricks/s per core,\n"
                   "and the ratios to it; with shadows, σt + τ as the world makes them, the CPU on bricks that end up\n"
                   "empty, and the τ direct marches proven clear.\n");

/*-*** The bench ***/

#define NLEVELS 22

typedef struct {
  const char *prog;
  const field_opts_t *o;
  ocs_field_t *f;
  oc_key_t *keys, *skeys; /* a level's nodes; those sampled */
  long nodes, sampled;
  float *s, *e;
  uint64_t dig_s, dig_n, dig_t; /* FNV-1a of sampled σt, of every node's σt, and of τ */
  char tau_rows[NLEVELS][512], exact_rows[NLEVELS][256];
} field_run_t;

/* One level's block: bounds, samples, the row of the main table; *anchor: the anchor's bricks/s.
 * @return 0, or -1 after printing the error. */
static int field_level(field_run_t *R, int level, oc_dvec3 centre, double *sink, double *anchor) {
  const long block = R->o->block;
  const double t = R->o->time;
  oc_key_t k0 = oc_key_from_point(level, centre);
  long classified = 0, nonempty = 0, nonempty_bricks = 0;
  double ts = 0.0;
  R->nodes = R->sampled = 0;
  for (long z = 0; z < block; z++)
    for (long y = 0; y < block; y++)
      for (long x = 0; x < block; x++) {
        oc_key_t k = oc_key_neighbor(k0, (int)(x - block / 2), (int)(y - block / 2), (int)(z - block / 2));
        if (k == OC_KEY_INVALID) continue;
        R->keys[R->nodes++] = k;
        float lo, hi;
        double t0 = oct_now();
        ocs_field_bound(R->f, k, t, &lo, &hi);
        if (lo == hi) {
          classified++;
          ts += oct_now() - t0;
          for (int i = 0; i < OC_BRICK_VOXELS; i++) R->s[i] = lo; /* what the state holds for it */
          R->dig_n = oct__fnv(R->dig_n, R->s, sizeof(float) * OC_BRICK_VOXELS);
          nonempty_bricks += hi > 0.0f;
          continue;
        }
        if (ocs_field_sample(R->f, k, t, R->s) < 0) return oc_cli_fail(R->prog, -1, "sampling failed");
        ts += oct_now() - t0;
        R->skeys[R->sampled++] = k;
        R->dig_s = oct__fnv(R->dig_s, R->s, sizeof(float) * OC_BRICK_VOXELS);
        R->dig_n = oct__fnv(R->dig_n, R->s, sizeof(float) * OC_BRICK_VOXELS);
        int any = 0;
        for (int i = 0; i < OC_BRICK_VOXELS; i++) nonempty += R->s[i] > 0.0f, any |= R->s[i] > 0.0f;
        nonempty_bricks += any;
      }
  long nodes = R->nodes, sampled = R->sampled;
  double ta = oct_anchor_seconds(R->keys, nodes, sink);
  *anchor = nodes / ta;
  fprintf(stderr, "\r\033[K");
  printf("| %d | %.1f | %ld | %.1f %% | %ld | %.0f | %.1f | %.1f %% | %ld | %.0f | %.0f | %.2f× | %.2f× |\n", level,
         oc_key_size(level), nodes, 100.0 * classified / nodes, sampled, sampled ? sampled / ts : 0.0,
         sampled ? 1e6 * ts / sampled : 0.0, sampled ? 100.0 * nonempty / (sampled * 512.0) : 0.0, nonempty_bricks,
         nonempty_bricks / ts, *anchor, sampled ? sampled / ts / *anchor : 0.0, nonempty_bricks / ts / *anchor);
  fflush(stdout);
  return 0;
}

/* --exact: the same sampled nodes through the exact box filter: its cost, and the fast one's error. */
static int field_exact(field_run_t *R, int level, char *row, size_t cap) {
  double tf = 0.0, tx = 0.0, sf = 0.0, sx = 0.0, sq = 0.0;
  long withc = 0, sampled = R->sampled;
  float *s = R->s, *e = R->e;
  for (long q = 0; q < sampled; q++) {
    double t0 = oct_now();
    ocs_field_set_exact(R->f, 0);
    if (ocs_field_sample(R->f, R->skeys[q], R->o->time, s) < 0) return oc_cli_fail(R->prog, -1, "sampling failed");
    double t1 = oct_now();
    ocs_field_set_exact(R->f, 1);
    if (ocs_field_sample(R->f, R->skeys[q], R->o->time, e) < 0) return oc_cli_fail(R->prog, -1, "exact sampling failed");
    tx += oct_now() - t1, tf += t1 - t0;
    double mx = 0.0, d2 = 0.0;
    for (int i = 0; i < OC_BRICK_VOXELS; i++) {
      sf += s[i], sx += e[i], mx = fmax(mx, (double)e[i]);
      d2 += ((double)s[i] - e[i]) * ((double)s[i] - e[i]);
    }
    if (mx > 0.0) sq += d2 / (OC_BRICK_VOXELS * mx * mx), withc++;
  }
  ocs_field_set_exact(R->f, 0);
  snprintf(row, cap, "| %d | %ld | %.1f | %.1f | %.1f× | %+.2f %% | %.2f %% |\n", level, sampled,
           sampled ? 1e6 * tx / sampled : 0.0, sampled ? 1e6 * tf / sampled : 0.0, tf > 0.0 ? tx / tf : 0.0,
           sx > 0.0 ? 100.0 * (sf / sx - 1.0) : 0.0, withc ? 100.0 * sqrt(sq / withc) : 0.0);
  return 0;
}

/* σt + τ as the world makes them, each brick timed, over a cold brick cache. */
static int field_tau(field_run_t *R, const oc_scene_t *sc, int level, double anchor, char *row, size_t cap) {
  const long block = R->o->block;
  int ground_tau = oc_scene_has(sc, OC_FEATURE_PLANET_SURFACE);
  const char *env = getenv("OCS_TAU_GROUND_DIRECT"); /* "1": the ground ray by ray, as the world (before/after) */
  int ground_direct = env && strcmp(env, "1") == 0;
  oct_fcache_t cache = {.f = R->f, .t = R->o->time};
  ocs_tau_stats_t st = {0};
  ocs_tau_desc_t d = {.sigma = oct_fcache_sigma, .bound = oct_fcache_bound, .ctx = &cache, .sun_dir = sc->sun_dir,
                      .ground = ground_tau && !ground_direct ? oct__ground : NULL,
                      .march_clear = R->o->march_clear, .stats = &st};
  int vcap = (int)((block / 4 + 2) * (block / 4 + 2) * (block / 4 + 2)), nvols = 0, rc = 0;
  oct__vol_t *vols = malloc(sizeof *vols * (size_t)vcap);
  if (!vols) return oc_cli_fail(R->prog, -1, "out of memory");
  long ne = 0, ground = 0, with_tau = 0;
  double t_all = 0.0, t_empty = 0.0, t_tau = 0.0;
  float tau[OC_BRICK_VOXELS], *s = R->s;
  for (long q = 0; q < R->nodes && !rc; q++) {
    oc_key_t k = R->keys[q];
    double t0 = oct_now();
    float lo, hi;
    oct_fcache_bound(&cache, k, &lo, &hi);
    int any = 0, tany = 0;
    if (hi > 0.0f) {
      if (oct_fcache_sigma(&cache, k, s) < 0) rc = oc_cli_fail(R->prog, -1, "sampling failed");
      for (int i = 0; i < OC_BRICK_VOXELS; i++) any |= s[i] > 0.0f;
    }
    int gt = !any && ground_tau && ocs_plan_ground_tau(k);
    if (!rc && (any || gt)) {
      double t1 = oct_now();
      if (oct__tau(&d, vols, &nvols, vcap, k, tau) < 0) rc = oc_cli_fail(R->prog, -1, "τ failed");
      for (int i = 0; i < OC_BRICK_VOXELS; i++) tany |= tau[i] > 0.0f;
      R->dig_t = oct__fnv(R->dig_t, tau, sizeof tau);
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
  snprintf(row, cap, "| %d | %ld | %ld | %ld | %d | %.1f | %.1f | %.0f | %.2f× | %.1f %% | %ld | %ld | %ld | %ld |\n", level,
           ne, with_tau, ground, nvols, 1e3 * t_all, 1e3 * t_tau, ne / t_all, ne / t_all / anchor,
           t_all > 0.0 ? 100.0 * t_empty / t_all : 0.0, (long)atomic_load(&st.direct),
           (long)atomic_load(&st.clear_proven), (long)atomic_load(&st.clear_marched), (long)atomic_load(&st.columns));
  return rc;
}

/* The tables after the main one, and the bound cache's and the digests' lines. */
static void field_tail(const field_run_t *R, int shadows) {
  const int n = R->o->levels.n;
  if (R->o->exact) {
    printf("\nThe fast box filter (what bricks hold) against the exact one (--exact), the same sampled nodes:\n\n"
           "| level | nodes | exact µs per brick | fast µs per brick | speed-up | sum of means, fast vs exact | voxel RMS "
           "difference (of each brick's largest) |\n|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int li = 0; li < n; li++) fputs(R->exact_rows[li], stdout);
  }
  if (shadows) {
    printf("\nσt + τ together, as the world produces them (cold brick cache per level; %s):\n\n"
           "| level | non-empty bricks | with τ | of which empty ground | τ volumes | CPU ms | of which τ ms | non-empty bricks/s per core | / anchor |"
           " CPU on bricks that end up empty | τ single-node | proven clear | clear marched | ground by columns |\n"
           "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
           R->o->march_clear ? "--march-clear: provably clear columns marched anyway" : "clear columns skipped");
    for (int li = 0; li < n; li++) fputs(R->tau_rows[li], stdout);
  }
  ocs_field_stats_t fs;
  ocs_field_stats(R->f, &fs);
  printf("\nfield bounds: %llu calls, bound cache %llu hits / %llu misses (hit rate %.3f%s)\n",
         (unsigned long long)fs.bound_calls, (unsigned long long)fs.bound_hits, (unsigned long long)fs.bound_misses,
         fs.bound_hits + fs.bound_misses ? (double)fs.bound_hits / (double)(fs.bound_hits + fs.bound_misses) : 0.0,
         fs.bound_hits + fs.bound_misses ? "" : "; OCS_FIELD_BOUND_CACHE=0 or no cacheable source");
  printf("digest (FNV-1a of the bytes): sampled σt %016llx, τ %016llx; σt of every node %016llx (the bounds "
         "decide which bricks are sampled, not what any holds)\n",
         (unsigned long long)R->dig_s, (unsigned long long)R->dig_t, (unsigned long long)R->dig_n);
}

/* The procedural source builds a layer's tables at its first use (up to 0.1 s, docs/procedural.md
 * "Filtering"), which the first level timed used to carry (its µs per brick 2–3× the same level's
 * run again). One untimed sample of the level-6 node holding the centre, whose bound spans every
 * layer active there, builds them first. @return 0, or -1 after printing the error. */
static int field_warm(field_run_t *R, oc_dvec3 centre) {
  memset(R->s, 0, sizeof(float) * OC_BRICK_VOXELS);
  if (ocs_field_sample(R->f, oc_key_from_point(6, centre), R->o->time, R->s) < 0)
    return oc_cli_fail(R->prog, -1, "sampling failed");
  return 0;
}

/* Every level of the block; 0, or -1 after printing the error. */
static int field_run(field_run_t *R, const oc_scene_t *sc, oc_geo_t g) {
  char why[1024];
  const field_opts_t *o = R->o;
  double tc = oct_now();
  if (ocs_field_create(&R->f, sc, why, sizeof why) < 0) return oc_cli_fail(R->prog, -1, "%s", why);
  tc = oct_now() - tc;
  printf("# field sources of %s (%d source(s), built in %.3f s), %d³ nodes per level around %.3f°, %.3f°, %.0f m, "
         "t = %g s, one thread\n\n",
         o->scene ? o->scene : "the built-in planet", sc->nsources, tc, o->block, g.lat, g.lon, o->alt, o->time);
  int shadows = oc_scene_has(sc, OC_FEATURE_SHADOWS);
  printf("| level | node size (m) | nodes | classified by bound | sampled | bricks/s per core | µs per brick | non-empty samples |"
         " non-empty bricks | non-empty bricks/s per core | anchor bricks/s per core | sampled / anchor | non-empty / anchor |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  double sink = 0.0, anchor = 0.0;
  oc_dvec3 centre = oc_geo_to_xyz(g);
  if (field_warm(R, centre)) return -1;
  for (int li = 0; li < o->levels.n; li++) {
    int level = (int)o->levels.v[li];
    if (field_level(R, level, centre, &sink, &anchor)) return -1;
    R->exact_rows[li][0] = 0;
    if (o->exact && field_exact(R, level, R->exact_rows[li], sizeof R->exact_rows[li])) return -1;
    if (shadows && field_tau(R, sc, level, anchor, R->tau_rows[li], sizeof R->tau_rows[li])) return -1;
  }
  field_tail(R, shadows);
  if (sink == 1234.5) printf("\n"); /* keeps the anchor's sum alive */
  return 0;
}

int oct_bench_field(const char *prog, int argc, char **argv) {
  field_opts_t o = {0};
  static oc_scene_t sc;
  int rc = oct_begin(&oct_bench_field_spec, argc, argv, &o, &o.scene, NULL, &sc, NULL);
  if (rc != OCT_GO) return rc;
  oc_geo_t g = oct_block_centre(&o.at, o.alt, &sc);
  size_t nk = (size_t)o.block * (size_t)o.block * (size_t)o.block;
  static field_run_t R;
  R = (field_run_t){.prog = prog, .o = &o, .dig_s = 0xcbf29ce484222325ull, .dig_n = 0xcbf29ce484222325ull,
                      .dig_t = 0xcbf29ce484222325ull};
  R.s = malloc(sizeof(float) * OC_BRICK_VOXELS);
  R.e = malloc(sizeof(float) * OC_BRICK_VOXELS);
  R.keys = malloc(sizeof(oc_key_t) * nk);
  R.skeys = malloc(sizeof(oc_key_t) * nk);
  if (!R.s || !R.e || !R.keys || !R.skeys) rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  else rc = field_run(&R, &sc, g) ? OC_EXIT_RUNTIME : OC_EXIT_OK;
  free(R.keys);
  free(R.skeys);
  free(R.e);
  free(R.s);
  ocs_field_free(R.f);
  oc_scene_free(&sc);
  return rc;
}
