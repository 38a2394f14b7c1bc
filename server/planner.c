/* planner.c — per-viewer split/merge planning under the budget (see planner.h for the model).
 *
 * The tree is a pool of nodes; the 8 children of a node are consecutive (one block), so a split
 * allocates one block and a merge frees one. Heaps hold (index, key, priority) and are validated
 * lazily when popped: a merge can free a block whose stale entries are still queued. */
#include "planner.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "oc_bytes.h"
#include "oc_err.h"
#include "oc_planet.h"

#define AGE_NEW 255
#define F_NOGEOM 0x01  /* inside the planet or above the atmosphere: never split */
#define F_SPLIT 0x02   /* split this epoch: not merged again this epoch */
#define F_MERGED 0x04  /* merged this epoch: not split again this epoch */
#define F_FREE 0x08    /* in the free list */
#define F_REFRESH 0x10 /* its content refreshed this epoch */
#define F_SKIND 0x20   /* stepped, refreshed: its σt class stays as last made until made again */

/* pn_t.tcost: a brick as last made (or, until made, as predicted), and a brick by the bound's class
 * (what a refresh is predicted as, stepped) */
#define T_MADE 0x01
#define T_BOUND 0x02
#define T_OF(kind) ((kind) == OC_NODE_BRICK ? T_MADE | T_BOUND : 0) /* both as the one kind known */

typedef struct {
  oc_key_t key;
  uint64_t stamp;    /* content stamp held (leaves) */
  int32_t parent;
  int32_t child;     /* first of 8 consecutive children; -1 for a leaf */
  uint32_t brick_id; /* held brick (age < AGE_NEW) */
  float prio;
  uint8_t skind;     /* σt class (predicted or exact): only OC_NODE_BRICK may be split */
  uint8_t kind;      /* record kind (cost) */
  uint8_t age;       /* 1..K-1: content held in that state; AGE_NEW: to produce */
  uint8_t flags;
  uint8_t tcost;     /* what the steady cost T counts it as (T_MADE, T_BOUND; leaf_cost) */
  uint32_t topo;     /* commit count when it was last split or merged: until K commits later its
                        children (or, for a merged node, itself) may still be in a held state */
} pn_t;

typedef struct {
  oc_key_t key;
  uint64_t stamp;
  uint32_t brick_id;
  uint8_t kind, skind, tcost;
} snap_rec_t;

typedef struct {
  snap_rec_t *rec; /* ascending key */
  uint32_t n;
  uint32_t *ids;   /* ascending brick ids */
  uint32_t nids;
  uint64_t budget; /* the budget it was planned under (a window counts against its largest) */
} snap_t;

typedef struct {
  int32_t idx;
  float prio;
  oc_key_t key;
} hent_t;

typedef struct {
  hent_t *a;
  size_t n, cap;
  int max; /* 1: max-heap (splits), 0: min-heap (merges) */
} heap_t;

struct ocs_planner_s {
  ocs_plan_desc_t d;
  int K;
  pn_t *nodes;
  int32_t count, cap;
  int32_t free_block; /* first free block (linked through .parent), -1 none */
  int32_t placed;     /* blocks allocated since the pool was last laid out in walk order */
  uint32_t commits;   /* states committed */
  snap_t snap[OCS_PLAN_MAX_KEPT]; /* snap[0] newest held state */
  heap_t split_h, merge_h;
  /* the plan of the last ocs_plan_epoch() */
  ocs_plan_leaf_t *out;
  int32_t *out_node;
  uint32_t out_n, out_cap;
  int pending; /* a plan awaits commit/abandon */
  int gated;   /* the pending plan used only content that exists (in->ready) */
  /* per-epoch */
  const ocs_plan_input_t *in;
  double C[OCS_PLAN_MAX_KEPT], T, target;
  uint64_t aim; /* a lower budget the steady target heads for before it is in force; 0: none */
  double rate[OC_KEY_MAX_LEVEL + 1]; /* the input's refresh rate per level, clamped to [0, 1] */
  uint32_t new_bricks;
};

/*-*** Heaps ***/

static int h_before(const heap_t *h, const hent_t *a, const hent_t *b) {
  if (a->prio != b->prio) return h->max ? a->prio > b->prio : a->prio < b->prio;
  return a->key < b->key; /* deterministic ties */
}

static void h_down(heap_t *h, size_t i) {
  for (;;) {
    size_t l = 2 * i + 1, r = l + 1, m = i;
    if (l < h->n && h_before(h, &h->a[l], &h->a[m])) m = l;
    if (r < h->n && h_before(h, &h->a[r], &h->a[m])) m = r;
    if (m == i) return;
    hent_t t = h->a[i];
    h->a[i] = h->a[m];
    h->a[m] = t;
    i = m;
  }
}

/* append without ordering; h_heapify() afterwards */
static int h_append(heap_t *h, hent_t e) {
  hent_t *a = oc_grow(h->a, &h->cap, h->n, sizeof *a, 1024);
  if (!a) return OC_ENOMEM;
  h->a = a;
  h->a[h->n++] = e;
  return 0;
}

static int h_push(heap_t *h, hent_t e) {
  OC_TRY(h_append(h, e));
  size_t i = h->n - 1;
  while (i > 0) {
    size_t p = (i - 1) / 2;
    if (!h_before(h, &h->a[i], &h->a[p])) break;
    hent_t t = h->a[i];
    h->a[i] = h->a[p];
    h->a[p] = t;
    i = p;
  }
  return 0;
}

static void h_pop(heap_t *h) {
  h->a[0] = h->a[--h->n];
  if (h->n) h_down(h, 0);
}

static void h_heapify(heap_t *h) {
  for (size_t i = h->n / 2; i-- > 0;) h_down(h, i);
}

/*-*** Limits ***/

uint64_t ocs_plan_min_budget(const ocs_plan_desc_t *d) {
  return (uint64_t)d->kept_states * ((uint64_t)d->slot_bytes + d->record_bytes);
}

