/* overcast-ctl — the control client: one request per run (docs/protocol.md, "CONTROL and
 * CONTROL_REPLY"). Builds the request JSON from the command line, sends it over a control
 * connection (client/net.h) and prints the reply, pretty, on stdout. */
#include <cjson/cJSON.h>
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ocv.h"

static const char *prog = "overcast-ctl";

static void usage(FILE *f) {
  fprintf(f,
          "usage: overcast-ctl [options] COMMAND [ARGS]\n"
          "Sends one control request to a running overcast-server and prints its JSON reply.\n"
          "\n"
          "options (also accepted after the command):\n"
          "  --connect HOST:PORT   the server (default 127.0.0.1:7420; [V6]:PORT for IPv6)\n"
          "  --control-token TEXT  the token control requests present: the server's --control-token, or\n"
          "                        its --token when it has no control token (the viewer token is refused\n"
          "                        for control where a control token is set)\n"
          "  --token TEXT          the same option under its older name\n"
          "  --timeout S           seconds to wait for the connection and the reply (default 30)\n"
          "  --help, --version\n"
          "\n"
          "commands:\n"
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
          "exit status: 0 ok, 1 refused by the server or no connection, 2 usage error\n");
}

typedef struct {
  char host[OCV_HOST_MAX];
  int port;
  const char *token;
  double timeout;
} ctl_opts_t;

/* --control-token or --token (one token: HELLO carries one). @return 0, or -1 after a message. */
static int set_token(ctl_opts_t *o, const char *opt, const char *val) {
  if (!*val || strlen(val) > OCP_TOKEN_MAX) {
    oc_cli_fail(prog, 0, "%s: 1..%d bytes", opt, OCP_TOKEN_MAX);
    return -1;
  }
  if (o->token && strcmp(o->token, val) != 0) {
    oc_cli_fail(prog, 0, "%s: a token was given already (--control-token and --token are one option)", opt);
    return -1;
  }
  o->token = val;
  return 0;
}

/* Global options, wherever they appear. @return 1 consumed (and *i advanced), 0 not one, -1 bad. */
static int global_opt(ctl_opts_t *o, int argc, char **argv, int *i) {
  const char *a = argv[*i], *val = NULL;
  static const char *names[] = {"--connect", "--control-token", "--token", "--timeout"};
  int which = -1;
  for (int k = 0; k < 4 && which < 0; k++) {
    size_t n = strlen(names[k]);
    if (!strncmp(a, names[k], n) && (a[n] == '\0' || a[n] == '=')) {
      which = k;
      val = a[n] == '=' ? a + n + 1 : NULL;
    }
  }
  if (which < 0) return 0;
  if (!val) {
    if (*i + 1 >= argc) {
      oc_cli_fail(prog, 0, "%s needs a value (see --help)", names[which]);
      return -1;
    }
    val = argv[++*i];
  }
  switch (which) {
    case 0:
      if (ocv_parse_address(val, o->host, sizeof o->host, &o->port) < 0) {
        oc_cli_fail(prog, 0, "--connect: expected HOST:PORT (port 1..65535), got \"%s\"", val);
        return -1;
      }
      break;
    case 1:
    case 2:
      if (set_token(o, names[which], val) < 0) return -1;
      break;
    default:
      if (oc_cli_double(prog, "--timeout", val, 0.01, 86400, &o->timeout)) return -1;
      break;
  }
  return 1;
}

/* "--name VALUE" or "--name=VALUE" of a command; @return the value, or NULL when argv[*i] is not it. */
static const char *cmd_opt(const char *name, int argc, char **argv, int *i, int *missing) {
  size_t n = strlen(name);
  const char *a = argv[*i];
  if (strncmp(a, name, n) != 0) return NULL;
  if (a[n] == '=') return a + n + 1;
  if (a[n] != '\0') return NULL;
  if (*i + 1 >= argc) {
    *missing = 1;
    return NULL;
  }
  return argv[++*i];
}

