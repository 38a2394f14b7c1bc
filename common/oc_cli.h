/* oc_cli.h — command-line conventions shared by every program.
 *
 * Exit status 0 on success, 1 on a runtime error, 2 on a usage error; errors are one line on
 * stderr, "<program>: <cause>". Numeric options are parsed whole and range-checked, and the message
 * names the option. */
#ifndef OC_COMMON_CLI_H
#define OC_COMMON_CLI_H

#include <stddef.h>
#include <stdio.h>

#define OC_EXIT_OK 0
#define OC_EXIT_RUNTIME 1
#define OC_EXIT_USAGE 2

/*! oc_cli_fail() : prints "<prog>: <message>" and returns `code` (for `return oc_cli_fail(...)`). */
int oc_cli_fail(const char *prog, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/*! oc_cli_int() / oc_cli_double() : whole-string parse with inclusive bounds; 0 or -1 after
 *  printing "<prog>: --opt: ..." to stderr. */
int oc_cli_int(const char *prog, const char *opt, const char *text, long lo, long hi, long *out);
int oc_cli_double(const char *prog, const char *opt, const char *text, double lo, double hi, double *out);
/*! oc_cli_size() : "WxH", each 1..16384. */
int oc_cli_size(const char *prog, const char *opt, const char *text, int *w, int *h);
/*! oc_cli_version() : prints "<prog> <version>" to stdout. */
void oc_cli_version(const char *prog);

/* ---- Table-driven options (as Redis's static_configs[] in config.c) ----
 *
 * A program describes each option once, in a table of oc_cli_opt_t rows ending with a row whose
 * name is NULL; oc_cli_parse() builds getopt_long()'s array from it and stores each value into the
 * caller's struct at the row's offset, and oc_cli_help() prints --help from the same rows: one line
 * per option (wrapped at 100 columns) with its default and range, under the heading of its group.
 *
 *   static const oc_cli_opt_t opts[] = {
 *     {.name = "max-viewers", .type = OC_CLI_INT, .offset = offsetof(cfg_t, max_viewers), .arg = "N",
 *      .lo = 1, .hi = 100000, .def = OC_CLI_STR(CFG_DEFAULT_MAX_VIEWERS), .group = "Serving",
 *      .help = "viewers at once"},
 *     {.name = "help", .type = OC_CLI_HELP, .group = "Serving", .help = "print this and exit"},
 *     {0}};
 *
 * Errors are the oc_cli_int() / oc_cli_double() lines, "<prog>: --opt: ...". */

/*! OC_CLI_STR() : a macro's value as a string literal, for .def from a default macro. */
#define OC_CLI_STR_(x) #x
#define OC_CLI_STR(x) OC_CLI_STR_(x)

typedef enum {
  OC_CLI_FLAG,    /**< no argument; stores 1 into an int */
  OC_CLI_INT,     /**< an integer in [lo, hi] into an int */
  OC_CLI_DOUBLE,  /**< a finite number in [lo, hi] into a double */
  OC_CLI_MIB,     /**< an integer count of MiB in [lo, hi]; stores the bytes into a uint64_t */
  OC_CLI_STRING,  /**< the argument itself into a const char * (argv's storage); when lo < hi its
                       length in bytes must be in [lo, hi] */
  OC_CLI_CUSTOM,  /**< .parse() parses and stores; it takes an argument when .arg is set */
  OC_CLI_HELP,    /**< prints oc_cli_help() to stdout; oc_cli_parse() returns 1 */
  OC_CLI_VERSION, /**< prints oc_cli_version(); oc_cli_parse() returns 1 */
} oc_cli_type_t;

typedef struct oc_cli_opt_s oc_cli_opt_t;

/*! oc_cli_parse_fn : parses `text` (NULL for a row without .arg) into the caller's struct `base`
 *  (the row's own field is oc_cli_field(opt, base); a parser may fill several fields). On a bad
 *  value it prints one line, "<prog>: --name: ...", and returns -1; otherwise 0. */
typedef int (*oc_cli_parse_fn)(const char *prog, const oc_cli_opt_t *opt, const char *text, void *base);

struct oc_cli_opt_s {
  const char *name;      /**< long name without "--", hyphenated lowercase; NULL ends the table */
  char short_name;       /**< a one-letter alias ('q' for -q), or 0 */
  oc_cli_type_t type;
  size_t offset;         /**< of the destination field in the caller's struct (offsetof) */
  oc_cli_parse_fn parse; /**< OC_CLI_CUSTOM */
  const char *arg;       /**< the argument's name in --help ("N", "MIB", "HOST:PORT"); set for
                              every type that takes one, NULL for flags */
  double lo, hi;         /**< inclusive range (INT, DOUBLE, MIB; a STRING's length); printed by
                              --help when lo < hi */
  const char *def;       /**< default value, as an argument would be written: parsed into the
                              destination before argv is read, and printed; NULL: none */
  const char *def_note;  /**< printed as the default when .def is NULL ("the scene's"); the
                              destination keeps what the caller put there */
  const char *group;     /**< heading of the option's group; --help prints it where it changes */
  const char *help;      /**< one sentence, no final period; wrapped by --help */
};

/*! oc_cli_spec_t : a program's options and the text around them in --help. */
typedef struct {
  const char *prog;      /**< "overcast-server": the error prefix and the usage line */
  const char *synopsis;  /**< after "usage: <prog> ", e.g. "[options]" */
  const char *about;     /**< printed after the usage line, as is (lines end with \n); NULL: none */
  const char *epilog;    /**< printed after the options, as is; NULL: none */
  const oc_cli_opt_t *opts;
} oc_cli_spec_t;

/*! oc_cli_field() : the destination of `opt` in the caller's struct `base`. */
static inline void *oc_cli_field(const oc_cli_opt_t *opt, void *base) { return (char *)base + opt->offset; }

/*! oc_cli_count() : rows of a table, without the terminating one. */
int oc_cli_count(const oc_cli_opt_t *opts);

/*! oc_cli_parse() : applies every row's .def to `base`, then parses argv (from argv[1]; getopt is
 *  reset first, so a program may parse several times). `given`: NULL, or one byte per row set to 1
 *  when its option appears in argv. `first_operand`: NULL refuses operands ("unexpected argument");
 *  otherwise it receives the index of the first one (argc when none). At most 127 rows.
 *  @return 0 to go on; 1 after --help or --version (exit 0); -1 after a one-line usage error on
 *  stderr, "<prog>: ..." (exit OC_EXIT_USAGE). */
int oc_cli_parse(const oc_cli_spec_t *spec, int argc, char **argv, void *base, unsigned char *given,
                 int *first_operand);

/*! oc_cli_help() : prints the usage line, .about, every row under its group's heading (columns
 *  aligned, each option's default and range from its row, wrapped at 100 columns) and .epilog. */
void oc_cli_help(FILE *f, const oc_cli_spec_t *spec);

#endif /* OC_COMMON_CLI_H */
