/* bench.h — the subcommands of overcast-bench, one file each (bench_main.c dispatches; what they
 * share is in bench_util.h). */
#ifndef OC_TOOLS_BENCH_H
#define OC_TOOLS_BENCH_H

#include "oc.h"

/* Each subcommand <cmd> (bench_<cmd>.c): its entry point oct_bench_<cmd>() (argv[0] its name) and
 * oct_bench_<cmd>_spec, the table of its options, which its --help and overcast-bench --help print. */
#define OCT_BENCH_COMMANDS(X) \
  X(render) X(field) X(tau) X(plan) X(world) X(wire) X(sweep) X(truth) X(model) X(stability) X(features) X(look) X(noise)
#define OCT_BENCH_DECLARE(cmd)                                       \
  int oct_bench_##cmd(const char *prog, int argc, char **argv); \
  extern const oc_cli_spec_t oct_bench_##cmd##_spec;
OCT_BENCH_COMMANDS(OCT_BENCH_DECLARE)
#undef OCT_BENCH_DECLARE

#endif /* OC_TOOLS_BENCH_H */
