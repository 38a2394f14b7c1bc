/* test_world_share.c — two front-ends' worlds of one scene sharing bricks (world.h, "Sharing
 * bricks"), relayed by hand as the network layer relays them through Redis: what one made is
 * exported, the other looks its queue up and is offered it; it then makes nothing that was
 * shared, and its viewer's states are the first one's, brick for brick. A brick held back is not
 * made and stays queued; damaged offers are refused; the identity depends on every input; an
 * empty brick costs the cache no more than the bytes it counts. */
#include <malloc.h> /* mallinfo2 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "world.h"

static const char *SPHERE =
    "{\"version\":1,\"features\":{\"animation\":false},\"sun\":{\"lat\":20,\"lon\":10},"
    "\"sources\":[{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":2000,\"sigma_t\":0.05},"
    "{\"type\":\"box\",\"lat\":0.05,\"lon\":0.02,\"alt\":1500,\"size\":[3000,2000,1500],\"sigma_t\":0.01}]}";

static ocs_world_t *world(uint64_t content_id) {
  oc_scene_t sc;
  char why[512];
  if (oc_scene_parse(&sc, SPHERE, strlen(SPHERE), "test.json", why, sizeof why) < 0) fail_msg("scene: %s", why);
  ocs_world_desc_t d = {.threads = 2, .cache_bytes = 64u << 20, .validate = 1, .clocked = 1, .content_id = content_id};
  ocs_world_t *w = NULL;
  if (ocs_world_create(&w, &sc, &d, why, sizeof why) < 0) fail_msg("world: %s", why);
  oc_scene_free(&sc);
  return w;
}

