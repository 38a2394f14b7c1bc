/* gl_interp.c — the previous values of the newest state's leaves on the GPU (ocv_gl.h,
 * "Interpolation between states"): per-leaf records and the pool of resampled bricks. The pool
 * holds ip->pool's entries in order, entry k at brick position (k % X, k / X % Y, k / (X·Y)), so a
 * fine (merged) leaf's 8 sub-bricks are the consecutive entries base + c, c = x | y<<1 | z<<2. */
#include <epoxy/gl.h>
#include <stdlib.h>
#include <string.h>

#include "gl_internal.h"
#include "interp.h"
#include "oc_err.h"
#include "ocv_gl.h"

typedef struct {
  float value[4];   /* uniform previous σt, τ; 0, 0 */
  uint32_t info[4]; /* blends (weight t, else 1), uniform, pool entry (the first of 8 when fine), fine */
} ocv__prev_rec_t;
_Static_assert(sizeof(ocv__prev_rec_t) == 32, "std430 record of vec4 + uvec4");

void ocv_gl_prev_free(ocv_gl_prev_t *gp) {
  if (!gp) return;
  if (gp->records) glDeleteBuffers(1, &gp->records);
  if (gp->pool) glDeleteTextures(1, &gp->pool);
  memset(gp, 0, sizeof *gp);
}

int ocv_gl_prev_upload(ocv_gl_prev_t *gp, const ocv_interp_t *ip, int animated, char *why, size_t why_len) {
  memset(gp, 0, sizeof *gp);
  if (!ip || !ip->node_count) return oc_errorf(OC_EINVAL, why, why_len, "gl prev: no previous values");
  ocv__prev_rec_t *rec = calloc(ip->node_count, sizeof *rec);
  float *texels = malloc(512 * 2 * sizeof *texels);
  if (!rec || !texels) {
    free(rec);
    free(texels);
    return oc_errorf(OC_ENOMEM, why, why_len, "gl prev: out of memory");
  }
  for (uint32_t i = 0; i < ip->node_count; i++) {
    const ocv_interp_prev_t *p = &ip->prev[i];
    /* a leaf blends where its newest value's weight is not 1 at t < 1 (ocv_interp_weight) */
    rec[i].info[0] = ocv_interp_weight(p->source, animated, 0.0, 0.0, 1.0) < 1.0f;
    rec[i].info[1] = p->uniform;
    rec[i].info[2] = p->prev_index;
    rec[i].info[3] = p->fine;
    rec[i].value[0] = p->value[OC_CH_SIGMA];
    rec[i].value[1] = p->value[OC_CH_TAU];
  }
  int rc = ocv__gl_atlas_shape(ip->pool_count, gp->pool_bricks, "gl prev (resampled bricks)", why, why_len);
  if (rc < 0) goto out;
  uint32_t bx = (uint32_t)gp->pool_bricks[0], by = (uint32_t)gp->pool_bricks[1], bz = (uint32_t)gp->pool_bricks[2];
  gp->count = ip->node_count;
  gp->pool_count = ip->pool_count;
  glCreateBuffers(1, &gp->records);
  glNamedBufferStorage(gp->records, (GLsizeiptr)((size_t)ip->node_count * sizeof *rec), rec, 0);
  glCreateTextures(GL_TEXTURE_3D, 1, &gp->pool);
  glTextureParameteri(gp->pool, GL_TEXTURE_MIN_FILTER, GL_NEAREST); /* texelFetch only */
  glTextureParameteri(gp->pool, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureStorage3D(gp->pool, 1, GL_RG32F, (GLsizei)(bx * 8), (GLsizei)(by * 8), (GLsizei)(bz * 8));
  for (uint32_t k = 0; k < ip->pool_count; k++) {
    const float *e = ip->pool + (size_t)k * OCV_INTERP_ENTRY_FLOATS;
    for (int v = 0; v < 512; v++) {
      texels[2 * v] = e[v];
      texels[2 * v + 1] = e[512 + v];
    }
    glTextureSubImage3D(gp->pool, 0, (GLint)(k % bx * 8), (GLint)(k / bx % by * 8), (GLint)(k / (bx * by) * 8), 8, 8, 8,
                        GL_RG, GL_FLOAT, texels);
  }
  gp->gpu_bytes = (uint64_t)ip->node_count * sizeof *rec + (uint64_t)bx * by * bz * 512 * 8;
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) rc = oc_errorf(OC_ENOMEM, why, why_len, "gl prev: upload failed (GL error 0x%x)", (unsigned)err);
out:
  free(rec);
  free(texels);
  if (rc) ocv_gl_prev_free(gp);
  return rc;
}
