/* overcast-ctl — the control client: one request per run (docs/protocol.md, "CONTROL and
 * CONTROL_REPLY"). Builds the request JSON from the command line, sends it over a control
 * connection (client/net.h) and prints the reply, pretty, on stdout. The options, the commands'
 * own included, are one table (common/oc_cli.h), from which they are parsed and --help is printed. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocv.h"

static const char *prog = "overcast-ctl";

typedef struct {
  const char *connect; /* --connect, parsed into host and port after the table */
  char host[OCV_HOST_MAX];
  int port;
  const char *token;
  double timeout;
  double seconds, set, scale, lat, lon, dir[3]; /* the commands' options */
} ctl_opts_t;

/* --control-token or --token (one token: HELLO carries one). */
static int opt_token(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  ctl_opts_t *c = base;
  if (!*text || strlen(text) > OCP_TOKEN_MAX) return oc_cli_fail(p, -1, "--%s: 1..%d bytes", o->name, OCP_TOKEN_MAX);
  if (c->token && strcmp(c->token, text) != 0)
    return oc_cli_fail(p, -1, "--%s: a token was given already (--control-token and --token are one option)", o->name);
  c->token = text;
  return 0;
}

/* sun --dir "X,Y,Z": three finite numbers, not all zero. */
static int opt_dir(const char *p, const oc_cli_opt_t *o, const char *text, void *base) {
  double *v = oc_cli_field(o, base);
  const char *s = text;
  char *end;
  for (int k = 0; k < 3; k++) {
    v[k] = strtod(s, &end);
    if (end == s || !isfinite(v[k]) || (k < 2 && *end != ',') || (k == 2 && *end)) break;
    if (k == 2 && (v[0] != 0 || v[1] != 0 || v[2] != 0)) return 0;
    s = end + 1;
  }
  return oc_cli_fail(p, -1, "--%s: expected X,Y,Z (finite, not all zero), got \"%s\"", o->name, text);
}

/* ---- The table: rows indexed by R_*, so that given[R_*] says what the command line holds ---- */

enum { R_CONNECT, R_CONTROL_TOKEN, R_TOKEN, R_TIMEOUT, R_HELP, R_VERSION, R_SECONDS, R_SET, R_SCALE, R_LAT, R_LON,
       R_DIR, R_COUNT };

#define GLOBAL "options (also accepted after the command)"
#define CMD_GROUP(cmd) cmd " options"
#define AT(field) offsetof(ctl_opts_t, field)
#define TOKEN_BYTES "1.." OC_CLI_STR(OCP_TOKEN_MAX) " bytes"