static ocs_viewer_t *viewer(ocs_world_t *w) {
  ocs_plan_desc_t d = {.budget = 4u << 20, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 18,
                       .split_fraction = 0.5, .reserve = 0.1};
  ocs_viewer_t *v = NULL;
  char why[256];
  if (ocs_world_add_viewer(w, &d, &v, NULL, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  oc_camera_t c = oc_camera_from_pose((oc_camera_pose_t){{0.0, 0.0, 6000.0}, 0.0, -30.0, 60.0});
  ocs_view_t view = {c.pos, c.forward, c.up, 60.0, 160, 90};
  assert_int_equal(ocs_viewer_set_view(v, &view), 0);
  return v;
}

static void tick(ocs_world_t *w, ocs_viewer_t *v, uint64_t n) {
  assert_int_equal(ocs_world_step_at(w, n, (double)n), 0);
  ocs_epoch_out_t o;
  if (ocs_viewer_in_flight(v) && ocs_viewer_output(v, &o) == 0) assert_int_equal(ocs_viewer_ack(v, o.state->epoch), 0);
}

static uint64_t produced(const ocs_world_t *w) {
  ocs_world_stats_t s;
  ocs_world_stats(w, &s);
  return s.bricks_produced;
}

/* The shared store, as Redis holds it: identity → exported bytes. */
typedef struct {
  ocs_bkey_t id;
  size_t n;
  uint8_t bytes[OCS_SHARE_MAX_BYTES];
} stored_t;
typedef struct {
  stored_t *v;
  size_t n, cap;
} store_t;

static void store_made(store_t *s, ocs_world_t *w) {
  oc_key_t keys[256];
  uint64_t stamps[256];
  size_t n;
  while ((n = ocs_world_made_take(w, keys, stamps, 256)) > 0)
    for (size_t i = 0; i < n; i++) {
      if (s->n == s->cap) {
        s->cap = s->cap ? 2 * s->cap : 256;
        s->v = realloc(s->v, s->cap * sizeof *s->v);
        assert_non_null(s->v);
      }
      stored_t *e = &s->v[s->n];
      e->id = ocs_world_brick_id(w, keys[i], stamps[i]);
      e->n = ocs_world_export(w, keys[i], stamps[i], e->bytes, sizeof e->bytes);
      assert_true(e->n > 0); /* made this production: still cached */
      s->n++;
    }
}

static const stored_t *store_find(const store_t *s, ocs_bkey_t id) {
  for (size_t i = 0; i < s->n; i++)
    if (s->v[i].id.lo == id.lo && s->v[i].id.hi == id.hi) return &s->v[i];
  return NULL;
}

/* B's queue looked up in the store and offered, as after every tick. @return bricks offered. */
static size_t relay(const store_t *s, ocs_world_t *b) {
  oc_key_t key;
  uint64_t stamp;
  size_t taken = 0;
  for (size_t i = 0; ocs_world_queue_item(b, i, &key, &stamp) == 0; i++) {
    const stored_t *e = store_find(s, ocs_world_brick_id(b, key, stamp));
    if (e && ocs_world_offer(b, key, stamp, e->bytes, e->n) == 1) taken++;
  }
  return taken;
}

static void test_share__made_once_states_equal(void **st) {
  (void)st;
  ocs_world_t *a = world(77), *b = world(77);
  ocs_viewer_t *va = viewer(a), *vb = viewer(b);
  store_t s = {0};
  size_t offered = 0;
  for (uint64_t n = 1; n <= 16; n++) {
    tick(a, va, n);
    assert_true(ocs_world_produce(a, 1e9, 0) >= 0);
    store_made(&s, a);
    tick(b, vb, n);
    assert_true(ocs_world_produce(b, 0.0, 0) >= 0); /* the queue of the tick is made (targets), nothing else */
    offered += relay(&s, b);
    assert_true(ocs_world_produce(b, 1e9, 0) >= 0);
  }
  print_message("A made %llu bricks, B %llu; %zu offered to B\n", (unsigned long long)produced(a),
                (unsigned long long)produced(b), offered);
  assert_true(produced(a) > 50);
  assert_true(offered > 50);
  assert_true(produced(b) == 0);
  ocs_epoch_out_t oa, ob;
  assert_int_equal(ocs_viewer_output(va, &oa), 0);
  assert_int_equal(ocs_viewer_output(vb, &ob), 0);
  assert_true(oa.state->brick_count > 10);
  assert_int_equal(oa.state->node_count, ob.state->node_count);
  assert_true(oc_state_digest(oa.state) == oc_state_digest(ob.state));
  free(s.v);
  ocs_world_free(a);
  ocs_world_free(b);
}

/* Without a content id nothing is logged for sharing; another id is another identity. */
static void test_share__identity(void **st) {
  (void)st;
  ocs_world_t *a = world(77), *c = world(78), *z = world(0);
  ocs_bkey_t ka = ocs_world_brick_id(a, 5, 9), kc = ocs_world_brick_id(c, 5, 9);
  assert_true(ka.lo != kc.lo || ka.hi != kc.hi);
  ocs_bkey_t k2 = ocs_world_brick_id(a, 5, 10), k3 = ocs_world_brick_id(a, 6, 9);
  assert_true(k2.lo != ka.lo && k3.lo != ka.lo);
  /* the sun's bits and the weather history count */
  assert_int_equal(ocs_world_set_sun(a, (oc_dvec3){0.0, 0.6, 0.8}), 0);
  ocs_bkey_t ks = ocs_world_brick_id(a, 5, 9);
  assert_true(ks.lo != ka.lo || ks.hi != ka.hi);
  ocs_viewer_t *v = viewer(z);
  tick(z, v, 1);
  assert_true(ocs_world_produce(z, 1e9, 0) > 0);
  oc_key_t keys[4];
  uint64_t stamps[4];
  assert_int_equal(ocs_world_made_take(z, keys, stamps, 4), 0);
  ocs_world_free(a);
  ocs_world_free(c);
  ocs_world_free(z);
}

/* Held back: not made, still queued; cleared: made. Damaged offers are refused. */
static void test_share__held_back_and_damaged(void **st) {
  (void)st;
  ocs_world_t *w = world(5);
  ocs_viewer_t *v = viewer(w);
  tick(w, v, 1);
  assert_true(ocs_world_produce(w, 0.0, 0) >= 0);
  size_t q = ocs_world_queue_length(w);
  assert_true(q > 0);
  oc_key_t key;
  uint64_t stamp;
  for (size_t i = 0; ocs_world_queue_item(w, i, &key, &stamp) == 0; i++) ocs_world_hold_back(w, key, stamp);
  assert_int_equal(ocs_world_produce(w, 1e9, 0), 0);
  assert_true(produced(w) == 0 && ocs_world_queue_length(w) == q);
  ocs_world_hold_clear(w);
  assert_true(ocs_world_produce(w, 1e9, 0) > 0);
  assert_true(produced(w) > 0);
  oc_key_t keys[1];
  uint64_t stamps[1];
  assert_int_equal(ocs_world_made_take(w, keys, stamps, 1), 1);
  uint8_t bytes[OCS_SHARE_MAX_BYTES];
  size_t n = ocs_world_export(w, keys[0], stamps[0], bytes, sizeof bytes);
  assert_true(n > 0);
  /* offered back where it is cached: not needed */
  assert_int_equal(ocs_world_offer(w, keys[0], stamps[0], bytes, n), 0);
  ocs_world_t *x = world(5);
  uint8_t bad[OCS_SHARE_MAX_BYTES];
  memcpy(bad, bytes, n);
  bad[0] = 7; /* no such kind */
  assert_int_equal(ocs_world_offer(x, keys[0], stamps[0], bad, n), OC_ECORRUPT);
  assert_int_equal(ocs_world_offer(x, keys[0], stamps[0], bytes, n - 1), OC_ECORRUPT); /* short */
  memcpy(bad, bytes, n);
  float nan = __builtin_nanf("");
  memcpy(bad + 1, &nan, 4); /* a range no encoder makes */
  assert_int_equal(ocs_world_offer(x, keys[0], stamps[0], bad, n), OC_ECORRUPT);
  assert_int_equal(ocs_world_offer(x, keys[0], stamps[0], bytes, n), 1);
  assert_int_equal(ocs_world_export(x, keys[0], stamps[0], bad, sizeof bad), n);
  assert_memory_equal(bad, bytes, n); /* what went in comes out */
  assert_int_equal(ocs_world_export(x, keys[0] ^ 1, stamps[0], bad, sizeof bad), 0);
  ocs_world_free(x);
  ocs_world_free(w);
}

/* Three made bricks in four are empty: the cache counts such a payload by its head (kind, ranges),
 * and its memory must be that, not a whole payload with codes (2 KiB each: a process held about
 * twice its cache's cap). 4 096 empty bricks offered into the cache: what the heap grew by, per
 * brick, the entry's own bookkeeping included. glibc's counters only (ASan has its own allocator). */
static void test_share__empty_bricks_cost_their_head(void **st) {
  (void)st;
#if defined(__SANITIZE_ADDRESS__)
  skip();
#endif
  ocs_world_t *w = world(9);
  uint8_t empty[1 + 8 * OC_CHANNELS] = {OC_NODE_EMPTY}; /* kind, then both ranges [0, 0] */
  enum { N = 4096 };
  size_t before = mallinfo2().uordblks;
  oc_key_t k0 = oc_key_make(14, 1000, 2000, 3000);
  for (uint32_t i = 0; i < N; i++)
    assert_int_equal(ocs_world_offer(w, oc_key_neighbor(k0, (int)(i % 64), (int)(i / 64), 0), 7, empty, sizeof empty), 1);
  double per = (double)(mallinfo2().uordblks - before) / N;
  printf("an empty brick in the cache: %.0f bytes of heap\n", per);
  assert_true(per > 0.0 && per < 512.0);
  ocs_world_free(w);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_share__empty_bricks_cost_their_head),
             cmocka_unit_test(test_share__made_once_states_equal),
             cmocka_unit_test(test_share__identity),
             cmocka_unit_test(test_share__held_back_and_damaged))