int ocs_plan_clamp(ocs_plan_desc_t *d, uint64_t max_budget) {
  if (!d) return OC_EINVAL;
  const uint32_t lim = 1u << 20;
  if (d->slot_bytes < 1) d->slot_bytes = 1;
  if (d->slot_bytes > lim) d->slot_bytes = lim;
  if (d->record_bytes < 1) d->record_bytes = 1;
  if (d->record_bytes > lim) d->record_bytes = lim;
  if (d->max_depth < 0) d->max_depth = 0;
  if (d->max_depth > OC_KEY_MAX_LEVEL) d->max_depth = OC_KEY_MAX_LEVEL;
  if (d->kept_states < 2) d->kept_states = 2;
  if (d->kept_states > OCS_PLAN_MAX_KEPT) d->kept_states = OCS_PLAN_MAX_KEPT;
  if (!(d->split_fraction > 0.0)) d->split_fraction = 0.1;
  if (d->split_fraction > 1.0) d->split_fraction = 1.0;
  if (!(d->reserve > 0.0)) d->reserve = d->split_fraction;
  if (d->reserve > 0.5) d->reserve = 0.5;
  if (!(d->min_pixels > 0.0)) d->min_pixels = 1.0;
  if (d->min_pixels > 1e6) d->min_pixels = 1e6;
  if (!(d->outside_weight > 0.0)) d->outside_weight = 0.25;
  if (d->outside_weight > 1.0) d->outside_weight = 1.0;
  uint64_t mn = ocs_plan_min_budget(d);
  if (max_budget < mn) return OC_ERANGE;
  if (d->budget < mn) d->budget = mn;
  if (d->budget > max_budget) d->budget = max_budget;
  return 0;
}

/*-*** Views and priority ***/

int ocs_view_valid(const ocs_view_t *v) {
  if (!v) return 0;
  double p[] = {v->pos.x, v->pos.y, v->pos.z, v->forward.x, v->forward.y, v->forward.z, v->up.x, v->up.y, v->up.z};
  for (int i = 0; i < 9; i++)
    if (!isfinite(p[i])) return 0;
  if (fabs(oc_dlen(v->forward) - 1.0) > 1e-3 || fabs(oc_dlen(v->up) - 1.0) > 1e-3) return 0;
  if (fabs(oc_ddot(v->forward, v->up)) > 1e-3) return 0;
  if (!(v->vfov_deg > 0.0 && v->vfov_deg < 180.0)) return 0;
  return v->width >= 1 && v->height >= 1 && v->width <= 65536 && v->height <= 65536;
}

typedef struct {
  oc_dvec3 eye, f, r, u;
  double th, tv, ch, cv; /* tangents of the half angles and 1/sqrt(1+t²) */
  double ppr;            /* pixels per radian */
  double out_w;
  double horizon;        /* eye's distance to its horizon (0 inside the planet) */
} frustum_t;

static frustum_t frustum_make(const ocs_view_t *v, double out_w) {
  frustum_t fr;
  fr.eye = v->pos;
  fr.f = v->forward;
  fr.u = v->up;
  fr.r = oc_dcross(v->forward, v->up);
  fr.tv = tan(0.5 * v->vfov_deg * OC_DEG);
  fr.th = fr.tv * (double)v->width / (double)v->height;
  fr.cv = 1.0 / sqrt(1.0 + fr.tv * fr.tv);
  fr.ch = 1.0 / sqrt(1.0 + fr.th * fr.th);
  fr.ppr = v->height / (2.0 * fr.tv);
  fr.out_w = out_w;
  double de = oc_dlen(v->pos), R = OC_PLANET_RADIUS;
  fr.horizon = de > R ? sqrt(de * de - R * R) : 0.0;
  return fr;
}

/* Node box: origin o, edge s. Priority = voxel pixels at the nearest point (ocs_lod_pixels' measure)
 * times out_w when the bounding sphere is outside the frustum. */
