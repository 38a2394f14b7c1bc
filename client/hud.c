/* hud.c — text into an RGB8 image through stb_easy_font (hud.h). */
#include "hud.h"

#include <stdio.h>
#include <string.h>

#define STB_EASY_FONT_IMPLEMENTATION
#include <stb_easy_font.h>

/* Fills [x0, x1) × [y0, y1) clipped to the image, blending toward col by a (0..256). With 4 channels
 * the image is premultiplied RGBA and alpha composites the same way ("over"), so drawing into a
 * transparent overlay and compositing it later gives what drawing into the frame gives. */
static void ocv__fill(uint8_t *px, int channels, int w, int h, int x0, int y0, int x1, int y1, const uint8_t col[3],
                      int a) {
  const uint8_t c4[4] = {col[0], col[1], col[2], 255};
  if (x0 < 0) x0 = 0;
  if (y0 < 0) y0 = 0;
  if (x1 > w) x1 = w;
  if (y1 > h) y1 = h;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      uint8_t *p = px + (size_t)channels * ((size_t)y * (size_t)w + (size_t)x);
      for (int c = 0; c < channels; c++) p[c] = (uint8_t)((p[c] * (256 - a) + c4[c] * a) >> 8);
    }
}

static int ocv__text(uint8_t *px, int channels, int w, int h, int x, int y, int scale, const char *text,
                     const uint8_t color[3]) {
  if (!px || !text || w <= 0 || h <= 0) return 0;
  if (scale < 1) scale = 1;
  static char quads[64 * 1024]; /* 270 bytes a character (stb_easy_font.h): about 240 characters */
  char line[256];
  const uint8_t black[3] = {0, 0, 0};
  int ty = y;
  for (const char *p = text; *p;) {
    const char *e = strchr(p, '\n');
    size_t n = e ? (size_t)(e - p) : strlen(p);
    if (n >= sizeof line) n = sizeof line - 1;
    memcpy(line, p, n);
    line[n] = 0;
    int lw = stb_easy_font_width(line) * scale, lh = 12 * scale;
    ocv__fill(px, channels, w, h, x - 2, ty - 1, x + lw + 2, ty + lh - 1, black, 140); /* backdrop */
    int nq = stb_easy_font_print(0.0f, 0.0f, line, NULL, quads, sizeof quads);
    for (int q = 0; q < nq; q++) { /* each quad: 4 vertices of x, y, z (float) and rgba (4 bytes) */
      const float *v0 = (const float *)(quads + q * 64), *v2 = (const float *)(quads + q * 64 + 32);
      ocv__fill(px, channels, w, h, x + (int)v0[0] * scale, ty + (int)v0[1] * scale, x + (int)v2[0] * scale, ty + (int)v2[1] * scale,
                color, 256);
    }
    ty += lh;
    p = e ? e + 1 : p + n;
  }
  return ty - y;
}

int ocv_hud_text(uint8_t *rgb, int w, int h, int x, int y, int scale, const char *text, const uint8_t color[3]) {
  return ocv__text(rgb, 3, w, h, x, y, scale, text, color);
}

int ocv_hud_text_rgba(uint8_t *rgba, int w, int h, int x, int y, int scale, const char *text, const uint8_t color[3]) {
  return ocv__text(rgba, 4, w, h, x, y, scale, text, color);
}

void ocv_hud_format(const ocv_hud_stats_t *s, char *buf, int cap) {
  char gpu[64] = "";
  if (s->trace_ms >= 0 && s->reproject_ms >= 0)
    snprintf(gpu, sizeof gpu, "  gpu trace %.2f ms, reproject %.2f ms", s->trace_ms, s->reproject_ms);
  else if (s->trace_ms >= 0)
    snprintf(gpu, sizeof gpu, "  gpu trace %.2f ms", s->trace_ms);
  char trace[64] = "";
  if (s->trace_w > 0 && s->trace_h > 0) {
    if (s->trace_scale > 1) snprintf(trace, sizeof trace, "  |  trace %dx%d (1/%d)", s->trace_w, s->trace_h, s->trace_scale);
    else snprintf(trace, sizeof trace, "  |  trace %dx%d (full)", s->trace_w, s->trace_h);
  }
  snprintf(buf, (size_t)cap,
           "%s  frame %.1f ms%s\n"
           "epoch %llu, %.1f s old  |  %u bricks, %.1f of %.1f MiB\n"
           "received %.1f KiB/s%s",
           s->renderer ? s->renderer : "", s->frame_ms, gpu, (unsigned long long)s->epoch, s->epoch_age_s, s->bricks,
           (double)s->resident_bytes / 1048576.0, (double)s->budget_bytes / 1048576.0, s->bytes_per_s / 1024.0, trace);
}
