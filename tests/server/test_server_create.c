/* test_server_create.c — ocs_server_create() through the library API with a bad --redis: a clear
 * error naming it, nothing left behind (ASan: no use after free, LeakSanitizer: no leak). The CLI
 * refuses these addresses first (server_config.c); through the API the Redis client's own check
 * (ocs_redis_open) refuses them. Stepped mode opens only the control stream's connections, so it
 * meets that refusal in ocs_ctl_open(), whose failure path used to write its message from the
 * stream after freeing it: this test failed there under ASan (heap-use-after-free), as gcc's
 * -Wuse-after-free had warned. Clocked mode meets it first in the brick store's connection. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "test_main.h"
#include "oc_err.h"
#include "ocs_server.h"

static const char *SPHERE =
    "{\"version\":1,\"features\":{\"animation\":false},\"sun\":{\"lat\":20,\"lon\":10},"
    "\"sources\":[{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":2000,\"sigma_t\":0.05}]}";

static void bad_redis(const char *host, int port, double period) {
  oc_scene_t sc;
  char why[512] = "";
  if (oc_scene_parse(&sc, SPHERE, strlen(SPHERE), "test.json", why, sizeof why) < 0) fail_msg("scene: %s", why);
  ocs_server_desc_t d = {.host = "127.0.0.1", .port = 0, .epoch_period = period, .linger_s = 0,
                         .redis_host = host, .redis_port = port, .world = {.threads = 1, .cache_bytes = 16u << 20}};
  ocs_server_t *srv = NULL;
  int r = ocs_server_create(&srv, &sc, &d, why, sizeof why);
  printf("  redis \"%.20s\" port %d, epoch period %g: %s\n", host, port, period, why);
  assert_int_equal(r, OC_EINVAL);
  assert_null(srv);
  assert_non_null(strstr(why, "--redis"));
  oc_scene_free(&sc);
}

static void test_server_create__bad_redis_is_a_clear_error(void **st) {
  (void)st;
  char long_host[300];
  memset(long_host, 'h', sizeof long_host - 1);
  long_host[sizeof long_host - 1] = '\0';
  for (int clocked = 0; clocked < 2; clocked++) {
    bad_redis("127.0.0.1", 0, clocked);
    bad_redis("127.0.0.1", 70000, clocked);
    bad_redis("", 6379, clocked);
    bad_redis(long_host, 6379, clocked);
  }
}

OC_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_server_create__bad_redis_is_a_clear_error))
