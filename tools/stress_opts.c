/* stress_opts.c — overcast-stress's options: one table (common/oc_cli.h), from which the options
 * are parsed and --help is printed, its custom parsers, and the checks between options. */
#include <arpa/inet.h> /* inet_pton */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc.h"
#include "stress.h"

static const char *prog = "overcast-stress";

/* ---- Custom parsers (oc_cli_parse_fn) ---- */

/* An integer in the row's range; the message names the option. */
static int row_int(const char *p, const oc_cli_opt_t *o, const char *text, long *v) {
  char opt[80];
  snprintf(opt, sizeof opt, "--%s", o->name);
  return oc_cli_int(p, opt, text, (long)o->lo, (long)o->hi, v);
}

/* An integer in the row's range into a long. */
static int opt_long(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  return row_int(p, o, text, (long *)oc_cli_field(o, base));
}

/* An integer in the row's range into a uint64_t. */
static int opt_u64(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  long v;
  if (row_int(p, o, text, &v) < 0) return -1;
  *(uint64_t *)oc_cli_field(o, base) = (uint64_t)v;
  return 0;
}

/* The next item of a comma-separated list at *s (NULL: the list is over): its start and length;
 * *s moves past it. @return 0 when the list is over. */
static int next_item(const char **s, const char **item, size_t *len) {
  if (!*s) return 0;
  const char *comma = strchr(*s, ',');
  *item = *s;
  *len = comma ? (size_t)(comma - *s) : strlen(*s);
  *s = comma ? comma + 1 : NULL;
  return 1;
}

/* "a,b,c" → integers in the row's range. @return count, or -1 after a message naming the option. */
static int parse_int_list(const char *p, const oc_cli_opt_t *o, const char *text, long *out, int cap) {
  int n = 0;
  const char *item;
  size_t len;
  for (const char *s = text; next_item(&s, &item, &len); n++) {
    char buf[64];
    if (len == 0 || len >= sizeof buf || n >= cap)
      return oc_cli_fail(p, -1, "--%s: expected a comma-separated list of at most %d integers, got \"%s\"", o->name, cap,
                         text);
    memcpy(buf, item, len);
    buf[len] = '\0';
    if (row_int(p, o, buf, &out[n]) < 0) return -1;
  }
  return n;
}

