#include "oc_cli.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef OC_VERSION
#define OC_VERSION "0.0.0"
#endif

int oc_cli_fail(const char *prog, int code, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  fprintf(stderr, "%s: %s\n", prog, msg);
  return code;
}

int oc_cli_int(const char *prog, const char *opt, const char *text, long lo, long hi, long *out) {
  char *end;
  errno = 0;
  long v = strtol(text, &end, 10);
  if (end == text || *end || errno)
    return oc_cli_fail(prog, -1, "%s: expected an integer, got \"%s\"", opt, text);
  if (v < lo || v > hi) return oc_cli_fail(prog, -1, "%s: %ld is outside [%ld, %ld]", opt, v, lo, hi);
  *out = v;
  return 0;
}

int oc_cli_double(const char *prog, const char *opt, const char *text, double lo, double hi, double *out) {
  char *end;
  double v = strtod(text, &end);
  if (end == text || *end || !isfinite(v))
    return oc_cli_fail(prog, -1, "%s: expected a finite number, got \"%s\"", opt, text);
  if (v < lo || v > hi) return oc_cli_fail(prog, -1, "%s: %g is outside [%g, %g]", opt, v, lo, hi);
  *out = v;
  return 0;
}

int oc_cli_size(const char *prog, const char *opt, const char *text, int *w, int *h) {
  char *end;
  long a = strtol(text, &end, 10), b;
  if (end == text || *end != 'x') goto bad;
  const char *s = end + 1;
  b = strtol(s, &end, 10);
  if (end == s || *end) goto bad;
  if (a < 1 || a > 16384 || b < 1 || b > 16384)
    return oc_cli_fail(prog, -1, "%s: %s: each side must be 1..16384", opt, text);
  *w = (int)a;
  *h = (int)b;
  return 0;
bad:
  return oc_cli_fail(prog, -1, "%s: expected WxH, got \"%s\"", opt, text);
}

void oc_cli_version(const char *prog) { printf("%s %s\n", prog, OC_VERSION); }

/* ---- Table-driven options ---- */

#define OC_CLI_MAX_OPTS 127   /* rows of one table; getopt values 256 + row */
#define OC_CLI_COLUMNS 100    /* --help wraps here */
#define OC_CLI_LEFT_MAX 30    /* an option column wider than this puts its text on the next line */

int oc_cli_count(const oc_cli_opt_t *opts) {
  int n = 0;
  while (opts[n].name) n++;
  return n;
}

static int takes_arg(const oc_cli_opt_t *o) {
  return o->type != OC_CLI_FLAG && o->type != OC_CLI_HELP && o->type != OC_CLI_VERSION &&
         !(o->type == OC_CLI_CUSTOM && !o->arg);
}

/* Parses `text` as the value of row `o` into `base`. */
static int store(const char *prog, const oc_cli_opt_t *o, const char *text, void *base) {
  char opt[80];
  snprintf(opt, sizeof opt, "--%s", o->name);
  void *dst = oc_cli_field(o, base);
  long v;
  switch (o->type) {
    case OC_CLI_FLAG: *(int *)dst = 1; return 0;
    case OC_CLI_INT:
      if (oc_cli_int(prog, opt, text, (long)o->lo, (long)o->hi, &v)) return -1;
      *(int *)dst = (int)v;
      return 0;
    case OC_CLI_DOUBLE: return oc_cli_double(prog, opt, text, o->lo, o->hi, (double *)dst);
    case OC_CLI_MIB:
      if (oc_cli_int(prog, opt, text, (long)o->lo, (long)o->hi, &v)) return -1;
      *(uint64_t *)dst = (uint64_t)v << 20;
      return 0;
    case OC_CLI_STRING: {
      size_t n = strlen(text);
      if (o->lo < o->hi && (n < o->lo || n > o->hi))
        return oc_cli_fail(prog, -1, "%s: %.0f..%.0f bytes", opt, o->lo, o->hi);
      *(const char **)dst = text;
      return 0;
    }
    case OC_CLI_CUSTOM: return o->parse(prog, o, o->arg ? text : NULL, base);
    case OC_CLI_HELP:
    case OC_CLI_VERSION: break;
  }
  return 0;
}

/* "unknown or incomplete option": the short letter getopt stopped at, or the argument it took. */
static int unknown(const char *prog, char **argv) {
  if (optopt > 0 && optopt < 256)
    return oc_cli_fail(prog, -1, "unknown or incomplete option \"-%c\" (see --help)", optopt);
  return oc_cli_fail(prog, -1, "unknown or incomplete option \"%s\" (see --help)", argv[optind - 1]);
}

