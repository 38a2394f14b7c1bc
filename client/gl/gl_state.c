/* gl_state.c — the GPU copy of a state: brick atlas, pointer octree, leaf records (README.md).
 *
 * The state's leaves are a linear octree in key order, which is not depth-first order across levels,
 * so the shader cannot binary-search it cheaply. Instead the CPU builds a pointer octree from the
 * leaves: each interior node holds 8 child references and the shader descends from the root with
 * the integer level-21 cell of a point, one level per step, never touching a float position. */
#include <epoxy/gl.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "gl_internal.h"
#include "ocv_gl.h"

#define OCV__LEAF_BIT 0x80000000u
#define OCV__UNSET 0xFFFFFFFFu
/* OCV__NO_SLOT: gl_internal.h */

/* The leaf record as the shader reads it (std430: vec4 then uvec4, 32 bytes). */
typedef struct {
  float range[4];   /* σt lo, hi, τ lo, hi */
  uint32_t info[4]; /* kind, atlas slot (OCV__NO_SLOT unless a brick), level, 0 */
} ocv__leaf_rec_t;
_Static_assert(sizeof(ocv__leaf_rec_t) == OC_RECORD_BYTES, "leaf record is 32 bytes");

typedef struct {
  uint32_t *w; /* word 0: root reference; then 8 words per interior node */
  uint32_t inner, cap;
} ocv__tree_t;

static int ocv__tree_new_inner(ocv__tree_t *t, uint32_t *idx) {
  if (t->inner == t->cap) {
    uint32_t cap = t->cap ? t->cap * 2 : 1024;
    uint32_t *w = realloc(t->w, (1 + (size_t)cap * 8) * sizeof *w);
    if (!w) return OC_ENOMEM;
    t->w = w;
    t->cap = cap;
  }
  *idx = t->inner++;
  for (int c = 0; c < 8; c++) t->w[1 + (size_t)*idx * 8 + (size_t)c] = OCV__UNSET;
  return 0;
}

/* Inserts leaf i (key) below the root, creating interior nodes on the way. */
static int ocv__tree_insert(ocv__tree_t *t, oc_key_t key, uint32_t leaf) {
  int level = oc_key_level(key);
  if (level < 0) return OC_ECORRUPT;
  if (level == 0) {
    if (t->w[0] != OCV__UNSET) return OC_ECORRUPT;
    t->w[0] = OCV__LEAF_BIT | leaf;
    return 0;
  }
  uint32_t ix, iy, iz;
  oc_key_coords(key, &ix, &iy, &iz);
  if (t->w[0] == OCV__UNSET) {
    uint32_t root;
    int rc = ocv__tree_new_inner(t, &root);
    if (rc) return rc;
    t->w[0] = root;
  }
  if (t->w[0] & OCV__LEAF_BIT) return OC_ECORRUPT;
  uint32_t cur = t->w[0];
  for (int l = 1; l <= level; l++) {
    int sh = level - l;
    uint32_t c = ((ix >> sh) & 1u) | (((iy >> sh) & 1u) << 1) | (((iz >> sh) & 1u) << 2);
    size_t slot = 1 + (size_t)cur * 8 + c;
    if (l == level) {
      if (t->w[slot] != OCV__UNSET) return OC_ECORRUPT;
      t->w[slot] = OCV__LEAF_BIT | leaf;
      return 0;
    }
    if (t->w[slot] == OCV__UNSET) {
      uint32_t child;
      int rc = ocv__tree_new_inner(t, &child); /* may move t->w */
      if (rc) return rc;
      t->w[slot] = child;
    }
    if (t->w[slot] & OCV__LEAF_BIT) return OC_ECORRUPT; /* a leaf with descendants */
    cur = t->w[slot];
  }
  return 0;
}

/* Builds the leaf records and the pointer octree of s; slot_of(ctx, id) gives a brick's atlas slot
 * (OCV__NO_SLOT: missing). On success *rec_out and *tree_out (1 + 8·inner words) are malloc'd. */
