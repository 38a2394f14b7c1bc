/* interp.c — previous values of the newest state's leaves (interp.h).
 *
 * Both states are walked in spatial order (the first level-21 cell of each leaf ascending), each
 * leaf being the half-open interval [a, b) of level-21 Morton cells it covers. Two partitions of
 * the root then line up as interval lists whose members either coincide (same key), nest with the
 * P leaf outside (split) or nest with the P leaves inside (merge). Sample values go through
 * shaders/brick.h exactly as in common/oc_render.c (oc__leaf_channel). */
#include "interp.h"

#include <math.h>   /* ldexp, isfinite */
#include <stdlib.h> /* malloc, realloc, free */
#include <string.h> /* memset, memcpy */

#include "brick.h" /* ocg_code_decode, ocg_brick_base, ocg_brick_frac, ocg_trilerp */
#include "oc_err.h"
#include "oc_key.h"

#define OC__LEVELS (OC_KEY_MAX_LEVEL + 1)
#define OC__ALL_CELLS ((uint64_t)1 << 63) /* level-21 cells in the root */

/*-*** Spatial walk over one state ***/

/* Ascending keys give one Morton-sorted run per level; merging the runs by first cell yields the
 * leaves in space-filling order. */
typedef struct {
  const oc_state_t *s;
  int levels;                  /* non-empty levels */
  int level[OC__LEVELS];       /* which ones */
  uint32_t head[OC__LEVELS];   /* next record of each (indexed like level[]) */
  uint32_t end[OC__LEVELS];
  uint64_t hstart[OC__LEVELS]; /* first cell of head[] */
  uint32_t i;                  /* current record */
  int lv;                      /* its level */
  uint64_t a, b;               /* its cells [a, b) */
} oc__walk_t;

static inline uint64_t oc__start(oc_key_t key, int level) {
  return (key ^ ((oc_key_t)1 << (3 * level))) << (3 * (OC_KEY_MAX_LEVEL - level));
}

/* @return 0 or OC_ECORRUPT (an invalid key, or keys not strictly ascending). */
static int oc__walk_init(oc__walk_t *w, const oc_state_t *s) {
  memset(w, 0, sizeof *w);
  w->s = s;
  if (s->node_count == 0 || !s->nodes) return OC_ECORRUPT;
  int last = -1;
  for (uint32_t i = 0; i < s->node_count; i++) {
    oc_key_t k = s->nodes[i].key;
    int L = oc_key_level(k);
    if (L < 0 || (i > 0 && k <= s->nodes[i - 1].key)) return OC_ECORRUPT;
    if (L != last) { /* ascending keys: levels never decrease */
      w->level[w->levels] = L;
      w->head[w->levels] = i;
      w->hstart[w->levels] = oc__start(k, L);
      w->levels++;
      last = L;
    }
    w->end[w->levels - 1] = i + 1;
  }
  return 0;
}

/* Advances to the next leaf in spatial order. @return 1, or 0 when every leaf was visited. */
static int oc__walk_next(oc__walk_t *w) {
  int best = -1;
  for (int q = 0; q < w->levels; q++)
    if (w->head[q] < w->end[q] && (best < 0 || w->hstart[q] < w->hstart[best])) best = q;
  if (best < 0) return 0;
  w->i = w->head[best];
  w->lv = w->level[best];
  w->a = w->hstart[best];
  w->b = w->a + ((uint64_t)1 << (3 * (OC_KEY_MAX_LEVEL - w->lv)));
  if (++w->head[best] < w->end[best]) w->hstart[best] = oc__start(w->s->nodes[w->head[best]].key, w->lv);
  return 1;
}

/*-*** One P leaf, decoded as the renderer sees it ***/

typedef struct {
  int64_t idx;                /* P record decoded here, -1 none */
  int uniform;                /* empty, uniform, or a brick without payload */
  float value[OC_CHANNELS];   /* when uniform */
  float v[OC_CHANNELS][OC_BRICK_VOXELS];
} oc__leaf_t;

/* Mirrors oc__leaf_channel() of common/oc_render.c: empty → 0; uniform (or a brick whose payload
 * is missing) → range lo; a brick → ocg_code_decode of each code (0 for a zero channel). */