static const oc_cli_opt_t opts[R_COUNT + 1] = {
    [R_CONNECT] = {.name = "connect", .type = OC_CLI_STRING, .offset = AT(connect), .arg = "HOST:PORT",
                   .def = OCV_DEFAULT_HOST ":" OC_CLI_STR(OCV_DEFAULT_PORT), .group = GLOBAL,
                   .help = "the server ([V6]:PORT for IPv6)"},
    [R_CONTROL_TOKEN] = {.name = "control-token", .type = OC_CLI_CUSTOM, .parse = opt_token, .arg = "TEXT",
                         .group = GLOBAL,
                         .help = "the token control requests present (" TOKEN_BYTES "): the server's "
                                 "--control-token, or its --token when it has no control token (the viewer token "
                                 "is refused for control where a control token is set)"},
    [R_TOKEN] = {.name = "token", .type = OC_CLI_CUSTOM, .parse = opt_token, .arg = "TEXT", .group = GLOBAL,
                 .help = "the same option under its older name"},
    [R_TIMEOUT] = {.name = "timeout", .type = OC_CLI_DOUBLE, .offset = AT(timeout), .arg = "S", .lo = 0.01,
                   .hi = 86400, .def = "30", .group = GLOBAL,
                   .help = "seconds to wait for the connection and the reply"},
    [R_HELP] = {.name = "help", .type = OC_CLI_HELP, .group = GLOBAL, .help = "print this and exit"},
    [R_VERSION] = {.name = "version", .type = OC_CLI_VERSION, .group = GLOBAL, .help = "print the version and exit"},
    [R_SECONDS] = {.name = "seconds", .type = OC_CLI_DOUBLE, .offset = AT(seconds), .arg = "S", .lo = 0, .hi = 1e7,
                   .def_note = "0", .group = CMD_GROUP("weather"), .help = "blend into the preset over S seconds"},
    [R_SET] = {.name = "set", .type = OC_CLI_DOUBLE, .offset = AT(set), .arg = "T", .lo = -1e12, .hi = 1e12,
               .group = CMD_GROUP("time"), .help = "set the world clock (s)"},
    [R_SCALE] = {.name = "scale", .type = OC_CLI_DOUBLE, .offset = AT(scale), .arg = "S", .lo = 0, .hi = 1e6,
                 .group = CMD_GROUP("time"), .help = "set its rate (0 pauses)"},
    [R_LAT] = {.name = "lat", .type = OC_CLI_DOUBLE, .offset = AT(lat), .arg = "LAT", .lo = -90, .hi = 90,
               .group = CMD_GROUP("sun"), .help = "put the sun over this latitude (degrees), with --lon"},
    [R_LON] = {.name = "lon", .type = OC_CLI_DOUBLE, .offset = AT(lon), .arg = "LON", .lo = -360, .hi = 360,
               .group = CMD_GROUP("sun"), .help = "and this longitude (degrees)"},
    [R_DIR] = {.name = "dir", .type = OC_CLI_CUSTOM, .parse = opt_dir, .offset = AT(dir), .arg = "X,Y,Z",
               .group = CMD_GROUP("sun"), .help = "or along this direction (planet frame)"},
    [R_COUNT] = {0}};

static const oc_cli_spec_t spec = {
    .prog = "overcast-ctl",
    .synopsis = "[options] COMMAND [ARGS]",
    .about = "Sends one control request to a running overcast-server and prints its JSON reply.\n",
    .epilog = "commands:\n"
              "  weather PRESET [--seconds S]   clear, fair, overcast, storm or cirrus, blended over S s (default 0)\n"
              "  time [--set T] [--scale S]     set the world clock (s) and/or its rate (0 pauses)\n"
              "  pause | resume                 stop the world clock / restart it at its last rate\n"
              "  sun --lat LAT --lon LON        put the sun over this point (degrees)\n"
              "  sun --dir X,Y,Z                or along this direction (planet frame)\n"
              "  step [N]                       step N epochs now (default 1; 1..1000); replies when done\n"
              "  reload                         re-read the scene file; viewers reconnect\n"
              "  sessions                       list the sessions\n"
              "  disconnect ID                  close a session (GOODBYE KICKED)\n"
              "  budget ID MIB                  set a viewer's budget (protocol version 3 viewers, BUDGET); a\n"
              "                                 lowering holds once the states of the old one have left\n"
              "  stats                          world and server statistics\n"
              "  drain                          stop admitting viewers, tell each GOODBYE RECONNECT; the server\n"
              "                                 exits once they have left (or after its --drain-timeout)\n"
              "  raw JSON                       send a request object as given, e.g. '{\"op\":\"stats\"}'\n"
              "\n"
              "exit status: 0 ok, 1 refused by the server or no connection, 2 usage error\n",
    .opts = opts,
};

/* ---- The request ---- */

/* The command's name, known and with its own options only; its operands in pos[0..1].
 * @return 0, or -1 after a usage message. */
