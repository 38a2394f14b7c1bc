/* gl_present.c — tone mapping and the HUD overlay on the GPU (ocv_gl.h, "The picture";
 * shaders/present.comp.glsl). The window draws the texture this makes; nothing goes back to the CPU
 * unless a screenshot asks (ocv_gl_present_read). */
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "ocv_gl.h"

#define OCV__GROUP 8

struct ocv_gl_present_s {
  GLuint prog;
  GLuint tex;         /* RGBA8, w×h */
  int w, h;
  GLuint overlay;     /* RGBA8, ow×oh; a 1×1 transparent texel when there is none */
  int ow, oh;
};

/* An immutable RGBA8 texture of w×h with nearest filtering (texels are fetched, never filtered). */
static GLuint ocv__texture(int w, int h) {
  GLuint t;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTextureStorage2D(t, 1, GL_RGBA8, w, h);
  return t;
}

ocv_gl_present_t *ocv_gl_present_create(char *why, size_t why_len) {
  ocv_gl_present_t *p = calloc(1, sizeof *p);
  if (!p) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  p->prog = ocv_gl_compute_program("present.comp.glsl", NULL, why, why_len);
  if (!p->prog) {
    free(p);
    return NULL;
  }
  return p;
}

void ocv_gl_present_free(ocv_gl_present_t *p) {
  if (!p) return;
  if (p->tex) glDeleteTextures(1, &p->tex);
  if (p->overlay) glDeleteTextures(1, &p->overlay);
  glDeleteProgram(p->prog);
  free(p);
}

GLuint ocv_gl_present_tonemap(ocv_gl_present_t *p, GLuint radiance, int w, int h, float exposure, const uint8_t *overlay,
                              int ow, int oh, char *why, size_t why_len) {
  return ocv_gl_present_upsample(p, radiance, w, h, w, h, exposure, overlay, ow, oh, why, why_len);
}

GLuint ocv_gl_present_upsample(ocv_gl_present_t *p, GLuint radiance, int rw, int rh, int w, int h, float exposure,
                               const uint8_t *overlay, int ow, int oh, char *why, size_t why_len) {
  if (!p || !radiance || w <= 0 || h <= 0 || w > 16384 || h > 16384) {
    (void)oc_errorf(0, why, why_len, "gl present: no radiance buffer or a bad size %dx%d", w, h);
    return 0;
  }
  if (rw <= 0 || rh <= 0 || rw > w || rh > h) {
    (void)oc_errorf(0, why, why_len, "gl present: a radiance buffer of %dx%d for a %dx%d picture", rw, rh, w, h);
    return 0;
  }
  if (!(exposure >= 0.0f && exposure < 1e30f)) {
    (void)oc_errorf(0, why, why_len, "gl present: exposure %g is not a finite value ≥ 0", (double)exposure);
    return 0;
  }
  if (!overlay || ow <= 0 || oh <= 0) ow = oh = 0;
  if (!p->tex || p->w != w || p->h != h) {
    if (p->tex) glDeleteTextures(1, &p->tex);
    p->tex = ocv__texture(w, h);
    p->w = w;
    p->h = h;
  }
  int tw = ow > 0 ? ow : 1, th = oh > 0 ? oh : 1;
  if (!p->overlay || p->ow != tw || p->oh != th) {
    if (p->overlay) glDeleteTextures(1, &p->overlay);
    p->overlay = ocv__texture(tw, th);
    p->ow = tw;
    p->oh = th;
  }
  if (ow > 0) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage2D(p->overlay, 0, 0, 0, ow, oh, GL_RGBA, GL_UNSIGNED_BYTE, overlay);
  }
  glProgramUniform2i(p->prog, 0, w, h);
  glProgramUniform1f(p->prog, 1, exposure);
  glProgramUniform2i(p->prog, 2, ow, oh);
  glProgramUniform2i(p->prog, 3, rw, rh);
  glUseProgram(p->prog);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, radiance);
  glBindImageTexture(0, p->tex, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA8);
  glBindTextureUnit(1, p->overlay);
  glDispatchCompute((GLuint)((w + OCV__GROUP - 1) / OCV__GROUP), (GLuint)((h + OCV__GROUP - 1) / OCV__GROUP), 1);
  /* the window samples it next, a screenshot reads it */
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
  glUseProgram(0);
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    (void)oc_errorf(0, why, why_len, "gl present: GL error 0x%x", (unsigned)err);
    return 0;
  }
  return p->tex;
}

int ocv_gl_present_read(ocv_gl_present_t *p, uint8_t *rgb8, char *why, size_t why_len) {
  if (!p || !p->tex || !rgb8) return oc_errorf(OC_EINVAL, why, why_len, "gl present: nothing tone-mapped yet");
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glGetTextureImage(p->tex, 0, GL_RGB, GL_UNSIGNED_BYTE, (GLsizei)((size_t)p->w * (size_t)p->h * 3), rgb8);
  GLenum err = glGetError();
  if (err != GL_NO_ERROR) return oc_errorf(OC_EIO, why, why_len, "gl present: reading back: GL error 0x%x", (unsigned)err);
  return 0;
}
