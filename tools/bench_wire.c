/* bench_wire.c — `overcast-bench wire`: what an epoch costs on the wire, four ways side by side.
 *
 * The server core plans and produces epochs for one viewer at the scene camera, acknowledging
 * each, and every epoch is encoded
 *   plain  each lacking brick's 2048 code bytes zstd'd alone (one frame each), the records zstd'd
 *          as one blob: the baseline
 *   batch  the epoch encoder (proto/ocp_epoch.h): record op stream, batches of x-predicted planes
 *   delta  the same, with deltas against the node's previous brick where its range is unchanged
 *   dict   the same, with a dictionary trained on the first epoch's bricks (its DICT frame counted)
 * all at the same zstd level, then decoded again (ocp_epoch_dec_*; plain zstd for `plain`) by a
 * viewer holding its K−1 newest states: every decoded state must hash exactly like the server's,
 * or the bench fails. Speeds are of the uncompressed content (2048 bytes per brick sent and 32 per
 * record, the same figure for every variant) over one core's encode or decode wall time.
 *
 * The plain baseline calls zstd itself (proto's ocp_zstd_*): it measures what ocp_epoch.c saves over it. */
#include <inttypes.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


#include "bench.h"
#include "bench_util.h"
#include "bench_epoch.h"
#include "ocs.h"

enum { W_PLAIN, W_BATCH, W_DELTA, W_DICT, W_N };
static const char *const wname[W_N] = {"plain", "batch", "delta", "dict"};

#define W_HELD_MAX 4
#define W_DICT_ID 1u
#define W_DICT_BYTES (64u << 10)
#define W_VERSION OCP_VERSION_MAX

typedef struct {
  ocp_epoch_enc_t *enc; /* batch, delta, dict */
  ocp_epoch_dec_t *dec;
  int enabled;
  oc_buf_t buf;      /* this epoch's frames */
  oc_state_t out;    /* this epoch's decoded state */
  /* this epoch */
  uint64_t wire, brick_bytes;
  uint32_t delta_ch, full_ch;
  double enc_s, dec_s;
  /* the run */
  uint64_t t_wire, t_brick_bytes, t_bricks, t_content, anim_delta, anim_full;
  double t_enc, t_dec;
} wvar_t;

/* What the viewer holds: its K−1 newest states, newest first (the same for every variant, since
 * each variant's decode is checked against the server's checksum). */
typedef struct {
  oc_state_t s[W_HELD_MAX];
  int n, keep;
} held_t;

static const oc_brick_codes_t *held_lookup(void *ctx, uint32_t id) {
  const held_t *h = ctx;
  return oc_states_find_codes(h->s, h->n, id);
}

/* The newest state becomes held[0] (moved); the oldest beyond `keep` is dropped. */
static void held_push(held_t *h, oc_state_t *s) {
  if (h->n == h->keep) oc_state_free(&h->s[--h->n]);
  memmove(&h->s[1], &h->s[0], sizeof h->s[0] * (size_t)h->n);
  h->s[0] = *s;
  h->n++;
  oc_state_init(s);
}

/*-*** The plain baseline ***/

static void w_pack_record(const oc_node_t *n, uint8_t *r) {
  oc_put_u64(r, n->key);
  r[8] = n->kind;
  r[9] = r[10] = r[11] = 0;
  oc_put_u32(r + 12, n->brick_id);
  oc_put_f32(r + 16, n->range[0].lo);
  oc_put_f32(r + 20, n->range[0].hi);
  oc_put_f32(r + 24, n->range[1].lo);
  oc_put_f32(r + 28, n->range[1].hi);
}

/* Appends one frame of `type`: `head` (0 or 4 bytes), then src zstd'd. @return 0 or -1. */
static int plain_frame(oc_buf_t *out, uint8_t type, const uint8_t *head, size_t head_len, ocp_zcctx_t *cc, int level,
                       const void *src, size_t n) {
  size_t h = ocp_frame_begin(out, W_VERSION, type);
  oc_buf_append(out, head, head_len);
  size_t bound = ocp_zstd_bound(n);
  uint8_t *dst = oc_buf_grow(out, bound);
  if (!dst) return -1;
  size_t z = ocp_zstd_compress(cc, dst, bound, src, n, level);
  if (ocp_zstd_is_error(z)) return -1;
  out->len -= bound - z;
  ocp_frame_end(out, h);
  return 0;
}

