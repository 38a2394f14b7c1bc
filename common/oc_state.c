/* oc_state.c — the state: construction, canonical order, validation, look-ups, resident bytes
 * (oc_state.h). Serialisation is in oc_state_io.c. */
#include "oc_state.h"

#include <inttypes.h> /* PRIx64 */
#include <math.h>     /* isfinite, signbit, fabs */
#include <stdarg.h>
#include <stdio.h>  /* vsnprintf */
#include <stdlib.h> /* malloc, qsort */
#include <string.h> /* memcpy */

#include "oc_err.h" /* OC_E* */

/*-*** Construction ***/

void oc_state_init(oc_state_t *s) {
  if (!s) return;
  memset(s, 0, sizeof *s);
  /* A usable default: adding a root node to a fresh state gives a valid state. */
  s->sun_dir = oc_dv3(0.0, 0.0, 1.0);
}

void oc_state_clear(oc_state_t *s) {
  if (!s) return;
  oc_node_t *nodes = s->nodes;
  oc_brick_t *bricks = s->bricks;
  uint32_t ncap = s->node_cap, bcap = s->brick_cap;
  oc_state_init(s);
  s->nodes = nodes, s->node_cap = ncap;
  s->bricks = bricks, s->brick_cap = bcap;
}

void oc_state_free(oc_state_t *s) {
  if (!s) return;
  free(s->nodes);
  free(s->bricks);
  oc_state_init(s);
}

/* Grows an array of `size`-byte elements to hold one more (doubling, from 16). */
static int oc__grow(void **arr, uint32_t count, uint32_t *cap, size_t size) {
  if (count < *cap) return 0;
  if (count == UINT32_MAX) return OC_ENOMEM;
  uint64_t ncap = *cap ? (uint64_t)*cap * 2 : 16;
  if (ncap > UINT32_MAX) ncap = UINT32_MAX;
  if (ncap > SIZE_MAX / size) return OC_ENOMEM;
  void *p = realloc(*arr, (size_t)ncap * size);
  if (!p) return OC_ENOMEM;
  *arr = p;
  *cap = (uint32_t)ncap;
  return 0;
}

int oc_state_add_node(oc_state_t *s, const oc_node_t *n) {
  if (!s || !n) return OC_EINVAL;
  OC_TRY(oc__grow((void **)&s->nodes, s->node_count, &s->node_cap, sizeof *s->nodes));
  s->nodes[s->node_count++] = *n;
  return 0;
}

int oc_state_add_brick(oc_state_t *s, uint32_t id, const oc_brick_codes_t *codes) {
  if (!s || !codes) return OC_EINVAL;
  OC_TRY(oc__grow((void **)&s->bricks, s->brick_count, &s->brick_cap, sizeof *s->bricks));
  oc_brick_t *b = &s->bricks[s->brick_count++];
  b->id = id;
  b->codes = *codes;
  return 0;
}

static int oc__cmp_node(const void *a, const void *b) {
  oc_key_t x = ((const oc_node_t *)a)->key, y = ((const oc_node_t *)b)->key;
  return (x > y) - (x < y);
}

static int oc__cmp_brick(const void *a, const void *b) {
  uint32_t x = ((const oc_brick_t *)a)->id, y = ((const oc_brick_t *)b)->id;
  return (x > y) - (x < y);
}

void oc_state_canonicalize(oc_state_t *s) {
  if (!s) return;
  if (s->node_count > 1) qsort(s->nodes, s->node_count, sizeof *s->nodes, oc__cmp_node);
  if (s->brick_count > 1) qsort(s->bricks, s->brick_count, sizeof *s->bricks, oc__cmp_brick);
}

int oc_state_copy(oc_state_t *dst, const oc_state_t *src) {
  if (!dst || !src) return OC_EINVAL;
  if (dst == src) return 0;
  oc_node_t *nodes = NULL;
  oc_brick_t *bricks = NULL;
  /* Allocate both first, so a failure leaves dst untouched. */
  if (src->node_count) {
    nodes = malloc((size_t)src->node_count * sizeof *nodes);
    if (!nodes) return OC_ENOMEM;
    memcpy(nodes, src->nodes, (size_t)src->node_count * sizeof *nodes);
  }
  if (src->brick_count) {
    bricks = malloc((size_t)src->brick_count * sizeof *bricks);
    if (!bricks) {
      free(nodes);
      return OC_ENOMEM;
    }
    memcpy(bricks, src->bricks, (size_t)src->brick_count * sizeof *bricks);
  }
  oc_state_free(dst);
  dst->epoch = src->epoch;
  dst->time = src->time;
  dst->sun_dir = src->sun_dir;
  dst->nodes = nodes;
  dst->node_count = dst->node_cap = src->node_count;
  dst->bricks = bricks;
  dst->brick_count = dst->brick_cap = src->brick_count;
  return 0;
}

