/* server_config.c — overcast-server's options: one table, its custom parsers and the checks
 * between options (server_config.h). */
#include "server_config.h"

#include <arpa/inet.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_proxy.h" /* --trusted-proxy */
#include "oc_cli.h"
#include "ocp_wire.h"

static const char *prog = "overcast-server";

/* ---- Custom types ---- */

/* "HOST:PORT", "[V6]:PORT", ":PORT" or "PORT" (the host then 127.0.0.1) into host and *port. */
static int parse_address(const char *p, const oc_cli_opt_t *o, const char *text, char *host, size_t cap, int *port_out) {
  const char *colon = strrchr(text, ':');
  const char *ps = colon ? colon + 1 : text, *h = text;
  size_t n = colon ? (size_t)(colon - text) : 0;
  char *end;
  long port = strtol(ps, &end, 10);
  if (n >= 2 && h[0] == '[' && h[n - 1] == ']') {
    h++;
    n -= 2;
  }
  if (end == ps || *end || port < 0 || port > 65535 || (colon && colon != text && (n == 0 || n >= cap))) {
    oc_cli_fail(p, 0, "--%s: expected HOST:PORT (port 0..65535), got \"%s\"", o->name, text);
    return -1;
  }
  if (!colon || colon == text) {
    snprintf(host, cap, "%s", OCS_CONFIG_DEFAULT_HOST);
  } else {
    memcpy(host, h, n);
    host[n] = 0;
  }
  *port_out = (int)port;
  return 0;
}

static int parse_listen(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  c->listen = text;
  return parse_address(p, o, text, c->host, sizeof c->host, &c->desc.port);
}

static int parse_metrics_listen(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  c->metrics_listen = text;
  c->desc.metrics = 1;
  return parse_address(p, o, text, c->metrics_host, sizeof c->metrics_host, &c->desc.metrics_port);
}

static int parse_redis(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  if (parse_address(p, o, text, c->redis_host, sizeof c->redis_host, &c->desc.redis_port) < 0) return -1;
  if (c->desc.redis_port == 0) {
    oc_cli_fail(p, 0, "--%s: Redis needs a port (1..65535), got \"%s\"", o->name, text);
    return -1;
  }
  c->desc.redis_host = c->redis_host;
  return 0;
}

/* --queue-limits: "SOFT,HARD" in MiB. */
static int parse_queue(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  long a, b;
  char extra;
  if (sscanf(text, "%ld,%ld%c", &a, &b, &extra) != 2 || a < 1 || b < a || b > 65536) {
    oc_cli_fail(p, 0, "--%s: expected SOFT,HARD in MiB (1 ≤ SOFT ≤ HARD ≤ 65536), got \"%s\"", o->name, text);
    return -1;
  }
  c->desc.queue_soft = (uint64_t)a << 20;
  c->desc.queue_hard = (uint64_t)b << 20;
  return 0;
}

/* A count of KiB in the row's range, stored as bytes into an int. */
static int parse_kib(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  char opt[80];
  long v;
  snprintf(opt, sizeof opt, "--%s", o->name);
  if (oc_cli_int(p, opt, text, (long)o->lo, (long)o->hi, &v)) return -1;
  *(int *)oc_cli_field(o, base) = (int)v << 10;
  return 0;
}

static int parse_no_deltas(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  (void)p, (void)o, (void)text;
  ((ocs_config_t *)base)->desc.deltas = -1;
  return 0;
}

/* --region: "LAT,LON,ALT,RADIUS". */
static int parse_region(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  double v[4];
  char *end;
  const char *s = text;
  int ok = 1;
  for (int i = 0; i < 4 && ok; i++) {
    v[i] = strtod(s, &end);
    ok = end != s && (i < 3 ? *end == ',' : !*end);
    s = end + 1;
  }
  if (!ok || !(v[0] >= -90 && v[0] <= 90 && v[1] >= -360 && v[1] <= 360 && v[3] > 0 && v[3] <= 1e6)) {
    oc_cli_fail(p, 0, "--%s: expected LAT,LON,ALT,RADIUS (radius in (0, 1e6] m), got \"%s\"", o->name, text);
    return -1;
  }
  memcpy(c->region, v, sizeof v);
  c->region_given = 1;
  return 0;
}

/* --trusted-proxy: "ADDR[,ADDR...]", numeric (ocs_proxy_list_parse(); the server parses it again). */
static int parse_trusted_proxy(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  ocs_proxy_addr_t a[OCS_PROXY_TRUSTED_MAX];
  char why[160];
  if (ocs_proxy_list_parse(text, a, why, sizeof why) < 0) {
    oc_cli_fail(p, 0, "--%s: %s", o->name, why);
    return -1;
  }
  c->desc.trusted_proxies = text;
  return 0;
}