static int plain_encode(ocp_zcctx_t *cc, int level, const oc_state_t *s, const uint32_t *lacking, uint32_t n, oc_buf_t *out,
                        uint8_t *scratch, uint64_t *brick_bytes) {
  ocp_epoch_begin_t m = {s->epoch, s->time, s->sun_dir, OCP_NO_BASE, s->node_count, s->brick_count, n};
  ocp_put_epoch_begin(out, W_VERSION, &m);
  for (uint32_t i = 0; i < s->node_count; i++) w_pack_record(&s->nodes[i], scratch + (size_t)i * OC_STATE_RECORD_BYTES);
  if (plain_frame(out, OCP_MSG_RECORDS, NULL, 0, cc, level, scratch, (size_t)s->node_count * OC_STATE_RECORD_BYTES)) return -1;
  for (uint32_t k = 0; k < n; k++) {
    const oc_brick_t *b = oc_state_find_brick(s, lacking[k]);
    uint8_t raw[OC_BRICK_CODE_BYTES], head[4];
    for (int c = 0; c < OC_CHANNELS; c++)
      for (int v = 0; v < OC_BRICK_VOXELS; v++) oc_put_u16(raw + 2 * (c * OC_BRICK_VOXELS + v), b->codes.code[c][v]);
    oc_put_u32(head, b->id);
    size_t before = out->len;
    if (plain_frame(out, OCP_MSG_BRICKS, head, sizeof head, cc, level, raw, sizeof raw)) return -1;
    *brick_bytes += out->len - before;
  }
  ocp_epoch_end_t e = {s->epoch, oc_state_checksum(s)};
  ocp_put_epoch_end(out, W_VERSION, &e);
  return out->err ? -1 : 0;
}

static int cmp_u32(const void *a, const void *b) {
  uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return (x > y) - (x < y);
}

/* Rebuilds the state from plain frames and the held bricks. @return 0 or -1 with a reason. */
static int plain_decode(ocp_zdctx_t *dc, const oc_buf_t *in, const held_t *held, oc_state_t *out, uint8_t *scratch, size_t scratch_cap,
                        char *why, size_t why_len) {
  ocp_epoch_begin_t m = {0};
  oc_state_t recv; /* received bricks, in arrival (ascending id) order */
  oc_state_init(&recv);
  oc_state_free(out);
  int r = -1;
  uint32_t *ids = NULL;
  for (size_t at = 0; at + OCP_HEADER_BYTES <= in->len;) {
    ocp_header_t h;
    if (ocp_header_parse(in->data + at, OCP_MAX_PAYLOAD, &h) < 0) goto done;
    const uint8_t *p = in->data + at + OCP_HEADER_BYTES;
    at += OCP_HEADER_BYTES + h.length;
    if (h.type == OCP_MSG_EPOCH_BEGIN) {
      if (ocp_get_epoch_begin(p, h.length, &m, why, why_len) < 0) goto done;
      out->epoch = m.epoch, out->time = m.time, out->sun_dir = m.sun_dir;
    } else if (h.type == OCP_MSG_RECORDS) {
      size_t want = (size_t)m.node_count * OC_STATE_RECORD_BYTES;
      if (want > scratch_cap || ocp_zstd_content_size(p, h.length) != want) goto bad;
      if (ocp_zstd_decompress(dc, scratch, want, p, h.length) != want) goto bad;
      for (uint32_t i = 0; i < m.node_count; i++) {
        const uint8_t *q = scratch + (size_t)i * OC_STATE_RECORD_BYTES;
        oc_node_t n = {.key = oc_get_u64(q), .kind = q[8], .brick_id = oc_get_u32(q + 12)};
        n.range[0] = (oc_range_t){oc_get_f32(q + 16), oc_get_f32(q + 20)};
        n.range[1] = (oc_range_t){oc_get_f32(q + 24), oc_get_f32(q + 28)};
        if (oc_state_add_node(out, &n) < 0) goto done;
      }
    } else if (h.type == OCP_MSG_BRICKS) {
      uint8_t raw[OC_BRICK_CODE_BYTES];
      oc_brick_codes_t c;
      if (h.length < 4 || ocp_zstd_decompress(dc, raw, sizeof raw, p + 4, h.length - 4) != sizeof raw) goto bad;
      for (int ch = 0; ch < OC_CHANNELS; ch++)
        for (int v = 0; v < OC_BRICK_VOXELS; v++) c.code[ch][v] = oc_get_u16(raw + 2 * (ch * OC_BRICK_VOXELS + v));
      if (oc_state_add_brick(&recv, oc_get_u32(p), &c) < 0) goto done;
    }
  }
  /* the state's bricks in id order: received, or held */
  ids = malloc(sizeof *ids * ((size_t)out->node_count + 1));
  if (!ids) goto done;
  uint32_t nb = 0;
  for (uint32_t i = 0; i < out->node_count; i++)
    if (out->nodes[i].kind == OC_NODE_BRICK) ids[nb++] = out->nodes[i].brick_id;
  qsort(ids, nb, sizeof *ids, cmp_u32);
  for (uint32_t k = 0; k < nb; k++) {
    const oc_brick_t *b = oc_state_find_brick(&recv, ids[k]);
    const oc_brick_codes_t *c = b ? &b->codes : held_lookup((void *)held, ids[k]);
    if (!c) {
      snprintf(why, why_len, "brick %" PRIu32 " neither sent nor held", ids[k]);
      goto done;
    }
    if (oc_state_add_brick(out, ids[k], c) < 0) goto done;
  }
  if (oc_state_validate(out, why, why_len) < 0) goto done;
  r = 0;
  goto done;
bad:
  snprintf(why, why_len, "bad zstd frame");
done:
  free(ids);
  oc_state_free(&recv);
  return r;
}

