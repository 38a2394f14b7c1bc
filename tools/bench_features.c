/* bench_features.c — `overcast-bench features`: what a scene does not use costs nothing
 * (design.md, "Leave out what a scene does not need"), measured side by side in one run.
 *
 * Configurations: the scene with all its features, then, for each feature the scene has on, a copy
 * of the scene with that feature alone turned off (its bit cleared in oc_scene_t.features). For
 * each one, from scratch:
 *   server  ocs_world_create() time; ocs_world_step() in process CPU time (the producer threads
 *           included) for --epochs epochs with one viewer at the camera, still, acknowledging each
 *           epoch; bricks produced per epoch (ocs_world_stats), τ volumes; the kept states K
 *           (ocs_world_kept_states) and the resident bytes of the K newest states (oc_resident_bytes:
 *           distinct bricks × 2048 + records × 32, the Conventions' budget measure);
 *   wire    every epoch encoded by the epoch encoder with deltas (bench_wire.c's "delta" variant:
 *           proto/ocp_epoch.h, zstd level 3, the previous state as the base), decoded again by a
 *           viewer holding the K−1 previous states and checked against the server's checksum; the
 *           bricks re-sent (a lacking brick whose node was already a brick in the previous state);
 *   client  the atmosphere tables the configuration needs (oc_scene_atmo: bytes of the four RGBA32F
 *           tables, build time) and the final state rendered with its render description
 *           (oc_scene_render_desc) by the CPU reference renderer (configurations alternated round by
 *           round so each sees the same machine load; best of --repeat) or the GL compute renderer
 *           (its shader variants on; alternated the same way, each timed render after an untimed one
 *           that compiles the variant and uploads the tables).
 * Times vary with the machine; bricks, bytes, K, resident bytes and checksums are deterministic. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench.h"
#include "bench_util.h"
#include "bench_epoch.h"
#include "ocs.h"
#include "ocv.h"

#define F_VERSION OCP_VERSION_MAX

typedef struct {
  char label[64];
  int off;        /* the feature turned off, or -1: all the scene's features */
  oc_scene_t *sc; /* the configuration's scene */
  /* server */
  double create_ms, cpu0_ms, cpu_after_ms, cpu_last_ms; /* epoch 0; epochs 1.. summed; the last epoch */
  uint64_t bricks0, bricks_after, bricks_last, tau_volumes;
  uint64_t resent_after, resent_last;
  int K;
  uint64_t resident;
  uint32_t nodes, state_bricks, kinds[3]; /* newest state: leaves; bricks; empty, uniform, brick leaves */
  uint64_t checksum;
  /* wire */
  uint64_t wire0, wire_after, wire_last;
  /* client */
  oc_atmo_t *atmo;
  uint64_t table_bytes;
  double table_ms, table_cpu_ms; /* best of --repeat builds: wall, process CPU */
  double render_s, render_cpu_s;  /* best of --repeat renders: wall, process CPU */
  uint64_t samples;
  oc_state_t final; /* the viewer's newest state after the last epoch */
} fcfg_t;

static double cpu_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp_u32(const void *a, const void *b) {
  uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return (x > y) - (x < y);
}

/* Bricks the viewer is sent again: lacking bricks whose node was a brick in the previous state. */
static uint32_t count_resent(const oc_state_t *s, const oc_state_t *prev, const uint32_t *lacking, uint32_t n) {
  if (!prev || !n) return 0;
  uint32_t k = 0;
  for (uint32_t i = 0; i < s->node_count; i++) {
    const oc_node_t *nd = &s->nodes[i];
    if (nd->kind != OC_NODE_BRICK || !bsearch(&nd->brick_id, lacking, n, sizeof *lacking, cmp_u32)) continue;
    int64_t j = oc_state_find_node(prev, nd->key);
    if (j >= 0 && prev->nodes[j].kind == OC_NODE_BRICK) k++;
  }
  return k;
}

/* The server and the wire for one configuration. @return OC_EXIT_* after printing any error. */
/* The wire of epoch e: encoded against the previous state, decoded as the viewer, compared with the
 * server's state; buf receives the epoch's bytes. @return OC_EXIT_OK, or OC_EXIT_RUNTIME after the error. */
