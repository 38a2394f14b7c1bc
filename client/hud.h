/* hud.h — the viewer's heads-up display: text (stb_easy_font's quads) drawn into an 8-bit RGB image,
 * so the headless PNGs and the window show the same overlay. */
#ifndef OC_CLIENT_HUD_H
#define OC_CLIENT_HUD_H

#include <stdint.h>

/*! ocv_hud_text() : draws `text` ('\n' starts a new line) with its top-left corner at (x, y), each
 *  font pixel `scale` image pixels, over a darkened backdrop so it reads on bright clouds; clipped to
 *  the image. @return the height in pixels of what was drawn. */
int ocv_hud_text(uint8_t *rgb, int w, int h, int x, int y, int scale, const char *text, const uint8_t color[3]);
/*! ocv_hud_text_rgba() : the same into a premultiplied RGBA8 overlay (start from all zeros:
 *  transparent). Composited as out = overlay.rgb + frame·(1 − overlay.a), it gives what
 *  ocv_hud_text() gives drawn into the frame (to rounding): the window draws its HUD this way on
 *  the GPU (client/gl/gl_present.c). */
int ocv_hud_text_rgba(uint8_t *rgba, int w, int h, int x, int y, int scale, const char *text, const uint8_t color[3]);

typedef struct {
  double frame_ms;          /**< wall time of the last frame */
  double trace_ms, reproject_ms; /**< GPU time per pass (timer queries); < 0: not measured */
  uint64_t epoch;           /**< of the newest state shown */
  double epoch_age_s;       /**< since it arrived */
  uint32_t bricks;          /**< resident bricks */
  uint64_t resident_bytes, budget_bytes;
  double bytes_per_s;       /**< received */
  const char *renderer;     /**< "gl (llvmpipe)", "cpu" */
  int trace_w, trace_h;     /**< the internal (traced) resolution; 0: not shown */
  int trace_scale;          /**< its divisor per axis of the picture's (1: full) */
} ocv_hud_stats_t;

/*! ocv_hud_format() : the standard HUD lines for s into buf. */
void ocv_hud_format(const ocv_hud_stats_t *s, char *buf, int cap);

#endif /* OC_CLIENT_HUD_H */
