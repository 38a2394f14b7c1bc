/* oc_image.h — linear HDR images and 8-bit PNG output (libpng).
 *
 * A renderer writes linear radiance (RGB) plus the cloud transmittance (A) per pixel. The 8-bit
 * picture is exposure × radiance → ACES fit → sRGB, through shaders/optics.h so the CPU reference
 * and the GL client tone-map identically. PNGs carry text chunks (camera, settings). */
#ifndef OC_COMMON_IMAGE_H
#define OC_COMMON_IMAGE_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
  int w, h;
  float *px; /**< w·h·4 floats, row-major from the top row: linear R, G, B, cloud transmittance */
} oc_image_t;

typedef struct {
  const char *key, *value;
} oc_png_text_t;

/*! oc_image_alloc() : zeroed image; @return 0 or OC_EINVAL (size ≤ 0 or > 16384) / OC_ENOMEM. */
int oc_image_alloc(oc_image_t *img, int w, int h);
void oc_image_free(oc_image_t *img);
/*! oc_image_tonemap() : exposure, ACES fit, sRGB → 8-bit RGB (w·h·3 bytes). A non-finite pixel
 *  shows black but never silently: non-finite pixels are counted and returned (0 when all finite). */
int oc_image_tonemap(const oc_image_t *img, float exposure, uint8_t *rgb8);
/*! oc_png_write() : 8-bit RGB PNG with optional text chunks. Errors name the path. */
int oc_png_write(const char *path, int w, int h, const uint8_t *rgb8, const oc_png_text_t *text, int ntext,
                 char *why, size_t why_len);
/*! oc_png_read() : any 8-bit PNG as RGB (caller frees *rgb8). Text chunk `want_key`, if given and
 *  present, is copied to text_out (NUL-terminated, truncated to text_cap). */
int oc_png_read(const char *path, int *w, int *h, uint8_t **rgb8, const char *want_key, char *text_out,
                size_t text_cap, char *why, size_t why_len);
/*! oc_rgb8_rmse() : RMSE between two 8-bit RGB images of the same size, on the 0–255 scale. */
double oc_rgb8_rmse(const uint8_t *a, const uint8_t *b, int w, int h);

#endif /* OC_COMMON_IMAGE_H */
