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
static inline uint8_t oc_get_u8(const uint8_t *p) { return p[0]; }
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

/*! OC_SCALAR_MAP(XX) : every scalar the formats use, as XX(name, C type, size in bytes); the reader and buffer
 * functions for each are generated from it, in the manner of libuv's UV_ERRNO_MAP. */
#define OC_SCALAR_MAP(XX) \
  XX(u8, uint8_t, 1) \
  XX(u16, uint16_t, 2) \
  XX(u32, uint32_t, 4) \
  XX(u64, uint64_t, 8) \
  XX(f32, float, 4) \
  XX(f64, double, 8)

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
/*! oc_read_u8() .. oc_read_f64() : the next scalar, little-endian, or 0 (and err set) when fewer bytes are left.
 * Generated from OC_SCALAR_MAP, as are the oc_buf_* writers below. */
#define OC_READ_FN(name, type, size) \
  static inline type oc_read_##name(oc_reader_t *r) { \
    const uint8_t *q = oc_reader_take(r, size); \
    return q ? oc_get_##name(q) : (type)0; \
  }
OC_SCALAR_MAP(OC_READ_FN)
#undef OC_READ_FN

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
/*! oc_buf_u8() .. oc_buf_f64() : appends one scalar, little-endian (nothing once err is set). */
#define OC_BUF_FN(name, type, size) \
  static inline void oc_buf_##name(oc_buf_t *b, type v) { \
    uint8_t *q = oc_buf_grow(b, size); \
    if (q) oc_put_##name(q, v); \
  }
OC_SCALAR_MAP(OC_BUF_FN)
#undef OC_BUF_FN

#endif /* OC_COMMON_BYTES_H */