static int wire_round_trip(const char *prog, const fcfg_t *c, long e, ocs_viewer_t *v, const ocs_epoch_out_t *o,
                           ocp_epoch_enc_t *enc, ocp_epoch_dec_t *dec, oc_buf_t *buf) {
  const oc_state_t *s = o->state, *prev = ocs_viewer_held(v, 1);
  char why[1024];
  int r = 0;
  buf->len = 0;
  if (ocp_epoch_enc_begin(enc, s, prev, o->lacking, o->nlacking) < 0) r = OC_ENOMEM;
  while (r >= 0 && (r = ocp_epoch_enc_next(enc, F_VERSION, buf)) > 0) {
  }
  if (r < 0) {
    fprintf(stderr, "\n");
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: epoch %ld: encoding failed: %s", c->label, e, oc_strerror(r));
  }
  why[0] = '\0';
  /* the viewer holds what the server has seen acknowledged: its held states 1..K−1 */
  const oc_state_t *held[OCS_PLAN_MAX_KEPT];
  int nheld = 0;
  for (int i = 1; i < c->K && nheld < OCS_PLAN_MAX_KEPT; i++) held[nheld++] = ocs_viewer_held(v, i);
  oc_state_t got;
  oc_state_init(&got);
  r = oct_epoch_decode(dec, buf, held, nheld, &got, why, sizeof why);
  int same = r >= 0 && oc_state_checksum(&got) == oc_state_checksum(s);
  oc_state_free(&got);
  if (same) return OC_EXIT_OK;
  fprintf(stderr, "\n");
  return oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: epoch %ld: DECODE %s: %s", c->label, e, r < 0 ? "FAILED" : "MISMATCH",
                     r < 0 ? why : "the decoded state's checksum differs from the server's");
}

/* The last epoch's state: resident bytes, counts, checksum, and a copy to render. @return 0 or -1. */
static int record_last(fcfg_t *c, ocs_viewer_t *v, const oc_state_t *s) {
  const oc_state_t *kept[OCS_PLAN_MAX_KEPT];
  int n = 0;
  for (int i = 0; i < c->K && i < OCS_PLAN_MAX_KEPT; i++)
    if ((kept[n] = ocs_viewer_held(v, i))) n++;
  c->resident = oc_resident_bytes(kept, n, OC_SLOT_BYTES, OC_RECORD_BYTES);
  c->nodes = s->node_count, c->state_bricks = s->brick_count, c->checksum = oc_state_checksum(s);
  for (uint32_t i = 0; i < s->node_count; i++)
    if (s->nodes[i].kind <= OC_NODE_BRICK) c->kinds[s->nodes[i].kind]++;
  return oc_state_copy(&c->final, s);
}

static int run_server(const char *prog, fcfg_t *c, const ocs_view_t *view, long epochs, long budget_mib, int threads) {
  char why[1024];
  ocs_world_desc_t wd = {.threads = threads, .cache_bytes = 1ull << 30};
  ocs_world_t *w = NULL;
  ocs_viewer_t *v = NULL;
  ocp_epoch_enc_t *enc = NULL;
  ocp_epoch_dec_t *dec = NULL;
  oc_buf_t buf = {0};
  int rc = OC_EXIT_OK, r;
  double t0 = oct_now();
  if ((r = ocs_world_create(&w, c->sc, &wd, why, sizeof why)) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: %s", c->label, why);
    goto out;
  }
  c->create_ms = 1e3 * (oct_now() - t0);
  ocs_plan_desc_t req = {.budget = (uint64_t)budget_mib << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES,
                         .max_depth = 21};
  if (ocs_world_add_viewer(w, &req, &v, NULL, why, sizeof why) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: %s", c->label, why);
    goto out;
  }
  if (ocs_viewer_set_view(v, view) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: the view is not valid");
    goto out;
  }
  c->K = ocs_world_kept_states(w);
  ocp_enc_desc_t ed = {.level = OCP_LEVEL_DEFAULT, .deltas = 1};
  if (ocp_epoch_enc_create(&enc, &ed) < 0 || ocp_epoch_dec_create(&dec) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: out of memory");
    goto out;
  }
  uint64_t produced = 0;
  for (long e = 0; e < epochs; e++) {
    fprintf(stderr, "\r\033[K%s: features: %s: epoch %ld/%ld", prog, c->label, e + 1, epochs);
    double c0 = cpu_now();
    r = ocs_world_step(w);
    double cpu_ms = 1e3 * (cpu_now() - c0);
    ocs_epoch_out_t o;
    if (r < 0 || (r = ocs_viewer_output(v, &o)) < 0) {
      fprintf(stderr, "\n");
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: epoch %ld: %s", c->label, e, oc_strerror(r));
      goto out;
    }
    ocs_world_stats_t ws;
    ocs_world_stats(w, &ws);
    uint64_t made = ws.bricks_produced - produced;
    produced = ws.bricks_produced;
    const oc_state_t *s = o.state, *prev = ocs_viewer_held(v, 1);
    if ((rc = wire_round_trip(prog, c, e, v, &o, enc, dec, &buf)) != OC_EXIT_OK) goto out;
    uint32_t resent = count_resent(s, prev, o.lacking, o.nlacking);
    if (e == 0) {
      c->cpu0_ms = cpu_ms, c->bricks0 = made, c->wire0 = buf.len;
    } else {
      c->cpu_after_ms += cpu_ms, c->bricks_after += made, c->wire_after += buf.len, c->resent_after += resent;
    }
    if (e == epochs - 1) {
      c->cpu_last_ms = cpu_ms, c->bricks_last = made, c->resent_last = resent, c->wire_last = buf.len;
      c->tau_volumes = ws.tau_volumes;
      if (record_last(c, v, s) < 0) {
        fprintf(stderr, "\n");
        rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: out of memory");
        goto out;
      }
    }
    ocs_viewer_ack(v, s->epoch);
  }
  fprintf(stderr, "\r\033[K");
out:
  oc_buf_free(&buf);
  ocp_epoch_enc_free(enc);
  ocp_epoch_dec_free(dec);
  ocs_world_free(w);
  return rc;
}