/* --camera: "LAT,LON,ALT,HEADING,PITCH,FOV" (oc_camera_parse()). */
static int parse_camera(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ocs_config_t *c = base;
  char why[256];
  if (oc_camera_parse(text, &c->camera, why, sizeof why) < 0) {
    oc_cli_fail(p, 0, "--%s: %s", o->name, why);
    return -1;
  }
  c->camera_given = 1;
  return 0;
}

/* --viewport: "WxH", each 1..16384. */
static int parse_viewport(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  int *v = oc_cli_field(o, base);
  int w, h;
  char extra;
  if (sscanf(text, "%dx%d%c", &w, &h, &extra) != 2 || w < 1 || h < 1 || w > 16384 || h > 16384) {
    oc_cli_fail(p, 0, "--%s: expected WxH (1..16384), got \"%s\"", o->name, text);
    return -1;
  }
  v[0] = w;
  v[1] = h;
  return 0;
}

/* ---- The table ---- */

#define SERVE "Serving (the default mode)"
#define OTHER "Other modes"
#define ANY "Any mode"
#define AT(field) offsetof(ocs_config_t, field)
#define DEF(name) OC_CLI_STR(OCS_CONFIG_DEFAULT_##name)
#define MIB_MAX (1 << 24)

static const oc_cli_opt_t opts[] = {
    /* Serving */
    {.name = "listen", .type = OC_CLI_CUSTOM, .parse = parse_listen, .arg = "HOST:PORT",
     .def = OCS_CONFIG_DEFAULT_HOST ":" DEF(PORT), .group = SERVE,
     .help = "address to listen on; port 0 picks a free port; the address bound is printed as \"listening on "
             "HOST:PORT\"; one that is not loopback needs --token or --insecure"},
    {.name = "token", .type = OC_CLI_STRING, .offset = AT(desc.token), .arg = "TEXT", .lo = 1, .hi = OCP_TOKEN_MAX,
     .group = SERVE, .help = "clients must present this token: viewers, and control clients too unless "
                             "--control-token is given"},
    {.name = "control-token", .type = OC_CLI_STRING, .offset = AT(desc.control_token), .arg = "TEXT", .lo = 1,
     .hi = OCP_TOKEN_MAX, .group = SERVE,
     .help = "control clients (overcast-ctl --control-token) must present this token instead of --token, which "
             "is then refused for control: a viewer's credentials cannot change the world; /metrics wants it too"},
    {.name = "insecure", .type = OC_CLI_FLAG, .offset = AT(desc.insecure), .group = SERVE,
     .help = "allow listening (--listen, --metrics-listen) on a non-loopback address without a token"},
    {.name = "metrics-listen", .type = OC_CLI_CUSTOM, .parse = parse_metrics_listen, .arg = "HOST:PORT",
     .def_note = "off", .group = SERVE,
     .help = "serve Prometheus metrics at http://HOST:PORT/metrics (HOST 127.0.0.1 when only PORT is given; "
             "port 0 picks a free port, printed as \"metrics on HOST:PORT\"); scrapes present \"Authorization: "
             "Bearer TOKEN\" when the server has a token (--control-token, else --token); an address that is not "
             "loopback needs a token or --insecure"},
    {.name = "trusted-proxy", .type = OC_CLI_CUSTOM, .parse = parse_trusted_proxy, .arg = "ADDR[,ADDR...]",
     .def_note = "none", .group = SERVE,
     .help = "connections from these addresses (a TLS-terminating HAProxy with send-proxy-v2) must begin with a "
             "PROXY protocol header (v2 or v1); the client address it carries is the one limits (--max-per-address, "
             "--handshake-rate), logs and the audit log see; a PROXY header from any other address is refused"},
    {.name = "audit-log", .type = OC_CLI_STRING, .offset = AT(desc.audit_log), .arg = "FILE", .def_note = "none",
     .group = SERVE,
     .help = "append one JSON line per control request that changes the world (weather, time, pause, resume, sun, "
             "step, reload, disconnect): when, who, what, and the outcome"},
    {.name = "redis", .type = OC_CLI_CUSTOM, .parse = parse_redis, .arg = "HOST:PORT", .def_note = "none",
     .group = SERVE,
     .help = "serve one world with the other front-ends through Redis there (docs/scale-out.md): bricks are "
             "shared (epochs on the clock: what one made, the others do not make; while Redis is down or slow, "
             "every brick is made here), and so is the control history, in the stream oc:ctl (weather, time, sun, "
             "steps apply on every front-end at the same epoch; refused while Redis is unreachable)"},
    {.name = "redis-deadline", .type = OC_CLI_INT, .offset = AT(desc.redis_deadline_ms), .arg = "MS", .lo = 1,
     .hi = 60000, .def_note = "200, and production waits at most a tenth of the epoch period", .group = SERVE,
     .help = "each Redis command's deadline, and how long production waits for a lookup's answers"},
    {.name = "epoch-period", .type = OC_CLI_DOUBLE, .offset = AT(desc.epoch_period), .arg = "S", .lo = 0, .hi = 60,
     .def_note = "the scene's, 1", .group = SERVE,
     .help = "seconds between epochs; 0: epochs are stepped only by control requests (overcast-ctl step)"},
    {.name = "max-viewers", .type = OC_CLI_INT, .offset = AT(desc.world.max_viewers), .arg = "N", .lo = 1,
     .hi = 100000, .def = DEF(MAX_VIEWERS), .group = SERVE, .help = "viewers at once"},
    {.name = "max-budget", .type = OC_CLI_MIB, .offset = AT(desc.world.max_budget), .arg = "MIB", .lo = 1,
     .hi = MIB_MAX, .def_note = "a fair share: a quarter of --total-budget, at most 1024", .group = SERVE,
     .help = "largest budget granted to one viewer"},
    {.name = "total-budget", .type = OC_CLI_MIB, .offset = AT(desc.world.viewer_bytes), .arg = "MIB", .lo = 1,
     .hi = MIB_MAX, .def = DEF(TOTAL_BUDGET), .group = SERVE, .help = "sum of all viewers' budgets"},
    {.name = "cache", .type = OC_CLI_MIB, .offset = AT(desc.world.cache_bytes), .arg = "MIB", .lo = 1, .hi = 1 << 20,
     .def = DEF(CACHE), .group = SERVE, .help = "shared brick cache"},
    {.name = "drain-timeout", .type = OC_CLI_DOUBLE, .offset = AT(desc.drain_s), .arg = "S", .lo = 0.1, .hi = 86400,
     .def = DEF(DRAIN), .group = SERVE,
     .help = "a drain (SIGTERM, overcast-ctl drain) waits this long for viewers to leave, then closes the rest"},
    {.name = "linger", .type = OC_CLI_DOUBLE, .offset = AT(desc.linger_s), .arg = "S", .lo = 0, .hi = 86400,
     .def = DEF(LINGER), .group = SERVE, .help = "keep a dropped viewer's session this long for resume; 0: off"},
    {.name = "max-lingering", .type = OC_CLI_INT, .offset = AT(desc.max_lingering), .arg = "N", .lo = 0,
     .hi = 100000, .def = DEF(MAX_LINGERING), .group = SERVE,
     .help = "dropped viewers kept for resume at once, the oldest let go first; 0: none lingers"},
    {.name = "linger-budget", .type = OC_CLI_MIB, .offset = AT(desc.linger_budget), .arg = "MIB", .lo = 1,
     .hi = MIB_MAX, .def_note = "half of --total-budget", .group = SERVE,
     .help = "sum of the budgets of the viewers kept for resume"},
    {.name = "max-per-address", .type = OC_CLI_INT, .offset = AT(desc.max_per_address), .arg = "N", .lo = 1,
     .hi = 100000, .def = DEF(MAX_PER_ADDRESS), .group = SERVE, .help = "connections at once from one IP address"},
    {.name = "handshake-rate", .type = OC_CLI_DOUBLE, .offset = AT(desc.handshake_rate), .arg = "R", .lo = 0.1,
     .hi = 100000, .def = DEF(HANDSHAKE_RATE), .group = SERVE,
     .help = "connections accepted per second from one IP address, a token bucket the size of --max-per-address"},
    {.name = "idle-timeout", .type = OC_CLI_DOUBLE, .offset = AT(desc.idle_s), .arg = "S", .lo = 0.1, .hi = 86400,
     .def = DEF(IDLE_TIMEOUT), .group = SERVE, .help = "close connections silent this long"},
    {.name = "stall-timeout", .type = OC_CLI_DOUBLE, .offset = AT(desc.stall_s), .arg = "S", .lo = 0.1,
     .hi = 86400, .def = DEF(STALL_TIMEOUT), .group = SERVE, .help = "close connections that stop reading this long"},
    {.name = "queue-limits", .type = OC_CLI_CUSTOM, .parse = parse_queue, .arg = "SOFT,HARD",
     .def = DEF(QUEUE_SOFT) "," DEF(QUEUE_HARD), .group = SERVE,
     .help = "unsent bytes per connection in MiB, 1 ≤ SOFT ≤ HARD ≤ 65536"},
    {.name = "zstd-level", .type = OC_CLI_INT, .offset = AT(desc.zstd_level), .arg = "N", .lo = 1, .hi = 19,
     .def = DEF(ZSTD_LEVEL), .group = SERVE, .help = "compression level"},
    {.name = "send-buffer", .type = OC_CLI_CUSTOM, .parse = parse_kib, .offset = AT(desc.send_buffer), .arg = "KIB",
     .lo = 1, .hi = 1 << 20, .def_note = "the system's", .group = SERVE,
     .help = "kernel send buffer per connection; smaller keeps more of a slow viewer's backlog under the "
             "server's own limits"},
    {.name = "no-deltas", .type = OC_CLI_CUSTOM, .parse = parse_no_deltas, .group = SERVE,
     .help = "send refreshed bricks whole"},
    {.name = "step-gate", .type = OC_CLI_STRING, .offset = AT(desc.step_gate), .arg = "FILE", .group = SERVE,
     .help = "for tests: every step waits, before it produces anything, until FILE exists (the test holds "
             "the producer and releases it by creating the file: a step as long as the test wants, whatever "
             "the machine's speed; at most 600 s)"},
    /* Other modes */
    {.name = "check", .type = OC_CLI_FLAG, .offset = AT(check), .group = OTHER,
     .help = "load the scene, build every source, print a summary and exit"},
    {.name = "inspect", .type = OC_CLI_STRING, .offset = AT(inspect), .arg = "FILE.vdb", .group = OTHER,
     .help = "print the grids of a VDB file and exit: types, classes, voxel size, active voxels, bounding box, "
             "value range"},
    {.name = "json", .type = OC_CLI_FLAG, .offset = AT(json), .group = OTHER,
     .help = "with --inspect: machine-readable output"},
    {.name = "export-vdb", .type = OC_CLI_STRING, .offset = AT(export_path), .arg = "OUT.vdb", .group = OTHER,
     .help = "write a region of the field as a float grid \"density\" and exit"},
    {.name = "region", .type = OC_CLI_CUSTOM, .parse = parse_region, .arg = "LAT,LON,ALT,RADIUS",
     .def_note = "the scene camera's position, " DEF(RADIUS) " m", .group = OTHER,
     .help = "the region to export: a cube of half-size RADIUS metres around a point"},
    {.name = "level", .type = OC_CLI_INT, .offset = AT(level), .arg = "N", .lo = 0, .hi = 21, .def = DEF(LEVEL),
     .group = OTHER, .help = "octree level of the exported voxels"},
    {.name = "save-state", .type = OC_CLI_STRING, .offset = AT(save_path), .arg = "OUT", .group = OTHER,
     .help = "run the server core for one viewer and write the state it holds after the last epoch (a state "
             "file: overcast-view --state OUT renders it)"},
    {.name = "camera", .type = OC_CLI_CUSTOM, .parse = parse_camera, .arg = "LAT,LON,ALT,HEADING,PITCH,FOV",
     .def_note = "the scene's", .group = OTHER, .help = "the viewer's camera for --save-state"},
    {.name = "epochs", .type = OC_CLI_INT, .offset = AT(epochs), .arg = "N", .lo = 1, .hi = 100000,
     .def = DEF(EPOCHS), .group = OTHER, .help = "epochs to step for --save-state"},
    {.name = "budget", .type = OC_CLI_MIB, .offset = AT(budget), .arg = "MIB", .lo = 1, .hi = 1 << 20,
     .def = DEF(BUDGET), .group = OTHER,
     .help = "the viewer's budget for --save-state, counted in 2048-byte slots and 32-byte records"},
    {.name = "viewport", .type = OC_CLI_CUSTOM, .parse = parse_viewport, .offset = AT(viewport), .arg = "WxH",
     .def = DEF(VIEWPORT_W) "x" DEF(VIEWPORT_H), .group = OTHER,
     .help = "the viewer's viewport for --save-state, each side 1..16384"},
    /* Any mode */
    {.name = "scene", .type = OC_CLI_STRING, .offset = AT(scene_path), .arg = "FILE",
     .def_note = "the built-in procedural planet", .group = ANY, .help = "scene file"},
    {.name = "time", .type = OC_CLI_DOUBLE, .offset = AT(time), .arg = "T", .lo = -1e12, .hi = 1e12,
     .def = DEF(TIME), .group = ANY,
     .help = "world time in seconds: of the first epoch (serving, --save-state) or of the field --export-vdb writes"},
    {.name = "threads", .type = OC_CLI_INT, .offset = AT(threads), .arg = "N", .lo = 0, .hi = 64,
     .def_note = "all cores", .group = ANY, .help = "producer threads; 0: all cores"},
    {.name = "quiet", .short_name = 'q', .type = OC_CLI_FLAG, .offset = AT(quiet), .group = ANY,
     .help = "only errors"},
    {.name = "help", .type = OC_CLI_HELP, .group = ANY, .help = "print this and exit"},
    {.name = "version", .type = OC_CLI_VERSION, .group = ANY, .help = "print the version and exit"},
    {0}};

