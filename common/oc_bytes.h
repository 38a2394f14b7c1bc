/* oc_bytes.h — explicit little-endian packing, a bounds-checked reader and a growable buffer.
 *
 * Every byte format of Overcast (state file, wire) is written field by field through these, never
 * as a struct image, so the bytes do not depend on the compiler, padding or host byte order
 * (docs/protocol.md). The reader never reads past its end: a short input sets `err` and every
 * later get returns 0, so a decoder checks once at the end instead of after every field. */
#ifndef OC_COMMON_BYTES_H
#define OC_COMMON_BYTES_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static inline void oc_put_u8(uint8_t *p, uint8_t v) { p[0] = v; }
static inline void oc_put_u16(uint8_t *p, uint16_t v) {
  p[0] = (uint8_t)v;
  p[1] = (uint8_t)(v >> 8);
}
static inline void oc_put_u32(uint8_t *p, uint32_t v) {
  for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void oc_put_u64(uint8_t *p, uint64_t v) {
  for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void oc_put_f32(uint8_t *p, float f) {
  uint32_t u;
  memcpy(&u, &f, 4); /* the bit pattern of one scalar, not a struct image */
  oc_put_u32(p, u);
}
static inline void oc_put_f64(uint8_t *p, double f) {
  uint64_t u;
  memcpy(&u, &f, 8);
  oc_put_u64(p, u);
}
static inline uint16_t oc_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static inline uint32_t oc_get_u32(const uint8_t *p) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; i--) v = (v << 8) | p[i];
  return v;
}
static inline uint64_t oc_get_u64(const uint8_t *p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; i--) v = (v << 8) | p[i];
  return v;
}
static inline float oc_get_f32(const uint8_t *p) {
  uint32_t u = oc_get_u32(p);
  float f;
  memcpy(&f, &u, 4);
  return f;
}
static inline double oc_get_f64(const uint8_t *p) {
  uint64_t u = oc_get_u64(p);
  double f;
  memcpy(&f, &u, 8);
  return f;
}

/*-*** Reader: a cursor over untrusted bytes ***/

typedef struct {
  const uint8_t *p;
  size_t len, pos;
  int err; /**< set once a get ran past the end; sticky */
} oc_reader_t;

static inline oc_reader_t oc_reader(const void *p, size_t len) { return (oc_reader_t){(const uint8_t *)p, len, 0, 0}; }
static inline size_t oc_reader_left(const oc_reader_t *r) { return r->err ? 0 : r->len - r->pos; }
/*! oc_reader_take() : the next n bytes, or NULL (and err set) when fewer are left. */
static inline const uint8_t *oc_reader_take(oc_reader_t *r, size_t n) {
  if (r->err || n > r->len - r->pos) {
    r->err = 1;
    return NULL;
  }
  const uint8_t *q = r->p + r->pos;
  r->pos += n;
  return q;
}
static inline uint8_t oc_read_u8(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 1);
  return q ? q[0] : 0;
}
static inline uint16_t oc_read_u16(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 2);
  return q ? oc_get_u16(q) : 0;
}
static inline uint32_t oc_read_u32(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 4);
  return q ? oc_get_u32(q) : 0;
}
static inline uint64_t oc_read_u64(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 8);
  return q ? oc_get_u64(q) : 0;
}
static inline float oc_read_f32(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 4);
  return q ? oc_get_f32(q) : 0.0f;
}
static inline double oc_read_f64(oc_reader_t *r) {
  const uint8_t *q = oc_reader_take(r, 8);
  return q ? oc_get_f64(q) : 0.0;
}

/*-*** Arrays: growth by doubling ***/

/*! oc_grow() : room for one more element in the array `arr` of `*cap` elements of `size` bytes, `n` of them in
 * use: when full, reallocates it to twice `*cap` (`first` when empty) and updates `*cap`.
 * @return the array (moved or not), or NULL when the allocation failed (then `arr` and `*cap` are unchanged). */
static inline void *oc_grow(void *arr, size_t *cap, size_t n, size_t size, size_t first) {
  if (n < *cap) return arr;
  size_t nc = *cap ? 2 * *cap : first;
  if (nc > SIZE_MAX / size) return NULL;
  void *a = realloc(arr, nc * size);
  if (a) *cap = nc;
  return a;
}

/*-*** Buffer: a growable byte array (writers append; on allocation failure `err` is set) ***/

typedef struct {
  uint8_t *data;
  size_t len, cap;
  int err; /**< set once an allocation failed; sticky, later appends do nothing */
} oc_buf_t;

static inline void oc_buf_free(oc_buf_t *b) {
  free(b->data);
  memset(b, 0, sizeof *b);
}
/*! oc_buf_grow() : room for n more bytes; @return a pointer to them (len advanced), or NULL. */
static inline uint8_t *oc_buf_grow(oc_buf_t *b, size_t n) {
  if (b->err) return NULL;
  if (n > b->cap - b->len) {
    size_t nc = b->cap ? b->cap : 256;
    while (nc - b->len < n) {
      if (nc > SIZE_MAX / 2) {
        b->err = 1;
        return NULL;
      }
      nc *= 2;
    }
    uint8_t *d = (uint8_t *)realloc(b->data, nc);
    if (!d) {
      b->err = 1;
      return NULL;
    }
    b->data = d;
    b->cap = nc;
  }
  uint8_t *q = b->data + b->len;
  b->len += n;
  return q;
}
static inline void oc_buf_append(oc_buf_t *b, const void *p, size_t n) {
  uint8_t *q = oc_buf_grow(b, n);
  if (q && n) memcpy(q, p, n);
}
static inline void oc_buf_u8(oc_buf_t *b, uint8_t v) {
  uint8_t *q = oc_buf_grow(b, 1);
  if (q) q[0] = v;
}
static inline void oc_buf_u16(oc_buf_t *b, uint16_t v) {
  uint8_t *q = oc_buf_grow(b, 2);
  if (q) oc_put_u16(q, v);
}
static inline void oc_buf_u32(oc_buf_t *b, uint32_t v) {
  uint8_t *q = oc_buf_grow(b, 4);
  if (q) oc_put_u32(q, v);
}
static inline void oc_buf_u64(oc_buf_t *b, uint64_t v) {
  uint8_t *q = oc_buf_grow(b, 8);
  if (q) oc_put_u64(q, v);
}
static inline void oc_buf_f32(oc_buf_t *b, float v) {
  uint8_t *q = oc_buf_grow(b, 4);
  if (q) oc_put_f32(q, v);
}
static inline void oc_buf_f64(oc_buf_t *b, double v) {
  uint8_t *q = oc_buf_grow(b, 8);
  if (q) oc_put_f64(q, v);
}

#endif /* OC_COMMON_BYTES_H */