/* The atmosphere tables the configuration needs (built again: the previous build is freed), their
 * bytes and the best build times so far. */
static int build_tables(const char *prog, fcfg_t *c, int threads) {
  oc_atmo_free(c->atmo);
  c->atmo = NULL;
  double t0 = oct_now(), c0 = cpu_now();
  if (oc_scene_atmo(c->sc, threads, &c->atmo) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: could not build the atmosphere tables", c->label);
  double ms = 1e3 * (oct_now() - t0), cpu_ms = 1e3 * (cpu_now() - c0);
  if (!c->atmo) ms = cpu_ms = 0.0; /* nothing built */
  if (ms < c->table_ms) c->table_ms = ms;
  if (cpu_ms < c->table_cpu_ms) c->table_cpu_ms = cpu_ms;
  c->table_bytes = 0;
  for (int k = 0; c->atmo && k < OC_ATMO_TABLE_COUNT; k++) {
    int tw = 0, th = 0;
    const float *px = NULL;
    if (oc_atmo_table(c->atmo, k, &tw, &th, &px) == 0) c->table_bytes += (uint64_t)tw * (uint64_t)th * 4u * sizeof(float);
  }
  return OC_EXIT_OK;
}

static oc_render_desc_t render_desc(const fcfg_t *c, oc_camera_t cam, int w, int h, int threads) {
  oc_render_desc_t d = oc_scene_render_desc(c->sc, c->atmo);
  d.width = w, d.height = h, d.camera = cam, d.threads = threads;
  return d;
}

/* CPU reference renders, configurations alternated round by round. */
static int render_cpu(const char *prog, fcfg_t *cf, int n, oc_camera_t cam, int w, int h, long repeat, int threads) {
  oc_image_t img = {0};
  if (oc_image_alloc(&img, w, h) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: out of memory");
  for (int i = 0; i < n; i++) cf[i].render_s = cf[i].render_cpu_s = 1e30;
  for (long k = 0; k < repeat; k++)
    for (int i = 0; i < n; i++) {
      fprintf(stderr, "\r\033[K%s: features: render %ld/%ld: %s", prog, k + 1, repeat, cf[i].label);
      oc_render_desc_t d = render_desc(&cf[i], cam, w, h, threads);
      oc_render_stats_t rs = {0};
      double t0 = oct_now(), c0 = cpu_now();
      if (oc_render_state(&cf[i].final, &d, &img, &rs) < 0) {
        oc_image_free(&img);
        fprintf(stderr, "\n");
        return oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: %s: render failed", cf[i].label);
      }
      double t = oct_now() - t0, tc = cpu_now() - c0;
      if (t < cf[i].render_s) cf[i].render_s = t;
      if (tc < cf[i].render_cpu_s) cf[i].render_cpu_s = tc;
      cf[i].samples = rs.samples;
    }
  fprintf(stderr, "\r\033[K");
  oc_image_free(&img);
  return OC_EXIT_OK;
}

#ifdef OC_HAVE_GL
/* GL compute renders (shader variants on): every configuration's state uploaded, then rounds with the
 * configurations alternated, as on the CPU. Each timed render follows an untimed one of the same
 * configuration, which compiles its variant the first time and uploads its tables when the previous
 * configuration's differed, so neither is counted. */
static int render_gl(const char *prog, fcfg_t *cf, int n, oc_camera_t cam, int w, int h, long repeat, char *info, size_t info_len) {
  char why[1024];
  ocv_gl_context_t *ctx = ocv_gl_context_init(why, sizeof why);
  if (!ctx) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s", why);
  ocv_gl_context_describe(ctx, info, info_len);
  ocv_gl_renderer_t *r = ocv_gl_renderer_create(why, sizeof why);
  ocv_gl_state_t *gs = calloc((size_t)n, sizeof *gs);
  oc_image_t img = {0};
  int rc = OC_EXIT_OK;
  if (!r) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s", why);
    goto out;
  }
  ocv_gl_renderer_set_variants(r, 1);
  if (!gs || oc_image_alloc(&img, w, h) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: out of memory");
    goto out;
  }
  for (int i = 0; i < n && rc == OC_EXIT_OK; i++) {
    cf[i].render_s = cf[i].render_cpu_s = 1e30;
    cf[i].samples = 0;
    if (ocv_gl_state_upload(&gs[i], &cf[i].final, why, sizeof why) < 0)
      rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s: %s", cf[i].label, why);
  }
  for (long k = 0; k < repeat && rc == OC_EXIT_OK; k++)
    for (int i = 0; i < n && rc == OC_EXIT_OK; i++) {
      fprintf(stderr, "\r\033[K%s: features: gl render %ld/%ld: %s", prog, k + 1, repeat, cf[i].label);
      oc_render_desc_t d = render_desc(&cf[i], cam, w, h, 1);
      double t = 0.0, tc = 0.0;
      for (int timed = 0; timed < 2; timed++) {
        double t0 = oct_now(), c0 = cpu_now();
        if (ocv_gl_render_state(r, &gs[i], &d, &img, why, sizeof why) < 0) {
          fprintf(stderr, "\n");
          rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "--renderer gl: %s: %s", cf[i].label, why);
          break;
        }
        t = oct_now() - t0, tc = cpu_now() - c0;
      }
      if (rc == OC_EXIT_OK && t < cf[i].render_s) cf[i].render_s = t;
      if (rc == OC_EXIT_OK && tc < cf[i].render_cpu_s) cf[i].render_cpu_s = tc;
    }
  fprintf(stderr, "\r\033[K");
out:
  for (int i = 0; gs && i < n; i++) ocv_gl_state_free(&gs[i]);
  free(gs);
  oc_image_free(&img);
  ocv_gl_renderer_free(r);
  ocv_gl_context_free(ctx);
  return rc;
}
#endif