static void oc__leaf_decode(oc__leaf_t *lf, const oc_state_t *s, uint32_t idx) {
  if (lf->idx == (int64_t)idx) return;
  lf->idx = idx;
  const oc_node_t *n = &s->nodes[idx];
  const oc_brick_t *b = n->kind == OC_NODE_BRICK ? oc_state_find_brick(s, n->brick_id) : NULL;
  if (!b) {
    lf->uniform = 1;
    for (int c = 0; c < OC_CHANNELS; c++) lf->value[c] = n->kind == OC_NODE_EMPTY ? 0.0f : n->range[c].lo;
    return;
  }
  lf->uniform = 0;
  for (int c = 0; c < OC_CHANNELS; c++) {
    float lo = n->range[c].lo, hi = n->range[c].hi;
    for (int q = 0; q < OC_BRICK_VOXELS; q++)
      lf->v[c][q] = hi == 0.0f ? 0.0f : ocg_code_decode(b->codes.code[c][q], lo, hi);
  }
}

/* Per-axis interpolation setup of a local coordinate u ∈ [0,1]: ocg_brick_base / ocg_brick_frac
 * are component-wise, so an axis can be set up once for all samples sharing its coordinate. */
typedef struct {
  ocg_uint base; /* sample cell, 0..6 */
  float frac;    /* weight of base + 1, 0..1 */
} oc__axis_t;

static oc__axis_t oc__axis(float u) {
  ocg_vec3 uu = ocg_v3s(u), b = ocg_brick_base(uu), f = ocg_brick_frac(uu, b);
  oc__axis_t a = {OCG_TO_UINT(b.x), f.x};
  return a;
}

/* The reconstruction at the point set up by (x, y, z): exactly oc__leaf_channel() of
 * common/oc_render.c (ocg_trilerp of the eight decoded corners). */
static float oc__leaf_eval(const oc__leaf_t *lf, int ch, oc__axis_t x, oc__axis_t y, oc__axis_t z) {
  if (lf->uniform) return lf->value[ch];
  ocg_uint b0 = ocg_brick_voxel(x.base, y.base, z.base);
  const float *c = lf->v[ch];
  float v[8];
  for (ocg_uint q = 0; q < 8u; q++) v[q] = c[b0 + ocg_brick_voxel(q & 1u, (q >> 1) & 1u, q >> 2)];
  return ocg_trilerp(ocg_v4(v[0], v[1], v[2], v[3]), ocg_v4(v[4], v[5], v[6], v[7]), ocg_v3(x.frac, y.frac, z.frac));
}

/*-*** Result ***/

typedef struct {
  ocv_interp_t *ip;
  const oc_state_t *p;
  oc__leaf_t *leaf;     /* decode cache (one P leaf) */
  double (*sum)[OC_BRICK_VOXELS]; /* CHILDREN accumulators [8 octants · 2 channels][512] */
  uint8_t *cnt;         /* [8 octants · 512] */
  uint32_t *kids;       /* CHILDREN: P records inside the current N leaf */
  uint32_t kids_cap;
  int count_only;       /* first pass: only count the pool entries that may be needed */
  uint32_t need;        /* what the first pass counted */
} oc__ctx_t;

/* n new pool entries (the last ones); the first pass sized the pool, so NULL means a bug. */
static float *oc__pool_take(ocv_interp_t *ip, uint32_t n) {
  if (n > ip->pool_cap - ip->pool_count) return NULL;
  float *dst = ip->pool + (size_t)ip->pool_count * OCV_INTERP_ENTRY_FLOATS;
  ip->pool_count += n;
  return dst;
}

/* Files the n entries just filled (the last ones in the pool; n = 1, or OCV_INTERP_FINE_ENTRIES
 * for a fine value) under e, or turns them into a uniform value when both channels are constant
 * over all of them (the entries are then given back). */
static void oc__pool_commit(ocv_interp_t *ip, ocv_interp_prev_t *e, uint32_t n) {
  uint32_t idx = ip->pool_count - n;
  const float *v = ip->pool + (size_t)idx * OCV_INTERP_ENTRY_FLOATS;
  int constant = 1;
  for (uint32_t k = 0; k < n && constant; k++)
    for (int c = 0; c < OC_CHANNELS && constant; c++) {
      const float *w = v + (size_t)k * OCV_INTERP_ENTRY_FLOATS + c * OC_BRICK_VOXELS;
      for (int q = 0; q < OC_BRICK_VOXELS; q++)
        if (w[q] != v[c * OC_BRICK_VOXELS]) {
          constant = 0;
          break;
        }
    }
  if (constant) {
    e->uniform = 1;
    e->fine = 0;
    e->value[0] = v[0];
    e->value[1] = v[OC_BRICK_VOXELS];
    e->prev_index = OCV_INTERP_NO_POOL;
    ip->pool_count = idx;
    return;
  }
  e->uniform = 0;
  e->fine = n > 1;
  e->prev_index = idx;
}