/* Parses "X,Y,Z" (three finite numbers). */
static int parse_vec3(const char *text, double v[3]) {
  const char *s = text;
  char *end;
  for (int k = 0; k < 3; k++) {
    v[k] = strtod(s, &end);
    if (end == s || !isfinite(v[k]) || (k < 2 && *end != ',') || (k == 2 && *end)) return -1;
    s = end + 1;
  }
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

/* Builds the request object from the command and its arguments (argv[first..argc)), consuming
 * global options found among them. @return the object, or NULL after a usage message. */
static cJSON *build_request(ctl_opts_t *o, int argc, char **argv, int first) {
  const char *cmd = argv[first];
  const char *pos[2] = {NULL, NULL}; /* positional arguments */
  int npos = 0;
  const char *seconds = NULL, *set = NULL, *scale = NULL, *lat = NULL, *lon = NULL, *dir = NULL;
  int takes_pos = !strcmp(cmd, "weather") || !strcmp(cmd, "step") || !strcmp(cmd, "disconnect") || !strcmp(cmd, "raw") ||
                  !strcmp(cmd, "budget");
  int max_pos = !strcmp(cmd, "budget") ? 2 : 1;
  static const char *known[] = {"weather", "time",       "pause", "resume", "sun",    "step", "reload",
                                "sessions", "disconnect", "stats", "drain",  "budget", "raw"};
  int ok = 0;
  for (size_t k = 0; k < sizeof known / sizeof known[0]; k++) ok |= !strcmp(cmd, known[k]);
  if (!ok) {
    oc_cli_fail(prog, 0, "unknown command \"%s\" (see --help)", cmd);
    return NULL;
  }
  for (int i = first + 1; i < argc; i++) {
    int g = global_opt(o, argc, argv, &i);
    if (g < 0) return NULL;
    if (g) continue;
    const char *a = argv[i], *v;
    int missing = 0;
    if (!strcmp(cmd, "weather") && (v = cmd_opt("--seconds", argc, argv, &i, &missing))) seconds = v;
    else if (!strcmp(cmd, "time") && (v = cmd_opt("--set", argc, argv, &i, &missing))) set = v;
    else if (!strcmp(cmd, "time") && (v = cmd_opt("--scale", argc, argv, &i, &missing))) scale = v;
    else if (!strcmp(cmd, "sun") && (v = cmd_opt("--lat", argc, argv, &i, &missing))) lat = v;
    else if (!strcmp(cmd, "sun") && (v = cmd_opt("--lon", argc, argv, &i, &missing))) lon = v;
    else if (!strcmp(cmd, "sun") && (v = cmd_opt("--dir", argc, argv, &i, &missing))) dir = v;
    else if (missing) {
      oc_cli_fail(prog, 0, "%s %s needs a value", cmd, a);
      return NULL;
    } else if (a[0] == '-' && a[1] == '-' && strcmp(cmd, "raw") != 0) {
      oc_cli_fail(prog, 0, "%s: unknown option \"%s\" (see --help)", cmd, a);
      return NULL;
    } else if (takes_pos && npos < max_pos) {
      pos[npos++] = a;
    } else {
      oc_cli_fail(prog, 0, "%s: unexpected argument \"%s\" (see --help)", cmd, a);
      return NULL;
    }
  }

  cJSON *j = NULL;
  double d;
  long l;
  if (!strcmp(cmd, "raw")) {
    if (!pos[0]) {
      oc_cli_fail(prog, 0, "raw: give the request, e.g. '{\"op\":\"stats\"}'");
      return NULL;
    }
    j = cJSON_Parse(pos[0]);
    if (!cJSON_IsObject(j)) {
      cJSON_Delete(j);
      oc_cli_fail(prog, 0, "raw: not a JSON object: %s", pos[0]);
      return NULL;
    }
    return j;
  }
  j = cJSON_CreateObject();
  if (!j) return NULL;
  cJSON_AddStringToObject(j, "op", cmd);
  if (!strcmp(cmd, "weather")) {
    if (!pos[0] || oc_scene_preset_parse(pos[0]) < 0) {
      oc_cli_fail(prog, 0, "weather: PRESET must be one of clear, fair, overcast, storm, cirrus (got %s%s%s)",
                  pos[0] ? "\"" : "", pos[0] ? pos[0] : "nothing", pos[0] ? "\"" : "");
      goto bad;
    }
    cJSON_AddStringToObject(j, "preset", pos[0]);
    if (seconds) {
      if (oc_cli_double(prog, "--seconds", seconds, 0, 1e7, &d)) goto bad;
      cJSON_AddNumberToObject(j, "seconds", d);
    }
  } else if (!strcmp(cmd, "time")) {
    if (!set && !scale) {
      oc_cli_fail(prog, 0, "time: give --set T and/or --scale S");
      goto bad;
    }
    if (set) {
      if (oc_cli_double(prog, "--set", set, -1e12, 1e12, &d)) goto bad;
      cJSON_AddNumberToObject(j, "set", d);
    }
    if (scale) {
      if (oc_cli_double(prog, "--scale", scale, 0, 1e6, &d)) goto bad;
      cJSON_AddNumberToObject(j, "scale", d);
    }
  } else if (!strcmp(cmd, "sun")) {
    if (dir && (lat || lon)) {
      oc_cli_fail(prog, 0, "sun: --dir excludes --lat and --lon");
      goto bad;
    }
    if (dir) {
      double v[3];
      if (parse_vec3(dir, v) < 0 || !(v[0] != 0 || v[1] != 0 || v[2] != 0)) {
        oc_cli_fail(prog, 0, "--dir: expected X,Y,Z (finite, not all zero), got \"%s\"", dir);
        goto bad;
      }
      cJSON_AddItemToObject(j, "dir", cJSON_CreateDoubleArray(v, 3));
    } else {
      if (!lat || !lon) {
        oc_cli_fail(prog, 0, "sun: give --lat LAT --lon LON, or --dir X,Y,Z");
        goto bad;
      }
      double la, lo;
      if (oc_cli_double(prog, "--lat", lat, -90, 90, &la) || oc_cli_double(prog, "--lon", lon, -360, 360, &lo)) goto bad;
      cJSON_AddNumberToObject(j, "lat", la);
      cJSON_AddNumberToObject(j, "lon", lo);
    }
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
  enum { O_CONNECT = 256, O_CONTROL_TOKEN, O_TOKEN, O_TIMEOUT, O_HELP, O_VERSION };
  static const struct option opts[] = {{"connect", required_argument, 0, O_CONNECT},
                                       {"control-token", required_argument, 0, O_CONTROL_TOKEN},
                                       {"token", required_argument, 0, O_TOKEN},
                                       {"timeout", required_argument, 0, O_TIMEOUT},
                                       {"help", no_argument, 0, O_HELP},
                                       {"version", no_argument, 0, O_VERSION},
                                       {0, 0, 0, 0}};
  ctl_opts_t o = {OCV_DEFAULT_HOST, OCV_DEFAULT_PORT, NULL, 30.0};
  int c;
  opterr = 0;
  /* "+": stop at the command, whose own options are parsed by build_request() */
  while ((c = getopt_long(argc, argv, "+", opts, NULL)) != -1) {
    switch (c) {
      case O_CONNECT:
        if (ocv_parse_address(optarg, o.host, sizeof o.host, &o.port) < 0)
          return oc_cli_fail(prog, OC_EXIT_USAGE, "--connect: expected HOST:PORT (port 1..65535), got \"%s\"", optarg);
        break;
      case O_CONTROL_TOKEN:
      case O_TOKEN:
        if (set_token(&o, c == O_TOKEN ? "--token" : "--control-token", optarg) < 0) return OC_EXIT_USAGE;
        break;
      case O_TIMEOUT: if (oc_cli_double(prog, "--timeout", optarg, 0.01, 86400, &o.timeout)) return OC_EXIT_USAGE; break;
      case O_HELP: usage(stdout); return OC_EXIT_OK;
      case O_VERSION: oc_cli_version(prog); return OC_EXIT_OK;
      default:
        return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown or incomplete option \"%s\" (see --help)", argv[optind - 1]);
    }
  }
  if (optind >= argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "no command (see --help)");
  for (int i = optind + 1; i < argc; i++) /* --help anywhere still helps */
    if (!strcmp(argv[i], "--help")) {
      usage(stdout);
      return OC_EXIT_OK;
    }
  cJSON *req = build_request(&o, argc, argv, optind);
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