/* "12.3 %" of the all-features figure saved; "—" when there is nothing to compare. */
static const char *saved(char *buf, size_t cap, double all, double x) {
  if (!(all > 0.0)) snprintf(buf, cap, "—");
  else snprintf(buf, cap, "%.1f %%", 100.0 * (1.0 - x / all));
  return buf;
}

/*-*** Options ***/

typedef struct {
  const char *scene, *camera;
  int epochs, budget, repeat, threads, gl;
  int viewport[2], size[2];
} feat_opts_t;

static const oc_cli_opt_t feat_opts[] = {
    OCT_OPT_SCENE(feat_opts_t),
    OCT_OPT_CAMERA(feat_opts_t),
    OCT_OPT_EPOCHS(feat_opts_t, "6", "epochs to step per configuration"),
    OCT_OPT_BUDGET(feat_opts_t, "64", "the viewer's"),
    OCT_SIZE(feat_opts_t, viewport, "viewport", "1280x720", "the viewport the server plans for"),
    OCT_SIZE(feat_opts_t, size, "size", "160x90", "rendered image size"),
    OCT_OPT_RENDERER(feat_opts_t, "renderer of the final state (gl: headless EGL)"),
    OCT_INT(feat_opts_t, repeat, "repeat", "N", 1, 1000, "3", "table builds and renders per configuration; the "
        "fastest counts"),
    OCT_INT_NOTE(feat_opts_t, threads, "threads", "N", 0, 64, "all cores", "producer, table and CPU render threads; "
        "0: all cores"),
    OCT_OPTS_END};

OCT_SPEC(features,
         "Each feature a scene uses turned off alone (all of the scene's features first; the camera held still):\n"
         "server time, bricks, wire, memory, tables, render.",
         feat_opts);

