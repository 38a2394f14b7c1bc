/* gl_store.c — the viewer's kept states on the GPU: one shared brick atlas with a slot per brick id,
 * uploads spread over frames, per-state records and trees (ocv_gl.h, "Kept states").
 *
 * Brick ids name one content for the whole session (oc_state.h), so a brick is uploaded once and
 * referenced by every kept state that holds it; a slot is freed when no kept or staged state does.
 * The map from id to slot is open addressing with linear probing and backward-shift deletion, sized
 * from the atlas, so it never grows. */
#include <epoxy/gl.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"
#include "oc_err.h"
#include "ocv_gl.h"

typedef struct {
  uint32_t id, slot, refs; /* id 0: an empty bucket (the server never uses brick id 0) */
  uint32_t uploaded;
} ocv__entry_t;

typedef struct {
  ocv_gl_state_t gs;
  uint32_t *ids; /* its brick ids (distinct), to release them when it is dropped */
  uint32_t nids, nodes;
} ocv__kept_t;

struct ocv_gl_store_s {
  GLuint atlas;
  int bricks[3];
  oc_budget_t grant; /* sizes the atlas; its slot and record bytes count resident bytes */
  uint32_t capacity;
  uint32_t *free_slots, nfree;
  ocv__entry_t *map;
  uint32_t map_mask;
  ocv__kept_t *kept;
  int nkept, max_kept;
  /* the staged state */
  const oc_state_t *staged;
  uint32_t *pending, npending, pending_pos; /* indices into staged->bricks */
  uint16_t texels[1024];
  uint64_t uploaded_bricks, uploaded_bytes;
};

static uint32_t ocv__hash(uint32_t id) {
  id ^= id >> 16;
  id *= 0x7FEB352Du;
  id ^= id >> 15;
  id *= 0x846CA68Bu;
  return id ^ (id >> 16);
}

static ocv__entry_t *ocv__find(const ocv_gl_store_t *st, uint32_t id) {
  for (uint32_t i = ocv__hash(id) & st->map_mask;; i = (i + 1) & st->map_mask) {
    if (st->map[i].id == id) return &st->map[i];
    if (!st->map[i].id) return NULL;
  }
}

static ocv__entry_t *ocv__insert(ocv_gl_store_t *st, uint32_t id, uint32_t slot) {
  uint32_t i = ocv__hash(id) & st->map_mask;
  while (st->map[i].id) i = (i + 1) & st->map_mask;
  st->map[i] = (ocv__entry_t){id, slot, 1, 0};
  return &st->map[i];
}

/* Removes e and shifts back the entries of its probe run that would no longer be found. */
static void ocv__remove(ocv_gl_store_t *st, ocv__entry_t *e) {
  uint32_t i = (uint32_t)(e - st->map);
  st->free_slots[st->nfree++] = e->slot;
  st->map[i].id = 0;
  for (uint32_t j = (i + 1) & st->map_mask; st->map[j].id; j = (j + 1) & st->map_mask) {
    uint32_t home = ocv__hash(st->map[j].id) & st->map_mask;
    /* move j to the hole i when its home is not in (i, j] (cyclically) */
    if (((j - home) & st->map_mask) >= ((j - i) & st->map_mask)) {
      st->map[i] = st->map[j];
      st->map[j].id = 0;
      i = j;
    }
  }
}

static void ocv__release(ocv_gl_store_t *st, uint32_t id) {
  ocv__entry_t *e = ocv__find(st, id);
  if (e && --e->refs == 0) ocv__remove(st, e);
}

static void ocv__release_state(ocv_gl_store_t *st, const oc_state_t *s) {
  for (uint32_t b = 0; b < s->brick_count; b++) ocv__release(st, s->bricks[b].id);
}

/* Drops the staged state: its references go, and so do the bricks only it held. */
static void ocv__unstage(ocv_gl_store_t *st) {
  if (!st->staged) return;
  ocv__release_state(st, st->staged);
  st->staged = NULL;
  st->npending = st->pending_pos = 0;
}

static void ocv__drop_kept(ocv_gl_store_t *st, ocv__kept_t *k) {
  for (uint32_t i = 0; i < k->nids; i++) ocv__release(st, k->ids[i]);
  free(k->ids);
  ocv_gl_state_free(&k->gs);
  memset(k, 0, sizeof *k);
}