/*-*** Validation ***/


/* Level of a key already known to be valid: the sentinel sits at bit 3L. */
static int oc__level(oc_key_t k) { return (63 - __builtin_clzll(k)) / 3; }

static bool oc__key_ok(oc_key_t k) {
  if (k == 0) return false;
  int top = 63 - __builtin_clzll(k);
  return top % 3 == 0 && top / 3 <= OC_KEY_MAX_LEVEL;
}

/* Why a channel range is malformed, or NULL. Canonical too: −0 would serialise differently from
 * +0 for the same content, so it is rejected like any negative. */
static const char *oc__range_error(oc_range_t r) {
  if (!isfinite(r.lo) || !isfinite(r.hi)) return "is not finite";
  if (signbit(r.lo) || signbit(r.hi)) return "is negative";
  if (r.lo > r.hi) return "has lo > hi";
  if (r.lo == 0.0f && r.hi != 0.0f) return "has lo = 0 < hi";
  if (r.hi > OC_VALUE_MAX) return "exceeds OC_VALUE_MAX";
  /* The encoder flushes below hi/1e9, so hi/lo ≤ 1e9 up to float rounding of the threshold. */
  if ((double)r.hi > (double)r.lo * OC_CODE_MAX_RATIO * (1.0 + 1e-6)) return "has hi/lo above OC_CODE_MAX_RATIO";
  return NULL;
}

static const char *oc__kind_name(int kind) {
  return kind == OC_NODE_EMPTY ? "empty" : kind == OC_NODE_UNIFORM ? "uniform" : kind == OC_NODE_BRICK ? "brick" : "?";
}

/* Per-record checks: kind, ranges consistent with it, brick id only on bricks. */
static int oc__check_node(const oc_node_t *n, uint32_t i, char *why, size_t why_len) {
  static const char *ch_name[OC_CHANNELS] = {"sigma", "tau"};
  if (n->kind > OC_NODE_BRICK)
    return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): bad kind %u", i, n->key, (unsigned)n->kind);
  for (int c = 0; c < OC_CHANNELS; c++) {
    const char *e = oc__range_error(n->range[c]);
    if (e)
      return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): %s range [%g, %g] %s", i, n->key,
                      ch_name[c], (double)n->range[c].lo, (double)n->range[c].hi, e);
  }
  bool zero = n->range[0].hi == 0.0f && n->range[1].hi == 0.0f;
  switch (n->kind) {
    case OC_NODE_EMPTY:
      if (!zero) return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): empty node with non-zero range", i, n->key);
      break;
    case OC_NODE_UNIFORM:
      for (int c = 0; c < OC_CHANNELS; c++)
        if (n->range[c].lo != n->range[c].hi)
          return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): uniform node with %s lo != hi", i, n->key,
                          ch_name[c]);
      /* fall through */
    default:
      if (zero)
        return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): %s node with both channels zero (must be empty)",
                        i, n->key, oc__kind_name(n->kind));
  }
  if (n->kind != OC_NODE_BRICK && n->brick_id != 0)
    return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): %s node with brick id %" PRIu32, i, n->key,
                    oc__kind_name(n->kind), n->brick_id);
  return 0;
}

/* Exact partition check, O(21·n), no allocation.
 *  Octree cells either nest or are disjoint, so leaves with no ancestor among them are pairwise
 *  disjoint; disjoint cells whose volumes (in level-21 cells, 2^(3(21−L)) each) sum to 2^63, the
 *  root's, then cover it exactly.
 *  Ancestors: keys ascend with level (a level-L key lies in [8^L, 2·8^L)), so sorted records form
 *  one contiguous block per level, and within the level-L block the ancestors at level l,
 *  key >> 3(L−l), are non-decreasing: one merge-walk per pair of levels finds any ancestor. */
