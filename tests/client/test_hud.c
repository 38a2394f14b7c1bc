/* test_hud.c — HUD text drawn into an RGB8 image (client/hud.c over stb_easy_font): lit pixels in
 * the text colour, scaled by scale², a backdrop, clipping at every edge, the standard lines. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "hud.h"

#define W 200
#define H 60

static int count_colour(const uint8_t *rgb, const uint8_t c[3]) {
  int n = 0;
  for (int i = 0; i < W * H; i++) n += rgb[3 * i] == c[0] && rgb[3 * i + 1] == c[1] && rgb[3 * i + 2] == c[2];
  return n;
}

static void test_hud__text(void **state) {
  (void)state;
  static uint8_t img[W * H * 3];
  const uint8_t white[3] = {255, 255, 255}, grey[3] = {200, 200, 200};
  memset(img, 200, sizeof img);
  assert_int_equal(ocv_hud_text(img, W, H, 4, 4, 1, "HUD 1.0", white), 12);
  int lit1 = count_colour(img, white);
  assert_true(lit1 > 20);
  assert_true(count_colour(img, grey) < W * H); /* the backdrop darkened some pixels */
  for (int y = 0; y < H; y++) /* nothing lit left of the text or below its line */
    for (int x = 0; x < W; x++)
      if (!memcmp(&img[3 * (y * W + x)], white, 3)) assert_true(x >= 4 && y >= 4 && y < 4 + 12);
  memset(img, 200, sizeof img);
  assert_int_equal(ocv_hud_text(img, W, H, 4, 4, 2, "HUD 1.0", white), 24);
  assert_int_equal(count_colour(img, white), 4 * lit1); /* each font pixel becomes 2×2 */
  memset(img, 200, sizeof img);
  assert_int_equal(ocv_hud_text(img, W, H, 4, 4, 1, "a\nb\nc", white), 36);
  /* clipped at every edge, never written outside */
  ocv_hud_text(img, W, H, -30, -5, 3, "clipped text that runs well past the right edge", white);
  ocv_hud_text(img, W, H, W - 3, H - 3, 2, "x\ny", white);
  assert_int_equal(ocv_hud_text(NULL, W, H, 0, 0, 1, "x", white), 0);
}

static void test_hud__format(void **state) {
  (void)state;
  ocv_hud_stats_t s = {.frame_ms = 16.7, .trace_ms = 3.25, .reproject_ms = 0.5, .epoch = 42, .epoch_age_s = 0.4,
                       .bricks = 1234, .resident_bytes = 48u << 20, .budget_bytes = 64u << 20, .bytes_per_s = 2048,
                       .renderer = "gl"};
  char buf[512];
  ocv_hud_format(&s, buf, sizeof buf);
  assert_non_null(strstr(buf, "frame 16.7 ms"));
  assert_non_null(strstr(buf, "gpu trace 3.25 ms"));
  assert_non_null(strstr(buf, "epoch 42"));
  assert_non_null(strstr(buf, "1234 bricks, 48.0 of 64.0 MiB"));
  assert_non_null(strstr(buf, "received 2.0 KiB/s"));
  s.trace_ms = -1;
  ocv_hud_format(&s, buf, sizeof buf);
  assert_null(strstr(buf, "gpu"));
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_hud__text), cmocka_unit_test(test_hud__format))
