/* plot.c — the tools' PNG plot (plot.h): `overcast-bench sweep --plot` draws error (RMSE) against
 * render time, `overcast-stress --ramp --plot` figures against the number of viewers. Drawn by hand
 * into an RGB8 buffer and written with the project's PNG writer (oc_image.h): axes with ticks and a
 * grid, one colour per group (the budgets), optionally each group joined as a line, the Pareto
 * front joined in order of x and ringed, the reference boxed, a dashed horizontal limit. Text comes from stb_easy_font (libstb-dev, the font the
 * viewer's HUD uses), included directly so the plot does not depend on the GL client; without the
 * header the plot is drawn without text. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc.h"
#include "plot.h"

#if defined(__has_include)
#if __has_include(<stb/stb_easy_font.h>)
#define OCTS_HAVE_FONT 1
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb/stb_easy_font.h>
#pragma GCC diagnostic pop
#endif
#endif

#define PW 1000
#define PH 600
#define PL 92        /* plot area: left, right, top, bottom */
#define PR (PW - 230)
#define PT 84
#define PB (PH - 66)

typedef struct {
  uint8_t *px;
  int w, h;
} canvas_t;

static const uint8_t col_black[3] = {0, 0, 0}, col_grid[3] = {226, 226, 226}, col_axis[3] = {60, 60, 60},
                     col_front[3] = {214, 39, 40}, col_text[3] = {20, 20, 20}, col_dim[3] = {90, 90, 90};
/* tab10 without its red (the front's colour) */
static const uint8_t palette[OCTS_PLOT_GROUPS][3] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44}, {148, 103, 189},
                                                     {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34},
                                                     {23, 190, 207}, {0, 0, 128}};

static void put(canvas_t *c, int x, int y, const uint8_t col[3]) {
  if (x < 0 || y < 0 || x >= c->w || y >= c->h) return;
  memcpy(c->px + 3 * ((size_t)y * (size_t)c->w + (size_t)x), col, 3);
}

static void fill(canvas_t *c, int x0, int y0, int x1, int y1, const uint8_t col[3]) {
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) put(c, x, y, col);
}

static void disc(canvas_t *c, double cx, double cy, double r, const uint8_t col[3]) {
  for (int y = (int)floor(cy - r); y <= (int)ceil(cy + r); y++)
    for (int x = (int)floor(cx - r); x <= (int)ceil(cx + r); x++)
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r) put(c, x, y, col);
}

static void ring(canvas_t *c, double cx, double cy, double r, double th, const uint8_t col[3]) {
  for (int y = (int)floor(cy - r - th); y <= (int)ceil(cy + r + th); y++)
    for (int x = (int)floor(cx - r - th); x <= (int)ceil(cx + r + th); x++) {
      double d = sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy));
      if (fabs(d - r) <= th * 0.5) put(c, x, y, col);
    }
}

/* A line of width about `th` pixels: discs along it every half pixel. */
static void line(canvas_t *c, double x0, double y0, double x1, double y1, double th, const uint8_t col[3]) {
  double len = hypot(x1 - x0, y1 - y0);
  int n = (int)ceil(len * 2.0) + 1;
  for (int i = 0; i <= n; i++) {
    double t = (double)i / n;
    disc(c, x0 + t * (x1 - x0), y0 + t * (y1 - y0), th * 0.5, col);
  }
}

static void box(canvas_t *c, double cx, double cy, double r, const uint8_t col[3]) {
  line(c, cx - r, cy - r, cx + r, cy - r, 1.5, col);
  line(c, cx + r, cy - r, cx + r, cy + r, 1.5, col);
  line(c, cx + r, cy + r, cx - r, cy + r, 1.5, col);
  line(c, cx - r, cy + r, cx - r, cy - r, 1.5, col);
}

/* Text with its top-left corner at (x, y), font pixels `s` image pixels; returns its width. With
 * align 1 the text ends at x, with 2 it is centred on x. */
