/* oc_err.h — Overcast error codes.
 *
 * Functions return int: 0 on success, a negative OC_E* on failure. Where a POSIX errno exists the
 * code is its negation; codes that exist only in Overcast sit in -5000..-5999. The enum, the names
 * and the messages are generated from one list (as libuv's UV_ERRNO_MAP). */
#ifndef OC_COMMON_ERR_H
#define OC_COMMON_ERR_H

#include <errno.h> /* the POSIX values the list negates */

#define OC_ERRNO_MAP(XX)                                                  \
  XX(EINVAL, -EINVAL, "invalid argument")                                 \
  XX(ENOMEM, -ENOMEM, "out of memory")                                    \
  XX(ENOENT, -ENOENT, "no such file or directory")                        \
  XX(EIO, -EIO, "input/output error")                                     \
  XX(ENOBUFS, -ENOBUFS, "buffer too small")                               \
  XX(ERANGE, -ERANGE, "value out of range")                               \
  XX(ECORRUPT, -5000, "corrupt or malformed data")                        \
  XX(EVERSION, -5001, "unsupported format or protocol version")           \
  XX(ECHECKSUM, -5002, "checksum mismatch")                               \
  XX(ETRUNC, -5003, "truncated data")                                     \
  XX(ETOOBIG, -5004, "data exceeds a size limit")                         \
  XX(ESCENE, -5005, "invalid scene description")                          \
  XX(EOBUFLIMIT, -5006, "output buffer limit reached")                    \
  XX(EAGAIN, -EAGAIN, "not ready yet")

typedef enum {
#define OC__ERR_ENUM(name, val, msg) OC_##name = (val),
  OC_ERRNO_MAP(OC__ERR_ENUM)
#undef OC__ERR_ENUM
} oc_err_t;

/*! oc_strerror() : @return a static message for an OC_E* code ("unknown error" otherwise). */
const char *oc_strerror(int err);
/*! oc_err_name() : @return the code's name without prefix, e.g. "ECORRUPT". */
const char *oc_err_name(int err);

#include <stddef.h> /* size_t */

/*! oc_errorf() : writes a one-line reason into why (when why is not NULL and why_len > 0) and
 *  returns `code`, for `return oc_errorf(OC_ECORRUPT, why, why_len, "...", ...)`. */
int oc_errorf(int code, char *why, size_t why_len, const char *fmt, ...) __attribute__((format(printf, 4, 5)));

/* Internal helpers in the manner of zstd's RETURN_ERROR_IF / FORWARD_IF_ERROR. */
#define OC_RETURN_IF(cond, err) \
  do {                          \
    if (cond) return (err);     \
  } while (0)
#define OC_TRY(expr)            \
  do {                          \
    int oc__r = (expr);         \
    if (oc__r < 0) return oc__r; \
  } while (0)

#endif /* OC_COMMON_ERR_H */