#define NOPTS ((int)(sizeof opts / sizeof *opts) - 1)

static const oc_cli_spec_t spec = {
    .prog = "overcast-server",
    .synopsis = "[options]",
    .about = "Owns the cloud field of a scene (procedural, analytic, or imported from OpenVDB) and serves\n"
             "it to viewers (overcast-view) and control clients (overcast-ctl) over TCP.\n",
    .epilog = "SIGINT or SIGTERM: every client gets a goodbye and the server exits with status 0.\n"
              "exit status: 0 ok, 1 runtime error (bad scene or file), 2 usage error\n",
    .opts = opts,
};

int ocs_config_is_loopback(const char *host) {
  static const unsigned char lo6[16] = {[15] = 1}, v4mapped[12] = {[10] = 0xff, [11] = 0xff};
  unsigned char a[16];
  if (!host) return 1;
  if (inet_pton(AF_INET, host, a) == 1) return a[0] == 127;
  if (inet_pton(AF_INET6, host, a) == 1) return !memcmp(a, lo6, 16) || (!memcmp(a, v4mapped, 12) && a[12] == 127);
  return -1;
}

/* ---- Checks between options ---- */

static int any_given(const unsigned char *given, const char *group) {
  for (int i = 0; i < NOPTS; i++)
    if (given[i] && !strcmp(opts[i].group, group)) return 1;
  return 0;
}