/*-*** The epoch encoder and decoder ***/

static int epoch_encode(ocp_epoch_enc_t *e, const oc_state_t *s, const oc_state_t *base, const uint32_t *lacking, uint32_t n,
                        oc_buf_t *out, uint64_t *brick_bytes) {
  if (ocp_epoch_enc_begin(e, s, base, lacking, n) < 0) return -1;
  for (;;) {
    size_t start = out->len;
    int r = ocp_epoch_enc_next(e, W_VERSION, out);
    if (r < 0) return -1;
    if (r == 0) return 0;
    if (out->data[start + 3] == OCP_MSG_BRICKS) *brick_bytes += out->len - start;
  }
}

/*-*** The subcommand ***/

typedef struct {
  int epochs, budget, level, threads;
  const char *csv;
} wire_opts_t;

static const oc_cli_opt_t wire_opts[] = {
    OCT_OPT_EPOCHS(wire_opts_t, "8", "epochs to step"),
    OCT_OPT_BUDGET(wire_opts_t, "64", "the viewer's"),
    OCT_INT(wire_opts_t, level, "level", "N", 1, 19, OC_CLI_STR(OCP_LEVEL_DEFAULT), "zstd level of every variant"),
    OCT_OPT_THREADS(wire_opts_t),
    OCT_STR(wire_opts_t, csv, "csv", "FILE", "also write one row per epoch and variant"),
    OCT_OPTS_END};

OCT_SPEC(wire,
         "Epoch encodings side by side: per-brick zstd, batches, deltas, a dictionary (the built-in procedural\n"
         "planet, one viewer at its camera; every decode is checked).",
         wire_opts);

typedef struct {
  const char *prog;
  const wire_opts_t *o;
  int animated;
  FILE *csv;
  wvar_t var[W_N];
  held_t held;
  oc_state_t prev; /* the server's previous state: the base of each difference */
  ocp_zcctx_t *cc;
  ocp_zdctx_t *dc;
  uint8_t *scratch;
  size_t scratch_cap;
  double train_s;
  size_t dict_len;
} wire_run_t;