static void oc__set_uniform(ocv_interp_prev_t *e, const float value[OC_CHANNELS]) {
  e->uniform = 1;
  e->value[0] = value[0];
  e->value[1] = value[1];
  e->prev_index = OCV_INTERP_NO_POOL;
}

static int oc__same_content(const oc_node_t *a, const oc_node_t *b) {
  if (a->kind != b->kind) return 0;
  if (a->kind == OC_NODE_EMPTY) return 1;
  if (a->kind == OC_NODE_BRICK && a->brick_id != b->brick_id) return 0;
  for (int c = 0; c < OC_CHANNELS; c++)
    if (a->range[c].lo != b->range[c].lo || a->range[c].hi != b->range[c].hi) return 0;
  return 1;
}

/* P's record pi decoded into cx->leaf: a uniform one is set in e (*dst NULL), otherwise *dst is
 * the pool entry to fill. @return 0 or OC_ECORRUPT (the pool is full). */
static int oc__decode_prev(oc__ctx_t *cx, ocv_interp_prev_t *e, uint32_t pi, float **dst) {
  *dst = NULL;
  oc__leaf_decode(cx->leaf, cx->p, pi);
  if (cx->leaf->uniform) {
    oc__set_uniform(e, cx->leaf->value);
    return 0;
  }
  *dst = oc__pool_take(cx->ip, 1);
  return *dst ? 0 : OC_ECORRUPT;
}

/* OWN: P's record pi decoded. */
static int oc__fill_own(oc__ctx_t *cx, ocv_interp_prev_t *e, uint32_t pi) {
  float *dst;
  int rc = oc__decode_prev(cx, e, pi, &dst);
  if (rc < 0 || !dst) return rc;
  memcpy(dst, cx->leaf->v, sizeof cx->leaf->v);
  oc__pool_commit(cx->ip, e, 1);
  return 0;
}

/* PARENT: P ancestor pi (level la) reconstructed at the samples of N leaf nkey (level ln > la). */
static int oc__fill_parent(oc__ctx_t *cx, ocv_interp_prev_t *e, uint32_t pi, int la, oc_key_t nkey, int ln) {
  float *dst;
  int rc = oc__decode_prev(cx, e, pi, &dst);
  if (rc < 0 || !dst) return rc;
  int D = ln - la;
  uint32_t n[3], a[3];
  oc_key_coords(nkey, &n[0], &n[1], &n[2]);
  oc_key_coords(cx->p->nodes[pi].key, &a[0], &a[1], &a[2]);
  /* A-local coordinate of sample i on each axis: (7c + i) / (7·2^D), rounded once to float. */
  oc__axis_t u[3][OC_BRICK_EDGE];
  double den = ldexp(7.0, D);
  for (int ax = 0; ax < 3; ax++) {
    int64_t c = (int64_t)n[ax] - ((int64_t)a[ax] << D);
    for (int i = 0; i < OC_BRICK_EDGE; i++) u[ax][i] = oc__axis((float)((double)(7 * c + i) / den));
  }
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    for (int k = 0; k < OC_BRICK_EDGE; k++)
      for (int j = 0; j < OC_BRICK_EDGE; j++)
        for (int i = 0; i < OC_BRICK_EDGE; i++)
          dst[ch * OC_BRICK_VOXELS + i + 8 * j + 64 * k] = oc__leaf_eval(cx->leaf, ch, u[0][i], u[1][j], u[2][k]);
  oc__pool_commit(cx->ip, e, 1);
  return 0;
}

/* CHILDREN: the kid_count P descendants in cx->kids sampled on the lattices of the 8 octants of N
 * leaf nkey (level ln), one sub-brick each: per sample, the mean over the descendants inside the
 * octant whose closed box holds it (interp.h: always one). */