ocv_gl_store_t *ocv_gl_store_create(const oc_budget_t *grant, char *why, size_t why_len) {
  if (!grant || grant->kept_states < 2 || grant->kept_states > 3) {
    (void)oc_errorf(0, why, why_len, "gl store: the grant's kept states must be 2 or 3, not %d", grant ? grant->kept_states : 0);
    return NULL;
  }
  uint32_t slots = oc_budget_slots(grant);
  if (slots == 0) {
    (void)oc_errorf(0, why, why_len,
                    "gl store: a budget of %llu bytes holds no window of %d states (%u-byte slots, %u-byte records)",
                    (unsigned long long)grant->budget, grant->kept_states, grant->slot_bytes, grant->record_bytes);
    return NULL;
  }
  if (slots > 0x7FFFFFFFu) slots = 0x7FFFFFFFu;
  int kept = grant->kept_states - 1;
  int shape[3];
  if (ocv__gl_atlas_shape(slots, shape, "gl store", why, why_len) < 0) return NULL;
  uint32_t bx = (uint32_t)shape[0], by = (uint32_t)shape[1], bz = (uint32_t)shape[2];
  ocv_gl_store_t *st = calloc(1, sizeof *st);
  uint32_t mapn = 16;
  while (mapn < 2 * slots) mapn *= 2;
  if (st) {
    st->free_slots = malloc((size_t)slots * sizeof *st->free_slots);
    st->map = calloc(mapn, sizeof *st->map);
    st->kept = calloc((size_t)kept, sizeof *st->kept);
    st->pending = malloc((size_t)slots * sizeof *st->pending);
  }
  if (!st || !st->free_slots || !st->map || !st->kept || !st->pending) {
    (void)oc_errorf(0, why, why_len, "gl store: out of memory");
    ocv_gl_store_free(st);
    return NULL;
  }
  st->grant = *grant;
  st->capacity = slots;
  st->map_mask = mapn - 1;
  st->max_kept = kept;
  for (uint32_t i = 0; i < slots; i++) st->free_slots[i] = slots - 1 - i; /* slot 0 first */
  st->nfree = slots;
  st->bricks[0] = (int)bx, st->bricks[1] = (int)by, st->bricks[2] = (int)bz;
  glCreateTextures(GL_TEXTURE_3D, 1, &st->atlas);
  glTextureParameteri(st->atlas, GL_TEXTURE_MIN_FILTER, GL_NEAREST); /* integer texture: texelFetch only */
  glTextureParameteri(st->atlas, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureStorage3D(st->atlas, 1, GL_RG16UI, (GLsizei)(bx * 8), (GLsizei)(by * 8), (GLsizei)(bz * 8));
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    (void)oc_errorf(0, why, why_len, "gl store: atlas of %u×%u×%u bricks failed (GL error 0x%x)", bx, by, bz, (unsigned)err);
    ocv_gl_store_free(st);
    return NULL;
  }
  return st;
}

void ocv_gl_store_free(ocv_gl_store_t *st) {
  if (!st) return;
  for (int i = 0; i < st->nkept; i++) {
    free(st->kept[i].ids);
    ocv_gl_state_free(&st->kept[i].gs);
  }
  if (st->atlas) glDeleteTextures(1, &st->atlas);
  free(st->free_slots);
  free(st->map);
  free(st->kept);
  free(st->pending);
  free(st);
}

/* References to s's bricks, and the pending list of those not uploaded yet; on a shortage of
 * slots nothing is taken. */
static int ocv__take(ocv_gl_store_t *st, const oc_state_t *s, char *why, size_t why_len) {
  st->npending = st->pending_pos = 0;
  for (uint32_t b = 0; b < s->brick_count; b++) {
    uint32_t id = s->bricks[b].id;
    ocv__entry_t *e = ocv__find(st, id);
    if (e) {
      e->refs++;
      if (!e->uploaded) st->pending[st->npending++] = b; /* staged before, not uploaded yet */
      continue;
    }
    if (!st->nfree || id == 0) {
      for (uint32_t u = 0; u < b; u++) ocv__release(st, s->bricks[u].id);
      st->npending = 0;
      if (id == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "gl store: brick id 0");
      return oc_errorf(OC_ETOOBIG, why, why_len,
                       "gl store: state %llu needs more than the %u brick slots of the budget beside the kept states",
                       (unsigned long long)s->epoch, st->capacity);
    }
    ocv__insert(st, id, st->free_slots[--st->nfree]);
    st->pending[st->npending++] = b;
  }
  return 0;
}

int ocv_gl_store_stage(ocv_gl_store_t *st, const oc_state_t *s, char *why, size_t why_len) {
  if (!st || !s || !s->node_count) return oc_errorf(OC_EINVAL, why, why_len, "gl store: no state to stage");
  /* The new state's references first, then the old staged state's go: the bricks both hold and
   * that were uploaded already stay, so states that come faster than one uploads still complete
   * (each replaced stage would otherwise start again from nothing). Where the slots do not hold
   * both, the old stage goes first. */
  const oc_state_t *old = st->staged;
  st->staged = NULL;
  int rc = ocv__take(st, s, why, why_len);
  if (rc == OC_ETOOBIG && old) {
    ocv__release_state(st, old);
    old = NULL;
    rc = ocv__take(st, s, why, why_len);
  }
  if (old) ocv__release_state(st, old);
  if (rc < 0) return rc;
  st->staged = s;
  st->pending_pos = 0;
  return 0;
}