/* The dictionary: trained on the first epoch's bricks, sent before its first BRICKS. */
static void wire_train(wire_run_t *R, const oc_state_t *s, const ocs_epoch_out_t *o) {
  wvar_t *x = &R->var[W_DICT];
  const oc_brick_codes_t **smp = malloc(sizeof *smp * ((size_t)o->nlacking + 1));
  oc_buf_t dict = {0};
  double t0 = oct_now();
  int tr = smp ? 0 : OC_ENOMEM;
  for (uint32_t k = 0; smp && k < o->nlacking; k++) smp[k] = &oc_state_find_brick(s, o->lacking[k])->codes;
  if (tr == 0) tr = ocp_dict_train(smp, o->nlacking, W_DICT_BYTES, &dict);
  R->train_s = oct_now() - t0;
  free(smp);
  ocp_enc_desc_t d = {.level = R->o->level, .deltas = 1, .dict_id = W_DICT_ID, .dict = dict.data, .dict_len = dict.len};
  if (tr < 0 || ocp_epoch_enc_create(&x->enc, &d) < 0) {
    printf("(no dictionary: training on %u bricks failed: %s)\n", o->nlacking, oc_strerror(tr < 0 ? tr : OC_ENOMEM));
    x->enabled = 0;
  } else {
    R->dict_len = dict.len;
    ocp_put_dict(&x->buf, W_VERSION, W_DICT_ID, dict.data, dict.len); /* counted in epoch 0 */
  }
  oc_buf_free(&dict);
}

/* Variant i of epoch e: encoded, decoded by the viewer, checked against the server's checksum.
 * @return 0, or -1 after printing the error. */
static int wire_variant(wire_run_t *R, int i, long e, const ocs_epoch_out_t *o, uint64_t content) {
  wvar_t *x = &R->var[i];
  const oc_state_t *s = o->state, *base = R->prev.node_count ? &R->prev : NULL;
  char why[1024];
  if (!(i == W_DICT && e == 0)) x->buf.len = 0;
  x->brick_bytes = 0;
  double t0 = oct_now();
  int r = i == W_PLAIN ? plain_encode(R->cc, R->o->level, s, o->lacking, o->nlacking, &x->buf, R->scratch, &x->brick_bytes)
                       : epoch_encode(x->enc, s, base, o->lacking, o->nlacking, &x->buf, &x->brick_bytes);
  x->enc_s = oct_now() - t0;
  if (r < 0) return oc_cli_fail(R->prog, -1, "wire: epoch %ld, %s: encoding failed", e, wname[i]);
  x->wire = x->buf.len;
  x->delta_ch = x->full_ch = 0;
  if (x->enc) {
    ocp_enc_stats_t st;
    ocp_epoch_enc_stats(x->enc, &st);
    x->delta_ch = st.delta_channels, x->full_ch = st.full_channels;
  }
  why[0] = '\0';
  const oc_state_t *held_ptr[W_HELD_MAX];
  for (int k = 0; k < R->held.n; k++) held_ptr[k] = &R->held.s[k];
  t0 = oct_now();
  r = i == W_PLAIN ? plain_decode(R->dc, &x->buf, &R->held, &x->out, R->scratch, R->scratch_cap, why, sizeof why)
                   : oct_epoch_decode(x->dec, &x->buf, held_ptr, R->held.n, &x->out, why, sizeof why);
  x->dec_s = oct_now() - t0;
  if (r < 0) return oc_cli_fail(R->prog, -1, "wire: epoch %ld, %s: DECODE FAILED: %s", e, wname[i], why);
  uint64_t checksum = oc_state_checksum(s), got = oc_state_checksum(&x->out);
  if (got != checksum)
    return oc_cli_fail(R->prog, -1, "wire: epoch %ld, %s: ROUND TRIP MISMATCH: server %016" PRIx64 ", decoded %016" PRIx64,
                       e, wname[i], checksum, got);
  x->t_wire += x->wire, x->t_brick_bytes += x->brick_bytes, x->t_bricks += o->nlacking, x->t_content += content;
  x->t_enc += x->enc_s, x->t_dec += x->dec_s;
  if (e > 0 && R->animated) x->anim_delta += x->delta_ch, x->anim_full += x->full_ch;
  if (R->csv)
    fprintf(R->csv, "%ld,%s,%u,%u,%" PRIu64 ",%" PRIu64 ",%" PRIu64 ",%.6f,%.6f,%u,%u\n", e, wname[i], s->node_count,
            o->nlacking, content, x->wire, x->brick_bytes, x->enc_s, x->dec_s, x->delta_ch, x->full_ch);
  return 0;
}