static int check_modes(ocs_config_t *c, const unsigned char *given) {
  if (c->json && !c->inspect) return oc_cli_fail(prog, OC_EXIT_USAGE, "--json goes with --inspect");
  if (c->inspect && (c->check || c->export_path || c->scene_path))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--inspect takes no scene, --check or --export-vdb");
  if ((c->region_given || c->level != OCS_CONFIG_DEFAULT_LEVEL) && !c->export_path)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--region and --level go with --export-vdb");
  if (c->inspect) return OCS_CONFIG_RUN;
  c->serving = !c->check && !c->export_path && !c->save_path;
  if (!c->serving && any_given(given, SERVE))
    return oc_cli_fail(prog, OC_EXIT_USAGE, "serving options go without --check, --export-vdb and --save-state");
  if (c->camera_given && !c->save_path) return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera goes with --save-state");
  if (c->serving && !c->desc.token && !c->desc.insecure && ocs_config_is_loopback(c->host) == 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE,
                       "--listen %s: refusing a non-loopback address without --token (anyone who reaches it could "
                       "take the whole budget); add --token, or --insecure to allow it",
                       c->listen);
  if (c->desc.metrics && !ocs_metrics_token(&c->desc) && !c->desc.insecure && ocs_config_is_loopback(c->metrics_host) == 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE,
                       "--metrics-listen %s: refusing a non-loopback address without a token (anyone who reaches it "
                       "could read who is connected); add --control-token or --token, or --insecure to allow it",
                       c->metrics_listen);
  return OCS_CONFIG_RUN;
}

int ocs_config_parse(ocs_config_t *c, int argc, char **argv) {
  unsigned char given[NOPTS];
  memset(c, 0, sizeof *c);
  c->desc.epoch_period = -1; /* the scene's */
  c->region[3] = OCS_CONFIG_DEFAULT_RADIUS;
  int r = oc_cli_parse(&spec, argc, argv, c, given, NULL);
  if (r) return r > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  if ((r = check_modes(c, given)) != OCS_CONFIG_RUN) return r;
  c->desc.host = c->host;
  c->desc.metrics_host = c->metrics_host;
  c->desc.scene_path = c->scene_path;
  c->desc.world.threads = c->threads;
  c->desc.world.time = c->time;
  if (c->desc.max_lingering == 0) c->desc.linger_s = 0; /* no viewer lingers */
  return OCS_CONFIG_RUN;
}