static int text(canvas_t *c, int x, int y, int s, int align, const char *str, const uint8_t col[3]) {
#ifdef OCTS_HAVE_FONT
  static char quads[64 * 1024];
  char buf[256];
  snprintf(buf, sizeof buf, "%s", str);
  int w = stb_easy_font_width(buf) * s;
  if (align == 1) x -= w;
  if (align == 2) x -= w / 2;
  int nq = stb_easy_font_print(0.0f, 0.0f, buf, NULL, quads, sizeof quads);
  for (int q = 0; q < nq; q++) { /* each quad: 4 vertices of x, y, z (float) and rgba (4 bytes) */
    float v0[3], v2[3];
    memcpy(v0, quads + q * 64, sizeof v0);
    memcpy(v2, quads + q * 64 + 32, sizeof v2);
    fill(c, x + (int)v0[0] * s, y + (int)v0[1] * s, x + (int)v2[0] * s, y + (int)v2[1] * s, col);
  }
  return w;
#else
  (void)c, (void)x, (void)y, (void)s, (void)align, (void)str, (void)col;
  return 0;
#endif
}

/* Distance from a point to the nearest point of a label's box. */
static double dist_line(double x, double y, int bx, int by, int tw, int th) {
  double dx = x < bx ? bx - x : x > bx + tw ? x - bx - tw : 0.0, dy = y < by ? by - y : y > by + th ? y - by - th : 0.0;
  return hypot(dx, dy);
}

static int text_width(const char *str, int s) {
#ifdef OCTS_HAVE_FONT
  char buf[256];
  snprintf(buf, sizeof buf, "%s", str);
  return stb_easy_font_width(buf) * s;
#else
  (void)str, (void)s;
  return 0;
#endif
}

/* A tick step of 1, 2 or 5 × 10^k giving about `want` intervals over span. */
static double nice_step(double span, int want) {
  double raw = span / want, p = pow(10.0, floor(log10(raw))), f = raw / p;
  return (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0) * p;
}

static void tick_label(double v, double step, char *out, size_t cap) {
  int dec = step >= 1.0 ? 0 : (int)ceil(-log10(step) - 1e-9);
  if (dec > 6) dec = 6;
  snprintf(out, cap, "%.*f", dec, v);
}

static int cmp_x(const void *a, const void *b) {
  const octs_plot_point_t *p = *(const octs_plot_point_t *const *)a, *q = *(const octs_plot_point_t *const *)b;
  return (p->x > q->x) - (p->x < q->x);
}

