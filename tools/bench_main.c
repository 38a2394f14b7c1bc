/* overcast-bench — benchmarks; one file per subcommand (bench_*.c), what they share in bench_util.c.
 * This file only dispatches. Figures go into docs/performance.md with the command that made them. */
#include <stdio.h>
#include <string.h>

#include "bench.h"
#include "oc.h"

static const char *prog = "overcast-bench";

typedef struct {
  const char *name, *summary;
  int (*run)(const char *prog, int argc, char **argv);
  const oc_cli_spec_t *spec; /* its options */
} cmd_t;

static const cmd_t cmds[] = {
    {"render", "CPU reference renderer throughput per thread count", oct_bench_render, &oct_bench_render_spec},
    {"field", "brick production of a scene's field sources: bricks/s per core, bound classification",
     oct_bench_field, &oct_bench_field_spec},
    {"tau", "sun optical depth τ: direct march vs group volume, µs per brick and the volume's error", oct_bench_tau,
     &oct_bench_tau_spec},
    {"plan", "LOD planner: a re-plan of about a million leaves (still, moved, teleported), ms on one core",
     oct_bench_plan, &oct_bench_plan_spec},
    {"world", "the server core stepped for some epochs: plans, production, cache, refresh savings", oct_bench_world,
     &oct_bench_world_spec},
    {"wire", "epoch encodings side by side: per-brick zstd, batches, deltas, a dictionary", oct_bench_wire, &oct_bench_wire_spec},
    {"sweep", "error against run time: quality knobs swept, RMSE/PSNR against the best setting", oct_bench_sweep,
     &oct_bench_sweep_spec},
    {"truth", "Monte Carlo ground truth (delta tracking, every scattering order) for small views", oct_bench_truth,
     &oct_bench_truth_spec},
    {"model", "the cloud model against stored truth images (truth --save): errors, fit objective", oct_bench_model,
     &oct_bench_model_spec},
    {"stability", "stiff and extreme cases end to end (server, protocol, renderers): finite, bounded, known answers",
     oct_bench_stability, &oct_bench_stability_spec},
    {"features", "each feature a scene uses turned off alone: server time, bricks, wire, memory, tables, render",
     oct_bench_features, &oct_bench_features_spec},
    {"noise", "the fBm evaluated against a tiled pre-filtered volume of it: build, ns per point, bound widths",
     oct_bench_noise, &oct_bench_noise_spec},
    {"look", "a view's look measured: cloud pixels, lit against dark cloud, the ground's colour", oct_bench_look,
     &oct_bench_look_spec},
};
#define NCMDS ((int)(sizeof cmds / sizeof *cmds))

/* --help: the commands, then each one's options (its own --help, from its table). */
static void usage(FILE *f) {
  fprintf(f, "usage: %s COMMAND [options]\n\ncommands:\n", prog);
  for (int i = 0; i < NCMDS; i++) fprintf(f, "  %-10s %s\n", cmds[i].name, cmds[i].summary);
  for (int i = 0; i < NCMDS; i++) {
    fputc('\n', f);
    oc_cli_help(f, cmds[i].spec);
  }
  fprintf(f, "\n  --help, --version\n\nexit status: 0 ok, 1 runtime error, 2 usage error\n");
}

int main(int argc, char **argv) {
  if (argc < 2) return oc_cli_fail(prog, OC_EXIT_USAGE, "missing command (see --help for usage)");
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    usage(stdout);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    oc_cli_version(prog);
    return OC_EXIT_OK;
  }
  for (int i = 0; i < NCMDS; i++)
    if (!strcmp(argv[1], cmds[i].name)) return cmds[i].run(prog, argc - 1, argv + 1);
  return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown command \"%s\" (see --help)", argv[1]);
}