/* Epoch e: stepped, every variant, its line; the viewer and the server then hold its state. */
static int wire_epoch(wire_run_t *R, ocs_world_t *w, ocs_viewer_t *v, long e) {
  int r;
  ocs_epoch_out_t o;
  if ((r = ocs_world_step(w)) < 0 || (r = ocs_viewer_output(v, &o)) < 0)
    return oc_cli_fail(R->prog, -1, "wire: epoch %ld: %s", e, oc_strerror(r));
  const oc_state_t *s = o.state;
  uint64_t content = (uint64_t)o.nlacking * OC_BRICK_CODE_BYTES + (uint64_t)s->node_count * OC_STATE_RECORD_BYTES;
  size_t need = (size_t)s->node_count * OC_STATE_RECORD_BYTES;
  if (need > R->scratch_cap) {
    uint8_t *p = realloc(R->scratch, need);
    if (!p) return oc_cli_fail(R->prog, -1, "wire: out of memory");
    R->scratch = p, R->scratch_cap = need;
  }
  if (e == 0) wire_train(R, s, &o);
  for (int i = 0; i < W_N; i++)
    if (R->var[i].enabled && wire_variant(R, i, e, &o, content)) return -1;
  printf("%5ld %7u %7u            ", e, s->node_count, o.nlacking);
  for (int i = 0; i < W_N; i++) {
    if (R->var[i].enabled)
      printf(" %9.1f", R->var[i].wire / 1024.0);
    else
      printf(" %9s", "-");
  }
  printf("\n");
  fflush(stdout);
  /* the viewer now holds this state (every variant decoded it identically); the server too */
  int keep_from = R->var[W_DICT].enabled ? W_DICT : W_DELTA;
  held_push(&R->held, &R->var[keep_from].out);
  for (int i = 0; i < W_N; i++) oc_state_free(&R->var[i].out);
  if (oc_state_copy(&R->prev, s) < 0) return oc_cli_fail(R->prog, -1, "wire: out of memory");
  ocs_viewer_ack(v, s->epoch);
  return 0;
}

/* The table over the run. */
static void wire_summary(const wire_run_t *R) {
  const wvar_t *var = R->var;
  int epochs = R->o->epochs;
  printf("\nover %d epochs (%" PRIu64 " bricks sent); MB/s of content (2048 B a brick sent + 32 B a record) on one core\n",
         epochs, var[W_PLAIN].t_bricks);
  if (var[W_DICT].enabled)
    printf("dictionary: %zu bytes, trained in %.1f ms on epoch 0's bricks; its DICT frame is in dict's epoch-0 wire bytes\n",
           R->dict_len, 1e3 * R->train_s);
  printf("variant  bytes/brick  wire KiB/epoch  vs plain  ratio  encode MB/s  decode MB/s  delta channels (epochs 1..)\n");
  for (int i = 0; i < W_N; i++) {
    const wvar_t *x = &var[i];
    if (!x->enabled) continue;
    char dfrac[32] = "-";
    if (x->enc && i >= W_DELTA && R->animated && epochs > 1 && x->anim_delta + x->anim_full)
      snprintf(dfrac, sizeof dfrac, "%.1f%%", 100.0 * (double)x->anim_delta / (double)(x->anim_delta + x->anim_full));
    printf("%-7s %12.1f %15.1f %8.3f %6.2f %12.1f %12.1f  %s\n", wname[i],
           x->t_bricks ? (double)x->t_brick_bytes / (double)x->t_bricks : 0.0, x->t_wire / 1024.0 / (double)epochs,
           (double)x->t_wire / (double)var[W_PLAIN].t_wire, (double)x->t_content / (double)x->t_wire,
           x->t_enc > 0 ? x->t_content / 1e6 / x->t_enc : 0.0, x->t_dec > 0 ? x->t_content / 1e6 / x->t_dec : 0.0, dfrac);
  }
  printf("every decoded state matched the server's checksum\n");
}

