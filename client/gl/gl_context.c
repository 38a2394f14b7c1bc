/* gl_context.c — a headless OpenGL 4.5 core context through libepoxy's EGL (design.md, "Testing
 * without a GPU"). Platforms in order: EGL_PLATFORM_SURFACELESS_MESA (llvmpipe, no X server), then
 * EGL_PLATFORM_DEVICE_EXT on each device (NVIDIA's headless path), then eglGetDisplay(default).
 * The context has no surface (EGL_KHR_surfaceless_context) and no config where
 * EGL_KHR_no_config_context allows it: the renderer draws into buffers and reads them back. */
#include <epoxy/egl.h> /* through libepoxy: <EGL/egl.h>'s Khronos headers clash with epoxy's */
#include <epoxy/gl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocv_gl.h"
#include "oc_err.h" /* oc_errorf */

struct ocv_gl_context_s {
  EGLDisplay dpy;
  EGLContext ctx;
  const char *platform;
};

static int ocv__has_ext(const char *list, const char *name) {
  size_t n = strlen(name);
  for (const char *p = list; p && (p = strstr(p, name)) != NULL; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return 1;
  return 0;
}

/* One display: initialise, bind desktop GL, make a 4.5 core context current without a surface. */
static int ocv__try_display(ocv_gl_context_t *c, EGLDisplay dpy, const char *platform, char *why, size_t wl) {
  EGLint major = 0, minor = 0;
  if (dpy == EGL_NO_DISPLAY) {
    (void)oc_errorf(0, why, wl, "%s: no display (EGL error 0x%x)", platform, (unsigned)eglGetError());
    return -1;
  }
  if (!eglInitialize(dpy, &major, &minor)) {
    (void)oc_errorf(0, why, wl, "%s: eglInitialize failed (0x%x)", platform, (unsigned)eglGetError());
    return -1;
  }
  const char *ext = eglQueryString(dpy, EGL_EXTENSIONS);
  if (!ocv__has_ext(ext, "EGL_KHR_surfaceless_context")) {
    (void)oc_errorf(0, why, wl, "%s: EGL %d.%d lacks EGL_KHR_surfaceless_context", platform, major, minor);
    eglTerminate(dpy);
    return -1;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    (void)oc_errorf(0, why, wl, "%s: eglBindAPI(EGL_OPENGL_API) failed (0x%x)", platform, (unsigned)eglGetError());
    eglTerminate(dpy);
    return -1;
  }
  EGLConfig cfg = EGL_NO_CONFIG_KHR;
  if (!ocv__has_ext(ext, "EGL_KHR_no_config_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(dpy, want, &cfg, 1, &n) || n < 1) {
      (void)oc_errorf(0, why, wl, "%s: no EGL config with EGL_OPENGL_BIT", platform);
      eglTerminate(dpy);
      return -1;
    }
  }
  const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION,       4,
                          EGL_CONTEXT_MINOR_VERSION,       5,
                          EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                          EGL_NONE};
  EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, attrs);
  if (ctx == EGL_NO_CONTEXT) {
    (void)oc_errorf(0, why, wl, "%s: no OpenGL 4.5 core context (0x%x)", platform, (unsigned)eglGetError());
    eglTerminate(dpy);
    return -1;
  }
  if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
    (void)oc_errorf(0, why, wl, "%s: eglMakeCurrent without surface failed (0x%x)", platform, (unsigned)eglGetError());
    eglDestroyContext(dpy, ctx);
    eglTerminate(dpy);
    return -1;
  }
  if (epoxy_gl_version() < 45 || !epoxy_is_desktop_gl()) {
    (void)oc_errorf(0, why, wl, "%s: context is GL %d, need desktop 4.5", platform, epoxy_gl_version());
    eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(dpy, ctx);
    eglTerminate(dpy);
    return -1;
  }
  c->dpy = dpy;
  c->ctx = ctx;
  c->platform = platform;
  return 0;
}

ocv_gl_context_t *ocv_gl_context_init(char *why, size_t why_len) {
  ocv_gl_context_t *c = calloc(1, sizeof *c);
  if (!c) {
    (void)oc_errorf(0, why, why_len, "out of memory");
    return NULL;
  }
  char first[256] = "", last[256] = "no EGL platform tried";
  const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS); /* NULL without client extensions */
  int has_platform = ocv__has_ext(client, "EGL_EXT_platform_base");
  if (has_platform && ocv__has_ext(client, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (ocv__try_display(c, d, "EGL_PLATFORM_SURFACELESS_MESA", first, sizeof first) == 0) return c;
  }
  if (has_platform && ocv__has_ext(client, "EGL_EXT_platform_device") &&
      ocv__has_ext(client, "EGL_EXT_device_enumeration")) {
    EGLDeviceEXT devs[8];
    EGLint n = 0;
    if (eglQueryDevicesEXT(8, devs, &n)) {
      for (EGLint i = 0; i < n; ++i) {
        EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
        if (ocv__try_display(c, d, "EGL_PLATFORM_DEVICE_EXT", last, sizeof last) == 0) return c;
      }
    }
  }
  if (ocv__try_display(c, eglGetDisplay(EGL_DEFAULT_DISPLAY), "EGL_DEFAULT_DISPLAY", last, sizeof last) == 0)
    return c;
  if (first[0]) (void)oc_errorf(0, why, why_len, "no headless OpenGL 4.5 context: %s; %s", first, last);
  else (void)oc_errorf(0, why, why_len, "no headless OpenGL 4.5 context: %s", last);
  free(c);
  return NULL;
}

void ocv_gl_context_free(ocv_gl_context_t *c) {
  if (!c) return;
  eglMakeCurrent(c->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(c->dpy, c->ctx);
  free(c);
}

const char *ocv_gl_context_platform(const ocv_gl_context_t *c) { return c ? c->platform : "none"; }

void ocv_gl_context_describe(const ocv_gl_context_t *c, char *out, size_t cap) {
  (void)oc_errorf(0, out, cap, "%s | %s | %s | via %s", (const char *)glGetString(GL_VENDOR),
            (const char *)glGetString(GL_RENDERER), (const char *)glGetString(GL_VERSION), ocv_gl_context_platform(c));
}
