/* fuzz_scene.c — libFuzzer target for oc_scene_parse() (untrusted scene files).
 *
 * Whatever parses must satisfy the schema's invariants (unit sun, ranges), and every rejection must
 * leave a one-line reason. The input buffer is exactly `size` bytes, so an over-read past a
 * missing terminator is caught by ASan. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "oc_scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  oc_scene_t *sc = malloc(sizeof *sc);
  char why[512];
  if (!sc) return 0;
  why[0] = '\0';
  int r = oc_scene_parse(sc, (const char *)data, size, "fuzz.json", why, sizeof why);
  if (r == 0) {
    double n = sqrt(sc->sun_dir.x * sc->sun_dir.x + sc->sun_dir.y * sc->sun_dir.y + sc->sun_dir.z * sc->sun_dir.z);
    if (!(fabs(n - 1.0) < 1e-9)) abort();
    if (sc->nsources < 0 || sc->nsources > OC_SCENE_MAX_SOURCES) abort();
    if (!(sc->epoch_period > 0.0 && sc->epoch_period <= 60.0)) abort();
    oc_scene_free(sc);
  } else if (why[0] == '\0' || strchr(why, '\n')) {
    abort(); /* errors are one non-empty line */
  }
  free(sc);
  return 0;
}