#define INT_LIST(fn, count, array)                                                        \
  static int fn(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {    \
    stress_opts_t *c = base;                                                              \
    int cap = (int)(sizeof c->array / sizeof c->array[0]);                                \
    return (c->count = parse_int_list(p, o, text, c->array, cap)) < 0 ? -1 : 0;           \
  }
INT_LIST(opt_budget, nbudgets, budgets_mib)
INT_LIST(opt_depth, ndepths, depths)
INT_LIST(opt_sweep_budgets, nsweep_budgets, sweep_budgets_mib)
INT_LIST(opt_sweep_depths, nsweep_depths, sweep_depths)
#undef INT_LIST

static int opt_paths(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  stress_opts_t *c = base;
  int n = 0, cap = (int)(sizeof c->paths / sizeof c->paths[0]);
  const char *item;
  size_t len;
  for (const char *s = text; next_item(&s, &item, &len); n++) {
    int k = stress_path_parse(item, len);
    if (k < 0)
      return oc_cli_fail(p, -1, "--%s: unknown path \"%.*s\" (orbit, dive, cruise, teleport, random)", o->name, (int)len,
                         item);
    if (n >= cap) return oc_cli_fail(p, -1, "--%s: at most %d entries", o->name, cap);
    c->paths[n] = k;
  }
  c->npaths = n;
  return 0;
}

static int opt_faults(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  static const char *const names[] = {"stall", "drop", "garbage", "restart"};
  int f = 0;
  const char *item;
  size_t len;
  for (const char *s = text; next_item(&s, &item, &len);) {
    int k = -1;
    if (len == 3 && !strncmp(item, "all", 3)) {
      f |= (1 << STRESS_FK_COUNT) | ((1 << STRESS_FK_COUNT) - 1);
      k = 4;
    }
    for (int i = 0; i < 4 && k < 0; i++)
      if (strlen(names[i]) == len && !strncmp(item, names[i], len)) k = i;
    if (k < 0)
      return oc_cli_fail(p, -1, "--%s: unknown fault \"%.*s\" (stall, drop, garbage, restart, all)", o->name, (int)len,
                         item);
    if (k < 4) f |= 1 << k;
  }
  ((stress_opts_t *)base)->faults = f;
  return 0;
}

/* --rebalance-at "S:MIB". */
static int opt_rebalance(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  stress_opts_t *c = base;
  char step[32];
  const char *colon = strchr(text, ':');
  if (!colon || (size_t)(colon - text) >= sizeof step)
    return oc_cli_fail(p, -1, "--%s: give STEP:MIB, e.g. 3:2 (got \"%s\")", o->name, text);
  memcpy(step, text, (size_t)(colon - text));
  step[colon - text] = 0;
  if (oc_cli_int(p, "--rebalance-at STEP", step, 1, STRESS_MAX_STEPS, &c->rebalance_at) ||
      oc_cli_int(p, "--rebalance-at MIB", colon + 1, 1, 65536, &c->rebalance_mib))
    return -1;
  return 0;
}

static int opt_connect(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  stress_opts_t *c = base;
  if (ocv_parse_address(text, c->host, sizeof c->host, &c->port) < 0)
    return oc_cli_fail(p, -1, "--%s: expected HOST:PORT (port 1..65535), got \"%s\"", o->name, text);
  return 0;
}

static int opt_source(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  struct in6_addr ip;
  if (strlen(text) >= OCV_HOST_MAX || (inet_pton(AF_INET, text, &ip) != 1 && inet_pton(AF_INET6, text, &ip) != 1))
    return oc_cli_fail(p, -1, "--%s: expected a numeric IPv4 or IPv6 address (e.g. 127.0.0.2), got \"%s\"", o->name, text);
  ((stress_opts_t *)base)->source = text;
  return 0;
}

static int opt_server_arg(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  stress_opts_t *c = base;
  int cap = (int)(sizeof c->server_args / sizeof c->server_args[0]);
  if (c->nserver_args >= cap) return oc_cli_fail(p, -1, "--%s: at most %d", o->name, cap);
  c->server_args[c->nserver_args++] = (char *)text;
  return 0;
}

static int opt_size(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  stress_opts_t *c = base;
  char opt[80];
  snprintf(opt, sizeof opt, "--%s", o->name);
  return oc_cli_size(p, opt, text, &c->width, &c->height);
}

static int opt_restart_by(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  if (strcmp(text, "kill") && strcmp(text, "drain")) return oc_cli_fail(p, -1, "--%s \"%s\": kill or drain", o->name, text);
  ((stress_opts_t *)base)->restart_drain = !strcmp(text, "drain");
  return 0;
}

static int opt_detail_ref(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  static const char *const names[] = {[STRESS_DETAIL_REF_HELD] = "held", [STRESS_DETAIL_REF_SECONDS] = "seconds",
                                      [STRESS_DETAIL_REF_EPOCHS] = "epochs"};
  for (int k = 0; k < 3; k++)
    if (!strcmp(text, names[k])) {
      ((stress_opts_t *)base)->detail_ref = k;
      return 0;
    }
  return oc_cli_fail(p, -1, "--%s: expected held, seconds or epochs, got \"%s\"", o->name, text);
}

static int opt_plot(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  if (!*text) return oc_cli_fail(p, -1, "--%s: expected a file prefix, e.g. docs/images/stress_ramp", o->name);
  ((stress_opts_t *)base)->plot = text;
  return 0;
}

static int opt_no_reference(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  (void)p, (void)o, (void)text;
  ((stress_opts_t *)base)->reference = 0;
  return 0;
}

/* ---- The table ---- */

#define SERVER "The server"
#define VIEWERS "The viewers"
#define RUN "The run"
#define RAMP "Ramp mode (--ramp)"
#define SWEEP "Sweep mode (--sweep-budgets)"
#define FAULTS "Fault mode (--faults; see below)"
#define OTHER "Other"
#define AT(field) offsetof(stress_opts_t, field)
#define DEF(x) OC_CLI_STR(x)

static const oc_cli_opt_t opts[] = {
    {.name = "spawn", .type = OC_CLI_FLAG, .offset = AT(spawn), .group = SERVER,
     .help = "start overcast-server on 127.0.0.1:0 as a child process (the default)"},
    {.name = "server", .type = OC_CLI_STRING, .offset = AT(server_path), .arg = "PATH",
     .def_note = "the one next to this program", .group = SERVER, .help = "the overcast-server to start"},
    {.name = "scene", .type = OC_CLI_STRING, .offset = AT(scene), .arg = "FILE",
     .def_note = "the built-in procedural planet", .group = SERVER, .help = "its scene"},
    {.name = "epoch-period", .type = OC_CLI_DOUBLE, .offset = AT(epoch_period), .arg = "S", .lo = 0, .hi = 60,
     .def_note = "the scene's; 0 with --faults, and with --sweep-budgets", .group = SERVER,
     .help = "its epoch period; 0: stepped by this tool, one step once every viewer has the last one's state (or "
             "gave up on it)"},
    {.name = "server-threads", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(server_threads), .arg = "N",
     .lo = 1, .hi = 64, .def_note = "all cores", .group = SERVER, .help = "its producer threads"},
    {.name = "connect", .type = OC_CLI_CUSTOM, .parse = opt_connect, .arg = "HOST:PORT", .group = SERVER,
     .help = "use a running server instead"},
    {.name = "server-pid", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(server_pid), .arg = "PID", .lo = 1,
     .hi = 1L << 30, .group = SERVER, .help = "with --connect: a local server process to read RSS and CPU from"},
    {.name = "token", .type = OC_CLI_STRING, .offset = AT(token), .arg = "TEXT", .lo = 1, .hi = OCP_TOKEN_MAX,
     .group = SERVER, .help = "the server's token (passed on with --spawn)"},
    {.name = "source-address", .type = OC_CLI_CUSTOM, .parse = opt_source, .arg = "IP",
     .def_note = "the system's choice", .group = SERVER,
     .help = "the viewers and the fault connections connect from this local address (bound before connecting, port "
             "0), e.g. 127.0.0.2: Linux routes all of 127.0.0.0/8 to the loopback (the control connection keeps the "
             "system's choice; fault connections need IPv4)"},
    {.name = "server-arg", .type = OC_CLI_CUSTOM, .parse = opt_server_arg, .arg = "ARG", .group = SERVER,
     .help = "passed on to the spawned server (repeatable, at most 32), e.g. --stall-timeout"},

    {.name = "viewers", .type = OC_CLI_INT, .offset = AT(viewers), .arg = "N", .lo = 1, .hi = STRESS_MAX_VIEWERS,
     .def = "5", .group = VIEWERS, .help = "how many"},
    {.name = "paths", .type = OC_CLI_CUSTOM, .parse = opt_paths, .arg = "LIST", .def_note = "all five",
     .group = VIEWERS, .help = "camera paths, assigned round-robin: orbit, dive, cruise, teleport, random"},
    {.name = "budget", .type = OC_CLI_CUSTOM, .parse = opt_budget, .arg = "LIST", .lo = 1, .hi = 65536,
     .def_note = "16", .group = VIEWERS, .help = "budgets in MiB, round-robin"},
    {.name = "max-depth", .type = OC_CLI_CUSTOM, .parse = opt_depth, .arg = "LIST", .lo = 0, .hi = 21,
     .def_note = "21", .group = VIEWERS, .help = "deepest octree levels, round-robin"},
    {.name = "size", .type = OC_CLI_CUSTOM, .parse = opt_size, .arg = "WxH", .def = "320x180", .group = VIEWERS,
     .help = "each viewer's viewport"},
    {.name = "full-sessions", .type = OC_CLI_FLAG, .offset = AT(full_sessions), .group = VIEWERS,
     .help = "keep every brick's codes as overcast-view does (default: lean sessions that verify each state by its "
             "digest checksum and keep 12 bytes a brick, so N x budget may exceed this machine's memory)"},
    {.name = "share-paths", .type = OC_CLI_FLAG, .offset = AT(share_paths), .group = VIEWERS,
     .help = "every viewer flies its path with the same seed: viewers on one path share a region (default: each "
             "viewer its own seed, disjoint paths)"},
    {.name = "seed", .type = OC_CLI_CUSTOM, .parse = opt_u64, .offset = AT(seed), .arg = "N", .lo = 0,
     .hi = 2147483647L, .def = "1", .group = VIEWERS, .help = "camera paths' seed"},
    {.name = "time-scale", .type = OC_CLI_DOUBLE, .offset = AT(time_scale), .arg = "S", .lo = 0, .hi = 1e6,
     .def_note = "the server's", .group = VIEWERS,
     .help = "world seconds per second, set on the server before the viewers come (a control request; e.g. 60: an "
             "animated scene's content changes faster, which --verify-content's ages then show)"},
    {.name = "tick-hz", .type = OC_CLI_DOUBLE, .offset = AT(tick_hz), .arg = "F", .lo = 0.1, .hi = 1000, .def = "10",
     .group = VIEWERS, .help = "camera updates per second, with a period"},
    {.name = "step-seconds", .type = OC_CLI_DOUBLE, .offset = AT(step_seconds), .arg = "S", .lo = 0.001, .hi = 3600,
     .def = "1", .group = VIEWERS, .help = "stepped: path seconds per epoch"},
    {.name = "teleport-every", .type = OC_CLI_DOUBLE, .offset = AT(teleport_every), .arg = "S", .lo = 0.1, .hi = 1e6,
     .def = "10", .group = VIEWERS, .help = "path seconds between teleports"},
    {.name = "dive-seconds", .type = OC_CLI_DOUBLE, .offset = AT(dive_seconds), .arg = "S", .lo = 0.1, .hi = 1e6,
     .def = "30", .group = VIEWERS, .help = "path seconds from 1000 km down to 10 m"},

    {.name = "epochs", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(epochs), .arg = "E", .lo = 1,
     .hi = STRESS_MAX_STEPS, .def_note = "8 unless --duration is given; 12 with --faults", .group = RUN,
     .help = "stepped: E steps; with a period: until every viewer has E states"},
    {.name = "duration", .type = OC_CLI_DOUBLE, .offset = AT(duration), .arg = "S", .lo = 0.1, .hi = 1e6, .group = RUN,
     .help = "run this long (stepped: keep stepping until then)"},
    {.name = "timeout", .type = OC_CLI_DOUBLE, .offset = AT(timeout), .arg = "S", .lo = 0.1, .hi = 86400, .def = "120",
     .group = RUN, .help = "for connecting, each step, and each wait"},
    {.name = "json", .type = OC_CLI_STRING, .offset = AT(json), .arg = "FILE", .group = RUN,
     .help = "write everything measured"},
    {.name = "verify-content", .type = OC_CLI_DOUBLE, .offset = AT(verify_content), .arg = "F", .lo = 0, .hi = 1,
     .def = "0", .group = RUN,
     .help = "re-produce a random fraction F (e.g. 0.01) of the bricks each viewer receives, in this process with a "
             "world of the server's scene, at the stamps s, s-1, s-2 (and older, to say how old) of the state's world "
             "time, and count its content age; a brick matching none is a MISMATCH (a failure). Off-thread, at the "
             "lowest priority; what is left is verified after the run"},
    {.name = "verify-queue", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(verify_queue), .arg = "N", .lo = 1,
     .hi = 1L << 20, .def = "256", .group = RUN,
     .help = "samples waiting for the verifier at most; more are dropped, counted (F is what is offered, the "
             "verifier's pace what is done)"},
    {.name = "verify-drain", .type = OC_CLI_DOUBLE, .offset = AT(verify_drain_s), .arg = "S", .lo = 0, .hi = 86400,
     .def = "300", .group = RUN, .help = "seconds to verify what is left after the run or a ramp phase"},
    {.name = "rebalance-at", .type = OC_CLI_CUSTOM, .parse = opt_rebalance, .arg = "S:MIB", .group = RUN,
     .help = "stepped: after step S, set viewer 0's budget to MIB (a control \"budget\", BUDGET to the viewer); "
             "every state is checked against the budget in force as the session defines it, and at the end MIB "
             "must be in force"},

    {.name = "ramp", .type = OC_CLI_FLAG, .offset = AT(ramp), .group = RAMP,
     .help = "for each --budget: N = --ramp-from, x2, .. --ramp-max viewers, all at that budget, one phase each on "
             "the same spawned server (needs a period); stops at the first phase not sustained (the rule: below) and "
             "reports the largest N sustained per budget"},
    {.name = "ramp-all", .type = OC_CLI_FLAG, .offset = AT(ramp_all), .group = RAMP,
     .help = "measure every phase up to --ramp-max even after one was not sustained (figures against N; the "
             "largest sustained N is unchanged)"},
    {.name = "plot", .type = OC_CLI_CUSTOM, .parse = opt_plot, .arg = "PREFIX", .group = RAMP,
     .help = "PREFIX-age.png (content age p99 against N) and PREFIX-detail.png (time to full detail against N, "
             "stepped beside it)"},
    {.name = "no-reference", .type = OC_CLI_CUSTOM, .parse = opt_no_reference, .group = RAMP,
     .help = "no stepped reference (time to detail is not judged)"},
    {.name = "reference-teleports", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(ref_teleports), .arg = "K",
     .lo = 1, .hi = 100, .def = "3", .group = RAMP, .help = "teleports the stepped reference measures"},
    {.name = "detail-reference", .type = OC_CLI_CUSTOM, .parse = opt_detail_ref, .arg = "M", .def = "held",
     .group = RAMP,
     .help = "what the rule compares time to full detail with: held (the larger of the stepped server's seconds and "
             "its epochs x the period, what a server whose epochs wait for their bricks takes on the clock), seconds "
             "(stepped as fast as it makes epochs) or epochs (x the period)"},
    {.name = "ramp-from", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(ramp_from), .arg = "N", .lo = 1,
     .hi = STRESS_MAX_VIEWERS, .def = "1", .group = RAMP, .help = "the first phase's viewers"},
    {.name = "ramp-max", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(ramp_max), .arg = "N", .lo = 1,
     .hi = STRESS_MAX_VIEWERS, .def = DEF(STRESS_MAX_VIEWERS), .group = RAMP, .help = "the last phase's at most"},
    {.name = "ramp-seconds", .type = OC_CLI_DOUBLE, .offset = AT(ramp_seconds), .arg = "S", .lo = 0.5, .hi = 3600,
     .def = "10", .group = RAMP, .help = "each phase's measured time, after its warm-up"},
    {.name = "ramp-warmup", .type = OC_CLI_DOUBLE, .offset = AT(ramp_warmup), .arg = "S", .lo = 0, .hi = 3600,
     .def = "5", .group = RAMP, .help = "each phase's warm-up"},

    {.name = "sweep-budgets", .type = OC_CLI_CUSTOM, .parse = opt_sweep_budgets, .arg = "LIST", .lo = 0, .hi = 65536,
     .group = SWEEP, .help = "MiB (0: 1 byte, the smallest the server accepts), with --sweep-depths"},
    {.name = "sweep-depths", .type = OC_CLI_CUSTOM, .parse = opt_sweep_depths, .arg = "LIST", .lo = 0, .hi = 21,
     .group = SWEEP,
     .help = "one viewer per (budget, depth), all on one path (default orbit) and the same seed, stepped unless "
             "--epoch-period is given; checks that detail (deepest level) never drops with a bigger budget or a "
             "deeper limit"},

    {.name = "faults", .type = OC_CLI_CUSTOM, .parse = opt_faults, .arg = "LIST", .group = FAULTS,
     .help = "misbehaving clients beside the measured viewers, stepped: stall, drop, garbage, restart, or all"},
    {.name = "fault-every", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(fault_every), .arg = "N", .lo = 1,
     .hi = STRESS_MAX_STEPS, .def = "1", .group = FAULTS, .help = "steps between rounds of misbehaving connections"},
    {.name = "fault-budget", .type = OC_CLI_CUSTOM, .parse = opt_u64, .offset = AT(fault_budget_mib), .arg = "MIB",
     .lo = 1, .hi = 65536, .def = "16", .group = FAULTS, .help = "their budget"},
    {.name = "restart-at", .type = OC_CLI_CUSTOM, .parse = opt_long, .offset = AT(restart_at), .arg = "STEP", .lo = 1,
     .hi = STRESS_MAX_STEPS, .def_note = "the middle of the run", .group = FAULTS,
     .help = "restart: kill the server (SIGKILL) right after this step's reply and start it again on the same port"},
    {.name = "restart-by", .type = OC_CLI_CUSTOM, .parse = opt_restart_by, .arg = "HOW", .def = "kill",
     .group = FAULTS,
     .help = "kill or drain: SIGTERM, so that the server tells every viewer GOODBYE RECONNECT and exits 0 once they "
             "left (a spawned server drains for at most " DEF(STRESS_DRAIN_S) " s); the viewers come back with "
             "backoff and jitter"},
    {.name = "fault-rss-slack", .type = OC_CLI_DOUBLE, .offset = AT(fault_rss_slack), .arg = "MIB", .lo = 0,
     .hi = 1 << 20, .def = DEF(STRESS_FAULT_SLACK_MIB), .group = FAULTS,
     .help = "the server's RSS may grow this much beyond its own accounting of brick cache, held states, send "
             "queues and connections"},

    {.name = "verbose", .short_name = 'v', .type = OC_CLI_FLAG, .offset = AT(verbose), .group = OTHER,
     .help = "a line per state on stderr, and the server's log"},
    {.name = "help", .type = OC_CLI_HELP, .group = OTHER, .help = "print this and exit"},
    {.name = "version", .type = OC_CLI_VERSION, .group = OTHER, .help = "print the version and exit"},
    {0}};

static const char about[] =
    "Runs N headless viewers over the real protocol against one overcast-server, each flying its\n"
    "own camera path with its own budget and depth, and checks every state live: resident bytes\n"
    "(counted here from the states each viewer keeps) never above the granted budget, every\n"
    "checksum verified, every skipped epoch reported. Measures bytes/s per viewer, epoch latency,\n"
    "with a period each epoch's lateness (EPOCH_BEGIN readable minus its due instant n x P, UTC)\n"
    "and the ticks coalesced, with --verify-content the content age it verifies itself, time to\n"
    "full detail after a teleport, server RSS and CPU, the tool's own CPU and the brick cache hit\n"
    "rate; prints a table, and JSON with --json. No GPU memory is allocated.\n"
    "Definitions and measured runs: docs/performance.md, \"Many viewers\" and \"Epochs on the clock\".\n";

/* The text after the options: the ramp's rule (from stress.h's figures), faults, exit status. */
static const char *epilog(void) {
  static char text[2048];
  snprintf(text, sizeof text,
           "A ramp phase is sustained when every viewer has lateness p99 <= %.0f ms, <= %.0f %% of its ticks\n"
           "coalesced, verified content age p99 <= %d steps (with --verify-content), time to full detail after\n"
           "a teleport <= %.2f x a stepped server's on the same path and budget (measured first, side by side),\n"
           "and a median interval <= %.1f x the period.\n"
           "\n"
           "Faults (--faults), from step 2 on, one round every --fault-every steps: stall opens a viewer\n"
           "that stops reading; drop one that vanishes (at once, mid-HELLO, mid-epoch or after a state);\n"
           "garbage a connection sending junk (no magic, a 4 GiB frame, a short HELLO, an unknown type, a\n"
           "NaN camera, a stalled header), which must get an ERROR and be closed; restart kills the server\n"
           "once and the viewers must reconnect and resynchronise. Checked: no measured viewer misses an\n"
           "epoch (restart aside), the server's RSS stays within its accounting plus the slack, no\n"
           "connection's send queue passes the server's hard limit.\n"
           "\n"
           "exit status: 0 every check passed; 1 a check failed (budget, checksum, protocol, a viewer\n"
           "lost its connection or got no state, a fault check) or a runtime error; 2 usage error\n",
           1e3 * STRESS_LATE_P99, 100.0 * STRESS_COALESCED_MAX, STRESS_AGE_ALLOWED, STRESS_DETAIL_FACTOR,
           STRESS_RAMP_INTERVAL);
  return text;
}

/* Whether the option `name` appeared on the command line. */
static int was_given(const unsigned char *given, const char *name) {
  for (int i = 0; opts[i].name; i++)
    if (!strcmp(opts[i].name, name)) return given[i];
  return 0;
}

/* The first of `names` (NULL-terminated) given, or NULL. */
static const char *first_given(const unsigned char *given, const char *const *names) {
  for (int k = 0; names[k]; k++)
    if (was_given(given, names[k])) return names[k];
  return NULL;
}

/* Which server it is: --spawn (the default) or --connect, and the options that go with one. */
static int check_server(stress_opts_t *o, const unsigned char *given) {
  static const char *const spawn_only[] = {"server", "scene", "epoch-period", "server-threads", "server-arg", NULL};
  int connect = was_given(given, "connect");
  const char *s = first_given(given, spawn_only);
  if (o->spawn && connect) return oc_cli_fail(prog, -1, "--spawn and --connect exclude each other");
  if (connect && s) return oc_cli_fail(prog, -1, "--%s goes with --spawn, not --connect", s);
  if (o->server_pid && !connect) return oc_cli_fail(prog, -1, "--server-pid goes with --connect");
  o->spawn = !connect;
  return 0;
}

/* --ramp and --sweep-budgets. */
static int check_modes(stress_opts_t *o, const unsigned char *given) {
  static const char *const ramp_only[] = {"plot", "ramp-all", "no-reference", "reference-teleports", "detail-reference",
                                          NULL};
  if (!o->nsweep_budgets != !o->nsweep_depths)
    return oc_cli_fail(prog, -1, "--sweep-budgets and --sweep-depths go together");
  o->sweep = o->nsweep_budgets > 0;
  if (o->ramp && o->sweep) return oc_cli_fail(prog, -1, "--ramp and --sweep-budgets exclude each other");
  if (o->ramp && !o->spawn) return oc_cli_fail(prog, -1, "--ramp goes with --spawn, not --connect");
  if (o->ramp && o->epoch_period == 0) return oc_cli_fail(prog, -1, "--ramp needs a period (--epoch-period > 0)");
  if (!o->ramp && first_given(given, ramp_only))
    return oc_cli_fail(prog, -1,
                       "--plot, --ramp-all, --no-reference, --reference-teleports and --detail-reference go with --ramp");
  if (o->verify_content > 0 && !o->spawn)
    return oc_cli_fail(prog, -1, "--verify-content needs --spawn: the tool re-produces bricks of the scene it gave the server");
  if (o->ramp && o->ramp_from > o->ramp_max)
    return oc_cli_fail(prog, -1, "--ramp-from %ld is above --ramp-max %ld", o->ramp_from, o->ramp_max);
  if (o->sweep) {
    if ((long)o->nsweep_budgets * o->nsweep_depths > STRESS_MAX_VIEWERS)
      return oc_cli_fail(prog, -1, "--sweep-budgets × --sweep-depths: at most %d combinations", STRESS_MAX_VIEWERS);
    o->viewers = o->nsweep_budgets * o->nsweep_depths;
    if (o->spawn && o->epoch_period < 0) o->epoch_period = 0;
    if (!o->npaths) o->paths[o->npaths++] = STRESS_ORBIT;
  }
  return 0;
}

/* --faults and the options that go with it. */
static int check_faults(stress_opts_t *o, const unsigned char *given) {
  static const char *const fault_only[] = {"fault-every", "fault-budget", "restart-at", "restart-by", "fault-rss-slack",
                                           NULL};
  int restart = (o->faults & STRESS_FAULT_RESTART) != 0;
  if (!o->faults) {
    if (first_given(given, fault_only))
      return oc_cli_fail(prog, -1,
                         "--fault-every, --fault-budget, --restart-at, --restart-by and --fault-rss-slack go with --faults");
    return 0;
  }
  if (o->ramp || o->sweep) return oc_cli_fail(prog, -1, "--faults goes with neither --ramp nor --sweep-budgets");
  if (o->epoch_period > 0)
    return oc_cli_fail(prog, -1, "--faults needs a stepped server (--epoch-period 0, the default with --faults)");
  if (restart && !o->spawn) return oc_cli_fail(prog, -1, "--faults restart needs a spawned server, not --connect");
  if (o->spawn) o->epoch_period = 0;
  if (!o->epochs && o->duration <= 0) o->epochs = 12;
  if (restart && !o->restart_at) o->restart_at = o->epochs ? (o->epochs + 1) / 2 : 6;
  if (restart && o->epochs && o->restart_at >= o->epochs)
    return oc_cli_fail(prog, -1, "--restart-at %ld: must come before the last step (--epochs %ld)", o->restart_at,
                       o->epochs);
  return 0;
}

int stress_opts_parse(int argc, char **argv, stress_opts_t *o) {
  unsigned char given[sizeof opts / sizeof opts[0]];
  const oc_cli_spec_t spec = {.prog = prog, .synopsis = "[options]", .about = about, .epilog = epilog(), .opts = opts};
  memset(o, 0, sizeof *o);
  o->epoch_period = -1; /* the scene's */
  o->time_scale = -1;   /* not set */
  o->reference = 1;
  int r = oc_cli_parse(&spec, argc, argv, o, given, NULL);
  if (r) return r;
  if (check_server(o, given) < 0 || check_modes(o, given) < 0 || check_faults(o, given) < 0) return -1;
  if (o->ramp) o->viewers = (int)o->ramp_max;
  if (!o->npaths) {
    for (int k = 0; k < STRESS_PATH_COUNT; k++) o->paths[k] = k;
    o->npaths = STRESS_PATH_COUNT;
  }
  if (!o->nbudgets) o->budgets_mib[o->nbudgets++] = 16;
  if (!o->ndepths) o->depths[o->ndepths++] = 21;
  if (!o->epochs && o->duration <= 0) o->epochs = 8;
  return 0;
}