static int oc__check_partition(const oc_state_t *s, char *why, size_t why_len) {
  uint32_t first[OC_KEY_MAX_LEVEL + 1], count[OC_KEY_MAX_LEVEL + 1] = {0};
  uint64_t volume = 0;
  for (uint32_t i = 0; i < s->node_count; i++) {
    int L = oc__level(s->nodes[i].key);
    if (!count[L]) first[L] = i;
    count[L]++;
  }
  for (int L = 1; L <= OC_KEY_MAX_LEVEL; L++) {
    if (!count[L]) continue;
    for (int l = 0; l < L; l++) {
      if (!count[l]) continue;
      uint32_t p = first[l], end = first[l] + count[l];
      int shift = 3 * (L - l);
      for (uint32_t i = first[L]; i < first[L] + count[L]; i++) {
        oc_key_t a = s->nodes[i].key >> shift;
        while (p < end && s->nodes[p].key < a) p++;
        if (p == end) break;
        if (s->nodes[p].key == a)
          return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 ") overlaps its ancestor, node %" PRIu32 " (key 0x%" PRIx64 ")",
                          i, s->nodes[i].key, p, a);
      }
    }
  }
  /* Disjoint now, so the sum cannot exceed 2^63 (no overflow). */
  for (int L = 0; L <= OC_KEY_MAX_LEVEL; L++) volume += (uint64_t)count[L] << (3 * (OC_KEY_MAX_LEVEL - L));
  if (volume != (uint64_t)1 << 63)
    return oc_errorf(OC_ECORRUPT, why, why_len, "leaves leave a gap: they cover %" PRIu64 " of 2^63 level-21 cells", volume);
  return 0;
}

/* Brick ids as a strided array: the id field of oc_brick_t (full states) or a plain uint32_t
 * list (lean states), so one check and one merge serve both. */
typedef struct {
  const uint8_t *p;
  size_t stride;
  uint32_t n;
} oc__ids_t;

static uint32_t oc__id_at(const oc__ids_t *v, uint32_t k) { return *(const uint32_t *)(const void *)(v->p + (size_t)k * v->stride); }

static oc__ids_t oc__ids_full(const oc_state_t *s) {
  oc__ids_t v = {NULL, sizeof(oc_brick_t), s->brick_count};
  if (s->bricks) v.p = (const uint8_t *)s->bricks + offsetof(oc_brick_t, id);
  return v;
}

static oc__ids_t oc__ids_lean(const oc_brick_digests_t *b) {
  return (oc__ids_t){(const uint8_t *)b->ids, sizeof *b->ids, b->count};
}

int64_t oc_ids_find(const void *first, size_t stride, uint32_t n, uint32_t id) {
  oc__ids_t v = {first, stride, n};
  uint32_t a = 0, b = n;
  while (a < b) {
    uint32_t m = a + (b - a) / 2;
    if (oc__id_at(&v, m) < id)
      a = m + 1;
    else
      b = m;
  }
  return a < n && oc__id_at(&v, a) == id ? (int64_t)a : -1;
}

/* Index of id in the ascending list, or -1. */
static int64_t oc__ids_find(const oc__ids_t *v, uint32_t id) { return oc_ids_find(v->p, v->stride, v->n, id); }

/* Every brick node's id resolves, and every brick is referenced exactly once. With `codes` (the
 * full state's bricks, in the order of ids), zero channels also have all-zero codes. */
static int oc__check_bricks(const oc_state_t *s, const oc__ids_t *ids, const oc_brick_t *codes, char *why, size_t why_len) {
  static const char *ch_name[OC_CHANNELS] = {"sigma", "tau"};
  for (uint32_t b = 1; b < ids->n; b++) {
    uint32_t id = oc__id_at(ids, b), prev = oc__id_at(ids, b - 1);
    if (id <= prev)
      return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": id %" PRIu32 " %s", b, id,
                      id == prev ? "is duplicated" : "is out of order");
  }
  uint8_t *seen = NULL;
  if (ids->n) {
    seen = calloc(((size_t)ids->n + 7) / 8, 1);
    if (!seen) return OC_ENOMEM;
  }
  int err = 0;
  for (uint32_t i = 0; i < s->node_count && !err; i++) {
    const oc_node_t *n = &s->nodes[i];
    if (n->kind != OC_NODE_BRICK) continue;
    int64_t found = oc__ids_find(ids, n->brick_id);
    if (found < 0) {
      err = oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 ") references missing brick %" PRIu32, i, n->key, n->brick_id);
      break;
    }
    size_t bi = (size_t)found;
    if (seen[bi / 8] & (1u << (bi % 8))) {
      err = oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 " is referenced by more than one node (again by node %" PRIu32 ")",
                     n->brick_id, i);
      break;
    }
    seen[bi / 8] |= (uint8_t)(1u << (bi % 8));
    if (!codes) continue;
    /* A zero channel decodes to 0 whatever its codes; requiring zeros keeps one byte form per
     * content, so checksums compare content. */
    for (int c = 0; c < OC_CHANNELS && !err; c++) {
      if (n->range[c].hi != 0.0f) continue;
      for (int v = 0; v < OC_BRICK_VOXELS; v++)
        if (codes[bi].codes.code[c][v] != OC_CODE_ZERO) {
          err = oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": non-zero %s code in a zero channel", n->brick_id, ch_name[c]);
          break;
        }
    }
  }
  for (uint32_t bi = 0; bi < ids->n && !err; bi++)
    if (!(seen[bi / 8] & (1u << (bi % 8))))
      err = oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 " is not referenced by any node", oc__id_at(ids, bi));
  free(seen);
  return err;
}

