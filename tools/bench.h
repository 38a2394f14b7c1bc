/* bench.h — the subcommands of overcast-bench (one file each) and their shared helpers. */
#ifndef OC_TOOLS_BENCH_H
#define OC_TOOLS_BENCH_H

#include <stdio.h>

void oct_bench_usage(FILE *f);
/*! oct_parse_list() : "a,b,c" of integers in [lo, hi]; 0, or -1 after printing the error. */
int oct_parse_list(const char *prog, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n);
int oct_bench_render(const char *prog, int argc, char **argv);
int oct_bench_field(const char *prog, int argc, char **argv);
int oct_bench_tau(const char *prog, int argc, char **argv);
int oct_bench_plan(const char *prog, int argc, char **argv);
int oct_bench_world(const char *prog, int argc, char **argv);

#endif /* OC_TOOLS_BENCH_H */