static inline double clampd(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

static double prio_box(const frustum_t *fr, oc_dvec3 o, double s) {
  /* ternaries, not fmin/fmax: those are libm calls without -ffinite-math-only, and this runs for
   * every node of every epoch (the eye is finite, checked by ocs_view_valid) */
  oc_dvec3 q = oc_dv3(clampd(fr->eye.x, o.x, o.x + s), clampd(fr->eye.y, o.y, o.y + s), clampd(fr->eye.z, o.z, o.z + s));
  double d = oc_dlen(oc_dsub(q, fr->eye));
  double p = s / 7.0 * fr->ppr / (d > 1.0 ? d : 1.0);
  oc_dvec3 c = oc_dsub(oc_dmad(o, oc_dv3(1, 1, 1), 0.5 * s), fr->eye);
  double rad = 0.8660254037844386 * s;
  double x = oc_ddot(c, fr->r), y = oc_ddot(c, fr->u), z = oc_ddot(c, fr->f);
  int out = z < -rad || (fr->th * z - x) * fr->ch < -rad || (fr->th * z + x) * fr->ch < -rad ||
            (fr->tv * z - y) * fr->cv < -rad || (fr->tv * z + y) * fr->cv < -rad;
  if (out) p *= fr->out_w;
  /* Behind the planet: two points see each other over the sphere only when their distance is less
   * than the sum of their horizon distances; the node's highest point bounds its own. */
  double rc = oc_dlen(oc_dadd(c, fr->eye)) + rad, R = OC_PLANET_RADIUS;
  double h_node = rc > R ? sqrt(rc * rc - R * R) : 0.0;
  if (d > fr->horizon + h_node) p *= fr->out_w * fr->out_w;
  return p;
}

double ocs_view_priority(const ocs_view_t *v, oc_key_t key, double outside_weight) {
  frustum_t fr = frustum_make(v, outside_weight);
  oc_dvec3 o;
  double s;
  oc_key_bounds(key, &o, &s);
  return prio_box(&fr, o, s);
}

/* Inside the planet (below the lowest source altitude) or wholly above the atmosphere. */
static int geom_excluded(oc_key_t key) {
  double rmin, rmax;
  oc_key_radius_range(key, &rmin, &rmax);
  return rmax < OC_PLANET_RADIUS - 1e4 || rmin > OC_PLANET_RADIUS + OC_ATMOSPHERE_HEIGHT;
}

/*-*** Node pool ***/

static int32_t block_alloc(ocs_planner_t *p) {
  p->placed++;
  if (p->free_block >= 0) {
    int32_t b = p->free_block;
    p->free_block = p->nodes[b].parent;
    return b;
  }
  if (p->count + 8 > p->cap) {
    if (p->cap > INT32_MAX / 2) return OC_ENOMEM;
    int32_t nc = p->cap ? 2 * p->cap : 1024;
    pn_t *n = realloc(p->nodes, (size_t)nc * sizeof *n);
    if (!n) return OC_ENOMEM;
    p->nodes = n;
    p->cap = nc;
  }
  int32_t b = p->count;
  p->count += 8;
  return b;
}

static void block_free(ocs_planner_t *p, int32_t b) {
  for (int i = 0; i < 8; i++) p->nodes[b + i].flags = F_FREE;
  p->nodes[b].parent = p->free_block;
  p->free_block = b;
}

static void tree_reset(ocs_planner_t *p) {
  p->placed = 0;
  p->count = 1;
  p->free_block = -1;
  pn_t *r = &p->nodes[0];
  memset(r, 0, sizeof *r);
  r->key = OC_KEY_ROOT;
  r->parent = -1;
  r->child = -1;
  r->kind = r->skind = OC_NODE_BRICK;
  r->tcost = T_OF(r->kind);
  r->age = AGE_NEW;
  r->topo = p->commits;
}

/*-*** Held states ***/

static void snap_free(snap_t *s) {
  free(s->rec);
  free(s->ids);
  memset(s, 0, sizeof *s);
}

static const snap_rec_t *snap_find(const snap_t *s, oc_key_t key) {
  uint32_t lo = 0, hi = s->n;
  while (lo < hi) {
    uint32_t m = lo + (hi - lo) / 2;
    if (s->rec[m].key < key) lo = m + 1; else hi = m;
  }
  return lo < s->n && s->rec[lo].key == key ? &s->rec[lo] : NULL;
}

static uint64_t union_count(const uint32_t *a, uint32_t na, const uint32_t *b, uint32_t nb) {
  uint64_t n = 0;
  uint32_t i = 0, j = 0;
  while (i < na && j < nb) {
    if (a[i] < b[j]) i++;
    else if (b[j] < a[i]) j++;
    else i++, j++;
    n++;
  }
  return n + (na - i) + (nb - j);
}

/* Records and distinct bricks of held states 0..m-1 (the m newest), in bytes. */
static double held_bytes(const ocs_planner_t *p, int m) {
  double rec = 0.0;
  for (int i = 0; i < m; i++) rec += p->snap[i].n;
  uint64_t b = 0;
  if (m == 1) b = p->snap[0].nids;
  else if (m == 2) b = union_count(p->snap[0].ids, p->snap[0].nids, p->snap[1].ids, p->snap[1].nids);
  else if (m == 3) {
    /* union of three: |A ∪ B| + |C| − |C ∩ (A ∪ B)| counted by a three-way merge */
    const snap_t *A = &p->snap[0], *B = &p->snap[1], *C = &p->snap[2];
    uint32_t i = 0, j = 0, k = 0;
    for (;;) {
      uint32_t x = UINT32_MAX;
      if (i < A->nids && A->ids[i] < x) x = A->ids[i];
      if (j < B->nids && B->ids[j] < x) x = B->ids[j];
      if (k < C->nids && C->ids[k] < x) x = C->ids[k];
      if (i >= A->nids && j >= B->nids && k >= C->nids) break;
      b++;
      if (i < A->nids && A->ids[i] == x) i++;
      if (j < B->nids && B->ids[j] == x) j++;
      if (k < C->nids && C->ids[k] == x) k++;
    }
  }
  return rec * p->d.record_bytes + (double)b * p->d.slot_bytes;
}

uint64_t ocs_plan_resident(const ocs_planner_t *p) { return (uint64_t)held_bytes(p, p->K); }

/*-*** Budget changes ***/

int ocs_plan_fits(const ocs_planner_t *p, uint64_t budget) {
  const snap_t *s = &p->snap[0];
  return (double)p->K * s->n * p->d.record_bytes + (double)s->nids * p->d.slot_bytes <= (double)budget;
}

int ocs_plan_set_budget(ocs_planner_t *p, uint64_t budget) {
  if (!p || budget < ocs_plan_min_budget(&p->d) || (budget < p->d.budget && !ocs_plan_fits(p, budget))) return OC_EINVAL;
  ocs_plan_abandon(p); /* a plan not sent was made under the old budget */
  p->d.budget = budget;
  p->aim = 0;
  return 0;
}

void ocs_plan_aim(ocs_planner_t *p, uint64_t budget) { p->aim = budget < p->d.budget ? budget : 0; }

uint64_t ocs_plan_reserved(const ocs_planner_t *p) {
  uint64_t b = p->d.budget;
  for (int i = 0; i < p->K - 1; i++) /* the window of any later plan: these and new ones */
    if (p->snap[i].rec && p->snap[i].budget > b) b = p->snap[i].budget;
  return b;
}

/*-*** Content and costs ***/

int ocs_plan_ground_tau(oc_key_t key) { return oc_key_level(key) >= OCS_GROUND_TAU_LEVEL && oc_key_meets_ground(key); }

/* Whether the held states may hold a node whose topology changed at commit count `topo`: the
 * binary searches of content_held() are skipped for the rest (most splits and merges). */
static int recent(const ocs_planner_t *p, uint32_t topo) { return (uint64_t)topo + (uint64_t)p->K >= p->commits; }

/* Content of this epoch's stamp that some kept state holds: taken into n. @return 1 if found. */
static int content_held(const ocs_planner_t *p, pn_t *n, int level) {
  uint64_t st = p->in->stamp[level];
  n->stamp = st;
  for (int i = 0; i < p->K - 1; i++) {
    const snap_rec_t *r = snap_find(&p->snap[i], n->key);
    if (r && r->stamp == st) {
      n->kind = r->kind;
      n->skind = r->skind;
      n->tcost = r->tcost;
      n->brick_id = r->brick_id;
      n->age = (uint8_t)(i + 1);
      return 1;
    }
  }
  return 0;
}

static void content_new(ocs_planner_t *p, pn_t *n);


/* New content: its kind from the field's bound (classify), to be produced. */
static void content_new(ocs_planner_t *p, pn_t *n) {
  oc_node_kind_t k = p->in->classify(p->in->ctx, n->key);
  n->skind = (uint8_t)k;
  n->kind = (uint8_t)k;
  if ((k == OC_NODE_UNIFORM && p->in->uniform_is_brick) || (k == OC_NODE_EMPTY && p->in->ground_tau && ocs_plan_ground_tau(n->key)))
    n->kind = OC_NODE_BRICK;
  n->tcost = T_OF(n->kind);
  n->brick_id = 0;
  n->age = AGE_NEW;
}

/* What refreshing a node of `pixels` buys: its pixels times the share of its level's content that
 * one time step changes (ocs_plan_input_t.step_change). */
static double refresh_gain(const ocs_planner_t *p, double pixels, int level) {
  double c = p->in->step_change[level];
  return c > 0 ? pixels * c : pixels;
}


/* A node's content at this epoch's stamp (into n): held already (looked up when `look`), else new,
 * and in clocked plans usable only when it exists and differs from `held` (the stamp the node
 * shows now; 0: none). Existence is asked before the node is classified: classifying costs a field
 * bound, and a split or refresh that waits is tried again every tick. @return 1 usable, 0 waiting
 * (wanted at prio). */
static int new_content(ocs_planner_t *p, pn_t *n, int level, int look, uint64_t held, double prio) {
  if (look && content_held(p, n, level)) return 1;
  n->stamp = p->in->stamp[level];
  if (!p->in->ready) {
    content_new(p, n);
    return 1;
  }
  uint8_t made = OC_NODE_BRICK;
  uint64_t s = p->in->ready(p->in->ctx, n->key, level, n->stamp, held, &made);
  if (!s || s == held) {
    if (p->in->want) p->in->want(p->in->ctx, n->key, n->stamp, prio);
    return 0;
  }
  content_new(p, n); /* the bound's class decides splits (ocs_plan_commit) */
  n->stamp = s;
  if (made <= OC_NODE_BRICK) n->kind = made; /* its cost, as made, and the hard limits' for its refreshes */
  n->tcost = T_OF(n->kind);
  return 1;
}

/* Contribution of a leaf to C_j (j = 0..K-1) and to T. T is what the leaf adds to the C_j in the
 * steady state, with r its level's refresh rate: its content as made (T_MADE) in the held states,
 * in 1 + (K-2)·r of them on average, and in the share r of the epochs that refresh it, the newest
 * state's slot, counted as the hard limits count it before it is made: a brick by the bound's class
 * (T_BOUND). Counted as made instead, a refreshed leaf the bound cannot prove empty raised T by a
 * whole slot only in the epochs that refreshed it, and the tree split and merged by turns. */
static void leaf_cost(const ocs_planner_t *p, const pn_t *n, int level, double c[OCS_PLAN_MAX_KEPT], double *t) {
  const double R = p->d.record_bytes, S = p->d.slot_bytes, r = p->rate[level];
  int brick = n->kind == OC_NODE_BRICK;
  for (int j = 0; j < p->K; j++) c[j] = (1 + j) * R + ((brick && n->age > p->K - 1 - j) ? S : 0.0);
  double made = n->tcost & T_MADE ? 1.0 + (p->K - 2) * r : 0.0, bound = n->tcost & T_BOUND ? r : 0.0;
  *t = p->K * R + S * (made + bound);
}

/* The budget window j counts against (C_j: the K-1-j newest held states and N repeated): the
 * largest its states were planned under, as the viewer counts it (ocp_viewer.c). After a change,
 * a window still holding states of an older, larger budget may use it. */
static double window_budget(const ocs_planner_t *p, int j) {
  uint64_t b = p->d.budget;
  for (int i = 0; i < p->K - 1 - j; i++)
    if (p->snap[i].budget > b) b = p->snap[i].budget;
  return (double)b;
}

static int fits(const ocs_planner_t *p, const double dc[OCS_PLAN_MAX_KEPT]) {
  for (int j = 0; j < p->K; j++)
    if (p->C[j] + dc[j] > window_budget(p, j)) return 0;
  return 1;
}

static int new_brick(const pn_t *n) { return n->kind == OC_NODE_BRICK && n->age == AGE_NEW; }

static int splittable(const ocs_planner_t *p, const pn_t *n, int level) {
  return n->child < 0 && level < p->d.max_depth && n->skind == OC_NODE_BRICK && !(n->flags & (F_NOGEOM | F_MERGED | F_FREE));
}

/*-*** Life cycle ***/

int ocs_planner_create(ocs_planner_t **out, const ocs_plan_desc_t *d) {
  if (!out || !d) return OC_EINVAL;
  *out = NULL;
  ocs_plan_desc_t c = *d;
  if (ocs_plan_clamp(&c, d->budget) < 0 || c.budget != d->budget) return OC_EINVAL;
  ocs_planner_t *p = calloc(1, sizeof *p);
  if (!p) return OC_ENOMEM;
  p->d = c;
  p->K = c.kept_states;
  p->cap = 1024;
  p->nodes = malloc((size_t)p->cap * sizeof *p->nodes);
  if (!p->nodes) {
    free(p);
    return OC_ENOMEM;
  }
  p->split_h.max = 1;
  tree_reset(p);
  *out = p;
  return 0;
}

void ocs_planner_free(ocs_planner_t *p) {
  if (!p) return;
  for (int i = 0; i < OCS_PLAN_MAX_KEPT; i++) snap_free(&p->snap[i]);
  free(p->nodes);
  free(p->split_h.a);
  free(p->merge_h.a);
  free(p->out);
  free(p->out_node);
  free(p);
}

const ocs_plan_desc_t *ocs_planner_desc(const ocs_planner_t *p) { return &p->d; }

/* Lays the pool out in the order the walks visit it: each node's child block follows, in memory,
 * the blocks of its elder siblings' subtrees. Splits and merges scatter blocks over the pool; once
 * enough have moved, a walk of a million nodes is bound by cache misses, and one copy in walk order
 * makes the next walks nearly sequential. @return 0 or OC_ENOMEM (the pool is left as it was). */
static int compact(ocs_planner_t *p) {
  int32_t used = p->count;
  for (int32_t b = p->free_block; b >= 0; b = p->nodes[b].parent) used -= 8;
  pn_t *nn = malloc((size_t)(used > 0 ? used : 1) * sizeof *nn);
  if (!nn) return OC_ENOMEM;
  typedef struct { int32_t old, new_; } pair_t;
  pair_t stack[8 * (OC_KEY_MAX_LEVEL + 1) + 8];
  int sp = 0;
  nn[0] = p->nodes[0];
  int32_t next = 1;
  stack[sp++] = (pair_t){0, 0};
  while (sp) {
    pair_t e = stack[--sp];
    int32_t oc = p->nodes[e.old].child;
    if (oc < 0) continue;
    int32_t b = next;
    next += 8;
    nn[e.new_].child = b;
    for (int c = 0; c < 8; c++) {
      nn[b + c] = p->nodes[oc + c];
      nn[b + c].parent = e.new_;
    }
    for (int c = 7; c >= 0; c--) stack[sp++] = (pair_t){oc + c, b + c};
  }
  free(p->nodes);
  p->nodes = nn;
  p->count = p->cap = next;
  p->free_block = -1;
  p->placed = 0;
  return 0;
}

/*-*** Planning ***/

typedef struct {
  int32_t idx;
  int32_t x, y, z; /* cell coordinates at the node's level */
  int level;
} walk_t;

/* Splits leaf `i` into children whose content was worked out already (kids[]). */
static int do_split(ocs_planner_t *p, int32_t i, const pn_t kids[8], const frustum_t *fr) {
  int32_t b = block_alloc(p);
  if (b < 0) return b;
  pn_t *n = &p->nodes[i];
  n->child = b;
  n->flags |= F_SPLIT;
  n->topo = p->commits;
  for (int c = 0; c < 8; c++) {
    pn_t *ch = &p->nodes[b + c];
    *ch = kids[c];
    ch->parent = i;
    ch->child = -1;
    oc_dvec3 o;
    double s;
    oc_key_bounds(ch->key, &o, &s);
    ch->prio = (float)prio_box(fr, o, s);
    ch->flags = geom_excluded(ch->key) ? F_NOGEOM : 0;
  }
  return b;
}

static int children_are_leaves(const ocs_planner_t *p, const pn_t *n) {
  if (n->child < 0) return 0;
  for (int c = 0; c < 8; c++)
    if (p->nodes[n->child + c].child >= 0) return 0;
  return 1;
}

static void apply_delta(ocs_planner_t *p, const double dc[OCS_PLAN_MAX_KEPT], double dt) {
  for (int j = 0; j < p->K; j++) p->C[j] += dc[j];
  p->T += dt;
}

/* Cost change of merging internal node m (children leaves) into a leaf with content `pc`. */
static void merge_delta(ocs_planner_t *p, int32_t m, const pn_t *pc, int level, double dc[OCS_PLAN_MAX_KEPT], double *dt,
                        int *dnew) {
  double c[OCS_PLAN_MAX_KEPT], t;
  leaf_cost(p, pc, level, dc, dt);
  *dnew = new_brick(pc);
  for (int k = 0; k < 8; k++) {
    const pn_t *ch = &p->nodes[p->nodes[m].child + k];
    leaf_cost(p, ch, level + 1, c, &t);
    for (int j = 0; j < p->K; j++) dc[j] -= c[j];
    *dt -= t;
    *dnew -= new_brick(ch);
  }
}

static int new_ok(const ocs_planner_t *p, int dnew) {
  return !p->in->max_new_bricks || dnew <= 0 || p->new_bricks + (uint32_t)dnew <= p->in->max_new_bricks;
}

/* Tries to merge the cheapest valid candidate (other than `keep`); @return 1 merged, 0 none left
 * with priority below `limit`, -1 a candidate was dropped (try again). */
static int try_merge(ocs_planner_t *p, double limit, int32_t keep, ocs_plan_stats_t *st) {
  while (p->merge_h.n) {
    hent_t e = p->merge_h.a[0];
    pn_t *m = &p->nodes[e.idx];
    if (m->key != e.key || (m->flags & (F_FREE | F_SPLIT)) || !children_are_leaves(p, m) || m->prio != e.prio) {
      h_pop(&p->merge_h);
      continue;
    }
    if (!(e.prio < limit)) return 0;
    h_pop(&p->merge_h);
    if (e.idx == keep) return -1;
    int level = oc_key_level(m->key);
    pn_t pc = *m;
    if (!new_content(p, &pc, level, recent(p, m->topo), 0, m->prio)) return -1; /* not until the parent's content exists */
    pc.topo = p->commits;
    double dc[OCS_PLAN_MAX_KEPT], dt;
    int dnew;
    merge_delta(p, e.idx, &pc, level, dc, &dt, &dnew);
    if (!(dt < 0.0) || !fits(p, dc) || !new_ok(p, dnew)) return -1; /* cannot help now */
    apply_delta(p, dc, dt);
    p->new_bricks += dnew;
    int32_t b = m->child;
    pc.child = -1;
    pc.flags = (uint8_t)((m->flags & F_NOGEOM) | F_MERGED);
    *m = pc;
    block_free(p, b);
    st->merges++;
    /* the parent may now be mergeable */
    if (m->parent >= 0) {
      pn_t *pp = &p->nodes[m->parent];
      if (!(pp->flags & F_SPLIT) && children_are_leaves(p, pp)) {
        int rc = h_push(&p->merge_h, (hent_t){m->parent, pp->prio, pp->key});
        if (rc < 0) return rc;
      }
    }
    return 1;
  }
  return 0;
}

static int cmp_prio_desc(const void *a, const void *b) {
  const hent_t *x = a, *y = b;
  if (x->prio != y->prio) return x->prio > y->prio ? -1 : 1;
  return x->key < y->key ? -1 : (x->key > y->key);
}

/* An error once passes 2-3 have changed the tree (refreshes, splits, merges) must not leave a
 * half-applied tree: rebuild the last committed one from the newest held state, as
 * ocs_plan_abandon() does ("OC_ENOMEM: the previous tree is kept"). */
static int epoch_fail(ocs_planner_t *p, int rc) {
  p->pending = 1;
  ocs_plan_abandon(p);
  return rc;
}

/* Epoch set-up: the input, the per-level cost factor of content that is refreshed. */
static void epoch_begin(ocs_planner_t *p, const ocs_plan_input_t *in) {
  if (p->pending) ocs_plan_abandon(p);
  if ((int64_t)p->placed * 8 > p->count / 16 && p->count > 4096) compact(p); /* best effort */
  p->in = in;
  p->gated = in->ready != NULL;
  p->new_bricks = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    double r = in->refresh_rate[l];
    p->rate[l] = r > 0.0 ? (r < 1.0 ? r : 1.0) : 0.0;
  }
}

