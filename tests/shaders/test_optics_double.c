/* test_optics_double.c — the checks of test_optics.c run on the double build of shaders/optics.h.
 *
 * OCG_REAL_DOUBLE makes ocg_real double and OCG_R(x) a double literal (oc_port.h), so the same
 * formulas are exercised with EPS = DBL_EPSILON; tolerances in test_optics.c scale with EPS or switch
 * on OCG_REAL_DOUBLE where the error model differs (phase normalisation). One source of checks, two
 * precisions: a fix in one cannot be forgotten in the other. */
#define OCG_REAL_DOUBLE
#include "test_optics.c"