/* The codecs of every variant, the csv file; 0, or -1 after printing the error. */
static int wire_open(wire_run_t *R, int kept_states) {
  R->held = (held_t){.n = 0, .keep = kept_states - 1};
  if (R->held.keep < 1) R->held.keep = 1;
  if (R->held.keep > W_HELD_MAX) R->held.keep = W_HELD_MAX;
  oc_state_init(&R->prev);
  R->cc = ocp_zcctx_new();
  R->dc = ocp_zdctx_new();
  for (int i = 0; i < W_N; i++) {
    oc_state_init(&R->var[i].out);
    R->var[i].enabled = 1;
    ocp_enc_desc_t d = {.level = R->o->level, .deltas = i >= W_DELTA};
    if (!R->cc || !R->dc || ocp_epoch_dec_create(&R->var[i].dec) < 0 ||
        (i != W_PLAIN && i != W_DICT && ocp_epoch_enc_create(&R->var[i].enc, &d) < 0))
      return oc_cli_fail(R->prog, -1, "wire: out of memory");
  }
  if (R->o->csv && !(R->csv = fopen(R->o->csv, "w")))
    return oc_cli_fail(R->prog, -1, "--csv: cannot open '%s'", R->o->csv);
  if (R->csv)
    fprintf(R->csv, "epoch,variant,records,bricks_sent,content_bytes,wire_bytes,brick_bytes,encode_s,decode_s,"
                    "delta_channels,full_channels\n");
  return 0;
}

/* Releases what wire_open() made; @return rc, or OC_EXIT_RUNTIME when the csv file fails. */
static int wire_close(wire_run_t *R, int rc) {
  if (R->csv && fclose(R->csv) != 0 && rc == OC_EXIT_OK)
    rc = oc_cli_fail(R->prog, OC_EXIT_RUNTIME, "--csv: cannot write '%s'", R->o->csv);
  for (int i = 0; i < W_N; i++) {
    ocp_epoch_enc_free(R->var[i].enc);
    ocp_epoch_dec_free(R->var[i].dec);
    oc_buf_free(&R->var[i].buf);
    oc_state_free(&R->var[i].out);
  }
  for (int i = 0; i < R->held.n; i++) oc_state_free(&R->held.s[i]);
  oc_state_free(&R->prev);
  ocp_zcctx_free(R->cc);
  ocp_zdctx_free(R->dc);
  free(R->scratch);
  return rc;
}

int oct_bench_wire(const char *prog, int argc, char **argv) {
  wire_opts_t opt = {0};
  static oc_scene_t sc;
  oc_camera_pose_t pose;
  int rc = oct_begin(&oct_bench_wire_spec, argc, argv, &opt, NULL, NULL, &sc, &pose);
  if (rc != OCT_GO) return rc;
  char why[1024];
  ocs_world_desc_t wd = {.threads = opt.threads, .cache_bytes = 1ull << 30};
  ocs_world_t *w = NULL;
  ocs_viewer_t *v = NULL;
  ocs_plan_desc_t req = {.budget = (uint64_t)opt.budget << 20, .slot_bytes = OC_SLOT_BYTES,
                         .record_bytes = OC_RECORD_BYTES, .max_depth = 21}, granted;
  static wire_run_t R;
  R = (wire_run_t){.prog = prog, .o = &opt};
  if (ocs_world_create(&w, &sc, &wd, why, sizeof why) < 0 ||
      ocs_world_add_viewer(w, &req, &v, &granted, why, sizeof why) < 0) {
    ocs_world_free(w);
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  }
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocs_view_t view = {cam.pos, cam.forward, cam.up, pose.fov, 1280, 720};
  ocs_viewer_set_view(v, &view);
  R.animated = ocs_field_animated(ocs_world_field(w));
  rc = wire_open(&R, granted.kept_states) ? OC_EXIT_RUNTIME : OC_EXIT_OK;
  if (rc == OC_EXIT_OK) {
    printf("scene %s (%s), budget %d MiB, %d kept states, zstd level %d\n", sc.name, R.animated ? "animated" : "static",
           opt.budget, granted.kept_states, opt.level);
    printf("epoch  leaves  bricks   wire KiB: %9s %9s %9s %9s\n", wname[0], wname[1], wname[2], wname[3]);
    for (long e = 0; e < opt.epochs && rc == OC_EXIT_OK; e++)
      if (wire_epoch(&R, w, v, e)) rc = OC_EXIT_RUNTIME;
    if (rc == OC_EXIT_OK) wire_summary(&R);
  }
  rc = wire_close(&R, rc);
  ocs_world_free(w);
  oc_scene_free(&sc);
  return rc;
}