static int oc__fill_children(oc__ctx_t *cx, ocv_interp_prev_t *e, uint32_t kid_count, oc_key_t nkey, int ln) {
  uint32_t n[3];
  oc_key_coords(nkey, &n[0], &n[1], &n[2]);
  memset(cx->sum, 0, sizeof(double) * OCV_INTERP_FINE_ENTRIES * OC_CHANNELS * OC_BRICK_VOXELS);
  memset(cx->cnt, 0, OCV_INTERP_FINE_ENTRIES * OC_BRICK_VOXELS);
  for (uint32_t t = 0; t < kid_count; t++) {
    uint32_t di = cx->kids[t];
    oc_key_t dkey = cx->p->nodes[di].key;
    int D = oc_key_level(dkey) - ln - 1; /* depth below its octant, ≥ 0 */
    if (D < 0) return OC_ECORRUPT;
    uint32_t d[3];
    oc_key_coords(dkey, &d[0], &d[1], &d[2]);
    /* Its octant o, and per axis the samples i of o's lattice with c/2^D ≤ i/7 ≤ (c+1)/2^D (c its
     * cell offset inside o), i.e. 7c ≤ i·2^D ≤ 7c + 7; local u = (i·2^D − 7c)/7. */
    int lo[3], hi[3], o = 0;
    oc__axis_t u[3][OC_BRICK_EDGE];
    for (int ax = 0; ax < 3; ax++) {
      int64_t off = (int64_t)d[ax] - ((int64_t)n[ax] << (D + 1)), step = (int64_t)1 << D;
      if (off < 0 || off >= 2 * step) return OC_ECORRUPT; /* not inside the N leaf */
      int oa = (int)(off >> D);
      int64_t c = off - ((int64_t)oa << D);
      o |= oa << ax;
      int64_t l = (7 * c + step - 1) >> D, h = (7 * c + 7) >> D;
      lo[ax] = (int)(l < 0 ? 0 : l);
      hi[ax] = (int)(h > 7 ? 7 : h);
      for (int i = lo[ax]; i <= hi[ax]; i++) u[ax][i] = oc__axis((float)((double)((int64_t)i * step - 7 * c) / 7.0));
    }
    oc__leaf_decode(cx->leaf, cx->p, di);
    double (*sum)[OC_BRICK_VOXELS] = cx->sum + (size_t)o * OC_CHANNELS;
    uint8_t *cnt = cx->cnt + (size_t)o * OC_BRICK_VOXELS;
    for (int k = lo[2]; k <= hi[2]; k++)
      for (int j = lo[1]; j <= hi[1]; j++)
        for (int i = lo[0]; i <= hi[0]; i++) {
          int q = i + 8 * j + 64 * k;
          for (int ch = 0; ch < OC_CHANNELS; ch++) sum[ch][q] += oc__leaf_eval(cx->leaf, ch, u[0][i], u[1][j], u[2][k]);
          cnt[q]++;
        }
  }
  float *dst = oc__pool_take(cx->ip, OCV_INTERP_FINE_ENTRIES);
  if (!dst) return OC_ECORRUPT;
  for (int o = 0; o < OCV_INTERP_FINE_ENTRIES; o++)
    for (int q = 0; q < OC_BRICK_VOXELS; q++) {
      uint8_t cnt = cx->cnt[o * OC_BRICK_VOXELS + q];
      if (!cnt) { /* descendants that do not tile the node: not a partition */
        cx->ip->pool_count -= OCV_INTERP_FINE_ENTRIES;
        return OC_ECORRUPT;
      }
      for (int c = 0; c < OC_CHANNELS; c++)
        dst[(size_t)o * OCV_INTERP_ENTRY_FLOATS + c * OC_BRICK_VOXELS + q] =
            (float)(cx->sum[o * OC_CHANNELS + c][q] / cnt);
    }
  oc__pool_commit(cx->ip, e, OCV_INTERP_FINE_ENTRIES);
  return 0;
}

static int oc__kids_push(oc__ctx_t *cx, uint32_t count, uint32_t idx) {
  if (count == cx->kids_cap) {
    uint32_t cap = cx->kids_cap ? cx->kids_cap * 2 : 64;
    uint32_t *nk = realloc(cx->kids, (size_t)cap * sizeof *nk);
    if (!nk) return OC_ENOMEM;
    cx->kids = nk;
    cx->kids_cap = cap;
  }
  cx->kids[count] = idx;
  return 0;
}