/* Everything but the bricks: header fields, keys, records, the partition. */
static int oc__validate_records(const oc_state_t *s, uint32_t brick_count, char *why, size_t why_len) {
  if (!isfinite(s->time)) return oc_errorf(OC_ECORRUPT, why, why_len, "world time is not finite");
  double sl = oc_dlen(s->sun_dir);
  if (!isfinite(sl) || fabs(sl - 1.0) > 1e-6)
    return oc_errorf(OC_ECORRUPT, why, why_len, "sun direction (%g, %g, %g) is not a unit vector", s->sun_dir.x, s->sun_dir.y, s->sun_dir.z);
  if (s->node_count == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "no nodes: the leaves must cover the root cube");
  if (s->node_count > OC_STATE_MAX_NODES) return oc_errorf(OC_ECORRUPT, why, why_len, "%" PRIu32 " nodes exceed the limit", s->node_count);
  if (brick_count > OC_STATE_MAX_BRICKS) return oc_errorf(OC_ECORRUPT, why, why_len, "%" PRIu32 " bricks exceed the limit", brick_count);
  if (!s->nodes) return OC_EINVAL;
  for (uint32_t i = 0; i < s->node_count; i++) {
    const oc_node_t *n = &s->nodes[i];
    if (!oc__key_ok(n->key)) return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 ": invalid key 0x%" PRIx64, i, n->key);
    if (i > 0 && n->key <= s->nodes[i - 1].key)
      return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 " (key 0x%" PRIx64 "): %s", i, n->key,
                      n->key == s->nodes[i - 1].key ? "duplicate key" : "keys not in ascending order");
    OC_TRY(oc__check_node(n, i, why, why_len));
  }
  return oc__check_partition(s, why, why_len);
}

int oc_state_validate(const oc_state_t *s, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!s) return OC_EINVAL;
  OC_TRY(oc__validate_records(s, s->brick_count, why, why_len));
  if (s->brick_count && !s->bricks) return OC_EINVAL;
  oc__ids_t ids = oc__ids_full(s);
  return oc__check_bricks(s, &ids, s->bricks, why, why_len);
}

int oc_state_validate_lean(const oc_state_t *s, const oc_brick_digests_t *b, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!s || !b) return OC_EINVAL;
  OC_TRY(oc__validate_records(s, b->count, why, why_len));
  if (b->count && (!b->ids || !b->digests)) return OC_EINVAL;
  oc__ids_t ids = oc__ids_lean(b);
  return oc__check_bricks(s, &ids, NULL, why, why_len);
}

/*-*** Look-ups ***/

int64_t oc_state_find_node(const oc_state_t *s, oc_key_t key) {
  if (!s || !s->node_count) return -1;
  uint32_t a = 0, b = s->node_count; /* [a, b) */
  while (a < b) {
    uint32_t m = a + (b - a) / 2;
    if (s->nodes[m].key < key)
      a = m + 1;
    else
      b = m;
  }
  return a < s->node_count && s->nodes[a].key == key ? (int64_t)a : -1;
}

int64_t oc_state_find_leaf(const oc_state_t *s, oc_key_t key21) {
  if (!s || !oc__key_ok(key21)) return -1;
  /* The key itself, then each ancestor (dropping the lowest Morton triple moves the sentinel). */
  for (oc_key_t k = key21; k != 0; k >>= 3) {
    int64_t i = oc_state_find_node(s, k);
    if (i >= 0) return i;
  }
  return -1;
}

