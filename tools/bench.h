/* bench.h — the subcommands of overcast-bench, one file each (bench_main.c dispatches; what they
 * share is in bench_util.h). */
#ifndef OC_TOOLS_BENCH_H
#define OC_TOOLS_BENCH_H

#include "oc.h"

/* Each subcommand: its entry point (argv[0] its name) and the table of its options, which its --help
 * and overcast-bench --help print. */
int oct_bench_render(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_render_spec;
int oct_bench_field(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_field_spec;
int oct_bench_tau(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_tau_spec;
int oct_bench_plan(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_plan_spec;
int oct_bench_world(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_world_spec;
int oct_bench_sweep(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_sweep_spec;
int oct_bench_truth(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_truth_spec;
int oct_bench_model(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_model_spec;
int oct_bench_stability(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_stability_spec;
int oct_bench_features(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_features_spec;
int oct_bench_wire(const char *prog, int argc, char **argv);
extern const oc_cli_spec_t oct_bench_wire_spec;

#endif /* OC_TOOLS_BENCH_H */
