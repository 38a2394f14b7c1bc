/* gl_window.h — overcast-view's window: GLFW with an OpenGL 4.5 core, forward-compatible context
 * (entry points through libepoxy, which works with GLFW's GLX or EGL context), input collected per
 * frame, and presentation of a rendered frame as a fullscreen blit of its tone-mapped 8-bit RGB
 * pixels. The rendering itself is ocv_gl_render_state() (ocv_gl.h), the same compute path as the
 * headless viewer; the window's context is current on the thread that opened it.
 *
 * Built only with OC_HAVE_GLFW (client/CMakeLists.txt links GLFW through pkg-config glfw3);
 * without it ocv_window_available() is 0 and ocv_window_open() fails with a reason. */
#ifndef OC_CLIENT_GL_WINDOW_H
#define OC_CLIENT_GL_WINDOW_H

#include <stddef.h>
#include <stdint.h>

typedef struct ocv_window_s ocv_window_t;

/*! Keys held down (flight). */
typedef enum {
  OCV_KEY_FORWARD, /* W */
  OCV_KEY_BACK,    /* S */
  OCV_KEY_LEFT,    /* A */
  OCV_KEY_RIGHT,   /* D */
  OCV_KEY_DOWN,    /* Q */
  OCV_KEY_UP,      /* E */
  OCV_KEY_FAST,    /* Shift: ×10 */
  OCV_KEY_COUNT
} ocv_key_t;

/*! Key presses (counted, key repeat included but for the screenshot). */
typedef enum {
  OCV_ACT_STEP_MUL,     /* [ : step factor × 1.25 */
  OCV_ACT_STEP_DIV,     /* ] : step factor ÷ 1.25 */
  OCV_ACT_EXPOSURE_DOWN, /* - : exposure ÷ 1.25 */
  OCV_ACT_EXPOSURE_UP,  /* = : exposure × 1.25 */
  OCV_ACT_SCREENSHOT,   /* F12 or P */
  OCV_ACT_REPROJECT,    /* R : reprojection (one pixel in 16 traced) on/off */
  OCV_ACT_DEBUG,        /* V : cycle the debug views (off, LOD, τ, node bounds) */
  OCV_ACT_HUD,          /* H : HUD on/off */
  OCV_ACT_JITTER,       /* J : per-pixel ray-start jitter on/off */
  OCV_ACT_OCTAVES,      /* M : multiple-scattering octaves 1..8, cycled */
  OCV_ACT_WEATHER,      /* N : the server's next weather preset (control channel) */
  OCV_ACT_SUN_WEST,     /* K : the sun 15° west (control channel) */
  OCV_ACT_SUN_EAST,     /* L : the sun 15° east (control channel) */
  OCV_ACT_TIME,         /* T : world time paused / resumed (control channel) */
  OCV_ACT_QUIT,         /* Esc (or the window's close button) */
  OCV_ACT_COUNT
} ocv_action_t;

typedef struct {
  int held[OCV_KEY_COUNT];
  int presses[OCV_ACT_COUNT]; /**< since the previous ocv_window_poll() */
  double look_dx, look_dy;    /**< cursor motion in screen pixels while the left button was held */
  int fb_w, fb_h;             /**< framebuffer size in pixels (0 while minimised) */
  int resized;                /**< the framebuffer size changed since the previous poll */
  int close;                  /**< the window should close */
} ocv_window_input_t;

/*! ocv_window_available() : 1 when this build has GLFW. */
int ocv_window_available(void);
/*! ocv_window_open() : a w×h window titled `title` with an OpenGL 4.5 core context, current on
 *  this thread. @return NULL with a one-line reason in why (no display, no GL 4.5, ...). */
ocv_window_t *ocv_window_open(int w, int h, const char *title, char *why, size_t why_len);
/*! ocv_window_close() : destroys the window and terminates GLFW. NULL is fine. */
void ocv_window_close(ocv_window_t *win);
/*! ocv_window_poll() : processes pending events (without waiting) into *in. */
void ocv_window_poll(ocv_window_t *win, ocv_window_input_t *in);
/*! ocv_window_set_title() : the window's title (UTF-8). */
void ocv_window_set_title(ocv_window_t *win, const char *title);
/*! ocv_window_present() : draws the texture `tex` (an RGBA8 picture with rows from the top and the
 *  display encoding applied, as ocv_gl_present_tonemap() makes it) stretched over the whole
 *  framebuffer and swaps buffers; tex 0 clears to dark grey. The picture stays on the GPU.
 *  @return 0, or OC_EIO with why on a GL error. */
int ocv_window_present(ocv_window_t *win, unsigned int tex, char *why, size_t why_len);

#endif /* OC_CLIENT_GL_WINDOW_H */