/* The merge pass. */
static int oc__build(oc__ctx_t *cx, const oc_state_t *P, const oc_state_t *N) {
  ocv_interp_t *ip = cx->ip;
  oc__walk_t wn, wp;
  OC_TRY(oc__walk_init(&wn, N));
  int have_p = 0;
  uint64_t p_end = 0; /* cells of P visited so far */
  if (P) {
    OC_TRY(oc__walk_init(&wp, P));
    have_p = oc__walk_next(&wp);
    if (wp.a != 0) return OC_ECORRUPT;
  }
/* Moves P on by one leaf, checking that leaves follow each other without gap or overlap. */
#define OC__P_ADVANCE()                                         \
  do {                                                          \
    p_end = wp.b;                                               \
    have_p = oc__walk_next(&wp);                                \
    if (have_p && wp.a != p_end) return OC_ECORRUPT;            \
  } while (0)

  uint64_t n_end = 0;
  while (oc__walk_next(&wn)) {
    if (wn.a != n_end) return OC_ECORRUPT;
    n_end = wn.b;
    const oc_node_t *nn = &N->nodes[wn.i];
    ocv_interp_prev_t *e = &ip->prev[wn.i];
    memset(e, 0, sizeof *e);
    e->prev_index = OCV_INTERP_NO_POOL;
    if (!P) {
      e->source = OCV_INTERP_NONE;
      continue;
    }
    if (!have_p || wp.a > wn.a) return OC_ECORRUPT;
    if (wp.a == wn.a && wp.b == wn.b) { /* same key */
      const oc_node_t *pn = &P->nodes[wp.i];
      if (oc__same_content(pn, nn)) {
        e->source = OCV_INTERP_SAME;
      } else {
        e->source = OCV_INTERP_OWN;
        if (cx->count_only) cx->need += pn->kind == OC_NODE_BRICK;
        else OC_TRY(oc__fill_own(cx, e, wp.i));
      }
      OC__P_ADVANCE();
    } else if (wn.b <= wp.b) { /* P leaf strictly contains the N leaf: a split */
      e->source = OCV_INTERP_PARENT;
      if (cx->count_only) cx->need += P->nodes[wp.i].kind == OC_NODE_BRICK;
      else OC_TRY(oc__fill_parent(cx, e, wp.i, wp.lv, nn->key, wn.lv));
      if (wn.b == wp.b) OC__P_ADVANCE();
    } else if (wp.a == wn.a) { /* P leaves strictly inside the N leaf: a merge */
      uint32_t count = 0;
      while (have_p && wp.b <= wn.b) {
        if (!cx->count_only) OC_TRY(oc__kids_push(cx, count++, wp.i));
        OC__P_ADVANCE();
      }
      if (p_end != wn.b) return OC_ECORRUPT; /* a P leaf straddles the N leaf's end */
      e->source = OCV_INTERP_CHILDREN;
      if (cx->count_only) cx->need += OCV_INTERP_FINE_ENTRIES;
      else OC_TRY(oc__fill_children(cx, e, count, nn->key, wn.lv));
    } else {
      return OC_ECORRUPT;
    }
  }
#undef OC__P_ADVANCE
  if (n_end != OC__ALL_CELLS) return OC_ECORRUPT;
  if (P && (have_p || p_end != OC__ALL_CELLS)) return OC_ECORRUPT;
  return 0;
}

/*-*** API ***/

void ocv_interp_init(ocv_interp_t *ip) {
  if (ip) memset(ip, 0, sizeof *ip);
}

void ocv_interp_free(ocv_interp_t *ip) {
  if (!ip) return;
  free(ip->prev);
  free(ip->pool);
  memset(ip, 0, sizeof *ip);
}