int oc_cli_parse(const oc_cli_spec_t *spec, int argc, char **argv, void *base, unsigned char *given,
                 int *first_operand) {
  const oc_cli_opt_t *opts = spec->opts;
  int n = oc_cli_count(opts);
  if (n > OC_CLI_MAX_OPTS) return oc_cli_fail(spec->prog, -1, "%d options: at most %d", n, OC_CLI_MAX_OPTS);
  struct option lo[OC_CLI_MAX_OPTS + 1];
  char shorts[2 * OC_CLI_MAX_OPTS + 1];
  int ns = 0;
  for (int i = 0; i < n; i++) {
    const oc_cli_opt_t *o = &opts[i];
    if (o->def && store(spec->prog, o, o->def, base)) return -1;
    lo[i] = (struct option){o->name, takes_arg(o) ? required_argument : no_argument, NULL, 256 + i};
    if (o->short_name) {
      shorts[ns++] = o->short_name;
      if (takes_arg(o)) shorts[ns++] = ':';
    }
  }
  lo[n] = (struct option){0, 0, 0, 0};
  shorts[ns] = 0;
  if (given) memset(given, 0, (size_t)n);
  opterr = 0;
  optind = 0; /* 0, not 1: glibc and musl then reset their state too */
  int c;
  while ((c = getopt_long(argc, argv, shorts, lo, NULL)) != -1) {
    int i = c >= 256 ? c - 256 : -1;
    for (int k = 0; i < 0 && k < n; k++)
      if (c != '?' && opts[k].short_name == c) i = k;
    if (i < 0 || i >= n) return unknown(spec->prog, argv);
    const oc_cli_opt_t *o = &opts[i];
    if (given) given[i] = 1;
    if (o->type == OC_CLI_HELP) {
      oc_cli_help(stdout, spec);
      return 1;
    }
    if (o->type == OC_CLI_VERSION) {
      oc_cli_version(spec->prog);
      return 1;
    }
    if (store(spec->prog, o, optarg, base)) return -1;
  }
  if (first_operand)
    *first_operand = optind;
  else if (optind < argc)
    return oc_cli_fail(spec->prog, -1, "unexpected argument \"%s\" (see --help)", argv[optind]);
  return 0;
}

/* Display width of UTF-8 text (code points). */
static int width(const char *s, size_t n) {
  int w = 0;
  for (size_t i = 0; i < n; i++) w += ((unsigned char)s[i] & 0xC0) != 0x80;
  return w;
}

/* The option column of a row: "  -q, --quiet", "  --listen HOST:PORT". */
static int left_of(const oc_cli_opt_t *o, char *buf, size_t cap) {
  int k = snprintf(buf, cap, "  ");
  if (o->short_name) k += snprintf(buf + k, cap - (size_t)k, "-%c, ", o->short_name);
  k += snprintf(buf + k, cap - (size_t)k, "--%s%s%s", o->name, o->arg ? " " : "", o->arg ? o->arg : "");
  return width(buf, strlen(buf));
}

/* A bound as --help prints it: whole numbers in full below 1e15, others as %g. */
static int num(char *buf, size_t cap, double v) {
  if (v == floor(v) && fabs(v) < 1e15) return snprintf(buf, cap, "%.0f", v);
  return snprintf(buf, cap, "%g", v);
}

/* The row's text with its default and range: "viewers at once (default: 64; 1..100000)". */
static void text_of(const oc_cli_opt_t *o, char *buf, size_t cap) {
  const char *def = o->def ? o->def : o->def_note;
  char range[96] = "";
  if (o->lo < o->hi) {
    int k = num(range, sizeof range, o->lo);
    k += snprintf(range + k, sizeof range - (size_t)k, "..");
    k += num(range + k, sizeof range - (size_t)k, o->hi);
    if (o->type == OC_CLI_STRING) snprintf(range + k, sizeof range - (size_t)k, " bytes");
  }
  int k = snprintf(buf, cap, "%s", o->help ? o->help : "");
  if (def || range[0])
    snprintf(buf + k, cap - (size_t)k, " (%s%s%s%s)", def ? "default: " : "", def ? def : "",
             def && range[0] ? "; " : "", range);
}

/* Prints `text` in the columns [col, OC_CLI_COLUMNS), the first line after `used` columns. */
static void wrap(FILE *f, const char *text, int col, int used) {
  const char *s = text;
  int first = 1;
  while (*s) {
    if (!first || used >= col) {
      fputc('\n', f);
      used = 0;
    }
    fprintf(f, "%*s", col - used, "");
    int room = OC_CLI_COLUMNS - col, w = 0;
    const char *line = s, *cut = NULL;
    for (const char *p = s; *p; p++) {
      if (*p == ' ') {
        if (w > room && cut) break;
        cut = p;
      }
      w += ((unsigned char)*p & 0xC0) != 0x80;
    }
    if (w <= room || !cut) cut = line + strlen(line);
    fwrite(line, 1, (size_t)(cut - line), f);
    s = *cut ? cut + 1 : cut;
    first = 0;
  }
  fputc('\n', f);
}

void oc_cli_help(FILE *f, const oc_cli_spec_t *spec) {
  const oc_cli_opt_t *opts = spec->opts;
  char left[160], text[1024];
  int col = 0;
  for (int i = 0; opts[i].name; i++) {
    int w = left_of(&opts[i], left, sizeof left);
    if (w <= OC_CLI_LEFT_MAX && w > col) col = w;
  }
  col += 2;
  fprintf(f, "usage: %s %s\n", spec->prog, spec->synopsis ? spec->synopsis : "[options]");
  if (spec->about) fputs(spec->about, f);
  const char *group = NULL;
  for (int i = 0; opts[i].name; i++) {
    const oc_cli_opt_t *o = &opts[i];
    if (o->group && (!group || strcmp(group, o->group))) fprintf(f, "\n%s:\n", o->group);
    group = o->group;
    int w = left_of(o, left, sizeof left);
    text_of(o, text, sizeof text);
    fputs(left, f);
    wrap(f, text, col, w);
  }
  if (spec->epilog) {
    fputc('\n', f);
    fputs(spec->epilog, f);
  }
}