int octs_plot_png(const char *path, const octs_plot_point_t *p, int n, const octs_plot_desc_t *d, char *why, size_t why_len) {
  canvas_t c = {malloc((size_t)PW * PH * 3), PW, PH};
  const octs_plot_point_t **front = malloc(sizeof *front * (size_t)(n + 1));
  if (!c.px || !front) {
    free(c.px);
    free(front);
    return oc_errorf(OC_ENOMEM, why, why_len, "out of memory");
  }
  memset(c.px, 255, (size_t)PW * PH * 3);
  double xmax = 0.0, ymax = 0.0;
  for (int i = 0; i < n; i++) {
    if (isfinite(p[i].x)) xmax = fmax(xmax, p[i].x);
    if (isfinite(p[i].y)) ymax = fmax(ymax, p[i].y);
  }
  int has_hline = isfinite(d->hline) && d->hline != 0.0;
  if (has_hline) ymax = fmax(ymax, d->hline);
  if (d->ymin_top > 0.0) ymax = fmax(ymax, d->ymin_top / 1.08);
  if (!(xmax > 0.0)) xmax = 1.0;
  if (!(ymax > 0.0)) ymax = 1.0;
  double xs = nice_step(xmax * 1.05, 6), ys = nice_step(ymax * 1.08, 6);
  double x1 = ceil(xmax * 1.05 / xs) * xs, y1 = ceil(ymax * 1.08 / ys) * ys;
#define SX(v) (PL + (v) / x1 * (PR - PL))
#define SY(v) (PB - (v) / y1 * (PB - PT))
  char lab[64];
  for (double v = 0.0; v <= x1 + 1e-9 * x1; v += xs) { /* grid and ticks */
    int x = (int)lround(SX(v));
    fill(&c, x, PT, x + 1, PB, col_grid);
    fill(&c, x, PB, x + 1, PB + 5, col_axis);
    tick_label(v, xs, lab, sizeof lab);
    text(&c, x, PB + 9, 2, 2, lab, col_text);
  }
  for (double v = 0.0; v <= y1 + 1e-9 * y1; v += ys) {
    int y = (int)lround(SY(v));
    fill(&c, PL, y, PR, y + 1, col_grid);
    fill(&c, PL - 5, y, PL, y + 1, col_axis);
    tick_label(v, ys, lab, sizeof lab);
    text(&c, PL - 9, y - 6, 2, 1, lab, col_text);
  }
  fill(&c, PL, PT, PL + 2, PB + 1, col_axis);
  fill(&c, PL, PB - 1, PR + 1, PB + 1, col_axis);
  text(&c, (PL + PR) / 2, PB + 36, 2, 2, d->xlabel ? d->xlabel : "", col_text);
  text(&c, PL - 70, PT - 28, 2, 0, d->ylabel ? d->ylabel : "", col_text);
  text(&c, 12, 8, 2, 0, d->title ? d->title : "", col_black);
  if (d->subtitle) text(&c, 12, 32, 2, 0, d->subtitle, col_dim);

  if (has_hline) { /* dashed */
    double y = SY(d->hline);
    for (int x = PL; x < PR; x += 14) line(&c, x, y, fmin(x + 8, PR), y, 1.5, col_axis);
    if (d->hline_label) text(&c, PR - 4 - text_width(d->hline_label, 2), (int)y - 18, 2, 0, d->hline_label, col_dim);
  }
  if (d->lines) { /* each group joined in order of x */
    const octs_plot_point_t **g = front; /* borrowed: the front is built after this */
    for (int grp = 0; grp < OCTS_PLOT_GROUPS; grp++) {
      int ng = 0;
      for (int i = 0; i < n; i++)
        if ((p[i].group >= 0 && p[i].group < OCTS_PLOT_GROUPS ? p[i].group : 0) == grp && isfinite(p[i].x) && isfinite(p[i].y))
          g[ng++] = &p[i];
      qsort(g, (size_t)ng, sizeof *g, cmp_x);
      for (int i = 0; i + 1 < ng; i++) line(&c, SX(g[i]->x), SY(g[i]->y), SX(g[i + 1]->x), SY(g[i + 1]->y), 2.0, palette[grp]);
    }
  }
  /* the Pareto front, in order of time */
  int nf = 0;
  for (int i = 0; i < n; i++)
    if (p[i].pareto && isfinite(p[i].x) && isfinite(p[i].y)) front[nf++] = &p[i];
  qsort(front, (size_t)nf, sizeof *front, cmp_x);
  for (int i = 0; i + 1 < nf; i++) line(&c, SX(front[i]->x), SY(front[i]->y), SX(front[i + 1]->x), SY(front[i + 1]->y), 2.5, col_front);
  for (int i = 0; i < n; i++) { /* points */
    if (!isfinite(p[i].x) || !isfinite(p[i].y)) continue;
    int g = p[i].group >= 0 && p[i].group < OCTS_PLOT_GROUPS ? p[i].group : 0;
    disc(&c, SX(p[i].x), SY(p[i].y), 5.0, palette[g]);
  }
  /* labels of the front: the first candidate place that stays inside the plot and meets no label
   * placed before it nor a ring of the front */
  int placed[64][4], np = 0;
  for (int i = 0; i < nf; i++) {
    double x = SX(front[i]->x), y = SY(front[i]->y);
    ring(&c, x, y, 9.0, 2.0, col_front);
  }
  for (int i = 0; i < nf && np < 64; i++) {
    double x = SX(front[i]->x), y = SY(front[i]->y);
    char lab2[64];
    snprintf(lab2, sizeof lab2, "%s%s", front[i]->label, front[i]->reference ? " (ref.)" : "");
    int tw = text_width(lab2, 2), th = 14;
    /* candidates: right, left, above, below of the point, at growing distances */
    int bx = 0, by = 0, found = 0;
    for (int k = 0; k < 40 && !found; k++) {
      int dist = 12 + 16 * (k / 8), dir = k % 8;
      const int dx[8] = {1, 1, -1, -1, 0, 0, 1, -1}, dy[8] = {-1, 1, -1, 1, -1, 1, 0, 0};
      int x0 = dx[dir] > 0 ? (int)x + dist : dx[dir] < 0 ? (int)x - dist - tw : (int)x - tw / 2;
      int y0 = dy[dir] > 0 ? (int)y + dist - 4 : dy[dir] < 0 ? (int)y - dist - th + 4 : (int)y - th / 2;
      int ok = x0 >= PL + 4 && x0 + tw <= PR && y0 >= PT && y0 + th <= PB - 2;
      for (int j = 0; j < np && ok; j++)
        if (x0 - 2 < placed[j][2] && placed[j][0] < x0 + tw + 2 && y0 - 2 < placed[j][3] && placed[j][1] < y0 + th) ok = 0;
      for (int j = 0; j < nf && ok; j++) {
        double fx = SX(front[j]->x), fy = SY(front[j]->y);
        if (fx + 10 > x0 && fx - 10 < x0 + tw && fy + 10 > y0 && fy - 10 < y0 + th) ok = 0;
      }
      if (ok) bx = x0, by = y0, found = 1;
    }
    if (!found) continue; /* crowded: the Markdown table names it */
    if (dist_line(x, y, bx, by, tw, th) > 30.0) line(&c, x, y, bx < x ? bx + tw : bx, by + th / 2, 1.0, col_front);
    fill(&c, bx - 2, by - 2, bx + tw + 2, by + th, (const uint8_t[3]){255, 255, 255});
    text(&c, bx, by, 2, 0, lab2, col_front);
    placed[np][0] = bx - 2, placed[np][1] = by - 2, placed[np][2] = bx + tw + 2, placed[np][3] = by + th, np++;
  }
  for (int i = 0; i < n; i++)
    if (p[i].reference && isfinite(p[i].x) && isfinite(p[i].y)) box(&c, SX(p[i].x), SY(p[i].y), 13.0, col_black);

  /* legend */
  int ly = PT + 4, lx = PR + 24;
  for (int g = 0; g < d->ngroups && g < OCTS_PLOT_GROUPS; g++, ly += 24) {
    disc(&c, lx + 6, ly + 7, 5.0, palette[g]);
    text(&c, lx + 18, ly, 2, 0, d->group_name[g] ? d->group_name[g] : "", col_text);
  }
  int any_ref = 0;
  for (int i = 0; i < n; i++) any_ref |= p[i].reference;
  ly += 10;
  if (nf) {
    line(&c, lx, ly + 7, lx + 12, ly + 7, 2.5, col_front);
    ring(&c, lx + 6, ly + 7, 9.0, 2.0, col_front);
    text(&c, lx + 22, ly, 2, 0, "Pareto front", col_text);
    ly += 26;
  }
  if (any_ref) {
    box(&c, lx + 6, ly + 7, 7.0, col_black);
    text(&c, lx + 22, ly, 2, 0, "reference", col_text);
  }
  if (d->note) { /* lines of the note */
    char buf[256];
    snprintf(buf, sizeof buf, "%s", d->note);
    int y = ly + 34;
    for (char *save = NULL, *tok = strtok_r(buf, "\n", &save); tok; tok = strtok_r(NULL, "\n", &save), y += 22)
      text(&c, lx, y, 2, 0, tok, col_dim);
  }
#undef SX
#undef SY
  int r = oc_png_write(path, PW, PH, c.px, NULL, 0, why, why_len);
  free(c.px);
  free(front);
  return r;
}