static int check_command(const char *cmd, const unsigned char *given, int npos, char **operands, const char *pos[2]) {
  static const char *known[] = {"weather", "time",       "pause", "resume", "sun",    "step", "reload",
                                "sessions", "disconnect", "stats", "drain",  "budget", "raw"};
  int ok = 0;
  for (size_t k = 0; k < sizeof known / sizeof known[0]; k++) ok |= !strcmp(cmd, known[k]);
  if (!ok) return oc_cli_fail(prog, -1, "unknown command \"%s\" (see --help)", cmd);
  char group[32];
  snprintf(group, sizeof group, CMD_GROUP("%s"), cmd);
  for (int i = R_SECONDS; i < R_COUNT; i++)
    if (given[i] && strcmp(opts[i].group, group) != 0)
      return oc_cli_fail(prog, -1, "%s: unknown option \"--%s\" (see --help)", cmd, opts[i].name);
  int takes_pos = !strcmp(cmd, "weather") || !strcmp(cmd, "step") || !strcmp(cmd, "disconnect") || !strcmp(cmd, "raw") ||
                  !strcmp(cmd, "budget");
  int max_pos = !takes_pos ? 0 : !strcmp(cmd, "budget") ? 2 : 1;
  if (npos > max_pos) return oc_cli_fail(prog, -1, "%s: unexpected argument \"%s\" (see --help)", cmd, operands[max_pos]);
  for (int k = 0; k < npos; k++) pos[k] = operands[k];
  return 0;
}

/* "budget ID MIB": the session and the budget in bytes. @return 0, or -1 after a message. */
static int budget_args(cJSON *j, const char *pos[2]) {
  long id;
  double mib;
  if (!pos[0] || !pos[1]) {
    oc_cli_fail(prog, 0, "budget: give the session ID and the budget in MiB, e.g. budget 3 16 (see: overcast-ctl sessions)");
    return -1;
  }
  if (oc_cli_int(prog, "budget ID", pos[0], 1, UINT32_MAX, &id) ||
      oc_cli_double(prog, "budget MIB", pos[1], 1.0 / 1024, 1 << 23, &mib))
    return -1;
  cJSON_AddNumberToObject(j, "session", (double)id);
  cJSON_AddNumberToObject(j, "bytes", floor(mib * 1048576.0));
  return 0;
}

/* "raw JSON": the object as given. */
static cJSON *raw_request(const char *text) {
  if (!text) {
    oc_cli_fail(prog, 0, "raw: give the request, e.g. '{\"op\":\"stats\"}'");
    return NULL;
  }
  cJSON *j = cJSON_Parse(text);
  if (!cJSON_IsObject(j)) {
    cJSON_Delete(j);
    oc_cli_fail(prog, 0, "raw: not a JSON object: %s", text);
    return NULL;
  }
  return j;
}

/* "sun": --dir, or --lat and --lon. @return 0, or -1 after a message. */
static int sun_args(cJSON *j, const ctl_opts_t *o, const unsigned char *given) {
  if (given[R_DIR] && (given[R_LAT] || given[R_LON])) return oc_cli_fail(prog, -1, "sun: --dir excludes --lat and --lon");
  if (given[R_DIR]) {
    cJSON_AddItemToObject(j, "dir", cJSON_CreateDoubleArray(o->dir, 3));
    return 0;
  }
  if (!given[R_LAT] || !given[R_LON]) return oc_cli_fail(prog, -1, "sun: give --lat LAT --lon LON, or --dir X,Y,Z");
  cJSON_AddNumberToObject(j, "lat", o->lat);
  cJSON_AddNumberToObject(j, "lon", o->lon);
  return 0;
}

/* The request object for the command operands[0] with its operands (npos of them after it) and
 * options. @return the object, or NULL after a usage message. */
