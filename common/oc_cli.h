/* oc_cli.h — command-line conventions shared by every program.
 *
 * Exit status 0 on success, 1 on a runtime error, 2 on a usage error; errors are one line on
 * stderr, "<program>: <cause>". Numeric options are parsed whole and range-checked, and the message
 * names the option. */
#ifndef OC_COMMON_CLI_H
#define OC_COMMON_CLI_H

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

#endif /* OC_COMMON_CLI_H */