/* Pass 1: priorities, costs, candidates; a stack walk carrying exact integer coordinates. Leaves
 * at or below min_pixels can never be split this epoch: they stay out of the heap. Stale leaves
 * go to `refresh` (a list, not yet a heap). */
static int plan_walk(ocs_planner_t *p, const frustum_t *fr, heap_t *refresh) {
  const int K = p->K;
  double size[OC_KEY_MAX_LEVEL + 1];
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) size[l] = oc_key_size(l);
  for (int j = 0; j < K; j++) p->C[j] = held_bytes(p, K - 1 - j);
  p->T = 0.0;
  p->split_h.n = p->merge_h.n = 0;
  walk_t stack[8 * (OC_KEY_MAX_LEVEL + 1) + 8];
  int sp = 0, rc;
  stack[sp++] = (walk_t){0, 0, 0, 0, 0};
  while (sp) {
    walk_t w = stack[--sp];
    pn_t *n = &p->nodes[w.idx];
    n->flags &= (uint8_t)~(F_SPLIT | F_MERGED | F_REFRESH);
    double s = size[w.level];
    oc_dvec3 o = oc_dv3(-OC_ROOT_HALF + w.x * s, -OC_ROOT_HALF + w.y * s, -OC_ROOT_HALF + w.z * s);
    n->prio = (float)prio_box(fr, o, s);
    hent_t e = {w.idx, n->prio, n->key};
    if (n->child >= 0) {
      if (children_are_leaves(p, n) && (rc = h_append(&p->merge_h, e)) < 0) return rc;
      for (int c = 7; c >= 0; c--)
        stack[sp++] = (walk_t){n->child + c, 2 * w.x + (c & 1), 2 * w.y + ((c >> 1) & 1), 2 * w.z + ((c >> 2) & 1), w.level + 1};
      continue;
    }
    double c[OCS_PLAN_MAX_KEPT], t;
    leaf_cost(p, n, w.level, c, &t);
    for (int j = 0; j < K; j++) p->C[j] += c[j];
    p->T += t;
    if (new_brick(n)) p->new_bricks++;
    if ((n->stamp != p->in->stamp[w.level] || n->age == AGE_NEW) && (rc = h_append(refresh, e)) < 0) return rc;
    if (n->prio > p->d.min_pixels && splittable(p, n, w.level) && (rc = h_append(&p->split_h, e)) < 0) return rc;
  }
  h_heapify(&p->split_h);
  h_heapify(&p->merge_h);
  return 0;
}

