#include "oc_image.h"

#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "optics.h" /* ocg_aces_fit, ocg_srgb_encode3: one tone-mapping formula for C and GLSL */

int oc_image_alloc(oc_image_t *img, int w, int h) {
  img->w = img->h = 0;
  img->px = NULL;
  if (w <= 0 || h <= 0 || w > 16384 || h > 16384) return OC_EINVAL;
  img->px = calloc((size_t)w * (size_t)h * 4, sizeof(float));
  if (!img->px) return OC_ENOMEM;
  img->w = w;
  img->h = h;
  return 0;
}

void oc_image_free(oc_image_t *img) {
  if (!img) return;
  free(img->px);
  img->px = NULL;
  img->w = img->h = 0;
}

int oc_image_tonemap(const oc_image_t *img, float exposure, uint8_t *rgb8) {
  int bad = 0;
  size_t n = (size_t)img->w * (size_t)img->h;
  for (size_t i = 0; i < n; i++) {
    const float *p = img->px + 4 * i;
    ocg_vec3 c = ocg_v3(p[0] * exposure, p[1] * exposure, p[2] * exposure);
    if (!isfinite(c.x) || !isfinite(c.y) || !isfinite(c.z)) {
      bad++;
      c = ocg_v3s(0.0f);
    }
    c = ocg_srgb_encode3(ocg_aces_fit(c));
    rgb8[3 * i + 0] = (uint8_t)lrintf(ocg_clamp(c.x, 0.0f, 1.0f) * 255.0f);
    rgb8[3 * i + 1] = (uint8_t)lrintf(ocg_clamp(c.y, 0.0f, 1.0f) * 255.0f);
    rgb8[3 * i + 2] = (uint8_t)lrintf(ocg_clamp(c.z, 0.0f, 1.0f) * 255.0f);
  }
  return bad;
}

static void oc__why(char *why, size_t cap, const char *fmt, const char *a, const char *b) {
  if (why && cap) snprintf(why, cap, fmt, a, b);
}

int oc_png_write(const char *path, int w, int h, const uint8_t *rgb8, const oc_png_text_t *text, int ntext,
                 char *why, size_t why_len) {
  png_image im;
  memset(&im, 0, sizeof im);
  /* The simplified API cannot write text chunks, so use the classic one. */
  FILE *f = fopen(path, "wb");
  if (!f) {
    oc__why(why, why_len, "%s: cannot create: %s", path, strerror(errno));
    return OC_EIO;
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  png_textp tx = NULL;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    fclose(f);
    return OC_ENOMEM;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    free(tx);
    fclose(f);
    oc__why(why, why_len, "%s: libpng write error%s", path, "");
    return OC_EIO;
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (ntext > 0) {
    tx = calloc((size_t)ntext, sizeof *tx);
    if (!tx) longjmp(png_jmpbuf(png), 1);
    for (int i = 0; i < ntext; i++) {
      tx[i].compression = PNG_TEXT_COMPRESSION_NONE;
      tx[i].key = (png_charp)text[i].key;
      tx[i].text = (png_charp)text[i].value;
    }
    png_set_text(png, info, tx, ntext);
  }
  png_write_info(png, info);
  for (int y = 0; y < h; y++) png_write_row(png, (png_const_bytep)(rgb8 + (size_t)y * (size_t)w * 3));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  free(tx);
  if (fclose(f) != 0) {
    oc__why(why, why_len, "%s: write failed: %s", path, strerror(errno));
    return OC_EIO;
  }
  return 0;
}

int oc_png_read(const char *path, int *w, int *h, uint8_t **rgb8, const char *want_key, char *text_out,
                size_t text_cap, char *why, size_t why_len) {
  *rgb8 = NULL;
  if (text_out && text_cap) text_out[0] = '\0';
  FILE *f = fopen(path, "rb");
  if (!f) {
    oc__why(why, why_len, "%s: cannot open: %s", path, strerror(errno));
    return errno == ENOENT ? OC_ENOENT : OC_EIO;
  }
  uint8_t sig[8];
  if (fread(sig, 1, 8, f) != 8 || png_sig_cmp(sig, 0, 8)) {
    fclose(f);
    oc__why(why, why_len, "%s: not a PNG file%s", path, "");
    return OC_ECORRUPT;
  }
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  uint8_t *volatile buf = NULL;
  if (!png || !info) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    return OC_ENOMEM;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, NULL);
    free(buf);
    fclose(f);
    oc__why(why, why_len, "%s: corrupt PNG%s", path, "");
    return OC_ECORRUPT;
  }
  png_init_io(png, f);
  png_set_sig_bytes(png, 8);
  png_set_user_limits(png, 16384, 16384);
  png_read_info(png, info);
  png_set_strip_16(png);
  png_set_strip_alpha(png);
  png_set_palette_to_rgb(png);
  png_set_gray_to_rgb(png);
  png_set_expand_gray_1_2_4_to_8(png);
  png_read_update_info(png, info);
  int ww = (int)png_get_image_width(png, info), hh = (int)png_get_image_height(png, info);
  if (png_get_rowbytes(png, info) != (size_t)ww * 3) longjmp(png_jmpbuf(png), 1);
  buf = malloc((size_t)ww * (size_t)hh * 3);
  if (!buf) longjmp(png_jmpbuf(png), 1);
  for (int y = 0; y < hh; y++) png_read_row(png, (png_bytep)(buf + (size_t)y * (size_t)ww * 3), NULL);
  png_read_end(png, info);
  if (want_key && text_out && text_cap) {
    png_textp tx = NULL;
    int nt = 0;
    png_get_text(png, info, &tx, &nt);
    for (int i = 0; i < nt; i++)
      if (strcmp(tx[i].key, want_key) == 0) {
        snprintf(text_out, text_cap, "%s", tx[i].text);
        break;
      }
  }
  png_destroy_read_struct(&png, &info, NULL);
  fclose(f);
  *w = ww;
  *h = hh;
  *rgb8 = buf;
  return 0;
}

double oc_rgb8_rmse(const uint8_t *a, const uint8_t *b, int w, int h) {
  double s = 0.0;
  size_t n = (size_t)w * (size_t)h * 3;
  for (size_t i = 0; i < n; i++) {
    double d = (double)a[i] - (double)b[i];
    s += d * d;
  }
  return n ? sqrt(s / (double)n) : 0.0;
}
