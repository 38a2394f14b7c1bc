/* test_brick_value.c — keys and packed values of shared bricks (server/brick_value.h): every
 * field of the identity changes the key; a value round-trips; each kind of damage is named. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <string.h>

#include "test_main.h"
#include "brick_value.h"
#include "oc_err.h"

static const ocs_bkey_in_t base = {.scene = 1, .weather = 2, .sun = 3, .stamp = 4, .node = 5, .channel = 1};

static void test_bkey__every_field_counts(void **state) {
  (void)state;
  ocs_bkey_t k0 = ocs_bkey_make(&base), k1 = ocs_bkey_make(&base);
  assert_memory_equal(&k0, &k1, sizeof k0); /* a pure function of the identity */
  for (int f = 0; f < 6; f++) {
    ocs_bkey_in_t in = base;
    if (f == 0) in.scene ^= 1ull << 63;
    if (f == 1) in.weather++;
    if (f == 2) in.sun++;
    if (f == 3) in.stamp++;
    if (f == 4) in.node++;
    if (f == 5) in.channel++;
    ocs_bkey_t k = ocs_bkey_make(&in);
    assert_true(k.lo != k0.lo || k.hi != k0.hi);
  }
  char text[OCS_BKEY_TEXT];
  ocs_bkey_t k = {0x0123456789abcdefull, 0xfedcba9876543210ull};
  ocs_bkey_text(&k, "oc:b:", text);
  assert_string_equal(text, "oc:b:fedcba98765432100123456789abcdef");
}

static void test_bval__round_trip_and_damage(void **state) {
  (void)state;
  ocs_bkey_t k = ocs_bkey_make(&base), other = {k.lo ^ 1, k.hi};
  uint8_t content[300], v[400];
  for (size_t i = 0; i < sizeof content; i++) content[i] = (uint8_t)(i * 7 + 1);
  size_t len = ocs_bval_pack(&k, content, sizeof content, v, sizeof v);
  assert_int_equal(len, ocs_bval_size(sizeof content));
  const uint8_t *c;
  size_t n;
  assert_int_equal(ocs_bval_unpack(&k, v, len, &c, &n), 0);
  assert_int_equal(n, sizeof content);
  assert_memory_equal(c, content, n);
  assert_int_equal(ocs_bval_unpack(&other, v, len, &c, &n), OC_EINVAL);
  assert_null(c);
  /* every single flipped bit is caught, whichever field it lands in */
  for (size_t i = 0; i < len; i++) {
    for (int b = 0; b < 8; b++) {
      v[i] ^= (uint8_t)(1u << b);
      assert_true(ocs_bval_unpack(&k, v, len, &c, &n) < 0);
      v[i] ^= (uint8_t)(1u << b);
    }
  }
  for (size_t cut = 0; cut < len; cut++) assert_true(ocs_bval_unpack(&k, v, cut, &c, &n) < 0);
  assert_int_equal(ocs_bval_unpack(&k, v, len - 1, &c, &n), OC_ETRUNC);
  v[len] = 0;
  assert_int_equal(ocs_bval_unpack(&k, v, len + 1, &c, &n), OC_ECORRUPT);
  v[0] = 'X';
  assert_int_equal(ocs_bval_unpack(&k, v, len, &c, &n), OC_ECORRUPT);
  v[0] = 'O';
  v[27] = 0xff; /* length over the limit */
  assert_int_equal(ocs_bval_unpack(&k, v, len, &c, &n), OC_ETOOBIG);
  v[27] = 0;
  v[50] ^= 1;
  assert_int_equal(ocs_bval_unpack(&k, v, len, &c, &n), OC_ECHECKSUM);
  /* empty content is a value too (an empty node); short buffers and huge content refused */
  assert_int_equal(ocs_bval_pack(&k, NULL, 0, v, sizeof v), ocs_bval_size(0));
  assert_int_equal(ocs_bval_unpack(&k, v, ocs_bval_size(0), &c, &n), 0);
  assert_int_equal(n, 0);
  assert_int_equal(ocs_bval_pack(&k, content, sizeof content, v, 100), 0);
  assert_int_equal(ocs_bval_pack(&k, content, OCS_BVAL_MAX_CONTENT + 1u, v, sizeof v), 0);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_bkey__every_field_counts),
             cmocka_unit_test(test_bval__round_trip_and_damage))