/* Pass 2: refresh stale content, nearest first, while the hard limits allow. */
static int plan_refresh(ocs_planner_t *p, hent_t *refresh, size_t nrefresh, ocs_plan_stats_t *st) {
  /* qsort(NULL, 0, ...) is undefined: static epochs have nothing stale */
  if (nrefresh) qsort(refresh, nrefresh, sizeof *refresh, cmp_prio_desc);
  for (size_t i = 0; i < nrefresh; i++) {
    pn_t *n = &p->nodes[refresh[i].idx];
    int level = oc_key_level(n->key);
    pn_t nc = *n;
    if (!new_content(p, &nc, level, 1, n->age == AGE_NEW ? 0 : n->stamp, n->age == AGE_NEW ? n->prio : refresh_gain(p, n->prio, level))) {
      if (n->age == AGE_NEW) return OC_EAGAIN; /* a leaf with nothing to show (the first root): no plan yet */
      st->deferred++;
      continue;
    }
    if (n->age != AGE_NEW && !p->gated) { /* made after the plan: counted and split as last made until then */
      nc.tcost = (uint8_t)((nc.tcost & ~T_MADE) | (n->tcost & T_MADE));
      if (n->skind != OC_NODE_BRICK && nc.skind == OC_NODE_BRICK) nc.skind = n->skind, nc.flags |= F_SKIND;
    }
    double c0[OCS_PLAN_MAX_KEPT], c1[OCS_PLAN_MAX_KEPT], t0c, t1c;
    leaf_cost(p, n, level, c0, &t0c);
    leaf_cost(p, &nc, level, c1, &t1c);
    for (int j = 0; j < p->K; j++) c1[j] -= c0[j];
    int dnew = new_brick(&nc) - new_brick(n);
    if (n->age != AGE_NEW && !(fits(p, c1) && new_ok(p, dnew))) {
      st->deferred++;
      continue;
    }
    apply_delta(p, c1, t1c - t0c);
    p->new_bricks += dnew;
    int was_new = n->age == AGE_NEW;
    nc.flags = (uint8_t)(n->flags | (was_new ? 0 : F_REFRESH));
    nc.prio = n->prio;
    *n = nc;
    if (!was_new) st->refreshed++;
    /* a refresh can change the σt class: re-queue if it became splittable */
    int rc;
    if (splittable(p, n, level) && (rc = h_push(&p->split_h, (hent_t){refresh[i].idx, n->prio, n->key})) < 0) return rc;
  }
  return 0;
}

