/* sepbrdf bench: the benchmark engine of bench/bench.c as a subcommand
 * (same options as the sepbrdf_bench executable; `--quick` for a short run). */
#include "bench.h"
#include "cli.h"

int cmd_bench(int argc, char **argv) { return sb_bench_main(argc, argv, "sepbrdf bench"); }