/*-*** The subcommand ***/

/* The configurations: all the scene's features, then each one it uses turned off alone. @return
 * how many, or -1 after printing the error. */
static int features_configs(const char *prog, const oc_scene_t *base, fcfg_t *cf) {
  int n = 0;
  for (int f = -1; f < OC_FEATURE_COUNT; f++) {
    if (f >= 0 && !oc_scene_has(base, (oc_scene_feature_t)f)) continue;
    fcfg_t *x = &cf[n++];
    x->off = f;
    oc_state_init(&x->final);
    if (f < 0) snprintf(x->label, sizeof x->label, "all the scene's features");
    else snprintf(x->label, sizeof x->label, "no %s", oc_scene_feature_name(f));
    if (!(x->sc = calloc(1, sizeof *x->sc)) || oc_scene_copy(x->sc, base) < 0) {
      oc_cli_fail(prog, 0, "features: out of memory");
      return -n;
    }
    if (f >= 0) x->sc->features &= ~(1u << f);
  }
  return n;
}

/* Every configuration's server run, tables and renders. */
static int features_measure(const char *prog, const feat_opts_t *o, fcfg_t *cf, int n, oc_camera_pose_t pose,
                            char *info, size_t info_len) {
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, o->viewport[0], o->viewport[1]};
  int rc = OC_EXIT_OK, w = o->size[0], h = o->size[1];
  for (int i = 0; i < n && rc == OC_EXIT_OK; i++) rc = run_server(prog, &cf[i], &view, o->epochs, o->budget, o->threads);
  /* the tables, configurations alternated round by round */
  for (int i = 0; i < n; i++) cf[i].table_ms = cf[i].table_cpu_ms = 1e30;
  for (long k = 0; k < o->repeat && rc == OC_EXIT_OK; k++)
    for (int i = 0; i < n && rc == OC_EXIT_OK; i++) {
      fprintf(stderr, "\r\033[K%s: features: tables %ld/%d: %s", prog, k + 1, o->repeat, cf[i].label);
      rc = build_tables(prog, &cf[i], o->threads);
    }
  fprintf(stderr, "\r\033[K");
  if (rc != OC_EXIT_OK) return rc;
#ifdef OC_HAVE_GL
  if (o->gl) return render_gl(prog, cf, n, cam, w, h, o->repeat, info, info_len);
#else
  (void)info, (void)info_len;
#endif
  return render_cpu(prog, cf, n, cam, w, h, o->repeat, o->threads);
}

/* The first two tables: each configuration's figures. */
static void features_tables(const feat_opts_t *o, const fcfg_t *cf, int n) {
  long after = o->epochs - 1;
  /* "a / b / c": epoch 0, the mean of epochs 1.., the last epoch ("a" alone with one epoch) */
  printf("| configuration | kept states | server CPU ms: epoch 0 / mean 1.. / last | bricks produced: 0 / mean 1.. / last "
         "| bricks re-sent: mean 1.. / last | wire KiB: 0 / mean 1.. / last | resident MiB | tables KiB | tables ms (CPU ms) "
         "| render ms (CPU ms) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int i = 0; i < n; i++) {
    const fcfg_t *x = &cf[i];
    printf("| %s | %d | %.0f", x->label, x->K, x->cpu0_ms);
    if (after > 0) printf(" / %.0f / %.0f", x->cpu_after_ms / after, x->cpu_last_ms);
    printf(" | %" PRIu64, x->bricks0);
    if (after > 0) printf(" / %.0f / %" PRIu64, (double)x->bricks_after / after, x->bricks_last);
    if (after > 0) printf(" | %.0f / %" PRIu64, (double)x->resent_after / after, x->resent_last);
    else printf(" | —");
    printf(" | %.1f", x->wire0 / 1024.0);
    if (after > 0) printf(" / %.1f / %.1f", x->wire_after / 1024.0 / after, x->wire_last / 1024.0);
    printf(" | %.2f | %.0f | %.0f (%.0f) | %.1f (%.1f) |\n", x->resident / 1048576.0, x->table_bytes / 1024.0, x->table_ms,
           x->table_cpu_ms, 1e3 * x->render_s, 1e3 * x->render_cpu_s);
  }
  printf("\n| configuration | world create ms | bricks produced, epoch 0 | τ volumes | state leaves: empty / uniform / brick "
         "| state bricks | state checksum | render samples |\n|---|---:|---:|---:|---:|---:|---|---:|\n");
  for (int i = 0; i < n; i++) {
    const fcfg_t *x = &cf[i];
    printf("| %s | %.1f | %" PRIu64 " | %" PRIu64 " | %u: %u / %u / %u | %u | %016" PRIx64 " | ", x->label, x->create_ms, x->bricks0,
           x->tau_volumes, x->nodes, x->kinds[OC_NODE_EMPTY], x->kinds[OC_NODE_UNIFORM], x->kinds[OC_NODE_BRICK], x->state_bricks,
           x->checksum);
    if (o->gl) printf("— |\n");
    else printf("%" PRIu64 " |\n", x->samples);
  }
}