static uint32_t ocv__slot_of(void *ctx, const oc_state_t *s, uint32_t id) {
  (void)s;
  const ocv__entry_t *e = ocv__find(ctx, id);
  return e && e->uploaded ? e->slot : OCV__NO_SLOT;
}

int ocv_gl_store_pump(ocv_gl_store_t *st, uint64_t max_bytes, char *why, size_t why_len) {
  if (!st || !st->staged) return 0;
  const oc_state_t *s = st->staged;
  uint64_t sent = 0;
  while (st->pending_pos < st->npending && (sent == 0 || sent + OC_SLOT_BYTES <= max_bytes)) {
    const oc_brick_t *b = &s->bricks[st->pending[st->pending_pos++]];
    ocv__entry_t *e = ocv__find(st, b->id);
    ocv__gl_put_brick(st->atlas, st->bricks, e->slot, &b->codes, st->texels);
    e->uploaded = 1;
    sent += OC_SLOT_BYTES;
    st->uploaded_bricks++;
  }
  st->uploaded_bytes += sent;
  if (st->pending_pos < st->npending) return 0;

  /* Every brick is resident: the state's records and tree, then it is the newest kept state. */
  ocv__kept_t k;
  memset(&k, 0, sizeof k);
  void *rec = NULL;
  uint32_t *tree = NULL, inner = 0;
  k.ids = malloc((s->brick_count ? s->brick_count : 1) * sizeof *k.ids);
  int rc = k.ids ? ocv__gl_build(s, ocv__slot_of, st, &rec, &tree, &inner, why, why_len) : OC_ENOMEM;
  if (rc) {
    if (rc == OC_ENOMEM) (void)oc_errorf(0, why, why_len, "gl store: out of memory");
    free(k.ids);
    ocv__unstage(st);
    return rc;
  }
  for (uint32_t b = 0; b < s->brick_count; b++) k.ids[b] = s->bricks[b].id;
  k.nids = s->brick_count;
  k.nodes = s->node_count;
  k.gs.atlas = st->atlas;
  k.gs.shared_atlas = 1;
  memcpy(k.gs.atlas_bricks, st->bricks, sizeof st->bricks);
  k.gs.leaf_count = s->node_count;
  k.gs.brick_count = s->brick_count;
  k.gs.sun_dir = s->sun_dir;
  ocv__gl_buffers(&k.gs, rec, s->node_count, tree, inner);
  k.gs.resident_bytes = (uint64_t)s->node_count * OC_RECORD_BYTES + k.gs.tree_bytes;
  free(rec);
  free(tree);
  st->staged = NULL; /* its references now belong to the kept state */
  st->npending = st->pending_pos = 0;
  if (st->nkept == st->max_kept) ocv__drop_kept(st, &st->kept[--st->nkept]);
  memmove(&st->kept[1], &st->kept[0], (size_t)st->nkept * sizeof *st->kept);
  st->kept[0] = k;
  st->nkept++;
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) return oc_errorf(OC_EIO, why, why_len, "gl store: upload failed (GL error 0x%x)", (unsigned)err);
  return 1;
}

const ocv_gl_state_t *ocv_gl_store_state(const ocv_gl_store_t *st, int i) {
  return st && i >= 0 && i < st->nkept ? &st->kept[i].gs : NULL;
}

void ocv_gl_store_stats(const ocv_gl_store_t *st, ocv_gl_store_stats_t *out) {
  memset(out, 0, sizeof *out);
  if (!st) return;
  out->capacity = st->capacity;
  out->used = st->capacity - st->nfree;
  out->pending = st->npending - st->pending_pos;
  out->ready = (uint32_t)st->nkept;
  out->uploaded_bricks = st->uploaded_bricks;
  out->uploaded_bytes = st->uploaded_bytes;
  uint64_t records = st->staged ? st->staged->node_count : 0;
  out->gpu_bytes = (uint64_t)st->bricks[0] * st->bricks[1] * st->bricks[2] * OC_SLOT_BYTES;
  for (int i = 0; i < st->nkept; i++) {
    records += st->kept[i].nodes;
    out->gpu_bytes += st->kept[i].gs.resident_bytes;
  }
  out->resident_bytes = (uint64_t)out->used * st->grant.slot_bytes + records * st->grant.record_bytes;
}