int ocv__gl_build(const oc_state_t *s, uint32_t (*slot_of)(void *ctx, const oc_state_t *s, uint32_t id), void *ctx,
                  void **rec_out, uint32_t **tree_out, uint32_t *inner_out, char *why, size_t why_len) {
  ocv__leaf_rec_t *rec = calloc(s->node_count, sizeof *rec);
  ocv__tree_t t = {0};
  int rc = rec && (t.w = malloc(sizeof *t.w)) ? 0 : OC_ENOMEM;
  if (!rc) t.w[0] = OCV__UNSET;
  for (uint32_t i = 0; !rc && i < s->node_count; i++) {
    const oc_node_t *nd = &s->nodes[i];
    rec[i].range[0] = nd->range[OC_CH_SIGMA].lo;
    rec[i].range[1] = nd->range[OC_CH_SIGMA].hi;
    rec[i].range[2] = nd->range[OC_CH_TAU].lo;
    rec[i].range[3] = nd->range[OC_CH_TAU].hi;
    rec[i].info[0] = nd->kind;
    rec[i].info[1] = OCV__NO_SLOT;
    rec[i].info[2] = (uint32_t)oc_key_level(nd->key);
    if (nd->kind == OC_NODE_BRICK && (rec[i].info[1] = slot_of(ctx, s, nd->brick_id)) == OCV__NO_SLOT) rc = OC_ECORRUPT;
    if (!rc) rc = ocv__tree_insert(&t, nd->key, i);
  }
  for (size_t w = 0; !rc && w < 1 + (size_t)t.inner * 8; w++)
    if (t.w[w] == OCV__UNSET) rc = OC_ECORRUPT; /* a hole: the leaves do not cover the cube */
  if (rc) {
    (void)oc_errorf(0, why, why_len, rc == OC_ENOMEM ? "gl state: out of memory" : "gl state: leaves do not partition the root cube, or a brick is missing");
    free(rec);
    free(t.w);
    return rc;
  }
  *rec_out = rec;
  *tree_out = t.w;
  *inner_out = t.inner;
  return 0;
}

/* slot = the brick's index in the state (ascending id): a one-state atlas. */
static uint32_t ocv__slot_by_index(void *ctx, const oc_state_t *s, uint32_t id) {
  (void)ctx;
  const oc_brick_t *b = oc_state_find_brick(s, id);
  return b ? (uint32_t)(b - s->bricks) : OCV__NO_SLOT;
}

/* The tree and leaf buffers of gs from built arrays. */
/* The octree map (Pettersson's 64³ map): the reference reached after up to `level` descent steps for
 * every cell of that level, appended to the tree, so a lookup starts `level` steps down. Its level is
 * the deepest ≤ OCV_GL_MAP_MAX_LEVEL, not past the deepest leaf, whose 8^level words stay within the
 * tree and records' own size: a small state pays little, a big one saves up to six dependent reads. */
static int ocv__map_level(const ocv__leaf_rec_t *rec, uint32_t nrec, uint32_t inner) {
  uint32_t deepest = 0;
  for (uint32_t i = 0; i < nrec; i++)
    if (rec[i].info[2] > deepest) deepest = rec[i].info[2];
  uint64_t words = 1 + 8 * (uint64_t)inner + 8 * (uint64_t)nrec;
  int level = 0;
  while (level < OCV_GL_MAP_MAX_LEVEL && (uint32_t)level < deepest && (1ull << (3 * (level + 1))) <= words) level++;
  return level;
}

/* Serial numbers of the states' GPU copies (ocv_gl_state_t.serial), across contexts and threads. */
static _Atomic uint64_t ocv__gl_serial;

void ocv__gl_buffers(ocv_gl_state_t *gs, const void *rec, uint32_t nrec, const uint32_t *tree, uint32_t inner) {
  gs->serial = atomic_fetch_add(&ocv__gl_serial, 1) + 1;
  gs->inner_count = inner;
  size_t tree_words = 1 + (size_t)inner * 8;
  int level = ocv__map_level(rec, nrec, inner);
  size_t n = (size_t)1 << level, map_words = level > 0 ? n * n * n : 0;
  uint32_t *w = map_words ? malloc((tree_words + map_words) * sizeof *w) : NULL;
  if (!w) map_words = 0, level = 0; /* no map: every lookup descends from the root */
  if (w) {
    memcpy(w, tree, tree_words * sizeof *w);
    for (size_t z = 0; z < n; z++)
      for (size_t y = 0; y < n; y++)
        for (size_t x = 0; x < n; x++) {
          uint32_t ref = tree[0];
          for (int l = 1; l <= level && !(ref & OCV__LEAF_BIT); l++) {
            int sh = level - l;
            ref = tree[1 + 8 * (size_t)ref + (((x >> sh) & 1) | (((y >> sh) & 1) << 1) | (((z >> sh) & 1) << 2))];
          }
          w[tree_words + x + n * (y + n * z)] = ref;
        }
  }
  gs->map_level = level;
  gs->map_offset = (uint32_t)tree_words;
  gs->tree_bytes = (tree_words + map_words) * sizeof *tree;
  glCreateBuffers(1, &gs->tree);
  glNamedBufferStorage(gs->tree, (GLsizeiptr)gs->tree_bytes, w ? w : tree, 0);
  free(w);
  glCreateBuffers(1, &gs->leaves);
  glNamedBufferStorage(gs->leaves, (GLsizeiptr)((size_t)nrec * sizeof(ocv__leaf_rec_t)), rec, 0);
}