/* The last table: what turning each feature off saves against all of them. */
static void features_saved(const fcfg_t *cf, int n) {
  const fcfg_t *a = &cf[0];
  printf("\nsaved against all the scene's features (share of its figure; negative: costs more):\n\n"
         "| turned off | server CPU, all epochs | bricks produced | wire, all epochs | wire, epochs 1.. | resident "
         "| tables bytes | tables CPU | render | render CPU |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int i = 1; i < n; i++) {
    const fcfg_t *x = &cf[i];
    char s[9][32];
    printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", oc_scene_feature_name(x->off),
           saved(s[0], 32, a->cpu0_ms + a->cpu_after_ms, x->cpu0_ms + x->cpu_after_ms),
           saved(s[1], 32, (double)(a->bricks0 + a->bricks_after), (double)(x->bricks0 + x->bricks_after)),
           saved(s[2], 32, (double)(a->wire0 + a->wire_after), (double)(x->wire0 + x->wire_after)),
           saved(s[3], 32, (double)a->wire_after, (double)x->wire_after), saved(s[4], 32, (double)a->resident, (double)x->resident),
           saved(s[5], 32, (double)a->table_bytes, (double)x->table_bytes), saved(s[6], 32, a->table_cpu_ms, x->table_cpu_ms),
           saved(s[7], 32, a->render_s, x->render_s), saved(s[8], 32, a->render_cpu_s, x->render_cpu_s));
  }
}

int oct_bench_features(const char *prog, int argc, char **argv) {
  feat_opts_t o = {0};
  static oc_scene_t base;
  oc_camera_pose_t pose;
  int rc = oct_begin(&oct_bench_features_spec, argc, argv, &o, &o.scene, &o.camera, &base, &pose);
  if (rc != OCT_GO) return rc;
  if (o.threads == 0) {
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    o.threads = n < 1 ? 1 : n > 64 ? 64 : (int)n;
  }
  fcfg_t *cf = calloc(OC_FEATURE_COUNT + 1, sizeof *cf);
  int n = cf ? features_configs(prog, &base, cf) : 0;
  char feat[256] = "", cam_text[256], info[512] = "CPU reference";
  if (!cf) rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "features: out of memory");
  else if (n <= 0) rc = OC_EXIT_RUNTIME, n = -n;
  else rc = features_measure(prog, &o, cf, n, pose, info, sizeof info);
  if (rc != OC_EXIT_OK) goto out;
  for (int f = 0; f < OC_FEATURE_COUNT; f++)
    if (oc_scene_has(&base, (oc_scene_feature_t)f))
      snprintf(feat + strlen(feat), sizeof feat - strlen(feat), "%s%s", feat[0] ? ", " : "", oc_scene_feature_name(f));
  oc_camera_format(pose, cam_text, sizeof cam_text);
  printf("# overcast-bench features: %s\n\n", o.scene ? o.scene : "the built-in procedural planet");
  printf("scene features on: %s; camera %s (still); %d epochs, budget %d MiB, viewport %dx%d; %d threads;\n"
         "renderer %s at %dx%d, best of %d; wire: epoch encoder with deltas, zstd level %d (every decode checked)\n\n",
         feat[0] ? feat : "none", cam_text, o.epochs, o.budget, o.viewport[0], o.viewport[1], o.threads,
         o.gl ? info : "CPU reference", o.size[0], o.size[1], o.repeat, OCP_LEVEL_DEFAULT);
  features_tables(&o, cf, n);
  if (n > 1) features_saved(cf, n);
  fflush(stdout);
out:
  for (int i = 0; cf && i < n; i++) {
    oc_state_free(&cf[i].final);
    oc_atmo_free(cf[i].atmo);
    if (cf[i].sc) oc_scene_free(cf[i].sc);
    free(cf[i].sc);
  }
  free(cf);
  oc_scene_free(&base);
  return rc;
}
