/* overcast-bench — benchmarks; one file per subcommand (bench_*.c). Figures go into
 * docs/performance.md with the command that made them. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "oc_cli.h"

static const char *prog = "overcast-bench";

void oct_bench_usage(FILE *f) {
  fprintf(f,
          "usage: overcast-bench COMMAND [options]\n"
          "\n"
          "commands:\n"
          "  render     CPU reference renderer throughput per thread count\n"
          "  field      brick production of a scene's field sources: bricks/s per core, bound classification\n"
          "\n"
          "render options:\n"
          "  --scene FILE        analytic scene (default scenes/analytic_sphere.json)\n"
          "  --camera LAT,LON,ALT,HEADING,PITCH,FOV   (default: the scene's camera)\n"
          "  --size WxH          image size (default 320x180)\n"
          "  --threads LIST      comma-separated thread counts (default 1,2)\n"
          "  --repeat N          renders per thread count; the fastest counts (default 3)\n"
          "  --step-factor X     (default 0.5)\n"
          "  --time T            world time in seconds (default 0)\n"
          "  --png FILE          also write the first thread count's image\n"
          "  (scenes with procedural or vdb sources are built through the server's field, with τ\n"
          "   marched toward the sun: a preview until the server core produces states)\n"
          "\n"
          "field options:\n"
          "  --scene FILE        scene (default: the built-in procedural planet)\n"
          "  --levels LIST       octree levels (default 10,13,16)\n"
          "  --block N           N³ nodes per level around the scene camera (default 6)\n"
          "  --at LAT,LON        centre of the block (default: the scene camera)\n"
          "  --alt M             altitude of the block's centre in metres (default 2000)\n"
          "  --time T            world time in seconds (default 0)\n"
          "\n"
          "  --help, --version\n"
          "\n"
          "exit status: 0 ok, 1 runtime error, 2 usage error\n");
}

int oct_parse_list(const char *p, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n) {
  char buf[256];
  *n = 0;
  snprintf(buf, sizeof buf, "%s", text);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    if (*n == cap) {
      oc_cli_fail(p, 0, "%s: at most %d entries", opt, cap);
      return -1;
    }
    if (oc_cli_int(p, opt, tok, lo, hi, &out[(*n)++])) return -1;
  }
  if (*n == 0) {
    oc_cli_fail(p, 0, "%s: empty list", opt);
    return -1;
  }
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 2) return oc_cli_fail(prog, OC_EXIT_USAGE, "missing command (see --help for usage)");
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    oct_bench_usage(stdout);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    oc_cli_version(prog);
    return OC_EXIT_OK;
  }
  if (!strcmp(argv[1], "render")) return oct_bench_render(prog, argc - 1, argv + 1);
  if (!strcmp(argv[1], "field")) return oct_bench_field(prog, argc - 1, argv + 1);
  return oc_cli_fail(prog, OC_EXIT_USAGE, "unknown command \"%s\" (see --help)", argv[1]);
}