static cJSON *build_request(const ctl_opts_t *o, const unsigned char *given, int noperands, char **operands) {
  const char *cmd = operands[0];
  const char *pos[2] = {NULL, NULL};
  if (check_command(cmd, given, noperands - 1, operands + 1, pos) < 0) return NULL;
  if (!strcmp(cmd, "raw")) return raw_request(pos[0]);
  cJSON *j = cJSON_CreateObject();
  long l;
  if (!j) return NULL;
  cJSON_AddStringToObject(j, "op", cmd);
  if (!strcmp(cmd, "weather")) {
    if (!pos[0] || oc_scene_preset_parse(pos[0]) < 0) {
      oc_cli_fail(prog, 0, "weather: PRESET must be one of clear, fair, overcast, storm, cirrus (got %s%s%s)",
                  pos[0] ? "\"" : "", pos[0] ? pos[0] : "nothing", pos[0] ? "\"" : "");
      goto bad;
    }
    cJSON_AddStringToObject(j, "preset", pos[0]);
    if (given[R_SECONDS]) cJSON_AddNumberToObject(j, "seconds", o->seconds);
  } else if (!strcmp(cmd, "time")) {
    if (!given[R_SET] && !given[R_SCALE]) {
      oc_cli_fail(prog, 0, "time: give --set T and/or --scale S");
      goto bad;
    }
    if (given[R_SET]) cJSON_AddNumberToObject(j, "set", o->set);
    if (given[R_SCALE]) cJSON_AddNumberToObject(j, "scale", o->scale);
  } else if (!strcmp(cmd, "sun")) {
    if (sun_args(j, o, given) < 0) goto bad;
  } else if (!strcmp(cmd, "step")) {
    l = 1;
    if (pos[0] && oc_cli_int(prog, "step N", pos[0], 1, 1000, &l)) goto bad;
    cJSON_AddNumberToObject(j, "epochs", (double)l);
  } else if (!strcmp(cmd, "disconnect")) {
    if (!pos[0]) {
      oc_cli_fail(prog, 0, "disconnect: give the session ID (see: overcast-ctl sessions)");
      goto bad;
    }
    if (oc_cli_int(prog, "disconnect ID", pos[0], 1, UINT32_MAX, &l)) goto bad;
    cJSON_AddNumberToObject(j, "session", (double)l);
  } else if (!strcmp(cmd, "budget") && budget_args(j, pos) < 0) {
    goto bad;
  }
  return j;
bad:
  cJSON_Delete(j);
  return NULL;
}

int main(int argc, char **argv) {
  ctl_opts_t o = {0};
  unsigned char given[R_COUNT];
  int first;
  /* GNU getopt moves the operands (the command and its arguments) behind the options, wherever
   * the options stand: before the command, or after it */
  int parsed = oc_cli_parse(&spec, argc, argv, &o, given, &first);
  if (parsed) return parsed > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  if (ocv_parse_address(o.connect, o.host, sizeof o.host, &o.port) < 0)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect: expected HOST:PORT (port 1..65535), got \"%s\"", o.connect);
  if (first >= argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "no command (see --help)");
  cJSON *req = build_request(&o, given, argc - first, argv + first);
  if (!req) return OC_EXIT_USAGE;
  char *req_text = cJSON_PrintUnformatted(req);
  cJSON_Delete(req);
  if (!req_text) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");

  char why[1024];
  ocv_conn_t *conn = NULL;
  ocp_viewer_desc_t vd = {.role = OCP_ROLE_CONTROL, .token = o.token};
  char *reply = NULL;
  int32_t status = 0;
  int rc = OC_EXIT_OK;
  if (ocv_conn_open(&conn, o.host, o.port, &vd, NULL, o.timeout, why, sizeof why) < 0 ||
      ocv_control_request(conn, req_text, o.timeout, &reply, &status, why, sizeof why) < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    goto out;
  }
  cJSON *r = cJSON_Parse(reply);
  char *pretty = r ? cJSON_Print(r) : NULL;
  printf("%s\n", pretty ? pretty : reply);
  fflush(stdout);
  const cJSON *okv = cJSON_GetObjectItemCaseSensitive(r, "ok");
  if (status != OCP_CODE_OK || !cJSON_IsTrue(okv)) {
    const cJSON *err = cJSON_GetObjectItemCaseSensitive(r, "error");
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: refused: %s", ocv_conn_address(conn),
                     cJSON_IsString(err) ? err->valuestring : status != OCP_CODE_OK ? ocp_code_text((uint32_t)status)
                                                                                    : "the reply is not ok");
  }
  cJSON_free(pretty);
  cJSON_Delete(r);
out:
  free(reply);
  cJSON_free(req_text);
  ocv_conn_close(conn);
  return rc;
}