int ocv__gl_atlas_shape(uint32_t n, int bricks[3], const char *what, char *why, size_t why_len) {
  GLint max3d = 0;
  glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
  uint32_t per = (uint32_t)(max3d > 0 ? max3d : 256) / 8u, m = n ? n : 1;
  uint32_t bx = m < per ? m : per, by = (m + bx - 1) / bx;
  if (by > per) by = per;
  uint32_t bz = (m + bx * by - 1) / (bx * by);
  if (bz > per) return oc_errorf(OC_ETOOBIG, why, why_len, "%s: %u bricks exceed a %d³ atlas", what, n, max3d);
  bricks[0] = (int)bx, bricks[1] = (int)by, bricks[2] = (int)bz;
  return 0;
}

/* Brick codes → 8³ RG16UI texels of atlas slot k. */
void ocv__gl_put_brick(GLuint atlas, const int bricks[3], uint32_t k, const oc_brick_codes_t *c, uint16_t *texels) {
  uint32_t bx = (uint32_t)bricks[0], by = (uint32_t)bricks[1];
  for (int v = 0; v < 512; v++) {
    texels[2 * v] = c->code[OC_CH_SIGMA][v];
    texels[2 * v + 1] = c->code[OC_CH_TAU][v];
  }
  glTextureSubImage3D(atlas, 0, (GLint)(k % bx * 8), (GLint)(k / bx % by * 8), (GLint)(k / (bx * by) * 8), 8, 8, 8,
                      GL_RG_INTEGER, GL_UNSIGNED_SHORT, texels);
}

void ocv_gl_state_free(ocv_gl_state_t *gs) {
  if (!gs) return;
  if (gs->atlas && !gs->shared_atlas) glDeleteTextures(1, &gs->atlas);
  if (gs->tree) glDeleteBuffers(1, &gs->tree);
  if (gs->leaves) glDeleteBuffers(1, &gs->leaves);
  memset(gs, 0, sizeof *gs);
}

int ocv_gl_state_upload(ocv_gl_state_t *gs, const oc_state_t *s, char *why, size_t why_len) {
  memset(gs, 0, sizeof *gs);
  if (!s || s->node_count == 0) {
    (void)oc_errorf(0, why, why_len, "gl state: empty state");
    return OC_EINVAL;
  }
  gs->sun_dir = s->sun_dir;
  gs->leaf_count = s->node_count;
  gs->brick_count = s->brick_count;

  int sh = ocv__gl_atlas_shape(s->brick_count, gs->atlas_bricks, "gl state", why, why_len);
  if (sh < 0) return sh;
  uint32_t bx = (uint32_t)gs->atlas_bricks[0], by = (uint32_t)gs->atlas_bricks[1], bz = (uint32_t)gs->atlas_bricks[2];

  void *rec = NULL;
  uint32_t *tree = NULL, inner = 0;
  uint16_t *texels = malloc(512 * 2 * sizeof *texels);
  int rc = texels ? ocv__gl_build(s, ocv__slot_by_index, NULL, &rec, &tree, &inner, why, why_len) : OC_ENOMEM;
  if (rc) {
    if (rc == OC_ENOMEM) (void)oc_errorf(0, why, why_len, "gl state: out of memory");
    goto out;
  }
  ocv__gl_buffers(gs, rec, s->node_count, tree, inner);

  glCreateTextures(GL_TEXTURE_3D, 1, &gs->atlas);
  glTextureParameteri(gs->atlas, GL_TEXTURE_MIN_FILTER, GL_NEAREST); /* integer texture: texelFetch only */
  glTextureParameteri(gs->atlas, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureStorage3D(gs->atlas, 1, GL_RG16UI, (GLsizei)(bx * 8), (GLsizei)(by * 8), (GLsizei)(bz * 8));
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (uint32_t k = 0; k < s->brick_count; k++) {
    const oc_brick_t *b = &s->bricks[k];
    ocv__gl_put_brick(gs->atlas, gs->atlas_bricks, k, &b->codes, texels);
  }
  gs->resident_bytes = (uint64_t)bx * by * bz * OC_SLOT_BYTES + (uint64_t)s->node_count * OC_RECORD_BYTES +
                       gs->tree_bytes;
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    (void)oc_errorf(0, why, why_len, "gl state: upload failed (GL error 0x%x)", (unsigned)err);
    rc = OC_ENOMEM;
  }
out:
  free(rec);
  free(tree);
  free(texels);
  if (rc) ocv_gl_state_free(gs);
  return rc;
}