/* kids[] := the content of n's 8 children; @return 1 when all 8 exist. */
static int make_kids(ocs_planner_t *p, const pn_t *n, int level, float prio, pn_t kids[8]) {
  int all = 1;
  for (int k = 0; k < 8; k++) {
    memset(&kids[k], 0, sizeof kids[k]);
    kids[k].key = oc_key_child(n->key, k);
    all &= new_content(p, &kids[k], level + 1, recent(p, n->topo), 0, prio);
    kids[k].topo = n->topo; /* their children can be held only if n was internal lately */
  }
  return all;
}

/* Cost change of splitting leaf n into kids[], children content included. */
static void split_delta(const ocs_planner_t *p, const pn_t *n, int level, const pn_t kids[8], double dc[OCS_PLAN_MAX_KEPT],
                        double *dt, int *dnew) {
  double c[OCS_PLAN_MAX_KEPT], t;
  leaf_cost(p, n, level, c, &t);
  for (int j = 0; j < p->K; j++) dc[j] = -c[j];
  *dt = -t;
  *dnew = -new_brick(n);
  for (int k = 0; k < 8; k++) {
    leaf_cost(p, &kids[k], level + 1, c, &t);
    for (int j = 0; j < p->K; j++) dc[j] += c[j];
    *dt += t;
    *dnew += new_brick(&kids[k]);
  }
}

