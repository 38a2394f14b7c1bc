/* gl_internal.h — what gl_state.c (one state, its own atlas) and gl_store.c (kept states sharing
 * one atlas) share. Not a public interface. */
#ifndef OC_CLIENT_GL_INTERNAL_H
#define OC_CLIENT_GL_INTERNAL_H

#include <epoxy/gl.h>
#include <stddef.h>
#include <stdint.h>

#include "oc_state.h"
#include "ocv_gl.h"

#define OCV__NO_SLOT 0xFFFFFFFFu

/*! ocv__gl_build() : leaf records (OC_RECORD_BYTES each) and pointer octree of s, bricks placed
 *  by slot_of(); malloc'd outputs. @return 0, OC_ENOMEM or OC_ECORRUPT (with why). */
int ocv__gl_build(const oc_state_t *s, uint32_t (*slot_of)(void *ctx, const oc_state_t *s, uint32_t id), void *ctx,
                  void **rec_out, uint32_t **tree_out, uint32_t *inner_out, char *why, size_t why_len);
/*! ocv__gl_buffers() : gs->tree and gs->leaves from built arrays (sets inner_count). */
void ocv__gl_buffers(ocv_gl_state_t *gs, const void *rec, uint32_t nrec, const uint32_t *tree, uint32_t inner);
/*! ocv__gl_put_brick() : one brick's codes into atlas slot k (texels: scratch of 1024 u16). */
void ocv__gl_put_brick(GLuint atlas, const int bricks[3], uint32_t k, const oc_brick_codes_t *c, uint16_t *texels);

/*! ocv__gl_atlas_shape() : bricks per axis of an atlas of n bricks (8³ texels each) within
 *  GL_MAX_3D_TEXTURE_SIZE. @return 0, or OC_ETOOBIG with "<what>: N bricks exceed a M³ atlas". */
int ocv__gl_atlas_shape(uint32_t n, int bricks[3], const char *what, char *why, size_t why_len);

#endif /* OC_CLIENT_GL_INTERNAL_H */