const oc_brick_t *oc_state_find_brick(const oc_state_t *s, uint32_t id) {
  if (!s || !s->brick_count) return NULL;
  int64_t k = oc_ids_find(&s->bricks[0].id, sizeof *s->bricks, s->brick_count, id);
  return k < 0 ? NULL : &s->bricks[k];
}

const oc_brick_codes_t *oc_states_find_codes(const oc_state_t *states, int n, uint32_t id) {
  for (int i = 0; i < n; i++) {
    const oc_brick_t *b = oc_state_find_brick(&states[i], id);
    if (b) return &b->codes;
  }
  return NULL;
}

/*-*** Budget ***/

/* Distinct ids by an n-way merge of the (canonical, ascending) id lists: no allocation for the 2–3
 * states a viewer keeps, and O(total · n). */
static uint64_t oc__resident(const oc__ids_t *ids, int n, uint64_t records, uint32_t slot_bytes, uint32_t record_bytes) {
  uint32_t head_small[8], *head = head_small;
  uint64_t distinct = 0;
  if (n > 8) {
    head = calloc((size_t)n, sizeof *head);
    if (!head) return UINT64_MAX; /* unknown: report "over any budget" rather than too little */
  }
  for (int i = 0; i < n; i++) head[i] = 0;
  for (;;) {
    bool any = false;
    uint32_t min = 0;
    for (int i = 0; i < n; i++) {
      if (head[i] >= ids[i].n) continue;
      uint32_t id = oc__id_at(&ids[i], head[i]);
      if (!any || id < min) min = id;
      any = true;
    }
    if (!any) break;
    distinct++;
    for (int i = 0; i < n; i++)
      while (head[i] < ids[i].n && oc__id_at(&ids[i], head[i]) == min) head[i]++;
  }
  if (head != head_small) free(head);
  return distinct * slot_bytes + records * record_bytes;
}

/* The id lists of n states (full: their bricks; lean: bricks[i]), then the merge. */
static uint64_t oc__resident_of(const oc_state_t *const *states, const oc_brick_digests_t *const *bricks, int n,
                                uint32_t slot_bytes, uint32_t record_bytes) {
  oc__ids_t small[8], *ids = small;
  uint64_t records = 0;
  if (!states || n <= 0) return 0;
  if (n > 8) {
    ids = calloc((size_t)n, sizeof *ids);
    if (!ids) return UINT64_MAX;
  }
  for (int i = 0; i < n; i++) {
    ids[i] = (oc__ids_t){NULL, sizeof(uint32_t), 0};
    if (bricks && bricks[i])
      ids[i] = oc__ids_lean(bricks[i]);
    else if (!bricks && states[i])
      ids[i] = oc__ids_full(states[i]);
    if (states[i]) records += states[i]->node_count;
  }
  uint64_t r = oc__resident(ids, n, records, slot_bytes, record_bytes);
  if (ids != small) free(ids);
  return r;
}

uint64_t oc_resident_bytes(const oc_state_t *const *states, int n, uint32_t slot_bytes, uint32_t record_bytes) {
  return oc__resident_of(states, NULL, n, slot_bytes, record_bytes);
}

uint64_t oc_resident_bytes_lean(const oc_state_t *const *states, const oc_brick_digests_t *const *bricks, int n,
                                uint32_t slot_bytes, uint32_t record_bytes) {
  if (!bricks) return 0;
  return oc__resident_of(states, bricks, n, slot_bytes, record_bytes);
}

/*-*** Lean states ***/

void oc_brick_digests_free(oc_brick_digests_t *b) {
  if (!b) return;
  free(b->ids);
  free(b->digests);
  memset(b, 0, sizeof *b);
}

int64_t oc_brick_digests_find(const oc_brick_digests_t *b, uint32_t id) {
  if (!b || !b->count) return -1;
  oc__ids_t v = oc__ids_lean(b);
  return oc__ids_find(&v, id);
}

int oc_brick_digests_lookup(const oc_brick_digests_t *lists, int n, uint32_t id, uint64_t *digest) {
  for (int i = 0; i < n; i++) {
    int64_t k = oc_brick_digests_find(&lists[i], id);
    if (k >= 0) {
      *digest = lists[i].digests[k];
      return 1;
    }
  }
  return 0;
}