/* Splits leaf s (its children content in kids[]) and queues its splittable children. */
static int apply_split(ocs_planner_t *p, hent_t s, const pn_t kids[8], const frustum_t *fr, const double dc[OCS_PLAN_MAX_KEPT],
                       double dt, int dnew) {
  h_pop(&p->split_h);
  int32_t b = do_split(p, s.idx, kids, fr);
  if (b < 0) return b;
  apply_delta(p, dc, dt);
  p->new_bricks += dnew;
  int level = oc_key_level(s.key);
  for (int k = 0; k < 8; k++) {
    pn_t *ch = &p->nodes[b + k];
    int rc;
    if (splittable(p, ch, level + 1) && (rc = h_push(&p->split_h, (hent_t){b + k, ch->prio, ch->key})) < 0) return rc;
  }
  return 0;
}

/* Pass 3: Pettersson's split/merge loop; st->stop says why it stopped. */
static int plan_split_merge(ocs_planner_t *p, const frustum_t *fr, ocs_plan_stats_t *st) {
  p->target = (1.0 - p->d.reserve) * (double)(p->aim && p->aim < p->d.budget ? p->aim : p->d.budget);
  double capacity = (double)p->d.budget / ((double)p->d.slot_bytes + p->K * (double)p->d.record_bytes);
  double max_new_nodes = fmax(8.0, p->d.split_fraction * capacity * (p->in->split_scale > 1.0 ? p->in->split_scale : 1.0));
  double created = 0.0;
  pn_t kids[8];
  oc_key_t kids_of = OC_KEY_INVALID; /* kids[] holds this node's children content */
  for (;;) {
    if (p->T > p->target) { /* over the steady target (budget lowered, content grew): merge */
      int r = try_merge(p, INFINITY, -1, st);
      if (r < 0 && r != -1) return r;
      if (r == 0) { st->stop = "over target, nothing mergeable"; return 0; }
      continue;
    }
    if (!p->split_h.n) { st->stop = "converged (no splittable leaf above min_pixels)"; return 0; }
    hent_t s = p->split_h.a[0];
    pn_t *n = &p->nodes[s.idx];
    int level = oc_key_level(s.key);
    if (n->key != s.key || !splittable(p, n, level)) {
      h_pop(&p->split_h);
      continue;
    }
    if (!(s.prio > p->d.min_pixels)) { st->stop = "converged (voxels below min_pixels)"; return 0; }
    if (created + 8 > max_new_nodes) { st->stop = "split cap"; return 0; }
    if (kids_of != n->key) { /* a retry after a merge reuses it */
      kids_of = n->key;
      if (!make_kids(p, n, level, s.prio, kids)) { /* a split comes with its 8 children or waits for them */
        h_pop(&p->split_h);
        st->split_backlog++;
        kids_of = OC_KEY_INVALID;
        /* Past eight times the splits an epoch may make, further waiting splits are left for later
         * ticks: each costs 8 looks into the brick cache, and behind a teleport or a budget that
         * grew faster than production, tens of thousands wait (their children are wished by the
         * target plans meanwhile). Fewer, and a teleport's ready splits further down were not
         * reached: 2× took 12-15 ticks to full detail at 4 MiB where the stepped server needs 10. */
        if (st->split_backlog > 8 * max_new_nodes / 8) { st->stop = "split backlog (children not made yet)"; return 0; }
        continue;
      }
    }
    double dc[OCS_PLAN_MAX_KEPT], dt;
    int dnew;
    split_delta(p, n, level, kids, dc, &dt, &dnew);
    if (!fits(p, dc) || !new_ok(p, dnew)) { st->stop = "epoch change limit (held states, throughput)"; return 0; }
    if (p->T + dt <= p->target) {
      int rc = apply_split(p, s, kids, fr, dc, dt, dnew);
      if (rc < 0) return rc;
      created += 8;
      st->splits++;
      continue;
    }
    int r = try_merge(p, s.prio, n->parent, st);
    if (r == 0) { st->stop = "balanced (cheapest merge outweighs best split)"; return 0; }
    if (r < -1) return r;
  }
}

/* Output: leaves in canonical order (level, then Morton: a walk in child order per level). A
 * target plan also wishes every new content it holds. */
static int plan_output(ocs_planner_t *p, ocs_plan_stats_t *st) {
  const ocs_plan_input_t *in = p->in;
  uint32_t per_level[OC_KEY_MAX_LEVEL + 2] = {0};
  uint32_t nleaves = 0;
  for (int32_t i = 0; i < p->count; i++) {
    const pn_t *n = &p->nodes[i];
    if (!(n->flags & F_FREE) && n->child < 0) per_level[oc_key_level(n->key) + 1]++, nleaves++;
  }
  if (nleaves > p->out_cap) {
    ocs_plan_leaf_t *o = realloc(p->out, nleaves * sizeof *o);
    if (o) p->out = o;
    int32_t *on = o ? realloc(p->out_node, nleaves * sizeof *on) : NULL;
    if (!on) return OC_ENOMEM;
    p->out_node = on;
    p->out_cap = nleaves;
  }
  for (int l = 1; l <= OC_KEY_MAX_LEVEL + 1; l++) per_level[l] += per_level[l - 1];
  int32_t stack[8 * (OC_KEY_MAX_LEVEL + 1) + 8];
  int sp = 0;
  stack[sp++] = 0;
  while (sp) {
    int32_t i = stack[--sp];
    const pn_t *n = &p->nodes[i];
    /* a target plan: every new content it holds, inner nodes too, since a clocked tick can show
     * a node's children only once it shows the node */
    if (!in->ready && in->want && n->age == AGE_NEW)
      in->want(in->ctx, n->key, n->stamp, n->flags & F_REFRESH ? refresh_gain(p, n->prio, oc_key_level(n->key)) : n->prio);
    if (n->child >= 0) {
      for (int c = 7; c >= 0; c--) stack[sp++] = n->child + c;
      continue;
    }
    int level = oc_key_level(n->key);
    uint32_t k = per_level[level]++;
    ocs_plan_leaf_t *o = &p->out[k];
    o->key = n->key;
    o->stamp = n->stamp;
    o->kind = n->kind;
    o->produce = n->age == AGE_NEW;
    o->held = o->produce ? 0 : n->age;
    o->brick_id = o->produce ? 0 : n->brick_id;
    p->out_node[k] = i;
    if ((uint32_t)level > st->max_level) st->max_level = (uint32_t)level;
  }
  p->out_n = nleaves;
  return 0;
}