int ocv_interp_build(ocv_interp_t *ip, const oc_state_t *prev, const oc_state_t *next) {
  if (!ip || !next) return OC_EINVAL;
  if (next->node_count == 0 || (prev && prev->node_count == 0)) {
    ocv_interp_free(ip);
    return OC_ECORRUPT;
  }
  ocv_interp_prev_t *np = realloc(ip->prev, (size_t)next->node_count * sizeof *np);
  if (!np) {
    ocv_interp_free(ip);
    return OC_ENOMEM;
  }
  ip->prev = np;
  ip->node_count = next->node_count;
  ip->pool_count = 0;

  /* Two passes: classify and count the pool entries that may be needed (a brick source), size the
   * pool once, then fill. Entries that turn out constant are given back, so the pool may end a
   * little shorter than sized and is trimmed. */
  oc__ctx_t cx = {.ip = ip, .p = prev, .count_only = 1};
  int err = oc__build(&cx, prev, next);
  if (!err && cx.need != ip->pool_cap) {
    float *sp = NULL;
    if (cx.need) sp = realloc(ip->pool, (size_t)cx.need * OCV_INTERP_ENTRY_FLOATS * sizeof *sp);
    else free(ip->pool);
    if (cx.need && !sp) {
      err = OC_ENOMEM;
    } else {
      ip->pool = sp;
      ip->pool_cap = cx.need;
    }
  }
  if (!err && prev) {
    cx.count_only = 0;
    cx.leaf = malloc(sizeof *cx.leaf);
    cx.sum = malloc(sizeof(double) * OCV_INTERP_FINE_ENTRIES * OC_CHANNELS * OC_BRICK_VOXELS);
    cx.cnt = malloc(OCV_INTERP_FINE_ENTRIES * OC_BRICK_VOXELS);
    if (!cx.leaf || !cx.sum || !cx.cnt) err = OC_ENOMEM;
    else cx.leaf->idx = -1;
    if (!err) err = oc__build(&cx, prev, next);
  }
  free(cx.leaf);
  free(cx.sum);
  free(cx.cnt);
  free(cx.kids);
  if (err) {
    ocv_interp_free(ip);
    return err;
  }
  if (ip->pool_count < ip->pool_cap) { /* constant entries were given back */
    if (ip->pool_count == 0) {
      free(ip->pool);
      ip->pool = NULL;
      ip->pool_cap = 0;
    } else {
      float *sp = realloc(ip->pool, (size_t)ip->pool_count * OCV_INTERP_ENTRY_FLOATS * sizeof *sp);
      if (sp) {
        ip->pool = sp;
        ip->pool_cap = ip->pool_count;
      }
    }
  }
  return 0;
}

const float *ocv_interp_sub_samples(const ocv_interp_t *ip, uint32_t i, int sub, int ch) {
  if (!ip || i >= ip->node_count || ch < 0 || ch >= OC_CHANNELS) return NULL;
  const ocv_interp_prev_t *e = &ip->prev[i];
  int subs = e->fine ? OCV_INTERP_FINE_ENTRIES : 1;
  if (sub < 0 || sub >= subs || e->prev_index == OCV_INTERP_NO_POOL || (uint64_t)e->prev_index + (uint64_t)subs > ip->pool_count)
    return NULL;
  return ip->pool + ((size_t)e->prev_index + (size_t)sub) * OCV_INTERP_ENTRY_FLOATS + (size_t)ch * OC_BRICK_VOXELS;
}

const float *ocv_interp_samples(const ocv_interp_t *ip, uint32_t i, int ch) {
  if (!ip || i >= ip->node_count || ip->prev[i].fine) return NULL;
  return ocv_interp_sub_samples(ip, i, 0, ch);
}

void ocv_interp_stats(const ocv_interp_t *ip, ocv_interp_stats_t *out) {
  if (!out) return;
  memset(out, 0, sizeof *out);
  if (!ip) return;
  for (uint32_t i = 0; i < ip->node_count; i++) {
    const ocv_interp_prev_t *e = &ip->prev[i];
    if (e->source < OCV_INTERP_SOURCES) out->count[e->source]++;
    if (e->uniform) out->uniform++;
    if (e->fine) out->fine++;
    if (e->prev_index != OCV_INTERP_NO_POOL) out->pooled += e->fine ? OCV_INTERP_FINE_ENTRIES : 1;
  }
}

float ocv_interp_param(double now, double arrival, double period) {
  if (!(period > 0.0) || !isfinite(period) || !isfinite(now) || !isfinite(arrival)) return 1.0f;
  double t = (now - arrival) / period;
  if (!(t > 0.0)) return 0.0f;
  return t >= 1.0 ? 1.0f : (float)t;
}

double ocv_interp_blend_seconds(double period, uint64_t prev_epoch, uint64_t next_epoch) {
  if (!(period > 0.0) || !isfinite(period)) return 0.0;
  uint64_t span = next_epoch > prev_epoch ? next_epoch - prev_epoch : 1;
  if (span > OCV_INTERP_MAX_SPAN) span = OCV_INTERP_MAX_SPAN;
  return (double)span * period;
}

float ocv_interp_weight(int source, int animated, double now, double arrival, double period) {
  switch (source) {
    case OCV_INTERP_OWN:
      return animated ? ocv_interp_param(now, arrival, period) : 1.0f;
    case OCV_INTERP_PARENT:
    case OCV_INTERP_CHILDREN:
      return ocv_interp_param(now, arrival, period);
    default:
      return 1.0f;
  }
}