int ocs_plan_epoch(ocs_planner_t *p, const ocs_view_t *view, const ocs_plan_input_t *in,
                   const ocs_plan_leaf_t **leaves, uint32_t *count, ocs_plan_stats_t *stats) {
  if (!p || !in || !in->classify || !leaves || !count || !ocs_view_valid(view)) return OC_EINVAL;
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  ocs_plan_stats_t st;
  memset(&st, 0, sizeof st);
  epoch_begin(p, in);
  frustum_t fr = frustum_make(view, p->d.outside_weight);
  heap_t refresh = {0};
  int rc = plan_walk(p, &fr, &refresh); /* an error here has changed no tree: nothing to undo */
  if (rc < 0) {
    free(refresh.a);
    return rc;
  }
  rc = plan_refresh(p, refresh.a, refresh.n, &st);
  free(refresh.a);
  if (rc >= 0) rc = plan_split_merge(p, &fr, &st);
  if (rc >= 0) rc = plan_output(p, &st);
  if (rc < 0) return epoch_fail(p, rc);
  p->pending = 1;
  *leaves = p->out;
  *count = p->out_n;
  st.leaves = p->out_n;
  st.new_bricks = p->new_bricks;
  st.predicted_bytes = (uint64_t)p->C[0];
  st.steady_bytes = (uint64_t)p->T;
  clock_gettime(CLOCK_MONOTONIC, &t1);
  st.seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
  if (stats) *stats = st;
  return 0;
}

/*-*** Commit and abandon ***/

/* LSD radix sort, 4 passes of 8 bits: a million ids in a few ms where qsort took tens. */
static int sort_ids(uint32_t *a, uint32_t n) {
  if (n < 2) return 0;
  uint32_t *t = malloc(n * sizeof *t);
  if (!t) return OC_ENOMEM;
  uint32_t *src = a, *dst = t;
  for (int shift = 0; shift < 32; shift += 8) {
    uint32_t cnt[257] = {0};
    for (uint32_t i = 0; i < n; i++) cnt[((src[i] >> shift) & 255) + 1]++;
    for (int b = 0; b < 256; b++) cnt[b + 1] += cnt[b];
    for (uint32_t i = 0; i < n; i++) dst[cnt[(src[i] >> shift) & 255]++] = src[i];
    uint32_t *x = src;
    src = dst;
    dst = x;
  }
  free(t); /* four passes: the sorted data is back in a */
  return 0;
}

int ocs_plan_commit(ocs_planner_t *p, const uint8_t *kind, const uint32_t *brick_id) {
  if (!p || !p->pending || !kind || !brick_id) return OC_EINVAL;
  snap_t s = {0};
  s.rec = malloc((p->out_n ? p->out_n : 1) * sizeof *s.rec);
  s.ids = malloc((p->out_n ? p->out_n : 1) * sizeof *s.ids);
  if (!s.rec || !s.ids) {
    snap_free(&s);
    return OC_ENOMEM;
  }
  for (uint32_t i = 0; i < p->out_n; i++) {
    pn_t *n = &p->nodes[p->out_node[i]];
    uint8_t k = kind[i] <= OC_NODE_BRICK ? kind[i] : OC_NODE_BRICK;
    uint32_t id = k == OC_NODE_BRICK ? brick_id[i] : 0;
    /* Stepped, a leaf's content is made after the epoch's splits: an empty or uniform one is known
     * so and stays a leaf. Clocked, content is shown first and split later: a coarse node's box
     * average can round to empty while finer levels hold cloud, so the bound's class stays. */
    if (k != OC_NODE_BRICK && !p->gated) n->skind = k;
    if (k == OC_NODE_BRICK && (n->flags & F_SKIND)) n->skind = OC_NODE_BRICK; /* made one: the bound's class */
    n->flags &= (uint8_t)~F_SKIND;
    /* clocked, a refresh is counted as made (ready()); stepped, by the bound's class (leaf_cost) */
    n->tcost = p->gated ? T_OF(k) : (uint8_t)((n->tcost & T_BOUND) | (T_OF(k) & T_MADE));
    s.rec[i] = (snap_rec_t){n->key, n->stamp, id, k, n->skind, n->tcost};
    if (id) s.ids[s.nids++] = id;
    n->kind = k;
    n->brick_id = id;
    n->age = 1;
  }
  s.n = p->out_n;
  if (sort_ids(s.ids, s.nids) < 0) {
    snap_free(&s);
    return OC_ENOMEM;
  }
  snap_free(&p->snap[p->K - 1]);
  memmove(&p->snap[1], &p->snap[0], (size_t)(p->K - 1) * sizeof p->snap[0]);
  s.budget = p->d.budget;
  p->snap[0] = s;
  p->pending = 0;
  p->commits++;
  return 0;
}

/* Rebuilds the tree from the newest held state (its leaves are a complete partition). */
void ocs_plan_abandon(ocs_planner_t *p) {
  if (!p || !p->pending) return;
  p->pending = 0;
  tree_reset(p);
  const snap_t *s = &p->snap[0];
  for (uint32_t i = 0; i < s->n; i++) {
    oc_key_t key = s->rec[i].key;
    int level = oc_key_level(key);
    int32_t idx = 0;
    for (int l = 1; l <= level; l++) {
      pn_t *n = &p->nodes[idx];
      if (n->child < 0) {
        int32_t b = block_alloc(p);
        if (b < 0) { /* out of memory: fall back to the root alone */
          tree_reset(p);
          return;
        }
        n = &p->nodes[idx];
        n->child = b;
        for (int c = 0; c < 8; c++) {
          pn_t *ch = &p->nodes[b + c];
          memset(ch, 0, sizeof *ch);
          ch->key = oc_key_child(n->key, c);
          ch->parent = idx;
          ch->child = -1;
          ch->topo = p->commits; /* history unknown: look everything up */
        }
      }
      oc_key_t a = oc_key_ancestor(key, l);
      idx = n->child + (int32_t)(a & 7);
    }
    pn_t *n = &p->nodes[idx];
    n->stamp = s->rec[i].stamp;
    n->brick_id = s->rec[i].brick_id;
    n->kind = s->rec[i].kind;
    n->skind = s->rec[i].skind;
    n->tcost = s->rec[i].tcost;
    n->age = 1;
    n->flags = geom_excluded(key) ? F_NOGEOM : 0;
  }
}
